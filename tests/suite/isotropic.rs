//! Castellanos and Williams' isotropic neighbourhood (§3.12, issue #19): a striped sample
//! gives an isotropic result under `castellanos`, while the square-template presets keep
//! the stripes; and on real photographs the preset stays within the presets' limits.

use crate::common;

use btfsynth::synth::{Candidates, Preset, Stencil};
use common::btfsynth;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn run_ok(args: &[&str]) {
    let r = btfsynth(args);
    assert!(r.status.success(), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
}

/// The anisotropy of an image: (λ₁ − λ₂) / (λ₁ + λ₂) of its mean structure tensor (central
/// differences of the luminance), 1 for straight stripes, 0 for no preferred direction.
fn anisotropy(png: &Path) -> f64 {
    let img = image::open(png).unwrap().to_luma32f();
    let (w, h) = img.dimensions();
    let at = |x: u32, y: u32| f64::from(img.get_pixel(x, y)[0]);
    let (mut xx, mut xy, mut yy) = (0.0, 0.0, 0.0);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let gx = (at(x + 1, y) - at(x - 1, y)) / 2.0;
            let gy = (at(x, y + 1) - at(x, y - 1)) / 2.0;
            (xx, xy, yy) = (xx + gx * gx, xy + gx * gy, yy + gy * gy);
        }
    }
    let root = ((xx - yy) * (xx - yy) + 4.0 * xy * xy).sqrt();
    root / (xx + yy).max(f64::MIN_POSITIVE)
}

/// A 96² sample of horizontal stripes, 8 texels a period, analysed.
fn stripes(dir: &Path) -> PathBuf {
    let png = dir.join("stripes.png");
    common::write_png(&png, 96, 96, |_, y| {
        let v = (127.5 + 120.0 * (std::f64::consts::TAU * f64::from(y) / 8.0).sin()) as u8;
        [v, v / 2 + 60, 255 - v]
    });
    let analysis = dir.join("stripes");
    run_ok(&["-q", "analyze", s(&png), "-o", s(&analysis)]);
    analysis
}

/// The anisotropy of a 192² plane synthesized from `analysis` with `how` (flags).
fn result_anisotropy(analysis: &Path, out: &Path, how: &[&str]) -> f64 {
    run_ok(&[&["-q", "synth", s(analysis), "--plane", "192x192", "-o", s(out)], how].concat());
    anisotropy(&out.join("result.png"))
}

/// Stripes in, the isotropic variant out (§3.12, §5's Fig. 15–16): castellanos' result
/// has no strong direction, where tong2002 and castellanos' own schedule on the square
/// template reproduce the stripes.
#[test]
fn stripes_give_an_isotropic_result_under_castellanos() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = stripes(dir.path());
    assert!(anisotropy(&dir.path().join("stripes.png")) > 0.99);
    let mut square = Preset::castellanos();
    square.name = "castellanos-square".into();
    // The kd-trees hold isotropic neighbourhoods: on the square template the coarsest level
    // searches every candidate directly, as the preset did before them.
    let on_square = |r: &mut btfsynth::synth::PassRecord| {
        r.stencil = Stencil::Square;
        if r.candidates == Candidates::KdTrees {
            r.candidates = Candidates::Full;
        }
    };
    square.all_passes_mut().for_each(|p| *p = p.edited(on_square).unwrap());
    let recipe = common::write_recipe(&dir.path().join("square.json"), &square);
    let isotropic = result_anisotropy(&analysis, &dir.path().join("iso"), &["--preset", "castellanos"]);
    let tong = result_anisotropy(&analysis, &dir.path().join("tong"), &["--preset", "tong2002"]);
    let on_square = result_anisotropy(&analysis, &dir.path().join("square"), &["--recipe", s(&recipe)]);
    assert!(isotropic < 0.4, "castellanos: anisotropy {isotropic}");
    assert!(tong > 0.8 && on_square > 0.8, "tong2002 {tong}, castellanos on the square template {on_square}");
}

fn eval(analysis: &Path, result: &Path) -> Value {
    let r = btfsynth(&["eval", s(analysis), s(result), "--json"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    serde_json::from_slice(&r.stdout).unwrap()
}

/// Real photographs (stone33, and walnut, the burl-like one) cropped to 96², synthesized
/// at 192²: colour χ² at most 0.01 (the square template gave 0.0003–0.03 on the benchmark's
/// photographs, docs/castellanos.md), collapse at most 5% and smear at most 1% (every
/// preset's limits).
#[test]
fn castellanos_stays_within_the_limits_on_photographs() {
    let dir = tempfile::tempdir().unwrap();
    for photo in ["textures/gimp-Stone_stone33.png", "textures/gimp-Wood_walnut.png"] {
        let Some(path) = btfsynth::testdata::shared_data("castellanos_stays_within_the_limits", photo) else {
            return;
        };
        let name = Path::new(photo).file_stem().unwrap().to_str().unwrap();
        let analysis = dir.path().join(name);
        run_ok(&["-q", "analyze", s(&path), "--crop", "0,0,96,96", "-o", s(&analysis)]);
        let out = dir.path().join(format!("{name}-plane"));
        run_ok(&[
            "-q",
            "synth",
            s(&analysis),
            "--plane",
            "192x192",
            "--preset",
            "castellanos",
            "-o",
            s(&out),
        ]);
        let q = eval(&analysis, &out);
        let chi2 = q["probes"][0]["colour_chi2"].as_f64().unwrap();
        let (collapse, smear) =
            (q["coords"]["collapse"].as_f64().unwrap(), q["coords"]["smear"].as_f64().unwrap());
        assert!(
            chi2 <= 0.01 && collapse <= 0.05 && smear <= 0.01,
            "{name}: χ² {chi2}, collapse {collapse}, smear {smear}"
        );
    }
}
