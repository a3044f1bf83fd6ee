//! `synth --plane --tileable-output`: the result repeats without a seam. Measured the way a
//! user meets a seam, on real photographs: the patch energy of the patches that cross the
//! wrap edge (where copies join) against the patch energy of the whole result, and against
//! the same join of an ordinary plane, which the measure must see.

mod common;

use btfsynth::eval::picture::wrap_seam_energy;
use btfsynth::eval::Picture;
use common::btfsynth;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn plane(analysis: &Path, out: &Path, extra: &[&str]) -> PathBuf {
    let args = ["-q", "synth", s(analysis), "--plane", "160x160", "--seed", "1", "-o", s(out)];
    let r = btfsynth(&[&args[..], extra].concat());
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    out.to_path_buf()
}

fn eval(analysis: &Path, result: &Path) -> Value {
    let r = btfsynth(&["eval", s(analysis), s(result), "--json"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    serde_json::from_slice(&r.stdout).unwrap()
}

fn picture(path: &Path) -> Picture {
    let rgb = image::open(path).unwrap().to_rgb32f();
    // PNG values are already sRGB-encoded, as the measures want them.
    Picture {
        width: rgb.width() as usize,
        height: rgb.height() as usize,
        rgb: rgb.pixels().map(|p| p.0).collect(),
    }
}

/// Seams of a tileable and an ordinary plane of the analysis, checked against each other.
fn check_seams(analysis: &Path, dir: &Path, what: &str) {
    let tiled = plane(analysis, &dir.join(format!("{what}-tiled")), &["--tileable-output"]);
    let plain = plane(analysis, &dir.join(format!("{what}-plain")), &[]);

    let q = eval(analysis, &tiled);
    let c = &q["coords"];
    assert!(c["collapse"].as_f64().unwrap() <= 0.05, "{what}: {q}");
    assert!(c["smear"].as_f64().unwrap() <= 0.01, "{what}: {q}");
    // A strip along two lines is a small sample: across seeds and photographs the seam's
    // energy is 0.74–1.78× the whole result's (mean 1.0); an ordinary plane's is 3–5×.
    for p in q["probes"].as_array().unwrap() {
        let (seam, inside) = (p["wrap_seam_energy"].as_f64().unwrap(), p["patch_energy"].as_f64().unwrap());
        eprintln!("{what}, {}: wrap seam {seam:.5}, whole result {inside:.5}", p["name"]);
        assert!(seam <= 1.5 * inside, "{what}, {}: the wrap edge shows ({seam} against {inside})", p["name"]);
    }
    assert!(eval(analysis, &plain)["probes"][0].get("wrap_seam_energy").is_none());

    // The measure sees the seam an ordinary plane makes when repeated.
    let sample = picture(&tiled.join(first_sample(&tiled)));
    let seam = |dir: &Path| wrap_seam_energy(&picture(&dir.join("result.png")), &sample, false);
    let (tiled_seam, plain_seam) = (seam(&tiled), seam(&plain));
    eprintln!("{what}: head-on wrap seam, tileable {tiled_seam:.5}, ordinary {plain_seam:.5}");
    assert!(plain_seam > 1.3 * tiled_seam, "{what}: ordinary {plain_seam} vs tileable {tiled_seam}");
}

/// The first `sample_*.png` the plane wrote (a one-image BTF writes only the head-on one).
fn first_sample(dir: &Path) -> String {
    let mut names = common::entries(dir);
    names.retain(|n| n.starts_with("sample_"));
    names.into_iter().next().expect("the plane shows its sample")
}

#[test]
fn tileable_planes_join_without_a_seam_on_the_bundled_photograph() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel(dir.path(), "gravel", "0,0,96,96");
    check_seams(&analysis, dir.path(), "gravel");
}

#[test]
fn tileable_planes_join_without_a_seam_on_shared_photographs() {
    let dir = tempfile::tempdir().unwrap();
    for photo in ["textures/gimp-Stone_stone33.png", "textures/sh3d-pebbles.jpg"] {
        let Some(path) = btfsynth::testdata::shared_data("tileable_planes_join_without_a_seam", photo) else {
            return;
        };
        let name = Path::new(photo).file_stem().unwrap().to_str().unwrap();
        let analysis = dir.path().join(name);
        let r = btfsynth(&["-q", "analyze", s(&path), "--crop", "0,0,96,96", "-o", s(&analysis)]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        check_seams(&analysis, dir.path(), name);
    }
}

#[test]
fn tileable_output_needs_a_plane() {
    let r = btfsynth(&["synth", "a.analysis", common::BUNNY, "--tileable-output", "-o", "x.ply"]);
    common::assert_usage_error(&r, "--plane");
}
