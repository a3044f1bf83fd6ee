//! How a level's map starts before its passes: random texels, random coherent patches, or
//! inherited from the coarser level (Tong §5.1, first pass).

use super::engine::State;
use super::lattice::Lattice;
use super::metric::Metric;
use super::recipe::KeepInteriors;
use super::sample::SampleLevel;
use super::target::{Neighbourhoods, Shift, TargetLevel};
use rand::seq::{IndexedRandom, SliceRandom};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Neighbours closer than this many texels are joined when growing patches: the grid's 8
/// neighbours, a mesh's one-ring, so that offsets add up along short steps.
const STEP: f32 = 1.5;

/// Random sample coordinates for every vertex (Tong §5.1: "randomly mapped to the pixels").
pub fn random_state(level: &TargetLevel, sample: &SampleLevel, margin: usize, rng: &mut ChaCha8Rng) -> State {
    let uv = (0..level.vertices).map(|_| random_texel(sample, margin, rng)).collect();
    with_labels(uv, sample)
}

/// A uniformly random candidate texel (`margin` inside the sample's edges).
pub fn random_texel(sample: &SampleLevel, margin: usize, rng: &mut ChaCha8Rng) -> [i32; 2] {
    let p = sample.candidate_pixel(
        rng.random_range(0..sample.width as i64),
        rng.random_range(0..sample.height as i64),
        margin,
    );
    [(p % sample.width) as i32, (p / sample.width) as i32]
}

/// Coherent patches (beyond the paper; after the "chaos mosaic" of Xu, Guo and Shum 2000 and
/// the image quilting of Efros and Freeman 2001): seeds about `patch_radius` texels apart
/// (each a random spacing, [`SPACING_SPREAD`]) cover the level, every vertex joins its
/// nearest seed along the surface, and each patch
/// copies a piece of the sample whole, each vertex at its patch's texel plus its offset from
/// the seed summed along the way.
///
/// Patches are placed one after another, each next to patches already placed, at whichever
/// of a few candidate places matches them best along the seam: random places, and the
/// places the neighbours' k-coherence lists suggest (where the neighbourhood of the texel a
/// neighbour predicts recurs elsewhere in the sample — for a periodic sample, the same phase
/// elsewhere). Places that continue a neighbour's copy, or lie within [`PLACE_APART`] patch
/// radii of such a place, are not taken, so copies stay patch-sized and neighbouring
/// patches come from unrelated parts of the sample.
///
/// Why patches: random texels make every neighbourhood noise, and the best match to noise is
/// the sample's most featureless neighbourhood, so passes from a random start converge onto a
/// few flat texels; patches start from real neighbourhoods and leave the passes only the
/// seams to mend. Patches wrap around the band of candidate texels, also on a sample that
/// does not tile: the wrap is one more seam, whereas patches kept inside the sample use its
/// middle far more than its edges (measured: 7% of the output from the most-used 1% of
/// texels, against 2.6% wrapped).
///
/// Along an axis where the sample has edges of its own ([`own_edges`]) a patch is moved,
/// where it fits, so that its copy does not wrap. On a lattice sample ([`Layout::lattice`])
/// a plane's patches are the lattice's cells ([`cell_seeds`]) and every patch is placed in
/// phase ([`in_phase`]).
pub(crate) fn patch_state<M: Metric>(
    level: &TargetLevel,
    sample: &SampleLevel,
    metric: &M,
    (margin, patch_radius, k): (usize, f32, usize),
    layout: Layout,
    rng: &mut ChaCha8Rng,
) -> PatchStart {
    let graph = Steps::of(level);
    let cells = layout.lattice.zip(plane_grid(level));
    let seeds = match cells {
        Some((lattice, width)) => cell_seeds(level.vertices, width, &lattice, rng),
        None => spread_seeds(&graph, patch_radius, rng),
    };
    let centre = cells.map(|(lattice, _)| cell_centre(sample, metric, &lattice, margin));
    let (owner, position) = graph.nearest_seed(&seeds);
    let mut members = vec![Vec::new(); seeds.len()];
    for v in 0..level.vertices {
        members[owner[v] as usize].push(v as u32);
    }
    let place = |c: [i64; 2], v: usize| {
        let o = position[v].map(|p| p.round() as i64);
        sample.wrap_into_candidates(c[0] + o[0], c[1] + o[1], margin)
    };
    let mut uv = vec![[0i32; 2]; level.vertices];
    let mut places: Vec<Option<[i64; 2]>> = vec![None; seeds.len()];
    let mut uses = Uses::new(sample, margin, level.vertices);
    for patch in seam_order(&graph, &owner, seeds.len()) {
        let seam = seam_pairs(&graph, &members[patch], &owner, &places, &uv, sample, margin);
        let footprint = Footprint::of(&members[patch], &position, border_axes(level, &members[patch]));
        let continued = continuations(&seam, &position);
        let mut apart_from = continued.clone();
        let mut candidates = match layout.lattice {
            Some(lattice) if !seam.is_empty() => in_phase(&continued, &lattice, &footprint, sample, margin),
            // The first patch of a part: a whole number of periods from the cell centre.
            Some(lattice) if centre.is_some() => {
                let first = in_phase(&[centre.unwrap_or_default()], &lattice, &footprint, sample, margin);
                first.choose(rng).into_iter().copied().collect()
            }
            _ => placements(&seam, &position, sample, (margin, k), rng),
        };
        if layout.lattice.is_some() {
            // On a lattice the places are few, and among them are the neighbours' own cells:
            // the same element twice side by side is the lattice of copies at its plainest.
            let neighbours = members[patch].iter().flat_map(|&v| graph.neighbours(v as usize));
            apart_from.extend(neighbours.filter_map(|(u, ..)| places[owner[u] as usize]));
            // One entry per neighbour, not per step to it: a mesh's patches are large.
            apart_from.sort_unstable();
            apart_from.dedup();
        }
        if layout.own_edges.contains(&true) {
            let inside = footprint.inside(sample, margin, layout.own_edges);
            candidates.iter_mut().for_each(|c| *c = inside(*c));
        }
        keep_apart(&mut candidates, &apart_from, sample, (margin, patch_radius));
        let cost = |c: [i64; 2]| -> f32 {
            let seam_cost: f32 =
                seam.iter().map(|&(v, predicted)| metric.texel_distance(place(c, v), predicted)).sum();
            let texels = members[patch].iter().map(|&v| place(c, v as usize));
            (seam_cost + f32::MIN_POSITIVE) * uses.factor(texels, members[patch].len())
        };
        let best = candidates.iter().copied().min_by(|&a, &b| cost(a).total_cmp(&cost(b))).unwrap_or([0, 0]);
        for &v in &members[patch] {
            uv[v as usize] = place(best, v as usize);
            uses.add(uv[v as usize]);
        }
        places[patch] = Some(best);
    }
    PatchStart { state: with_labels(uv, sample), owner, position }
}

/// How far from its texel's centre a vertex's place may lie, in texels: short of half a
/// texel by a margin the float sum of texel and place cannot round across.
const SUBTEXEL_REACH: f32 = 0.49;

/// The start's patches on a level.
pub(crate) struct PatchStart {
    /// Every vertex a copy of its patch's place.
    pub state: State,
    /// Per vertex, its patch.
    pub owner: Vec<u32>,
    /// Per vertex, its offset from its patch's seed in texels, summed along the level.
    position: Vec<[f32; 2]>,
}

impl PatchStart {
    /// Per vertex, where it lies within the texel it copies ([`State::subtexel`]): its copy
    /// lies `round(position)` from the patch's place, so what the rounding left. Kept off
    /// the texel's very edge, so that the coordinate written as a float rounds back to it.
    /// Zero on a plane, whose offsets are whole texels.
    pub fn subtexel(&self) -> Vec<[f32; 2]> {
        let within = |x: f32| (x - x.round()).clamp(-SUBTEXEL_REACH, SUBTEXEL_REACH);
        self.position.iter().map(|p| p.map(within)).collect()
    }
}

/// What the start knows of the sample as a whole, besides its texels.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Layout {
    /// Per axis, whether the sample has edges of its own there ([`own_edges`]).
    pub own_edges: [bool; 2],
    /// The sample's lattice in texels of the level patches are placed on, if it is one
    /// ([`super::lattice::detect`]).
    pub lattice: Option<Lattice>,
}

/// Continuations to move by whole periods ([`in_phase`]), spread along the seam.
const PHASE_SOURCES: usize = 8;
/// The most periods a place is moved by along either: at most 17² places per continuation
/// are costed, and on the start level a sample holds far fewer periods than 8 a side.
const MOST_PERIODS: i64 = 8;

/// On a lattice sample, the places in phase with the placed neighbours: each continuation
/// of a neighbour's copy moved by whole periods, those whose copy stays inside the band
/// (wrapping there would shift the phase, the band not being a whole number of periods)
/// unless the sample tiles or no place fits. Random places would cut every element the
/// patch's edge crosses against a misplaced one: on a tiled floor, joints that jump.
fn in_phase(
    continued: &[[i64; 2]],
    lattice: &Lattice,
    footprint: &Footprint,
    sample: &SampleLevel,
    margin: usize,
) -> Vec<[i64; 2]> {
    let sides = [sample.width, sample.height];
    let shortest = lattice.periods.iter().map(|p| p[0].hypot(p[1])).fold(f32::INFINITY, f32::min);
    let reach = ((sides[0].max(sides[1]) as f32 / shortest.max(1.0)).ceil() as i64 + 1).min(MOST_PERIODS);
    let step = continued.len().div_ceil(PHASE_SOURCES).max(1);
    let mut all = Vec::new();
    for &c in continued.iter().step_by(step) {
        for n0 in -reach..=reach {
            for n1 in -reach..=reach {
                let s = lattice.shift([n0, n1]);
                all.push([c[0] + s[0], c[1] + s[1]]);
            }
        }
    }
    let fits = |p: &[i64; 2]| {
        (0..2).all(|axis| {
            let (lo, hi) = sample.band_ends(sides[axis], margin);
            lo <= p[axis] + footprint.low[axis] && p[axis] + footprint.high[axis] <= hi
        })
    };
    if !sample.tileable && all.iter().any(fits) {
        all.retain(fits);
    }
    all.sort_unstable();
    all.dedup();
    all
}

/// A plane's grid width (its vertices row by row), `None` on a mesh.
fn plane_grid(level: &TargetLevel) -> Option<usize> {
    match level.neighbourhoods {
        Neighbourhoods::Grid { width, .. } => Some(width),
        Neighbourhoods::Mesh { .. } => None,
    }
}

/// On a plane and a lattice sample, one seed per cell of the lattice (at a random phase):
/// every patch is then one cell, and placed with its seed on a [`cell_centre`] of the
/// sample its edges run where neighbouring elements meet (a tiled floor's joints), so every
/// element is copied whole (after the near-regular textures of Liu, Lin and Hays 2004).
fn cell_seeds(vertices: usize, width: usize, lattice: &Lattice, rng: &mut ChaCha8Rng) -> Vec<usize> {
    let height = vertices / width.max(1);
    let [a, b] = lattice.periods;
    let origin = [rng.random_range(0.0..1.0f32), rng.random_range(0.0..1.0f32)];
    // Lattice coordinates of the grid's corners bound the cells to visit.
    let det = a[0] * b[1] - a[1] * b[0];
    let coords = |x: f32, y: f32| [(x * b[1] - y * b[0]) / det, (a[0] * y - a[1] * x) / det];
    let corners = [[0.0, 0.0], [width as f32, 0.0], [0.0, height as f32], [width as f32, height as f32]]
        .map(|[x, y]| coords(x, y));
    let range = |i: usize| {
        let (lo, hi) = corners.iter().fold((f32::MAX, f32::MIN), |(lo, hi), c| (lo.min(c[i]), hi.max(c[i])));
        (lo.floor() as i64 - 1)..=(hi.ceil() as i64 + 1)
    };
    let mut seeds = Vec::new();
    for i in range(0) {
        for j in range(1) {
            let (u, v) = (origin[0] + i as f32, origin[1] + j as f32);
            let [x, y] = [u * a[0] + v * b[0], u * a[1] + v * b[1]].map(|c| c.round() as i64);
            if (0..width as i64).contains(&x) && (0..height as i64).contains(&y) {
                seeds.push(y as usize * width + x as usize);
            }
        }
    }
    seeds.sort_unstable();
    seeds.dedup();
    if seeds.is_empty() {
        seeds.push(0);
    }
    seeds
}

/// The texel of the sample's band whose lattice cell around it has the cheapest edges: where
/// each edge texel is most like the texels a period away on either side (Liu, Lin and Hays
/// cut where neighbouring periods agree: on a tiled floor, the joints between the tiles,
/// whereas the tiles' faces differ in tone).
fn cell_centre<M: Metric>(sample: &SampleLevel, metric: &M, lattice: &Lattice, margin: usize) -> [i64; 2] {
    let (x_ends, y_ends) = (sample.band_ends(sample.width, margin), sample.band_ends(sample.height, margin));
    let inside = |p: [i64; 2]| (x_ends.0..=x_ends.1).contains(&p[0]) && (y_ends.0..=y_ends.1).contains(&p[1]);
    let unlike: Vec<f32> =
        super::lattice::structure(sample.width, sample.height, metric).iter().map(|s| -s).collect();
    let [a, b] = lattice.periods;
    let edge_steps = (a[0].hypot(a[1]) + b[0].hypot(b[1])).ceil() as usize * 2;
    let edge: Vec<[f32; 2]> = (0..edge_steps)
        .flat_map(|k| {
            let s = k as f32 / edge_steps as f32 - 0.5;
            [[0.5, s], [-0.5, s], [s, 0.5], [s, -0.5]]
        })
        .map(|[u, v]| [u * a[0] + v * b[0], u * a[1] + v * b[1]])
        .collect();
    let cost = |c: [i64; 2]| -> f32 {
        let (mut sum, mut n) = (0.0, 0);
        for e in &edge {
            let q = [c[0] + e[0].round() as i64, c[1] + e[1].round() as i64];
            let u = if inside(q) { unlike[q[1] as usize * sample.width + q[0] as usize] } else { f32::NAN };
            if u.is_nan() {
                // Only cells wholly inside the band are judged, all on as many texels.
                return f32::INFINITY;
            }
            sum += u;
            n += 1;
        }
        sum / n.max(1) as f32
    };
    let mut best = ([x_ends.0, y_ends.0], f32::INFINITY);
    for y in y_ends.0..=y_ends.1 {
        for x in x_ends.0..=x_ends.1 {
            let c = cost([x, y]);
            if c < best.1 {
                best = ([x, y], c);
            }
        }
    }
    best.0
}

/// A wrap whose [`wrap_unlikeness`] is above this joins texels far less alike than any two
/// unrelated ones: the sample has edges of its own (a board's dark and light edges, a
/// frame), and a patch whose copy wraps there shows them as a bar. On the 23 photographs of
/// ../shared/data/textures, the finest level: a pine board's sides 27.6; every other axis
/// −0.4–0.5 where the sample tiles and 0.6–2.4 where it does not (one row or column is a
/// small sample of the mean, so unrelated columns spread about 1).
const OWN_EDGES: f32 = 4.0;

/// Per axis (x, y), whether `sample` has edges of its own there: its wrap is
/// [`OWN_EDGES`] unlike. Always false on a tileable sample.
pub(crate) fn own_edges<M: Metric>(sample: &SampleLevel, metric: &M, margin: usize) -> [bool; 2] {
    [0, 1].map(|axis| !sample.tileable && wrap_unlikeness(sample, metric, margin, axis) > OWN_EDGES)
}

/// How unlike the texels that wrapping the candidate band along `axis` (0: x, 1: y) makes
/// neighbours are, on a scale where 0 is the sample's own neighbouring texels and 1 texels
/// half the band apart.
fn wrap_unlikeness<M: Metric>(sample: &SampleLevel, metric: &M, margin: usize, axis: usize) -> f32 {
    let sides = [sample.width, sample.height];
    let (lo, hi) = sample.band_ends(sides[axis], margin);
    let (first_row, last_row) = sample.band_ends(sides[1 - axis], margin);
    let at = |row: i64, along: i64| {
        let mut t = [row as i32; 2];
        t[axis] = along as i32;
        t
    };
    // Mean distance between the texels of `pairs` (positions along the axis), over the rows.
    let mean_distance = |pairs: &[(i64, i64)]| -> f64 {
        let by_row = (first_row..=last_row).flat_map(|row| pairs.iter().map(move |&pair| (row, pair)));
        let sum: f64 =
            by_row.map(|(row, (a, b))| f64::from(metric.texel_distance(at(row, a), at(row, b)))).sum();
        sum / (pairs.len() * (last_row - first_row + 1) as usize).max(1) as f64
    };
    let apart = |gap: i64| -> Vec<(i64, i64)> { (lo..=hi - gap).map(|a| (a, a + gap)).collect() };
    let (wrap, near, far) =
        (mean_distance(&[(hi, lo)]), mean_distance(&apart(1)), mean_distance(&apart((hi - lo + 1) / 2)));
    ((wrap - near) / (far - near).max(f64::MIN_POSITIVE)) as f32
}

/// The box of a patch's members' offsets from its seed.
struct Footprint {
    low: [i64; 2],
    high: [i64; 2],
    /// Per axis, whether the patch reaches the edge of a plane's output there.
    clipped: [bool; 2],
}

impl Footprint {
    fn of(members: &[u32], position: &[[f32; 2]], clipped: [bool; 2]) -> Self {
        let offsets = || members.iter().map(|&v| position[v as usize].map(|p| p.round() as i64));
        let extreme = |pick: fn(i64, i64) -> i64, start: i64| {
            [0, 1].map(|axis| offsets().map(|o| o[axis]).fold(start, pick))
        };
        Footprint { low: extreme(i64::min, i64::MAX), high: extreme(i64::max, i64::MIN), clipped }
    }

    /// Moves a place along each axis of `own_edges` so that the patch's copy lies inside
    /// the sample's candidate band, where it fits; elsewhere the copy wraps. Moving rather
    /// than refusing keeps the texels near the edges in use: the least move, which puts the
    /// copy's side on the sample's edge. Except where the patch is cut by the output's
    /// edge: that side is no edge of the patch, and the least move would lay the sample's
    /// edge along the output's (a pine board's dark edge down the whole of a plane's side),
    /// so such a place wraps around the places that fit instead.
    fn inside(
        &self,
        sample: &SampleLevel,
        margin: usize,
        own_edges: [bool; 2],
    ) -> impl Fn([i64; 2]) -> [i64; 2] {
        let sides = [sample.width, sample.height];
        let range = [0, 1].map(|axis| {
            let (lo, hi) = sample.band_ends(sides[axis], margin);
            let (first, last) = (lo - self.low[axis], hi - self.high[axis]);
            (own_edges[axis] && first <= last).then_some((first, last))
        });
        let clipped = self.clipped;
        move |place: [i64; 2]| {
            let mut moved = place;
            for axis in 0..2 {
                if let Some((first, last)) = range[axis] {
                    moved[axis] = if clipped[axis] {
                        first + (place[axis] - first).rem_euclid(last - first + 1)
                    } else {
                        place[axis].clamp(first, last)
                    };
                }
            }
            moved
        }
    }
}

/// Per axis, whether any of a plane's `members` lies on the output's edge there (never on
/// a mesh).
fn border_axes(level: &TargetLevel, members: &[u32]) -> [bool; 2] {
    let Neighbourhoods::Grid { width, height, wraps: false, .. } = level.neighbourhoods else {
        return [false; 2];
    };
    let on_edge = |v: u32, axis: usize| {
        let (at, side) = if axis == 0 { (v as usize % width, width) } else { (v as usize / width, height) };
        at == 0 || at + 1 == side
    };
    [0, 1].map(|axis| members.iter().any(|&v| on_edge(v, axis)))
}

/// Per vertex of `level` whose patch is `owner` (from [`patch_state`], inherited down the
/// levels through the parent links), the factor on its distance to any texel but its own:
/// `keep.move_cost` farther than `keep.depth` template radii along the surface from its
/// patch's edge, 1 nearer. Vertices with no neighbour in another patch anywhere count as
/// inside.
pub(crate) fn move_costs(level: &TargetLevel, owner: &[u32], keep: KeepInteriors) -> Vec<f32> {
    let depth = keep.depth * (level.template / 2) as f32;
    // Each vertex's steps are read when it is reached, not kept for the level as `Steps`
    // keeps them: on a 1024² plane's finest level those held 134 MB, half the peak.
    let (mut scratch, mut steps) = (Vec::new(), Vec::new());
    let mut distance = vec![f32::INFINITY; level.vertices];
    let mut queue: BinaryHeap<Entry> = BinaryHeap::new();
    for v in 0..level.vertices {
        steps_from(level, v, &mut scratch, &mut steps);
        if steps.iter().any(|&(u, _)| owner[u] != owner[v]) {
            distance[v] = 0.0;
            queue.push(Reverse((0, v as u32)));
        }
    }
    while let Some(Reverse((d, v))) = queue.pop() {
        let (d, v) = (f32::from_bits(d), v as usize);
        if d > distance[v] || d > depth {
            continue;
        }
        steps_from(level, v, &mut scratch, &mut steps);
        for &(u, length) in &steps {
            if d + length < distance[u] {
                distance[u] = d + length;
                queue.push(Reverse(((d + length).to_bits(), u as u32)));
            }
        }
    }
    distance.iter().map(|&d| if d > depth { keep.move_cost } else { 1.0 }).collect()
}

/// `v`'s steps on `level` (neighbour, length), the ones [`Steps`] keeps, into `out`.
fn steps_from(level: &TargetLevel, v: usize, scratch: &mut Vec<Shift>, out: &mut Vec<(usize, f32)>) {
    out.clear();
    let lengths =
        level.shifts_of(v, scratch).iter().filter_map(|&(u, o)| Some((u as usize, step_length(v, u, o)?)));
    out.extend(lengths);
}

/// The length of the step from `v` to its neighbour `u` at offset `o`, where patches grow
/// along it (not to itself, and no longer than [`STEP`]).
fn step_length(v: usize, u: u32, o: [f32; 2]) -> Option<f32> {
    let length = o[0].hypot(o[1]);
    (u as usize != v && length <= STEP).then_some(length)
}

/// Each vertex of `level` in its parent's patch.
pub(crate) fn inherit_owner(level: &TargetLevel, coarse_owner: &[u32]) -> Vec<u32> {
    level.parents.iter().map(|link| coarse_owner[link.vertex as usize]).collect()
}

/// Random places to try for a patch, besides those the seam suggests.
const RANDOM_PLACES: usize = 8;
/// Seam pairs whose predictions suggest places (spread along the seam).
const SUGGESTING_PAIRS: usize = 8;

/// Patches in the order they are placed: breadth-first over patch adjacency, so each one
/// after the first (of its connected part) borders some already placed.
fn seam_order(graph: &Steps, owner: &[u32], patches: usize) -> Vec<usize> {
    let mut adjacent = vec![Vec::new(); patches];
    for v in 0..graph.vertices() {
        for (u, _, _) in graph.neighbours(v) {
            let (a, b) = (owner[v] as usize, owner[u] as usize);
            if a != b && !adjacent[a].contains(&b) {
                adjacent[a].push(b);
            }
        }
    }
    let mut seen = vec![false; patches];
    let mut order = Vec::with_capacity(patches);
    for start in 0..patches {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        let mut queue = std::collections::VecDeque::from([start]);
        while let Some(p) = queue.pop_front() {
            order.push(p);
            for &q in &adjacent[p] {
                if !seen[q] {
                    seen[q] = true;
                    queue.push_back(q);
                }
            }
        }
    }
    order
}

/// The seam of a patch with the patches already placed: per member vertex next to a placed
/// one, the texel that neighbour predicts for it (its own texel shifted back by the offset).
fn seam_pairs(
    graph: &Steps,
    members: &[u32],
    owner: &[u32],
    places: &[Option<[i64; 2]>],
    uv: &[[i32; 2]],
    sample: &SampleLevel,
    margin: usize,
) -> Vec<(usize, [i32; 2])> {
    let mut seam = Vec::new();
    for &v in members {
        for (u, o, _) in graph.neighbours(v as usize) {
            if places[owner[u] as usize].is_some() {
                let [x, y] = uv[u];
                let predicted = sample.wrap_into_candidates(
                    (x as f32 - o[0]).round() as i64,
                    (y as f32 - o[1]).round() as i64,
                    margin,
                );
                seam.push((v as usize, predicted));
            }
        }
    }
    seam
}

/// Candidate places (the texel of the patch's seed) for a patch with `seam`.
fn placements(
    seam: &[(usize, [i32; 2])],
    position: &[[f32; 2]],
    sample: &SampleLevel,
    (margin, k): (usize, usize),
    rng: &mut ChaCha8Rng,
) -> Vec<[i64; 2]> {
    let mut out: Vec<[i64; 2]> =
        (0..RANDOM_PLACES).map(|_| random_texel(sample, margin, rng).map(i64::from)).collect();
    let step = seam.len().div_ceil(SUGGESTING_PAIRS).max(1);
    for &(v, [x, y]) in seam.iter().step_by(step) {
        let pixel = sample.candidate_pixel(x as i64, y as i64, margin);
        let o = position[v].map(|p| p.round() as i64);
        for &q in sample.list(pixel, k, false).iter().skip(1) {
            let (qx, qy) = ((q as usize % sample.width) as i64, (q as usize / sample.width) as i64);
            out.push([qx - o[0], qy - o[1]]);
        }
    }
    out
}

/// How hard [`Uses`] pushes patches towards the least-used parts of the sample: a place whose
/// footprint is already used at the fair share costs 1 + this times its seam. Measured on
/// eight 50²–100² samples (seeds 0–1): at 0, luma contrast 0.39–0.94 of the sample's (the
/// terra's cracks thinned to 0.79); at 1, 0.40–0.97; at 4, 0.41–0.98 (terra 0.86), for
/// repetition within ±0.004 and patch energy up to 1.3× (the 50² choc swirl).
const USE_STRENGTH: f32 = 4.0;

/// How often the patches placed so far use each texel of the sample level, so that a patch
/// goes where the sample has been used least (after the occurrence term of Kaspar et al.,
/// Self Tuning Texture Optimization, 2015, over the patch's whole footprint rather than per
/// texel). Without it the seam alone decides, and the seam is cheapest in the sample's
/// plainest parts: distinctive elements (a pine knot, a terra crack network) come out
/// rarer than in the sample, or not at all.
struct Uses {
    width: usize,
    count: Vec<u32>,
    /// Uses per candidate texel if the level's vertices were spread evenly over them.
    fair: f32,
}

impl Uses {
    fn new(sample: &SampleLevel, margin: usize, vertices: usize) -> Self {
        let band = sample.band(sample.width, margin) * sample.band(sample.height, margin);
        let fair = vertices as f32 / band as f32;
        Uses { width: sample.width, count: vec![0; sample.width * sample.height], fair }
    }

    /// The factor on a place's seam cost whose patch would cover `texels` (`n` of them):
    /// 1 + [`USE_STRENGTH`] × (mean uses of those texels over the fair share)².
    fn factor(&self, texels: impl Iterator<Item = [i32; 2]>, n: usize) -> f32 {
        let total: u64 =
            texels.map(|[x, y]| u64::from(self.count[y as usize * self.width + x as usize])).sum();
        let share = total as f32 / n.max(1) as f32 / self.fair.max(f32::MIN_POSITIVE);
        1.0 + USE_STRENGTH * share * share
    }

    fn add(&mut self, [x, y]: [i32; 2]) {
        self.count[y as usize * self.width + x as usize] += 1;
    }
}

/// The places at which a patch would merely continue a placed neighbour's copy: per seam
/// pair, the place that gives its vertex exactly the texel the neighbour predicts.
fn continuations(seam: &[(usize, [i32; 2])], position: &[[f32; 2]]) -> Vec<[i64; 2]> {
    let mut out: Vec<[i64; 2]> = seam
        .iter()
        .map(|&(v, [x, y])| {
            let o = position[v].map(|p| p.round() as i64);
            [i64::from(x) - o[0], i64::from(y) - o[1]]
        })
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// How far (in patch radii) a patch's place must lie from every continuation of its placed
/// neighbours. A place near a continuation (a kNN entry two texels from the predicted
/// texel, as most are on an organic sample) makes the patch a near copy of its neighbour's
/// piece slipped by a texel or two: patch after patch then rebuilds the whole band of the
/// sample, and the output is a lattice of near-whole copies at the band's period, the same
/// blotch every band width (issue: repetition at every sample size). Measured on six
/// organic 50²–100² samples (4× → their outputs, seeds 0–1), with the coarsest level of
/// [`super::session::coarsest_side_for`]: repetition 0.007–0.024 against 0.014–0.24
/// without, Resynthesizer 0.022–0.047.
pub const PLACE_APART: f32 = 1.0;

/// Drops the `candidates` within [`PLACE_APART`] patch radii of any of `continuations`
/// (distances wrap around the band the patches wrap around), unless that would drop them
/// all.
fn keep_apart(
    candidates: &mut Vec<[i64; 2]>,
    continuations: &[[i64; 2]],
    sample: &SampleLevel,
    (margin, patch_radius): (usize, f32),
) {
    let (bw, bh) = (sample.band(sample.width, margin) as i64, sample.band(sample.height, margin) as i64);
    let slip = |c: [i64; 2], t: [i64; 2]| {
        let (dx, dy) = ((c[0] - t[0]).rem_euclid(bw), (c[1] - t[1]).rem_euclid(bh));
        (dx.min(bw - dx) as f32).hypot(dy.min(bh - dy) as f32)
    };
    let apart = |&c: &[i64; 2]| continuations.iter().all(|&t| slip(c, t) >= PLACE_APART * patch_radius);
    if candidates.iter().any(apart) {
        candidates.retain(apart);
    }
}

/// The first pass of a finer level (Tong §5.1): each vertex's coordinate is twice its
/// parent's plus its offset from the parent, folded back into the sample where the offset
/// leads out of it; labels come from this level's texton map.
pub fn inherit(level: &TargetLevel, coarse: &State, sample: &SampleLevel, margin: usize) -> State {
    let uv = level
        .parents
        .iter()
        .map(|link| {
            let [cx, cy] = coarse.uv[link.vertex as usize];
            sample.fold_into_candidates(
                2 * cx as i64 + link.offset[0].round() as i64,
                2 * cy as i64 + link.offset[1].round() as i64,
                margin,
            )
        })
        .collect();
    with_labels(uv, sample)
}

/// `state` with every coordinate moved by its jitter (Lefebvre and Hoppe 2005 §3.2; see
/// [`super::recipe::Start::Jittered`]): per axis `floor(texels · u + ½)`, u uniform in
/// [−1, 1) from a hash of `seed`, the vertex and the axis, folded back into the sample's
/// candidate texels. Labels are read again at the new coordinates.
pub fn jitter(state: State, sample: &SampleLevel, margin: usize, texels: f32, seed: u64) -> State {
    let offset = |v: usize, axis: i64| {
        let u = 2.0 * crate::seeded::unit(seed, v as i64, axis, 0) - 1.0;
        (texels * u + 0.5).floor() as i64
    };
    let uv = (state.uv.iter().enumerate())
        .map(|(v, &[x, y])| {
            sample.fold_into_candidates(x as i64 + offset(v, 0), y as i64 + offset(v, 1), margin)
        })
        .collect();
    with_labels(uv, sample)
}

fn with_labels(uv: Vec<[i32; 2]>, sample: &SampleLevel) -> State {
    let labels = uv.iter().map(|&[x, y]| sample.label_at(x as i64, y as i64)).collect();
    State::new(labels, uv)
}

/// The level's short steps: per vertex the neighbours within [`STEP`] texels, with their
/// offsets and lengths (CSR).
struct Steps {
    start: Vec<u32>,
    steps: Vec<(u32, [f32; 2], f32)>,
}

/// A Dijkstra queue entry: distance (as ordered bits of a non-negative f32), vertex.
type Entry = Reverse<(u32, u32)>;

impl Steps {
    fn of(level: &TargetLevel) -> Self {
        let (mut start, mut steps, mut scratch) = (vec![0u32], Vec::new(), Vec::new());
        for v in 0..level.vertices {
            for &(u, o) in level.shifts_of(v, &mut scratch) {
                if let Some(length) = step_length(v, u, o) {
                    steps.push((u, o, length));
                }
            }
            start.push(steps.len() as u32);
        }
        Steps { start, steps }
    }

    fn neighbours(&self, v: usize) -> impl Iterator<Item = (usize, [f32; 2], f32)> + '_ {
        self.steps[self.start[v] as usize..self.start[v + 1] as usize]
            .iter()
            .map(|&(u, o, l)| (u as usize, o, l))
    }

    fn vertices(&self) -> usize {
        self.start.len() - 1
    }

    /// Vertices in random order become seeds unless already within `spacing` of one, so
    /// seeds end up at least `spacing` apart and every vertex within `spacing` of one.
    fn covered_within(
        &self,
        seed: usize,
        spacing: f32,
        covered: &mut [bool],
        distance: &mut [f32],
        touched: &mut Vec<usize>,
    ) {
        let mut queue: BinaryHeap<Entry> = BinaryHeap::new();
        distance[seed] = 0.0;
        touched.push(seed);
        queue.push(Reverse((0, seed as u32)));
        while let Some(Reverse((d, v))) = queue.pop() {
            let (d, v) = (f32::from_bits(d), v as usize);
            if d > distance[v] {
                continue;
            }
            covered[v] = true;
            for (u, _, length) in self.neighbours(v) {
                let next = d + length;
                if next <= spacing && next < distance[u] {
                    if distance[u] == f32::INFINITY {
                        touched.push(u);
                    }
                    distance[u] = next;
                    queue.push(Reverse((next.to_bits(), u as u32)));
                }
            }
        }
    }

    /// Per vertex its nearest seed (index into `seeds`) and its offset from that seed in
    /// texels, summed along the shortest path's steps.
    fn nearest_seed(&self, seeds: &[usize]) -> (Vec<u32>, Vec<[f32; 2]>) {
        let n = self.vertices();
        let (mut owner, mut position, mut distance) =
            (vec![u32::MAX; n], vec![[0.0f32; 2]; n], vec![f32::INFINITY; n]);
        let mut queue: BinaryHeap<Entry> = BinaryHeap::new();
        for (i, &s) in seeds.iter().enumerate() {
            owner[s] = i as u32;
            distance[s] = 0.0;
            queue.push(Reverse((0, s as u32)));
        }
        while let Some(Reverse((d, v))) = queue.pop() {
            let (d, v) = (f32::from_bits(d), v as usize);
            if d > distance[v] {
                continue;
            }
            for (u, o, length) in self.neighbours(v) {
                if d + length < distance[u] {
                    distance[u] = d + length;
                    owner[u] = owner[v];
                    position[u] = [position[v][0] + o[0], position[v][1] + o[1]];
                    queue.push(Reverse(((d + length).to_bits(), u as u32)));
                }
            }
        }
        // A vertex with no short steps at all (an isolated one) is a patch of its own.
        (owner.iter().map(|&o| if o == u32::MAX { 0 } else { o }).collect(), position)
    }
}

/// How much the seeds' spacing varies around the patch radius: each seed covers a random
/// radius in (1 ± this) × the patch radius. Seeds all one spacing apart tile the level
/// with patches of one size, a near-regular lattice the eye picks out (issue: repetition);
/// varied sizes keep the mean patch size and break the lattice.
const SPACING_SPREAD: f32 = 0.5;

/// Seeds covering every vertex (dart throwing on the graph), each one a random spacing
/// within [`SPACING_SPREAD`] of `spacing` from the seeds before it.
fn spread_seeds(graph: &Steps, spacing: f32, rng: &mut ChaCha8Rng) -> Vec<usize> {
    let n = graph.vertices();
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(rng);
    let (mut covered, mut distance, mut touched) = (vec![false; n], vec![f32::INFINITY; n], Vec::new());
    let mut seeds = Vec::new();
    for v in order {
        if covered[v] {
            continue;
        }
        seeds.push(v);
        let radius = spacing * rng.random_range(1.0 - SPACING_SPREAD..=1.0 + SPACING_SPREAD);
        graph.covered_within(v, radius, &mut covered, &mut distance, &mut touched);
        for &t in &touched {
            distance[t] = f32::INFINITY;
        }
        touched.clear();
    }
    seeds
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::engine::tests::periodic_sample;
    use crate::synth::target::grid_levels;
    use rand::SeedableRng;

    /// Jitter moves each axis by at most round(texels), moves nothing below half a texel,
    /// moves most vertices at one texel, and is a function of the seed alone.
    #[test]
    fn jitter_moves_within_its_amplitude_and_follows_the_seed() {
        let sample = periodic_sample(4);
        let uv: Vec<[i32; 2]> = (0..200i32).map(|v| [v % 16, v / 16 % 16]).collect();
        let state = with_labels(uv.clone(), &sample);
        let moved = |texels: f32, seed: u64| jitter(state.clone(), &sample, 2, texels, seed);
        assert_eq!(moved(0.45, 1).uv, uv);
        let one = moved(1.0, 1);
        assert_eq!(one.uv, moved(1.0, 1).uv);
        assert_ne!(one.uv, moved(1.0, 2).uv);
        // A tileable sample wraps, so a step of one texel may read as a step across it.
        let step = |a: i32, b: i32| (a - b).rem_euclid(16).min((b - a).rem_euclid(16));
        assert!(one.uv.iter().zip(&uv).all(|(a, b)| step(a[0], b[0]) <= 1 && step(a[1], b[1]) <= 1));
        let changed = one.uv.iter().zip(&uv).filter(|(a, b)| a != b).count();
        assert!(changed > 100, "{changed} of 200 moved");
        assert!(one.uv.iter().zip(&one.labels).all(|(&[x, y], &l)| l == sample.label_at(x as i64, y as i64)));
    }

    /// On a plane, patches come to within [`PLANE_EDGE_MARGIN`] of the edge of a sample that
    /// does not tile, so what lies along its edges (a brick sample's mortar courses) is
    /// copied too; a mesh's margin stays the template's radius.
    #[test]
    fn plane_patches_reach_the_sample_s_edge_band_and_mesh_patches_do_not() {
        use crate::synth::target::{Neighbourhoods, PLANE_EDGE_MARGIN};
        let mut sample = periodic_sample(4);
        sample.tileable = false;
        let plane = &grid_levels(40, 40, 1, 5, 3)[0];
        let mesh =
            Neighbourhoods::Mesh { template: 5, slots: Vec::new(), shift_start: vec![0], shifts: Vec::new() };
        assert_eq!(plane.candidate_margin(2), PLANE_EDGE_MARGIN);
        assert_eq!(TargetLevel::new(0, mesh).candidate_margin(2), 2);
        let metric = crate::synth::metric::GammaMetric { sample: &sample, template: 5 };
        let used = |margin: usize| {
            let PatchStart { state, .. } = patch_state(
                plane,
                &sample,
                &metric,
                (margin, 4.0, 4),
                Layout::default(),
                &mut ChaCha8Rng::seed_from_u64(7),
            );
            let xs = state.uv.iter().flat_map(|&[x, y]| [x, y]);
            (xs.clone().min().unwrap(), xs.max().unwrap())
        };
        let last = sample.width as i32 - 1;
        assert_eq!(used(PLANE_EDGE_MARGIN), (1, last - 1));
        assert_eq!(used(2), (2, last - 2));
    }

    /// A tileable sample of 8×8 tiles: joints (texton 0) on every eighth row and column, each
    /// tile's face one of textons 1–3.
    fn tiled_sample() -> SampleLevel {
        let mut sample = periodic_sample(4);
        for p in 0..sample.width * sample.height {
            let (x, y) = (p % sample.width, p / sample.width);
            let face = 1 + (x / 8 + 2 * (y / 8)) % 3;
            sample.labels[p] = if x % 8 == 0 || y % 8 == 0 { 0 } else { face as u16 };
        }
        sample
    }

    /// On a plane and a lattice sample every patch is one cell, copied whole periods from the
    /// cell centre, so every output texel is in phase with the sample and the joints run on:
    /// without the lattice, patches land at any phase.
    #[test]
    fn plane_patches_on_a_lattice_sample_are_whole_cells_in_phase() {
        let sample = tiled_sample();
        let plane = &grid_levels(40, 40, 1, 5, 3)[0];
        let metric = crate::synth::metric::GammaMetric { sample: &sample, template: 5 };
        let run = |lattice: Option<Lattice>, seed: u64| {
            let layout = Layout { own_edges: [false; 2], lattice };
            patch_state(plane, &sample, &metric, (2, 4.0, 4), layout, &mut ChaCha8Rng::seed_from_u64(seed))
        };
        let phases = |state: &State| {
            let mut phases: Vec<[i32; 2]> = (0..plane.vertices)
                .map(|v| {
                    let (x, y) = ((v % 40) as i32, (v / 40) as i32);
                    [(state.uv[v][0] - x).rem_euclid(8), (state.uv[v][1] - y).rem_euclid(8)]
                })
                .collect();
            phases.sort_unstable();
            phases.dedup();
            phases
        };
        // Texels from the nearest joint (every eighth row or column of the sample).
        let from_joint = |t: i32| t.rem_euclid(8).min(8 - t.rem_euclid(8));
        let lattice = Lattice { periods: [[8.0, 0.0], [0.0, 8.0]] };
        for seed in 0..4 {
            let PatchStart { state, owner, .. } = run(Some(lattice), seed);
            assert_eq!(phases(&state).len(), 1, "seed {seed}: {:?}", phases(&state));
            let patches = owner.iter().max().map_or(0, |&o| o as usize + 1);
            // Cells of 8×8 over 40×40 texels: 25, one more row and column where the random
            // phase cuts the grid's edges.
            assert!((25..=36).contains(&patches), "seed {seed}: {patches} patches");
            // Where two cells meet, the texels are on a joint or beside it: the cells' edges run
            // along the joints, so every tile is one patch's.
            for v in 0..plane.vertices {
                for (u, axis) in [(v + 1, 0), (v + 40, 1)] {
                    let inside = if axis == 0 { v % 40 < 39 } else { u < plane.vertices };
                    if inside && owner[u] != owner[v] {
                        assert!(from_joint(state.uv[v][axis]) <= 1, "seed {seed}: vertex {v} axis {axis}");
                    }
                }
            }
        }
        assert!((0..4).any(|seed| phases(&run(None, seed).state).len() > 1));
    }

    /// On a mesh the patches are not the lattice's cells, but each is placed in phase with
    /// its placed neighbours: on a flat mesh every vertex ends in one phase, so joints run on
    /// across every seam. Without the lattice the phases vary.
    #[test]
    fn mesh_patches_on_a_lattice_sample_are_placed_in_phase() {
        let sample = tiled_sample();
        let (mesh, frames) = crate::synth::surface::tests::flat_grid(40, 40, 1.0);
        let level = crate::synth::surface::surface_level(&mesh, &frames, 1.0, 5).expect("valid");
        let metric = crate::synth::metric::GammaMetric { sample: &sample, template: 5 };
        let phases = |lattice: Option<Lattice>, seed: u64| {
            let layout = Layout { own_edges: [false; 2], lattice };
            let PatchStart { state, .. } = patch_state(
                &level,
                &sample,
                &metric,
                (2, 6.0, 4),
                layout,
                &mut ChaCha8Rng::seed_from_u64(seed),
            );
            let mut phases: Vec<[i32; 2]> = (0..level.vertices)
                .map(|v| {
                    let (x, y) = ((v % 40) as i32, (v / 40) as i32);
                    [(state.uv[v][0] - x).rem_euclid(8), (state.uv[v][1] - y).rem_euclid(8)]
                })
                .collect();
            phases.sort_unstable();
            phases.dedup();
            phases.len()
        };
        let lattice = Lattice { periods: [[8.0, 0.0], [0.0, 8.0]] };
        for seed in 0..4 {
            assert_eq!(phases(Some(lattice), seed), 1, "seed {seed}");
        }
        assert!((0..4).any(|seed| phases(None, seed) > 1));
    }

    #[test]
    fn patches_copy_whole_pieces_with_their_offsets() {
        let mut sample = periodic_sample(4);
        sample.tileable = false;
        let level = &grid_levels(40, 40, 1, 5, 3)[0];
        let metric = crate::synth::metric::GammaMetric { sample: &sample, template: 5 };
        let PatchStart { state, owner, .. } = patch_state(
            level,
            &sample,
            &metric,
            (2, 4.0, 4),
            Layout::default(),
            &mut ChaCha8Rng::seed_from_u64(7),
        );
        // Right neighbours continue their patch (uv + (1, 0)) except across a seam; the seams
        // are a minority at this patch size.
        let coherent = (0..40 * 40)
            .filter(|&v| v % 40 < 39)
            .filter(|&v| state.uv[v + 1] == [state.uv[v][0] + 1, state.uv[v][1]])
            .count();
        assert!(coherent > 39 * 40 * 6 / 10, "{coherent} of {} coherent", 39 * 40);
        let inside = |&[x, y]: &[i32; 2]| (2..14).contains(&x) && (2..14).contains(&y);
        assert!(state.uv.iter().all(inside), "every coordinate is a candidate texel");
        let mut uses = [0usize; 256];
        state.uv.iter().for_each(|&[x, y]| uses[y as usize * 16 + x as usize] += 1);
        let interior: Vec<usize> =
            (2..14).flat_map(|y| (2..14).map(move |x| y * 16 + x)).map(|p| uses[p]).collect();
        let (lo, hi) = (interior.iter().min().unwrap(), interior.iter().max().unwrap());
        let mean = 40 * 40 / interior.len();
        assert!(*lo > 0 && *hi < 3 * mean, "placement uses the whole band evenly: {lo}..{hi} per texel");
        let distinct: std::collections::HashSet<_> = state.uv.iter().collect();
        assert!(distinct.len() > 100, "patches spread over the sample: {} texels", distinct.len());
        let inherited = inherit_owner(&grid_levels(80, 80, 2, 5, 3)[0], &owner);
        assert!(inherited.iter().enumerate().all(|(v, &o)| o == owner[(v / 80 / 2) * 40 + v % 80 / 2]));
    }

    /// A sample with edges of its own along x: a column at each end of its candidate band
    /// whose texton is unlike every other, and unlike each other (a board's dark and light
    /// edges).
    fn sample_with_side_edges() -> SampleLevel {
        let mut sample = periodic_sample(4);
        sample.tileable = false;
        let n = sample.textons;
        sample.gamma[4 * n + 4] = 9.0;
        (0..4).for_each(|i| (sample.gamma[4 * n + i], sample.gamma[i * n + 4]) = (0.0, 0.0));
        for y in 0..16 {
            sample.labels[y * 16 + 1] = 4;
            sample.labels[y * 16 + 14] = 0;
        }
        sample
    }

    #[test]
    fn own_edges_are_found_where_the_wrap_joins_unlike_texels_only() {
        let metric = |sample| crate::synth::metric::GammaMetric { sample, template: 5 };
        let edged = sample_with_side_edges();
        assert_eq!(own_edges(&edged, &metric(&edged), 1), [true, false]);
        let mut plain = periodic_sample(4);
        plain.tileable = false;
        assert_eq!(own_edges(&plain, &metric(&plain), 1), [false, false]);
        let mut tileable = edged.clone();
        tileable.tileable = true;
        assert_eq!(own_edges(&tileable, &metric(&tileable), 1), [false, false]);
    }

    /// Along an axis with edges of its own, no patch's copy wraps (it fits the band here);
    /// without, some do.
    #[test]
    fn patches_do_not_wrap_across_a_sample_s_own_edges() {
        let sample = sample_with_side_edges();
        let level = &grid_levels(40, 40, 1, 5, 3)[0];
        let metric = crate::synth::metric::GammaMetric { sample: &sample, template: 5 };
        let wrapped_steps = |edges: [bool; 2]| {
            let PatchStart { state, owner, .. } = patch_state(
                level,
                &sample,
                &metric,
                (1, 4.0, 4),
                Layout { own_edges: edges, lattice: None },
                &mut ChaCha8Rng::seed_from_u64(7),
            );
            (0..40 * 40)
                .filter(|&v| v % 40 < 39 && owner[v] == owner[v + 1])
                .filter(|&v| state.uv[v + 1][0] < state.uv[v][0])
                .count()
        };
        assert_eq!(wrapped_steps([true, false]), 0);
        assert!(wrapped_steps([false, false]) > 0);
    }

    /// A patch whose copy would wrap across the sample's own edge is moved the least, onto
    /// the edge; one the output's edge cuts wraps around the places that fit instead, so
    /// that no place (and no sample column along the output's side) gets all of them.
    #[test]
    fn a_patch_cut_by_the_output_s_edge_is_not_pinned_to_the_sample_s_edge() {
        let sample = sample_with_side_edges();
        let footprint = |clipped| Footprint { low: [-2, -2], high: [3, 2], clipped };
        // The band is columns 1–14, so places 3–11 keep the copy inside.
        let moved = |clipped| {
            let inside = footprint(clipped).inside(&sample, 1, [true, false]);
            (-8..24).map(|x| inside([x, 5])).collect::<Vec<_>>()
        };
        let count = |places: &[[i64; 2]], x: i64| places.iter().filter(|p| p[0] == x).count();
        let least = moved([false, false]);
        assert!(least.iter().all(|p| (3..=11).contains(&p[0]) && p[1] == 5), "{least:?}");
        // The 23 places outside, and 3 and 11 themselves.
        assert_eq!(count(&least, 3) + count(&least, 11), 25, "every place outside goes to an end");
        let wrapped = moved([true, false]);
        assert!(wrapped.iter().all(|p| (3..=11).contains(&p[0]) && p[1] == 5), "{wrapped:?}");
        assert!((3..=11).all(|x| (3..=4).contains(&count(&wrapped, x))), "{wrapped:?}");
    }

    /// A move costs more only deeper inside a patch than the depth (in radii of the 5×5
    /// template: 2.5 texels): a vertex beside another patch costs nothing more, and the
    /// costly ones are those farther from every other patch.
    #[test]
    fn moves_cost_more_only_deep_inside_patches() {
        let sample = periodic_sample(4);
        let level = &grid_levels(30, 30, 1, 5, 3)[0];
        let owner: Vec<u32> = (0..900).map(|v| u32::from(v % 30 >= 12)).collect();
        let keep = KeepInteriors { depth: 1.25, move_cost: 7.0 };
        let costs = move_costs(level, &owner, keep);
        for (v, &cost) in costs.iter().enumerate() {
            let from_edge = if v % 30 < 12 { 11 - v % 30 } else { v % 30 - 12 };
            let expected = if from_edge as f32 > 2.5 { 7.0 } else { 1.0 };
            assert_eq!(cost, expected, "vertex {v}, {from_edge} from the edge");
        }
        let metric = crate::synth::metric::GammaMetric { sample: &sample, template: 5 };
        let PatchStart { owner, .. } = patch_state(
            level,
            &sample,
            &metric,
            (2, 6.0, 4),
            Layout::default(),
            &mut ChaCha8Rng::seed_from_u64(3),
        );
        let inside = move_costs(level, &owner, keep).iter().filter(|&&c| c > 1.0).count();
        assert!((1..900 / 2).contains(&inside), "{inside} of 900 deep inside patches of radius 6");
    }
}
