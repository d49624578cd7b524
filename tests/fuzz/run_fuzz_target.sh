#!/usr/bin/env bash
# run_fuzz_target.sh TARGET SEEDS WORK [libFuzzer flags...]
# Fuzzes TARGET from a fresh copy of its seed corpus in WORK (the source tree's
# corpus is never written to). Fails when libFuzzer finds a crash, a leak, a
# timeout or an out-of-memory input; the input is kept under the artifact prefix.
set -euo pipefail
target=$1 seeds=$2 work=$3
shift 3
rm -rf "$work"
mkdir -p "$work"
cp -r "$seeds"/. "$work"/
exec "$target" "$@" "$work"
