//! `synth --plane --tileable-output`: the result repeats without a seam. Measured the way a
//! user meets a seam, on real photographs: the patch energy of the patches that cross the
//! wrap edge (where copies join) against the patch energy of the whole result, and against
//! the same join of an ordinary plane, which the measure must see.

use crate::common;

use btfsynth::eval::picture::wrap_seam_energy;
use btfsynth::eval::Picture;
use common::btfsynth;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn plane(analysis: &Path, out: &Path, seed: u64, extra: &[&str]) -> PathBuf {
    let seed = seed.to_string();
    let args = ["-q", "synth", s(analysis), "--plane", "160x160", "--seed", &seed, "-o", s(out)];
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
    Picture::read(path).unwrap()
}

/// The patch energy along the wrap edge of one plane, its whole patch energy, and the wrap
/// edge's energy of an ordinary plane of the same seed (head-on).
struct Seams {
    tiled_edge: f64,
    tiled_whole: f64,
    plain_edge: f64,
}

/// Tileable and ordinary planes of the analysis by `preset`, seeds 1–3. The patches along
/// two lines are a small sample (one seed's edge scores 0.5–2.4× its whole result over the
/// benchmark's photographs, mean 1.07), so the figures are summed over the seeds.
fn check_seams(analysis: &Path, dir: &Path, what: &str, preset: &str) {
    let samples_without_replacement =
        btfsynth::synth::Preset::by_name(preset).is_ok_and(|p| common::samples_without_replacement(&p));
    let what = &format!("{what}, {preset}");
    let mut sum = Seams { tiled_edge: 0.0, tiled_whole: 0.0, plain_edge: 0.0 };
    for seed in 1..=3 {
        let seams = seams_of_seed(analysis, &dir.join(format!("{what}-{seed}")), seed, preset);
        sum.tiled_edge += seams.tiled_edge;
        sum.tiled_whole += seams.tiled_whole;
        sum.plain_edge += seams.plain_edge;
    }
    let Seams { tiled_edge, tiled_whole, plain_edge } = sum;
    eprintln!(
        "{what}: wrap edge {tiled_edge:.5}, whole {tiled_whole:.5}, ordinary plane's edge {plain_edge:.5}"
    );
    assert!(
        tiled_edge <= 1.25 * tiled_whole,
        "{what}: the wrap edge shows ({tiled_edge} against {tiled_whole})"
    );
    // The measure sees the seam an ordinary plane makes when repeated: 1.8-2.5× the tileable
    // result's edge on the gravel (2.6× and more before the default's patches shrank, which
    // raised every result's own patch energy, the edge's floor).
    // A result that samples without replacement is as rough inside as along any line
    // (castellanos: 1.3× here), so only the first check applies to it.
    if !samples_without_replacement {
        assert!(plain_edge > 1.5 * tiled_edge, "{what}: ordinary {plain_edge} vs tileable {tiled_edge}");
    }
}

fn seams_of_seed(analysis: &Path, dir: &Path, seed: u64, preset: &str) -> Seams {
    let tiled =
        plane(analysis, &dir.with_extension("tiled"), seed, &["--tileable-output", "--preset", preset]);
    let plain = plane(analysis, &dir.with_extension("plain"), seed, &["--preset", preset]);
    let q = eval(analysis, &tiled);
    let c = &q["coords"];
    assert!(c["collapse"].as_f64().unwrap() <= 0.05, "{}: {q}", tiled.display());
    assert!(c["smear"].as_f64().unwrap() <= 0.01, "{}: {q}", tiled.display());
    assert!(eval(analysis, &plain)["probes"][0].get("wrap_seam_energy").is_none());
    let head_on = &q["probes"][0];

    let sample = picture(&tiled.join(first_sample(&tiled)));
    let edge = |dir: &Path| wrap_seam_energy(&picture(&dir.join("result.png")), &sample, false);
    let tiled_edge = head_on["wrap_seam_energy"].as_f64().unwrap();
    assert!(
        (edge(&tiled) - tiled_edge).abs() <= 0.05 * tiled_edge,
        "eval measures what the test does (8-bit PNG aside)"
    );
    Seams { tiled_edge, tiled_whole: head_on["patch_energy"].as_f64().unwrap(), plain_edge: edge(&plain) }
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
    for preset in btfsynth::synth::Preset::all() {
        check_seams(&analysis, dir.path(), "gravel", preset.name.as_str());
    }
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
        check_seams(&analysis, dir.path(), name, &btfsynth::synth::Preset::appearance().name);
    }
}

#[test]
fn tileable_output_needs_a_plane() {
    let r = btfsynth(&["synth", "a.analysis", common::BUNNY, "--tileable-output", "-o", "x.ply"]);
    common::assert_usage_error(&r, "--plane");
}
