#!/usr/bin/env bash
# Installs what is missing, builds, and runs the appliance's main job on the
# bundled photo: infer the scene and composite a prop. Writes out/composite.png.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)" --target propcam
mkdir -p out
./build/release/firmware/propcam composite board/virtual/photos/living_room.png \
  --prop chair --at 320,350 --spp 64 --save-scene out/living_room_scene -o out/composite.png
echo "demo: open out/composite.png (scene model in out/living_room_scene/)"
