#!/usr/bin/env bash
# Units check of the Blender world's light conversions (docs/blender_world.md):
# for each light type (area light, a turned one and emissive quad, point light
# with and without radius and emissive sphere, spot light with and without
# radius, disc, an area light in view shown and hidden to the camera, sun,
# environment map) one small diffuse scene rendered by Blender
# Cycles and by `propcam render` (its SCENE.json written with the conversion
# functions of scripts/blender/units.py); prints a table and exits non-zero if
# an image mean differs by more than 2% (or a 4x4 block mean by more than 5%).
#
#   scripts/blender_units_check.sh [--out DIR] [--size WxH] [--spp N] [--bounces B] [--threads T]
#
# Needs `blender` on PATH and a release build (build/release/firmware/propcam,
# or the binary in $PROPCAM).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
out="" size=96x72 spp=256 bounces=4 threads=2
propcam="${PROPCAM:-$root/build/release/firmware/propcam}"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --size) size="$2"; shift 2 ;;
    --spp) spp="$2"; shift 2 ;;
    --bounces) bounces="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    -h|--help) sed -n '2,14p' "$0"; exit 0 ;;
    *) echo "blender_units_check: unknown argument $1" >&2; exit 2 ;;
  esac
done
command -v blender >/dev/null || { echo "blender_units_check: blender is not on PATH" >&2; exit 1; }
[[ -x "$propcam" ]] || { echo "blender_units_check: no $propcam (build the release preset first)" >&2; exit 1; }
[[ -n "$out" ]] || out="$(mktemp -d /tmp/propcam_units_check.XXXXXX)"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
set +e
blender -b --factory-startup --python "$here/blender/units_check.py" -- --out "$out" --propcam "$propcam" \
  --size "$size" --spp "$spp" --bounces "$bounces" --threads "$threads" >"$out/blender.log" 2>&1
rc=$?
set -e
grep '^UNITS' "$out/blender.log" | sed 's/^UNITS  //' || true
if [[ $rc -ne 0 && $rc -ne 3 ]]; then
  echo "blender_units_check: failed (exit $rc), see $out/blender.log" >&2
  tail -20 "$out/blender.log" >&2
  exit 1
fi
echo "details: $out/units_check.json"
[[ $rc -eq 0 ]]
