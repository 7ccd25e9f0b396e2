#!/usr/bin/env bash
# The "shading survives LOD" goal: at epsilon 2, SAT LOD's image RMSE against the brute-force render
# is within 1.2x of distance LOD's, on every shared terrain (default camera, 640x360, `render --json
# --ground-truth --resident`: the brute-force reference reads the whole terrain). Usage: scripts/survive_lod.sh [CLIPSAT_BINARY] [PROFILE] [EXTRA ARGS...]
# (run from the repository root; needs jq). Writes a Markdown table on stdout.
set -euo pipefail
# DATA and TERRAINS: the shared terrains.
source "$(dirname "$0")/shared_terrains.sh"
BIN=${1:-target/release/clipsat}
PROFILE=${2:-gles3-mid}
shift $(( $# > 2 ? 2 : $# ))
OUT=out/survive_lod
mkdir -p "$OUT"
echo "| terrain | distance RMSE | sat RMSE (tri) | ratio | sat-conservative RMSE (tri) | ratio |"
echo "|---|---|---|---|---|---|"
for t in "${TERRAINS[@]}"; do
  read -r -a a <<< "$t"; name=${a[0]}; args=("${a[@]:1}")
  if [ ! -f "$DATA/$name" ]; then echo "skipped $name (missing)" >&2; continue; fi
  row="| $name |"
  for mode in distance sat sat-conservative; do
    f="$OUT/$name.$mode.json"
    "$BIN" render --terrain "$DATA/$name" "${args[@]}" --profile "$PROFILE" --size 640x360 \
      --lod "$mode" --epsilon 2 --json --ground-truth --resident --out "$OUT/$name.$mode.png" "$@" > "$f"
    r=$(jq .rmse_vs_ground_truth "$f")
    if [ "$mode" = distance ]; then d=$r; row="$row $(printf %.2f "$r") |"; else
      row="$row $(printf %.2f "$r") ($(jq .triangles "$f")) | $(echo "$r / $d" | bc -l | xargs printf %.2f)x |"; fi
  done
  echo "$row"
done
