//! `btfsynth demo`: the pipeline on bundled defaults, into demo-out/ (staged whole).

use super::progress::Bars;
use anyhow::Result;
use btfsynth::analysis::pipeline::{analyze, AnalysisParams};
use btfsynth::analysis::store;
use btfsynth::btf::gen::{generate, GenParams, MaterialKind};
use btfsynth::btf::{load, write_stack, Btf, DirectionSet, ImageFormat, LoadOptions};
use btfsynth::fsutil::StagedDir;
use btfsynth::mesh::field::Orientation;
use btfsynth::render::cpu::{render_sequence, RenderOptions};
use btfsynth::render::{FrameFormat, Material, Orbit, Scene, SequenceWriter, ShotPlan};
use btfsynth::synth::plane::{synthesize_plane, write_plane};
use btfsynth::synth::surface_map::{
    build_pyramid, comment_paths, escape_path, synthesize_surface, write_surface_ply, Density, SurfaceMap,
};
use btfsynth::synth::{Sample, Search, SynthParams};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct DemoArgs {
    /// Where to write the demo's outputs: built under a temporary name and moved there when
    /// complete, replacing an earlier demo's outputs (anything else there needs --force).
    #[arg(short, long, default_value = "demo-out", value_name = "DIR")]
    output: PathBuf,
    /// The bundled inputs (default: ./data, else the crate's own data/).
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
    /// Replace DIR even if it holds files the demo does not write.
    #[arg(long)]
    force: bool,
}

/// What the demo writes into its directory.
const DEMO_ENTRIES: [&str; 7] =
    ["stack", "analysis", "plane", "gravel-analysis", "gravel-plane", "bunny.ply", "frames"];

fn data_dir(given: Option<PathBuf>) -> PathBuf {
    given.unwrap_or_else(|| {
        let local = PathBuf::from("data");
        if local.is_dir() {
            local
        } else {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data")
        }
    })
}

/// Refuses to replace `dir` if it holds anything but an earlier demo's outputs, unless `force`.
fn check_demo_target(dir: &Path, force: bool) -> Result<()> {
    if force || std::fs::symlink_metadata(dir).is_err() {
        return Ok(());
    }
    if !dir.is_dir() {
        return Err(btfsynth::Error::invalid(format!(
            "{} already exists and is not a directory (pass --force to replace it)",
            dir.display()
        ))
        .into());
    }
    let entries = std::fs::read_dir(dir).map_err(|e| btfsynth::Error::io(dir, e))?;
    let foreign: Vec<String> = entries
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|name| !DEMO_ENTRIES.contains(&name.as_str()))
        .collect();
    if let Some(first) = foreign.first() {
        return Err(btfsynth::Error::invalid(format!(
            "{} holds files the demo does not write ({first}{}); pass --force to replace it",
            dir.display(),
            if foreign.len() > 1 { format!(" and {} more", foreign.len() - 1) } else { String::new() }
        ))
        .into());
    }
    Ok(())
}

pub fn run(args: DemoArgs, bars: &Bars) -> Result<()> {
    let data = data_dir(args.data.clone());
    check_demo_target(&args.output, args.force)?;
    btfsynth::fsutil::check_not_input("-o", &args.output, &[&data])?;
    // Everything is built in one staged directory, so an interrupted or failed demo leaves
    // nothing and an earlier demo's outputs stay until the new ones are complete.
    let staged = StagedDir::new(&args.output, true)?;
    let relocation = Relocation::new(staged.path(), &args.output);
    let out = |name: &str| staged.path().join(name);
    let shown = |name: &str| args.output.join(name);
    // Printed once the outputs are in place.
    let mut printed = Vec::new();
    eprintln!("[1/6] generating a 64x64 pebbles BTF on a 16-direction dome (256 images)");
    let params = GenParams { size: 64, directions: DirectionSet::Grid(16), ..GenParams::default() };
    let stack = generate(MaterialKind::Pebbles, &params, bars)?;
    let source = serde_json::json!({
        "generator": "btfsynth demo", "kind": "pebbles", "size": 64, "directions": "grid:16", "seed": 0
    });
    write_stack(&stack, &out("stack"), ImageFormat::Exr, Some(source), true, bars)?;
    let reloaded = load(&out("stack"), &LoadOptions::default(), bars)?;
    printed.push(serde_json::to_string_pretty(&super::info::stack_json(&shown("stack"), &reloaded))?);

    eprintln!("[2/6] texton analysis (200 textons, 3 levels, k = 11) and a 192x192 synthesized plane");
    let (manifest, sample) = analyse_and_synthesize(
        &reloaded,
        &out("stack"),
        AnalysisParams { textons: 200, ..AnalysisParams::default() },
        &out("analysis"),
        &out("plane"),
        bars,
    )?;
    printed.push(relocation.json_text(super::info::analysis_json(&manifest))?);

    let texture = data.join("gravel-128.png");
    eprintln!("[3/6] reading the bundled photograph {} as a one-image BTF", texture.display());
    let photo = load(&texture, &LoadOptions::default(), bars)?;
    printed.push(serde_json::to_string_pretty(&super::info::stack_json(&texture, &photo))?);
    eprintln!("[4/6] texture synthesis from the photograph: analysis and a 192x192 plane");
    let (manifest, _) = analyse_and_synthesize(
        &photo,
        &texture,
        AnalysisParams::default(),
        &out("gravel-analysis"),
        &out("gravel-plane"),
        bars,
    )?;
    printed.push(relocation.json_text(super::info::analysis_json(&manifest))?);
    let bunny = data.join("bunny-1k8.obj");
    eprintln!("[5/6] the pebbles BTF on {}: a 20k-vertex surface texton map", bunny.display());
    let scene = surface_map(&sample, (&out("analysis"), &bunny), &out("bunny.ply"), bars)?;
    eprintln!(
        "[6/6] rendering a {DEMO_FRAMES}-frame sun orbit under a sky, beside the sample under the same light"
    );
    light_orbit((&scene, &Material::from_btf(&reloaded)?), &out("frames"), bars)?;
    // The outputs name each other by the paths they were written at; they are about to move.
    for name in [
        "analysis/analysis.json",
        "gravel-analysis/analysis.json",
        "plane/plane.json",
        "gravel-plane/plane.json",
    ] {
        relocation.json_file(&out(name))?;
    }
    relocation.ply_header(&out("bunny.ply"))?;
    staged.commit()?;
    eprintln!(
        "done: look at {}/contact.png (the bunny under a moving light, beside the sample), \
         {}/frame_0000.exr (linear; .png beside it), {}/result.png (the photograph, \
         resynthesized), {}/level0_textons.png (a BTF's texton map), {} (open it in MeshLab \
         or Blender; per vertex: texton, u, v, frame) and {}/btf.json",
        shown("frames").display(),
        shown("frames").display(),
        shown("gravel-plane").display(),
        shown("analysis").display(),
        shown("bunny.ply").display(),
        shown("stack").display()
    );
    for text in printed {
        super::print(text)?;
    }
    Ok(())
}

/// Rewrites the paths that outputs built in the staging directory record of each other to
/// the final directory's (as given, and absolute).
struct Relocation {
    prefixes: Vec<(String, String)>,
}

impl Relocation {
    fn new(staging: &Path, target: &Path) -> Self {
        let mut prefixes = vec![(staging.display().to_string(), target.display().to_string())];
        if let (Ok(absolute), Some(name)) = (std::fs::canonicalize(staging), target.file_name()) {
            if let Some(parent) = absolute.parent() {
                prefixes.push((absolute.display().to_string(), parent.join(name).display().to_string()));
            }
        }
        Relocation { prefixes }
    }

    fn text(&self, s: &str) -> Option<String> {
        self.prefixes.iter().find_map(|(from, to)| {
            let rest = s.strip_prefix(from.as_str())?;
            (rest.is_empty() || rest.starts_with('/')).then(|| format!("{to}{rest}"))
        })
    }

    fn value(&self, v: &mut serde_json::Value) {
        match v {
            serde_json::Value::String(s) => {
                if let Some(moved) = self.text(s) {
                    *s = moved;
                }
            }
            serde_json::Value::Array(items) => items.iter_mut().for_each(|i| self.value(i)),
            serde_json::Value::Object(map) => map.values_mut().for_each(|i| self.value(i)),
            _ => {}
        }
    }

    fn json_text(&self, mut v: serde_json::Value) -> Result<String> {
        self.value(&mut v);
        Ok(serde_json::to_string_pretty(&v)?)
    }

    /// A JSON file rewritten in place (inside the staging directory, before the commit).
    fn json_file(&self, path: &Path) -> Result<()> {
        let text = std::fs::read_to_string(path).map_err(|e| btfsynth::Error::io(path, e))?;
        let mut v: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| btfsynth::Error::format(path, e.to_string()))?;
        self.value(&mut v);
        btfsynth::fsutil::write_file_atomic(path, self.json_text(v)?.as_bytes())?;
        Ok(())
    }

    /// A PLY's header comments rewritten in place (the body is kept byte for byte).
    fn ply_header(&self, path: &Path) -> Result<()> {
        let bytes = std::fs::read(path).map_err(|e| btfsynth::Error::io(path, e))?;
        let marker = b"end_header\n";
        let Some(end) = bytes.windows(marker.len()).position(|w| w == marker) else {
            return Err(btfsynth::Error::format(path, "no end_header").into());
        };
        let header = String::from_utf8_lossy(&bytes[..end]);
        let lines: Vec<String> = header
            .lines()
            .map(|line| match line.split_once(' ') {
                Some(("comment", rest)) => match rest.split_once(' ') {
                    // Paths are escaped in headers (`escape_path`).
                    Some((key, value)) => match self.text(&comment_paths(value)[0].display().to_string()) {
                        Some(moved) => format!("comment {key} {}", escape_path(Path::new(&moved))),
                        None => line.to_string(),
                    },
                    None => line.to_string(),
                },
                _ => line.to_string(),
            })
            .collect();
        let mut rewritten = lines.join("\n").into_bytes();
        rewritten.push(b'\n');
        rewritten.extend_from_slice(&bytes[end..]);
        btfsynth::fsutil::write_file_atomic(path, &rewritten)?;
        Ok(())
    }
}

/// Frames of the demo's light orbit.
const DEMO_FRAMES: usize = 16;

/// Renders the surface under a sun circling at 45° elevation and the built-in sky, EXR and
/// PNG frames.
fn light_orbit((scene, material): (&Scene, &Material), dir: &Path, bars: &Bars) -> Result<()> {
    let plan = ShotPlan { size: (384, 384), frames: DEMO_FRAMES, orbit: Orbit::Light, ..ShotPlan::default() };
    let mut writer = SequenceWriter::new(dir, &[FrameFormat::Exr, FrameFormat::Png], true)?;
    // The sky lights what the orbiting sun leaves in shadow (`render --env sky`).
    let sky = btfsynth::render::Environment::sky();
    render_sequence((scene, material), &plan, RenderOptions::default(), Some(&sky), true, &mut writer, bars)?;
    writer.finish()?;
    Ok(())
}

/// Synthesizes `sample` (stored in `analysis_dir`) onto `mesh` (20k vertices, smooth
/// frames), writes the surface map to `output` and returns the surface as a scene.
fn surface_map(
    sample: &Sample,
    (analysis_dir, mesh): (&Path, &Path),
    output: &Path,
    bars: &Bars,
) -> Result<Scene> {
    let params = SynthParams::default();
    let input = btfsynth::mesh::load(mesh)?;
    let pyramid = build_pyramid(&input, Density::Vertices(20_000), 3, &Orientation::Smooth, &params, bars)?;
    let (state, _) = synthesize_surface(&pyramid, sample, &params, bars)?;
    let params_json = serde_json::json!({"preset": params.preset.name, "k": 11, "levels": 3, "neighborhood": params.neighborhood, "orient": "smooth", "seed": params.seed});
    write_surface_ply(output, &pyramid.levels[0], &state, (analysis_dir, mesh), &params_json)?;
    Ok(Scene::from_surface_map(SurfaceMap::from_synthesis(&pyramid.levels[0], &state)))
}

/// Analyses `stack` into `analysis_dir` and synthesizes a 192×192 plane from it into
/// `plane_dir`; returns the analysis' manifest and its sample (in memory).
fn analyse_and_synthesize(
    stack: &Btf,
    source: &Path,
    params: AnalysisParams,
    analysis_dir: &Path,
    plane_dir: &Path,
    bars: &Bars,
) -> Result<(btfsynth::analysis::store::Manifest, Sample)> {
    let analysis = analyze(stack, &params, bars)?;
    store::write(&analysis, stack, source, None, analysis_dir, true)?;
    let manifest = store::read_manifest(analysis_dir)?;
    let sample = Sample::from_analysis(&analysis, stack, params.levels)?;
    let synth = SynthParams { search: Search::KCoherence { k: params.k }, ..SynthParams::default() };
    let mut plane = synthesize_plane(&sample, (192, 192), false, &synth, bars)?;
    super::synth::untimed(&mut plane.reports);
    write_plane(
        &plane,
        analysis_dir,
        &[],
        serde_json::json!({"preset": synth.preset.name, "neighborhood": synth.neighborhood, "seed": synth.seed}),
        plane_dir,
        true,
    )?;
    Ok((manifest, sample))
}
