//! The library's in-memory path: an analysis used straight from memory synthesizes exactly
//! what the same analysis gives after a round trip through its directory.

use btfsynth::analysis::pipeline::{analyze, AnalysisParams};
use btfsynth::analysis::store;
use btfsynth::btf::{
    self,
    gen::{GenParams, MaterialKind},
    DirectionSet,
};
use btfsynth::progress::Silent;
use btfsynth::synth::{plane::synthesize_plane, Sample, SynthParams};

#[test]
fn a_sample_from_memory_synthesizes_what_its_directory_does() {
    let params = GenParams {
        size: 32,
        samples_per_pixel: 1,
        directions: DirectionSet::Grid(4),
        ..GenParams::default()
    };
    let stack = btf::gen::generate(MaterialKind::Bricks, &params, &Silent).unwrap();
    let analysis =
        analyze(&stack, &AnalysisParams { textons: 48, levels: 2, ..AnalysisParams::default() }, &Silent)
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("analysis");
    store::write(&analysis, &stack, std::path::Path::new("bricks"), None, &out, false).unwrap();
    let from_disk = Sample::open(&out, 2).unwrap();
    let from_memory = Sample::from_analysis(&analysis, &stack, 2).unwrap();
    for params in [SynthParams::default(), SynthParams { seed: 3, ..SynthParams::default() }] {
        let a = synthesize_plane(&from_disk, (48, 40), false, &params, &Silent).unwrap();
        let b = synthesize_plane(&from_memory, (48, 40), false, &params, &Silent).unwrap();
        assert_eq!((a.state.uv, a.state.labels), (b.state.uv, b.state.labels));
    }
    assert!(Sample::from_analysis(&analysis, &stack, 3).is_err(), "only the analysed levels exist");
}

/// The rest of the path in memory: a surface synthesized in memory renders from the same
/// scene as its PLY read back, and bakes into the same glTF bytes that `export` writes from
/// the files.
#[test]
fn a_surface_from_memory_renders_and_exports_what_its_files_do() {
    use btfsynth::export::{bake_export, export, ExportOptions, ExportSource, SourceNames};
    use btfsynth::mesh::{field::Orientation, textured::load_textured};
    use btfsynth::render::{scene::open_surface, Material, Scene};
    use btfsynth::synth::surface_map::{
        build_pyramid, synthesize_surface, write_surface_ply, Density, SurfaceMap,
    };
    let params = GenParams {
        size: 32,
        samples_per_pixel: 1,
        directions: DirectionSet::Grid(4),
        ..GenParams::default()
    };
    let stack = btf::gen::generate(MaterialKind::Pebbles, &params, &Silent).unwrap();
    let analysis =
        analyze(&stack, &AnalysisParams { textons: 48, levels: 2, ..AnalysisParams::default() }, &Silent)
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let analysis_dir = dir.path().join("analysis");
    store::write(&analysis, &stack, std::path::Path::new("pebbles"), None, &analysis_dir, false).unwrap();
    let sample = Sample::from_analysis(&analysis, &stack, 2).unwrap();
    let mesh_path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/bunny-1k8.obj");
    let mesh = btfsynth::mesh::load(&mesh_path).unwrap();
    let synth = SynthParams::default();
    let pyramid =
        build_pyramid(&mesh, Density::Vertices(3_000), 2, &Orientation::Smooth, &synth, &Silent).unwrap();
    let (state, _) = synthesize_surface(&pyramid, &sample, &synth, &Silent).unwrap();
    let ply = dir.path().join("bunny.ply");
    write_surface_ply(&ply, &pyramid.levels[0], &state, (&analysis_dir, &mesh_path), &serde_json::json!({}))
        .unwrap();

    let in_memory = Scene::from_surface_map(SurfaceMap::from_synthesis(&pyramid.levels[0], &state));
    let (read_back, _) = open_surface(&ply, None, true).unwrap();
    assert_eq!(in_memory.mesh.positions(), read_back.mesh.positions());
    assert_eq!(in_memory.mesh.triangles(), read_back.mesh.triangles());
    assert_eq!((&in_memory.uv, &in_memory.labels), (&read_back.uv, &read_back.labels));
    assert_eq!((&in_memory.frames.s, in_memory.texel), (&read_back.frames.s, read_back.texel));

    let options = ExportOptions {
        size: Some(64),
        analysis: Some(analysis_dir.clone()),
        mesh: Some(mesh_path.clone()),
        ..ExportOptions::default()
    };
    let glb = dir.path().join("bunny.glb");
    export(&ply, &glb, &options, &Silent).unwrap();
    let material = Material::open(&analysis_dir).unwrap();
    let original = load_textured(&mesh_path).unwrap();
    let names = SourceNames { surface: &ply, analysis: &analysis_dir, mesh: &mesh_path };
    let source =
        ExportSource { scene: &in_memory, material: &material, maps: &[], mesh: Some(&original), names };
    let baked = bake_export("bunny", &source, &options, &Silent).unwrap();
    assert!(baked.document.to_glb() == std::fs::read(&glb).unwrap(), "the same glTF bytes");
    // The sample of the analysis is the stack's own images.
    let from_btf = Material::from_btf(&stack).unwrap();
    assert_eq!((from_btf.len(), from_btf.image(0)), (material.len(), material.image(0)));
}
