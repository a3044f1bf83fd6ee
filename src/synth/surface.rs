//! Targets on a triangle mesh (Tong et al. 2002 §5.1, Fig. 4; §5.2): per vertex, the
//! triangles around it are flattened into its (s, t) plane, the square neighbourhood
//! template is resampled from that patch (each pixel a surface texton: three vertices and
//! barycentric weights), and the patch vertices inside the template become the forward
//! shifts of the k-coherence candidate set.
//!
//! Conventions are those of [`super::target`]: template pixel (i, j) sits at offset
//! (dx, dy) = (i − r, j − r) texels; x runs along s and y runs *down* t (image rows), so the
//! surface point of offset (dx, dy) is `v + texel·(dx·s − dy·t)`.

use super::target::{Neighbourhoods, ParentLink, Shift, Slot, TargetLevel};
use crate::mesh::bvh::TriangleBvh;
use crate::mesh::frames::Frames;
use crate::mesh::topology::{edge_incidences, one_rings, VertexRings};
use crate::mesh::Mesh;
use crate::{Error, Result};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::collections::VecDeque;
use std::f32::consts::TAU;

/// No face across this edge (a boundary, or a non-manifold edge, where flattening stops).
const NO_FACE: u32 = u32::MAX;

/// Barycentric weights may dip this far below 0 for a pixel on an edge or corner.
const INSIDE_TOLERANCE: f32 = 1e-5;

/// Offsets within this many texels of the template's edge still count as inside it.
const SQUARE_TOLERANCE: f32 = 1e-3;

/// The level of a mesh whose template pixels are `texel` apart on the surface: per vertex
/// a `template × template` square of slots resampled from its flattened patch, and the
/// patch vertices inside that square with their offsets. Parents are left empty (see
/// [`link_levels`]).
pub fn surface_level(mesh: &Mesh, frames: &Frames, texel: f32, template: usize) -> Result<TargetLevel> {
    check_frames(mesh, frames, "mesh")?;
    if !(texel.is_finite() && texel > 0.0) {
        return Err(Error::invalid(format!("texel size must be positive and finite, got {texel}")));
    }
    if template % 2 == 0 {
        return Err(Error::invalid(format!("template side must be odd, got {template}")));
    }
    let topology = Topology::new(mesh);
    let r = template / 2;
    // A triangle can overlap the template's square only if one of its corners lies within
    // the square's circumradius plus one of its edges.
    let reach = r as f32 * texel * std::f32::consts::SQRT_2;
    let per_vertex: Vec<(Vec<Slot>, Vec<Shift>)> = (0..mesh.vertex_count())
        .into_par_iter()
        .map_init(
            || Patch::new(mesh),
            |patch, v| {
                flatten(mesh, frames, &topology, v as u32, reach, patch);
                (resample(mesh, patch, v as u32, texel, r), patch_shifts(patch, texel, r))
            },
        )
        .collect();
    let mut slots = Vec::with_capacity(mesh.vertex_count() * template * template);
    let (mut shift_start, mut shifts) = (vec![0u32], Vec::new());
    for (vertex_slots, vertex_shifts) in per_vertex {
        slots.extend(vertex_slots);
        shifts.extend(vertex_shifts);
        shift_start.push(shifts.len() as u32);
    }
    Ok(TargetLevel::new(mesh.vertex_count(), Neighbourhoods::Mesh { template, slots, shift_start, shifts }))
}

fn check_frames(mesh: &Mesh, frames: &Frames, name: &str) -> Result<()> {
    if frames.len() != mesh.vertex_count() {
        return Err(Error::invalid(format!(
            "{name}: {} frames for {} vertices",
            frames.len(),
            mesh.vertex_count()
        )));
    }
    Ok(())
}

/// What flattening needs of the connectivity, built once per mesh.
pub(super) struct Topology {
    rings: VertexRings,
    /// CSR: the faces around vertex v are `vertex_faces[face_start[v]..face_start[v + 1]]`.
    face_start: Vec<usize>,
    vertex_faces: Vec<u32>,
    /// Per face, the face across edge k (corners k → k + 1), or [`NO_FACE`].
    across: Vec<[u32; 3]>,
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
        Topology { rings: one_rings(mesh), face_start, vertex_faces, across: across(triangles) }
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
    /// Faces in the order they were reached (the vertex's own faces first).
    pub(super) faces: Vec<u32>,
    /// Vertices in the order they were placed (the centre first).
    order: Vec<u32>,
    generation: u32,
    /// Per mesh vertex: the generation that placed it, and where.
    placed: Vec<u32>,
    uv: Vec<Vec2>,
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
            reached: vec![0; mesh.face_count()],
        }
    }

    /// Empties the patch for the next vertex.
    fn restart(&mut self) {
        self.faces.clear();
        self.order.clear();
        self.generation += 1;
    }

    fn uv_of(&self, vertex: u32) -> Option<Vec2> {
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

/// Flattens the triangles around `v` into `patch` (Tong §5.1 after Turk / Wei-Levoy): the
/// one-ring by a discrete exponential map, then breadth-first across shared edges, each new
/// vertex placed rigidly against the edge it was reached over, until the triangles lie
/// beyond `reach` (plus one edge) of `v`.
pub(super) fn flatten(
    mesh: &Mesh,
    frames: &Frames,
    topology: &Topology,
    v: u32,
    reach: f32,
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
        patch.faces.push(f);
        let Some(corners) = patch.corners(mesh, f) else { continue };
        if !within_reach(&corners, reach) || !within_reach_in_space(mesh, f, v, reach) {
            continue;
        }
        for &g in &topology.across[f as usize] {
            if g != NO_FACE && patch.reach(g) {
                place_apex(mesh, g, patch);
                queue.push_back(g);
            }
        }
    }
}

/// Whether a flattened triangle may still reach into the template, so that its
/// neighbours are worth flattening too.
fn within_reach(corners: &[Vec2; 3], reach: f32) -> bool {
    let nearest = corners.iter().map(|c| c.length()).fold(f32::INFINITY, f32::min);
    let longest = (0..3).map(|k| corners[k].distance(corners[(k + 1) % 3])).fold(0.0, f32::max);
    nearest <= reach + longest
}

/// Whether face `f` may still reach into the template measured in space: a straight line
/// is never longer than a path on the surface, so a face beyond reach in space is beyond
/// it on the surface too, however the flattening (which closes loops inconsistently around
/// cones and handles) has placed it.
fn within_reach_in_space(mesh: &Mesh, f: u32, v: u32, reach: f32) -> bool {
    let p = mesh.positions();
    let t = mesh.triangles()[f as usize].map(|c| p[c as usize]);
    let nearest = t.iter().map(|c| c.distance(p[v as usize])).fold(f32::INFINITY, f32::min);
    let longest = (0..3).map(|k| t[k].distance(t[(k + 1) % 3])).fold(0.0, f32::max);
    nearest <= reach + longest
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
fn place_apex(mesh: &Mesh, g: u32, patch: &mut Patch) {
    let t = mesh.triangles()[g as usize];
    let p = mesh.positions();
    for k in 0..3 {
        let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
        if patch.uv_of(c).is_some() {
            continue;
        }
        let (Some(pa), Some(pb)) = (patch.uv_of(a), patch.uv_of(b)) else { continue };
        let (ab, ac) = (p[b as usize] - p[a as usize], p[c as usize] - p[a as usize]);
        let direction = (pb - pa).try_normalize().unwrap_or(Vec2::X);
        let turn = Vec2::from_angle(ab.angle_between(ac));
        patch.place(c, pa + direction.rotate(turn) * ac.length());
        return;
    }
}

/// The template of `v` resampled from its patch: each pixel takes the barycentric
/// coordinates of the first patch face (in breadth-first order, so the least distorted)
/// that contains it, or the default texton.
fn resample(mesh: &Mesh, patch: &Patch, v: u32, texel: f32, r: usize) -> Vec<Slot> {
    let side = 2 * r + 1;
    let ri = r as i64;
    let mut slots = vec![Slot::DEFAULT; side * side];
    for &f in &patch.faces {
        let Some(corners) = patch.corners(mesh, f) else { continue };
        // Corners in texel offsets: x along s, y down t.
        let offsets = corners.map(|c| Vec2::new(c.x / texel, -c.y / texel));
        let lo = offsets.iter().fold(Vec2::INFINITY, |m, &o| m.min(o));
        let hi = offsets.iter().fold(Vec2::NEG_INFINITY, |m, &o| m.max(o));
        let (x0, x1) = ((lo.x.floor() as i64).max(-ri), (hi.x.ceil() as i64).min(ri));
        let (y0, y1) = ((lo.y.floor() as i64).max(-ri), (hi.y.ceil() as i64).min(ri));
        for dy in y0..=y1 {
            for dx in x0..=x1 {
                let i = ((dy + ri) as usize) * side + (dx + ri) as usize;
                if slots[i] != Slot::DEFAULT {
                    continue;
                }
                let q = Vec2::new(dx as f32, dy as f32);
                if let Some(weights) = barycentric(q, &offsets) {
                    slots[i] = slot(mesh.triangles()[f as usize], weights);
                }
            }
        }
    }
    // v sits at the centre even when no (non-degenerate) face around it does.
    if slots[r * side + r] == Slot::DEFAULT {
        slots[r * side + r] = Slot::at(v);
    }
    slots
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

/// The patch vertices inside the template's square with their offsets in texels (the
/// centre first, at offset 0).
fn patch_shifts(patch: &Patch, texel: f32, r: usize) -> Vec<Shift> {
    let limit = r as f32 + SQUARE_TOLERANCE;
    patch
        .order
        .iter()
        .filter_map(|&u| {
            let c = patch.uv_of(u)?;
            let offset = [c.x / texel, -c.y / texel];
            (offset[0].abs() <= limit && offset[1].abs() <= limit).then_some((u, offset))
        })
        .collect()
}

/// Links each vertex of `fine_level` to the coarser level (Tong §5.1, multi-resolution):
/// its parent is a corner of the coarse triangle nearest to it, with the offset from that
/// corner in fine texels, and its parent template is that corner's template in
/// `coarse_parent_templates` (a [`surface_level`] of `coarse` at twice `fine_texel`, which
/// the fine level keeps).
///
/// Tong casts along the normal; the nearest point is used instead because it always
/// exists (a ray can miss a coarse mesh that lies just inside a convex fine surface, or
/// hit a far sheet first in a thin part), and the two agree where the meshes are close,
/// as successive remeshed levels are.
pub fn link_levels(
    fine: &Mesh,
    fine_frames: &Frames,
    fine_level: &mut TargetLevel,
    coarse: &Mesh,
    coarse_frames: &Frames,
    coarse_parent_templates: TargetLevel,
    fine_texel: f32,
) -> Result<()> {
    check_frames(fine, fine_frames, "fine mesh")?;
    check_frames(coarse, coarse_frames, "coarse mesh")?;
    if fine_level.vertices != fine.vertex_count() || coarse_parent_templates.vertices != coarse.vertex_count()
    {
        return Err(Error::invalid("link_levels: the levels do not belong to the given meshes"));
    }
    if !(fine_texel.is_finite() && fine_texel > 0.0) || coarse.face_count() == 0 {
        return Err(Error::invalid("link_levels: needs a positive texel size and a coarse mesh with faces"));
    }
    let bvh = TriangleBvh::new(coarse);
    let parents: Vec<ParentLink> =
        fine.positions().par_iter().map(|&p| parent_of(p, coarse, coarse_frames, &bvh, fine_texel)).collect();
    fine_level.parent_template = coarse_parent_templates.template;
    fine_level.parent_neighbourhoods = Some(coarse_parent_templates.neighbourhoods);
    fine_level.parents = parents;
    Ok(())
}

/// The parent link of the fine point `p`. A coarse vertex stands for fine texels
/// 2u and 2u + 1 (as on a grid), so corners are compared by the centre of that footprint,
/// half a fine texel along +x and +y; this also settles the exact ties of regular meshes the
/// way grids do.
fn parent_of(p: Vec3, coarse: &Mesh, frames: &Frames, bvh: &TriangleBvh, fine_texel: f32) -> ParentLink {
    let hit = bvh.closest_point(p);
    let corners = coarse.triangles()[hit.triangle as usize];
    let footprint = |c: u32| {
        let (s, t) = (frames.s[c as usize], frames.t[c as usize]);
        coarse.positions()[c as usize] + 0.5 * fine_texel * (s - t)
    };
    let vertex = corners
        .into_iter()
        .min_by(|&a, &b| {
            footprint(a).distance_squared(hit.point).total_cmp(&footprint(b).distance_squared(hit.point))
        })
        .unwrap_or(corners[0]);
    let d = p - coarse.positions()[vertex as usize];
    let (s, t) = (frames.s[vertex as usize], frames.t[vertex as usize]);
    ParentLink { vertex, offset: [d.dot(s) / fine_texel, -d.dot(t) / fine_texel] }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::synth::target::{grid_levels, OUTSIDE};

    /// A w × h grid in z = 0 with `spacing` between vertices; vertex (x, y) is index
    /// y·w + x at (x, −y)·spacing, so rows run down t = +y as image rows do, and its frames
    /// are s = +x, t = +y, n = +z.
    pub(crate) fn flat_grid(w: u32, h: u32, spacing: f32) -> (Mesh, Frames) {
        let at = |x: u32, y: u32| y * w + x;
        let positions = (0..h)
            .flat_map(|y| (0..w).map(move |x| Vec3::new(x as f32, -(y as f32), 0.0) * spacing))
            .collect();
        let mut triangles = Vec::new();
        for y in 0..h - 1 {
            for x in 0..w - 1 {
                // Counter-clockwise seen from +z.
                triangles.push([at(x, y), at(x, y + 1), at(x + 1, y + 1)]);
                triangles.push([at(x, y), at(x + 1, y + 1), at(x + 1, y)]);
            }
        }
        let mesh = Mesh::new(positions, triangles).expect("the grid is valid");
        let n = mesh.vertex_count();
        let frames = Frames::from_directions(&vec![Vec3::Z; n], &vec![Vec3::X; n]);
        (mesh, frames)
    }

    /// The vertex a slot falls on, if it carries (almost) all the weight.
    fn on_vertex(slot: &Slot) -> Option<u32> {
        (0..3).find(|&k| slot.weights[k] > 1.0 - 1e-4).map(|k| slot.vertices[k])
    }

    fn interior(w: u32, h: u32, margin: u32) -> impl Iterator<Item = usize> {
        (margin..h - margin).flat_map(move |y| (margin..w - margin).map(move |x| (y * w + x) as usize))
    }

    #[test]
    fn flat_grid_matches_grid_levels() {
        let (w, h, template) = (9, 8, 5);
        let (mesh, frames) = flat_grid(w, h, 0.5);
        let level = surface_level(&mesh, &frames, 0.5, template).expect("valid");
        let grid = &grid_levels(w as usize, h as usize, 1, template, 3)[0];
        let (mut a, mut b, mut c, mut d) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for v in interior(w, h, 2) {
            let got: Vec<Option<u32>> = level.slots_of(v, &mut a).iter().map(on_vertex).collect();
            let want: Vec<Option<u32>> = grid.slots_of(v, &mut b).iter().map(on_vertex).collect();
            assert_eq!(got, want, "slots of vertex {v}");
            let mut got = level.shifts_of(v, &mut c).to_vec();
            let mut want = grid.shifts_of(v, &mut d).to_vec();
            got.sort_by_key(|s| s.0);
            want.sort_by_key(|s| s.0);
            assert_eq!(got.len(), want.len(), "shifts of vertex {v}");
            for ((gv, go), (wv, wo)) in got.iter().zip(&want) {
                assert_eq!(gv, wv);
                assert!((go[0] - wo[0]).abs() < 1e-4 && (go[1] - wo[1]).abs() < 1e-4, "{go:?} vs {wo:?}");
            }
        }
        // Past the mesh's edge the surface has the default texton.
        assert_eq!(level.slots_of(0, &mut a)[0], Slot::DEFAULT);
    }

    #[test]
    fn off_vertex_pixels_interpolate_within_one_face() {
        // Texel 0.75 of a unit grid: pixel (1, 0) of vertex (2, 2) is at x = 2.75, y = 2.
        let (mesh, frames) = flat_grid(6, 6, 1.0);
        let level = surface_level(&mesh, &frames, 0.75, 3).expect("valid");
        let slot = level.slots_of(14, &mut Vec::new())[5];
        let mut pairs: Vec<(u32, f32)> = slot.vertices.into_iter().zip(slot.weights).collect();
        pairs.retain(|p| p.1 > 1e-6);
        pairs.sort_by_key(|p| p.0);
        assert_eq!(pairs.len(), 2, "{slot:?}");
        assert_eq!((pairs[0].0, pairs[1].0), (14, 15));
        assert!((pairs[0].1 - 0.25).abs() < 1e-5 && (pairs[1].1 - 0.75).abs() < 1e-5);
    }

    pub(crate) fn bunny() -> (Mesh, Frames, f32) {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/bunny-1k8.obj");
        let mesh = crate::mesh::load(std::path::Path::new(path)).expect("bundled mesh").with_normals();
        let normals = mesh.normals().expect("computed").to_vec();
        let frames = Frames::from_directions(&normals, &vec![Vec3::X; normals.len()]);
        let edges = crate::mesh::topology::edges(&mesh);
        let p = mesh.positions();
        let texel = edges.iter().map(|[a, b]| p[*a as usize].distance(p[*b as usize])).sum::<f32>()
            / edges.len() as f32;
        (mesh, frames, texel)
    }

    #[test]
    fn same_level_whatever_the_thread_count() {
        let (mesh, frames, texel) = bunny();
        let many = surface_level(&mesh, &frames, texel, 5).expect("valid");
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a pool");
        let one = pool.install(|| surface_level(&mesh, &frames, texel, 5)).expect("valid");
        assert_eq!(many, one);
    }

    #[test]
    fn bunny_slots_are_convex_combinations() {
        let (mesh, frames, texel) = bunny();
        let p = mesh.positions();
        let template = 5;
        let level = surface_level(&mesh, &frames, texel, template).expect("valid");
        let Neighbourhoods::Mesh { slots: all_slots, .. } = &level.neighbourhoods else {
            panic!("a mesh level")
        };
        assert_eq!(all_slots.len(), mesh.vertex_count() * template * template);
        let (mut scratch, mut shift_scratch) = (Vec::new(), Vec::new());
        let limit = (template / 2) as f32 + SQUARE_TOLERANCE;
        let (mut default, mut folded, mut shifted) = (0, 0, 0);
        for v in 0..mesh.vertex_count() {
            for s in level.slots_of(v, &mut scratch) {
                if s.vertices[0] == OUTSIDE {
                    default += 1;
                    continue;
                }
                assert!(s.weights.iter().all(|&w| w >= -1e-4), "{s:?}");
                assert!((s.weights.iter().sum::<f32>() - 1.0).abs() < 1e-4, "{s:?}");
            }
            let centre = level.slots_of(v, &mut scratch)[template * template / 2];
            let on_v: f32 =
                (0..3).filter(|&k| centre.vertices[k] == v as u32).map(|k| centre.weights[k]).sum();
            assert!(on_v >= 0.99, "centre of {v}: {centre:?}");
            let shifts = level.shifts_of(v, &mut shift_scratch);
            assert_eq!(shifts[0], (v as u32, [0.0, 0.0]));
            assert!(shifts.iter().all(|(_, o)| o[0].abs() <= limit && o[1].abs() <= limit));
            // Unfolding lays paths on the surface flat, so nothing should land much nearer
            // than it is in space, as it would on a face folded back over its edge.
            for &(u, o) in &shifts[1..] {
                let chord = p[u as usize].distance(p[v]);
                folded += usize::from(Vec2::from(o).length() * texel < 0.8 * chord);
                shifted += 1;
            }
        }
        // About 1% (sharp cones, where the exponential map stretches angles); a face
        // flattened onto the wrong side of its edge folds nearly 90%.
        assert!(folded * 50 < shifted, "{folded} of {shifted} shifts folded back");
        // The patches cover the templates almost everywhere on a closed-ish mesh.
        assert!(default * 20 < all_slots.len(), "{default} default slots");
    }

    #[test]
    fn link_levels_matches_grid_parents() {
        let (w, h) = (9, 9);
        let (fine, fine_frames) = flat_grid(w, h, 1.0);
        let (coarse, coarse_frames) = flat_grid(w.div_ceil(2), h.div_ceil(2), 2.0);
        let mut level = surface_level(&fine, &fine_frames, 1.0, 5).expect("valid");
        let coarse_templates = surface_level(&coarse, &coarse_frames, 2.0, 3).expect("valid");
        link_levels(&fine, &fine_frames, &mut level, &coarse, &coarse_frames, coarse_templates, 1.0)
            .expect("valid");
        let grid = &grid_levels(w as usize, h as usize, 2, 5, 3)[0];
        assert_eq!(level.parent_template, 3);
        for v in interior(w, h, 1) {
            let (got, want) = (level.parents[v], grid.parents[v]);
            assert_eq!(got.vertex, want.vertex, "parent of {v}");
            assert!((got.offset[0] - want.offset[0]).abs() < 1e-5, "{got:?} vs {want:?}");
            assert!((got.offset[1] - want.offset[1]).abs() < 1e-5, "{got:?} vs {want:?}");
        }
        // Parent templates are the coarse vertices' own (interior ones match the grid's).
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for v in interior(w, h, 3) {
            let got: Vec<Option<u32>> = level.parent_slots_of(v, &mut a).iter().map(on_vertex).collect();
            let want: Vec<Option<u32>> = grid.parent_slots_of(v, &mut b).iter().map(on_vertex).collect();
            assert_eq!(got, want, "parent slots of {v}");
        }
    }

    #[test]
    fn rejects_bad_arguments() {
        let (mesh, frames) = flat_grid(3, 3, 1.0);
        assert!(surface_level(&mesh, &frames, 0.0, 3).is_err());
        assert!(surface_level(&mesh, &frames, 1.0, 4).is_err());
        let (other, other_frames) = flat_grid(2, 2, 1.0);
        assert!(surface_level(&mesh, &other_frames, 1.0, 3).is_err());
        let mut level = surface_level(&mesh, &frames, 1.0, 3).expect("valid");
        let coarse = surface_level(&other, &other_frames, 2.0, 3).expect("valid");
        assert!(link_levels(&mesh, &frames, &mut level, &other, &frames, coarse, 1.0).is_err());
    }
}
