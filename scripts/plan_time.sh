#!/usr/bin/env bash
# Plan time per frame, measured inside the run: `clipsat fly --json` times every `Planner::plan` call
# (wall clock, and the thread's CPU time beside it) and counts the screen-space bounds it evaluated (the
# same on every machine). Every shared terrain, sat-conservative at epsilon 1, 2 and 4 (and distance LOD),
# a 200-frame figure-8 flight at 1920x1080, streamed as `fly` streams by default; then a teleport flight
# (a jump every 60 frames, 1 m/frame between jumps) for the frames until the plan settles after each jump.
# Usage: scripts/plan_time.sh [CLIPSAT_BINARY] [PROFILE] [FRAMES]   (from the repository root; needs jq)
# Writes Markdown tables on stdout (the load average before and after beside them); the JSON goes to
# out/plan_time/. Each SAT row's last column is its CPU p99 over distance LOD's CPU p50 in the same run.
# PLAN_TIME_EXTRA adds terrains outside the shared folder, `;`-separated, each a path (absolute, or a
# folder of tiles) and its options, e.g. the steep tile of scripts/steep_tile.py and a tile mosaic:
#   PLAN_TIME_EXTRA="/tmp/N34W119.hgt --resample-ew;/tmp/tiles --fill-height 0" scripts/plan_time.sh
set -euo pipefail
# DATA and TERRAINS: the shared terrains.
source "$(dirname "$0")/shared_terrains.sh"
IFS=';' read -r -a EXTRA <<< "${PLAN_TIME_EXTRA:-}"
BIN=${1:-target/release/clipsat}
PROFILE=${2:-gles3-mid}
FRAMES=${3:-200}
OUT=out/plan_time/$(basename "$PROFILE" .toml)
mkdir -p "$OUT"
num() { jq -r "if $1 == null then \"-\" else ($1*1000|round/1000|tostring) end" "$2"; }
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "Figure-8, $FRAMES frames ($PROFILE, 1920x1080): plan ms per frame, wall (CPU), and bound evaluations per frame"
echo
echo "| terrain | mode | epsilon | p50 ms | p99 ms | max ms | mean ms | bounds p50 | p99 | max | clamped max | CPU p99 / distance p50 |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
specs=()
for t in "${TERRAINS[@]}"; do specs+=("$DATA/$t"); done
for t in "${EXTRA[@]}"; do [ -n "$t" ] && specs+=("$t"); done
for t in "${specs[@]}"; do
  read -r -a a <<< "$t"; path=${a[0]}; name=$(basename "$path"); args=("${a[@]:1}")
  if [ ! -e "$path" ]; then echo "skipped $name (missing)" >&2; continue; fi
  dist=
  for run in "distance -" "sat-conservative 1" "sat-conservative 2" "sat-conservative 4"; do
    read -r mode eps <<< "$run"
    f="$OUT/$name.$mode.$eps.figure8.json"
    e=(); [ "$eps" != - ] && e=(--epsilon "$eps")
    "$BIN" fly --terrain "$path" "${args[@]}" --profile "$PROFILE" --lod "$mode" "${e[@]}" \
      --size 1920x1080 --frames "$FRAMES" --path figure8 --json > "$f"
    [ "$mode" = distance ] && dist=$(jq -r .plan_cpu_ms_p50 "$f")
    ratio=$(jq -r --arg d "$dist" 'if .lod == "distance" then "-" else (.plan_cpu_ms_p99 / ($d|tonumber) * 10 | round / 10 | tostring) + "x" end' "$f")
    echo "| $name | $mode | $eps | $(num .plan_ms_p50 "$f") ($(num .plan_cpu_ms_p50 "$f")) |" \
      "$(num .plan_ms_p99 "$f") ($(num .plan_cpu_ms_p99 "$f")) | $(num .plan_ms_max "$f") ($(num .plan_cpu_ms_max "$f")) |" \
      "$(num .plan_ms_mean "$f") | $(jq -r '"\(.bound_evaluations_p50) | \(.bound_evaluations_p99) | \(.bound_evaluations_max) | \(.blocks_clamped_max)"' "$f") | $ratio |"
  done
done
echo
echo "Teleport (a jump every 60 frames, 1 m/frame between, 240 frames): frames from each jump (frame 0 included)"
echo "until the plan settles (no ring stale, no refinement work its budget stopped, every tile its cells read"
echo "resident), the blocks clamped then, and the plan time over the whole flight"
echo
echo "| terrain | epsilon | settle frames | clamped at settle | p99 ms | max ms |"
echo "|---|---|---|---|---|---|"
for t in "${TERRAINS[@]}"; do
  read -r -a a <<< "$t"; name=${a[0]}; args=("${a[@]:1}")
  if [ ! -f "$DATA/$name" ]; then continue; fi
  for eps in 1 2 4; do
    f="$OUT/$name.sat-conservative.$eps.teleport.json"
    "$BIN" fly --terrain "$DATA/$name" "${args[@]}" --profile "$PROFILE" --lod sat-conservative \
      --epsilon "$eps" --size 1920x1080 --frames 240 --path teleport:60 --speed 1 --json > "$f"
    echo "| $name | $eps | $(jq -c '.settle_frames' "$f") | $(jq -c '.settle_blocks_clamped' "$f") |" \
      "$(num .plan_ms_p99 "$f") ($(num .plan_cpu_ms_p99 "$f")) | $(num .plan_ms_max "$f") ($(num .plan_cpu_ms_max "$f")) |"
  done
done
echo
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
