#!/usr/bin/env bash
# Plan time per frame, measured inside the run: `clipsat fly --json` times every `Planner::plan` call
# (wall clock) and counts the screen-space bounds it evaluated (the same on every machine). Every shared
# terrain, sat-conservative at epsilon 1, 2 and 4 (and distance LOD), gles3-mid at 1920x1080, a 200-frame
# figure-8 flight, streamed as `fly` streams by default.
# Usage: scripts/plan_time.sh [CLIPSAT_BINARY] [PROFILE] [FRAMES] [PATH]   (from the repository root; needs jq)
# Writes a Markdown table on stdout (load average before and after beside it); the JSON goes to out/plan_time/.
set -euo pipefail
BIN=${1:-target/release/clipsat}
PROFILE=${2:-gles3-mid}
FRAMES=${3:-200}
FLIGHT=${4:-figure8}
OUT=out/plan_time
mkdir -p "$OUT"
TERRAINS=("ps_height_1k.png --spacing 160" "n07_w006_3arc_v2.tif" "srtm_bigtujunga30m_utm11.tif"
  "aletsch_200m.tif" "lidar_pkg_dem_1m_400x400.tif" "N57E011.hgt")
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "| terrain | mode | epsilon | plan ms p50 | p99 | max | mean | bounds p50 | p99 | max | clamped max | triangles max |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for t in "${TERRAINS[@]}"; do
  read -r -a a <<< "$t"; name=${a[0]}; args=("${a[@]:1}")
  if [ ! -f "../shared/data/$name" ]; then echo "skipped $name (missing)" >&2; continue; fi
  for run in "distance -" "sat-conservative 1" "sat-conservative 2" "sat-conservative 4"; do
    read -r mode eps <<< "$run"
    f="$OUT/$name.$mode.$eps.$FLIGHT.json"
    e=(); [ "$eps" != - ] && e=(--epsilon "$eps")
    "$BIN" fly --terrain "../shared/data/$name" "${args[@]}" --profile "$PROFILE" --lod "$mode" "${e[@]}" \
      --size 1920x1080 --frames "$FRAMES" --path "$FLIGHT" --json > "$f"
    jq -r --arg n "$name" --arg m "$mode" --arg e "$eps" \
      '"| \($n) | \($m) | \($e) | \(.plan_ms_p50*1000|round/1000) | \(.plan_ms_p99*1000|round/1000) | \(.plan_ms_max*1000|round/1000) | \(.plan_ms_mean*1000|round/1000) | \(.bound_evaluations_p50) | \(.bound_evaluations_p99) | \(.bound_evaluations_max) | \(.blocks_clamped_max) | \(.triangles_max) |"' "$f"
  done
done
echo
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
