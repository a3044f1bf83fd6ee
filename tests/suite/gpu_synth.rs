//! Synthesis passes on the GPU (`synth --device gpu`, `src/synth/gpu`): the same coordinates
//! as the CPU for a seed, byte for byte, on every level of the presets whose passes have a
//! GPU form (`appearance` and `tong2002`, on planes and meshes), and on a recipe
//! that reaches the other branches of the shader (colour metric, wide parent template,
//! argmin, full search).
//!
//! The comparisons need a wgpu adapter (Mesa's lavapipe is enough, and slow: the sizes here
//! are small). Without one each prints one line and passes, unless `BTFSYNTH_REQUIRE_GPU=1`
//! (set by CI) makes that a failure; `BTFSYNTH_SKIP_GPU=1` skips them outright (see
//! `btfsynth::testdata`). The refusals without an adapter need none.
#![cfg(feature = "gpu")]

use crate::common;

use btfsynth::progress::Silent;
use btfsynth::synth::neighbourhood::{OwnPixels, ParentTemplate, SquareMetric, SquareTemplate};
use btfsynth::synth::plane::{synthesize_plane, PlaneResult};
use btfsynth::synth::{Candidates, Device, Neighbourhood, Preset, Sample, Select, Start, SynthParams};
use std::path::Path;
use std::process::{Command, Output};

/// A backend wgpu cannot find on this system, so that it finds no adapter at all.
const ABSENT_BACKEND: &str = if cfg!(target_os = "macos") { "dx12" } else { "metal" };

/// `btfsynth args` with `WGPU_BACKEND` set to `backend`, if given.
fn btfsynth_with(backend: Option<&str>, args: &[&str]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_btfsynth"));
    command.args(args).env_remove("RUST_LOG");
    if let Some(b) = backend {
        command.env("WGPU_BACKEND", b);
    }
    command.output().expect("the btfsynth binary runs")
}

/// The plane on `device`, or `None` (after one line) where the GPU is missing and may be.
fn plane(
    test: &str,
    sample: &Sample,
    size: (usize, usize),
    tiles: bool,
    params: &SynthParams,
) -> Option<PlaneResult> {
    match synthesize_plane(sample, size, tiles, params, &Silent) {
        Ok(result) => Some(result),
        Err(e) if btfsynth::testdata::gpu_missing(test, &e.to_string()) => None,
        Err(e) => panic!("{test}: {e}"),
    }
}

/// Synthesizes `size` on the CPU and on the GPU and asserts the same labels, coordinates and
/// per-level figures; every level ran on the GPU. False if the GPU is missing.
fn same_on_both(test: &str, sample: &Sample, size: (usize, usize), tiles: bool, params: SynthParams) -> bool {
    let cpu = plane(test, sample, size, tiles, &SynthParams { device: Device::Cpu, ..params.clone() })
        .expect("the CPU is always there");
    let Some(gpu) = plane(test, sample, size, tiles, &SynthParams { device: Device::Gpu, ..params.clone() })
    else {
        return false;
    };
    let name = &params.preset.name;
    assert!(cpu.state.uv == gpu.state.uv, "{test} {name}: the GPU's coordinates differ from the CPU's");
    assert!(cpu.state.labels == gpu.state.labels, "{test} {name}: the GPU's labels differ");
    for (c, g) in cpu.reports.iter().zip(&gpu.reports) {
        assert_eq!(c.mean_candidates.to_bits(), g.mean_candidates.to_bits(), "{name} level {}", c.level);
        assert_eq!(
            c.mean_best_distance.to_bits(),
            g.mean_best_distance.to_bits(),
            "{name} level {}",
            c.level
        );
        assert_eq!(c.device.as_deref(), Some("cpu"));
        let on = g.device.as_deref().unwrap_or_default();
        assert!(on.starts_with("gpu (") && !on.contains("cpu"), "{name} level {}: ran on {on}", c.level);
    }
    true
}

#[test]
fn the_gpu_gives_the_cpus_coordinates_for_every_preset_with_a_gpu_form() {
    const TEST: &str = "the_gpu_gives_the_cpus_coordinates_for_every_preset_with_a_gpu_form";
    if btfsynth::testdata::gpu_skipped(TEST) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel(dir.path(), "gravel", "0,0,64,64");
    let sample = Sample::open(&analysis, 2).unwrap();
    // Sides that are no multiple of the 4 × 4 interleave; both seeds' draws and patches.
    for (preset, seed, tiles) in
        [(Preset::appearance(), 0, false), (Preset::tong2002(), 3, false), (Preset::appearance(), 7, true)]
    {
        let params = SynthParams { preset, seed, ..SynthParams::default() };
        if !same_on_both(TEST, &sample, (75, 66), tiles, params) {
            return;
        }
    }
}

/// The shader's other branches: colour SSD, the coarser level's own template as the parent
/// (Turk's F(n, 1)), argmin selection, no coherence bias, and a full search; and a jittered
/// start on the finer level (the GPU starts from whatever state the CPU's start left).
#[test]
fn the_gpu_gives_the_cpus_coordinates_on_a_recipe_of_its_other_branches() {
    const TEST: &str = "the_gpu_gives_the_cpus_coordinates_on_a_recipe_of_its_other_branches";
    if btfsynth::testdata::gpu_skipped(TEST) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel(dir.path(), "gravel", "16,16,48,48");
    let mut sample = Sample::open(&analysis, 2).unwrap();
    sample.load_colours(&analysis).unwrap();
    let mut preset = Preset::appearance();
    preset.name = "gpu-branches".into();
    for pass in preset.coarsest.passes.iter_mut() {
        pass.neighbourhood = Neighbourhood::Square {
            metric: SquareMetric::Colour,
            template: SquareTemplate::Own(OwnPixels::Full),
        };
        pass.candidates = Candidates::Full;
        pass.select = Select::Argmin;
    }
    for pass in preset.finer.passes.iter_mut() {
        pass.neighbourhood = Neighbourhood::Square {
            metric: SquareMetric::Colour,
            template: SquareTemplate::OwnAndParent(OwnPixels::Full, ParentTemplate::Wide),
        };
        pass.coherence_bias = 0.0;
    }
    preset.coarsest.passes.truncate(2);
    preset.finer.start = Start::Jittered { texels: 1.0 };
    preset.validate().unwrap();
    same_on_both(TEST, &sample, (40, 36), false, SynthParams { preset, seed: 1, ..SynthParams::default() });
}

/// On a real photograph through the command line: `uv.npy` and `labels.npy` byte for byte,
/// and `--report` says each level ran on the GPU.
#[test]
fn synth_device_gpu_writes_the_cpus_bytes_for_a_shared_photo() {
    const TEST: &str = "synth_device_gpu_writes_the_cpus_bytes_for_a_shared_photo";
    let Some(photo) = btfsynth::testdata::shared_data(TEST, "textures/gimp-Stone_stone33.png") else {
        return;
    };
    if btfsynth::testdata::gpu_skipped(TEST) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (analysis, photo) = (path("stone.analysis"), photo.to_str().unwrap().to_string());
    let args =
        ["-q", "analyze", &photo, "--crop", "0,0,96,96", "--textons", "48", "--levels", "3", "-o", &analysis];
    let r = common::btfsynth(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let synth = |device: &str| {
        let (out, report) = (path(device), path(&format!("{device}.json")));
        // All three levels, asked for (the default stops at 48²), so that each runs on the GPU.
        let args = [
            "-q", "synth", &analysis, "--plane", "128x112", "--seed", "4", "--levels", "3", "--device",
            device,
        ];
        let r = common::btfsynth(&[&args[..], &["-o", &out, "--report", &report]].concat());
        (r, out, report)
    };
    let (cpu, cpu_out, _) = synth("cpu");
    assert!(cpu.status.success(), "{}", String::from_utf8_lossy(&cpu.stderr));
    let (gpu, gpu_out, gpu_report) = synth("gpu");
    let stderr = String::from_utf8_lossy(&gpu.stderr);
    if !gpu.status.success() && btfsynth::testdata::gpu_missing(TEST, &stderr) {
        return;
    }
    assert!(gpu.status.success(), "{stderr}");
    for file in ["uv.npy", "labels.npy", "plane.json"] {
        let (a, b) = (Path::new(&cpu_out).join(file), Path::new(&gpu_out).join(file));
        assert!(std::fs::read(a).unwrap() == std::fs::read(b).unwrap(), "{file} differs between the devices");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(gpu_report).unwrap()).unwrap();
    let levels = report["levels"].as_array().unwrap();
    assert_eq!(levels.len(), 3);
    for level in levels {
        let on = level["device"].as_str().unwrap();
        assert!(on.starts_with("gpu ("), "{on}");
    }
    assert!(stderr.contains(", on gpu ("), "the log says where each level ran: {stderr}");
}

/// `--device gpu` where wgpu finds no adapter: one error line, nothing written. (Simulated
/// by pointing wgpu at a backend this system does not have.)
#[test]
fn synth_device_gpu_without_an_adapter_is_one_error_line() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "gravel");
    let out = dir.path().join("plane");
    let args = ["synth", analysis.to_str().unwrap(), "--plane", "32x32", "--device", "gpu", "-o"];
    let r = btfsynth_with(Some(ABSENT_BACKEND), &[&args[..], &[out.to_str().unwrap()]].concat());
    common::assert_one_line_error(&r, "no GPU adapter found");
    assert!(!out.exists(), "nothing is written");
}

/// `--device auto` (the default) where there is no hardware adapter runs on the CPU, writes
/// the CPU's bytes, and the report says why; `--device cpu` says just "cpu".
#[test]
fn synth_device_auto_without_a_hardware_adapter_runs_on_the_cpu_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "gravel");
    let run = |device: &str| {
        let (out, report) = (dir.path().join(device), dir.path().join(format!("{device}.json")));
        let args = ["-q", "synth", analysis.to_str().unwrap(), "--plane", "40x40", "--device", device];
        let paths = ["-o", out.to_str().unwrap(), "--report", report.to_str().unwrap()];
        let r = btfsynth_with(Some(ABSENT_BACKEND), &[&args[..], &paths].concat());
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(report).unwrap()).unwrap();
        let devices: Vec<String> = report["levels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l["device"].as_str().unwrap().to_string())
            .collect();
        (std::fs::read(out.join("uv.npy")).unwrap(), devices)
    };
    let (auto_uv, auto_devices) = run("auto");
    let (cpu_uv, cpu_devices) = run("cpu");
    assert!(auto_uv == cpu_uv);
    assert!(auto_devices.iter().all(|d| d == "cpu (no hardware GPU adapter)"), "{auto_devices:?}");
    assert!(cpu_devices.iter().all(|d| d == "cpu"), "{cpu_devices:?}");
}

/// On a mesh, `appearance` (appearance SSD over blended template pixels) and `tong2002` (Γ
/// over blended textons, with the parent template on two levels; under k-coherence, whose
/// pixel costs are computed side by side, and a full search, whose are not, on one level
/// too: 1,764 candidates, more than one score dispatch takes), with forward shifts from stored
/// patch vertices, run on the GPU and write the CPU's PLY byte for byte, and the same
/// per-level figures to the bit; `turk2001`'s sequential sweep has no GPU form, so its
/// levels run on the CPU and the report says why.
#[test]
fn synth_device_gpu_on_a_mesh_writes_the_cpus_bytes_where_the_passes_have_a_gpu_form() {
    const TEST: &str = "synth_device_gpu_on_a_mesh_writes_the_cpus_bytes_where_the_passes_have_a_gpu_form";
    if btfsynth::testdata::gpu_skipped(TEST) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel(dir.path(), "gravel", "0,0,48,48");
    let run = |preset: &str, search: &str, levels: &str, device: &str| {
        let out = dir.path().join(format!("{preset}-{search}-{levels}-{device}.ply"));
        let report = dir.path().join(format!("{preset}-{search}-{levels}-{device}.json"));
        let args = [
            "-q",
            "synth",
            analysis.to_str().unwrap(),
            common::BUNNY,
            "--vertices",
            "900",
            "--levels",
            levels,
        ];
        let more = ["--preset", preset, "--search", search, "--seed", "2", "--device", device];
        let paths = ["-o", out.to_str().unwrap(), "--report", report.to_str().unwrap()];
        let r = common::btfsynth(&[&args[..], &more, &paths].concat());
        (r, out, report)
    };
    let levels = |report: &Path| {
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(report).unwrap()).unwrap();
        report["levels"].as_array().unwrap().clone()
    };
    let cases = [
        ("appearance", "kcoherence", "2", true),
        ("tong2002", "kcoherence", "2", true),
        ("tong2002", "full", "2", true),
        ("tong2002", "full", "1", true),
        ("turk2001", "kcoherence", "2", false),
    ];
    for (preset, search, depth, on_gpu) in cases {
        let (cpu, cpu_out, cpu_report) = run(preset, search, depth, "cpu");
        assert!(cpu.status.success(), "{}", String::from_utf8_lossy(&cpu.stderr));
        let (gpu, gpu_out, report) = run(preset, search, depth, "gpu");
        let stderr = String::from_utf8_lossy(&gpu.stderr);
        if !gpu.status.success() && btfsynth::testdata::gpu_missing(TEST, &stderr) {
            return;
        }
        assert!(gpu.status.success(), "{stderr}");
        assert!(
            std::fs::read(cpu_out).unwrap() == std::fs::read(gpu_out).unwrap(),
            "{preset} {search} on {depth} level(s): the PLYs differ"
        );
        let (cpu_levels, gpu_levels) = (levels(&cpu_report), levels(&report));
        assert_eq!(cpu_levels.len(), gpu_levels.len());
        for (c, g) in cpu_levels.iter().zip(&gpu_levels) {
            for figure in ["mean_best_distance", "mean_candidates"] {
                assert_eq!(c[figure], g[figure], "{preset} {search}: {figure} of level {}", c["level"]);
            }
            let on = g["device"].as_str().unwrap();
            match on_gpu {
                true => assert!(on.starts_with("gpu (") && !on.contains("cpu"), "{preset}: {on}"),
                false => assert_eq!(on, "cpu (no GPU form: a sequential visiting order)", "{preset}"),
            }
        }
    }
}
