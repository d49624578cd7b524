#!/usr/bin/env bash
# Installs what is missing, builds (Release) and runs the whole test suite.
# Before it: the fuzz targets (scripts/fuzz.sh, ~4-5 min from scratch on 2
# cores) and the library modules' test programs under AddressSanitizer +
# UndefinedBehaviorSanitizer (scripts/sanitize.sh --modules, ~9.6 min build +
# ~4.5 min run), so the run still ends with the main suite's ctest summary.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export PROPCAM_SETUP_DONE=1
bash scripts/fuzz.sh
bash scripts/sanitize.sh --modules
cmake --preset release
cmake --build --preset release -j "$(nproc)"
ctest --preset release -j "$(nproc)"
