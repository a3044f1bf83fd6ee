//! Image-space quality of a synthesized texture against its sample, on the pictures a user
//! looks at (sRGB-encoded values in [0, 1]): nearest-patch energy at two scales, the colour
//! histogram χ² and the luminance-contrast ratio.
//!
//! Texton-space figures can look perfect on a broken result (a smear of one texel, a
//! featureless blur); these cannot, because they compare what is seen.

use super::nearest::PatchIndex;

/// An RGB picture, row-major, sRGB-encoded values in [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct Picture {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width × height` pixels, row `y` at `y * width`.
    pub rgb: Vec<[f32; 3]>,
}

impl Picture {
    /// A PNG or JPEG file, its values kept as stored (sRGB-encoded).
    pub fn read(path: &std::path::Path) -> crate::Result<Self> {
        let rgb = image::open(path)
            .map_err(|e| crate::Error::format(path, format!("cannot read the picture: {e}")))?
            .to_rgb32f();
        let (width, height) = (rgb.width() as usize, rgb.height() as usize);
        Ok(Picture { width, height, rgb: rgb.pixels().map(|p| p.0).collect() })
    }

    /// A picture from linear RGB values (clamped, then sRGB-encoded).
    pub fn from_linear(width: usize, height: usize, linear: impl IntoIterator<Item = [f32; 3]>) -> Self {
        let rgb = linear.into_iter().map(|p| p.map(encode_srgb)).collect();
        Picture { width, height, rgb }
    }

    #[inline]
    fn at(&self, x: usize, y: usize) -> [f32; 3] {
        self.rgb[y * self.width + x]
    }

    /// Half the size, each pixel the mean of a 2×2 block (an odd last row/column is dropped).
    pub fn half(&self) -> Picture {
        let (w, h) = (self.width / 2, self.height / 2);
        let rgb = (0..w * h)
            .map(|i| {
                let (x, y) = (2 * (i % w), 2 * (i / w));
                let block = [self.at(x, y), self.at(x + 1, y), self.at(x, y + 1), self.at(x + 1, y + 1)];
                [0, 1, 2].map(|c| block.iter().map(|p| p[c]).sum::<f32>() / 4.0)
            })
            .collect();
        Picture { width: w, height: h, rgb }
    }

    /// Rec. 709 luma of the encoded values.
    fn luma(&self) -> impl Iterator<Item = f32> + '_ {
        self.rgb.iter().map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
    }
}

/// Linear to sRGB-encoded, clamped to [0, 1].
pub fn encode_srgb(v: f32) -> f32 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Side of the patches compared.
pub const PATCH_SIDE: usize = 7;
/// Result patches are taken every this many pixels in x and y (the sample's at every pixel).
pub const PATCH_STRIDE: usize = 4;

/// Mean nearest-patch squared difference per value (see [`super::PictureQuality::patch_energy`]).
/// NaN if either picture is smaller than a patch.
pub fn patch_energy(result: &Picture, sample: &Picture, stride: usize, tileable: bool) -> f64 {
    let positions = patch_positions(result, stride.max(1), false);
    nearest_patch_energy(&patch_matrix(result, &positions), sample, tileable)
}

/// [`patch_energy`] of the result's patches that cross its wrap edge (all of them, at every
/// pixel along the edges): how well copies of a tileable result join. Compare with the
/// result's `patch_energy`; a plain plane joins at random and scores far above it.
pub fn wrap_seam_energy(result: &Picture, sample: &Picture, tileable: bool) -> f64 {
    let crosses = |x: usize, y: usize| x + PATCH_SIDE > result.width || y + PATCH_SIDE > result.height;
    let positions: Vec<(usize, usize)> =
        patch_positions(result, 1, true).into_iter().filter(|&(x, y)| crosses(x, y)).collect();
    nearest_patch_energy(&patch_matrix(result, &positions), sample, tileable)
}

/// Mean over the rows of `queries` (7×7×3 patches laid out as [`patch_matrix`] lays them
/// out) of the squared difference per value to the nearest patch of `sample`. NaN when
/// there are no queries or the sample is smaller than a patch.
pub(crate) fn nearest_patch_energy(queries: &ndarray::Array2<f32>, sample: &Picture, tileable: bool) -> f64 {
    mean_energy(&nearest_patches(queries, sample, tileable))
}

/// The mean per value of the nearest patches' squared differences (NaN for none).
pub(crate) fn mean_energy(nearest: &[(u32, f64)]) -> f64 {
    if nearest.is_empty() {
        return f64::NAN;
    }
    let values = (PATCH_SIDE * PATCH_SIDE * 3) as f64;
    nearest.iter().map(|n| n.1).sum::<f64>() / (nearest.len() as f64 * values)
}

/// Per row of `queries`, the nearest patch of `sample` (an index into its
/// [`patch_positions`], wrapping when `tileable`) and its summed squared difference. Exact
/// nearest neighbours ([`PatchIndex`]); of equally near patches, the first. Empty when the
/// sample is smaller than a patch.
pub(crate) fn nearest_patches(
    queries: &ndarray::Array2<f32>,
    sample: &Picture,
    tileable: bool,
) -> Vec<(u32, f64)> {
    let sample_positions = patch_positions(sample, 1, tileable);
    if sample_positions.is_empty() {
        return Vec::new();
    }
    let samples = patch_matrix(sample, &sample_positions);
    let index = PatchIndex::new(&samples);
    let found = index.search(queries, f64::INFINITY, |_, _| true);
    // Only a NaN value leaves a query with no nearest patch; its energy is then NaN too.
    found.into_iter().map(|f| f.unwrap_or((0, f64::NAN))).collect()
}

/// Top-left corners of the patches of `picture`: inside it, or everywhere when it wraps.
pub(crate) fn patch_positions(picture: &Picture, stride: usize, wraps: bool) -> Vec<(usize, usize)> {
    let (w, h) = if wraps {
        (picture.width, picture.height)
    } else {
        ((picture.width + 1).saturating_sub(PATCH_SIDE), (picture.height + 1).saturating_sub(PATCH_SIDE))
    };
    if picture.width < PATCH_SIDE || picture.height < PATCH_SIDE {
        return Vec::new();
    }
    (0..h).step_by(stride).flat_map(|y| (0..w).step_by(stride).map(move |x| (x, y))).collect()
}

/// One row per patch: its 7×7×3 values (wrapping around the picture's edges).
pub(crate) fn patch_matrix(picture: &Picture, positions: &[(usize, usize)]) -> ndarray::Array2<f32> {
    let dims = PATCH_SIDE * PATCH_SIDE * 3;
    let mut m = ndarray::Array2::zeros((positions.len(), dims));
    for (mut row, &(x, y)) in m.rows_mut().into_iter().zip(positions) {
        for dy in 0..PATCH_SIDE {
            for dx in 0..PATCH_SIDE {
                let p = picture.at((x + dx) % picture.width, (y + dy) % picture.height);
                let o = (dy * PATCH_SIDE + dx) * 3;
                row[o] = p[0];
                row[o + 1] = p[1];
                row[o + 2] = p[2];
            }
        }
    }
    m
}

/// χ² between 8×8×8-bin colour histograms.
pub fn colour_chi2(result: &Picture, sample: &Picture) -> f64 {
    const BINS: usize = 8;
    let histogram = |p: &Picture| {
        let mut h = vec![0.0f64; BINS * BINS * BINS];
        for c in &p.rgb {
            let bin = c.map(|v| ((v * BINS as f32) as usize).min(BINS - 1));
            h[(bin[0] * BINS + bin[1]) * BINS + bin[2]] += 1.0;
        }
        let n = p.rgb.len().max(1) as f64;
        h.iter_mut().for_each(|v| *v /= n);
        h
    };
    let (p, q) = (histogram(result), histogram(sample));
    0.5 * p.iter().zip(&q).filter(|(a, b)| *a + *b > 0.0).map(|(a, b)| (a - b).powi(2) / (a + b)).sum::<f64>()
}

/// Luma standard deviation of `result` over that of `sample` (1 for a flat sample).
pub fn contrast(result: &Picture, sample: &Picture) -> f64 {
    let std = |p: &Picture| {
        let n = p.rgb.len().max(1) as f64;
        let mean = p.luma().map(f64::from).sum::<f64>() / n;
        (p.luma().map(|l| (l as f64 - mean).powi(2)).sum::<f64>() / n).sqrt()
    };
    let s = std(sample);
    if s == 0.0 {
        1.0
    } else {
        std(result) / s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::quality::picture_quality;
    use rand::seq::SliceRandom;
    use rand::SeedableRng;

    /// A smooth but structured test picture: blobs of colour.
    fn blobs(w: usize, h: usize) -> Picture {
        let rgb = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                [
                    0.5 + 0.4 * (x * 0.31).sin() * (y * 0.17).cos(),
                    0.5 + 0.4 * (x * 0.11 + y * 0.23).sin(),
                    0.5 + 0.3 * ((x - y) * 0.19).cos(),
                ]
            })
            .collect();
        Picture { width: w, height: h, rgb }
    }

    fn crop(p: &Picture, x0: usize, y0: usize, w: usize, h: usize) -> Picture {
        let rgb = (0..w * h).map(|i| p.at(x0 + i % w, y0 + i / w)).collect();
        Picture { width: w, height: h, rgb }
    }

    #[test]
    fn a_crop_of_the_sample_has_zero_patch_energy() {
        let sample = blobs(40, 36);
        let part = crop(&sample, 5, 7, 20, 18);
        assert!(patch_energy(&part, &sample, 1, false) < 1e-9);
        let q = picture_quality(&sample, &sample, false);
        assert!(q.patch_energy < 1e-9 && q.colour_chi2 == 0.0 && (q.contrast - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_pixel_shuffled_sample_is_flagged_by_patch_energy_not_by_colour() {
        let sample = blobs(48, 48);
        let mut shuffled = sample.clone();
        shuffled.rgb.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(3));
        let q = picture_quality(&shuffled, &sample, false);
        assert_eq!(q.colour_chi2, 0.0, "same pixels, same histogram");
        assert!(q.patch_energy > 0.01, "shuffled patches match nothing: {}", q.patch_energy);
    }

    #[test]
    fn a_flat_result_loses_contrast_and_colours() {
        let sample = blobs(32, 32);
        let mean = [0, 1, 2].map(|c| sample.rgb.iter().map(|p| p[c]).sum::<f32>() / 1024.0);
        let flat = Picture { width: 32, height: 32, rgb: vec![mean; 1024] };
        let q = picture_quality(&flat, &sample, false);
        assert!(q.contrast < 1e-6 && q.colour_chi2 > 0.5, "{q:?}");
    }
}
