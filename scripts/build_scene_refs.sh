#!/usr/bin/env bash
# Regenerates the k-NN scene-class references committed at inference/data/scene_refs.bin:
# the committed depth database's rendered rooms and streets plus views cut from
# the CC0 panoramas of Debian's blender-data (scripts/setup.sh installs it).
# Deterministic: the same inputs give the same bytes.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --preset release >/dev/null
cmake --build --preset release --target propcam -j2
build/release/firmware/propcam build-scene-refs -o inference/data/scene_refs.bin --db inference/data/depth_db.bin "$@"
