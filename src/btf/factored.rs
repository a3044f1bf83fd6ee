//! A stack held as its factors, the way a DFMF or FMF file stores it, instead of as images.
//!
//! Channel `c` of image `i` at texel `p` is Σₖ `image[c][i][k] · texel[c][p][k]`; the
//! file's colour model turns the three channels into RGB, a log-encoded file
//! ("dynamic-range reduction") then takes exp(x) − ε, and a file whose data hold cos θ_light
//! is divided by it (a per-image scale). Decoding one value is a K-term dot product per
//! channel, so a 400×400 × 22,801-image UBO2014 material (20 GiB of f16 images) is 60 MiB
//! of factors here, and any value is computed when asked for.

use crate::btf::colour::{ColourModel, DRR_EPS};
use crate::btf::source::ImageSource;
use crate::btf::DirectionPair;
use crate::{Error, Result};
use half::f16;
use ndarray::Array2;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// A stack as per-channel factors plus the decoding that turns them into linear RGB.
#[derive(Clone, Debug)]
pub struct FactoredStack {
    path: PathBuf,
    width: usize,
    height: usize,
    pairs: Vec<DirectionPair>,
    /// Per channel: `[images][components]`.
    pub image: Vec<Array2<f32>>,
    /// Per channel: `[texels][components]`, texels row-major (`x + width · y`).
    pub texel: Vec<Array2<f32>>,
    /// How the three channels encode RGB.
    pub model: ColourModel,
    /// The channels hold log(value + ε) of the colour model's output.
    pub log_encoded: bool,
    /// Per image: the factor decoded RGB is multiplied by (1/cos θ_light for a file whose
    /// cosine flag is set, else 1).
    pub scale: Vec<f32>,
}

impl FactoredStack {
    /// Assembles a factored stack; checks that the factor shapes agree with the sizes.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        path: &Path,
        (width, height): (usize, usize),
        pairs: Vec<DirectionPair>,
        image: Vec<Array2<f32>>,
        texel: Vec<Array2<f32>>,
        model: ColourModel,
        log_encoded: bool,
        scale: Vec<f32>,
    ) -> Result<Self> {
        let n = pairs.len();
        let bad = |m: String| Error::format(path, m);
        if image.len() != 3 || texel.len() != 3 {
            return Err(bad(format!(
                "{} image and {} texel factors; expected 3 channels",
                image.len(),
                texel.len()
            )));
        }
        if n == 0 || width == 0 || height == 0 || scale.len() != n {
            return Err(bad(format!(
                "factors of {n} images of {width}x{height} with {} scales",
                scale.len()
            )));
        }
        for c in 0..3 {
            let (a, b) = (&image[c], &texel[c]);
            if a.nrows() != n || b.nrows() != width * height || a.ncols() != b.ncols() || a.ncols() == 0 {
                return Err(bad(format!(
                    "channel {c}: image factors {:?} and texel factors {:?} do not fit {n} images of {width}x{height}",
                    a.dim(),
                    b.dim()
                )));
            }
        }
        if let Some(c) = (0..3).find(|&c| image[c].iter().chain(texel[c].iter()).any(|v| !v.is_finite())) {
            return Err(bad(format!("channel {c}: a factor is not a finite number")));
        }
        Ok(FactoredStack {
            path: path.to_path_buf(),
            width,
            height,
            pairs,
            image,
            texel,
            model,
            log_encoded,
            scale,
        })
    }

    /// Width of the images in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height of the images in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Number of images.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Whether the stack holds no images.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// The light and view directions of every image, in image order.
    pub fn pairs(&self) -> &[DirectionPair] {
        &self.pairs
    }

    /// Where the factors came from (for messages).
    pub fn source_path(&self) -> &Path {
        &self.path
    }

    /// Components per channel.
    pub fn components(&self) -> [usize; 3] {
        [0, 1, 2].map(|c| self.image[c].ncols())
    }

    /// Why decoding is not linear in the factors, if it is not: then a sum of images is
    /// not the decoding of the summed factors, and the factors are no basis of the images.
    pub fn nonlinearity(&self) -> Option<String> {
        if self.model.affine().is_none() {
            let why = match self.model {
                ColourModel::Lab => "takes a cube and the sRGB curve",
                ColourModel::Spectral | ColourModel::SpectralLinear => "multiplies channels",
                _ => "takes exponentials",
            };
            return Some(format!("its colour model {} ({}) {why}", self.model.id(), self.model.name()));
        }
        self.log_encoded.then(|| "its data are log-encoded (dynamic-range reduction: exp(x) - ε)".to_string())
    }

    /// The three channel values (before the colour model) of image `i` at texel `p`.
    #[inline]
    pub fn channels(&self, i: usize, p: usize) -> [f32; 3] {
        [0, 1, 2].map(|c| {
            let (a, b) = (self.image[c].row(i), self.texel[c].row(p));
            a.iter().zip(b.iter()).map(|(x, y)| x * y).sum()
        })
    }

    /// Linear RGB of image `i` at texel `p` (`x + width · y`), in f32 (no f16 rounding).
    #[inline]
    pub fn rgb(&self, i: usize, p: usize) -> [f32; 3] {
        decode_channels(self.model, self.log_encoded, self.scale[i], self.channels(i, p))
    }

    /// Linear RGB of the images of `block`, `[image][texel][3]`, by one matrix product per
    /// channel.
    pub fn decode_block(&self, block: Range<usize>) -> Vec<f32> {
        let pixels = self.width * self.height;
        let mut out = vec![0f32; block.len() * pixels * 3];
        for c in 0..3 {
            let values = self.image[c].slice(ndarray::s![block.clone(), ..]).dot(&self.texel[c].t());
            for (i, row) in values.rows().into_iter().enumerate() {
                let dst = &mut out[i * pixels * 3..(i + 1) * pixels * 3];
                for (p, v) in row.iter().enumerate() {
                    dst[p * 3 + c] = *v;
                }
            }
        }
        for (k, px) in out.chunks_exact_mut(3).enumerate() {
            let image = block.start + k / pixels;
            let rgb = decode_channels(self.model, self.log_encoded, self.scale[image], [px[0], px[1], px[2]]);
            px.copy_from_slice(&rgb);
        }
        out
    }

    /// Bytes the factors take in memory.
    pub fn bytes(&self) -> u64 {
        let values: usize = self.image.iter().chain(&self.texel).map(|a| a.len()).sum();
        values as u64 * 4 + self.scale.len() as u64 * 4
    }
}

/// Channel values to linear RGB: undo the colour model, then the log encoding, then scale.
#[inline]
pub(crate) fn decode_channels(model: ColourModel, log_encoded: bool, scale: f32, v: [f32; 3]) -> [f32; 3] {
    let rgb = model.to_rgb(v);
    let rgb = if log_encoded { rgb.map(|x| x.exp() - DRR_EPS) } else { rgb };
    rgb.map(|x| x * scale)
}

/// Rounds to f16, saturating at ±65504 (and NaN, which finite factors cannot produce but
/// an overflowing colour model might, becomes 0).
pub(crate) fn saturating_f16(x: f32) -> f16 {
    if x.is_nan() {
        return f16::ZERO;
    }
    f16::from_f32(x.clamp(-65504.0, 65504.0))
}

impl ImageSource for FactoredStack {
    fn path(&self) -> &Path {
        &self.path
    }

    fn width(&self) -> usize {
        self.width
    }

    fn height(&self) -> usize {
        self.height
    }

    fn pairs(&self) -> &[DirectionPair] {
        &self.pairs
    }

    fn decode_image(&self, i: usize, out: &mut [f16]) -> Result<()> {
        for (dst, v) in out.iter_mut().zip(self.decode_block(i..i + 1)) {
            *dst = saturating_f16(v);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::DirectionSet;

    #[test]
    fn a_value_is_the_dot_product_through_the_colour_model() {
        let pairs: Vec<_> = DirectionSet::Grid(2).pairs();
        let n = pairs.len();
        let image: Vec<Array2<f32>> =
            (0..3).map(|c| Array2::from_shape_fn((n, 2), |(i, k)| 0.1 * (i + k + c) as f32)).collect();
        let texel: Vec<Array2<f32>> =
            (0..3).map(|c| Array2::from_shape_fn((6, 2), |(p, k)| 0.2 * (p * k + c) as f32 - 0.1)).collect();
        let scale = (0..n).map(|i| 1.0 + i as f32).collect();
        let stack = FactoredStack::new(
            Path::new("t"),
            (3, 2),
            pairs,
            image.clone(),
            texel.clone(),
            ColourModel::LogYUvOverY,
            false,
            scale,
        )
        .unwrap();
        let block = stack.decode_block(0..n);
        for i in 0..n {
            for p in 0..6 {
                let v = [0, 1, 2].map(|c| image[c].row(i).dot(&texel[c].row(p)));
                let want = ColourModel::LogYUvOverY.to_rgb(v).map(|x| x * (1.0 + i as f32));
                let got = stack.rgb(i, p);
                for c in 0..3 {
                    assert!((got[c] - want[c]).abs() < 1e-5 * want[c].abs().max(1.0), "{got:?} {want:?}");
                    assert!((block[(i * 6 + p) * 3 + c] - want[c]).abs() < 1e-5 * want[c].abs().max(1.0));
                }
            }
        }
        assert!(stack.nonlinearity().unwrap().contains("exponentials"));
    }
}
