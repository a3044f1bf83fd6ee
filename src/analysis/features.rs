//! Per-pixel filter responses of basis images: the rows that textons are clustered from.

use super::basis::PrincipalImages;
use super::convolve::{BankConvolver, Padding};
use crate::Result;
use ndarray::{Array1, Array2, ArrayView1};
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
    let per_block = 3 * convolver.bank().len();
    let mut features = Array2::zeros((width * height, blocks.len() * per_block));
    // A few blocks at a time (as many as threads), so that the responses waiting to be
    // copied stay a few blocks' worth rather than a second copy of the features.
    let group = rayon::current_num_threads().max(1);
    for first in (0..blocks.len()).step_by(group) {
        let last = (first + group).min(blocks.len());
        let responses: Vec<Array2<f32>> = blocks[first..last]
            .par_iter()
            .map(|image| rgb_responses(*image, width, height, convolver, padding))
            .collect::<Result<_>>()?;
        for (b, r) in (first..last).zip(&responses) {
            let w = weights[b];
            features
                .slice_mut(ndarray::s![.., b * per_block..(b + 1) * per_block])
                .zip_mut_with(&r.t(), |dst, &src| *dst = src * w);
        }
    }
    Ok(features)
}
