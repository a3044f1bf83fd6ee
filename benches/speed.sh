#!/usr/bin/env bash
# Speed at working sizes (issue #24): wall seconds and peak memory of the issue's target
# cases, each a plain `btfsynth` command, with the synthesis stage from `--report` (the sum
# of its levels' seconds). Prints a Markdown table and keeps it in OUT/speed.md. A benchmark,
# never a test: the figures depend on the machine and on what else runs.
#   benches/speed.sh [--out DIR] [CASE...]
# CASES (default: all): surface250k threads plane1024 plane2048 plane512 analysis512 analysisbtf search
#   resynth (128² → 512² CPU seconds against Resynthesizer, which needs `pip install resynthesizer`)
# Needs jq and GNU time (/usr/bin/time); ../shared/data for the mesh and the photographs.
set -euo pipefail
cd "$(dirname "$0")/.."
out=bench-out/speed
cases=()
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out=$2; shift 2 ;;
    -*) echo "usage: benches/speed.sh [--out DIR] [CASE...]" >&2; exit 2 ;;
    *) cases+=("$1"); shift ;;
  esac
done
[ ${#cases[@]} -gt 0 ] || cases=(surface250k threads plane1024 plane2048 plane512 analysis512 analysisbtf search resynth)
shared=../shared/data
for need in "$shared/meshes/bunny-37k.off" "$shared/textures/skimage-gravel.png"; do
  [ -f "$need" ] || { echo "error: $need is missing (benches/speed.sh needs ../shared/data)" >&2; exit 1; }
done
cargo build --release
bin=$PWD/target/release/btfsynth
mkdir -p "$out"
table="$out/speed.md"
echo "| case | command | wall s | CPU s | peak MB | synthesis stage s |" >"$table"
echo "|---|---|---|---|---|---|" >>"$table"

# Runs `btfsynth ARGS...` under GNU time; appends a row named $1. A `--report FILE` among
# the arguments gives the synthesis stage.
row() {
  local name=$1; shift
  command_row "$name" "$bin" -q "$@"
}

# Runs any command under GNU time (CPU s: user + system) and appends a row named $1.
command_row() {
  local name=$1; shift
  local report="" prev=""
  for a in "$@"; do [ "$prev" = "--report" ] && report=$a; prev=$a; done
  /usr/bin/time -f "%e %M %U %S" -o "$out/time.txt" "$@" >/dev/null
  read -r wall kb user sys <"$out/time.txt"
  local stage="–"
  [ -n "$report" ] && stage=$(jq '[.levels[].seconds] | add | . * 100 | round / 100' "$report")
  local cpu
  cpu=$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.2f", u + s }')
  echo "| $name | \`$*\` | $wall | $cpu | $((kb / 1024)) | $stage |" |
    sed "s|$out/||g; s|$bin|btfsynth|g; s| -q | |" >>"$table"
}

# Inputs, made once: the 64² pebbles BTF (6,561 images) and its analysis; 512², 256² and
# 128² crops of a 512² photograph.
btf=$out/pebbles-btf
[ -d "$btf" ] || "$bin" -q gen pebbles --size 64 --directions ubo81 -o "$btf"
[ -d "$btf.analysis" ] || "$bin" -q analyze "$btf" -o "$btf.analysis"
photo=$shared/textures/skimage-gravel.png
for side in 512 256 128; do
  [ -d "$out/gravel$side.analysis" ] ||
    "$bin" -q analyze "$photo" --crop "0,0,$side,$side" -o "$out/gravel$side.analysis"
done

for c in "${cases[@]}"; do
  case $c in
    surface250k) row "250k-vertex surface, 2 threads" synth "$btf.analysis" "$shared/meshes/bunny-37k.off" \
      --vertices 250000 --report "$out/s250k.json" --force -o "$out/s250k.ply" ;;
    threads) for t in 1 2; do
      row "250k-vertex surface, $t thread(s)" --threads $t synth "$btf.analysis" "$shared/meshes/bunny-37k.off" \
        --vertices 250000 --report "$out/s250k-$t.json" --force -o "$out/s250k-$t.ply"
    done ;;
    plane1024) row "512² photo → 1024²" synth "$out/gravel512.analysis" --plane 1024x1024 \
      --report "$out/p1024.json" --force -o "$out/p1024" ;;
    plane2048) row "256² photo → 2048²" synth "$out/gravel256.analysis" --plane 2048x2048 \
      --report "$out/p2048.json" --force -o "$out/p2048" ;;
    plane512) row "128² photo → 512²" synth "$out/gravel128.analysis" --plane 512x512 \
      --report "$out/p512.json" --force -o "$out/p512" ;;
    analysis512) row "analysis of a 512² photo" analyze "$photo" --force -o "$out/a512" ;;
    analysisbtf) row "analysis of a 64² × 6,561-image BTF" analyze "$btf" --force -o "$out/abtf" ;;
    search) for s in kcoherence full; do
      row "128² → 256², --search $s" synth "$out/gravel128.analysis" --plane 256x256 --search $s \
        --report "$out/search-$s.json" --force -o "$out/search-$s"
    done ;;
    resynth)
      # CPU seconds, not wall: Resynthesizer runs on one core. Its canvas is 512², the sample
      # in a corner (scripts/resynth_peer.py --timing); btfsynth's analysis is paid once per
      # sample, so it has its own row.
      python3 -c "from PIL import Image; Image.open('$photo').convert('RGB').crop((0, 0, 128, 128)).save('$out/gravel128.png')"
      row "128² photo, analysis" analyze "$out/gravel128.png" --force -o "$out/gravel128-again.analysis"
      row "128² → 512², 1 thread" --threads 1 synth "$out/gravel128.analysis" --plane 512x512 \
        --report "$out/r512-1.json" --force -o "$out/r512-1"
      row "128² → 512², 2 threads" synth "$out/gravel128.analysis" --plane 512x512 \
        --report "$out/r512-2.json" --force -o "$out/r512-2"
      command_row "Resynthesizer, 128² in a 512² canvas" python3 scripts/resynth_peer.py --timing \
        "$out/gravel128.png" "$out/resynth512.png" 512 ;;
    *) echo "error: unknown case '$c'" >&2; exit 2 ;;
  esac
done
cat "$table"
