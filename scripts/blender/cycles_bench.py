"""Renderer bench: `propcam render` against Blender Cycles on the same scenes
(geometry, materials and lights built twice by twin.py). Run by
scripts/cycles_bench.sh:

  blender -b --factory-startup --python scripts/blender/cycles_bench.py -- \
      --out DIR --propcam PATH [--size 320x240] [--threads 2]
      [--scenes box_area,small_bulb,emissive_mesh,glossy_env] [--ref-spp 4096]
      [--cycles-spp 64,256,1024] [--max-spp 4096] [--bounces 4]

Per scene: a Cycles reference (two halves of ref-spp/2 with other seeds, so
its own noise is known), timed Cycles renders at --cycles-spp and timed
propcam renders at 1, 2, 4, ... --max-spp, each image's RMSE against the
reference (linear RGB, all pixels). Reports propcam's time to reach each
Cycles render's RMSE (log-log interpolation between propcam's points), the
variance proxy RMSE^2 x spp at equal spp, and the image means (a comparison
is void unless they agree within 2%). Writes DIR/cycles_bench.json and
DIR/cycles_bench.png (or .svg without matplotlib). Exits 3 when some
scene's means differ by more than 2%."""
import json
import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True  # scripts/blender/__pycache__ is in git: leave it as it is

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import bcommon  # noqa: E402
import exrio  # noqa: E402
import propcam_cli  # noqa: E402
import twin  # noqa: E402
import units  # noqa: E402
from units_check import BLOCK_TOL, ENV_FILE, block_rel_diffs  # noqa: E402

MEAN_TOL = 0.02
CYCLES_SEED, REF_SEEDS, PROPCAM_SEED = 1, (1001, 1002), 7
WARM = [1.0, 0.85, 0.7]
ROOM_LO, ROOM_HI = (-2.0, 0.0, -2.5), (2.0, 2.7, 2.5)


def log(*msg):
    print("BENCH ", *msg, flush=True)


def args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    a = {"size": "320x240", "threads": "2", "scenes": ",".join(SCENES), "ref_spp": "4096",
         "cycles_spp": "64,256,1024", "max_spp": "4096", "bounces": "4"}
    for i in range(0, len(argv), 2):
        a[argv[i].lstrip("-").replace("-", "_")] = argv[i + 1]
    a["w"], a["h"] = (int(x) for x in a["size"].split("x"))
    for k in ("threads", "ref_spp", "max_spp", "bounces"):
        a[k] = int(a[k])
    a["scenes"] = [s for s in a["scenes"].split(",") if s]
    a["cycles_spp"] = sorted(int(s) for s in a["cycles_spp"].split(","))
    unknown = [s for s in a["scenes"] if s not in SCENES]
    if unknown:
        raise SystemExit("cycles_bench: unknown scene(s) %s (have %s)" % (unknown, list(SCENES)))
    return a


# --- scenes (our coordinates: Y up, metres) ----------------------------------
def room(t):
    """A closed 4 x 2.7 x 5 m room, two boxes, the camera looking a little down
    so that the ceiling (and its light) stays out of a 4:3 view."""
    t.box(ROOM_LO, ROOM_HI, 0.7, inward=True)
    t.box((-1.4, 0.0, -1.7), (-0.5, 0.8, -0.8), [0.7, 0.35, 0.25])
    t.box((0.3, 0.0, -1.3), (1.1, 0.45, -0.5), 0.6)
    t.camera((0.3, 1.5, 2.2), 8.0, -18.0, 70.0)


def box_area(t):
    room(t)
    c, s = (0.0, ROOM_HI[1] - 0.001, 0.0), 1.0
    t.area_light(c, (0, -1, 0), (s, s), WARM, 12.0)
    return [(c[0] + dx, c[1], c[2] + dz) for dx in (-s / 2, s / 2) for dz in (-s / 2, s / 2)]


def small_bulb(t):
    """A 1.5 cm bulb 0.4 m under the ceiling, of box_area's panel's power
    (pi L x 4 pi r^2 = pi L A), so the two images are about as bright."""
    room(t)
    c, r = (0.2, ROOM_HI[1] - 0.4, -0.3), 0.0075
    t.sphere_light(c, r, WARM, 12.0 * 1.0 / (4.0 * math.pi * r * r))
    return [c]


def emissive_mesh(t):
    """The room lit only by emissive meshes, no lamp objects: an opal globe (a
    smooth 48 x 24 UV sphere of radius 7 cm, 2208 triangles) at 1.0 m near the
    left wall, out of view, and a 60 cm tube (radius 1.25 cm, 24 flat sides,
    capped: 92 triangles) 2.3 m up on the wall behind the camera. Together 1.5
    times box_area's panel's power (pi L x area), for about box_area's image
    mean; the globe has three quarters of it. Cycles samples the triangles as
    lights; propcam meets them by BSDF sampling only (render/README.md)."""
    room(t)
    g, r, n, rings = (-1.6, 1.0, 0.8), 0.07, 48, 24
    a, b, rt, nt = (-0.2, 2.3, 2.42), (0.4, 2.3, 2.42), 0.0125, 24
    area_g = 4.0 * math.pi * units.uv_sphere_effective_radius(r, n, rings) ** 2
    area_t = 2.0 * nt * rt * math.sin(math.pi / nt) * (math.dist(a, b) + rt * math.cos(math.pi / nt))  # sides, caps
    power = 1.5 * 12.0 * 1.0  # / pi, per unit of WARM
    t.emissive_sphere(g, r, WARM, 0.75 * power / area_g, n, rings)  # radiance 220
    t.emissive_tube(a, b, rt, WARM, 0.25 * power / area_t, nt)  # radiance 94
    return [tuple(np.add(g, r * e)) for e in np.vstack([np.eye(3), -np.eye(3)])] + [a, b]


def glossy_env(t):
    """Glossy props on a diffuse ground under courtyard.exr (max luminance 53)."""
    t.box((-20.0, -0.5, -20.0), (20.0, 0.0, 20.0), 0.5)
    t.uv_sphere((-0.75, 0.4, -0.6), 0.4, {"type": "plastic", "albedo": [0.7, 0.12, 0.08], "roughness": 0.02,
                                          "specular": 0.04})
    t.uv_sphere((0.65, 0.4, -1.1), 0.4, {"type": "metal", "albedo": [0.95, 0.93, 0.88], "roughness": 0.02})
    t.box((-0.25, 0.0, 0.2), (0.35, 0.3, 0.8), {"type": "plastic", "albedo": [0.1, 0.3, 0.6], "roughness": 0.1,
                                                "specular": 0.04})
    t.box((1.3, 0.0, -2.6), (2.1, 0.8, -1.8), {"type": "metal", "albedo": [1.0, 0.78, 0.34], "roughness": 0.15})
    t.camera((0.0, 1.3, 3.0), 0.0, -15.0, 60.0)
    t.environment(ENV_FILE, 1.0)
    return []


SCENES = {"box_area": box_area, "small_bulb": small_bulb, "emissive_mesh": emissive_mesh,
          "glossy_env": glossy_env}


# --- Cycles --------------------------------------------------------------------
def match_propcam(bounces):
    """Cycles estimating propcam's integral: same bounce limit, caustics on
    (propcam traces diffuse -> glossy -> light paths), no clamps, denoising,
    adaptive sampling or glossy filter (bcommon.reset_scene), box pixel filter
    (cycles_render), no passes but Combined."""
    sc = bpy.context.scene
    cy = sc.cycles
    cy.max_bounces = cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = bounces
    cy.caustics_reflective = cy.caustics_refractive = True
    if hasattr(cy, "use_light_tree"):  # Cycles 3.5+
        cy.use_light_tree = False
    vl = sc.view_layers[0]
    # bcommon's emitter AOV stays (this Blender cannot remove it from Python); no material writes it
    vl.use_pass_z = vl.use_pass_normal = vl.use_pass_diffuse_color = vl.use_pass_object_index = False
    return {k: getattr(cy, k) for k in ("max_bounces", "caustics_reflective", "caustics_refractive",
                                        "sample_clamp_direct", "sample_clamp_indirect", "blur_glossy",
                                        "use_adaptive_sampling", "use_denoising", "light_sampling_threshold",
                                        "sampling_pattern")}


_CLOCK = {"t0": 0.0, "seconds": 0.0}


@bpy.app.handlers.persistent  # kept when reset_scene reloads the factory settings
def _render_pre(*_):
    _CLOCK["t0"] = time.perf_counter()


@bpy.app.handlers.persistent
def _render_post(*_):
    _CLOCK["seconds"] = time.perf_counter() - _CLOCK["t0"]


def start_render_clock():
    """Seconds between Blender's render_pre and render_post handlers: the
    render (with persistent data the scene is synced once), not the EXR write."""
    bpy.app.handlers.render_pre.append(_render_pre)
    bpy.app.handlers.render_post.append(_render_post)


def cycles_render(spp, seed, bounces):
    """(image, render seconds, wall seconds incl. writing and reading the EXR)."""
    t0 = time.perf_counter()
    out, _ = bcommon.render_layers(spp, seed, (), filter_px=1.0, max_bounces=bounces)
    return out["combined"], _CLOCK["seconds"], time.perf_counter() - t0


def cycles_reference(spp, bounces):
    """Mean of two halves with their own seeds; its RMSE from their difference
    (the mean of two independent halves has a quarter of their squared difference)."""
    a, ta, _ = cycles_render(spp // 2, REF_SEEDS[0], bounces)
    b, tb, _ = cycles_render(spp // 2, REF_SEEDS[1], bounces)
    return (a + b) / 2, float(np.sqrt(np.mean((a - b) ** 2)) / 2), ta + tb


# --- errors --------------------------------------------------------------------
def rmse(img, ref):
    return float(np.sqrt(np.mean((img.astype(np.float64) - ref) ** 2)))


def interp_loglog(x0, y0, x1, y1, y):
    """x at y on the straight line through (x0, y0), (x1, y1) in log-log."""
    if y0 == y1:
        return x1
    f = (math.log(y) - math.log(y0)) / (math.log(y1) - math.log(y0))
    return math.exp(math.log(x0) + f * (math.log(x1) - math.log(x0)))


def reach(points, target, key):
    """`key` (seconds, wall_s, spp) where the points (by spp) first reach RMSE
    `target`, interpolated between the two that bracket it; None if never."""
    for i, p in enumerate(points):
        if p["rmse"] <= target:
            if i == 0:
                return p[key]  # reached by the first point already (an upper bound)
            q = points[i - 1]
            return interp_loglog(q[key], q["rmse"], p[key], p["rmse"], target)
    return None


def image_stats(img):
    lum = units.luminance(img)
    return {"mean": float(lum.mean()), "mean_rgb": img.reshape(-1, 3).mean(0).tolist()}


# --- one scene -------------------------------------------------------------------
def propcam_sweep(a, scene_json, folder, ref):
    points, last = [], None
    out = os.path.join(folder, "propcam_tmp.exr")
    spp = 1
    while spp <= a["max_spp"]:
        s = propcam_cli.render(a["propcam"], scene_json, out, spp, a["bounces"], PROPCAM_SEED, a["threads"])
        last = twin.load_image_linear(out)
        points.append({"spp": spp, "seconds": s["seconds"], "wall_s": s["wall_s"], "rmse": rmse(last, ref),
                       "rays_per_s": s.get("rays_per_s"), **image_stats(last)})
        log("  propcam %5d spp  %8.3f s (wall %7.3f)  RMSE %.5f" % (spp, s["seconds"], s["wall_s"],
                                                                     points[-1]["rmse"]))
        spp *= 2
    os.replace(out, os.path.join(folder, "propcam_%d.exr" % points[-1]["spp"]))
    return points, last


def cycles_sweep(a, ref):
    points, last = [], None
    for spp in a["cycles_spp"]:
        last, secs, wall = cycles_render(spp, CYCLES_SEED, a["bounces"])
        points.append({"spp": spp, "seconds": secs, "wall_s": wall, "rmse": rmse(last, ref), **image_stats(last)})
        log("  cycles  %5d spp  %8.3f s (wall %7.3f)  RMSE %.5f" % (spp, secs, wall, points[-1]["rmse"]))
    return points, last


def matches(cyc, ours):
    """propcam's cost to reach each Cycles render's RMSE."""
    rows = []
    for c in cyc:
        t, w, s = (reach(ours, c["rmse"], k) for k in ("seconds", "wall_s", "spp"))
        rows.append({"cycles_spp": c["spp"], "cycles_s": c["seconds"], "cycles_wall_s": c["wall_s"],
                     "rmse": c["rmse"], "propcam_s": t, "propcam_wall_s": w, "propcam_spp": s,
                     "ratio": t / c["seconds"] if t is not None else None,
                     "ratio_wall": w / c["wall_s"] if w is not None else None})
    return rows


def variance_proxy(cyc, ours, ref_noise):
    """RMSE^2 x spp at equal spp (raw, and without the reference's own noise)."""
    by_spp = {p["spp"]: p for p in ours}
    rows = []
    for c in cyc:
        o = by_spp.get(c["spp"])
        row = {"spp": c["spp"], "cycles": c["rmse"] ** 2 * c["spp"],
               "cycles_corrected": max(c["rmse"] ** 2 - ref_noise ** 2, 0.0) * c["spp"]}
        if o:
            row["propcam"] = o["rmse"] ** 2 * o["spp"]
            row["propcam_corrected"] = max(o["rmse"] ** 2 - ref_noise ** 2, 0.0) * o["spp"]
        rows.append(row)
    return rows


def bench_scene(name, a, settings_out):
    folder = os.path.join(a["out"], name)
    t = twin.TwinScene(folder, a["w"], a["h"], a["threads"])
    hidden = SCENES[name](t)
    settings_out.update(match_propcam(a["bounces"]))
    scene_json = t.write_scene_json()
    # lights seen directly: scripted Blender lights start hidden from the camera, ours do not
    warnings = ["light point %s is in view (use a 4:3 size)" % (p,) for p in hidden if t.in_view(p)]
    log("scene %s" % name)
    cycles_render(1, CYCLES_SEED, a["bounces"])  # warm-up: scene sync, BVH, kernels
    ref, ref_noise, ref_s = cycles_reference(a["ref_spp"], a["bounces"])
    exrio.write_exr(os.path.join(folder, "cycles_reference.exr"), ref)
    log("  reference %d spp  %.1f s  own RMSE %.5f" % (a["ref_spp"], ref_s, ref_noise))
    cyc, cyc_img = cycles_sweep(a, ref)
    ours, ours_img = propcam_sweep(a, scene_json, folder, ref)
    for img, fn in ((ref, "cycles_reference.png"), (cyc_img, "cycles_%d.png" % cyc[-1]["spp"]),
                    (ours_img, "propcam_%d.png" % ours[-1]["spp"])):
        bcommon.save_display_image(img, os.path.join(folder, fn), "Standard")
    ref_stats, o = image_stats(ref), ours[-1]
    rel = o["mean"] / ref_stats["mean"] - 1.0
    blocks = block_rel_diffs(units.luminance(ref), units.luminance(ours_img))
    worst = max(blocks, key=abs)
    if abs(rel) > MEAN_TOL:
        warnings.append("image means differ by %+.2f%% (propcam %d spp vs the Cycles reference): "
                        "the comparison is void" % (100 * rel, o["spp"]))
    if abs(worst) > BLOCK_TOL:
        warnings.append("a 4x4 block mean differs by %+.2f%% (noise, or a local mismatch)" % (100 * worst))
    return {"scene": name, "reference": {"spp": a["ref_spp"], "seconds": ref_s, "rmse_own": ref_noise, **ref_stats},
            "cycles": cyc, "propcam": ours, "matches": matches(cyc, ours),
            "variance_proxy": variance_proxy(cyc, ours, ref_noise),
            "means": {"cycles_reference": ref_stats["mean"], "propcam": o["mean"], "propcam_spp": o["spp"],
                      "rel_diff": rel, "rel_diff_rgb": (np.asarray(o["mean_rgb"]) /
                                                        np.asarray(ref_stats["mean_rgb"]) - 1).tolist(),
                      "worst_block_rel_diff": worst, "blocks_rel_diff": blocks,
                      "cycles_largest_vs_reference": cyc[-1]["mean"] / ref_stats["mean"] - 1.0},
            "warnings": warnings}


# --- report ----------------------------------------------------------------------
def fmt(x, f="%.3f", none="not reached"):
    return none if x is None else f % x


def print_scene(r):
    ref, m = r["reference"], r["means"]
    log("")
    log("%s: reference %d spp (%.1f s), its own RMSE %.5f, mean %.4f" % (r["scene"], ref["spp"], ref["seconds"],
                                                                       ref["rmse_own"], ref["mean"]))
    log("  means: propcam %d spp %.4f vs Cycles reference %.4f: %+.2f%% (R %+.2f%% G %+.2f%% B %+.2f%%), "
        "worst 4x4 block %+.2f%%; Cycles %d spp vs reference %+.2f%%" % (
            m["propcam_spp"], m["propcam"], m["cycles_reference"], 100 * m["rel_diff"],
            *(100 * x for x in m["rel_diff_rgb"]), 100 * m["worst_block_rel_diff"], r["cycles"][-1]["spp"],
            100 * m["cycles_largest_vs_reference"]))
    log("  %-10s %9s %9s | %12s %10s %8s | %9s %9s" % ("cycles spp", "cycles s", "RMSE", "propcam s", "wall s",
                                                     "at spp", "ratio", "ratio wall"))
    for x in r["matches"]:
        log("  %-10d %9.3f %9.5f | %12s %10s %8s | %9s %9s" % (
            x["cycles_spp"], x["cycles_s"], x["rmse"], fmt(x["propcam_s"]), fmt(x["propcam_wall_s"], none="-"),
            fmt(x["propcam_spp"], "%.0f", "-"), fmt(x["ratio"], "%.2fx", "-"), fmt(x["ratio_wall"], "%.2fx", "-")))
    log("  RMSE^2 x spp at equal spp (in brackets: without the reference's own noise):")
    for v in r["variance_proxy"]:
        ours = "propcam %.3g (%.3g)  ratio %.2f" % (v["propcam"], v["propcam_corrected"], v["propcam"] / v["cycles"]) \
            if "propcam" in v else "propcam -"
        log("    %5d spp: Cycles %.3g (%.3g)  %s" % (v["spp"], v["cycles"], v["cycles_corrected"], ours))
    for w in r["warnings"]:
        log("  WARNING: " + w)


def write_plot(results, base):
    """RMSE vs render seconds, log-log, a panel per scene: PNG by matplotlib
    when Blender's Python has it, else a hand-written SVG."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return write_svg(results, base + ".svg")
    fig, axes = plt.subplots(1, len(results), figsize=(4.2 * len(results), 3.8), squeeze=False)
    for ax, r in zip(axes[0], results):
        for key, style in (("cycles", "o-"), ("propcam", "s-")):
            pts = r[key]
            ax.loglog([p["seconds"] for p in pts], [p["rmse"] for p in pts], style, ms=4,
                      label="Cycles" if key == "cycles" else "propcam")
            for p in pts:
                ax.annotate(str(p["spp"]), (p["seconds"], p["rmse"]), fontsize=6, xytext=(2, 2),
                            textcoords="offset points")
        ax.axhline(r["reference"]["rmse_own"], ls=":", c="grey", label="reference's own RMSE")
        ax.set_title(r["scene"])
        ax.set_xlabel("render seconds")
        ax.set_ylabel("RMSE vs Cycles reference")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(base + ".png", dpi=110)
    plt.close(fig)
    return base + ".png"


def write_svg(results, path):
    pw, ph, m = 360, 300, 50
    series = (("cycles", "#1f77b4", "Cycles"), ("propcam", "#d62728", "propcam"))
    parts = ['<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" font-family="sans-serif" '
             'font-size="11">' % (pw * len(results), ph)]
    for k, r in enumerate(results):
        pts = [p for key, _, _ in series for p in r[key]]
        xs = [math.log10(p["seconds"]) for p in pts]
        ys = [math.log10(p["rmse"]) for p in pts] + [math.log10(r["reference"]["rmse_own"])]
        x0, x1 = math.floor(min(xs)), math.ceil(max(xs))
        y0, y1 = math.floor(min(ys)), math.ceil(max(ys))
        x1, y1 = max(x1, x0 + 1), max(y1, y0 + 1)

        def px(x, y, k=k, x0=x0, x1=x1, y0=y0, y1=y1):
            return (k * pw + m + (x - x0) / (x1 - x0) * (pw - 1.5 * m),
                    ph - m - (y - y0) / (y1 - y0) * (ph - 1.7 * m))
        parts += _svg_axes(px, x0, x1, y0, y1, r["scene"])
        for j, (key, colour, label) in enumerate(series):
            xy = [px(math.log10(p["seconds"]), math.log10(p["rmse"])) for p in r[key]]
            parts.append('<polyline fill="none" stroke="%s" points="%s"/>' % (
                colour, " ".join("%.1f,%.1f" % q for q in xy)))
            parts += ['<circle cx="%.1f" cy="%.1f" r="2.5" fill="%s"/>' % (q[0], q[1], colour) for q in xy]
            parts.append('<text x="%.1f" y="%d" fill="%s">%s</text>' % (k * pw + pw - 150, 52 + 14 * j, colour, label))
        yr = px(x0, math.log10(r["reference"]["rmse_own"]))[1]
        parts.append('<line x1="%.1f" x2="%.1f" y1="%.1f" y2="%.1f" stroke="grey" stroke-dasharray="3,3"/>' % (
            px(x0, 0)[0], px(x1, 0)[0], yr, yr))
        parts.append('<text x="%.1f" y="80" fill="grey">- - reference\'s own RMSE</text>' % (k * pw + pw - 150))
    parts.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(parts))
    return path


def _svg_axes(px, x0, x1, y0, y1, title):
    (ax0, ay0), (ax1, ay1) = px(x0, y0), px(x1, y1)
    out = ['<rect x="%.1f" y="%.1f" width="%.1f" height="%.1f" fill="none" stroke="black"/>' % (
        ax0, ay1, ax1 - ax0, ay0 - ay1),
        '<text x="%.1f" y="20" text-anchor="middle">%s</text>' % ((ax0 + ax1) / 2, title),
        '<text x="%.1f" y="%.1f" text-anchor="middle">render seconds</text>' % ((ax0 + ax1) / 2, ay0 + 32)]
    for e in range(x0, x1 + 1):
        x = px(e, y0)[0]
        out.append('<text x="%.1f" y="%.1f" text-anchor="middle">1e%d</text>' % (x, ay0 + 14, e))
    for e in range(y0, y1 + 1):
        y = px(x0, e)[1]
        out.append('<line x1="%.1f" x2="%.1f" y1="%.1f" y2="%.1f" stroke="#ddd"/>' % (ax0, ax1, y, y))
        out.append('<text x="%.1f" y="%.1f" text-anchor="end">1e%d</text>' % (ax0 - 4, y + 4, e))
    return out


def main():
    a = args()
    os.makedirs(a["out"], exist_ok=True)
    dropped = [s for s in a["cycles_spp"] if s >= a["ref_spp"]]
    a["cycles_spp"] = [s for s in a["cycles_spp"] if s < a["ref_spp"]]
    if dropped or not a["cycles_spp"]:
        log("note: Cycles spp %s dropped (not below --ref-spp %d)" % (dropped, a["ref_spp"]))
    if not a["cycles_spp"]:
        raise SystemExit("cycles_bench: no Cycles spp below --ref-spp")
    log("Blender %s, %dx%d, max_bounces %d in both (propcam --bounces %d), threads %d in both; "
        "propcam's sample clamp: off (--clamp 0)" % (
            bpy.app.version_string, a["w"], a["h"], a["bounces"], a["bounces"], a["threads"]))
    start_render_clock()
    cycles_settings, results = {}, []
    for name in a["scenes"]:
        results.append(bench_scene(name, a, cycles_settings))
    for r in results:
        print_scene(r)
    plot = write_plot(results, os.path.join(a["out"], "cycles_bench"))
    doc = {"size": [a["w"], a["h"]], "threads": a["threads"], "ref_spp": a["ref_spp"],
           "cycles": {"version": bpy.app.version_string, "settings": cycles_settings, "pixel_filter": "BOX 1 px",
                      "seeds": {"timed": CYCLES_SEED, "reference_halves": list(REF_SEEDS)}},
           "propcam": {"binary": a["propcam"], "bounces": a["bounces"], "threads": a["threads"],
                       "seed": PROPCAM_SEED, "sample_clamp": "off", "max_spp": a["max_spp"]},
           "mean_tolerance": MEAN_TOL, "plot": os.path.basename(plot), "scenes": results}
    with open(os.path.join(a["out"], "cycles_bench.json"), "w") as f:
        json.dump(doc, f, indent=1)
    log("")
    log("plot: %s" % plot)
    sys.exit(3 if any(abs(r["means"]["rel_diff"]) > MEAN_TOL for r in results) else 0)


if __name__ == "__main__":
    bcommon.run_main(main)
