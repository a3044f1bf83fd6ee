//! Square templates (Tong §5.1, Turk's half squares, Wei and Levoy's two-level
//! neighbourhoods) as the [`VertexMatch`] part of the pass loop: a vertex's template under
//! the pass's mask, plus its parent neighbourhood on the coarser level, compared with each
//! candidate by a [`Metric`].

use super::engine::State;
use super::metric::Metric;
use super::neighbourhood::Mask;
use super::pass::{Choice, VertexMatch};
use super::sample::SampleLevel;
use super::target::{Slot, TargetLevel};

/// The coarser level while refining: its state and metric, for two-level neighbourhoods
/// (a candidate (x, y) is compared there at (x/2, y/2)).
pub struct Parent<'a, M> {
    /// The coarser level's synthesized state.
    pub state: &'a State,
    /// The distance on the coarser level.
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

/// A vertex's square template (and parent neighbourhood) under a metric: the
/// [`VertexMatch`] of Tong's, Turk's and Wei and Levoy's neighbourhoods.
pub struct SquareMatch<'a, M: Metric> {
    level: &'a TargetLevel,
    sample: &'a SampleLevel,
    metric: &'a M,
    parent: Option<&'a Parent<'a, M>>,
    mask: Mask,
    own: M::Query,
    up: M::Query,
    scratch: [Vec<Slot>; 3],
}

impl<'a, M: Metric> SquareMatch<'a, M> {
    /// Matches `level`'s templates under `mask` with `metric` against `sample`, and with a
    /// parent neighbourhood on the coarser level where `parent` is given.
    pub fn new(
        level: &'a TargetLevel,
        sample: &'a SampleLevel,
        metric: &'a M,
        parent: Option<&'a Parent<'a, M>>,
        mask: Mask,
    ) -> Self {
        let (own, up, scratch) = (M::Query::default(), M::Query::default(), Default::default());
        SquareMatch { level, sample, metric, parent, mask, own, up, scratch }
    }

    fn texel(&self, q: u32) -> [i32; 2] {
        [(q as usize % self.sample.width) as i32, (q as usize / self.sample.width) as i32]
    }
}

impl<M: Metric> VertexMatch for SquareMatch<'_, M> {
    fn reach(&self) -> usize {
        self.level.template / 2
    }

    fn two_level(&self) -> bool {
        self.parent.is_some()
    }

    fn prepare(&mut self, v: usize, state: &State, known: Option<&[bool]>) {
        let [slots, parent_slots, masked_slots] = &mut self.scratch;
        let own_slots = masked(self.level.slots_of(v, slots), self.mask, self.level.template, masked_slots);
        self.metric.prepare(own_slots, state, known, &mut self.own);
        if let Some(p) = self.parent {
            p.metric.prepare(p.slots_of(self.level, v, parent_slots), p.state, None, &mut self.up);
        }
    }

    fn choose(
        &mut self,
        candidates: &[u32],
        current: [i32; 2],
        factor: impl Fn(u32) -> f32,
        draw: impl FnOnce() -> [i32; 2],
    ) -> Choice {
        let seed;
        let set = if candidates.is_empty() {
            let [x, y] = draw();
            seed = [(y as usize * self.sample.width + x as usize) as u32];
            &seed[..]
        } else {
            candidates
        };
        let (metric, own, up, parent) = (self.metric, &self.own, &self.up, self.parent);
        let width = self.sample.width;
        let score = |q: u32, bound: f32| -> f32 {
            let (x, y) = ((q as usize % width) as i64, (q as usize / width) as i64);
            let factor = factor(q);
            // A factor of 1 (a texel within its fair share) leaves bound and distance as they
            // are: no division.
            let bound = if factor == 1.0 { bound } else { bound / factor };
            let mut d = metric.cost(own, x, y, bound);
            if let (Some(p), true) = (parent, d < bound) {
                d += p.metric.cost(up, x / 2, y / 2, bound - d);
            }
            d * factor
        };
        let mut best = (f32::INFINITY, current);
        // An extrapolating pass sees only the parent level, on which the four texels of a
        // parent texel tie: it keeps the inherited texel unless another is strictly better.
        if self.mask == Mask::Off {
            best.0 = score((current[1] as usize * width + current[0] as usize) as u32, f32::INFINITY);
        }
        for &q in set {
            let d = score(q, best.0);
            if d < best.0 {
                best = (d, self.texel(q));
            }
        }
        let found = best.0.is_finite();
        Choice {
            texel: found.then_some(best.1),
            figure: if found { best.0 as f64 } else { 0.0 },
            compared: set.len(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::candidates::Search;
    use crate::synth::engine::tests::periodic_sample;
    use crate::synth::engine::{visit_order, PassPlan, Select, VisitOrder};
    use crate::synth::metric::GammaMetric;
    use crate::synth::pass::{masked_shifts, run_pass};
    use crate::synth::target::grid_levels;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

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
            move_cost: None,
        };
        run_pass(
            level,
            &mut state,
            &sample,
            &mut SquareMatch::new(level, &sample, &spy, None, plan.mask),
            &plan,
            &order,
            &mut rng,
        );
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
        let mut state = State::new(labels, uv);
        let before = state.clone();
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let order: Vec<u32> = (0..32 * 32).collect();
        let metric = GammaMetric { sample: &sample, template: 5 };
        let plan = PassPlan {
            search: Search::Full,
            select: Select::Argmin,
            coherence_bias: 0.0,
            mask: Mask::Full,
            move_cost: None,
        };
        let mut matcher = SquareMatch::new(level, &sample, &metric, None, plan.mask);
        run_pass(level, &mut state, &sample, &mut matcher, &plan, &order, &mut rng);
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
