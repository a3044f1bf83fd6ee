//! Filtering a grey image with a whole [`FilterBank`] by FFT.
//!
//! The image is padded by the bank's largest kernel half-width `H` (see [`Padding`]),
//! transformed once, and multiplied by every kernel's spectrum; each product is transformed
//! back and cropped to the image. Kernel spectra are cached per FFT size, so filtering many
//! images of one size transforms each kernel once. Direct 49×49 filtering is ~50× slower.
//!
//! Responses are correlations, `response(x, y) = Σ kernel(dx, dy) · image(x + dx, y + dy)`,
//! with `(dx, dy)` the kernel offsets of [`crate::analysis::filters`]: the kernel is not
//! flipped, so a filter answers most strongly to a patch that looks like it (flipping
//! would only change the sign of the odd filters).
//!
//! Work is parallel with rayon over images and filters; each output value is computed by the
//! same arithmetic whatever the thread count, so results are reproducible bit for bit.

use super::filters::{Filter, FilterBank};
use crate::progress::Progress;
use crate::{Error, Result};
use ndarray::Array3;
use rayon::prelude::*;
use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftPlanner};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// How the image is extended past its borders before filtering.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Padding {
    /// Symmetric reflection, the edge pixel repeated (`… c b a | a b c | c b a …`). For an
    /// image narrower than the kernel the reflection repeats: the row is extended as the
    /// periodic sequence `a b c c b a a b c c b a …`, so every kernel tap sees a real pixel.
    /// The default: it invents no edges at the borders of an ordinary photograph.
    #[default]
    Mirror,
    /// Wrap-around, for tileable samples: the image is treated as one period of an infinite
    /// tiling, at any size relative to the kernel.
    Wrap,
}

impl Padding {
    /// [`Padding::Wrap`] for a tileable sample, [`Padding::Mirror`] otherwise.
    pub fn from_tileable(tileable: bool) -> Self {
        if tileable {
            Padding::Wrap
        } else {
            Padding::Mirror
        }
    }

    /// The source index for position `i` (which may lie outside `0..n`) of a row of `n`.
    fn source(self, i: isize, n: usize) -> usize {
        let n = n as isize;
        match self {
            Padding::Wrap => i.rem_euclid(n) as usize,
            Padding::Mirror => {
                let m = i.rem_euclid(2 * n);
                (if m < n { m } else { 2 * n - 1 - m }) as usize
            }
        }
    }
}

/// Filters images with one bank, caching the kernels' spectra per image size.
///
/// Shareable between threads. The cache keeps one entry per distinct FFT size seen, of
/// `filters × (fw / 2 + 1) × fh` complex values: with LM48, 2.4 MB for 64×64 images and
/// 60 MB for 512×512; drop the convolver to free it.
pub struct BankConvolver {
    bank: FilterBank,
    plans: Mutex<HashMap<(usize, usize), Arc<SizePlan>>>,
}

/// FFT plans and kernel spectra for one padded size.
struct SizePlan {
    /// FFT width and height (≥ image size + 2 × the bank's largest half-width).
    fw: usize,
    fh: usize,
    r2c: Arc<dyn RealToComplex<f32>>,
    c2r: Arc<dyn ComplexToReal<f32>>,
    col_forward: Arc<dyn Fft<f32>>,
    col_inverse: Arc<dyn Fft<f32>>,
    /// Per filter: the conjugated spectrum (conjugation turns the product into a
    /// correlation) scaled by 1 / (fw × fh) (undoing the unnormalised inverse), stored
    /// column-major like every spectrum here: `[fw / 2 + 1][fh]`.
    kernels: Vec<Vec<Complex<f32>>>,
}

impl BankConvolver {
    /// A convolver for `bank`; nothing is computed until the first image.
    pub fn new(bank: FilterBank) -> Self {
        BankConvolver { bank, plans: Mutex::new(HashMap::new()) }
    }

    /// The bank every image is filtered with.
    pub fn bank(&self) -> &FilterBank {
        &self.bank
    }

    /// Filters one `width × height` row-major image with every filter of the bank.
    ///
    /// Returns the responses as an array of shape `(filters, height, width)`: plane `i` is
    /// filter `i`'s response. Fails if the sizes do not match `image.len()`, are zero, or the
    /// image holds NaN or infinity (which the FFT would spread over the whole plane).
    pub fn filter(
        &self,
        image: &[f32],
        width: usize,
        height: usize,
        padding: Padding,
    ) -> Result<Array3<f32>> {
        check_image(image, width, height)?;
        let plan = self.plan(width, height)?;
        self.filter_with(&plan, image, width, height, padding)
    }

    /// Filters several images of one size, in parallel; `progress` advances by one per image
    /// (stage "filtering"). Returns one `(filters, height, width)` array per image, in order.
    pub fn filter_many(
        &self,
        images: &[&[f32]],
        width: usize,
        height: usize,
        padding: Padding,
        progress: &dyn Progress,
    ) -> Result<Vec<Array3<f32>>> {
        for (i, image) in images.iter().enumerate() {
            check_image(image, width, height).map_err(|e| Error::invalid(format!("image {i}: {e}")))?;
        }
        // Built before the parallel loop so the workers share one plan instead of racing
        // to build it.
        let plan = self.plan(width, height)?;
        progress.start("filtering", images.len() as u64);
        let out = images
            .par_iter()
            .map(|image| {
                let r = self.filter_with(&plan, image, width, height, padding);
                progress.advance(1);
                r
            })
            .collect();
        progress.finish();
        out
    }

    fn filter_with(
        &self,
        plan: &Arc<SizePlan>,
        image: &[f32],
        width: usize,
        height: usize,
        padding: Padding,
    ) -> Result<Array3<f32>> {
        let sized = SizedBank { convolver: self, plan: plan.clone(), size: (width, height) };
        let spectrum = sized.spectrum(image, padding)?;
        let mut out = vec![0f32; self.bank.len() * width * height];
        sized.respond_many(&spectrum, &sized.kernels(0..self.bank.len())?, &mut out)?;
        Array3::from_shape_vec((self.bank.len(), height, width), out)
            .map_err(|e| Error::internal(format!("shaping filter responses: {e}")))
    }

    /// The bank ready for images of `width × height`, to filter them a few filters at a
    /// time ([`SizedBank`]). Its kernel spectra are the cached ones where this size was
    /// filtered before; else they are made when asked for ([`SizedBank::kernels`]) and
    /// freed by the caller, never cached: a pyramid level is filtered once, and at 512² the
    /// bank's spectra take 60 MB.
    pub fn sized(&self, width: usize, height: usize) -> Result<SizedBank<'_>> {
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!("cannot filter a {width}×{height} image: it has no pixels")));
        }
        let half = self.bank.max_half();
        let key = (fft_len(width + 2 * half), fft_len(height + 2 * half));
        let plan = match self.cached(key) {
            Some(plan) => plan,
            None => Arc::new(SizePlan::bare(key.0, key.1)),
        };
        Ok(SizedBank { convolver: self, plan, size: (width, height) })
    }

    /// The cached plan for images of this size, built on first use.
    fn plan(&self, width: usize, height: usize) -> Result<Arc<SizePlan>> {
        let half = self.bank.max_half();
        let key = (fft_len(width + 2 * half), fft_len(height + 2 * half));
        if let Some(plan) = self.cached(key) {
            return Ok(plan);
        }
        // Built without holding the lock: the build runs rayon tasks, and a worker waiting
        // inside it may pick up another image's task that needs the lock.
        let plan = Arc::new(SizePlan::new(key.0, key.1, &self.bank)?);
        let mut plans = self.plans.lock().unwrap_or_else(|p| p.into_inner());
        Ok(plans.entry(key).or_insert(plan).clone())
    }

    fn cached(&self, key: (usize, usize)) -> Option<Arc<SizePlan>> {
        let plans = self.plans.lock().unwrap_or_else(|p| p.into_inner());
        plans.get(&key).cloned()
    }
}

/// A bank's FFT plans for images of one size ([`BankConvolver::sized`]): an image is
/// transformed once ([`SizedBank::spectrum`]), then answers any run of filters whose
/// kernels' spectra the caller holds ([`SizedBank::kernels`], [`SizedBank::respond_many`]),
/// so that a caller holds a few filters' responses at a time rather than the whole bank's
/// (at 512², 50 MB per image), and the spectra of the kernels or of the images, whichever
/// are fewer.
pub struct SizedBank<'a> {
    convolver: &'a BankConvolver,
    plan: Arc<SizePlan>,
    size: (usize, usize),
}

/// The spectrum of one padded image, as [`SizedBank::spectrum`] makes it.
pub struct ImageSpectrum(Vec<Complex<f32>>);

/// The spectra of a run of the bank's kernels, as [`SizedBank::kernels`] gives them.
pub struct KernelSpectra<'a>(std::borrow::Cow<'a, [Vec<Complex<f32>>]>);

impl KernelSpectra<'_> {
    /// Number of kernels.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The kernels `range` of these, borrowed.
    pub fn slice(&self, range: std::ops::Range<usize>) -> KernelSpectra<'_> {
        KernelSpectra(std::borrow::Cow::Borrowed(&self.0[range]))
    }
}

impl SizedBank<'_> {
    /// The transform of `image` (`width × height` row-major, finite) padded by `padding`.
    pub fn spectrum(&self, image: &[f32], padding: Padding) -> Result<ImageSpectrum> {
        let ((width, height), plan) = (self.size, &self.plan);
        check_image(image, width, height)?;
        let half = self.convolver.bank.max_half();
        let mut padded = pad(image, width, height, half, padding, plan.fw, plan.fh);
        Ok(ImageSpectrum(plan.forward(&mut padded)?))
    }

    /// The spectra of the kernels of `filters` (bank indices): the cached ones, or made
    /// now, in parallel, the same values.
    pub fn kernels(&self, filters: std::ops::Range<usize>) -> Result<KernelSpectra<'_>> {
        if let Some(cached) = self.plan.kernels.get(filters.clone()) {
            return Ok(KernelSpectra(std::borrow::Cow::Borrowed(cached)));
        }
        let bank = self.convolver.bank.filters().get(filters.clone()).ok_or_else(|| {
            Error::internal(format!("filters {filters:?} of a bank of {}", self.convolver.bank.len()))
        })?;
        let made = bank.par_iter().map(|filter| self.plan.kernel_spectrum(filter)).collect::<Result<_>>()?;
        Ok(KernelSpectra(std::borrow::Cow::Owned(made)))
    }

    /// The responses of the image of `spectrum` to each kernel of `kernels`, one plane of
    /// `width × height` after the other in `out` (as many planes as kernels); the same
    /// values as [`BankConvolver::filter`]'s. The kernels run in parallel.
    pub fn respond_many(
        &self,
        spectrum: &ImageSpectrum,
        kernels: &KernelSpectra,
        out: &mut [f32],
    ) -> Result<()> {
        let (width, height) = self.size;
        if out.len() != kernels.len() * width * height {
            return Err(Error::internal(format!(
                "{} values are not the responses to {} kernels",
                out.len(),
                kernels.len()
            )));
        }
        let half = self.convolver.bank.max_half();
        out.par_chunks_mut(width * height).zip(kernels.0.par_iter()).try_for_each(|(plane, kernel)| {
            self.plan.respond(&spectrum.0, kernel, (half, half), self.size, plane)
        })
    }
}

/// Bytes of one spectrum of the FFT frame that `bank` filters `width × height` images in
/// (a kernel's, an image's, or a product's while a response is made).
pub fn spectrum_bytes(bank: &FilterBank, width: usize, height: usize) -> u64 {
    let half = bank.max_half();
    let (fw, fh) = (fft_len(width + 2 * half), fft_len(height + 2 * half));
    ((fw / 2 + 1) * fh * std::mem::size_of::<Complex<f32>>()) as u64
}

/// Filters one image with `bank` (see [`BankConvolver::filter`]). Transforms every kernel
/// on each call: to filter many images, keep a [`BankConvolver`].
pub fn convolve_bank(
    image: &[f32],
    width: usize,
    height: usize,
    bank: &FilterBank,
    padding: Padding,
) -> Result<Array3<f32>> {
    BankConvolver::new(bank.clone()).filter(image, width, height, padding)
}

/// The response of one filter computed directly from the definition, O(K²) per pixel.
/// The reference the FFT path is tested against; returns a `width × height` plane.
pub fn correlate_direct(
    image: &[f32],
    width: usize,
    height: usize,
    filter: &Filter,
    padding: Padding,
) -> Result<Vec<f32>> {
    check_image(image, width, height)?;
    let (size, half) = (filter.size(), filter.half() as isize);
    let at = |x: isize, y: isize| image[padding.source(y, height) * width + padding.source(x, width)] as f64;
    let pixel = |x: isize, y: isize| -> f32 {
        let taps = filter.weights().chunks_exact(size).enumerate();
        let sum: f64 = taps
            .flat_map(|(r, row)| {
                let dy = r as isize - half;
                row.iter().enumerate().map(move |(c, &w)| (c as isize - half, dy, w))
            })
            .map(|(dx, dy, w)| w as f64 * at(x + dx, y + dy))
            .sum();
        sum as f32
    };
    Ok((0..width * height).map(|i| pixel((i % width) as isize, (i / width) as isize)).collect())
}

fn check_image(image: &[f32], width: usize, height: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::invalid(format!("cannot filter a {width}×{height} image: it has no pixels")));
    }
    if width.checked_mul(height) != Some(image.len()) {
        return Err(Error::invalid(format!(
            "a {width}×{height} image needs {} values, got {}",
            width.saturating_mul(height),
            image.len()
        )));
    }
    if let Some(i) = image.iter().position(|v| !v.is_finite()) {
        return Err(Error::invalid(format!(
            "pixel ({}, {}) is {}; filtering needs finite values",
            i % width,
            i / width,
            image[i]
        )));
    }
    Ok(())
}

/// The image extended to the `fw × fh` FFT frame, shifted so pixel (0, 0) lands at
/// (half, half). Cells past `size + 2 × half` are filled by the same rule; no output reads them.
fn pad(
    image: &[f32],
    width: usize,
    height: usize,
    half: usize,
    padding: Padding,
    fw: usize,
    fh: usize,
) -> Vec<f32> {
    let columns: Vec<usize> = (0..fw).map(|x| padding.source(x as isize - half as isize, width)).collect();
    let mut padded = Vec::with_capacity(fw * fh);
    for y in 0..fh {
        let row = padding.source(y as isize - half as isize, height) * width;
        padded.extend(columns.iter().map(|&x| image[row + x]));
    }
    padded
}

/// The smallest even length ≥ `n` whose prime factors are all ≤ 7, where FFTs are fastest.
fn fft_len(n: usize) -> usize {
    let smooth = |mut m: usize| {
        for p in [2, 3, 5, 7] {
            while m % p == 0 {
                m /= p;
            }
        }
        m == 1
    };
    let mut m = n.max(2);
    m += m % 2;
    while !smooth(m) {
        m += 2;
    }
    m
}

fn fft_error(e: realfft::FftError) -> Error {
    Error::internal(format!("FFT: {e}"))
}

impl SizePlan {
    fn new(fw: usize, fh: usize, bank: &FilterBank) -> Result<Self> {
        let mut plan = SizePlan::bare(fw, fh);
        plan.kernels =
            bank.filters().par_iter().map(|filter| plan.kernel_spectrum(filter)).collect::<Result<_>>()?;
        Ok(plan)
    }

    /// The plans without the kernels' spectra.
    fn bare(fw: usize, fh: usize) -> Self {
        let mut real = RealFftPlanner::<f32>::new();
        let mut complex = FftPlanner::<f32>::new();
        SizePlan {
            fw,
            fh,
            r2c: real.plan_fft_forward(fw),
            c2r: real.plan_fft_inverse(fw),
            col_forward: complex.plan_fft_forward(fh),
            col_inverse: complex.plan_fft_inverse(fh),
            kernels: Vec::new(),
        }
    }

    /// One kernel's spectrum as [`SizePlan::kernels`] holds it.
    fn kernel_spectrum(&self, filter: &Filter) -> Result<Vec<Complex<f32>>> {
        let scale = 1.0 / (self.fw * self.fh) as f32;
        let mut spectrum = self.forward(&mut self.embed(filter))?;
        spectrum.iter_mut().for_each(|z| *z = z.conj() * scale);
        Ok(spectrum)
    }

    /// Number of complex columns of a spectrum (the real transform keeps half of them).
    fn cw(&self) -> usize {
        self.fw / 2 + 1
    }

    /// The kernel in the FFT frame with its centre at (0, 0), negative offsets wrapped.
    fn embed(&self, filter: &Filter) -> Vec<f32> {
        let (size, half) = (filter.size(), filter.half());
        let mut frame = vec![0f32; self.fw * self.fh];
        for (r, row) in filter.weights().chunks_exact(size).enumerate() {
            let y = (r + self.fh - half) % self.fh;
            for (c, &w) in row.iter().enumerate() {
                frame[y * self.fw + (c + self.fw - half) % self.fw] = w;
            }
        }
        frame
    }

    /// 2-D forward transform of a row-major `fw × fh` frame (used as scratch). Rows are
    /// transformed and stored transposed so that each column is contiguous for its FFT.
    fn forward(&self, frame: &mut [f32]) -> Result<Vec<Complex<f32>>> {
        let (cw, fh) = (self.cw(), self.fh);
        let mut spectrum = vec![Complex::default(); cw * fh];
        let mut row_out = self.r2c.make_output_vec();
        let mut scratch = self.r2c.make_scratch_vec();
        for (y, row) in frame.chunks_exact_mut(self.fw).enumerate() {
            self.r2c.process_with_scratch(row, &mut row_out, &mut scratch).map_err(fft_error)?;
            for (c, &z) in row_out.iter().enumerate() {
                spectrum[c * fh + y] = z;
            }
        }
        let mut col_scratch = vec![Complex::default(); self.col_forward.get_inplace_scratch_len()];
        self.col_forward.process_with_scratch(&mut spectrum, &mut col_scratch);
        Ok(spectrum)
    }

    /// One filter's response: `image spectrum × kernel`, transformed back; writes the
    /// `size` window starting at `origin` of the frame into `out` (row-major).
    fn respond(
        &self,
        spectrum: &[Complex<f32>],
        kernel: &[Complex<f32>],
        origin: (usize, usize),
        size: (usize, usize),
        out: &mut [f32],
    ) -> Result<()> {
        let (cw, fh) = (self.cw(), self.fh);
        let mut product: Vec<Complex<f32>> = spectrum.iter().zip(kernel).map(|(a, b)| a * b).collect();
        let mut col_scratch = vec![Complex::default(); self.col_inverse.get_inplace_scratch_len()];
        self.col_inverse.process_with_scratch(&mut product, &mut col_scratch);
        let mut row_in = self.c2r.make_input_vec();
        let mut row_out = self.c2r.make_output_vec();
        let mut scratch = self.c2r.make_scratch_vec();
        let (width, height) = size;
        for (y, out_row) in out.chunks_exact_mut(width).take(height).enumerate() {
            let fy = origin.1 + y;
            for (c, z) in row_in.iter_mut().enumerate() {
                *z = product[c * fh + fy];
            }
            // The transform of real data has real DC and Nyquist terms; rounding leaves
            // tiny imaginary parts there, which the inverse real FFT rejects.
            row_in[0].im = 0.0;
            if self.fw % 2 == 0 {
                row_in[cw - 1].im = 0.0;
            }
            self.c2r.process_with_scratch(&mut row_in, &mut row_out, &mut scratch).map_err(fft_error)?;
            out_row.copy_from_slice(&row_out[origin.0..origin.0 + width]);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::filters::{FilterKind, FilterSpec};
    use crate::progress::Silent;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_image(width: usize, height: usize, seed: u64) -> Vec<f32> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..width * height).map(|_| rng.random::<f32>()).collect()
    }

    fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
        a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
    }

    /// FFT responses of every filter against the direct definition.
    fn assert_matches_direct(bank: &FilterBank, width: usize, height: usize, padding: Padding) {
        let image = random_image(width, height, (width * 1000 + height) as u64);
        let fft = convolve_bank(&image, width, height, bank, padding).unwrap();
        assert_eq!(fft.dim(), (bank.len(), height, width));
        for (i, filter) in bank.filters().iter().enumerate() {
            let direct = correlate_direct(&image, width, height, filter, padding).unwrap();
            let plane = fft.index_axis(ndarray::Axis(0), i);
            let err = max_abs_diff(plane.as_slice().unwrap(), &direct);
            assert!(err < 1e-4, "{width}×{height} {padding:?} filter {i}: max error {err}");
        }
    }

    #[test]
    fn fft_equals_direct_convolution_for_both_paddings() {
        let bank = FilterBank::lm48();
        for padding in [Padding::Mirror, Padding::Wrap] {
            assert_matches_direct(&bank, 23, 14, padding);
        }
    }

    #[test]
    fn fft_equals_direct_convolution_on_images_smaller_than_the_kernel() {
        let bank = FilterBank::lm48();
        for padding in [Padding::Mirror, Padding::Wrap] {
            for (w, h) in [(8, 8), (5, 3), (1, 1)] {
                assert_matches_direct(&bank, w, h, padding);
            }
        }
    }

    #[test]
    fn filters_of_different_supports_share_one_padding() {
        let spec = |kind, sigma, support| FilterSpec {
            kind,
            sigma,
            elongation: 2.0,
            orientation_deg: 20.0,
            support,
        };
        let specs = vec![
            spec(FilterKind::FirstDerivative, 1.0, 5),
            spec(FilterKind::Laplacian, 3.0, 21),
            spec(FilterKind::Gaussian, 0.7, 1),
        ];
        let bank = FilterBank::from_specs("mixed", specs).unwrap();
        assert_matches_direct(&bank, 17, 30, Padding::Mirror);
        assert_matches_direct(&bank, 17, 30, Padding::Wrap);
    }

    #[test]
    fn mirror_padding_repeats_its_reflection() {
        let rows: Vec<usize> = (-7..10).map(|i| Padding::Mirror.source(i, 3)).collect();
        // … c b a | a b c | c b a …, starting at -7.
        assert_eq!(rows, [0, 0, 1, 2, 2, 1, 0, 0, 1, 2, 2, 1, 0, 0, 1, 2, 2]);
        let rows: Vec<usize> = (-4..4).map(|i| Padding::Wrap.source(i, 3)).collect();
        assert_eq!(rows, [2, 0, 1, 2, 0, 1, 2, 0]);
        assert!((-5..5).all(|i| Padding::Mirror.source(i, 1) == 0));
    }

    #[test]
    fn wrap_padding_commutes_with_circular_shifts() {
        let (w, h, (sx, sy)) = (19, 12, (5, 7));
        let image = random_image(w, h, 3);
        let shifted: Vec<f32> =
            (0..w * h).map(|i| image[((i / w + h - sy) % h) * w + (i % w + w - sx) % w]).collect();
        let conv = BankConvolver::new(FilterBank::lm48());
        let a = conv.filter(&image, w, h, Padding::Wrap).unwrap();
        let b = conv.filter(&shifted, w, h, Padding::Wrap).unwrap();
        for ((f, y, x), &v) in a.indexed_iter() {
            let u = b[[f, (y + sy) % h, (x + sx) % w]];
            assert!((u - v).abs() < 1e-5, "filter {f} at ({x}, {y}): {v} vs {u}");
        }
    }

    #[test]
    fn filter_many_reuses_one_plan_and_matches_single_images() {
        let conv = BankConvolver::new(FilterBank::lm48());
        let images: Vec<Vec<f32>> = (0..3).map(|s| random_image(16, 9, s)).collect();
        let refs: Vec<&[f32]> = images.iter().map(Vec::as_slice).collect();
        let many = conv.filter_many(&refs, 16, 9, Padding::Mirror, &Silent).unwrap();
        assert_eq!(conv.plans.lock().unwrap().len(), 1);
        for (image, responses) in images.iter().zip(&many) {
            assert_eq!(conv.filter(image, 16, 9, Padding::Mirror).unwrap(), *responses);
        }
    }

    #[test]
    fn bad_images_are_rejected() {
        let conv = BankConvolver::new(FilterBank::lm48());
        let err = |image: &[f32], w, h| conv.filter(image, w, h, Padding::Mirror).unwrap_err().to_string();
        assert!(err(&[], 0, 0).contains("no pixels"));
        assert!(err(&[0.0; 5], 2, 3).contains("needs 6 values, got 5"));
        assert!(err(&[0.0, f32::NAN, 0.0, 0.0], 2, 2).contains("pixel (1, 0) is NaN"));
        let e = conv.filter_many(&[&[0.0; 4], &[0.0; 3]], 2, 2, Padding::Wrap, &Silent).unwrap_err();
        assert!(e.to_string().starts_with("image 1: "), "{e}");
    }

    #[test]
    fn fft_lengths_are_even_and_7_smooth() {
        assert_eq!(fft_len(1), 2);
        assert_eq!(fft_len(112), 112);
        assert_eq!(fft_len(113), 120);
        assert_eq!(fft_len(561), 576);
    }
}
