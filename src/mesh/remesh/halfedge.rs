//! The editable connectivity the remesher works on: a triangle-only halfedge structure
//! in corner-table form. Halfedge `3f + k` runs from corner `k` to corner `k + 1` of face
//! `f`, so `next`, `prev` and `face` are arithmetic and only the origin and the opposite
//! halfedge are stored. Boundary edges have no opposite ([`NONE`]). Removed faces and
//! vertices stay in the arrays, marked dead, until [`Halfedges::extract`].

use crate::mesh::layout;
use crate::mesh::Mesh;
use glam::Vec3;

/// No halfedge (the opposite of a boundary halfedge).
pub(crate) const NONE: u32 = u32::MAX;

pub(crate) fn next(h: u32) -> u32 {
    if h % 3 == 2 {
        h - 2
    } else {
        h + 1
    }
}

pub(crate) fn prev(h: u32) -> u32 {
    if h % 3 == 0 {
        h + 2
    } else {
        h - 1
    }
}

pub(crate) struct Halfedges {
    pub pos: Vec<Vec3>,
    /// For every vertex, the input triangle it was last projected onto.
    pub hint: Vec<u32>,
    /// Origin vertex of every halfedge.
    pub from: Vec<u32>,
    /// Opposite halfedge, or [`NONE`] on a boundary.
    pub opp: Vec<u32>,
    /// One outgoing halfedge per vertex; on a boundary vertex always the boundary one, so
    /// that counter-clockwise circulation from it sees the whole open fan.
    pub out: Vec<u32>,
    pub face_alive: Vec<bool>,
    pub vertex_alive: Vec<bool>,
}

impl Halfedges {
    /// Builds the structure for a manifold mesh (every [`Mesh`] is one) with one hint per
    /// vertex. Returns `None` if an edge has more than two halfedges or two running the
    /// same way, which a valid `Mesh` never has.
    pub fn new(pos: Vec<Vec3>, triangles: &[[u32; 3]], hint: Vec<u32>) -> Option<Halfedges> {
        let from: Vec<u32> = triangles.iter().flatten().copied().collect();
        let opp = pair_opposites(&from)?;
        let mut he = Halfedges {
            out: vec![NONE; pos.len()],
            vertex_alive: vec![true; pos.len()],
            face_alive: vec![true; triangles.len()],
            pos,
            hint,
            from,
            opp,
        };
        for h in 0..he.from.len() as u32 {
            he.out[he.from[h as usize] as usize] = h;
        }
        for v in 0..he.pos.len() {
            he.vertex_alive[v] = he.out[v] != NONE;
            if he.vertex_alive[v] {
                he.normalize_out(v as u32);
            }
        }
        Some(he)
    }

    /// Builds the structure for `mesh`, hinting every vertex with one of its faces.
    pub fn from_mesh(mesh: &Mesh) -> Option<Halfedges> {
        let mut hint = vec![0; mesh.vertex_count()];
        for (f, t) in mesh.triangles().iter().enumerate() {
            for &v in t {
                hint[v as usize] = f as u32;
            }
        }
        Halfedges::new(mesh.positions().to_vec(), mesh.triangles(), hint)
    }

    /// The same surface with its live vertices and faces renumbered in spatial order
    /// ([`crate::mesh::layout`]); dead slots are dropped. (A renumbered manifold surface
    /// stays manifold; should that ever fail, the structure is kept as it was.)
    pub fn in_spatial_order(self) -> Halfedges {
        let (pos, triangles, hint) = self.extract();
        let (order, triangles) = layout::spatial_order(&pos, &triangles);
        let (pos, hint) = (layout::permuted(&pos, &order), layout::permuted(&hint, &order));
        Halfedges::new(pos, &triangles, hint).unwrap_or(self)
    }

    /// The live vertices (renumbered in order), their hints, and the live faces.
    pub fn extract(&self) -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<u32>) {
        let mut index = vec![NONE; self.pos.len()];
        let (mut pos, mut hint) = (Vec::new(), Vec::new());
        for (v, slot) in index.iter_mut().enumerate() {
            if self.vertex_alive[v] {
                *slot = pos.len() as u32;
                pos.push(self.pos[v]);
                hint.push(self.hint[v]);
            }
        }
        let triangles = (0..self.face_alive.len())
            .filter(|&f| self.face_alive[f])
            .map(|f| [0, 1, 2].map(|k| index[self.from[3 * f + k] as usize]))
            .collect();
        (pos, triangles, hint)
    }

    pub fn to(&self, h: u32) -> u32 {
        self.from[next(h) as usize]
    }

    pub fn opp(&self, h: u32) -> u32 {
        self.opp[h as usize]
    }

    pub fn from(&self, h: u32) -> u32 {
        self.from[h as usize]
    }

    pub fn p(&self, v: u32) -> Vec3 {
        self.pos[v as usize]
    }

    pub fn halfedge_count(&self) -> u32 {
        self.from.len() as u32
    }

    pub fn face_is_alive(&self, h: u32) -> bool {
        self.face_alive[(h / 3) as usize]
    }

    pub fn is_boundary_vertex(&self, v: u32) -> bool {
        self.opp[self.out[v as usize] as usize] == NONE
    }

    /// Appends the outgoing halfedges of `v`, counter-clockwise, starting at `out[v]`.
    pub fn outgoing(&self, v: u32, buf: &mut Vec<u32>) {
        buf.clear();
        let start = self.out[v as usize];
        let mut h = start;
        // The bound only guards against a corrupted structure.
        for _ in 0..self.from.len() {
            buf.push(h);
            h = self.opp[prev(h) as usize];
            if h == NONE || h == start {
                return;
            }
        }
    }

    /// The neighbours of `v`, counter-clockwise; on a boundary vertex the first and last
    /// are its two boundary neighbours.
    pub fn ring(&self, v: u32, buf: &mut Vec<u32>) {
        self.outgoing(v, buf);
        let last = buf.last().copied();
        for h in buf.iter_mut() {
            *h = self.to(*h);
        }
        if let Some(last) = last.filter(|&h| self.opp[prev(h) as usize] == NONE) {
            buf.push(self.from[prev(last) as usize]);
        }
    }

    pub fn valence(&self, v: u32, buf: &mut Vec<u32>) -> usize {
        self.ring(v, buf);
        buf.len()
    }

    /// Moves `out[v]` clockwise to the boundary halfedge, if `v` has one.
    pub fn normalize_out(&mut self, v: u32) {
        let start = self.out[v as usize];
        let mut h = start;
        for _ in 0..self.from.len() {
            let o = self.opp[h as usize];
            if o == NONE {
                break;
            }
            h = next(o);
            if h == start {
                break;
            }
        }
        self.out[v as usize] = h;
    }

    fn link(&mut self, a: u32, b: u32) {
        if a != NONE {
            self.opp[a as usize] = b;
        }
        if b != NONE {
            self.opp[b as usize] = a;
        }
    }

    fn add_vertex(&mut self, p: Vec3, hint: u32) -> u32 {
        self.pos.push(p);
        self.hint.push(hint);
        self.out.push(NONE);
        self.vertex_alive.push(true);
        (self.pos.len() - 1) as u32
    }

    /// Adds a face with corners `v` and no opposites yet; returns its first halfedge.
    fn add_face(&mut self, v: [u32; 3]) -> u32 {
        let h = self.from.len() as u32;
        self.from.extend_from_slice(&v);
        self.opp.extend_from_slice(&[NONE; 3]);
        self.face_alive.push(true);
        h
    }

    /// Splits the edge of `h` at `p`, splitting the one or two faces beside it in two.
    /// Returns the new vertex.
    pub fn split(&mut self, h: u32, p: Vec3) -> u32 {
        let (n, pr, o) = (next(h), prev(h), self.opp(h));
        let (a, b, c) = (self.from(h), self.from(n), self.from(pr));
        let m = self.add_vertex(p, self.hint[a as usize]);
        // Face (a, b, c) becomes (a, m, c); the new face (m, b, c) takes its edge b→c.
        let f2 = self.add_face([m, b, c]);
        let outer = self.opp(n);
        self.from[n as usize] = m;
        self.link(f2 + 1, outer);
        self.link(n, f2 + 2);
        if self.out[b as usize] == n {
            self.out[b as usize] = f2 + 1;
        }
        self.out[m as usize] = f2;
        if o == NONE {
            self.opp[h as usize] = NONE;
            return m;
        }
        // Face (b, a, d) becomes (b, m, d); the new face (m, a, d) takes its edge a→d.
        let (no, po) = (next(o), prev(o));
        let d = self.from(po);
        let g2 = self.add_face([m, a, d]);
        let outer = self.opp(no);
        self.from[no as usize] = m;
        self.link(g2 + 1, outer);
        self.link(no, g2 + 2);
        if self.out[a as usize] == no {
            self.out[a as usize] = g2 + 1;
        }
        self.link(h, g2);
        self.link(o, f2);
        m
    }

    /// Flips the interior edge of `h` between faces (a, b, c) and (b, a, d) to c–d.
    pub fn flip(&mut self, h: u32) {
        let o = self.opp(h);
        let (n, no, po) = (next(h), next(o), prev(o));
        let (a, b, c, d) = (self.from(h), self.from(n), self.from(prev(h)), self.from(po));
        let (x1, x3) = (self.opp(n), self.opp(no));
        // Faces become (a, d, c) and (b, c, d), reusing every halfedge slot.
        self.from[n as usize] = d;
        self.from[no as usize] = c;
        self.link(h, x3);
        self.link(o, x1);
        self.link(n, no);
        if self.out[a as usize] == no {
            self.out[a as usize] = h;
        }
        if self.out[b as usize] == n {
            self.out[b as usize] = o;
        }
    }

    /// Collapses the edge of `h` by removing vertex `remove` (one end of it) into `keep`
    /// (the other), whose position the caller sets. The faces beside the edge disappear
    /// and their outer edges are glued together.
    pub fn collapse(&mut self, h: u32, remove: u32, keep: u32, buf: &mut Vec<u32>) {
        self.outgoing(remove, buf);
        let o = self.opp(h);
        let mut touched = [NONE; 4];
        for (k, e) in [h, o].into_iter().enumerate() {
            if e == NONE {
                continue;
            }
            let (x1, x2) = (self.opp(next(e)), self.opp(prev(e)));
            self.link(x1, x2);
            self.face_alive[(e / 3) as usize] = false;
            touched[2 * k] = x1;
            touched[2 * k + 1] = x2;
        }
        for &e in buf.iter() {
            if self.face_is_alive(e) {
                self.from[e as usize] = keep;
            }
        }
        self.vertex_alive[remove as usize] = false;
        let third = [self.from(prev(h)), if o == NONE { NONE } else { self.from(prev(o)) }];
        for v in [keep, third[0], third[1]] {
            if v != NONE {
                self.reset_out(v, &touched, buf);
            }
        }
    }

    /// Points `out[v]` at a live outgoing halfedge found among (or next to) `candidates`,
    /// else among `fallback`, then normalizes it.
    fn reset_out(&mut self, v: u32, candidates: &[u32], fallback: &[u32]) {
        let found = candidates.iter().chain(fallback).copied().find_map(|e| {
            if e == NONE || !self.face_is_alive(e) {
                None
            } else if self.from(e) == v {
                Some(e)
            } else if self.to(e) == v {
                Some(next(e))
            } else {
                None
            }
        });
        match found {
            Some(e) => {
                self.out[v as usize] = e;
                self.normalize_out(v);
            }
            // Only a vertex whose every face was removed; the collapse checks prevent it.
            None => self.vertex_alive[v as usize] = false,
        }
    }
}

/// Pairs every halfedge with the one running the opposite way along the same edge.
fn pair_opposites(from: &[u32]) -> Option<Vec<u32>> {
    let to = |h: usize| from[next(h as u32) as usize];
    let mut keyed: Vec<(u32, u32, u32)> =
        (0..from.len()).map(|h| (from[h].min(to(h)), from[h].max(to(h)), h as u32)).collect();
    keyed.sort_unstable();
    let mut opp = vec![NONE; from.len()];
    for group in keyed.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        match group {
            [_] => {}
            [x, y] if from[x.2 as usize] != from[y.2 as usize] => {
                opp[x.2 as usize] = y.2;
                opp[y.2 as usize] = x.2;
            }
            _ => return None,
        }
    }
    Some(opp)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::mesh::test_meshes::grid;
    use crate::mesh::{topology, Mesh};

    pub(crate) fn to_mesh(he: &Halfedges) -> Mesh {
        let (p, t, _) = he.extract();
        Mesh::from_valid_parts(p, t)
    }

    /// Checks the invariants the operations must keep: opposites pair up in reverse,
    /// every live vertex's `out` leaves it, and boundary vertices point at the boundary.
    pub(crate) fn check(he: &Halfedges) {
        for h in 0..he.halfedge_count() {
            if !he.face_is_alive(h) {
                continue;
            }
            let o = he.opp(h);
            if o != NONE {
                assert!(he.face_is_alive(o), "{h} is paired with a dead halfedge");
                assert_eq!(he.opp(o), h);
                assert_eq!((he.from(o), he.to(o)), (he.to(h), he.from(h)));
            }
        }
        for v in 0..he.pos.len() as u32 {
            if he.vertex_alive[v as usize] {
                let h = he.out[v as usize];
                assert!(he.face_is_alive(h) && he.from(h) == v, "vertex {v}");
                let on_boundary = (0..he.halfedge_count())
                    .any(|e| he.face_is_alive(e) && he.opp(e) == NONE && he.from(e) == v);
                assert_eq!(he.is_boundary_vertex(v), on_boundary, "vertex {v}");
            }
        }
        assert!(crate::mesh::manifold::is_manifold(to_mesh(he).triangles()));
    }

    #[test]
    fn rings_and_boundaries_of_a_grid() {
        let he = Halfedges::from_mesh(&grid(2)).expect("manifold");
        let mut buf = Vec::new();
        he.ring(4, &mut buf);
        assert_eq!(buf.len(), 6);
        assert!(!he.is_boundary_vertex(4));
        he.ring(0, &mut buf);
        assert_eq!(buf, vec![1, 4, 3]);
        assert!(he.is_boundary_vertex(0));
        check(&he);
    }

    #[test]
    fn split_interior_and_boundary_edges() {
        let mut he = Halfedges::from_mesh(&grid(1)).expect("manifold");
        // Halfedge 2 runs 2 → 0 along the diagonal (interior); halfedge 0 runs 0 → 1 (boundary).
        let h = (0..6).find(|&h| he.opp(h) != NONE).expect("a diagonal");
        let m = he.split(h, Vec3::new(0.5, 0.5, 0.0));
        check(&he);
        let mut buf = Vec::new();
        assert_eq!(he.valence(m, &mut buf), 4);
        let b = (0..he.halfedge_count()).find(|&h| he.opp(h) == NONE).expect("boundary");
        let m2 = he.split(b, (he.p(he.from(b)) + he.p(he.to(b))) / 2.0);
        check(&he);
        assert!(he.is_boundary_vertex(m2));
        assert_eq!(to_mesh(&he).face_count(), 5);
    }

    #[test]
    fn flip_the_diagonal_of_a_square() {
        let mut he = Halfedges::from_mesh(&grid(1)).expect("manifold");
        let h = (0..6).find(|&h| he.opp(h) != NONE).expect("a diagonal");
        he.flip(h);
        check(&he);
        // The square 0 1 / 2 3 had the diagonal 0–3; now it has 1–2.
        let edges = topology::edges(&to_mesh(&he));
        assert!(edges.contains(&[1, 2]) && !edges.contains(&[0, 3]), "{edges:?}");
    }

    #[test]
    fn collapse_keeps_a_valid_surface() {
        let m = grid(4);
        let mut he = Halfedges::from_mesh(&m).expect("manifold");
        let mut buf = Vec::new();
        let h = (0..he.halfedge_count()).find(|&h| {
            let (a, b) = (he.from(h), he.to(h));
            !he.is_boundary_vertex(a) && !he.is_boundary_vertex(b)
        });
        let h = h.expect("an edge between well-connected vertices");
        let (a, b) = (he.from(h), he.to(h));
        he.collapse(h, a, b, &mut buf);
        check(&he);
        let after = to_mesh(&he);
        assert_eq!(after.vertex_count(), m.vertex_count() - 1);
        assert_eq!(topology::euler_characteristic(&after), 1);
        assert_eq!(he.p(b), m.positions()[b as usize]);
    }

    #[test]
    fn collapse_along_a_boundary_edge() {
        let m = grid(3);
        let mut he = Halfedges::from_mesh(&m).expect("manifold");
        let mut buf = Vec::new();
        // The boundary edge 1 → 2 along y = 0: vertex 1 is removed into 2.
        let h = (0..he.halfedge_count()).find(|&h| he.from(h) == 1 && he.to(h) == 2).expect("edge");
        assert_eq!(he.opp(h), NONE);
        he.collapse(h, 1, 2, &mut buf);
        check(&he);
        let after = to_mesh(&he);
        assert_eq!(topology::summary(&after).boundary_edges, 11);
    }

    #[test]
    fn non_manifold_triangles_are_refused() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!(Halfedges::new(p, &[[0, 1, 2], [0, 1, 2]], vec![0; 3]).is_none());
    }
}
