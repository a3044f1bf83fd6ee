//! Appearance vectors (beyond the paper, after Lefebvre and Hoppe 2006): every pixel's 5×5
//! neighbourhood across the whole stack, projected on its leading principal components.
//!
//! Textons quantize appearance into a few hundred labels, so many neighbourhoods tie
//! exactly and ties resolve by candidate order; continuous vectors keep the differences the
//! labels round away. A pixel's vector describes its surroundings, so comparing templates of
//! vectors sees further than the template itself (a 7×7 template of 5×5 descriptors spans
//! 11×11 pixels).
//!
//! Why neighbourhoods of the images rather than the filter responses the textons cluster:
//! the filter bank's large kernels blur where an edge is, so ±1-texel shifts cost almost
//! nothing and the result stutters (measured on 128² photographs → 512²: nearest-patch
//! energy 0.0056 with filter responses, 0.0032 with these, same engine otherwise).

use super::basis::{principal_images, principal_images_streamed, BasisOptions, PrincipalImages, RowSource};
use crate::Result;
use ndarray::{Array2, ArrayView2};
use rayon::prelude::*;

/// Dimensions kept by default: 16 keep nearly all the variance of a photograph's 5×5×3
/// neighbourhoods (8 measurably lose detail: nearest-patch energy +15%).
pub const DEFAULT_DIMS: usize = 16;

/// Side of the neighbourhood each vector describes.
pub const NEIGHBOURHOOD: usize = 5;

/// Per-pixel appearance vectors of one level whose images `basis` holds: `pixels × dims`,
/// row-major like the map. Borders mirror, or wrap when `wraps`.
pub fn appearance_vectors(
    basis: &PrincipalImages,
    (width, height): (usize, usize),
    dims: usize,
    wraps: bool,
    seed: u64,
) -> Result<Array2<f32>> {
    // A BTF pixel's colour over every image has (rank + 1)·3 values; reduce it first so the
    // neighbourhoods stay small.
    let colours = project(pixel_colours(basis).view(), dims, seed)?;
    // Every pixel's neighbourhood is 25 × dims values (a 512² photo's: 420 MB); they are
    // made a block at a time, for each pass of the projection, instead of held.
    let rows = Neighbourhoods { vectors: colours.view(), size: (width, height), side: NEIGHBOURHOOD, wraps };
    let options = BasisOptions { energy: 1.0, max_rank: dims, seed, ..BasisOptions::default() };
    Ok(leading_columns(&principal_images_streamed(&rows, &options)?, rows.rows(), dims))
}

/// Each pixel's colour in every image, as the basis represents it (dot products equal those
/// of the concatenated images): `pixels × (rank + 1)·3`.
fn pixel_colours(basis: &PrincipalImages) -> Array2<f32> {
    let weights = basis.block_weights();
    let blocks: Vec<ndarray::ArrayView1<f32>> =
        std::iter::once(basis.mean.view()).chain(basis.components.rows()).collect();
    let pixels = basis.mean.len() / 3;
    Array2::from_shape_fn((pixels, 3 * blocks.len()), |(p, j)| blocks[j / 3][3 * p + j % 3] * weights[j / 3])
}

/// Rows projected on their `dims` leading principal components (fewer if the rows span
/// fewer; the missing columns are 0).
fn project(rows: ArrayView2<f32>, dims: usize, seed: u64) -> Result<Array2<f32>> {
    let options = BasisOptions { energy: 1.0, max_rank: dims, seed, ..BasisOptions::default() };
    Ok(leading_columns(&principal_images(rows, &options)?, rows.nrows(), dims))
}

/// The first `dims` columns of the coordinates of `n` rows, zeros past those there are.
fn leading_columns(pca: &PrincipalImages, n: usize, dims: usize) -> Array2<f32> {
    let mut out = Array2::zeros((n, dims));
    let kept = pca.coords.ncols().min(dims);
    out.slice_mut(ndarray::s![.., ..kept]).assign(&pca.coords.slice(ndarray::s![.., ..kept]));
    out
}

/// Every pixel's `side × side` neighbourhood of `vectors`, concatenated row by row (see
/// [`neighbourhood_rows`]), as a stack of rows made on demand.
struct Neighbourhoods<'a> {
    vectors: ArrayView2<'a, f32>,
    size: (usize, usize),
    side: usize,
    wraps: bool,
}

impl RowSource for Neighbourhoods<'_> {
    fn rows(&self) -> usize {
        self.size.0 * self.size.1
    }

    fn cols(&self) -> usize {
        self.side * self.side * self.vectors.ncols()
    }

    fn block(&self, start: usize, len: usize) -> Array2<f32> {
        neighbourhood_rows(self.vectors, self.size, self.side, self.wraps, start..start + len)
    }
}

/// Every pixel's `side × side` neighbourhood of `vectors`, concatenated row by row.
#[cfg(test)]
fn neighbourhoods(vectors: ArrayView2<f32>, size: (usize, usize), side: usize, wraps: bool) -> Array2<f32> {
    neighbourhood_rows(vectors, size, side, wraps, 0..size.0 * size.1)
}

/// The neighbourhoods of the pixels `pixels` (row-major indices), one per row.
fn neighbourhood_rows(
    vectors: ArrayView2<f32>,
    (width, height): (usize, usize),
    side: usize,
    wraps: bool,
    pixels: std::ops::Range<usize>,
) -> Array2<f32> {
    let d = vectors.ncols();
    let r = (side / 2) as i64;
    let fold = |v: i64, n: usize| -> usize {
        let n = n as i64;
        if wraps {
            v.rem_euclid(n) as usize
        } else if n == 1 {
            0
        } else {
            let period = 2 * (n - 1);
            let m = v.rem_euclid(period);
            (if m < n { m } else { period - m }) as usize
        }
    };
    let (rows, cols) = (pixels.len(), side * side * d);
    let mut out = vec![0f32; rows * cols];
    out.par_chunks_mut(cols.max(1)).zip(pixels.into_par_iter()).for_each(|(row, p)| {
        let (x, y) = ((p % width) as i64, (p / width) as i64);
        for (k, (dy, dx)) in (-r..=r).flat_map(|dy| (-r..=r).map(move |dx| (dy, dx))).enumerate() {
            let q = fold(y + dy, height) * width + fold(x + dx, width);
            row[k * d..(k + 1) * d].iter_mut().zip(vectors.row(q)).for_each(|(o, &v)| *o = v);
        }
    });
    Array2::from_shape_vec((rows, cols), out).expect("the buffer holds rows × cols values")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::seeded::normal;

    #[test]
    fn projection_keeps_the_distances_of_low_rank_rows() {
        // 300 rows whose 40 values live on a 3-dimensional subspace (+ an offset).
        let latent = Array2::from_shape_fn((300, 3), |(i, k)| normal(1, i as i64, k as i64));
        let mixing = Array2::from_shape_fn((3, 40), |(k, j)| normal(2, k as i64, j as i64));
        let rows = latent.dot(&mixing) + 2.0;
        let vectors = project(rows.view(), 8, 0).unwrap();
        assert_eq!(vectors.dim(), (300, 8));
        for (a, b) in [(0, 1), (5, 200), (17, 299)] {
            let full = (&rows.row(a) - &rows.row(b)).mapv(|v| v * v).sum();
            let reduced = (&vectors.row(a) - &vectors.row(b)).mapv(|v| v * v).sum();
            assert!((full - reduced).abs() < 1e-3 * full, "{full} vs {reduced}");
        }
    }

    #[test]
    fn neighbourhoods_mirror_or_wrap_at_the_border() {
        // A 3×1 image of scalars 0, 1, 2.
        let v = Array2::from_shape_fn((3, 1), |(p, _)| p as f32);
        let mirrored = neighbourhoods(v.view(), (3, 1), 3, false);
        assert_eq!(mirrored.row(0).to_vec(), [1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0]);
        let wrapped = neighbourhoods(v.view(), (3, 1), 3, true);
        assert_eq!(wrapped.row(0).to_vec(), [2.0, 0.0, 1.0, 2.0, 0.0, 1.0, 2.0, 0.0, 1.0]);
    }

    #[test]
    fn streamed_vectors_equal_those_of_the_neighbourhoods_held_whole() {
        // 70 × 60 pixels: more rows than the exact limit, in three streamed blocks.
        let images = Array2::from_shape_fn((3, 70 * 60 * 3), |(a, i)| normal(5, a as i64, i as i64));
        let basis = principal_images(images.view(), &BasisOptions::default()).unwrap();
        for wraps in [false, true] {
            let streamed = appearance_vectors(&basis, (70, 60), 8, wraps, 4).unwrap();
            let colours = project(pixel_colours(&basis).view(), 8, 4).unwrap();
            let whole = project(neighbourhoods(colours.view(), (70, 60), NEIGHBOURHOOD, wraps).view(), 8, 4);
            let (a, b) = (streamed.mapv(f32::to_bits), whole.unwrap().mapv(f32::to_bits));
            assert!(a == b, "wraps {wraps}: the streamed vectors differ");
        }
    }

    #[test]
    fn a_flat_sample_gives_vanishing_vectors() {
        let images = Array2::from_elem((2, 6 * 5 * 3), 0.5f32);
        let basis = principal_images(images.view(), &BasisOptions::default()).unwrap();
        let vectors = appearance_vectors(&basis, (6, 5), 8, false, 0).unwrap();
        assert_eq!(vectors.dim(), (30, 8));
        assert!(vectors.iter().all(|&v| v.abs() < 1e-5), "{vectors:?}");
    }
}
