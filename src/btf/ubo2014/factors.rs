//! The factor matrices of (D)FMF files and the products that turn them back into images.
//!
//! A channel's value in image `i` at pixel `p` is Σₖ A[i][k] · B[p][k], where A is the
//! image-side factor (one row per light × view pair) and B the pixel-side factor (one row
//! per texel). Which of the file's U and SxV plays which side depends on the file's
//! orientation; FMF files interleave the colour channels in the rows of one side.
//! Only the rows a crop needs are read from disk.

use super::bytes::Bytes;
use crate::{Error, Result};
use half::f16;
use ndarray::Array2;
use std::ops::Range;
use std::path::Path;

/// How a matrix stores its scalars.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Scalar {
    /// IEEE half precision, 2 bytes.
    F16,
    /// IEEE single precision, 4 bytes.
    F32,
    /// IEEE double precision, 8 bytes.
    F64,
}

impl Scalar {
    /// The scalar for a file's size byte (2, 4 or 8).
    pub fn from_size(size: u8) -> Option<Self> {
        match size {
            2 => Some(Scalar::F16),
            4 => Some(Scalar::F32),
            8 => Some(Scalar::F64),
            _ => None,
        }
    }

    /// Bytes per scalar.
    pub fn size(self) -> u64 {
        match self {
            Scalar::F16 => 2,
            Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// Little-endian scalars to f32.
    pub fn decode(self, bytes: &[u8], out: &mut [f32]) {
        match self {
            Scalar::F16 => {
                for (o, b) in out.iter_mut().zip(bytes.chunks_exact(2)) {
                    *o = f16::from_le_bytes([b[0], b[1]]).to_f32();
                }
            }
            Scalar::F32 => {
                for (o, b) in out.iter_mut().zip(bytes.chunks_exact(4)) {
                    *o = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                }
            }
            Scalar::F64 => {
                for (o, b) in out.iter_mut().zip(bytes.chunks_exact(8)) {
                    let mut a = [0u8; 8];
                    a.copy_from_slice(b);
                    *o = f64::from_le_bytes(a) as f32;
                }
            }
        }
    }
}

/// A row-major matrix in the file: `rows` × `cols` scalars from `offset`.
#[derive(Clone, Debug, PartialEq)]
pub struct Matrix {
    /// What the matrix is, for error messages ("channel 1 SxV").
    pub name: String,
    pub offset: u64,
    pub rows: u64,
    pub cols: usize,
    pub scalar: Scalar,
}

impl Matrix {
    /// Bytes the matrix takes.
    pub fn bytes(&self) -> u64 {
        self.rows * self.cols as u64 * self.scalar.size()
    }

    /// Reads the rows in `ranges` (in order) as f32. Every range lies inside the matrix,
    /// whose extent was checked against the file when the header was read.
    pub fn read_rows(&self, bytes: &Bytes, path: &Path, ranges: &[Range<u64>]) -> Result<Array2<f32>> {
        let total: u64 = ranges.iter().map(|r| r.end - r.start).sum();
        let row_bytes = self.cols as u64 * self.scalar.size();
        let mut out = Array2::<f32>::zeros((total as usize, self.cols));
        let flat = out.as_slice_mut().ok_or_else(|| Error::internal("factor buffer is not contiguous"))?;
        let mut raw = Vec::new();
        let mut filled = 0usize;
        for r in ranges {
            debug_assert!(r.end <= self.rows);
            let n = ((r.end - r.start) * row_bytes) as usize;
            raw.resize(n, 0);
            bytes.read_at(path, self.offset + r.start * row_bytes, &mut raw)?;
            let values = ((r.end - r.start) as usize) * self.cols;
            self.scalar.decode(&raw, &mut flat[filled..filled + values]);
            filled += values;
        }
        if let Some(bad) = flat.iter().position(|v| !v.is_finite()) {
            let row = ranges_row(ranges, (bad / self.cols.max(1)) as u64);
            return Err(Error::format(
                path,
                format!("{}: row {row} holds a value that is not a finite number", self.name),
            ));
        }
        Ok(out)
    }
}

/// The matrix row of the `k`-th row read from `ranges`.
fn ranges_row(ranges: &[Range<u64>], mut k: u64) -> u64 {
    for r in ranges {
        let n = r.end - r.start;
        if k < n {
            return r.start + k;
        }
        k -= n;
    }
    0
}

/// Where one side of one channel's factorization lies.
#[derive(Clone, Debug, PartialEq)]
pub enum Side {
    /// Row `item` of the matrix.
    Rows(Matrix),
    /// Row `channel + channels · item` (FMF interleaves the colour channels).
    Interleaved { matrix: Matrix, channels: usize, channel: usize },
}

impl Side {
    /// Reads the rows of the items in `items` (in order).
    pub fn read(&self, bytes: &Bytes, path: &Path, items: &[Range<u64>]) -> Result<Array2<f32>> {
        match self {
            Side::Rows(m) => m.read_rows(bytes, path, items),
            Side::Interleaved { matrix, channels, channel } => {
                let c = *channels as u64;
                let rows: Vec<Range<u64>> = items.iter().map(|r| r.start * c..r.end * c).collect();
                let all = matrix.read_rows(bytes, path, &rows)?;
                Ok(all.slice(ndarray::s![*channel..;*channels, ..]).to_owned())
            }
        }
    }
}

/// One channel: its image-side and pixel-side factors as stored.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelLayout {
    pub image: Side,
    pub pixel: Side,
    /// The components (columns) of both sides.
    pub components: usize,
}

/// The factors of every channel, read for one crop.
pub struct Factors {
    /// Per channel: `[images][components]`.
    pub image: Vec<Array2<f32>>,
    /// Per channel: `[crop pixels][components]`, crop rows top to bottom.
    pub pixel: Vec<Array2<f32>>,
}

impl Factors {
    /// Reads every channel's image side whole and the pixel rows of `pixel_ranges`.
    pub fn read(
        layouts: &[ChannelLayout],
        images: u64,
        pixel_ranges: &[Range<u64>],
        bytes: &Bytes,
        path: &Path,
    ) -> Result<Self> {
        let mut image = Vec::with_capacity(layouts.len());
        let mut pixel = Vec::with_capacity(layouts.len());
        for layout in layouts {
            image.push(layout.image.read(bytes, path, std::slice::from_ref(&(0..images)))?);
            pixel.push(layout.pixel.read(bytes, path, pixel_ranges)?);
        }
        Ok(Factors { image, pixel })
    }

    /// The channel values of `images` (a block), `[image][pixel][channel]` flattened.
    pub fn product(&self, images: Range<usize>) -> Vec<f32> {
        let channels = self.image.len();
        let pixels = self.pixel.first().map_or(0, |p| p.nrows());
        let mut out = vec![0f32; images.len() * pixels * channels];
        for (c, (a, b)) in self.image.iter().zip(&self.pixel).enumerate() {
            let block = a.slice(ndarray::s![images.clone(), ..]).dot(&b.t());
            for (i, row) in block.rows().into_iter().enumerate() {
                let dst = &mut out[i * pixels * channels..(i + 1) * pixels * channels];
                for (p, v) in row.iter().enumerate() {
                    dst[p * channels + c] = *v;
                }
            }
        }
        out
    }
}
