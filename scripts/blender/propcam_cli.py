"""`propcam render` as the Blender scripts call it. No Blender import."""
import json
import subprocess
import time


def render(propcam, scene, out, spp, cycles_bounces, seed, threads, time_budget=None):
    """Runs `propcam render --json` with --bounces as Cycles' max_bounces
    (0 = direct light only), --threads `threads` and --clamp 0 (no per-sample
    clamp: Cycles' clamps are off too); returns its summary plus `wall_s` (the
    whole process: loading, BVH build, rendering, writing) and `command`."""
    cmd = [propcam, "render", scene, "-o", out, "--json", "--seed", str(seed),
           "--bounces", str(cycles_bounces), "--threads", str(threads), "--clamp", "0"]
    cmd += ["--time", str(time_budget)] if time_budget else ["--spp", str(spp)]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError("%s failed (exit %d): %s" % (" ".join(cmd), r.returncode, r.stderr.strip()[-2000:]))
    summary = json.loads(r.stdout[r.stdout.index("{"):])
    summary["wall_s"] = wall
    summary["command"] = cmd
    return summary
