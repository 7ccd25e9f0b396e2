#!/usr/bin/env bash
# How a bake scales with the cores (docs/guide.md "Tile mosaics", **Measured**): `clipsat bake` of one
# terrain on one core (`taskset -c 0`: the bake's threads follow the process's CPU affinity) and on all of
# them, ROUNDS rounds alternating, into a fresh folder each time (no cache). Prints each run's wall and CPU
# seconds, the median wall of each, their ratio, and whether every package is byte-identical (a package
# does not depend on the thread count).
# Usage: scripts/bake_scaling.sh CLIPSAT_BINARY TERRAIN [ROUNDS] [BAKE OPTIONS...]   (from the repository root)
# Example, the 16-tile 7201^2 mosaic of docs/guide.md "Tile mosaics" (written by `make_mosaic`):
#   scripts/bake_scaling.sh target/release/clipsat /tmp/m7/tiles-4 3 --fill-height 0
# SCALING_PARTS=1 bakes a package set (`--parts`, docs/guide.md "Package sets") instead of one package,
# and compares the sets' folders.
set -euo pipefail
BIN=${1:?usage: scripts/bake_scaling.sh CLIPSAT_BINARY TERRAIN [ROUNDS] [BAKE OPTIONS...]}
TERRAIN=${2:?usage: scripts/bake_scaling.sh CLIPSAT_BINARY TERRAIN [ROUNDS] [BAKE OPTIONS...]}
ROUNDS=${3:-3}
shift $(($# < 3 ? $# : 3))
command -v taskset >/dev/null || { echo "bake_scaling: taskset (util-linux) is needed" >&2; exit 1; }
cores=$(nproc)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
one=() all=()
printf "round\tcores\twall s\tCPU s\n"
for round in $(seq 1 "$ROUNDS"); do
  for mode in one all; do
    dir="$out/$mode-$round"
    mkdir -p "$dir"
    pin=()
    [ "$mode" = one ] && pin=(taskset -c 0)
    n=$([ "$mode" = one ] && echo 1 || echo "$cores")
    target=(--out "$dir/t.clipsat")
    [ -n "${SCALING_PARTS:-}" ] && target=(--parts "$dir/set")
    /usr/bin/time -f "%e %U %S" -o "$dir/time" "${pin[@]}" "$BIN" bake --terrain "$TERRAIN" "$@" \
      "${target[@]}" >/dev/null
    read -r wall user sys <"$dir/time"
    printf "%s\t%s\t%s\t%s\n" "$round" "$n" "$wall" "$(echo "$user + $sys" | bc)"
    if [ "$mode" = one ]; then one+=("$wall"); else all+=("$wall"); fi
  done
done
median() { printf "%s\n" "$@" | sort -n | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }
m1=$(median "${one[@]}") ma=$(median "${all[@]}")
same=yes
for f in "$out"/*/t.clipsat; do
  [ -e "$f" ] || continue
  cmp -s "$f" "$out/one-1/t.clipsat" || same=no
done
for d in "$out"/*/set; do
  [ -e "$d" ] || continue
  diff -rq "$d" "$out/one-1/set" >/dev/null || same=no
done
echo "median wall: 1 core $m1 s, $cores cores $ma s, speed-up $(echo "scale=2; $m1 / $ma" | bc)x; packages byte-identical: $same"
