//! `analyze`: a BTF stack in, the texton pyramid with its kNN lists out.

use super::basis::{principal_images_low_rank, LowRankStack, RowSource};
use super::convolve::{BankConvolver, Padding};
use super::gamma::distance_table;
use super::knn::{KnnParams, Level, PyramidSearch};
use super::memory;
pub use super::params::AnalysisParams;
use super::pyramid::{downsample, level_sizes};
use super::select::{representatives, representatives_from_basis, selection_basis_options};
use super::textons::{
    basis_options, filter_level, filter_level_images, finish_level, FilteredLevel, LevelTextons,
    TextonOptions,
};
use crate::btf::Btf;
use crate::progress::{Progress, Silent};
use crate::{Error, Result};
use ndarray::Array2;
use std::time::{Duration, Instant};

/// One analysed pyramid level.
#[derive(Clone, Debug)]
pub struct AnalysisLevel {
    /// Texton map, Γ, embedding and appearance vectors of the level.
    pub textons: LevelTextons,
    /// `[pixels][k]` single-level kNN lists, the pixel itself first.
    pub knn: Vec<u32>,
    /// `[pixels][k]` lists by two-level neighbourhoods (this level + the next coarser one);
    /// absent on the coarsest level.
    pub knn_two_level: Option<Vec<u32>>,
}

/// Wall time per stage, summed over levels (which may run side by side, so the stages may
/// add up to more than `total`).
#[derive(Clone, Copy, Debug, Default)]
pub struct Timings {
    /// Choosing the representative images.
    pub selection: Duration,
    /// Filtering the images (texton features and appearance vectors).
    pub filtering: Duration,
    /// Clustering the features into textons.
    pub kmeans: Duration,
    /// Forming Γ and its spectral embedding.
    pub gamma: Duration,
    /// Building the kNN lists.
    pub knn: Duration,
    /// The whole analysis, from start to end.
    pub total: Duration,
}

/// The result of [`analyze`].
#[derive(Clone, Debug)]
pub struct Analysis {
    /// The parameters the analysis ran with.
    pub params: AnalysisParams,
    /// Indices of the representative images, increasing.
    pub selected: Vec<usize>,
    /// Finest level first.
    pub levels: Vec<AnalysisLevel>,
    /// Wall time per stage.
    pub timings: Timings,
}

/// Analyses `btf`: representative images, then per level textons, Γ, embedding and kNN lists.
pub fn analyze(btf: &Btf, params: &AnalysisParams, progress: &dyn Progress) -> Result<Analysis> {
    let (width, height) = (btf.width(), btf.height());
    params.validate(width, height)?;
    let started = Instant::now();
    let mut timings = Timings::default();
    let padding = Padding::from_tileable(params.tileable);
    // The selection's convolver caches the kernels' spectra at the sample's size; dropped
    // with it, they are not held through the levels (each level's own are freed with it).
    let selected = representatives(
        &BtfRows(btf),
        (width, height),
        params.selected,
        &BankConvolver::new(params.filters.clone()),
        padding,
        params.seed,
        progress,
    )?;
    timings.selection = started.elapsed();
    let convolver = BankConvolver::new(params.filters.clone());

    let sizes = level_sizes(width, height, params.levels);
    let mut pyramid = vec![stack_rows(btf, &selected)];
    for l in 1..sizes.len() {
        pyramid.push(downsample_rows(&pyramid[l - 1], sizes[l - 1], params.tileable));
    }
    let rank = params.basis_rank.min(selected.len().saturating_sub(1));
    let beside = side_by_side(&sizes, rank, params);
    let levels = textons_per_level(sizes.len(), beside, progress, |l| {
        filter_level_images(pyramid[l].view(), sizes[l], &convolver, &texton_options(params, padding, l))
    })?;
    drop(pyramid);
    add_level_timings(&mut timings, &levels);

    let knn_started = Instant::now();
    let analysed = knn_lists(levels, params, progress);
    timings.knn = knn_started.elapsed();
    timings.total = started.elapsed();
    Ok(Analysis { params: params.clone(), selected, levels: analysed, timings })
}

/// Analyses a stack held as a product of low rank (the factors of a DFMF file, or a basis
/// streamed from images): the same stages as [`analyze`], with every image replaced by its
/// coordinates. The representative selection clusters the coordinates of all images
/// through the exact principal images of the whole stack; each level takes the principal
/// images of the selected images from q × q matrices and moves down the pyramid by
/// downsampling the q rows. Memory and time grow with texels × rank, not texels × images.
pub fn analyze_low_rank(
    stack: LowRankStack,
    (width, height): (usize, usize),
    params: &AnalysisParams,
    progress: &dyn Progress,
) -> Result<Analysis> {
    params.validate(width, height)?;
    if stack.rows.ncols() != width * height * 3 {
        return Err(Error::invalid(format!(
            "a low-rank stack of {} values per image is not {width}x{height} RGB",
            stack.rows.ncols()
        )));
    }
    let started = Instant::now();
    let mut timings = Timings::default();
    let padding = Padding::from_tileable(params.tileable);

    let selected = if stack.len() <= params.selected {
        (0..stack.len()).collect()
    } else {
        let basis = principal_images_low_rank(&stack, &selection_basis_options(params.seed))?;
        representatives_from_basis(
            &basis,
            (width, height),
            params.selected,
            &BankConvolver::new(params.filters.clone()),
            padding,
            params.seed,
            progress,
        )?
    };
    timings.selection = started.elapsed();
    let convolver = BankConvolver::new(params.filters.clone());

    let sizes = level_sizes(width, height, params.levels);
    let mut pyramid = vec![stack.select(&selected)];
    for l in 1..sizes.len() {
        let (pw, ph) = sizes[l - 1];
        pyramid.push(pyramid[l - 1].map_rows(|row| downsample(row, pw, ph, 3, params.tileable).0));
    }
    let rank = params.basis_rank.min(selected.len().saturating_sub(1)).min(pyramid[0].rows.nrows());
    let beside = side_by_side(&sizes, rank, params);
    let levels = textons_per_level(sizes.len(), beside, progress, |l| {
        let started = Instant::now();
        let options = texton_options(params, padding, l);
        let basis = principal_images_low_rank(&pyramid[l], &basis_options(&options))?;
        let basis_time = started.elapsed();
        let mut level = filter_level(basis, sizes[l], &convolver, &options)?;
        level.add_filtering(basis_time);
        Ok(level)
    })?;
    drop(pyramid);
    add_level_timings(&mut timings, &levels);

    let knn_started = Instant::now();
    let analysed = knn_lists(levels, params, progress);
    timings.knn = knn_started.elapsed();
    timings.total = started.elapsed();
    Ok(Analysis { params: params.clone(), selected, levels: analysed, timings })
}

/// Level `l`'s texton options under `params`: a quarter of the finer level's textons, and a
/// seed of its own.
fn texton_options(params: &AnalysisParams, padding: Padding, l: usize) -> TextonOptions {
    TextonOptions {
        textons: (params.textons >> (2 * l)).max(1),
        basis_rank: params.basis_rank,
        appearance_dims: params.appearance_dims,
        padding,
        seed: params.seed + l as u64,
    }
}

/// Whether the levels of `sizes` run side by side: where the memory they need together fits
/// the budget as it stands, and either stays below [`memory::BESIDE_FREELY`] or is no more
/// than the largest level needs alone (else one after the other, within the estimate
/// `analyze` checked before it started), so that the peak stays that of the levels in turn.
fn side_by_side(sizes: &[(usize, usize)], rank: usize, params: &AnalysisParams) -> bool {
    let (beside, in_turn) =
        (memory::levels_side_by_side(sizes, rank, params), memory::levels_in_turn(sizes, rank, params));
    beside <= in_turn.max(memory::BESIDE_FREELY) && memory::fits_now(beside)
}

/// The textons of `count` levels, finest first, each filtered by `filter(l)` and then
/// finished ([`finish_level`]). Each level is made from its own images alone, so the
/// coarser levels may run `beside` the finest: once the finest is filtered (its features
/// and the kernels' spectra, the largest part of its peak, are then made and the spectra
/// freed), the coarser levels (a third of its work between them, reporting to nobody) run
/// one after the other beside its clustering, appearance vectors and Γ, which report to
/// `progress`. The serial steps of one level (its eigendecompositions, k-means++ seeding,
/// Γ's embedding) left a core idle for about a fifth of a 64² × 6,561-image BTF's
/// analysis. Each level's result is the same to the bit whatever runs beside it.
fn textons_per_level(
    count: usize,
    beside: bool,
    progress: &dyn Progress,
    filter: impl Fn(usize) -> Result<FilteredLevel> + Sync,
) -> Result<Vec<LevelTextons>> {
    if !beside || count < 2 {
        return (0..count).map(|l| finish_level(filter(l)?, progress)).collect();
    }
    let finest = filter(0)?;
    let (finest, coarser) = rayon::join(
        || finish_level(finest, progress),
        || (1..count).map(|l| finish_level(filter(l)?, &Silent)).collect::<Result<Vec<_>>>(),
    );
    Ok(std::iter::once(finest?).chain(coarser?).collect())
}

/// Adds each level's stage times to `timings` (wall times of levels that ran side by side,
/// so their sum may exceed the whole analysis').
fn add_level_timings(timings: &mut Timings, levels: &[LevelTextons]) {
    for textons in levels {
        timings.filtering += textons.timings.filtering;
        timings.kmeans += textons.timings.kmeans;
        timings.gamma += textons.timings.gamma;
    }
}

/// The chosen images as rows of interleaved linear RGB.
fn stack_rows(btf: &Btf, indices: &[usize]) -> Array2<f32> {
    use rayon::prelude::*;
    let per_image = btf.width() * btf.height() * 3;
    let mut rows = vec![0f32; indices.len() * per_image];
    // The slice conversion runs the CPU's f16 instructions several values at a time; the
    // selection converts the whole stack once per pass of its basis.
    rows.par_chunks_mut(per_image.max(1))
        .zip(indices)
        .for_each(|(row, &i)| half::slice::HalfFloatSliceExt::convert_to_f32_slice(btf.image(i), row));
    Array2::from_shape_vec((indices.len(), per_image), rows).expect("the buffer holds images × values")
}

/// A stack's images as f32 rows, converted a block at a time.
struct BtfRows<'a>(&'a Btf);

impl RowSource for BtfRows<'_> {
    fn rows(&self) -> usize {
        self.0.len()
    }

    fn cols(&self) -> usize {
        self.0.width() * self.0.height() * 3
    }

    fn block(&self, start: usize, len: usize) -> Array2<f32> {
        stack_rows(self.0, &(start..start + len).collect::<Vec<_>>())
    }
}

fn downsample_rows(images: &Array2<f32>, (width, height): (usize, usize), tileable: bool) -> Array2<f32> {
    let rows: Vec<Vec<f32>> = images
        .rows()
        .into_iter()
        .map(|row| match row.as_slice() {
            Some(pixels) => downsample(pixels, width, height, 3, tileable).0,
            None => downsample(&row.to_vec(), width, height, 3, tileable).0,
        })
        .collect();
    let cols = rows.first().map_or(0, Vec::len);
    Array2::from_shape_vec((rows.len(), cols), rows.concat()).unwrap_or_else(|_| Array2::zeros((0, 0)))
}

fn knn_lists(
    levels: Vec<LevelTextons>,
    params: &AnalysisParams,
    progress: &dyn Progress,
) -> Vec<AnalysisLevel> {
    let tables: Vec<Vec<f32>> = levels.iter().map(|l| distance_table(&l.gamma)).collect();
    let pyramid: Vec<Level> = levels
        .iter()
        .zip(&tables)
        .map(|(l, t)| Level { map: &l.map, distances: t, textons: l.textons + 1 })
        .collect();
    let knn = KnnParams { k: params.k, neighborhood: params.neighborhood, tileable: params.tileable };
    progress.start("kNN lists", levels.len() as u64);
    let mut search = PyramidSearch::new(&pyramid, knn);
    let lists: Vec<(Vec<u32>, Option<Vec<u32>>)> = (0..levels.len())
        .map(|l| {
            let (single, two) = if l + 1 < levels.len() {
                let (single, two) = search.single_and_two_level(l);
                (single, Some(two))
            } else {
                (search.single_level(l), None)
            };
            progress.advance(1);
            (single, two)
        })
        .collect();
    progress.finish();
    levels
        .into_iter()
        .zip(lists)
        .map(|(textons, (knn, knn_two_level))| AnalysisLevel { textons, knn, knn_two_level })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The coarser levels run beside the finest give every level the bits it gets when the
    /// levels run in turn.
    #[test]
    fn levels_side_by_side_are_the_levels_in_turn() {
        let params = AnalysisParams { textons: 16, levels: 3, ..AnalysisParams::default() };
        let sizes = level_sizes(16, 16, 3);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut pyramid = vec![Array2::from_shape_fn((12, 16 * 16 * 3), |_| rng.random::<f32>())];
        for l in 1..sizes.len() {
            pyramid.push(downsample_rows(&pyramid[l - 1], sizes[l - 1], true));
        }
        let convolver = BankConvolver::new(params.filters.clone());
        let run = |beside| {
            textons_per_level(3, beside, &Silent, |l| {
                let options = texton_options(&params, Padding::Wrap, l);
                filter_level_images(pyramid[l].view(), sizes[l], &convolver, &options)
            })
            .unwrap()
        };
        let (beside, in_turn) = (run(true), run(false));
        assert_eq!((beside.len(), in_turn.len()), (3, 3));
        let bits = |a: &Array2<f32>| a.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        for (l, (a, b)) in beside.iter().zip(&in_turn).enumerate() {
            assert_eq!(a.map.labels, b.map.labels, "level {l}");
            assert_eq!(bits(&a.gamma), bits(&b.gamma), "level {l}");
            assert_eq!(bits(&a.appearance), bits(&b.appearance), "level {l}");
            assert_eq!(a.map.labels.len(), sizes[l].0 * sizes[l].1);
        }
    }
}
