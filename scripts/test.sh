#!/usr/bin/env bash
# Installs what is missing, builds (Release) and runs the whole test suite.
# The fuzz targets run first (scripts/fuzz.sh, ~4-5 min from scratch on 2
# cores), so the run still ends with the main suite's ctest summary.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/fuzz.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)"
ctest --preset release -j "$(nproc)"
