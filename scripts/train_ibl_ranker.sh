#!/usr/bin/env bash
# Retrains the IBL ranker (inference/README.md, "Out-of-view light") into
# inference/data/ibl_ranker.yml.gz: the IBL library is built in memory
# (blender-data's panoramas from their Debian path, plus the procedural skies
# and rooms), cut into 10 views each, and the 1-slack SVM-rank is trained on
# them with the rendering-based IBL distance as margin. Deterministic.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --preset release >/dev/null
cmake --build --preset release --target propcam
build/release/firmware/propcam train-ibl-ranker -o inference/data/ibl_ranker.yml.gz "$@"
