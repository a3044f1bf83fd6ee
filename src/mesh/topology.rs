//! Connectivity of a [`Mesh`]: edges, one-rings, boundaries, connected components and the
//! Euler characteristic. All results are in a fixed order (sorted or by index), never in
//! hash order, so everything built on them is deterministic.

use super::Mesh;
use rayon::slice::ParallelSliceMut;
use std::fmt;

/// One face's use of an undirected edge `lo < hi`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct EdgeIncidence {
    pub lo: u32,
    pub hi: u32,
    pub face: u32,
    /// The face runs along the edge from `lo` to `hi`.
    pub forward: bool,
}

impl EdgeIncidence {
    pub fn key(&self) -> (u32, u32) {
        (self.lo, self.hi)
    }
}

/// Every (edge, face) incidence, sorted by edge then face, so that the faces of an edge are
/// adjacent (`chunk_by(key)` groups them).
pub(crate) fn edge_incidences(triangles: &[[u32; 3]]) -> Vec<EdgeIncidence> {
    let mut out = Vec::with_capacity(3 * triangles.len());
    for (f, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            out.push(EdgeIncidence { lo: a.min(b), hi: a.max(b), face: f as u32, forward: a < b });
        }
    }
    // The whole incidence is the key, so any sort gives this order; in parallel, as a
    // mesh of a million faces sorts three million of them.
    out.par_sort_unstable();
    out
}

/// Disjoint sets over `0..n` with path halving; the smaller index always becomes the root,
/// which keeps labels independent of the order of unions.
pub(crate) struct UnionFind {
    parent: Vec<usize>,
}

impl UnionFind {
    pub fn new(n: usize) -> Self {
        UnionFind { parent: (0..n).collect() }
    }

    pub fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] != x {
            self.parent[x] = self.parent[self.parent[x]];
            x = self.parent[x];
        }
        x
    }

    pub fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        let (lo, hi) = (ra.min(rb), ra.max(rb));
        self.parent[hi] = lo;
    }
}

/// The undirected edges `[lo, hi]` (`lo < hi`), sorted.
pub fn edges(mesh: &Mesh) -> Vec<[u32; 2]> {
    let mut e: Vec<[u32; 2]> = edge_incidences(mesh.triangles()).iter().map(|i| [i.lo, i.hi]).collect();
    e.dedup();
    e
}

/// The boundary edges (used by exactly one face), directed as their face runs along them
/// (so a boundary loop runs clockwise seen from outside), sorted.
pub fn boundary_edges(mesh: &Mesh) -> Vec<[u32; 2]> {
    let mut out: Vec<[u32; 2]> = edge_incidences(mesh.triangles())
        .chunk_by(|a, b| a.key() == b.key())
        .filter_map(|g| match g {
            [e] if e.forward => Some([e.lo, e.hi]),
            [e] => Some([e.hi, e.lo]),
            _ => None,
        })
        .collect();
    out.sort_unstable();
    out
}

/// For every vertex, whether it lies on a boundary edge.
pub fn boundary_vertices(mesh: &Mesh) -> Vec<bool> {
    let mut on = vec![false; mesh.vertex_count()];
    for [a, b] in boundary_edges(mesh) {
        on[a as usize] = true;
        on[b as usize] = true;
    }
    on
}

/// The neighbours of every vertex, in compressed rows.
#[derive(Clone, Debug)]
pub struct VertexRings {
    offsets: Vec<usize>,
    neighbours: Vec<u32>,
}

impl VertexRings {
    /// The neighbours of vertex `v`, counter-clockwise seen from outside. On a boundary
    /// vertex the ring starts and ends at its two boundary neighbours (an open fan).
    pub fn ring(&self, v: usize) -> &[u32] {
        &self.neighbours[self.offsets[v]..self.offsets[v + 1]]
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// True for a mesh without vertices (never the case for a loaded mesh).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The ordered one-ring of every vertex (see [`VertexRings::ring`]).
pub fn one_rings(mesh: &Mesh) -> VertexRings {
    let n = mesh.vertex_count();
    // Around vertex a, face (a, b, c) leads counter-clockwise from neighbour b to c.
    let mut steps: Vec<(u32, u32, u32)> = Vec::with_capacity(3 * mesh.face_count());
    for t in mesh.triangles() {
        for k in 0..3 {
            steps.push((t[k], t[(k + 1) % 3], t[(k + 2) % 3]));
        }
    }
    // Whole tuples are the key: any sort gives this order.
    steps.par_sort_unstable();
    let mut offsets = Vec::with_capacity(n + 1);
    let mut neighbours = Vec::with_capacity(steps.len() + n);
    let mut rest = steps.as_slice();
    let mut arrivals = Vec::new();
    for v in 0..n as u32 {
        offsets.push(neighbours.len());
        let split = rest.partition_point(|s| s.0 == v);
        walk_fan(&rest[..split], &mut arrivals, &mut neighbours);
        rest = &rest[split..];
    }
    offsets.push(neighbours.len());
    VertexRings { offsets, neighbours }
}

/// Appends the neighbours of one vertex by chaining its `(v, from, to)` steps (sorted by
/// `from`), starting where no step arrives (a boundary) or else at the first step.
fn walk_fan(steps: &[(u32, u32, u32)], arrivals: &mut Vec<u32>, out: &mut Vec<u32>) {
    let Some(first) = steps.first() else { return };
    arrivals.clear();
    arrivals.extend(steps.iter().map(|s| s.2));
    arrivals.sort_unstable();
    let start = steps.iter().map(|s| s.1).find(|b| arrivals.binary_search(b).is_err()).unwrap_or(first.1);
    let mut at = start;
    out.push(at);
    // A manifold fan takes each step once; the bound guards against anything else.
    for _ in 0..steps.len() {
        let Ok(i) = steps.binary_search_by_key(&at, |s| s.1) else {
            return;
        };
        at = steps[i].2;
        if at == start {
            return;
        }
        out.push(at);
    }
}

/// Connected components of a mesh (vertices joined by edges).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Components {
    /// Number of components.
    pub count: usize,
    /// Component of every vertex, numbered in order of each component's lowest vertex.
    pub vertex_component: Vec<u32>,
}

/// The connected components of `mesh`.
pub fn connected_components(mesh: &Mesh) -> Components {
    let mut sets = UnionFind::new(mesh.vertex_count());
    for t in mesh.triangles() {
        sets.union(t[0] as usize, t[1] as usize);
        sets.union(t[0] as usize, t[2] as usize);
    }
    let mut label = vec![u32::MAX; mesh.vertex_count()];
    let mut count = 0;
    let mut vertex_component = Vec::with_capacity(mesh.vertex_count());
    for v in 0..mesh.vertex_count() {
        let root = sets.find(v);
        if label[root] == u32::MAX {
            label[root] = count;
            count += 1;
        }
        vertex_component.push(label[root]);
    }
    Components { count: count as usize, vertex_component }
}

/// V − E + F; 2 − 2g for a closed connected surface of genus g.
pub fn euler_characteristic(mesh: &Mesh) -> i64 {
    mesh.vertex_count() as i64 - edges(mesh).len() as i64 + mesh.face_count() as i64
}

/// Counts that describe a mesh's topology, for logs and tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Summary {
    /// Number of vertices.
    pub vertices: usize,
    /// Number of triangles.
    pub faces: usize,
    /// Number of undirected edges.
    pub edges: usize,
    /// Number of edges with a single face.
    pub boundary_edges: usize,
    /// Number of connected components.
    pub components: usize,
    /// V − E + F.
    pub euler_characteristic: i64,
}

/// The [`Summary`] of `mesh`.
pub fn summary(mesh: &Mesh) -> Summary {
    let edges = edges(mesh).len();
    Summary {
        vertices: mesh.vertex_count(),
        faces: mesh.face_count(),
        edges,
        boundary_edges: boundary_edges(mesh).len(),
        components: connected_components(mesh).count,
        euler_characteristic: mesh.vertex_count() as i64 - edges as i64 + mesh.face_count() as i64,
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} vertices, {} faces, {} edges ({} on a boundary), {} connected component{}, \
             Euler characteristic {}",
            self.vertices,
            self.faces,
            self.edges,
            self.boundary_edges,
            self.components,
            if self.components == 1 { "" } else { "s" },
            self.euler_characteristic
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::test_meshes::{cube, grid};

    #[test]
    fn cube_is_a_closed_sphere() {
        let s = summary(&cube());
        assert_eq!((s.vertices, s.faces, s.edges, s.boundary_edges), (8, 12, 18, 0));
        assert_eq!((s.components, s.euler_characteristic), (1, 2));
        assert!(crate::mesh::manifold::is_manifold(cube().triangles()));
    }

    #[test]
    fn grid_is_a_disc_with_a_boundary() {
        let g = grid(3);
        let s = summary(&g);
        assert_eq!((s.boundary_edges, s.euler_characteristic), (12, 1));
        let on = boundary_vertices(&g);
        assert_eq!(on.iter().filter(|&&b| b).count(), 12);
        assert!(!on[5] && !on[6] && !on[9] && !on[10]);
    }

    #[test]
    fn rings_are_counter_clockwise_and_open_at_the_boundary() {
        let g = grid(2); // vertices 0..9 on a 3×3 lattice, 4 in the middle
        let rings = one_rings(&g);
        let centre = rings.ring(4);
        assert_eq!(centre.len(), 6);
        let p = g.positions();
        for w in 0..6 {
            let (a, b) = (p[centre[w] as usize] - p[4], p[centre[(w + 1) % 6] as usize] - p[4]);
            assert!(a.cross(b).z > 0.0, "ring {centre:?} turns clockwise at {w}");
        }
        // Corner 0 sees the boundary neighbours 1 and 3 at the ends of its open fan.
        assert_eq!(rings.ring(0), &[1, 4, 3]);
    }

    #[test]
    fn components_count_separate_pieces() {
        let mut p = cube().positions().to_vec();
        let mut t = cube().triangles().to_vec();
        p.extend(cube().positions().iter().map(|q| *q + glam::Vec3::splat(3.0)));
        t.extend(cube().triangles().iter().map(|f| f.map(|i| i + 8)));
        let two = Mesh::new(p, t).expect("valid");
        let c = connected_components(&two);
        assert_eq!(c.count, 2);
        assert_eq!(c.vertex_component[..8], [0; 8]);
        assert_eq!(c.vertex_component[8..], [1; 8]);
        assert_eq!(euler_characteristic(&two), 4);
    }
}
