#!/usr/bin/env bash
# Builds the libFuzzer targets (preset fuzz: clang, ASan + UBSan) and runs each
# for a bounded time on a copy of its seed corpus (tests/fuzz/README.md).
# PROPCAM_FUZZ_SECONDS sets the time per target (default 20); PROPCAM_SETUP_DONE=1
# skips setup.sh, for a caller that has run it.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -n "${PROPCAM_SETUP_DONE:-}" ] || bash scripts/setup.sh
cmake --preset fuzz -DPROPCAM_FUZZ_SECONDS="${PROPCAM_FUZZ_SECONDS:-20}"
cmake --build --preset fuzz -j "$(nproc)"
ctest --preset fuzz -L fuzz -j "$(nproc)"
