#!/usr/bin/env bash
# Retrains the visible-light classifier committed at
# inference/data/light_classifier.yml.gz from views of CC0 HDR panoramas
# (the eight Debian's blender-data installs and the eighteen of the npm
# package @pmndrs/assets, fetched and decoded by scripts/fetch_pmndrs_hdri.sh,
# never committed) and the photos of the Blender world's tune split with their
# true emitters (never its held split). The Blender world must exist
# (scripts/make_blender_world.sh --out DIR; BLENDER_WORLD=DIR, default
# build/worlds/blender). Deterministic: the same file each run.
set -euo pipefail
cd "$(dirname "$0")/.."
world="${BLENDER_WORLD:-build/worlds/blender}"
[[ -f "$world/world.json" ]] || {
  echo "train_light_classifier: no Blender world in $world (scripts/make_blender_world.sh --out $world)" >&2
  exit 1
}
cmake --preset release >/dev/null
cmake --build --preset release --target propcam
extra=$(bash scripts/fetch_pmndrs_hdri.sh)
panoramas="city,courtyard,forest,interior,night,studio,sunrise,sunset"
for f in "$extra"/*.exr; do panoramas="$panoramas,$f"; done
build/release/firmware/propcam train-light-classifier -o inference/data/light_classifier.yml.gz --panoramas "$panoramas" \
  --blender-world "$world" "$@"
