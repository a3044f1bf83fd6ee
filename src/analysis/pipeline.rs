//! `analyze`: a BTF stack in, the texton pyramid with its kNN lists out.

use super::basis::{principal_images_low_rank, LowRankStack, RowSource};
use super::convolve::{BankConvolver, Padding};
use super::filters::FilterBank;
use super::gamma::distance_table;
use super::knn::{KnnParams, Level, PyramidSearch};
use super::pyramid::{downsample, level_sizes};
use super::select::{representatives, representatives_from_basis, selection_basis_options};
use super::textons::{basis_options, level_textons, level_textons_from_basis, LevelTextons, TextonOptions};
use crate::btf::Btf;
use crate::progress::Progress;
use crate::{Error, Param, Remedy, Result};
use ndarray::Array2;
use std::time::{Duration, Instant};

/// Parameters of an analysis; defaults follow Tong et al. 2002.
#[derive(Clone, Debug)]
pub struct AnalysisParams {
    /// Textons at the finest level (default 400, the paper's n_t; capped by the pixel count).
    /// Each coarser level gets a quarter as many.
    pub textons: usize,
    /// Representative images (default 400, the paper's n_s; capped by the image count).
    pub selected: usize,
    /// Pyramid levels (default 3).
    pub levels: usize,
    /// Length of every kNN list, the pixel itself included (default 11; 1 = Ashikhmin).
    pub k: usize,
    /// Side of the square neighbourhood of the kNN search, odd (default 5).
    pub neighborhood: usize,
    /// Whether the sample wraps around: filters and neighbourhoods wrap (default false).
    pub tileable: bool,
    /// Most principal images filtered per level (default 32; see `analysis::basis`).
    pub basis_rank: usize,
    /// Dimensions of the per-pixel appearance vectors (default 8; see `analysis::appearance`).
    pub appearance_dims: usize,
    /// Seed of every random choice (default 0).
    pub seed: u64,
    /// The filter bank (default Leung–Malik 48, `filters/lm48.toml`).
    pub filters: FilterBank,
}

impl Default for AnalysisParams {
    fn default() -> Self {
        AnalysisParams {
            textons: 400,
            selected: 400,
            levels: 3,
            k: 11,
            neighborhood: 5,
            tileable: false,
            basis_rank: 32,
            appearance_dims: super::appearance::DEFAULT_DIMS,
            seed: 0,
            filters: FilterBank::lm48(),
        }
    }
}

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

/// Wall time per stage, summed over levels.
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

impl AnalysisParams {
    /// Checks every parameter against the sample size; errors name the [`Param`] at fault.
    pub fn validate(&self, width: usize, height: usize) -> Result<()> {
        let positive = [
            (Param::Textons, self.textons),
            (Param::SelectedImages, self.selected),
            (Param::Levels, self.levels),
            (Param::K, self.k),
            (Param::BasisRank, self.basis_rank),
            (Param::AppearanceDims, self.appearance_dims),
        ];
        for (param, value) in positive {
            if value == 0 {
                return Err(Error::out_of_range(param, value, "must be at least 1"));
            }
        }
        let n = self.neighborhood;
        if n < 3 || n % 2 == 0 {
            return Err(Error::out_of_range(Param::Neighbourhood, n, "must be odd and at least 3"));
        }
        let need = self.neighborhood + 4;
        let sizes = level_sizes(width, height, self.levels);
        let (w, h) = sizes[sizes.len() - 1];
        if w.min(h) < need {
            let fit = (1..=self.levels)
                .take_while(|&l| {
                    let (w, h) = level_sizes(width, height, l)[l - 1];
                    w.min(h) >= need
                })
                .count();
            if fit == 0 {
                return Err(Error::out_of_range(
                    Param::Neighbourhood,
                    n,
                    format!(
                        "the sample is {width}x{height} pixels, but a {n}x{n} neighbourhood search needs at least {need}x{need}; analyse a larger sample or use a smaller neighbourhood"
                    ),
                ));
            }
            return Err(Error::OutOfRange {
                param: Param::Levels,
                value: self.levels.to_string(),
                message: format!(
                    "the coarsest level would be {w}x{h} pixels, but a {n}x{n} neighbourhood search needs at least {need}x{need}"
                ),
                remedy: Some(Remedy::FewerLevels(fit)),
            });
        }
        Ok(())
    }
}

/// Analyses `btf`: representative images, then per level textons, Γ, embedding and kNN lists.
pub fn analyze(btf: &Btf, params: &AnalysisParams, progress: &dyn Progress) -> Result<Analysis> {
    let (width, height) = (btf.width(), btf.height());
    params.validate(width, height)?;
    let started = Instant::now();
    let mut timings = Timings::default();
    let convolver = BankConvolver::new(params.filters.clone());
    let padding = Padding::from_tileable(params.tileable);

    let selected = representatives(
        &BtfRows(btf),
        (width, height),
        params.selected,
        &convolver,
        padding,
        params.seed,
        progress,
    )?;
    timings.selection = started.elapsed();

    let mut images = stack_rows(btf, &selected);
    let mut levels = Vec::with_capacity(params.levels);
    let sizes = level_sizes(width, height, params.levels);
    for (l, &(w, h)) in sizes.iter().enumerate() {
        if l > 0 {
            images = downsample_rows(&images, sizes[l - 1], params.tileable);
        }
        let options = TextonOptions {
            textons: (params.textons >> (2 * l)).max(1),
            basis_rank: params.basis_rank,
            appearance_dims: params.appearance_dims,
            padding,
            seed: params.seed + l as u64,
        };
        let textons = level_textons(images.view(), (w, h), &convolver, &options, progress)?;
        timings.filtering += textons.timings.filtering;
        timings.kmeans += textons.timings.kmeans;
        timings.gamma += textons.timings.gamma;
        levels.push(textons);
    }

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
    let convolver = BankConvolver::new(params.filters.clone());
    let padding = Padding::from_tileable(params.tileable);

    let selected = if stack.len() <= params.selected {
        (0..stack.len()).collect()
    } else {
        let basis = principal_images_low_rank(&stack, &selection_basis_options(params.seed))?;
        representatives_from_basis(
            &basis,
            (width, height),
            params.selected,
            &convolver,
            padding,
            params.seed,
            progress,
        )?
    };
    timings.selection = started.elapsed();

    let mut images = stack.select(&selected);
    let mut levels = Vec::with_capacity(params.levels);
    let sizes = level_sizes(width, height, params.levels);
    for (l, &(w, h)) in sizes.iter().enumerate() {
        let level_started = Instant::now();
        if l > 0 {
            let (pw, ph) = sizes[l - 1];
            images = images.map_rows(|row| downsample(row, pw, ph, 3, params.tileable).0);
        }
        let options = TextonOptions {
            textons: (params.textons >> (2 * l)).max(1),
            basis_rank: params.basis_rank,
            appearance_dims: params.appearance_dims,
            padding,
            seed: params.seed + l as u64,
        };
        let basis = principal_images_low_rank(&images, &basis_options(&options))?;
        let basis_time = level_started.elapsed();
        let mut textons = level_textons_from_basis(&basis, (w, h), &convolver, &options, progress)?;
        drop(basis);
        textons.timings.filtering += basis_time;
        timings.filtering += textons.timings.filtering;
        timings.kmeans += textons.timings.kmeans;
        timings.gamma += textons.timings.gamma;
        levels.push(textons);
    }
    drop(images);

    let knn_started = Instant::now();
    let analysed = knn_lists(levels, params, progress);
    timings.knn = knn_started.elapsed();
    timings.total = started.elapsed();
    Ok(Analysis { params: params.clone(), selected, levels: analysed, timings })
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
