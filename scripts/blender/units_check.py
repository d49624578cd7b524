"""Units check: the same simple diffuse scenes rendered by Blender Cycles and
by `propcam render`, lights converted by units.py (what the world generator
uses). Run by scripts/blender_units_check.sh:

  blender -b --factory-startup --python scripts/blender/units_check.py -- \
      --out DIR --propcam PATH [--size 96x72] [--spp 256] [--bounces 4] [--threads 2]

Cases: area_light (Blender AREA light), area_mesh (emissive quad), point_light
(Blender POINT light with soft radius), point_mesh (emissive UV sphere), sun
(Blender SUN), environment (equirectangular EXR world). Prints a table of
image means and the worst of 4x4 block means (a block's difference relative
to its Cycles mean, or to the image mean where the block is darker); exits 1 when an image mean
differs by more than 2% (or a block mean by more than 5%)."""
import json
import math
import os
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import bcommon  # noqa: E402
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


def write_obj(path, verts, faces):
    with open(path, "w") as f:
        for v in verts:
            f.write("v %.6f %.6f %.6f\n" % tuple(v))
        for fc in faces:
            f.write("f " + " ".join(str(i + 1) for i in fc) + "\n")


class Case:
    """Geometry kept twice: Blender objects and OBJ files for SCENE.json."""

    def __init__(self, name, a):
        self.name, self.a = name, a
        self.dir = os.path.join(a["out"], name)
        os.makedirs(self.dir, exist_ok=True)
        bcommon.reset_scene(a["w"], a["h"], int(a["threads"]))
        self.meshes, self.lights, self.n = [], [], 0

    def box(self, lo, hi, albedo, inward=False):
        x0, y0, z0 = lo
        x1, y1, z1 = hi
        v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1),
             (x0, y1, z1)]
        f = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (3, 7, 6, 2), (0, 4, 7, 3), (1, 2, 6, 5)]
        if inward:
            f = [tuple(reversed(q)) for q in f]
        tris = [t for q in f for t in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))]
        self.n += 1
        fn = "mesh_%d.obj" % self.n
        write_obj(os.path.join(self.dir, fn), v, tris)
        self.meshes.append({"file": fn, "material": {"type": "diffuse", "albedo": albedo}})
        bcommon.mesh_object("m%d" % self.n, v, f, bcommon.diffuse_material("d%d" % self.n, [albedo] * 3))

    def camera(self, center, yaw, pitch, fov_deg):
        w, h = self.a["w"], self.a["h"]
        f = (w / 2) / math.tan(math.radians(fov_deg) / 2)
        self.R = units.camera_rotation(yaw, pitch, 0.0)
        self.K = {"fx": f, "fy": f, "cx": (w - 1) / 2, "cy": (h - 1) / 2}
        self.center = center
        bcommon.set_camera(self.R, center, f, w, h)

    def run(self, blender_desc):
        a = self.a
        cy = bpy.context.scene.cycles
        B = int(a["bounces"])
        cy.max_bounces = cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = B
        out, secs = bcommon.render_layers(int(a["spp"]), 1, (), max_bounces=B)
        cyc = out["combined"]
        scene = {"camera": {"K": self.K, "R_world_from_cam": np.asarray(self.R).tolist(), "center": list(self.center),
                            "width": a["w"], "height": a["h"]},
                 "meshes": self.meshes, "lights": self.lights}
        with open(os.path.join(self.dir, "scene.json"), "w") as f:
            json.dump(scene, f, indent=1)
        ours_path = os.path.join(self.dir, "propcam.exr")
        # Cycles max_bounces B (B = 0: direct light only) is our --bounces B + 1
        cmd = [a["propcam"], "render", os.path.join(self.dir, "scene.json"), "--spp", a["spp"], "--bounces",
               str(B + 1), "-o", ours_path]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        img = bpy.data.images.load(ours_path)
        px = np.empty(img.size[0] * img.size[1] * 4, np.float32)
        img.pixels.foreach_get(px)
        ours = px.reshape(img.size[1], img.size[0], 4)[::-1, :, :3]
        bcommon.save_display_image(cyc, os.path.join(self.dir, "cycles.png"), "Standard")
        bcommon.save_display_image(ours, os.path.join(self.dir, "propcam.png"), "Standard")
        lc, lo = units.luminance(cyc), units.luminance(ours)
        mean_c, mean_o = cyc.reshape(-1, 3).mean(0), ours.reshape(-1, 3).mean(0)
        rel = float(lo.mean() / lc.mean() - 1)
        rel_rgb = (mean_o / np.maximum(mean_c, 1e-12) - 1).tolist()
        hh, ww = lc.shape
        blocks = []
        for by in range(4):
            for bx in range(4):
                sl = (slice(by * hh // 4, (by + 1) * hh // 4), slice(bx * ww // 4, (bx + 1) * ww // 4))
                # relative to the block's mean, or to the image's where the block is darker (black sky)
                blocks.append(float((lo[sl].mean() - lc[sl].mean()) / max(lc[sl].mean(), lc.mean())))
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

    c = Case("sun", a)
    ground(c)
    d = np.array([0.5, 0.7, 0.3])
    d /= np.linalg.norm(d)
    E, ang = 3.0, math.radians(2.0)
    from mathutils import Vector
    sun = light_object("SUN", (0, 10, 0), (0, 0, 0), energy=E, angle=ang, color=color)
    sun.rotation_euler = Vector(units.to_blender(d)).to_track_quat("Z", "Y").to_euler()
    c.lights = [{"type": "sun", "direction": d.tolist(), "intensity": units.sun_irradiance(color, E),
                 "angle_deg": units.sun_angle_radius_deg(ang)}]
    results.append(c.run("SUN strength %.1f, angle %.1f deg (diameter)" % (E, math.degrees(ang))))

    c = Case("environment", a)
    ground(c)
    shutil.copy(ENV_FILE, os.path.join(c.dir, "env.exr"))
    s = 0.8
    bcommon.set_world_environment(os.path.join(c.dir, "env.exr"), s)
    c.lights = [{"type": "ibl", "file": "env.exr", "intensity": s}]
    results.append(c.run("world: %s x %.1f, Mapping Z %.0f deg" % (os.path.basename(ENV_FILE), s,
                                                                    units.ENV_MAPPING_Z_DEG)))

    with open(os.path.join(a["out"], "units_check.json"), "w") as f:
        json.dump({"size": [a["w"], a["h"]], "spp": int(a["spp"]), "cycles_max_bounces": int(a["bounces"]),
                   "propcam_bounces": int(a["bounces"]) + 1, "mean_tolerance": MEAN_TOL,
                   "block_tolerance": BLOCK_TOL, "results": results}, f, indent=1)
    print("UNITS  %-12s %10s %10s %8s %8s %8s %8s %10s  %s" % ("case", "cycles", "propcam", "diff", "R", "G", "B",
                                                              "worstblk", "ok"))
    for r in results:
        print("UNITS  %-12s %10.5f %10.5f %+7.2f%% %+7.2f%% %+7.2f%% %+7.2f%% %+9.2f%%  %s" % (
            r["case"], r["cycles_mean"], r["propcam_mean"], 100 * r["mean_rel_diff"], *(100 * x for x in r["rgb_rel_diff"]),
            100 * r["worst_block_rel_diff"], "ok" if r["ok"] else "FAIL"))
    sys.exit(0 if all(r["ok"] for r in results) else 3)


if __name__ == "__main__":
    try:
        main()
    except SystemExit:
        raise
    except Exception:
        import traceback
        traceback.print_exc()
        sys.exit(1)
