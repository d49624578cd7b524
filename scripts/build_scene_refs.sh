#!/usr/bin/env bash
# Regenerates the scene-class references committed at inference/data/scene_refs.bin
# and the classifier trained on them (inference/data/scene_classifier.yml.gz):
# the committed depth database's rendered rooms and streets, views cut from the
# 26 CC0 HDR panoramas (Debian's blender-data, installed by scripts/setup.sh, and
# npm's @pmndrs/assets, fetched by scripts/fetch_pmndrs_hdri.sh), and the photos
# of the Blender world's tune split (never its held split), each with its mirror
# image. The Blender world must exist (scripts/make_blender_world.sh --out DIR;
# BLENDER_WORLD=DIR, default build/worlds/blender).
# Deterministic for the same inputs: the same files give the same bytes.
set -euo pipefail
cd "$(dirname "$0")/.."
world="${BLENDER_WORLD:-build/worlds/blender}"
[[ -f "$world/world.json" ]] || {
  echo "build_scene_refs: no Blender world in $world (scripts/make_blender_world.sh --out $world)" >&2
  exit 1
}
bash scripts/fetch_pmndrs_hdri.sh >/dev/null
cmake --preset release >/dev/null
cmake --build --preset release --target propcam -j2
build/release/firmware/propcam build-scene-refs -o inference/data/scene_refs.bin --db inference/data/depth_db.bin \
  --classifier inference/data/scene_classifier.yml.gz \
  --blender-world "$world" "$@"
