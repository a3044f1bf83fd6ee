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
//! `synth::plane::write_plane`, the command line). Generate a small BTF, analyse it and
//! synthesize a larger plane from it:
//!
//! ```
//! use btfsynth::analysis::pipeline::{analyze, AnalysisParams};
//! use btfsynth::btf::{self, gen::{GenParams, MaterialKind}, DirectionSet};
//! use btfsynth::progress::Silent;
//! use btfsynth::synth::{plane::synthesize_plane, Sample, SynthParams};
//!
//! let params = GenParams { size: 32, samples_per_pixel: 1, directions: DirectionSet::Grid(4), ..GenParams::default() };
//! let stack = btf::gen::generate(MaterialKind::Pebbles, &params, &Silent)?;
//! let analysis = analyze(&stack, &AnalysisParams { textons: 64, levels: 2, ..AnalysisParams::default() }, &Silent)?;
//! let sample = Sample::from_analysis(&analysis, &stack, analysis.levels.len())?;
//! let plane = synthesize_plane(&sample, (64, 64), false, &SynthParams::default(), &Silent)?;
//! // Per output pixel: a texton and the sample coordinate it copies.
//! let [u, v] = plane.state.uv[0];
//! assert!((0..32).contains(&u) && (0..32).contains(&v));
//! # Ok::<(), btfsynth::Error>(())
//! ```

#![warn(missing_docs)]

pub mod analysis;
pub mod btf;
pub mod error;
pub mod eval;
pub mod export;
pub mod fsutil;
pub mod maps;
pub mod mesh;
pub mod progress;
pub mod render;
pub mod seeded;
pub mod synth;
#[doc(hidden)]
pub mod testdata;

pub use error::{Error, Result};
