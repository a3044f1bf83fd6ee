//! Feature reduction for large levels: the texton features of a level with more than
//! [`REDUCE_ABOVE`] values are clustered in their leading principal subspace.
//!
//! A level's features are pixels × (r + 1)·3·filters values: at 400×400 texels with a
//! rank-32 basis and LM48, 160,000 × 4,752 (2.8 GiB), and one Lloyd iteration of k = 400
//! multiplies that by 400 centres. The features of neighbouring filters and of the basis
//! images are strongly correlated, so their centred energy lies in a few hundred
//! directions. Above the limit the features are projected on those directions (a
//! randomized range finder: one sketch, no power iteration, [`PROJECTED_DIMS`] columns,
//! enough kept for [`KEPT_ENERGY`] of the sketch's energy) and k-means runs there;
//! squared distances then differ from the full ones by at most the energy left out, which
//! `analysis.json` records per level (`feature_energy`). The textons' appearance vectors
//! (Γ) are the means of their pixels' full features, as without the reduction. Smaller
//! levels (every analysis of a 64×64 sample, the pinned goldens among them) are clustered
//! in full.

use super::products::{columns_in_parallel, rows_in_parallel};
use crate::seeded::normal;
use ndarray::{Array1, Array2, ArrayView2, Axis};

/// Feature matrices with more values than this (256 MiB of f32) are reduced first.
pub const REDUCE_ABOVE: usize = 1 << 26;
/// Columns of the sketch.
pub const PROJECTED_DIMS: usize = 384;
/// Share of the sketch's energy the kept dimensions hold.
pub const KEPT_ENERGY: f64 = 0.999;

/// The features' centred coordinates on their leading directions (pixels × kept), and the
/// share of the centred features' energy those coordinates hold.
pub struct Reduced {
    /// pixels × kept: each pixel's centred features on the leading directions.
    pub coords: Array2<f32>,
    /// Share (0–1) of the centred features' energy that `coords` holds.
    pub energy: f64,
}

/// Reduces `features` (pixels × D) as the module notes say; `seed` drives the sketch.
pub fn reduce(features: ArrayView2<f32>, seed: u64) -> Reduced {
    let (n, d) = features.dim();
    let l = PROJECTED_DIMS.min(n).min(d);
    let mean: Array1<f32> = features.mean_axis(Axis(0)).unwrap_or_else(|| Array1::zeros(d));
    let total: f64 = features
        .rows()
        .into_iter()
        .map(|row| row.iter().zip(&mean).map(|(&x, &m)| ((x - m) as f64).powi(2)).sum::<f64>())
        .sum();
    // Y = (F − 1μᵀ) Ω, with the centring applied to the product: F Ω − 1 (μᵀ Ω).
    let omega = Array2::from_shape_fn((d, l), |(i, j)| normal(seed, i as i64, j as i64));
    let mut y = rows_in_parallel(features, omega.view(), PRODUCT_BLOCK);
    let shift = mean.dot(&omega);
    y -= &shift;
    let q = orthonormal(&y);
    drop(y);
    // B = Qᵀ (F − 1μᵀ) = Qᵀ F − (Qᵀ 1) μᵀ.
    let mut b = columns_in_parallel(q.t().as_standard_layout().view(), features, PRODUCT_BLOCK);
    let ones = q.sum_axis(Axis(0));
    for (mut row, &o) in b.rows_mut().into_iter().zip(&ones) {
        row.scaled_add(-o, &mean);
    }
    // B = W S Uᵀ: the coordinates are Q W S.
    let gram = b.mapv(|v| v as f64).dot(&b.t().mapv(|v| v as f64));
    let (w, values) = eigen(&gram);
    let sketch: f64 = values.iter().sum();
    let mut kept = 0.0;
    let dims = values
        .iter()
        .take_while(|&&v| {
            let more = kept < KEPT_ENERGY * sketch && v > 0.0;
            kept += v;
            more
        })
        .count()
        .max(1);
    let ws = Array2::from_shape_fn((w.nrows(), dims), |(i, j)| (w[[i, j]] * values[j].sqrt()) as f32);
    let coords = q.dot(&ws);
    let inside: f64 = values[..dims].iter().sum();
    Reduced { coords, energy: if total > 0.0 { (inside / total).min(1.0) } else { 1.0 } }
}

/// Rows and columns of the products below, per rayon task.
const PRODUCT_BLOCK: usize = 4096;

/// Orthonormal columns spanning those of `y` (n × l, n ≫ l): twice, Y V Λ^-½ with
/// YᵀY = V Λ Vᵀ (Cholesky–QR by eigenvectors, repeated for orthogonality); columns of
/// vanishing energy are dropped.
fn orthonormal(y: &Array2<f32>) -> Array2<f32> {
    let mut q = y.clone();
    for _ in 0..2 {
        let gram = q.t().dot(&q).mapv(|v| v as f64);
        let (v, values) = eigen(&gram);
        let largest = values.first().copied().unwrap_or(0.0);
        let kept = values.iter().take_while(|&&x| x > largest * 1e-10).count().max(1);
        let scale = Array2::from_shape_fn((v.nrows(), kept), |(i, j)| (v[[i, j]] / values[j].sqrt()) as f32);
        q = q.dot(&scale);
    }
    q
}

/// Eigenvectors (columns) and eigenvalues ≥ 0 of a symmetric matrix, decreasing.
fn eigen(m: &Array2<f64>) -> (Array2<f64>, Vec<f64>) {
    let n = m.nrows();
    let e = nalgebra::DMatrix::<f64>::from_fn(n, n, |i, j| 0.5 * (m[[i, j]] + m[[j, i]])).symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| e.eigenvalues[b].total_cmp(&e.eigenvalues[a]));
    let vectors = Array2::from_shape_fn((n, n), |(i, c)| e.eigenvectors[(i, order[c])]);
    (vectors, order.iter().map(|&k| e.eigenvalues[k].max(0.0)).collect())
}

/// The mean of each cluster's rows of `features` (summed in f64, in row order), one
/// centre per label `0..k` (the mean of every row for a label no row has).
pub fn full_centres(features: ArrayView2<f32>, labels: &[usize], k: usize) -> Array2<f32> {
    use rayon::prelude::*;
    let d = features.ncols();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); k];
    labels.iter().enumerate().for_each(|(i, &l)| members[l].push(i));
    let mut centres = Array2::<f32>::zeros((k, d));
    let all: Vec<usize> = (0..features.nrows()).collect();
    let rows: Vec<Vec<f32>> = members
        .par_iter()
        .map(|m| {
            // A cluster the last assignment left empty gets the mean of all features.
            let m = if m.is_empty() { &all } else { m };
            let mut sum = vec![0f64; d];
            for &i in m {
                sum.iter_mut().zip(features.row(i)).for_each(|(s, &x)| *s += x as f64);
            }
            let scale = 1.0 / m.len().max(1) as f64;
            sum.iter().map(|&s| (s * scale) as f32).collect()
        })
        .collect();
    for (mut dst, src) in centres.rows_mut().into_iter().zip(&rows) {
        dst.assign(&ndarray::ArrayView1::from(src.as_slice()));
    }
    centres
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduced_coordinates_keep_the_distances_of_low_rank_features() {
        // 2,000 points on a 20-dimensional subspace of 600 dimensions, plus an offset.
        let latent =
            Array2::from_shape_fn((2000, 20), |(i, k)| normal(1, i as i64, k as i64) * (20 - k) as f32);
        let mixing = Array2::from_shape_fn((20, 600), |(k, j)| normal(2, k as i64, j as i64));
        let features = latent.dot(&mixing) + 3.0;
        let r = reduce(features.view(), 0);
        assert!(r.coords.ncols() <= 20, "{}", r.coords.ncols());
        assert!(r.energy > 0.998, "{}", r.energy);
        for (a, b) in [(0, 1), (10, 1500), (77, 1999)] {
            let full: f32 = (&features.row(a) - &features.row(b)).mapv(|v| v * v).sum();
            let reduced: f32 = (&r.coords.row(a) - &r.coords.row(b)).mapv(|v| v * v).sum();
            assert!((full - reduced).abs() < 3e-3 * full, "{full} vs {reduced}");
        }
        let centres = full_centres(features.view(), &vec![0; 2000], 1);
        let mean = features.mean_axis(Axis(0)).unwrap();
        assert!((&centres.row(0) - &mean).iter().all(|v| v.abs() < 1e-3));
    }
}
