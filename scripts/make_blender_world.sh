#!/usr/bin/env bash
# The Blender world: randomised indoor/outdoor scenes rendered by Blender
# Cycles, with exact ground truth in PropCam's formats (docs/blender_world.md).
#
#   scripts/make_blender_world.sh --out DIR [--count N] [--size WxH] [--spp N]
#       [--max-spp M] [--noise-target L] [--seed S] [--threads T] [--probe-spp N]
#       [--noise-check K] [--only-missing] [--held-only] [--indoor-plan PLAN]
#
# Works from a fresh clone after `bash scripts/setup.sh` and a release build
# (build/release/firmware/propcam): it exports the preset props with
# `propcam props --export DIR/props`, renders scene seeds S..S+N-1 with one
# `blender -b --factory-startup --python scripts/blender/world.py` process per
# scene (a failure stays in that scene's log), then writes DIR/world.json.
# A scene is complete when DIR/scene_<seed>/scene_done.json exists; a rerun
# (or --only-missing) skips complete scenes. `blender` (3.4, Cycles) must be
# on PATH. Defaults: 66 scenes from seed 1 at 320x240, 2 threads, per scene the
# fewest spp in [128, 256] whose predicted noise is at most 3 8-bit levels
# (--spp N --max-spp N: always N), a 4x-spp noise check on the first 3 scenes.
# --held-only renders only the held split's seeds (multiples of 3): a fresh
# held set above seed 66 judges a change chosen after the first one was seen.
# --indoor-plan (ceiling|lamps|window_sun|window_overcast|offscreen|dim|mixed)
# gives every indoor scene that light plan (for a study of one kind of light;
# every other choice of the seed stays as it was); outdoor seeds are skipped.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
out="" count=66 size=320x240 spp=128 max_spp=256 noise_target=3 seed=1 threads=2 probe_spp=256 noise_check=3
only_missing=0 held_only=0 indoor_plan=""
propcam="${PROPCAM:-$root/build/release/firmware/propcam}"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --count) count="$2"; shift 2 ;;
    --size) size="$2"; shift 2 ;;
    --spp) spp="$2"; shift 2 ;;
    --max-spp) max_spp="$2"; shift 2 ;;
    --noise-target) noise_target="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    --probe-spp) probe_spp="$2"; shift 2 ;;
    --noise-check) noise_check="$2"; shift 2 ;;
    --only-missing) only_missing=1; shift ;;
    --held-only) held_only=1; shift ;;
    --indoor-plan) indoor_plan="$2"; shift 2 ;;
    -h|--help) sed -n '2,23p' "$0"; exit 0 ;;
    *) echo "make_blender_world: unknown argument $1" >&2; exit 2 ;;
  esac
done
[[ -n "$out" ]] || { echo "make_blender_world: --out DIR is required" >&2; exit 2; }
[[ "$size" =~ ^[0-9]+x[0-9]+$ ]] || { echo "make_blender_world: --size expects WxH" >&2; exit 2; }
command -v blender >/dev/null || { echo "make_blender_world: blender is not on PATH (apt-get install blender)" >&2; exit 1; }
[[ -x "$propcam" ]] || { echo "make_blender_world: no $propcam (build the release preset first)" >&2; exit 1; }
mkdir -p "$out"
out="$(cd "$out" && pwd)"
"$propcam" props --export "$out/props" >/dev/null
py=/usr/bin/python3
failed=0 done_count=0 wanted=0
for ((i = 0; i < count; i++)); do
  s=$((seed + i))
  if ((held_only && s % 3 != 0)); then continue; fi  # the split rule of scripts/blender/world.py
  if [[ -n "$indoor_plan" ]] && ((s % 4 == 3)); then continue; fi  # outdoor seeds (world.py's rule)
  wanted=$((wanted + 1))
  dir="$out/scene_$s"
  if [[ -f "$dir/scene_done.json" ]]; then done_count=$((done_count + 1)); continue; fi
  rm -rf "$dir"
  mkdir -p "$dir"
  nc=0
  if ((i < noise_check)); then nc=1; fi
  start=$(date +%s)
  if PROPCAM_WORLD_INDOOR_PLAN="$indoor_plan" blender -b --factory-startup --python "$here/blender/world.py" -- --out "$dir" --seed "$s" \
      --props "$out/props" --size "$size" --spp "$spp" --max-spp "$max_spp" --noise-target "$noise_target" \
      --threads "$threads" --probe-spp "$probe_spp" --noise-check "$nc" >"$dir/blender.log" 2>&1 && [[ -f "$dir/scene_done.json" ]]; then
    done_count=$((done_count + 1))
    echo "scene $s done in $(($(date +%s) - start)) s ($done_count done)"
  else
    failed=$((failed + 1))
    echo "scene $s FAILED after $(($(date +%s) - start)) s: see $dir/blender.log" >&2
  fi
  # world.json after every scene: a stopped run leaves an index of what is done
  "$py" "$here/blender/world_index.py" "$out" "$seed" "$count" "$size" "$spp" "$probe_spp" "$threads" \
    "$max_spp" "$noise_target"
done
"$py" "$here/blender/world_index.py" "$out" "$seed" "$count" "$size" "$spp" "$probe_spp" "$threads" \
    "$max_spp" "$noise_target"
echo "$done_count of $wanted scenes complete in $out ($failed failed this run)"
[[ $failed -eq 0 ]]
