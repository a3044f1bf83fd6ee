//! Quality of a synthesized result against its sample.
//!
//! - [`picture`]: image space, on what a user sees: nearest-patch energy at two scales,
//!   colour χ², contrast; [`repetition`]: sample places recurring at regular offsets, and
//!   how evenly the sample is used.
//! - [`coords`]: the coordinate map: collapse, smear, copy, coherence.
//! - [`texton`]: texton space (Tong's terms): texton χ² and Γ energy.
//!
//! Texton-space figures alone can score a broken result as perfect; the image-space and
//! coordinate figures are the ones to read first.

pub mod coords;
pub mod picture;
pub mod repetition;
pub mod report;
pub mod texton;

pub use coords::{coord_quality, CoordQuality};
pub use picture::{picture_quality, Picture, PictureQuality};
pub use repetition::Repetition;
pub use texton::{chi2, energy, TextonQuality};
