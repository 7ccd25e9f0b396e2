#!/usr/bin/env bash
# The whole frame's measured screen error during a flight (docs/plan-time.md): `clipsat fly --error-every
# 20` (streamed, as `fly` streams by default) on every shared terrain, sat-conservative at epsilon 1, 2 and 4, gles3-mid at 1920x1080,
# a 200-frame figure-8 flight: the largest error over sampled frames 20, 40, ..., over every block and over
# the blocks the held data could pay for (unclamped), and how many sampled frames passed 1.05 epsilon.
# Usage: scripts/flight_error.sh [CLIPSAT_BINARY] [PROFILE]   (from the repository root; needs jq)
set -euo pipefail
# DATA and TERRAINS: the shared terrains.
source "$(dirname "$0")/shared_terrains.sh"
BIN=${1:-target/release/clipsat}
PROFILE=${2:-gles3-mid}
OUT=out/flight_error
mkdir -p "$OUT"
echo "| terrain | epsilon | sampled frames | max error px | max unclamped px | sampled frames with unclamped > 1.05 epsilon |"
echo "|---|---|---|---|---|---|"
for t in "${TERRAINS[@]}"; do
  read -r -a a <<< "$t"; name=${a[0]}; args=("${a[@]:1}")
  if [ ! -f "$DATA/$name" ]; then echo "skipped $name (missing)" >&2; continue; fi
  for eps in 1 2 4; do
    f="$OUT/$name.$eps.json"
    "$BIN" fly --terrain "$DATA/$name" "${args[@]}" --profile "$PROFILE" --lod sat-conservative \
      --epsilon "$eps" --size 1920x1080 --frames 200 --path figure8 --error-every 20 --json > "$f"
    jq -r --arg n "$name" --arg e "$eps" '.screen_error_sampled as $s
      | ([$s.per_frame[] | select(.max_px_unclamped > 1.05 * ($e|tonumber))] | length) as $over
      | "| \($n) | \($e) | \($s.frames) | \($s.max_px*100|round/100) | \($s.max_px_unclamped*100|round/100) | \($over) |"' "$f"
  done
done
