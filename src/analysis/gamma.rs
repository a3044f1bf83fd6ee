//! The texton space of Tong et al. §4: the dot-product matrix Γ of the textons' appearance
//! vectors (default texton included), the texton distances it implies, and its spectral
//! embedding (beyond the paper).
//!
//! Γ = V Λ Vᵀ, so the rows of E = V Λ^½ are vectors whose dot products are Γ: textons become
//! points of a small Euclidean space with ‖Eᵢ − Eⱼ‖² = ‖tᵢ − tⱼ‖², exact at full rank. Keeping
//! the d components that hold 99.9% of the trace makes them cheap to store and search.

use crate::{Error, Result};
use ndarray::{Array2, Axis};

/// Fraction of Γ's trace the embedding keeps by default.
pub const DEFAULT_ENERGY: f64 = 0.999;

/// Appends the default texton (the mean of all appearance vectors, Tong §4) as the last row
/// and returns Γ, the (n + 1) × (n + 1) dot products.
pub fn gamma_with_default(appearance: &Array2<f32>) -> Array2<f32> {
    let mean = appearance.mean_axis(Axis(0)).unwrap_or_else(|| ndarray::Array1::zeros(appearance.ncols()));
    let mut all = Array2::zeros((appearance.nrows() + 1, appearance.ncols()));
    all.slice_mut(ndarray::s![..appearance.nrows(), ..]).assign(appearance);
    all.row_mut(appearance.nrows()).assign(&mean);
    let gamma = all.dot(&all.t());
    // The product is symmetric in exact arithmetic; make it so bit for bit.
    symmetrize(gamma)
}

fn symmetrize(mut m: Array2<f32>) -> Array2<f32> {
    for i in 0..m.nrows() {
        for j in 0..i {
            let v = 0.5 * (m[[i, j]] + m[[j, i]]);
            m[[i, j]] = v;
            m[[j, i]] = v;
        }
    }
    m
}

/// The one texton distance of the crate: ‖tᵢ − tⱼ‖² = Γᵢᵢ + Γⱼⱼ − 2Γᵢⱼ from three entries
/// of Γ, clamped at 0 against rounding.
#[inline]
pub fn texton_distance(ii: f32, jj: f32, ij: f32) -> f32 {
    (ii + jj - 2.0 * ij).max(0.0)
}

/// [`texton_distance`] for every pair, row-major (n × n).
pub fn distance_table(gamma: &Array2<f32>) -> Vec<f32> {
    let n = gamma.nrows();
    let mut table = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            table[i * n + j] = texton_distance(gamma[[i, i]], gamma[[j, j]], gamma[[i, j]]);
        }
    }
    table
}

/// The spectral embedding of Γ: rows are textons, columns the d leading components that
/// hold `energy` of the trace (1.0 keeps every non-zero one).
pub fn spectral_embedding(gamma: &Array2<f32>, energy: f64) -> Result<Array2<f32>> {
    let n = gamma.nrows();
    if n == 0 || gamma.ncols() != n {
        return Err(Error::invalid(format!("Γ must be square and non-empty, not {:?}", gamma.shape())));
    }
    if !(0.0..=1.0).contains(&energy) || energy == 0.0 {
        return Err(Error::invalid(format!("embedding energy {energy} must be in (0, 1]")));
    }
    let m = nalgebra::DMatrix::<f64>::from_fn(n, n, |i, j| gamma[[i, j]] as f64);
    let eigen = m.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    // Γ is positive semidefinite; negative eigenvalues are rounding noise.
    let values: Vec<f64> = order.iter().map(|&k| eigen.eigenvalues[k].max(0.0)).collect();
    let trace: f64 = values.iter().sum();
    let d = if trace <= 0.0 {
        1
    } else {
        let mut kept = 0.0;
        values
            .iter()
            .take_while(|&&v| {
                let more = kept < energy * trace && v > 0.0;
                kept += v;
                more
            })
            .count()
            .max(1)
    };
    Ok(Array2::from_shape_fn((n, d), |(i, c)| (eigen.eigenvectors[(i, order[c])] * values[c].sqrt()) as f32))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random_appearance(n: usize, dims: usize) -> Array2<f32> {
        let mut state = 0x1234_5678_u64;
        Array2::from_shape_fn((n, dims), |_| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 40) as f32 / (1u64 << 24) as f32) - 0.3
        })
    }

    #[test]
    fn gamma_is_symmetric_positive_semidefinite_with_the_mean_appended() {
        let a = random_appearance(12, 30);
        let g = gamma_with_default(&a);
        assert_eq!(g.shape(), &[13, 13]);
        assert_eq!(g, g.t());
        let mean = a.mean_axis(Axis(0)).unwrap();
        assert!((g[[12, 12]] - mean.dot(&mean)).abs() < 1e-4);
        let eigen = nalgebra::DMatrix::<f64>::from_fn(13, 13, |i, j| g[[i, j]] as f64).symmetric_eigen();
        assert!(eigen.eigenvalues.iter().all(|&v| v > -1e-4), "{:?}", eigen.eigenvalues);
    }

    #[test]
    fn full_rank_embedding_reproduces_gamma_distances() {
        let a = random_appearance(20, 50);
        let g = gamma_with_default(&a);
        let e = spectral_embedding(&g, 1.0).unwrap();
        let table = distance_table(&g);
        for i in 0..21 {
            for j in 0..21 {
                let d: f32 = (0..e.ncols()).map(|c| (e[[i, c]] - e[[j, c]]).powi(2)).sum();
                let want = table[i * 21 + j];
                assert!((d - want).abs() <= 1e-3 * want.max(1e-3), "({i},{j}) {d} vs {want}");
            }
        }
    }

    #[test]
    fn truncated_embedding_keeps_fewer_components_for_low_rank_gamma() {
        // Appearance vectors in a 3-dimensional subspace: Γ has rank ≤ 3.
        let basis = random_appearance(3, 40);
        let coeffs = random_appearance(30, 3);
        let g = gamma_with_default(&coeffs.dot(&basis));
        let e = spectral_embedding(&g, DEFAULT_ENERGY).unwrap();
        assert!(e.ncols() <= 3, "d = {}", e.ncols());
        assert!(spectral_embedding(&g, 0.0).is_err());
    }

    #[test]
    fn gamma_distances_equal_explicit_appearance_distances() {
        let a = random_appearance(6, 9);
        let table = distance_table(&gamma_with_default(&a));
        let mean = a.mean_axis(Axis(0)).unwrap();
        let row = |i: usize| if i < 6 { a.row(i).to_owned() } else { mean.clone() };
        for i in 0..7 {
            for j in 0..7 {
                let d: f32 = (&row(i) - &row(j)).iter().map(|v| v * v).sum();
                assert!((table[i * 7 + j] - d).abs() < 1e-4 * d.max(1.0), "({i},{j})");
            }
        }
    }
}
