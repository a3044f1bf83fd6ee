//! Local relaxation along a cluster's textured borders (Soler et al. §4.4): once a cluster
//! is placed, the sample coordinates of its border vertices are moved a little, in texture
//! space, to lessen the difference between its texture and its neighbours' along each
//! shared edge; the neighbours never move.
//!
//! The difference at a border vertex is the sum, at about one point per texel along its
//! shared border edges, of the squared difference (in the fitting space) between the two
//! sides' texture at that point, weighted by the vertex's share of the point (1 at the
//! vertex, 0 at the edge's other end: the paper's hat function). The search is the paper's
//! greedy one: random moves within a radius that halves each round (2, 1, ½ texel), a move
//! kept only if it lowers the difference. The paper spreads a move through its recursive
//! coordinates; here the moves spread into the cluster as a harmonic field (Jacobi sweeps
//! with the border held), and are scaled back if a face would fold.

use super::chart::Chart;
use super::graph::NONE;
use super::mapper::{Mapper, Mapping};
use glam::Vec2;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::collections::HashMap;

/// Moves tried per vertex per round.
const TRIES: usize = 8;
/// Search radius of the first round, in texels.
const RADIUS: f32 = 2.0;

/// One shared border edge: the cluster's two vertices (indices in the chart) and the
/// neighbour's coordinates at each.
struct Shared {
    a: usize,
    b: usize,
    theirs: [Vec2; 2],
}

/// The edges cluster `c` shares with textured faces outside it, with the neighbours'
/// coordinates at their ends.
fn shared_edges(m: &Mapper, c: u32, chart: &Chart, mapping: &Mapping) -> Vec<Shared> {
    let (graph, h) = (m.graph, m.hierarchy);
    let cluster = &h.clusters[c as usize];
    let owner = &h.owner[cluster.level as usize];
    let index = |v: u32| chart.vertices.binary_search_by_key(&v, |&(w, _)| w).ok();
    let mut shared = Vec::new();
    for &f in &cluster.faces {
        let t = graph.corners[f as usize];
        for k in 0..3 {
            let g = graph.across[f as usize][k];
            if g == NONE || owner[g as usize] == c || mapping.mapped_by[g as usize] == NONE {
                continue;
            }
            let (va, vb) = (t[k], t[(k + 1) % 3]);
            let (Some(a), Some(b), Some(ka), Some(kb)) =
                (index(va), index(vb), graph.corner_of(g, va), graph.corner_of(g, vb))
            else {
                continue;
            };
            let theirs = mapping.face_uv[g as usize];
            shared.push(Shared { a, b, theirs: [theirs[ka], theirs[kb]] });
        }
    }
    shared
}

/// The output fitting error of §4.4 for cluster `c` with coordinates `uv` (per chart
/// vertex): the mean squared difference (in the fitting space) between its texture and its
/// textured neighbours' at about one point per texel along every shared edge, as a
/// fraction of two random texels' (2 in that space). None without a shared edge.
pub(super) fn output_error(m: &Mapper, c: u32, chart: &Chart, uv: &[Vec2], mapping: &Mapping) -> Option<f32> {
    let image = &m.fitter.image;
    let (mut mine, mut theirs) = (vec![0f32; image.channels], vec![0f32; image.channels]);
    let (mut total, mut n) = (0f64, 0usize);
    for s in shared_edges(m, c, chart, mapping) {
        let (ua, ub) = (uv[s.a], uv[s.b]);
        let steps = (ua.distance(ub).max(s.theirs[0].distance(s.theirs[1])).ceil() as usize).clamp(2, 64);
        for i in 0..=steps {
            let t = i as f32 / steps as f32;
            image.sample(ua.lerp(ub, t), &mut mine);
            image.sample(s.theirs[0].lerp(s.theirs[1], t), &mut theirs);
            total += f64::from(mine.iter().zip(&theirs).map(|(a, b)| (a - b) * (a - b)).sum::<f32>());
            n += 1;
        }
    }
    (n > 0).then(|| (total / n as f64 / 2.0) as f32)
}

/// Relaxes the coordinates `uv` (per chart vertex) of cluster `c`.
pub(super) fn relax(
    m: &Mapper,
    c: u32,
    chart: &Chart,
    uv: &mut [Vec2],
    mapping: &Mapping,
    rng: &mut ChaCha8Rng,
) {
    let shared = shared_edges(m, c, chart, mapping);
    if shared.is_empty() {
        return;
    }
    let mut edges_of: HashMap<usize, Vec<usize>> = HashMap::new();
    for (e, s) in shared.iter().enumerate() {
        edges_of.entry(s.a).or_default().push(e);
        edges_of.entry(s.b).or_default().push(e);
    }
    let mut movers: Vec<usize> = edges_of.keys().copied().collect();
    movers.sort_unstable();
    let image = &m.fitter.image;
    let channels = image.channels;
    let (mut mine_v, mut theirs_v) = (vec![0f32; channels], vec![0f32; channels]);
    // The weighted difference at vertex `v` with the current coordinates but `at` for v.
    let mut cost = |v: usize, at: Vec2, uv: &[Vec2]| -> f32 {
        let mut total = 0.0;
        for &e in &edges_of[&v] {
            let s = &shared[e];
            let (ua, ub) = if s.a == v { (at, uv[s.b]) } else { (uv[s.a], at) };
            let steps = (ua.distance(ub).max(s.theirs[0].distance(s.theirs[1])).ceil() as usize).clamp(2, 64);
            for i in 0..=steps {
                let t = i as f32 / steps as f32;
                let weight = if s.a == v { 1.0 - t } else { t };
                if weight <= 0.0 {
                    continue;
                }
                image.sample(ua.lerp(ub, t), &mut mine_v);
                image.sample(s.theirs[0].lerp(s.theirs[1], t), &mut theirs_v);
                let d: f32 = mine_v.iter().zip(&theirs_v).map(|(a, b)| (a - b) * (a - b)).sum();
                total += weight * d;
            }
        }
        total
    };
    let original: Vec<Vec2> = movers.iter().map(|&v| uv[v]).collect();
    let mut radius = RADIUS;
    let mut work = uv.to_vec();
    for _ in 0..3 {
        for &v in &movers {
            let mut best = (cost(v, work[v], &work), work[v]);
            for _ in 0..TRIES {
                let angle = rng.random_range(0.0..std::f32::consts::TAU);
                let r = radius * rng.random::<f32>().sqrt();
                let at = work[v] + r * Vec2::from_angle(angle);
                if !image.inside(at) {
                    continue;
                }
                let e = cost(v, at, &work);
                if e < best.0 {
                    best = (e, at);
                }
            }
            work[v] = best.1;
        }
        radius *= 0.5;
    }
    let moves: Vec<(usize, Vec2)> = movers
        .iter()
        .zip(&original)
        .map(|(&v, &o)| (v, work[v] - o))
        .filter(|(_, d)| d.length_squared() > 0.0)
        .collect();
    if moves.is_empty() {
        return;
    }
    spread(m, c, chart, uv, &moves);
}

/// Adds the border `moves` (chart vertex, displacement) to `uv`, spread into the cluster
/// as a harmonic field; halves them (up to three times) where a face would fold or a
/// coordinate leave a sample that does not tile (a continuation may lie against its edge).
fn spread(m: &Mapper, c: u32, chart: &Chart, uv: &mut [Vec2], moves: &[(usize, Vec2)]) {
    let image = &m.fitter.image;
    let cluster = &m.hierarchy.clusters[c as usize];
    let n = chart.vertices.len();
    let mut fixed = vec![false; n];
    let index = |v: u32| chart.vertices.binary_search_by_key(&v, |&(w, _)| w).ok();
    for &v in &cluster.border {
        if let Some(i) = index(v) {
            fixed[i] = true;
        }
    }
    let mut field = vec![Vec2::ZERO; n];
    for &(v, d) in moves {
        field[v] = d;
        fixed[v] = true;
    }
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
    for t in &chart.corners {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            neighbours[a as usize].push(b);
            neighbours[b as usize].push(a);
        }
    }
    for _ in 0..30 {
        let previous = field.clone();
        for i in 0..n {
            if fixed[i] || neighbours[i].is_empty() {
                continue;
            }
            let sum: Vec2 = neighbours[i].iter().map(|&j| previous[j as usize]).sum();
            field[i] = sum / neighbours[i].len() as f32;
        }
    }
    let signed = |p: &[Vec2], t: &[u32; 3]| {
        let [a, b, d] = t.map(|i| p[i as usize]);
        (b - a).perp_dot(d - a)
    };
    let mut scale = 1.0;
    for _ in 0..4 {
        let moved: Vec<Vec2> = uv.iter().zip(&field).map(|(&p, &d)| p + scale * d).collect();
        let folds = chart.corners.iter().any(|t| {
            let before = signed(uv, t);
            let after = signed(&moved, t);
            before != 0.0 && after * before <= 0.0
        });
        let outside = moved.iter().zip(uv.iter()).any(|(&p, &q)| !image.inside(p) && image.inside(q));
        if !folds && !outside {
            uv.copy_from_slice(&moved);
            return;
        }
        scale *= 0.5;
    }
}
