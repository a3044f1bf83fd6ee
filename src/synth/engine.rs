//! The per-vertex synthesis engine (Tong §5): one pass visits every vertex and gives it the
//! candidate texel whose neighbourhood best matches the vertex's template.

use super::candidates::{full_candidates, Coherence, Search};
use super::metric::Metric;
use super::recipe::Mask;
use super::sample::SampleLevel;
use super::target::{Shift, Slot, TargetLevel};
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

/// The surface texton map of one level: per vertex a texton label and a sample coordinate.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    pub labels: Vec<u16>,
    pub uv: Vec<[i32; 2]>,
}

/// Order in which a pass visits the vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum VisitOrder {
    /// A fresh seeded permutation every pass.
    Random,
    /// Vertex index order (scanline order on a plane).
    Sequential,
    /// Increasing sweep distance along the texture direction (Turk §4.2, [`super::sweep`]).
    Sweep,
    /// The unvisited vertex with the most visited neighbours next (Chen and Dong §6,
    /// [`super::constrained`]).
    MostConstrained,
}

/// What one pass found.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassStats {
    /// Mean over vertices of the best candidate's neighbourhood distance.
    pub mean_best: f64,
    /// Mean candidate-set size.
    pub mean_candidates: f64,
}

/// How a vertex picks among its candidates.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Select {
    /// The smallest distance (Tong §5.1).
    Argmin,
    /// Choosy sampling (Castellanos and Williams §3.11, adapted): the distance is multiplied
    /// by 1 + strength · excess², excess being how far beyond its fair share (output
    /// vertices over candidate texels) the texel is already used on this level. Exact matches
    /// (distance 0) keep winning, so coherent copies are untouched; among inexact ones, the
    /// texels the level leans on too often lose, which keeps the first-order statistics.
    Choosy { strength: f32 },
}

/// How a pass runs.
#[derive(Clone, Copy, Debug)]
pub struct PassPlan {
    pub search: Search,
    pub select: Select,
    /// Distances of candidates that start a new copy (not a patch vertex's forward shift)
    /// are multiplied by 1 + this (Ashikhmin's and Hertzmann's coherence preference).
    pub coherence_bias: f32,
    /// Which template pixels count, in distances and as sources of candidates. With
    /// [`Mask::Visited`] and [`Mask::Half`], a vertex with no source of candidates starts from
    /// a random texel.
    pub mask: Mask,
}

/// The coarser level while refining: its state and metric, for two-level neighbourhoods
/// (a candidate (x, y) is compared there at (x/2, y/2)).
pub(crate) struct Parent<'a, M> {
    pub state: &'a State,
    pub metric: M,
    /// Where the parent neighbourhood comes from: the level's narrow parent templates
    /// (`None`), or this coarser level's own templates at the parent vertex (Turk's F(n, 1)).
    pub wide: Option<&'a TargetLevel>,
}

impl<M> Parent<'_, M> {
    /// The parent-neighbourhood slots of `level`'s vertex v.
    fn slots_of<'s>(&'s self, level: &'s TargetLevel, v: usize, scratch: &'s mut Vec<Slot>) -> &'s [Slot] {
        match (self.wide, level.parents.get(v)) {
            (Some(coarse), Some(link)) => coarse.slots_of(link.vertex as usize, scratch),
            _ => level.parent_slots_of(v, scratch),
        }
    }
}

/// The template `slots` (side `template`) under `mask`: pixels outside it become
/// [`Slot::NONE`], which no metric compares.
fn masked<'a>(slots: &'a [Slot], mask: Mask, template: usize, scratch: &'a mut Vec<Slot>) -> &'a [Slot] {
    match mask {
        Mask::Full | Mask::Visited => slots,
        Mask::Off => &[],
        Mask::Half => {
            let r = template / 2;
            let centre = r * template + r;
            let upstream = |i: usize| i % template <= r && i != centre;
            scratch.clear();
            scratch.extend(slots.iter().enumerate().map(|(i, &s)| if upstream(i) { s } else { Slot::NONE }));
            scratch
        }
    }
}

/// The forward shifts under `mask`: with [`Mask::Half`], only those upstream or level
/// (x ≤ 0; the pass's visited mask then drops those not visited yet).
fn masked_shifts<'a>(shifts: &'a [Shift], mask: Mask, scratch: &'a mut Vec<Shift>) -> &'a [Shift] {
    if mask != Mask::Half {
        return shifts;
    }
    scratch.clear();
    scratch.extend(shifts.iter().filter(|s| s.1[0] < 0.5));
    scratch
}

/// One pass over `level`: every vertex takes the candidate whose neighbourhood best matches
/// its own under `metric` (plus its parent neighbourhood's, when there is a parent).
#[allow(clippy::too_many_arguments)]
pub(crate) fn pass<M: Metric>(
    level: &TargetLevel,
    state: &mut State,
    sample: &SampleLevel,
    metric: &M,
    parent: Option<&Parent<M>>,
    plan: &PassPlan,
    order: &[u32],
    rng: &mut ChaCha8Rng,
) -> PassStats {
    let radius = level.template / 2;
    let full = matches!(plan.search, Search::Full).then(|| full_candidates(sample, radius));
    let mut coherence = Coherence::new(sample);
    let mut known = matches!(plan.mask, Mask::Visited | Mask::Half).then(|| vec![false; level.vertices]);
    let (mut own, mut up) = (M::Query::default(), M::Query::default());
    let (mut slots, mut parent_slots, mut shifts) = (Vec::new(), Vec::new(), Vec::new());
    let (mut masked_slots, mut vertex_shifts) = (Vec::new(), Vec::new());
    let (mut best_sum, mut candidate_sum) = (0.0f64, 0usize);
    let mut usage = Usage::new(sample, state, radius, plan.select);
    for &v in order {
        let v = v as usize;
        let own_slots = masked(level.slots_of(v, &mut slots), plan.mask, level.template, &mut masked_slots);
        metric.prepare(own_slots, state, known.as_deref(), &mut own);
        if let Some(p) = parent {
            p.metric.prepare(p.slots_of(level, v, &mut parent_slots), p.state, None, &mut up);
        }
        let shift_list = masked_shifts(level.shifts_of(v, &mut shifts), plan.mask, &mut vertex_shifts);
        let seed;
        let k = if let Search::KCoherence { k } = plan.search { k } else { 1 };
        // A full search gathers the forward shifts too, to know which texels continue a copy.
        let gathered =
            coherence.gather(shift_list, known.as_deref(), state, sample, (k, radius, parent.is_some()));
        let set: &[u32] = match &full {
            Some(all) => all,
            None if gathered.is_empty() => {
                let [x, y] = super::start::random_texel(sample, radius, rng);
                seed = [(y as usize * sample.width + x as usize) as u32];
                &seed
            }
            None => &coherence.out,
        };
        let current = state.uv[v];
        let score = |q: u32, bound: f32| -> f32 {
            let (x, y) = ((q as usize % sample.width) as i64, (q as usize / sample.width) as i64);
            let factor = selection_factor(&usage, &coherence, q, current, plan.coherence_bias);
            let bound = bound / factor;
            let mut d = metric.cost(&own, x, y, bound);
            if let (Some(p), true) = (parent, d < bound) {
                d += p.metric.cost(&up, x / 2, y / 2, bound - d);
            }
            d * factor
        };
        let mut best = (f32::INFINITY, current);
        // An extrapolating pass sees only the parent level, on which the four texels of a
        // parent texel tie: it keeps the inherited texel unless another is strictly better.
        if plan.mask == Mask::Off {
            best.0 = score((current[1] as usize * sample.width + current[0] as usize) as u32, f32::INFINITY);
        }
        for &q in set {
            let d = score(q, best.0);
            if d < best.0 {
                best = (d, [(q as usize % sample.width) as i32, (q as usize / sample.width) as i32]);
            }
        }
        if best.0.is_finite() {
            usage.moved(current, best.1);
            state.uv[v] = best.1;
            state.labels[v] = sample.label_at(best.1[0] as i64, best.1[1] as i64);
            best_sum += best.0 as f64;
        }
        if let Some(k) = known.as_mut() {
            k[v] = true;
        }
        candidate_sum += set.len();
    }
    let n = order.len().max(1) as f64;
    PassStats { mean_best: best_sum / n, mean_candidates: candidate_sum as f64 / n }
}

/// The factor on candidate `q`'s distance for a vertex now at `current`: choosy
/// selection's usage penalty times the coherence bias on candidates that start a new copy.
#[inline]
pub(crate) fn selection_factor(
    usage: &Usage,
    coherence: &Coherence,
    q: u32,
    current: [i32; 2],
    bias: f32,
) -> f32 {
    let fresh = if coherence.continues(q) { 1.0 } else { 1.0 + bias };
    usage.factor(q, current) * fresh
}

/// How often each texel is in use on the level, for [`Select::Choosy`].
pub(crate) struct Usage {
    width: usize,
    /// Per texel, the vertices whose coordinate it is (empty for [`Select::Argmin`]).
    count: Vec<u32>,
    fair: f32,
    strength: f32,
}

impl Usage {
    pub(crate) fn new(sample: &SampleLevel, state: &State, radius: usize, select: Select) -> Self {
        let Select::Choosy { strength } = select else {
            return Usage { width: sample.width, count: Vec::new(), fair: 1.0, strength: 0.0 };
        };
        let mut count = vec![0u32; sample.width * sample.height];
        for &[x, y] in &state.uv {
            count[y as usize * sample.width + x as usize] += 1;
        }
        let candidates = full_candidates(sample, radius).len().max(1);
        Usage {
            width: sample.width,
            count,
            fair: (state.uv.len() as f32 / candidates as f32).max(1.0),
            strength,
        }
    }

    /// The factor on texel `q`'s distance for a vertex now at `current`.
    #[inline]
    pub(crate) fn factor(&self, q: u32, current: [i32; 2]) -> f32 {
        let Some(&n) = self.count.get(q as usize) else { return 1.0 };
        let own = u32::from(current[1] as usize * self.width + current[0] as usize == q as usize);
        let excess = ((n - own) as f32 / self.fair - 1.0).max(0.0);
        1.0 + self.strength * excess * excess
    }

    pub(crate) fn moved(&mut self, from: [i32; 2], to: [i32; 2]) {
        if !self.count.is_empty() {
            self.count[from[1] as usize * self.width + from[0] as usize] -= 1;
            self.count[to[1] as usize * self.width + to[0] as usize] += 1;
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
        _ => {}
    }
    ids
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::synth::metric::GammaMetric;
    use crate::synth::target::grid_levels;
    use rand::SeedableRng;

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

    /// A metric that records what a pass lets it read: every vertex whose state a template
    /// would use must have been visited before the vertex being matched.
    struct Spy<'a> {
        order: &'a [u32],
        rank: &'a [usize],
        next: std::cell::Cell<usize>,
        reads: std::cell::Cell<usize>,
    }

    impl Metric for Spy<'_> {
        type Query = ();
        fn prepare(&self, slots: &[Slot], _: &State, known: Option<&[bool]>, _: &mut ()) {
            let v = self.order[self.next.get()] as usize;
            self.next.set(self.next.get() + 1);
            for (_, parts, count) in crate::synth::metric::known_parts(slots, known) {
                for &(u, _) in &parts[..count] {
                    assert!(self.rank[u as usize] < self.rank[v], "vertex {v} reads vertex {u}");
                    self.reads.set(self.reads.get() + 1);
                }
            }
        }
        fn cost(&self, _: &(), _: i64, _: i64, _: f32) -> f32 {
            0.0
        }
        fn texel_distance(&self, _: [i32; 2], _: [i32; 2]) -> f32 {
            0.0
        }
    }

    /// Turk's half square H(n, 0), in sweep order, reads only vertices visited before:
    /// its template pixels and its forward shifts alike.
    #[test]
    fn a_half_square_reads_only_vertices_visited_before_in_sweep_order() {
        let targets = grid_levels(21, 13, 2, 7, 3);
        let sweep = crate::synth::sweep::sweep_distances(&targets, 5);
        let level = &targets[0];
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let order = visit_order(level, VisitOrder::Sweep, Some(&sweep[0]), &mut rng);
        let mut rank = vec![0usize; level.vertices];
        order.iter().enumerate().for_each(|(i, &v)| rank[v as usize] = i);
        let sample = periodic_sample(4);
        let mut state = crate::synth::start::random_state(level, &sample, 3, &mut rng);
        let spy = Spy { order: &order, rank: &rank, next: 0.into(), reads: 0.into() };
        let plan = PassPlan {
            search: Search::KCoherence { k: 4 },
            select: Select::Argmin,
            coherence_bias: 0.0,
            mask: Mask::Half,
        };
        pass(level, &mut state, &sample, &spy, None, &plan, &order, &mut rng);
        // Away from the upstream edge, a half square reads three columns and the part of the
        // middle one above the vertex: 24 of its 49 pixels.
        assert!(spy.reads.get() > level.vertices * 12, "{} pixels read", spy.reads.get());
        // Forward shifts come from the same side (the visited mask drops the middle column's
        // vertices not visited yet, as it does for pixels).
        let (mut shifts, mut scratch) = (vec![], vec![]);
        for v in 0..level.vertices {
            for &(u, o) in masked_shifts(level.shifts_of(v, &mut shifts), Mask::Half, &mut scratch) {
                assert!(o[0] <= 0.0, "vertex {v} shifts from downstream vertex {u}");
                assert!(o[0] == 0.0 || rank[u as usize] < rank[v], "vertex {v} shifts from {u}");
            }
        }
        // A full square does read vertices not visited yet.
        let mut slots = vec![];
        let full = level.slots_of(21 * 6 + 10, &mut slots);
        assert!(full.iter().any(|s| rank[s.vertices[0] as usize] > rank[21 * 6 + 10]));
    }

    #[test]
    fn an_exact_copy_is_a_fixed_point_of_a_full_search_pass() {
        let sample = periodic_sample(4);
        let level = &grid_levels(32, 32, 1, 5, 3)[0];
        let uv: Vec<[i32; 2]> = (0..32 * 32).map(|v| [v % 32 % 16, v / 32 % 16]).collect();
        let labels = uv.iter().map(|&[x, y]| sample.label_at(x as i64, y as i64)).collect();
        let mut state = State { labels, uv };
        let before = state.clone();
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let order: Vec<u32> = (0..32 * 32).collect();
        let metric = GammaMetric { sample: &sample, template: 5 };
        let plan =
            PassPlan { search: Search::Full, select: Select::Argmin, coherence_bias: 0.0, mask: Mask::Full };
        pass(level, &mut state, &sample, &metric, None, &plan, &order, &mut rng);
        let interior_changed = (0..32 * 32)
            .filter(|&v| {
                (2..30).contains(&(v % 32))
                    && (2..30).contains(&(v / 32))
                    && state.labels[v] != before.labels[v]
            })
            .count();
        assert_eq!(interior_changed, 0);
    }
}
