//! Principal images: a stack of images as mean + Σ coordinates × orthonormal components.
//!
//! Filtering is linear, so the filter responses of any image are the same combination of the
//! responses of the mean and the components. btfsynth therefore filters r + 1 basis images
//! instead of every image, and — because the components are orthonormal and the centred
//! coordinates sum to zero — the dot products of the paper's concatenated response vectors
//! are reproduced exactly by r + 1 scaled blocks (see [`PrincipalImages::block_weights`]).
//! Truncating to the components that hold 99.9% of the variance is the only approximation.

use crate::seeded::normal;
use crate::{Error, Result};
use ndarray::{s, Array1, Array2, ArrayView2, Axis};

/// How the basis is computed.
#[derive(Clone, Copy, Debug)]
pub struct BasisOptions {
    /// Fraction of the centred variance to keep (default 0.999).
    pub energy: f64,
    /// Most components kept (default 64).
    pub max_rank: usize,
    /// Stacks with more images than this use a randomized range finder (default 1024).
    pub exact_limit: usize,
    /// Seed of the randomized range finder's test matrix (default 0).
    pub seed: u64,
}

impl Default for BasisOptions {
    fn default() -> Self {
        BasisOptions { energy: 0.999, max_rank: 64, exact_limit: 1024, seed: 0 }
    }
}

/// Image `a` ≈ `mean + Σₖ coords[a, k] · components[k]`.
#[derive(Clone, Debug)]
pub struct PrincipalImages {
    /// The mean image (P values).
    pub mean: Array1<f32>,
    /// r orthonormal component images, one per row (r × P).
    pub components: Array2<f32>,
    /// Singular values σₖ of the centred stack, decreasing.
    pub sigma: Vec<f32>,
    /// Coordinates of every image (n × r); column k has norm σₖ.
    pub coords: Array2<f32>,
    /// Fraction of the centred variance the components hold.
    pub energy: f64,
}

impl PrincipalImages {
    /// Weights that make the blocks [mean, component 1, …, component r] reproduce the dot
    /// products of the n images' concatenated (linear) features: Σₐ f(Iₐ)·g(Iₐ) =
    /// n f(m)·g(m) + Σₖ σₖ² f(Pₖ)·g(Pₖ), so block 0 is weighted √n and block k by σₖ.
    pub fn block_weights(&self) -> Vec<f32> {
        let n = self.coords.nrows() as f32;
        std::iter::once(n.sqrt()).chain(self.sigma.iter().copied()).collect()
    }
}

/// The principal images of `images` (one image per row).
pub fn principal_images(images: ArrayView2<f32>, options: &BasisOptions) -> Result<PrincipalImages> {
    if images.nrows() == 0 || images.ncols() == 0 {
        return Err(Error::invalid("principal images of an empty stack"));
    }
    let mean = images.mean_axis(Axis(0)).unwrap_or_else(|| Array1::zeros(images.ncols()));
    let centred = &images - &mean;
    let total: f64 = centred.iter().map(|&v| (v as f64) * (v as f64)).sum();
    if total <= 0.0 {
        // Every image is the same (e.g. a one-image BTF): the mean says it all.
        return Ok(PrincipalImages {
            mean,
            components: Array2::zeros((0, images.ncols())),
            sigma: vec![],
            coords: Array2::zeros((images.nrows(), 0)),
            energy: 1.0,
        });
    }
    let (range, rows) = if images.nrows() <= options.exact_limit {
        (None, centred)
    } else {
        let q = randomized_range(&centred, options.max_rank + 10, options.seed);
        let b = q.t().dot(&centred);
        (Some(q), b)
    };
    let (u, lambda) = leading_eigenvectors(&rows.dot(&rows.t()));
    let rank = kept_rank(&lambda, total, options);
    let sigma: Vec<f32> = lambda[..rank].iter().map(|l| l.sqrt() as f32).collect();
    let u = u.slice(s![.., ..rank]).to_owned();
    let inverse = Array1::from_iter(sigma.iter().map(|s| 1.0 / s));
    let components = (&u * &inverse).t().dot(&rows);
    let local = &u * &Array1::from_vec(sigma.clone());
    let coords = match range {
        Some(q) => q.dot(&local),
        None => local,
    };
    let energy = lambda[..rank].iter().sum::<f64>() / total;
    Ok(PrincipalImages { mean, components, sigma, coords, energy: energy.min(1.0) })
}

/// Components to keep: enough for `energy` of `total`, at most `max_rank`, none that is
/// numerically zero.
fn kept_rank(lambda: &[f64], total: f64, options: &BasisOptions) -> usize {
    let mut kept = 0.0;
    let mut rank = 0;
    for &l in lambda.iter().take(options.max_rank) {
        if kept >= options.energy * total || l <= total * 1e-10 {
            break;
        }
        kept += l;
        rank += 1;
    }
    rank
}

/// Eigenvectors (columns) and eigenvalues of a symmetric matrix, decreasing, clamped ≥ 0.
fn leading_eigenvectors(gram: &Array2<f32>) -> (Array2<f32>, Vec<f64>) {
    let n = gram.nrows();
    let eigen =
        nalgebra::DMatrix::<f64>::from_fn(n, n, |i, j| 0.5 * (gram[[i, j]] as f64 + gram[[j, i]] as f64))
            .symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let vectors = Array2::from_shape_fn((n, n), |(i, c)| eigen.eigenvectors[(i, order[c])] as f32);
    (vectors, order.iter().map(|&k| eigen.eigenvalues[k].max(0.0)).collect())
}

/// An orthonormal basis (n × q) of the range of `x` (n × P): a seeded Gaussian test matrix
/// and one power iteration (Halko, Martinsson and Tropp 2011).
fn randomized_range(x: &Array2<f32>, q: usize, seed: u64) -> Array2<f32> {
    let q = q.min(x.nrows()).min(x.ncols());
    let omega = Array2::from_shape_fn((x.ncols(), q), |(i, j)| normal(seed, i as i64, j as i64));
    let y = x.dot(&omega);
    let y = x.dot(&x.t().dot(&orthonormal_columns(y)));
    orthonormal_columns(y)
}

/// Modified Gram–Schmidt in f64; a column that vanishes is left zero.
fn orthonormal_columns(y: Array2<f32>) -> Array2<f32> {
    let mut m = y.mapv(|v| v as f64);
    for j in 0..m.ncols() {
        for i in 0..j {
            let proj = m.column(i).dot(&m.column(j));
            let ci = m.column(i).to_owned();
            m.column_mut(j).scaled_add(-proj, &ci);
        }
        let norm = m.column(j).dot(&m.column(j)).sqrt();
        if norm > 1e-12 {
            m.column_mut(j).mapv_inplace(|v| v / norm);
        } else {
            m.column_mut(j).fill(0.0);
        }
    }
    m.mapv(|v| v as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// n images that are random combinations of `rank` patterns plus a mean.
    fn low_rank_stack(n: usize, pixels: usize, rank: usize) -> Array2<f32> {
        let patterns = Array2::from_shape_fn((rank, pixels), |(k, p)| normal(1, k as i64, p as i64));
        let weights =
            Array2::from_shape_fn((n, rank), |(a, k)| normal(2, a as i64, k as i64) * (rank - k) as f32);
        weights.dot(&patterns) + 0.5
    }

    fn check_reconstruction(images: &Array2<f32>, basis: &PrincipalImages) {
        let rebuilt = basis.coords.dot(&basis.components) + &basis.mean;
        let err = (&rebuilt - images).iter().map(|v| v.abs()).fold(0.0f32, f32::max);
        assert!(err < 1e-3, "reconstruction error {err}");
        let gram = basis.components.dot(&basis.components.t());
        for ((i, j), v) in gram.indexed_iter() {
            assert!((v - if i == j { 1.0 } else { 0.0 }).abs() < 1e-3, "components not orthonormal");
        }
    }

    #[test]
    fn exact_and_randomized_bases_rebuild_a_low_rank_stack() {
        let images = low_rank_stack(60, 300, 5);
        let exact = principal_images(images.view(), &BasisOptions::default()).unwrap();
        assert_eq!(exact.sigma.len(), 5);
        check_reconstruction(&images, &exact);
        let randomized =
            principal_images(images.view(), &BasisOptions { exact_limit: 10, ..Default::default() }).unwrap();
        assert_eq!(randomized.sigma.len(), 5);
        check_reconstruction(&images, &randomized);
        for (a, b) in exact.sigma.iter().zip(&randomized.sigma) {
            assert!((a - b).abs() < 1e-3 * a, "{a} vs {b}");
        }
    }

    #[test]
    fn block_weights_reproduce_dot_products_of_linear_features() {
        // f = any linear map; Σₐ f(Iₐ)·f(Iₐ) must equal the weighted basis sum.
        let images = low_rank_stack(30, 80, 4);
        let basis =
            principal_images(images.view(), &BasisOptions { energy: 1.0, ..Default::default() }).unwrap();
        let f = Array2::from_shape_fn((80, 7), |(p, c)| normal(9, p as i64, c as i64));
        let direct: f32 = images.dot(&f).iter().map(|v| v * v).sum();
        let weights = basis.block_weights();
        let mut blocks = vec![basis.mean.dot(&f)];
        blocks.extend(basis.components.rows().into_iter().map(|c| c.dot(&f)));
        let via_basis: f32 = blocks.iter().zip(&weights).map(|(b, w)| w * w * b.dot(b)).sum();
        assert!((direct - via_basis).abs() < 1e-3 * direct, "{direct} vs {via_basis}");
    }

    #[test]
    fn identical_images_need_no_components() {
        let images = Array2::from_elem((3, 10), 0.25f32);
        let basis = principal_images(images.view(), &BasisOptions::default()).unwrap();
        assert_eq!(basis.components.nrows(), 0);
        assert_eq!(basis.block_weights(), vec![3f32.sqrt()]);
    }
}
