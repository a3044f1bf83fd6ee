//! The per-vertex synthesis engine's vocabulary (Tong §5): the state a pass rewrites, the
//! order it visits vertices in, how a vertex picks among candidates, and what a pass
//! reports. The pass loop itself is [`super::pass`].

use super::candidates::{full_candidates, Coherence, Search};
use super::neighbourhood::Mask;
pub use super::recipe::{Select, VisitOrder};
use super::sample::SampleLevel;
pub use super::state::State;
use super::target::TargetLevel;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

/// What one pass found.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassStats {
    /// Mean over vertices of the best candidate's neighbourhood distance.
    pub mean_best: f64,
    /// Mean candidate-set size.
    pub mean_candidates: f64,
}

/// How a pass runs.
#[derive(Clone, Copy, Debug)]
pub struct PassPlan<'a> {
    /// How the candidates are formed.
    pub search: Search,
    /// How one of them is chosen.
    pub select: Select,
    /// Distances of candidates that start a new copy (not a patch vertex's forward shift)
    /// are multiplied by 1 + this (Ashikhmin's and Hertzmann's coherence preference).
    pub coherence_bias: f32,
    /// Which template pixels count, in distances and as sources of candidates. With
    /// [`Mask::Visited`] and [`Mask::Half`], a vertex with no source of candidates starts from
    /// a random texel.
    pub mask: Mask,
    /// Per vertex, the factor on its distance to any texel but its current one
    /// ([`super::recipe::KeepInteriors`]); none: 1 everywhere.
    pub move_cost: Option<&'a [f32]>,
}

/// The factor on candidate `q`'s distance for a vertex now at `current`, whose candidates'
/// least use count is `floor` ([`Usage::floor`]): the selection's usage penalty times the
/// coherence bias on candidates that start a new copy.
#[inline]
pub(crate) fn selection_factor(
    usage: &Usage,
    coherence: &Coherence,
    q: u32,
    (current, floor): ([i32; 2], u32),
    bias: f32,
) -> f32 {
    let fresh = if coherence.continues(q) { 1.0 } else { 1.0 + bias };
    usage.factor(q, current, floor) * fresh
}

/// How often each texel is used on the level, for the selections that penalize use.
pub(crate) struct Usage {
    width: usize,
    /// Per texel: for [`Select::Choosy`] the vertices whose coordinate it is, for
    /// [`Select::UsePenalty`] the times it was chosen in this pass (empty for Argmin).
    count: Vec<u32>,
    rule: UsageRule,
    /// Under a search of every candidate through kd-trees ([`Search::KdTrees`]), which
    /// compares only some of them: the level's floor, kept as choices are made.
    level: Option<Tally>,
}

/// How many of the level's candidate texels have each use count, so that the least count
/// over the level costs no scan per visit.
struct Tally {
    candidate: Vec<bool>,
    with_count: Vec<u32>,
    floor: u32,
}

impl Tally {
    fn new(texels: usize, candidates: &[u32]) -> Self {
        let mut candidate = vec![false; texels];
        candidates.iter().for_each(|&q| candidate[q as usize] = true);
        Tally { candidate, with_count: vec![candidates.len() as u32], floor: 0 }
    }

    /// A candidate chosen `before` times was chosen again.
    fn raise(&mut self, q: usize, before: u32) {
        if !self.candidate[q] {
            return;
        }
        let c = before as usize;
        if self.with_count.len() == c + 1 {
            self.with_count.push(0);
        }
        self.with_count[c] -= 1;
        self.with_count[c + 1] += 1;
        while self.with_count[self.floor as usize] == 0 {
            self.floor += 1;
        }
    }
}

enum UsageRule {
    Argmin,
    /// [`Select::Choosy`]: texels beyond their fair share of uses lose.
    FairShare {
        fair: f32,
        strength: f32,
    },
    /// [`Select::UsePenalty`]: `base`^(c − c_min), c_min from [`Usage::floor`].
    Chosen {
        base: f32,
    },
}

impl Usage {
    pub(crate) fn new(sample: &SampleLevel, state: &State, radius: usize, select: Select) -> Self {
        let (width, texels) = (sample.width, sample.width * sample.height);
        match select {
            Select::Argmin => Usage { width, count: Vec::new(), rule: UsageRule::Argmin, level: None },
            Select::Choosy { strength } => {
                let mut count = vec![0u32; texels];
                for &[x, y] in &state.uv {
                    count[y as usize * width + x as usize] += 1;
                }
                let candidates = full_candidates(sample, radius).len().max(1);
                let fair = (state.uv.len() as f32 / candidates as f32).max(1.0);
                Usage { width, count, rule: UsageRule::FairShare { fair, strength }, level: None }
            }
            Select::UsePenalty { base } => {
                Usage { width, count: vec![0; texels], rule: UsageRule::Chosen { base }, level: None }
            }
        }
    }

    /// Under `search`, with [`Select::UsePenalty`]: [`Usage::floor`] is the least count over
    /// the level's candidates within `radius` of the edge, whatever candidates it is given.
    /// For [`Search::KdTrees`], whose visits compare only the candidates worth comparing
    /// but choose among all of them, as the full search does.
    pub(crate) fn over_level(mut self, search: Search, sample: &SampleLevel, radius: usize) -> Self {
        if search == Search::KdTrees && matches!(self.rule, UsageRule::Chosen { .. }) {
            self.level = Some(Tally::new(self.count.len(), &full_candidates(sample, radius)));
        }
        self
    }

    /// The least use count among `candidates`, c_min of [`Select::UsePenalty`] (0 for the
    /// other selections). Under a full search it is the paper's minimum over the level; among
    /// k-coherence candidates it is the least over those the vertex can take, so that the
    /// penalty stays relative to the least-used choice at hand, not to texels no vertex
    /// can reach.
    pub(crate) fn floor(&self, candidates: &[u32]) -> u32 {
        if let Some(level) = &self.level {
            return level.floor;
        }
        match self.rule {
            UsageRule::Chosen { .. } => {
                candidates.iter().filter_map(|&q| self.count.get(q as usize)).min().copied().unwrap_or(0)
            }
            _ => 0,
        }
    }

    /// The factor on texel `q`'s distance for a vertex now at `current` whose candidates'
    /// least count is `floor`.
    #[inline]
    pub(crate) fn factor(&self, q: u32, current: [i32; 2], floor: u32) -> f32 {
        let Some(&n) = self.count.get(q as usize) else { return 1.0 };
        match self.rule {
            UsageRule::Argmin => 1.0,
            UsageRule::FairShare { fair, strength } => {
                let own = u32::from(current[1] as usize * self.width + current[0] as usize == q as usize);
                let uses = (n - own) as f32;
                // Within its fair share (as most texels are) the excess is 0: no division.
                // Beyond it the quotient is at least 1, as division by fair keeps the order.
                if uses <= fair {
                    return 1.0;
                }
                let excess = uses / fair - 1.0;
                1.0 + strength * excess * excess
            }
            // Beyond 2^60 no distance ratio matters; the cap keeps the power finite.
            UsageRule::Chosen { base } => base.powi(n.saturating_sub(floor).min(60) as i32),
        }
    }

    /// A vertex at `from` took `to` (the same texel counts as a choice too).
    pub(crate) fn moved(&mut self, from: [i32; 2], to: [i32; 2]) {
        let index = |[x, y]: [i32; 2]| y as usize * self.width + x as usize;
        match self.rule {
            UsageRule::Argmin => {}
            UsageRule::FairShare { .. } => {
                self.count[index(from)] -= 1;
                self.count[index(to)] += 1;
            }
            UsageRule::Chosen { .. } => {
                let before = self.count[index(to)];
                self.count[index(to)] += 1;
                if let Some(level) = &mut self.level {
                    level.raise(index(to), before);
                }
            }
        }
    }
}

/// The visiting order of one pass over `level`; [`VisitOrder::Sweep`] needs the level's
/// sweep distances (without them it falls back to index order).
pub fn visit_order(
    level: &TargetLevel,
    order: VisitOrder,
    sweep: Option<&[f32]>,
    rng: &mut ChaCha8Rng,
) -> Vec<u32> {
    let mut ids: Vec<u32> = (0..level.vertices as u32).collect();
    match (order, sweep) {
        (VisitOrder::Random, _) => ids.shuffle(rng),
        (VisitOrder::Sweep, Some(s)) => ids.sort_by(|&a, &b| s[a as usize].total_cmp(&s[b as usize])),
        (VisitOrder::MostConstrained, _) => return super::constrained::most_constrained_order(level, rng),
        // Only reached where the level has no colouring: the nearest sequential order.
        (VisitOrder::Interleaved, _) => ids.shuffle(rng),
        _ => {}
    }
    ids
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A tileable 16×16 sample of 4 orthonormal textons (Γ = I, default texton = their mean)
    /// in an aperiodic-looking but periodic layout.
    pub(crate) fn periodic_sample(k: usize) -> SampleLevel {
        let (w, h, n) = (16usize, 16usize, 5usize);
        let labels: Vec<u16> = (0..w * h)
            .map(|p| (((p % w) / 2 + (p / w) / 3 * 3 + (p % w) * (p / w) % 3) % 4) as u16)
            .collect();
        let mut gamma = vec![0.0f32; n * n];
        for i in 0..4 {
            gamma[i * n + i] = 1.0;
            gamma[i * n + 4] = 0.25;
            gamma[4 * n + i] = 0.25;
        }
        gamma[4 * n + 4] = 0.25;
        // Exhaustive kNN lists by plain label comparison of 5×5 wrapped neighbourhoods.
        let patch = |p: usize| -> Vec<u16> {
            let (x, y) = ((p % w) as i64, (p / w) as i64);
            (-2..=2)
                .flat_map(|dy| (-2..=2).map(move |dx| (dx, dy)))
                .map(|(dx, dy)| {
                    labels
                        [((y + dy).rem_euclid(h as i64) * w as i64 + (x + dx).rem_euclid(w as i64)) as usize]
                })
                .collect()
        };
        let mut knn = Vec::new();
        for p in 0..w * h {
            let mut others: Vec<(usize, usize)> = (0..w * h)
                .filter(|&q| q != p)
                .map(|q| (patch(p).iter().zip(patch(q)).filter(|(a, b)| **a != *b).count(), q))
                .collect();
            others.sort();
            knn.push(p as u32);
            knn.extend(others.iter().take(k - 1).map(|&(_, q)| q as u32));
        }
        SampleLevel {
            width: w,
            height: h,
            labels,
            gamma,
            textons: n,
            knn,
            knn_two_level: None,
            k,
            tileable: true,
            appearance: None,
            colour: None,
        }
    }

    /// The paper's penalty: 2^(c − c_min) by the times a texel was chosen in this pass, the
    /// texel the vertex already holds counting like any other, c_min the least count among
    /// the candidates at hand.
    #[test]
    fn the_use_penalty_doubles_per_choice_beyond_the_least_used_candidate() {
        let sample = periodic_sample(4);
        let state = State::new(vec![0; 3], vec![[0, 0]; 3]);
        let mut usage = Usage::new(&sample, &state, 1, Select::UsePenalty { base: 2.0 });
        assert_eq!(usage.factor(5, [5, 0], usage.floor(&[5, 6])), 1.0, "nothing chosen yet");
        usage.moved([0, 0], [5, 0]);
        usage.moved([0, 0], [5, 0]);
        usage.moved([0, 0], [6, 0]);
        assert_eq!(usage.floor(&[5, 6]), 1);
        assert_eq!(usage.factor(5, [5, 0], usage.floor(&[5, 6])), 2.0, "chosen twice against once");
        assert_eq!(usage.factor(5, [5, 0], usage.floor(&[5, 6, 7])), 4.0, "texel 7 never chosen");
        assert_eq!(usage.factor(6, [0, 0], usage.floor(&[5, 6])), 1.0);
        let argmin = Usage::new(&sample, &state, 1, Select::Argmin);
        assert_eq!(argmin.factor(5, [0, 0], argmin.floor(&[5])), 1.0);
    }

    /// Over the level (kd-trees), the floor is the least count of all candidates, whatever
    /// few the visit is given, and it rises once every candidate was chosen.
    #[test]
    fn the_level_floor_counts_every_candidate() {
        let sample = periodic_sample(4);
        let state = State::new(vec![0; 3], vec![[0, 0]; 3]);
        let select = Select::UsePenalty { base: 2.0 };
        let mut usage = Usage::new(&sample, &state, 1, select).over_level(Search::KdTrees, &sample, 1);
        usage.moved([0, 0], [5, 0]);
        assert_eq!(usage.floor(&[5]), 0, "other texels were never chosen");
        for q in 0..16 * 16 {
            usage.moved([0, 0], [q % 16, q / 16]);
        }
        assert_eq!((usage.floor(&[5]), usage.floor(&[6])), (1, 1));
    }
}
