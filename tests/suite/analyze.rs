//! `analyze`: planted textures are recovered, the stored arrays are consistent, runs are
//! deterministic, and bad input is refused cleanly.

use crate::common;

use btfsynth::analysis::npy;
use btfsynth::analysis::pipeline::{analyze, AnalysisParams};
use btfsynth::btf::{write_stack, Btf, Direction, DirectionPair, ImageFormat};
use btfsynth::progress::Silent;
use common::{assert_one_line_error, btfsynth, entries};
use half::f16;

const SIZE: usize = 48;

/// Left half: a bumpy relief shaded under each light; right half: flat and plain.
fn two_material_stack() -> Btf {
    let lights: Vec<Direction> = [(0.0, 0.0), (45.0, 0.0), (45.0, 90.0), (45.0, 180.0), (60.0, 270.0)]
        .iter()
        .map(|&(t, p)| Direction::new(t, p).unwrap())
        .collect();
    let mut pixels = Vec::new();
    for light in &lights {
        let l = light.unit();
        for y in 0..SIZE {
            for x in 0..SIZE {
                let v = if x < SIZE / 2 {
                    let (fx, fy) =
                        (x as f32 * std::f32::consts::TAU / 6.0, y as f32 * std::f32::consts::TAU / 6.0);
                    let n = glam::Vec3::new(-fx.cos() * fy.sin(), -fx.sin() * fy.cos(), 0.8).normalize();
                    0.7 * n.dot(l).max(0.0)
                } else {
                    0.3 * l.z
                };
                pixels.extend([f16::from_f32(v), f16::from_f32(0.8 * v), f16::from_f32(0.6 * v)]);
            }
        }
    }
    let pairs = lights.iter().map(|&light| DirectionPair { light, view: Direction::NORMAL }).collect();
    Btf::new(SIZE, SIZE, pairs, pixels).unwrap()
}

#[test]
fn textons_separate_a_planted_two_material_sample() {
    let stack = two_material_stack();
    let params = AnalysisParams { textons: 12, levels: 1, ..AnalysisParams::default() };
    let analysis = analyze(&stack, &params, &Silent).unwrap();
    let map = &analysis.levels[0].textons.map;
    let textons = analysis.levels[0].textons.textons;
    let mut counts = vec![[0usize; 2]; textons];
    for (p, &label) in map.labels.iter().enumerate() {
        counts[label as usize][usize::from(p % SIZE >= SIZE / 2)] += 1;
    }
    let majority: usize = counts.iter().map(|c| c[0].max(c[1])).sum();
    let purity = majority as f64 / map.labels.len() as f64;
    assert!(purity >= 0.95, "texton purity {purity:.3}: {counts:?}");
}

#[test]
fn analysis_directory_is_consistent_and_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let stack_dir = dir.path().join("stack");
    write_stack(&two_material_stack(), &stack_dir, ImageFormat::Exr, None, false, &Silent).unwrap();
    let run = |name: &str| {
        let out = dir.path().join(name);
        let r = btfsynth(&[
            "-q",
            "analyze",
            stack_dir.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--textons",
            "16",
            "--levels",
            "2",
            "--k",
            "5",
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        out
    };
    let (a, b) = (run("a"), run("b"));
    for file in [
        "level0_textons.npy",
        "level0_gamma.npy",
        "level0_knn.npy",
        "level0_knn2.npy",
        "level1_knn.npy",
        "images.npy",
    ] {
        assert_eq!(
            std::fs::read(a.join(file)).unwrap(),
            std::fs::read(b.join(file)).unwrap(),
            "{file} differs between runs"
        );
    }
    let gamma: npy::NpyArray<f32> = npy::read(&a.join("level0_gamma.npy")).unwrap();
    let n = gamma.shape[0];
    assert_eq!(gamma.shape, vec![n, n]);
    for i in 0..n {
        for j in 0..n {
            assert_eq!(gamma.data[i * n + j], gamma.data[j * n + i], "Γ is symmetric");
        }
    }
    let knn: npy::NpyArray<u32> = npy::read(&a.join("level0_knn.npy")).unwrap();
    assert_eq!(knn.shape, vec![SIZE, SIZE, 5]);
    for p in 0..SIZE * SIZE {
        assert_eq!(knn.data[p * 5] as usize, p, "each list starts with its own pixel");
    }
    let info = btfsynth(&["info", a.to_str().unwrap(), "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(json["kind"], "analysis");
    assert_eq!(json["k"], 5);
    assert_eq!(json["images"], 5);
    assert_eq!(json["selected"], 5);
    assert_eq!(json["levels"][1]["width"], SIZE / 2);
    assert!(json["levels"][0]["embedding_dims"].as_u64().unwrap() >= 1);
    for preview in ["level0_textons.png", "filters.png"] {
        assert!(image::open(a.join(preview)).is_ok(), "{preview} opens");
    }
}

#[test]
fn a_single_photograph_is_a_one_image_btf() {
    let dir = tempfile::tempdir().unwrap();
    let texture = concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png");
    let out = dir.path().join("gravel");
    let r = btfsynth(&[
        "-q",
        "analyze",
        texture,
        "-o",
        out.to_str().unwrap(),
        "--crop",
        "0,0,64,64",
        "--textons",
        "32",
        "--levels",
        "2",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let json: serde_json::Value =
        serde_json::from_slice(&btfsynth(&["info", out.to_str().unwrap(), "--json"]).stdout).unwrap();
    assert_eq!((json["images"].as_u64(), json["selected"].as_u64()), (Some(1), Some(1)));
    assert_eq!(json["levels"][0]["textons"], 32);
    assert_eq!(json["levels"][1]["textons"], 8);
}

#[test]
fn bad_analysis_inputs_leave_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let stack_dir = dir.path().join("stack");
    write_stack(&two_material_stack(), &stack_dir, ImageFormat::Png, None, false, &Silent).unwrap();
    let s = stack_dir.to_str().unwrap();
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    common::assert_usage_error(&btfsynth(&["analyze", s, "-o", o, "--textons", "0"]), "--textons");
    common::assert_usage_error(
        &btfsynth(&["analyze", s, "-o", o, "--levels", "4"]),
        "use --levels 3 or fewer",
    );
    common::assert_usage_error(&btfsynth(&["analyze", s, "-o", o, "--neighborhood", "4"]), "--neighborhood");
    assert_one_line_error(&btfsynth(&["analyze", s, "-o", "/proc/forbidden/out"]), "/proc/forbidden");
    let bank = dir.path().join("bank.toml");
    std::fs::write(&bank, "filters = [ { kind = \"blob\", sigma = 1.0 } ]").unwrap();
    assert_one_line_error(
        &btfsynth(&["analyze", s, "-o", o, "--filters", bank.to_str().unwrap()]),
        "bank.toml",
    );
    let first = std::fs::read_dir(&stack_dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .find(|e| e.path().extension().is_some_and(|x| x == "png"))
        .unwrap();
    std::fs::write(first.path(), b"corrupt").unwrap();
    assert_one_line_error(&btfsynth(&["analyze", s, "-o", o]), &first.file_name().to_string_lossy());
    assert_eq!(entries(dir.path()), vec!["bank.toml".to_string(), "stack".to_string()], "nothing written");
}
