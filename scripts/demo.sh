#!/usr/bin/env bash
# Installs what is missing, builds, and runs the appliance on the virtual
# board (the bundled recorded frames, a scripted button session), then
# composites props into two real photos.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --demo
cmake --preset release
cmake --build --preset release -j "$(nproc)" --target propcam propcamd
mkdir -p out
# The appliance on the virtual board: propcamd serves the recorded raw
# frames (board/virtual/recordings, YUYV) as it serves a live camera, and
# `propcam run` plays the board's scripted session through the real
# debouncer, state machine, screens and export: shoot, pick the chrome
# sphere, place it, render until converged, relight, export. Screen
# snapshots land in out/snapshots, the exported composite on the stand-in
# stick out/usb/PropCam/.
rm -rf out/propcamd.sock out/snapshots out/usb
mkdir -p out/usb
./build/release/firmware/propcamd --socket out/propcamd.sock \
  --camera replay:board/virtual/recordings/living_room &
daemon=$!
trap 'kill "$daemon" 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -S out/propcamd.sock ] && break; sleep 0.1; done
./build/release/firmware/propcam run --board virtual --daemon out/propcamd.sock \
  --snapshots out/snapshots --usb out/usb --data out/appliance-data
kill "$daemon"; wait "$daemon" || true
# Real photographs: a hotel room cut from blender-data's CC0 panorama, and
# OpenCV's sample street façade (both installed from Debian by setup.sh).
./build/release/firmware/propcam view /usr/share/blender/datafiles/studiolights/world/interior.exr \
  --yaw 135 --pitch -20 --fov 65 --size 640x480 -o out/hotel_room.png
./build/release/firmware/propcam composite out/hotel_room.png \
  --prop sphere_plinth --at 400,420 --spp 64 -o out/composite_hotel_room.png
./build/release/firmware/propcam composite /usr/share/doc/opencv-doc/examples/data/building.jpg \
  --prop chair --at 300,560 --height 2 --yaw 30 --spp 32 -o out/composite_street.png
echo "demo: the appliance's screens are in out/snapshots/, its export in out/usb/PropCam/;"
echo "      real photos composited: out/composite_hotel_room.png and out/composite_street.png"
