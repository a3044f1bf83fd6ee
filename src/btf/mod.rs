//! The BTF stack: a W×H sample of one material photographed under n (light, view)
//! direction pairs, plus its loaders, writer and synthetic generator.
//!
//! Pixels are linear RGB stored as `f16`, one copy per image: a 64×64 × 6561-image stack
//! (the Bonn UBO2003 dome) takes 161 MiB.

pub mod archive;
pub mod colour;
pub mod convert;
pub mod directions;
pub mod factored;
pub mod factorize;
pub mod gen;
pub mod image_io;
mod jpeg_check;
pub mod load;
pub mod names;
pub mod source;
pub mod stack_file;
pub mod ubo2014;
pub mod utia;
pub mod write;

pub use directions::{Direction, DirectionPair, DirectionSet};
pub use load::{load, LoadOptions};
pub use source::ImageSource;
pub use write::{write_images, write_stack, ImageFormat};

use crate::{Error, Result};
use half::f16;

/// A rectangle of the sample, in pixels: origin `x, y`, size `w × h`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crop {
    /// Left edge in pixels.
    pub x: u32,
    /// Top edge in pixels.
    pub y: u32,
    /// Width in pixels (positive).
    pub width: u32,
    /// Height in pixels (positive).
    pub height: u32,
}

impl std::str::FromStr for Crop {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let bad = || {
            Error::out_of_range(
                crate::Param::Crop,
                format!("'{s}'"),
                "expected x,y,w,h (four non-negative integers, w and h > 0)",
            )
        };
        if parts.len() != 4 {
            return Err(bad());
        }
        let v: Vec<u32> =
            parts.iter().map(|p| p.parse::<u32>()).collect::<Result<_, _>>().map_err(|_| bad())?;
        if v[2] == 0 || v[3] == 0 {
            return Err(bad());
        }
        Ok(Crop { x: v[0], y: v[1], width: v[2], height: v[3] })
    }
}

/// One BTF sample: `len()` images of `width × height` linear RGB pixels, image `i` taken
/// under `pairs()[i]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Btf {
    width: usize,
    height: usize,
    pairs: Vec<DirectionPair>,
    /// Image-major, then row-major, RGB interleaved: `[n][height][width][3]`.
    pixels: Vec<f16>,
}

impl Btf {
    /// Assembles a stack from its parts; checks that the sizes agree and the pairs are
    /// distinct.
    pub fn new(width: usize, height: usize, pairs: Vec<DirectionPair>, pixels: Vec<f16>) -> Result<Self> {
        if width == 0 || height == 0 || pairs.is_empty() {
            return Err(Error::invalid("a BTF needs at least one image of at least 1x1 pixels"));
        }
        if pixels.len() != pairs.len() * width * height * 3 {
            return Err(Error::invalid(format!(
                "{} pixel values do not make {} images of {width}x{height} RGB",
                pixels.len(),
                pairs.len()
            )));
        }
        if let Some((a, b)) = directions::first_duplicate(&pairs) {
            return Err(Error::invalid(format!(
                "images {a} and {b} have the same light and view directions ({})",
                pairs[a]
            )));
        }
        Ok(Btf { width, height, pairs, pixels })
    }

    /// Width of every image in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height of every image in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Number of images.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Always false: a `Btf` holds at least one image.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// The (light, view) pair of every image, in image order.
    pub fn pairs(&self) -> &[DirectionPair] {
        &self.pairs
    }

    /// All pixels, `[n][height][width][3]`.
    pub fn pixels(&self) -> &[f16] {
        &self.pixels
    }

    /// The pixels of image `i`, `[height][width][3]`.
    pub fn image(&self, i: usize) -> &[f16] {
        let n = self.width * self.height * 3;
        &self.pixels[i * n..(i + 1) * n]
    }

    /// Linear RGB of pixel (x, y) in image `i`.
    pub fn rgb(&self, i: usize, x: usize, y: usize) -> [f32; 3] {
        let o = ((i * self.height + y) * self.width + x) * 3;
        [self.pixels[o].to_f32(), self.pixels[o + 1].to_f32(), self.pixels[o + 2].to_f32()]
    }

    /// The distinct view directions, in first-seen order.
    pub fn views(&self) -> Vec<Direction> {
        directions::distinct(self.pairs.iter().map(|p| p.view))
    }

    /// The distinct light directions, in first-seen order.
    pub fn lights(&self) -> Vec<Direction> {
        directions::distinct(self.pairs.iter().map(|p| p.light))
    }

    /// Index of the image taken under exactly this pair, if any.
    pub fn find(&self, pair: &DirectionPair) -> Option<usize> {
        self.pairs.iter().position(|p| p.same_as(pair))
    }
}
