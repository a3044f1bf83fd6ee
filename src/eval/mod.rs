//! Quality of a synthesized result against its sample.
//!
//! - [`picture`]: image space, on what a user sees: nearest-patch energy at two scales,
//!   colour χ², contrast; [`quality`] all of them at once; [`repetition`]: sample places recurring at regular offsets, and
//!   how evenly the sample is used; both on an exact nearest-patch search (`nearest`).
//! - [`surface`]: a texture as it lies on a surface (an exported model's, or a surface
//!   map's baked), against the sample at the same scale: smeared share, detail, contrast, colour.
//! - [`coords`]: the coordinate map: collapse, smear, copy, coherence.
//! - [`texton`]: texton space (Tong's terms): texton χ² and Γ energy.
//!
//! Texton-space figures alone can score a broken result as perfect; the image-space and
//! coordinate figures are the ones to read first.

pub mod coords;
pub(crate) mod nearest;
pub mod picture;
pub mod quality;
pub mod repetition;
pub mod report;
pub mod surface;
pub mod texton;

pub use coords::{coord_quality, CoordQuality};
pub use picture::Picture;
pub use quality::{picture_quality, PictureQuality};
pub use repetition::Repetition;
pub use texton::{chi2, energy, TextonQuality};
