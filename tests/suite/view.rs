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

/// A surface map of a small factorized BTF: `gen pebbles --size 24 --directions ubo81
/// --spp 1` (6,561 images), `convert --to btf --components 8 --colour-model MODEL` for each
/// of `models`, each analysed from its factors (which stores the sample as factors) and
/// synthesized onto the bunny. Returns the surface map of each model.
fn factored_surfaces(dir: &Path, models: &[&str]) -> Vec<PathBuf> {
    let stack = dir.join("stack");
    let gen = ["-q", "gen", "pebbles", "--size", "24", "--directions", "ubo81", "--spp", "1", "-o"];
    let r = btfsynth(&[&gen[..], &[stack.to_str().unwrap()]].concat());
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let run = |args: &[&str]| {
        let r = btfsynth(args);
        assert!(r.status.success(), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
    };
    let path = |name: String| dir.join(name).to_str().unwrap().to_string();
    models
        .iter()
        .map(|model| {
            let (btf, analysis, surface) =
                (path(format!("m{model}.btf")), path(format!("m{model}")), path(format!("m{model}.ply")));
            let stack = stack.to_str().unwrap();
            run(&[
                "-q",
                "convert",
                stack,
                "--to",
                "btf",
                "--components",
                "8",
                "--colour-model",
                model,
                "-o",
                &btf,
            ]);
            run(&["-q", "analyze", &btf, "--textons", "8", "--levels", "1", "-o", &analysis]);
            run(&["-q", "synth", &analysis, common::BUNNY, "--texels-across", "64", "-o", &surface]);
            PathBuf::from(surface)
        })
        .collect()
}

/// Runs `view --headless` (one 256² frame under light 45,45) with `extra` arguments into
/// `out` and returns its stderr, or `None` (after the skip line) without an adapter.
fn headless_frame(test: &str, surface: &Path, mode: &str, extra: &[&str], out: &Path) -> Option<String> {
    let shot = ["--size", "256x256", "--light", "45,45", "--mode", mode, "--format", "exr"];
    let args = [
        &["-q", "view", surface.to_str().unwrap(), "--headless"][..],
        &shot,
        extra,
        &["-o", out.to_str().unwrap()],
    ];
    let g = btfsynth(&args.concat());
    let stderr = String::from_utf8_lossy(&g.stderr).to_string();
    if !g.status.success() && btfsynth::testdata::gpu_missing(test, &stderr) {
        return None;
    }
    assert!(g.status.success(), "{stderr}");
    Some(stderr)
}

#[test]
fn the_factor_path_draws_what_the_image_atlas_draws() {
    const TEST: &str = "the_factor_path_draws_what_the_image_atlas_draws";
    if btfsynth::testdata::gpu_skipped(TEST) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // RGB (the colour model is linear) and log-Y, U/Y, V/Y (the UBO2014 files' model: the
    // shader's exponentials and ratios).
    for (model, surface) in ["0", "11"].iter().zip(factored_surfaces(dir.path(), &["0", "11"])) {
        for mode in ["pixel", "vertex"] {
            let name = format!("model {model}, {mode} mode");
            let frames = |upload: &str| dir.path().join(format!("{model}-{mode}-{upload}"));
            let Some(images) =
                headless_frame(TEST, &surface, mode, &["--upload", "images"], &frames("images"))
            else {
                return;
            };
            let factors =
                headless_frame(TEST, &surface, mode, &["--upload", "factors"], &frames("factors")).unwrap();
            assert!(
                images.contains("sample images as an atlas") && factors.contains("sample factors"),
                "{factors}"
            );
            let cpu = frames("cpu");
            let shot = ["--size", "256x256", "--light", "45,45", "--mode", mode, "--format", "exr"];
            let r = btfsynth(
                &[&["-q", "render", surface.to_str().unwrap()][..], &shot, &["-o", cpu.to_str().unwrap()]]
                    .concat(),
            );
            assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
            let read = |d: PathBuf| read_rgb(&d.join("frame_0000.exr"));
            let (a, b, c) = (read(frames("images")), read(frames("factors")), read(cpu));
            let covered = b.iter().filter(|p| p.iter().any(|&v| v > 0.0)).count();
            assert!(covered > b.len() / 20, "{name}: the factor path shows the model ({covered} lit pixels)");
            let mean = c.iter().flatten().map(|&v| v as f64).sum::<f64>() / (3 * c.len()) as f64;
            let (gpu, cpu) = (mean_abs_difference(&a, &b), mean_abs_difference(&c, &b));
            eprintln!("{name}: mean |atlas − factors| = {gpu:.6}, mean |CPU − factors| = {cpu:.6} (mean value {mean:.4})");
            // The atlas holds f16 values, the factor path computes f32 ones: the frames differ
            // by that rounding and by nothing else (measured on lavapipe: 3–5·10⁻⁶ on a mean
            // value of 0.05–0.07, i.e. 6–7·10⁻⁵ of it).
            assert!(gpu < 5e-4 * mean, "{name}: the atlas and the factors differ by {gpu} on average");
            assert!(cpu < 0.02, "{name}: CPU and factor-path frames differ by {cpu} on average");
        }
    }
}

#[test]
fn a_scene_over_the_gpu_memory_limit_is_refused_with_one_line() {
    const TEST: &str = "a_scene_over_the_gpu_memory_limit_is_refused_with_one_line";
    if btfsynth::testdata::gpu_skipped(TEST) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let surface = &factored_surfaces(dir.path(), &["11"])[0];
    let out = dir.path().join("frames");
    // At 64² pixels the scene takes about 50 MiB with the atlas (30 MiB of it the 6,561
    // images of 24² on lavapipe, 36 MiB on an NVIDIA H200, whose larger textures lay the
    // tiles out otherwise), about 20 MiB with the factors (16 MiB of it the shadow map).
    let view = |limit: &str, upload: &str| {
        let args = ["view", surface.to_str().unwrap(), "--headless", "--size", "64x64", "--upload", upload];
        std::process::Command::new(env!("CARGO_BIN_EXE_btfsynth"))
            .args(args)
            .args(["-q", "-o", out.to_str().unwrap()])
            .env("BTFSYNTH_GPU_MEMORY", limit)
            .output()
            .unwrap()
    };
    let r = view("32M", "images");
    if !r.status.success() && btfsynth::testdata::gpu_missing(TEST, &String::from_utf8_lossy(&r.stderr)) {
        return;
    }
    assert_one_line_error(&r, "of GPU memory (sample images as an atlas: ");
    assert_one_line_error(&r, " MiB), more than its 32 MiB limit");
    assert_one_line_error(&r, "BTFSYNTH_GPU_MEMORY=32M); show the factors with --upload factors");
    assert!(!out.exists(), "nothing written");
    // The same limit holds the factors, and nothing holds anything.
    let r = view("32M", "factors");
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    std::fs::remove_dir_all(&out).unwrap();
    assert_one_line_error(
        &view("8M", "factors"),
        "of GPU memory (shadow map: 16 MiB), more than its 8 MiB limit",
    );
    // A bad value is the invocation's mistake, refused by every command (exit 2).
    common::assert_usage_error(&view("lots", "factors"), "BTFSYNTH_GPU_MEMORY='lots'");
    assert!(!out.exists(), "nothing written");
    // An analysis that stores images has no factors to show.
    let images = bunny_surface(dir.path());
    let r = btfsynth(&[
        "view",
        images.to_str().unwrap(),
        "--headless",
        "--upload",
        "factors",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_one_line_error(&r, "--upload factors: this analysis stores its sample as images");
}
