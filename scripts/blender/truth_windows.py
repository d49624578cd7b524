"""A room's windows in the truth's scene.json (plain Python, no Blender).

Indoors the sky and the sun reach the room only through its windows, which
hold Cycles light portals. The truth's scene holds the room only as far as
the camera sees it, so its walls out of view are not there to stop the sky
and the sun: each portal becomes a `windows` entry and the sun and the sky
are marked `through_windows`, as the room lets them in.

    python3 scripts/blender/truth_windows.py WORLD_DIR

rewrites every WORLD_DIR/scene_*/truth/scene.json from its meta.json
(a world rendered before the truth carried its windows).
"""
import glob
import json
import os
import sys


def windows_from_portals(portals, truth_world_shift):
    """Each portal (centre in scene coordinates, horizontal inward normal,
    width along the horizontal, height along Y) as a parallelogram in the
    truth's world: corner, edge_u, edge_v."""
    out = []
    for p in portals:
        c = [p["center"][i] + truth_world_shift[i] for i in range(3)]
        n = p["inward"]
        w, h = p["size_m"]
        # the horizontal tangent Y x inward, unit (inward is horizontal)
        t = [n[2], 0.0, -n[0]]
        tn = (t[0] ** 2 + t[2] ** 2) ** 0.5
        t = [x / tn for x in t]
        edge_u = [t[i] * w for i in range(3)]
        edge_v = [0.0, h, 0.0]
        corner = [c[i] - 0.5 * edge_u[i] - 0.5 * edge_v[i] for i in range(3)]
        out.append({"corner": corner, "edge_u": edge_u, "edge_v": edge_v})
    return out


def add_windows(scene_json, meta):
    """Indoors with portals: the windows, and the sun and sky through them."""
    portals = meta.get("portals") or []
    if not meta.get("indoor") or not portals:
        scene_json.pop("windows", None)
        return scene_json
    scene_json["windows"] = windows_from_portals(portals, meta["truth_world_shift"])
    for light in scene_json["lights"]:
        if light["type"] in ("sun", "ibl"):
            light["through_windows"] = True
    return scene_json


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: truth_windows.py WORLD_DIR")
    changed = 0
    for d in sorted(glob.glob(os.path.join(sys.argv[1], "scene_*"))):
        path = os.path.join(d, "truth", "scene.json")
        if not os.path.exists(path) or not os.path.exists(os.path.join(d, "meta.json")):
            continue
        with open(os.path.join(d, "meta.json")) as f:
            meta = json.load(f)
        with open(path) as f:
            scene_json = json.load(f)
        add_windows(scene_json, meta)
        tmp = path + ".tmp"
        with open(tmp, "w") as f:
            json.dump(scene_json, f, indent=1)
        os.replace(tmp, path)
        changed += "windows" in scene_json
    print("truth_windows: %d scenes with windows" % changed)


if __name__ == "__main__":
    main()
