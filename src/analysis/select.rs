//! Representative images (Tong §4): cluster the stack's images by their filter responses on a
//! regular subsampling grid and keep the image nearest each cluster centre.
//!
//! The responses of all n images are never computed: images are expressed in a principal
//! image basis, only the basis is filtered, and the squared response distance between two
//! images becomes a quadratic form in their basis coordinates (exact up to the basis' 99.9%
//! energy cut).

use super::basis::{principal_images_streamed, BasisOptions, PrincipalImages, RowSource};
use super::convolve::{BankConvolver, Padding};
use super::features::rgb_responses;
use super::kmeans::{kmeans, KMeansOptions};
use crate::progress::Progress;
use crate::Result;
use ndarray::Array2;
use rayon::prelude::*;

/// Grid points per side of the subsampling grid (about).
const GRID_POINTS: usize = 16;

/// Indices of `count` representative images of `images` (one image per row, interleaved
/// RGB, `width × height`, made a block at a time: the whole stack as f32 rows, with its
/// centred copy, would be four times its f16 size), in increasing order; all images if
/// there are no more than `count`.
pub fn representatives(
    images: &dyn RowSource,
    (width, height): (usize, usize),
    count: usize,
    convolver: &BankConvolver,
    padding: Padding,
    seed: u64,
    progress: &dyn Progress,
) -> Result<Vec<usize>> {
    let n = images.rows();
    if n <= count {
        return Ok((0..n).collect());
    }
    let basis = principal_images_streamed(images, &selection_basis_options(seed))?;
    representatives_from_basis(&basis, (width, height), count, convolver, padding, seed, progress)
}

/// The basis options of the selection: the defaults with `seed`.
pub fn selection_basis_options(seed: u64) -> BasisOptions {
    BasisOptions { seed, ..BasisOptions::default() }
}

/// [`representatives`] of the images whose principal images `basis` holds (one row of
/// `basis.coords` per image), without the images themselves.
pub fn representatives_from_basis(
    basis: &PrincipalImages,
    (width, height): (usize, usize),
    count: usize,
    convolver: &BankConvolver,
    padding: Padding,
    seed: u64,
    progress: &dyn Progress,
) -> Result<Vec<usize>> {
    let n = basis.coords.nrows();
    if n <= count {
        return Ok((0..n).collect());
    }
    let coords = response_coordinates(&basis.components, (width, height), convolver, padding)?;
    let points = basis.coords.dot(&coords);
    let clustering =
        kmeans(points.view(), &KMeansOptions { k: count, seed, ..KMeansOptions::default() }, progress)?;
    Ok(nearest_distinct(&points, &clustering.centres))
}

/// The symmetric square root S of the components' response Gram matrix on the grid, so that
/// ‖F(Iₐ − I_b)‖² = ‖(cₐ − c_b) S‖².
fn response_coordinates(
    components: &Array2<f32>,
    (width, height): (usize, usize),
    convolver: &BankConvolver,
    padding: Padding,
) -> Result<Array2<f32>> {
    let step = (width.min(height) / GRID_POINTS).max(1);
    let grid: Vec<usize> = (0..height)
        .step_by(step)
        .flat_map(|y| (0..width).step_by(step).map(move |x| y * width + x))
        .collect();
    let r = components.nrows();
    let mut sampled = Vec::with_capacity(r);
    for component in components.rows() {
        let responses = rgb_responses(component, width, height, convolver, padding)?;
        sampled.push(grid.iter().flat_map(|&p| responses.column(p).to_vec()).collect::<Vec<f32>>());
    }
    let dot =
        |i: usize, j: usize| sampled[i].iter().zip(&sampled[j]).map(|(a, b)| (*a as f64) * (*b as f64)).sum();
    let gram: Vec<Vec<f64>> = (0..r).into_par_iter().map(|i| (0..r).map(|j| dot(i, j)).collect()).collect();
    let eigen = nalgebra::DMatrix::from_fn(r, r, |i, j| gram[i][j]).symmetric_eigen();
    let root = &eigen.eigenvectors
        * nalgebra::DMatrix::from_diagonal(&eigen.eigenvalues.map(|v| v.max(0.0).sqrt()))
        * eigen.eigenvectors.transpose();
    Ok(Array2::from_shape_fn((r, r), |(i, j)| root[(i, j)] as f32))
}

/// For each centre in turn, the nearest image not yet taken; sorted.
fn nearest_distinct(points: &Array2<f32>, centres: &Array2<f32>) -> Vec<usize> {
    let mut taken = vec![false; points.nrows()];
    let mut chosen = Vec::with_capacity(centres.nrows());
    for centre in centres.rows() {
        let best = points
            .rows()
            .into_iter()
            .enumerate()
            .filter(|(a, _)| !taken[*a])
            .map(|(a, p)| (p.iter().zip(centre).map(|(x, c)| (x - c) * (x - c)).sum::<f32>(), a))
            .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        if let Some((_, a)) = best {
            taken[a] = true;
            chosen.push(a);
        }
    }
    chosen.sort_unstable();
    chosen
}
