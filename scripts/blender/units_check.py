"""Units check: the same simple diffuse scenes rendered by Blender Cycles and
by `propcam render`, lights converted by units.py (what the world generator
uses). Run by scripts/blender_units_check.sh:

  blender -b --factory-startup --python scripts/blender/units_check.py -- \
      --out DIR --propcam PATH [--size 96x72] [--spp 256] [--bounces 4] [--threads 2]

Cases: area_light (Blender AREA light), area_mesh (emissive quad), point_light
(Blender POINT light with soft radius), point_mesh (emissive UV sphere),
spot_light (SPOT with soft radius: our spot sphere), spot_point (SPOT of
radius 0: our spot point), point_zero (POINT of radius 0: our point),
disc_light (AREA DISK: our disc), area_turned (an AREA bar turned about
its normal: our rotation_deg), area_seen and area_hidden (an AREA light in
view with the object's camera ray visibility on and off: our
visible_to_camera), sun (Blender SUN), environment (equirectangular EXR
world). Light objects start with visible_camera False (measured in Blender
3.4), so the other cases keep their lights out of view. --bounces B is
Cycles' max_bounces and propcam's --bounces alike (0: direct light only).
Prints a table of image means and the worst of 4x4 block means (a block's difference relative
to its Cycles mean, or to the image mean where the block is darker); exits 1 when an image mean
differs by more than 2% (or a block mean by more than 5%)."""
import json
import math
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import bcommon  # noqa: E402
import twin  # noqa: E402
import units  # noqa: E402

ENV_FILE = "/usr/share/blender/datafiles/studiolights/world/courtyard.exr"
MEAN_TOL, BLOCK_TOL = 0.02, 0.05


def args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    a = {"size": "96x72", "spp": "256", "bounces": "4", "threads": "2"}
    for i in range(0, len(argv), 2):
        a[argv[i].lstrip("-")] = argv[i + 1]
    a["w"], a["h"] = (int(x) for x in a["size"].split("x"))
    return a


def block_rel_diffs(lum_ref, lum, n=4):
    """n x n block means of lum against lum_ref's, row by row: relative to the
    block's reference mean, or to the image's where the block is darker (black sky)."""
    hh, ww = lum_ref.shape
    out = []
    for by in range(n):
        for bx in range(n):
            sl = (slice(by * hh // n, (by + 1) * hh // n), slice(bx * ww // n, (bx + 1) * ww // n))
            out.append(float((lum[sl].mean() - lum_ref[sl].mean()) / max(lum_ref[sl].mean(), lum_ref.mean())))
    return out


class Case(twin.TwinScene):
    """One case: its geometry kept twice (twin.py) and compared by run()."""

    def __init__(self, name, a):
        super().__init__(os.path.join(a["out"], name), a["w"], a["h"], int(a["threads"]))
        self.name, self.a = name, a

    def run(self, blender_desc):
        a = self.a
        cy = bpy.context.scene.cycles
        B = int(a["bounces"])
        cy.max_bounces = cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = B
        out, secs = bcommon.render_layers(int(a["spp"]), 1, (), max_bounces=B)
        cyc = out["combined"]
        scene_path = self.write_scene_json()
        ours_path = os.path.join(self.dir, "propcam.exr")
        # --bounces counts as Cycles' max_bounces (B = 0: direct light only)
        cmd = [a["propcam"], "render", scene_path, "--spp", a["spp"], "--bounces", str(B), "-o", ours_path]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        ours = twin.load_image_linear(ours_path)
        bcommon.save_display_image(cyc, os.path.join(self.dir, "cycles.png"), "Standard")
        bcommon.save_display_image(ours, os.path.join(self.dir, "propcam.png"), "Standard")
        lc, lo = units.luminance(cyc), units.luminance(ours)
        mean_c, mean_o = cyc.reshape(-1, 3).mean(0), ours.reshape(-1, 3).mean(0)
        rel = float(lo.mean() / lc.mean() - 1)
        rel_rgb = (mean_o / np.maximum(mean_c, 1e-12) - 1).tolist()
        blocks = block_rel_diffs(lc, lo)
        worst = max(blocks, key=abs)
        return {"case": self.name, "blender": blender_desc, "ours": self.lights, "cycles_mean": float(lc.mean()),
                "propcam_mean": float(lo.mean()), "mean_rel_diff": rel, "rgb_rel_diff": rel_rgb,
                "worst_block_rel_diff": worst, "blocks": blocks, "cycles_s": secs,
                "ok": abs(rel) <= MEAN_TOL and abs(worst) <= BLOCK_TOL}


def room(case):
    case.box((-2, 0, -2), (2, 3, 2), 0.5, inward=True)
    case.box((-1.2, 0, -1.4), (-0.4, 0.9, -0.6), 0.7)
    case.box((0.3, 0, -1.0), (1.1, 0.5, -0.2), 0.3)
    case.camera((0.0, 1.4, 1.7), 10.0, -20.0, 70.0)


def ground(case):
    case.box((-20, -0.5, -20), (20, 0, 20), 0.3)
    case.box((-1.5, 0, -2.0), (-0.5, 1.0, -1.0), 0.7)
    case.box((0.5, 0, -3.0), (1.5, 2.0, -2.0), 0.5)
    case.box((-0.3, 0, 0.0), (0.3, 0.4, 0.6), 0.6)
    case.camera((0.0, 1.5, 4.0), 0.0, -15.0, 70.0)


def light_object(kind, loc_ours, rot_euler_blender, **props):
    lamp = bpy.data.lights.new(kind.lower(), kind)
    for k, v in props.items():
        setattr(lamp, k, v)
    o = bpy.data.objects.new(kind.lower(), lamp)
    bpy.context.scene.collection.objects.link(o)
    o.location = units.to_blender(loc_ours)
    o.rotation_euler = rot_euler_blender
    return o


def main():
    a = args()
    os.makedirs(a["out"], exist_ok=True)
    results = []
    color = [1.0, 0.85, 0.7]

    # area: Blender AREA light, rectangle w x h facing down (its -Z local = Blender -Z world;
    # local X = our +X = the width of our SCENE.json area light, local Y = our -Z)
    c = Case("area_light", a)
    room(c)
    w, h, P = 0.6, 0.4, 3.0
    light_object("AREA", (0.0, 2.999, 1.0), (0, 0, 0), energy=P, shape="RECTANGLE", size=w, size_y=h, color=color)
    L = units.area_light_radiance(color, P, w * h)
    c.lights = [{"type": "area", "position": [0.0, 2.999, 1.0], "normal": [0, -1, 0], "size": [w, h], "intensity": L}]
    results.append(c.run("AREA %.2fx%.2f m, power %.1f W, colour %s" % (w, h, P, color)))

    c = Case("area_mesh", a)
    room(c)
    S = 8.0
    mat = bcommon.emission_material("panel", color, S)
    bcommon.quad("panel", (-w / 2, 2.999, 1.0 - h / 2), (w, 0, 0), (0, 0, h), mat)
    c.lights = [{"type": "area", "position": [0.0, 2.999, 1.0], "normal": [0, -1, 0], "size": [w, h],
                 "intensity": units.mesh_emission_radiance(color, S)}]
    results.append(c.run("emissive quad %.2fx%.2f m, strength %.1f" % (w, h, S)))

    c = Case("point_light", a)
    room(c)
    r, P = 0.1, 20.0
    light_object("POINT", (0.5, 2.3, 1.0), (0, 0, 0), energy=P, shadow_soft_size=r, color=color)
    c.lights = [{"type": "sphere", "position": [0.5, 2.3, 1.0], "radius": r,
                 "intensity": units.point_light_sphere_radiance(color, P, r)}]
    results.append(c.run("POINT power %.1f W, soft radius %.2f m" % (P, r)))

    c = Case("point_mesh", a)
    room(c)
    r, S = 0.08, 10.0
    bcommon.uv_sphere("bulb", (0.5, 2.3, 1.0), r, bcommon.emission_material("bulb", color, S, one_sided=False), 24,
                      12)
    c.lights = [{"type": "sphere", "position": [0.5, 2.3, 1.0], "radius": units.uv_sphere_effective_radius(r, 24, 12),
                 "intensity": units.mesh_emission_radiance(color, S)}]
    results.append(c.run("emissive UV sphere 24x12 r %.2f m, strength %.1f" % (r, S)))

    # spot: Blender SPOT shining along local -Z, turned to our direction d (local +Z toward -d)
    from mathutils import Vector
    d_spot = np.array([0.3, -1.0, -0.4])
    d_spot /= np.linalg.norm(d_spot)
    spot_rot = Vector(units.to_blender(-d_spot)).to_track_quat("Z", "Y").to_euler()
    for name, r, size_deg, blend, P in (("spot_light", 0.1, 70.0, 0.3, 40.0), ("spot_point", 0.0, 50.0, 0.6, 30.0)):
        c = Case(name, a)
        room(c)
        light_object("SPOT", (0.5, 2.3, 1.0), spot_rot, energy=P, shadow_soft_size=r,
                     spot_size=math.radians(size_deg), spot_blend=blend, color=color)
        spot = units.spot_light(color, P, r, math.radians(size_deg), blend)
        spot.update({"position": [0.5, 2.3, 1.0], "direction": d_spot.tolist()})
        c.lights = [spot]
        results.append(c.run("SPOT %.1f W, soft radius %.2f m, spot_size %.0f deg, blend %.2f" % (P, r, size_deg, blend)))

    c = Case("point_zero", a)
    room(c)
    P = 20.0
    light_object("POINT", (0.5, 2.3, 1.0), (0, 0, 0), energy=P, shadow_soft_size=0.0, color=color)
    c.lights = [{"type": "point", "position": [0.5, 2.3, 1.0], "intensity": units.point_light_intensity(color, P)}]
    results.append(c.run("POINT power %.1f W, soft radius 0" % P))

    # disc: Blender AREA light of shape DISK (size = diameter), one-sided along local -Z = our normal
    c = Case("disc_light", a)
    room(c)
    r, P = 0.25, 3.0
    n_disc = np.array([0.3, -1.0, 0.2])
    n_disc /= np.linalg.norm(n_disc)
    light_object("AREA", (-0.3, 2.7, 0.6), Vector(units.to_blender(-n_disc)).to_track_quat("Z", "Y").to_euler(),
                 energy=P, shape="DISK", size=2 * r, color=color)
    c.lights = [{"type": "disc", "position": [-0.3, 2.7, 0.6], "normal": n_disc.tolist(), "radius": r,
                 "intensity": units.disc_light_radiance(color, P, r)}]
    results.append(c.run("AREA DISK radius %.2f m, power %.1f W" % (r, P)))

    # a long bar facing down just above the view, near the back wall, turned 30 degrees
    # about its normal: our rotation_deg. Its left end comes within 0.15 m of the wall
    # and throws a bright patch there (the opposite turn throws it on the right)
    c = Case("area_turned", a)
    room(c)
    w, h, L, turn = 1.4, 0.1, 3.0, 30.0
    centre = (0.0, 1.95, -1.5)
    axis_u = [math.cos(math.radians(turn)), 0.0, math.sin(math.radians(turn))]
    bcommon.area_light("bar", centre, (0, -1, 0), axis_u, w, h, color, L)
    P = units.area_light_power(L, w * h)
    c.lights = [{"type": "area", "position": list(centre), "normal": [0, -1, 0], "size": [w, h],
                 "rotation_deg": units.area_rotation_deg([0, -1, 0], axis_u),
                 "intensity": units.area_light_radiance(color, P, w * h), "visible_to_camera": False}]
    results.append(c.run("AREA %.1fx%.1f m turned %.0f deg about its normal, power %.2f W" % (w, h, turn, P)))

    # a panel in view on the back wall: Blender's object ray visibility "Camera"
    # (visible_camera) is our visible_to_camera; hidden, both keep its light
    for name, seen in (("area_seen", True), ("area_hidden", False)):
        c = Case(name, a)
        room(c)
        w, h, L = 0.6, 0.4, 3.0
        obj, P = bcommon.area_light("panel", (0.0, 1.4, -1.99), (0, 0, 1), (1, 0, 0), w, h, color, L)
        obj.visible_camera = seen
        c.lights = [{"type": "area", "position": [0.0, 1.4, -1.99], "normal": [0, 0, 1], "size": [w, h],
                     "intensity": units.area_light_radiance(color, P, w * h), "visible_to_camera": seen}]
        results.append(c.run("AREA %.1fx%.1f m in view, power %.2f W, visible_camera %s" % (w, h, P, seen)))

    c = Case("sun", a)
    ground(c)
    d = np.array([0.5, 0.7, 0.3])
    d /= np.linalg.norm(d)
    E, ang = 3.0, math.radians(2.0)
    sun = light_object("SUN", (0, 10, 0), (0, 0, 0), energy=E, angle=ang, color=color)
    sun.rotation_euler = Vector(units.to_blender(d)).to_track_quat("Z", "Y").to_euler()
    c.lights = [{"type": "sun", "direction": d.tolist(), "intensity": units.sun_irradiance(color, E),
                 "angle_deg": units.sun_angle_radius_deg(ang)}]
    results.append(c.run("SUN strength %.1f, angle %.1f deg (diameter)" % (E, math.degrees(ang))))

    c = Case("environment", a)
    ground(c)
    s = 0.8
    c.environment(ENV_FILE, s)
    results.append(c.run("world: %s x %.1f, Mapping Z %.0f deg" % (os.path.basename(ENV_FILE), s,
                                                                    units.ENV_MAPPING_Z_DEG)))

    with open(os.path.join(a["out"], "units_check.json"), "w") as f:
        json.dump({"size": [a["w"], a["h"]], "spp": int(a["spp"]), "bounces": int(a["bounces"]),
                   "mean_tolerance": MEAN_TOL, "block_tolerance": BLOCK_TOL, "results": results}, f, indent=1)
    print("UNITS  %-12s %10s %10s %8s %8s %8s %8s %10s  %s" % ("case", "cycles", "propcam", "diff", "R", "G", "B",
                                                              "worstblk", "ok"))
    for r in results:
        print("UNITS  %-12s %10.5f %10.5f %+7.2f%% %+7.2f%% %+7.2f%% %+7.2f%% %+9.2f%%  %s" % (
            r["case"], r["cycles_mean"], r["propcam_mean"], 100 * r["mean_rel_diff"], *(100 * x for x in r["rgb_rel_diff"]),
            100 * r["worst_block_rel_diff"], "ok" if r["ok"] else "FAIL"))
    sys.exit(0 if all(r["ok"] for r in results) else 3)


if __name__ == "__main__":
    bcommon.run_main(main)
