//! A surface texton map ready to render: the mesh, its frames, per-vertex sample
//! coordinates, and the per-vertex blends of a shot, which both renderers use.

use super::blend::Nearest4;
use super::camera::Shot;
use super::material::{Blend16, Material};
use crate::mesh::frames::Frames;
use crate::mesh::Mesh;
use crate::synth::surface_map::{read_surface_ply, SurfaceMap, ANALYSIS_FINGERPRINT_KEY, ANALYSIS_KEY};
use crate::{Error, Remedy, Result};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// How a point between vertices is shaded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Mode {
    /// Tong §6: a colour per vertex, interpolated across each triangle.
    Vertex,
    /// Per pixel, one lookup of the sample at the pixel's synthesized coordinate
    /// ([`Scene::point_uv`]): each corner of the triangle predicts a coordinate (its own plus
    /// the pixel's offset in its tangent frame, in texels); corners that agree (one copy of
    /// the sample) are interpolated, and where they disagree (a seam between copies) one
    /// side is taken whole, cut along the seam smoothed over two rings of vertices. Shows
    /// sample-resolution detail between vertices, crisp inside copies and with a hard cut at
    /// seams, where blending the corners' lookups would blur and double the image.
    #[default]
    Pixel,
}

/// Corner predictions closer than this (in sample texels) show one copy of the sample and are
/// interpolated ([`Scene::point_uv`]). Inside a copy, predictions differ by the rounding of
/// each vertex's integer coordinate and the turn between neighbouring frames (under a texel);
/// across a seam between copies, by many texels.
pub const AGREE_TEXELS: f32 = 2.0;

/// What the renderers draw.
pub struct Scene {
    /// The mesh, with vertex normals.
    pub mesh: Mesh,
    /// One tangent frame per vertex (s, t, n): the sample's u grows along s, and its v
    /// (rows, running down) against t.
    pub frames: Frames,
    /// Per vertex, the sample coordinate (u along columns, v along rows) in texels.
    pub uv: Vec<Vec2>,
    /// Per vertex, the texton label (for false-colour display).
    pub labels: Vec<u16>,
    /// One sample texel in model units.
    pub texel: f32,
    /// A texture-mapped mesh (pattern mapping, [`crate::synth::patches`]): vertices split at
    /// texture seams, and pixel mode interpolates the corners' sample coordinates across each
    /// triangle, as a rasteriser does, instead of letting each corner predict from its tangent
    /// frame.
    pub mapped: bool,
    /// Per vertex, how much its neighbourhood continues its copy of the sample
    /// ([`Scene::belonging`]), worked out on first use (it needs the material's wrap).
    belonging: OnceLock<Vec<f32>>,
}

impl Scene {
    /// The scene of a synthesized surface map: its mesh, frames, sample coordinates, texton
    /// labels and texel size (not texture-mapped).
    pub fn from_surface_map(map: SurfaceMap) -> Scene {
        let uv = (0..map.state.uv.len()).map(|v| Vec2::from(map.state.coordinate(v))).collect();
        Scene::new(map.mesh, map.frames, uv, map.state.labels, map.texel)
    }

    /// A synthesized scene (not texture-mapped) from its parts: per vertex a frame, a sample
    /// coordinate and a texton label, and one sample texel in model units.
    pub fn new(mesh: Mesh, frames: Frames, uv: Vec<Vec2>, labels: Vec<u16>, texel: f32) -> Scene {
        Scene { mesh, frames, uv, labels, texel, mapped: false, belonging: OnceLock::new() }
    }

    /// A texture-mapped result: one vertex per distinct (vertex, sample coordinate) corner,
    /// with the normals of the welded surface (smooth across texture seams and across the
    /// file's own unwelded seams), frames whose s runs along the texture's columns, and the
    /// level of the cluster that textured each vertex as its label.
    pub fn from_uv_map(map: &crate::synth::patches::output::UvMap, path: &Path) -> Result<Scene> {
        let file = &map.mesh;
        let graph = crate::synth::patches::graph::SurfaceGraph::new(&file.positions, &file.triangles, path)?;
        let mut index: std::collections::HashMap<(u32, [u32; 2]), u32> = std::collections::HashMap::new();
        let (mut positions, mut normals, mut uv, mut labels) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut triangles = Vec::with_capacity(file.triangles.len());
        for (f, t) in file.triangles.iter().enumerate() {
            let corners: [u32; 3] = std::array::from_fn(|k| {
                let s = map.corner_uv[f][k];
                *index.entry((t[k], s.to_array().map(f32::to_bits))).or_insert_with(|| {
                    positions.push(file.positions[t[k] as usize]);
                    let at = graph.weld[t[k] as usize];
                    normals.push(graph.normals.get(at as usize).copied().unwrap_or(Vec3::Z));
                    uv.push(s);
                    labels.push(u16::from(map.level[f]));
                    (uv.len() - 1) as u32
                })
            });
            triangles.push(corners);
        }
        // s: the surface direction of increasing texture column, averaged over each vertex's
        // faces by area (rows run down t, as in surface maps).
        let mut along = vec![Vec3::ZERO; positions.len()];
        for t in &triangles {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            let [ua, ub, uc] = t.map(|i| uv[i as usize]);
            let (e1, e2, d1, d2) = (b - a, c - a, ub - ua, uc - ua);
            let det = d1.x * d2.y - d2.x * d1.y;
            if det.abs() < 1e-12 {
                continue;
            }
            let dp_du = (e1 * d2.y - e2 * d1.y) / det;
            let weight = 0.5 * e1.cross(e2).length();
            for &i in t {
                along[i as usize] += weight * dp_du.normalize_or_zero();
            }
        }
        let mesh = Mesh::from_split_parts(positions, triangles, normals);
        let frames = Frames::from_directions(mesh.normals().unwrap_or(&[]), &along);
        Ok(Scene { mesh, frames, uv, labels, texel: map.texel, mapped: true, belonging: OnceLock::new() })
    }

    /// The vertex normals.
    pub fn normals(&self) -> &[Vec3] {
        &self.frames.n
    }

    /// The blend of every vertex for `shot`: its view and light in the vertex's frame.
    pub fn vertex_blends(&self, material: &Material, shot: &Shot) -> Vec<Blend16> {
        let positions = self.mesh.positions();
        (0..positions.len())
            .into_par_iter()
            .with_min_len(1024)
            .map(|v| {
                let view = shot.camera.towards_eye(positions[v]);
                material.blend(self.to_local(v, view), self.to_local(v, shot.light))
            })
            .collect()
    }

    /// Vertex `v`'s frame: s, t and n as world vectors.
    pub fn frame(&self, v: usize) -> [Vec3; 3] {
        [self.frames.s[v], self.frames.t[v], self.frames.n[v]]
    }

    /// A world direction in vertex `v`'s (s, t, n) frame.
    pub fn to_local(&self, v: usize, d: Vec3) -> Vec3 {
        let f = &self.frames;
        Vec3::new(d.dot(f.s[v]), d.dot(f.t[v]), d.dot(f.n[v]))
    }

    /// The sample coordinate that corner vertex `v` predicts for surface point `p`: its own
    /// coordinate plus the offset to `p` in its tangent frame (rows run down t).
    pub fn predict_uv(&self, v: usize, p: Vec3) -> Vec2 {
        let d = p - self.mesh.positions()[v];
        self.uv[v] + Vec2::new(d.dot(self.frames.s[v]), -d.dot(self.frames.t[v])) / self.texel
    }

    /// The sample coordinate that point `p`, with barycentric weights `bary` in the triangle
    /// of vertices `corners`, shows: on a texture-mapped scene the corners' coordinates
    /// interpolated; otherwise each corner's prediction ([`Scene::predict_uv`]), grouped by
    /// agreement (within [`AGREE_TEXELS`], across the wrap of a tileable sample), the group
    /// with the largest claim interpolated. A corner claims the point for its own group by
    /// its weight times its [`Scene::belonging`], and for the others by its weight times
    /// the rest. Inside one copy of the sample all three agree and the coordinate runs on
    /// continuously; at a seam the cut falls where the two sides' claims balance, which on
    /// a shared edge depends on its two vertices only, so neighbouring triangles cut alike.
    /// Returns the coordinate and the weight each corner
    /// had in it (zero outside the chosen group), for lookups that follow the corners' frames.
    pub fn point_uv(&self, material: &Material, corners: [u32; 3], bary: Vec3, p: Vec3) -> (Vec2, [f32; 3]) {
        let w = bary.to_array();
        if self.mapped {
            let q = (0..3).map(|k| w[k] * self.uv[corners[k] as usize]).sum();
            return (q, w);
        }
        let q = corners.map(|v| self.predict_uv(v as usize, p));
        let offset = |a: Vec2, b: Vec2| wrapped_offset(material, a, b);
        let agree = |i: usize, j: usize| one_copy(material, q[i], q[j]);
        let group_weight = |i: usize| (0..3).filter(|&j| agree(i, j)).map(|j| w[j]).sum::<f32>();
        let belonging = self.belonging(material);
        let belongs = |j: usize| belonging[corners[j] as usize];
        let claim = |i: usize| {
            (0..3).map(|j| w[j] * if agree(i, j) { belongs(j) } else { 1.0 - belongs(j) }).sum::<f32>()
        };
        let lead =
            (0..3).max_by(|&i, &j| claim(i).total_cmp(&claim(j)).then(w[i].total_cmp(&w[j]))).unwrap_or(0);
        let mut weights = [0.0; 3];
        // A point can go to a group none of whose corners weighs on it (at a lone vertex of
        // another copy): its corners then share it equally.
        let (total, members) = (group_weight(lead), (0..3).filter(|&j| agree(lead, j)).count());
        let mut uv = q[lead];
        for j in (0..3).filter(|&j| agree(lead, j)) {
            weights[j] = if total > 0.0 { w[j] / total } else { 1.0 / members as f32 };
            uv += weights[j] * offset(q[lead], q[j]);
        }
        (uv, weights)
    }

    /// Per vertex, the share of its neighbours within two rings (and itself) whose
    /// prediction of its coordinate agrees with it ([`AGREE_TEXELS`], across `material`'s
    /// wrap): 1 inside a copy of the sample, about a half on a straight seam, below a half
    /// on a vertex that pokes into its neighbours' copy. [`Scene::point_uv`] cuts between
    /// copies where these balance.
    ///
    /// Why: each vertex chooses its texel on its own, so the boundary between two copies runs
    /// zigzag from vertex to vertex, and a cut by the corners' barycentric weights alone
    /// follows every zigzag: at the close range a model is looked at, where a texel spans
    /// several pixels, every copy's edge is a sawtooth (docs/surfaces.md). Weighing each
    /// corner by its share follows the seam averaged over two rings instead, and a lone vertex
    /// of another copy is drawn as the copy around it. Three rings or more straighten the
    /// seam further but leave small curled islands where three copies meet (choc swirl on
    /// the bunny, looked at in the CPU renderer at 2400²).
    pub fn belonging(&self, material: &Material) -> &[f32] {
        self.belonging.get_or_init(|| {
            let rings = crate::mesh::topology::one_rings(&self.mesh);
            let positions = self.mesh.positions();
            (0..positions.len())
                .into_par_iter()
                .with_min_len(1024)
                .map_init(Vec::new, |near: &mut Vec<u32>, v| {
                    // The vertex itself, its ring and theirs (its own prediction agrees).
                    near.clear();
                    near.push(v as u32);
                    for &u in rings.ring(v) {
                        near.push(u);
                        near.extend_from_slice(rings.ring(u as usize));
                    }
                    near.sort_unstable();
                    near.dedup();
                    let agrees = |u: usize| one_copy(material, self.uv[v], self.predict_uv(u, positions[v]));
                    near.iter().filter(|&&u| agrees(u as usize)).count() as f32 / near.len() as f32
                })
                .collect()
        })
    }

    /// The colour of point `p` with barycentric weights `bary` in triangle `tri`, before
    /// shadowing (see [`Mode`]).
    pub fn shade_point(
        &self,
        material: &Material,
        blends: &[Blend16],
        mode: Mode,
        (tri, bary, p): (usize, Vec3, Vec3),
    ) -> Vec3 {
        let corners = self.mesh.triangles()[tri];
        match mode {
            Mode::Vertex => (0..3)
                .map(|k| {
                    let v = corners[k] as usize;
                    bary[k] * material.shade(&blends[v], self.uv[v].x, self.uv[v].y)
                })
                .sum(),
            Mode::Pixel => {
                // One lookup at the point's coordinate; the view and light blends (smooth
                // across the surface) still follow the corners.
                let (q, _) = self.point_uv(material, corners, bary, p);
                (0..3).map(|k| bary[k] * material.shade(&blends[corners[k] as usize], q.x, q.y)).sum()
            }
        }
    }

    /// Per-vertex colours (Tong §6's vertex mode) under `blends`; `lit[v]` false makes a
    /// vertex black (in shadow).
    pub fn vertex_colours(&self, material: &Material, blends: &[Blend16], lit: Option<&[bool]>) -> Vec<Vec3> {
        (0..self.uv.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|v| {
                if lit.is_some_and(|l| !l[v]) {
                    return Vec3::ZERO;
                }
                material.shade(&blends[v], self.uv[v].x, self.uv[v].y)
            })
            .collect()
    }

    /// The sample itself on a flat quad in the world's XZ plane (normal +Y, s = +X, rows
    /// running towards +Z), one model unit per texel, its map the identity: what a comparison
    /// puts beside each frame.
    pub fn sample_quad(material: &Material) -> Result<Scene> {
        let (w, h) = (material.width() as f32, material.height() as f32);
        let corners = [(-0.5, -0.5), (w - 0.5, -0.5), (w - 0.5, h - 0.5), (-0.5, h - 0.5)];
        let positions = corners.iter().map(|&(x, z)| Vec3::new(x, 0.0, z)).collect();
        let mesh = Mesh::new(positions, vec![[0, 2, 1], [0, 3, 2]])?.with_normals();
        let n = mesh.vertex_count();
        let frames = Frames::from_directions(&vec![Vec3::Y; n], &vec![Vec3::X; n]);
        let uv = mesh.positions().iter().map(|p| Vec2::new(p.x, p.z)).collect();
        Ok(Scene::new(mesh, frames, uv, vec![0; n], 1.0))
    }
}

/// Whether sample coordinates `a` and `b` lie in one copy of the sample: within
/// [`AGREE_TEXELS`] of each other, across the wrap when `material`'s sample tiles.
pub(crate) fn one_copy(material: &Material, a: Vec2, b: Vec2) -> bool {
    wrapped_offset(material, a, b).length_squared() <= AGREE_TEXELS * AGREE_TEXELS
}

/// The offset from `a` to `b` in sample texels, across the wrap when `material`'s sample
/// tiles.
fn wrapped_offset(material: &Material, a: Vec2, b: Vec2) -> Vec2 {
    let d = b - a;
    if material.tileable {
        let size = Vec2::new(material.width() as f32, material.height() as f32);
        d - size * (d / size).round()
    } else {
        d
    }
}

/// What per-vertex relighting keeps while only the light moves (Tong §6's interactive
/// mode): per vertex its frame, sample coordinate and weighted nearest views for a fixed
/// camera, stored in an order grouped by sample texel, so that consecutive vertices read
/// the same texel of the images and stay in cache. With a tracer it also keeps, once per
/// camera, which vertices matter at all: the corners of triangles with a corner the camera
/// sees (facing it, nothing in between). The others are hidden from this camera whatever
/// the light does, so they are not relit (their colour stays black); on a closed model that
/// is more than half of them.
pub struct Relighter {
    vertices: Vec<RelightVertex>,
    count: usize,
}

/// How per-vertex relighting decides what the light reaches.
#[derive(Clone, Copy)]
pub enum Shadows<'a> {
    /// Everything facing the light is lit.
    None,
    /// A shadow ray per vertex: exact.
    Rays(&'a super::tracer::Tracer),
    /// A lookup in a shadow map rasterised for this light: faster, exact to about a texel.
    Map(&'a super::shadow_map::ShadowMap),
}

struct RelightVertex {
    index: u32,
    position: Vec3,
    frame: [Vec3; 3],
    uv: Vec2,
    views: Nearest4,
}

impl Relighter {
    /// Prepares relighting `scene` seen by `camera`; with `tracer`, only the vertices that
    /// can show (see [`Relighter`]).
    pub fn new(
        scene: &Scene,
        material: &Material,
        camera: &super::Camera,
        tracer: Option<&super::tracer::Tracer>,
    ) -> Relighter {
        let positions = scene.mesh.positions();
        let needed = tracer.map(|t| scene.seen_triangle_corners(camera, t));
        let f = &scene.frames;
        let mut vertices: Vec<RelightVertex> = (0..positions.len())
            .into_par_iter()
            .with_min_len(1024)
            .filter(|&v| needed.as_ref().is_none_or(|n| n[v]))
            .map(|v| RelightVertex {
                index: v as u32,
                position: positions[v],
                frame: [f.s[v], f.t[v], f.n[v]],
                uv: scene.uv[v],
                views: material.view_weights(scene.to_local(v, camera.towards_eye(positions[v]))),
            })
            .collect();
        vertices.sort_by_key(|r| (r.uv.y.floor() as i64, r.uv.x.floor() as i64));
        Relighter { vertices, count: positions.len() }
    }

    /// How many vertices each frame relights.
    pub fn relit(&self) -> usize {
        self.vertices.len()
    }

    /// Per-vertex colours under a directional light towards `light`; a vertex that
    /// `shadows` says the light does not reach (asked only for vertices facing the light) is
    /// black.
    pub fn colours(&self, material: &Material, light: Vec3, shadows: Shadows<'_>) -> Vec<Vec3> {
        let in_order: Vec<Vec3> = self
            .vertices
            .par_iter()
            .with_min_len(1024)
            .map(|r| {
                let [s, t, n] = r.frame;
                let local = Vec3::new(light.dot(s), light.dot(t), light.dot(n));
                let Some(nl) = material.light_weights(local) else { return Vec3::ZERO };
                let lit = match shadows {
                    Shadows::None => true,
                    Shadows::Rays(tracer) => tracer.lit(r.position, n, light),
                    Shadows::Map(map) => map.lit(r.position, n),
                };
                if !lit {
                    return Vec3::ZERO;
                }
                let blend = material.combine(&r.views, &nl, local.z);
                material.shade(&blend, r.uv.x, r.uv.y)
            })
            .collect();
        let mut colours = vec![Vec3::ZERO; self.count];
        for (r, c) in self.vertices.iter().zip(in_order) {
            colours[r.index as usize] = c;
        }
        colours
    }
}

impl Scene {
    /// Per vertex, whether it is a corner of a triangle that has a corner `camera` sees: one
    /// facing the camera with nothing between them.
    pub fn seen_triangle_corners(&self, camera: &super::Camera, tracer: &super::tracer::Tracer) -> Vec<bool> {
        let positions = self.mesh.positions();
        let seen: Vec<bool> = (0..positions.len())
            .into_par_iter()
            .with_min_len(1024)
            .map(|v| {
                let towards = camera.towards_eye(positions[v]);
                let n = self.frames.n[v];
                n.dot(towards) > 0.0 && tracer.lit(positions[v], n, towards)
            })
            .collect();
        let mut needed = vec![false; positions.len()];
        for tri in self.mesh.triangles() {
            if tri.iter().any(|&v| seen[v as usize]) {
                tri.iter().for_each(|&v| needed[v as usize] = true);
            }
        }
        needed
    }
}

/// Opens a surface map and finds its analysis: `analysis` if given, else the one its header
/// names (see [`SurfaceMap::find_analysis`]). With `verify`, the analysis must be the one the
/// map was synthesized from ([`Error::AnalysisMismatch`] otherwise).
pub fn open_surface(path: &Path, analysis: Option<&Path>, verify: bool) -> Result<(Scene, PathBuf)> {
    let (scene, comments) = match crate::synth::patches::output::uv_map_comments(path) {
        Some(_) => {
            let map = crate::synth::patches::output::read_uv_map(path)?;
            (Scene::from_uv_map(&map, path)?, map.comments)
        }
        None => {
            let map = read_surface_ply(path)?;
            let comments = map.comments.clone();
            (Scene::from_surface_map(map), comments)
        }
    };
    let comment = |key: &str| crate::synth::surface_map::comment_value(&comments, key);
    let dir = match analysis {
        Some(a) => a.to_path_buf(),
        None => crate::synth::surface_map::find_analysis(&comments, path).ok_or_else(|| {
            let named = comment(ANALYSIS_KEY).map(crate::synth::surface_map::comment_paths);
            let named = named.and_then(|n| n.first().map(|p| p.display().to_string()));
            let named = named.as_deref().unwrap_or("none");
            Error::unavailable(
                format!(
                    "{}: its analysis ({named}) is missing, beside the map and at its recorded path",
                    path.display()
                ),
                Remedy::GiveAnalysis,
            )
        })?,
    };
    if !dir.join(crate::analysis::store::MANIFEST).is_file() {
        return Err(Error::invalid(format!(
            "{}: the analysis {} is missing (no {})",
            path.display(),
            dir.display(),
            crate::analysis::store::MANIFEST
        )));
    }
    if verify {
        crate::analysis::store::verify_fingerprint(&dir, path, comment(ANALYSIS_FINGERPRINT_KEY))?;
    }
    Ok((scene, dir))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::directions::{Direction, DirectionPair};

    /// Side of the test grid, in vertices one texel apart.
    const SIDE: usize = 16;
    /// The column where the second copy begins, on even rows; odd rows begin one later.
    const SEAM: usize = 8;
    /// A vertex of the second copy alone inside the first.
    const LONE: [usize; 2] = [3, 9];

    /// A flat grid of two copies of the sample: the first at (10, 10) texels from each
    /// vertex's place, the second at (40, 10), meeting on a zigzag of one vertex a row (as a
    /// mesh's vertices choosing on their own leave it), with one vertex of the second copy
    /// inside the first.
    fn two_copies(belonging: Option<f32>) -> (Scene, Material) {
        let n = SIDE * SIDE;
        let positions: Vec<Vec3> =
            (0..n).map(|v| Vec3::new((v % SIDE) as f32, 0.0, (v / SIDE) as f32)).collect();
        let mut triangles = Vec::new();
        for j in 0..SIDE - 1 {
            for i in 0..SIDE - 1 {
                let (a, b, c, d) =
                    (j * SIDE + i, j * SIDE + i + 1, (j + 1) * SIDE + i, (j + 1) * SIDE + i + 1);
                triangles.push([a, b, d].map(|v| v as u32));
                triangles.push([a, d, c].map(|v| v as u32));
            }
        }
        let second = |i: usize, j: usize| i >= SEAM + j % 2 || [i, j] == LONE;
        let uv = (0..n)
            .map(|v| {
                let (i, j) = (v % SIDE, v / SIDE);
                let x = if second(i, j) { 40.0 } else { 10.0 };
                Vec2::new(i as f32 + x, j as f32 + 10.0)
            })
            .collect();
        let mesh = Mesh::new(positions, triangles).unwrap().with_normals();
        let frames = Frames::from_directions(&vec![Vec3::Y; n], &vec![Vec3::X; n]);
        let belonging = match belonging {
            Some(share) => OnceLock::from(vec![share; n]),
            None => OnceLock::new(),
        };
        let scene = Scene { mesh, frames, uv, labels: vec![0; n], texel: 1.0, mapped: false, belonging };
        let pair = DirectionPair { light: Direction::NORMAL, view: Direction::NORMAL };
        let material = Material::new(64, 32, vec![0.5; 64 * 32 * 3], vec![pair]).unwrap();
        (scene, material)
    }

    /// The sample coordinate `scene` shows at grid point (x, z), and its corners' weights.
    fn shown_with_weights(scene: &Scene, material: &Material, x: f32, z: f32) -> (Vec2, [f32; 3]) {
        let (i, j) = ((x.floor() as usize).min(SIDE - 2), (z.floor() as usize).min(SIDE - 2));
        let (fx, fz) = (x - i as f32, z - j as f32);
        let at = |di: usize, dj: usize| ((j + dj) * SIDE + i + di) as u32;
        let (corners, bary) = if fx >= fz {
            ([at(0, 0), at(1, 0), at(1, 1)], Vec3::new(1.0 - fx, fx - fz, fz))
        } else {
            ([at(0, 0), at(1, 1), at(0, 1)], Vec3::new(1.0 - fz, fx, fz - fx))
        };
        scene.point_uv(material, corners, bary, Vec3::new(x, 0.0, z))
    }

    /// The sample coordinate `scene` shows at grid point (x, z).
    fn shown(scene: &Scene, material: &Material, x: f32, z: f32) -> Vec2 {
        shown_with_weights(scene, material, x, z).0
    }

    /// Per row (halfway between vertex rows), where the second copy begins.
    fn cut_per_row(scene: &Scene, material: &Material) -> Vec<f32> {
        (2..SIDE - 3)
            .map(|j| {
                let z = j as f32 + 0.5;
                let x = (0..(SIDE - 1) * 100)
                    .map(|k| k as f32 / 100.0)
                    .find(|&x| x > (LONE[0] + 2) as f32 && shown(scene, material, x, z).x - x > 25.0);
                x.expect("the second copy shows on every row")
            })
            .collect()
    }

    #[test]
    fn inside_a_copy_every_vertex_belongs_wholly_and_on_the_seam_about_half() {
        let (scene, material) = two_copies(None);
        let belonging = scene.belonging(&material);
        assert_eq!(belonging[4 * SIDE + 2], 1.0);
        assert_eq!(belonging[4 * SIDE + 13], 1.0);
        let on_seam = belonging[4 * SIDE + SEAM];
        assert!((0.3..0.7).contains(&on_seam), "{on_seam}");
        let lone = belonging[LONE[1] * SIDE + LONE[0]];
        assert!(lone < 0.1, "the lone vertex belongs {lone}");
    }

    #[test]
    fn a_lone_vertex_of_another_copy_is_drawn_as_the_copy_around_it() {
        let [x, z] = LONE.map(|c| c as f32);
        let (corner_cut, material) = two_copies(Some(1.0));
        assert!((shown(&corner_cut, &material, x, z) - Vec2::new(x + 40.0, z + 10.0)).length() < 1e-4);
        let (scene, _) = two_copies(None);
        let (uv, weights) = shown_with_weights(&scene, &material, x, z);
        assert!((uv - Vec2::new(x + 10.0, z + 10.0)).length() < 1e-4, "{uv}");
        // None of the copy's corners weighs on the vertex's own point; they share it.
        assert!((weights.iter().sum::<f32>() - 1.0).abs() < 1e-5, "{weights:?}");
    }

    #[test]
    fn a_zigzag_seam_is_cut_straighter_than_its_vertices_run() {
        let spread = |cuts: Vec<f32>| {
            let mean = cuts.iter().sum::<f32>() / cuts.len() as f32;
            (cuts.iter().map(|c| (c - mean).powi(2)).sum::<f32>() / cuts.len() as f32).sqrt()
        };
        let (corner_cut, material) = two_copies(Some(1.0));
        let (scene, _) = two_copies(None);
        let (before, after) =
            (spread(cut_per_row(&corner_cut, &material)), spread(cut_per_row(&scene, &material)));
        assert!(before > 0.2, "the corners alone cut the zigzag: spread {before}");
        assert!(after < 0.5 * before, "the cut's spread across rows: {after} against {before}");
    }
}
