//! Colour spaces of measured BTF files, undone to the linear RGB btfsynth works in.
//!
//! - The colour models of Bonn's DFMF files (btflib's `undecorrelate`): the factorized
//!   channels are RGB, YUV, Lab, a PCA basis, YCoCg, "spectral" ratios, or log-luminance
//!   variants of YUV; [`ColourModel::to_rgb`] turns one decoded texel back into RGB and
//!   [`ColourModel::from_rgb`] is its inverse for the models btfsynth writes.
//! - UTIA's EXRs hold CIE XYZ (D65 white); [`xyz_to_linear_srgb`] converts them.

use crate::{Error, Result};

/// The ε that btflib adds before taking logarithms of luminance ("dynamic range reduction").
pub const DRR_EPS: f32 = 1e-5;

/// btflib's YUV → RGB matrix (rows R, G, B; columns Y, U, V).
const YUV_TO_RGB: [[f64; 3]; 3] = [[1.0, 0.0, 1.13983], [1.0, -0.39465, -0.5806], [1.0, 2.03211, 0.0]];
/// btflib's YCoCg → RGB matrix.
const YCOCG_TO_RGB: [[f64; 3]; 3] = [[1.0, 1.0, -1.0], [1.0, 0.0, 1.0], [1.0, -1.0, -1.0]];

/// How a DFMF file's three channels encode RGB (the file's `color_model` field).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ColourModel {
    /// 0: plain RGB.
    Rgb,
    /// 1: YUV.
    Yuv,
    /// 2: CIE L*a*b* (D50, as MATLAB's `makecform('lab2srgb')`).
    Lab,
    /// 3: a PCA basis: rgb = v · transform + mean.
    Pca {
        /// Linear RGB added after the transform.
        mean: [f32; 3],
        /// Row c holds the RGB that channel c contributes per unit.
        transform: [[f32; 3]; 3],
    },
    /// 4: YCoCg.
    YCoCg,
    /// 5: "spectral": a sum and ratios.
    Spectral,
    /// 6: "spectral linear": a scaled sum and offsets.
    SpectralLinear,
    /// 9: log Y, U, V.
    LogYUv,
    /// 10: log Y, signed log U and V.
    LogYLogUv,
    /// 11: log Y, U/Y, V/Y (the UBO2014 files).
    LogYUvOverY,
    /// 12: log RGB.
    LogRgb,
}

impl ColourModel {
    /// The model numbered `id` in a DFMF header (`mean` and `transform` are only used by
    /// the PCA model); an unknown number is "not supported yet".
    pub fn from_id(id: i32, mean: [f32; 3], transform: [[f32; 3]; 3]) -> Result<Self, String> {
        Ok(match id {
            0 => ColourModel::Rgb,
            1 => ColourModel::Yuv,
            2 => ColourModel::Lab,
            3 => {
                let finite = mean.iter().chain(transform.iter().flatten()).all(|v| v.is_finite());
                if !finite {
                    return Err("the PCA colour model's mean or transform is not finite".into());
                }
                ColourModel::Pca { mean, transform }
            }
            4 => ColourModel::YCoCg,
            5 => ColourModel::Spectral,
            6 => ColourModel::SpectralLinear,
            9 => ColourModel::LogYUv,
            10 => ColourModel::LogYLogUv,
            11 => ColourModel::LogYUvOverY,
            12 => ColourModel::LogRgb,
            other => {
                return Err(format!("not supported yet: colour model {other} (btflib defines 0-6 and 9-12)"))
            }
        })
    }

    /// The number written in a DFMF header.
    pub fn id(&self) -> i32 {
        match self {
            ColourModel::Rgb => 0,
            ColourModel::Yuv => 1,
            ColourModel::Lab => 2,
            ColourModel::Pca { .. } => 3,
            ColourModel::YCoCg => 4,
            ColourModel::Spectral => 5,
            ColourModel::SpectralLinear => 6,
            ColourModel::LogYUv => 9,
            ColourModel::LogYLogUv => 10,
            ColourModel::LogYUvOverY => 11,
            ColourModel::LogRgb => 12,
        }
    }

    /// A short human name.
    pub fn name(&self) -> &'static str {
        match self {
            ColourModel::Rgb => "RGB",
            ColourModel::Yuv => "YUV",
            ColourModel::Lab => "CIE Lab",
            ColourModel::Pca { .. } => "PCA",
            ColourModel::YCoCg => "YCoCg",
            ColourModel::Spectral => "spectral",
            ColourModel::SpectralLinear => "spectral linear",
            ColourModel::LogYUv => "log-Y, U, V",
            ColourModel::LogYLogUv => "log-Y, log-U, log-V",
            ColourModel::LogYUvOverY => "log-Y, U/Y, V/Y",
            ColourModel::LogRgb => "log-RGB",
        }
    }

    /// One decoded texel of the three channels back to RGB (btflib's `undecorrelate`).
    pub fn to_rgb(&self, v: [f32; 3]) -> [f32; 3] {
        let eps = DRR_EPS as f64;
        let [a, b, c] = v.map(|x| x as f64);
        let rgb = match self {
            ColourModel::Rgb => [a, b, c],
            ColourModel::Yuv => mul(&YUV_TO_RGB, [a, b, c]),
            ColourModel::Lab => lab_d50_to_rgb([a, b, c]),
            ColourModel::Pca { mean, transform } => {
                let t = |i: usize, j: usize| transform[i][j] as f64;
                [0, 1, 2].map(|j| a * t(0, j) + b * t(1, j) + c * t(2, j) + mean[j] as f64)
            }
            ColourModel::YCoCg => mul(&YCOCG_TO_RGB, [a, b, c]),
            ColourModel::Spectral => {
                let sum = a;
                [(1.0 - b - c) * sum, b * sum, c * sum]
            }
            ColourModel::SpectralLinear => {
                let (div, sum) = (1.0 / 3.0, a * 3.0);
                [sum - b * div - c * div, sum + b * sum, sum + c * sum]
            }
            ColourModel::LogYUv => mul(&YUV_TO_RGB, [a.exp() - eps, b, c]),
            ColourModel::LogYLogUv => {
                let signed_log = |x: f64| x.signum() * (x.abs() + eps.ln()).exp();
                mul(&YUV_TO_RGB, [a.exp() - eps, signed_log(b), signed_log(c)])
            }
            ColourModel::LogYUvOverY => {
                let y = a.exp() - eps;
                mul(&YUV_TO_RGB, [y, b * (y + eps), c * (y + eps)])
            }
            ColourModel::LogRgb => [a.exp() - eps, b.exp() - eps, c.exp() - eps],
        };
        rgb.map(|x| x as f32)
    }

    /// The model as an affine map, `rgb = m · v + t` (rows of `m` are R, G, B), for the
    /// models that are one: RGB, YUV, the PCA basis and YCoCg. `None` for the others, whose
    /// decoding multiplies channels (the spectral models), takes exponentials (the log
    /// models) or a cube and a gamma curve (Lab): there a sum of decoded images is not the
    /// decoding of the summed factors.
    pub fn affine(&self) -> Option<([[f32; 3]; 3], [f32; 3])> {
        let f = |m: &[[f64; 3]; 3]| m.map(|row| row.map(|v| v as f32));
        match self {
            ColourModel::Rgb => Some(([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0; 3])),
            ColourModel::Yuv => Some((f(&YUV_TO_RGB), [0.0; 3])),
            ColourModel::YCoCg => Some((f(&YCOCG_TO_RGB), [0.0; 3])),
            ColourModel::Pca { mean, transform } => {
                Some(([0, 1, 2].map(|j| [0, 1, 2].map(|i| transform[i][j])), *mean))
            }
            _ => None,
        }
    }

    /// RGB to the model's three channels: the inverse of [`ColourModel::to_rgb`], for the
    /// models btfsynth writes (RGB and log-Y, U/Y, V/Y). Luminance below zero is clamped
    /// to zero first, since its logarithm is taken.
    pub fn from_rgb(&self, rgb: [f32; 3]) -> Result<[f32; 3]> {
        let [r, g, b] = rgb.map(|x| x as f64);
        match self {
            ColourModel::Rgb => Ok(rgb),
            ColourModel::LogYUvOverY => {
                let [y, u, v] = mul(&rgb_to_yuv(), [r, g, b]);
                let y = y.max(0.0) + DRR_EPS as f64;
                Ok([y.ln() as f32, (u / y) as f32, (v / y) as f32])
            }
            other => Err(Error::invalid(format!(
                "writing colour model {} ({}) is not supported: use 0 (RGB) or 11 (log-Y, U/Y, V/Y)",
                other.id(),
                other.name()
            ))),
        }
    }
}

fn mul(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    m.map(|row| row[0] * v[0] + row[1] * v[1] + row[2] * v[2])
}

/// The exact inverse of btflib's YUV → RGB matrix, so that encoding then decoding is the
/// identity up to rounding.
fn rgb_to_yuv() -> [[f64; 3]; 3] {
    invert(&YUV_TO_RGB)
}

fn invert(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let c = |r: usize, k: usize| {
        let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
        let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
        m[r1][k1] * m[r2][k2] - m[r1][k2] * m[r2][k1]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    // The adjugate is the transposed cofactor matrix.
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| c(j, i) / det))
}

/// The ICC sRGB profile's linear RGB → XYZ matrix, Bradford-adapted to D50: what MATLAB's
/// `makecform('srgb2lab')` uses.
const SRGB_TO_XYZ_D50: [[f64; 3]; 3] = [
    [0.436_074_7, 0.385_064_9, 0.143_080_4],
    [0.222_504_5, 0.716_878_6, 0.060_616_9],
    [0.013_932_2, 0.097_104_5, 0.714_173_3],
];
const D50_WHITE: [f64; 3] = [0.964_2, 1.0, 0.824_9];

/// Lab (D50) back to the values the file's writer started from. MATLAB's conversion
/// treats its input as sRGB-encoded, so the encoding is re-applied here to return exactly
/// those (linear, measured) values.
fn lab_d50_to_rgb([l, a, b]: [f64; 3]) -> [f64; 3] {
    let fy = (l + 16.0) / 116.0;
    let f = [fy + a / 500.0, fy, fy - b / 200.0];
    let inv =
        |t: f64| if t > 6.0 / 29.0 { t * t * t } else { 3.0 * (6.0f64 / 29.0).powi(2) * (t - 4.0 / 29.0) };
    let xyz = [0, 1, 2].map(|i| D50_WHITE[i] * inv(f[i]));
    let linear = mul(&invert(&SRGB_TO_XYZ_D50), xyz);
    linear.map(|v| {
        let s = if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
        s.clamp(0.0, 1.0)
    })
}

/// Chromaticities (x, y) of the sRGB primaries and of the D65 white point (IEC 61966-2-1).
const SRGB_PRIMARIES: [[f64; 2]; 3] = [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06]];
const D65_XY: [f64; 2] = [0.3127, 0.3290];

/// CIE XYZ of the D65 white with luminance Y = 1.
pub fn d65_white_xyz() -> [f32; 3] {
    let [x, y] = D65_XY;
    [(x / y) as f32, 1.0, ((1.0 - x - y) / y) as f32]
}

/// The CIE XYZ (D65) → linear sRGB matrix, derived from the primaries and the white point
/// so that the D65 white maps to (1, 1, 1) exactly (up to rounding).
fn xyz_to_srgb_matrix() -> [[f64; 3]; 3] {
    let xyz_of = |[x, y]: [f64; 2]| [x / y, 1.0, (1.0 - x - y) / y];
    let columns = SRGB_PRIMARIES.map(xyz_of);
    let primaries = [0, 1, 2].map(|r| [0, 1, 2].map(|c| columns[c][r]));
    let white = d65_white_xyz().map(|v| v as f64);
    let scale = mul(&invert(&primaries), white);
    let rgb_to_xyz = [0, 1, 2].map(|r| [0, 1, 2].map(|c| primaries[r][c] * scale[c]));
    invert(&rgb_to_xyz)
}

/// One CIE XYZ (D65) value in linear sRGB.
pub fn xyz_to_linear_srgb(xyz: [f32; 3]) -> [f32; 3] {
    let m = xyz_to_srgb_matrix();
    mul(&m, xyz.map(|v| v as f64)).map(|v| v as f32)
}

/// Converts interleaved XYZ triples to linear sRGB in place.
pub fn xyz_to_linear_srgb_in_place(pixels: &mut [half::f16]) {
    let m = xyz_to_srgb_matrix();
    for px in pixels.chunks_exact_mut(3) {
        let rgb = mul(&m, [px[0].to_f64(), px[1].to_f64(), px[2].to_f64()]);
        for (dst, v) in px.iter_mut().zip(rgb) {
            *dst = half::f16::from_f64(v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn d65_white_is_srgb_white() {
        let rgb = xyz_to_linear_srgb(d65_white_xyz());
        for c in rgb {
            assert!((c - 1.0).abs() < 1e-6, "{rgb:?}");
        }
        // The matrix agrees with the published IEC 61966-2-1 coefficients to 4 decimals.
        let m = xyz_to_srgb_matrix();
        let published = [[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]];
        for r in 0..3 {
            for c in 0..3 {
                assert!((m[r][c] - published[r][c]).abs() < 6e-4, "{m:?}");
            }
        }
    }

    #[test]
    fn models_btfsynth_writes_round_trip() {
        for model in [ColourModel::Rgb, ColourModel::LogYUvOverY] {
            for rgb in [[0.2, 0.5, 0.1], [1.5, 0.0, 0.3], [0.0, 0.0, 0.0], [0.01, 0.02, 0.03]] {
                let back = model.to_rgb(model.from_rgb(rgb).unwrap());
                for c in 0..3 {
                    assert!((back[c] - rgb[c]).abs() < 2e-6, "{model:?} {rgb:?} -> {back:?}");
                }
            }
        }
        assert!(ColourModel::Yuv.from_rgb([0.1; 3]).is_err());
    }

    #[test]
    fn model_11_matches_btflib_on_a_hand_computed_texel() {
        // log Y = ln(0.5 + ε), U/Y = 0.1, V/Y = -0.2: Y = 0.5, U = 0.1 (Y + ε), V = -0.2 (Y + ε).
        let y = 0.5f64;
        let (u, v) = (0.1 * (y + 1e-5), -0.2 * (y + 1e-5));
        let want = [y + 1.13983 * v, y - 0.39465 * u - 0.5806 * v, y + 2.03211 * u];
        let got = ColourModel::LogYUvOverY.to_rgb([((y + 1e-5).ln()) as f32, 0.1, -0.2]);
        for c in 0..3 {
            assert!((got[c] as f64 - want[c]).abs() < 1e-6, "{got:?} {want:?}");
        }
    }

    #[test]
    fn affine_models_decode_as_their_matrix() {
        let pca = ColourModel::Pca {
            mean: [0.1, 0.2, 0.3],
            transform: [[1.0, 2.0, 0.0], [0.0, 1.0, 0.5], [0.3, 0.0, 1.0]],
        };
        for model in [ColourModel::Rgb, ColourModel::Yuv, ColourModel::YCoCg, pca] {
            let (m, t) = model.affine().unwrap();
            let v = [0.3f32, -0.2, 0.7];
            let want = model.to_rgb(v);
            for r in 0..3 {
                let got = m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2] + t[r];
                assert!((got - want[r]).abs() < 1e-5, "{model:?}: {got} vs {}", want[r]);
            }
        }
        for model in [
            ColourModel::Lab,
            ColourModel::Spectral,
            ColourModel::SpectralLinear,
            ColourModel::LogYUvOverY,
            ColourModel::LogRgb,
        ] {
            assert!(model.affine().is_none(), "{model:?}");
        }
    }

    #[test]
    fn every_btflib_model_id_is_known_and_others_are_not() {
        for id in [0, 1, 2, 3, 4, 5, 6, 9, 10, 11, 12] {
            let m = ColourModel::from_id(id, [0.0; 3], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
                .unwrap();
            assert_eq!(m.id(), id);
            assert!(m.to_rgb([0.1, 0.2, 0.3]).iter().all(|v| v.is_finite()));
        }
        for id in [-1, 7, 8, 13] {
            let e = ColourModel::from_id(id, [0.0; 3], [[0.0; 3]; 3]).unwrap_err();
            assert!(e.contains("not supported yet"), "{e}");
        }
        // PCA: identity transform plus mean is a shift.
        let pca = ColourModel::Pca {
            mean: [1.0, 2.0, 3.0],
            transform: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        };
        assert_eq!(pca.to_rgb([0.5, 0.5, 0.5]), [1.5, 2.5, 3.5]);
        // Lab: white (L = 100) is white.
        let white = ColourModel::Lab.to_rgb([100.0, 0.0, 0.0]);
        assert!(white.iter().all(|v| (v - 1.0).abs() < 2e-3), "{white:?}");
    }
}
