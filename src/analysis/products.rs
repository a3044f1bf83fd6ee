//! Matrix products split over rayon tasks along a dimension they do not sum over, so that
//! every element is computed by one GEMM call in the same order as without the split: the
//! same bits at any thread count. ndarray's products run on the calling thread only (its
//! own thread pool would compete with rayon's for the same cores).

use ndarray::{concatenate, Array2, ArrayView2, ArrayViewMut2, Axis};
use rayon::prelude::*;

/// `a · b` with `a`'s rows split into tasks of `rows` rows.
pub fn rows_in_parallel(a: ArrayView2<f32>, b: ArrayView2<f32>, rows: usize) -> Array2<f32> {
    split_product(a.view(), b.view(), Axis(0), rows)
}

/// `a · b` with `b`'s columns split into tasks of `columns` columns.
pub fn columns_in_parallel(a: ArrayView2<f32>, b: ArrayView2<f32>, columns: usize) -> Array2<f32> {
    split_product(a.view(), b.view(), Axis(1), columns)
}

/// `a · b` split along the product's `axis` (0: `a`'s rows, 1: `b`'s columns).
fn split_product<'a>(a: ArrayView2<'a, f32>, b: ArrayView2<'a, f32>, axis: Axis, size: usize) -> Array2<f32> {
    let split = if axis == Axis(0) { a } else { b };
    let parts: Vec<ArrayView2<f32>> = split.axis_chunks_iter(axis, size.max(1)).collect();
    let product = |part: ArrayView2<f32>| if axis == Axis(0) { part.dot(&b) } else { a.dot(&part) };
    let blocks: Vec<Array2<f32>> = parts.into_par_iter().map(product).collect();
    let views: Vec<ArrayView2<f32>> = blocks.iter().map(|m| m.view()).collect();
    concatenate(axis, &views).unwrap_or_else(|_| a.dot(&b))
}

/// `c ← a · b + beta · c`, with `c` (and `a`) split by rows into tasks of `rows` rows.
pub fn accumulate_by_rows(
    a: ArrayView2<f32>,
    b: ArrayView2<f32>,
    beta: f32,
    mut c: ArrayViewMut2<f32>,
    rows: usize,
) {
    let parts: Vec<_> =
        a.axis_chunks_iter(Axis(0), rows.max(1)).zip(c.axis_chunks_iter_mut(Axis(0), rows.max(1))).collect();
    parts.into_par_iter().for_each(|(a, mut c)| ndarray::linalg::general_mat_mul(1.0, &a, &b, beta, &mut c));
}

/// `c ← a · b + beta · c`, with `c` (and `b`) split by columns into tasks of `columns`.
pub fn accumulate_by_columns(
    a: ArrayView2<f32>,
    b: ArrayView2<f32>,
    beta: f32,
    mut c: ArrayViewMut2<f32>,
    columns: usize,
) {
    let parts: Vec<_> = b
        .axis_chunks_iter(Axis(1), columns.max(1))
        .zip(c.axis_chunks_iter_mut(Axis(1), columns.max(1)))
        .collect();
    parts.into_par_iter().for_each(|(b, mut c)| ndarray::linalg::general_mat_mul(1.0, &a, &b, beta, &mut c));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::seeded::normal;

    fn random(rows: usize, cols: usize, seed: u64) -> Array2<f32> {
        Array2::from_shape_fn((rows, cols), |(i, j)| normal(seed, i as i64, j as i64))
    }

    fn bits(m: &Array2<f32>) -> Vec<u32> {
        m.iter().map(|v| v.to_bits()).collect()
    }

    #[test]
    fn split_products_have_the_bits_of_one_product() {
        let (a, b) = (random(300, 257, 1), random(257, 70, 2));
        let whole = a.dot(&b);
        for split in [1, 7, 64, 300, 1000] {
            assert_eq!(bits(&rows_in_parallel(a.view(), b.view(), split)), bits(&whole), "rows {split}");
            assert_eq!(
                bits(&columns_in_parallel(a.view(), b.view(), split)),
                bits(&whole),
                "columns {split}"
            );
        }
    }

    #[test]
    fn split_accumulations_have_the_bits_of_one_accumulation() {
        let (a, b, start) = (random(300, 257, 3), random(257, 70, 4), random(300, 70, 5));
        let mut whole = start.clone();
        ndarray::linalg::general_mat_mul(1.0, &a, &b, 1.0, &mut whole);
        for split in [1, 9, 128, 300] {
            let (mut by_rows, mut by_columns) = (start.clone(), start.clone());
            accumulate_by_rows(a.view(), b.view(), 1.0, by_rows.view_mut(), split);
            accumulate_by_columns(a.view(), b.view(), 1.0, by_columns.view_mut(), split);
            assert_eq!(bits(&by_rows), bits(&whole), "rows {split}");
            assert_eq!(bits(&by_columns), bits(&whole), "columns {split}");
        }
    }
}
