#!/usr/bin/env bash
# How much `--preset castellanos` depends on the start of its finer levels (issue #19: the
# departure "no Laplacian blend across seams" needs a number). The preset's own recorded
# recipe is run with the finer levels' start set to each of: the inherited texel (the
# preset), the inherited texel jittered by up to 1 and 2 texels, and a random texel (the
# coarser level discarded). 128² top-left crops of a few photographs → 256² planes, seeds 0
# and 1; `btfsynth eval` scores each. Writes OUT/start.md: patch energy and colour χ² per
# start, the mean over the seeds. Needs jq.
#   benches/castellanos_start.sh [--out DIR] [PHOTO...]
set -euo pipefail
cd "$(dirname "$0")/.."
out=bench-out/castellanos-start
photos=()
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out=$2; shift 2 ;;
    -*) echo "usage: benches/castellanos_start.sh [--out DIR] [PHOTO...]" >&2; exit 2 ;;
    *) photos+=("$1"); shift ;;
  esac
done
shared=../shared/data/textures
[ ${#photos[@]} -gt 0 ] || photos=("$shared/gimp-Stone_stone33.png" "$shared/gimp-Wood_walnut.png" \
  "$shared/sh3d-pebbles.jpg" "$shared/skimage-grass.png")
for p in "${photos[@]}"; do [ -f "$p" ] || { echo "error: $p is missing" >&2; exit 1; }; done
cargo build --release
bin=target/release/btfsynth
mkdir -p "$out"
starts=(inherit jitter1 jitter2 random)
start_json() {
  case $1 in
    inherit) echo '"Inherit"' ;;
    jitter1) echo '{"Jittered":{"texels":1}}' ;;
    jitter2) echo '{"Jittered":{"texels":2}}' ;;
    random) echo '"Random"' ;;
  esac
}
table="$out/start.md"
{
  printf "| photograph |"; for s in "${starts[@]}"; do printf " %s: patch energy, χ² |" "$s"; done; echo
  printf "|---|"; for _ in "${starts[@]}"; do printf -- "---|"; done; echo
} >"$table"
for photo in "${photos[@]}"; do
  name=$(basename "${photo%.*}")
  a="$out/$name.analysis"
  [ -d "$a" ] || $bin -q analyze "$photo" --crop 0,0,128,128 --force -o "$a"
  # The preset's recipe as it records it, so the bench follows the preset when it changes.
  [ -f "$out/$name-preset.json" ] ||
    { $bin -q synth "$a" --plane 32x32 --levels 1 --preset castellanos --force -o "$out/$name-preset" &&
      jq '.params.recipe' "$out/$name-preset/plane.json" >"$out/$name-preset.json"; }
  row="| $name |"
  for s in "${starts[@]}"; do
    jq ".finer.start = $(start_json "$s")" "$out/$name-preset.json" >"$out/$name-$s.json"
    for seed in 0 1; do
      $bin -q synth "$a" --plane 256x256 --recipe "$out/$name-$s.json" --seed $seed --force -o "$out/$name-$s-$seed"
      $bin eval "$a" "$out/$name-$s-$seed" --json >"$out/$name-$s-$seed.eval.json"
    done
    row+=$(jq -rs '[.[].probes[0]] | " \((map(.patch_energy) | add / 2 * 1e5 | round / 1e5)), \((map(.colour_chi2) | add / 2 * 1e5 | round / 1e5)) |"' \
      "$out/$name-$s-0.eval.json" "$out/$name-$s-1.eval.json")
  done
  echo "$row" >>"$table"
done
cat "$table"
