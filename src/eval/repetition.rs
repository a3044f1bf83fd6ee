//! Repetition, from the pictures alone (so another tool's result is scored by the same code):
//! how strongly the same sample places recur at regular offsets in a result, and how evenly
//! the result uses its sample. A surface map is scored from its vertices' coordinates, on
//! the same scale (`SurfaceRecurrences`, [`SURFACE_REACH`]).
//!
//! Patch energy cannot see repetition: a verbatim copy scores zero wherever it is pasted. A
//! tiled look is the same distinctive vein, knot or blotch at the same offset again and
//! again, so this module matches every result patch to its nearest sample patch (its source)
//! and asks, per offset d, which share of the result has the same source at d away.
//!
//! A periodic sample (tiles, a weave) has places that recur in the sample itself, and its
//! correct output recurs at the sample's period: such places are not distinctive, so they
//! carry no weight. A place weighs by how far its patch is from every other patch of the
//! sample that does not overlap it ([`DISTINCT`]): a unique knot weighs 1, a tile that
//! recurs in the sample about 0, and flat areas (where a repeat cannot be seen either) little.

use super::nearest::PatchIndex;
use super::picture::{patch_matrix, patch_positions, Picture, PATCH_SIDE};
use ndarray::Array2;
use serde::Serialize;

/// The repetition measures of one result against its sample.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Repetition {
    /// Mean over the [`PEAKS`] strongest offsets of the (weighted) share of the result whose
    /// source recurs at that offset (within [`TOLERANCE`] texels), less the share at a
    /// typical (the median) offset. 0: no sample place recurs at one offset more than at
    /// any other; near 1: the result is a tiling of a piece of the sample (less the edge
    /// that has no partner at the period). A single duplicated piece counts at a quarter of
    /// its share, a lattice of copies at all of it.
    pub repetition: f64,
    /// The strongest of those offsets, in result pixels (on a surface, in texels along the
    /// frame of the point it is measured from).
    pub repeat_offset: [i32; 2],
    /// Share of the sample's places (cells of [`TOLERANCE`]² texels) that are the source of
    /// no result patch. Depends on the result's size; compare tools on equal sizes.
    pub unused: f64,
    /// Coefficient of variation of the per-cell source counts: 0 when every place of the
    /// sample is used equally often; copies that lean on a few places score high.
    pub use_spread: f64,
}

impl Repetition {
    /// Where there is nothing to measure (pictures smaller than a patch).
    pub const NAN: Repetition =
        Repetition { repetition: f64::NAN, repeat_offset: [0, 0], unused: f64::NAN, use_spread: f64::NAN };
}

/// Result patches are taken every this many pixels (the stride of patch energy).
pub const STRIDE: usize = 4;
/// Two sources this close (in texels, either axis) are the same place: at least the stride,
/// so a period that falls between two stride offsets is counted whole at both.
pub const TOLERANCE: i32 = STRIDE as i32;
/// Offsets shorter than this (either axis) are the same feature, not a repeat of it.
pub const MIN_OFFSET: i32 = 4 * PATCH_SIDE as i32;
/// How many offset peaks the figure averages.
pub const PEAKS: usize = 4;
/// A sample place weighs 1 when its nearest non-overlapping patch differs from it by this
/// share of the mean difference between two random patches of the sample, and less in
/// proportion when closer (a place repeated within the sample weighs ~0).
pub const DISTINCT: f64 = 0.15;

/// Every repetition measure of `result` against `sample`, given each result patch's
/// position (on the [`STRIDE`] grid, as [`patch_positions`] lists them) and source (an
/// index into the sample's patch positions, `tileable` or not).
pub(crate) fn repetition(
    result: &Picture,
    positions: &[(usize, usize)],
    sources: &[u32],
    sample: &Picture,
    tileable: bool,
) -> Repetition {
    let sample_positions = patch_positions(sample, 1, tileable);
    if positions.is_empty() || sample_positions.is_empty() {
        return Repetition::NAN;
    }
    let place = |i: u32| {
        let (x, y) = sample_positions[i as usize];
        [x as i32, y as i32]
    };
    let weight = distinctiveness(sample, &sample_positions, tileable);
    let grid = Grid::of(result, positions);
    let weights: Vec<f64> = sources.iter().map(|&s| weight[s as usize]).collect();
    let recurring = recurrences(&grid, positions, sources, &weights, place);
    let (repetition, repeat_offset) = peaks(&grid, &weights, &recurring);
    let (unused, use_spread) = usage(sample, &sample_positions, sources);
    Repetition { repetition, repeat_offset, unused, use_spread }
}

/// The result positions as a grid of cells one [`STRIDE`] apart.
struct Grid {
    columns: usize,
    rows: usize,
}

impl Grid {
    fn of(result: &Picture, positions: &[(usize, usize)]) -> Grid {
        let columns = positions.iter().map(|p| p.0 / STRIDE + 1).max().unwrap_or(0);
        let rows = positions.iter().map(|p| p.1 / STRIDE + 1).max().unwrap_or(0);
        debug_assert_eq!(columns * rows, positions.len(), "{}×{} result", result.width, result.height);
        Grid { columns, rows }
    }

    /// Offsets in cells, dx in -(columns-1)..columns, dy in 0..rows: index of (dx, dy).
    fn offset_index(&self, dx: i64, dy: i64) -> usize {
        dy as usize * (2 * self.columns - 1) + (dx + self.columns as i64 - 1) as usize
    }

    fn offsets(&self) -> usize {
        self.rows * (2 * self.columns - 1)
    }
}

/// Per offset (dy ≥ 0, in cells), the summed weight of the positions whose source recurs
/// there. Sources are bucketed by place so that only pairs that can match are compared.
fn recurrences(
    grid: &Grid,
    positions: &[(usize, usize)],
    sources: &[u32],
    weights: &[f64],
    place: impl Fn(u32) -> [i32; 2],
) -> Vec<f64> {
    let cell = |[x, y]: [i32; 2]| (x.div_euclid(TOLERANCE), y.div_euclid(TOLERANCE));
    let mut buckets: std::collections::HashMap<(i32, i32), Vec<usize>> = Default::default();
    for (i, &s) in sources.iter().enumerate() {
        buckets.entry(cell(place(s))).or_default().push(i);
    }
    let mut recurring = vec![0.0f64; grid.offsets()];
    for (i, &s) in sources.iter().enumerate() {
        let (here, (cx, cy)) = (place(s), cell(place(s)));
        for (bx, by) in (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (cx + dx, cy + dy))) {
            for &j in buckets.get(&(bx, by)).map_or(&[][..], Vec::as_slice) {
                let there = place(sources[j]);
                if (here[0] - there[0]).abs() > TOLERANCE || (here[1] - there[1]).abs() > TOLERANCE {
                    continue;
                }
                let dx = (positions[j].0 / STRIDE) as i64 - (positions[i].0 / STRIDE) as i64;
                let dy = (positions[j].1 / STRIDE) as i64 - (positions[i].1 / STRIDE) as i64;
                // Each unordered pair once, with the offset on the dy ≥ 0 side.
                if dy > 0 || (dy == 0 && dx > 0) {
                    recurring[grid.offset_index(dx, dy)] += weights[i];
                }
            }
        }
    }
    recurring
}

/// The mean of the [`PEAKS`] strongest offsets' shares (each the weight of the positions
/// whose source recurs at that offset over the count of all positions), no two within
/// two cells of each other, less the median offset's share (the chance that two places
/// share a source at all: high where a result leans on a few sample places, wherever they
/// lie); and the strongest offset in pixels. Offsets shorter than [`MIN_OFFSET`] and longer
/// than half the result are left out.
fn peaks(grid: &Grid, weights: &[f64], recurring: &[f64]) -> (f64, [i32; 2]) {
    let (columns, rows) = (grid.columns as i64, grid.rows as i64);
    // Over the count of positions, not their weight: a result made of places that recur in
    // the sample itself (weights ~0) then scores ~0, whatever its period.
    let total = weights.len() as f64;
    let shares = (0..=rows / 2)
        .flat_map(|dy| (-(columns / 2)..=columns / 2).map(move |dx| [dx, dy]))
        .filter(|&[dx, dy]| far_enough([dx, dy]))
        .map(|[dx, dy]| (recurring[grid.offset_index(dx, dy)] / total, [dx, dy]))
        .collect();
    strongest(shares)
}

/// Whether an offset (in cells, on the dy ≥ 0 side) is long enough to be a repeat.
fn far_enough([dx, dy]: [i64; 2]) -> bool {
    dx.abs().max(dy) >= MIN_OFFSET as i64 / STRIDE as i64 && (dy > 0 || dx > 0)
}

/// [`peaks`]' figure from every offset's share (offsets in cells).
fn strongest(mut shares: Vec<(f64, [i64; 2])>) -> (f64, [i32; 2]) {
    if shares.is_empty() {
        return (f64::NAN, [0, 0]);
    }
    shares.sort_by(|a, b| b.0.total_cmp(&a.0));
    let chance = shares[shares.len() / 2].0;
    let mut chosen: Vec<(f64, [i64; 2])> = Vec::new();
    for &(share, d) in &shares {
        if chosen.len() == PEAKS {
            break;
        }
        if chosen.iter().all(|(_, c)| (c[0] - d[0]).abs().max((c[1] - d[1]).abs()) > 2) {
            chosen.push((share, d));
        }
    }
    let strongest = chosen.first().map_or([0, 0], |(_, d)| d.map(|c| (c * STRIDE as i64) as i32));
    let mean = chosen.iter().map(|c| c.0).sum::<f64>() / PEAKS as f64;
    ((mean - chance).max(0.0), strongest)
}

/// Per sample patch position, its weight in [0, 1]: the distance to its nearest patch
/// that does not overlap it, over [`DISTINCT`] × the mean distance between random patches.
fn distinctiveness(sample: &Picture, positions: &[(usize, usize)], tileable: bool) -> Vec<f64> {
    let patches = patch_matrix(sample, positions);
    let norms: Vec<f32> = patches.rows().into_iter().map(|r| r.dot(&r)).collect();
    let dims = patches.ncols() as f64;
    let scale = DISTINCT * mean_random_distance(&patches, &norms);
    if scale.is_nan() || scale <= 0.0 {
        return vec![0.0; positions.len()];
    }
    let side = PATCH_SIDE as i64;
    let apart = |a: usize, b: usize| {
        let d = |p: usize, q: usize, n: usize| {
            let d = (p as i64 - q as i64).abs();
            if tileable {
                d.min(n as i64 - d)
            } else {
                d
            }
        };
        let (a, b) = (positions[a], positions[b]);
        d(a.0, b.0, sample.width).max(d(a.1, b.1, sample.height)) >= side
    };
    // A place at least `scale` from every other weighs 1 however far it is, so the search
    // need not look further: most places of a photograph are that distinct.
    let found = PatchIndex::new(&patches).search(&patches, scale * dims, apart);
    found.iter().map(|f| f.map_or(1.0, |(_, d)| (d / dims / scale).min(1.0))).collect()
}

/// Mean squared difference per value between two patches of the sample drawn at random
/// (every patch against a fixed spread of others).
fn mean_random_distance(patches: &Array2<f32>, norms: &[f32]) -> f64 {
    let n = patches.nrows();
    let step = (n / 64).max(1);
    let others: Vec<usize> = (0..n).step_by(step).collect();
    let mut sum = 0.0f64;
    for i in (0..n).step_by(step.max(1)) {
        for &j in &others {
            sum += (norms[i] + norms[j] - 2.0 * patches.row(i).dot(&patches.row(j))).max(0.0) as f64;
        }
    }
    let pairs = (n.div_ceil(step) * others.len()).max(1) as f64;
    sum / pairs / patches.ncols() as f64
}

/// (share of sample cells no result patch comes from, coefficient of variation of the
/// per-cell counts).
fn usage(sample: &Picture, positions: &[(usize, usize)], sources: &[u32]) -> (f64, f64) {
    let cell = TOLERANCE as usize;
    let (columns, rows) = (sample.width.div_ceil(cell), sample.height.div_ceil(cell));
    let mut counts = vec![0u32; columns * rows];
    let mut exists = vec![false; columns * rows];
    for &(x, y) in positions {
        exists[(y / cell) * columns + x / cell] = true;
    }
    for &s in sources {
        let (x, y) = positions[s as usize];
        counts[(y / cell) * columns + x / cell] += 1;
    }
    let used: Vec<f64> = counts.iter().zip(&exists).filter(|(_, &e)| e).map(|(&c, _)| c as f64).collect();
    let n = used.len().max(1) as f64;
    let unused = used.iter().filter(|&&c| c == 0.0).count() as f64 / n;
    let mean = used.iter().sum::<f64>() / n;
    let variance = used.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / n;
    (unused, if mean > 0.0 { variance.sqrt() / mean } else { f64::NAN })
}

/// Where a surface's vertices lie, for [`SurfaceRecurrences`]: positions, the tangent frame
/// the synthesis laid the sample along at each, and the texel size in model units.
pub(crate) struct SurfacePlaces<'a> {
    pub positions: &'a [glam::Vec3],
    pub frames: &'a crate::mesh::frames::Frames,
    pub texel: f32,
}

/// How far a surface's repeats are looked for, in sample sides. A lattice of copies recurs
/// at most a copy apart, and a copy is at most the sample; a little more catches a whole
/// sample's period between two cells. Further out a curved model's tangent plane no longer
/// holds the offset (on a plane, half the result: two sides of a 4× output).
pub const SURFACE_REACH: f64 = 1.25;

/// The repetition measures of a surface result, from its vertices' sample coordinates
/// (`uv`, texels) rather than from a picture, but on the plane's scale: a vertex in 16 (the
/// plane's one position per [`STRIDE`]² pixels) is a position, and every other vertex whose
/// source is the same place (within [`TOLERANCE`]) is a recurrence at its offset, measured
/// in the position's frame in texels (a copy is laid along that frame, so a lattice of
/// copies recurs at one offset there) and counted once per cell of offsets. Offsets reach
/// [`SURFACE_REACH`] sample sides; pairs whose offset leaves the tangent plane by more than
/// 30° (across a fold or an ear) are not compared. The positions and the offsets at which
/// each one's source recurs depend on the coordinates alone: they are found once
/// ([`SurfaceRecurrences::of`]), then scored against each probe's picture
/// ([`SurfaceRecurrences::score`]; only the places' weights differ between a BTF's probes).
pub(crate) struct SurfaceRecurrences {
    /// Per position, its sample coordinate.
    uv: Vec<[i32; 2]>,
    /// Per position, the distinct offset cells (within `reach`) where its source recurs.
    offsets: Vec<Vec<[i64; 2]>>,
    /// The longest offset looked at, in cells.
    reach: i64,
}

impl SurfaceRecurrences {
    pub(crate) fn of(places: &SurfacePlaces, uv: &[[i32; 2]], (width, height): (usize, usize)) -> Self {
        let reach = (SURFACE_REACH * width.max(height) as f64 / STRIDE as f64).ceil() as i64;
        let buckets = buckets_by_place(uv);
        let chosen: Vec<usize> = (0..uv.len()).filter(|&i| is_position(i)).collect();
        let offsets = chosen
            .iter()
            .map(|&i| {
                let mut cells: Vec<[i64; 2]> = recurrence_offsets(places, uv, &buckets, i)
                    .filter(|d| d[0].abs().max(d[1]) <= reach)
                    .collect();
                cells.sort_unstable();
                cells.dedup();
                cells
            })
            .collect();
        SurfaceRecurrences { uv: chosen.iter().map(|&i| uv[i]).collect(), offsets, reach }
    }

    /// The repetition measures against `sample` (one probe's picture).
    pub(crate) fn score(&self, sample: &Picture, tileable: bool) -> Repetition {
        let sample_positions = patch_positions(sample, 1, tileable);
        if sample_positions.is_empty() || self.uv.is_empty() {
            return Repetition::NAN;
        }
        let columns = if tileable { sample.width } else { sample.width + 1 - PATCH_SIDE } as i32;
        let rows = sample_positions.len() as i32 / columns;
        // The sample patch centred on a texel (clamped where it would leave a sample that
        // does not tile).
        let source = |[u, v]: [i32; 2]| {
            let (x, y) = (u - PATCH_SIDE as i32 / 2, v - PATCH_SIDE as i32 / 2);
            let (x, y) = if tileable {
                (x.rem_euclid(columns), y.rem_euclid(rows))
            } else {
                (x.clamp(0, columns - 1), y.clamp(0, rows - 1))
            };
            (y * columns + x) as u32
        };
        let weight = distinctiveness(sample, &sample_positions, tileable);
        let reach = self.reach;
        let offset_index = |[dx, dy]: [i64; 2]| (dy * (2 * reach + 1) + dx + reach) as usize;
        let mut recurring = vec![0.0f64; ((reach + 1) * (2 * reach + 1)) as usize];
        let sources: Vec<u32> = self.uv.iter().map(|&at| source(at)).collect();
        for (cells, &s) in self.offsets.iter().zip(&sources) {
            for &d in cells {
                recurring[offset_index(d)] += weight[s as usize];
            }
        }
        let total = self.uv.len() as f64;
        let shares = (0..=reach)
            .flat_map(|dy| (-reach..=reach).map(move |dx| [dx, dy]))
            .filter(|&d| far_enough(d) && (d[0] * d[0] + d[1] * d[1]) as f64 <= (reach * reach) as f64)
            .map(|d| (recurring[offset_index(d)] / total, d))
            .collect();
        let (repetition, repeat_offset) = strongest(shares);
        let (unused, use_spread) = usage(sample, &sample_positions, &sources);
        Repetition { repetition, repeat_offset, unused, use_spread }
    }
}

/// A texture-mapped mesh (pattern mapping's corner coordinates, texels) as points for
/// [`SurfaceRecurrences`]: about one per texel on every face, each with the face's sample
/// coordinate there and a frame along the face's own texture axes (where its `u` and `v`
/// grow), so that a copy's offsets are measured along the copy as on a surface map.
pub(crate) fn texture_mapped_points(
    positions: &[glam::Vec3],
    triangles: &[[u32; 3]],
    corner_uv: &[[glam::Vec2; 3]],
    texel: f32,
) -> (Vec<glam::Vec3>, crate::mesh::frames::Frames, Vec<[i32; 2]>) {
    let mut frames = crate::mesh::frames::Frames { s: Vec::new(), t: Vec::new(), n: Vec::new() };
    let (mut points, mut uv) = (Vec::new(), Vec::new());
    for (tri, c) in triangles.iter().zip(corner_uv) {
        let p = tri.map(|v| positions[v as usize]);
        let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
        let (d1, d2) = (c[1] - c[0], c[2] - c[0]);
        let n = e1.cross(e2).normalize_or_zero();
        let det = d1.x * d2.y - d2.x * d1.y;
        // The direction along which u grows (the face's tangent); a face mapped to a line of
        // the sample has none and is left out.
        let along_u = ((e1 * d2.y - e2 * d1.y) / det).reject_from_normalized(n).normalize_or_zero();
        if n == glam::Vec3::ZERO || !det.is_finite() || det == 0.0 || along_u == glam::Vec3::ZERO {
            continue;
        }
        let texels = e1.cross(e2).length() / 2.0 / (texel * texel);
        let k = ((2.0 * texels).sqrt().ceil() as usize).max(1);
        for i in 0..k {
            for j in 0..k - i {
                let (b1, b2) = ((i as f32 + 1.0 / 3.0) / k as f32, (j as f32 + 1.0 / 3.0) / k as f32);
                let b0 = 1.0 - b1 - b2;
                points.push(p[0] * b0 + p[1] * b1 + p[2] * b2);
                let at = c[0] * b0 + c[1] * b1 + c[2] * b2;
                uv.push([at.x.round() as i32, at.y.round() as i32]);
                frames.s.push(along_u);
                frames.t.push(n.cross(along_u));
                frames.n.push(n);
            }
        }
    }
    (points, frames, uv)
}

/// One vertex in [`STRIDE`]²: those whose index falls in the first 16th of the golden-ratio
/// sequence (gaps of unequal lengths, where a remesher's spatial order could put every 16th
/// vertex in rows). Partners are every vertex, so which ones are positions does not bias
/// the offsets.
fn is_position(i: usize) -> bool {
    (i as u64).wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 60 == 0
}

/// The vertices by the [`TOLERANCE`]-texel cell of their source.
fn buckets_by_place(uv: &[[i32; 2]]) -> std::collections::HashMap<(i32, i32), Vec<u32>> {
    let mut buckets: std::collections::HashMap<(i32, i32), Vec<u32>> = Default::default();
    for (j, &[u, v]) in uv.iter().enumerate() {
        buckets.entry((u.div_euclid(TOLERANCE), v.div_euclid(TOLERANCE))).or_default().push(j as u32);
    }
    buckets
}

/// The offsets (cells of [`STRIDE`] texels in `i`'s frame, on the dy ≥ 0 side) of
/// every vertex whose source lies within [`TOLERANCE`] of `i`'s, where the offset stays
/// near `i`'s tangent plane.
fn recurrence_offsets<'a>(
    places: &'a SurfacePlaces,
    uv: &'a [[i32; 2]],
    buckets: &'a std::collections::HashMap<(i32, i32), Vec<u32>>,
    i: usize,
) -> impl Iterator<Item = [i64; 2]> + 'a {
    let here = uv[i];
    let (cx, cy) = (here[0].div_euclid(TOLERANCE), here[1].div_euclid(TOLERANCE));
    let (p, f) = (places.positions[i], &places.frames);
    let cell = STRIDE as f32 * places.texel;
    (-1..=1)
        .flat_map(move |dy| (-1..=1).map(move |dx| (cx + dx, cy + dy)))
        .flat_map(move |b| buckets.get(&b).map_or(&[][..], Vec::as_slice).iter())
        .filter(move |&&j| {
            let there = uv[j as usize];
            (here[0] - there[0]).abs() <= TOLERANCE && (here[1] - there[1]).abs() <= TOLERANCE
        })
        .filter_map(move |&j| {
            let e = places.positions[j as usize] - p;
            // sin 30° = 0.5: the offset's part along the normal at most half its length.
            if e.dot(f.n[i]).abs() > 0.5 * e.length() {
                return None;
            }
            let d = [(e.dot(f.s[i]) / cell).round() as i64, (e.dot(f.t[i]) / cell).round() as i64];
            // Each pair of positions once, as on a plane: its partner on the dy ≥ 0 side.
            (d[1] > 0 || (d[1] == 0 && d[0] > 0)).then_some(d)
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::frames::Frames;
    use glam::Vec3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Texels around and along the sheet.
    const SIDE: i32 = 192;
    /// The sheet's radius of curvature, in texels: gently curved, as much of a model is at
    /// 256 texels across.
    const RADIUS: f32 = 200.0;

    /// A 64² crop of the bundled gravel photograph (the size of most pattern libraries).
    fn gravel() -> Picture {
        let full =
            Picture::read(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/gravel-128.png"))
                .unwrap();
        let rgb = (0..64 * 64).map(|i| full.rgb[(i / 64) * full.width + i % 64]).collect();
        Picture { width: 64, height: 64, rgb }
    }

    /// A curved sheet with one vertex per texel, each jittered within its texel as a
    /// remesher leaves them, and its frames: `s` around the curve, `t` along it. Returns
    /// the vertices' (around, along) places in texels too.
    fn sheet(rng: &mut ChaCha8Rng) -> (Vec<Vec3>, Frames, Vec<[f32; 2]>) {
        let mut places = Vec::new();
        for y in 0..SIDE {
            for x in 0..SIDE {
                places.push([x as f32 + rng.random_range(-0.4..0.4), y as f32 + rng.random_range(-0.4..0.4)]);
            }
        }
        let angle = |a: f32| a / RADIUS;
        let positions = places
            .iter()
            .map(|&[a, z]| Vec3::new(RADIUS * angle(a).sin(), z, RADIUS * angle(a).cos()))
            .collect();
        let normals: Vec<Vec3> =
            places.iter().map(|&[a, _]| Vec3::new(angle(a).sin(), 0.0, angle(a).cos())).collect();
        let around: Vec<Vec3> =
            places.iter().map(|&[a, _]| Vec3::new(angle(a).cos(), 0.0, -angle(a).sin())).collect();
        (positions, Frames::from_directions(&normals, &around), places)
    }

    fn score(
        places: &[[f32; 2]],
        uv: impl Fn([i32; 2]) -> [i32; 2],
        mesh: &(Vec<Vec3>, Frames),
        sample: &Picture,
    ) -> f64 {
        let uv: Vec<[i32; 2]> = places.iter().map(|p| uv(p.map(|c| c.round() as i32))).collect();
        let on = SurfacePlaces { positions: &mesh.0, frames: &mesh.1, texel: 1.0 };
        SurfaceRecurrences::of(&on, &uv, (sample.width, sample.height)).score(sample, false).repetition
    }

    /// A texture-mapped mesh is scored along its faces' own texture axes: a flat grid of
    /// 16-texel squares (two faces each, turned a quarter turn every other square, as
    /// pattern mapping turns its patches) each mapped to one of four places of the sample
    /// in a 2×2 rhythm is a lattice; each mapped to a place of its own is not (measured 0.73
    /// and 0.03; the bounds are the plane's).
    #[test]
    fn a_texture_mapped_mesh_s_lattice_of_squares_is_flagged_and_random_squares_are_not() {
        let (sample, side, squares) = (gravel(), 16.0f32, 12);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let places: Vec<glam::Vec2> = (0..4)
            .map(|_| glam::Vec2::new(rng.random_range(0..48) as f32, rng.random_range(0..48) as f32))
            .collect();
        let score = |place: &mut dyn FnMut(usize, usize) -> glam::Vec2| {
            let (mut positions, mut triangles, mut corner_uv) = (Vec::new(), Vec::new(), Vec::new());
            for (i, j) in (0..squares).flat_map(|j| (0..squares).map(move |i| (i, j))) {
                let base = positions.len() as u32;
                let (x, y) = (i as f32 * side, j as f32 * side);
                positions.extend(
                    [[x, y], [x + side, y], [x + side, y + side], [x, y + side]]
                        .map(|[x, y]| Vec3::new(x, y, 0.0)),
                );
                let o = place(i, j);
                let mut corners = [[0.0, 0.0], [side, 0.0], [side, side], [0.0, side]]
                    .map(|[u, v]| o + glam::Vec2::new(u, v));
                if (i + j) % 2 == 1 {
                    corners.rotate_left(1);
                }
                triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
                corner_uv
                    .extend([[corners[0], corners[1], corners[2]], [corners[0], corners[2], corners[3]]]);
            }
            let (points, frames, uv) = texture_mapped_points(&positions, &triangles, &corner_uv, 1.0);
            let on = SurfacePlaces { positions: &points, frames: &frames, texel: 1.0 };
            SurfaceRecurrences::of(&on, &uv, (sample.width, sample.height)).score(&sample, false).repetition
        };
        let on_lattice = score(&mut |i, j| places[(j % 2) * 2 + i % 2]);
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let at_random = score(&mut |_, _| {
            glam::Vec2::new(rng.random_range(0..48) as f32, rng.random_range(0..48) as f32)
        });
        assert!(on_lattice > 0.4, "squares on a lattice: repetition {on_lattice}");
        assert!(at_random < 0.1, "squares from random places: repetition {at_random}");
        assert!(on_lattice > 4.0 * at_random, "{on_lattice} vs {at_random}");
    }

    /// The plane's lattice / random-placement pair on a surface: nine pieces of a quarter of
    /// the sample's side on a lattice are flagged, the same kind of pieces at random places
    /// are not, and neither is the whole sample tiled along the surface missed.
    #[test]
    fn a_surface_lattice_of_pieces_is_flagged_and_the_same_pieces_at_random_places_are_not() {
        let (sample, piece) = (gravel(), 16);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let (positions, frames, places) = sheet(&mut rng);
        let mesh = (positions, frames);
        let mut origin = || [rng.random_range(0..=64 - piece), rng.random_range(0..=64 - piece)];
        let cut: Vec<[i32; 2]> = (0..9).map(|_| origin()).collect();
        let on_lattice = score(
            &places,
            |[x, y]| {
                let (i, j) = ((x / piece).rem_euclid(3), (y / piece).rem_euclid(3));
                let o = cut[(j * 3 + i) as usize];
                [o[0] + x.rem_euclid(piece), o[1] + y.rem_euclid(piece)]
            },
            &mesh,
            &sample,
        );
        // Pieces half as large again, at jittered places in a random order, each from a
        // random place of the sample: the last one laid over a vertex is its source.
        let big = piece * 3 / 2;
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let mut laid: Vec<([i32; 2], [i32; 2])> = (-1..=SIDE / piece)
            .flat_map(|j| (-1..=SIDE / piece).map(move |i| [i * piece, j * piece]))
            .map(|at| {
                let jitter = [rng.random_range(-4..=4), rng.random_range(-4..=4)];
                (
                    [at[0] + jitter[0], at[1] + jitter[1]],
                    [rng.random_range(0..=64 - big), rng.random_range(0..=64 - big)],
                )
            })
            .collect();
        rand::seq::SliceRandom::shuffle(laid.as_mut_slice(), &mut rng);
        let at_random = score(
            &places,
            |p| {
                let (at, o) = laid
                    .iter()
                    .rev()
                    .find(|(at, _)| (0..2).all(|k| (at[k]..at[k] + big).contains(&p[k])))
                    .expect("the pieces cover the sheet");
                [o[0] + p[0] - at[0], o[1] + p[1] - at[1]]
            },
            &mesh,
            &sample,
        );
        let tiled = score(&places, |[x, y]| [x.rem_euclid(64), y.rem_euclid(64)], &mesh, &sample);
        // The plane's bounds (tests/suite/repetition.rs); measured 0.64, 0.044 and 0.50.
        assert!(on_lattice > 0.4, "pieces on a lattice: repetition {on_lattice}");
        assert!(at_random < 0.1, "the same pieces at random places: repetition {at_random}");
        assert!(on_lattice > 4.0 * at_random, "{on_lattice} vs {at_random}");
        assert!(tiled > 0.4, "the whole sample tiled: repetition {tiled}");
    }
}
