//! The one pass loop of the per-vertex engine (Tong §5, and every preset built on it): each
//! vertex, in the pass's order, gathers its candidates (k-coherence from its neighbours'
//! copies, or every texel), lets its [`VertexMatch`] pick one under the selection rule and
//! the coherence bias, and takes it. What differs between the papers — how a neighbourhood
//! is read and compared (square templates, Chen and Dong's round ones) — is the
//! [`VertexMatch`] part; the loop itself is the same for all.

use super::candidates::{full_candidates, Coherence, Search};
use super::engine::{selection_factor, PassPlan, PassStats, State, Usage};
use super::recipe::Mask;
use super::sample::SampleLevel;
use super::target::{Shift, TargetLevel};
use rand_chacha::ChaCha8Rng;

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
/// candidates under `plan`. With [`Mask::Visited`] and [`Mask::Half`], vertices not visited
/// yet in the pass are neither compared nor sources of candidates.
pub fn run_pass<V: VertexMatch>(
    level: &TargetLevel,
    state: &mut State,
    sample: &SampleLevel,
    matcher: &mut V,
    plan: &PassPlan,
    order: &[u32],
    rng: &mut ChaCha8Rng,
) -> PassStats {
    let reach = matcher.reach();
    let full = matches!(plan.search, Search::Full).then(|| full_candidates(sample, reach));
    let k = if let Search::KCoherence { k } = plan.search { k } else { 1 };
    let mut known = matches!(plan.mask, Mask::Visited | Mask::Half).then(|| vec![false; level.vertices]);
    let mut coherence = Coherence::new(sample);
    let mut usage = Usage::new(sample, state, reach, plan.select);
    let (mut shifts, mut vertex_shifts) = (Vec::new(), Vec::new());
    let (mut figure_sum, mut compared_sum) = (0.0f64, 0usize);
    for &v in order {
        let v = v as usize;
        matcher.prepare(v, state, known.as_deref());
        let shift_list = masked_shifts(level.shifts_of(v, &mut shifts), plan.mask, &mut vertex_shifts);
        // Gathered under a full search too: the forward shifts tell which candidates
        // continue a neighbour's copy, for the coherence bias.
        coherence.gather(shift_list, known.as_deref(), state, sample, (k, reach, matcher.two_level()));
        let candidates: &[u32] = full.as_deref().unwrap_or(coherence.out.as_slice());
        let current = state.uv[v];
        let factor = |q: u32| selection_factor(&usage, &coherence, q, current, plan.coherence_bias);
        let choice =
            matcher.choose(candidates, current, factor, || super::start::random_texel(sample, reach, rng));
        if let Some(texel) = choice.texel {
            usage.moved(current, texel);
            state.uv[v] = texel;
            state.labels[v] = sample.label_at(texel[0] as i64, texel[1] as i64);
        }
        if let Some(k) = known.as_mut() {
            k[v] = true;
        }
        figure_sum += choice.figure;
        compared_sum += choice.compared;
    }
    let n = order.len().max(1) as f64;
    PassStats { mean_best: figure_sum / n, mean_candidates: compared_sum as f64 / n }
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
