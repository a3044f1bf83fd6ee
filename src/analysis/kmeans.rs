//! k-means clustering: k-means++ seeding, then Lloyd's iterations.
//!
//! Used twice by the texton analysis (Tong et al. 2002, §4): on image appearance vectors to
//! pick representative images, and on per-pixel filter responses to find the 3D textons
//! (`k = 400` clusters of 4096 points × thousands of dimensions).
//!
//! Squared distances to all centres come from one matrix product per block of points,
//! `‖x‖² − 2 x·c + ‖c‖²`, skipped for points that [Elkan's bounds](super::elkan) show
//! cannot change centre; k-means++ keeps each point's distance to its nearest centre and
//! updates it with one pass per added centre.
//!
//! # Determinism
//!
//! For a given seed the result is the same bit for bit whatever the number of rayon
//! threads: work is split into blocks of fixed size, never by thread, every value is computed
//! by one task in a fixed order, and sums across blocks or points are taken sequentially in
//! index order.

use super::elkan::{Bounds, MOST_LOWER_BOUNDS};
use crate::progress::Progress;
use crate::{Error, Result};
use ndarray::{Array2, ArrayView2, CowArray, Ix2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// The seed used when none is given.
pub const DEFAULT_SEED: u64 = 2002;

/// Points per block of the distance matrix product: large enough for an efficient GEMM,
/// small enough to spread 4096 points over several threads. Fixed, so that the results do
/// not depend on the thread count.
const ROW_BLOCK: usize = 256;

/// k-means++ skips a point when the new seed is at least twice as far from the point's
/// nearest seed as the point is (squared: 4×); the extra 0.1% covers rounding in the
/// distances, so a skipped point is never one the new seed would have won.
const PRUNE_MARGIN: f32 = 4.004;

/// Parameters of [`kmeans`]; see each field for its default.
#[derive(Clone, Debug, PartialEq)]
pub struct KMeansOptions {
    /// Number of clusters. Default 400 (the paper's `n_t`). Must be ≥ 1; capped at the
    /// number of distinct points, so the result may have fewer centres.
    pub k: usize,
    /// Most Lloyd iterations after seeding. Default 100; 0 returns the k-means++ seeds.
    pub max_iterations: usize,
    /// Convergence threshold: stop when the centres moved, in total squared distance, by at
    /// most `tolerance` × the data's total variance (scikit-learn's rule). Default 1e-4;
    /// 0 iterates until the centres stop moving or `max_iterations` is reached.
    pub tolerance: f64,
    /// Independent seedings, each followed by Lloyd's iterations; the run with the lowest
    /// inertia is kept. Default 1: at `k = 400` the texton vocabulary gains little from
    /// more, while each run costs as much again. linfa (and scikit-learn before 1.4) run 10,
    /// which escapes poor local minima on small, tightly clustered problems. Must be ≥ 1.
    pub runs: usize,
    /// Seed of the ChaCha8 generator behind every random choice. Default [`DEFAULT_SEED`].
    pub seed: u64,
    /// Most points the centres are fitted on. A larger set is clustered on a uniform random
    /// subset of this many points (drawn from the seed), and the centres are then refined by
    /// [`REFINE_ITERATIONS`] Lloyd iterations over every point, which also label every
    /// point. Default [`DEFAULT_FIT_POINTS`]; 0 fits on every point. A 512² photograph has
    /// 262,144 pixels: fitting 400 centres to all of them cost 50 s of the analysis, and
    /// a centre is an average, which 80 points per centre already estimate well.
    pub fit_points: usize,
}

/// Default of [`KMeansOptions::fit_points`]: 80 points per centre at the paper's 400 textons,
/// and more points than any 128² level has, so small samples are clustered in full.
pub const DEFAULT_FIT_POINTS: usize = 32_768;

/// Lloyd iterations over every point after a subset fit (see [`KMeansOptions::fit_points`]).
pub const REFINE_ITERATIONS: usize = 2;

impl Default for KMeansOptions {
    fn default() -> Self {
        KMeansOptions {
            k: 400,
            max_iterations: 100,
            tolerance: 1e-4,
            runs: 1,
            seed: DEFAULT_SEED,
            fit_points: DEFAULT_FIT_POINTS,
        }
    }
}

impl KMeansOptions {
    /// The defaults with `k` clusters.
    pub fn with_k(k: usize) -> Self {
        KMeansOptions { k, ..Self::default() }
    }
}

/// The result of [`kmeans`].
#[derive(Clone, Debug, PartialEq)]
pub struct Clustering {
    /// One centre per row: `min(k, distinct points)` rows.
    pub centres: Array2<f32>,
    /// For each point, the row of its nearest centre (ties go to the lower row).
    pub labels: Vec<usize>,
    /// Sum over points of the squared distance to their centre.
    pub inertia: f64,
    /// Lloyd iterations run.
    pub iterations: usize,
    /// Whether the tolerance was met before `max_iterations`.
    pub converged: bool,
}

/// Each point's nearest centre, as returned by [`assign`].
#[derive(Clone, Debug, PartialEq)]
pub struct Assignment {
    /// For each point, the row of its nearest centre (ties go to the lower row).
    pub labels: Vec<usize>,
    /// For each point, the squared distance to that centre.
    pub distances: Vec<f32>,
}

/// Clusters the rows of `data` (one point per row) into `options.k` clusters.
///
/// `progress` sees two stages per run: "k-means++" (one unit per centre) and "k-means" (one
/// unit per iteration). Fails if `k` or `runs` is 0, `data` is empty, holds NaN or
/// infinity, or the tolerance is negative.
pub fn kmeans(
    data: ArrayView2<'_, f32>,
    options: &KMeansOptions,
    progress: &dyn Progress,
) -> Result<Clustering> {
    if !(options.tolerance.is_finite() && options.tolerance >= 0.0) {
        return Err(Error::invalid(format!(
            "k-means: tolerance must be a number ≥ 0, got {}",
            options.tolerance
        )));
    }
    if options.runs == 0 {
        return Err(Error::invalid("k-means: runs must be at least 1"));
    }
    let data = standard(data);
    let points = Points::new(&data)?;
    check_k(options.k)?;
    // One generator for all runs, drawn from in order, keeps the result a function of the seed.
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let mut best: Option<Clustering> = None;
    for _ in 0..options.runs {
        let run = match fit_subset(points.n, options.fit_points, &mut rng) {
            Some(subset) => fit_then_refine(&points, &subset, options, &mut rng, progress),
            None => {
                let seeds = plus_plus(&points, options.k, &mut rng, progress);
                lloyd(&points, seeds, options, progress)
            }
        };
        if best.as_ref().is_none_or(|b| run.inertia < b.inertia) {
            best = Some(run);
        }
    }
    best.ok_or_else(|| Error::invalid("k-means: runs must be at least 1"))
}

/// The rows a run fits its centres on when there are more than `fit_points`: a uniform
/// subset, in index order; `None` when every point is used.
fn fit_subset(n: usize, fit_points: usize, rng: &mut ChaCha8Rng) -> Option<Vec<usize>> {
    if fit_points == 0 || n <= fit_points {
        return None;
    }
    let mut subset = rand::seq::index::sample(rng, n, fit_points).into_vec();
    subset.sort_unstable();
    Some(subset)
}

/// One run fitted on the rows `subset` of `points`, then refined over all of them.
fn fit_then_refine(
    points: &Points,
    subset: &[usize],
    options: &KMeansOptions,
    rng: &mut ChaCha8Rng,
    progress: &dyn Progress,
) -> Clustering {
    let rows: Vec<f32> = subset.iter().flat_map(|&i| points.row(i).iter().copied()).collect();
    let fitted_on = Points { data: &rows, n: subset.len(), d: points.d };
    let seeds = plus_plus(&fitted_on, options.k, rng, progress);
    let fit = lloyd(&fitted_on, seeds, options, progress);
    let refine = KMeansOptions { max_iterations: REFINE_ITERATIONS, ..options.clone() };
    let refined = lloyd(points, fit.centres, &refine, progress);
    Clustering { iterations: fit.iterations + refined.iterations, ..refined }
}

/// The k-means++ seeds alone: up to `k` rows of `data`, the first drawn uniformly and each
/// next with probability proportional to its squared distance from the nearest seed so far.
/// Stops early when every point coincides with a seed (fewer than `k` distinct points).
pub fn kmeans_plus_plus(data: ArrayView2<'_, f32>, k: usize, seed: u64) -> Result<Array2<f32>> {
    let data = standard(data);
    let points = Points::new(&data)?;
    check_k(k)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Ok(plus_plus(&points, k, &mut rng, &crate::progress::Silent))
}

/// The nearest row of `centres` to each row of `data` (e.g. the texton label of each
/// pixel). Fails if either is empty, their widths differ, or they hold NaN or infinity.
pub fn assign(data: ArrayView2<'_, f32>, centres: ArrayView2<'_, f32>) -> Result<Assignment> {
    let data = standard(data);
    let centres = standard(centres);
    let points = Points::new(&data)?;
    let centre_points = Points::new(&centres).map_err(|e| Error::invalid(format!("centres: {e}")))?;
    if centre_points.d != points.d {
        return Err(Error::invalid(format!(
            "k-means: centres have {} dimensions but the points have {}",
            centre_points.d, points.d
        )));
    }
    // One assignment: bounds would only be kept, never used.
    let mut scoring = Scoring::around(&mean(&points), &points, centre_points.n, 0);
    Ok(nearest(&points, &centre_points, &vec![0; points.n], &mut scoring))
}

fn check_k(k: usize) -> Result<()> {
    if k == 0 {
        return Err(Error::invalid("k-means: k must be at least 1"));
    }
    Ok(())
}

/// Row-major contiguous data, copied only if the view is not already.
fn standard(data: ArrayView2<'_, f32>) -> CowArray<'_, f32, Ix2> {
    if data.is_standard_layout() {
        CowArray::from(data)
    } else {
        CowArray::from(data.as_standard_layout().into_owned())
    }
}

/// `n` points of `d` dimensions, row-major and contiguous.
struct Points<'a> {
    data: &'a [f32],
    n: usize,
    d: usize,
}

impl<'a> Points<'a> {
    fn new(array: &'a CowArray<'_, f32, Ix2>) -> Result<Self> {
        let (n, d) = array.dim();
        if n == 0 || d == 0 {
            return Err(Error::invalid(format!(
                "k-means: {n} points of {d} dimensions is nothing to cluster"
            )));
        }
        let data = array.as_slice().ok_or_else(|| Error::internal("k-means: data not contiguous"))?;
        if let Some(i) = data.par_iter().position_first(|v| !v.is_finite()) {
            return Err(Error::invalid(format!(
                "k-means: point {} has {} in dimension {}; clustering needs finite values",
                i / d,
                data[i],
                i % d
            )));
        }
        Ok(Points { data, n, d })
    }

    fn row(&self, i: usize) -> &'a [f32] {
        &self.data[i * self.d..(i + 1) * self.d]
    }
}

/// A `rows × cols` view of a buffer this module sized itself.
fn matrix(data: &[f32], rows: usize, cols: usize) -> ArrayView2<'_, f32> {
    ArrayView2::from_shape((rows, cols), data).expect("buffer holds rows × cols values")
}

/// `‖a − b‖²` with eight independent partial sums, so the compiler can vectorise it without
/// reordering floating-point additions (the order is fixed, hence reproducible).
fn squared_distance(a: &[f32], b: &[f32]) -> f32 {
    const LANES: usize = 8;
    let mut acc = [0f32; LANES];
    let (a_chunks, b_chunks) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
    let tail: f32 =
        a_chunks.remainder().iter().zip(b_chunks.remainder()).map(|(x, y)| (x - y) * (x - y)).sum();
    for (x, y) in a_chunks.zip(b_chunks) {
        for l in 0..LANES {
            let t = x[l] - y[l];
            acc[l] += t * t;
        }
    }
    acc.iter().sum::<f32>() + tail
}

/// The k-means++ seeds (see [`kmeans_plus_plus`]), one per row.
fn plus_plus(points: &Points, k: usize, rng: &mut ChaCha8Rng, progress: &dyn Progress) -> Array2<f32> {
    progress.start("k-means++", k as u64);
    let first = rng.random_range(0..points.n);
    let mut chosen = vec![first];
    // Each point's squared distance to its nearest seed, and which seed that is.
    let mut nearest_d: Vec<(f32, usize)> = (0..points.n)
        .into_par_iter()
        .map(|i| (squared_distance(points.row(i), points.row(first)), 0))
        .collect();
    progress.advance(1);
    while chosen.len() < k {
        let total: f64 = nearest_d.iter().map(|&(d, _)| d as f64).sum();
        if total <= 0.0 {
            break; // every point coincides with a seed: no more distinct points
        }
        let next = sample(&nearest_d, rng.random::<f64>() * total);
        let centre = points.row(next);
        let gaps: Vec<f32> = chosen.par_iter().map(|&c| squared_distance(points.row(c), centre)).collect();
        let seed = chosen.len();
        chosen.push(next);
        nearest_d.par_iter_mut().enumerate().with_min_len(64).for_each(|(i, (d, s))| {
            // Triangle inequality: a seed at least twice as far from x's nearest seed
            // as x is cannot be nearer to x, so most rows need not be read at all once
            // the clusters have seeds.
            if gaps[*s] < PRUNE_MARGIN * *d {
                let e = squared_distance(points.row(i), centre);
                if e < *d {
                    (*d, *s) = (e, seed);
                }
            }
        });
        progress.advance(1);
    }
    progress.finish();
    let rows: Vec<f32> = chosen.iter().flat_map(|&i| points.row(i).iter().copied()).collect();
    matrix(&rows, chosen.len(), points.d).to_owned()
}

/// The first index where the running sum of the weights (first members) exceeds `target`; rounding can leave
/// `target` just past the total, hence the fallback to the last positive weight.
fn sample(weights: &[(f32, usize)], target: f64) -> usize {
    let (mut sum, mut last) = (0f64, 0);
    for (i, &(w, _)) in weights.iter().enumerate().filter(|(_, &(w, _))| w > 0.0) {
        sum += w as f64;
        last = i;
        if sum > target {
            return i;
        }
    }
    last
}

fn lloyd(
    points: &Points,
    seeds: Array2<f32>,
    options: &KMeansOptions,
    progress: &dyn Progress,
) -> Clustering {
    let mut scoring = Scoring::around(&mean(points), points, seeds.nrows(), MOST_LOWER_BOUNDS);
    iterate(points, seeds, options, progress, &mut scoring)
}

/// Lloyd's iterations from `seeds`, scored by `scoring`.
fn iterate(
    points: &Points,
    seeds: Array2<f32>,
    options: &KMeansOptions,
    progress: &dyn Progress,
    scoring: &mut Scoring,
) -> Clustering {
    let threshold = options.tolerance * total_variance(points, &scoring.mean);
    let mut centres = seeds;
    let mut labels = vec![0; points.n];
    let (mut iterations, mut converged) = (0, false);
    progress.start("k-means", options.max_iterations as u64);
    while iterations < options.max_iterations {
        let mut assignment = nearest(points, &centre_view(&centres), &labels, scoring);
        for i in reseed_empty(&mut assignment, centres.nrows()) {
            scoring.bounds.forget(i);
        }
        let moved = means(points, &assignment.labels, &centres);
        let shifts = squared_shifts(&centres, &moved);
        let distances_moved: Vec<f64> = shifts.iter().map(|&s| scoring.bounds.distance_above(s)).collect();
        scoring.bounds.moved(&assignment.labels, &distances_moved);
        labels = assignment.labels;
        centres = moved;
        iterations += 1;
        progress.advance(1);
        if shifts.iter().map(|&s| s as f64).sum::<f64>() <= threshold {
            converged = true;
            break;
        }
    }
    progress.finish();
    let assignment = nearest(points, &centre_view(&centres), &labels, scoring);
    Clustering {
        inertia: assignment.distances.iter().map(|&d| d as f64).sum(),
        labels: assignment.labels,
        centres,
        iterations,
        converged,
    }
}

fn centre_view(centres: &Array2<f32>) -> Points<'_> {
    Points {
        data: centres.as_slice().expect("centres are built row-major"),
        n: centres.nrows(),
        d: centres.ncols(),
    }
}

/// Rows at least this long are scored about the data's mean and with [`Bounds`]: there a
/// row of the distance product costs far more than the bounds' upkeep (a square root and a
/// subtraction per centre), and at the texton features' thousands of dimensions most
/// points settle within a few iterations. Shorter rows keep plain Lloyd, to the bit.
const LONG_ROWS: usize = 1024;

/// How [`nearest`] scores points against centres: about `origin` (the data's mean for long
/// rows, so that the scores' rounding, which grows with the norms, stays small beside the
/// distances, and [`Bounds`] settle more points; zero otherwise).
struct Scoring {
    mean: Vec<f64>,
    origin: Vec<f32>,
    bounds: Bounds,
    /// Rows of the distance product computed so far.
    evaluated: usize,
}

impl Scoring {
    /// Scoring of `points` (whose mean is `mean`) against `k` centres, with at most `most`
    /// lower bounds for long rows and none for short ones.
    fn around(mean: &[f64], points: &Points, k: usize, most: usize) -> Scoring {
        let long = points.d >= LONG_ROWS;
        let origin: Vec<f32> = mean.iter().map(|&m| if long { m as f32 } else { 0.0 }).collect();
        let most = if long { most } else { 0 };
        // The norms only size the lower bounds' margins: no bounds, no pass over the data.
        let norm = |i: usize| {
            points.row(i).iter().zip(&origin).map(|(&x, &o)| ((x - o) as f64).powi(2)).sum::<f64>()
        };
        let norms = if most > 0 {
            (0..points.n).into_par_iter().map(|i| norm(i).sqrt()).collect()
        } else {
            vec![0.0; points.n]
        };
        let bounds = Bounds::new(norms, points.d, k, most);
        Scoring { mean: mean.to_vec(), bounds, origin, evaluated: 0 }
    }

    /// Whether the origin is zero: rows are then scored as they are.
    fn at_zero(&self) -> bool {
        self.origin.iter().all(|&o| o == 0.0)
    }

    /// The rows `indices` (increasing) about the origin, one after the other; borrowed
    /// when they already are.
    fn rows<'a>(&self, points: &Points<'a>, indices: &[usize]) -> std::borrow::Cow<'a, [f32]> {
        match (indices.first(), indices.last()) {
            (Some(&first), Some(&last)) if last - first + 1 == indices.len() && self.at_zero() => {
                std::borrow::Cow::Borrowed(&points.data[first * points.d..(last + 1) * points.d])
            }
            _ => {
                let row = |i: usize| points.row(i).iter().zip(&self.origin).map(|(&x, &o)| x - o);
                std::borrow::Cow::Owned(indices.iter().flat_map(|&i| row(i)).collect())
            }
        }
    }
}

/// Nearest centre of every point, given each point's current centre in `labels` (updating
/// the bounds of `scoring`). A point the bounds settle keeps its centre and has only that
/// distance measured again. The others are gathered, in index order, into blocks of
/// [`ROW_BLOCK`]; one `ROW_BLOCK × k` matrix product per block gives `x·c` about the
/// origin, the lowest `‖c‖² − 2x·c` names the centre, and its distance is then recomputed
/// exactly, since `‖x‖² − 2x·c + ‖c‖²` loses precision to cancellation. A row of the
/// product depends only on its point, so settling points changes no label.
fn nearest(points: &Points, centres: &Points, labels: &[usize], scoring: &mut Scoring) -> Assignment {
    let all: Vec<usize> = (0..centres.n).collect();
    let moved_rows = scoring.rows(centres, &all);
    let zero = vec![0f32; centres.d];
    let norms: Vec<f32> = moved_rows.chunks_exact(centres.d).map(|c| squared_distance(c, &zero)).collect();
    let moved_centres = matrix(&moved_rows, centres.n, centres.d);
    let bounds = &scoring.bounds;
    let centre_norms: Vec<f64> = norms.iter().map(|&n| bounds.distance_above(n)).collect();
    let own: Vec<Option<(f32, bool)>> = (0..points.n)
        .into_par_iter()
        .with_min_len(64)
        .map(|i| {
            (bounds.per_centre() && bounds.known(i)).then(|| {
                let distance = squared_distance(points.row(i), centres.row(labels[i]));
                (distance, bounds.settles(i, labels[i], distance, &centre_norms))
            })
        })
        .collect();
    let mut assignment = Assignment { labels: labels.to_vec(), distances: vec![0f32; points.n] };
    let mut open = Vec::new();
    for (i, own) in own.into_iter().enumerate() {
        match own {
            Some((distance, true)) => {
                scoring.bounds.tighten(i, distance);
                assignment.distances[i] = distance;
            }
            _ => open.push(i),
        }
    }
    let (shared, transposed) = (&*scoring, moved_centres.reversed_axes());
    let evaluated: Vec<Vec<(usize, f32, Vec<f32>)>> = open
        .par_chunks(ROW_BLOCK)
        .map(|block| {
            let rows = shared.rows(points, block);
            let dots = matrix(&rows, block.len(), points.d).dot(&transposed);
            let evaluate = |(&i, row): (&usize, ndarray::ArrayView1<f32>)| {
                let row = row.to_slice().expect("a GEMM result row is contiguous");
                let best = lowest_score(&norms, row);
                let distance = squared_distance(points.row(i), centres.row(best));
                let scores = norms.iter().zip(row).map(|(n, d)| n - 2.0 * d);
                (best, distance, shared.bounds.lower_row(i, scores, &centre_norms))
            };
            block.iter().zip(dots.rows()).map(evaluate).collect()
        })
        .collect();
    scoring.evaluated += open.len();
    for (&i, (label, distance, lower)) in open.iter().zip(evaluated.into_iter().flatten()) {
        (assignment.labels[i], assignment.distances[i]) = (label, distance);
        scoring.bounds.record(i, distance, &lower);
    }
    assignment
}

/// The index of the smallest `norms[j] − 2 dots[j]`, the lowest index among equal scores.
///
/// Eight lanes each keep their own best (strictly smaller replaces, so a lane keeps its
/// lowest index among ties), then the lanes are merged by score and index: the same index a
/// sequential scan would return, whatever the order of the comparisons, since every score is
/// computed the same way and the scores are finite. The lanes let the compiler vectorise
/// what is, at the textons' few dimensions, as much work as the distance product itself.
fn lowest_score(norms: &[f32], dots: &[f32]) -> usize {
    const LANES: usize = 8;
    let mut best_score = [f32::INFINITY; LANES];
    // Each lane starts on its first index, so that where every score is +∞ (overflowing
    // norms) the lowest index wins, as in the scan.
    let mut best_index: [usize; LANES] = std::array::from_fn(|l| l);
    let full = norms.len() / LANES * LANES;
    for start in (0..full).step_by(LANES) {
        for l in 0..LANES {
            let score = norms[start + l] - 2.0 * dots[start + l];
            if score < best_score[l] {
                (best_score[l], best_index[l]) = (score, start + l);
            }
        }
    }
    let mut best = (f32::INFINITY, 0);
    let tail = (full..norms.len()).map(|j| (norms[j] - 2.0 * dots[j], j));
    for (score, index) in best_score.into_iter().zip(best_index).chain(tail) {
        if score < best.0 || (score == best.0 && index < best.1) {
            best = (score, index);
        }
    }
    best.1
}

/// Gives each empty cluster the point farthest from its centre (ties: lowest index), so
/// that no centre is wasted. Returns the points that moved to one.
fn reseed_empty(assignment: &mut Assignment, k: usize) -> Vec<usize> {
    let mut counts = vec![0usize; k];
    assignment.labels.iter().for_each(|&l| counts[l] += 1);
    let empty: Vec<usize> = (0..k).filter(|&j| counts[j] == 0).collect();
    if empty.is_empty() {
        return Vec::new();
    }
    let d = &assignment.distances;
    let mut farthest: Vec<usize> = (0..d.len()).collect();
    farthest.sort_by(|&a, &b| d[b].total_cmp(&d[a]).then(a.cmp(&b)));
    let mut reseeded = Vec::new();
    for (&cluster, &point) in empty.iter().zip(&farthest) {
        if assignment.distances[point] <= 0.0 {
            break; // the remaining points all sit on a centre already
        }
        assignment.labels[point] = cluster;
        assignment.distances[point] = 0.0;
        reseeded.push(point);
    }
    reseeded
}

/// The mean of each cluster's points (summed in f64, in point order); a cluster left
/// without points keeps its previous centre.
fn means(points: &Points, labels: &[usize], previous: &Array2<f32>) -> Array2<f32> {
    let k = previous.nrows();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); k];
    labels.iter().enumerate().for_each(|(i, &l)| members[l].push(i));
    let mut centres = previous.clone();
    let slice = centres.as_slice_mut().expect("centres are built row-major");
    slice.par_chunks_mut(points.d).zip(&members).for_each(|(centre, members)| {
        if members.is_empty() {
            return;
        }
        let mut sum = vec![0f64; points.d];
        for &i in members {
            sum.iter_mut().zip(points.row(i)).for_each(|(s, &x)| *s += x as f64);
        }
        let scale = 1.0 / members.len() as f64;
        centre.iter_mut().zip(&sum).for_each(|(c, &s)| *c = (s * scale) as f32);
    });
    centres
}

/// The squared distance each centre moved.
fn squared_shifts(before: &Array2<f32>, after: &Array2<f32>) -> Vec<f32> {
    let (b, a) = (centre_view(before), centre_view(after));
    (0..b.n).map(|j| squared_distance(b.row(j), a.row(j))).collect()
}

/// The mean point, summed in f64 over blocks of [`ROW_BLOCK`] points.
fn mean(points: &Points) -> Vec<f64> {
    let block_sums: Vec<Vec<f64>> = (0..points.n.div_ceil(ROW_BLOCK))
        .into_par_iter()
        .map(|b| {
            let mut sum = vec![0f64; points.d];
            for i in b * ROW_BLOCK..((b + 1) * ROW_BLOCK).min(points.n) {
                sum.iter_mut().zip(points.row(i)).for_each(|(s, &x)| *s += x as f64);
            }
            sum
        })
        .collect();
    let mut mean = vec![0f64; points.d];
    for sum in &block_sums {
        mean.iter_mut().zip(sum).for_each(|(m, s)| *m += s);
    }
    mean.iter_mut().for_each(|m| *m /= points.n as f64);
    mean
}

/// Sum over dimensions of the data's variance (mean squared distance to `mean`).
fn total_variance(points: &Points, mean: &[f64]) -> f64 {
    let per_point: Vec<f64> = (0..points.n)
        .into_par_iter()
        .map(|i| points.row(i).iter().zip(mean).map(|(&x, m)| (x as f64 - m).powi(2)).sum())
        .collect();
    per_point.iter().sum::<f64>() / points.n as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::Silent;
    use ndarray::Array2;

    /// Gaussian blobs: `per` points around each centre, std `spread`, interleaved so no
    /// cluster is a contiguous range. Returns the data and each point's blob.
    fn blobs(centres: &Array2<f32>, per: usize, spread: f32, seed: u64) -> (Array2<f32>, Vec<usize>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (k, d) = centres.dim();
        let mut normal = || {
            // Box–Muller: rand 0.9 alone has no normal distribution.
            let (u, v) = (1.0 - rng.random::<f32>(), rng.random::<f32>());
            (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
        };
        let truth: Vec<usize> = (0..per * k).map(|i| i % k).collect();
        let data = Array2::from_shape_fn((per * k, d), |(i, j)| centres[[truth[i], j]] + spread * normal());
        (data, truth)
    }

    fn uniform(rows: usize, cols: usize, scale: f32, seed: u64) -> Array2<f32> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        Array2::from_shape_fn((rows, cols), |_| scale * rng.random::<f32>())
    }

    fn inertia_of(data: &Array2<f32>, centres: &Array2<f32>) -> f64 {
        let a = assign(data.view(), centres.view()).unwrap();
        a.distances.iter().map(|&d| d as f64).sum()
    }

    #[test]
    fn inertia_is_within_2_percent_of_linfa() {
        use linfa::traits::Fit;
        // Overlapping blobs have several local minima; both sides keep the best of 10 runs.
        let centres = uniform(8, 4, 6.0, 1);
        let (data, _) = blobs(&centres, 75, 1.0, 2);
        let options = KMeansOptions { runs: 10, ..KMeansOptions::with_k(8) };
        let ours = kmeans(data.view(), &options, &Silent).unwrap();
        let dataset = linfa::DatasetBase::from(data.mapv(f64::from));
        let theirs = linfa_clustering::KMeans::params(8).fit(&dataset).unwrap();
        let linfa_inertia = inertia_of(&data, &theirs.centroids().mapv(|v| v as f32));
        assert!((ours.inertia - inertia_of(&data, &ours.centres)).abs() < 1e-6 * ours.inertia);
        let ratio = ours.inertia / linfa_inertia;
        assert!((ratio - 1.0).abs() < 0.02, "ours {} linfa {linfa_inertia}", ours.inertia);
    }

    #[test]
    fn the_lanes_pick_the_scan_s_centre_ties_included() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for k in [1, 7, 8, 9, 25, 100, 403] {
            // Values on a coarse grid, so equal scores are common.
            let mut grid = |n: usize| (0..n).map(|_| rng.random_range(0..6) as f32).collect::<Vec<_>>();
            let (mut norms, dots) = (grid(k), grid(k));
            if k == 9 {
                norms.fill(f32::INFINITY); // every score +∞: the first centre, as in the scan
            }
            let score = |j: usize| norms[j] - 2.0 * dots[j];
            let scan = (1..k).fold(0, |best, j| if score(j) < score(best) { j } else { best });
            assert_eq!(lowest_score(&norms, &dots), scan, "k = {k}");
        }
    }

    #[test]
    fn same_bits_whatever_the_thread_count() {
        let centres = uniform(30, 40, 3.0, 3);
        let (data, _) = blobs(&centres, 40, 1.0, 4);
        let options = KMeansOptions { k: 25, max_iterations: 20, runs: 2, ..KMeansOptions::default() };
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| kmeans(data.view(), &options, &Silent).unwrap())
        };
        let bits = |c: &Clustering| c.centres.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        let one = run(1);
        for threads in [2, 3] {
            let other = run(threads);
            assert_eq!(bits(&one), bits(&other), "{threads} threads");
            assert_eq!(one.labels, other.labels);
            assert_eq!(one.inertia.to_bits(), other.inertia.to_bits());
        }
    }

    #[test]
    fn settled_points_change_no_label_and_save_rows() {
        // Overlapping blobs far from the origin, in rows long enough for bounds.
        let centres = uniform(30, LONG_ROWS, 4.0, 21).mapv(|v| v + 50.0);
        let (data, _) = blobs(&centres, 40, 2.0, 22);
        let owned = standard(data.view());
        let points = Points::new(&owned).unwrap();
        let options = KMeansOptions { k: 30, tolerance: 0.0, ..KMeansOptions::default() };
        let run = |most| {
            let seeds = plus_plus(&points, 30, &mut ChaCha8Rng::seed_from_u64(3), &Silent);
            let mut scoring = Scoring::around(&mean(&points), &points, 30, most);
            (iterate(&points, seeds, &options, &Silent, &mut scoring), scoring.evaluated)
        };
        let ((bounded, fewer), (plain, all)) = (run(MOST_LOWER_BOUNDS), run(0));
        assert_eq!(all, points.n * (plain.iterations + 1));
        assert!(fewer < all * 3 / 4, "{fewer} of {all} rows evaluated");
        assert!(bounded.iterations > 3, "{} iterations", bounded.iterations);
        let bits = |c: &Clustering| c.centres.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&bounded), bits(&plain));
        assert_eq!(bounded.labels, plain.labels);
        assert_eq!(bounded.inertia.to_bits(), plain.inertia.to_bits());
    }

    #[test]
    fn a_fit_on_a_subset_labels_every_point_nearly_as_well_as_a_full_fit() {
        // Overlapping blobs, so the centres are estimates, not just the planted points.
        let centres = uniform(12, 6, 8.0, 11);
        let (data, _) = blobs(&centres, 400, 1.0, 12);
        let full = KMeansOptions { k: 12, fit_points: 0, ..KMeansOptions::default() };
        let subset = KMeansOptions { fit_points: 600, ..full.clone() };
        let (full, subset) =
            (kmeans(data.view(), &full, &Silent).unwrap(), kmeans(data.view(), &subset, &Silent).unwrap());
        assert_eq!(subset.labels.len(), data.nrows());
        assert!((subset.inertia - inertia_of(&data, &subset.centres)).abs() < 1e-6 * subset.inertia);
        assert!(subset.inertia < 1.02 * full.inertia, "subset {} full {}", subset.inertia, full.inertia);
        // Not the full fit under another name: the subset was really used.
        assert_ne!(subset.centres, full.centres);
    }

    #[test]
    fn sets_no_larger_than_the_fit_size_are_fitted_in_full() {
        let data = uniform(300, 3, 1.0, 13);
        let all = KMeansOptions { k: 5, fit_points: 0, ..KMeansOptions::default() };
        let at_size = KMeansOptions { fit_points: 300, ..all.clone() };
        assert_eq!(
            kmeans(data.view(), &all, &Silent).unwrap(),
            kmeans(data.view(), &at_size, &Silent).unwrap()
        );
    }

    #[test]
    fn recovers_planted_well_separated_clusters() {
        let planted = uniform(6, 10, 100.0, 5);
        let (data, truth) = blobs(&planted, 50, 0.5, 6);
        let found = kmeans(data.view(), &KMeansOptions::with_k(6), &Silent).unwrap();
        assert!(found.converged);
        // Same partition up to renaming: each found cluster maps to exactly one planted one.
        let mut map = [None; 6];
        for (&f, &t) in found.labels.iter().zip(&truth) {
            assert_eq!(*map[f].get_or_insert(t), t, "cluster {f} mixes planted clusters");
        }
        for (f, t) in map.iter().enumerate() {
            let t = t.expect("every cluster has points");
            let error = squared_distance(&found.centres.row(f).to_vec(), &planted.row(t).to_vec());
            assert!(error < 0.5, "centre {f} is {error} from planted {t}");
        }
    }

    #[test]
    fn k_is_capped_at_the_number_of_distinct_points() {
        let distinct = uniform(4, 3, 1.0, 7);
        let data = Array2::from_shape_fn((10, 3), |(i, j)| distinct[[i % 4, j]]);
        let found = kmeans(data.view(), &KMeansOptions::with_k(10), &Silent).unwrap();
        assert_eq!(found.centres.nrows(), 4);
        assert_eq!(found.inertia, 0.0);
        let one = Array2::from_elem((5, 2), 1.5f32);
        let found = kmeans(one.view(), &KMeansOptions::with_k(3), &Silent).unwrap();
        assert_eq!(found.centres, Array2::from_elem((1, 2), 1.5f32));
        assert_eq!(found.labels, vec![0; 5]);
    }

    #[test]
    fn empty_clusters_take_the_farthest_point() {
        let mut a = Assignment { labels: vec![0, 0, 0, 2, 0], distances: vec![1.0, 5.0, 3.0, 0.5, 5.0] };
        assert_eq!(reseed_empty(&mut a, 4), [1, 4]);
        assert_eq!(a.labels, [0, 1, 0, 2, 3]);
        // A centre far from all points gets none; Lloyd's iterations give it the outlier.
        let data = ndarray::array![[0.0f32, 0.0], [0.1, 0.0], [0.0, 0.1], [5.0, 5.0]];
        let seeds = ndarray::array![[0.0f32, 0.0], [100.0, 100.0]];
        let points_owned = standard(data.view());
        let points = Points::new(&points_owned).unwrap();
        let found = lloyd(&points, seeds, &KMeansOptions::with_k(2), &Silent);
        assert_eq!(found.labels, [0, 0, 0, 1]);
        assert_eq!(found.centres.row(1).to_vec(), [5.0, 5.0]);
    }

    #[test]
    fn any_memory_layout_gives_the_same_result() {
        let data = uniform(300, 7, 1.0, 8);
        let transposed = data.t().to_owned();
        let options = KMeansOptions::with_k(5);
        let a = kmeans(data.view(), &options, &Silent).unwrap();
        let b = kmeans(transposed.t(), &options, &Silent).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn bad_inputs_are_rejected() {
        let data = uniform(10, 3, 1.0, 9);
        let err = |d: ArrayView2<f32>, o: KMeansOptions| kmeans(d, &o, &Silent).unwrap_err().to_string();
        assert!(err(data.view(), KMeansOptions::with_k(0)).contains("k must be at least 1"));
        assert!(err(Array2::zeros((0, 3)).view(), KMeansOptions::with_k(2)).contains("nothing to cluster"));
        let mut bad = data.clone();
        bad[[4, 2]] = f32::INFINITY;
        assert!(err(bad.view(), KMeansOptions::with_k(2)).contains("point 4 has inf in dimension 2"));
        let negative = KMeansOptions { tolerance: -1.0, ..KMeansOptions::with_k(2) };
        assert!(err(data.view(), negative).contains("tolerance"));
        let no_runs = KMeansOptions { runs: 0, ..KMeansOptions::with_k(2) };
        assert!(err(data.view(), no_runs).contains("runs must be at least 1"));
        let e = assign(data.view(), Array2::zeros((2, 4)).view()).unwrap_err();
        assert!(e.to_string().contains("centres have 4 dimensions but the points have 3"));
    }

    /// Textbook k-means++ drawing the same random numbers, without the pruning.
    fn unpruned_plus_plus(data: &Array2<f32>, k: usize, seed: u64) -> Array2<f32> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let row = |i: usize| data.row(i).to_vec();
        let mut chosen = vec![rng.random_range(0..data.nrows())];
        let mut nearest: Vec<f32> =
            (0..data.nrows()).map(|i| squared_distance(&row(i), &row(chosen[0]))).collect();
        while chosen.len() < k {
            let total: f64 = nearest.iter().map(|&d| d as f64).sum();
            let weights: Vec<(f32, usize)> = nearest.iter().map(|&d| (d, 0)).collect();
            let next = sample(&weights, rng.random::<f64>() * total);
            chosen.push(next);
            for (i, d) in nearest.iter_mut().enumerate() {
                *d = d.min(squared_distance(&row(i), &row(next)));
            }
        }
        data.select(ndarray::Axis(0), &chosen)
    }

    #[test]
    fn pruning_leaves_the_seeds_unchanged() {
        // Tight clusters are where the triangle-inequality test skips most points.
        let centres = uniform(20, 16, 10.0, 11);
        let (data, _) = blobs(&centres, 30, 0.2, 12);
        for seed in 0..5 {
            let seeds = kmeans_plus_plus(data.view(), 40, seed).unwrap();
            assert_eq!(seeds, unpruned_plus_plus(&data, 40, seed), "seed {seed}");
        }
    }

    #[test]
    fn seeds_are_distinct_rows_of_the_data() {
        let data = uniform(200, 5, 1.0, 10);
        let seeds = kmeans_plus_plus(data.view(), 20, 1).unwrap();
        assert_eq!(seeds.nrows(), 20);
        for seed in seeds.rows() {
            assert_eq!(data.rows().into_iter().filter(|r| *r == seed).count(), 1);
        }
        assert_eq!(seeds, kmeans_plus_plus(data.view(), 20, 1).unwrap());
        assert_ne!(seeds, kmeans_plus_plus(data.view(), 20, 2).unwrap());
    }
}
