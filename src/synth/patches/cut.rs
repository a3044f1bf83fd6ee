//! The minimum-error cut between two patches, through a band of faces along their border.
//!
//! Image quilting (Efros and Freeman 2001) overlaps two blocks and cuts the overlap where
//! their difference is least; graph-cut textures (Kwatra et al. 2003) make that cut a
//! minimum s–t cut. On the mesh, two patches that share a border overlap wherever one's
//! texture, continued rigidly over the other's faces (unfolded across their edges from
//! the shared border), stays inside the sample: within a few rings of faces either side of
//! the border both textures are defined. Each face of that band is given to one of the two
//! patches so that the jump summed over the edges where the labels change (and over the
//! band's edges to faces outside it) is least. Moving faces one at a time
//! (`borders::move_borders`) only drifts a border by a face where that alone lowers the
//! jump; the cut finds the border of least jump in the whole band at once.

use super::borders::edge_jump;
use super::chart::unfold;
use super::graph::NONE;
use super::mapper::{Mapper, Mapping};
use glam::Vec2;
use std::collections::{HashMap, VecDeque};

/// Rings of faces either side of a border that the cut may give to the other patch (on the
/// dragon, at 3–9 texels per face, 3 rings gave 1.85 on seed 0, 5 rings 1.83, 8 rings
/// 1.82, 12 rings 1.82; wider bands mostly reach past where a continuation stays inside
/// the sample).
const RINGS: usize = 8;

/// A cost no cut pays: a face whose texture is undefined under a label keeps the other.
const FORBIDDEN: f64 = 1e18;

/// Cuts every pair of neighbouring patches, the pairs of largest jump first; returns how
/// many faces changed patch.
pub(super) fn cut_borders(m: &Mapper, mapping: &mut Mapping) -> usize {
    border_pairs(m, mapping).into_iter().map(|(a, b)| cut_pair(m, mapping, a, b)).sum()
}

/// Each pair of patches that share an edge, by the jump summed along their border, largest
/// first.
fn border_pairs(m: &Mapper, mapping: &Mapping) -> Vec<(u32, u32)> {
    let graph = m.graph;
    let mut jumps: HashMap<(u32, u32), f32> = HashMap::new();
    for f in 0..graph.face_count() as u32 {
        for k in 0..3 {
            let g = graph.across[f as usize][k];
            if g == NONE || g < f {
                continue;
            }
            let (p, q) = (mapping.mapped_by[f as usize], mapping.mapped_by[g as usize]);
            if p == q || p == NONE || q == NONE {
                continue;
            }
            let uv = mapping.face_uv[f as usize];
            *jumps.entry((p.min(q), p.max(q))).or_default() +=
                shared_edge_jump(m, f, (uv[k], uv[(k + 1) % 3]), k, g, &mapping.face_uv[g as usize]);
        }
    }
    let mut pairs: Vec<((u32, u32), f32)> = jumps.into_iter().collect();
    pairs.sort_by(|x, y| y.1.total_cmp(&x.1).then(x.0.cmp(&y.0)));
    pairs.into_iter().map(|(p, _)| p).collect()
}

/// The jump along edge `k` of face `f` (its ends at `mine` there) against face `g`'s
/// coordinates `theirs` of the same two vertices.
fn shared_edge_jump(m: &Mapper, f: u32, mine: (Vec2, Vec2), k: usize, g: u32, theirs: &[Vec2; 3]) -> f32 {
    let graph = m.graph;
    let t = graph.corners[f as usize];
    match (graph.corner_of(g, t[k]), graph.corner_of(g, t[(k + 1) % 3])) {
        (Some(ga), Some(gb)) => edge_jump(&m.fitter.image, mine, (theirs[ga], theirs[gb])),
        _ => 0.0,
    }
}

/// Cuts the band between patches `a` and `b`; returns how many faces changed patch.
fn cut_pair(m: &Mapper, mapping: &mut Mapping, a: u32, b: u32) -> usize {
    let band = band(m, mapping, a, b);
    if band.is_empty() {
        return 0;
    }
    let under = [continuation(m, mapping, &band, a), continuation(m, mapping, &band, b)];
    let labels = min_cut(m, mapping, &band, &under);
    let mut moved = 0;
    for (i, &f) in band.iter().enumerate() {
        let (p, uv) = if labels[i] { (a, under[0][i]) } else { (b, under[1][i]) };
        if p != mapping.mapped_by[f as usize] {
            let Some(uv) = uv else { continue };
            mapping.mapped_by[f as usize] = p;
            mapping.face_uv[f as usize] = uv;
            moved += 1;
        }
    }
    moved
}

/// The faces of `a` and `b` (with area) within [`RINGS`] rings of their shared border,
/// breadth first from it.
fn band(m: &Mapper, mapping: &Mapping, a: u32, b: u32) -> Vec<u32> {
    let graph = m.graph;
    let of = |f: u32| mapping.mapped_by[f as usize];
    let either = |f: u32| graph.area[f as usize] > 0.0 && (of(f) == a || of(f) == b);
    let mut depth: HashMap<u32, usize> = HashMap::new();
    let mut queue = VecDeque::new();
    for f in 0..graph.face_count() as u32 {
        let across = graph.across[f as usize];
        if either(f) && across.iter().any(|&g| g != NONE && either(g) && of(g) != of(f)) {
            depth.insert(f, 0);
            queue.push_back(f);
        }
    }
    let mut order = Vec::new();
    while let Some(f) = queue.pop_front() {
        order.push(f);
        let d = depth[&f];
        if d + 1 >= RINGS {
            continue;
        }
        for &g in &graph.across[f as usize] {
            if g != NONE && either(g) && !depth.contains_key(&g) {
                depth.insert(g, d + 1);
                queue.push_back(g);
            }
        }
    }
    order
}

/// Per band face, patch `p`'s texture on it: its own coordinates on `p`'s faces, and on the
/// others `p`'s texture continued over them, face by face across their edges (a vertex
/// takes the coordinates `p`'s faces give it, else the first unfolding that reaches it).
/// None where a corner has two coordinates in `p`, the face would turn over or be
/// stretched to more than twice (or less than half) its area, or a corner leaves a sample
/// that does not tile.
fn continuation(m: &Mapper, mapping: &Mapping, band: &[u32], p: u32) -> Vec<Option<[Vec2; 3]>> {
    let graph = m.graph;
    // Per vertex, p's coordinate; None where p's faces disagree there.
    let mut at: HashMap<u32, Option<Vec2>> = HashMap::new();
    for &f in band {
        for &v in &graph.corners[f as usize] {
            for &g in graph.faces_of(v) {
                if mapping.mapped_by[g as usize] != p {
                    continue;
                }
                let Some(i) = graph.corner_of(g, v) else { continue };
                let uv = mapping.face_uv[g as usize][i];
                let entry = at.entry(v).or_insert(Some(uv));
                if entry.is_some_and(|c| c.distance(uv) > 1e-3) {
                    *entry = None;
                }
            }
        }
    }
    let mut out: Vec<Option<[Vec2; 3]>> = band
        .iter()
        .map(|&f| (mapping.mapped_by[f as usize] == p).then(|| mapping.face_uv[f as usize]))
        .collect();
    let mut settled: Vec<bool> = out.iter().map(Option::is_some).collect();
    loop {
        let mut progress = false;
        for (i, &f) in band.iter().enumerate() {
            if settled[i] {
                continue;
            }
            let t = graph.corners[f as usize];
            let known = t.map(|v| at.get(&v).copied());
            if known.iter().filter(|k| k.is_some()).count() < 2 {
                continue;
            }
            settled[i] = true;
            progress = true;
            out[i] = continue_over(m, mapping, f, known);
            if let Some(uv) = out[i] {
                for k in 0..3 {
                    at.entry(t[k]).or_insert(Some(uv[k]));
                }
            }
        }
        if !progress {
            return out;
        }
    }
}

/// Face `f`'s coordinates from those `known` at its corners (`Some(None)`: two
/// coordinates there), the one corner left over unfolded with the face's own lengths on
/// the side of its own winding; None where that fails the checks of [`continuation`].
fn continue_over(
    m: &Mapper,
    mapping: &Mapping,
    f: u32,
    known: [Option<Option<Vec2>>; 3],
) -> Option<[Vec2; 3]> {
    let graph = m.graph;
    let t = graph.corners[f as usize];
    if known.iter().any(|k| matches!(k, Some(None))) {
        return None;
    }
    let own = mapping.face_uv[f as usize];
    let sign = (own[1] - own[0]).perp_dot(own[2] - own[0]);
    let scale = m.params.texels_per_unit;
    let mut uv = known.map(|k| k.flatten().unwrap_or_default());
    if let Some(apex) = (0..3).find(|&i| known[i].is_none()) {
        let (k, l) = ((apex + 1) % 3, (apex + 2) % 3);
        let at = |i: usize| graph.positions[t[i] as usize];
        let (la, lb) = (at(k).distance(at(apex)) * scale, at(l).distance(at(apex)) * scale);
        uv[apex] = unfold(uv[k], uv[l], la, lb);
        if (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]) * sign < 0.0 {
            uv[apex] = unfold(uv[l], uv[k], lb, la);
        }
    }
    let area = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]);
    let surface = 2.0 * graph.area[f as usize] * scale * scale;
    let ratio = area.abs() / surface.max(f32::MIN_POSITIVE);
    let upright = area * sign > 0.0 && (0.5..=2.0).contains(&ratio);
    (upright && uv.iter().all(|&c| m.fitter.image.inside(c))).then_some(uv)
}

/// The labels (true: the first patch) of least total jump: along edges between band faces
/// of different labels, and along the band's edges to faces outside it, each face's
/// texture under its label against the outside face's own.
fn min_cut(m: &Mapper, mapping: &Mapping, band: &[u32], under: &[Vec<Option<[Vec2; 3]>>; 2]) -> Vec<bool> {
    let graph = m.graph;
    let index: HashMap<u32, usize> = band.iter().enumerate().map(|(i, &f)| (f, i)).collect();
    let (source, sink) = (band.len(), band.len() + 1);
    let mut net = Network::new(band.len() + 2);
    let edge = |uv: &[Vec2; 3], k: usize| (uv[k], uv[(k + 1) % 3]);
    for (i, &f) in band.iter().enumerate() {
        // Cost of each label against the outside; FORBIDDEN where the label is undefined.
        let mut outside = [0f64; 2];
        for k in 0..3 {
            let g = graph.across[f as usize][k];
            if g == NONE || mapping.mapped_by[g as usize] == NONE {
                continue;
            }
            if let Some(&j) = index.get(&g) {
                if j > i {
                    // Cut f|g with f on the first patch's side, then the other way round.
                    for (from, to, x, y) in [(i, j, 0, 1), (j, i, 1, 0)] {
                        if let (Some(uf), Some(ug)) = (under[x][i], under[y][j]) {
                            let cost = shared_edge_jump(m, f, edge(&uf, k), k, g, &ug);
                            net.add(from, to, f64::from(cost));
                        }
                    }
                }
                continue;
            }
            for (label, cost) in outside.iter_mut().enumerate() {
                if let Some(uv) = under[label][i] {
                    let theirs = &mapping.face_uv[g as usize];
                    *cost += f64::from(shared_edge_jump(m, f, edge(&uv, k), k, g, theirs));
                }
            }
        }
        for (label, cost) in outside.iter_mut().enumerate() {
            if under[label][i].is_none() {
                *cost = FORBIDDEN;
            }
        }
        // Cutting source → f puts f on the second patch's side, and pays its cost there.
        net.add(source, i, outside[1]);
        net.add(i, sink, outside[0]);
    }
    net.max_flow(source, sink);
    let reach = net.reachable(source);
    reach[..band.len()].to_vec()
}

/// A flow network for [`min_cut`] (Dinic's algorithm; a band holds a few hundred faces).
struct Network {
    /// Per node, its arcs: (head, residual capacity, index of the reverse arc in head's list).
    arcs: Vec<Vec<(usize, f64, usize)>>,
}

impl Network {
    fn new(nodes: usize) -> Network {
        Network { arcs: vec![Vec::new(); nodes] }
    }

    fn add(&mut self, from: usize, to: usize, capacity: f64) {
        let (r_from, r_to) = (self.arcs[to].len(), self.arcs[from].len());
        self.arcs[from].push((to, capacity, r_from));
        self.arcs[to].push((from, 0.0, r_to));
    }

    /// Nodes reachable from `from` through arcs with residual capacity.
    fn reachable(&self, from: usize) -> Vec<bool> {
        self.levels(from).iter().map(|l| l.is_some()).collect()
    }

    fn levels(&self, from: usize) -> Vec<Option<usize>> {
        let mut level = vec![None; self.arcs.len()];
        level[from] = Some(0);
        let mut queue = VecDeque::from([from]);
        while let Some(n) = queue.pop_front() {
            for &(to, capacity, _) in &self.arcs[n] {
                if capacity > 1e-12 && level[to].is_none() {
                    level[to] = level[n].map(|l| l + 1);
                    queue.push_back(to);
                }
            }
        }
        level
    }

    fn max_flow(&mut self, source: usize, sink: usize) {
        loop {
            let level = self.levels(source);
            if level[sink].is_none() {
                return;
            }
            let mut next = vec![0usize; self.arcs.len()];
            while self.push(source, sink, f64::INFINITY, &level, &mut next) > 0.0 {}
        }
    }

    /// One blocking-flow step of Dinic's: pushes up to `limit` from `n` to `sink` along
    /// arcs that go one level down.
    fn push(
        &mut self,
        n: usize,
        sink: usize,
        limit: f64,
        level: &[Option<usize>],
        next: &mut [usize],
    ) -> f64 {
        if n == sink {
            return limit;
        }
        while next[n] < self.arcs[n].len() {
            let (to, capacity, rev) = self.arcs[n][next[n]];
            let down = level[to].is_some() && level[to] == level[n].map(|l| l + 1);
            if capacity > 1e-12 && down {
                let pushed = self.push(to, sink, limit.min(capacity), level, next);
                if pushed > 0.0 {
                    self.arcs[n][next[n]].1 -= pushed;
                    self.arcs[to][rev].1 += pushed;
                    return pushed;
                }
            }
            next[n] += 1;
        }
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::super::borders::tests::NoisePlane;
    use super::*;

    /// A plane in three strips: the outer two carry one rigid map, the middle one the same
    /// texture shifted (noise, so the shift agrees with it nowhere), as a patch of its own
    /// two squares wide. The band between the first strip and the middle one reaches the
    /// third strip, which agrees with the first strip's texture continued: the cut of least
    /// jump gives the whole middle strip to the first patch, several faces deep, and no seam
    /// is left. (Moving single faces needs a face whose move alone lowers the jump.)
    #[test]
    fn a_misplaced_strip_is_cut_away_whole() {
        let plane = NoisePlane::new(8);
        let (graph, m) = (&plane.graph, plane.mapper());
        let map = |v: u32| plane.texel(v);
        let strip = |f: usize| {
            let x = graph.corners[f].iter().map(|&v| graph.positions[v as usize].x).sum::<f32>() / 3.0;
            u32::from(x > 0.375) + u32::from(x > 0.625)
        };
        let mut mapping = Mapping::new(graph.face_count());
        for f in 0..graph.face_count() {
            mapping.mapped_by[f] = strip(f);
            let shift = if strip(f) == 1 { Vec2::new(3.0, 2.0) } else { Vec2::ZERO };
            mapping.face_uv[f] = graph.corners[f].map(|v| map(v) + shift);
        }
        let middle = (0..graph.face_count()).filter(|&f| strip(f) == 1).count();
        assert!(middle >= 32, "{middle} faces in the middle strip");

        assert_eq!(cut_borders(&m, &mut mapping), middle);
        for f in 0..graph.face_count() {
            assert_ne!(mapping.mapped_by[f], 1, "face {f}");
            let want = graph.corners[f].map(map);
            let uv = mapping.face_uv[f];
            assert!(uv.iter().zip(want).all(|(got, want)| got.distance(want) < 1e-3), "face {f}: {uv:?}");
        }
    }
}
