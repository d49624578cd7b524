#!/usr/bin/env bash
# Fetches the 18 CC0 HDR panoramas of the npm package @pmndrs/assets (512x256
# EXR, stored base64 inside hdri/*.exr.js) and decodes them into
# build/pmndrs_hdri/NAME.exr. Training data only: never committed.
set -euo pipefail
cd "$(dirname "$0")/.."
out=build/pmndrs_hdri
mkdir -p "$out"
if ls "$out"/*.exr >/dev/null 2>&1; then echo "$out"; exit 0; fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
(cd "$work" && npm pack --silent @pmndrs/assets@1.7.0 >/dev/null && tar xzf pmndrs-assets-*.tgz)
for js in "$work"/package/hdri/*.exr.js; do
  name=$(basename "$js" .exr.js)
  sed -e "s/^[^,]*base64,//" -e "s/'.*\$//" "$js" | tr -d '\n' | base64 -d > "$out/$name.exr.tmp"
  mv "$out/$name.exr.tmp" "$out/$name.exr"
done
echo "$out"
