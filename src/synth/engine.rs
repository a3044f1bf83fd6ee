//! The per-vertex synthesis engine (Tong §5): distances through Γ, candidate sets, passes.

use super::sample::SampleLevel;
use super::target::{Slot, TargetLevel, OUTSIDE};
use rand::seq::SliceRandom;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// The surface texton map of one level: per vertex a texton label and a sample coordinate.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    pub labels: Vec<u16>,
    pub uv: Vec<[i32; 2]>,
}

/// How candidates are formed (Tong §5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Search {
    /// The union of the kNN lists (first `k` entries) at the forward-shifted coordinates of
    /// the patch's vertices.
    KCoherence { k: usize },
    /// Every pixel of the sample whose neighbourhood lies inside it (Table 2's full search).
    Full,
}

/// Order in which a pass visits the vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VisitOrder {
    /// A fresh seeded permutation every pass.
    Random,
    /// Vertex index order.
    Sequential,
    /// Breadth-first growth from a random vertex through the patch adjacency.
    Grow,
}

/// What one pass found.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassStats {
    /// Mean over vertices of the best candidate's neighbourhood distance.
    pub mean_best: f64,
    /// Mean candidate-set size.
    pub mean_candidates: f64,
}

/// A template pixel ready for matching: s = Σ wₐ t(textonsₐ) and s·s, computed once per
/// vertex so each candidate pixel costs `count` Γ lookups and one diagonal term.
#[derive(Clone, Copy)]
pub(crate) struct Term {
    textons: [u16; 3],
    weights: [f32; 3],
    count: usize,
    ss: f32,
}

/// The terms of `slots` under `labels`. With `known`, vertices not yet synthesized are left
/// out (their weight goes to the others); a pixel with none known is skipped (count 0).
pub(crate) fn terms(
    slots: &[Slot],
    labels: &[u16],
    sample: &SampleLevel,
    known: Option<&[bool]>,
) -> Vec<Term> {
    slots
        .iter()
        .map(|slot| {
            let mut term =
                Term { textons: [sample.default_texton(); 3], weights: [0.0; 3], count: 0, ss: 0.0 };
            let mut total = 0.0;
            for a in 0..3 {
                let (vertex, weight) = (slot.vertices[a], slot.weights[a]);
                if weight == 0.0 || (vertex != OUTSIDE && known.is_some_and(|k| !k[vertex as usize])) {
                    continue;
                }
                term.textons[term.count] =
                    if vertex == OUTSIDE { sample.default_texton() } else { labels[vertex as usize] };
                term.weights[term.count] = weight;
                term.count += 1;
                total += weight;
            }
            for a in 0..term.count {
                term.weights[a] /= total;
            }
            for a in 0..term.count {
                for b in 0..term.count {
                    term.ss +=
                        term.weights[a] * term.weights[b] * sample.dot(term.textons[a], term.textons[b]);
                }
            }
            term
        })
        .collect()
}

/// Σ over template pixels of ‖s − t‖² against the sample neighbourhood centred at (px, py);
/// stops early once it exceeds `bound`.
pub(crate) fn distance(
    terms: &[Term],
    sample: &SampleLevel,
    template: usize,
    (px, py): (i64, i64),
    bound: f32,
) -> f32 {
    let r = (template / 2) as i64;
    let mut d = 0.0;
    for (i, term) in terms.iter().enumerate().filter(|(_, t)| t.count > 0) {
        let t = sample.label_at(px + (i % template) as i64 - r, py + (i / template) as i64 - r);
        let mut st = 0.0;
        for a in 0..term.count {
            st += term.weights[a] * sample.dot(term.textons[a], t);
        }
        d += term.ss - 2.0 * st + sample.dot(t, t);
        if d > bound {
            break;
        }
    }
    d.max(0.0)
}

/// The coarser level while refining: its state and sample, for two-level neighbourhoods.
pub struct Parent<'a> {
    pub state: &'a State,
    pub sample: &'a SampleLevel,
}

/// What a pass may look at besides the current level.
pub struct PassContext<'a> {
    /// The coarser level, for two-level neighbourhoods (second pass of a finer level).
    pub parent: Option<&'a Parent<'a>>,
    pub search: Search,
    /// Causal pass: only vertices already synthesized in this pass count, in distances and
    /// as sources of candidates; the first vertex of a region starts from a random pixel.
    pub causal: bool,
}

/// One pass over `level`: every vertex takes the candidate pixel whose neighbourhood best
/// matches its own (plus the parent neighbourhood's when the context has a parent).
pub fn pass(
    level: &TargetLevel,
    state: &mut State,
    sample: &SampleLevel,
    context: &PassContext,
    order: &[u32],
    rng: &mut ChaCha8Rng,
) -> PassStats {
    let r = level.template / 2;
    let full: Vec<u32> = match context.search {
        Search::Full => full_candidates(sample, r),
        Search::KCoherence { .. } => Vec::new(),
    };
    let mut known = context.causal.then(|| vec![false; level.vertices]);
    let mut stamp = vec![u32::MAX; sample.width * sample.height];
    let mut candidates = Vec::new();
    let (mut best_sum, mut candidate_sum) = (0.0f64, 0usize);
    for (visit, &v) in order.iter().enumerate() {
        let v = v as usize;
        let own = terms(level.slots_of(v), &state.labels, sample, known.as_deref());
        let parent_terms = context
            .parent
            .map(|p| (terms(level.parent_slots_of(v), &p.state.labels, p.sample, None), p.sample));
        let set: &[u32] = match context.search {
            Search::Full => &full,
            Search::KCoherence { k } => {
                let sources = Sources { shifts: level.shifts_of(v), known: known.as_deref() };
                coherence_candidates(
                    &sources,
                    state,
                    sample,
                    (k, r),
                    context.parent.is_some(),
                    visit as u32,
                    &mut stamp,
                    &mut candidates,
                );
                if candidates.is_empty() {
                    let seed = random_pixel(sample, r, rng);
                    candidates.push(seed);
                }
                &candidates
            }
        };
        let mut best = (f32::INFINITY, state.uv[v]);
        for &q in set {
            let (qx, qy) = ((q as usize % sample.width) as i64, (q as usize / sample.width) as i64);
            let mut d = distance(&own, sample, level.template, (qx, qy), best.0);
            if let Some((pt, ps)) = &parent_terms {
                if d < best.0 {
                    d += distance(pt, ps, level.parent_template, (qx / 2, qy / 2), best.0 - d);
                }
            }
            if d < best.0 {
                best = (d, [qx as i32, qy as i32]);
            }
        }
        if best.0.is_finite() {
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

/// Pixels whose `r` neighbourhood lies inside the sample (all of them when it tiles).
fn full_candidates(sample: &SampleLevel, r: usize) -> Vec<u32> {
    let mut all: Vec<u32> = (0..sample.height as i64)
        .flat_map(|y| (0..sample.width as i64).map(move |x| (x, y)))
        .map(|(x, y)| sample.candidate_pixel(x, y, r) as u32)
        .collect();
    all.sort_unstable();
    all.dedup();
    all
}

/// The patch vertices a vertex's candidates come from; with `known`, only those already
/// synthesized in this pass.
struct Sources<'a> {
    shifts: &'a [(u32, [f32; 2])],
    known: Option<&'a [bool]>,
}

/// k-coherence (Tong §5.2): forward-shift every source vertex's coordinate by its offset and
/// take that pixel's kNN list (first `k` entries); deduplicated with a per-visit stamp.
#[allow(clippy::too_many_arguments)]
fn coherence_candidates(
    sources: &Sources,
    state: &State,
    sample: &SampleLevel,
    (k, r): (usize, usize),
    two_level: bool,
    visit: u32,
    stamp: &mut [u32],
    out: &mut Vec<u32>,
) {
    out.clear();
    for &(u, offset) in sources.shifts {
        if sources.known.is_some_and(|known| !known[u as usize]) {
            continue;
        }
        let [su, sv] = state.uv[u as usize];
        let x = (su as f32 - offset[0]).round() as i64;
        let y = (sv as f32 - offset[1]).round() as i64;
        let pixel = sample.candidate_pixel(x, y, r);
        for &q in sample.list(pixel, k, two_level) {
            if stamp[q as usize] != visit {
                stamp[q as usize] = visit;
                out.push(q);
            }
        }
    }
}

/// A uniformly random pixel whose `radius` neighbourhood lies inside the sample.
fn random_pixel(sample: &SampleLevel, radius: usize, rng: &mut ChaCha8Rng) -> u32 {
    sample.candidate_pixel(
        rng.random_range(0..sample.width as i64),
        rng.random_range(0..sample.height as i64),
        radius,
    ) as u32
}

/// Random sample coordinates for every vertex (the coarsest level's start).
pub fn random_state(vertices: usize, sample: &SampleLevel, radius: usize, rng: &mut ChaCha8Rng) -> State {
    let uv: Vec<[i32; 2]> = (0..vertices)
        .map(|_| {
            let p = random_pixel(sample, radius, rng) as usize;
            [(p % sample.width) as i32, (p / sample.width) as i32]
        })
        .collect();
    let labels = uv.iter().map(|&[x, y]| sample.label_at(x as i64, y as i64)).collect();
    State { labels, uv }
}

/// First pass of a finer level (Tong §5.1): coordinates derived from the coarser level,
/// labels fetched from this level's texton map.
pub fn inherit(level: &TargetLevel, coarse: &State, sample: &SampleLevel) -> State {
    let uv: Vec<[i32; 2]> = level
        .parents
        .iter()
        .map(|link| {
            let [cx, cy] = coarse.uv[link.vertex as usize];
            let (x, y) = sample.bring_inside(
                (2 * cx) as i64 + link.offset[0].round() as i64,
                (2 * cy) as i64 + link.offset[1].round() as i64,
            );
            [x as i32, y as i32]
        })
        .collect();
    let labels = uv.iter().map(|&[x, y]| sample.label_at(x as i64, y as i64)).collect();
    State { labels, uv }
}

/// The visiting order of one pass over `level`.
pub fn visit_order(level: &TargetLevel, order: VisitOrder, rng: &mut ChaCha8Rng) -> Vec<u32> {
    let mut ids: Vec<u32> = (0..level.vertices as u32).collect();
    match order {
        VisitOrder::Random => ids.shuffle(rng),
        VisitOrder::Sequential => {}
        VisitOrder::Grow => ids = grow_order(level, rng),
    }
    ids
}

/// Breadth-first over the patch adjacency from a random vertex (a new random start for each
/// disconnected part), so a causal pass extends one coherent region instead of many seeds.
fn grow_order(level: &TargetLevel, rng: &mut ChaCha8Rng) -> Vec<u32> {
    let mut starts: Vec<u32> = (0..level.vertices as u32).collect();
    starts.shuffle(rng);
    let mut seen = vec![false; level.vertices];
    let mut order = Vec::with_capacity(level.vertices);
    let mut queue = std::collections::VecDeque::new();
    for start in starts {
        if seen[start as usize] {
            continue;
        }
        seen[start as usize] = true;
        queue.push_back(start);
        while let Some(v) = queue.pop_front() {
            order.push(v);
            for &(u, _) in level.shifts_of(v as usize) {
                if !seen[u as usize] {
                    seen[u as usize] = true;
                    queue.push_back(u);
                }
            }
        }
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;
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
        }
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
        let context = PassContext { parent: None, search: Search::Full, causal: false };
        pass(level, &mut state, &sample, &context, &order, &mut rng);
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
