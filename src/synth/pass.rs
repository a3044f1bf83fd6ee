//! The one pass loop of the per-vertex engine (Tong §5, and every preset built on it): each
//! vertex, in the pass's order, gathers its candidates (k-coherence from its neighbours'
//! copies, or every texel), lets its [`VertexMatch`] pick one under the selection rule and
//! the coherence bias, and takes it. What differs between the papers — how a neighbourhood
//! is read and compared (square templates, Chen and Dong's round ones) — is the
//! [`VertexMatch`] part; the loop itself is the same for all.
//!
//! Every part is public, so a pass can be run by hand (what [`super::synthesize`] does per
//! level and pass of a recipe), or with a [`VertexMatch`] of one's own:
//!
//! ```
//! use btfsynth::analysis::pipeline::{analyze, AnalysisParams};
//! use btfsynth::btf::{self, gen::{GenParams, MaterialKind}, DirectionSet};
//! use btfsynth::progress::Silent;
//! use btfsynth::synth::engine::{visit_order, PassPlan, Select, VisitOrder};
//! use btfsynth::synth::metric::AppearanceMetric;
//! use btfsynth::synth::neighbourhood::Mask;
//! use btfsynth::synth::pass::run_pass;
//! use btfsynth::synth::square_pass::SquareMatch;
//! use btfsynth::synth::{start::random_state, target::grid_levels, Sample, Search};
//! use rand::SeedableRng;
//!
//! let params = GenParams { size: 32, samples_per_pixel: 1, directions: DirectionSet::Grid(2), ..GenParams::default() };
//! let stack = btf::gen::generate(MaterialKind::Pebbles, &params, &Silent)?;
//! let analysis = analyze(&stack, &AnalysisParams { textons: 32, levels: 1, ..AnalysisParams::default() }, &Silent)?;
//! let sample = Sample::from_analysis(&analysis, &stack, 1)?;
//! let level = &sample.levels[0];
//!
//! // A 48² plane, a 7×7 template compared on appearance vectors, k-coherence candidates.
//! let target = &grid_levels(48, 48, 1, 7, 3)[0];
//! let metric = AppearanceMetric { map: level.appearance.as_ref().expect("analysed"), template: 7 };
//! let mut matcher = SquareMatch::new(target, level, &metric, None, Mask::Full);
//! let plan = PassPlan { search: Search::KCoherence { k: 4 }, select: Select::Argmin, coherence_bias: 0.5, mask: Mask::Full, move_cost: None };
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
//! let mut state = random_state(target, level, 3, &mut rng);
//! let first = visit_order(target, VisitOrder::Random, None, &mut rng);
//! let before = run_pass(target, &mut state, level, &mut matcher, &plan, &first, &mut rng);
//! let again = visit_order(target, VisitOrder::Random, None, &mut rng);
//! let after = run_pass(target, &mut state, level, &mut matcher, &plan, &again, &mut rng);
//! assert!(after.mean_best < before.mean_best, "a second pass matches better");
//! # Ok::<(), btfsynth::Error>(())
//! ```

use super::candidates::{full_candidates, Coherence, Search};
use super::engine::{selection_factor, PassPlan, PassStats, State, Usage};
use super::neighbourhood::Mask;
use super::sample::SampleLevel;
use super::target::{Neighbourhoods, Shift, TargetLevel, OUTSIDE};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// How one vertex is compared with the sample: a neighbourhood part plus a distance part.
///
/// [`run_pass`] calls [`prepare`](VertexMatch::prepare) once per vertex, then
/// [`choose`](VertexMatch::choose) once with that vertex's candidates.
pub trait VertexMatch {
    /// Texels a candidate's neighbourhood reaches around it: candidates of a sample that
    /// does not wrap stay this far inside it.
    fn reach(&self) -> usize;

    /// Whether candidates are gathered for two-level neighbourhoods (the sample's lists by
    /// this level and its parent).
    fn two_level(&self) -> bool;

    /// Reads vertex `v`'s neighbourhood from `state`; with `known`, only the vertices
    /// visited so far in the pass.
    fn prepare(&mut self, v: usize, state: &State, known: Option<&[bool]>);

    /// The forward shifts candidates are gathered from, given the level's (after
    /// [`prepare`](VertexMatch::prepare), with the same `state`): a part whose copies may
    /// be turned against the sample ([`super::isotropic`]) turns each offset the way its
    /// vertex's copy runs. The others use the level's as they are.
    #[inline]
    fn follow<'s>(
        &mut self,
        shifts: &'s [Shift],
        _state: &State,
        _scratch: &'s mut Vec<Shift>,
    ) -> &'s [Shift] {
        shifts
    }

    /// Picks among `candidates` (texel indices y·w + x) for the vertex now at `current`,
    /// each distance scaled by `factor` (selection and coherence). `draw` gives a random
    /// texel where nothing can be judged.
    fn choose(
        &mut self,
        candidates: &[u32],
        current: [i32; 2],
        factor: impl Fn(u32) -> f32,
        draw: impl FnOnce() -> [i32; 2],
    ) -> Choice;
}

/// What a [`VertexMatch`] chose for one vertex.
#[derive(Clone, Copy, Debug)]
pub struct Choice {
    /// The texel the vertex takes; `None` keeps the one it has.
    pub texel: Option<[i32; 2]>,
    /// The figure the pass reports the mean of (the best distance, or the adaptive metric's
    /// top size).
    pub figure: f64,
    /// Candidates it compared.
    pub compared: usize,
}

/// One pass over `level` in `order`: every vertex takes what `matcher` chooses among its
/// candidates under `plan`, seeing every choice made before it (Gauss–Seidel). With
/// [`Mask::Visited`] and [`Mask::Half`], vertices not visited yet in the pass are neither
/// compared nor sources of candidates.
pub fn run_pass<V: VertexMatch>(
    level: &TargetLevel,
    state: &mut State,
    sample: &SampleLevel,
    matcher: &mut V,
    plan: &PassPlan,
    order: &[u32],
    rng: &mut ChaCha8Rng,
) -> PassStats {
    let pass = PassInputs::new(level, sample, plan, matcher.reach());
    let mut usage =
        Usage::new(sample, state, pass.margin, plan.select).over_level(plan.search, sample, pass.margin);
    let mut scratch = VisitScratch::new(sample);
    let mut known = pass.known_mask();
    let mut sums = Sums::default();
    for &v in order {
        let v = v as usize;
        let draw = || super::start::random_texel(sample, pass.margin, rng);
        let choice = pass.visit(v, matcher, &mut scratch, state, known.as_deref(), &usage, draw);
        apply(v, choice, state, sample, &mut usage, known.as_deref_mut(), &mut sums);
    }
    sums.stats(order.len())
}

/// One pass over `level` as sub-passes, one per colour of `colouring` (Lefebvre and Hoppe
/// 2005): within a sub-pass no vertex reads another, so its vertices are matched in
/// parallel against the state the earlier sub-passes left, and their choices applied
/// together. `make` builds one matcher per worker. The result depends on `seed` only,
/// never on the thread count: each vertex's random draw is seeded by `seed` and the vertex.
pub fn run_interleaved_pass<V: VertexMatch>(
    level: &TargetLevel,
    state: &mut State,
    sample: &SampleLevel,
    make: impl Fn() -> V + Sync,
    plan: &PassPlan,
    colouring: &Colouring,
    seed: u64,
) -> PassStats {
    let pass = PassInputs::new(level, sample, plan, make().reach());
    let mut usage = Usage::new(sample, state, pass.margin, plan.select);
    let mut known = pass.known_mask();
    let mut sums = Sums::default();
    for class in &colouring.classes {
        let (frozen, seen) = (&*state, known.as_deref());
        let choices: Vec<Choice> = class
            .par_iter()
            .map_init(
                || (make(), VisitScratch::new(sample)),
                |(matcher, scratch), &v| {
                    let draw = || {
                        let mut rng =
                            ChaCha8Rng::seed_from_u64(seed ^ u64::from(v).wrapping_mul(VERTEX_SEED));
                        super::start::random_texel(sample, pass.margin, &mut rng)
                    };
                    pass.visit(v as usize, matcher, scratch, frozen, seen, &usage, draw)
                },
            )
            .collect();
        for (&v, choice) in class.iter().zip(choices) {
            apply(v as usize, choice, state, sample, &mut usage, known.as_deref_mut(), &mut sums);
        }
    }
    sums.stats(state.uv.len())
}

/// How a pass visits its level's vertices.
pub enum Schedule<'a> {
    /// One after the other in this order, each seeing the choices made before it.
    Order(Vec<u32>),
    /// In sub-passes by colour, each in parallel ([`run_interleaved_pass`]).
    Interleaved {
        /// The sub-passes: one per colour.
        colouring: &'a Colouring,
        /// Seeds each vertex's random draw together with the vertex index.
        seed: u64,
    },
}

/// One pass under `schedule`, with matchers from `make`.
pub fn run_scheduled_pass<V: VertexMatch>(
    level: &TargetLevel,
    state: &mut State,
    sample: &SampleLevel,
    make: impl Fn() -> V + Sync,
    plan: &PassPlan,
    schedule: &Schedule,
    rng: &mut ChaCha8Rng,
) -> PassStats {
    match schedule {
        Schedule::Order(order) => run_pass(level, state, sample, &mut make(), plan, order, rng),
        &Schedule::Interleaved { colouring, seed } => {
            run_interleaved_pass(level, state, sample, make, plan, colouring, seed)
        }
    }
}

/// Spreads vertex indices over the seed space (the 64-bit golden ratio).
pub(crate) const VERTEX_SEED: u64 = 0x9E37_79B9_7F4A_7C15;

/// What every vertex of one pass shares.
struct PassInputs<'a> {
    level: &'a TargetLevel,
    sample: &'a SampleLevel,
    plan: &'a PassPlan<'a>,
    /// How far inside the sample's edges candidates stay ([`TargetLevel::candidate_margin`]).
    margin: usize,
    full: Option<Vec<u32>>,
    k: usize,
}

/// A vertex visit's reusable buffers.
struct VisitScratch {
    coherence: Coherence,
    shifts: Vec<Shift>,
    masked: Vec<Shift>,
    followed: Vec<Shift>,
}

impl VisitScratch {
    fn new(sample: &SampleLevel) -> Self {
        let (shifts, masked, followed) = Default::default();
        VisitScratch { coherence: Coherence::new(sample), shifts, masked, followed }
    }
}

impl<'a> PassInputs<'a> {
    fn new(level: &'a TargetLevel, sample: &'a SampleLevel, plan: &'a PassPlan<'a>, reach: usize) -> Self {
        let margin = level.candidate_margin(reach);
        let full = matches!(plan.search, Search::Full).then(|| full_candidates(sample, margin));
        let k = if let Search::KCoherence { k } = plan.search { k } else { 1 };
        PassInputs { level, sample, plan, margin, full, k }
    }

    fn known_mask(&self) -> Option<Vec<bool>> {
        matches!(self.plan.mask, Mask::Visited | Mask::Half).then(|| vec![false; self.level.vertices])
    }

    /// Vertex `v`'s choice: its neighbourhood read from `state` (only `known` vertices, if
    /// given), its candidates gathered, and `matcher`'s pick among them.
    #[allow(clippy::too_many_arguments)]
    fn visit<V: VertexMatch>(
        &self,
        v: usize,
        matcher: &mut V,
        scratch: &mut VisitScratch,
        state: &State,
        known: Option<&[bool]>,
        usage: &Usage,
        draw: impl FnOnce() -> [i32; 2],
    ) -> Choice {
        matcher.prepare(v, state, known);
        let VisitScratch { coherence, shifts, masked, followed } = scratch;
        let shift_list = masked_shifts(self.level.shifts_of(v, shifts), self.plan.mask, masked);
        let shift_list = matcher.follow(shift_list, state, followed);
        // Gathered under a full search too: the forward shifts tell which candidates
        // continue a neighbour's copy, for the coherence bias.
        coherence.gather(shift_list, known, state, self.sample, (self.k, self.margin, matcher.two_level()));
        let coherence = &*coherence;
        let candidates: &[u32] = self.full.as_deref().unwrap_or(coherence.out.as_slice());
        let current = state.uv[v];
        let bias = self.plan.coherence_bias;
        let at = (current, usage.floor(candidates));
        let here = current[1] as u32 * self.sample.width as u32 + current[0] as u32;
        let move_cost = self.plan.move_cost.map_or(1.0, |costs| costs[v]);
        let factor = |q| {
            let moved = if q == here { 1.0 } else { move_cost };
            selection_factor(usage, coherence, q, at, bias) * moved
        };
        matcher.choose(candidates, current, factor, draw)
    }
}

/// Running sums of what a pass reports.
#[derive(Default)]
struct Sums {
    figure: f64,
    compared: usize,
}

impl Sums {
    fn stats(&self, visits: usize) -> PassStats {
        let n = visits.max(1) as f64;
        PassStats { mean_best: self.figure / n, mean_candidates: self.compared as f64 / n }
    }
}

/// Vertex `v` takes `choice`.
fn apply(
    v: usize,
    choice: Choice,
    state: &mut State,
    sample: &SampleLevel,
    usage: &mut Usage,
    known: Option<&mut [bool]>,
    sums: &mut Sums,
) {
    if let Some(texel) = choice.texel {
        usage.moved(state.uv[v], texel);
        state.uv[v] = texel;
        state.labels[v] = sample.label_at(texel[0] as i64, texel[1] as i64);
    }
    if let Some(k) = known {
        k[v] = true;
    }
    sums.figure += choice.figure;
    sums.compared += choice.compared;
}

/// A colouring of a level's vertices in which no vertex reads another of its colour (its
/// template's vertices and its patch vertices), so each colour is a sub-pass whose vertices
/// can be matched at once. Greedy, in vertex order: deterministic.
#[derive(Clone, Debug)]
pub struct Colouring {
    /// The vertices of each colour, increasing.
    pub classes: Vec<Vec<u32>>,
}

/// Colours a greedy colouring may use; a level that needs more (a template covering far more
/// vertices than texels) is matched sequentially instead.
pub const MAX_COLOURS: usize = 128;

impl Colouring {
    /// The colouring of `level`, or `None` if it needs more than [`MAX_COLOURS`] colours.
    pub fn of(level: &TargetLevel) -> Option<Colouring> {
        // forbidden[w]: the colours of already coloured vertices that read w.
        let mut forbidden = vec![0u128; level.vertices];
        let mut colour = vec![0u8; level.vertices];
        let (mut slots, mut shifts, mut reads) = (Vec::new(), Vec::new(), Vec::new());
        // A grid's patch vertices are its template's pixels: reading them twice changes no
        // colour, and on a 2048² level this loop runs alone on one core.
        let grid = matches!(level.neighbourhoods, Neighbourhoods::Grid { .. });
        for v in 0..level.vertices {
            reads.clear();
            let slot_vertices = level.slots_of(v, &mut slots).iter().flat_map(|s| s.vertices);
            reads.extend(slot_vertices.filter(|&u| u != OUTSIDE && u as usize != v));
            if !grid {
                reads
                    .extend(level.shifts_of(v, &mut shifts).iter().map(|s| s.0).filter(|&u| u as usize != v));
            }
            let taken = reads
                .iter()
                .filter(|&&u| (u as usize) < v)
                .fold(forbidden[v], |m, &u| m | 1 << colour[u as usize]);
            let c = (!taken).trailing_zeros() as usize;
            if c >= MAX_COLOURS {
                return None;
            }
            colour[v] = c as u8;
            reads.iter().for_each(|&u| forbidden[u as usize] |= 1 << c);
        }
        let count = colour.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
        let mut classes = vec![Vec::new(); count];
        colour.iter().enumerate().for_each(|(v, &c)| classes[c as usize].push(v as u32));
        Some(Colouring { classes })
    }
}

/// The forward shifts under `mask`: with [`Mask::Half`], only those upstream or level
/// (x ≤ 0; the pass's visited mask then drops those not visited yet).
pub(crate) fn masked_shifts<'a>(shifts: &'a [Shift], mask: Mask, scratch: &'a mut Vec<Shift>) -> &'a [Shift] {
    if mask != Mask::Half {
        return shifts;
    }
    scratch.clear();
    scratch.extend(shifts.iter().filter(|s| s.1[0] < 0.5));
    scratch
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::target::grid_levels;

    /// No vertex reads another of its colour, and every vertex has one colour.
    fn check(level: &TargetLevel, colouring: &Colouring) {
        let mut colour = vec![usize::MAX; level.vertices];
        for (c, class) in colouring.classes.iter().enumerate() {
            class.iter().for_each(|&v| colour[v as usize] = c);
        }
        assert!(colour.iter().all(|&c| c != usize::MAX), "a vertex has no colour");
        let (mut slots, mut shifts) = (Vec::new(), Vec::new());
        for v in 0..level.vertices {
            let slot_reads =
                level.slots_of(v, &mut slots).iter().flat_map(|s| s.vertices).collect::<Vec<_>>();
            let shift_reads = level.shifts_of(v, &mut shifts).iter().map(|s| s.0).collect::<Vec<_>>();
            for u in slot_reads.into_iter().chain(shift_reads).filter(|&u| u != OUTSIDE && u as usize != v) {
                assert_ne!(colour[u as usize], colour[v], "vertex {v} reads vertex {u} of its colour");
            }
        }
    }

    /// On a grid a 7×7 template reads 3 texels each way: the greedy colouring finds the
    /// 4×4 interleave, also where the grid wraps.
    #[test]
    fn a_grid_colours_as_a_4_by_4_interleave() {
        for wraps in [false, true] {
            let level = &crate::synth::target::wrapping_grid_levels(40, 24, 1, 7, 3, wraps)[0];
            let colouring = Colouring::of(level).expect("a grid needs few colours");
            check(level, &colouring);
            assert_eq!(colouring.classes.len(), 16, "wraps {wraps}");
        }
        let level = &grid_levels(13, 9, 1, 5, 3)[0];
        check(level, &Colouring::of(level).unwrap());
    }

    /// A mesh level's resampled templates read the nearest vertex of each pixel: at texel
    /// 0.4 on a 0.5 grid a 7×7 template reaches 1.2 each way, whose nearest vertices are
    /// 2 grid steps away, so no vertex reads one of its colour with a 3×3 interleave.
    #[test]
    fn a_mesh_level_is_coloured_so_no_sub_pass_reads_itself() {
        let (mesh, frames) = crate::synth::surface::tests::flat_grid(24, 20, 0.5);
        let level = crate::synth::surface::surface_level(&mesh, &frames, 0.4, 7).unwrap();
        let colouring = Colouring::of(&level).expect("fits in MAX_COLOURS");
        check(&level, &colouring);
        assert_eq!(colouring.classes.len(), 9);
    }
}
