//! `btfsynth demo`: the pipeline on bundled defaults, into demo-out/.

use super::progress::Bars;
use crate::analysis::pipeline::{analyze, AnalysisParams};
use crate::analysis::store;
use crate::btf::gen::{generate, GenParams, MaterialKind};
use crate::btf::{load, write_stack, Btf, DirectionSet, ImageFormat, LoadOptions};
use crate::mesh::field::Orientation;
use crate::render::cpu::{render_sequence, RenderOptions};
use crate::render::scene::open_surface;
use crate::render::{FrameFormat, Material, Orbit, SequenceWriter, ShotPlan};
use crate::synth::plane::{synthesize_plane, write_plane};
use crate::synth::surface_map::{build_pyramid, synthesize_surface, write_surface_ply, Density};
use crate::synth::{Sample, Search, SynthParams};
use anyhow::Result;
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct DemoArgs {
    /// Where to write the demo's outputs (replaced if it exists).
    #[arg(short, long, default_value = "demo-out", value_name = "DIR")]
    output: PathBuf,
    /// The bundled inputs (default: ./data, else the crate's own data/).
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
}

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

pub fn run(args: DemoArgs, bars: &Bars) -> Result<()> {
    std::fs::create_dir_all(&args.output).map_err(|e| crate::Error::io(&args.output, e))?;
    let out = |name: &str| args.output.join(name);
    let data = data_dir(args.data.clone());
    eprintln!("[1/6] generating a 64x64 pebbles BTF on a 16-direction dome (256 images)");
    let params = GenParams { size: 64, directions: DirectionSet::Grid(16), ..GenParams::default() };
    let stack = generate(MaterialKind::Pebbles, &params, bars)?;
    let source = serde_json::json!({
        "generator": "btfsynth demo", "kind": "pebbles", "size": 64, "directions": "grid:16", "seed": 0
    });
    write_stack(&stack, &out("stack"), ImageFormat::Exr, Some(source), true, bars)?;
    let reloaded = load(&out("stack"), &LoadOptions::default(), bars)?;
    println!("{}", serde_json::to_string_pretty(&super::info::stack_json(&out("stack"), &reloaded))?);

    eprintln!("[2/6] texton analysis (200 textons, 3 levels, k = 11) and a 192x192 synthesized plane");
    analyse_and_synthesize(
        &reloaded,
        &out("stack"),
        AnalysisParams { textons: 200, ..AnalysisParams::default() },
        &out("analysis"),
        &out("plane"),
        bars,
    )?;

    let texture = data.join("gravel-128.png");
    eprintln!("[3/6] reading the bundled photograph {} as a one-image BTF", texture.display());
    let photo = load(&texture, &LoadOptions::default(), bars)?;
    println!("{}", serde_json::to_string_pretty(&super::info::stack_json(&texture, &photo))?);
    eprintln!("[4/6] texture synthesis from the photograph: analysis and a 192x192 plane");
    analyse_and_synthesize(
        &photo,
        &texture,
        AnalysisParams::default(),
        &out("gravel-analysis"),
        &out("gravel-plane"),
        bars,
    )?;
    let bunny = data.join("bunny-1k8.obj");
    eprintln!("[5/6] the pebbles BTF on {}: a 20k-vertex surface texton map", bunny.display());
    surface_map(&out("analysis"), &bunny, &out("bunny.ply"), bars)?;
    eprintln!(
        "[6/6] rendering a {DEMO_FRAMES}-frame sun orbit under a sky, beside the sample under the same light"
    );
    light_orbit(&out("bunny.ply"), &out("frames"), bars)?;
    eprintln!(
        "done: look at {}/contact.png (the bunny under a moving light, beside the sample), \
         {}/frame_0000.exr (linear; .png beside it), {}/result.png (the photograph, \
         resynthesized), {}/level0_textons.png (a BTF's texton map), {} (open it in MeshLab \
         or Blender; per vertex: texton, u, v, frame) and {}/btf.json",
        out("frames").display(),
        out("frames").display(),
        out("gravel-plane").display(),
        out("analysis").display(),
        out("bunny.ply").display(),
        out("stack").display()
    );
    Ok(())
}

/// Frames of the demo's light orbit.
const DEMO_FRAMES: usize = 16;

/// Renders the surface map under a sun circling at 45° elevation and the built-in sky, EXR
/// and PNG frames.
fn light_orbit(surface: &Path, dir: &Path, bars: &Bars) -> Result<()> {
    let (scene, analysis) = open_surface(surface, None, true)?;
    let material = Material::open(&analysis)?;
    let plan = ShotPlan { size: (384, 384), frames: DEMO_FRAMES, orbit: Orbit::Light, ..ShotPlan::default() };
    let mut writer = SequenceWriter::new(dir, &[FrameFormat::Exr, FrameFormat::Png], true)?;
    // The sky lights what the orbiting sun leaves in shadow (`render --env sky`).
    let sky = crate::render::Environment::sky();
    render_sequence(
        (&scene, &material),
        &plan,
        RenderOptions::default(),
        Some(&sky),
        true,
        &mut writer,
        bars,
    )?;
    writer.finish()?;
    Ok(())
}

/// Synthesizes the analysis in `analysis_dir` onto `mesh` (20k vertices, smooth frames).
fn surface_map(analysis_dir: &Path, mesh: &Path, output: &Path, bars: &Bars) -> Result<()> {
    let sample = Sample::open(analysis_dir, 3)?;
    let params = SynthParams::default();
    let input = crate::mesh::load(mesh)?;
    let pyramid = build_pyramid(&input, Density::Vertices(20_000), 3, &Orientation::Smooth, &params, bars)?;
    let (state, _) = synthesize_surface(&pyramid, &sample, &params, bars)?;
    let params_json = serde_json::json!({"preset": params.preset.name, "k": 11, "levels": 3, "neighborhood": params.neighborhood, "orient": "smooth", "seed": params.seed});
    write_surface_ply(output, &pyramid.levels[0], &state, (analysis_dir, mesh), &params_json)?;
    Ok(())
}

/// Analyses `stack` into `analysis_dir`, prints its description, and synthesizes a 192×192
/// plane from it into `plane_dir`.
fn analyse_and_synthesize(
    stack: &Btf,
    source: &Path,
    params: AnalysisParams,
    analysis_dir: &Path,
    plane_dir: &Path,
    bars: &Bars,
) -> Result<()> {
    let analysis = analyze(stack, &params, bars)?;
    store::write(&analysis, stack, source, None, analysis_dir, true)?;
    println!(
        "{}",
        serde_json::to_string_pretty(&super::info::analysis_json(&store::read_manifest(analysis_dir)?))?
    );
    let sample = Sample::open(analysis_dir, params.levels)?;
    let synth = SynthParams { search: Search::KCoherence { k: params.k }, ..SynthParams::default() };
    let plane = synthesize_plane(&sample, (192, 192), false, &synth, bars)?;
    write_plane(
        &plane,
        analysis_dir,
        &[],
        serde_json::json!({"preset": synth.preset.name, "neighborhood": synth.neighborhood, "seed": synth.seed}),
        plane_dir,
        true,
    )?;
    Ok(())
}
