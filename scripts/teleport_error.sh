#!/usr/bin/env bash
# How fast the whole frame's measured error comes back after a teleport (docs/plan-time.md): `clipsat fly
# --resident --path teleport:60 --speed 1 --error-every 1` (a jump every 60 frames, 1 m/frame between, 240
# frames) on every shared terrain, sat-conservative at epsilon 1, 2 and 4, gles3-mid at 1920x1080. Per leg:
# the first frame whose error is within 1.05 epsilon, the frame from which every later frame of the leg is
# (`-`: none within the leg), and the error on the leg's last frame; then the plan's CPU p99 and max.
# Usage: scripts/teleport_error.sh [CLIPSAT_BINARY] [PROFILE]   (from the repository root; needs jq)
set -euo pipefail
# DATA and TERRAINS: the shared terrains.
source "$(dirname "$0")/shared_terrains.sh"
BIN=${1:-target/release/clipsat}
PROFILE=${2:-gles3-mid}
OUT=out/teleport_error
mkdir -p "$OUT"
echo "| terrain | epsilon | first frame within 1.05 epsilon, per leg | every later frame within | error at each leg's end, px | plan CPU p99 / max ms |"
echo "|---|---|---|---|---|---|"
for t in "${TERRAINS[@]}"; do
  read -r -a a <<< "$t"; name=${a[0]}; args=("${a[@]:1}")
  if [ ! -f "$DATA/$name" ]; then echo "skipped $name (missing)" >&2; continue; fi
  for eps in 1 2 4; do
    f="$OUT/$name.$eps.json"
    "$BIN" fly --terrain "$DATA/$name" "${args[@]}" --profile "$PROFILE" --lod sat-conservative \
      --epsilon "$eps" --size 1920x1080 --frames 240 --path teleport:60 --speed 1 --resident \
      --error-every 1 --json > "$f"
    t=$(jq -r '"\(.plan_cpu_ms_p99*1000|round/1000) / \(.plan_cpu_ms_max*1000|round/1000)"' "$f")
    jq -r --arg n "$name" --argjson e "$eps" --arg t "$t" '
      [.screen_error_sampled.per_frame[] | {leg: (.frame / 60 | floor), at: (.frame % 60), px: .max_px}]
      | group_by(.leg) | map(
          ([.[] | select(.px <= 1.05 * $e) | .at] | if length > 0 then (min | tostring) else "-" end) as $first
          | ([.[] | select(.px > 1.05 * $e) | .at] | if length == 0 then "0"
              elif max >= 59 then "-" else (max + 1 | tostring) end) as $all
          | {first: $first, all: $all, end: (last.px * 100 | round / 100 | tostring)})
      | "| \($n) | \($e) | \(map(.first) | join(", ")) | \(map(.all) | join(", ")) | \(map(.end) | join(", ")) | \($t) |"' "$f"
  done
done
