#!/usr/bin/env bash
# The synthesis-quality benchmark (examples/quality.rs): btfsynth beside two peers, Embark's
# texture-synthesis and Resynthesizer (the C engine of GIMP's plug-in), on every photograph
# of ../shared/data/textures at its own size (at most 256² of it) → 4× and as a 128² crop,
# and on generated BTFs; the summary gives repetition per band of sample sizes. Installs the peers into target/peer (the
# first time: a few minutes): Embark's with cargo, Resynthesizer with pip into a venv.
# Resynthesizer is GPL: it is only ever run as an outside program (scripts/resynth_peer.py),
# never linked or shipped. Writes bench-out/quality/quality.md plus one montage per sample
# (sample | Embark | Resynthesizer | btfsynth).
#   benches/quality.sh [--seeds N] [--only NAME] [--out DIR] [--set own|crops|gen|all]
set -euo pipefail
cd "$(dirname "$0")/.."
peer=target/peer/bin/texture-synthesis
if [ ! -x "$peer" ]; then
  # Without --locked the peer does not compile with today's crates.
  cargo install --locked texture-synthesis-cli --root target/peer
fi
venv=target/peer/resynth-venv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import resynthesizer' 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q resynthesizer pillow
fi
cargo build --release
cargo run --release --example quality -- --peer "$peer" \
  --resynth "$venv/bin/python scripts/resynth_peer.py" "$@"
