#!/usr/bin/env bash
# Peak RSS of streamed renders (README, Terrain packages, **Streaming**): two release binaries alternating
# in one sitting, three runs each (the first may bake into the shared cache), over three terrain sizes.
# Usage: scripts/rss_stream.sh BIN_BEFORE BIN_AFTER [CACHE_DIR]
set -euo pipefail
# The test terrains' folder, as the tests find it.
DATA=${CLIPSAT_DATA:-../shared/data}
before=$1 after=$2
export CLIPSAT_CACHE=${3:-target/rss-stream-cache}
out=$(mktemp -d)
for t in procedural:size=257 $DATA/N57E011.hgt procedural:size=4097; do
  for cmd in "--lod sat" "--profile desktop --shading sg"; do
    for run in 1 2 3; do
      for b in "$before" "$after"; do
        # shellcheck disable=SC2086 # $cmd is two words on purpose
        /usr/bin/time -v "$b" render --terrain "$t" $cmd --size 320x180 --json --out "$out/f.png" \
          > "$out/r.json" 2> "$out/time.txt"
        kib=$(awk '/Maximum resident/ {print $NF}' "$out/time.txt")
        hash=$(sed -n 's/.*"image_hash": *"\([0-9a-f]*\)".*/\1/p' "$out/r.json")
        echo "$t | $cmd | $b | run $run | peak RSS $((kib / 1024)).$(((kib % 1024) * 10 / 1024)) MiB | image $hash"
      done
    done
  done
done
