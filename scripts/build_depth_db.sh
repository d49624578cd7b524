#!/usr/bin/env bash
# Regenerates the depth-transfer database committed at inference/data/depth_db.bin
# from the project's own scene generator (deterministic for the same seeds).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --preset release >/dev/null
cmake --build --preset release --target propcam
build/release/firmware/propcam build-depth-db -o inference/data/depth_db.bin --rooms "${ROOMS:-160}" --streets "${STREETS:-120}" --first-seed 1001 "$@"
