#!/usr/bin/env bash
# Installs what is missing, builds (Release) and runs the whole test suite.
# Before it: the fuzz targets (scripts/fuzz.sh, ~4-5 min from scratch on 2
# cores) and every test program under AddressSanitizer +
# UndefinedBehaviorSanitizer (scripts/sanitize.sh; the tests over ~20 s under
# ASan, soak and qemu are left to the release suite), so the run still ends
# with the main suite's ctest summary.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export PROPCAM_SETUP_DONE=1
bash scripts/fuzz.sh
bash scripts/sanitize.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)"
ctest --preset release -j "$(nproc)"
