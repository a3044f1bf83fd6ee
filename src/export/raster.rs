//! Which surface point each atlas texel shows, and what fills the gutters.
//!
//! **Coverage.** A texel belongs to the triangle nearest its centre in UV space, if that
//! triangle comes within [`MARGIN`] texels (conservative rasterization: a texel the
//! triangle only grazes is still baked, from the triangle's point nearest the texel's
//! centre, so bilinear filtering along a chart's edge reads colours of that chart's own
//! surface). Ties go to the triangle listed first.
//!
//! **Gutters.** Every other texel copies the nearest baked texel ([`gutter_sources`], a
//! breadth-first fill from all baked texels at once), so mip-mapping and filtering near a
//! chart's edge read that chart's colours, not black. Generated atlases keep charts at least
//! 2 × padding texels apart, so a texel next to a chart is always filled from that chart.

use glam::{Vec2, Vec3};
use std::collections::VecDeque;

/// How far (in texels) outside a triangle a texel centre may lie and still be baked from
/// it: just over half a texel's diagonal, so every texel the triangle touches is baked.
pub const MARGIN: f32 = 0.75;

/// Per texel of a `width × height` atlas, the triangle and the barycentric weights of the
/// surface point it shows.
#[derive(Clone, Debug, PartialEq)]
pub struct Coverage {
    /// Atlas width in texels.
    pub width: usize,
    /// Atlas height in texels.
    pub height: usize,
    /// Per texel, row-major: its triangle, or [`Coverage::NONE`] for a gutter texel.
    pub triangle: Vec<u32>,
    /// Per texel: barycentric weights of its point in that triangle.
    pub bary: Vec<Vec3>,
}

impl Coverage {
    /// The triangle of a gutter texel.
    pub const NONE: u32 = u32::MAX;

    /// Number of baked (non-gutter) texels.
    pub fn baked(&self) -> usize {
        self.triangle.iter().filter(|&&t| t != Self::NONE).count()
    }
}

/// Rasterizes `triangles` (indices into `uv`, glTF convention: [0, 1]² spans the atlas,
/// v down) into a `width × height` atlas.
pub fn rasterize(uv: &[Vec2], triangles: &[[u32; 3]], (width, height): (usize, usize)) -> Coverage {
    let n = width * height;
    let mut coverage =
        Coverage { width, height, triangle: vec![Coverage::NONE; n], bary: vec![Vec3::ZERO; n] };
    let mut distance = vec![f32::INFINITY; n];
    let scale = Vec2::new(width as f32, height as f32);
    for (f, t) in triangles.iter().enumerate() {
        let [a, b, c] = t.map(|i| uv[i as usize] * scale);
        if (b - a).perp_dot(c - a).abs() <= 1e-12 {
            continue; // no area in the atlas: nothing to bake
        }
        let lo = a.min(b).min(c) - MARGIN;
        let hi = a.max(b).max(c) + MARGIN;
        let (x0, y0) = (lo.x.floor().max(0.0) as usize, lo.y.floor().max(0.0) as usize);
        let (x1, y1) = (hi.x.ceil().min(width as f32) as usize, hi.y.ceil().min(height as f32) as usize);
        for y in y0..y1 {
            for x in x0..x1 {
                let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let (d, bary) = nearest_in_triangle(centre, a, b, c);
                let i = y * width + x;
                if d <= MARGIN && d < distance[i] {
                    distance[i] = d;
                    coverage.triangle[i] = f as u32;
                    coverage.bary[i] = bary;
                }
            }
        }
    }
    coverage
}

/// Distance from `p` to triangle `abc` (0 inside) and the barycentric weights of the
/// triangle's point nearest `p`.
fn nearest_in_triangle(p: Vec2, a: Vec2, b: Vec2, c: Vec2) -> (f32, Vec3) {
    let [p, a, b, c] = [p, a, b, c].map(|q| q.extend(0.0));
    let q = crate::mesh::bvh::closest_on_triangle(p, a, b, c);
    (q.distance(p), barycentric(q, a, b, c))
}

/// Barycentric weights of `p` (on the plane of triangle `abc`), clamped into the triangle.
pub fn barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (e0, e1, e2) = (b - a, c - a, p - a);
    let (d00, d01, d11, d20, d21) = (e0.dot(e0), e0.dot(e1), e1.dot(e1), e2.dot(e0), e2.dot(e1));
    let denom = d00 * d11 - d01 * d01;
    if denom.abs() <= f32::MIN_POSITIVE {
        return Vec3::X;
    }
    let v = ((d11 * d20 - d01 * d21) / denom).clamp(0.0, 1.0);
    let w = ((d00 * d21 - d01 * d20) / denom).clamp(0.0, 1.0 - v);
    Vec3::new(1.0 - v - w, v, w)
}

/// Per texel, the baked texel whose values it takes: itself if baked, else the nearest
/// baked texel, reached breadth-first over 8-neighbours (all baked texels start at once,
/// in row order, so the fill is deterministic). `None` if nothing is baked.
pub fn gutter_sources(coverage: &Coverage) -> Option<Vec<u32>> {
    let (w, h) = (coverage.width, coverage.height);
    let mut source = vec![u32::MAX; w * h];
    let mut queue = VecDeque::new();
    for (i, &t) in coverage.triangle.iter().enumerate() {
        if t != Coverage::NONE {
            source[i] = i as u32;
            queue.push_back(i);
        }
    }
    if queue.is_empty() {
        return None;
    }
    while let Some(i) = queue.pop_front() {
        let (x, y) = ((i % w) as i64, (i / w) as i64);
        for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (1, -1), (-1, 1), (1, 1)] {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                continue;
            }
            let j = ny as usize * w + nx as usize;
            if source[j] == u32::MAX {
                source[j] = source[i];
                queue.push_back(j);
            }
        }
    }
    Some(source)
}

/// `values` (one item per texel) with every gutter texel replaced by its source's value.
pub fn fill_gutters<T: Copy>(values: &mut [T], sources: &[u32]) {
    for i in 0..values.len() {
        values[i] = values[sources[i] as usize];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::layout::{AtlasMesh, AtlasOptions};

    #[test]
    fn a_quad_covers_its_texels_and_interpolates() {
        let uv = [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y];
        let c = rasterize(&uv, &[[0, 1, 2], [0, 2, 3]], (8, 4));
        assert_eq!(c.baked(), 32);
        // Texel (1, 3) has centre (1.5 / 8, 3.5 / 4) = below the diagonal u = v: triangle 1.
        let i = 3 * 8 + 1;
        assert_eq!(c.triangle[i], 1);
        let b = c.bary[i];
        let p = uv[0] * b.x + uv[2] * b.y + uv[3] * b.z;
        assert!((p - Vec2::new(1.5 / 8.0, 3.5 / 4.0)).length() < 1e-6);
    }

    #[test]
    fn grazed_texels_are_baked_from_the_nearest_point() {
        // A triangle covering the left half of texel column 2 only.
        let uv = [Vec2::new(0.0, 0.0), Vec2::new(0.25, 0.0), Vec2::new(0.0, 1.0)]
            .map(|p| p * Vec2::new(10.0 / 8.0, 1.0));
        let c = rasterize(&uv, &[[0, 1, 2]], (8, 1));
        assert_eq!(c.triangle[2], 0, "grazed: baked");
        assert_eq!(c.triangle[4], Coverage::NONE, "beyond the margin: gutter");
    }

    #[test]
    fn gutters_take_the_nearest_baked_texel() {
        let mut c =
            Coverage { width: 5, height: 1, triangle: vec![Coverage::NONE; 5], bary: vec![Vec3::ZERO; 5] };
        c.triangle[0] = 0;
        c.triangle[4] = 1;
        let sources = gutter_sources(&c).expect("something is baked");
        assert_eq!(sources, vec![0, 0, 0, 4, 4]);
        let mut values = [1, 0, 0, 0, 9];
        fill_gutters(&mut values, &sources);
        assert_eq!(values, [1, 1, 1, 9, 9]);
    }

    /// The property that keeps chart seams invisible: wherever filtering reads around a
    /// point of a chart (the 3 × 3 texels around any texel it covers), it reads only texels
    /// baked from that chart or filled from it.
    #[test]
    fn no_texel_near_a_chart_takes_colour_from_another_chart() {
        let mesh = crate::mesh::textured::load_textured(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/data/bunny-1k8.obj"
        )))
        .expect("the bundled bunny loads");
        for size in [128usize, 512] {
            let atlas = AtlasMesh::generate(
                &mesh,
                AtlasOptions { size: size as u32, padding: 2 },
                &crate::progress::Silent,
            )
            .expect("unwraps");
            let c = rasterize(&atlas.uv, &atlas.triangles, (size, size));
            let sources = gutter_sources(&c).expect("baked");
            let chart_of = |i: usize| atlas.chart[c.triangle[sources[i] as usize] as usize];
            let mut checked = 0;
            for (i, &t) in c.triangle.iter().enumerate() {
                if t == Coverage::NONE {
                    continue;
                }
                let chart = atlas.chart[t as usize];
                let (x, y) = ((i % size) as i64, (i / size) as i64);
                for (dx, dy) in (-1..=1).flat_map(|dx| (-1..=1).map(move |dy| (dx, dy))) {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx >= size as i64 || ny >= size as i64 {
                        continue;
                    }
                    let j = ny as usize * size + nx as usize;
                    assert_eq!(
                        chart_of(j),
                        chart,
                        "texel {j} next to chart {chart} reads chart {}",
                        chart_of(j)
                    );
                    checked += 1;
                }
            }
            assert!(checked > size * size / 10, "{checked} neighbours checked at {size}²");
        }
    }
}
