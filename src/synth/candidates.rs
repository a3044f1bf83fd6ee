//! Candidate sets (Tong §5.2): k-coherence from the kNN lists at the forward-shifted
//! coordinates of the patch's vertices, or every pixel (full search).

use super::sample::SampleLevel;
use super::state::State;

/// How candidates are formed (Tong §5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Search {
    /// The union of the kNN lists (first `k` entries) at the forward-shifted coordinates of
    /// the patch's vertices.
    KCoherence {
        /// Entries read from each kNN list (capped by the lists' length).
        k: usize,
    },
    /// Every candidate texel of the sample, the target's margin inside its edges (Table 2's full
    /// search; [`super::target::TargetLevel::candidate_margin`]).
    Full,
    /// Every candidate, as [`Search::Full`], found through Castellanos and Williams' dynamic
    /// kd-trees over the eigenvector-transformed neighbourhoods (§6, [`super::kdtrees`]):
    /// within 1 + ε of its choice, comparing only the candidates that can win by more than
    /// that ([`super::kdtrees::APPROXIMATION`]). Isotropic passes under
    /// [`super::Select::UsePenalty`] or [`super::Select::Argmin`], in a sequential order.
    KdTrees,
}

impl Search {
    /// How many entries of each kNN list the search reads (all of them for a full search,
    /// where lists only guide placement).
    pub fn list_length(&self, sample: &SampleLevel) -> usize {
        match *self {
            Search::KCoherence { k } => k.min(sample.k),
            Search::Full | Search::KdTrees => sample.k,
        }
    }
}

/// Every texel `margin` inside the sample's edges (all of them when it tiles), for the full
/// search.
pub fn full_candidates(sample: &SampleLevel, margin: usize) -> Vec<u32> {
    (0..(sample.width * sample.height) as u32)
        .filter(|&p| {
            sample.is_candidate(
                (p as usize % sample.width) as i64,
                (p as usize / sample.width) as i64,
                margin,
            )
        })
        .collect()
}

/// `t.round() as i64` (halves away from zero, saturating), without the call into libm's
/// `roundf` that x86-64's baseline instruction set needs for it: every visit rounds two
/// values per patch vertex, and the call was 2.5% of a plane synthesis. Exact: `t` minus
/// its integer part is exact in f32, so the comparisons with ±½ decide as `round` does.
#[inline]
pub(crate) fn round_to_i64(t: f32) -> i64 {
    let whole = t as i64;
    let fraction = t - whole as f32;
    whole.saturating_add((fraction >= 0.5) as i64).saturating_sub((fraction <= -0.5) as i64)
}

/// Gathers k-coherence candidates, deduplicated by a per-visit stamp.
pub struct Coherence {
    stamp: Vec<u32>,
    /// Texels that are some patch vertex's forward shift itself during the visit that
    /// stamped them: candidates that continue a copy rather than start a new one.
    shift_stamp: Vec<u32>,
    visit: u32,
    /// The candidates of the last [`Coherence::gather`], deduplicated, in gathering order.
    pub(crate) out: Vec<u32>,
}

impl Coherence {
    /// A gatherer for candidates among `sample`'s texels, reused across a pass's visits.
    pub fn new(sample: &SampleLevel) -> Self {
        let n = sample.width * sample.height;
        Coherence { stamp: vec![u32::MAX; n], shift_stamp: vec![u32::MAX; n], visit: 0, out: Vec::new() }
    }

    /// The candidates of a vertex whose patch vertices are `shifts` (with their offsets in
    /// texels; with `known`, only those synthesized so far count): each one's coordinate
    /// shifted back by its offset and, where that lands on a candidate texel, the first `k`
    /// entries of its list. A shift that lands outside is dropped, not clamped: clamping sends
    /// every such shift to the same edge texel, which then wins by sheer repetition.
    pub fn gather(
        &mut self,
        shifts: &[(u32, [f32; 2])],
        known: Option<&[bool]>,
        state: &State,
        sample: &SampleLevel,
        (k, radius, two_level): (usize, usize, bool),
    ) -> &[u32] {
        self.visit = self.visit.wrapping_add(1);
        self.out.clear();
        for &(u, offset) in shifts {
            if known.is_some_and(|known| !known[u as usize]) {
                continue;
            }
            let [su, sv] = state.uv[u as usize];
            let x = round_to_i64(su as f32 - offset[0]);
            let y = round_to_i64(sv as f32 - offset[1]);
            if !sample.is_candidate(x, y, radius) {
                continue;
            }
            let pixel = sample.candidate_pixel(x, y, radius);
            // Where the neighbours are coherent, most shifts land on a pixel already seen,
            // whose whole list is in already.
            if self.shift_stamp[pixel] == self.visit {
                continue;
            }
            self.shift_stamp[pixel] = self.visit;
            for &q in sample.list(pixel, k, two_level) {
                if self.stamp[q as usize] != self.visit {
                    self.stamp[q as usize] = self.visit;
                    self.out.push(q);
                }
            }
        }
        &self.out
    }

    /// Whether texel `q` is a forward shift of the vertex last gathered for: it continues
    /// a neighbour's copy.
    #[inline]
    pub fn continues(&self, q: u32) -> bool {
        self.shift_stamp[q as usize] == self.visit
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::round_to_i64;
    use rand::{Rng, SeedableRng};

    /// Floats where rounding to an integer goes wrong first: halves and whole numbers with
    /// their neighbours in bit pattern (a NaN and the least subnormal beside 0), random
    /// values in ±600, beyond 2^23 and beyond i64's range, ±0, NaN, ±∞.
    pub(crate) fn awkward_floats(seed: u64) -> Vec<f32> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let halves = (-40..=40).map(|i| i as f32 * 0.5);
        let beside = halves.clone().flat_map(|h| {
            let bits = h.to_bits();
            [f32::from_bits(bits.wrapping_sub(1)), f32::from_bits(bits.wrapping_add(1))]
        });
        let mut random =
            |bound: f32| (0..10_000).map(|_| rng.random_range(-bound..bound)).collect::<Vec<f32>>();
        let (narrow, wide, beyond_i64) = (random(600.0), random(3.0e9), random(3.0e19));
        let odd =
            [0.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 8_388_607.5, -8_388_607.5, 1e30, -1e30];
        halves.chain(beside).chain(narrow).chain(wide).chain(beyond_i64).chain(odd).collect()
    }

    #[test]
    fn rounding_agrees_with_round_everywhere() {
        for t in awkward_floats(3) {
            assert_eq!(round_to_i64(t), t.round() as i64, "{t}");
        }
    }
}
