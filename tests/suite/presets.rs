//! The engine's presets: golden outputs that pin each preset's behaviour (a change must be
//! deliberate and explained in its commit), the recipe recorded in every output, and
//! `--list-presets`.

use crate::common;

use btfsynth::mesh::field::Orientation;
use btfsynth::progress::Silent;
use btfsynth::synth::plane::synthesize_plane;
use btfsynth::synth::session::SynthSessionBuilder;
use btfsynth::synth::surface_map::{build_pyramid, synthesize_surface, Density};
use btfsynth::synth::{MetricKind, Preset, Sample};
use common::btfsynth;
use std::path::{Path, PathBuf};

/// Per preset: FNV-1a 64 of the plane result (labels then coordinates) and of the surface
/// map's vertex labels and coordinates, for the fixed inputs of [`golden_inputs`].
const GOLDEN: &[(&str, u64, u64)] = &[
    ("appearance", 0x00e967524859da52, 0x4c5e4d613c0a7d62),
    ("tong2002", 0xc627eda0c3c641d2, 0xf310fbd3df61ca9f),
    ("turk2001", 0xbba6265602ef9349, 0x4c333c16c5ed4449),
    ("chen2008", 0x36163ad6f8f91e6e, 0xd36a4d88365235ee),
    ("castellanos", 0x35ff99ca13fe62ad, 0x71a2fb9a27118daa),
];

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn run_ok(args: &[&str]) {
    let r = btfsynth(args);
    assert!(r.status.success(), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
}

/// FNV-1a 64, a hash whose value never changes with the Rust release.
fn fnv(hash: &mut u64, bytes: &[u8]) {
    for &b in bytes {
        *hash ^= u64::from(b);
        *hash = hash.wrapping_mul(0x100_0000_01b3);
    }
}

fn state_hash(labels: &[u16], uv: &[[i32; 2]]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325;
    labels.iter().for_each(|l| fnv(&mut h, &l.to_le_bytes()));
    uv.iter().for_each(|c| c.iter().for_each(|v| fnv(&mut h, &v.to_le_bytes())));
    h
}

/// The analysis every golden output starts from: a 64² crop of the bundled gravel photo,
/// whose two levels the default synthesizes both (a 48² crop would start on its finest).
fn golden_inputs(dir: &Path) -> PathBuf {
    common::analyze_gravel(dir, "analysis", "0,0,64,64")
}

fn plane_hash(analysis: &Path, dir: &Path, preset: &str, threads: usize) -> u64 {
    let out = dir.join(format!("plane-{preset}-{threads}"));
    run_ok(&[
        "-q",
        "--threads",
        &threads.to_string(),
        "synth",
        s(analysis),
        "--plane",
        "64x64",
        "--preset",
        preset,
        "--seed",
        "7",
        "-o",
        s(&out),
    ]);
    let (_, _, state, _) = btfsynth::synth::plane::read_plane(&out).unwrap();
    state_hash(&state.labels, &state.uv)
}

fn surface_hash(analysis: &Path, dir: &Path, preset: &str, threads: usize) -> u64 {
    let out = dir.join(format!("{preset}-{threads}.ply"));
    run_ok(&[
        "-q",
        "--threads",
        &threads.to_string(),
        "synth",
        s(analysis),
        common::BUNNY,
        "--vertices",
        "3000",
        "--orient",
        "axis:0,1,0",
        "--preset",
        preset,
        "--seed",
        "7",
        "-o",
        s(&out),
    ]);
    let map = btfsynth::synth::surface_map::read_surface_ply(&out).unwrap();
    state_hash(&map.state.labels, &map.state.uv)
}

/// The plane and surface hashes of `preset` through the library, as a library user runs it
/// (session, sample, plane; pyramid, surface), on a pool of `threads` workers: the same
/// choices as [`plane_hash`] and [`surface_hash`] give the binary.
fn library_hashes(analysis: &Path, preset: Preset, threads: usize) -> (u64, u64) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let manifest = btfsynth::analysis::store::read_manifest(analysis).unwrap();
        // A mesh's default levels differ from a plane's (one for presets that start from
        // patches), so each target has its session, as the CLI builds them.
        let session = |surface: bool| {
            let builder = SynthSessionBuilder::new().preset(preset.clone()).seed(7).surface(surface);
            let session = builder.build(&manifest).unwrap();
            let mut sample = Sample::open(analysis, session.levels()).unwrap();
            if session.params().preset.uses(MetricKind::Colour) {
                sample.load_colours(analysis).unwrap();
            }
            session.check_sample(&sample).unwrap();
            (session, sample)
        };
        let (on_plane, sample) = session(false);
        let plane = synthesize_plane(&sample, (64, 64), false, on_plane.params(), &Silent).unwrap();
        let (on_mesh, sample) = session(true);
        let mesh = btfsynth::mesh::load(Path::new(common::BUNNY)).unwrap();
        let orientation = Orientation::Axis(glam::Vec3::Y);
        let (levels, params) = (on_mesh.levels(), on_mesh.params());
        let pyramid =
            build_pyramid(&mesh, Density::Vertices(3000), levels, &orientation, params, &Silent).unwrap();
        let (surface, _) = synthesize_surface(&pyramid, &sample, params, &Silent).unwrap();
        (state_hash(&plane.state.labels, &plane.state.uv), state_hash(&surface.labels, &surface.uv))
    })
}

/// The pinned hashes of preset `name`.
fn golden(name: &str) -> Option<(u64, u64)> {
    GOLDEN.iter().find(|g| g.0 == name).map(|g| (g.1, g.2))
}

/// Every preset's output is pinned, through the library: a refactoring of the engine must
/// not change it.
#[test]
fn every_preset_gives_its_golden_output() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = golden_inputs(dir.path());
    let mut wrong = Vec::new();
    for preset in Preset::all() {
        let name = preset.name.to_string();
        let got = library_hashes(&analysis, preset, 2);
        let want = golden(&name);
        if want != Some(got) {
            wrong.push(format!("(\"{name}\", {:#018x}, {:#018x}) (pinned: {want:x?})", got.0, got.1));
        }
    }
    assert!(wrong.is_empty(), "outputs differ from the golden ones:\n{}", wrong.join("\n"));
}

/// The interleaved passes run in parallel, yet a seed gives the same bytes at any thread
/// count (and so do the sequential presets); the binary's `--threads` gives the library's
/// golden bytes.
#[test]
fn every_preset_gives_the_same_output_at_1_2_and_4_threads() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = golden_inputs(dir.path());
    for preset in Preset::all() {
        let name = preset.name.to_string();
        let hashes: Vec<(u64, u64)> = [1, 2, 4]
            .iter()
            .map(|&t| {
                (plane_hash(&analysis, dir.path(), &name, t), surface_hash(&analysis, dir.path(), &name, t))
            })
            .collect();
        assert!(
            hashes.iter().all(|&h| Some(h) == golden(&name)),
            "{name}: {hashes:x?} at 1, 2 and 4 threads"
        );
    }
}

/// Every output records the whole recipe, not only its name.
#[test]
fn a_plane_records_its_whole_recipe() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = golden_inputs(dir.path());
    for preset in btfsynth::synth::Preset::all() {
        let out = dir.path().join(preset.name.as_str());
        run_ok(&[
            "-q",
            "synth",
            s(&analysis),
            "--plane",
            "32x32",
            "--preset",
            preset.name.as_str(),
            "-o",
            s(&out),
        ]);
        let (_, _, _, manifest) = btfsynth::synth::plane::read_plane(&out).unwrap();
        let recorded = &manifest["params"]["recipe"];
        assert_eq!(*recorded, preset.to_json(), "{}: {manifest}", preset.name.as_str());
        assert!(recorded["coarsest"]["passes"][0]["order"].is_string(), "{recorded}");
    }
}

/// `--list-presets` prints one line per preset naming its paper, and needs no other input.
#[test]
fn list_presets_names_each_preset_and_its_paper() {
    let r = btfsynth(&["synth", "--list-presets"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let out = String::from_utf8(r.stdout).unwrap();
    let presets = btfsynth::synth::Preset::all();
    assert_eq!(out.lines().count(), presets.len(), "{out}");
    for (line, preset) in out.lines().zip(&presets) {
        assert!(line.starts_with(preset.name.as_str()) && line.contains(preset.paper.as_str()), "{line}");
    }
    assert!(out.contains("Turk") && out.contains("Tong"), "{out}");
}

/// An unknown preset is a usage error that names the available ones.
#[test]
fn an_unknown_preset_is_refused_with_the_list() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = golden_inputs(dir.path());
    let out = dir.path().join("plane");
    let r = btfsynth(&["synth", s(&analysis), "--plane", "16x16", "--preset", "wei2000", "-o", s(&out)]);
    common::assert_usage_error(&r, "turk2001");
    assert!(!out.exists());
}

/// `chen2008` takes its candidates around the linked texels only: a full search is refused
/// up front with one usage error line.
#[test]
fn chen2008_refuses_a_full_search() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = golden_inputs(dir.path());
    let out = dir.path().join("full");
    let r = btfsynth(&[
        "synth",
        s(&analysis),
        "--plane",
        "16x16",
        "--preset",
        "chen2008",
        "--search",
        "full",
        "-o",
        s(&out),
    ]);
    common::assert_usage_error(&r, "--search full");
    assert!(!out.exists());
}
