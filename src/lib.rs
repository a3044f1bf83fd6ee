//! # btfsynth
//!
//! Puts real-world materials on 3D models: analysis, surface synthesis and rendering of
//! bidirectional texture functions (BTFs), after
//! Tong, Zhang, Liu, Wang, Guo and Shum, *Synthesis of Bidirectional Texture Functions on
//! Arbitrary Surfaces*, SIGGRAPH 2002.
//!
//! A BTF is a stack of photographs of one material patch under many view and light
//! directions. [`btf::Btf`] holds one; [`btf::load()`] reads the common layouts (a `btf.json`
//! manifest, Bonn/UTIA file names, or a single image as a one-image BTF), and
//! [`btf::gen`] makes synthetic ground truth by ray-tracing height fields.
//!
//! The whole path runs in memory; the disk is only an adapter (`analysis::store`,
//! `synth::plane::write_plane`, `synth::surface_map::write_surface_ply`, `export::export`,
//! the command line). Generate a small BTF, analyse it, synthesize a plane and the bundled
//! bunny from it, render the bunny and bake it into a glTF document
//! (`examples/pipeline.rs` is the same path, with the outputs saved if asked):
//!
//! ```
//! use btfsynth::analysis::pipeline::{analyze, AnalysisParams};
//! use btfsynth::btf::{self, gen::{GenParams, MaterialKind}, DirectionSet};
//! use btfsynth::export::{bake_export, ExportOptions, ExportSource, SourceNames};
//! use btfsynth::mesh::{field::Orientation, textured::load_textured};
//! use btfsynth::progress::Silent;
//! use btfsynth::render::{cpu::{render, RenderOptions}, tracer::Tracer, Material, Scene, ShotPlan};
//! use btfsynth::synth::surface_map::{build_pyramid, synthesize_surface, Density, SurfaceMap};
//! use btfsynth::synth::{plane::synthesize_plane, Sample, SynthParams};
//!
//! let params = GenParams { size: 32, samples_per_pixel: 1, directions: DirectionSet::Grid(4), ..GenParams::default() };
//! let stack = btf::gen::generate(MaterialKind::Pebbles, &params, &Silent)?;
//! let analysis = analyze(&stack, &AnalysisParams { textons: 64, levels: 2, ..AnalysisParams::default() }, &Silent)?;
//! let sample = Sample::from_analysis(&analysis, &stack, analysis.levels.len())?;
//! let synth = SynthParams::default();
//!
//! // A plane: per output pixel, a texton and the sample coordinate it copies.
//! let plane = synthesize_plane(&sample, (64, 64), false, &synth, &Silent)?;
//! let [u, v] = plane.state.uv[0];
//! assert!((0..32).contains(&u) && (0..32).contains(&v));
//!
//! // A mesh: the same per vertex of a remeshed pyramid (one level, the CLI's default on a
//! // mesh: the patches carry the structure), then a render and a glTF.
//! let bunny = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/bunny-1k8.obj");
//! let pyramid = build_pyramid(&btfsynth::mesh::load(&bunny)?, Density::Vertices(3_000), 1, &Orientation::Smooth, &synth, &Silent)?;
//! let (state, _) = synthesize_surface(&pyramid, &sample, &synth, &Silent)?;
//! let scene = Scene::from_surface_map(SurfaceMap::from_synthesis(&pyramid.levels[0], &state));
//! let material = Material::from_btf(&stack)?;
//! let shot = ShotPlan { size: (64, 64), ..ShotPlan::default() }.shots(scene.mesh.bounds())[0];
//! let frame = render(&scene, &material, &Tracer::new(&scene.mesh), &shot, RenderOptions::default(), None);
//! assert!(frame.rgba.chunks_exact(4).any(|p| p[3] > 0.0), "the bunny is in view");
//! let original = load_textured(&bunny)?;
//! let names = SourceNames { surface: "(memory)".as_ref(), analysis: "(memory)".as_ref(), mesh: &bunny };
//! let source = ExportSource { scene: &scene, material: &material, maps: &[], mesh: Some(&original), names };
//! let options = ExportOptions { size: Some(64), ..ExportOptions::default() };
//! let glb = bake_export("bunny", &source, &options, &Silent)?.document.to_glb();
//! assert_eq!(&glb[..4], b"glTF");
//! # Ok::<(), btfsynth::Error>(())
//! ```

#![warn(missing_docs)]

pub mod analysis;
pub mod btf;
pub mod cache;
pub mod env;
pub mod error;
pub mod eval;
pub mod export;
pub mod fsutil;
pub mod maps;
pub mod mesh;
pub mod progress;
pub mod render;
pub mod seeded;
pub mod sentinel;
pub mod synth;
#[doc(hidden)]
pub mod testdata;

pub use error::{Error, Param, Remedy, Result};
