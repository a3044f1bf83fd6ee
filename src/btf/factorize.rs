//! A stack as a DFMF: per colour channel (after the colour model) a truncated SVD of the
//! (lights · views) × (width · height) matrix, as Bonn's UBO2014 files store it.
//!
//! Small matrices (the shorter side up to [`EXACT_LIMIT`]) get the exact SVD through the
//! Gram matrix of their shorter side; larger ones a randomized range finder with power
//! iterations (Halko, Martinsson and Tropp 2011), which is near-optimal when the spectrum
//! decays, as a BTF's does. Either way the image-side factor U has orthonormal columns
//! and the pixel side holds σₖ·vₖ, so the discarded energy is ‖M‖² − Σₖ σₖ².

use crate::btf::colour::ColourModel;
use crate::btf::ubo2014::write::ChannelFactors;
use crate::btf::{Btf, Direction, DirectionPair};
use crate::progress::Progress;
use crate::{seeded, Error, Param, Result};
use nalgebra::{DMatrix, SymmetricEigen};
use ndarray::{Array2, ArrayView2, Axis};
use std::collections::HashMap;

/// Shorter sides up to this size are factorized exactly.
pub const EXACT_LIMIT: usize = 512;
/// Extra columns of the randomized range finder beyond the components kept.
const OVERSAMPLING: usize = 16;
/// Power iterations of the randomized range finder.
const POWER_ITERATIONS: usize = 2;

/// A stack as a view × light grid: image `grid[l + lights · v]` of the stack is taken under
/// light `l` and view `v`.
pub struct Grid {
    /// The distinct view directions, indexed by `v` in `order`.
    pub views: Vec<Direction>,
    /// The distinct light directions, indexed by `l` in `order`.
    pub lights: Vec<Direction>,
    /// `views × lights` stack image indices: image `order[l + lights · v]` is taken under
    /// light `l` and view `v`.
    pub order: Vec<usize>,
}

/// Arranges the stack's images by view and light; fails unless it holds every pair.
pub fn grid(btf: &Btf) -> Result<Grid> {
    let (views, lights) = (btf.views(), btf.lights());
    let index: HashMap<_, usize> =
        btf.pairs().iter().enumerate().map(|(i, p)| ((p.light.key(), p.view.key()), i)).collect();
    let mut order = Vec::with_capacity(views.len() * lights.len());
    for view in &views {
        for light in &lights {
            match index.get(&(light.key(), view.key())) {
                Some(&i) => order.push(i),
                None => {
                    return Err(Error::invalid(format!(
                        "a DFMF file needs every view × light pair: this stack has {} images, but its {} views × {} lights make {} (missing: {})",
                        btf.len(),
                        views.len(),
                        lights.len(),
                        views.len() * lights.len(),
                        DirectionPair { light: *light, view: *view }
                    )))
                }
            }
        }
    }
    Ok(Grid { views, lights, order })
}

/// The result of [`factorize`].
pub struct Factorization {
    /// The view × light arrangement of the stack's images that the factors follow.
    pub grid: Grid,
    /// The factors of each colour channel, in the colour model's space.
    pub channels: Vec<ChannelFactors>,
    /// Per channel: ‖M − U·SxVᵀ‖ / ‖M‖ in the colour model's space, from the discarded
    /// singular values.
    pub relative_error: [f64; 3],
}

/// Factorizes every channel of `btf` (encoded by `model`) with `components` components
/// (capped by the matrix size). `seed` drives the randomized range finder.
pub fn factorize(
    btf: &Btf,
    model: ColourModel,
    components: usize,
    seed: u64,
    progress: &dyn Progress,
) -> Result<Factorization> {
    if components == 0 {
        return Err(Error::out_of_range(Param::Components, 0, "must be at least 1"));
    }
    let grid = grid(btf)?;
    let mut channels = Vec::with_capacity(3);
    let mut relative_error = [0.0; 3];
    progress.start("factorizing channels", 3);
    for (c, error) in relative_error.iter_mut().enumerate() {
        let m = channel_matrix(btf, &grid.order, model, c)?;
        let total = energy(m.view());
        let (factors, discarded) = truncated_svd(m.view(), components, seed.wrapping_add(c as u64));
        *error = if total > 0.0 { (discarded / total).sqrt() } else { 0.0 };
        channels.push(factors);
        progress.advance(1);
    }
    progress.finish();
    Ok(Factorization { grid, channels, relative_error })
}

/// Channel `c` of the encoded stack: one row per image in grid order, one column per pixel.
fn channel_matrix(btf: &Btf, order: &[usize], model: ColourModel, c: usize) -> Result<Array2<f32>> {
    let pixels = btf.width() * btf.height();
    let mut m = Array2::<f32>::zeros((order.len(), pixels));
    for (mut row, &i) in m.axis_iter_mut(Axis(0)).zip(order) {
        for (dst, px) in row.iter_mut().zip(btf.image(i).chunks_exact(3)) {
            let encoded = model.from_rgb([px[0].to_f32(), px[1].to_f32(), px[2].to_f32()])?;
            *dst = encoded[c];
        }
    }
    Ok(m)
}

/// The `k` leading singular triplets of `m`: U (rows × k, orthonormal) and σ·V (cols × k),
/// with the energy Σ σ² of the components left out.
pub fn truncated_svd(m: ArrayView2<f32>, k: usize, seed: u64) -> (ChannelFactors, f64) {
    let (rows, cols) = m.dim();
    let k = k.min(rows).min(cols).max(1);
    if rows.min(cols) <= EXACT_LIMIT {
        if rows <= cols {
            return from_range(None, m, k, 0.0);
        }
        // Factorize the transpose and swap the sides back.
        let (t, discarded) = from_range(None, m.t(), k, 0.0);
        return (swap_sides(t), discarded);
    }
    let basis = range_finder(m, (k + OVERSAMPLING).min(rows.min(cols)), seed);
    let b = basis.t().dot(&m);
    // The energy outside the basis' span is discarded too.
    let outside = (energy(m) - energy(b.view())).max(0.0);
    from_range(Some(&basis), b.view(), k, outside)
}

/// Σ v² in f64.
fn energy(m: ArrayView2<f32>) -> f64 {
    m.iter().map(|&v| v as f64 * v as f64).sum()
}

/// B·Bᵀ in f64, a block of columns at a time (so that small eigenvalues, and with them the
/// discarded energy, keep their precision).
fn gram(b: ArrayView2<f32>) -> DMatrix<f64> {
    let l = b.nrows();
    let mut g = Array2::<f64>::zeros((l, l));
    for start in (0..b.ncols()).step_by(4096) {
        let end = (start + 4096).min(b.ncols());
        let block = b.slice(ndarray::s![.., start..end]).mapv(|v| v as f64);
        g += &block.dot(&block.t());
    }
    DMatrix::from_fn(l, l, |i, j| (g[[i, j]] + g[[j, i]]) / 2.0)
}

/// With `basis` Q (orthonormal, rows × l) and B = Qᵀ·M (or Q = I and B = M when `basis`
/// is `None`): the eigenvectors W of B·Bᵀ give U = Q·W and σ·V = Bᵀ·W. Returns the factors
/// and the discarded energy: the eigenvalues left out plus `outside`.
fn from_range(
    basis: Option<&Array2<f32>>,
    b: ArrayView2<f32>,
    k: usize,
    outside: f64,
) -> (ChannelFactors, f64) {
    let eigen = SymmetricEigen::new(gram(b));
    let l = eigen.eigenvalues.len();
    let mut order: Vec<usize> = (0..l).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let discarded: f64 = order[k..].iter().map(|&j| eigen.eigenvalues[j].max(0.0)).sum();
    let w = Array2::from_shape_fn((l, k), |(i, j)| eigen.eigenvectors[(i, order[j])] as f32);
    let u = match basis {
        Some(q) => q.dot(&w),
        None => w.clone(),
    };
    let sxv = b.t().dot(&w);
    let singular_values = sxv.axis_iter(Axis(1)).map(|col| col.dot(&col).sqrt()).collect();
    (ChannelFactors { singular_values, u, sxv }, discarded + outside)
}

/// From the factors of Mᵀ (U′, σ·V′) to those of M: U = V′ = (σ·V′)/σ and σ·V = σ·U′.
/// Components with σ ≈ 0 carry nothing and become zero columns.
fn swap_sides(t: ChannelFactors) -> ChannelFactors {
    let largest = t.singular_values.iter().copied().fold(0f32, f32::max);
    let mut u = t.sxv;
    let mut sxv = t.u;
    for (j, &s) in t.singular_values.iter().enumerate() {
        let (scale_u, scale_v) = if s > largest * 1e-6 { (1.0 / s, s) } else { (0.0, 0.0) };
        u.column_mut(j).mapv_inplace(|v| v * scale_u);
        sxv.column_mut(j).mapv_inplace(|v| v * scale_v);
    }
    ChannelFactors { singular_values: t.singular_values, u, sxv }
}

/// An orthonormal basis (rows × l) that captures the leading column space of `m`.
fn range_finder(m: ArrayView2<f32>, l: usize, seed: u64) -> Array2<f32> {
    let cols = m.ncols();
    let omega = Array2::from_shape_fn((cols, l), |(i, j)| seeded::normal(seed, i as i64, j as i64));
    let mut q = orthonormalize(m.dot(&omega));
    for _ in 0..POWER_ITERATIONS {
        let z = orthonormalize(m.t().dot(&q));
        q = orthonormalize(m.dot(&z));
    }
    q
}

/// Orthonormal columns spanning those of `a`, by Gram–Schmidt applied twice (in f64);
/// a column that is (numerically) dependent on the previous ones becomes zero.
fn orthonormalize(a: Array2<f32>) -> Array2<f32> {
    let (rows, cols) = a.dim();
    let mut q: Vec<Vec<f64>> = Vec::with_capacity(cols);
    for j in 0..cols {
        let mut v: Vec<f64> = a.column(j).iter().map(|&x| x as f64).collect();
        let norm0 = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        for _ in 0..2 {
            for prev in &q {
                let d: f64 = prev.iter().zip(&v).map(|(a, b)| a * b).sum();
                v.iter_mut().zip(prev).for_each(|(x, p)| *x -= d * p);
            }
        }
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let keep = norm > 1e-10 * norm0.max(f64::MIN_POSITIVE);
        v.iter_mut().for_each(|x| *x = if keep { *x / norm } else { 0.0 });
        q.push(v);
    }
    Array2::from_shape_fn((rows, cols), |(i, j)| q[j][i] as f32)
}

/// ‖a − b‖ / ‖a‖ over every value of two stacks of one shape.
pub fn relative_difference(a: &Btf, b: &Btf) -> f64 {
    let (mut diff, mut total) = (0f64, 0f64);
    for (x, y) in a.pixels().iter().zip(b.pixels()) {
        let (x, y) = (x.to_f64(), y.to_f64());
        diff += (x - y) * (x - y);
        total += x * x;
    }
    if total > 0.0 {
        (diff / total).sqrt()
    } else {
        diff.sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rows × cols matrix of rank `rank` with singular values 1, ½, ¼, …
    fn low_rank(rows: usize, cols: usize, rank: usize) -> Array2<f32> {
        let u = orthonormalize(Array2::from_shape_fn((rows, rank), |(i, j)| {
            seeded::normal(1, i as i64, j as i64)
        }));
        let v = orthonormalize(Array2::from_shape_fn((cols, rank), |(i, j)| {
            seeded::normal(2, i as i64, j as i64)
        }));
        let mut s = Array2::<f32>::zeros((rank, rank));
        for r in 0..rank {
            s[[r, r]] = 0.5f32.powi(r as i32);
        }
        u.dot(&s).dot(&v.t())
    }

    fn residual(m: &Array2<f32>, f: &ChannelFactors) -> f64 {
        let approx = f.u.dot(&f.sxv.t());
        let d: f64 = (m - &approx).iter().map(|&v| v as f64 * v as f64).sum();
        let t: f64 = m.iter().map(|&v| v as f64 * v as f64).sum();
        (d / t).sqrt()
    }

    #[test]
    fn exact_and_randomized_paths_find_the_planted_spectrum() {
        // Exact on both orientations, randomized on a tall one.
        for (rows, cols) in [(40, 300), (300, 40), (700, 600)] {
            let m = low_rank(rows, cols, 8);
            let (f, discarded) = truncated_svd(m.view(), 3, 7);
            let want = [1.0, 0.5, 0.25];
            for (s, w) in f.singular_values.iter().zip(want) {
                assert!((s - w).abs() < 1e-4, "{rows}x{cols}: {:?}", f.singular_values);
            }
            let utu = f.u.t().dot(&f.u);
            for i in 0..3 {
                for j in 0..3 {
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((utu[[i, j]] - want).abs() < 1e-4, "{rows}x{cols}: UᵀU = {utu:?}");
                }
            }
            // The residual is what the discarded values 1/8, 1/16, … predict.
            let planted: f64 = (3..8).map(|r| 0.25f64.powi(r)).sum();
            let total: f64 = (0..8).map(|r| 0.25f64.powi(r)).sum();
            let predicted = (planted / total).sqrt();
            let got = residual(&m, &f);
            assert!((got - predicted).abs() < 1e-3 * predicted + 1e-6, "{rows}x{cols}: {got} vs {predicted}");
            let reported = (discarded / energy(m.view())).sqrt();
            assert!(
                (reported - predicted).abs() < 1e-3 * predicted,
                "{rows}x{cols}: {reported} vs {predicted}"
            );
        }
    }

    #[test]
    fn full_rank_reconstructs_exactly() {
        let m = low_rank(30, 50, 30);
        let (f, discarded) = truncated_svd(m.view(), 30, 0);
        assert!(residual(&m, &f) < 1e-5);
        assert!(discarded < 1e-12, "{discarded}");
    }
}
