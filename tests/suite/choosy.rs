//! Castellanos and Williams' claim for choosy sampling (§3.11, §5): against greedy argmin on
//! the same recipe, the result's colour histogram stays closer to the sample's. Run through
//! the CLI on real photographs: the bundled gravel, and the shared data's stone33, burlap
//! and pebbles where present.

use crate::common;

use btfsynth::synth::{Preset, Select};
use common::btfsynth;
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn run_ok(args: &[&str]) {
    let r = btfsynth(args);
    assert!(r.status.success(), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
}

/// The head-on colour χ² of a `size` plane synthesized from `analysis` by `recipe`.
fn colour_chi2(analysis: &Path, recipe: &Path, out: &Path, size: &str) -> f64 {
    run_ok(&["-q", "synth", s(analysis), "--plane", size, "--recipe", s(recipe), "-o", s(out)]);
    let r = btfsynth(&["eval", s(analysis), s(out), "--json"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let q: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    q["probes"][0]["colour_chi2"].as_f64().unwrap()
}

/// Choosy sampling's χ² and greedy argmin's on one photograph (crop `crop`, output `size`).
fn choosy_and_greedy(photo: &Path, crop: &str, size: &str, dir: &Path) -> (f64, f64) {
    let analysis = dir.join("analysis");
    run_ok(&["-q", "analyze", s(photo), "--crop", crop, "--textons", "64", "-o", s(&analysis)]);
    let choosy = Preset::castellanos();
    let mut greedy = choosy.clone();
    greedy.name = "castellanos-argmin".into();
    greedy.all_passes_mut().for_each(|p| p.select = Select::Argmin);
    let recipe = |p: &Preset| common::write_recipe(&dir.join(format!("{}.json", p.name)), p);
    (
        colour_chi2(&analysis, &recipe(&choosy), &dir.join("choosy"), size),
        colour_chi2(&analysis, &recipe(&greedy), &dir.join("greedy"), size),
    )
}

fn assert_choosy_keeps_the_histogram(photo: &Path, crop: &str, size: &str) {
    let dir = tempfile::tempdir().unwrap();
    let (choosy, greedy) = choosy_and_greedy(photo, crop, size, dir.path());
    assert!(choosy < greedy, "{}: choosy χ² {choosy} is not below argmin's {greedy}", photo.display());
}

#[test]
fn choosy_sampling_keeps_the_colour_histogram_closer_than_argmin_on_the_bundled_photo() {
    let gravel = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png"));
    assert_choosy_keeps_the_histogram(gravel, "0,0,96,96", "192x192");
}

#[test]
fn choosy_sampling_keeps_the_colour_histogram_closer_than_argmin_on_shared_photos() {
    for photo in
        ["textures/gimp-Stone_stone33.png", "textures/gimp-Fabric_burlap.png", "textures/sh3d-pebbles.jpg"]
    {
        let Some(path) = btfsynth::testdata::shared_data("choosy_sampling_keeps_the_histogram", photo) else {
            return;
        };
        assert_choosy_keeps_the_histogram(&path, "0,0,96,96", "192x192");
    }
}
