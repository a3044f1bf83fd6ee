//! One pass of Chen and Dong's matching (2008 §5–6) over a level: each vertex's round
//! neighbourhood ([`super::round`]) is compared with the sample's by the adaptive metric
//! ([`super::adaptive`]), among k-coherence candidates (on a finer level these surround the
//! inherited texel, the paper's candidates near the 4 linked pixels). Vertices not visited
//! yet in the pass are left out of the neighbourhoods (the paper's non-coloured points).
//! The `chen2008` preset runs it ([`super::Preset::chen2008`]).

use super::adaptive::{choose_weighted, RoundQuery, Scratch};
use super::candidates::Search;
use super::engine::{PassPlan, PassStats, Select, State};
use super::flatten::slot;
use super::metric::known_parts;
use super::neighbourhood::Compared;
use super::pass::{run_scheduled_pass, Choice, Schedule, VertexMatch};
use super::round::{RoundSample, RoundStencil, StartPoint, SurfaceMarching};
use super::sample::{AppearanceMap, SampleLevel};
use super::target::{Slot, TargetLevel, OUTSIDE};
use crate::{Error, Result};
use rand_chacha::ChaCha8Rng;
use std::f32::consts::TAU;

/// Where a level's round neighbourhoods come from.
pub enum RoundTarget<'a> {
    /// A regular `width × height` grid (plane mode) with the texture's x along the grid's:
    /// the points resampled from the grid's cells, each cut into two triangles, on demand.
    /// Points past the edge are not compared unless the grid `wraps`.
    Grid {
        /// Columns of the grid.
        width: usize,
        /// Rows of the grid.
        height: usize,
        /// Whether points past one edge continue from the opposite edge.
        wraps: bool,
    },
    /// A mesh: read from its marching at each vertex's start point.
    Mesh {
        /// The circles of every vertex through its flattened patch.
        marching: &'a SurfaceMarching,
        /// Per vertex, where its circles start (its texture direction).
        starts: &'a [StartPoint],
    },
}

impl RoundTarget<'_> {
    /// The round neighbourhood of vertex `v` under `stencil`, into `out`.
    pub fn slots(&self, v: usize, stencil: RoundStencil, out: &mut Vec<Slot>) {
        match *self {
            RoundTarget::Mesh { marching, starts } => marching.slots(v, starts[v], out),
            RoundTarget::Grid { width, height, wraps } => {
                out.clear();
                let (x, y) = ((v % width) as f32, (v / width) as f32);
                out.extend(stencil.layout().iter().map(|&(c, turn)| {
                    let angle = turn * TAU;
                    // x along the grid, y down its rows, as the square templates.
                    let (px, py) = (x + c as f32 * angle.cos(), y - c as f32 * angle.sin());
                    grid_slot(px, py, width, height, wraps)
                }));
            }
        }
    }
}

impl RoundTarget<'_> {
    /// Vertex `v`'s surface points at `points` (circle, fraction of a turn), for stencils
    /// other than the round one (the isotropic stencil, [`super::isotropic`]), into `out`.
    pub fn slots_at(&self, v: usize, points: &[(usize, f32)], out: &mut Vec<Slot>) {
        match *self {
            RoundTarget::Mesh { marching, starts } => marching.slots_at(v, starts[v], points, out),
            RoundTarget::Grid { width, height, wraps } => {
                out.clear();
                let (x, y) = ((v % width) as f32, (v / width) as f32);
                out.extend(points.iter().map(|&(c, turn)| {
                    let angle = turn * TAU;
                    grid_slot(x + c as f32 * angle.cos(), y - c as f32 * angle.sin(), width, height, wraps)
                }));
            }
        }
    }
}

/// The slot at real grid position (px, py): barycentric in the half of its cell it lies in.
fn grid_slot(px: f32, py: f32, width: usize, height: usize, wraps: bool) -> Slot {
    // Snap rounding noise so that points on grid lines stay on them.
    let (px, py) = (snap(px), snap(py));
    let (x0, y0) = (px.floor() as i64, py.floor() as i64);
    let (u, w) = (px - x0 as f32, py - y0 as f32);
    let vertex = |dx: i64, dy: i64| -> Option<u32> {
        let (mut x, mut y) = (x0 + dx, y0 + dy);
        if wraps {
            (x, y) = (x.rem_euclid(width as i64), y.rem_euclid(height as i64));
        }
        ((0..width as i64).contains(&x) && (0..height as i64).contains(&y))
            .then(|| (y * width as i64 + x) as u32)
    };
    let (corners, weights) = if u >= w {
        ([vertex(0, 0), vertex(1, 0), vertex(1, 1)], [1.0 - u, u - w, w])
    } else {
        ([vertex(0, 0), vertex(0, 1), vertex(1, 1)], [1.0 - w, w - u, u])
    };
    // A corner off the grid with weight on it: nothing to compare there.
    if corners.iter().zip(&weights).any(|(c, &wt)| c.is_none() && wt > 1e-6) {
        return Slot::NONE;
    }
    slot(corners.map(|c| c.unwrap_or(OUTSIDE)), weights)
}

fn snap(p: f32) -> f32 {
    if (p - p.round()).abs() < 1e-4 {
        p.round()
    } else {
        p
    }
}

/// A vertex's round neighbourhood under the adaptive metric, as the [`VertexMatch`] part of
/// the pass loop.
pub struct RoundMatch<'a> {
    round: &'a RoundTarget<'a>,
    sample: &'a SampleLevel,
    map: &'a AppearanceMap,
    round_sample: &'a RoundSample,
    query: RoundQuery,
    slots: Vec<Slot>,
    scratch: Scratch,
}

impl<'a> RoundMatch<'a> {
    /// The round neighbourhoods of `round` against `round_sample`, resampled from `map`,
    /// the appearance vectors of `sample` ([`RoundMatch::appearance`]).
    pub fn new(
        round: &'a RoundTarget<'a>,
        sample: &'a SampleLevel,
        map: &'a AppearanceMap,
        round_sample: &'a RoundSample,
    ) -> Self {
        let (query, slots, scratch) = Default::default();
        RoundMatch { round, sample, map, round_sample, query, slots, scratch }
    }

    /// The appearance vectors of `sample` a pass compares.
    pub fn appearance(sample: &SampleLevel) -> Result<&AppearanceMap> {
        sample
            .appearance
            .as_ref()
            .ok_or_else(|| Error::invalid("the adaptive metric needs appearance vectors"))
    }
}

impl VertexMatch for RoundMatch<'_> {
    fn reach(&self) -> usize {
        // The round neighbourhood reads one texel beyond its outer circle (bilinear).
        self.round_sample.stencil.circles + 1
    }

    fn two_level(&self) -> bool {
        false
    }

    fn prepare(&mut self, v: usize, state: &State, known: Option<&[bool]>) {
        let (query, dims) = (&mut self.query, self.map.dims);
        self.round.slots(v, self.round_sample.stencil, &mut self.slots);
        query.values.clear();
        query.values.resize(self.slots.len() * dims, 0.0);
        query.known.clear();
        query.known.resize(self.slots.len(), false);
        for (p, parts, count) in known_parts(&self.slots, known) {
            query.known[p] = true;
            for &(u, weight) in &parts[..count] {
                if u == OUTSIDE {
                    continue;
                }
                let [x, y] = state.uv[u as usize];
                let values = &mut query.values[p * dims..(p + 1) * dims];
                values.iter_mut().zip(self.map.at(x as i64, y as i64)).for_each(|(q, &a)| *q += weight * a);
            }
        }
    }

    fn choose(
        &mut self,
        candidates: &[u32],
        _current: [i32; 2],
        factor: impl Fn(u32) -> f32,
        draw: impl FnOnce() -> [i32; 2],
    ) -> Choice {
        // Nothing known around the vertex: every candidate ties at zero, and a full search
        // would give every such vertex the same first texel (streaks); start it at random.
        let candidates = if self.query.known.contains(&true) { candidates } else { &[] };
        let width = self.sample.width;
        match choose_weighted(&self.query, self.round_sample, candidates, factor, &mut self.scratch) {
            // The top size stands where the square passes report their best distance.
            Some(choice) => Choice {
                texel: Some([(choice.texel as usize % width) as i32, (choice.texel as usize / width) as i32]),
                figure: choice.top_size as f64,
                compared: candidates.len(),
            },
            None => Choice { texel: Some(draw()), figure: 0.0, compared: candidates.len() },
        }
    }
}

/// One adaptive pass over `level` under `schedule`, from k-coherence candidates (lists of
/// `k`) or, with [`Search::Full`], every candidate texel, picked as `select` says with
/// `bias` on candidates that start a new copy (as the square passes weigh them): the pass
/// loop with a [`RoundMatch`].
#[allow(clippy::too_many_arguments)]
pub fn adaptive_pass(
    level: &TargetLevel,
    round: &RoundTarget,
    state: &mut State,
    sample: &SampleLevel,
    round_sample: &RoundSample,
    (search, compared, select, coherence_bias): (Search, Compared, Select, f32),
    schedule: &Schedule,
    rng: &mut ChaCha8Rng,
) -> Result<PassStats> {
    let map = RoundMatch::appearance(sample)?;
    let make = || RoundMatch::new(round, sample, map, round_sample);
    let plan = PassPlan { search, select, coherence_bias, mask: compared.mask(), move_cost: None };
    Ok(run_scheduled_pass(level, state, sample, make, &plan, schedule, rng))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::engine::tests::periodic_sample;
    use crate::synth::sample::AppearanceMap;
    use crate::synth::surface::tests::flat_grid;
    use crate::synth::target::grid_levels;
    use glam::Vec3;
    use rand::SeedableRng;

    const STENCIL: RoundStencil = RoundStencil { circles: 3 };

    /// On a grid, the round neighbourhood of the grid itself equals the one marched on the
    /// same grid as a mesh, direction along x: the same surface points.
    #[test]
    fn grid_round_neighbourhoods_match_the_marching_of_a_flat_mesh() {
        let (w, h) = (11usize, 10usize);
        let (mesh, frames) = flat_grid(w as u32, h as u32, 0.5);
        let marching = SurfaceMarching::new(&mesh, &frames.n, 0.5, STENCIL).unwrap();
        let starts = marching.start_points(&frames);
        let on_mesh = RoundTarget::Mesh { marching: &marching, starts: &starts };
        let on_grid = RoundTarget::Grid { width: w, height: h, wraps: false };
        let p = mesh.positions();
        let at = |s: &Slot| -> Vec3 { (0..3).map(|k| p[s.vertices[k] as usize] * s.weights[k]).sum() };
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for v in [4 * w + 5, 5 * w + 4, 6 * w + 6] {
            on_mesh.slots(v, STENCIL, &mut a);
            on_grid.slots(v, STENCIL, &mut b);
            for (i, (sa, sb)) in a.iter().zip(&b).enumerate() {
                assert!(at(sa).distance(at(sb)) < 1e-4, "vertex {v}, point {i}: {sa:?} vs {sb:?}");
            }
        }
        // Near the edge, points off the grid are not compared; wrapped, they are.
        on_grid.slots(0, STENCIL, &mut b);
        assert!(b.contains(&Slot::NONE));
        RoundTarget::Grid { width: w, height: h, wraps: true }.slots(0, STENCIL, &mut b);
        assert!(!b.contains(&Slot::NONE));
    }

    fn with_appearance(mut sample: SampleLevel) -> SampleLevel {
        let onehot: Vec<f32> = sample
            .labels
            .iter()
            .flat_map(|&l| (0..4).map(move |d| f32::from(u8::from(l as usize == d))))
            .collect();
        sample.appearance = Some(AppearanceMap::new(sample.width, sample.height, 4, &onehot, true));
        sample
    }

    /// An exact copy of a tileable sample stays one: every vertex's own texel matches
    /// exactly and survives every cut of the adaptive metric.
    #[test]
    fn an_exact_copy_is_a_fixed_point_of_an_adaptive_pass() {
        let sample = with_appearance(periodic_sample(4));
        let round_sample = RoundSample::new(sample.appearance.as_ref().unwrap(), 16, 16, STENCIL).unwrap();
        let level = &grid_levels(32, 32, 1, 7, 3)[0];
        let uv: Vec<[i32; 2]> = (0..32 * 32).map(|v| [v % 32 % 16, v / 32 % 16]).collect();
        let labels = uv.iter().map(|&[x, y]| sample.label_at(x as i64, y as i64)).collect();
        let mut state = State::new(labels, uv);
        let before = state.clone();
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let order = crate::synth::constrained::most_constrained_order(level, &mut rng);
        let round = RoundTarget::Grid { width: 32, height: 32, wraps: true };
        let full = (Search::KCoherence { k: 4 }, Compared::Full, Select::Argmin, 0.0);
        adaptive_pass(
            level,
            &round,
            &mut state,
            &sample,
            &round_sample,
            full,
            &Schedule::Order(order.clone()),
            &mut rng,
        )
        .unwrap();
        assert_eq!(state.labels, before.labels);
        // A random start is pulled towards the sample: most vertices then continue a
        // neighbour's copy (their texel is a neighbour's shifted by one step).
        let mut state = crate::synth::start::random_state(level, &sample, 4, &mut rng);
        for compared in [Compared::Visited, Compared::Full] {
            let order = crate::synth::constrained::most_constrained_order(level, &mut rng);
            let how = (Search::KCoherence { k: 4 }, compared, Select::Argmin, 0.0);
            adaptive_pass(
                level,
                &round,
                &mut state,
                &sample,
                &round_sample,
                how,
                &Schedule::Order(order),
                &mut rng,
            )
            .unwrap();
        }
        let coherent = (0..32 * 32)
            .filter(|&v| {
                let right = (v / 32) * 32 + (v % 32 + 1) % 32;
                let (a, b) = (state.uv[v], state.uv[right]);
                (b[0] - a[0]).rem_euclid(16) == 1 && b[1] == a[1]
            })
            .count();
        assert!(coherent > 32 * 32 / 2, "{coherent} of 1024 continue to the right");
    }
}
