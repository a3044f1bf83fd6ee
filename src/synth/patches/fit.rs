//! Mask fitting (Soler et al. §4.2): the placement of a cluster's mask in the sample with
//! the least squared difference, over every position and a fixed set of rotations, through
//! FFT correlations.
//!
//! For a mask I (the textured neighbours' colours around the cluster) with support J, the
//! error of placing it at x₀ in the sample T is
//! `E(x₀) = Σ J (I − T(x + x₀))² = Σ I² − 2 (I ⋄ T)(x₀) + (J ⋄ T²)(x₀)`, with `⋄` the
//! correlation, computed for every x₀ at once from Fourier transforms. As in the paper, the
//! transforms of T and T² are computed once per object for each of the rotations (19 by
//! default) of the sample; a fit costs the transforms of I's channels and of J, then one
//! inverse transform per rotation. Values are compared in a colour space of the caller's
//! choice ([`ColourSpace`]), standardised so that the channels' variances sum to 1.
//!
//! A sample that does not tile is zero beyond its edges: positions where the mask would
//! leave it are not considered, so a patch never crosses the sample's border. A tileable
//! sample is rotated with wrap-around, and every position is a placement.

use crate::{Error, Param, Result};
use glam::{Affine2, Mat2, Vec2};
use rayon::prelude::*;
use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// The colour space masks are matched in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ColourSpace {
    /// CIE L*a*b* (D65): differences close to perceived ones.
    #[default]
    Lab,
    /// Hue, saturation, value of the sRGB colour (the paper's choice); hue does not wrap.
    Hsv,
    /// Linear RGB.
    Rgb,
}

impl ColourSpace {
    /// The colour space called `name` (`lab`, `hsv`, `rgb`, `appearance`); an error lists them.
    pub fn parse(name: &str) -> Result<ColourSpace> {
        match name {
            "lab" => Ok(ColourSpace::Lab),
            "hsv" => Ok(ColourSpace::Hsv),
            "rgb" => Ok(ColourSpace::Rgb),
            _ => {
                Err(Error::out_of_range(Param::ColourSpace, format!("'{name}'"), "expected lab, hsv or rgb"))
            }
        }
    }

    /// Linear RGB in this space.
    pub fn convert(self, rgb: [f32; 3]) -> [f32; 3] {
        match self {
            ColourSpace::Rgb => rgb,
            ColourSpace::Hsv => hsv(rgb.map(crate::eval::picture::encode_srgb)),
            ColourSpace::Lab => lab(rgb),
        }
    }
}

fn hsv([r, g, b]: [f32; 3]) -> [f32; 3] {
    let max = r.max(g).max(b);
    let min = r.min(g).min(b);
    let delta = max - min;
    let h = if delta <= 0.0 {
        0.0
    } else if max == r {
        ((g - b) / delta).rem_euclid(6.0) / 6.0
    } else if max == g {
        ((b - r) / delta + 2.0) / 6.0
    } else {
        ((r - g) / delta + 4.0) / 6.0
    };
    let s = if max > 0.0 { delta / max } else { 0.0 };
    [h, s, max]
}

fn lab([r, g, b]: [f32; 3]) -> [f32; 3] {
    let x = 0.412_456_4 * r + 0.357_576_1 * g + 0.180_437_5 * b;
    let y = 0.212_672_9 * r + 0.715_152_2 * g + 0.072_175 * b;
    let z = 0.019_333_9 * r + 0.119_192 * g + 0.950_304_1 * b;
    let f = |t: f32| {
        let t = t.max(0.0);
        if t > 0.008_856 {
            t.cbrt()
        } else {
            7.787 * t + 16.0 / 116.0
        }
    };
    let (fx, fy, fz) = (f(x / 0.950_47), f(y), f(z / 1.088_83));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// The sample in the fitting space: `channels` values per texel, standardised.
#[derive(Clone, Debug)]
pub struct FitImage {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Values per texel.
    pub channels: usize,
    /// Whether fits may wrap around the sample's edges.
    pub tileable: bool,
    /// `[y][x][c]`.
    values: Vec<f32>,
}

impl FitImage {
    /// From per-texel vectors (`[y][x][c]`), centred and scaled so that the variances of the
    /// channels sum to 1 (one scale for all, keeping their relative weights).
    pub fn new(
        width: usize,
        height: usize,
        channels: usize,
        mut values: Vec<f32>,
        tileable: bool,
    ) -> Result<FitImage> {
        if width == 0 || height == 0 || channels == 0 || values.len() != width * height * channels {
            return Err(Error::invalid("a sample to fit against needs at least one texel and one channel"));
        }
        let n = (width * height) as f64;
        let mut total = 0.0;
        for c in 0..channels {
            let mean = values.iter().skip(c).step_by(channels).map(|&v| f64::from(v)).sum::<f64>() / n;
            let var =
                values.iter().skip(c).step_by(channels).map(|&v| (f64::from(v) - mean).powi(2)).sum::<f64>()
                    / n;
            values.iter_mut().skip(c).step_by(channels).for_each(|v| *v -= mean as f32);
            total += var;
        }
        let scale = if total > 0.0 { (1.0 / total.sqrt()) as f32 } else { 1.0 };
        values.iter_mut().for_each(|v| *v *= scale);
        Ok(FitImage { width, height, channels, tileable, values })
    }

    /// From linear RGB texels, in `space`.
    pub fn from_rgb(
        width: usize,
        height: usize,
        rgb: impl Fn(usize, usize) -> [f32; 3],
        space: ColourSpace,
        tileable: bool,
    ) -> Result<FitImage> {
        let mut values = Vec::with_capacity(width * height * 3);
        for y in 0..height {
            for x in 0..width {
                values.extend(space.convert(rgb(x, y)));
            }
        }
        FitImage::new(width, height, 3, values, tileable)
    }

    fn texel(&self, x: i64, y: i64) -> &[f32] {
        let (x, y) = if self.tileable {
            (x.rem_euclid(self.width as i64), y.rem_euclid(self.height as i64))
        } else {
            (x.clamp(0, self.width as i64 - 1), y.clamp(0, self.height as i64 - 1))
        };
        let o = (y as usize * self.width + x as usize) * self.channels;
        &self.values[o..o + self.channels]
    }

    /// Bilinear value at sample coordinate `s` (texel centres at integers), wrapped or
    /// clamped at the edges, into `out`.
    pub fn sample(&self, s: Vec2, out: &mut [f32]) {
        let (x0, y0) = (s.x.floor(), s.y.floor());
        let (fx, fy) = (s.x - x0, s.y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        out.iter_mut().for_each(|v| *v = 0.0);
        for (dx, dy, w) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ] {
            if w > 0.0 {
                for (o, v) in out.iter_mut().zip(self.texel(x0 + dx, y0 + dy)) {
                    *o += w * v;
                }
            }
        }
    }

    /// Whether `s` lies inside the sample (always, for a tileable one).
    pub fn inside(&self, s: Vec2) -> bool {
        self.tileable
            || (s.x >= -1e-3
                && s.y >= -1e-3
                && s.x <= self.width as f32 - 1.0 + 1e-3
                && s.y <= self.height as f32 - 1.0 + 1e-3)
    }
}

/// What is matched: per pixel of a `width × height` frame, the neighbours' values and
/// whether the pixel is in the support J.
#[derive(Clone, Debug)]
pub struct Mask {
    /// Frame width in pixels.
    pub width: usize,
    /// Frame height in pixels.
    pub height: usize,
    /// `[c][y][x]`, zero outside the support.
    pub values: Vec<f32>,
    /// `[y][x]`: 1 in the support, else 0.
    pub support: Vec<f32>,
}

impl Mask {
    /// Pixels in the support.
    pub fn count(&self) -> usize {
        self.support.iter().filter(|&&j| j > 0.0).count()
    }

    /// The mean squared difference per support pixel (summed over channels, as
    /// [`Placement::error`]) between the mask and `image` seen through `map` (mask pixels →
    /// sample coordinates).
    pub fn error_at(&self, image: &FitImage, map: Affine2) -> f32 {
        let (w, h) = (self.width, self.height);
        let mut value = vec![0f32; image.channels];
        let mut total = 0f32;
        for y in 0..h {
            for x in 0..w {
                if self.support[y * w + x] == 0.0 {
                    continue;
                }
                image.sample(map.transform_point2(Vec2::new(x as f32, y as f32)), &mut value);
                for (c, v) in value.iter().enumerate() {
                    let d = self.values[c * w * h + y * w + x] - v;
                    total += d * d;
                }
            }
        }
        total / self.count().max(1) as f32
    }
}

/// The best placement of a mask.
#[derive(Clone, Copy, Debug)]
pub struct Placement {
    /// Index of the rotation.
    pub rotation: usize,
    /// Where the mask's pixel (0, 0) lies in the rotated sample.
    pub position: (usize, usize),
    /// Mean squared difference per support pixel (summed over channels; 2 is the mean for
    /// two random texels of the standardised sample).
    pub error: f32,
}

/// Why a mask could not be placed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unplaced {
    /// It is larger than any placement the sample allows.
    TooLarge,
}

struct Rotation {
    /// Mask pixel p lies at sample coordinate `R⁻¹ (p + x₀ − offset)`.
    inverse: Mat2,
    offset: Vec2,
    /// Transforms of the rotated sample's channels, then of the sum of their squares.
    spectra: Vec<Vec<Complex<f32>>>,
}

/// The sample's transforms at every rotation, and the plans to fit masks with.
pub struct Fitter {
    /// The sample in the fitting space.
    pub image: FitImage,
    nx: usize,
    ny: usize,
    rotations: Vec<Rotation>,
    r2c: Arc<dyn RealToComplex<f32>>,
    c2r: Arc<dyn ComplexToReal<f32>>,
    col_forward: Arc<dyn Fft<f32>>,
    col_inverse: Arc<dyn Fft<f32>>,
}

/// The smallest length ≥ `n` whose prime factors are 2, 3 and 5.
fn fft_len(n: usize) -> usize {
    (n.max(1)..)
        .find(|&m| {
            let mut m = m;
            for p in [2, 3, 5] {
                while m % p == 0 {
                    m /= p;
                }
            }
            m == 1
        })
        .unwrap_or(n)
}

fn fft_error(e: realfft::FftError) -> Error {
    Error::internal(format!("FFT: {e}"))
}

impl Fitter {
    /// Prepares `image` at `rotations` evenly spaced angles.
    pub fn new(image: FitImage, rotations: usize) -> Result<Fitter> {
        let (w, h) = (image.width as f32, image.height as f32);
        let (nx, ny) = if image.tileable {
            (fft_len(2 * image.width), fft_len(2 * image.height))
        } else {
            let diagonal = (w * w + h * h).sqrt().ceil() as usize + 2;
            (fft_len(diagonal), fft_len(diagonal))
        };
        let mut real = RealFftPlanner::<f32>::new();
        let mut complex = FftPlanner::<f32>::new();
        let mut fitter = Fitter {
            nx,
            ny,
            rotations: Vec::new(),
            r2c: real.plan_fft_forward(nx),
            c2r: real.plan_fft_inverse(nx),
            col_forward: complex.plan_fft_forward(ny),
            col_inverse: complex.plan_fft_inverse(ny),
            image,
        };
        let rotations = rotations.max(1);
        let built: Result<Vec<Rotation>> = (0..rotations)
            .into_par_iter()
            .map(|k| fitter.rotation(std::f32::consts::TAU * k as f32 / rotations as f32))
            .collect();
        fitter.rotations = built?;
        Ok(fitter)
    }

    /// Number of rotations tried.
    pub fn rotation_count(&self) -> usize {
        self.rotations.len()
    }

    /// The angle of rotation `k` (radians, counter-clockwise in sample coordinates).
    pub fn angle(&self, k: usize) -> f32 {
        std::f32::consts::TAU * k as f32 / self.rotations.len() as f32
    }

    fn rotation(&self, angle: f32) -> Result<Rotation> {
        let image = &self.image;
        let rotate = Mat2::from_angle(angle);
        let inverse = rotate.inverse();
        let offset = if image.tileable {
            Vec2::ZERO
        } else {
            let (w, h) = (image.width as f32 - 1.0, image.height as f32 - 1.0);
            let corners =
                [Vec2::ZERO, Vec2::new(w, 0.0), Vec2::new(w, h), Vec2::new(0.0, h)].map(|c| rotate * c);
            -corners.iter().fold(Vec2::splat(f32::INFINITY), |m, &c| m.min(c))
        };
        let channels = image.channels;
        let mut frames = vec![vec![0f32; self.nx * self.ny]; channels + 1];
        let mut value = vec![0f32; channels];
        for y in 0..self.ny {
            for x in 0..self.nx {
                let s = inverse * (Vec2::new(x as f32, y as f32) - offset);
                if !image.inside(s) {
                    continue;
                }
                image.sample(s, &mut value);
                let o = y * self.nx + x;
                let mut square = 0.0;
                for c in 0..channels {
                    frames[c][o] = value[c];
                    square += value[c] * value[c];
                }
                frames[channels][o] = square;
            }
        }
        let spectra = frames.iter_mut().map(|f| self.forward(f)).collect::<Result<Vec<_>>>()?;
        Ok(Rotation { inverse, offset, spectra })
    }

    fn cw(&self) -> usize {
        self.nx / 2 + 1
    }

    /// 2-D forward transform of a row-major `nx × ny` frame, stored column by column.
    fn forward(&self, frame: &mut [f32]) -> Result<Vec<Complex<f32>>> {
        let (cw, ny) = (self.cw(), self.ny);
        let mut spectrum = vec![Complex::default(); cw * ny];
        let mut row_out = self.r2c.make_output_vec();
        let mut scratch = self.r2c.make_scratch_vec();
        for (y, row) in frame.chunks_exact_mut(self.nx).enumerate() {
            self.r2c.process_with_scratch(row, &mut row_out, &mut scratch).map_err(fft_error)?;
            for (c, &z) in row_out.iter().enumerate() {
                spectrum[c * ny + y] = z;
            }
        }
        let mut col_scratch = vec![Complex::default(); self.col_forward.get_inplace_scratch_len()];
        self.col_forward.process_with_scratch(&mut spectrum, &mut col_scratch);
        Ok(spectrum)
    }

    /// The inverse of [`Fitter::forward`] (unnormalised), into the first `rows` rows of a
    /// row-major frame.
    fn inverse(&self, mut spectrum: Vec<Complex<f32>>, out: &mut [f32], rows: usize) -> Result<()> {
        let (cw, ny) = (self.cw(), self.ny);
        let mut col_scratch = vec![Complex::default(); self.col_inverse.get_inplace_scratch_len()];
        self.col_inverse.process_with_scratch(&mut spectrum, &mut col_scratch);
        let mut row_in = self.c2r.make_input_vec();
        let mut scratch = self.c2r.make_scratch_vec();
        for (y, row) in out.chunks_exact_mut(self.nx).take(rows).enumerate() {
            for (c, z) in row_in.iter_mut().enumerate() {
                *z = spectrum[c * ny + y];
            }
            row_in[0].im = 0.0;
            if self.nx % 2 == 0 {
                row_in[cw - 1].im = 0.0;
            }
            self.c2r.process_with_scratch(&mut row_in, row, &mut scratch).map_err(fft_error)?;
        }
        Ok(())
    }

    /// The valid positions of a `mw × mh` mask in rotation `k`, per row of positions: an
    /// inclusive range of x (empty rows have lo > hi).
    fn valid_rows(&self, k: usize, mw: usize, mh: usize) -> Vec<(i64, i64)> {
        let image = &self.image;
        if image.tileable {
            let ok = mw + image.width <= self.nx + 1 && mh + image.height <= self.ny + 1;
            return (0..image.height)
                .map(|_| if ok { (0, image.width as i64 - 1) } else { (1, 0) })
                .collect();
        }
        let rotation = &self.rotations[k];
        let (w, h) = (image.width as f32 - 1.0, image.height as f32 - 1.0);
        let corners = [
            Vec2::ZERO,
            Vec2::new(mw as f32 - 1.0, 0.0),
            Vec2::new(mw as f32 - 1.0, mh as f32 - 1.0),
            Vec2::new(0.0, mh as f32 - 1.0),
        ];
        let x_max = self.nx as i64 - mw as i64;
        let y_max = self.ny as i64 - mh as i64;
        (0..=y_max.max(-1))
            .map(|y0| {
                let (mut lo, mut hi) = (0f32, x_max as f32);
                for c in corners {
                    // s = R⁻¹ (c + (x₀, y₀) − offset) = base + x₀ · R⁻¹ e_x, inside [0, w] × [0, h].
                    let base = rotation.inverse * (c + Vec2::new(0.0, y0 as f32) - rotation.offset);
                    let dir = rotation.inverse * Vec2::X;
                    for (b, d, top) in [(base.x, dir.x, w), (base.y, dir.y, h)] {
                        if d.abs() < 1e-7 {
                            if b < -1e-3 || b > top + 1e-3 {
                                hi = -1.0;
                            }
                        } else {
                            let (a, z) = ((-1e-3 - b) / d, (top + 1e-3 - b) / d);
                            lo = lo.max(a.min(z));
                            hi = hi.min(a.max(z));
                        }
                    }
                }
                (lo.ceil() as i64, hi.floor() as i64)
            })
            .collect()
    }

    /// The placement of `mask` with the least error over every rotation and position.
    pub fn fit(&self, mask: &Mask) -> Result<std::result::Result<Placement, Unplaced>> {
        let (mw, mh) = (mask.width, mask.height);
        if mw > self.nx || mh > self.ny {
            return Ok(Err(Unplaced::TooLarge));
        }
        let channels = self.image.channels;
        let embed = |values: &[f32]| {
            let mut frame = vec![0f32; self.nx * self.ny];
            for y in 0..mh {
                frame[y * self.nx..y * self.nx + mw].copy_from_slice(&values[y * mw..(y + 1) * mw]);
            }
            frame
        };
        let mut spectra = Vec::with_capacity(channels + 1);
        for c in 0..channels {
            spectra.push(self.forward(&mut embed(&mask.values[c * mw * mh..(c + 1) * mw * mh]))?);
        }
        spectra.push(self.forward(&mut embed(&mask.support))?);
        let energy: f64 = mask.values.iter().map(|&v| f64::from(v) * f64::from(v)).sum();
        let count = mask.count().max(1) as f64;
        let norm = 1.0 / (self.nx * self.ny) as f32;
        let best: Result<Vec<Option<Placement>>> = (0..self.rotations.len())
            .into_par_iter()
            .map(|k| {
                let rows = self.valid_rows(k, mw, mh);
                if rows.iter().all(|&(lo, hi)| lo > hi) {
                    return Ok(None);
                }
                let rotation = &self.rotations[k];
                let mut product = vec![Complex::default(); spectra[0].len()];
                for (spectrum, rotated) in spectra[..channels].iter().zip(&rotation.spectra) {
                    for ((p, i), t) in product.iter_mut().zip(spectrum).zip(rotated) {
                        *p -= 2.0 * i.conj() * t;
                    }
                }
                for ((p, j), t) in product.iter_mut().zip(&spectra[channels]).zip(&rotation.spectra[channels])
                {
                    *p += j.conj() * t;
                }
                let mut e = vec![0f32; self.nx * self.ny];
                self.inverse(product, &mut e, rows.len().min(self.ny))?;
                let mut found: Option<(f32, usize, usize)> = None;
                for (y, &(lo, hi)) in rows.iter().enumerate() {
                    for x in lo.max(0)..=hi {
                        let v = e[y * self.nx + x as usize];
                        if found.is_none_or(|(b, _, _)| v < b) {
                            found = Some((v, x as usize, y));
                        }
                    }
                }
                Ok(found.map(|(v, x, y)| Placement {
                    rotation: k,
                    position: (x, y),
                    error: ((energy + f64::from(v * norm)).max(0.0) / count) as f32,
                }))
            })
            .collect();
        let best = best?
            .into_iter()
            .flatten()
            .min_by(|a, b| a.error.total_cmp(&b.error).then(a.rotation.cmp(&b.rotation)));
        Ok(best.ok_or(Unplaced::TooLarge))
    }

    /// The map from mask pixels to sample coordinates of a placement.
    pub fn to_sample(&self, p: &Placement) -> Affine2 {
        let r = &self.rotations[p.rotation];
        let shift = Vec2::new(p.position.0 as f32, p.position.1 as f32) - r.offset;
        Affine2::from_mat2_translation(r.inverse, r.inverse * shift)
    }

    /// The positions a `mw × mh` mask may take in rotation `k` (for a first, unmatched
    /// placement): per row, an inclusive range of x.
    pub fn positions(&self, k: usize, mw: usize, mh: usize) -> Vec<(i64, i64)> {
        if mw > self.nx || mh > self.ny {
            return Vec::new();
        }
        self.valid_rows(k, mw, mh)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn noise(w: usize, h: usize, tileable: bool) -> FitImage {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let v: Vec<f32> = (0..w * h * 3).map(|_| rng.random::<f32>()).collect();
        FitImage::new(w, h, 3, v, tileable).expect("image")
    }

    /// A mask copied from the sample at `at`, rotated by `angle`: a ring of width 3.
    fn copied_mask(image: &FitImage, at: Vec2, angle: f32, side: usize) -> Mask {
        let r = Mat2::from_angle(angle).inverse();
        let mut values = vec![0f32; 3 * side * side];
        let mut support = vec![0f32; side * side];
        let mut v = [0f32; 3];
        for y in 0..side {
            for x in 0..side {
                let ring = x < 3 || y < 3 || x + 3 >= side || y + 3 >= side;
                if !ring {
                    continue;
                }
                image.sample(at + r * Vec2::new(x as f32, y as f32), &mut v);
                for c in 0..3 {
                    values[c * side * side + y * side + x] = v[c];
                }
                support[y * side + x] = 1.0;
            }
        }
        Mask { width: side, height: side, values, support }
    }

    #[test]
    fn a_copied_mask_is_found_where_and_at_the_angle_it_was_copied() {
        for tileable in [true, false] {
            let image = noise(48, 40, tileable);
            let fitter = Fitter::new(image.clone(), 8).expect("fitter");
            let angle = fitter.angle(3);
            // The copy starts at a whole position of rotation 3's grid (the middle of the
            // valid ones): the fitter only tries whole positions, and on white noise a copy
            // between them differs by a sub-texel shift that no placement undoes.
            let rows = fitter.positions(3, 12, 12);
            let valid: Vec<usize> = (0..rows.len()).filter(|&y| rows[y].0 <= rows[y].1).collect();
            let y0 = valid[valid.len() / 2];
            let x0 = ((rows[y0].0 + rows[y0].1) / 2) as usize;
            let grid = Placement { rotation: 3, position: (x0, y0), error: 0.0 };
            let at = fitter.to_sample(&grid).transform_point2(Vec2::ZERO);
            let mask = copied_mask(&image, at, angle, 12);
            let p = fitter.fit(&mask).expect("fft").expect("placed");
            assert_eq!((p.rotation, p.position), (3, (x0, y0)), "tileable {tileable}");
            assert!(p.error < 1e-3, "{}", p.error);
            let m = fitter.to_sample(&p);
            let r = Mat2::from_angle(angle).inverse();
            for c in [Vec2::ZERO, Vec2::new(11.0, 0.0), Vec2::new(0.0, 11.0), Vec2::splat(11.0)] {
                // The placement maps each mask pixel back to where it was copied from,
                // inside the sample.
                let s = m.transform_point2(c);
                assert!(s.distance(at + r * c) < 1e-3, "pixel {c} at {s}, copied from {}", at + r * c);
                assert!(fitter.image.inside(s));
            }
            // A mask of noise fits about as badly as two random texels differ.
            let mut rng = ChaCha8Rng::seed_from_u64(9);
            let mut random = mask.clone();
            random
                .values
                .iter_mut()
                .zip(mask.support.iter().cycle())
                .for_each(|(v, &j)| *v = j * (rng.random::<f32>() - 0.5) * 3.4);
            let q = fitter.fit(&random).expect("fft").expect("placed");
            assert!(q.error > 0.8, "{}", q.error);
        }
    }

    /// Noise averaged over 5×5 texels (wrapped or clamped at the edges): a texture whose
    /// values change little within a texel.
    fn smooth(w: usize, h: usize, tileable: bool) -> FitImage {
        let noise = noise(w, h, tileable);
        let mut values = Vec::with_capacity(w * h * 3);
        let mut v = [0f32; 3];
        for y in 0..h {
            for x in 0..w {
                let mut sum = [0f32; 3];
                for dy in -2..=2 {
                    for dx in -2..=2 {
                        noise.sample(Vec2::new((x as i64 + dx) as f32, (y as i64 + dy) as f32), &mut v);
                        (0..3).for_each(|c| sum[c] += v[c] / 25.0);
                    }
                }
                values.extend(sum);
            }
        }
        FitImage::new(w, h, 3, values, tileable).expect("image")
    }

    #[test]
    fn a_copy_between_grid_positions_is_found_at_the_nearest_one() {
        for tileable in [true, false] {
            let image = smooth(48, 40, tileable);
            let fitter = Fitter::new(image.clone(), 8).expect("fitter");
            let at = Vec2::new(30.3, 20.6);
            let mask = copied_mask(&image, at, fitter.angle(3), 12);
            let p = fitter.fit(&mask).expect("fft").expect("placed");
            assert_eq!(p.rotation, 3, "tileable {tileable}");
            assert!(p.error < 0.1, "{}", p.error);
            let s = fitter.to_sample(&p).transform_point2(Vec2::ZERO);
            let wrapped = if tileable { Vec2::new(s.x.rem_euclid(48.0), s.y.rem_euclid(40.0)) } else { s };
            // Within half a grid diagonal of the copy.
            assert!(wrapped.distance(at) < 0.75, "found at {wrapped}, copied from {at}");
        }
    }

    #[test]
    fn too_large_masks_are_refused_for_a_sample_that_does_not_tile() {
        let fitter = Fitter::new(noise(16, 16, false), 4).expect("fitter");
        let mask = Mask { width: 30, height: 30, values: vec![0.0; 3 * 900], support: vec![1.0; 900] };
        assert_eq!(fitter.fit(&mask).expect("fft").unwrap_err(), Unplaced::TooLarge);
    }

    #[test]
    fn colour_spaces() {
        let [l, a, b] = ColourSpace::Lab.convert([1.0, 1.0, 1.0]);
        assert!((l - 100.0).abs() < 0.1 && a.abs() < 0.1 && b.abs() < 0.1, "{l} {a} {b}");
        let [h, s, v] = ColourSpace::Hsv.convert([0.0, 1.0, 0.0]);
        assert!(((h - 1.0 / 3.0).abs(), s, v) == (0.0, 1.0, 1.0) || (h - 1.0 / 3.0).abs() < 1e-6);
    }
}
