//! Figures of a texture as it lies on a surface, against its sample at the same scale: what
//! a user sees on a model, rather than what the coordinate or texton maps say.
//!
//! The texture is an atlas (an exported model's base colour, or any surface's colours baked
//! into a generated atlas) whose texels cover the surface at `scale` atlas texels per sample
//! texel. The sample is resampled to that scale (bilinear; a box filter first when the atlas
//! is coarser), so that both are compared texel for texel:
//!
//! - **smeared**: the share of the atlas' 12×12-texel windows (wholly on the surface, every
//!   6 texels) whose luma standard deviation is below the sample's flattest 5% of windows.
//!   The sample itself scores 0.05; a blurred or stretched stretch scores above it.
//! - **detail**: the mean squared Laplacian of luma (high-frequency energy) over that of the
//!   resampled sample, both measured on 2×2 means (so sub-texel resampling, which any
//!   texture lookup does, does not count as lost detail; a 2× upscale does).
//! - **contrast**: luma standard deviation over the resampled sample's.
//! - **colour**: χ² of the 8×8×8-bin colour histograms, and the distance between the mean
//!   colours (sRGB, 0–1).
//! - **patch energy**: on the same 2×2 means, the mean squared difference (sRGB, per value)
//!   of 7×7 patches of the texture (wholly on the surface, at most [`MAX_PATCHES`] of them,
//!   evenly spaced) to their nearest patch of the sample at the same scale, as
//!   [`super::PictureQuality::patch_energy`] measures a plane. What the sample holds scores
//!   0; a blur, a smear, jagged coordinates and seams all raise it, so it tells a clean copy
//!   from one whose detail figure is raised by noise.
//!
//! Gutter texels (not on the surface) are never counted.

use super::picture::{colour_chi2, Picture};
use serde::Serialize;

/// Side of the windows the smeared share looks at, in atlas texels.
pub const WINDOW: usize = 12;
/// The share of the sample's windows that are "flat": the threshold of the smeared share.
pub const FLATTEST: f64 = 0.05;
/// At most this many texture patches are matched for the patch energy (each against every
/// patch of the resampled sample).
pub const MAX_PATCHES: usize = 4096;

/// The figures of one texture on a surface (see the module documentation).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct TextureFigures {
    /// Atlas texels per sample texel on the surface, at which it was measured.
    pub scale: f64,
    /// Windows wholly on the surface that the smeared share counted.
    pub windows: usize,
    /// Share of those windows flatter than the sample's flattest 5% (the sample: 0.05).
    pub smeared: f64,
    /// High-frequency energy over the sample's at the same scale (1: as detailed).
    pub detail: f64,
    /// Luma standard deviation over the sample's (1: as contrasted).
    pub contrast: f64,
    /// Colour-histogram χ² against the sample (0 identical .. 1 disjoint).
    pub colour_chi2: f64,
    /// Distance between the mean colours (sRGB-encoded, 0–1 per channel).
    pub colour_shift: f64,
    /// Mean nearest-patch squared difference against the sample at the same scale, on 2×2
    /// means (0: every patch is in the sample).
    pub patch_energy: f64,
}

/// The figures of `texture` (an atlas whose texels with `covered` true lie on the surface, at
/// `scale` atlas texels per sample texel) against `sample` (which repeats when `tileable`).
pub fn texture_figures(
    texture: &Picture,
    covered: &[bool],
    sample: &Picture,
    scale: f64,
    tileable: bool,
) -> TextureFigures {
    let reference = resample(sample, scale, tileable);
    let all = vec![true; reference.width * reference.height];
    let sample_flatness = window_flatness(&reference, &all, 2, tileable);
    let threshold = quantile(&sample_flatness, FLATTEST);
    let flatness = window_flatness(texture, covered, WINDOW / 2, false);
    let smeared = if flatness.is_empty() {
        f64::NAN
    } else {
        flatness.iter().filter(|&&f| f < threshold).count() as f64 / flatness.len() as f64
    };
    let on_surface = only(texture, covered);
    let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { f64::NAN };
    let (half, half_covered) = halve(texture, covered);
    let (half_reference, half_all) = halve(&reference, &all);
    TextureFigures {
        scale,
        windows: flatness.len(),
        smeared,
        detail: ratio(
            laplacian_energy(&half, &half_covered, false),
            laplacian_energy(&half_reference, &half_all, tileable),
        ),
        contrast: ratio(luma_std(&on_surface.rgb), luma_std(&reference.rgb)),
        colour_chi2: colour_chi2(&on_surface, &reference),
        colour_shift: {
            let (a, b) = (mean(&on_surface.rgb), mean(&reference.rgb));
            (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>().sqrt()
        },
        patch_energy: surface_patch_energy(&half, &half_covered, &half_reference, tileable),
    }
}

/// The mean nearest-patch energy of at most [`MAX_PATCHES`] patches of `texture` wholly
/// on the surface (`covered`), evenly spaced, against every patch of `reference`.
fn surface_patch_energy(texture: &Picture, covered: &[bool], reference: &Picture, tileable: bool) -> f64 {
    use super::picture::{nearest_patch_energy, patch_matrix, patch_positions, PATCH_SIDE};
    let w = texture.width;
    let inside = |&(x, y): &(usize, usize)| {
        (0..PATCH_SIDE).all(|dy| (0..PATCH_SIDE).all(|dx| covered[(y + dy) * w + x + dx]))
    };
    let all: Vec<(usize, usize)> = patch_positions(texture, 1, false).into_iter().filter(inside).collect();
    let step = all.len().div_ceil(MAX_PATCHES).max(1);
    let chosen: Vec<(usize, usize)> = all.into_iter().step_by(step).collect();
    if chosen.is_empty() {
        return f64::NAN;
    }
    nearest_patch_energy(&patch_matrix(texture, &chosen), reference, tileable)
}

/// `sample` at `scale` times its size (bilinear, texel centres aligned; box-filtered first
/// when shrinking), wrapping when `tileable`, else clamped at its edges.
pub fn resample(sample: &Picture, scale: f64, tileable: bool) -> Picture {
    let scale = if scale.is_finite() && scale > 0.0 { scale } else { 1.0 };
    let source =
        if scale < 1.0 { box_blur(sample, (1.0 / scale).round() as usize, tileable) } else { sample.clone() };
    let (w, h) = (
        ((sample.width as f64 * scale).round() as usize).max(1),
        ((sample.height as f64 * scale).round() as usize).max(1),
    );
    let at = |x: i64, y: i64| {
        let (sw, sh) = (source.width as i64, source.height as i64);
        let (x, y) = if tileable {
            (x.rem_euclid(sw), y.rem_euclid(sh))
        } else {
            (x.clamp(0, sw - 1), y.clamp(0, sh - 1))
        };
        source.rgb[(y * sw + x) as usize]
    };
    let rgb = (0..w * h)
        .map(|i| {
            let u = ((i % w) as f64 + 0.5) / scale - 0.5;
            let v = ((i / w) as f64 + 0.5) / scale - 0.5;
            let (x0, y0) = (u.floor(), v.floor());
            let (fx, fy) = ((u - x0) as f32, (v - y0) as f32);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let [a, b, c, d] = [at(x0, y0), at(x0 + 1, y0), at(x0, y0 + 1), at(x0 + 1, y0 + 1)];
            std::array::from_fn(|k| {
                (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
            })
        })
        .collect();
    Picture { width: w, height: h, rgb }
}

/// The mean of each `side × side` block around every pixel (wrapping or clamped).
fn box_blur(p: &Picture, side: usize, tileable: bool) -> Picture {
    let side = side.max(1) as i64;
    let (w, h) = (p.width as i64, p.height as i64);
    let at = |x: i64, y: i64| {
        let (x, y) = if tileable {
            (x.rem_euclid(w), y.rem_euclid(h))
        } else {
            (x.clamp(0, w - 1), y.clamp(0, h - 1))
        };
        p.rgb[(y * w + x) as usize]
    };
    let rgb = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w - side / 2, i / w - side / 2);
            let mut s = [0.0f32; 3];
            for dy in 0..side {
                for dx in 0..side {
                    let c = at(x + dx, y + dy);
                    (0..3).for_each(|k| s[k] += c[k]);
                }
            }
            s.map(|v| v / (side * side) as f32)
        })
        .collect();
    Picture { width: p.width, height: p.height, rgb }
}

fn luma(c: [f32; 3]) -> f64 {
    f64::from(0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2])
}

/// Per [`WINDOW`]-side window (every `stride` texels) wholly covered, its luma standard
/// deviation; windows wrap around a tileable picture.
fn window_flatness(p: &Picture, covered: &[bool], stride: usize, wraps: bool) -> Vec<f64> {
    let (w, h) = (p.width, p.height);
    if w < WINDOW || h < WINDOW {
        return Vec::new();
    }
    let (xs, ys) = if wraps { (w, h) } else { (w - WINDOW + 1, h - WINDOW + 1) };
    let mut out = Vec::new();
    for y in (0..ys).step_by(stride) {
        'window: for x in (0..xs).step_by(stride) {
            let (mut s, mut s2) = (0.0, 0.0);
            for dy in 0..WINDOW {
                for dx in 0..WINDOW {
                    let i = ((y + dy) % h) * w + (x + dx) % w;
                    if !covered[i] {
                        continue 'window;
                    }
                    let l = luma(p.rgb[i]);
                    s += l;
                    s2 += l * l;
                }
            }
            let n = (WINDOW * WINDOW) as f64;
            out.push((s2 / n - (s / n).powi(2)).max(0.0).sqrt());
        }
    }
    out
}

/// The `q` quantile of `values` (NaN if empty).
fn quantile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[((q * sorted.len() as f64) as usize).min(sorted.len() - 1)]
}

/// Half the size: each pixel the mean of a 2×2 block, covered only if all four are.
fn halve(p: &Picture, covered: &[bool]) -> (Picture, Vec<bool>) {
    let (w, h) = (p.width / 2, p.height / 2);
    let block = |i: usize| {
        let (x, y) = (2 * (i % w), 2 * (i / w));
        [(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)].map(|(x, y)| y * p.width + x)
    };
    let rgb = (0..w * h)
        .map(|i| {
            let b = block(i);
            std::array::from_fn(|k| b.iter().map(|&j| p.rgb[j][k]).sum::<f32>() / 4.0)
        })
        .collect();
    let cov = (0..w * h).map(|i| block(i).iter().all(|&j| covered[j])).collect();
    (Picture { width: w, height: h, rgb }, cov)
}

/// Mean squared 4-neighbour Laplacian of luma at covered pixels whose neighbours are covered.
fn laplacian_energy(p: &Picture, covered: &[bool], wraps: bool) -> f64 {
    let (w, h) = (p.width as i64, p.height as i64);
    let index = |x: i64, y: i64| {
        if wraps {
            Some((y.rem_euclid(h) * w + x.rem_euclid(w)) as usize)
        } else {
            (x >= 0 && y >= 0 && x < w && y < h).then_some((y * w + x) as usize)
        }
    };
    let (mut sum, mut n) = (0.0, 0usize);
    for y in 0..h {
        'pixel: for x in 0..w {
            let mut l = 0.0;
            for (dx, dy, weight) in [(0, 0, -4.0), (1, 0, 1.0), (-1, 0, 1.0), (0, 1, 1.0), (0, -1, 1.0)] {
                match index(x + dx, y + dy) {
                    Some(i) if covered[i] => l += weight * luma(p.rgb[i]),
                    _ => continue 'pixel,
                }
            }
            sum += l * l;
            n += 1;
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        sum / n as f64
    }
}

/// The covered pixels of `p` as one row.
fn only(p: &Picture, covered: &[bool]) -> Picture {
    let rgb: Vec<[f32; 3]> = p.rgb.iter().zip(covered).filter(|(_, &c)| c).map(|(c, _)| *c).collect();
    Picture { width: rgb.len(), height: 1, rgb }
}

fn luma_std(rgb: &[[f32; 3]]) -> f64 {
    let n = rgb.len().max(1) as f64;
    let m = rgb.iter().map(|&c| luma(c)).sum::<f64>() / n;
    (rgb.iter().map(|&c| (luma(c) - m).powi(2)).sum::<f64>() / n).sqrt()
}

fn mean(rgb: &[[f32; 3]]) -> [f64; 3] {
    let n = rgb.len().max(1) as f64;
    std::array::from_fn(|k| rgb.iter().map(|c| f64::from(c[k])).sum::<f64>() / n)
}

/// The figures of an exported model's base colour texture on its surface, against `sample`
/// (repeating when `tileable`), where one sample texel is `texel` model units.
///
/// A texture laid out as an atlas (clamped, UVs inside [0, 1], no texel claimed twice) is
/// measured as it is. A texture whose UVs overlap or repeat (the sample itself mapped by
/// pattern mapping) is first baked into a generated atlas at about one texel per sample
/// texel (each texel its surface point's bilinear lookup), so that both are judged on what
/// covers the surface.
pub fn model_figures(
    model: &crate::export::read::Model,
    sample: &Picture,
    tileable: bool,
    texel: f32,
) -> crate::Result<TextureFigures> {
    use crate::export::raster::{rasterize, Coverage};
    let texture = &model.base_colour;
    let size = (texture.width, texture.height);
    let inside = model.uv.iter().all(|uv| (0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y));
    if !model.repeat && inside {
        let coverage = rasterize(&model.uv, &model.triangles, size);
        let covered: Vec<bool> = coverage.triangle.iter().map(|&t| t != Coverage::NONE).collect();
        let claimed = uv_area(&model.uv, &model.triangles, size);
        // Conservative rasterization covers a little more than the charts' area; an atlas
        // whose charts overlap claims far more area than it covers.
        if claimed <= 1.1 * coverage.baked() as f64 {
            let scale = density(&model.positions, &model.uv, &model.triangles, size) * f64::from(texel);
            return Ok(texture_figures(texture, &covered, sample, scale, tileable));
        }
    }
    let (atlas, covered, scale) = rebake(model, texel)?;
    Ok(texture_figures(&atlas, &covered, sample, scale, tileable))
}

/// `model`'s texture baked into a generated atlas at about one texel per sample texel
/// (`texel` model units): the atlas, which texels lie on the surface, and atlas texels per
/// sample texel.
fn rebake(model: &crate::export::read::Model, texel: f32) -> crate::Result<(Picture, Vec<bool>, f64)> {
    use crate::export::layout::{AtlasMesh, AtlasOptions};
    use crate::export::raster::{rasterize, Coverage};
    let mesh = crate::mesh::textured::TexturedMesh {
        positions: model.positions.clone(),
        triangles: model.triangles.clone(),
        uvs: None,
    };
    let area: f64 = model
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| model.positions[i as usize]);
            0.5 * f64::from((b - a).cross(c - a).length())
        })
        .sum();
    // A generated atlas covers about half of its square.
    let side = (area / (f64::from(texel).powi(2) * 0.5)).sqrt().ceil();
    let side = if side.is_finite() { side.clamp(64.0, 4096.0) as u32 } else { 64 };
    let atlas =
        AtlasMesh::generate(&mesh, AtlasOptions { size: side, padding: 2 }, &crate::progress::Silent)?;
    let n = side as usize;
    let coverage = rasterize(&atlas.uv, &atlas.triangles, (n, n));
    let texture = &model.base_colour;
    let (tw, th) = (texture.width as i64, texture.height as i64);
    let at = |x: i64, y: i64| {
        let (x, y) = if model.repeat {
            (x.rem_euclid(tw), y.rem_euclid(th))
        } else {
            (x.clamp(0, tw - 1), y.clamp(0, th - 1))
        };
        texture.rgb[(y * tw + x) as usize]
    };
    let rgb = (0..n * n)
        .map(|i| {
            let f = coverage.triangle[i];
            if f == Coverage::NONE {
                return [0.0; 3];
            }
            let corners = model.triangles[f as usize];
            let b = coverage.bary[i].to_array();
            let uv: glam::Vec2 = (0..3).map(|k| b[k] * model.uv[corners[k] as usize]).sum();
            let (u, v) = (uv.x * tw as f32 - 0.5, uv.y * th as f32 - 0.5);
            let (x0, y0) = (u.floor(), v.floor());
            let (fx, fy) = (u - x0, v - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let [p, q, r, s] = [at(x0, y0), at(x0 + 1, y0), at(x0, y0 + 1), at(x0 + 1, y0 + 1)];
            std::array::from_fn(|k| {
                (p[k] * (1.0 - fx) + q[k] * fx) * (1.0 - fy) + (r[k] * (1.0 - fx) + s[k] * fx) * fy
            })
        })
        .collect();
    let covered = coverage.triangle.iter().map(|&t| t != Coverage::NONE).collect();
    let positions: Vec<glam::Vec3> =
        atlas.source_vertex.iter().map(|&v| model.positions[v as usize]).collect();
    let scale = density(&positions, &atlas.uv, &atlas.triangles, (n, n)) * f64::from(texel);
    Ok((Picture { width: n, height: n, rgb }, covered, scale))
}

/// Σ of the triangles' areas in the texture, in texels².
fn uv_area(uv: &[glam::Vec2], triangles: &[[u32; 3]], (w, h): (usize, usize)) -> f64 {
    let scale = glam::Vec2::new(w as f32, h as f32);
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| uv[i as usize] * scale);
            0.5 * f64::from((b - a).perp_dot(c - a).abs())
        })
        .sum()
}

/// Texels per model unit of a layout: √(UV area in texels² / surface area).
pub fn density(
    positions: &[glam::Vec3],
    uv: &[glam::Vec2],
    triangles: &[[u32; 3]],
    size: (usize, usize),
) -> f64 {
    let area: f64 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            0.5 * f64::from((b - a).cross(c - a).length())
        })
        .sum();
    (uv_area(uv, triangles, size) / area.max(1e-30)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Structured test picture: blobs and fine stripes.
    fn pattern(w: usize, h: usize) -> Picture {
        let rgb = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let v = 0.5 + 0.25 * (x * 0.9).sin() * (y * 0.45).cos() + 0.2 * (x * 0.13 + y * 0.07).sin();
                [v, v * 0.9, v * 0.8]
            })
            .collect();
        Picture { width: w, height: h, rgb }
    }

    #[test]
    fn the_sample_scores_itself_and_a_blur_is_flagged() {
        let sample = pattern(96, 96);
        let all = vec![true; 96 * 96];
        let own = texture_figures(&sample, &all, &sample, 1.0, true);
        // The atlas is not wrapped (its edges lose a ring of Laplacians), the sample is.
        assert!((own.contrast - 1.0).abs() < 1e-9 && (own.detail - 1.0).abs() < 0.02, "{own:?}");
        assert!(own.smeared <= 2.0 * FLATTEST && own.colour_chi2 == 0.0, "{own:?}");
        // The sample at twice its size, read back at scale 1: upscaled, so blurred.
        let upscaled = resample(&sample, 2.0, true);
        let all2 = vec![true; upscaled.width * upscaled.height];
        let blurred = texture_figures(&upscaled, &all2, &sample, 1.0, true);
        assert!(blurred.detail < 0.5 && blurred.smeared > 2.0 * own.smeared, "{blurred:?}");
        // At its true scale, it is the sample again.
        let right = texture_figures(&upscaled, &all2, &sample, 2.0, true);
        assert!((right.detail - 1.0).abs() < 0.05 && (right.contrast - 1.0).abs() < 0.01, "{right:?}");
    }

    #[test]
    fn gutters_are_not_counted_and_a_flat_patch_is_a_smear() {
        let sample = pattern(96, 96);
        let mut atlas = sample.clone();
        let mut covered = vec![true; 96 * 96];
        // A gutter of black texels: not on the surface, not counted.
        atlas.rgb[..96 * 20].fill([0.0; 3]);
        covered[..96 * 20].fill(false);
        let f = texture_figures(&atlas, &covered, &sample, 1.0, true);
        assert!(f.colour_shift < 0.05 && (f.contrast - 1.0).abs() < 0.1, "{f:?}");
        // A flat quarter: about a quarter of the windows smeared.
        for y in 48..96 {
            for x in 48..96 {
                atlas.rgb[y * 96 + x] = [0.5, 0.45, 0.4];
            }
        }
        let g = texture_figures(&atlas, &covered, &sample, 1.0, true);
        assert!(g.smeared > f.smeared + 0.15, "{f:?} {g:?}");
    }
}
