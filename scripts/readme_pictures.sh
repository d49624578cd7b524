#!/usr/bin/env bash
# Remakes the README's pictures (docs/images/) from a release build:
#   scripts/readme_pictures.sh
# - appliance_screens.jpg: four of the appliance's screens from the virtual
#   board's scripted session (propcam run --snapshots), side by side;
# - composites.jpg: the two real photos the demo composites into.
# Needs the demo's outputs: runs scripts/demo.sh's steps itself when
# out/snapshots or the composites are missing.
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ ! -d out/snapshots || ! -f out/composite_hotel_room.png || ! -f out/composite_street.png ]]; then
  bash scripts/demo.sh
fi
mkdir -p docs/images
# The screens in the order a user meets them: viewfinder, prop choice,
# placement, the converged composite (the last adjusting screen).
pick() { ls out/snapshots/*"$1"*.png | head -n 1; }
last() { ls out/snapshots/*"$1"*.png | tail -n 1; }
screens=("$(pick viewfinder)" "$(pick placing-prop)" "$(pick placing-spot)" "$(last adjusting)")
oiiotool "${screens[@]}" --mosaic:pad=8 4x1 --resize 1280x0 --quality 85 -o docs/images/appliance_screens.jpg
oiiotool out/composite_hotel_room.png --resize 480x360 out/composite_street.png --fit 480x360 \
  --mosaic:pad=8 2x1 --quality 85 -o docs/images/composites.jpg
ls -la docs/images
