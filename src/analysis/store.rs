//! The analysis directory: `analysis.json`, `.npy` arrays and PNG previews, written
//! atomically. Everything later stages need is here, sample images included.
//!
//! | file | dtype | shape |
//! |---|---|---|
//! | `images.npy` | f16 | [n, h, w, 3] linear RGB of every image |
//! | `directions.npy` | f32 | [n, 4]: θ_light, φ_light, θ_view, φ_view in degrees |
//! | `level{L}_textons.npy` | u16 | [h_L, w_L] texton map |
//! | `level{L}_gamma.npy` | f32 | [t+1, t+1] Γ, default texton last |
//! | `level{L}_embedding.npy` | f32 | [t+1, d] spectral embedding |
//! | `level{L}_knn.npy` | u32 | [h_L, w_L, k] kNN lists (pixel index y·w+x, itself first) |
//! | `level{L}_knn2.npy` | u32 | [h_L, w_L, k] two-level-neighbourhood lists (not on the coarsest level) |
//! | `level{L}_appearance.npy` | f32 | [h_L, w_L, d] per-pixel appearance vectors |
//!
//! An analysis of a factorized `.btf` file or of a streamed basis (see
//! [`super::input`]) stores its sample as factors instead of `images.npy` (whose 400×400 ×
//! 22,801 images would be 20 GiB); `analysis.json` then has a `sample` entry with the
//! colour model, and a `basis` entry saying how the analysis saw the images:
//!
//! | file | dtype | shape |
//! |---|---|---|
//! | `sample_image_factors.npy` | f32 | [3, n, K] per channel, zero-padded to the largest K |
//! | `sample_texel_factors.npy` | f32 | [3, h, w, K] |
//! | `sample_scale.npy` | f32 | \[n\] per-image scale after decoding |

use super::npy;
use super::pipeline::Analysis;
use crate::btf::colour::ColourModel;
use crate::btf::factored::FactoredStack;
use crate::btf::image_io::linear_to_srgb8;
use crate::btf::Btf;
use crate::fsutil::{write_file_atomic, StagedDir};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The manifest file of an analysis directory.
pub const MANIFEST: &str = "analysis.json";

/// `analysis.json`: what was analysed, how, and what came out.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Manifest {
    /// Always "btfsynth-analysis".
    pub format: String,
    /// Version of this layout; 1 so far.
    pub version: u32,
    /// The stack that was analysed.
    pub source: Source,
    /// The analysis parameters as run.
    pub params: Params,
    /// The filter bank: name and one entry per filter.
    pub filters: serde_json::Value,
    /// Indices of the representative images.
    pub selected: Vec<usize>,
    /// Number of images in the sample.
    pub images: usize,
    /// Width of the sample in texels (after the crop).
    pub width: usize,
    /// Height of the sample in texels (after the crop).
    pub height: usize,
    /// Length of every kNN list, the pixel itself included.
    pub k: usize,
    /// Per pyramid level, finest first: sizes and file names.
    pub levels: Vec<LevelInfo>,
    /// Material maps stored beside the sample (see [`crate::maps`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub maps: Vec<crate::maps::MapInfo>,
    /// The sample as factors (absent: `images.npy` holds the images).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample: Option<SampleInfo>,
    /// How the analysis saw the images (absent: decoded images).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub basis: Option<super::input::BasisInfo>,
}

/// A sample stored as factors (see the module notes): channel c of image i at texel p is
/// `Σₖ image[c][i][k] · texel[c][p][k]`, decoded by the colour model, then exp(x) − ε when
/// `log_encoded`, then times the image's scale.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SampleInfo {
    /// Always "factors".
    pub kind: String,
    /// Components per channel.
    pub components: [usize; 3],
    /// The DFMF colour model number (0 RGB, 11 log-Y U/Y V/Y, …).
    pub colour_model: i32,
    /// The PCA colour model's mean and transform (model 3 only).
    #[serde(default)]
    pub colour_mean: [f32; 3],
    /// The PCA colour model's transform (model 3 only).
    #[serde(default)]
    pub colour_transform: [[f32; 3]; 3],
    /// Whether the decoded values are log(x + ε), undone as exp(x) − ε.
    pub log_encoded: bool,
    /// File name of the image factors, relative to the analysis directory.
    pub image_factors: String,
    /// File name of the texel factors, relative to the analysis directory.
    pub texel_factors: String,
    /// File name of the per-image scales, relative to the analysis directory.
    pub scale: String,
}

/// Where the stack came from.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Source {
    /// The path the stack was read from, as given (`analyze`'s input).
    pub path: String,
    /// FNV-1a 64 of the pixels (f16 bits) and directions: detects a changed stack.
    pub fingerprint: String,
    /// The rectangle of the stack that was analysed, `[x, y, width, height]` in texels
    /// (`None`: all of it).
    pub crop: Option<[u32; 4]>,
}

/// The parameters as run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Params {
    /// Textons asked for at the finest level (see [`super::pipeline::AnalysisParams`]).
    pub textons: usize,
    /// Representative images asked for.
    pub selected: usize,
    /// Pyramid levels.
    pub levels: usize,
    /// Length of every kNN list, the pixel itself included.
    pub k: usize,
    /// Side in texels of the square neighbourhood of the kNN search, odd.
    pub neighborhood: usize,
    /// Whether the sample was analysed as wrapping around.
    pub tileable: bool,
    /// Most principal images filtered per level.
    pub basis_rank: usize,
    /// Absent in analyses written before appearance vectors existed.
    #[serde(default)]
    pub appearance_dims: usize,
    /// Seed of every random choice.
    pub seed: u64,
}

fn one() -> f64 {
    1.0
}

fn is_one(v: &f64) -> bool {
    *v == 1.0
}

/// One level's sizes and files.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LevelInfo {
    /// Width of the level in texels.
    pub width: usize,
    /// Height of the level in texels.
    pub height: usize,
    /// Textons, not counting the default texton (which is index `textons`).
    pub textons: usize,
    /// Columns of the level's spectral embedding.
    pub embedding_dims: usize,
    /// Principal images the level's filter responses were computed from.
    pub basis_rank: usize,
    /// Share (0–1) of the level's centred image energy those principal images hold.
    pub basis_energy: f64,
    /// Lloyd iterations the level's clustering ran.
    pub kmeans_iterations: usize,
    /// Share of the features' energy the clustering saw (absent: 1, the full features;
    /// see [`super::reduce`]).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub feature_energy: f64,
    /// The level's array files.
    pub files: LevelFiles,
}

/// File names of one level's arrays, relative to the analysis directory.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LevelFiles {
    /// `level{L}_textons.npy`: the texton map.
    pub textons: String,
    /// `level{L}_gamma.npy`: Γ, default texton last.
    pub gamma: String,
    /// `level{L}_embedding.npy`: the spectral embedding of Γ.
    pub embedding: String,
    /// `level{L}_knn.npy`: the single-level kNN lists.
    pub knn: String,
    /// `level{L}_knn2.npy`: the two-level kNN lists (`None` on the coarsest level).
    pub knn_two_level: Option<String>,
    /// Absent in analyses written before appearance vectors existed.
    #[serde(default)]
    pub appearance: Option<String>,
}

/// Writes `analysis` of `btf` (read from `source_path` with `crop`) into `dir`.
pub fn write(
    analysis: &Analysis,
    btf: &Btf,
    source_path: &Path,
    crop: Option<[u32; 4]>,
    dir: &Path,
    overwrite: bool,
) -> Result<PathBuf> {
    write_with_maps(analysis, btf, (source_path, crop), &[], dir, overwrite)
}

/// [`write()`], with material maps (already cropped like the sample) stored beside it.
pub fn write_with_maps(
    analysis: &Analysis,
    btf: &Btf,
    source: (&Path, Option<[u32; 4]>),
    maps: &[crate::maps::MaterialMap],
    dir: &Path,
    overwrite: bool,
) -> Result<PathBuf> {
    write_sample(analysis, Stored::Images(btf), None, source, maps, dir, overwrite)
}

/// Writes the result of [`super::input::run`]: the decoded images' analysis as
/// [`write_with_maps`] does, an analysis from factors or a streamed basis with its sample
/// as factors.
pub fn write_analysed(
    analysed: &super::input::Analysed,
    input: &super::input::Input,
    source: (&Path, Option<[u32; 4]>),
    maps: &[crate::maps::MaterialMap],
    dir: &Path,
    overwrite: bool,
) -> Result<PathBuf> {
    let stored = match (&analysed.factors, input.images()) {
        (Some(f), _) => Stored::Factors(f),
        (None, Some(btf)) => Stored::Images(btf),
        (None, None) => return Err(Error::invalid("an analysis from factors without its factors")),
    };
    write_sample(&analysed.analysis, stored, analysed.basis.clone(), source, maps, dir, overwrite)
}

/// The sample an analysis directory stores.
#[derive(Clone, Copy)]
enum Stored<'a> {
    Images(&'a Btf),
    Factors(&'a FactoredStack),
}

impl Stored<'_> {
    fn size(&self) -> (usize, usize, usize) {
        match self {
            Stored::Images(b) => (b.len(), b.width(), b.height()),
            Stored::Factors(f) => (f.len(), f.width(), f.height()),
        }
    }

    fn pairs(&self) -> &[crate::btf::DirectionPair] {
        match self {
            Stored::Images(b) => b.pairs(),
            Stored::Factors(f) => f.pairs(),
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn write_sample(
    analysis: &Analysis,
    stored: Stored,
    basis: Option<super::input::BasisInfo>,
    (source_path, crop): (&Path, Option<[u32; 4]>),
    maps: &[crate::maps::MaterialMap],
    dir: &Path,
    overwrite: bool,
) -> Result<PathBuf> {
    let staged = StagedDir::new(dir, overwrite)?;
    let out = staged.path();
    let (n, w, h) = stored.size();
    // The write and the fingerprint each read the whole sample in order: a core each.
    let (sample, print) = rayon::join(
        || match stored {
            Stored::Images(btf) => {
                npy::write(&out.join("images.npy"), &[n, h, w, 3], btf.pixels()).map(|_| None)
            }
            Stored::Factors(f) => write_factors(out, f).map(Some),
        },
        || match stored {
            Stored::Images(btf) => fingerprint(btf),
            Stored::Factors(f) => factor_fingerprint(f),
        },
    );
    let sample = sample?;
    let directions: Vec<f32> =
        stored.pairs().iter().flat_map(|p| [p.light.theta, p.light.phi, p.view.theta, p.view.phi]).collect();
    npy::write(&out.join("directions.npy"), &[n, 4], &directions)?;
    let mut levels = Vec::new();
    for (l, level) in analysis.levels.iter().enumerate() {
        levels.push(write_level(out, l, level)?);
    }
    write_previews(out, analysis)?;
    let mut manifest = manifest(analysis, (n, w, h), print, source_path, crop, levels);
    manifest.maps = crate::maps::store_maps(out, maps)?;
    manifest.sample = sample;
    manifest.basis = basis;
    let json = serde_json::to_string_pretty(&manifest).map_err(|e| Error::internal(e.to_string()))?;
    write_file_atomic(&out.join(MANIFEST), json.as_bytes())?;
    staged.commit()
}

/// The factor files of a factored sample, and their manifest entry.
fn write_factors(out: &Path, f: &FactoredStack) -> Result<SampleInfo> {
    let components = f.components();
    let k = components.iter().copied().max().unwrap_or(0);
    let (n, texels) = (f.len(), f.width() * f.height());
    let padded = |a: &ndarray::Array2<f32>, rows: usize| -> Vec<f32> {
        (0..rows).flat_map(|r| (0..k).map(move |j| if j < a.ncols() { a[[r, j]] } else { 0.0 })).collect()
    };
    let image: Vec<f32> = f.image.iter().flat_map(|a| padded(a, n)).collect();
    let texel: Vec<f32> = f.texel.iter().flat_map(|a| padded(a, texels)).collect();
    let info = SampleInfo {
        kind: "factors".into(),
        components,
        colour_model: f.model.id(),
        colour_mean: match f.model {
            ColourModel::Pca { mean, .. } => mean,
            _ => [0.0; 3],
        },
        colour_transform: match f.model {
            ColourModel::Pca { transform, .. } => transform,
            _ => [[0.0; 3]; 3],
        },
        log_encoded: f.log_encoded,
        image_factors: "sample_image_factors.npy".into(),
        texel_factors: "sample_texel_factors.npy".into(),
        scale: "sample_scale.npy".into(),
    };
    npy::write(&out.join(&info.image_factors), &[3, n, k], &image)?;
    npy::write(&out.join(&info.texel_factors), &[3, f.height(), f.width(), k], &texel)?;
    npy::write(&out.join(&info.scale), &[n], &f.scale)?;
    Ok(info)
}

/// The factored sample of the analysis in `dir` (whose manifest has a `sample` entry).
pub fn read_factors(dir: &Path, manifest: &Manifest) -> Result<FactoredStack> {
    let Some(info) = &manifest.sample else {
        return Err(Error::format(dir.join(MANIFEST), "the analysis stores images, not factors"));
    };
    let (n, w, h) = (manifest.images, manifest.width, manifest.height);
    let image: npy::NpyArray<f32> = npy::read(&dir.join(&info.image_factors))?;
    let texel: npy::NpyArray<f32> = npy::read(&dir.join(&info.texel_factors))?;
    let scale: npy::NpyArray<f32> = npy::read(&dir.join(&info.scale))?;
    let k = image.shape.get(2).copied().unwrap_or(0);
    if image.shape != [3, n, k] || info.components.iter().any(|&c| c == 0 || c > k) {
        return Err(Error::format(dir.join(&info.image_factors), format!("expected shape [3, {n}, K]")));
    }
    if texel.shape != [3, h, w, k] {
        return Err(Error::format(
            dir.join(&info.texel_factors),
            format!("expected shape [3, {h}, {w}, {k}]"),
        ));
    }
    if scale.shape != [n] {
        return Err(Error::format(dir.join(&info.scale), format!("expected shape [{n}]")));
    }
    let take = |data: &[f32], c: usize, rows: usize| {
        let kc = info.components[c];
        ndarray::Array2::from_shape_fn((rows, kc), |(r, j)| data[(c * rows + r) * k + j])
    };
    let model = ColourModel::from_id(info.colour_model, info.colour_mean, info.colour_transform)
        .map_err(|m| Error::format(dir.join(MANIFEST), m))?;
    let pairs = read_directions(dir, n)?;
    FactoredStack::new(
        &dir.join(&info.texel_factors),
        (w, h),
        pairs,
        (0..3).map(|c| take(&image.data, c, n)).collect(),
        (0..3).map(|c| take(&texel.data, c, w * h)).collect(),
        model,
        info.log_encoded,
        scale.data,
    )
}

/// The direction pairs of `directions.npy` (n of them).
pub fn read_directions(dir: &Path, n: usize) -> Result<Vec<crate::btf::DirectionPair>> {
    use crate::btf::{Direction, DirectionPair};
    let path = dir.join("directions.npy");
    let dirs: npy::NpyArray<f32> = npy::read(&path)?;
    if dirs.shape != [n, 4] {
        return Err(Error::format(&path, format!("shape {:?} does not match {n} images", dirs.shape)));
    }
    dirs.data
        .chunks_exact(4)
        .map(|d| Ok(DirectionPair { light: Direction::new(d[0], d[1])?, view: Direction::new(d[2], d[3])? }))
        .collect::<Result<Vec<_>>>()
        .map_err(|e| Error::format(&path, e.to_string()))
}

/// The manifest `analysis` of `btf` would be written with (the `source_path` it was read
/// from, `crop`), so that a sample can be used straight from memory as from its directory.
pub fn manifest_of(analysis: &Analysis, btf: &Btf, source_path: &Path, crop: Option<[u32; 4]>) -> Manifest {
    let levels = analysis.levels.iter().enumerate().map(|(l, level)| level_info(l, level)).collect();
    manifest(analysis, (btf.len(), btf.width(), btf.height()), fingerprint(btf), source_path, crop, levels)
}

fn write_level(out: &Path, l: usize, level: &super::pipeline::AnalysisLevel) -> Result<LevelInfo> {
    let info = level_info(l, level);
    let (t, files) = (&level.textons, &info.files);
    let (w, h) = (t.map.width, t.map.height);
    let k = level.knn.len() / (w * h).max(1);
    npy::write(&out.join(&files.textons), &[h, w], &t.map.labels)?;
    npy::write(
        &out.join(&files.gamma),
        &[t.gamma.nrows(), t.gamma.ncols()],
        &t.gamma.iter().copied().collect::<Vec<_>>(),
    )?;
    npy::write(
        &out.join(&files.embedding),
        &[t.embedding.nrows(), t.embedding.ncols()],
        &t.embedding.iter().copied().collect::<Vec<_>>(),
    )?;
    npy::write(&out.join(&files.knn), &[h, w, k], &level.knn)?;
    if let (Some(name), Some(lists)) = (&files.knn_two_level, &level.knn_two_level) {
        npy::write(&out.join(name), &[h, w, k], lists)?;
    }
    if let Some(name) = &files.appearance {
        let a = &t.appearance;
        npy::write(&out.join(name), &[h, w, a.ncols()], &a.iter().copied().collect::<Vec<_>>())?;
    }
    Ok(info)
}

fn level_info(l: usize, level: &super::pipeline::AnalysisLevel) -> LevelInfo {
    let t = &level.textons;
    let files = LevelFiles {
        textons: format!("level{l}_textons.npy"),
        gamma: format!("level{l}_gamma.npy"),
        embedding: format!("level{l}_embedding.npy"),
        knn: format!("level{l}_knn.npy"),
        knn_two_level: level.knn_two_level.as_ref().map(|_| format!("level{l}_knn2.npy")),
        appearance: Some(format!("level{l}_appearance.npy")),
    };
    LevelInfo {
        width: t.map.width,
        height: t.map.height,
        textons: t.textons,
        embedding_dims: t.embedding.ncols(),
        basis_rank: t.basis_rank,
        basis_energy: t.basis_energy,
        kmeans_iterations: t.kmeans_iterations,
        feature_energy: t.feature_energy,
        files,
    }
}

fn manifest(
    analysis: &Analysis,
    (images, width, height): (usize, usize, usize),
    fingerprint: String,
    source_path: &Path,
    crop: Option<[u32; 4]>,
    levels: Vec<LevelInfo>,
) -> Manifest {
    let p = &analysis.params;
    let filters: Vec<serde_json::Value> = p
        .filters
        .filters()
        .iter()
        .map(|f| {
            let s = f.spec();
            serde_json::json!({"kind": s.kind.name(), "sigma": s.sigma, "elongation": s.elongation, "orientation": s.orientation_deg, "support": s.support})
        })
        .collect();
    Manifest {
        format: "btfsynth-analysis".into(),
        version: 1,
        source: Source { path: source_path.display().to_string(), fingerprint, crop },
        params: Params {
            textons: p.textons,
            selected: p.selected,
            levels: p.levels,
            k: p.k,
            neighborhood: p.neighborhood,
            tileable: p.tileable,
            basis_rank: p.basis_rank,
            appearance_dims: p.appearance_dims,
            seed: p.seed,
        },
        filters: serde_json::json!({"name": p.filters.name(), "filters": filters}),
        selected: analysis.selected.clone(),
        images,
        width,
        height,
        k: p.k,
        levels,
        maps: Vec::new(),
        sample: None,
        basis: None,
    }
}

/// What an analysis took: seconds per stage and the peak memory. Not part of
/// `analysis.json`, which holds only what the same inputs always give (a report of the
/// run holds this).
pub fn timings_json(analysis: &Analysis) -> serde_json::Value {
    let t = &analysis.timings;
    serde_json::json!({
        "timings_s": {
            "selection": t.selection.as_secs_f64(), "filtering": t.filtering.as_secs_f64(),
            "kmeans": t.kmeans.as_secs_f64(), "gamma": t.gamma.as_secs_f64(),
            "knn": t.knn.as_secs_f64(), "total": t.total.as_secs_f64(),
        },
        "peak_memory_bytes": peak_memory_bytes(),
    })
}

/// Checks the arrays of the first `levels` levels against `manifest` (shapes, label and
/// list ranges), naming the file at fault, so that a damaged array is reported as itself.
pub fn verify_levels(dir: &Path, manifest: &Manifest, levels: usize) -> Result<()> {
    for info in manifest.levels.iter().take(levels) {
        let (w, h, t) = (info.width, info.height, info.textons + 1);
        let path = dir.join(&info.files.textons);
        let labels: npy::NpyArray<u16> = npy::read(&path)?;
        if labels.shape != [h, w] {
            return Err(Error::format(
                &path,
                format!("shape {:?}, expected [{h}, {w}] (analysis.json)", labels.shape),
            ));
        }
        if labels.data.iter().any(|&l| l as usize >= t) {
            return Err(Error::format(
                &path,
                format!("a texton label is {} or more (analysis.json: {} textons)", t, info.textons),
            ));
        }
        drop(labels);
        let path = dir.join(&info.files.gamma);
        let gamma: npy::NpyArray<f32> = npy::read(&path)?;
        if gamma.shape != [t, t] {
            return Err(Error::format(
                &path,
                format!("shape {:?}, expected [{t}, {t}] (analysis.json)", gamma.shape),
            ));
        }
        let path = dir.join(&info.files.embedding);
        let embedding: npy::NpyArray<f32> = npy::read(&path)?;
        if embedding.shape.len() != 2 || embedding.shape[0] != t {
            return Err(Error::format(
                &path,
                format!("shape {:?}, expected [{t}, d] (analysis.json)", embedding.shape),
            ));
        }
        let lists = std::iter::once(&info.files.knn).chain(info.files.knn_two_level.as_ref());
        let mut k = None;
        for name in lists {
            let path = dir.join(name);
            let knn: npy::NpyArray<u32> = npy::read(&path)?;
            if knn.shape.len() != 3 || knn.shape[..2] != [h, w] || knn.shape[2] == 0 {
                return Err(Error::format(
                    &path,
                    format!("shape {:?}, expected [{h}, {w}, k] (analysis.json)", knn.shape),
                ));
            }
            if *k.get_or_insert(knn.shape[2]) != knn.shape[2] {
                return Err(Error::format(
                    &path,
                    format!(
                        "lists of {} entries, but {} has {}",
                        knn.shape[2],
                        info.files.knn,
                        k.unwrap_or(0)
                    ),
                ));
            }
            if knn.data.iter().any(|&p| p as usize >= w * h) {
                return Err(Error::format(
                    &path,
                    format!("a list entry is {} or more, beyond the {w}x{h} texels", w * h),
                ));
            }
        }
        if let Some(name) = &info.files.appearance {
            let path = dir.join(name);
            let a: npy::NpyArray<f32> = npy::read(&path)?;
            if a.shape.len() != 3 || a.shape[..2] != [h, w] || a.shape[2] == 0 {
                return Err(Error::format(
                    &path,
                    format!("shape {:?}, expected [{h}, {w}, d] (analysis.json)", a.shape),
                ));
            }
        }
    }
    Ok(())
}

/// Reads `analysis.json` of an analysis directory.
pub fn read_manifest(dir: &Path) -> Result<Manifest> {
    // A photo or stack file given where an analysis goes would otherwise read as the
    // system's "Not a directory" on `FILE/analysis.json`.
    if dir.is_file() {
        return Err(Error::format(
            dir,
            "a file, not an analysis directory (make one with `btfsynth analyze FILE -o DIR`)",
        ));
    }
    let path = dir.join(MANIFEST);
    let text = crate::fsutil::read_input_text(&path)?;
    let manifest: Manifest = serde_json::from_str(&text)
        .map_err(|e| Error::format(&path, format!("invalid analysis manifest: {e}")))?;
    if manifest.format != "btfsynth-analysis" {
        return Err(Error::format(
            &path,
            format!("format is '{}', not 'btfsynth-analysis'", manifest.format),
        ));
    }
    Ok(manifest)
}

/// Checks that the analysis in `dir` is the one `result` was synthesized from, by the
/// fingerprint the result recorded (results written before fingerprints were recorded,
/// `recorded` = None, are accepted).
pub fn verify_fingerprint(dir: &Path, result: &Path, recorded: Option<&str>) -> Result<()> {
    let Some(recorded) = recorded else { return Ok(()) };
    let found = read_manifest(dir)?.source.fingerprint;
    if found == recorded {
        return Ok(());
    }
    Err(Error::AnalysisMismatch {
        result: result.to_path_buf(),
        analysis: dir.to_path_buf(),
        recorded: recorded.to_string(),
        found,
    })
}

/// FNV-1a 64 over the directions and the pixels' f16 bits.
pub fn fingerprint(btf: &Btf) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(&(btf.width() as u64).to_le_bytes());
    eat(&(btf.height() as u64).to_le_bytes());
    for p in btf.pairs() {
        for a in [p.light.theta, p.light.phi, p.view.theta, p.view.phi] {
            eat(&a.to_le_bytes());
        }
    }
    for v in btf.pixels() {
        eat(&v.to_bits().to_le_bytes());
    }
    format!("fnv1a64:{h:016x}")
}

/// FNV-1a 64 over the sizes, the directions, the decoding and the factors' f32 bits of a
/// factored sample (prefix `fnv1a64-factors:`, so it never equals an images' fingerprint).
pub fn factor_fingerprint(f: &FactoredStack) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(&(f.width() as u64).to_le_bytes());
    eat(&(f.height() as u64).to_le_bytes());
    for p in f.pairs() {
        for a in [p.light.theta, p.light.phi, p.view.theta, p.view.phi] {
            eat(&a.to_le_bytes());
        }
    }
    eat(&f.model.id().to_le_bytes());
    eat(&[f.log_encoded as u8]);
    if let ColourModel::Pca { mean, transform } = f.model {
        for v in mean.iter().chain(transform.iter().flatten()) {
            eat(&v.to_le_bytes());
        }
    }
    for v in f.scale.iter().chain(f.image.iter().flatten()).chain(f.texel.iter().flatten()) {
        eat(&v.to_bits().to_le_bytes());
    }
    format!("fnv1a64-factors:{h:016x}")
}

/// Peak resident set size from /proc (Linux); None elsewhere.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// `level0_textons.png` (false colour: the embedding's first three components as RGB, so
/// similar textons get similar colours) and `filters.png` (the bank as a contact sheet).
fn write_previews(out: &Path, analysis: &Analysis) -> Result<()> {
    if let Some(level) = analysis.levels.first() {
        let t = &level.textons;
        let colours = false_colours(&t.embedding);
        let pixels: Vec<u8> = t.map.labels.iter().flat_map(|&l| colours[l as usize]).collect();
        save_png(&out.join("level0_textons.png"), t.map.width, t.map.height, &pixels)?;
    }
    let sheet = analysis.params.filters.contact_sheet();
    save_png(&out.join("filters.png"), sheet.width, sheet.height, &sheet.pixels)
}

/// One colour per texton: the embedding's first three components scaled to [0, 1] as RGB,
/// so similar textons get similar colours.
pub fn false_colours(embedding: &ndarray::Array2<f32>) -> Vec<[u8; 3]> {
    let dims = embedding.ncols().min(3);
    let range: Vec<(f32, f32)> = (0..dims)
        .map(|c| embedding.column(c).iter().fold((f32::MAX, f32::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v))))
        .collect();
    embedding
        .rows()
        .into_iter()
        .map(|row| {
            let mut rgb = [128u8; 3];
            for (c, &(lo, hi)) in range.iter().enumerate() {
                let t = if hi > lo { (row[c] - lo) / (hi - lo) } else { 0.5 };
                rgb[c] = linear_to_srgb8(0.05 + 0.9 * t);
            }
            rgb
        })
        .collect()
}

/// Writes 8-bit RGB as PNG.
pub fn save_png(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<()> {
    crate::btf::image_io::write_png8(path, width, height, rgb, image::ExtendedColorType::Rgb8)
}
