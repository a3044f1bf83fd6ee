#!/usr/bin/env bash
# Exports surface maps of the bundled data as glTF in every form `btfsynth export` writes
# (.glb and .gltf; a photograph with normal, roughness, occlusion and height maps; a BTF
# stack with its sample-coordinate map as PNG and EXR; per-vertex colours) and runs the
# Khronos glTF validator on each: any error fails the script.
#
#   scripts/check_export.sh            # validator only (needs node and npm)
#   BLENDER_CHECK=1 scripts/check_export.sh
#                                      # also imports one export into Blender, renders it and
#                                      # checks it is textured (needs `pip install bpy`)
#
# Uses target/release/btfsynth (built if missing). About a minute on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."

bin=target/release/btfsynth
[ -x "$bin" ] || cargo build --release
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
run() { "$bin" -q "$@"; }

# A photograph as a one-image BTF, with maps of the same size (the photograph itself stands
# in for them: the check is about the files, not the looks).
photo=data/gravel-128.png
run analyze "$photo" --crop 16,16,64,64 --textons 32 --levels 2 -o "$work/photo" \
  --maps "normal=$photo,roughness=$photo,occlusion=$photo,height=$photo"
run synth "$work/photo" data/bunny-1k8.obj --vertices 8000 -o "$work/photo.ply"
run export "$work/photo.ply" -o "$work/photo.glb"
run export "$work/photo.ply" -o "$work/photo.gltf" --size 512

# A small generated BTF stack on the teapot (four pieces, no UVs).
run gen pebbles --size 32 --directions grid:9 --spp 1 -o "$work/stack"
run analyze "$work/stack" --textons 32 --levels 2 -o "$work/btf"
run synth "$work/btf" data/teapot.obj --vertices 6000 -o "$work/btf.ply"
run export "$work/btf.ply" -o "$work/btf.glb" --light 45,30
run export "$work/btf.ply" -o "$work/btf.gltf" --format exr
run export "$work/btf.ply" -o "$work/btf-dense.glb" --vertex-colors

# Hierarchical pattern mapping: the user's mesh with its own coordinates into the sample,
# the sample itself (and its maps) as the textures; the stack tiles, so its texture repeats.
run synth "$work/photo" data/bunny-1k8.obj --method soler2002 -o "$work/soler.ply"
run export "$work/soler.ply" -o "$work/soler.glb"
run synth "$work/btf" data/teapot.obj --method soler2002 -o "$work/soler-btf.ply"
run export "$work/soler-btf.ply" -o "$work/soler-btf.gltf" --light 45,30

files=("$work/photo.glb" "$work/photo.gltf" "$work/btf.glb" "$work/btf.gltf" "$work/btf-dense.glb"
  "$work/soler.glb" "$work/soler-btf.gltf")
npm install --silent --no-audit --no-fund --prefix "$work/npm" gltf-validator >/dev/null
NODE_PATH="$work/npm/node_modules" node scripts/validate_gltf.mjs "${files[@]}"

if [ "${BLENDER_CHECK:-0}" = 1 ]; then
  python3 scripts/blender_check.py "$work/photo.glb" "$work/photo-render.png" --size 256 --samples 8
fi
