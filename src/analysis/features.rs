//! Per-pixel filter responses of basis images: the rows that textons are clustered from.

use super::basis::PrincipalImages;
use super::convolve::{BankConvolver, ImageSpectrum, Padding};
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
    let (filters, pixels) = (convolver.bank().len(), width * height);
    let mut features = Array2::zeros((pixels, blocks.len() * 3 * filters));
    let bank = convolver.sized(width, height)?;
    let planes: Vec<(usize, usize)> = (0..blocks.len()).flat_map(|b| (0..3).map(move |c| (b, c))).collect();
    let threads = rayon::current_num_threads().max(1);
    // One colour channel of one block per plane. Where there are more planes than filters
    // (a BTF's basis), the kernels' spectra are made once and held, and the planes
    // transformed a few at a time (as many as threads); else (a photograph's three planes)
    // every plane's spectrum is held and the kernels' are made a run at a time. Either way
    // each is transformed once, and of the two kinds of spectra only the fewer are held.
    let held = match planes.len() > filters {
        true => Some(bank.kernels(0..filters)?),
        false => None,
    };
    let group = if held.is_some() { threads } else { planes.len() };
    // The responses of a group's planes to a run of filters are copied into their columns
    // as soon as they are made: what waits is about `WAITING_VALUES` responses, never a
    // second copy of the features nor a plane's whole bank (at 512², 50 MB per plane).
    for group in planes.chunks(group) {
        let spectra: Vec<ImageSpectrum> = group
            .par_iter()
            .map(|&(b, c)| {
                let plane: Vec<f32> = blocks[b].iter().skip(c).step_by(3).copied().collect();
                bank.spectrum(&plane, padding)
            })
            .collect::<Result<_>>()?;
        let run = filters_per_run(WAITING_VALUES / (group.len() * pixels).max(1), threads, filters);
        let mut responses = vec![0f32; group.len() * run * pixels];
        for first in (0..filters).step_by(run) {
            let n = run.min(filters - first);
            let kernels = match &held {
                Some(all) => all.slice(first..first + n),
                None => bank.kernels(first..first + n)?,
            };
            let used = &mut responses[..group.len() * n * pixels];
            used.par_chunks_mut(n * pixels)
                .zip(&spectra)
                .try_for_each(|(out, spectrum)| bank.respond_many(spectrum, &kernels, out))?;
            let made: Vec<(usize, f32, &[f32])> = group
                .iter()
                .zip(used.chunks(n * pixels))
                .map(|(&(b, c), values)| ((3 * b + c) * filters + first, weights[b], values))
                .collect();
            scatter(&mut features, &made, n);
        }
    }
    Ok(features)
}

/// Filters per run when `fit` fit the responses waiting: at least one, at most `filters`,
/// and a multiple of the thread count where that fits, so that a run's kernels, made in
/// parallel, keep every thread busy.
fn filters_per_run(fit: usize, threads: usize, filters: usize) -> usize {
    let run = if fit >= threads { fit / threads * threads } else { fit };
    run.clamp(1, filters.max(1))
}

/// Filter responses made before they are copied into the features (16 MiB of f32): at 512²
/// sixteen planes, enough filters to keep every thread busy.
pub const WAITING_VALUES: usize = 1 << 22;

/// Pixel rows per task when responses are copied into the features.
const SCATTER_ROWS: usize = 64;

/// Copies each plane's responses (`filters` rows of pixels), scaled by its weight, into
/// `filters` features' columns from its first, pixel rows split over rayon tasks: the copy
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::basis::{principal_images, BasisOptions};
    use crate::analysis::filters::FilterBank;
    use crate::seeded::normal;

    /// The features of a basis with fewer planes than filters (the kernels' spectra made a
    /// run at a time) and with more (held whole) are, to the bit, each plane's whole-bank
    /// responses (as `BankConvolver::filter` gives them) times the block's weight.
    #[test]
    fn features_are_the_weighted_responses_of_every_plane() {
        let (width, height) = (23, 17);
        // Two convolvers: the features' own spectra are made, not the reference's cached ones.
        let (convolver, reference) =
            (BankConvolver::new(FilterBank::lm48()), BankConvolver::new(FilterBank::lm48()));
        for images in [1, 3, 40] {
            let stack =
                Array2::from_shape_fn((images, width * height * 3), |(a, i)| normal(7, a as i64, i as i64));
            let basis = principal_images(stack.view(), &BasisOptions::default()).unwrap();
            let features = texton_features(&basis, width, height, &convolver, Padding::Mirror).unwrap();
            let weights = basis.block_weights();
            let blocks: Vec<ArrayView1<f32>> =
                std::iter::once(basis.mean.view()).chain(basis.components.rows()).collect();
            assert_eq!(features.dim(), (width * height, blocks.len() * 3 * 48), "{images} images");
            for (b, block) in blocks.iter().enumerate() {
                let responses =
                    rgb_responses(block.view(), width, height, &reference, Padding::Mirror).unwrap();
                for (j, row) in responses.rows().into_iter().enumerate() {
                    let column = features.column(b * 3 * 48 + j);
                    let same = row.iter().zip(column).all(|(r, f)| (r * weights[b]).to_bits() == f.to_bits());
                    assert!(same, "{images} images: block {b}, channel × filter {j}");
                }
            }
        }
    }
}
