#!/usr/bin/env bash
# Builds the asan preset (clang, AddressSanitizer + UndefinedBehaviorSanitizer,
# RelWithDebInfo; clang's sanitized objects compile in about two thirds of
# gcc's time) and runs the test suite under it: any UB report or ASan
# error fails its test, and leaks are reported except the third-party ones
# named in tests/sanitize/lsan.supp. Tests labelled slow_under_asan (over
# about 20 s under ASan, set in tests/CMakeLists.txt) and the soak and qemu
# suites are left out; the release suite runs them. The preset registers one
# ctest test per gtest suite (PROPCAM_CTEST_BY_SUITE): a sanitized test
# program takes about 1 s of CPU to start, more than most tests.
#
#   bash scripts/sanitize.sh            every program, what CI runs (scripts/test.sh)
#   bash scripts/sanitize.sh --modules  the library modules' own programs only (label
#                                       `module`: capture, render, inference, ui_fb), a
#                                       quicker check while working on them
#
# PROPCAM_SETUP_DONE=1 skips setup.sh, for a caller that has run it.
set -euo pipefail
cd "$(dirname "$0")/.."
scope=all
case "${1:-}" in
  "") ;;
  --modules) scope=modules ;;
  *) echo "usage: bash scripts/sanitize.sh [--modules]" >&2; exit 2 ;;
esac
[ -n "${PROPCAM_SETUP_DONE:-}" ] || bash scripts/setup.sh
root="$(pwd)"
export ASAN_OPTIONS="detect_leaks=1"
export LSAN_OPTIONS="suppressions=${root}/tests/sanitize/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
cmake --preset asan
if [ "$scope" = modules ]; then
  cmake --build --preset asan -j "$(nproc)" --target module_tests
  ctest --preset asan -j "$(nproc)" -L module -LE "slow_under_asan|soak|qemu"
else
  cmake --build --preset asan -j "$(nproc)"
  ctest --preset asan -j "$(nproc)" -LE "slow_under_asan|soak|qemu"
fi
