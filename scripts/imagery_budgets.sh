#!/usr/bin/env bash
# Imagery within every budget on a long flight (docs/guide.md "Imagery", **Budgets**): `clipsat fly
# --imagery` for FRAMES frames (default 10^4) of the figure-8 on every profile, over the shared imagery
# pairs and any extra image given (placed over Grand Canyon's heights), twice each. Per run: frames over
# the sample budget, the most colour texels and tiles a frame against the profile's [imagery] budgets,
# peak RSS, and whether the two runs' final hashes are equal. Exits non-zero on any miss.
# Usage: scripts/imagery_budgets.sh [CLIPSAT_BINARY] [FRAMES] [EXTRA_IMAGE...]   (from the repository root)
set -euo pipefail
DATA=${CLIPSAT_DATA:-../shared/data}
BIN=${1:-target/release/clipsat}
FRAMES=${2:-10000}
shift $(($# < 2 ? $# : 2))
export CLIPSAT_CACHE=${CLIPSAT_CACHE:-target/imagery-budgets-cache}
out=$(mktemp -d)
pairs=("$DATA/ps_height_1k.png --spacing 160|$DATA/imagery/ps_texture_1k.png"
  "$DATA/imagery/gcanyon_elev_1200.png --spacing 60 --height-scale 10|$DATA/imagery/gcanyon_color_1024.png")
for extra in "$@"; do
  pairs+=("$DATA/imagery/gcanyon_elev_1200.png --spacing 60 --height-scale 10|$extra")
done
fail=0
printf "profile\timage\tframes\tover budget\ttexels max/budget\ttiles max/budget\tpeak RSS MiB\tsame hash\n"
for profile in gles3-low gles3-mid desktop; do
  budget_texels=$(sed -n 's/^texels_per_frame *= *\([0-9]*\).*/\1/p' "profiles/$profile.toml")
  budget_tiles=$(sed -n 's/^tiles_per_frame *= *\([0-9]*\).*/\1/p' "profiles/$profile.toml")
  for pair in "${pairs[@]}"; do
    terrain=${pair%%|*} image=${pair##*|}
    hashes=()
    for run in 1 2; do
      # shellcheck disable=SC2086 # $terrain is the file and its reading options
      /usr/bin/time -f "%M" "$BIN" fly --terrain $terrain --imagery "$image" --profile "$profile" \
        --path figure8 --frames "$FRAMES" --json > "$out/f.json" 2> "$out/time.txt"
      hashes+=("$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["final_hash"])' "$out/f.json")")
    done
    line=$(python3 - "$out/f.json" "$budget_texels" "$budget_tiles" "$(tail -1 "$out/time.txt")" <<'PY'
import json, sys
d = json.load(open(sys.argv[1])); texels, tiles, kib = int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
im = d["imagery"]
ok = d["frames_over_budget"] == 0 and im["texels_per_frame_max"] <= texels and im["tiles_per_frame_max"] <= tiles
print(f'{d["frames"]}\t{d["frames_over_budget"]}\t{im["texels_per_frame_max"]}/{texels}\t'
      f'{im["tiles_per_frame_max"]}/{tiles}\t{kib / 1024:.1f}\t{"ok" if ok else "MISS"}')
PY
)
    same=$([ "${hashes[0]}" = "${hashes[1]}" ] && echo yes || echo NO)
    printf "%s\t%s\t%s\t%s\n" "$profile" "$(basename "$image")" "${line%	*}" "$same"
    case "$line$same" in *MISS*|*NO) fail=1 ;; esac
  done
done
rm -rf "$out"
exit $fail
