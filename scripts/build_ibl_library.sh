#!/usr/bin/env bash
# Builds the IBL library (docs/ibl.md, "Library") into
# build/ibl_library: blender-data's panoramas (read from their Debian path) and
# the project's procedural skies and rooms, downsampled and annotated by code.
# Not committed: it is derived from installed data and rebuilt in ~1 s.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --preset release >/dev/null
cmake --build --preset release --target propcam
build/release/firmware/propcam build-ibl-library -o "${IBL_LIBRARY_DIR:-build/ibl_library}" "$@"
