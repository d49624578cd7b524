#!/usr/bin/env bash
# Installs what is missing, builds, and runs the appliance's main job on the
# bundled photo and on two real photos: infer the scene and composite a prop.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)" --target propcam
mkdir -p out
./build/release/firmware/propcam composite board/virtual/photos/living_room.png \
  --prop chair --at 320,350 --spp 64 --save-scene out/living_room_scene -o out/composite.png
# Real photographs: a hotel room cut from blender-data's CC0 panorama, and
# OpenCV's sample street façade (both installed from Debian by setup.sh).
./build/release/firmware/propcam view /usr/share/blender/datafiles/studiolights/world/interior.exr \
  --yaw 135 --pitch -20 --fov 65 --size 640x480 -o out/hotel_room.png
./build/release/firmware/propcam composite out/hotel_room.png \
  --prop sphere_plinth --at 400,420 --spp 64 -o out/composite_hotel_room.png
./build/release/firmware/propcam composite /usr/share/doc/opencv-doc/examples/data/building.jpg \
  --prop chair --at 300,560 --height 2 --yaw 30 --spp 32 -o out/composite_street.png
echo "demo: open out/composite.png, out/composite_hotel_room.png and out/composite_street.png"
