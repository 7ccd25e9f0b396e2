#!/usr/bin/env bash
# Whether the reported bound holds on every frame (docs/plan-time.md): `clipsat fly --resident
# --error-every 1` measures the whole frame's screen error on every frame of the figure-8 (600 frames) and
# of the teleport flight (a jump every 60 frames, 1 m/frame between, 240 frames) on every shared terrain,
# sat-conservative at epsilon 1, 2 and 4, gles3-mid at 1920x1080, and compares it with max(epsilon,
# unmet_px) of the same frame (`--csv`). Per flight: frames measured, the worst ratio measured / bound and
# its frame, the frames where it passes 1 (frame: measured/bound px) and the flight's plan_run_hash.
# Usage: scripts/bound_every_frame.sh [CLIPSAT_BINARY] [OUT_FOLDER]   (from the repository root; python3)
set -euo pipefail
# DATA and TERRAINS: the shared terrains.
source "$(dirname "$0")/shared_terrains.sh"
BIN=${1:-target/release/clipsat}
OUT=${2:-out/bound_every_frame}
mkdir -p "$OUT"
printf "terrain\tpath\tepsilon\tframes\tworst ratio\tat frame\tframes over\tover (measured/bound px)\tplan_run_hash\n"
for t in "${TERRAINS[@]}"; do
  read -r -a a <<< "$t"; name=${a[0]}; args=("${a[@]:1}")
  if [ ! -f "$DATA/$name" ]; then echo "skipped $name (missing)" >&2; continue; fi
  for path in figure8 teleport; do
    case $path in
      figure8) flight=(--frames 600 --path figure8) ;;
      teleport) flight=(--frames 240 --path teleport:60 --speed 1) ;;
    esac
    for eps in 1 2 4; do
      f="$OUT/$name.$path.$eps"
      "$BIN" fly --terrain "$DATA/$name" "${args[@]}" --profile gles3-mid --lod sat-conservative \
        --epsilon "$eps" --size 1920x1080 "${flight[@]}" --resident --error-every 1 --json \
        --csv "$f.csv" > "$f.json"
      printf "%s\t%s\t%s\t" "$name" "$path" "$eps"
      python3 "$(dirname "$0")/bound_every_frame.py" "$eps" "$f.json" "$f.csv"
    done
  done
done
