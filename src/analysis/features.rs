//! Per-pixel filter responses of basis images: the rows that textons are clustered from.

use super::basis::PrincipalImages;
use super::convolve::{BankConvolver, Padding};
use crate::Result;
use ndarray::{Array1, Array2, Array3, ArrayView1};
use rayon::prelude::*;

/// The responses of one interleaved RGB image to every filter, per colour channel:
/// `[channel][filter][pixel]` flattened to `(3 × filters) × pixels`.
pub fn rgb_responses(
    image: ArrayView1<f32>,
    width: usize,
    height: usize,
    convolver: &BankConvolver,
    padding: Padding,
) -> Result<Array2<f32>> {
    let filters = convolver.bank().len();
    let mut out = Array2::zeros((3 * filters, width * height));
    for c in 0..3 {
        let plane: Vec<f32> = image.iter().skip(c).step_by(3).copied().collect();
        let responses = convolver.filter(&plane, width, height, padding)?;
        for f in 0..filters {
            let row = responses.index_axis(ndarray::Axis(0), f);
            out.row_mut(c * filters + f).assign(&Array1::from_iter(row.iter().copied()));
        }
    }
    Ok(out)
}

/// The feature matrix (pixels × (r + 1)·3·filters) whose row dot products equal those of
/// the paper's concatenated responses over all images of the basis (see
/// [`PrincipalImages::block_weights`]).
pub fn texton_features(
    basis: &PrincipalImages,
    width: usize,
    height: usize,
    convolver: &BankConvolver,
    padding: Padding,
) -> Result<Array2<f32>> {
    let weights = basis.block_weights();
    let blocks: Vec<ArrayView1<f32>> =
        std::iter::once(basis.mean.view()).chain(basis.components.rows()).collect();
    let (filters, pixels) = (convolver.bank().len(), width * height);
    let mut features = Array2::zeros((pixels, blocks.len() * 3 * filters));
    // One colour channel of one block per task, a few tasks at a time (as many as threads),
    // each task's responses copied into its columns as soon as the group is done: what waits
    // is a few planes' responses (at 512², 50 MB each), never a second copy of the features.
    let tasks: Vec<(usize, usize)> = (0..blocks.len()).flat_map(|b| (0..3).map(move |c| (b, c))).collect();
    for group in tasks.chunks(rayon::current_num_threads().max(1)) {
        let responses: Vec<Array3<f32>> = group
            .par_iter()
            .map(|&(b, c)| {
                let plane: Vec<f32> = blocks[b].iter().skip(c).step_by(3).copied().collect();
                convolver.filter(&plane, width, height, padding)
            })
            .collect::<Result<_>>()?;
        let planes: Vec<(usize, f32, &[f32])> = group
            .iter()
            .zip(&responses)
            .map(|(&(b, c), r)| {
                let values =
                    r.as_slice().ok_or_else(|| crate::Error::internal("filter responses not contiguous"))?;
                Ok(((3 * b + c) * filters, weights[b], values))
            })
            .collect::<Result<_>>()?;
        scatter(&mut features, &planes, filters);
    }
    Ok(features)
}

/// Pixel rows per task when responses are copied into the features.
const SCATTER_ROWS: usize = 64;

/// Copies each plane's responses (`filters` rows of pixels), scaled by its weight, into
/// the features' columns from its first, pixel rows split over rayon tasks: the copy
/// transposes (a write per pixel and filter, each a row apart), and on one core the other
/// idled.
fn scatter(features: &mut Array2<f32>, planes: &[(usize, f32, &[f32])], filters: usize) {
    let (pixels, cols) = features.dim();
    let values = features.as_slice_mut().expect("the features are built row-major");
    values.par_chunks_mut(cols * SCATTER_ROWS).enumerate().for_each(|(task, rows)| {
        for (k, row) in rows.chunks_mut(cols).enumerate() {
            let p = task * SCATTER_ROWS + k;
            for &(first, w, responses) in planes {
                for f in 0..filters {
                    row[first + f] = responses[f * pixels + p] * w;
                }
            }
        }
    });
}
