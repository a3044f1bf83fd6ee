//! Helpers shared by the integration tests: running the real CLI and writing fixtures.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs the built `btfsynth` binary with `args`.
pub fn btfsynth(args: &[&str]) -> Output {
    btfsynth_in(Path::new("."), args)
}

/// Runs the built `btfsynth` binary with `args` in the working directory `dir`, under the
/// log filter a user gets by default (not the developer's `RUST_LOG`).
pub fn btfsynth_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_btfsynth"))
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_LOG")
        .output()
        .expect("the btfsynth binary runs")
}

/// Asserts the run failed with exactly one line on stderr that mentions `needle`, and no
/// panic.
pub fn assert_one_line_error(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure, got success; stderr: {stderr}");
    assert_eq!(out.status.code(), Some(1), "stderr: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "expected one error line, got: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    assert!(lines[0].contains(needle), "error line should mention {needle:?}: {stderr}");
    assert!(!stderr.contains("panicked") && !stderr.contains("internal error"), "{stderr}");
}

/// Asserts the run was refused as a usage error: exit code 2 and one line on stderr that
/// mentions `needle`.
pub fn assert_usage_error(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "a usage error exits 2; stderr: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "expected one error line, got: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    assert!(lines[0].contains(needle), "error line should mention {needle:?}: {stderr}");
    assert!(!stderr.contains("panicked") && !stderr.contains("internal error"), "{stderr}");
}

/// Writes an 8-bit RGB PNG whose pixel (x, y) is `f(x, y)`.
pub fn write_png(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) {
    let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb(f(x, y)));
    img.save(path).expect("fixture PNG is written");
}

/// A deterministic test pattern distinct per `seed`.
pub fn pattern(seed: u32) -> impl Fn(u32, u32) -> [u8; 3] {
    move |x, y| {
        let v = x.wrapping_mul(37).wrapping_add(y.wrapping_mul(91)).wrapping_add(seed.wrapping_mul(53));
        [(v % 251) as u8, ((v / 3) % 241) as u8, ((v * 7) % 239) as u8]
    }
}

/// Names of the entries of `dir` (to check nothing was left behind).
pub fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|rd| rd.filter_map(|e| e.ok()).map(|e| e.file_name().to_string_lossy().into_owned()).collect())
        .unwrap_or_default();
    v.sort();
    v
}

/// Analyses a 48×48 crop of the bundled gravel photograph (32 textons, 2 levels) into
/// `dir/name`: a small real analysis for synthesis tests.
pub fn analyze_gravel_crop(dir: &Path, name: &str) -> std::path::PathBuf {
    analyze_gravel(dir, name, "0,0,48,48")
}

/// Analyses the rectangle `crop` ("x,y,w,h") of the bundled gravel photograph (32
/// textons, 2 levels) into `dir/name`.
pub fn analyze_gravel(dir: &Path, name: &str, crop: &str) -> std::path::PathBuf {
    let out = dir.join(name);
    let texture = concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png");
    let args = ["-q", "analyze", texture, "--crop", crop, "--textons", "32", "--levels", "2", "-o"];
    let r = btfsynth(&[&args[..], &[out.to_str().unwrap()]].concat());
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    out
}

/// The bundled 1,839-vertex Stanford bunny.
pub const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/bunny-1k8.obj");

/// The presets whose passes match square templates, the ones [`colour_recipe`] recolours
/// (round-neighbourhood passes compare appearance vectors only).
pub fn square_presets() -> Vec<btfsynth::synth::Preset> {
    btfsynth::synth::Preset::all().into_iter().filter(|p| !p.rounds()).collect()
}

/// `preset` with every pass matched on colour SSD (`MetricKind::Colour`, reached only
/// through `synth --recipe`), named `<preset>-colour`.
pub fn colour_recipe(preset: &btfsynth::synth::Preset) -> btfsynth::synth::Preset {
    let mut p = preset.clone();
    p.name = format!("{}-colour", p.name);
    for pass in p.coarsest.passes.iter_mut().chain(&mut p.finer.passes) {
        *pass = pass
            .edited(|r| r.metric = btfsynth::synth::MetricKind::Colour)
            .expect("a square pass takes colours");
    }
    p
}

/// Writes `preset` where `synth --recipe` reads it, as `synth` records it.
pub fn write_recipe(path: &Path, preset: &btfsynth::synth::Preset) -> std::path::PathBuf {
    std::fs::write(path, serde_json::to_string_pretty(&preset.to_json()).unwrap()).unwrap();
    path.to_path_buf()
}

/// Whether `preset` selects by Castellanos and Williams' use penalty (sampling without
/// replacement, texel by texel): its results keep the sample's statistics but not its exact
/// patches, so the checks that need a verbatim reproduction, or a result smooth enough for
/// a repeated plane's seam to stand out, do not apply to it (docs/castellanos.md).
pub fn samples_without_replacement(preset: &btfsynth::synth::Preset) -> bool {
    preset.all_passes().any(|p| matches!(p.select, btfsynth::synth::Select::UsePenalty { .. }))
}
