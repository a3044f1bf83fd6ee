#!/usr/bin/env bash
# A measured BTF at its real size (issue #21): builds a UBO2014-sized DFMF — pebbles
# generated at 96² on the 151-direction dome (22,801 images, one sample per pixel),
# converted with 32 components per channel, its texel factors tiled to 400² by
# scripts/tile_dfmf.py — and times `analyze` on it under /usr/bin/time -v:
#   - from the file's factors (the default): no crop (400²) and a 192² crop;
#   - from decoded images (`--decoded`): a 64² crop, where both paths fit, with the texton
#     maps' agreement and Γ's spectrum compared against the factor path on that crop.
# Then, with --use, the full 400² analysis at work: `synth` onto a 250k-vertex bunny
# (bunny-37k.off from ../shared/data), `render` at 1024² with shadows, `view --headless`
# (needs a wgpu adapter) and `export --size 2048`, and the crossover of the renderer's two
# ways to hold a factored sample (decoded when opened, or values computed from the factors,
# BTFSYNTH_DECODE_LIMIT=0) on 32², 48² and 64² crops of the file.
# With --folder, a 6,561-image folder of 512² EXRs (pebbles at 64² on the 81-direction
# dome, 32 components, tiled to 512², decoded by `convert`) and its streamed analysis.
# Prints Markdown tables (wall time, peak resident memory) and writes everything under
# OUT (default bench-out/big-btf). Needs python3 with numpy, and GNU time at /usr/bin/time.
# Not part of CI: the file takes minutes to build and the no-crop analysis minutes to run.
# --bin uses a btfsynth binary built before (e.g. a copy taken while sources change);
# --no-analyze skips the analyses of the file except the no-crop one that --use needs.
#   benches/big_btf.sh [--out DIR] [--bin FILE] [--skip-decoded] [--no-analyze] [--use] [--folder]
set -euo pipefail
cd "$(dirname "$0")/.."
out=bench-out/big-btf
decoded=1
analyze=1
use=0
folder=0
bin=
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out=$2; shift 2 ;;
    --bin) bin=$2; shift 2 ;;
    --skip-decoded) decoded=0; shift ;;
    --no-analyze) analyze=0; shift ;;
    --use) use=1; shift ;;
    --folder) folder=1; shift ;;
    *) echo "usage: benches/big_btf.sh [--out DIR] [--bin FILE] [--skip-decoded] [--no-analyze] [--use] [--folder]" >&2; exit 2 ;;
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
# Runs `btfsynth ARGS...` under GNU time as NAME; sets $wall, $cpu and $peak. Returns the
# command's status.
measured() {
  local name=$1 status=0
  shift
  /usr/bin/time -v -o "$out/$name.time" $bin -q "$@" 2>"$out/$name.log" || status=$?
  wall=$(awk -F': ' '/Elapsed \(wall clock\)/ {print $2}' "$out/$name.time")
  cpu=$(awk -F': ' '/User time/ {u=$2} /System time/ {s=$2} END {printf "%.1f s", u + s}' "$out/$name.time")
  peak=$(awk -F': ' '/Maximum resident set size/ {printf "%.2f GiB", $2 / 1048576}' "$out/$name.time")
  return $status
}

# `measured`, stopping the script when the command fails.
timed() {
  measured "$@" || { echo "error: $1 failed; see $out/$1.log" >&2; cat "$out/$1.log" >&2; exit 1; }
}

# Runs `analyze` with the given label and arguments; records its own estimate of the peak
# (the refusal line under a 1-byte budget), wall time and peak memory.
run() {
  local label=$1 name=$2
  shift 2
  local estimate
  estimate=$(BTFSYNTH_MEMORY=1 $bin -q analyze "$out/big400.btf" --force -o "$out/$name.analysis" "$@" 2>&1 |
    sed -n 's/.*would need about \(.*\) at its peak.*/\1/p' || true)
  timed "$name" analyze "$out/big400.btf" --force -o "$out/$name.analysis" "$@"
  rows+=("| $label | $wall | $cpu | $peak | $estimate |")
  echo "$label: $wall, $peak (estimated $estimate)" >&2
}

# What the decoded path says without a crop: one line, before any work.
started=$(date +%s.%N)
refusal=$($bin -q analyze "$out/big400.btf" --decoded --force -o "$out/refused.analysis" 2>&1 || true)
refused_s=$(echo "$(date +%s.%N) - $started" | bc)
echo "$refusal" >&2
if [ "$analyze" = 1 ] || [ ! -f "$out/full.analysis/analysis.json" ]; then
  run "\`analyze big400.btf\` (factors, no crop, 400²)" full
fi
if [ "$analyze" = 1 ]; then
  run "\`--crop 0,0,192,192\` (factors)" crop192 --crop 0,0,192,192
  run "\`--crop 0,0,64,64\` (factors)" crop64 --crop 0,0,64,64
else
  decoded=0
fi
if [ "$decoded" = 1 ]; then
  run "\`--crop 0,0,64,64 --decoded\` (decoded images)" crop64-decoded --crop 0,0,64,64 --decoded
fi

echo
echo "$(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GB", $2 / 1e6}' /proc/meminfo); $(du -h "$out/big400.btf" | cut -f1) file"
echo
echo "| command | wall | CPU | peak memory (measured) | peak (btfsynth's estimate) |"
echo "|---|---|---|---|---|"
printf '%s\n' "${rows[@]}"
printf '| `--decoded`, no crop | refused in %.2f s | — | — | see below |\n' "$refused_s"
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

if [ "$use" = 1 ]; then
  mesh=../shared/data/meshes/bunny-37k.off
  [ -f "$mesh" ] || { echo "error: $mesh is missing (--use needs ../shared/data)" >&2; exit 1; }
  use_rows=()
  # Adds a row for `btfsynth ARGS...` run under GNU time as NAME.
  use_row() {
    local label=$1 name=$2
    shift 2
    timed "$name" "$@"
    use_rows+=("| $label | $wall | $cpu | $peak |")
    echo "$label: $wall, $peak" >&2
  }
  use_row "\`synth\` onto bunny-37k, 250k vertices" synth synth "$out/full.analysis" "$mesh" --vertices 250000 \
    --force -o "$out/bunny250k.ply"
  use_row "\`render --size 1024x1024\` (shadows)" render render "$out/bunny250k.ply" --size 1024x1024 \
    --force -o "$out/render"
  # No wgpu adapter is not a failure of the benchmark: its one line goes in the table.
  if measured view view "$out/bunny250k.ply" --headless --size 1024x1024 --force -o "$out/view"; then
    use_rows+=("| \`view --headless --size 1024x1024\` | $wall | $cpu | $peak |")
  else
    use_rows+=("| \`view --headless\` | $(tail -1 "$out/view.log") | | |")
  fi
  use_row "\`export --size 2048\`" export export "$out/bunny250k.ply" --size 2048 --force -o "$out/bunny250k.glb"
  echo
  echo "| the full 400² analysis at work | wall | CPU | peak memory |"
  echo "|---|---|---|---|"
  printf '%s\n' "${use_rows[@]}"

  # The crossover: a 1024² render of a 20k-vertex bunny synthesized from a crop's analysis,
  # the sample decoded when opened against every value computed from the factors.
  echo
  echo "| crop (22,801 images) | decoded values | render, decoded when opened | render, from the factors |"
  echo "|---|---|---|---|"
  for side in 32 48 64; do
    name=cross$side
    $bin -q analyze "$out/big400.btf" --crop 0,0,$side,$side --levels 2 --force -o "$out/$name.analysis"
    $bin -q synth "$out/$name.analysis" "$mesh" --vertices 20000 --force -o "$out/$name.ply"
    BTFSYNTH_DECODE_LIMIT=unlimited timed "$name-decoded" render "$out/$name.ply" --size 1024x1024 --force -o "$out/$name-decoded"
    decoded_figures="$wall, $peak"
    BTFSYNTH_DECODE_LIMIT=0 timed "$name-factors" render "$out/$name.ply" --size 1024x1024 --force -o "$out/$name-factors"
    printf '| %d² | %.2f GiB | %s | %s |\n' "$side" "$(echo "$side * $side * 22801 * 12 / 1073741824" | bc -l)" \
      "$decoded_figures" "$wall, $peak"
  done
fi

if [ "$folder" = 1 ]; then
  # 6,561 images of 512²: pebbles at 64² on the 81-direction dome, factored and tiled as
  # the 400² file is, then decoded to one half-float EXR per image.
  if [ ! -f "$out/folder512/btf.json" ]; then
    $bin -q gen pebbles --size 64 --spp 1 --directions ubo81 --force -o "$out/pebbles64-81"
    $bin -q convert "$out/pebbles64-81" --to btf --components 32 --force -o "$out/pebbles64-81.btf"
    rm -rf "$out/pebbles64-81"
    python3 scripts/tile_dfmf.py "$out/pebbles64-81.btf" "$out/big512-81.btf" --size 512
    $bin -q convert "$out/big512-81.btf" --force -o "$out/folder512"
  fi
  timed folder analyze "$out/folder512" --force -o "$out/folder512.analysis"
  echo
  echo "| 6,561 × 512² EXR folder ($(du -sh "$out/folder512" | cut -f1)) | wall | CPU | peak memory |"
  echo "|---|---|---|---|"
  echo "| \`analyze folder512\` | $wall | $cpu | $peak |"
  grep -o 'analysed .*' "$out/folder.log" | tail -1 || true
fi
