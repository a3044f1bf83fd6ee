#!/usr/bin/env bash
# The GPU passes against the CPU's (issue #24): each case once with `--device gpu` and once
# with `--device cpu`, their wall seconds and per-level synthesis seconds, and whether the
# outputs are the same bytes (they must be). A benchmark, never a test: run it where a
# hardware GPU is; on lavapipe it measures the software rasterizer.
#   benches/gpu.sh [--bin BTFSYNTH] [--out DIR] [--threads N] [CASE...]
# CASES (default: all): plane512 plane1024 plane2048 surface250k
# Needs ../shared/data (the 512² photograph and the 250k-vertex bunny's mesh).
set -euo pipefail
cd "$(dirname "$0")/.."
out=bench-out/gpu
bin=""
threads=()
cases=()
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --threads) threads=(--threads "$2"); shift 2 ;;
    -*) echo "usage: benches/gpu.sh [--bin BTFSYNTH] [--out DIR] [--threads N] [CASE...]" >&2; exit 2 ;;
    *) cases+=("$1"); shift ;;
  esac
done
shared=../shared/data
photo=$shared/textures/skimage-gravel.png
mesh=$shared/meshes/bunny-37k.off
for need in "$photo" "$mesh"; do
  [ -f "$need" ] || { echo "error: $need is missing (benches/gpu.sh needs ../shared/data)" >&2; exit 1; }
done
if [ -z "$bin" ]; then
  cargo build --release
  bin=$PWD/target/release/btfsynth
fi
mkdir -p "$out"
for side in 128 256 512; do
  [ -d "$out/gravel$side.analysis" ] ||
    "$bin" -q analyze "$photo" --crop "0,0,$side,$side" -o "$out/gravel$side.analysis"
done

# Runs `synth ARGS...` on both devices into OUT/NAME-DEVICE (a directory for a plane, a
# PLY for a surface); prints their times and compares what they wrote.
both() {
  local name=$1 suffix=$2; shift 2
  for device in gpu cpu; do
    local start=$EPOCHREALTIME
    "$bin" "${threads[@]}" synth "$@" --device "$device" -v --force -o "$out/$name-$device$suffix" \
      2>"$out/$name-$device.log"
    local wall
    wall=$(awk -v a="$start" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.2f", b - a }')
    local levels
    levels=$(grep -o 'level [0-9]*: [0-9]* vertices, [0-9.]* s' "$out/$name-$device.log" | awk '{printf "%s ", $5}')
    echo "$name --device $device: $wall s wall; synthesis levels (coarsest first): ${levels}s"
  done
  local files=("")
  [ -z "$suffix" ] && files=(/uv.npy /labels.npy)
  for f in "${files[@]}"; do
    cmp -s "$out/$name-gpu$suffix$f" "$out/$name-cpu$suffix$f" ||
      { echo "error: $name$f differs between the devices" >&2; exit 1; }
  done
  echo "$name: the same bytes on both devices"
}

[ ${#cases[@]} -gt 0 ] || cases=(plane512 plane1024 plane2048 surface250k)
for c in "${cases[@]}"; do
  case $c in
    plane512) both plane512 "" "$out/gravel128.analysis" --plane 512x512 ;;
    plane1024) both plane1024 "" "$out/gravel512.analysis" --plane 1024x1024 ;;
    plane2048) both plane2048 "" "$out/gravel256.analysis" --plane 2048x2048 ;;
    surface250k) both surface250k .ply "$out/gravel128.analysis" "$mesh" --vertices 250000 ;;
    *) echo "error: unknown case '$c' (plane512 plane1024 plane2048 surface250k)" >&2; exit 2 ;;
  esac
done
