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
if has check; then  # the capture's poses, intrinsics and depth checked first (a second; exit 1 would stop here)
  $F check "$OUT/furball_scan" --frames 0::2
fi
if has model; then
  $F model "$OUT/furball_scan" -o "$OUT/furball_model" --frames 0::2 --max-res 128 --overwrite --json > "$OUT/furball_model.json"
fi
if has render && [ -d "$OUT/furball_model" ]; then
  $F render "$OUT/furball_model" --cameras "$OUT/furball_scan" --orbit 8 -o "$OUT/furball_orbit"
  $F render "$OUT/furball_model" --cameras "$OUT/furball_scan" --orbit 8 -o "$OUT/furball_orbit_sunset" --env sunset --ground
fi
# a capture as a camera takes it: the room behind the object (kept views), a turntable disc in the
# depth, auto exposure; furrow model removes the disc, mattes every view and aligns the exposure,
# then the RGBA render is composited over a white backdrop (docs/real_captures.md).
if has model; then
  $F synth furball -o "$OUT/room_scan" --views 36 --size 320x240 --seed 2 --background env --support disc \
    --background-frames 0::2 --auto-exposure --overwrite
  $F model "$OUT/room_scan" -o "$OUT/room_model" --frames 0::2 --max-res 128 --overwrite --json > "$OUT/room_model.json"
  $F render "$OUT/room_model" --cameras "$OUT/room_scan" --frames 1::6 -o "$OUT/room_rgba"
  $F render "$OUT/room_model" --cameras "$OUT/room_scan" --frames 1::6 -o "$OUT/room_over_white" --background white
  $F eval "$OUT/room_scan" --holdout 2 --json "$OUT/room_eval.json" -o "$OUT/room_eval"
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
