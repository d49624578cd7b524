#!/usr/bin/env bash
# Retrains the IBL ranker (docs/ibl.md, "Ranking") into
# inference/data/ibl_ranker.yml.gz. The IBL library is built in memory:
# blender-data's panoramas (from their Debian path), the eighteen CC0 maps of
# the npm package @pmndrs/assets (fetched and decoded by
# scripts/fetch_pmndrs_hdri.sh, never committed; labelled indoor/outdoor
# below, as the paper's SUN360 panoramas carry a label), and the procedural
# skies and rooms. Each is cut into 10 views and the 1-slack SVM-rank is
# trained on them with the rendering-based IBL distance as margin.
# Deterministic: the same file each run.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --preset release >/dev/null
cmake --build --preset release --target propcam
extra=$(bash scripts/fetch_pmndrs_hdri.sh)
indoor="apartment bridge esplanade hall lab lobby studio warehouse workshop"
outdoor="city dawn forest night park sky sunrise sunset venice"
panoramas=""
for n in $indoor; do panoramas="$panoramas,$extra/$n.exr=indoor"; done
for n in $outdoor; do panoramas="$panoramas,$extra/$n.exr=outdoor"; done
build/release/firmware/propcam train-ibl-ranker -o inference/data/ibl_ranker.yml.gz --panoramas "${panoramas#,}" "$@"
