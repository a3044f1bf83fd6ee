//! Elkan's bounds for Lloyd's iterations (Elkan 2003, "Using the triangle inequality to
//! accelerate k-means"): per point an upper bound on the distance to its own centre, and
//! per point and centre a lower bound on the distance to that centre. While every other
//! centre's lower bound stays above the upper bound, the point keeps its centre and its row
//! of the distance product need not be computed; the bounds follow the centres by the
//! distances they moved.
//!
//! The labels must stay those of the full product, whose scores `‖c‖² − 2x·c` are rounded:
//! a point is only left alone when the gap between the bounds exceeds twice the largest
//! error those scores can have, so the rounded scores would have named the same centre.

use rayon::prelude::*;

/// Most lower bounds kept (f32 each, 64 MiB); beyond, no point is ever settled and every
/// iteration evaluates every point, as plain Lloyd does.
pub const MOST_LOWER_BOUNDS: usize = 1 << 24;

/// Distance bounds of `n` points to `k` centres (distances, not squared).
pub struct Bounds {
    /// Per point: at least the distance to its current centre; +∞ when unknown.
    upper: Vec<f64>,
    /// Per point, `k` in a row: at most the distance to each centre (rounded down).
    lower: Vec<f32>,
    /// ‖x‖ of each point.
    norms: Vec<f64>,
    /// Dimensions: rounding errors grow with the length of a sum.
    dims: usize,
    k: usize,
}

impl Bounds {
    /// Bounds that settle nothing yet, for points with norms `norms` in `dims` dimensions
    /// and `k` centres; none are kept if there would be more than `most` lower bounds.
    pub fn new(norms: Vec<f64>, dims: usize, k: usize, most: usize) -> Self {
        let n = norms.len();
        let lower = match n.checked_mul(k) {
            Some(entries) if entries <= most => vec![0.0; entries],
            _ => Vec::new(),
        };
        Bounds { upper: vec![f64::INFINITY; n], lower, norms, dims, k }
    }

    /// Relative error of a sum of `dims` f32 products, with fourfold room: Higham's
    /// γₙ ≈ n·u with u = ε/2, and one more rounding for the score's subtraction.
    fn relative_error(&self) -> f64 {
        2.0 * (self.dims + 3) as f64 * f32::EPSILON as f64
    }

    /// An upper bound on a distance whose square was computed as `squared` in f32.
    pub fn distance_above(&self, squared: f32) -> f64 {
        (squared.max(0.0) as f64 * (1.0 + self.relative_error())).sqrt()
    }

    /// The most a score `‖c‖² − 2x·c` of point `i` can be off by, for a centre of norm at
    /// most `centre_norm`: the products' error is bounded by γₙ·Σ|xₖcₖ| ≤ γₙ‖x‖‖c‖. The
    /// second term covers the scores' vectors being the points and centres moved to the
    /// origin in f32 (each component rounded once), while the bounds measure the vectors
    /// themselves: the squared distances differ by less than 3u(‖x‖ + ‖c‖)².
    fn score_error(&self, i: usize, centre_norm: f64) -> f64 {
        let (x, c) = (self.norms[i], centre_norm);
        self.relative_error() * (c * c + 2.0 * x * c) + 2.0 * f32::EPSILON as f64 * (x + c) * (x + c)
    }

    /// Whether a bound is kept per point and centre (false when there would be too many,
    /// and then no point is ever settled).
    pub fn per_centre(&self) -> bool {
        !self.lower.is_empty()
    }

    /// Whether point `i` has had a full evaluation since it last changed centre outside one.
    pub fn known(&self, i: usize) -> bool {
        self.upper[i].is_finite()
    }

    /// Point `i`'s lower bounds from a full evaluation: every centre's score `‖c‖² − 2x·c`
    /// (as rounded), with the centres' norms at most `centre_norms`. Empty if none are kept.
    pub fn lower_row(&self, i: usize, scores: impl Iterator<Item = f32>, centre_norms: &[f64]) -> Vec<f32> {
        if !self.per_centre() {
            return Vec::new();
        }
        let square = self.norms[i] * self.norms[i];
        let bound = |(score, &norm): (f32, &f64)| score as f64 + square - self.score_error(i, norm);
        scores.zip(centre_norms).map(|s| round_down(bound(s).max(0.0).sqrt())).collect()
    }

    /// Records a full evaluation of point `i`: the squared distance to its nearest centre
    /// and its [`Bounds::lower_row`].
    pub fn record(&mut self, i: usize, squared: f32, lower: &[f32]) {
        self.upper[i] = self.distance_above(squared);
        if self.per_centre() {
            self.lower[i * self.k..(i + 1) * self.k].copy_from_slice(lower);
        }
    }

    /// Point `i`'s distance to its centre, newly computed (squared, f32).
    pub fn tighten(&mut self, i: usize, squared: f32) {
        self.upper[i] = self.distance_above(squared);
    }

    /// Whether point `i`, `squared` (as computed) from its centre `label`, certainly keeps
    /// it, the centres' norms being at most `centre_norms`: every other centre is farther by
    /// more than the two scores' rounding.
    pub fn settles(&self, i: usize, label: usize, squared: f32, centre_norms: &[f64]) -> bool {
        if !self.per_centre() || !self.upper[i].is_finite() {
            return false;
        }
        let upper = self.distance_above(squared);
        let own = upper * upper + self.score_error(i, centre_norms[label]);
        let row = &self.lower[i * self.k..(i + 1) * self.k];
        let others = row.iter().zip(centre_norms).enumerate().filter(|&(j, _)| j != label);
        others
            .map(|(_, (&l, &norm))| l as f64 * l as f64 - self.score_error(i, norm))
            .all(|other| other > own)
    }

    /// Point `i` changed centre outside a full evaluation: nothing is known.
    pub fn forget(&mut self, i: usize) {
        self.upper[i] = f64::INFINITY;
    }

    /// The centres moved by `shifts` (upper bounds on each centre's distance moved): each
    /// point's own centre may have come closer by at most its shift, and so may any other.
    pub fn moved(&mut self, labels: &[usize], shifts: &[f64]) {
        for (upper, &label) in self.upper.iter_mut().zip(labels) {
            *upper += shifts[label];
        }
        let shifts: Vec<f32> = shifts.iter().map(|&s| round_up(s)).collect();
        self.lower.par_chunks_mut(self.k).with_min_len(64).for_each(|row| {
            for (lower, &shift) in row.iter_mut().zip(&shifts) {
                // Rounding here can only lower a bound, never raise it.
                *lower = (*lower - shift).max(0.0);
            }
        });
    }
}

/// The largest f32 not above `x` (x ≥ 0).
fn round_down(x: f64) -> f32 {
    let y = x as f32;
    if y as f64 > x && y > 0.0 {
        f32::from_bits(y.to_bits() - 1)
    } else {
        y
    }
}

/// The smallest f32 not below `x` (x ≥ 0).
fn round_up(x: f64) -> f32 {
    let y = x as f32;
    if (y as f64) < x {
        f32::from_bits(y.to_bits() + 1)
    } else {
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_far_inside_its_cluster_is_settled_until_the_centres_move_enough() {
        let mut bounds = Bounds::new(vec![1.0], 4, 2, MOST_LOWER_BOUNDS);
        assert!(!bounds.settles(0, 0, 1.0, &[10.0; 2]), "nothing is known before a full evaluation");
        // Own centre at distance 1, the other at distance 3: score = d² − ‖x‖².
        let lower = bounds.lower_row(0, [0.0, 8.0].into_iter(), &[10.0; 2]);
        bounds.record(0, 1.0, &lower);
        assert!(bounds.settles(0, 0, 1.0, &[10.0; 2]));
        bounds.moved(&[0], &[0.5, 0.5]);
        assert!(bounds.settles(0, 0, 1.5 * 1.5, &[10.0; 2]), "1.5 < 2.5");
        bounds.moved(&[0], &[0.6, 0.6]);
        assert!(!bounds.settles(0, 0, 2.1 * 2.1, &[10.0; 2]), "2.1 > 1.9");
        assert!(bounds.settles(0, 0, 1.0, &[10.0; 2]), "own centre measured again: 1 < 1.9");
        bounds.forget(0);
        assert!(!bounds.settles(0, 0, 1.0, &[10.0; 2]));
    }

    #[test]
    fn each_centre_lowers_its_own_bound() {
        let mut bounds = Bounds::new(vec![0.0], 2, 3, MOST_LOWER_BOUNDS);
        let lower = bounds.lower_row(0, [0.0, 16.0, 4.0].into_iter(), &[1.0; 3]);
        bounds.record(0, 0.0, &lower);
        bounds.moved(&[0], &[0.0, 3.0, 1.0]);
        let close = |a: f32, b: f32| (a - b).abs() < 1e-5;
        assert!(close(bounds.lower[1], 1.0) && close(bounds.lower[2], 1.0), "{:?}", bounds.lower);
        assert!(bounds.settles(0, 0, 0.0, &[1.0; 3]));
    }

    #[test]
    fn near_ties_are_never_settled() {
        // Large points, close centres: the gap 1e-4 is within the scores' rounding.
        let mut bounds = Bounds::new(vec![1000.0], 64, 2, MOST_LOWER_BOUNDS);
        let lower = bounds.lower_row(0, [1.0 - 1e6, 1.0001 - 1e6].into_iter(), &[1000.0; 2]);
        bounds.record(0, 1.0, &lower);
        assert!(!bounds.settles(0, 0, 1.0, &[1000.0; 2]));
    }

    #[test]
    fn too_many_bounds_settle_nothing() {
        let mut bounds = Bounds::new(vec![1.0; 1 << 13], 4, 1 << 12, MOST_LOWER_BOUNDS);
        assert!(!bounds.per_centre());
        let lower = bounds.lower_row(0, std::iter::repeat(1e6), &[10.0; 1 << 12]);
        bounds.record(0, 1.0, &lower);
        assert!(!bounds.settles(0, 0, 1.0, &[10.0; 2]));
    }

    #[test]
    fn rounding_goes_the_safe_way() {
        for x in [0.1f64, 1.0 / 3.0, 2.0, 1e-40, 0.0, 12345.678] {
            assert!(round_down(x) as f64 <= x && round_up(x) as f64 >= x, "{x}");
        }
    }
}
