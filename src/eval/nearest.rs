//! Exact nearest-patch search over one picture's patches.
//!
//! A brute-force search compares every query with every patch in all 147 values: for a
//! 256² sample's 62,500 patches against themselves that is minutes, and the figures built on
//! it feed benchmarks whose old numbers must stay comparable, so the search may not
//! approximate. A photograph's patches vary mostly along a few directions: on the leading
//! [`LEADING_AXES`] principal axes lie about nine tenths of their variance. A turn keeps
//! distances, so the squared distance along those axes alone is a lower bound of the whole:
//! one matrix product per block (a tenth of the brute force's) bounds every pair, and only
//! the few patches whose bound is below the best distance found so far are compared in
//! full, in the original values and with the brute force's sum. Ties go to the lower index,
//! as they do in the brute force's scan. (A kd-tree on the same axes was slower than the
//! brute force: its cells are bounded along too few axes to skip any.)

use nalgebra::{DMatrix, SymmetricEigen};
use ndarray::{s, Array2, ArrayView1, Axis};
use rayon::prelude::*;

/// Principal axes whose distances bound every pair.
const LEADING_AXES: usize = 16;
/// Queries per block (each block one task).
const QUERY_BLOCK: usize = 256;
/// Patches per block, so that a block of products stays in the core's cache while it is scanned.
const PATCH_BLOCK: usize = 1024;
/// The turned values are f32 and the axes orthonormal only to f32 precision: bounds are
/// loosened by this share and by [`ABSOLUTE_SLACK`] (summed squares) so that rounding never
/// skips the true nearest patch. Looser bounds cost time only.
const RELATIVE_SLACK: f64 = 1e-3;
/// See [`RELATIVE_SLACK`].
const ABSOLUTE_SLACK: f64 = 1e-5;
/// The bounds from the product ‖q‖² + ‖p‖² − 2 q·p cancel: they are loosened by this share
/// of ‖q‖² + ‖p‖² (f32 loses about 1e-7 of it per operation).
const EXPANSION_SLACK: f32 = 1e-4;

/// The patches of a picture (one row each), ready for exact nearest-neighbour queries.
pub(crate) struct PatchIndex<'a> {
    patches: &'a Array2<f32>,
    mean: Vec<f32>,
    /// One principal axis per column, by decreasing variance.
    axes: Array2<f32>,
    /// The patches on the principal axes, one row each.
    turned: Array2<f32>,
    /// Per patch, −2 × its leading turned values and its squared norm on them: one matrix
    /// product with queries' [leading values, 1] gives every bound less the query's norm.
    bounding: Array2<f32>,
    /// Per [`PATCH_BLOCK`] of patches, the largest norm on the leading axes.
    largest_norm: Vec<f32>,
}

impl<'a> PatchIndex<'a> {
    pub(crate) fn new(patches: &'a Array2<f32>) -> Self {
        let (mean, axes) = principal_axes(patches);
        let turned = turn(patches, &mean, &axes);
        let axes_used = LEADING_AXES.min(turned.ncols());
        let norm = |j: usize| turned.row(j).iter().take(axes_used).map(|v| v * v).sum::<f32>();
        let bounding = Array2::from_shape_fn((turned.nrows(), axes_used + 1), |(j, k)| {
            if k < axes_used {
                -2.0 * turned[[j, k]]
            } else {
                norm(j)
            }
        });
        let largest_norm = bounding
            .column(axes_used)
            .axis_chunks_iter(Axis(0), PATCH_BLOCK)
            .map(|c| c.fold(0.0, |m: f32, &v| m.max(v)))
            .collect();
        PatchIndex { patches, mean, axes, turned, bounding, largest_norm }
    }

    /// Per row of `queries`, the nearest patch `j` with `allowed(query, j)` whose summed
    /// squared difference is at most `within`, and that difference; `None` if there is none.
    pub(crate) fn search(
        &self,
        queries: &Array2<f32>,
        within: f64,
        allowed: impl Fn(usize, usize) -> bool + Sync,
    ) -> Vec<Option<(u32, f64)>> {
        let turned = turn(queries, &self.mean, &self.axes);
        let blocks: Vec<usize> = (0..queries.nrows()).step_by(QUERY_BLOCK).collect();
        let found: Vec<Vec<Option<(u32, f64)>>> = blocks
            .into_par_iter()
            .map_init(
                || Array2::zeros((QUERY_BLOCK, PATCH_BLOCK.min(self.patches.nrows()))),
                |products, first| {
                    let end = (first + QUERY_BLOCK).min(queries.nrows());
                    let mut block: Vec<Query> =
                        (first..end).map(|i| Query::new(queries.row(i), turned.row(i), within)).collect();
                    self.search_block(&mut block, products, |q, j| allowed(first + q, j));
                    block.into_iter().map(|q| q.best).collect()
                },
            )
            .collect();
        found.into_iter().flatten().collect()
    }

    /// The queries of one block against every patch, [`PATCH_BLOCK`] patches at a time.
    fn search_block(
        &self,
        block: &mut [Query],
        products: &mut Array2<f32>,
        allowed: impl Fn(usize, usize) -> bool,
    ) {
        let axes = self.bounding.ncols() - 1;
        let queries =
            Array2::from_shape_fn(
                (block.len(), axes + 1),
                |(q, k)| if k < axes { block[q].turned[k] } else { 1.0 },
            );
        for first in (0..self.patches.nrows()).step_by(PATCH_BLOCK) {
            let end = (first + PATCH_BLOCK).min(self.patches.nrows());
            let mut products = products.slice_mut(s![..block.len(), ..end - first]);
            let part = self.bounding.slice(s![first..end, ..]);
            ndarray::linalg::general_mat_mul(1.0, &queries, &part.t(), 0.0, &mut products);
            let slack = EXPANSION_SLACK * self.largest_norm[first / PATCH_BLOCK];
            for (q, query) in block.iter_mut().enumerate() {
                let row = products.row(q);
                let row = row.as_slice().expect("a row of a standard-layout block is contiguous");
                self.scan(query, row, slack, first, |j| allowed(q, j));
            }
        }
    }

    /// One query against one block of patches (`bounds` their ‖p‖² − 2 q·p on the leading
    /// axes, `first` the first's index): the least bound first while nothing bounds the
    /// search, then every patch whose bound is below the best so far.
    fn scan(
        &self,
        query: &mut Query,
        bounds: &[f32],
        slack: f32,
        first: usize,
        allowed: impl Fn(usize) -> bool,
    ) {
        if query.limit == f32::INFINITY {
            let least = bounds
                .iter()
                .enumerate()
                .fold((0, f32::INFINITY), |m, (j, &b)| if b < m.1 { (j, b) } else { m });
            if allowed(first + least.0) {
                self.consider(first + least.0, query);
            }
        }
        let slack = slack + EXPANSION_SLACK * query.leading_norm;
        let mut threshold = query.limit - query.leading_norm + slack;
        for (chunk, bounds) in bounds.chunks(32).enumerate() {
            // Nearly every chunk holds no candidate: the count is a branch-free test.
            if bounds.iter().map(|&b| (b <= threshold) as u32).sum::<u32>() == 0 {
                continue;
            }
            for (j, &b) in bounds.iter().enumerate() {
                let j = first + 32 * chunk + j;
                if b <= threshold && allowed(j) {
                    self.consider(j, query);
                    threshold = query.limit - query.leading_norm + slack;
                }
            }
        }
    }

    /// Patch `j` against the query: rejected on its turned values where it can be, else
    /// compared in the original values.
    fn consider(&self, j: usize, query: &mut Query) {
        let turned = self.turned.row(j);
        let turned = turned.as_slice().expect("rows of an owned standard-layout array are contiguous");
        if !within_limit(query.turned, turned, query.limit) {
            return;
        }
        let d: f64 =
            query.values.iter().zip(self.patches.row(j)).map(|(a, b)| ((a - b) as f64).powi(2)).sum();
        query.offer(j as u32, d);
    }
}

/// One query's state: its values, as given and turned, and the best patch so far.
struct Query<'q> {
    values: ArrayView1<'q, f32>,
    turned: &'q [f32],
    /// Its squared norm on the leading axes.
    leading_norm: f32,
    within: f64,
    best: Option<(u32, f64)>,
    /// Turned summed squares above this cannot beat `best` or come within `within`.
    limit: f32,
}

impl<'q> Query<'q> {
    fn new(values: ArrayView1<'q, f32>, turned: ArrayView1<'q, f32>, within: f64) -> Self {
        let turned = turned.to_slice().expect("rows of an owned standard-layout array are contiguous");
        let leading_norm = turned.iter().take(LEADING_AXES).map(|v| v * v).sum();
        Query { values, turned, leading_norm, within, best: None, limit: loosened(within) }
    }

    fn offer(&mut self, j: u32, d: f64) {
        let better = match self.best {
            None => d <= self.within,
            Some((b, bd)) => d < bd || (d == bd && j < b),
        };
        if better {
            self.best = Some((j, d));
            self.limit = loosened(d);
        }
    }
}

fn loosened(d: f64) -> f32 {
    (d * (1.0 + RELATIVE_SLACK) + ABSOLUTE_SLACK) as f32
}

/// Whether the summed squared difference of `a` and `b` is at most `limit`, stopping as
/// soon as a partial sum exceeds it (the leading axes carry most of it).
fn within_limit(a: &[f32], b: &[f32], limit: f32) -> bool {
    let mut sum = 0.0f32;
    for (ca, cb) in a.chunks(8).zip(b.chunks(8)) {
        sum += ca.iter().zip(cb).map(|(x, y)| (x - y) * (x - y)).sum::<f32>();
        if sum > limit {
            return false;
        }
    }
    true
}

/// The rows' mean and their covariance's eigenvectors (columns, by decreasing eigenvalue).
fn principal_axes(rows: &Array2<f32>) -> (Vec<f32>, Array2<f32>) {
    let dims = rows.ncols();
    let mean = rows.mean_axis(Axis(0)).unwrap_or_else(|| ndarray::Array1::zeros(dims));
    let centred = rows - &mean;
    let covariance = centred.t().dot(&centred);
    let eigen = SymmetricEigen::new(DMatrix::<f64>::from_fn(dims, dims, |i, j| covariance[[i, j]] as f64));
    let mut by_variance: Vec<usize> = (0..dims).collect();
    by_variance.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let axes = Array2::from_shape_fn((dims, dims), |(i, k)| eigen.eigenvectors[(i, by_variance[k])] as f32);
    (mean.to_vec(), axes)
}

/// `rows` less `mean`, on `axes`.
fn turn(rows: &Array2<f32>, mean: &[f32], axes: &Array2<f32>) -> Array2<f32> {
    let mean = ArrayView1::from(mean);
    (rows - &mean).dot(axes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::picture::{patch_matrix, patch_positions, Picture};
    use rand::{Rng, SeedableRng};

    /// Noisy blobs that repeat every 20 columns, so that exact ties occur (the lower index
    /// must win them), and a flat clipped band.
    fn picture(w: usize, h: usize, seed: u64) -> Picture {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let noise: Vec<f32> = (0..20 * h).map(|_| 0.05 * rng.random::<f32>()).collect();
        let rgb = (0..w * h)
            .map(|i| {
                let (x, y) = (((i % w) % 20) as f32, (i / w) as f32);
                let noise = noise[(i / w) * 20 + (i % w) % 20];
                [
                    0.5 + 0.4 * (x * 0.31).sin() * (y * 0.17).cos() + noise,
                    0.5 + 0.4 * (x * 0.11 + y * 0.23).sin(),
                    (0.5 + 0.3 * ((x - y) * 0.19).cos()).clamp(0.0, 0.6),
                ]
            })
            .collect();
        Picture { width: w, height: h, rgb }
    }

    fn brute_force(
        queries: &Array2<f32>,
        patches: &Array2<f32>,
        within: f64,
        allowed: impl Fn(usize, usize) -> bool,
    ) -> Vec<Option<(u32, f64)>> {
        let distance = |i: usize, j: usize| -> f64 {
            queries.row(i).iter().zip(patches.row(j)).map(|(a, b)| ((a - b) as f64).powi(2)).sum()
        };
        (0..queries.nrows())
            .map(|i| {
                (0..patches.nrows())
                    .filter(|&j| allowed(i, j))
                    .map(|j| (j as u32, distance(i, j)))
                    .filter(|&(_, d)| d <= within)
                    .min_by(|a, b| a.1.total_cmp(&b.1))
            })
            .collect()
    }

    #[test]
    fn the_bounded_search_finds_the_brute_force_nearest_patches() {
        // 42 × 34 patches: more than one block of patches, and of queries against itself.
        let sample = picture(48, 40, 1);
        let patches = patch_matrix(&sample, &patch_positions(&sample, 1, false));
        let index = PatchIndex::new(&patches);
        let other = picture(30, 30, 2);
        let queries = patch_matrix(&other, &patch_positions(&other, 2, false));
        let everything = |_: usize, _: usize| true;
        let found = index.search(&queries, f64::INFINITY, everything);
        assert_eq!(found, brute_force(&queries, &patches, f64::INFINITY, everything));
        assert!(found.iter().all(Option::is_some));

        // Against itself, leaving out each patch's neighbours, within a radius.
        let apart = |i: usize, j: usize| (i as i64 - j as i64).abs() > 40;
        let within = 0.5;
        let found = index.search(&patches, within, apart);
        assert_eq!(found, brute_force(&patches, &patches, within, apart));
        let misses = found.iter().filter(|f| f.is_none()).count();
        assert!(misses > 0 && misses < found.len(), "{misses} of {} beyond the radius", found.len());
    }
}
