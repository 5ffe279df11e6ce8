#!/usr/bin/env bash
# make demo: synthesise the bundled fur scene (and a plant), write the capture and a contact
# sheet; later stages (model, render, eval) run when their commands exist.
set -euo pipefail
cd "$(dirname "$0")/.."
F=.venv/bin/furrow
OUT=out/demo
mkdir -p "$OUT"
has() { $F --help 2>/dev/null | grep -qE "^\s+$1\s"; }

$F synth furball -o "$OUT/furball_scan" --views 36 --size 320x240 --seed 1 --preview --overwrite
$F synth plant -o "$OUT/plant_scan" --views 36 --size 320x240 --seed 1 --preview --overwrite
if has model; then
  $F model "$OUT/furball_scan" -o "$OUT/furball_model" --frames 0::2 --max-res 128 --overwrite --json > "$OUT/furball_model.json"
fi
if has render && [ -d "$OUT/furball_model" ]; then
  $F render "$OUT/furball_model" --cameras "$OUT/furball_scan" --orbit 8 -o "$OUT/furball_orbit"
  $F render "$OUT/furball_model" --cameras "$OUT/furball_scan" --orbit 8 -o "$OUT/furball_orbit_sunset" --env sunset --ground
fi
if has eval; then
  $F eval "$OUT/furball_scan" --holdout 2 --json "$OUT/furball_eval.json" -o "$OUT/furball_eval"
  $F eval "$OUT/plant_scan" --holdout 2 --json "$OUT/plant_eval.json" -o "$OUT/plant_eval"
fi
echo "demo outputs in $OUT:"
find "$OUT" -maxdepth 2 \( -name '*.png' -o -name '*.json' \) | sort | head -60
if [ -d "$OUT/furball_model" ] && has view; then
  echo
  echo "look at the model interactively (then open the printed URL in a browser; Ctrl-C stops it):"
  echo "  $F view $OUT/furball_model --cameras $OUT/furball_scan"
fi
