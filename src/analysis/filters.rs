//! Filter banks: parametric definitions read from TOML, sampled into square kernels.
//!
//! The default bank is Leung and Malik's 48 filters ([`FilterBank::lm48`], defined in
//! `filters/lm48.toml`), the bank Tong et al. 2002 (§4) filter every BTF image with. A user
//! can copy that file, edit it and load it with [`FilterBank::from_file`].
//!
//! # Kernel conventions
//!
//! A kernel of size `K × K` (`K` odd) is stored row-major; row `r`, column `c` is the pixel
//! offset `dx = c − K/2`, `dy = r − K/2` from the centre, with rows running down the image.
//! Orientation is measured counter-clockwise *on screen*, so in the filter's own frame
//! `x = dx`, `y = −dy` (up), and a filter at orientation θ has axes
//! `u = x cos θ + y sin θ` (along the edge) and `v = −x sin θ + y cos θ` (across it).
//!
//! With `g(t; s)` the 1-D Gaussian, `σ_u = elongation × σ` and `σ_v = σ`:
//!
//! | kind | kernel before normalisation |
//! |---|---|
//! | `gaussian` | `g(u; σ_u) g(v; σ_v)` |
//! | `first_derivative` | `g(u; σ_u) · (v / σ_v²) g(v; σ_v)`: positive where the image gets brighter towards +v |
//! | `second_derivative` | `g(u; σ_u) ∂²g(v; σ_v)/∂v²`: negative on a bright bar along u |
//! | `laplacian` | `∂²G/∂u² + ∂²G/∂v²` (negative centre) |
//!
//! Every kernel except `gaussian` is shifted to zero mean, then every kernel is scaled to
//! unit L1 norm (as in Leung and Malik's `makeLMfilters`, except that the Gaussians keep
//! their positive mean so they remain local averages).

use crate::{Error, Result};
use serde::Deserialize;
use std::path::Path;

/// The text of `filters/lm48.toml`, the default bank; the CLI can write it out for users
/// to copy and edit.
pub const LM48_TOML: &str = include_str!("../../filters/lm48.toml");

/// Most filters in a bank: each is a response channel of every image filtered, so a
/// bank of thousands would take gigabytes.
pub const MAX_FILTERS: usize = 256;

/// Largest kernel accepted from a file: a typo such as `support = 4900` would otherwise
/// make every FFT in the analysis enormous.
pub const MAX_SUPPORT: usize = 513;

/// Columns of the [`FilterBank::contact_sheet`] grid: 12 puts the LM bank's scales on rows
/// as in Leung and Malik's figure.
const SHEET_COLUMNS: usize = 12;
/// Pixels between kernels on the contact sheet.
const SHEET_GAP: usize = 2;
/// Colour of the gaps, distinct from every grey a kernel can map to.
const SHEET_GAP_RGB: [u8; 3] = [40, 56, 96];

/// The shape of one filter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FilterKind {
    /// A (possibly elongated) Gaussian: a local average.
    Gaussian,
    /// First Gaussian derivative across the edge: answers edges.
    FirstDerivative,
    /// Second Gaussian derivative across the edge: answers bars and lines.
    SecondDerivative,
    /// Laplacian of Gaussian: answers blobs and spots.
    Laplacian,
}

impl FilterKind {
    /// The name used in TOML files.
    pub fn name(self) -> &'static str {
        match self {
            FilterKind::Gaussian => "gaussian",
            FilterKind::FirstDerivative => "first_derivative",
            FilterKind::SecondDerivative => "second_derivative",
            FilterKind::Laplacian => "laplacian",
        }
    }

    /// Whether the kernel is shifted to zero mean (all kinds but [`FilterKind::Gaussian`]).
    pub fn is_zero_mean(self) -> bool {
        self != FilterKind::Gaussian
    }
}

/// The parameters of one filter, as written in a bank's TOML file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterSpec {
    /// The shape.
    pub kind: FilterKind,
    /// Standard deviation in pixels; across the edge for oriented kinds. Must be > 0.
    pub sigma: f64,
    /// Ratio of the standard deviation along the edge to `sigma`; TOML default 1 (isotropic).
    pub elongation: f64,
    /// Direction along the edge, degrees counter-clockwise on screen from the x axis;
    /// TOML default 0.
    pub orientation_deg: f64,
    /// Kernel width and height in pixels (odd); TOML default: the bank's `support`.
    pub support: usize,
}

/// One filter: its parameters and its sampled, normalised kernel.
#[derive(Clone, Debug, PartialEq)]
pub struct Filter {
    spec: FilterSpec,
    weights: Vec<f32>,
}

impl Filter {
    /// Samples `spec` into a kernel. Fails when the parameters are out of range or the
    /// kernel vanishes at this support (e.g. a derivative far narrower than a pixel).
    pub fn new(spec: FilterSpec) -> Result<Self, String> {
        validate_spec(&spec)?;
        let weights = sample_kernel(&spec)?;
        Ok(Filter { spec, weights })
    }

    /// The parameters the kernel was sampled from.
    pub fn spec(&self) -> &FilterSpec {
        &self.spec
    }

    /// Kernel width and height (odd).
    pub fn size(&self) -> usize {
        self.spec.support
    }

    /// Half the kernel width: the kernel covers offsets `-half..=half`.
    pub fn half(&self) -> usize {
        self.spec.support / 2
    }

    /// The kernel, row-major, `size() × size()` values.
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }
}

/// An ordered set of filters; filter `i` gives response channel `i`.
#[derive(Clone, Debug, PartialEq)]
pub struct FilterBank {
    name: String,
    filters: Vec<Filter>,
}

/// An 8-bit RGB image, row-major and interleaved, for the caller to encode (e.g. as PNG).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rgb8Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width × height × 3` bytes.
    pub pixels: Vec<u8>,
}

/// The TOML file as written; optional fields get their defaults in [`FilterBank::from_toml_str`].
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BankFile {
    name: Option<String>,
    support: Option<usize>,
    filters: Vec<FilterEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FilterEntry {
    kind: FilterKind,
    sigma: f64,
    elongation: Option<f64>,
    orientation: Option<f64>,
    support: Option<usize>,
}

impl FilterBank {
    /// Leung and Malik's 48 filters from the embedded `filters/lm48.toml`.
    pub fn lm48() -> Self {
        // The embedded file is part of the crate, not user input; a test parses it.
        Self::from_toml_str(LM48_TOML, "filters/lm48.toml")
            .expect("embedded filters/lm48.toml is a valid bank")
    }

    /// Parses a bank from TOML text; `source` names the text in error messages (usually
    /// its path).
    pub fn from_toml_str(text: &str, source: impl AsRef<Path>) -> Result<Self> {
        let source = source.as_ref();
        let file: BankFile = toml::from_str(text)
            .map_err(|e| Error::format(source, format!("not a valid filter bank: {}", one_line(text, &e))))?;
        let default_support = file.support;
        let specs = file
            .filters
            .into_iter()
            .enumerate()
            .map(|(i, entry)| {
                let support = entry.support.or(default_support).ok_or_else(|| {
                    Error::format(
                        source,
                        format!("filter {i}: no `support` here and no top-level `support` either"),
                    )
                })?;
                Ok(FilterSpec {
                    kind: entry.kind,
                    sigma: entry.sigma,
                    elongation: entry.elongation.unwrap_or(1.0),
                    orientation_deg: entry.orientation.unwrap_or(0.0),
                    support,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let name = file.name.unwrap_or_else(|| source.display().to_string());
        Self::from_specs(name, specs).map_err(|m| Error::format(source, m))
    }

    /// Reads a bank from a TOML file (see `filters/lm48.toml` for the format).
    pub fn from_file(path: &Path) -> Result<Self> {
        let text = crate::fsutil::read_input_text(path)?;
        Self::from_toml_str(&text, path)
    }

    /// Builds a bank from parameters; the message names the first bad filter by index.
    pub fn from_specs(name: impl Into<String>, specs: Vec<FilterSpec>) -> Result<Self, String> {
        if specs.is_empty() {
            return Err("the bank has no filters; add at least one entry to `filters`".into());
        }
        if specs.len() > MAX_FILTERS {
            return Err(format!("{} filters; a bank holds at most {MAX_FILTERS}", specs.len()));
        }
        let filters = specs
            .into_iter()
            .enumerate()
            .map(|(i, spec)| Filter::new(spec).map_err(|m| format!("filter {i}: {m}")))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(FilterBank { name: name.into(), filters })
    }

    /// The bank's `name` (TOML default: the file name).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Number of filters (response channels); never 0.
    pub fn len(&self) -> usize {
        self.filters.len()
    }

    /// Always false: a bank has at least one filter.
    pub fn is_empty(&self) -> bool {
        self.filters.is_empty()
    }

    /// The filters in channel order.
    pub fn filters(&self) -> &[Filter] {
        &self.filters
    }

    /// The largest kernel half-width: how far filtering reaches past a pixel.
    pub fn max_half(&self) -> usize {
        self.filters.iter().map(Filter::half).max().unwrap_or(0)
    }

    /// A preview of every kernel on a grid of up to 12 columns, in channel order. Each kernel
    /// is scaled by its own largest magnitude: zero is mid-grey, positive lighter, negative
    /// darker; cells are separated by dark blue gaps.
    pub fn contact_sheet(&self) -> Rgb8Image {
        let cell = 2 * self.max_half() + 1;
        let cols = self.len().clamp(1, SHEET_COLUMNS);
        let rows = self.len().div_ceil(cols);
        let width = cols * cell + (cols + 1) * SHEET_GAP;
        let height = rows * cell + (rows + 1) * SHEET_GAP;
        let mut pixels: Vec<u8> = SHEET_GAP_RGB.iter().copied().cycle().take(width * height * 3).collect();
        for (i, filter) in self.filters.iter().enumerate() {
            let x0 = SHEET_GAP + (i % cols) * (cell + SHEET_GAP);
            let y0 = SHEET_GAP + (i / cols) * (cell + SHEET_GAP);
            let greys = kernel_greys(filter, cell);
            for (r, row) in greys.chunks_exact(cell).enumerate() {
                for (c, &g) in row.iter().enumerate() {
                    let at = ((y0 + r) * width + x0 + c) * 3;
                    pixels[at..at + 3].fill(g);
                }
            }
        }
        Rgb8Image { width, height, pixels }
    }
}

/// The TOML error as "line L, column C: message": its own rendering spans several lines
/// with a source excerpt, and the CLI prints errors on one line.
fn one_line(text: &str, error: &toml::de::Error) -> String {
    let message = error.message().trim_end().replace('\n', "; ");
    match error.span().and_then(|span| text.get(..span.start)) {
        Some(before) => {
            let line = before.matches('\n').count() + 1;
            let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            format!("line {line}, column {column}: {message}")
        }
        None => message,
    }
}

/// A `cell × cell` grey rendering of the kernel, centred, padded with zero-grey.
fn kernel_greys(filter: &Filter, cell: usize) -> Vec<u8> {
    let peak = filter.weights.iter().fold(0f32, |m, w| m.max(w.abs()));
    let scale = if peak > 0.0 { 127.0 / peak } else { 0.0 };
    let mut greys = vec![128u8; cell * cell];
    let (size, offset) = (filter.size(), (cell - filter.size()) / 2);
    for (r, row) in filter.weights.chunks_exact(size).enumerate() {
        for (c, &w) in row.iter().enumerate() {
            greys[(offset + r) * cell + offset + c] = (128.0 + w * scale).round().clamp(0.0, 255.0) as u8;
        }
    }
    greys
}

fn validate_spec(spec: &FilterSpec) -> Result<(), String> {
    if !(spec.sigma.is_finite() && spec.sigma > 0.0) {
        return Err(format!("sigma must be a positive number of pixels, got {}", spec.sigma));
    }
    if !(spec.elongation.is_finite() && spec.elongation > 0.0) {
        return Err(format!("elongation must be positive (1 = isotropic), got {}", spec.elongation));
    }
    if !spec.orientation_deg.is_finite() {
        return Err(format!("orientation must be a number of degrees, got {}", spec.orientation_deg));
    }
    if spec.support % 2 == 0 || spec.support > MAX_SUPPORT {
        return Err(format!(
            "support must be an odd number of pixels between 1 and {MAX_SUPPORT}, got {}",
            spec.support
        ));
    }
    Ok(())
}

/// Point-samples the kernel at pixel centres and normalises it (see the module docs).
fn sample_kernel(spec: &FilterSpec) -> Result<Vec<f32>, String> {
    let half = (spec.support / 2) as f64;
    let (sin, cos) = spec.orientation_deg.to_radians().sin_cos();
    let (su, sv) = (spec.elongation * spec.sigma, spec.sigma);
    let mut k: Vec<f64> = (0..spec.support * spec.support)
        .map(|i| {
            let x = (i % spec.support) as f64 - half;
            let y = half - (i / spec.support) as f64;
            let (u, v) = (x * cos + y * sin, -x * sin + y * cos);
            profile(spec.kind, u, v, su, sv)
        })
        .collect();
    if spec.kind.is_zero_mean() {
        let mean = k.iter().sum::<f64>() / k.len() as f64;
        k.iter_mut().for_each(|w| *w -= mean);
    }
    let l1: f64 = k.iter().map(|w| w.abs()).sum();
    let peak = k.iter().fold(0f64, |m, w| m.max(w.abs()));
    // A kernel that is only rounding noise (a derivative narrower than a pixel sampled at
    // its zero crossings) would be blown up to garbage by the normalisation.
    if !(l1.is_finite() && l1 > 0.0 && peak > 1e-9 * l1) {
        return Err(format!(
            "the {} kernel with sigma {} vanishes on a {}-pixel support; use a larger sigma",
            spec.kind.name(),
            spec.sigma,
            spec.support
        ));
    }
    Ok(k.into_iter().map(|w| (w / l1) as f32).collect())
}

/// The unnormalised kernel value at filter coordinates (u along, v across the edge).
fn profile(kind: FilterKind, u: f64, v: f64, su: f64, sv: f64) -> f64 {
    let (gu, gv) = (gauss(u, su), gauss(v, sv));
    match kind {
        FilterKind::Gaussian => gu * gv,
        FilterKind::FirstDerivative => gu * (v / (sv * sv)) * gv,
        FilterKind::SecondDerivative => gu * gauss_d2(v, sv),
        FilterKind::Laplacian => gauss_d2(u, su) * gv + gu * gauss_d2(v, sv),
    }
}

fn gauss(t: f64, s: f64) -> f64 {
    (-t * t / (2.0 * s * s)).exp() / (s * (2.0 * std::f64::consts::PI).sqrt())
}

fn gauss_d2(t: f64, s: f64) -> f64 {
    gauss(t, s) * (t * t - s * s) / (s * s * s * s)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQRT2: f64 = std::f64::consts::SQRT_2;

    /// The reference definition from the task and from Leung–Malik, in channel order.
    fn reference_specs() -> Vec<FilterSpec> {
        let oriented = |kind, sigma, k: usize| FilterSpec {
            kind,
            sigma,
            elongation: 3.0,
            orientation_deg: 30.0 * k as f64,
            support: 49,
        };
        let round =
            |kind, sigma| FilterSpec { kind, sigma, elongation: 1.0, orientation_deg: 0.0, support: 49 };
        let scales = [SQRT2, 2.0, 2.0 * SQRT2];
        let mut specs = Vec::new();
        for kind in [FilterKind::FirstDerivative, FilterKind::SecondDerivative] {
            for s in scales {
                specs.extend((0..6).map(|k| oriented(kind, s, k)));
            }
        }
        let round_scales = [SQRT2, 2.0, 2.0 * SQRT2, 4.0];
        specs.extend(round_scales.iter().map(|&s| round(FilterKind::Laplacian, s)));
        specs.extend(round_scales.iter().map(|&s| round(FilterKind::Laplacian, 3.0 * s)));
        specs.extend(round_scales.iter().map(|&s| round(FilterKind::Gaussian, s)));
        specs
    }

    fn filter(spec: FilterSpec) -> Filter {
        Filter::new(spec).unwrap()
    }

    /// Response at the kernel centre of an image given by `f(x, y)` in y-up coordinates.
    fn response(filter: &Filter, f: impl Fn(f64, f64) -> f64) -> f64 {
        let (size, half) = (filter.size(), filter.half() as f64);
        let w = filter.weights();
        (0..size * size).map(|i| w[i] as f64 * f((i % size) as f64 - half, half - (i / size) as f64)).sum()
    }

    /// A step edge through the origin along angle `phi`, bright on its +v side.
    fn step(phi: f64) -> impl Fn(f64, f64) -> f64 {
        let (s, c) = phi.sin_cos();
        move |x, y| {
            let d = -x * s + y * c;
            if d.abs() < 1e-9 {
                0.5
            } else {
                f64::from(d > 0.0)
            }
        }
    }

    fn bar(phi: f64) -> impl Fn(f64, f64) -> f64 {
        let (s, c) = phi.sin_cos();
        move |x, y| f64::from((-x * s + y * c).abs() < 1.0)
    }

    #[test]
    fn lm48_matches_the_reference_definition() {
        let bank = FilterBank::lm48();
        assert_eq!(bank.len(), 48);
        assert_eq!(bank.name(), "LM48");
        let specs = reference_specs();
        for (i, (f, spec)) in bank.filters().iter().zip(&specs).enumerate() {
            let got = f.spec();
            assert_eq!((got.kind, got.support), (spec.kind, spec.support), "filter {i}");
            assert!((got.sigma - spec.sigma).abs() < 1e-12, "filter {i} sigma");
            assert!((got.elongation - spec.elongation).abs() < 1e-12, "filter {i} elongation");
            assert!((got.orientation_deg - spec.orientation_deg).abs() < 1e-12, "filter {i} orientation");
            assert_eq!(f.weights().len(), 49 * 49);
            let sum: f64 = f.weights().iter().map(|&w| w as f64).sum();
            let l1: f64 = f.weights().iter().map(|&w| (w as f64).abs()).sum();
            assert!((l1 - 1.0).abs() < 1e-5, "filter {i}: L1 {l1}");
            if spec.kind.is_zero_mean() {
                assert!(sum.abs() < 1e-5, "filter {i}: sum {sum}");
            } else {
                assert!((sum - 1.0).abs() < 1e-5, "gaussian {i}: sum {sum}");
            }
        }
        let (d1, d2, log, gauss) = (0, 18, 36, 44);
        let kinds = bank.filters().iter().map(|f| f.spec().kind).collect::<Vec<_>>();
        assert!(kinds[d1..d2].iter().all(|&k| k == FilterKind::FirstDerivative));
        assert!(kinds[d2..log].iter().all(|&k| k == FilterKind::SecondDerivative));
        assert!(kinds[log..gauss].iter().all(|&k| k == FilterKind::Laplacian));
        assert!(kinds[gauss..].iter().all(|&k| k == FilterKind::Gaussian));
    }

    #[test]
    fn first_derivative_answers_an_edge_and_its_mirror_image_with_opposite_signs() {
        for spec in reference_specs().into_iter().filter(|s| s.kind == FilterKind::FirstDerivative) {
            let f = filter(spec);
            let phi = spec.orientation_deg.to_radians();
            let edge = response(&f, step(phi));
            // Reflecting the edge across its own line swaps its bright and dark sides.
            let mirrored = response(&f, step(phi + std::f64::consts::PI));
            assert!(edge > 0.3, "{spec:?}: {edge} (bright on +v must answer positively)");
            assert!((edge + mirrored).abs() < 1e-5 * edge, "{spec:?}: {edge} vs {mirrored}");
        }
    }

    #[test]
    fn orientation_k_answers_most_strongly_to_an_edge_at_k_pi_over_6() {
        let angles: Vec<f64> = (0..12).map(|j| j as f64 * std::f64::consts::PI / 12.0).collect();
        for spec in reference_specs().into_iter().filter(|s| s.elongation > 1.0) {
            let f = filter(spec);
            let best = angles
                .iter()
                .map(|&phi| match spec.kind {
                    FilterKind::FirstDerivative => response(&f, step(phi)).abs(),
                    _ => response(&f, bar(phi)).abs(),
                })
                .enumerate()
                .fold((0, -1.0), |best, (j, r)| if r > best.1 { (j, r) } else { best });
            let expected = (spec.orientation_deg / 15.0).round() as usize;
            assert_eq!(best.0, expected, "{spec:?} peaks at {}°", best.0 * 15);
        }
    }

    #[test]
    fn second_derivative_and_laplacian_are_negative_on_a_bright_bar() {
        let bank = FilterBank::lm48();
        let d2 = &bank.filters()[18];
        assert!(response(d2, bar(0.0)) < -0.1);
        let log = &bank.filters()[36];
        assert!(response(log, |x, y| f64::from(x * x + y * y < 4.0)) < -0.1);
    }

    #[test]
    fn defaults_apply_when_fields_are_left_out() {
        let text = "support = 7\nfilters = [ { kind = \"laplacian\", sigma = 1.0 }, \
                    { kind = \"gaussian\", sigma = 1.0, support = 3 } ]";
        let bank = FilterBank::from_toml_str(text, "mine.toml").unwrap();
        assert_eq!(bank.name(), "mine.toml");
        let (a, b) = (bank.filters()[0].spec(), bank.filters()[1].spec());
        assert_eq!((a.elongation, a.orientation_deg, a.support), (1.0, 0.0, 7));
        assert_eq!(b.support, 3);
        assert_eq!(bank.max_half(), 3);
    }

    #[test]
    fn bad_banks_are_rejected_with_the_file_and_the_problem() {
        let cases = [
            ("filters = [", "not a valid filter bank: line 1, column 12: unclosed array"),
            ("support = 9\nfilters = []", "no filters"),
            ("support = 9\nfilters = [{ kind = \"sobel\", sigma = 1.0 }]", "sobel"),
            ("support = 9\nfilters = [{ kind = \"gaussian\", sigma = 1.0, sgima = 2 }]", "line 2, column 46: unknown field `sgima`"),
            ("filters = [{ kind = \"gaussian\", sigma = 1.0 }]", "filter 0: no `support`"),
            ("support = 8\nfilters = [{ kind = \"gaussian\", sigma = 1.0 }]", "odd"),
            ("support = 9999\nfilters = [{ kind = \"gaussian\", sigma = 1.0 }]", "odd"),
            ("support = 9\nfilters = [{ kind = \"gaussian\", sigma = 1.0 }, { kind = \"gaussian\", sigma = -1.0 }]", "filter 1: sigma"),
            ("support = 9\nfilters = [{ kind = \"gaussian\", sigma = 1.0, elongation = 0 }]", "elongation"),
            ("support = 9\nfilters = [{ kind = \"gaussian\", sigma = nan }]", "sigma"),
            ("support = 1\nfilters = [{ kind = \"first_derivative\", sigma = 1.0 }]", "vanishes"),
        ];
        for (text, needle) in cases {
            let err = FilterBank::from_toml_str(text, "bank.toml").unwrap_err().to_string();
            assert!(err.starts_with("bank.toml: "), "{text:?} -> {err}");
            assert!(err.contains(needle), "{text:?} -> {err}");
            assert!(!err.contains('\n'), "{text:?} -> {err}");
        }
    }

    #[test]
    fn from_file_reads_a_copy_of_the_default_and_names_a_missing_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("copy.toml");
        std::fs::write(&path, LM48_TOML).unwrap();
        assert_eq!(FilterBank::from_file(&path).unwrap(), FilterBank::lm48());
        let missing = dir.path().join("missing.toml");
        let err = FilterBank::from_file(&missing).unwrap_err().to_string();
        assert!(err.contains("missing.toml"), "{err}");
    }

    #[test]
    fn contact_sheet_lays_out_every_kernel_around_mid_grey() {
        let bank = FilterBank::lm48();
        let sheet = bank.contact_sheet();
        assert_eq!((sheet.width, sheet.height), (12 * 49 + 13 * 2, 4 * 49 + 5 * 2));
        assert_eq!(sheet.pixels.len(), sheet.width * sheet.height * 3);
        let grey = |x: usize, y: usize| &sheet.pixels[(y * sheet.width + x) * 3..][..3];
        assert_eq!(grey(0, 0), SHEET_GAP_RGB);
        // A corner of the first derivative is ~0 (mid-grey); the Gaussian's centre is its peak.
        assert_eq!(grey(2, 2), [128; 3]);
        let gauss_cell = (SHEET_GAP + 8 * 51, SHEET_GAP + 3 * 51);
        assert_eq!(grey(gauss_cell.0 + 24, gauss_cell.1 + 24), [255; 3]);
    }
}
