//! Flattening a mesh around a vertex into its tangent plane (a discrete exponential map of
//! the one-ring, grown outward across edges), and barycentric lookups in the flattened
//! faces: what the square templates ([`super::surface`]) and the round neighbourhoods
//! ([`super::round`]) are both resampled from.

use super::slot::Slot;
use crate::mesh::frames::Frames;
use crate::mesh::topology::{edge_incidences, one_rings, VertexRings};
use crate::mesh::Mesh;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::collections::VecDeque;
use std::f32::consts::TAU;

/// No face across this edge (a boundary, or a non-manifold edge, where flattening stops).
const NO_FACE: u32 = u32::MAX;

/// Barycentric weights may dip this far below 0 for a pixel on an edge or corner.
const INSIDE_TOLERANCE: f32 = 1e-5;

/// What flattening needs of the connectivity, built once per mesh.
pub(super) struct Topology {
    rings: VertexRings,
    /// CSR: the faces around vertex v are `vertex_faces[face_start[v]..face_start[v + 1]]`.
    face_start: Vec<usize>,
    vertex_faces: Vec<u32>,
    /// Per face, the face across edge k (corners k → k + 1), or [`NO_FACE`].
    across: Vec<[u32; 3]>,
    /// Per face, what flattening measures of it in space. A face is flattened into the
    /// patches of a hundred or more vertices; measuring it once saves those patches their
    /// arc cosines, sines and square roots (the same calls on the same values: the same
    /// bits).
    shapes: Vec<FaceShape>,
}

/// The measures of one face in space that flattening uses.
struct FaceShape {
    /// Per corner k (a = corner k, b = k + 1, c = k + 2): the rotation by the angle at a
    /// from a → b to a → c, and the length of a → c; what places c against edge a → b.
    apex: [(Vec2, f32); 3],
    /// The longest of its edges.
    longest: f32,
}

impl FaceShape {
    fn of(p: &[Vec3], t: [u32; 3]) -> FaceShape {
        let corner = |k: usize| p[t[k] as usize];
        let apex = std::array::from_fn(|k| {
            let (ab, ac) = (corner((k + 1) % 3) - corner(k), corner((k + 2) % 3) - corner(k));
            (Vec2::from_angle(ab.angle_between(ac)), ac.length())
        });
        let longest = (0..3).map(|k| corner(k).distance(corner((k + 1) % 3))).fold(0.0, f32::max);
        FaceShape { apex, longest }
    }
}

impl Topology {
    pub(super) fn new(mesh: &Mesh) -> Topology {
        let triangles = mesh.triangles();
        let mut face_start = vec![0usize; mesh.vertex_count() + 1];
        for t in triangles {
            for &c in t {
                face_start[c as usize + 1] += 1;
            }
        }
        for v in 0..mesh.vertex_count() {
            face_start[v + 1] += face_start[v];
        }
        let mut fill = face_start.clone();
        let mut vertex_faces = vec![0u32; face_start[mesh.vertex_count()]];
        for (f, t) in triangles.iter().enumerate() {
            for &c in t {
                vertex_faces[fill[c as usize]] = f as u32;
                fill[c as usize] += 1;
            }
        }
        let p = mesh.positions();
        let ((rings, across), shapes) = rayon::join(
            || rayon::join(|| one_rings(mesh), || across(triangles)),
            || triangles.par_iter().map(|&t| FaceShape::of(p, t)).collect(),
        );
        Topology { rings, face_start, vertex_faces, across, shapes }
    }

    fn faces_of(&self, v: u32) -> &[u32] {
        &self.vertex_faces[self.face_start[v as usize]..self.face_start[v as usize + 1]]
    }
}

/// Face adjacency across edges; an edge with other than two faces joins nothing.
fn across(triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let mut out = vec![[NO_FACE; 3]; triangles.len()];
    let edge_of = |f: u32, lo: u32, hi: u32| {
        let t = triangles[f as usize];
        (0..3).find(|&k| t[k].min(t[(k + 1) % 3]) == lo && t[k].max(t[(k + 1) % 3]) == hi).unwrap_or(0)
    };
    for group in edge_incidences(triangles).chunk_by(|a, b| a.key() == b.key()) {
        if let [a, b] = group {
            out[a.face as usize][edge_of(a.face, a.lo, a.hi)] = b.face;
            out[b.face as usize][edge_of(b.face, b.lo, b.hi)] = a.face;
        }
    }
    out
}

/// A flattened patch around one vertex, in (s, t) coordinates with the vertex at 0. One is
/// reused for every vertex a thread flattens: per-mesh arrays stamped with the patch's
/// generation stand in for maps and sets (hashing was most of the templates' time).
pub(super) struct Patch {
    /// Faces in the order they were reached (the vertex's own faces first), with their
    /// flattened corners.
    pub(super) faces: Vec<(u32, [Vec2; 3])>,
    /// Vertices in the order they were placed (the centre first).
    pub(super) order: Vec<u32>,
    generation: u32,
    /// Per mesh vertex: the generation that placed it, where, and how far from the centre.
    placed: Vec<u32>,
    uv: Vec<Vec2>,
    uv_length: Vec<f32>,
    /// Per mesh face: the generation that reached it.
    reached: Vec<u32>,
}

impl Patch {
    pub(super) fn new(mesh: &Mesh) -> Self {
        Patch {
            faces: Vec::new(),
            order: Vec::new(),
            generation: 0,
            placed: vec![0; mesh.vertex_count()],
            uv: vec![Vec2::ZERO; mesh.vertex_count()],
            uv_length: vec![0.0; mesh.vertex_count()],
            reached: vec![0; mesh.face_count()],
        }
    }

    /// Empties the patch for the next vertex.
    fn restart(&mut self) {
        self.faces.clear();
        self.order.clear();
        self.generation += 1;
    }

    pub(super) fn uv_of(&self, vertex: u32) -> Option<Vec2> {
        (self.placed[vertex as usize] == self.generation).then(|| self.uv[vertex as usize])
    }

    pub(super) fn corners(&self, mesh: &Mesh, f: u32) -> Option<[Vec2; 3]> {
        let t = mesh.triangles()[f as usize];
        Some([self.uv_of(t[0])?, self.uv_of(t[1])?, self.uv_of(t[2])?])
    }

    fn place(&mut self, vertex: u32, at: Vec2) {
        // A vertex reached twice (around a cone or a handle) keeps its first placement.
        if self.placed[vertex as usize] != self.generation {
            self.placed[vertex as usize] = self.generation;
            self.uv[vertex as usize] = at;
            self.uv_length[vertex as usize] = at.length();
            self.order.push(vertex);
        }
    }

    /// Marks face `f` reached; false if it already was.
    fn reach(&mut self, f: u32) -> bool {
        let first = self.reached[f as usize] != self.generation;
        self.reached[f as usize] = self.generation;
        first
    }
}

/// The part of the tangent plane a flattened patch must cover, about its vertex.
#[derive(Clone, Copy, Debug)]
pub(super) enum Cover {
    /// A disc of this radius (round neighbourhoods' circles).
    Disc(f32),
    /// A square of this half-side, its sides along s and t (square templates): 2/π of the
    /// disc around it, and so about half the faces to unfold and resample.
    Square(f32),
}

impl Cover {
    /// The radius of the disc about the vertex that holds the cover.
    fn radius(self) -> f32 {
        match self {
            Cover::Disc(r) => r,
            Cover::Square(half) => half * std::f32::consts::SQRT_2,
        }
    }

    /// Whether a flattened triangle may overlap the cover, so that its neighbours are
    /// worth flattening too. The faces a convex cover about the vertex overlaps are joined
    /// across edges that it overlaps, so the growth reaches all of them.
    fn may_overlap(self, patch: &Patch, face: [u32; 3], corners: &[Vec2; 3]) -> bool {
        match self {
            Cover::Disc(reach) => within_reach(patch, face, corners, reach),
            Cover::Square(half) => {
                let (lo, hi) = bounds(corners);
                lo.x <= half && hi.x >= -half && lo.y <= half && hi.y >= -half
            }
        }
    }
}

/// Flattens the triangles around `v` into `patch` (Tong §5.1 after Turk / Wei-Levoy): the
/// one-ring by a discrete exponential map, then breadth-first across shared edges, each new
/// vertex placed rigidly against the edge it was reached over, as long as the triangles
/// may overlap `cover` (the last ones reached may lie beyond it).
pub(super) fn flatten(
    mesh: &Mesh,
    frames: &Frames,
    topology: &Topology,
    v: u32,
    cover: Cover,
    patch: &mut Patch,
) {
    patch.restart();
    patch.place(v, Vec2::ZERO);
    unfold_ring(mesh, frames, topology, v, patch);
    let mut queue: VecDeque<u32> = VecDeque::new();
    for &f in topology.faces_of(v) {
        if patch.corners(mesh, f).is_some() && patch.reach(f) {
            queue.push_back(f);
        }
    }
    while let Some(f) = queue.pop_front() {
        let Some(corners) = patch.corners(mesh, f) else { continue };
        patch.faces.push((f, corners));
        if !cover.may_overlap(patch, mesh.triangles()[f as usize], &corners)
            || !within_reach_in_space(mesh, topology, f, v, cover.radius())
        {
            continue;
        }
        for &g in &topology.across[f as usize] {
            if g != NO_FACE && patch.reach(g) {
                place_apex(mesh, topology, g, patch);
                queue.push_back(g);
            }
        }
    }
}

/// Whether a flattened triangle may still reach into a disc of radius `reach`.
///
/// The test is `nearest <= reach + longest` with every distance as `distance` rounds it,
/// taken in fewer square roots: the longest edge is not needed where the nearest corner
/// is within reach (reach plus a length is never less than reach), and the square root
/// of the largest squared length is the largest of their square roots (it is monotone).
fn within_reach(patch: &Patch, face: [u32; 3], corners: &[Vec2; 3], reach: f32) -> bool {
    let nearest = face.iter().map(|&c| patch.uv_length[c as usize]).fold(f32::INFINITY, f32::min);
    nearest <= reach || {
        let longest = (0..3).map(|k| corners[k].distance_squared(corners[(k + 1) % 3])).fold(0.0, f32::max);
        nearest <= reach + longest.sqrt()
    }
}

/// Whether face `f` may still reach into the template measured in space: a straight line
/// is never longer than a path on the surface, so a face beyond reach in space is beyond
/// it on the surface too, however the flattening (which closes loops inconsistently around
/// cones and handles) has placed it.
fn within_reach_in_space(mesh: &Mesh, topology: &Topology, f: u32, v: u32, reach: f32) -> bool {
    let p = mesh.positions();
    let t = mesh.triangles()[f as usize].map(|c| p[c as usize]);
    // One square root, of the least squared distance: the least of the distances.
    let nearest = t.iter().map(|c| c.distance_squared(p[v as usize])).fold(f32::INFINITY, f32::min).sqrt();
    nearest <= reach + topology.shapes[f as usize].longest
}

/// Places the one-ring of `v`: each neighbour at its true distance, the angles between
/// neighbours scaled to sum to 2π (to at most 2π on a boundary, leaving an open fan), the
/// first neighbour at its angle from s in the tangent plane.
fn unfold_ring(mesh: &Mesh, frames: &Frames, topology: &Topology, v: u32, patch: &mut Patch) {
    let ring = topology.rings.ring(v as usize);
    let p = mesh.positions();
    let centre = p[v as usize];
    let Some(&first) = ring.first() else { return };
    // A closed fan of m neighbours has m faces, an open one m − 1.
    let closed = topology.faces_of(v).len() == ring.len() && ring.len() > 2;
    let gaps = if closed { ring.len() } else { ring.len() - 1 };
    let angles: Vec<f32> = (0..gaps)
        .map(|k| {
            (p[ring[k] as usize] - centre).angle_between(p[ring[(k + 1) % ring.len()] as usize] - centre)
        })
        // A zero-length edge has no angle; it then takes no room in the fan.
        .map(|a| if a.is_finite() { a } else { 0.0 })
        .collect();
    let total: f32 = angles.iter().sum();
    let scale = if closed || total > TAU { TAU / total.max(f32::EPSILON) } else { 1.0 };
    let (s, t) = (frames.s[v as usize], frames.t[v as usize]);
    let d = p[first as usize] - centre;
    let mut angle = d.dot(t).atan2(d.dot(s));
    for (k, &u) in ring.iter().enumerate() {
        if k > 0 {
            angle += angles[k - 1] * scale;
        }
        let length = (p[u as usize] - centre).length();
        patch.place(u, Vec2::from_angle(angle) * length);
    }
}

/// Places the one unplaced corner of face `g` (if any) against its opposite edge a → b:
/// at its true distance from a and its true angle at a, on the side that keeps the face
/// counter-clockwise. Anchoring at a (rather than intersecting circles around a and b)
/// stays well-defined when a and b were placed by different routes and the flat edge no
/// longer has its length; where it does, this is the rigid placement.
fn place_apex(mesh: &Mesh, topology: &Topology, g: u32, patch: &mut Patch) {
    let t = mesh.triangles()[g as usize];
    for k in 0..3 {
        let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
        if patch.uv_of(c).is_some() {
            continue;
        }
        let (Some(pa), Some(pb)) = (patch.uv_of(a), patch.uv_of(b)) else { continue };
        let (turn, length) = topology.shapes[g as usize].apex[k];
        let direction = (pb - pa).try_normalize().unwrap_or(Vec2::X);
        patch.place(c, pa + direction.rotate(turn) * length);
        return;
    }
}

/// The least and greatest coordinates of `points` (their bounding box).
pub(super) fn bounds(points: &[Vec2]) -> (Vec2, Vec2) {
    points.iter().fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)))
}

/// Barycentric weights of `q` in triangle `t`, if it lies inside (weights clamped to ≥ 0
/// and renormalised); `None` outside or for a degenerate triangle.
pub(super) fn barycentric(q: Vec2, t: &[Vec2; 3]) -> Option<[f32; 3]> {
    let area = (t[1] - t[0]).perp_dot(t[2] - t[0]);
    // NaN too: a patch vertex at NaN (from a zero-length edge) yields no slot.
    if area.is_nan() || area.abs() <= 1e-9 {
        return None;
    }
    let w1 = (q - t[0]).perp_dot(t[2] - t[0]) / area;
    let w2 = (t[1] - t[0]).perp_dot(q - t[0]) / area;
    let w = [1.0 - w1 - w2, w1, w2];
    if w.iter().any(|&x| x < -INSIDE_TOLERANCE) {
        return None;
    }
    let w = w.map(|x| x.max(0.0));
    let sum: f32 = w.iter().sum();
    Some(w.map(|x| x / sum))
}

/// A slot from a face and weights; a pixel on a vertex becomes [`Slot::at`], as on a grid.
pub(super) fn slot(face: [u32; 3], weights: [f32; 3]) -> Slot {
    match weights.iter().position(|&w| w >= 1.0 - INSIDE_TOLERANCE) {
        Some(k) => Slot::at(face[k]),
        None => Slot { vertices: face, weights },
    }
}
