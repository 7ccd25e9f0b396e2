#!/usr/bin/env bash
# The detail pool's goals, measured from the default camera after the fill (`clipsat render --json`, which fills the
# rings and then the detail pool at the still camera) on every shared terrain, gles3-mid at its 1920x1080:
#  1. the whole-frame bound: sat-conservative and exact at epsilon 1, 2, 4 (met: max error <= 1.05 epsilon);
#  2. equal error: distance LOD's whole-frame error D; the largest epsilon of a ladder at which
#     sat-conservative's whole-frame error is <= D; the triangles there against distance LOD's;
#  3. the image: RMSE against the brute-force render (`--ground-truth`) at epsilon 1 and distance LOD's.
# Every run is --resident: the measured screen error and the hole tracing read the whole terrain.
# Usage: scripts/pool_goals.sh [CLIPSAT_BINARY] [PROFILE]   (run from the repository root; needs jq)
# Writes Markdown tables on stdout; the per-run JSON goes to out/pool_goals/.
set -euo pipefail
# DATA and TERRAINS: the shared terrains.
source "$(dirname "$0")/shared_terrains.sh"
BIN=${1:-target/release/clipsat}
PROFILE=${2:-gles3-mid}
OUT=out/pool_goals
mkdir -p "$OUT"
LADDER="1 1.25 1.5 1.75 2 2.5 3 3.5 4 4.5 5 5.5 6 7 8 9 10 11 12 12.5 13 14 16 20 24 28 32 40 48 64"
run() { # name mode eps args...
  local name=$1 mode=$2 eps=$3; shift 3
  local f="$OUT/$name.$mode.$eps.json"
  "$BIN" render --terrain "$DATA/$name" "$@" --profile "$PROFILE" --lod "$mode" \
    ${eps:+--epsilon "$eps"} --resident --json --out "$OUT/frame.png" > "$f"
  echo "$f"
}
bound=""; equal=""; image=""
for t in "${TERRAINS[@]}"; do
  read -r -a a <<< "$t"; name=${a[0]}; args=("${a[@]:1}")
  if [ ! -f "$DATA/$name" ]; then echo "skipped $name (missing)" >&2; continue; fi
  irow="| $name |"
  for mode in sat-conservative exact; do
    row="| $name | $mode |"
    for e in 1 2 4; do
      if [ "$e" = 1 ]; then
        f=$(run "$name" "$mode" "$e" "${args[@]}" --ground-truth)
        irow="$irow $(jq -r '.rmse_vs_ground_truth*1000|round/1000' "$f") |"
      else
        f=$(run "$name" "$mode" "$e" "${args[@]}")
      fi
      row="$row $(jq -r --argjson e "$e" '"\(.max_screen_error_px*100|round/100) px, \(.triangles) tri, \(.detail_tiles_resident) tiles, \(.blocks_clamped) clamped, holes \(.crack_pixels), border view \(.border_view_pixels), fill \(.pool_fill_frames) frames \(if .max_screen_error_px <= 1.05*$e then "(met)" else "(NOT met)" end)"' "$f") |"
    done
    bound="$bound$row"$'\n'
  done
  f=$(run "$name" distance "" "${args[@]}" --ground-truth)
  d=$(jq .max_screen_error_px "$f"); dt=$(jq .triangles "$f")
  image="$image$irow $(jq -r '.rmse_vs_ground_truth*1000|round/1000' "$f") | $(printf %.2f "$d") px, $dt tri |"$'\n'
  best=""; bt=""; be=""
  for e in $LADDER; do
    f=$(run "$name" sat-conservative "$e" "${args[@]}")
    err=$(jq .max_screen_error_px "$f")
    if jq -e --argjson d "$d" '.max_screen_error_px <= $d' "$f" > /dev/null; then
      best=$e; bt=$(jq .triangles "$f"); be=$err
    fi
  done
  if [ -n "$best" ]; then
    equal="$equal| $name | $(printf %.2f "$d") | $dt | $best | $(printf %.2f "$be") | $bt | $(echo "scale=2; $bt/$dt" | bc) |"$'\n'
  else
    equal="$equal| $name | $(printf %.2f "$d") | $dt | none of: $LADDER | | | |"$'\n'
  fi
done
echo "Whole-frame bound ($PROFILE, default camera after the fill): max error, triangles, pool tiles resident, blocks clamped, crack pixels (holes), border-view pixels and the pool's fill frames (the refinement spread over frames by its budget, docs/plan-time.md)"
echo
echo "| terrain | mode | epsilon 1 | epsilon 2 | epsilon 4 |"
echo "|---|---|---|---|---|"
printf %s "$bound"
echo
echo "Equal error: the largest epsilon of {$LADDER} at which sat-conservative's whole-frame error is <= distance LOD's"
echo
echo "| terrain | distance: error px | distance: triangles | epsilon | sat-conservative: error px | triangles | triangles / distance's |"
echo "|---|---|---|---|---|---|---|"
printf %s "$equal"
echo
echo "Image at epsilon 1: RMSE against the brute-force render (8-bit units)"
echo
echo "| terrain | sat-conservative | exact | distance | distance: error, triangles |"
echo "|---|---|---|---|---|"
printf %s "$image"
