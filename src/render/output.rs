//! Rendered frames and the directory a sequence is written to: `frame_0000.exr` (linear f32
//! RGBA) or `.png` (8-bit sRGB RGBA), and `contact.png`, a sheet of every frame. The
//! directory is staged and renamed into place when the last file is written.

use crate::btf::image_io::{linear_to_srgb8, write_png8};
use crate::fsutil::StagedDir;
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// A rendered image: linear RGBA, rows top to bottom; alpha is the share of the pixel the
/// model covers (1 inside, between 0 and 1 on anti-aliased edges) and the colour is
/// premultiplied by it (as EXR expects).
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width × height × 4` values, RGBA interleaved, rows top to bottom.
    pub rgba: Vec<f32>,
}

impl Frame {
    /// A transparent black frame.
    pub fn new(width: usize, height: usize) -> Frame {
        Frame { width, height, rgba: vec![0.0; width * height * 4] }
    }

    /// Pixel (x, y) as RGBA.
    pub fn pixel(&self, x: usize, y: usize) -> [f32; 4] {
        let o = (y * self.width + x) * 4;
        [self.rgba[o], self.rgba[o + 1], self.rgba[o + 2], self.rgba[o + 3]]
    }

    /// `self` and `other` side by side (heights padded to the taller).
    pub fn beside(&self, other: &Frame) -> Frame {
        let mut out = Frame::new(self.width + other.width, self.height.max(other.height));
        for (src, x0) in [(self, 0), (other, self.width)] {
            for y in 0..src.height {
                let row = &src.rgba[y * src.width * 4..(y + 1) * src.width * 4];
                let o = (y * out.width + x0) * 4;
                out.rgba[o..o + row.len()].copy_from_slice(row);
            }
        }
        out
    }

    /// 8-bit sRGB RGBA with straight (not premultiplied) alpha, as PNG expects.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.rgba
            .chunks_exact(4)
            .flat_map(|p| {
                let a = p[3].clamp(0.0, 1.0);
                let straight = |c: f32| if a > 0.0 { c / a } else { c };
                [
                    linear_to_srgb8(straight(p[0])),
                    linear_to_srgb8(straight(p[1])),
                    linear_to_srgb8(straight(p[2])),
                    (a * 255.0).round() as u8,
                ]
            })
            .collect()
    }

    /// Writes an EXR (f32 RGBA, lossless) or PNG (by the extension of `path`).
    pub fn save(&self, path: &Path, format: FrameFormat) -> Result<()> {
        match format {
            FrameFormat::Exr => {
                use exr::prelude::{Encoding, Image, SpecificChannels, Vec2, WritableImage};
                let channels = SpecificChannels::rgba(|Vec2(x, y)| {
                    let p = self.pixel(x, y);
                    (p[0], p[1], p[2], p[3])
                });
                Image::from_encoded_channels((self.width, self.height), Encoding::SMALL_LOSSLESS, channels)
                    .write()
                    .to_file(path)
                    .map_err(|e| Error::format(path, format!("cannot write EXR: {e}")))
            }
            FrameFormat::Png => {
                write_png8(path, self.width, self.height, &self.to_srgb8(), image::ExtendedColorType::Rgba8)
            }
        }
    }

    /// A box-filtered copy at most `max_width` wide.
    pub fn thumbnail(&self, max_width: usize) -> Frame {
        let step = self.width.div_ceil(max_width).max(1);
        let (w, h) = (self.width / step, self.height / step);
        let mut out = Frame::new(w.max(1), h.max(1));
        for y in 0..out.height {
            for x in 0..out.width {
                let mut sum = [0.0f32; 4];
                for dy in 0..step {
                    for dx in 0..step {
                        let p = self
                            .pixel((x * step + dx).min(self.width - 1), (y * step + dy).min(self.height - 1));
                        (0..4).for_each(|c| sum[c] += p[c]);
                    }
                }
                let o = (y * out.width + x) * 4;
                (0..4).for_each(|c| out.rgba[o + c] = sum[c] / (step * step) as f32);
            }
        }
        out
    }
}

/// File format of the frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum FrameFormat {
    /// OpenEXR, linear f32 RGBA (lossless ZIP).
    #[default]
    Exr,
    /// PNG, 8-bit sRGB RGBA.
    Png,
}

impl FrameFormat {
    fn extension(self) -> &'static str {
        match self {
            FrameFormat::Exr => "exr",
            FrameFormat::Png => "png",
        }
    }
}

/// Width of one frame on the contact sheet.
const SHEET_CELL: usize = 256;

/// Writes a sequence of frames into a staged directory.
pub struct SequenceWriter {
    staged: StagedDir,
    formats: Vec<FrameFormat>,
    thumbnails: Vec<Frame>,
}

impl SequenceWriter {
    /// Prepares `dir` (fails now if it exists without `overwrite`, or cannot be created).
    /// Each frame is written in every one of `formats`.
    pub fn new(dir: &Path, formats: &[FrameFormat], overwrite: bool) -> Result<SequenceWriter> {
        Ok(SequenceWriter {
            staged: StagedDir::new(dir, overwrite)?,
            formats: formats.to_vec(),
            thumbnails: Vec::new(),
        })
    }

    /// Writes the next frame.
    pub fn push(&mut self, frame: &Frame) -> Result<()> {
        let i = self.thumbnails.len();
        for &format in &self.formats {
            let path = self.staged.path().join(format!("frame_{i:04}.{}", format.extension()));
            frame.save(&path, format)?;
        }
        self.thumbnails.push(frame.thumbnail(SHEET_CELL));
        Ok(())
    }

    /// Writes `contact.png` and moves the directory into place.
    pub fn finish(self) -> Result<PathBuf> {
        let sheet = contact_sheet(&self.thumbnails);
        sheet.save(&self.staged.path().join("contact.png"), FrameFormat::Png)?;
        self.staged.commit()
    }
}

/// The frames in a near-square grid, on an opaque dark grey.
pub fn contact_sheet(frames: &[Frame]) -> Frame {
    let columns = (frames.len() as f64).sqrt().ceil().max(1.0) as usize;
    let rows = frames.len().div_ceil(columns).max(1);
    let cell_w = frames.iter().map(|f| f.width).max().unwrap_or(1);
    let cell_h = frames.iter().map(|f| f.height).max().unwrap_or(1);
    let mut sheet = Frame::new(columns * cell_w, rows * cell_h);
    sheet.rgba.chunks_exact_mut(4).for_each(|p| p.copy_from_slice(&[0.02, 0.02, 0.02, 1.0]));
    for (i, f) in frames.iter().enumerate() {
        let (x0, y0) = ((i % columns) * cell_w, (i / columns) * cell_h);
        for y in 0..f.height {
            for x in 0..f.width {
                let p = f.pixel(x, y);
                let o = ((y0 + y) * sheet.width + x0 + x) * 4;
                for c in 0..3 {
                    sheet.rgba[o + c] = p[c] + sheet.rgba[o + c] * (1.0 - p[3]);
                }
            }
        }
    }
    sheet
}
