//! `view --headless`: the GPU renderer draws what the CPU renderer draws, and bad input is
//! refused with one line and nothing written.
//!
//! The GPU comparison needs a wgpu adapter (Mesa's lavapipe or llvmpipe is enough). Without
//! one it prints one line and passes, unless `BTFSYNTH_REQUIRE_GPU=1` (set by CI) makes that
//! a failure; `BTFSYNTH_SKIP_GPU=1` skips it outright (see `btfsynth::testdata`). CI runs
//! this file twice: on Vulkan and with `WGPU_BACKEND=gl`.
#![cfg(feature = "gpu")]

use crate::common;

use common::{assert_one_line_error, btfsynth};
use std::path::{Path, PathBuf};

/// A small bunny surface map synthesized from the gravel analysis.
fn bunny_surface(dir: &Path) -> PathBuf {
    let analysis = common::analyze_gravel_crop(dir, "analysis");
    let surface = dir.join("bunny.ply");
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/data/bunny-1k8.obj");
    let args = ["-q", "synth", analysis.to_str().unwrap(), bunny, "--texels-across", "64", "-o"];
    let r = btfsynth(&[&args[..], &[surface.to_str().unwrap()]].concat());
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    surface
}

/// Linear RGB of every pixel of an EXR frame.
fn read_rgb(path: &Path) -> Vec<[f32; 3]> {
    let image = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgba32f();
    image.pixels().map(|p| [p[0], p[1], p[2]]).collect()
}

fn mean_abs_difference(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    assert_eq!(a.len(), b.len());
    let sum: f64 =
        a.iter().zip(b).map(|(x, y)| (0..3).map(|c| (x[c] - y[c]).abs() as f64).sum::<f64>()).sum();
    sum / (3 * a.len()) as f64
}

#[test]
fn gpu_frames_match_cpu_frames_in_both_modes() {
    const TEST: &str = "gpu_frames_match_cpu_frames_in_both_modes";
    if btfsynth::testdata::gpu_skipped(TEST) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let surface = bunny_surface(dir.path());
    let s = surface.to_str().unwrap();
    // Both modes under the directional light, and both under the sky (sun and environment).
    for (mode, lighting) in [("pixel", "sun"), ("vertex", "sun"), ("pixel", "sky"), ("vertex", "sky")] {
        let env: &[&str] = if lighting == "sky" { &["--env", "sky"] } else { &[] };
        let shot =
            [&["--size", "256x256", "--light", "45,45", "--mode", mode, "--format", "exr"][..], env].concat();
        let name = format!("{mode}-{lighting}");
        let (cpu, gpu) = (dir.path().join(format!("cpu-{name}")), dir.path().join(format!("gpu-{name}")));
        let r = btfsynth(&[&["-q", "render", s][..], &shot, &["-o", cpu.to_str().unwrap()]].concat());
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let g =
            btfsynth(&[&["-q", "view", s, "--headless"][..], &shot, &["-o", gpu.to_str().unwrap()]].concat());
        if !g.status.success() && btfsynth::testdata::gpu_missing(TEST, &String::from_utf8_lossy(&g.stderr)) {
            return;
        }
        assert!(g.status.success(), "{}", String::from_utf8_lossy(&g.stderr));
        let stderr = String::from_utf8_lossy(&g.stderr);
        assert!(stderr.contains("ms per frame"), "{stderr}");
        let (a, b) = (read_rgb(&cpu.join("frame_0000.exr")), read_rgb(&gpu.join("frame_0000.exr")));
        let covered = b.iter().filter(|p| p.iter().any(|&c| c > 0.0)).count();
        assert!(covered > a.len() / 20, "{name}: the GPU frame shows the model ({covered} lit pixels)");
        let mad = mean_abs_difference(&a, &b);
        eprintln!("{name}: mean |CPU − GPU| = {mad:.5}");
        assert!(mad < 0.02, "{name}: CPU and GPU frames differ by {mad} on average");
        assert!(gpu.join("contact.png").is_file());
    }
}

#[test]
fn headless_view_refuses_bad_input_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let surface = bunny_surface(dir.path());
    let s = surface.to_str().unwrap();
    let out = dir.path().join("frames");
    let o = out.to_str().unwrap();
    let before = common::entries(dir.path());
    common::assert_usage_error(&btfsynth(&["view", s, "--headless"]), "--output <DIR>");
    let missing_parent = dir.path().join("no/such/dir/frames");
    assert_one_line_error(
        &btfsynth(&["view", s, "--headless", "-o", missing_parent.to_str().unwrap()]),
        "does not exist",
    );
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let r = btfsynth(&["view", s, "--headless", "--analysis", empty.to_str().unwrap(), "-o", o]);
    assert_one_line_error(&r, "analysis");
    assert!(!out.exists(), "nothing written");
    let mut after = common::entries(dir.path());
    after.retain(|e| e != "empty");
    assert_eq!(before, after, "no staging directory left behind");
}

#[test]
fn the_window_without_a_display_says_to_use_headless() {
    let dir = tempfile::tempdir().unwrap();
    let surface = bunny_surface(dir.path());
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_btfsynth"))
        .args(["view", surface.to_str().unwrap()])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("WAYLAND_SOCKET")
        .output()
        .unwrap();
    assert_one_line_error(&out, "--headless");
}
