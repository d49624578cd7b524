#!/usr/bin/env bash
# Retrains the visible-light classifier committed at
# inference/data/light_classifier.yml.gz from views of the CC0 HDR panoramas
# Debian's blender-data installs (deterministic: the same file each run).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --preset release >/dev/null
cmake --build --preset release --target propcam
build/release/firmware/propcam train-light-classifier -o inference/data/light_classifier.yml.gz "$@"
