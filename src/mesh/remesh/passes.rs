//! The four passes of one remeshing iteration (Botsch & Kobbelt 2004, §3): split long
//! edges, collapse short ones, flip edges towards regular valence, then relax vertices
//! tangentially and project them back onto the input surface.
//!
//! Every pass visits edges in halfedge order and decides from the current state, so the
//! result does not depend on the thread count; only the per-vertex relaxation and
//! projection, which read the old state and write each vertex once, run in parallel.

use super::halfedge::{next, prev, Halfedges, NONE};
use crate::mesh::bvh::TriangleBvh;
use glam::Vec3;
use rayon::prelude::*;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// A boundary vertex may be removed only where the boundary turns by less than this
/// (cos 10°), so that collapses do not cut the corners of holes and open borders.
const STRAIGHT_BOUNDARY_COS: f32 = 0.985;

/// Faces around a collapse may turn by at most this much (cos ≈ 78°): more means the
/// collapse folds the surface over.
const FOLD_COS: f32 = 0.2;

/// Scratch buffers for one-rings, reused across edges.
#[derive(Default)]
pub(crate) struct Scratch {
    a: Vec<u32>,
    b: Vec<u32>,
    c: Vec<u32>,
}

/// The halfedge of every edge once: its lower-numbered halfedge, or its only one.
fn is_edge_representative(he: &Halfedges, h: u32) -> bool {
    let o = he.opp(h);
    he.face_is_alive(h) && (o == NONE || h < o)
}

fn length_squared(he: &Halfedges, h: u32) -> f32 {
    he.p(he.from(h)).distance_squared(he.p(he.to(h)))
}

/// Splits every edge longer than `high` at its midpoint, always the longest first.
/// Longest-edge bisection keeps triangles well shaped: the new edges from the midpoint are
/// medians onto the longest side, at most √3/2 of it, so lengths shrink geometrically;
/// splitting in index order instead can grow slivers and fans without end. Returns the
/// number of splits.
pub(crate) fn split_long_edges(he: &mut Halfedges, high: f32) -> usize {
    let high2 = high * high;
    // Positive floats order like their bits; ties go to the lower halfedge index.
    let key = |he: &Halfedges, h: u32| (length_squared(he, h).to_bits(), Reverse(h));
    let mut queue: BinaryHeap<(u32, Reverse<u32>)> = (0..he.halfedge_count())
        .filter(|&h| is_edge_representative(he, h) && length_squared(he, h) > high2)
        .map(|h| key(he, h))
        .collect();
    let mut splits = 0;
    while let Some((bits, Reverse(h))) = queue.pop() {
        // An entry is stale once its edge was split (its length changed).
        if !is_edge_representative(he, h) || length_squared(he, h).to_bits() != bits {
            continue;
        }
        let mid = (he.p(he.from(h)) + he.p(he.to(h))) * 0.5;
        let m = he.split(h, mid);
        splits += 1;
        for e in edges_of_faces_around(he, m) {
            if length_squared(he, e) > high2 {
                queue.push(key(he, e));
            }
        }
    }
    splits
}

/// The representative halfedges of every edge of the faces around `v`. After a split
/// these are all the edges whose length or representative changed (the split hands the
/// outer edges of the two old faces to the two new ones), so all need fresh queue entries.
fn edges_of_faces_around(he: &Halfedges, v: u32) -> Vec<u32> {
    let mut faces = Vec::with_capacity(4);
    he.outgoing(v, &mut faces);
    let mut out = Vec::with_capacity(12);
    for e in faces {
        for x in [e, next(e), prev(e)] {
            let o = he.opp(x);
            out.push(if o != NONE && o < x { o } else { x });
        }
    }
    out
}

/// Collapses edges shorter than `low` into one of their ends, where the collapse keeps
/// the surface manifold, unfolded, its boundary in place, and creates no edge longer than
/// `high`. The end of lower valence is removed. Returns the number of collapses.
pub(crate) fn collapse_short_edges(he: &mut Halfedges, low: f32, high: f32, s: &mut Scratch) -> usize {
    let mut collapses = 0;
    for h in 0..he.halfedge_count() {
        if !is_edge_representative(he, h) || length_squared(he, h) >= low * low {
            continue;
        }
        let (a, b) = (he.from(h), he.to(h));
        let (va, vb) = (he.valence(a, &mut s.a), he.valence(b, &mut s.a));
        let order = if va <= vb { [(a, b), (b, a)] } else { [(b, a), (a, b)] };
        for (remove, keep) in order {
            if collapse_ok(he, h, remove, keep, low, high, s) {
                he.collapse(h, remove, keep, &mut s.a);
                collapses += 1;
                break;
            }
        }
    }
    collapses
}

/// Whether removing `remove` into `keep` (the ends of `h`) is allowed.
fn collapse_ok(he: &Halfedges, h: u32, remove: u32, keep: u32, low: f32, high: f32, s: &mut Scratch) -> bool {
    let o = he.opp(h);
    let boundary_edge = o == NONE;
    if he.is_boundary_vertex(remove) && !(boundary_edge && boundary_is_straight(he, remove, s)) {
        return false;
    }
    he.ring(remove, &mut s.a);
    he.ring(keep, &mut s.b);
    // Link condition: the two rings may share only the vertices opposite the edge.
    let common = s.a.iter().filter(|v| s.b.contains(v)).count();
    if common != if boundary_edge { 1 } else { 2 } {
        return false;
    }
    let keep_boundary = he.is_boundary_vertex(keep) || he.is_boundary_vertex(remove);
    if s.a.len() + s.b.len() - common - 2 < min_valence(keep_boundary) {
        return false;
    }
    let opposite = [he.from(prev(h)), if boundary_edge { NONE } else { he.from(prev(o)) }];
    for v in opposite.into_iter().filter(|&v| v != NONE) {
        if he.valence(v, &mut s.c) - 1 < min_valence(he.is_boundary_vertex(v)) {
            return false;
        }
    }
    let q = he.p(keep);
    if s.a.iter().any(|&x| x != keep && q.distance_squared(he.p(x)) > high * high) {
        return false;
    }
    !collapse_folds(he, h, remove, q, low, s)
}

/// The fewest neighbours a vertex may keep: a triangle fan needs two on a boundary and
/// three inside.
fn min_valence(boundary: bool) -> usize {
    if boundary {
        2
    } else {
        3
    }
}

/// Whether a boundary vertex's two boundary neighbours are nearly in line with it.
fn boundary_is_straight(he: &Halfedges, v: u32, s: &mut Scratch) -> bool {
    he.ring(v, &mut s.c);
    let (Some(&first), Some(&last)) = (s.c.first(), s.c.last()) else {
        return false;
    };
    let (d1, d2) = (he.p(v) - he.p(last), he.p(first) - he.p(v));
    d1.dot(d2) > STRAIGHT_BOUNDARY_COS * d1.length() * d2.length()
}

/// Whether moving `remove` to `q` turns a surviving face around it over or degenerate.
fn collapse_folds(he: &Halfedges, h: u32, remove: u32, q: Vec3, low: f32, s: &mut Scratch) -> bool {
    let dying = [h / 3, he.opp(h) / 3];
    he.outgoing(remove, &mut s.c);
    let p = he.p(remove);
    s.c.iter().filter(|&&e| !dying.contains(&(e / 3))).any(|&e| {
        let (x, y) = (he.p(he.to(e)), he.p(he.from(prev(e))));
        let before = (x - p).cross(y - p);
        let after = (x - q).cross(y - q);
        after.length() <= 1e-3 * low * low || before.dot(after) <= FOLD_COS * before.length() * after.length()
    })
}

/// Flips edges where that brings the four vertices involved closer to valence 6 (4 on a
/// boundary), without folding the two faces over. Returns the number of flips.
pub(crate) fn equalize_valences(he: &mut Halfedges, s: &mut Scratch) -> usize {
    // Valences change only at the four vertices of a flip, so count them once and keep
    // them current rather than walk four rings for every edge.
    let mut valence: Vec<i64> = (0..he.pos.len() as u32)
        .into_par_iter()
        .map_init(
            Vec::new,
            |ring, v| {
                if he.vertex_alive[v as usize] {
                    he.valence(v, ring) as i64
                } else {
                    0
                }
            },
        )
        .collect();
    let mut flips = 0;
    for h in 0..he.halfedge_count() {
        if !is_edge_representative(he, h) || he.opp(h) == NONE {
            continue;
        }
        let quad = [he.from(h), he.to(h), he.from(prev(h)), he.from(prev(he.opp(h)))];
        if flip_improves(he, quad, &valence) && !flip_exists(he, quad, s) && !flip_folds(he, h) {
            he.flip(h);
            for (v, change) in quad.into_iter().zip([-1, -1, 1, 1]) {
                valence[v as usize] += change;
            }
            flips += 1;
        }
    }
    flips
}

/// Whether flipping the edge a–b of the faces (a, b, c), (b, a, d) to c–d brings the
/// four valences closer to 6 (4 on a boundary), keeping every one at its minimum or more.
fn flip_improves(he: &Halfedges, [a, b, c, d]: [u32; 4], valence: &[i64]) -> bool {
    if c == d {
        return false;
    }
    let mut before = 0;
    let mut after = 0;
    for (v, change) in [(a, -1), (b, -1), (c, 1), (d, 1)] {
        let boundary = he.is_boundary_vertex(v);
        let n = valence[v as usize];
        if n + change < min_valence(boundary) as i64 {
            return false;
        }
        let target = if boundary { 4 } else { 6 };
        before += (n - target).abs();
        after += (n + change - target).abs();
    }
    after < before
}

/// Whether the edge c–d a flip would make exists already (flipping would duplicate it).
fn flip_exists(he: &Halfedges, [_, _, c, d]: [u32; 4], s: &mut Scratch) -> bool {
    he.ring(c, &mut s.c);
    s.c.contains(&d)
}

/// Whether the faces (a, d, c) and (b, c, d) that a flip would make fold against each
/// other or against the faces they replace, or are degenerate.
fn flip_folds(he: &Halfedges, h: u32) -> bool {
    let o = he.opp(h);
    let [a, b, c, d] = [he.from(h), he.to(h), he.from(prev(h)), he.from(prev(o))].map(|v| he.p(v));
    let old = (b - a).cross(c - a).normalize_or_zero() + (a - b).cross(d - b).normalize_or_zero();
    let (m1, m2) = ((d - a).cross(c - a), (c - b).cross(d - b));
    let tiny = 1e-6 * (a - b).length_squared().max((c - d).length_squared());
    m1.length() <= tiny
        || m2.length() <= tiny
        || m1.dot(old) <= 0.0
        || m2.dot(old) <= 0.0
        || m1.dot(m2) <= 0.0
}

/// Area-weighted vertex normals of the live faces.
fn vertex_normals(he: &Halfedges) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; he.pos.len()];
    for f in 0..he.face_alive.len() {
        if he.face_alive[f] {
            let [a, b, c] = [0, 1, 2].map(|k| he.from[3 * f + k] as usize);
            let fnormal = (he.pos[b] - he.pos[a]).cross(he.pos[c] - he.pos[a]);
            for v in [a, b, c] {
                n[v] += fnormal;
            }
        }
    }
    n.into_iter().map(Vec3::normalize_or_zero).collect()
}

/// Moves every interior vertex towards the centroid of its one-ring within its tangent
/// plane, then onto the nearest point of the input surface. Boundary vertices stay.
pub(crate) fn relax_and_project(he: &mut Halfedges, reference: &TriangleBvh) {
    let normals = vertex_normals(he);
    let moved: Vec<Option<(Vec3, u32)>> = (0..he.pos.len() as u32)
        .into_par_iter()
        .map_init(Vec::new, |ring, v| {
            if !he.vertex_alive[v as usize] || he.is_boundary_vertex(v) {
                return None;
            }
            he.ring(v, ring);
            let centroid = ring.iter().map(|&w| he.p(w)).sum::<Vec3>() / ring.len().max(1) as f32;
            let p = he.p(v);
            let n = normals[v as usize];
            let step = centroid - p;
            let target = p + step - n * n.dot(step);
            let hit = reference.closest_point_near(target, he.hint[v as usize]);
            Some((hit.point, hit.triangle))
        })
        .collect();
    for (v, m) in moved.into_iter().enumerate() {
        if let Some((p, hint)) = m {
            he.pos[v] = p;
            he.hint[v] = hint;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::halfedge::tests::check;
    use super::*;
    use crate::mesh::test_meshes::cube;

    #[test]
    fn split_pass_keeps_the_structure_valid() {
        let mut he = Halfedges::from_mesh(&cube()).expect("manifold");
        for h in 0..he.halfedge_count() {
            if is_edge_representative(&he, h) {
                let mid = (he.p(he.from(h)) + he.p(he.to(h))) * 0.5;
                he.split(h, mid);
                check(&he);
                for f in 0..he.face_alive.len() {
                    let [a, b, c] = [0, 1, 2].map(|k| he.p(he.from[3 * f + k]));
                    assert!(
                        (b - a).cross(c - a).length() > 1e-6,
                        "face {f} after splitting {h}: {a} {b} {c}"
                    );
                }
            }
        }
    }

    #[test]
    fn passes_keep_the_structure_valid_and_shapes_sound() {
        let mut he = Halfedges::from_mesh(&cube()).expect("manifold");
        let high = 0.133;
        assert!(split_long_edges(&mut he, high) > 0);
        check(&he);
        for h in 0..he.halfedge_count() {
            assert!(!he.face_is_alive(h) || length_squared(&he, h) <= high * high);
        }
        let mut s = Scratch::default();
        equalize_valences(&mut he, &mut s);
        check(&he);
        collapse_short_edges(&mut he, 0.1, high, &mut s);
        check(&he);
        for f in 0..he.face_alive.len() {
            if he.face_alive[f] {
                let [a, b, c] = [0, 1, 2].map(|k| he.p(he.from[3 * f + k]));
                assert!((b - a).cross(c - a).length() > 1e-4, "face {f}: {a} {b} {c}");
            }
        }
    }
}
