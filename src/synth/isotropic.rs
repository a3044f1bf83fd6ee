//! Castellanos and Williams' isotropic neighbourhood (§3.12) as the [`VertexMatch`] part of
//! the pass loop.
//!
//! The paper's 2-distant face neighbourhood holds 12 one-distant and 24 two-distant faces
//! around the face, centre excluded. The engine's state is a texel per vertex, not a colour
//! per face, so the stencil here is its point form: 12 points on a circle of radius one
//! texel and 24 on one of two texels, the rings' mean radii (1.62 and 3.18 adjacent-face
//! spacings, a ratio of 1.97). On a plane the points are resampled from the grid, on a mesh
//! from the round neighbourhoods' surface marching ([`super::round::SurfaceMarching`]).
//!
//! Proximity weights (Eq. 7): β = exp(−½ (d / 1.3 σ_k)²), σ_k the adjacent-face spacing.
//! Each ring takes the mean of β over the paper's faces of that ring: [`BETA`].
//!
//! Rotations: the distance is the least over the sample's neighbourhood turned by 0°, 60°
//! and 120°. Both rings hold a multiple of 6 points, so a turn by 60° only permutes them
//! (2 places on the inner ring, 4 on the outer): the sample is resampled once per level,
//! and each rotation is the query read in a permuted order. A vertex remembers the turn its
//! texel won by ([`Turns`]). Its neighbours' candidates follow that turn: the forward shift
//! from a neighbour at offset o is its texel minus o turned, and a child inherits its
//! parent's texel plus its own offset turned ([`inherit`]). So a copy continues in the
//! direction it was laid down, not in the sample's.

use super::candidates::Search;
use super::engine::{PassPlan, PassStats, Select, State};
use super::kdtrees::{Eigen, Flow, UseTrees, APPROXIMATION};
use super::metric::known_parts;
use super::neighbourhood::Compared;
use super::pass::{run_scheduled_pass, Choice, Schedule, VertexMatch};
use super::round::{layout_offsets, resample_at_offsets};
use super::round_pass::RoundTarget;
use super::sample::{AppearanceMap, SampleLevel};
use super::slot::{Slot, OUTSIDE};
use super::target::{Shift, TargetLevel};
use glam::Vec2;
use rand_chacha::ChaCha8Rng;
use std::f32::consts::TAU;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Mutex, OnceLock};

use super::isotropic_stencil::ring_of;
pub use super::isotropic_stencil::{turned, BETA, POINTS, RING_POINTS, TURNS};

/// The circles the mesh levels are marched for (defined beside the stencil in the recipe,
/// which must know it without using this module).
pub use super::neighbourhood::ISOTROPIC_MARCHED as MARCHED;

/// Texels a candidate's neighbourhood reaches: the outer ring and one more for bilinear
/// reads.
pub const REACH: usize = 3;

/// The stencil as (circle, fraction of a turn from the reference direction), inner ring
/// first.
pub fn layout() -> Vec<(usize, f32)> {
    RING_POINTS
        .iter()
        .enumerate()
        .flat_map(|(ring, &n)| (0..n).map(move |k| (ring + 1, k as f32 / n as f32)))
        .collect()
}

/// Offset `o` (x along the texture, y down its rows, in texels) turned by `turn` × 60°, in
/// the sense the stencil's points advance.
pub fn turn_offset(o: [f32; 2], turn: u8) -> [f32; 2] {
    let (s, c) = (f32::from(turn) * TAU / 6.0).sin_cos();
    [o[0] * c + o[1] * s, -o[0] * s + o[1] * c]
}

/// Offset `o` turned by `turn` × 60° as three shears, each by whole texels (Paeth 1986): on
/// whole offsets a one-to-one map, so two neighbours of a turned copy never land on one
/// texel, where rounding [`turn_offset`] would put 3% of a turned copy's adjacent pairs on
/// the same texel (a smear). 120° is a half turn after −60°, whose shears are short.
pub fn shear_offset(o: [f32; 2], turn: u8) -> [f32; 2] {
    let (sign, angle) = match turn % 3 {
        0 => return o,
        1 => (1.0, TAU / 6.0),
        _ => (-1.0, -TAU / 6.0),
    };
    let (t, s) = ((angle / 2.0).tan(), angle.sin());
    let [x, y] = o;
    let x1 = x + (t * y).round();
    let y1 = y - (s * x1).round();
    let x2 = x1 + (t * y1).round();
    [sign * x2, sign * y1]
}

/// Per vertex of a level, the turn (0, 1, 2 × 60°) by which the sample's neighbourhood
/// around its texel matched. Atomic so that the parallel sub-passes of an interleaved
/// pass may share it: within one, no vertex reads another's turn (they are shifts of each
/// other, which the colouring keeps apart).
pub struct Turns(Vec<AtomicU8>);

impl Turns {
    /// Every vertex unturned.
    pub fn zeros(vertices: usize) -> Self {
        Turns((0..vertices).map(|_| AtomicU8::new(0)).collect())
    }

    /// Vertex `v`'s turn.
    pub fn get(&self, v: usize) -> u8 {
        self.0[v].load(Ordering::Relaxed)
    }

    fn set(&self, v: usize, turn: u8) {
        self.0[v].store(turn, Ordering::Relaxed);
    }
}

/// Each vertex of `level` takes its parent's texel, times 2, plus its own offset turned by
/// the parent's turn, and the parent's turn: the coarse copy continues in its direction.
pub fn inherit(
    level: &TargetLevel,
    coarse: &State,
    coarse_turns: &Turns,
    sample: &SampleLevel,
    radius: usize,
) -> (State, Turns) {
    let turns = Turns::zeros(level.vertices);
    let uv: Vec<[i32; 2]> = level
        .parents
        .iter()
        .enumerate()
        .map(|(v, link)| {
            let turn = coarse_turns.get(link.vertex as usize);
            turns.set(v, turn);
            let [cx, cy] = coarse.uv[link.vertex as usize];
            let [dx, dy] = shear_offset(link.offset, turn);
            sample.fold_into_candidates(
                2 * cx as i64 + dx.round() as i64,
                2 * cy as i64 + dy.round() as i64,
                radius,
            )
        })
        .collect();
    let labels = uv.iter().map(|&[x, y]| sample.label_at(x as i64, y as i64)).collect();
    (State::new(labels, uv), turns)
}

/// The isotropic neighbourhoods of every texel of one sample level, unturned: `POINTS ×
/// dims` values per texel, resampled once per level.
pub struct IsoSample {
    dims: usize,
    values: Vec<f32>,
    /// The eigenvector transform of the candidates' neighbourhoods, built by the first pass
    /// that searches kd-trees ([`Search::KdTrees`]).
    eigen: OnceLock<Eigen>,
}

impl IsoSample {
    /// Resamples `map`, a `width × height` level (its border supplies texels past the edge).
    pub fn new(map: &AppearanceMap, width: usize, height: usize) -> Self {
        let offsets = layout_offsets(&layout());
        let values = resample_at_offsets(map, width, height, &offsets, halved_cell);
        let dims = map.dims;
        IsoSample { dims, values, eigen: OnceLock::new() }
    }

    /// The eigenvector transform of `sample`'s candidate texels (this level's, `margin` inside
    /// its edges), built once.
    pub fn eigen(&self, sample: &SampleLevel, margin: usize) -> &Eigen {
        self.eigen.get_or_init(|| {
            let texels = super::candidates::full_candidates(sample, margin);
            Eigen::new(texels, sample.width * sample.height, self.dims, |q| self.at(q))
        })
    }

    /// Texel `q`'s (index y · width + x) neighbourhood.
    fn at(&self, q: u32) -> &[f32] {
        let n = POINTS * self.dims;
        &self.values[q as usize * n..(q as usize + 1) * n]
    }
}

/// `map` at the real position `p`, linear in the half of its cell `p` lies in: the way a
/// plane's points are read from its grid ([`RoundTarget::slots_at`]), so that an exact copy
/// of the sample matches at distance 0 (bilinear reads would not).
fn halved_cell(map: &AppearanceMap, p: Vec2, out: &mut [f32]) {
    let snap = |v: f32| if (v - v.round()).abs() < 1e-4 { v.round() } else { v };
    let (px, py) = (snap(p.x), snap(p.y));
    let (x0, y0) = (px.floor(), py.floor());
    let (u, w) = (px - x0, py - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let corners = if u >= w {
        [((0, 0), 1.0 - u), ((1, 0), u - w), ((1, 1), w)]
    } else {
        [((0, 0), 1.0 - w), ((0, 1), w - u), ((1, 1), u)]
    };
    out.fill(0.0);
    for ((dx, dy), weight) in corners.into_iter().filter(|c| c.1 > 0.0) {
        out.iter_mut().zip(map.at(x0 + dx, y0 + dy)).for_each(|(o, &v)| *o += weight * v);
    }
}

/// What a level's isotropic passes share: where the points come from, the sample's
/// neighbourhoods and every vertex's turn.
pub struct IsoLevel<'a> {
    /// Where a vertex's stencil points lie (the grid of a plane, or marching on a mesh).
    pub target: RoundTarget<'a>,
    /// The sample's neighbourhoods, read once per level.
    pub sample: IsoSample,
    /// Every vertex's turn (0°, 60° or 120°), which its candidates follow.
    pub turns: &'a Turns,
}

/// A vertex's query turned each way: per turn the values and weights read in the order of
/// the sample's unturned points, so every turn compares contiguous memory.
#[derive(Default)]
struct Query {
    values: [Vec<f32>; TURNS],
    weights: [Vec<f32>; TURNS],
}

/// A vertex's isotropic neighbourhood under the proximity-weighted SSD, least over the
/// three turns.
pub struct IsoMatch<'a> {
    level: &'a IsoLevel<'a>,
    sample: &'a SampleLevel,
    map: &'a AppearanceMap,
    layout: Vec<(usize, f32)>,
    v: usize,
    slots: Vec<Slot>,
    own: Vec<f32>,
    known: Vec<bool>,
    query: Query,
    /// The texels of the vertex's adjacent vertices (within [`ADJACENT`] texels).
    adjacent: Vec<u32>,
    /// The pass's kd-trees, when it searches them ([`Search::KdTrees`]).
    trees: Option<&'a Mutex<UseTrees<'a>>>,
    /// Under the trees, the factor on a candidate that starts a new copy and was chosen
    /// `excess` times more than the least-used: `base`^excess (1 + bias), as
    /// [`super::engine::selection_factor`] gives it; a tree's search radius.
    fresh: (f32, f32),
    /// Per texel, the visit that compared it last (a tree yields each texel once per turn).
    seen: Vec<u32>,
    visit: u32,
}

/// The best candidate so far: scaled distance, texel, turn.
type Best = (f32, u32, u8);

/// Vertices this close are adjacent: the 8-neighbourhood on a grid, as `eval`'s smear
/// counts pairs.
const ADJACENT: f32 = 1.5;

impl<'a> IsoMatch<'a> {
    /// Matches `map` (the colours or appearance vectors of `sample`) on `level`.
    pub fn new(level: &'a IsoLevel<'a>, sample: &'a SampleLevel, map: &'a AppearanceMap) -> Self {
        IsoMatch {
            level,
            sample,
            map,
            layout: layout(),
            v: 0,
            slots: Vec::new(),
            own: Vec::new(),
            known: Vec::new(),
            query: Query::default(),
            adjacent: Vec::new(),
            trees: None,
            fresh: (1.0, 0.0),
            seen: Vec::new(),
            visit: 0,
        }
    }

    /// Searches the pass's kd-trees `trees` for every candidate texel, not only those
    /// [`VertexMatch::choose`] is given.
    /// `select` and `bias` are the pass's: the penalty on a tree's candidates.
    pub fn with_trees(mut self, trees: &'a Mutex<UseTrees<'a>>, select: Select, bias: f32) -> Self {
        self.seen = vec![0; self.sample.width * self.sample.height];
        self.trees = Some(trees);
        let base = if let Select::UsePenalty { base } = select { base } else { 1.0 };
        self.fresh = (base, bias);
        self
    }

    /// `best` improved by the candidates in `candidates`, each distance scaled by `factor`;
    /// an adjacent vertex's texel is passed over when `avoid`.
    fn scan(&self, candidates: &[u32], factor: &impl Fn(u32) -> f32, avoid: bool, mut best: Best) -> Best {
        for &q in candidates.iter().filter(|q| !(avoid && self.adjacent.contains(q))) {
            let f = factor(q);
            let (d, turn) = self.distance(q, best.0 / f);
            if d * f < best.0 {
                best = (d * f, q, turn);
            }
        }
        best
    }

    /// The best of every candidate texel, through the kd-trees (ε-approximate:
    /// [`super::kdtrees`]): first `seeds`, which hold every candidate continuing a
    /// neighbour's copy (the one cheaper factor), then each tree nearest first until its
    /// lower bound times its penalty cannot win by more than 1 + ε. A vertex with unknown
    /// points (past an edge) searches the same way from its known points' fit, its
    /// estimates scaled by their share of the weight (what its distances compare); scanning
    /// every candidate for them took a quarter of a 128² level's search.
    fn search_trees(
        &mut self,
        trees: &UseTrees,
        seeds: &[u32],
        factor: &impl Fn(u32) -> f32,
    ) -> (Best, usize) {
        let eigen = trees.eigen();
        let (query, share) = if self.known.contains(&false) {
            eigen.partial_query(&self.own, &self.known)
        } else {
            (eigen.query(&self.own), 1.0)
        };
        let slack = 1.0 + APPROXIMATION;
        let mut seeds: Vec<(f32, u32)> = seeds
            .iter()
            .filter(|q| !self.adjacent.contains(q))
            .map(|&q| (eigen.bound(&query, q) * share * factor(q), q))
            .collect();
        seeds.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let (mut best, mut compared) = ((f32::INFINITY, 0, 0), 0);
        for &(low, q) in &seeds {
            if low * slack > best.0 {
                break;
            }
            best = self.consider(q, factor(q), best);
            compared += 1;
        }
        let best = std::cell::Cell::new(best);
        self.visit = self.visit.wrapping_add(1);
        let visit = self.visit;
        let mut seen = std::mem::take(&mut self.seen);
        seeds.iter().map(|s| &s.1).chain(&self.adjacent).for_each(|&q| seen[q as usize] = visit);
        let (base, bias) = self.fresh;
        let radius =
            |excess: u32| best.get().0 / (base.powi(excess.min(60) as i32) * (1.0 + bias) * slack * share);
        trees.search(&query, radius, |q, bound| {
            if seen[q as usize] == visit {
                return Flow::Next;
            }
            // Every texel left in this tree starts a new copy: the same factor for all.
            let f = factor(q);
            if bound * share * f * slack > best.get().0 {
                return Flow::Leave;
            }
            seen[q as usize] = visit;
            compared += 1;
            best.set(self.consider(q, f, best.get()));
            Flow::Next
        });
        self.seen = seen;
        (best.get(), compared)
    }

    /// `best` or texel `q` under `factor` `f`, whichever is less; a tie goes to the lower
    /// texel index, as in the exhaustive scan's index order (the trees meet texels in
    /// another order, and on a striped sample ties are many).
    fn consider(&self, q: u32, f: f32, best: Best) -> Best {
        let (d, turn) = self.distance(q, best.0 / f);
        if d * f < best.0 || (d * f == best.0 && q < best.1) {
            (d * f, q, turn)
        } else {
            best
        }
    }

    /// Texel `q` was chosen: under [`Search::KdTrees`] it moves one tree up, as the pass's
    /// use count moves (every choice counts, [`Select::UsePenalty`]).
    fn chose(&self, q: u32) {
        if let Some(trees) = self.trees {
            trees.lock().expect("a pass's trees").chose(q);
        }
    }

    /// The least weighted SSD over the turns between the query and texel `q`, with its
    /// turn; stops a turn early once it passes `bound`.
    fn distance(&self, q: u32, bound: f32) -> (f32, u8) {
        let (s, dims) = (self.level.sample.at(q), self.map.dims);
        let mut best = (f32::INFINITY, 0u8);
        for turn in 0..TURNS {
            let (values, weights) = (&self.query.values[turn], &self.query.weights[turn]);
            let limit = bound.min(best.0);
            let mut d = 0.0;
            for (p, &w) in weights.iter().enumerate() {
                if w == 0.0 {
                    continue;
                }
                let (a, b) = (&values[p * dims..(p + 1) * dims], &s[p * dims..(p + 1) * dims]);
                d += w * a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f32>();
                if d > limit {
                    break;
                }
            }
            if d < best.0 {
                best = (d, turn as u8);
            }
        }
        best
    }
}

impl VertexMatch for IsoMatch<'_> {
    fn reach(&self) -> usize {
        REACH
    }

    fn two_level(&self) -> bool {
        false
    }

    fn prepare(&mut self, v: usize, state: &State, known: Option<&[bool]>) {
        self.v = v;
        let dims = self.map.dims;
        self.level.target.slots_at(v, &self.layout, &mut self.slots);
        self.own.clear();
        self.own.resize(POINTS * dims, 0.0);
        self.known.clear();
        self.known.resize(POINTS, false);
        for (p, parts, count) in known_parts(&self.slots, known) {
            // Past the surface or the plane's edge a point is a wild card (§3.12): it is
            // not compared at all.
            if parts[..count].iter().all(|&(u, _)| u == OUTSIDE) {
                continue;
            }
            self.known[p] = true;
            for &(u, weight) in parts[..count].iter().filter(|(u, _)| *u != OUTSIDE) {
                let [x, y] = state.uv[u as usize];
                let values = &mut self.own[p * dims..(p + 1) * dims];
                values.iter_mut().zip(self.map.at(x as i64, y as i64)).for_each(|(q, &a)| *q += weight * a);
            }
        }
        // Turned by t, the sample's point `turned(p, t)` faces the query's point p.
        for turn in 0..TURNS {
            let (values, weights) = (&mut self.query.values[turn], &mut self.query.weights[turn]);
            values.resize(POINTS * dims, 0.0);
            weights.resize(POINTS, 0.0);
            for p in 0..POINTS {
                let j = turned(p, turn);
                values[j * dims..(j + 1) * dims].copy_from_slice(&self.own[p * dims..(p + 1) * dims]);
                weights[j] = if self.known[p] { BETA[ring_of(p).0] } else { 0.0 };
            }
        }
    }

    fn follow<'s>(&mut self, shifts: &'s [Shift], state: &State, scratch: &'s mut Vec<Shift>) -> &'s [Shift] {
        scratch.clear();
        let turns = self.level.turns;
        scratch.extend(shifts.iter().map(|&(u, o)| (u, shear_offset(o, turns.get(u as usize)))));
        let (width, v) = (self.sample.width, self.v);
        let adjacent = shifts.iter().filter(|(u, o)| *u as usize != v && o[0].hypot(o[1]) <= ADJACENT);
        self.adjacent.clear();
        self.adjacent.extend(adjacent.map(|&(u, _)| {
            let [x, y] = state.uv[u as usize];
            (y as usize * width + x as usize) as u32
        }));
        scratch
    }

    fn choose(
        &mut self,
        candidates: &[u32],
        _current: [i32; 2],
        factor: impl Fn(u32) -> f32,
        draw: impl FnOnce() -> [i32; 2],
    ) -> Choice {
        // Nothing known around the vertex: every candidate ties; start it at random.
        if !self.known.contains(&true) || (candidates.is_empty() && self.trees.is_none()) {
            self.level.turns.set(self.v, 0);
            let texel = draw();
            self.chose((texel[1] as usize * self.sample.width + texel[0] as usize) as u32);
            return Choice { texel: Some(texel), figure: 0.0, compared: candidates.len() };
        }
        // A neighbour's own texel would repeat it (a smear): turned copies resampled on the
        // square grid land there, which the sample's own copies never do.
        let (best, compared) = match self.trees {
            Some(trees) => self.search_trees(&trees.lock().expect("a pass's trees"), candidates, &factor),
            None => {
                let avoid = candidates.iter().any(|q| !self.adjacent.contains(q));
                (self.scan(candidates, &factor, avoid, (f32::INFINITY, 0, 0)), candidates.len())
            }
        };
        let width = self.sample.width;
        let texel = [(best.1 as usize % width) as i32, (best.1 as usize / width) as i32];
        self.level.turns.set(self.v, best.2);
        self.chose(best.1);
        Choice { texel: Some(texel), figure: f64::from(best.0), compared }
    }
}

/// One isotropic pass over `level` under `schedule`, among k-coherence candidates that follow
/// each neighbour's turn or, with [`Search::Full`], every candidate texel; picked as `select`
/// says, with `bias` on candidates that start a new copy.
#[allow(clippy::too_many_arguments)]
pub fn isotropic_pass(
    level: &TargetLevel,
    iso: &IsoLevel,
    state: &mut State,
    sample: &SampleLevel,
    map: &AppearanceMap,
    (search, compared, select, coherence_bias): (Search, Compared, Select, f32),
    schedule: &Schedule,
    rng: &mut ChaCha8Rng,
) -> PassStats {
    // The trees follow each choice as it is made: a sequential order only (the recipe
    // refuses others; an interleaved level without a colouring runs sequentially too).
    let sequential = matches!(schedule, Schedule::Order(_));
    let trees = (search == Search::KdTrees && sequential)
        .then(|| Mutex::new(UseTrees::new(iso.sample.eigen(sample, level.candidate_margin(REACH)))));
    let search = if search == Search::KdTrees && !sequential { Search::Full } else { search };
    let make = || {
        let matcher = IsoMatch::new(iso, sample, map);
        match &trees {
            Some(trees) => matcher.with_trees(trees, select, coherence_bias),
            None => matcher,
        }
    };
    let plan = PassPlan { search, select, coherence_bias, mask: compared.mask(), move_cost: None };
    run_scheduled_pass(level, state, sample, make, &plan, schedule, rng)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Centroids of the faces of a triangular grid of unit edges around the up-pointing face
    /// at the origin, with their adjacency distance (faces sharing a vertex are 1 apart),
    /// in units of the spacing of edge-adjacent faces.
    fn face_rings() -> Vec<(usize, f32)> {
        let h = 3f32.sqrt() / 2.0;
        let corners = |i: i32, j: i32, up: bool| -> [(i32, i32); 3] {
            // Vertices as (2x, y/h) on the lattice, exact in integers.
            let (x, y) = (2 * i + j, j);
            if up {
                [(x, y), (x + 2, y), (x + 1, y + 1)]
            } else {
                [(x + 2, y), (x + 3, y + 1), (x + 1, y + 1)]
            }
        };
        let faces: Vec<[(i32, i32); 3]> = (-6..=6)
            .flat_map(|j| (-6..=6).flat_map(move |i| [corners(i, j, true), corners(i, j, false)]))
            .collect();
        let centre = corners(0, 0, true);
        let shares = |a: &[(i32, i32); 3], b: &[(i32, i32); 3]| a.iter().any(|p| b.contains(p));
        let one: Vec<_> = faces.iter().filter(|f| **f != centre && shares(f, &centre)).collect();
        let centroid = |f: &[(i32, i32); 3]| {
            let (x, y) = f.iter().fold((0, 0), |(sx, sy), p| (sx + p.0, sy + p.1));
            (x as f32 / 6.0, y as f32 * h / 3.0)
        };
        let c0 = centroid(&centre);
        let spacing = 1.0 / 3f32.sqrt();
        let dist = |f: &[(i32, i32); 3]| {
            let c = centroid(f);
            (c.0 - c0.0).hypot(c.1 - c0.1) / spacing
        };
        faces
            .iter()
            .filter(|f| **f != centre)
            .filter_map(|f| {
                if one.contains(&f) {
                    Some((1, dist(f)))
                } else if one.iter().any(|o| shares(o, f)) {
                    Some((2, dist(f)))
                } else {
                    None
                }
            })
            .collect()
    }

    /// The paper's stencil has 12 one-distant and 24 two-distant faces; BETA is Eq. 7's
    /// mean over each, and the circles sit at radii in the rings' ratio.
    #[test]
    fn the_weights_are_eq_7_over_the_papers_rings() {
        let rings = face_rings();
        for (ring, n) in [(1, 12), (2, 24)] {
            let d: Vec<f32> = rings.iter().filter(|r| r.0 == ring).map(|r| r.1).collect();
            assert_eq!(d.len(), n, "ring {ring}");
            let beta = d.iter().map(|d| (-0.5 * (d / 1.3).powi(2)).exp()).sum::<f32>() / n as f32;
            assert!((beta - BETA[ring - 1]).abs() < 5e-4, "ring {ring}: β {beta}");
        }
        let mean = |ring| {
            let d: Vec<f32> = rings.iter().filter(|r| r.0 == ring).map(|r| r.1).collect();
            d.iter().sum::<f32>() / d.len() as f32
        };
        assert!((mean(2) / mean(1) - 2.0).abs() < 0.05, "{} {}", mean(1), mean(2));
        assert_eq!(layout().len(), POINTS);
    }

    /// Where point p of the stencil sits, x along the texture and y down its rows.
    fn position(p: usize) -> [f32; 2] {
        let (c, turn) = layout()[p];
        let (s, co) = (turn * TAU).sin_cos();
        [c as f32 * co, -(c as f32) * s]
    }

    /// A turn by 60° moves every point onto the point `turned` names, and `turn_offset`
    /// turns offsets the same way.
    #[test]
    fn a_turn_permutes_the_points() {
        for turn in 0..TURNS {
            let mut seen = [false; POINTS];
            for p in 0..POINTS {
                let (want, got) = (turn_offset(position(p), turn as u8), position(turned(p, turn)));
                assert!((want[0] - got[0]).abs() < 1e-5 && (want[1] - got[1]).abs() < 1e-5, "{p}, {turn}");
                seen[turned(p, turn)] = true;
            }
            assert!(seen.iter().all(|&s| s), "turn {turn} is a permutation");
        }
        assert_eq!(turned(0, 1), 2);
        assert_eq!(turned(RING_POINTS[0], 1), RING_POINTS[0] + 4);
    }

    /// The shears map whole offsets one to one, each within a texel of the exact turn.
    #[test]
    fn sheared_turns_are_one_to_one_and_near_the_exact_turn() {
        let offsets: Vec<[f32; 2]> =
            (-6..=6).flat_map(|y| (-6..=6).map(move |x| [x as f32, y as f32])).collect();
        for turn in 0..TURNS as u8 {
            let mut images: Vec<[i32; 2]> =
                offsets.iter().map(|&o| shear_offset(o, turn).map(|v| v as i32)).collect();
            for (o, i) in offsets.iter().zip(&images) {
                let exact = turn_offset(*o, turn);
                let error = (exact[0] - i[0] as f32).hypot(exact[1] - i[1] as f32);
                assert!(error < 1.0, "{o:?} turned {turn}: {i:?} against {exact:?}");
            }
            images.sort();
            images.dedup();
            assert_eq!(images.len(), offsets.len(), "turn {turn}");
        }
    }

    /// A 64² crop of a shared photograph as a sample level of linear colours, or `None` (one
    /// `skipped:` line) where the shared data is absent.
    fn photo_level(test: &str, photo: &str) -> Option<(SampleLevel, AppearanceMap)> {
        let path = crate::testdata::shared_data(test, photo)?;
        let image = image::open(path).unwrap().to_rgb32f();
        let (w, h) = (64usize, 64usize);
        let colours: Vec<f32> =
            (0..w * h).flat_map(|p| image.get_pixel((p % w) as u32, (p / w) as u32).0).collect();
        let map = AppearanceMap::new(w, h, 3, &colours, false);
        let mut sample = crate::synth::engine::tests::periodic_sample(4);
        (sample.width, sample.height, sample.tileable, sample.labels) = (w, h, false, vec![0; w * h]);
        Some((sample, map))
    }

    /// On real photographs the kd-trees choose within their approximation of the exhaustive
    /// search: each vertex of a 40² plane of random texels picks among every candidate
    /// under choosy sampling's penalty (counts as the choices go, base 2, every candidate
    /// fresh), once by scanning all of them and once through the trees; where the stencil
    /// lies inside the plane the trees' choice is at most 1 + ε the scan's, and the trees
    /// compare a fraction of the candidates.
    #[test]
    fn the_kd_trees_choose_within_their_approximation_of_the_exhaustive_search_on_photographs() {
        for photo in ["textures/gimp-Stone_stone33.png", "textures/sh3d-pebbles.jpg"] {
            let test = "the_kd_trees_choose_what_the_exhaustive_search_chooses";
            let Some((sample, map)) = photo_level(test, photo) else { return };
            let (w, side) = (sample.width, 40usize);
            let turns = Turns::zeros(side * side);
            let target = RoundTarget::Grid { width: side, height: side, wraps: false };
            let level = IsoLevel { target, sample: IsoSample::new(&map, w, sample.height), turns: &turns };
            let eigen = level.sample.eigen(&sample, REACH);
            assert!(eigen.captured > 0.8, "{photo}: 20 components hold {} of the variance", eigen.captured);
            let all = eigen.texels().to_vec();
            let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(5);
            let uv = (0..side * side)
                .map(|_| super::super::start::random_texel(&sample, REACH, &mut rng))
                .collect();
            let state = State::new(vec![0; side * side], uv);
            let trees = Mutex::new(UseTrees::new(eigen));
            let (mut scan, mut tree) = (
                IsoMatch::new(&level, &sample, &map),
                IsoMatch::new(&level, &sample, &map).with_trees(
                    &trees,
                    Select::UsePenalty { base: 2.0 },
                    1.0,
                ),
            );
            let mut count = vec![0u32; w * sample.height];
            let (mut compared, mut worst, mut interior) = (0, 1f64, 0);
            for v in 0..side * side {
                let floor = all.iter().map(|&q| count[q as usize]).min().unwrap();
                let factor = |q: u32| 2f32.powi((count[q as usize] - floor) as i32) * 2.0;
                scan.prepare(v, &state, None);
                tree.prepare(v, &state, None);
                let a = scan.choose(&all, [0, 0], factor, || [0, 0]);
                let b = tree.choose(&[], [0, 0], factor, || [0, 0]);
                let index = |t: [i32; 2]| t[1] as usize * w + t[0] as usize;
                let tb = b.texel.unwrap();
                // Only a vertex whose stencil lies inside the grid has a bound: one past
                // an edge searches from an estimate of its missing points.
                let (x, y) = (v % side, v / side);
                if (REACH..side - REACH).contains(&x) && (REACH..side - REACH).contains(&y) {
                    worst = worst.max(b.figure / a.figure.max(1e-12));
                    interior += 1;
                }
                compared += b.compared;
                // The trees count their own choices, so the scan's penalties follow them:
                // both then judge every vertex under the same counts.
                count[index(tb)] += 1;
            }
            let n = side * side;
            let bound = 1.0 + f64::from(super::super::kdtrees::APPROXIMATION) + 1e-3;
            assert!(interior > n / 2 && worst <= bound, "{photo}: a tree's choice is {worst}× the scan's");
            let mean = compared as f64 / n as f64;
            assert!(mean < all.len() as f64 / 3.0, "{photo}: {mean} of {} compared", all.len());
        }
    }

    /// A plane that is an exact copy of the sample matches its own texels at distance 0,
    /// unturned (the sample is read as the grid is); an adjacent vertex's texel is passed
    /// over while another candidate remains.
    #[test]
    fn an_exact_copy_matches_itself_unturned() {
        let (w, h) = (24usize, 24usize);
        let colours: Vec<f32> = (0..w * h)
            .flat_map(|p| {
                let (x, y) = ((p % w) as f32, (p / w) as f32);
                [(x * 0.7).sin() + (y * 0.3).cos(), (x * 0.2 + y * 0.5).sin(), (x * y * 0.05).cos()]
            })
            .collect();
        let map = AppearanceMap::new(w, h, 3, &colours, false);
        let mut sample = crate::synth::engine::tests::periodic_sample(4);
        (sample.width, sample.height, sample.tileable) = (w, h, false);
        sample.labels = vec![0; w * h];
        let turns = Turns::zeros(w * h);
        let level = IsoLevel {
            target: RoundTarget::Grid { width: w, height: h, wraps: false },
            sample: IsoSample::new(&map, w, h),
            turns: &turns,
        };
        let state =
            State::new(vec![0; w * h], (0..w * h).map(|p| [(p % w) as i32, (p / w) as i32]).collect());
        let mut m = IsoMatch::new(&level, &sample, &map);
        let v = 12 * w + 11;
        m.prepare(v, &state, None);
        let candidates: Vec<u32> = (0..(w * h) as u32)
            .filter(|&q| sample.is_candidate((q as usize % w) as i64, (q as usize / w) as i64, REACH))
            .collect();
        assert_eq!(m.distance(v as u32, f32::INFINITY), (0.0, 0));
        let choice = m.choose(&candidates, state.uv[v], |_| 1.0, || [0, 0]);
        assert_eq!(choice.texel, Some([11, 12]));
        assert_eq!(turns.get(v), 0);
        // A neighbour's texel is passed over when another candidate exists.
        m.follow(&[((v + 1) as u32, [1.0, 0.0])], &state, &mut Vec::new());
        let choice = m.choose(&[v as u32 + 1, v as u32 + 2], state.uv[v], |_| 1.0, || [0, 0]);
        assert_eq!(choice.texel, Some([13, 12]));
    }
}
