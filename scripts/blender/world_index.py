"""Writes DIR/world.json: the generator's version and arguments, the scene
list and the render-noise check (plain Python, no Blender)."""
import glob
import json
import os
import statistics
import sys

out, seed, count, size, spp, probe_spp, threads = sys.argv[1:8]
max_spp = sys.argv[8] if len(sys.argv) > 8 else spp
noise_target = sys.argv[9] if len(sys.argv) > 9 else None
scenes, checks, secs = [], [], []
for s in range(int(seed), int(seed) + int(count)):
    d = os.path.join(out, "scene_%d" % s)
    if not os.path.exists(os.path.join(d, "scene_done.json")):
        continue
    with open(os.path.join(d, "meta.json")) as f:
        m = json.load(f)
    photo = [p for p in ("photo.png", "photo.jpg") if os.path.exists(os.path.join(d, p))][0]
    scenes.append({"name": "scene_%d" % s, "seed": s, "split": m["split"], "kind": m["kind"], "indoor": m["indoor"],
                   "prop": m["prop"], "photo": photo, "view_transform": m["view_transform"],
                   "jpeg_quality": m["jpeg_quality"], "spp": m["spp"],
                   "predicted_noise_8bit": (m.get("spp_rule") or {}).get("predicted_rmse_8bit"),
                   "seconds": round(m["total_seconds"], 1)})
    secs.append(m["total_seconds"])
    if m.get("noise_check"):
        checks.append(dict(m["noise_check"], scene="scene_%d" % s))
summary = None
if checks:
    summary = {k: statistics.mean(c[k] for c in checks)
               for k in ("rmse_relative", "rmse_relative_photo_alone", "rmse_8bit")}
world = {"generator": "propcam-blender-world/1",
         "args": {"seed": int(seed), "count": int(count), "size": size, "spp": int(spp), "max_spp": int(max_spp),
                  "noise_target_8bit": None if noise_target is None else float(noise_target),
                  "probe_spp": int(probe_spp), "threads": int(threads)},
         "scenes": scenes, "complete": len(scenes),
         "indoor": sum(1 for s in scenes if s["indoor"]),
         "seconds_per_scene": {"mean": statistics.mean(secs), "max": max(secs)} if secs else None,
         "noise_check": {"scenes": checks, "mean": summary}}
tmp = os.path.join(out, ".world.json.tmp")
with open(tmp, "w") as f:
    json.dump(world, f, indent=1)
os.replace(tmp, os.path.join(out, "world.json"))  # never a half-written index
