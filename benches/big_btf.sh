#!/usr/bin/env bash
# A measured BTF at its real size (issue #21): builds a UBO2014-sized DFMF — pebbles
# generated at 96² on the 151-direction dome (22,801 images, one sample per pixel),
# converted with 32 components per channel, its texel factors tiled to 400² by
# scripts/tile_dfmf.py — and times `analyze` on it under /usr/bin/time -v:
#   - from the file's factors (the default): no crop (400²) and a 192² crop;
#   - from decoded images (`--decoded`): a 64² crop, where both paths fit, with the texton
#     maps' agreement and Γ's spectrum compared against the factor path on that crop.
# Prints a Markdown table (wall time, peak resident memory) and writes everything under
# OUT (default bench-out/big-btf). Needs python3 with numpy, and GNU time at /usr/bin/time.
# Not part of CI: the file takes minutes to build and the no-crop analysis minutes to run.
# --bin uses a btfsynth binary built before (e.g. a copy taken while sources change).
#   benches/big_btf.sh [--out DIR] [--bin FILE] [--skip-decoded]
set -euo pipefail
cd "$(dirname "$0")/.."
out=bench-out/big-btf
decoded=1
bin=
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out=$2; shift 2 ;;
    --bin) bin=$2; shift 2 ;;
    --skip-decoded) decoded=0; shift ;;
    *) echo "usage: benches/big_btf.sh [--out DIR] [--bin FILE] [--skip-decoded]" >&2; exit 2 ;;
  esac
done
[ -x /usr/bin/time ] || { echo "error: needs GNU time at /usr/bin/time" >&2; exit 1; }
if [ -z "$bin" ]; then
  cargo build --release
  bin=target/release/btfsynth
fi
[ -x "$bin" ] || { echo "error: $bin is not an executable" >&2; exit 1; }
mkdir -p "$out"

if [ ! -f "$out/big400.btf" ]; then
  [ -f "$out/pebbles96.btf" ] || {
    $bin -q gen pebbles --size 96 --spp 1 --directions ubo151 --force -o "$out/pebbles96"
    $bin -q convert "$out/pebbles96" --to btf --components 32 --force -o "$out/pebbles96.btf"
    rm -rf "$out/pebbles96"
  }
  python3 scripts/tile_dfmf.py "$out/pebbles96.btf" "$out/big400.btf" --size 400
fi

rows=()
# Runs `analyze` with the given label and arguments; records its own estimate of the peak
# (the refusal line under a 1-byte budget), wall time and peak memory.
run() {
  local label=$1 name=$2
  shift 2
  local estimate
  estimate=$(BTFSYNTH_MEMORY=1 $bin -q analyze "$out/big400.btf" --force -o "$out/$name.analysis" "$@" 2>&1 |
    sed -n 's/.*would need about \(.*\) at its peak.*/\1/p' || true)
  /usr/bin/time -v -o "$out/$name.time" $bin -q analyze "$out/big400.btf" --force -o "$out/$name.analysis" "$@" \
    2>"$out/$name.log" || { echo "error: $label failed; see $out/$name.log" >&2; cat "$out/$name.log" >&2; exit 1; }
  local wall peak
  wall=$(awk -F': ' '/Elapsed \(wall clock\)/ {print $2}' "$out/$name.time")
  peak=$(awk -F': ' '/Maximum resident set size/ {printf "%.2f GiB", $2 / 1048576}' "$out/$name.time")
  rows+=("| $label | $wall | $peak | $estimate |")
  echo "$label: $wall, $peak (estimated $estimate)" >&2
}

# What the decoded path says without a crop: one line, before any work.
started=$(date +%s.%N)
refusal=$($bin -q analyze "$out/big400.btf" --decoded --force -o "$out/refused.analysis" 2>&1 || true)
refused_s=$(echo "$(date +%s.%N) - $started" | bc)
echo "$refusal" >&2
run "\`analyze big400.btf\` (factors, no crop, 400²)" full
run "\`--crop 0,0,192,192\` (factors)" crop192 --crop 0,0,192,192
run "\`--crop 0,0,64,64\` (factors)" crop64 --crop 0,0,64,64
if [ "$decoded" = 1 ]; then
  run "\`--crop 0,0,64,64 --decoded\` (decoded images)" crop64-decoded --crop 0,0,64,64 --decoded
fi

echo
echo "$(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GB", $2 / 1e6}' /proc/meminfo); $(du -h "$out/big400.btf" | cut -f1) file"
echo
echo "| command | wall | peak memory (measured) | peak (btfsynth's estimate) |"
echo "|---|---|---|---|"
printf '%s\n' "${rows[@]}"
printf '| `--decoded`, no crop | refused in %.2f s | — | see below |\n' "$refused_s"
echo
echo "$refusal"

if [ "$decoded" = 1 ]; then
  # Agreement of the 64² analyses: texton maps (labels matched by overlap, both ways,
  # the smaller kept) and the leading eigenvalues of Γ, per level.
  python3 - "$out/crop64.analysis" "$out/crop64-decoded.analysis" <<'EOF'
import json, sys
import numpy as np
a_dir, b_dir = sys.argv[1:3]
levels = len(json.load(open(f"{a_dir}/analysis.json"))["levels"])
def agreement(a, b):
    def one(a, b):
        pairs = {}
        for x, y in zip(a, b):
            pairs[(x, y)] = pairs.get((x, y), 0) + 1
        best = {}
        for (x, _), c in pairs.items():
            best[x] = max(best.get(x, 0), c)
        return sum(best.values()) / len(a)
    return min(one(a, b), one(b, a))
print()
print("| 64² crop, level | texton map agreement (factors vs decoded) | Γ leading eigenvalues, largest relative difference |")
print("|---|---|---|")
for l in range(levels):
    ta = np.load(f"{a_dir}/level{l}_textons.npy").ravel()
    tb = np.load(f"{b_dir}/level{l}_textons.npy").ravel()
    ga = np.sort(np.linalg.eigvalsh(np.load(f"{a_dir}/level{l}_gamma.npy").astype(np.float64)))[::-1][:8]
    gb = np.sort(np.linalg.eigvalsh(np.load(f"{b_dir}/level{l}_gamma.npy").astype(np.float64)))[::-1][:8]
    print(f"| {l} | {agreement(list(ta), list(tb)):.3f} | {np.max(np.abs(ga - gb) / np.abs(ga)):.4f} |")
EOF
fi
