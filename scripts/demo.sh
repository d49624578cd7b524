#!/usr/bin/env bash
# Installs what is missing, builds, and runs the appliance's main job on the
# bundled recorded frames and on two real photos: shoot, infer the scene and
# composite a prop.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)" --target propcam propcamd
mkdir -p out
# The virtual board's camera: propcamd serves the recorded raw frames
# (board/virtual/recordings, YUYV) and `propcam shoot` takes the still
# through it, by the same conversion code a live camera's frames go through.
rm -f out/propcamd.sock
./build/release/firmware/propcamd --socket out/propcamd.sock \
  --camera replay:board/virtual/recordings/living_room &
daemon=$!
trap 'kill "$daemon" 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -S out/propcamd.sock ] && break; sleep 0.1; done
./build/release/firmware/propcam shoot --daemon out/propcamd.sock -o out/shot.png
kill "$daemon"; wait "$daemon" || true
./build/release/firmware/propcam composite out/shot.png \
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
