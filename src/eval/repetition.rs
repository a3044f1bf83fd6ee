//! Repetition, from the pictures alone (so another tool's result is scored by the same code):
//! how strongly the same sample places recur at regular offsets in a result, and how evenly
//! the result uses its sample.
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
    /// The strongest of those offsets, in result pixels.
    pub repeat_offset: [i32; 2],
    /// Share of the sample's places (cells of [`TOLERANCE`]² texels) that are the source of
    /// no result patch. Depends on the result's size; compare tools on equal sizes.
    pub unused: f64,
    /// Coefficient of variation of the per-cell source counts: 0 when every place of the
    /// sample is used equally often; copies that lean on a few places score high.
    pub use_spread: f64,
}

impl Repetition {
    /// Where there is nothing to measure (pictures smaller than a patch, a surface).
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
    let min_cells = MIN_OFFSET as i64 / STRIDE as i64;
    let mut shares: Vec<(f64, [i64; 2])> = (0..=rows / 2)
        .flat_map(|dy| (-(columns / 2)..=columns / 2).map(move |dx| [dx, dy]))
        .filter(|&[dx, dy]| dx.abs().max(dy) >= min_cells && (dy > 0 || dx > 0))
        .map(|[dx, dy]| (recurring[grid.offset_index(dx, dy)] / total, [dx, dy]))
        .collect();
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
