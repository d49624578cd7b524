#!/usr/bin/env bash
# Rebuilds the virtual board's recording (board/virtual/recordings/living_room):
# the bundled photo packed as a YUYV camera would deliver it, 4 frames with
# seeded sensor noise (deterministic: the same bytes on every run).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --build --preset release --target propcam
rm -rf board/virtual/recordings/living_room
./build/release/firmware/propcam record --from-photo board/virtual/photos/living_room.png \
  --format YUYV --frames 4 -o board/virtual/recordings/living_room
