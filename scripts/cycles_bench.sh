#!/usr/bin/env bash
# Renderer bench against Blender Cycles 3.4 (docs/renderer_vs_cycles.md): the
# same scenes (box_area: a room under a ceiling panel; small_bulb: the room
# under a 1.5 cm bulb; emissive_mesh: the room lit by an emissive globe and
# tube; glossy_env: plastic and metal props under courtyard.exr) rendered by
# both; a Cycles reference at --ref-spp, timed Cycles renders at
# --cycles-spp, timed `propcam render` at 1, 2, 4, ... --max-spp; prints per
# scene the time propcam needs to reach each Cycles render's RMSE, the variance
# proxy RMSE^2 x spp and the image means (void above 2%: exit 3); writes
# DIR/cycles_bench.json and DIR/cycles_bench.png (or .svg).
#
#   scripts/cycles_bench.sh [--out DIR] [--size WxH] [--threads T] [--scenes a,b,c] [--ref-spp N]
#                           [--cycles-spp 64,256,1024] [--max-spp N] [--bounces B]
#
# Defaults: 320x240, 2 threads, all scenes, ref 4096 spp, max 4096 spp, Cycles
# max_bounces 4. Needs `blender` on PATH and build/release/firmware/propcam
# (or PROPCAM=path). A quick run: --size 96x72 --ref-spp 1024 --max-spp 1024.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
out="" size=320x240 threads=2 scenes=box_area,small_bulb,emissive_mesh,glossy_env ref_spp=4096
cycles_spp=64,256,1024 max_spp=4096 bounces=4
propcam="${PROPCAM:-$root/build/release/firmware/propcam}"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --size) size="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    --scenes) scenes="$2"; shift 2 ;;
    --ref-spp) ref_spp="$2"; shift 2 ;;
    --cycles-spp) cycles_spp="$2"; shift 2 ;;
    --max-spp) max_spp="$2"; shift 2 ;;
    --bounces) bounces="$2"; shift 2 ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    *) echo "cycles_bench: unknown argument $1" >&2; exit 2 ;;
  esac
done
command -v blender >/dev/null || { echo "cycles_bench: blender is not on PATH" >&2; exit 1; }
[[ -x "$propcam" ]] || { echo "cycles_bench: no $propcam (build the release preset first)" >&2; exit 1; }
[[ -n "$out" ]] || out="$(mktemp -d /tmp/propcam_cycles_bench.XXXXXX)"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
set +e
# progress and the tables as they come; everything else only in the log
blender -b --factory-startup --python "$here/blender/cycles_bench.py" -- --out "$out" --propcam "$propcam" \
  --size "$size" --threads "$threads" --scenes "$scenes" --ref-spp "$ref_spp" --cycles-spp "$cycles_spp" \
  --max-spp "$max_spp" --bounces "$bounces" 2>&1 | tee "$out/blender.log" | grep --line-buffered '^BENCH' |
  sed -u 's/^BENCH  //'
rc=${PIPESTATUS[0]}
set -e
if [[ $rc -ne 0 && $rc -ne 3 ]]; then
  echo "cycles_bench: failed (exit $rc), see $out/blender.log" >&2
  tail -20 "$out/blender.log" >&2
  exit 1
fi
echo "details: $out/cycles_bench.json"
[[ $rc -eq 0 ]] || { echo "cycles_bench: some scene's image means differ by more than 2% (see WARNING)" >&2; exit 3; }
