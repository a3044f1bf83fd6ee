//! Rendering a surface BTF (Tong et al. 2002 §6): per surface point, the view and light
//! directions in its (s, t, n) frame select 4 × 4 sample images, blended at its sample
//! coordinate.
//!
//! [`material`] holds the shading core that the CPU ray tracer and the wgpu renderer share:
//! the 16 images and weights of a (view, light) query ([`material::Material::blend`], with
//! the weighting scheme explained in [`blend`]) and the bilinear lookup.

pub mod ambient;
pub mod blend;
pub mod environment;
pub mod material;

pub use environment::Environment;
pub use material::{Blend16, Material};
pub mod camera;
pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod output;
pub mod overlay;
pub mod relight;
pub mod scene;
pub mod shadow_map;
pub mod tracer;
#[cfg(feature = "gpu")]
pub mod viewer;

pub use camera::{Camera, Orbit, Projection, Shot, ShotPlan};
pub use output::{Frame, FrameFormat, SequenceWriter};
pub use scene::{Mode, Scene};
