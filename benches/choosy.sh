#!/usr/bin/env bash
# Castellanos and Williams' claim (issue #19): choosy sampling keeps the sample's first-order
# statistics closer than greedy argmin. On every photograph of ../shared/data/textures (128²
# crop from the top left, or whole if smaller), `--preset castellanos` and the same recipe with every `select` set
# to "Argmin" synthesize a 256² plane (seed 0); `btfsynth eval` scores both. Writes
# OUT/choosy.md: colour χ² (50 bins per channel), patch energy and repetition of each, and
# the χ² ratio. Needs jq.
#   benches/choosy.sh [--out DIR] [--size N]
set -euo pipefail
cd "$(dirname "$0")/.."
out=bench-out/choosy
size=256
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    *) echo "usage: benches/choosy.sh [--out DIR] [--size N]" >&2; exit 2 ;;
  esac
done
cargo build --release
bin=target/release/btfsynth
shared=../shared/data/textures
[ -d "$shared" ] || { echo "no photographs: $shared is missing" >&2; exit 1; }
mkdir -p "$out"
table="$out/choosy.md"
{
  echo "| photograph | χ², choosy | χ², argmin | argmin / choosy | patch energy, choosy | patch energy, argmin | repetition, choosy | repetition, argmin |"
  echo "|---|---|---|---|---|---|---|---|"
} >"$table"
figures() { jq -r '.probes[0] | [.colour_chi2, .patch_energy, .repetition] | @tsv' "$1"; }
for photo in "$shared"/*; do
  name=$(basename "${photo%.*}")
  a="$out/$name.analysis"
  # A photograph smaller than the crop (burlap is 96²) is analysed whole.
  [ -d "$a" ] || $bin -q analyze "$photo" --crop 0,0,128,128 --force -o "$a" 2>/dev/null ||
    $bin -q analyze "$photo" --force -o "$a"
  $bin -q synth "$a" --plane "${size}x$size" --preset castellanos --seed 0 --force -o "$out/$name-choosy"
  # The preset's own recorded recipe, with argmin in place of choosy sampling.
  jq '.params.recipe | (.. | objects | select(has("select")) | .select) |= "Argmin"' \
    "$out/$name-choosy/plane.json" >"$out/$name-argmin.json"
  $bin -q synth "$a" --plane "${size}x$size" --recipe "$out/$name-argmin.json" --seed 0 --force -o "$out/$name-argmin"
  for kind in choosy argmin; do $bin eval "$a" "$out/$name-$kind" --json >"$out/$name-$kind.eval.json"; done
  read -r c_chi c_pe c_rep < <(figures "$out/$name-choosy.eval.json")
  read -r g_chi g_pe g_rep < <(figures "$out/$name-argmin.eval.json")
  awk -v n="$name" -v cc="$c_chi" -v gc="$g_chi" -v cp="$c_pe" -v gp="$g_pe" -v cr="$c_rep" -v gr="$g_rep" \
    'BEGIN { printf "| %s | %.4f | %.4f | %.0f× | %.4f | %.4f | %.3f | %.3f |\n", n, cc, gc, gc / (cc > 0 ? cc : 1e-9), cp, gp, cr, gr }' >>"$table"
done
cat "$table"
