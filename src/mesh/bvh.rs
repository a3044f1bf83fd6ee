//! Nearest point on a triangle mesh, through a bounding-volume hierarchy.
//!
//! obvhs answers ray queries but not nearest-point queries, which the remesher needs to
//! project vertices back onto the input surface; this small binary BVH (median splits,
//! up to four triangles a leaf) does that, with an optional hint triangle whose distance
//! bounds the search from the start: a vertex that moved a little is usually still
//! nearest to the triangle it was projected onto last time.

use super::Mesh;
use glam::Vec3;

const LEAF_SIZE: usize = 4;

/// A BVH over the triangles of a mesh, answering nearest-point queries.
#[derive(Clone, Debug)]
pub struct TriangleBvh {
    nodes: Vec<Node>,
    /// Triangle corners in leaf order.
    corners: Vec<[Vec3; 3]>,
    /// The mesh's index of each triangle in leaf order.
    ids: Vec<u32>,
    /// Where each mesh triangle sits in leaf order (for hints).
    slot_of: Vec<u32>,
}

#[derive(Clone, Copy, Debug)]
struct Node {
    min: Vec3,
    max: Vec3,
    /// First child (the second is `first + 1`) for an inner node; first triangle for a leaf.
    first: u32,
    /// Number of triangles of a leaf; 0 for an inner node.
    count: u32,
}

/// The answer to a nearest-point query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPoint {
    /// The nearest point on the surface.
    pub point: Vec3,
    /// The mesh triangle it lies on.
    pub triangle: u32,
    /// Squared distance from the query point.
    pub distance_squared: f32,
}

impl TriangleBvh {
    /// Builds the hierarchy over `mesh`'s triangles.
    pub fn new(mesh: &Mesh) -> TriangleBvh {
        let all: Vec<[Vec3; 3]> = (0..mesh.face_count()).map(|f| mesh.triangle_positions(f)).collect();
        let mut order: Vec<u32> = (0..all.len() as u32).collect();
        let centroids: Vec<Vec3> = all.iter().map(|t| (t[0] + t[1] + t[2]) / 3.0).collect();
        let mut nodes = vec![Node { min: Vec3::ZERO, max: Vec3::ZERO, first: 0, count: 0 }];
        build(&mut nodes, 0, &mut order, 0, &all, &centroids);
        let corners = order.iter().map(|&i| all[i as usize]).collect();
        let mut slot_of = vec![0; order.len()];
        for (slot, &id) in order.iter().enumerate() {
            slot_of[id as usize] = slot as u32;
        }
        TriangleBvh { nodes, corners, ids: order, slot_of }
    }

    /// The nearest point on the surface to `p`.
    pub fn closest_point(&self, p: Vec3) -> ClosestPoint {
        self.search(p, None)
    }

    /// The nearest point on the surface to `p`, starting from the bound that mesh
    /// triangle `hint` gives (faster when `hint` is near; any valid index is correct).
    pub fn closest_point_near(&self, p: Vec3, hint: u32) -> ClosestPoint {
        self.search(p, self.slot_of.get(hint as usize).copied())
    }

    fn search(&self, p: Vec3, hint: Option<u32>) -> ClosestPoint {
        let mut best = (f32::INFINITY, Vec3::ZERO, 0u32);
        if let Some(slot) = hint {
            self.consider(p, slot as usize, &mut best);
        }
        let mut stack = [0u32; 64];
        let mut depth = 1;
        while depth > 0 {
            depth -= 1;
            let node = self.nodes[stack[depth] as usize];
            if box_distance_squared(p, &node) >= best.0 {
                continue;
            }
            if node.count > 0 {
                for slot in node.first..node.first + node.count {
                    self.consider(p, slot as usize, &mut best);
                }
                continue;
            }
            let (a, b) = (node.first, node.first + 1);
            let (da, db) = (
                box_distance_squared(p, &self.nodes[a as usize]),
                box_distance_squared(p, &self.nodes[b as usize]),
            );
            // Nearer child on top, so it is searched first and tightens the bound.
            let (near, far) = if da <= db { (a, b) } else { (b, a) };
            stack[depth] = far;
            stack[depth + 1] = near;
            depth += 2;
        }
        ClosestPoint {
            point: best.1,
            triangle: self.ids.get(best.2 as usize).copied().unwrap_or(0),
            distance_squared: best.0,
        }
    }

    fn consider(&self, p: Vec3, slot: usize, best: &mut (f32, Vec3, u32)) {
        let [a, b, c] = self.corners[slot];
        let q = closest_on_triangle(p, a, b, c);
        let d = q.distance_squared(p);
        if d < best.0 {
            *best = (d, q, slot as u32);
        }
    }
}

/// Fills node `at` with the triangles `order[..]` (which start at leaf slot `offset`),
/// splitting at the median centroid along the widest axis until leaves are small. The
/// depth stays below 64 because every split halves the range.
fn build(
    nodes: &mut Vec<Node>,
    at: usize,
    order: &mut [u32],
    offset: u32,
    tris: &[[Vec3; 3]],
    centroids: &[Vec3],
) {
    let (min, max) = order
        .iter()
        .flat_map(|&i| tris[i as usize])
        .fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
    if order.len() <= LEAF_SIZE {
        nodes[at] = Node { min, max, first: offset, count: order.len() as u32 };
        return;
    }
    let (cmin, cmax) = order
        .iter()
        .map(|&i| centroids[i as usize])
        .fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
    let axis = (cmax - cmin).max_position();
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&i, &j| {
        let (ci, cj) = (centroids[i as usize][axis], centroids[j as usize][axis]);
        ci.total_cmp(&cj).then(i.cmp(&j))
    });
    let first = nodes.len();
    nodes[at] = Node { min, max, first: first as u32, count: 0 };
    nodes.push(nodes[at]);
    nodes.push(nodes[at]);
    let (left, right) = order.split_at_mut(mid);
    build(nodes, first, left, offset, tris, centroids);
    build(nodes, first + 1, right, offset + mid as u32, tris, centroids);
}

fn box_distance_squared(p: Vec3, node: &Node) -> f32 {
    let d = (node.min - p).max(p - node.max).max(Vec3::ZERO);
    d.length_squared()
}

/// The point of triangle `abc` nearest to `p` (Ericson, *Real-Time Collision Detection*,
/// §5.1.5: find the Voronoi region of `p` among vertices, edges and face).
pub fn closest_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() <= f32::MIN_POSITIVE {
        return a; // degenerate triangle; cannot occur in a valid Mesh
    }
    a + ab * (vb / denom) + ac * (vc / denom)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::test_meshes::{cube, grid};

    #[test]
    fn triangle_regions() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let inside = closest_on_triangle(Vec3::new(0.2, 0.2, 1.0), a, b, c);
        assert!(inside.distance(Vec3::new(0.2, 0.2, 0.0)) < 1e-6);
        assert_eq!(closest_on_triangle(Vec3::new(-1.0, -1.0, 0.0), a, b, c), a);
        assert_eq!(closest_on_triangle(Vec3::new(0.5, -1.0, 0.0), a, b, c), Vec3::new(0.5, 0.0, 0.0));
        let on_hyp = closest_on_triangle(Vec3::new(1.0, 1.0, 0.0), a, b, c);
        assert!(on_hyp.distance(Vec3::new(0.5, 0.5, 0.0)) < 1e-6);
    }

    #[test]
    fn matches_brute_force_on_a_cube_and_a_grid() {
        for mesh in [cube(), grid(9)] {
            let bvh = TriangleBvh::new(&mesh);
            for k in 0..200 {
                let t = k as f32;
                let p = Vec3::new((t * 0.37).sin(), (t * 0.71).cos(), (t * 0.13).sin()) * 1.5 + 0.5;
                let brute = (0..mesh.face_count())
                    .map(|f| {
                        let [a, b, c] = mesh.triangle_positions(f);
                        closest_on_triangle(p, a, b, c).distance_squared(p)
                    })
                    .fold(f32::INFINITY, f32::min);
                let found = bvh.closest_point(p);
                assert!((found.distance_squared - brute).abs() <= 1e-6, "{p}");
                let hinted = bvh.closest_point_near(p, (k % mesh.face_count()) as u32);
                assert!((hinted.distance_squared - brute).abs() <= 1e-6, "{p}");
                let [a, b, c] = mesh.triangle_positions(found.triangle as usize);
                assert!(closest_on_triangle(p, a, b, c).distance(found.point) < 1e-6);
            }
        }
    }
}
