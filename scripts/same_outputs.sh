#!/usr/bin/env bash
# Fingerprints what `propcam infer` and `propcam composite` write for the
# demo's photos, so a restructuring can show its outputs are bit for bit the
# same:
#   scripts/same_outputs.sh [build dir] > before.txt
#   ... change ...
#   scripts/same_outputs.sh [build dir] > after.txt && diff before.txt after.txt
# The photos: the demo's hotel-room view of blender-data's interior.exr, its
# 1280x960 view (the working size reduces it), OpenCV's street façade and a
# synthetic room. Each line is a sha256 and the file's name in the work folder.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
propcam="$build/firmware/propcam"
work=$(mktemp -d /tmp/propcam_same_outputs.XXXXXX)
trap 'rm -rf "$work"' EXIT
exec 2>/dev/null  # progress

"$propcam" view /usr/share/blender/datafiles/studiolights/world/interior.exr \
  --yaw 135 --pitch -20 --fov 65 --size 640x480 -o "$work/hotel.png" >/dev/null
"$propcam" view /usr/share/blender/datafiles/studiolights/world/interior.exr \
  --yaw 135 --pitch -20 --fov 65 --size 1280x960 -o "$work/hotel_large.png" >/dev/null
cp /usr/share/doc/opencv-doc/examples/data/building.jpg "$work/street.jpg"
"$propcam" synth -o "$work/room" --seed 4 --size 320x240 --spp 8 >/dev/null
cp "$work/room/photo.png" "$work/room.png"

run() {  # name, prop, where, extra composite flags
  local name=$1 prop=$2 at=$3
  shift 3
  "$propcam" infer "$work/$name".* -o "$work/scene_$name" >/dev/null
  "$propcam" composite "$work/$name".* --scene "$work/scene_$name" --prop "$prop" --at "$at" \
    --spp 8 "$@" -o "$work/composite_$name.png" >/dev/null
}
run hotel sphere_plinth 400,420
run hotel_large vase 800,840
run street chair 300,560 --height 2 --yaw 30
run room cube 160,200

cd "$work"
# EXR files by their pixels (their headers carry the time they were written),
# scene.json without the timings it keeps beside the estimates and with the
# work folder's name (it keeps the paths it was written with) made neutral.
for f in $(find . -path './scene_*' -type f ! -name '*.json' | sort); do
  printf '%s  %s\n' "$(oiiotool --info --hash "$f" | sed -n 's/.*SHA-1: //p')" "$f"
done
for j in scene_*/*.json; do
  printf '%s  %s\n' "$(python3 -c 'import json,sys
def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items() if "second" not in k and "time" not in k}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v
print(json.dumps(strip(json.load(open(sys.argv[1]))), sort_keys=True).replace(sys.argv[2], "WORK"))' "$j" "$work" | sha256sum | cut -d' ' -f1)" "$j"
done
sha256sum composite_*.png
