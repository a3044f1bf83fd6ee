//! The whole pipeline in memory, with no file between its stages: generate a small BTF,
//! analyse it, synthesize it on a plane and on the bundled bunny, render the bunny, and bake
//! it into a glTF document. The command line's `analyze`, `synth`, `render` and `export`
//! are these calls with the disk in between.
//!
//! `cargo run --release --example pipeline [-- OUT_DIR]`: with OUT_DIR, the render
//! (`bunny.png`) and the glTF (`bunny.glb`) are saved there; without, nothing is written.

use btfsynth::analysis::pipeline::{analyze, AnalysisParams};
use btfsynth::btf::gen::{generate, GenParams, MaterialKind};
use btfsynth::btf::DirectionSet;
use btfsynth::export::{bake_export, ExportOptions, ExportSource, SourceNames};
use btfsynth::mesh::field::Orientation;
use btfsynth::mesh::textured::load_textured;
use btfsynth::progress::Silent;
use btfsynth::render::cpu::{render, RenderOptions};
use btfsynth::render::tracer::Tracer;
use btfsynth::render::{FrameFormat, Material, Scene, ShotPlan};
use btfsynth::synth::plane::synthesize_plane;
use btfsynth::synth::surface_map::{build_pyramid, synthesize_surface, Density, SurfaceMap};
use btfsynth::synth::{Sample, SynthParams};
use std::path::{Path, PathBuf};

fn main() -> btfsynth::Result<()> {
    let out = std::env::args_os().nth(1).map(PathBuf::from);
    // A 32² pebbles BTF seen and lit from 4 directions each (16 images).
    let params = GenParams {
        size: 32,
        samples_per_pixel: 1,
        directions: DirectionSet::Grid(4),
        ..GenParams::default()
    };
    let stack = generate(MaterialKind::Pebbles, &params, &Silent)?;
    let analysis =
        analyze(&stack, &AnalysisParams { textons: 64, levels: 2, ..AnalysisParams::default() }, &Silent)?;
    let sample = Sample::from_analysis(&analysis, &stack, analysis.levels.len())?;
    println!(
        "analysed {} images of {}x{}: {} levels",
        stack.len(),
        stack.width(),
        stack.height(),
        sample.levels.len()
    );

    let synth = SynthParams::default();
    let plane = synthesize_plane(&sample, (96, 96), false, &synth, &Silent)?;
    println!("plane: 96x96 texels, texton of the first: {}", plane.state.labels[0]);

    let bunny = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/bunny-1k8.obj");
    let mesh = btfsynth::mesh::load(&bunny)?;
    let pyramid = build_pyramid(&mesh, Density::Vertices(8_000), 1, &Orientation::Smooth, &synth, &Silent)?;
    let (state, _) = synthesize_surface(&pyramid, &sample, &synth, &Silent)?;
    let scene = Scene::from_surface_map(SurfaceMap::from_synthesis(&pyramid.levels[0], &state));
    println!("surface: {} vertices on {}", scene.mesh.vertex_count(), bunny.display());

    let material = Material::from_btf(&stack)?;
    let shot = ShotPlan { size: (256, 256), ..ShotPlan::default() }.shots(scene.mesh.bounds())[0];
    let frame = render(&scene, &material, &Tracer::new(&scene.mesh), &shot, RenderOptions::default(), None);
    let covered = frame.rgba.chunks_exact(4).filter(|p| p[3] > 0.0).count();
    println!("render: 256x256, the bunny covers {covered} pixels");

    let original = load_textured(&bunny)?;
    let names =
        SourceNames { surface: Path::new("(in memory)"), analysis: Path::new("(in memory)"), mesh: &bunny };
    let source = ExportSource { scene: &scene, material: &material, maps: &[], mesh: Some(&original), names };
    let options = ExportOptions { size: Some(256), ..ExportOptions::default() };
    let exported = bake_export("bunny", &source, &options, &Silent)?;
    let glb = exported.document.to_glb();
    println!("glTF: {} bytes, {} triangles", glb.len(), original.triangles.len());

    if let Some(dir) = out {
        std::fs::create_dir_all(&dir).map_err(|e| btfsynth::Error::io(&dir, e))?;
        frame.save(&dir.join("bunny.png"), FrameFormat::Png)?;
        btfsynth::fsutil::write_file_atomic(&dir.join("bunny.glb"), &glb)?;
        println!("wrote {}/bunny.png and bunny.glb", dir.display());
    }
    Ok(())
}
