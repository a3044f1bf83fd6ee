//! One level of the texton pyramid (Tong §4): 3D textons by k-means of the per-pixel
//! responses of the representative images, the 2D texton map, Γ and its embedding.

use super::appearance::appearance_vectors;
use super::basis::{principal_images, BasisOptions, PrincipalImages};
use super::convolve::{BankConvolver, Padding};
use super::features::texton_features;
use super::gamma::{gamma_with_default, spectral_embedding, DEFAULT_ENERGY};
use super::kmeans::{kmeans, KMeansOptions};
use super::knn::TextonMap;
use super::reduce::{full_centres, reduce, REDUCE_ABOVE};
use crate::progress::Progress;
use crate::{Error, Result};
use ndarray::{Array2, ArrayView2};
use std::time::{Duration, Instant};

/// The textons of one pyramid level. Texton `textons` (the last row of Γ) is the default
/// texton: the mean of all appearance vectors.
#[derive(Clone, Debug)]
pub struct LevelTextons {
    /// The level's texton map: a label per pixel.
    pub map: TextonMap,
    /// (textons + 1)², dot products of the appearance vectors.
    pub gamma: Array2<f32>,
    /// (textons + 1) × d: rows whose distances are the texton distances.
    pub embedding: Array2<f32>,
    /// pixels × dims: every pixel's appearance vector (see [`super::appearance`]).
    pub appearance: Array2<f32>,
    /// Number of textons, not counting the default texton.
    pub textons: usize,
    /// Principal images the responses were computed from, and the variance they hold.
    pub basis_rank: usize,
    /// Share (0–1) of the centred images' energy those principal images hold.
    pub basis_energy: f64,
    /// Lloyd iterations the clustering ran.
    pub kmeans_iterations: usize,
    /// Share of the centred features' energy the clustering saw: 1 unless the level was
    /// clustered in its leading feature subspace (see [`super::reduce`]).
    pub feature_energy: f64,
    /// Time spent filtering, clustering and forming Γ.
    pub timings: StageTimes,
}

/// Wall time per stage.
#[derive(Clone, Copy, Debug, Default)]
pub struct StageTimes {
    /// Computing the filter responses and appearance vectors.
    pub filtering: Duration,
    /// Clustering the features into textons.
    pub kmeans: Duration,
    /// Forming Γ and its spectral embedding.
    pub gamma: Duration,
}

/// How one level's textons are made.
#[derive(Clone, Copy, Debug)]
pub struct TextonOptions {
    /// Textons wanted (capped by the pixel count).
    pub textons: usize,
    /// Most principal images filtered (see [`super::basis`]).
    pub basis_rank: usize,
    /// Dimensions of the per-pixel appearance vectors.
    pub appearance_dims: usize,
    /// How the filters treat the sample's border.
    pub padding: Padding,
    /// Seed of every random choice of the level (basis, appearance vectors, reduction,
    /// k-means).
    pub seed: u64,
}

/// The basis options a level uses: at most `basis_rank` components, the level's seed.
pub fn basis_options(options: &TextonOptions) -> BasisOptions {
    BasisOptions { max_rank: options.basis_rank, seed: options.seed, ..BasisOptions::default() }
}

/// Textons of `images` (one interleaved RGB image per row, `width × height`).
pub fn level_textons(
    images: ArrayView2<f32>,
    size: (usize, usize),
    convolver: &BankConvolver,
    options: &TextonOptions,
    progress: &dyn Progress,
) -> Result<LevelTextons> {
    finish_level(filter_level_images(images, size, convolver, options)?, progress)
}

/// A level half made: its basis and its texton features, which [`finish_level`] clusters.
/// The features are the level's largest array (at 512², 151 MB for a photo): a caller that
/// runs levels side by side can start the others once this one's filtering, the other
/// large part of its peak, is done.
pub struct FilteredLevel {
    basis: PrincipalImages,
    features: Array2<f32>,
    size: (usize, usize),
    options: TextonOptions,
    /// The basis and the filtering so far.
    filtering: Duration,
}

/// [`filter_level`] of the principal images of `images` (one interleaved RGB image per
/// row), the basis counted in its filtering time.
pub fn filter_level_images(
    images: ArrayView2<f32>,
    size: (usize, usize),
    convolver: &BankConvolver,
    options: &TextonOptions,
) -> Result<FilteredLevel> {
    let started = Instant::now();
    let basis = principal_images(images, &basis_options(options))?;
    let mut level = filter_level(basis, size, convolver, options)?;
    level.filtering = started.elapsed();
    Ok(level)
}

/// The texton features of the images whose principal images `basis` holds (the level's
/// images themselves are not needed: filtering is linear, see [`super::basis`]).
pub fn filter_level(
    basis: PrincipalImages,
    (width, height): (usize, usize),
    convolver: &BankConvolver,
    options: &TextonOptions,
) -> Result<FilteredLevel> {
    let started = Instant::now();
    let features = texton_features(&basis, width, height, convolver, options.padding)?;
    Ok(FilteredLevel {
        basis,
        features,
        size: (width, height),
        options: *options,
        filtering: started.elapsed(),
    })
}

impl FilteredLevel {
    /// Adds `time` to the level's filtering time (e.g. a basis made before it).
    pub fn add_filtering(&mut self, time: Duration) {
        self.filtering += time;
    }
}

/// The textons of a filtered level: its features clustered, then its appearance vectors,
/// Γ and the embedding.
pub fn finish_level(level: FilteredLevel, progress: &dyn Progress) -> Result<LevelTextons> {
    let FilteredLevel { basis, features, size: (width, height), options, filtering } = level;
    let mut timings = StageTimes { filtering, ..StageTimes::default() };
    let started = Instant::now();
    let k = options.textons.min(width * height);
    let kmeans_options = KMeansOptions { k, seed: options.seed, ..KMeansOptions::default() };
    let (clustering, feature_energy) = if features.len() > REDUCE_ABOVE {
        let reduced = reduce(features.view(), options.seed);
        let mut clustering = kmeans(reduced.coords.view(), &kmeans_options, progress)?;
        drop(reduced.coords);
        clustering.centres = full_centres(features.view(), &clustering.labels, clustering.centres.nrows());
        (clustering, reduced.energy)
    } else {
        (kmeans(features.view(), &kmeans_options, progress)?, 1.0)
    };
    drop(features);
    timings.kmeans = started.elapsed();
    // Made once the features are gone, so the two never take memory at the same time.
    let started = Instant::now();
    let wraps = matches!(options.padding, Padding::Wrap);
    let appearance =
        appearance_vectors(&basis, (width, height), options.appearance_dims, wraps, options.seed)?;
    timings.filtering += started.elapsed();
    let textons = clustering.centres.nrows();
    if textons >= u16::MAX as usize {
        return Err(Error::invalid(format!("{textons} textons do not fit the u16 texton map")));
    }
    let labels = clustering.labels.iter().map(|&l| l as u16).collect();

    let started = Instant::now();
    let gamma = gamma_with_default(&clustering.centres);
    let embedding = spectral_embedding(&gamma, DEFAULT_ENERGY)?;
    timings.gamma = started.elapsed();
    Ok(LevelTextons {
        map: TextonMap { width, height, labels },
        gamma,
        embedding,
        appearance,
        textons,
        basis_rank: basis.components.nrows(),
        basis_energy: basis.energy,
        kmeans_iterations: clustering.iterations,
        feature_energy,
        timings,
    })
}
