//! What `analyze` reads, and which way it is analysed.
//!
//! - **Decoded images** ([`super::pipeline::analyze`]): image folders, manifests and
//!   photographs that fit in memory decoded, and any stack opened to be decoded. This is the
//!   path the analysis goldens pin; memory grows with images × texels.
//! - **The file's factors** ([`factor_basis`]): a DFMF or FMF `.btf` whose decoding is
//!   linear in its factors — colour model RGB, YUV, PCA or YCoCg, no dynamic-range
//!   reduction. The per-image cosine scale of a file with the cosine flag is linear too
//!   (it scales the image's coordinates). The factors are then an exact basis of the
//!   linear-RGB images, and [`super::pipeline::analyze_low_rank`] works from them at a
//!   cost of texels × rank. The only difference from the decoded path is rounding: decoded
//!   images are rounded to f16 (and saturate at ±65504), the factor path is not.
//! - **A streamed basis** ([`super::basis::streamed_basis`]): where the decoding is not
//!   linear — colour models log-Y U/Y V/Y (the UBO2014 files' model 11) and the other log
//!   models take exponentials, Lab a cube and a gamma curve, the spectral models multiply
//!   channels, FMF12's dynamic-range reduction takes exp(x) − ε — a sum of images is not
//!   the decoding of the summed factors, so the factors are a basis of the encoded
//!   channels but not of RGB. There the images are decoded in batches (each a K-term
//!   product per value, then the non-linear decoding, exactly) and a randomized range
//!   finder builds an RGB basis in two passes; the analysis then proceeds as from factors.
//!   The same path takes BDI files, zips and image folders too large to decode at once.
//!   Its approximation (the energy outside the sketch) is recorded in `analysis.json`.
//!
//! Each path predicts its memory peak before anything is decoded and refuses with one
//! line when that would not fit ([`super::memory`]).

use super::basis::{streamed_basis, LowRankStack, StreamOptions};
use super::memory::{self, Stage};
use super::pipeline::{analyze, analyze_low_rank, Analysis, AnalysisParams};
use crate::btf::colour::ColourModel;
use crate::btf::factored::FactoredStack;
use crate::btf::source::{resolve_crop, ImageSource};
use crate::btf::{archive, ubo2014, Btf, Crop};
use crate::progress::Progress;
use crate::{Error, Remedy, Result};
use ndarray::{Array1, Array2};
use std::path::{Path, PathBuf};

/// Which path `analyze` takes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Mode {
    /// Factors for factorized files, decoded images for stacks that fit decoded, a streamed
    /// basis otherwise.
    #[default]
    Auto,
    /// Always the decoded images (refused when they would not fit).
    Decoded,
}

/// A stack ready to analyse.
pub enum Input {
    /// Every image decoded in memory.
    Images(Btf),
    /// A factorized `.btf` crop as its factors.
    Factors(FactoredStack),
    /// A stack read image by image for a streamed basis.
    Streamed(Box<dyn ImageSource>),
}

/// How the analysis saw the images, for `analysis.json` (absent for decoded images).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize, PartialEq)]
pub struct BasisInfo {
    /// `file factors` or `streamed`.
    pub kind: String,
    /// Rank of the low-rank stack the analysis worked from.
    pub rank: usize,
    /// Fraction of the centred images' energy that rank holds (1 for linear file factors).
    pub captured: f64,
    /// Why the file's own factors could not serve as the basis, if they could not.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nonlinearity: Option<String>,
}

/// An analysis and the sample it stores.
pub struct Analysed {
    /// The texton pyramid and its kNN lists.
    pub analysis: Analysis,
    /// The sample as factors (`None`: the decoded images of [`Input::Images`] are stored).
    pub factors: Option<FactoredStack>,
    /// How the analysis saw the images (`None`: decoded images).
    pub basis: Option<BasisInfo>,
}

impl Input {
    /// Width and height of the sample.
    pub fn size(&self) -> (usize, usize) {
        match self {
            Input::Images(b) => (b.width(), b.height()),
            Input::Factors(f) => (f.width(), f.height()),
            Input::Streamed(s) => (s.width(), s.height()),
        }
    }

    /// Number of images.
    pub fn len(&self) -> usize {
        match self {
            Input::Images(b) => b.len(),
            Input::Factors(f) => f.len(),
            Input::Streamed(s) => s.pairs().len(),
        }
    }

    /// Whether the input holds no images.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The decoded stack, for [`Input::Images`].
    pub fn images(&self) -> Option<&Btf> {
        match self {
            Input::Images(b) => Some(b),
            _ => None,
        }
    }
}

/// The streamed basis' settings for an analysis with `params`.
pub fn stream_options(params: &AnalysisParams) -> StreamOptions {
    StreamOptions { seed: params.seed, ..StreamOptions::default() }
}

/// Opens the stack at `path` (cropped to `crop`) for the path `mode` and the stack call
/// for, after checking that its memory estimate fits. Reads headers and factors, and
/// decodes images only for [`Input::Images`].
pub fn open(
    path: &Path,
    crop: Option<Crop>,
    mode: Mode,
    params: &AnalysisParams,
    progress: &dyn Progress,
) -> Result<Input> {
    if ubo2014::is_bonn_file(path) {
        let file = ubo2014::BonnBtf::open(path)?;
        let c = resolve_crop(path, crop, file.width(), file.height())?;
        let size = (c.width as usize, c.height as usize);
        let n = file.pairs().len();
        if let (Some((model, log_encoded, components)), Mode::Auto) = (file.factor_layout(), mode) {
            let k: usize = components.iter().sum();
            let held = ((n + size.0 * size.1) * k * 4) as u64;
            let linear = model.affine().is_some() && !log_encoded;
            let streamed = (!linear).then(|| stream_options(params));
            let rank = if linear { k + 1 } else { stream_options(params).rank };
            let stages = memory::low_rank_stages(n, rank, size, params, held, streamed);
            let what = format!(
                "analysing {}x{} texels × {n} images from the file's factors{}",
                size.0,
                size.1,
                if linear { "" } else { " (through a streamed basis)" }
            );
            memory::check(path, &what, &stages, Remedy::Crop)?;
            return Ok(Input::Factors(file.into_window(crop)?.into_factored()?));
        }
        return decoded_or_streamed(Box::new(file.into_window(crop)?), mode, params, progress);
    }
    if archive::is_zip(path) {
        return decoded_or_streamed(Box::new(archive::ZipStack::open(path, crop)?), mode, params, progress);
    }
    decoded_or_streamed(Box::new(crate::btf::load::FolderStack::open(path, crop)?), mode, params, progress)
}

/// Decoded images when they fit (or `mode` asks), else a streamed basis.
fn decoded_or_streamed(
    source: Box<dyn ImageSource>,
    mode: Mode,
    params: &AnalysisParams,
    progress: &dyn Progress,
) -> Result<Input> {
    let (n, size) = (source.pairs().len(), (source.width(), source.height()));
    let decoded = memory::decoded_stages(n, size, params);
    let what = format!("analysing {}x{} texels × {n} decoded images", size.0, size.1);
    let fits = memory::check(source.path(), &what, &decoded, Remedy::Crop);
    match (fits, mode) {
        (Ok(()), _) => Ok(Input::Images(source.decode_all(progress)?)),
        (Err(e), Mode::Decoded) => Err(e),
        (Err(_), Mode::Auto) => {
            let options = stream_options(params);
            let stages = memory::low_rank_stages(n, options.rank, size, params, 0, Some(options));
            let what =
                format!("analysing {}x{} texels × {n} images through a streamed basis", size.0, size.1);
            memory::check(source.path(), &what, &stages, Remedy::Crop)?;
            Ok(Input::Streamed(source))
        }
    }
}

/// Analyses `input` the way it was opened for.
pub fn run(input: &Input, params: &AnalysisParams, progress: &dyn Progress) -> Result<Analysed> {
    let size = input.size();
    match input {
        Input::Images(btf) => {
            Ok(Analysed { analysis: analyze(btf, params, progress)?, factors: None, basis: None })
        }
        Input::Factors(factors) => {
            let (stack, basis) = match factor_basis(factors) {
                Some(stack) => {
                    let info = BasisInfo {
                        kind: "file factors".into(),
                        rank: stack.rank(),
                        captured: 1.0,
                        nonlinearity: None,
                    };
                    (stack, info)
                }
                None => {
                    let stack = streamed_basis(factors, &stream_options(params), progress)?;
                    let info = streamed_info(&stack, factors.nonlinearity());
                    (stack, info)
                }
            };
            let analysis = analyze_low_rank(stack, size, params, progress)?;
            Ok(Analysed { analysis, factors: Some(factors.clone()), basis: Some(basis) })
        }
        Input::Streamed(source) => {
            let stack = streamed_basis(source.as_ref(), &stream_options(params), progress)?;
            let info = streamed_info(&stack, None);
            let sample = sample_of(&stack, source.as_ref())?;
            let analysis = analyze_low_rank(stack, size, params, progress)?;
            Ok(Analysed { analysis, factors: Some(sample), basis: Some(info) })
        }
    }
}

fn streamed_info(stack: &LowRankStack, nonlinearity: Option<String>) -> BasisInfo {
    let inside: f64 = stack.coords.iter().map(|&v| v as f64 * v as f64).sum();
    let total = inside + stack.outside;
    let captured = if total > 0.0 { inside / total } else { 1.0 };
    BasisInfo { kind: "streamed".into(), rank: stack.rank(), captured, nonlinearity }
}

/// The file's factors as an exact basis of the linear-RGB images, where the decoding is
/// linear (see the module notes); `None` where it is not.
///
/// With RGB = M·v + t (the colour model) and the image's scale s: image a at texel p is
/// `s_a (Σ_c M[·][c] Σ_k A_c[a][k] B_c[p][k] + t)`, so the rows are the texel factors
/// spread over the colours (`M[·][c] B_c[·][k]`) plus one row holding t, and image a's
/// coordinates are `s_a A_c[a][·]` and `s_a`.
pub fn factor_basis(f: &FactoredStack) -> Option<LowRankStack> {
    if f.log_encoded {
        return None;
    }
    let (m, t) = f.model.affine()?;
    let (n, texels) = (f.len(), f.width() * f.height());
    let components = f.components();
    let k: usize = components.iter().sum();
    let offset_row = t.iter().any(|&v| v != 0.0);
    let q = k + offset_row as usize;
    let mut coords = Array2::<f32>::zeros((n, q));
    let mut rows = Array2::<f32>::zeros((q, texels * 3));
    let mut at = 0;
    for c in 0..3 {
        for j in 0..components[c] {
            for a in 0..n {
                coords[[a, at]] = f.scale[a] * f.image[c][[a, j]];
            }
            let mut row = rows.row_mut(at);
            let row = row.as_slice_mut().expect("a row of a standard array is contiguous");
            for (p, px) in row.chunks_exact_mut(3).enumerate() {
                let b = f.texel[c][[p, j]];
                px.iter_mut().zip(&m).for_each(|(v, m_row)| *v = m_row[c] * b);
            }
            at += 1;
        }
    }
    if offset_row {
        for a in 0..n {
            coords[[a, at]] = f.scale[a];
        }
        let mut row = rows.row_mut(at);
        for (i, v) in row.iter_mut().enumerate() {
            *v = t[i % 3];
        }
    }
    Some(LowRankStack { offset: Array1::zeros(texels * 3), coords, rows, outside: 0.0 })
}

/// The sample of a streamed stack, stored as factors: the basis' rows as texel factors
/// (RGB, with the mean as one more component whose image factor is 1) and the images'
/// coordinates as image factors. Approximate by the energy outside the sketch.
fn sample_of(stack: &LowRankStack, source: &dyn ImageSource) -> Result<FactoredStack> {
    let (n, l) = (stack.len(), stack.rank());
    let texels = source.width() * source.height();
    let image: Vec<Array2<f32>> = (0..3)
        .map(|_| Array2::from_shape_fn((n, l + 1), |(a, k)| if k < l { stack.coords[[a, k]] } else { 1.0 }))
        .collect();
    let texel: Vec<Array2<f32>> = (0..3)
        .map(|c| {
            Array2::from_shape_fn((texels, l + 1), |(p, k)| {
                if k < l {
                    stack.rows[[k, 3 * p + c]]
                } else {
                    stack.offset[3 * p + c]
                }
            })
        })
        .collect();
    FactoredStack::new(
        source.path(),
        (source.width(), source.height()),
        source.pairs().to_vec(),
        image,
        texel,
        ColourModel::Rgb,
        false,
        vec![1.0; n],
    )
}

/// The path `analyze` read, for messages.
pub fn describe(input: &Input) -> &'static str {
    match input {
        Input::Images(_) => "decoded images",
        Input::Factors(f) if factor_basis_is_exact(f) => "the file's factors",
        Input::Factors(_) => "a basis streamed from the file's factors",
        Input::Streamed(_) => "a streamed basis",
    }
}

fn factor_basis_is_exact(f: &FactoredStack) -> bool {
    f.model.affine().is_some() && !f.log_encoded
}

/// Where a factored sample came from, for messages.
pub fn source_path(input: &Input) -> Option<PathBuf> {
    match input {
        Input::Images(_) => None,
        Input::Factors(f) => Some(f.source_path().to_path_buf()),
        Input::Streamed(s) => Some(s.path().to_path_buf()),
    }
}

/// Stages of `input`'s analysis (for reports and tests).
pub fn stages(input: &Input, params: &AnalysisParams) -> Vec<Stage> {
    let (n, size) = (input.len(), input.size());
    match input {
        Input::Images(_) => memory::decoded_stages(n, size, params),
        Input::Factors(f) => {
            let exact = factor_basis_is_exact(f);
            let rank =
                if exact { f.components().iter().sum::<usize>() + 1 } else { stream_options(params).rank };
            memory::low_rank_stages(
                n,
                rank,
                size,
                params,
                f.bytes(),
                (!exact).then(|| stream_options(params)),
            )
        }
        Input::Streamed(_) => memory::low_rank_stages(
            n,
            stream_options(params).rank,
            size,
            params,
            0,
            Some(stream_options(params)),
        ),
    }
}

/// Fails unless `input` was opened as decoded images (for callers that need the images).
pub fn require_images(input: &Input) -> Result<&Btf> {
    input.images().ok_or_else(|| Error::invalid("this stack is analysed from factors, not decoded images"))
}
