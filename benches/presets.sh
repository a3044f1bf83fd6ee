#!/usr/bin/env bash
# Every preset side by side (issue #11): each `synth --list-presets` preset on
# data/bunny-1k8.obj remeshed to 40k vertices, with two photographs of ../shared/data/textures
# (128² crops) and one generated BTF (64², 81 directions). Writes, under OUT:
#   presets.md       one row per preset and material: seconds per stage (remesh, frames,
#                    templates, synthesis per level) and every quality measure of `btfsynth eval`
#   soler2002.md     the same materials mapped by `--method soler2002` onto the original
#                    bunny (texture coordinates, no remesh): seconds, eval's patch energy,
#                    colour χ² and seam figure (border windows' energy over the interior's)
#   contact.png      rows: the sample (head-on, light at 45°, `btfsynth relight`), then the
#                    presets and soler2002; columns: materials (rendered with `btfsynth render`)
# --only PRESET (repeatable) runs those presets alone, without soler2002: their rows and
# sheet, for rerunning one preset without the others' hour of CPU.
# Needs jq and python3 with Pillow (for the contact sheet).
#   benches/presets.sh [--out DIR] [--vertices N] [--only PRESET]...
set -euo pipefail
cd "$(dirname "$0")/.."
out=bench-out/presets
vertices=40000
only=()
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out=$2; shift 2 ;;
    --vertices) vertices=$2; shift 2 ;;
    --only) only+=("$2"); shift 2 ;;
    *) echo "usage: benches/presets.sh [--out DIR] [--vertices N] [--only PRESET]..." >&2; exit 2 ;;
  esac
done
cargo build --release
bin=target/release/btfsynth
shared=../shared/data/textures
mkdir -p "$out"

# Materials: name and the stack it is analysed from.
materials=()
for photo in gimp-Stone_stone33.png sh3d-pebbles.jpg; do
  if [ -f "$shared/$photo" ]; then
    name=${photo%.*}; name=${name##*[-_]}
    [ -d "$out/$name.analysis" ] ||
      $bin -q analyze "$shared/$photo" --crop 0,0,128,128 --force -o "$out/$name.analysis"
    materials+=("$name")
  else
    echo "skipping $photo: not in $shared" >&2
  fi
done
if [ ! -d "$out/btf-pebbles.analysis" ]; then
  $bin -q gen pebbles --size 64 --directions ubo81 --force -o "$out/btf-pebbles"
  $bin -q analyze "$out/btf-pebbles" --force -o "$out/btf-pebbles.analysis"
fi
materials+=(btf-pebbles)
for m in "${materials[@]}"; do
  $bin -q relight "$out/$m.analysis" --view 0,0 --light 45,0 --force -o "$out/sample-$m.png"
done

presets=$($bin synth --list-presets | awk '{print $1}')
if [ ${#only[@]} -gt 0 ]; then
  for p in "${only[@]}"; do
    echo "$presets" | grep -qx "$p" || { echo "no preset named $p" >&2; exit 2; }
  done
  presets=$(printf '%s\n' "${only[@]}")
fi
table="$out/presets.md"
{
  echo "| preset | material | vertices | remesh s | frames s | templates s | synthesis s (coarsest → finest) | collapse | smear | copy | coherence | texton χ² | patch energy |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|"
} >"$table"
for preset in $presets; do
  for m in "${materials[@]}"; do
    ply="$out/$preset-$m.ply"
    $bin -q synth "$out/$m.analysis" data/bunny-1k8.obj --vertices "$vertices" --orient axis:0,1,0 \
      --preset "$preset" --report "$out/$preset-$m.report.json" --force -o "$ply"
    $bin eval "$out/$m.analysis" "$ply" --json >"$out/$preset-$m.eval.json"
    $bin -q render "$ply" --size 320x320 --format png --force -o "$out/render-$preset-$m"
    jq -r --arg p "$preset" --arg m "$m" --slurpfile q "$out/$preset-$m.eval.json" '
      def f: . * 1000 | round / 1000;
      [$p, $m, (.levels[-1].vertices | tostring),
       (.params.prepare_seconds.remesh | f | tostring), (.params.prepare_seconds.frames | f | tostring),
       (.params.prepare_seconds.templates | f | tostring),
       ([.levels[].seconds | f | tostring] | join(" → ")),
       ($q[0].coords.collapse | f | tostring), ($q[0].coords.smear | f | tostring),
       ($q[0].coords.copy | f | tostring), ($q[0].coords.coherence | f | tostring),
       ($q[0].textons.chi2 | f | tostring), ($q[0].probes[0].patch_energy * 10000 | round / 10000 | tostring)]
      | "| " + join(" | ") + " |"' "$out/$preset-$m.report.json" >>"$table"
  done
done
cat "$table"

# Soler et al. 2002, the method beside the presets: the sample's own texels mapped onto the
# original mesh by texture coordinates, rendered and scored like the presets' results, at
# the presets' scale (one texel per finest vertex spacing of the first preset's run).
first=$(echo "$presets" | head -1)
methods=soler2002
[ ${#only[@]} -gt 0 ] && methods=
soler_table="$out/soler2002.md"
{
  echo "| method | material | faces | seconds | patch energy | colour χ² | seam ratio (border / interior windows) |"
  echo "|---|---|---|---|---|---|---|"
} >"$soler_table"
for m in "${materials[@]}"; do
  [ -n "$methods" ] || break
  ply="$out/soler2002-$m.ply"
  scale=$(jq '1 / .params.mesh_levels[0].texel' "$out/$first-$m.report.json")
  $bin -q synth "$out/$m.analysis" data/bunny-1k8.obj --method soler2002 --scale "$scale" \
    --report "$out/soler2002-$m.report.json" --force -o "$ply"
  $bin eval "$out/$m.analysis" "$ply" --json >"$out/soler2002-$m.eval.json"
  $bin -q render "$ply" --size 320x320 --format png --force -o "$out/render-soler2002-$m"
  jq -r --arg m "$m" --slurpfile q "$out/soler2002-$m.eval.json" '
    def f: . * 10000 | round / 10000;
    ["soler2002", $m, (.faces | tostring), (.seconds * 100 | round / 100 | tostring),
     ($q[0].probes[0].patch_energy | f | tostring), ($q[0].probes[0].colour_chi2 | f | tostring),
     (if $q[0].seams then ($q[0].seams.border / $q[0].seams.interior * 100 | round / 100 | tostring) else "–" end)]
    | "| " + join(" | ") + " |"' "$out/soler2002-$m.report.json" >>"$soler_table"
done
cat "$soler_table"

python3 - "$out" "${materials[*]}" $presets $methods <<'EOF'
import glob, os, sys
from PIL import Image, ImageDraw
out, materials, presets = sys.argv[1], sys.argv[2].split(), sys.argv[3:]
cell, label = 320, 110
sheet = Image.new("RGB", (label + cell * len(materials), 24 + cell * (1 + len(presets))), "white")
draw = ImageDraw.Draw(sheet)
draw.text((8, 24 + cell // 2), "sample", fill="black")
for j, m in enumerate(materials):
    draw.text((label + j * cell + 8, 6), m, fill="black")
    sample = Image.open(os.path.join(out, f"sample-{m}.png")).convert("RGB")
    sheet.paste(sample.resize((cell, cell), Image.BICUBIC), (label + j * cell, 24))
for i, p in enumerate(presets, start=1):
    draw.text((8, 24 + i * cell + cell // 2), p, fill="black")
    for j, m in enumerate(materials):
        frames = sorted(glob.glob(os.path.join(out, f"render-{p}-{m}", "*.png")))
        frames = [f for f in frames if "contact" not in os.path.basename(f)] or frames
        if frames:
            image = Image.open(frames[0]).convert("RGB")
            w, h = image.size  # the model fills the middle of the frame
            image = image.crop((w // 8, h // 8, w - w // 8, h - h // 8))
            sheet.paste(image.resize((cell, cell)), (label + j * cell, 24 + i * cell))
sheet.save(os.path.join(out, "contact.png"))
print("wrote", os.path.join(out, "contact.png"))
EOF
