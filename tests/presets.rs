//! The engine's presets: golden outputs that pin each preset's behaviour (a change must be
//! deliberate and explained in its commit), the recipe recorded in every output, and
//! `--list-presets`.

mod common;

use common::btfsynth;
use std::path::{Path, PathBuf};

/// Per preset: FNV-1a 64 of the plane result (labels then coordinates) and of the surface
/// map's vertex labels and coordinates, for the fixed inputs of [`golden_inputs`].
const GOLDEN: &[(&str, u64, u64)] = &[
    ("appearance", 0x1613480722bf59cd, 0xfbcaf7b4d2a4eaf8),
    ("tong2002", 0x3af21d6038a3cc39, 0x51a76ee213269e44),
];

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn run_ok(args: &[&str]) {
    let r = btfsynth(args);
    assert!(r.status.success(), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
}

/// FNV-1a 64, a hash whose value never changes with the Rust release.
fn fnv(hash: &mut u64, bytes: &[u8]) {
    for &b in bytes {
        *hash ^= u64::from(b);
        *hash = hash.wrapping_mul(0x100_0000_01b3);
    }
}

fn state_hash(labels: &[u16], uv: &[[i32; 2]]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325;
    labels.iter().for_each(|l| fnv(&mut h, &l.to_le_bytes()));
    uv.iter().for_each(|c| c.iter().for_each(|v| fnv(&mut h, &v.to_le_bytes())));
    h
}

/// The analysis every golden output starts from: a 48² crop of the bundled gravel photo.
fn golden_inputs(dir: &Path) -> PathBuf {
    common::analyze_gravel_crop(dir, "analysis")
}

fn plane_hash(analysis: &Path, dir: &Path, preset: &str) -> u64 {
    let out = dir.join(format!("plane-{preset}"));
    run_ok(&[
        "-q",
        "synth",
        s(analysis),
        "--plane",
        "64x64",
        "--preset",
        preset,
        "--seed",
        "7",
        "-o",
        s(&out),
    ]);
    let (_, _, state, _) = btfsynth::synth::plane::read_plane(&out).unwrap();
    state_hash(&state.labels, &state.uv)
}

fn surface_hash(analysis: &Path, dir: &Path, preset: &str) -> u64 {
    let out = dir.join(format!("{preset}.ply"));
    run_ok(&[
        "-q",
        "synth",
        s(analysis),
        common::BUNNY,
        "--vertices",
        "3000",
        "--orient",
        "axis:0,1,0",
        "--preset",
        preset,
        "--seed",
        "7",
        "-o",
        s(&out),
    ]);
    let map = btfsynth::synth::surface_map::read_surface_ply(&out).unwrap();
    state_hash(&map.state.labels, &map.state.uv)
}

/// Every preset's output is pinned: a refactoring of the engine must not change it.
#[test]
fn every_preset_gives_its_golden_output() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = golden_inputs(dir.path());
    let mut wrong = Vec::new();
    for preset in btfsynth::synth::Preset::all() {
        let name = preset.name.to_string();
        let got = (plane_hash(&analysis, dir.path(), &name), surface_hash(&analysis, dir.path(), &name));
        let want = GOLDEN.iter().find(|g| g.0 == name).map(|g| (g.1, g.2));
        if want != Some(got) {
            wrong.push(format!("(\"{name}\", {:#018x}, {:#018x}) (pinned: {want:x?})", got.0, got.1));
        }
    }
    assert!(wrong.is_empty(), "outputs differ from the golden ones:\n{}", wrong.join("\n"));
}
