#!/usr/bin/env bash
# The surface benchmark (issue 44; not in CI): shared photographs on shared meshes by three
# routes, judged as a user sees them, beside each other:
#   default    btfsynth synth PHOTO MESH -> export (the user's mesh, a baked atlas)
#   soler2002  btfsynth synth --method soler2002 -> export (UVs into the sample itself)
#   triplanar  Embark's texture-synthesis --tiling at 2x the sample's side, box-projected
#              (blend 0.2) in Blender at the same texels per unit
# Each route is rendered by Blender (Cycles on the CPU, same sun, world and cameras: the whole
# model and a close-up, scripts/surfaces_render.py), the renders put in one montage per case
# (rows: routes; columns: whole, close-up), and the btfsynth routes' exported textures judged
# by `btfsynth eval ANALYSIS MODEL.glb` (smeared share, detail, contrast, colour against the
# sample at the same texels per sample texel) and the repetition `eval` scores from each
# result's own coordinates (on a plane's scale). Their table is appended to
# OUT/table.md (delete it for a fresh one), so runs with other MESHES or PHOTOS add rows.
#
#   benches/surfaces.sh [OUT]        (default target/surfaces)
# Environment: PHOTOS, MESHES (names under ../shared/data), ACROSS (sample texels across the
# mesh's largest side, as a multiple of the sample's width; default 4, synth's own default),
# TEXELS (sample texels across, the same for every photo; overrides ACROSS),
# SIZE (render side, 384), SAMPLES (Cycles samples, 16), BLENDER=0 (figures only), PEER
# (texture-synthesis binary; default target/peer/bin/texture-synthesis, else none).
#
# Setup, once: cargo build --release; python3 -m venv target/bpy-venv &&
# target/bpy-venv/bin/pip install bpy numpy pillow; cargo install --locked
# texture-synthesis-cli --root target/peer. Run it under `nice`: it is long on 2 cores.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/target/surfaces}
data=$root/../shared/data
bin=$root/target/release/btfsynth
py=$root/target/bpy-venv/bin/python
peer=${PEER:-$root/target/peer/bin/texture-synthesis}
photos=${PHOTOS:-"gimp-Stone_marble2.png gimp-Wood_walnut.png sh3d-pebbles.jpg sh3d-redTiles.jpg gimp-Stone_cracked.png gimp-Fabric_burlap.png gimp-Stone_amethyst.png gimp-Wood_wood1.png"}
meshes=${MESHES:-"bunny-1k8.obj cow.off dragon-10k.off"}
across=${ACROSS:-4}
size=${SIZE:-384}
samples=${SAMPLES:-16}
mkdir -p "$out"
table=$out/table.md
[ -f "$table" ] || {
  echo "| photo | mesh | texels | route | smeared | detail | contrast | colour chi2 | repetition | synth s | export s |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|"
} > "$table"

figures() { # analysis model.glb -> "smeared | detail | contrast | chi2"
  "$bin" -q eval "$1" "$2" --json | "$py" -c 'import json,sys; t=json.load(sys.stdin)["texture"]; print("%.3f | %.3f | %.3f | %.4f" % (t["smeared"], t["detail"], t["contrast"], t["colour_chi2"]))'
}
repetition() { # analysis result.ply -> its repetition ("-" where eval has none)
  "$bin" -q eval "$1" "$2" --no-texture --json | "$py" -c 'import json,sys; r=json.load(sys.stdin)["probes"][0]["repetition"]; print("-" if r is None else "%.4f" % r)'
}
seconds() { local s=$(date +%s.%N); "$@" > /dev/null; echo "$(date +%s.%N) - $s" | bc; }

for photo in $photos; do
  name=${photo%.*}
  an=$out/$name.analysis
  [ -d "$an" ] || "$bin" -q analyze "$data/textures/$photo" -o "$an"
  width=$("$py" -c "from PIL import Image; print(Image.open('$data/textures/$photo').size[0])")
  texels=${TEXELS:-$((across * width))}
  tile=$out/$name-tile.png
  if [ -x "$peer" ] && [ ! -f "$tile" ]; then
    "$peer" --out-size $((2 * width)) --tiling -o "$tile" generate "$data/textures/$photo" > /dev/null
  fi
  for mesh in $meshes; do
    case=$out/$name-${mesh%.*}
    row=()
    for route in default soler2002; do
      extra=(); [ $route = soler2002 ] && extra=(--method soler2002)
      ts=$(seconds "$bin" -q synth "$an" "$data/meshes/$mesh" --texels-across "$texels" "${extra[@]}" -o "$case-$route.ply" --force)
      te=$(seconds "$bin" -q export "$case-$route.ply" -o "$case-$route.glb" --force)
      echo "| $name | ${mesh%.*} | $texels | $route | $(figures "$an" "$case-$route.glb") | $(repetition "$an" "$case-$route.ply") | $ts | $te |" >> "$table"
      if [ "${BLENDER:-1}" = 1 ]; then
        "$py" "$root/scripts/surfaces_render.py" "$case-$route.glb" "$case-$route" --size "$size" --samples "$samples" > /dev/null
        row+=("$case-$route")
      fi
    done
    if [ "${BLENDER:-1}" = 1 ] && [ -f "$tile" ]; then
      # The same texels per unit as the btfsynth routes: the surface map's own.
      tpu=$("$py" -c "import json,struct; b=open('$case-default.glb','rb').read(); n=struct.unpack('<I',b[12:16])[0]; j=json.loads(b[20:20+n]); print(1/j['materials'][0]['extras']['btfsynth']['sampleTexel'])")
      "$py" "$root/scripts/surfaces_render.py" "$case-default.glb" "$case-triplanar" --triplanar "$tile" --texels-per-unit "$tpu" --size "$size" --samples "$samples" > /dev/null
      row+=("$case-triplanar")
      echo "| $name | ${mesh%.*} | $texels | triplanar | (rendered only) | | | | | | |" >> "$table"
    fi
    if [ ${#row[@]} -gt 0 ]; then
      "$py" - "$case-montage.png" "${row[@]}" <<'PY'
import sys
from PIL import Image
out, rows = sys.argv[1], sys.argv[2:]
pics = [[Image.open(f"{r}-{v}.png").convert("RGB") for v in ("whole", "close")] for r in rows]
w, h = pics[0][0].size
sheet = Image.new("RGB", (2 * w, len(rows) * h))
for i, row in enumerate(pics):
    for j, p in enumerate(row):
        sheet.paste(p, (j * w, i * h))
sheet.save(out)
PY
    fi
  done
done
cat "$table"
