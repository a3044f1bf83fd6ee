//! Principal images: a stack of images as mean + Σ coordinates × orthonormal components.
//!
//! Filtering is linear, so the filter responses of any image are the same combination of the
//! responses of the mean and the components. btfsynth therefore filters r + 1 basis images
//! instead of every image, and — because the components are orthonormal and the centred
//! coordinates sum to zero — the dot products of the paper's concatenated response vectors
//! are reproduced exactly by r + 1 scaled blocks (see [`PrincipalImages::block_weights`]).
//! Truncating to the components that hold 99.9% of the variance is the only approximation.

use super::products::{accumulate_by_columns, accumulate_by_rows, rows_in_parallel};
use crate::seeded::normal;
use crate::{Error, Result};
use ndarray::{s, Array1, Array2, ArrayView2, Axis};
use rayon::prelude::*;

/// How the basis is computed.
#[derive(Clone, Copy, Debug)]
pub struct BasisOptions {
    /// Fraction of the centred variance to keep (default 0.999).
    pub energy: f64,
    /// Most components kept (default 64).
    pub max_rank: usize,
    /// Stacks with more images than this use a randomized range finder (default 1024).
    pub exact_limit: usize,
    /// Seed of the randomized range finder's test matrix (default 0).
    pub seed: u64,
}

impl Default for BasisOptions {
    fn default() -> Self {
        BasisOptions { energy: 0.999, max_rank: 64, exact_limit: 1024, seed: 0 }
    }
}

/// Image `a` ≈ `mean + Σₖ coords[a, k] · components[k]`.
#[derive(Clone, Debug)]
pub struct PrincipalImages {
    /// The mean image (P values).
    pub mean: Array1<f32>,
    /// r orthonormal component images, one per row (r × P).
    pub components: Array2<f32>,
    /// Singular values σₖ of the centred stack, decreasing.
    pub sigma: Vec<f32>,
    /// Coordinates of every image (n × r); column k has norm σₖ.
    pub coords: Array2<f32>,
    /// Fraction of the centred variance the components hold.
    pub energy: f64,
}

impl PrincipalImages {
    /// Weights that make the blocks [mean, component 1, …, component r] reproduce the dot
    /// products of the n images' concatenated (linear) features: Σₐ f(Iₐ)·g(Iₐ) =
    /// n f(m)·g(m) + Σₖ σₖ² f(Pₖ)·g(Pₖ), so block 0 is weighted √n and block k by σₖ.
    pub fn block_weights(&self) -> Vec<f32> {
        let n = self.coords.nrows() as f32;
        std::iter::once(n.sqrt()).chain(self.sigma.iter().copied()).collect()
    }
}

/// The principal images of `images` (one image per row).
pub fn principal_images(images: ArrayView2<f32>, options: &BasisOptions) -> Result<PrincipalImages> {
    if images.nrows() == 0 || images.ncols() == 0 {
        return Err(Error::invalid("principal images of an empty stack"));
    }
    let mean = images.mean_axis(Axis(0)).unwrap_or_else(|| Array1::zeros(images.ncols()));
    let centred = &images - &mean;
    let total: f64 = centred.iter().map(|&v| (v as f64) * (v as f64)).sum();
    if total <= 0.0 {
        // Every image is the same (e.g. a one-image BTF): the mean says it all.
        return Ok(PrincipalImages {
            mean,
            components: Array2::zeros((0, images.ncols())),
            sigma: vec![],
            coords: Array2::zeros((images.nrows(), 0)),
            energy: 1.0,
        });
    }
    let (range, rows) = if images.nrows() <= options.exact_limit {
        (None, centred)
    } else {
        let q = randomized_range(&centred, options.max_rank + 10, options.seed);
        let b = q.t().dot(&centred);
        (Some(q), b)
    };
    from_range(mean, total, range, rows, options)
}

/// The principal images once the centred rows are known through `rows`: the centred stack
/// itself (`range` none), or its projection on the orthonormal columns `range`.
fn from_range(
    mean: Array1<f32>,
    total: f64,
    range: Option<Array2<f32>>,
    rows: Array2<f32>,
    options: &BasisOptions,
) -> Result<PrincipalImages> {
    let (u, lambda) = leading_eigenvectors(&rows.dot(&rows.t()))?;
    let rank = kept_rank(&lambda, total, options);
    let sigma: Vec<f32> = lambda[..rank].iter().map(|l| l.sqrt() as f32).collect();
    let u = u.slice(s![.., ..rank]).to_owned();
    let inverse = Array1::from_iter(sigma.iter().map(|s| 1.0 / s));
    let components = (&u * &inverse).t().dot(&rows);
    let local = &u * &Array1::from_vec(sigma.clone());
    let coords = match range {
        Some(q) => q.dot(&local),
        None => local,
    };
    let energy = lambda[..rank].iter().sum::<f64>() / total;
    Ok(PrincipalImages { mean, components, sigma, coords, energy: energy.min(1.0) })
}

/// A stack of rows made a block at a time (e.g. every pixel's neighbourhood), too large to
/// hold whole.
pub trait RowSource: Sync {
    /// Number of rows.
    fn rows(&self) -> usize;
    /// Values per row.
    fn cols(&self) -> usize;
    /// Rows `start..start + len`, one per row of a row-major array.
    fn block(&self, start: usize, len: usize) -> Array2<f32>;
}

/// Images per rayon task in the streamed basis' products that split the images.
const TASK_ROWS: usize = 64;
/// Values per rayon task in the streamed basis' products that split the pixels.
const TASK_PIXELS: usize = 1024;

/// Rows per block of [`principal_images_streamed`] for rows of `cols` values: about 16 MB
/// of values, and a multiple of the GEMM's depth block (matrixmultiply's 256 for f32), so
/// that products summed over the rows add the same partial sums in the same order as one
/// product over all rows.
fn stream_rows(cols: usize) -> usize {
    ((1 << 22) / cols.max(1) / 256).max(1) * 256
}

/// [`principal_images`] of the rows of `source`, the same to the bit, without holding them:
/// each pass over the stack (mean, energy and sketch, power iteration, projection) makes
/// the rows again a block at a time. At most `options.exact_limit` rows are made at once
/// and handed to [`principal_images`].
pub fn principal_images_streamed(source: &dyn RowSource, options: &BasisOptions) -> Result<PrincipalImages> {
    streamed_in_blocks(source, options, stream_rows(source.cols()))
}

fn streamed_in_blocks(
    source: &dyn RowSource,
    options: &BasisOptions,
    block: usize,
) -> Result<PrincipalImages> {
    let (n, p) = (source.rows(), source.cols());
    if n <= options.exact_limit || p == 0 {
        return principal_images(source.block(0, n).view(), options);
    }
    let blocks = || (0..n).step_by(block).map(move |start| (start, block.min(n - start)));
    // As `mean_axis` sums a row-major stack: row after row, in order.
    let mut sum = Array1::<f32>::zeros(p);
    for (start, len) in blocks() {
        source.block(start, len).rows().into_iter().for_each(|row| sum += &row);
    }
    let mean = sum / n as f32;
    let centred = |start: usize, len: usize| {
        let mut block = source.block(start, len);
        if let Some(values) = block.as_slice_mut() {
            let subtract = |row: &mut [f32]| row.iter_mut().zip(&mean).for_each(|(v, m)| *v -= m);
            values.par_chunks_mut(p).for_each(subtract);
        } else {
            block -= &mean;
        }
        block
    };
    let q = (options.max_rank + 10).min(n).min(p);
    let omega = Array2::from_shape_fn((p, q), |(i, j)| normal(options.seed, i as i64, j as i64));
    let (mut total, mut y) = (0f64, Array2::<f32>::zeros((n, q)));
    for (start, len) in blocks() {
        let c = centred(start, len);
        // The energy is one running sum in order, so it takes a core beside the product.
        let (sum, product) = rayon::join(
            || c.iter().fold(total, |t, &v| t + (v as f64) * (v as f64)),
            || rows_in_parallel(c.view(), omega.view(), TASK_ROWS),
        );
        total = sum;
        y.slice_mut(s![start..start + len, ..]).assign(&product);
    }
    if total <= 0.0 {
        return Ok(PrincipalImages {
            mean,
            components: Array2::zeros((0, p)),
            sigma: vec![],
            coords: Array2::zeros((n, 0)),
            energy: 1.0,
        });
    }
    // The power iteration of `randomized_range`: Y = C (Cᵀ orth(C Ω)).
    let first = orthonormal_columns(y);
    let mut z = Array2::<f32>::zeros((p, q));
    for (start, len) in blocks() {
        let beta = if start == 0 { 0.0 } else { 1.0 };
        let part = first.slice(s![start..start + len, ..]);
        accumulate_by_rows(centred(start, len).t(), part, beta, z.view_mut(), TASK_PIXELS);
    }
    drop(first);
    let mut y = Array2::<f32>::zeros((n, q));
    for (start, len) in blocks() {
        y.slice_mut(s![start..start + len, ..]).assign(&rows_in_parallel(
            centred(start, len).view(),
            z.view(),
            TASK_ROWS,
        ));
    }
    let range = orthonormal_columns(y);
    let mut b = Array2::<f32>::zeros((q, p));
    for (start, len) in blocks() {
        let beta = if start == 0 { 0.0 } else { 1.0 };
        let part = range.slice(s![start..start + len, ..]);
        accumulate_by_columns(part.t(), centred(start, len).view(), beta, b.view_mut(), TASK_PIXELS);
    }
    from_range(mean, total, Some(range), b, options)
}

/// A stack known as a product of low rank: image `a` is `offset + coords[a] · rows`, exactly
/// (the factors of a DFMF file whose decoding is linear) or up to the energy `outside` the
/// rows' span (a basis streamed from the images, [`streamed_basis`]).
///
/// The principal images of any subset of its images follow from q × q matrices
/// ([`principal_images_low_rank`]), and the stack moves down an image pyramid by
/// downsampling its q rows instead of every image ([`LowRankStack::map_rows`]): the
/// analysis of a 22,801-image material then touches q + 1 images' worth of values.
#[derive(Clone, Debug)]
pub struct LowRankStack {
    /// D values (interleaved RGB).
    pub offset: Array1<f32>,
    /// n × q.
    pub coords: Array2<f32>,
    /// q × D; need not be orthonormal or independent.
    pub rows: Array2<f32>,
    /// Σₐ ‖image a − its value here‖², where known (0 for exact factors).
    pub outside: f64,
}

impl LowRankStack {
    /// Number of images.
    pub fn len(&self) -> usize {
        self.coords.nrows()
    }

    /// Whether the stack holds no images.
    pub fn is_empty(&self) -> bool {
        self.coords.nrows() == 0
    }

    /// Rank of the representation (rows).
    pub fn rank(&self) -> usize {
        self.rows.nrows()
    }

    /// The images `images` (in that order) of the stack; the rows move, not copy.
    pub fn select(self, images: &[usize]) -> LowRankStack {
        let coords = self.coords.select(Axis(0), images);
        // The energy outside the span is not known per image: keep the share of the images.
        let share = images.len() as f64 / self.coords.nrows().max(1) as f64;
        LowRankStack { coords, outside: self.outside * share, ..self }
    }

    /// The stack under a linear map of images (e.g. a pyramid's downsampling): the map
    /// applied to the offset and to every row, in parallel; the coordinates stay. The
    /// energy outside the rows' span cannot be mapped without the images: it is scaled by
    /// the ratio the centred energy inside the span changed by (an estimate; exact stacks
    /// have none).
    pub fn map_rows(&self, f: impl Fn(&[f32]) -> Vec<f32> + Sync) -> LowRankStack {
        let before = if self.outside > 0.0 { self.inside_energy() } else { 0.0 };
        let mut mapped = self.map_rows_only(f);
        if mapped.outside > 0.0 {
            let after = mapped.inside_energy();
            mapped.outside *= if before > 0.0 { after / before } else { 0.0 };
        }
        mapped
    }

    /// Σₐ ‖(coords[a] − mean coords) · rows‖², the centred energy the stack represents.
    fn inside_energy(&self) -> f64 {
        let coords = self.coords.mapv(|v| v as f64);
        let cbar = coords.mean_axis(Axis(0)).unwrap_or_else(|| Array1::zeros(coords.ncols()));
        let centred = &coords - &cbar;
        let g = gram_f64(self.rows.view());
        (centred.dot(&g) * &centred).sum()
    }

    fn map_rows_only(&self, f: impl Fn(&[f32]) -> Vec<f32> + Sync) -> LowRankStack {
        use rayon::prelude::*;
        let mapped: Vec<Vec<f32>> = (0..self.rows.nrows())
            .into_par_iter()
            .map(|k| match self.rows.row(k).as_slice() {
                Some(row) => f(row),
                None => f(&self.rows.row(k).to_vec()),
            })
            .collect();
        let offset = Array1::from_vec(f(&self.offset.to_vec()));
        let d = offset.len();
        let mut rows = Array2::zeros((mapped.len(), d));
        for (mut dst, src) in rows.rows_mut().into_iter().zip(&mapped) {
            dst.assign(&ndarray::ArrayView1::from(src.as_slice()));
        }
        LowRankStack { offset, rows, coords: self.coords.clone(), outside: self.outside }
    }

    /// Image `a` (D values).
    pub fn image(&self, a: usize) -> Array1<f32> {
        self.coords.row(a).dot(&self.rows) + &self.offset
    }
}

/// The principal images of a low-rank stack (see [`LowRankStack`]), the same as
/// [`principal_images`] of its images multiplied out, up to rounding (and the randomized
/// range finder that `principal_images` uses above `options.exact_limit` images, which
/// this needs not: it is exact at any image count).
///
/// With G = R Rᵀ = V Λ Vᵀ for the rows R, Q = Λ^-½ Vᵀ R has orthonormal rows and the
/// centred images are C Q with C = (coords − mean) V Λ^½; the eigenvectors W of CᵀC give
/// the components Wᵀ Q and the coordinates C W.
pub fn principal_images_low_rank(stack: &LowRankStack, options: &BasisOptions) -> Result<PrincipalImages> {
    let (n, d) = (stack.coords.nrows(), stack.rows.ncols());
    if n == 0 || d == 0 || stack.offset.len() != d || stack.coords.ncols() != stack.rows.nrows() {
        return Err(Error::invalid("principal images of an empty or inconsistent low-rank stack"));
    }
    let coords = stack.coords.mapv(|v| v as f64);
    let cbar = coords.mean_axis(Axis(0)).unwrap_or_else(|| Array1::zeros(coords.ncols()));
    let mean = cbar.mapv(|v| v as f32).dot(&stack.rows) + &stack.offset;
    let centred = &coords - &cbar;
    let (v, g) = leading_eigenvectors_f64(&gram_f64(stack.rows.view()))?;
    let largest = g.first().copied().unwrap_or(0.0);
    let m = g.iter().take_while(|&&x| x > largest * 1e-12 && x > 0.0).count();
    let to_orthonormal = Array2::from_shape_fn((v.nrows(), m), |(i, j)| v[[i, j]] * g[j].sqrt());
    let c = centred.dot(&to_orthonormal);
    let (w, lambda) = leading_eigenvectors_f64(&c.t().dot(&c))?;
    let inside: f64 = lambda.iter().sum();
    let total = inside + stack.outside.max(0.0);
    if inside <= 0.0 || m == 0 {
        return Ok(PrincipalImages {
            mean,
            components: Array2::zeros((0, d)),
            sigma: vec![],
            coords: Array2::zeros((n, 0)),
            energy: 1.0,
        });
    }
    let rank = kept_rank(&lambda, total, options);
    let w = w.slice(s![.., ..rank]).to_owned();
    // Components: Wᵀ Λ^-½ Vᵀ R, as one (rank × q) matrix times the rows.
    let from_rows = Array2::from_shape_fn((m, v.nrows()), |(j, i)| v[[i, j]] / g[j].sqrt());
    let coefficients = w.t().dot(&from_rows).mapv(|x| x as f32);
    let components = coefficients.dot(&stack.rows);
    let coords = c.dot(&w).mapv(|x| x as f32);
    let sigma: Vec<f32> = lambda[..rank].iter().map(|l| l.sqrt() as f32).collect();
    let energy = lambda[..rank].iter().sum::<f64>() / total;
    Ok(PrincipalImages { mean, components, sigma, coords, energy: energy.min(1.0) })
}

/// R Rᵀ in f64, a block of columns at a time.
fn gram_f64(rows: ArrayView2<f32>) -> Array2<f64> {
    let q = rows.nrows();
    let mut g = Array2::<f64>::zeros((q, q));
    for start in (0..rows.ncols()).step_by(4096) {
        let end = (start + 4096).min(rows.ncols());
        let block = rows.slice(s![.., start..end]).mapv(|v| v as f64);
        g += &block.dot(&block.t());
    }
    g
}

/// Eigenvectors (columns) and eigenvalues of a symmetric f64 matrix, decreasing, ≥ 0.
fn leading_eigenvectors_f64(m: &Array2<f64>) -> Result<(Array2<f64>, Vec<f64>)> {
    symmetric_eigen_decreasing(m.nrows(), |i, j| m[[i, j]])
}

/// Eigenvectors (columns) and eigenvalues, decreasing and clamped ≥ 0, of the symmetric
/// n × n matrix whose entries `at` gives (symmetrised, as rounding may leave it not quite
/// so). faer's blocked decomposition, not nalgebra's: with one 400 × 400 Gram matrix of the
/// selected images per level, the filtering stage of a 64² × 6,561-image BTF's analysis
/// fell from 1.9 s to 0.8 s (its textons and Γ unchanged, bit for bit). It runs
/// sequentially so the result does not depend on the thread count.
fn symmetric_eigen_decreasing(n: usize, at: impl Fn(usize, usize) -> f64) -> Result<(Array2<f64>, Vec<f64>)> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::evd;
    let a = faer::Mat::<f64>::from_fn(n, n, |i, j| 0.5 * (at(i, j) + at(j, i)));
    let (mut u, mut values) = (faer::Mat::<f64>::zeros(n, n), faer::diag::Diag::<f64>::zeros(n));
    let (par, params) = (faer::Par::Seq, Default::default());
    let scratch = evd::self_adjoint_evd_scratch::<f64>(n, evd::ComputeEigenvectors::Yes, par, params);
    let mut buffer = MemBuffer::new(scratch);
    evd::self_adjoint_evd(
        a.as_ref(),
        values.as_mut(),
        Some(u.as_mut()),
        par,
        MemStack::new(&mut buffer),
        params,
    )
    .map_err(|e| Error::invalid(format!("the eigendecomposition of a {n}×{n} Gram matrix failed ({e:?})")))?;
    // faer sorts increasing.
    let vectors = Array2::from_shape_fn((n, n), |(i, c)| u[(i, n - 1 - c)]);
    Ok((vectors, (0..n).map(|c| values[n - 1 - c].max(0.0)).collect()))
}

/// How [`streamed_basis`] reads a stack.
#[derive(Clone, Copy, Debug)]
pub struct StreamOptions {
    /// Columns of the sketch: the rank of the result (default 96: the selection's 64
    /// components plus 32 of oversampling, since there is no power iteration).
    pub rank: usize,
    /// Images decoded at a time (default 32).
    pub batch: usize,
    /// Seed of the Gaussian test matrix.
    pub seed: u64,
}

impl Default for StreamOptions {
    fn default() -> Self {
        StreamOptions { rank: 96, batch: 32, seed: 0 }
    }
}

/// A low-rank basis of a stack that is never held in memory: a randomized range finder
/// (Halko, Martinsson and Tropp 2011, §4.1 with the sketch on the image side) in two
/// passes over batches of decoded images. Pass 1 sums the images and the sketch
/// Y = Σₐ xₐ ωₐᵀ (D × l, ω Gaussian), centred after the pass; Q = orth(Y). Pass 2 projects
/// every centred image on Q and measures what Q misses. Memory: D × l values (twice, in
/// f64, while orthonormalising) plus one batch; time: two decodings of the stack.
pub fn streamed_basis(
    source: &dyn crate::btf::ImageSource,
    options: &StreamOptions,
    progress: &dyn crate::progress::Progress,
) -> Result<LowRankStack> {
    let n = source.pairs().len();
    let d = source.width() * source.height() * 3;
    if n == 0 || d == 0 {
        return Err(Error::invalid("a streamed basis of an empty stack"));
    }
    let l = options.rank.min(n).min(d).max(1);
    let batch = options.batch.max(1);
    let omega = |a: usize, j: usize| normal(options.seed, a as i64, j as i64);
    let mut sum = Array1::<f64>::zeros(d);
    let mut sketch = Array2::<f32>::zeros((d, l));
    progress.start("basis: sketching the images", n as u64);
    for start in (0..n).step_by(batch) {
        let block = start..(start + batch).min(n);
        let x = decode_rows(source, block.clone())?;
        for row in x.rows() {
            sum.iter_mut().zip(row).for_each(|(s, &v)| *s += v as f64);
        }
        let w = Array2::from_shape_fn((block.len(), l), |(a, j)| omega(block.start + a, j));
        ndarray::linalg::general_mat_mul(1.0, &x.t(), &w, 1.0, &mut sketch);
        progress.advance(block.len() as u64);
    }
    progress.finish();
    let mean = sum.mapv(|s| (s / n as f64) as f32);
    // Centre: Σₐ (xₐ − m) ωₐᵀ = Y − m (Σₐ ωₐ)ᵀ.
    let omega_sum: Vec<f32> =
        (0..l).map(|j| (0..n).map(|a| omega(a, j) as f64).sum::<f64>() as f32).collect();
    for (mut row, &m) in sketch.rows_mut().into_iter().zip(&mean) {
        row.iter_mut().zip(&omega_sum).for_each(|(y, &o)| *y -= m * o);
    }
    let q = orthonormal_columns(sketch);
    let mut coords = Array2::<f32>::zeros((n, l));
    let (mut total, mut captured) = (0f64, 0f64);
    progress.start("basis: projecting the images", n as u64);
    for start in (0..n).step_by(batch) {
        let block = start..(start + batch).min(n);
        let mut x = decode_rows(source, block.clone())?;
        x -= &mean;
        total += x.iter().map(|&v| v as f64 * v as f64).sum::<f64>();
        let b = x.dot(&q);
        captured += b.iter().map(|&v| v as f64 * v as f64).sum::<f64>();
        coords.slice_mut(s![block, ..]).assign(&b);
        progress.advance(b.nrows() as u64);
    }
    progress.finish();
    Ok(LowRankStack { offset: mean, coords, rows: q.reversed_axes(), outside: (total - captured).max(0.0) })
}

/// The images of `block` decoded, one per row, in f32.
fn decode_rows(source: &dyn crate::btf::ImageSource, block: std::ops::Range<usize>) -> Result<Array2<f32>> {
    use rayon::prelude::*;
    let d = source.width() * source.height() * 3;
    let mut rows = Array2::<f32>::zeros((block.len(), d));
    let flat = rows.as_slice_mut().ok_or_else(|| Error::internal("batch buffer is not contiguous"))?;
    flat.par_chunks_mut(d).zip(block.into_par_iter()).try_for_each(|(out, i)| {
        let mut image = vec![half::f16::ZERO; d];
        source.decode_image(i, &mut image)?;
        out.iter_mut().zip(&image).for_each(|(o, v)| *o = v.to_f32());
        Ok::<(), Error>(())
    })?;
    Ok(rows)
}

/// Components to keep: enough for `energy` of `total`, at most `max_rank`, none that is
/// numerically zero.
fn kept_rank(lambda: &[f64], total: f64, options: &BasisOptions) -> usize {
    let mut kept = 0.0;
    let mut rank = 0;
    for &l in lambda.iter().take(options.max_rank) {
        if kept >= options.energy * total || l <= total * 1e-10 {
            break;
        }
        kept += l;
        rank += 1;
    }
    rank
}

/// Eigenvectors (columns) and eigenvalues of a symmetric matrix, decreasing, clamped ≥ 0.
fn leading_eigenvectors(gram: &Array2<f32>) -> Result<(Array2<f32>, Vec<f64>)> {
    let (vectors, values) = symmetric_eigen_decreasing(gram.nrows(), |i, j| gram[[i, j]] as f64)?;
    Ok((vectors.mapv(|v| v as f32), values))
}

/// An orthonormal basis (n × q) of the range of `x` (n × P): a seeded Gaussian test matrix
/// and one power iteration (Halko, Martinsson and Tropp 2011).
fn randomized_range(x: &Array2<f32>, q: usize, seed: u64) -> Array2<f32> {
    let q = q.min(x.nrows()).min(x.ncols());
    let omega = Array2::from_shape_fn((x.ncols(), q), |(i, j)| normal(seed, i as i64, j as i64));
    let y = x.dot(&omega);
    let y = x.dot(&x.t().dot(&orthonormal_columns(y)));
    orthonormal_columns(y)
}

/// Modified Gram–Schmidt in f64; a column that vanishes is left zero. The columns are worked
/// on as the rows of the transpose, so each pass reads memory in order (a 262,144-row sketch
/// read by columns spent most of its time in cache misses); the dot products add their terms
/// in index order, as a strided `dot` does, so the result is the same to the bit.
fn orthonormal_columns(y: Array2<f32>) -> Array2<f32> {
    let mut columns: Vec<Vec<f64>> =
        y.columns().into_iter().map(|c| c.iter().map(|&v| v as f64).collect()).collect();
    let in_order = |a: &[f64], b: &[f64]| a.iter().zip(b).fold(0.0, |sum, (x, y)| sum + x * y);
    for j in 0..columns.len() {
        let (done, rest) = columns.split_at_mut(j);
        let column = &mut rest[0];
        for earlier in done.iter() {
            let proj = in_order(earlier, column);
            column.iter_mut().zip(earlier).for_each(|(v, &e)| *v += -proj * e);
        }
        let norm = in_order(column, column).sqrt();
        if norm > 1e-12 {
            column.iter_mut().for_each(|v| *v /= norm);
        } else {
            column.fill(0.0);
        }
    }
    Array2::from_shape_fn(y.dim(), |(r, j)| columns[j][r] as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// n images that are random combinations of `rank` patterns plus a mean.
    fn low_rank_stack(n: usize, pixels: usize, rank: usize) -> Array2<f32> {
        let patterns = Array2::from_shape_fn((rank, pixels), |(k, p)| normal(1, k as i64, p as i64));
        let weights =
            Array2::from_shape_fn((n, rank), |(a, k)| normal(2, a as i64, k as i64) * (rank - k) as f32);
        weights.dot(&patterns) + 0.5
    }

    fn check_reconstruction(images: &Array2<f32>, basis: &PrincipalImages) {
        let rebuilt = basis.coords.dot(&basis.components) + &basis.mean;
        let err = (&rebuilt - images).iter().map(|v| v.abs()).fold(0.0f32, f32::max);
        assert!(err < 1e-3, "reconstruction error {err}");
        let gram = basis.components.dot(&basis.components.t());
        for ((i, j), v) in gram.indexed_iter() {
            assert!((v - if i == j { 1.0 } else { 0.0 }).abs() < 1e-3, "components not orthonormal");
        }
    }

    #[test]
    fn exact_and_randomized_bases_rebuild_a_low_rank_stack() {
        let images = low_rank_stack(60, 300, 5);
        let exact = principal_images(images.view(), &BasisOptions::default()).unwrap();
        assert_eq!(exact.sigma.len(), 5);
        check_reconstruction(&images, &exact);
        let randomized =
            principal_images(images.view(), &BasisOptions { exact_limit: 10, ..Default::default() }).unwrap();
        assert_eq!(randomized.sigma.len(), 5);
        check_reconstruction(&images, &randomized);
        for (a, b) in exact.sigma.iter().zip(&randomized.sigma) {
            assert!((a - b).abs() < 1e-3 * a, "{a} vs {b}");
        }
    }

    #[test]
    fn block_weights_reproduce_dot_products_of_linear_features() {
        // f = any linear map; Σₐ f(Iₐ)·f(Iₐ) must equal the weighted basis sum.
        let images = low_rank_stack(30, 80, 4);
        let basis =
            principal_images(images.view(), &BasisOptions { energy: 1.0, ..Default::default() }).unwrap();
        let f = Array2::from_shape_fn((80, 7), |(p, c)| normal(9, p as i64, c as i64));
        let direct: f32 = images.dot(&f).iter().map(|v| v * v).sum();
        let weights = basis.block_weights();
        let mut blocks = vec![basis.mean.dot(&f)];
        blocks.extend(basis.components.rows().into_iter().map(|c| c.dot(&f)));
        let via_basis: f32 = blocks.iter().zip(&weights).map(|(b, w)| w * w * b.dot(b)).sum();
        assert!((direct - via_basis).abs() < 1e-3 * direct, "{direct} vs {via_basis}");
    }

    /// The stack of `low_rank_stack` as factors: coords (n × rank) and rows (rank + 1 × P),
    /// the last row the offset with coordinate 1 (and the offset field zero).
    fn as_low_rank(n: usize, pixels: usize, rank: usize) -> LowRankStack {
        let patterns = Array2::from_shape_fn((rank, pixels), |(k, p)| normal(1, k as i64, p as i64));
        let weights =
            Array2::from_shape_fn((n, rank), |(a, k)| normal(2, a as i64, k as i64) * (rank - k) as f32);
        let mut rows = Array2::from_elem((rank + 1, pixels), 0.5f32);
        rows.slice_mut(s![..rank, ..]).assign(&patterns);
        let mut coords = Array2::from_elem((n, rank + 1), 1.0f32);
        coords.slice_mut(s![.., ..rank]).assign(&weights);
        LowRankStack { offset: Array1::zeros(pixels), coords, rows, outside: 0.0 }
    }

    #[test]
    fn low_rank_principal_images_equal_those_of_the_multiplied_out_stack() {
        for n in [60, 1500] {
            let images = low_rank_stack(n, 300, 5);
            let stack = as_low_rank(n, 300, 5);
            let multiplied = stack.coords.dot(&stack.rows) + &stack.offset;
            assert!((&multiplied - &images).iter().all(|v| v.abs() < 1e-4));
            let direct = principal_images(images.view(), &BasisOptions::default()).unwrap();
            let low = principal_images_low_rank(&stack, &BasisOptions::default()).unwrap();
            assert_eq!(low.sigma.len(), 5);
            check_reconstruction(&images, &low);
            for (a, b) in direct.sigma.iter().zip(&low.sigma) {
                assert!((a - b).abs() < 1e-3 * a, "n = {n}: {a} vs {b}");
            }
            let err = (&direct.mean - &low.mean).iter().map(|v| v.abs()).fold(0.0f32, f32::max);
            assert!(err < 1e-4, "mean differs by {err}");
            // The same subspace: each direct component lies in the span of the low-rank ones.
            let projected = low.components.dot(&direct.components.t());
            for k in 0..5 {
                let norm: f32 = projected.column(k).iter().map(|v| v * v).sum();
                assert!((norm - 1.0).abs() < 1e-3, "component {k}: {norm}");
            }
            assert!((low.energy - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn a_subset_and_a_linear_map_of_a_low_rank_stack_stay_exact() {
        let stack = as_low_rank(40, 64, 3);
        let images = stack.coords.dot(&stack.rows);
        let picked = [3usize, 7, 8, 30];
        let halve = |row: &[f32]| row.chunks(2).map(|c| 0.5 * (c[0] + c[1])).collect::<Vec<f32>>();
        let small = stack.select(&picked).map_rows(halve);
        assert_eq!(small.rows.dim(), (4, 32));
        for (k, &a) in picked.iter().enumerate() {
            let want = halve(images.row(a).as_slice().unwrap());
            let got = small.image(k);
            for (x, y) in want.iter().zip(got.iter()) {
                assert!((x - y).abs() < 1e-4, "{x} vs {y}");
            }
        }
    }

    #[test]
    fn a_streamed_basis_captures_a_low_rank_stack_in_two_passes() {
        use crate::btf::{Btf, DirectionSet};
        // 81 images of 8×6 RGB: a mean plus 4 patterns, stored as f16.
        let pairs = DirectionSet::Grid(9).pairs();
        let images = low_rank_stack(pairs.len(), 8 * 6 * 3, 4);
        let pixels = images.iter().map(|&v| half::f16::from_f32(v)).collect();
        let btf = Btf::new(8, 6, pairs, pixels).unwrap();
        let options = StreamOptions { rank: 12, batch: 10, seed: 3 };
        let stack = streamed_basis(&btf, &options, &crate::progress::Silent).unwrap();
        assert_eq!((stack.len(), stack.rank()), (81, 12));
        let rebuilt = stack.coords.dot(&stack.rows) + &stack.offset;
        let err = (&rebuilt - &images).iter().map(|v| v.abs()).fold(0.0f32, f32::max);
        assert!(err < 1e-2, "reconstruction error {err}");
        let total: f64 =
            (&images - &images.mean_axis(Axis(0)).unwrap()).iter().map(|&v| v as f64 * v as f64).sum();
        assert!(stack.outside < 1e-5 * total, "outside {} of {total}", stack.outside);
        let basis = principal_images_low_rank(&stack, &BasisOptions::default()).unwrap();
        assert_eq!(basis.sigma.len(), 4);
    }

    impl RowSource for Array2<f32> {
        fn rows(&self) -> usize {
            self.nrows()
        }
        fn cols(&self) -> usize {
            self.ncols()
        }
        fn block(&self, start: usize, len: usize) -> Array2<f32> {
            self.slice(s![start..start + len, ..]).to_owned()
        }
    }

    #[test]
    fn streamed_principal_images_equal_those_of_the_whole_stack_to_the_bit() {
        // 5,000 rows: past the exact limit, in blocks of 512 (the last one partial) or one.
        let rows = low_rank_stack(5000, 70, 6)
            + Array2::from_shape_fn((5000, 70), |(i, j)| 1e-3 * normal(3, i as i64, j as i64));
        for (max_rank, block) in [(4, 512), (20, 512), (20, stream_rows(70))] {
            let options = BasisOptions { max_rank, seed: 7, ..Default::default() };
            let whole = principal_images(rows.view(), &options).unwrap();
            let streamed = streamed_in_blocks(&rows, &options, block).unwrap();
            let bits = |a: &Array2<f32>| a.mapv(f32::to_bits);
            assert!(bits(&whole.components) == bits(&streamed.components), "rank {max_rank}: components");
            assert!(bits(&whole.coords) == bits(&streamed.coords), "rank {max_rank}: coordinates");
            assert!(
                whole.mean.mapv(f32::to_bits) == streamed.mean.mapv(f32::to_bits),
                "rank {max_rank}: mean"
            );
            assert_eq!(whole.sigma, streamed.sigma);
            assert_eq!(whole.energy.to_bits(), streamed.energy.to_bits());
        }
    }

    #[test]
    fn identical_images_need_no_components() {
        let images = Array2::from_elem((3, 10), 0.25f32);
        let basis = principal_images(images.view(), &BasisOptions::default()).unwrap();
        assert_eq!(basis.components.nrows(), 0);
        assert_eq!(basis.block_weights(), vec![3f32.sqrt()]);
    }
}
