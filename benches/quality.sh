#!/usr/bin/env bash
# The synthesis-quality benchmark (examples/quality.rs): btfsynth beside Embark's
# texture-synthesis on every photograph of ../shared/data/textures and on generated BTFs.
# Installs the peer into target/peer (the first time: a few minutes), builds btfsynth in
# release, and writes bench-out/quality/quality.md plus one montage per sample.
#   benches/quality.sh [--seeds N] [--only NAME] [--out DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
peer=target/peer/bin/texture-synthesis
if [ ! -x "$peer" ]; then
  # Without --locked the peer does not compile with today's crates.
  cargo install --locked texture-synthesis-cli --root target/peer
fi
cargo build --release
cargo run --release --example quality -- --peer "$peer" "$@"
