//! The face-cluster hierarchy (Soler et al. §3.1, "general mesh hierarchies"): level 0 is
//! each connected piece of the surface; every cluster is split into sub-clusters grown from
//! seed faces, each face joining the growing region whose seed is nearest (Dijkstra over
//! face centroids), until every cluster is one face. Every level partitions the surface.
//!
//! Below level 0 every cluster is a topological disc: a region that is not (an annulus, a
//! region wrapped around a handle, a pinched one) is split in two again until its pieces
//! are. Borders are regularised by handing a face over to the neighbour that holds two of
//! its three edges, where both stay discs. The *control vertices* of a cluster are the points
//! of its border shared by three or more regions of its level (the outside of an open
//! surface counting as one); a cluster with fewer than three, or with one stretch of border
//! longer than a third of its perimeter, gets more, spread along the border.
//!
//! Seeds are spread by farthest-point sampling from a random first face, then moved to
//! their regions' centres and grown again a few times (Lloyd's iteration) so that regions
//! of a level have nearly the same size (the paper draws them at random and checks the
//! non-alignment of the resulting control polygons; spread seeds give round regions, whose
//! polygons are not flat).

use super::graph::{SurfaceGraph, NONE};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Each cluster splits into about this many sub-clusters (by area).
pub const BRANCHING: f64 = 4.0;

/// One region of one level.
#[derive(Clone, Debug)]
pub struct Cluster {
    /// Its level, 0 the coarsest.
    pub level: u32,
    /// The cluster of the level above, or `NONE` on level 0.
    pub parent: u32,
    /// Its sub-clusters on the next level (none for a single face).
    pub children: Vec<u32>,
    /// Graph faces.
    pub faces: Vec<u32>,
    /// Clusters of the same level across its border.
    pub neighbours: Vec<u32>,
    /// Whether it is a topological disc (only level-0 clusters may not be).
    pub disc: bool,
    /// Its border as a loop of graph vertices, counter-clockwise seen from outside (a disc's;
    /// empty otherwise). A single face's border is its three corners in order.
    pub border: Vec<u32>,
    /// Positions in `border` of its control vertices, increasing.
    pub controls: Vec<u32>,
    /// Surface area.
    pub area: f64,
}

impl Cluster {
    /// The control vertices as graph vertices.
    pub fn control_vertices(&self) -> impl Iterator<Item = u32> + '_ {
        self.controls.iter().map(|&k| self.border[k as usize])
    }

    /// Whether this is one face.
    pub fn is_face(&self) -> bool {
        self.faces.len() == 1
    }
}

/// The hierarchy: clusters, the clusters of each level, and per level which cluster holds
/// each face.
#[derive(Clone, Debug)]
pub struct Hierarchy {
    /// Every cluster of every level.
    pub clusters: Vec<Cluster>,
    /// Per level, coarsest first, its clusters (indices into `clusters`).
    pub levels: Vec<Vec<u32>>,
    /// `owner[l][f]`: the cluster of level l holding graph face f.
    pub owner: Vec<Vec<u32>>,
}

impl Hierarchy {
    /// Builds the hierarchy of `graph`, drawing the first seed of each split from `rng`.
    pub fn build(graph: &SurfaceGraph, rng: &mut ChaCha8Rng) -> Hierarchy {
        let (label, count) = graph.components();
        let mut roots: Vec<Vec<u32>> = vec![Vec::new(); count];
        for (f, &c) in label.iter().enumerate() {
            roots[c as usize].push(f as u32);
        }
        let mut h = Hierarchy { clusters: Vec::new(), levels: Vec::new(), owner: Vec::new() };
        let mut scratch = Scratch::new(graph);
        let root_area: Vec<f64> = roots.iter().map(|faces| area(graph, faces)).collect();
        let mut level: Vec<u32> = Vec::new();
        let mut root_of: Vec<u32> = Vec::new();
        for (r, faces) in roots.into_iter().enumerate() {
            level.push(h.push(graph, 0, NONE, faces));
            root_of.push(r as u32);
        }
        h.finish_level(graph, &level, &mut scratch);
        h.levels.push(level);
        let mut l = 0;
        while h.levels[l].iter().any(|&c| !h.clusters[c as usize].is_face()) {
            let target = |root: u32| root_area[root as usize] / BRANCHING.powi(l as i32 + 1);
            let mut next = Vec::new();
            let mut next_root = Vec::new();
            for (i, &c) in h.levels[l].clone().iter().enumerate() {
                let faces = h.clusters[c as usize].faces.clone();
                let regions = if faces.len() == 1 {
                    vec![faces]
                } else {
                    let n = (h.clusters[c as usize].area / target(root_of[i])).round().max(2.0) as usize;
                    if faces.len() <= 4 || 2 * n > faces.len() {
                        faces.iter().map(|&f| vec![f]).collect()
                    } else {
                        split(graph, &faces, n, rng, &mut scratch)
                    }
                };
                for region in regions {
                    let child = h.push(graph, l as u32 + 1, c, region);
                    h.clusters[c as usize].children.push(child);
                    next.push(child);
                    next_root.push(root_of[i]);
                }
            }
            h.finish_level(graph, &next, &mut scratch);
            h.levels.push(next);
            root_of = next_root;
            l += 1;
        }
        h
    }

    fn push(&mut self, graph: &SurfaceGraph, level: u32, parent: u32, faces: Vec<u32>) -> u32 {
        let area = area(graph, &faces);
        self.clusters.push(Cluster {
            level,
            parent,
            children: Vec::new(),
            faces,
            neighbours: Vec::new(),
            disc: false,
            border: Vec::new(),
            controls: Vec::new(),
            area,
        });
        (self.clusters.len() - 1) as u32
    }

    /// Owners, neighbours, borders and control vertices of a level's clusters.
    fn finish_level(&mut self, graph: &SurfaceGraph, level: &[u32], scratch: &mut Scratch) {
        let mut owner = vec![NONE; graph.face_count()];
        for &c in level {
            for &f in &self.clusters[c as usize].faces {
                owner[f as usize] = c;
            }
        }
        for &c in level {
            let cluster = &self.clusters[c as usize];
            let mut neighbours: Vec<u32> = cluster
                .faces
                .iter()
                .flat_map(|&f| graph.across[f as usize])
                .filter(|&g| g != NONE && owner[g as usize] != c)
                .map(|g| owner[g as usize])
                .collect();
            neighbours.sort_unstable();
            neighbours.dedup();
            let (disc, border, controls) = if cluster.is_face() {
                (true, graph.corners[cluster.faces[0] as usize].to_vec(), vec![0, 1, 2])
            } else {
                match disc_border(graph, &cluster.faces, scratch) {
                    Some(border) => {
                        let controls = control_vertices(graph, &border, &owner);
                        (true, border, controls)
                    }
                    None => (false, Vec::new(), Vec::new()),
                }
            };
            let cluster = &mut self.clusters[c as usize];
            cluster.neighbours = neighbours;
            cluster.disc = disc;
            cluster.border = border;
            cluster.controls = controls;
        }
        self.owner.push(owner);
    }
}

fn area(graph: &SurfaceGraph, faces: &[u32]) -> f64 {
    faces.iter().map(|&f| f64::from(graph.area[f as usize])).sum()
}

/// Per-face and per-vertex arrays reused by every region operation, stamped with a
/// generation instead of cleared.
struct Scratch {
    generation: u32,
    face_stamp: Vec<u32>,
    /// Per face in the current set: its region.
    region: Vec<u32>,
    dist: Vec<f32>,
    vertex_stamp: Vec<u32>,
    vertex_count: Vec<u32>,
    next: Vec<u32>,
}

impl Scratch {
    fn new(graph: &SurfaceGraph) -> Scratch {
        let (f, v) = (graph.face_count(), graph.vertex_count());
        Scratch {
            generation: 0,
            face_stamp: vec![0; f],
            region: vec![NONE; f],
            dist: vec![0.0; f],
            vertex_stamp: vec![0; v],
            vertex_count: vec![0; v],
            next: vec![NONE; v],
        }
    }

    /// Starts a new generation with `faces` as the current set.
    fn mark(&mut self, faces: &[u32]) {
        self.generation += 1;
        for &f in faces {
            self.face_stamp[f as usize] = self.generation;
            self.region[f as usize] = 0;
            self.dist[f as usize] = f32::INFINITY;
        }
    }

    fn contains(&self, f: u32) -> bool {
        f != NONE && self.face_stamp[f as usize] == self.generation
    }
}

/// A (distance, face) for Dijkstra's min-heap.
#[derive(Clone, Copy, PartialEq)]
struct Entry(f32, u32);

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then_with(|| other.1.cmp(&self.1))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Dijkstra over the faces of the current set from `seed`, improving `dist` and giving the
/// faces it improves region `label` (so, run once per seed, every face ends in the region
/// of its nearest seed, and each region is connected through its faces).
fn grow_from(graph: &SurfaceGraph, seed: u32, label: u32, s: &mut Scratch) {
    let mut heap = BinaryHeap::new();
    s.dist[seed as usize] = 0.0;
    s.region[seed as usize] = label;
    heap.push(Entry(0.0, seed));
    while let Some(Entry(d, f)) = heap.pop() {
        if d > s.dist[f as usize] {
            continue;
        }
        for &g in &graph.across[f as usize] {
            if !s.contains(g) {
                continue;
            }
            let nd = d + graph.centroid[f as usize].distance(graph.centroid[g as usize]);
            if nd < s.dist[g as usize] {
                s.dist[g as usize] = nd;
                s.region[g as usize] = label;
                heap.push(Entry(nd, g));
            }
        }
    }
}

/// Splits the connected `faces` into about `n` disc regions (see the module documentation).
fn split(
    graph: &SurfaceGraph,
    faces: &[u32],
    n: usize,
    rng: &mut ChaCha8Rng,
    s: &mut Scratch,
) -> Vec<Vec<u32>> {
    let mut regions = grow(graph, faces, n, rng, s);
    if regions.len() < 2 {
        // Faces that cannot be told apart by distance (repeated faces): one each.
        return faces.iter().map(|&f| vec![f]).collect();
    }
    regularise(graph, &mut regions, s);
    let mut out = Vec::new();
    for region in regions {
        discs(graph, region, rng, s, &mut out, 0);
    }
    out
}

/// `n` regions grown from farthest-point seeds.
fn grow(
    graph: &SurfaceGraph,
    faces: &[u32],
    n: usize,
    rng: &mut ChaCha8Rng,
    s: &mut Scratch,
) -> Vec<Vec<u32>> {
    s.mark(faces);
    let mut seed = faces[rng.random_range(0..faces.len())];
    for label in 0..n.min(faces.len()) as u32 {
        grow_from(graph, seed, label, s);
        // The next seed is the face farthest from every seed so far.
        let far = faces
            .iter()
            .copied()
            .max_by(|&a, &b| s.dist[a as usize].total_cmp(&s.dist[b as usize]).then_with(|| b.cmp(&a)));
        match far {
            Some(f) if s.dist[f as usize] > 0.0 => seed = f,
            _ => break,
        }
    }
    let mut regions = collect_regions(faces, s);
    // Farthest-point seeds leave the first seed's region and those in corners far larger
    // than the rest; moving each seed to its region's centre and growing again (Lloyd's
    // iteration) evens them out, as the paper asks ("a nearly uniform region size").
    for _ in 0..LLOYD_ROUNDS {
        if regions.len() < 2 {
            break;
        }
        let seeds: Vec<u32> = regions.iter().map(|r| central_face(graph, r)).collect();
        s.mark(faces);
        for (label, &seed) in seeds.iter().enumerate() {
            grow_from(graph, seed, label as u32, s);
        }
        regions = collect_regions(faces, s);
    }
    regions
}

/// Rounds of seed re-centring in [`grow`].
const LLOYD_ROUNDS: usize = 3;

/// The faces of the current set by region label, empty regions dropped.
fn collect_regions(faces: &[u32], s: &Scratch) -> Vec<Vec<u32>> {
    let count = faces.iter().map(|&f| s.region[f as usize]).max().unwrap_or(0) as usize + 1;
    let mut regions = vec![Vec::new(); count];
    for &f in faces {
        regions[s.region[f as usize] as usize].push(f);
    }
    regions.retain(|r| !r.is_empty());
    regions
}

/// The face of `region` whose centroid is nearest the region's area-weighted centroid.
fn central_face(graph: &SurfaceGraph, region: &[u32]) -> u32 {
    let (sum, weight) = region.iter().fold((glam::DVec3::ZERO, 0f64), |(p, w), &f| {
        let a = f64::from(graph.area[f as usize]).max(1e-30);
        (p + graph.centroid[f as usize].as_dvec3() * a, w + a)
    });
    let centre = (sum / weight).as_vec3();
    region
        .iter()
        .copied()
        .min_by(|&a, &b| {
            let d = |f: u32| graph.centroid[f as usize].distance_squared(centre);
            d(a).total_cmp(&d(b)).then(a.cmp(&b))
        })
        .unwrap_or(region[0])
}

/// Hands a face to the region holding two or three of its edges' neighbours when both
/// regions stay discs (two passes).
fn regularise(graph: &SurfaceGraph, regions: &mut [Vec<u32>], s: &mut Scratch) {
    let all: Vec<u32> = regions.iter().flatten().copied().collect();
    for _ in 0..2 {
        s.mark(&all);
        for (r, region) in regions.iter().enumerate() {
            for &f in region {
                s.region[f as usize] = r as u32;
            }
        }
        let mut moves: Vec<(u32, u32, u32)> = Vec::new();
        for (r, region) in regions.iter().enumerate() {
            if region.len() < 3 {
                continue;
            }
            for &f in region {
                let others: Vec<u32> = graph.across[f as usize]
                    .iter()
                    .filter(|&&g| s.contains(g) && s.region[g as usize] != r as u32)
                    .map(|&g| s.region[g as usize])
                    .collect();
                if others.len() >= 2 && others.iter().all(|&o| o == others[0]) {
                    moves.push((f, r as u32, others[0]));
                }
            }
        }
        if moves.is_empty() {
            return;
        }
        for (f, from, to) in moves {
            let (from, to) = (from as usize, to as usize);
            let Some(i) = regions[from].iter().position(|&g| g == f) else { continue };
            if regions[from].len() < 2 {
                continue;
            }
            regions[from].swap_remove(i);
            regions[to].push(f);
            let keeps = |region: &[u32], s: &mut Scratch| disc_border(graph, region, s).is_some();
            let (a, b) = (regions[from].clone(), regions[to].clone());
            if !(keeps(&a, s) && keeps(&b, s)) {
                regions[to].pop();
                regions[from].push(f);
            }
        }
        for region in regions.iter_mut() {
            region.sort_unstable();
        }
    }
}

/// Splits `region` in two until every piece is a disc, appending the pieces to `out`.
fn discs(
    graph: &SurfaceGraph,
    region: Vec<u32>,
    rng: &mut ChaCha8Rng,
    s: &mut Scratch,
    out: &mut Vec<Vec<u32>>,
    depth: u32,
) {
    if region.len() == 1 || disc_border(graph, &region, s).is_some() {
        out.push(region);
        return;
    }
    if depth > 24 {
        out.extend(region.into_iter().map(|f| vec![f]));
        return;
    }
    for piece in grow(graph, &region, 2, rng, s) {
        discs(graph, piece, rng, s, out, depth + 1);
    }
}

/// The border of `faces` as a counter-clockwise vertex loop if the faces form a
/// topological disc: connected, Euler characteristic 1, every border vertex on exactly
/// two border edges, and the border one loop.
fn disc_border(graph: &SurfaceGraph, faces: &[u32], s: &mut Scratch) -> Option<Vec<u32>> {
    s.mark(faces);
    let generation = s.generation;
    let (mut vertices, mut border_edges, mut inner_halves) = (0i64, 0i64, 0i64);
    let mut first = NONE;
    for &f in faces {
        let c = graph.corners[f as usize];
        for &corner in &c {
            let v = corner as usize;
            if s.vertex_stamp[v] != generation {
                s.vertex_stamp[v] = generation;
                s.vertex_count[v] = 0;
                vertices += 1;
            }
        }
        for k in 0..3 {
            if s.contains(graph.across[f as usize][k]) {
                inner_halves += 1;
            } else {
                let (a, b) = (c[k], c[(k + 1) % 3]);
                border_edges += 1;
                s.vertex_count[a as usize] += 1;
                s.vertex_count[b as usize] += 1;
                s.next[a as usize] = b;
                if first == NONE {
                    first = a;
                }
            }
        }
    }
    let edges = border_edges + inner_halves / 2;
    if border_edges == 0 || vertices - edges + faces.len() as i64 != 1 {
        return None;
    }
    for &f in faces {
        for &v in &graph.corners[f as usize] {
            let n = s.vertex_count[v as usize];
            if n != 0 && n != 2 {
                return None;
            }
        }
    }
    let mut border = vec![first];
    let mut v = s.next[first as usize];
    while v != first {
        if border.len() as i64 > border_edges {
            return None;
        }
        border.push(v);
        v = s.next[v as usize];
    }
    if border.len() as i64 != border_edges {
        return None;
    }
    // Connected: a flood over shared edges reaches every face.
    let mut reached = 1usize;
    let mut stack = vec![faces[0]];
    s.region[faces[0] as usize] = 1;
    while let Some(f) = stack.pop() {
        for &g in &graph.across[f as usize] {
            if s.contains(g) && s.region[g as usize] == 0 {
                s.region[g as usize] = 1;
                reached += 1;
                stack.push(g);
            }
        }
    }
    (reached == faces.len()).then_some(border)
}

/// Control vertices of a border loop on a level whose face owners are `owner`: vertices
/// touching three or more regions (the outside of an open surface is one), then more until
/// there are at least three and no stretch of border between two is over a third of the
/// perimeter (at most 32).
fn control_vertices(graph: &SurfaceGraph, border: &[u32], owner: &[u32]) -> Vec<u32> {
    let mut controls: Vec<u32> = Vec::new();
    for (k, &v) in border.iter().enumerate() {
        let mut regions: Vec<u32> = graph.faces_of(v).iter().map(|&f| owner[f as usize]).collect();
        regions.sort_unstable();
        regions.dedup();
        if regions.len() + usize::from(graph.on_boundary[v as usize]) >= 3 {
            controls.push(k as u32);
        }
    }
    // Arc length from border[0] to border[k].
    let n = border.len();
    let mut arc = vec![0f64; n + 1];
    for k in 0..n {
        let (a, b) = (graph.positions[border[k] as usize], graph.positions[border[(k + 1) % n] as usize]);
        arc[k + 1] = arc[k] + f64::from(a.distance(b));
    }
    let perimeter = arc[n];
    let gap = |a: u32, b: u32| {
        let d = arc[b as usize] - arc[a as usize];
        if b > a {
            d
        } else {
            d + perimeter
        }
    };
    if controls.is_empty() {
        controls.push(0);
    }
    while controls.len() < 32.min(n) {
        // The longest stretch between consecutive controls.
        let m = controls.len();
        let (i, longest) = (0..m)
            .map(|i| (i, gap(controls[i], controls[(i + 1) % m])))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0, 0.0));
        if m >= 3 && longest <= perimeter / 3.0 + 1e-12 {
            break;
        }
        // Insert the border vertex nearest the middle of that stretch.
        let (a, b) = (controls[i], controls[(i + 1) % m]);
        let middle = arc[a as usize] + longest / 2.0;
        let mut best = None;
        let mut k = (a as usize + 1) % n;
        while k != b as usize {
            let at = if k as u32 > a { arc[k] } else { arc[k] + perimeter };
            let d = (at - middle).abs();
            if best.is_none_or(|(_, bd)| d < bd) {
                best = Some((k, d));
            }
            k = (k + 1) % n;
        }
        match best {
            Some((k, _)) => {
                controls.push(k as u32);
                controls.sort_unstable();
            }
            None => break,
        }
    }
    controls
}

#[cfg(test)]
mod tests {
    use super::super::graph::tests::grid;
    use super::*;
    use rand::SeedableRng;
    use std::path::Path;

    pub(crate) fn check_partitions(graph: &SurfaceGraph, h: &Hierarchy) {
        for (l, level) in h.levels.iter().enumerate() {
            let mut seen = vec![0u32; graph.face_count()];
            for &c in level {
                let cluster = &h.clusters[c as usize];
                assert_eq!(cluster.level as usize, l);
                for &f in &cluster.faces {
                    seen[f as usize] += 1;
                    assert_eq!(h.owner[l][f as usize], c);
                }
                if l > 0 {
                    assert!(cluster.disc, "level {l} cluster {c} is not a disc");
                    assert!(
                        cluster.controls.len() >= 3,
                        "cluster {c} has {} controls",
                        cluster.controls.len()
                    );
                    let parent = &h.clusters[cluster.parent as usize];
                    assert!(cluster.faces.iter().all(|f| parent.faces.contains(f)));
                }
            }
            assert!(seen.iter().all(|&n| n == 1), "level {l} does not partition the faces");
        }
        let last = h.levels.last().expect("a level");
        assert!(last.iter().all(|&c| h.clusters[c as usize].is_face()), "the finest level is single faces");
    }

    #[test]
    fn a_plane_hierarchy_partitions_every_level_down_to_faces() {
        let (p, t) = grid(16);
        let g = SurfaceGraph::new(&p, &t, Path::new("g.obj")).expect("manifold");
        let h = Hierarchy::build(&g, &mut ChaCha8Rng::seed_from_u64(1));
        check_partitions(&g, &h);
        assert!(h.levels.len() >= 4, "{} levels", h.levels.len());
        assert_eq!(h.levels[0].len(), 1);
        assert!(h.clusters[h.levels[0][0] as usize].disc, "the plane itself is a disc");
        // Level 1 splits the plane into about four clusters of about equal area.
        let areas: Vec<f64> = h.levels[1].iter().map(|&c| h.clusters[c as usize].area).collect();
        assert!((3..=6).contains(&areas.len()), "{areas:?}");
        let (lo, hi) = areas.iter().fold((f64::MAX, 0f64), |(lo, hi), &a| (lo.min(a), hi.max(a)));
        assert!(hi < 3.0 * lo, "{areas:?}");
    }

    #[test]
    fn the_bunny_hierarchy_partitions_every_level_into_discs() {
        let path = crate::mesh::test_meshes::bundled("bunny-1k8.obj");
        let mesh = crate::mesh::textured::load_textured(&path).expect("bunny");
        let g = SurfaceGraph::new(&mesh.positions, &mesh.triangles, &path).expect("manifold");
        let h = Hierarchy::build(&g, &mut ChaCha8Rng::seed_from_u64(0));
        check_partitions(&g, &h);
        assert!(!h.clusters[h.levels[0][0] as usize].disc, "the closed bunny is not a disc");
        for level in &h.levels[1..] {
            for &c in level {
                let cluster = &h.clusters[c as usize];
                // Neighbours are symmetric.
                for &n in &cluster.neighbours {
                    assert!(h.clusters[n as usize].neighbours.contains(&c));
                }
            }
        }
    }
}
