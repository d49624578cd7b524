"""One scene of the Blender world (run by scripts/make_blender_world.sh):

  blender -b --factory-startup --python scripts/blender/world.py -- \
      --out DIR/scene_<seed> --seed S --props DIR/props [--size 320x240] [--spp 128]
      [--max-spp 256] [--noise-target 3] [--threads 2] [--probe-size 128x64] [--probe-spp 256]
      [--noise-check 0|1]

Builds a randomised indoor or outdoor scene (scenes.py), inserts one preset
prop by PropCam's placement rule, renders photo and insertion with Cycles
(same seed and samples, no adaptive sampling, same sensor-noise field; the
samples per pixel of the scene from a pilot estimate of its noise, see
choose_spp), the truth passes,
the sky and the light probe, and writes the folder described in
docs/blender_world.md. scene_done.json is written last."""
import json
import math
import os
import random
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import Matrix, Vector  # noqa: E402

import bcommon  # noqa: E402
import exrio  # noqa: E402
import scenes  # noqa: E402
import truth_windows  # noqa: E402
import units  # noqa: E402

VERSION = "propcam-blender-world/1"
PROPS = ["chair", "vase", "sphere_plinth", "mug", "table", "cube"]
SMALL_PROPS = ("mug", "vase", "cube")
SKY_DEPTH_M = 1.0e4
PROP_INDEX = 7


def parse_args(argv):
    a = {"size": "320x240", "spp": 128, "max_spp": 256, "noise_target": 3.0, "threads": 2,
         "probe_size": "128x64", "probe_spp": 256, "noise_check": 0}
    i = 0
    while i < len(argv):
        k = argv[i].lstrip("-").replace("-", "_")
        a[k] = argv[i + 1]
        i += 2
    a["seed"] = int(a["seed"])
    a["spp"] = int(a["spp"])
    a["threads"] = int(a["threads"])
    a["probe_spp"] = int(a["probe_spp"])
    a["max_spp"] = max(int(a["max_spp"]), a["spp"])
    a["noise_target"] = float(a["noise_target"])
    a["noise_check"] = int(a["noise_check"])
    a["width"], a["height"] = (int(x) for x in a["size"].split("x"))
    a["probe_w"], a["probe_h"] = (int(x) for x in a["probe_size"].split("x"))
    return a


def read_obj_vertices(path):
    v = []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                v.append([float(x) for x in line.split()[1:4]])
    return np.asarray(v)


def prop_transform(base_prop, P, cam_center, yaw_deg):
    """render/src/placement.cpp: T(P + 1 mm up) Ry(atan2(t.x, t.z) + yaw) T(-base), scale 1."""
    t = np.asarray(cam_center, float) - np.asarray(P, float)
    t[1] = 0.0
    facing = math.atan2(t[0], t[2]) if np.linalg.norm(t) > 1e-6 else 0.0
    ang = facing + math.radians(yaw_deg)
    c, s = math.cos(ang), math.sin(ang)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    M = np.eye(4)
    M[:3, :3] = R
    base_world = np.asarray(P, float) + np.array([0, 1e-3, 0])
    M[:3, 3] = base_world - R @ np.asarray(base_prop, float)
    return M, base_world


def ray_hit_distance(origin_ours, target_ours):
    dg = bpy.context.evaluated_depsgraph_get()
    o = np.asarray(origin_ours, float)
    d = np.asarray(target_ours, float) - o
    dist = float(np.linalg.norm(d))
    hit, loc, *_ = bpy.context.scene.ray_cast(dg, Vector(units.to_blender(o)), Vector(units.to_blender(d / dist)),
                                              distance=dist + 1.0)
    return (np.linalg.norm(np.asarray(units.from_blender(loc)) - o) if hit else math.inf), dist


def choose_camera(sc, rnd, W, H):
    cx, cz = sc.camera_xz
    top = min(2.0, sc.choices.get("height_m", 9) - 0.35) if sc.indoor else 2.0
    h = rnd.uniform(1.0, top)
    yaw = sc.heading + rnd.uniform(-25, 25)
    pitch = rnd.uniform(-30, 10)
    roll = rnd.uniform(-5, 5)
    f = rnd.uniform(0.6, 1.6) * W
    return {"center": [cx, h, cz], "yaw_deg": yaw, "pitch_deg": pitch, "roll_deg": roll, "f_px": f,
            "R": units.camera_rotation(yaw, pitch, roll)}


def choose_placement(sc, rnd, cam, K, W, H, props_dir):
    """P on a support, in view, footprint free and inside its support, base seen."""
    center = np.asarray(cam["center"])
    order = PROPS[:]
    rnd.shuffle(order)
    for prop in order:
        verts = read_obj_vertices(os.path.join(props_dir, prop + ".obj"))
        lo, hi = verts.min(0), verts.max(0)
        base = np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2])
        tables = [s for s in sc.supports if s["support"] == "table"]
        for _ in range(150):
            if prop in SMALL_PROPS and tables and rnd.random() < 0.4:
                sup = rnd.choice(tables)
            else:
                sup = rnd.choice([s for s in sc.supports if s["support"] != "table"])
            x0, x1, z0, z1 = sup["rect"]
            P = np.array([rnd.uniform(x0, x1), sup["y"], rnd.uniform(z0, z1)])
            yaw = rnd.uniform(-180, 180)
            horiz = math.hypot(P[0] - center[0], P[2] - center[2])
            if horiz < 1.0 + (hi[2] - lo[2]) or horiz > (7.0 if sc.indoor else 8.0):
                continue
            u, v, z = units.project(K, cam["R"], center, P)
            if z < 0.5 or not (0.1 * W < u < 0.9 * W and 0.3 * H < v < 0.95 * H):
                continue
            M, base_world = prop_transform(base, P, center, yaw)
            wv = verts @ M[:3, :3].T + M[:3, 3]
            wlo, whi = wv.min(0), wv.max(0)
            if not (wlo[0] >= x0 - 0.02 and whi[0] <= x1 + 0.02 and wlo[2] >= z0 - 0.02 and whi[2] <= z1 + 0.02):
                continue
            if not scenes._free(sc, tuple(wlo), tuple(whi), [], margin=0.04):
                continue
            if sup["support"] == "floor" and not scenes._inside_cells(sc, wlo[0], whi[0], wlo[2], whi[2]):
                continue
            pc = (wv - center) @ cam["R"]
            if np.any(pc[:, 2] < 0.2):
                continue
            us = K["fx"] * pc[:, 0] / pc[:, 2] + K["cx"]
            vs = K["fy"] * pc[:, 1] / pc[:, 2] + K["cy"]
            if us.min() < 2 or us.max() > W - 3 or vs.min() < 2 or vs.max() > H - 3:
                continue
            if vs.max() - vs.min() < 0.08 * H:  # big enough to judge
                continue
            # the base is seen: rays to the base centre and to two points beside it
            side = np.cross([0, 1, 0], (center - P) / np.linalg.norm(center - P))
            ok = True
            for off in (0.0, 0.3, -0.3):
                q = P + np.array([0, 0.01, 0]) + side * off * (whi[0] - wlo[0])
                hit, dist = ray_hit_distance(center, q)
                if hit < dist - 0.03:
                    ok = False
                    break
            if not ok:
                continue
            return {"prop": prop, "P": P, "u": float(u), "v": float(v), "yaw": yaw, "M": M, "base_world": base_world,
                    "support": sup["support"], "support_y": sup["y"], "natural_height": float(hi[1] - lo[1]),
                    "base_prop": base}
    return None


def import_prop(props_dir, prop, M):
    with open(os.path.join(props_dir, prop + ".materials.json")) as f:
        mats = json.load(f)
    before = set(bpy.data.objects)
    bpy.ops.wm.obj_import(filepath=os.path.join(props_dir, prop + ".obj"), forward_axis="NEGATIVE_Z", up_axis="Y")
    objs = [o for o in bpy.data.objects if o not in before]
    MB = Matrix(units.matrix_to_blender(M).tolist())
    summary = {}
    for o in objs:
        o.data.transform(o.matrix_world)
        o.matrix_world = MB
        o.pass_index = PROP_INDEX
        for slot in o.material_slots:
            if slot.material is None:
                continue
            key = slot.material.name
            base = key if key in mats else key.rsplit(".", 1)[0]
            if base not in mats:
                raise RuntimeError("prop %s: material %s is not in %s.materials.json" % (prop, key, prop))
            slot.material = bcommon.prop_material("prop_" + base, mats[base])
            summary[base] = mats[base]
        if not o.material_slots:
            raise RuntimeError("prop %s has no material" % prop)
    return objs, summary


def hide(objs, hidden):
    for o in objs:
        o.hide_render = hidden


def sky_scale(sc, a, threads):
    """Renders the world alone as our panorama, scales the sky to the scene's
    target (irradiance on a horizontal surface = pi x target) and sets the sun."""
    objs = [o for o in bpy.data.objects if o.type == "MESH"]
    hide(objs, True)
    cam = bcommon.set_pano_camera([0, 0, 0], "sky_camera")
    out, secs = bcommon.render_layers(16, 1, (), camera=cam, resolution=(256, 128))
    hide(objs, False)
    pano = units.pano_to_ours(out["combined"])
    h, w = pano.shape[:2]
    th = (np.arange(h) + 0.5) / h * math.pi
    om = units.texel_solid_angles(h, w)
    cosw = np.maximum(np.cos(th), 0)[:, None]
    E = float(np.sum(units.luminance(pano) * om * cosw))
    target = sc.choices["sky_target_radiance"]
    k = target * math.pi / max(E, 1e-9)
    sc.sky["node"].inputs["Strength"].default_value = sc.sky["node"].inputs["Strength"].default_value * k
    if sc.sky.get("type") == "cie_overcast":
        # the strength is driven by a Math node: scale it there
        for n in bpy.context.scene.world.node_tree.nodes:
            if n.bl_idname == "ShaderNodeMath" and n.operation == "MULTIPLY":
                n.inputs[1].default_value *= k
    pano = pano * k
    sc.sky.update({"blender_strength_scale": k, "horizontal_irradiance": target * math.pi})
    if sc.sun is not None:
        E_sun = sc.choices["sun_ratio"] * target * math.pi
        scenes.set_sun_strength(sc, E_sun)
    return pano.astype(np.float32), secs


PILOT_SPP = 16
NOISE_CHECK_FACTOR = 4


def srgb_slope(y):
    """d(sRGB OETF)/dy of linear y in [0, 1): 12.92 below the knee."""
    y = np.maximum(y, 1e-12)
    return np.where(y <= 0.0031308, 12.92, 1.055 / 2.4 * y ** (1.0 / 2.4 - 1.0))


def box_blur(x, r=2):
    """(2r+1)^2 box mean of an H x W x C array, edges replicated."""
    k = 2 * r + 1
    c = np.cumsum(np.cumsum(np.pad(x, ((r, r), (r, r), (0, 0)), mode="edge"), 0), 1)
    c = np.pad(c, ((1, 0), (1, 0), (0, 0)))
    return (c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]) / (k * k)


def choose_spp(pilot_a, pilot_b, a):
    """Samples per pixel for the scene's photo and insertion: the fewest (a
    multiple of 16 in [spp, max_spp]) whose predicted noise-check figure (the
    8-bit RMSE of the photo against a 4x-spp render, Standard view, the
    automatic exposure, no sensor noise) is at most noise_target. The
    prediction linearises the display transform around the pilots' mean:
    rmse_8bit(n)^2 = (1 + 1/4) (PILOT_SPP / n) mean((255 f'(m) sigma_16)^2),
    sigma_16^2 = (a - b)^2 / 2 from two pilot renders of PILOT_SPP samples
    with other seeds, f'(m) the slope of the exposed sRGB transform at their
    mean m, 5x5 box-averaged so that a firefly does not flatten or clip its
    own slope (0 where the average clips). Measured against the noise check:
    1.0-1.4x the measured figure. Deterministic: a seed always gets the same
    spp."""
    m = 0.5 * (pilot_a + pilot_b)
    lum = units.luminance(m)
    key = float(np.exp(np.mean(np.log(np.maximum(lum, 0) + 1e-3))))
    mult = 0.18 / key
    y = box_blur(m) * mult
    slope = np.where(y < 1.0, srgb_slope(y), 0.0) * mult * 255.0
    var16 = 0.5 * (pilot_a - pilot_b) ** 2
    per_sample = float(np.mean(slope ** 2 * var16)) * PILOT_SPP * (1.0 + 1.0 / NOISE_CHECK_FACTOR)
    need = per_sample / max(a["noise_target"], 1e-6) ** 2
    spp = int(min(max(16 * math.ceil(need / 16.0), a["spp"]), a["max_spp"]))
    return spp, {"pilot_spp": PILOT_SPP, "predicted_rmse_8bit_at_min": math.sqrt(per_sample / a["spp"]),
                 "predicted_rmse_8bit": math.sqrt(per_sample / spp), "spp_needed": need, "min_spp": a["spp"],
                 "max_spp": a["max_spp"], "noise_target_8bit": a["noise_target"]}


def noise_field(rnd, h, w):
    g = np.random.Generator(np.random.PCG64(rnd.getrandbits(63)))
    return g.standard_normal((h, w, 3)).astype(np.float32)


def camera_pipeline(linear, mult, noise, n01):
    x = linear * mult
    if noise is not None:
        x = x + np.sqrt(noise["shot"] * np.maximum(x, 0) + noise["read"] ** 2) * n01
    return np.maximum(x, 0).astype(np.float32)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    a = parse_args(argv)
    seed = a["seed"]
    out = a["out"]
    W, H = a["width"], a["height"]
    os.makedirs(os.path.join(out, "truth", "lights"), exist_ok=True)
    os.environ["PROPCAM_BLENDER_TMP"] = os.path.join(out, ".tmp")
    t_start = time.time()
    rnd = random.Random(seed)
    indoor = seed % 4 != 3
    bcommon.reset_scene(W, H, a["threads"])
    sc = scenes.Scene(rnd)
    (scenes.build_indoor if indoor else scenes.build_outdoor)(sc)
    bpy.context.view_layer.update()

    placement = None
    for attempt in range(12):
        cam = choose_camera(sc, rnd, W, H)
        if attempt >= 6:
            cam["pitch_deg"] = rnd.uniform(-30, -10)
            cam["R"] = units.camera_rotation(cam["yaw_deg"], cam["pitch_deg"], cam["roll_deg"])
        K = {"fx": cam["f_px"], "fy": cam["f_px"], "cx": (W - 1) / 2.0, "cy": (H - 1) / 2.0}
        placement = choose_placement(sc, rnd, cam, K, W, H, a["props"])
        if placement:
            break
    if placement is None:
        raise RuntimeError("seed %d: no placement for any prop in 12 camera tries" % seed)
    center = np.asarray(cam["center"])
    probe_point = placement["base_world"] + np.array([0, 0.05, 0])
    sun_visible = None
    if sc.sun is not None:
        d = np.asarray(sc.sun["direction"])
        hit, dist = ray_hit_distance(probe_point, probe_point + d * 500.0)
        sun_visible = bool(hit >= dist - 1e-3)

    bcommon.set_camera(cam["R"], center, cam["f_px"], W, H)
    main_cam = bpy.context.scene.camera
    timings = {}
    sky_pano = None
    if sc.sky is not None:
        sky_pano, timings["sky_s"] = sky_scale(sc, a, a["threads"])
    sc.finish_lights()  # the Cycles light objects, once the sun's strength is known
    prop_objs, prop_mats = import_prop(a["props"], placement["prop"], placement["M"])

    cycles_seed = rnd.randrange(1, 2 ** 31 - 1)
    # the scene's samples per pixel from two pilot photos (other seeds)
    hide(prop_objs, True)
    p_a, t_pa = bcommon.render_layers(PILOT_SPP, cycles_seed + 101, (), camera=main_cam, resolution=(W, H))
    p_b, t_pb = bcommon.render_layers(PILOT_SPP, cycles_seed + 202, (), camera=main_cam, resolution=(W, H))
    timings["pilot_s"] = t_pa + t_pb
    spp, spp_rule = choose_spp(p_a["combined"], p_b["combined"], a)
    print("scene %d: %d spp (pilot predicts %.2f 8-bit levels)" % (seed, spp, spp_rule["predicted_rmse_8bit"]))
    # photo (no prop) and insertion: same seed, no adaptive sampling
    r_photo, timings["photo_s"] = bcommon.render_layers(spp, cycles_seed, (), camera=main_cam, resolution=(W, H))
    hide(prop_objs, False)
    r_ins, timings["insertion_s"] = bcommon.render_layers(spp, cycles_seed, (), camera=main_cam, resolution=(W, H))
    # exact passes at pixel centres: without the prop (truth), with it (mask)
    bcommon.coats(False)
    hide(prop_objs, True)
    r_pass, timings["passes_s"] = bcommon.render_layers(1, cycles_seed, ("depth", "normal", "diffcol", "aov"),
                                                        camera=main_cam, filter_px=0.01, max_bounces=0)
    hide(prop_objs, False)
    r_idx, t_idx = bcommon.render_layers(1, cycles_seed, ("index",), camera=main_cam, filter_px=0.01, max_bounces=0)
    timings["passes_s"] += t_idx
    bcommon.coats(True)
    bpy.context.scene.cycles.max_bounces = 8
    # probe: incident radiance at the prop's base, without the prop
    hide(prop_objs, True)
    pcam = bcommon.set_pano_camera(probe_point, "probe_camera")
    r_probe, timings["probe_s"] = bcommon.render_layers(a["probe_spp"], cycles_seed, (), camera=pcam,
                                                        resolution=(a["probe_w"], a["probe_h"]))
    probe = units.pano_to_ours(r_probe["combined"]).astype(np.float32)
    if sc.sun is not None and sun_visible:
        units.add_sun_to_pano(probe, sc.sun["direction"],
                              units.sun_irradiance(sc.sun["color"], sc.sun["strength"]))
    noise_check = None
    if a["noise_check"]:
        r_ref, t_ref = bcommon.render_layers(NOISE_CHECK_FACTOR * spp, cycles_seed + 1, (), camera=main_cam,
                                             resolution=(W, H))
        noise_check = {"spp": spp, "reference_spp": NOISE_CHECK_FACTOR * spp, "reference_s": t_ref,
                       "ref": r_ref["combined"]}
    hide(prop_objs, False)

    # --- camera pipeline -------------------------------------------------------
    photo_lin = r_photo["combined"]
    ins_lin = r_ins["combined"]
    lum = units.luminance(photo_lin)
    key = float(np.exp(np.mean(np.log(np.maximum(lum, 0) + 1e-3))))
    ev_auto = math.log2(0.18 / key)
    ev_offset = rnd.uniform(-1.0, 1.0)
    ev = ev_auto + ev_offset
    mult = 2.0 ** ev
    view = rnd.choice(["Standard", "Filmic"])
    noise = None
    if rnd.random() < 0.75:
        noise = {"model": "sigma^2 = shot * x + read^2 (x linear after exposure, before the view transform)",
                 "shot": rnd.uniform(2e-4, 4e-3), "read": rnd.uniform(5e-4, 3e-3)}
    n01 = noise_field(rnd, H, W)
    jpeg_q = rnd.randint(60, 95) if rnd.random() < 0.35 else None
    ext = ".jpg" if jpeg_q else ".png"
    bcommon.save_display_image(camera_pipeline(photo_lin, mult, noise, n01), os.path.join(out, "photo" + ext), view,
                               jpeg_q)
    bcommon.save_display_image(camera_pipeline(ins_lin, mult, noise, n01), os.path.join(out, "insertion" + ext), view,
                               jpeg_q)
    exrio.write_exr(os.path.join(out, "render.exr"), photo_lin)
    exrio.write_exr(os.path.join(out, "render_insertion.exr"), ins_lin)
    exrio.write_exr(os.path.join(out, "probe.exr"), probe)

    # --- masks and truth -----------------------------------------------------------
    depth = r_pass["depth"].copy()
    miss = depth > 1e6
    depth[miss] = SKY_DEPTH_M
    albedo = r_pass["diffcol"].copy()
    albedo[miss] = 0
    normals = units.normals_from_blender(r_pass["normal"])
    nn = np.linalg.norm(normals, axis=2, keepdims=True)
    normals = np.where(nn > 1e-6, normals / np.maximum(nn, 1e-12), 0).astype(np.float32)
    normals[miss] = 0
    emit = r_pass["aov"] > 0.5
    if sc.indoor:
        emit |= miss
    bcommon.save_mask_png(emit, os.path.join(out, "emitters.png"))
    prop_mask = np.abs(r_idx["index"] - PROP_INDEX) < 0.5
    bcommon.save_mask_png(prop_mask, os.path.join(out, "prop_mask.png"))
    exrio.write_exr(os.path.join(out, "truth", "depth.exr"), depth)
    exrio.write_exr(os.path.join(out, "truth", "albedo.exr"), albedo)
    exrio.write_exr(os.path.join(out, "truth", "normals.exr"), normals)

    shift = np.array([center[0], 0.0, center[2]])  # truth world: camera at (0, h, 0)

    def sh(p):
        return (np.asarray(p, float) - shift).tolist()

    lights = []
    for l in sc.lights:
        l2 = {k: v for k, v in l.items() if not k.startswith("_")}
        l2["position"] = sh(l["position"])
        if "corner" in l2:
            l2["corner"] = sh(l["corner"])
        lights.append(l2)
    if sc.sun is not None:
        lights.append({"type": "sun", "intensity": units.sun_irradiance(sc.sun["color"], sc.sun["strength"]),
                       "direction": [float(x) for x in sc.sun["direction"]]})
    if sky_pano is not None:
        exrio.write_exr(os.path.join(out, "truth", "lights", "sky.exr"), sky_pano)
        lights.append({"type": "ibl", "intensity": [1.0, 1.0, 1.0], "file": "lights/sky.exr"})
    sy = placement["support_y"]
    scene_json = {
        "format": "propcam-scene/1", "image": {"width": W, "height": H}, "K": K,
        "R_world_from_cam": np.asarray(cam["R"]).tolist(), "camera_height_m": float(center[1]), "gamma": 2.2,
        "indoor": bool(sc.indoor), "source_photo": "photo" + ext, "lights": lights,
        "planes": [{"name": placement["support"], "normal": [0.0, 1.0, 0.0], "offset": -float(sy)}],
        "reports": []}
    truth_windows.add_windows(scene_json, {"indoor": sc.indoor, "portals": sc.portals,
                                           "truth_world_shift": (-shift).tolist()})
    with open(os.path.join(out, "truth", "scene.json"), "w") as f:
        json.dump(scene_json, f, indent=1)
    # the truth lists the photo file relative to the scene folder's parent
    place = {"prop": placement["prop"], "at": [placement["u"], placement["v"]],
             "height": placement["natural_height"], "yaw": placement["yaw"], "support": placement["support"],
             "base_world": sh(placement["base_world"])}
    with open(os.path.join(out, "placement.json"), "w") as f:
        json.dump(place, f, indent=1)

    nc = None
    if noise_check is not None:
        ref = noise_check.pop("ref")
        diff = photo_lin - ref
        rmse = float(np.sqrt(np.mean(diff ** 2)))
        m = float(np.mean(ref))
        a8 = os.path.join(out, ".tmp", "nc_a.png")
        b8 = os.path.join(out, ".tmp", "nc_b.png")
        bcommon.save_display_image(camera_pipeline(photo_lin, mult, None, n01), a8, view)
        bcommon.save_display_image(camera_pipeline(ref, mult, None, n01), b8, view)
        d8 = bcommon.load_png_8bit(a8) - bcommon.load_png_8bit(b8)
        nc = dict(noise_check, rmse_linear=rmse, mean_linear=m, rmse_relative=rmse / m,
                  rmse_relative_photo_alone=rmse / m / math.sqrt(1 + spp / noise_check["reference_spp"]),
                  rmse_8bit=float(np.sqrt(np.mean(d8 ** 2))))

    meta = {
        "generator": VERSION, "seed": seed, "split": "held" if seed % 3 == 0 else "tune", "kind": sc.kind,
        "indoor": sc.indoor, "size": [W, H], "choices": sc.choices,
        "camera": {k: (np.asarray(v).tolist() if k == "R" else v) for k, v in cam.items()},
        "camera_center_scene_coords": center.tolist(), "truth_world_shift": (-shift).tolist(),
        "lights_blender": sc.lights_blender,
        "sun": None if sc.sun is None else {k: v for k, v in sc.sun.items() if k != "object"} | {
            "blender": "SUN light: strength = irradiance, angle = disc diameter", "visible_from_probe": sun_visible},
        "sky": None if sc.sky is None else {k: v for k, v in sc.sky.items() if k != "node"},
        "surfaces": sc.surfaces,
        "view_transform": view, "exposure_ev": ev, "exposure_ev_auto": ev_auto, "exposure_ev_offset": ev_offset,
        "exposure_multiplier": mult, "exposure_rule": "2^ev multiplies the linear render before noise and view",
        "noise": noise, "jpeg_quality": jpeg_q, "spp": spp, "spp_rule": spp_rule, "probe_spp": a["probe_spp"],
        "probe_size": [a["probe_w"], a["probe_h"]], "probe_point": sh(probe_point), "cycles_seed": cycles_seed,
        "cycles": {"max_bounces": 8, "clamp": 0, "filter": "Blackman-Harris 1.5 px (passes: box 0.01 px)",
                   "adaptive_sampling": False, "denoiser": None, "caustics_reflective": False,
                   "caustics_refractive": False},
        "lamps": sc.lamps, "portals": sc.portals,
        "render_seconds": timings, "prop": placement["prop"], "prop_materials": prop_mats,
        "prop_pixels": int(prop_mask.sum()), "emitter_pixels": int(emit.sum()),
        "sky_pixels": int(miss.sum()), "noise_check": nc, "total_seconds": None}
    meta["total_seconds"] = time.time() - t_start
    with open(os.path.join(out, "meta.json"), "w") as f:
        json.dump(meta, f, indent=1)
    tmp = os.path.join(out, ".tmp")
    if os.path.isdir(tmp):
        for fn in os.listdir(tmp):
            os.remove(os.path.join(tmp, fn))
        os.rmdir(tmp)
    with open(os.path.join(out, "scene_done.json"), "w") as f:
        json.dump({"seed": seed, "seconds": meta["total_seconds"]}, f)
    print("scene %d done: %s %s, prop %s, %.1f s" % (seed, sc.kind, "indoor" if sc.indoor else "outdoor",
                                                    placement["prop"], meta["total_seconds"]))


if __name__ == "__main__":
    try:
        main()
    except Exception:
        import traceback
        traceback.print_exc()
        sys.exit(1)
