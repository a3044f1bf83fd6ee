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
//! ```no_run
//! use btfsynth::btf::{self, gen::{GenParams, MaterialKind}, DirectionSet};
//!
//! let params = GenParams { size: 32, directions: DirectionSet::Grid(9), ..GenParams::default() };
//! let stack = btf::gen::generate(MaterialKind::Pebbles, &params, &btfsynth::progress::Silent)?;
//! println!("{} images of {}x{}", stack.len(), stack.width(), stack.height());
//! # Ok::<(), btfsynth::Error>(())
//! ```

pub mod analysis;
pub mod btf;
#[cfg(feature = "cli")]
pub mod cli;
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
