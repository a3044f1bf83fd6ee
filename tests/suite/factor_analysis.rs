//! Measured BTFs from their factors: a DFMF file is analysed from its own factors (or,
//! where its colour model is not linear, through a streamed basis) and agrees with the
//! analysis of its decoded images; the stored factor sample reads back as the images; an
//! analysis that would not fit in memory is refused with one line before any work.

use crate::common;

use btfsynth::analysis::images::SampleImages;
use btfsynth::analysis::input::{self, Input, Mode};
use btfsynth::analysis::pipeline::{Analysis, AnalysisParams};
use btfsynth::analysis::store;
use btfsynth::btf::colour::ColourModel;
use btfsynth::btf::convert::{to_btf, ToBtfOptions};
use btfsynth::btf::gen::{generate, GenParams, MaterialKind};
use btfsynth::btf::ubo2014::Scalar;
use btfsynth::btf::{Btf, Crop, DirectionSet};
use btfsynth::mesh::frames::Frames;
use btfsynth::mesh::Mesh;
use btfsynth::progress::Silent;
use btfsynth::render::cpu::{render, RenderOptions, Tracer};
use btfsynth::render::{Camera, Material, Projection, Scene, Shot};
use common::{assert_one_line_error, entries};
use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// `gen pebbles --size 32 --directions grid:16 --spp 1` (256 images: more than the
/// streamed basis' 96 sketch columns, so that basis is an approximation), generated once
/// for every test of this module.
fn pebbles() -> &'static Btf {
    static STACK: OnceLock<Btf> = OnceLock::new();
    STACK.get_or_init(|| {
        let params = GenParams {
            size: 32,
            directions: DirectionSet::Grid(16),
            samples_per_pixel: 1,
            ..GenParams::default()
        };
        generate(MaterialKind::Pebbles, &params, &Silent).unwrap()
    })
}

/// [`pebbles`] through `convert --to btf --components 8` with `model`.
fn small_dfmf(dir: &Path, model: ColourModel) -> PathBuf {
    let stack = pebbles();
    let path = dir.join(format!("pebbles-{}.btf", model.id()));
    let options = ToBtfOptions {
        components: 8,
        model,
        scalar: Scalar::F16,
        rotation_block: true,
        rotations: Vec::new(),
        seed: 0,
    };
    to_btf(stack, &path, &options, &Silent).unwrap();
    path
}

fn params() -> AnalysisParams {
    AnalysisParams { textons: 48, levels: 2, ..AnalysisParams::default() }
}

fn analyse(path: &Path, mode: Mode) -> (Input, input::Analysed) {
    analyse_crop(path, None, mode)
}

fn analyse_crop(path: &Path, crop: Option<Crop>, mode: Mode) -> (Input, input::Analysed) {
    let input = input::open(path, crop, mode, &params(), &Silent).unwrap();
    let analysed = input::run(&input, &params(), &Silent).unwrap();
    (input, analysed)
}

/// The share of pixels whose labels agree once each texton of `a` is mapped to the
/// texton of `b` it overlaps most (the maps' labels are arbitrary), taken both ways and
/// the smaller kept.
fn agreement(a: &[u16], b: &[u16]) -> f64 {
    let one_way = |a: &[u16], b: &[u16]| {
        let mut counts = std::collections::HashMap::<(u16, u16), usize>::new();
        for (&x, &y) in a.iter().zip(b) {
            *counts.entry((x, y)).or_default() += 1;
        }
        let mut best = std::collections::HashMap::<u16, usize>::new();
        for (&(x, _), &c) in &counts {
            let e = best.entry(x).or_default();
            *e = (*e).max(c);
        }
        best.values().sum::<usize>() as f64 / a.len() as f64
    };
    one_way(a, b).min(one_way(b, a))
}

/// Largest relative difference of Γ's leading eigenvalues (Γ itself depends on the
/// arbitrary texton order; its spectrum does not).
fn gamma_spectrum_difference(a: &Analysis, b: &Analysis, level: usize) -> f64 {
    let spectrum = |x: &Analysis| {
        let g = &x.levels[level].textons.gamma;
        let n = g.nrows();
        let m = nalgebra::DMatrix::<f64>::from_fn(n, n, |i, j| g[[i, j]] as f64);
        let mut v: Vec<f64> = m.symmetric_eigen().eigenvalues.iter().copied().collect();
        v.sort_by(|x, y| y.total_cmp(x));
        v
    };
    let (sa, sb) = (spectrum(a), spectrum(b));
    sa.iter().zip(&sb).take(8).map(|(x, y)| (x - y).abs() / x.abs().max(1e-12)).fold(0.0, f64::max)
}

#[test]
fn a_linear_dfmf_analysed_from_its_factors_agrees_with_its_decoded_images() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_dfmf(dir.path(), ColourModel::Rgb);
    // The whole file, and a crop off its corner (the factor rows of a window).
    for crop in [None, Some(Crop { x: 5, y: 3, width: 24, height: 26 })] {
        linear_dfmf_agrees(&path, crop);
    }
}

fn linear_dfmf_agrees(path: &Path, crop: Option<Crop>) {
    let (decoded_input, decoded) = analyse_crop(path, crop, Mode::Decoded);
    let (factor_input, factors) = analyse_crop(path, crop, Mode::Auto);
    assert_eq!(factor_input.size(), crop.map_or((32, 32), |c| (c.width as usize, c.height as usize)));
    assert!(matches!(decoded_input, Input::Images(_)));
    assert!(matches!(factor_input, Input::Factors(_)));
    assert_eq!(input::describe(&factor_input), "the file's factors");
    let basis = factors.basis.as_ref().unwrap();
    assert_eq!((basis.kind.as_str(), basis.rank, basis.captured), ("file factors", 24, 1.0));
    assert_eq!(decoded.analysis.selected, factors.analysis.selected);
    for level in 0..2 {
        let (a, b) = (&decoded.analysis.levels[level].textons, &factors.analysis.levels[level].textons);
        assert_eq!(a.basis_rank, b.basis_rank, "level {level}");
        assert!((a.basis_energy - b.basis_energy).abs() < 1e-4, "level {level}");
        let agree = agreement(&a.map.labels, &b.map.labels);
        let gamma = gamma_spectrum_difference(&decoded.analysis, &factors.analysis, level);
        eprintln!("linear, crop {crop:?}, level {level}: agreement {agree:.4}, Γ spectrum {gamma:.5}");
        assert!(agree >= 0.97, "level {level}: texton maps agree on {agree:.3}");
        assert!(gamma < 0.02, "level {level}: Γ spectra differ by {gamma:.4}");
    }
}

#[test]
fn a_log_luminance_dfmf_is_analysed_through_a_streamed_basis_within_k_means_noise() {
    // Colour model 11 (log-Y, U/Y, V/Y, the UBO2014 files') is not linear in the factors:
    // the basis is streamed from the decoded images, an approximation, so the textons may
    // differ from the decoded analysis' — but by no more than another k-means seed moves
    // the decoded analysis itself.
    let dir = tempfile::tempdir().unwrap();
    let path = small_dfmf(dir.path(), ColourModel::LogYUvOverY);
    let (_, decoded) = analyse(&path, Mode::Decoded);
    let (factor_input, streamed) = analyse(&path, Mode::Auto);
    assert_eq!(input::describe(&factor_input), "a basis streamed from the file's factors");
    let basis = streamed.basis.as_ref().unwrap();
    assert_eq!(basis.kind, "streamed");
    assert!(basis.nonlinearity.as_deref().unwrap_or("").contains("colour model 11"), "{basis:?}");
    // 96 sketch columns hold nearly all of the 256 decoded images' centred energy.
    assert!(basis.captured > 0.99, "{basis:?}");
    let reseeded = {
        let p = AnalysisParams { seed: 1, ..params() };
        let images = input::open(&path, None, Mode::Decoded, &p, &Silent).unwrap();
        input::run(&images, &p, &Silent).unwrap()
    };
    for level in 0..2 {
        let (a, b) = (&decoded.analysis.levels[level].textons, &streamed.analysis.levels[level].textons);
        eprintln!(
            "level {level}: basis energy decoded {:.4}, streamed {:.4}",
            a.basis_energy, b.basis_energy
        );
        assert!(
            (a.basis_energy - b.basis_energy).abs() < 0.01,
            "level {level}: {} vs {}",
            a.basis_energy,
            b.basis_energy
        );
        let agree = agreement(&a.map.labels, &b.map.labels);
        let gamma = gamma_spectrum_difference(&decoded.analysis, &streamed.analysis, level);
        let c = &reseeded.analysis.levels[level].textons;
        let noise_agree = agreement(&a.map.labels, &c.map.labels);
        let noise_gamma = gamma_spectrum_difference(&decoded.analysis, &reseeded.analysis, level);
        eprintln!(
            "level {level}: streamed vs decoded: agreement {agree:.3}, Γ {gamma:.3}; seed 1 vs 0: agreement {noise_agree:.3}, Γ {noise_gamma:.3}"
        );
        assert!(agree >= noise_agree - 0.1, "level {level}: agreement {agree:.3} vs noise {noise_agree:.3}");
        assert!(
            gamma <= noise_gamma + 0.1,
            "level {level}: Γ differs by {gamma:.3} vs noise {noise_gamma:.3}"
        );
    }
}

#[test]
fn the_stored_factor_sample_reads_back_as_the_decoded_images() {
    let dir = tempfile::tempdir().unwrap();
    for model in [ColourModel::Rgb, ColourModel::LogYUvOverY] {
        let path = small_dfmf(dir.path(), model);
        let out_images = dir.path().join(format!("images-{}", model.id()));
        let out_factors = dir.path().join(format!("factors-{}", model.id()));
        // Only the stored sample is compared here: the lightest analysis that stores one.
        let light = AnalysisParams { textons: 8, levels: 1, ..AnalysisParams::default() };
        for (mode, out) in [(Mode::Decoded, &out_images), (Mode::Auto, &out_factors)] {
            let input = input::open(&path, None, mode, &light, &Silent).unwrap();
            let analysed = input::run(&input, &light, &Silent).unwrap();
            store::write_analysed(&analysed, &input, (&path, None), &[], out, false).unwrap();
        }
        assert!(entries(&out_images).contains(&"images.npy".to_string()));
        let stored = entries(&out_factors);
        assert!(!stored.contains(&"images.npy".to_string()), "{stored:?}");
        assert!(stored.contains(&"sample_texel_factors.npy".to_string()), "{stored:?}");
        let manifest = store::read_manifest(&out_factors).unwrap();
        assert_eq!(manifest.sample.as_ref().unwrap().colour_model, model.id());
        assert!(manifest.source.fingerprint.starts_with("fnv1a64-factors:"));

        let (images, factors) =
            (SampleImages::open(&out_images).unwrap(), SampleImages::open(&out_factors).unwrap());
        assert!(factors.is_factored() && !images.is_factored());
        let (mut worst, mut sum, mut count) = (0f32, 0f64, 0usize);
        for i in (0..images.len()).step_by(7) {
            for (x, y) in [(0, 0), (5, 17), (31, 31), (20, 3)] {
                let (a, b) = (images.rgb(i, x, y), factors.rgb(i, x, y));
                for c in 0..3 {
                    // images.npy holds f16: 2⁻¹¹ relative, plus f16's subnormal floor.
                    worst = worst.max((a[c] - b[c]).abs() / (a[c].abs() + 1e-3));
                    sum += a[c] as f64;
                    count += 1;
                }
            }
        }
        assert!(worst < 2e-3, "model {}: largest relative difference {worst}", model.id());
        assert!(sum / count as f64 > 0.01, "the sample is not black");

        // The renderer's material: decoded when small, on the fly from the factors alike.
        let from_images = Material::open(&out_images).unwrap();
        let from_factors = Material::open(&out_factors).unwrap();
        assert!(!from_factors.is_factored(), "a 32x32 sample is decoded when opened");
        for (i, (a, b)) in from_images.image(3).iter().zip(from_factors.image(3)).enumerate() {
            assert!((a - b).abs() <= 2e-3 * (a.abs() + 1e-3), "value {i}: {a} vs {b}");
        }
    }
}

/// A wavy 40 × 40 height field (so views, lights and shadows vary over the frame) whose
/// vertex (x, z) is mapped to texel (x, z), the map running over the 32² sample's edge.
fn wavy_field() -> Scene {
    let n = 40u32;
    let height = |x: f32, z: f32| 2.5 * (x / 4.0).sin() * (z / 5.0).cos();
    let positions =
        (0..n).flat_map(|j| (0..n).map(move |i| Vec3::new(i as f32, height(i as f32, j as f32), j as f32)));
    let mut triangles = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let at = |a: u32, b: u32| b * n + a;
            triangles.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
            triangles.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
        }
    }
    let mesh = Mesh::new(positions.collect(), triangles).unwrap().with_normals();
    let count = mesh.vertex_count();
    let uv = mesh.positions().iter().map(|p| Vec2::new(p.x, p.z)).collect();
    let frames = Frames::from_directions(mesh.normals().unwrap(), &vec![Vec3::X; count]);
    Scene::new(mesh, frames, uv, vec![0; count], 1.0)
}

#[test]
fn a_render_from_the_stored_factors_agrees_with_the_render_of_the_decoded_images() {
    // Issue #21: the renderer computing every value from the analysis' factors (on the
    // fly, as it does for a sample too large to decode) gives the picture that the
    // decoded-image analysis gives, within 1% of the mean, for a linear colour model and
    // for the UBO2014 files' model 11 alike (the stored sample is the file's own factors
    // and colour model; images.npy holds f16, so the two differ by its rounding, ~1e-4).
    let dir = tempfile::tempdir().unwrap();
    let scene = wavy_field();
    let tracer = Tracer::new(&scene.mesh);
    let camera = Camera {
        eye: Vec3::new(19.5, 30.0, 55.0),
        target: Vec3::new(19.5, 0.0, 19.5),
        up: Vec3::Y,
        projection: Projection::Perspective { fov_y_deg: 45.0 },
        width: 96,
        height: 96,
        near: 1.0,
        far: 200.0,
    };
    let shot = Shot { camera, light: Vec3::new(0.6, 0.7, 0.4).normalize() };
    let options = RenderOptions { spp: 4, ..RenderOptions::default() };
    let light = AnalysisParams { textons: 8, levels: 1, ..AnalysisParams::default() };
    for model in [ColourModel::Rgb, ColourModel::LogYUvOverY] {
        let path = small_dfmf(dir.path(), model);
        let out = |mode: Mode| {
            let out = dir.path().join(format!("render-{}-{mode:?}", model.id()));
            let input = input::open(&path, None, mode, &light, &Silent).unwrap();
            let analysed = input::run(&input, &light, &Silent).unwrap();
            store::write_analysed(&analysed, &input, (&path, None), &[], &out, false).unwrap();
            out
        };
        let decoded = Material::open(&out(Mode::Decoded)).unwrap();
        let factors = Material::open_within(&out(Mode::Auto), 0).unwrap();
        assert!(!decoded.is_factored() && factors.is_factored());
        let a = render(&scene, &decoded, &tracer, &shot, options, None);
        let b = render(&scene, &factors, &tracer, &shot, options, None);
        let colour = |f: &btfsynth::render::output::Frame| {
            f.rgba.chunks_exact(4).flat_map(|p| p[..3].to_vec()).collect::<Vec<f32>>()
        };
        let (a, b) = (colour(&a), colour(&b));
        let mean = a.iter().map(|&x| x as f64).sum::<f64>() / a.len() as f64;
        let difference = a.iter().zip(&b).map(|(&x, &y)| (x - y).abs() as f64).sum::<f64>() / a.len() as f64;
        let lit = a.iter().filter(|&&x| x > 0.0).count() as f64 / a.len() as f64;
        eprintln!("model {}: mean {mean:.4}, mean |difference| {difference:.6}, lit {lit:.2}", model.id());
        assert!(mean > 0.01 && lit > 0.3, "the render shows the sample (mean {mean}, lit {lit})");
        assert!(difference <= 0.01 * mean, "model {}: {difference} against a mean of {mean}", model.id());
    }
}

#[test]
fn an_analysis_that_would_not_fit_in_memory_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_dfmf(dir.path(), ColourModel::Rgb);
    let out = dir.path().join("analysis");
    for extra in [&[][..], &["--decoded"][..]] {
        let mut args = vec!["analyze", path.to_str().unwrap(), "-o", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let run = Command::new(env!("CARGO_BIN_EXE_btfsynth"))
            .args(&args)
            .env("BTFSYNTH_MEMORY", "4M")
            .env_remove("RUST_LOG")
            .output()
            .unwrap();
        assert_one_line_error(&run, "more than the 4 MiB budget (BTFSYNTH_MEMORY=4M)");
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(stderr.contains(path.to_str().unwrap()) && stderr.contains("at its peak"), "{stderr}");
        assert!(!out.exists(), "nothing is written");
    }
    // The same run with room goes through from the factors.
    let run = Command::new(env!("CARGO_BIN_EXE_btfsynth"))
        .args(["-q", "analyze", path.to_str().unwrap(), "-o", out.to_str().unwrap(), "--levels", "1"])
        .args(["--textons", "8"])
        .env("BTFSYNTH_MEMORY", "2G")
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(String::from_utf8_lossy(&run.stderr).contains("from the file's factors"));
}

/// The peak that `analyze ARGS` under a 1-byte budget says it would need, in MiB.
fn estimated_mib(args: &[String]) -> f64 {
    let run =
        Command::new(env!("CARGO_BIN_EXE_btfsynth")).args(args).env("BTFSYNTH_MEMORY", "1").output().unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{stderr}");
    let figure = stderr.split("would need about ").nth(1).unwrap_or_else(|| panic!("{stderr}"));
    let (value, unit) = figure.split_once(' ').unwrap();
    value.parse::<f64>().unwrap() * if unit.starts_with("GiB") { 1024.0 } else { 1.0 }
}

#[test]
fn an_image_folder_too_large_to_decode_is_streamed_from_its_files() {
    // Issue #21's 6,561-image folders: when the decoded stack does not fit the budget,
    // `analyze` streams the folder's images (two passes over the files) into a basis, and
    // that basis holds the images.
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("pebbles");
    btfsynth::btf::write::write_stack(
        pebbles(),
        &folder,
        btfsynth::btf::write::ImageFormat::Exr,
        None,
        false,
        &Silent,
    )
    .unwrap();
    let out = dir.path().join("analysis");
    let args = |extra: &[&str]| {
        let (folder, out) = (folder.to_str().unwrap(), out.to_str().unwrap());
        let common = ["analyze", folder, "-o", out, "--textons", "8", "--levels", "1"];
        common.iter().chain(extra).map(|a| a.to_string()).collect::<Vec<_>>()
    };
    let auto_args = args(&[]);
    let (decoded, streamed) = (estimated_mib(&args(&["--decoded"])), estimated_mib(&auto_args));
    eprintln!("estimates: decoded {decoded} MiB, streamed {streamed} MiB");
    assert!(streamed + 1.0 < decoded, "streaming needs less: {streamed} vs {decoded} MiB");
    let budget = format!("{}M", ((streamed + decoded) / 2.0).ceil());
    let run = Command::new(env!("CARGO_BIN_EXE_btfsynth"))
        .args(&auto_args)
        .env("BTFSYNTH_MEMORY", &budget)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(stderr.contains("streamed"), "{stderr}");
    let manifest = store::read_manifest(&out).unwrap();
    let basis = manifest.basis.as_ref().expect("a streamed analysis records its basis");
    // 96 sketch columns of 256 full-rank images: most of their centred energy, not all.
    assert_eq!(basis.kind, "streamed");
    assert!(basis.captured > 0.9, "{basis:?}");
    assert!(!entries(&out).contains(&"images.npy".to_string()), "the sample is stored as factors");
    // The stored sample reads back as the folder's images, within what the basis misses
    // (a share of the centred energy, so less of the whole).
    let (images, stored) = (pebbles(), SampleImages::open(&out).unwrap());
    let (mut error, mut energy) = (0f64, 0f64);
    for i in (0..images.len()).step_by(5) {
        for (x, y) in [(0, 0), (7, 19), (31, 31), (22, 4)] {
            let (a, b) = (images.rgb(i, x, y), stored.rgb(i, x, y));
            for c in 0..3 {
                error += ((a[c] - b[c]) as f64).powi(2);
                energy += (a[c] as f64).powi(2);
            }
        }
    }
    let relative = error / energy;
    eprintln!(
        "stored sample: relative squared error {relative:.5}, basis misses {:.5}",
        1.0 - basis.captured
    );
    assert!(relative < 1.0 - basis.captured, "relative squared error {relative}");
}
