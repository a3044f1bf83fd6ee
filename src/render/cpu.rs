//! The CPU renderer: primary and shadow rays through an obvhs BVH of the mesh, then the
//! shared shading core per pixel ([`Mode::Pixel`]) or per vertex ([`Mode::Vertex`]).

use super::camera::Shot;
use super::material::Material;
use super::output::Frame;
use super::scene::{Mode, Scene};
use crate::btf::gen::trace::robust;
use crate::mesh::Mesh;
use glam::{Vec3, Vec3A};
use obvhs::cwbvh::{builder::build_cwbvh_from_tris, CwBvh};
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use rayon::prelude::*;

/// The mesh's triangles in a BVH.
pub struct Tracer {
    triangles: Vec<Triangle>,
    bvh: CwBvh,
    /// Secondary rays start this far off the surface (relative to the model's size) so
    /// they do not hit the triangle they leave.
    offset: f32,
}

/// A primary ray's first hit.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub triangle: usize,
    pub position: Vec3,
    /// Barycentric weights of the triangle's three corners.
    pub bary: Vec3,
    /// The triangle's unit geometric normal.
    pub normal: Vec3,
}

impl Tracer {
    pub fn new(mesh: &Mesh) -> Tracer {
        let triangles: Vec<Triangle> = (0..mesh.face_count())
            .map(|f| {
                let [a, b, c] = mesh.triangle_positions(f);
                Triangle { v0: a.into(), v1: b.into(), v2: c.into() }
            })
            .collect();
        let bvh = build_cwbvh_from_tris(&triangles, BvhBuildParams::medium_build(), &mut Default::default());
        let (lo, hi) = mesh.bounds();
        Tracer { triangles, bvh, offset: 1e-4 * (hi - lo).length().max(1e-6) }
    }

    /// The first triangle along the ray.
    pub fn closest(&self, origin: Vec3, direction: Vec3) -> Option<Hit> {
        let ray = Ray::new_inf(origin.into(), robust(direction));
        let mut hit = RayHit::none();
        let found = self.bvh.ray_traverse(ray, &mut hit, |ray, slot| {
            self.triangles[self.bvh.primitive_indices[slot] as usize].intersect(ray)
        });
        if !found {
            return None;
        }
        let triangle = self.bvh.primitive_indices[hit.primitive_id as usize] as usize;
        let position = origin + direction * hit.t;
        let t = &self.triangles[triangle];
        let (a, b, c) = (Vec3::from(t.v0), Vec3::from(t.v1), Vec3::from(t.v2));
        Some(Hit {
            triangle,
            position,
            bary: barycentric(position, a, b, c),
            normal: (b - a).cross(c - a).normalize_or_zero(),
        })
    }

    /// True if nothing lies between `position` (on a surface with unit normal `normal`,
    /// facing the light) and a directional light towards `light`.
    pub fn lit(&self, position: Vec3, normal: Vec3, light: Vec3) -> bool {
        let origin: Vec3A = (position + (normal + light) * self.offset).into();
        self.bvh.ray_traverse_miss(Ray::new_inf(origin, robust(light)), |ray, slot| {
            self.triangles[self.bvh.primitive_indices[slot] as usize].intersect(ray)
        })
    }
}

/// Barycentric weights of `p` (on the plane of a, b, c), clamped to the triangle.
fn barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (e0, e1, e2) = (b - a, c - a, p - a);
    let (d00, d01, d11, d20, d21) = (e0.dot(e0), e0.dot(e1), e1.dot(e1), e2.dot(e0), e2.dot(e1));
    let denom = d00 * d11 - d01 * d01;
    if denom.abs() < f32::MIN_POSITIVE {
        return Vec3::new(1.0, 0.0, 0.0);
    }
    let v = ((d11 * d20 - d01 * d21) / denom).clamp(0.0, 1.0);
    let w = ((d00 * d21 - d01 * d20) / denom).clamp(0.0, 1.0 - v);
    Vec3::new(1.0 - v - w, v, w)
}

/// What the CPU renderer does besides shading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    pub mode: Mode,
    /// Trace shadow rays (per pixel in pixel mode, per vertex in vertex mode).
    pub shadows: bool,
}

impl Default for RenderOptions {
    /// Pixel mode with shadows.
    fn default() -> Self {
        RenderOptions { mode: Mode::Pixel, shadows: true }
    }
}

/// Renders one shot. Points facing away from the camera are black; points facing away
/// from the light or in shadow get no light (there is no ambient term).
pub fn render(
    scene: &Scene,
    material: &Material,
    tracer: &Tracer,
    shot: &Shot,
    options: RenderOptions,
) -> Frame {
    let blends = scene.vertex_blends(material, shot);
    let vertex_colours = (options.mode == Mode::Vertex).then(|| {
        let lit = options.shadows.then(|| vertex_lit(scene, tracer, shot.light));
        scene.vertex_colours(material, &blends, lit.as_deref())
    });
    let (w, h) = (shot.camera.width as usize, shot.camera.height as usize);
    let mut frame = Frame::new(w, h);
    frame.rgba.par_chunks_mut(w * 4).enumerate().for_each(|(y, row)| {
        for x in 0..w {
            let (origin, direction) = shot.camera.ray(x as f32 + 0.5, y as f32 + 0.5);
            let Some(hit) = tracer.closest(origin, direction) else { continue };
            let colour = if hit.normal.dot(direction) >= 0.0 {
                Vec3::ZERO
            } else if let Some(colours) = &vertex_colours {
                let corners = scene.mesh.triangles()[hit.triangle].map(|v| colours[v as usize]);
                corners[0] * hit.bary.x + corners[1] * hit.bary.y + corners[2] * hit.bary.z
            } else if hit.normal.dot(shot.light) <= 0.0
                || (options.shadows && !tracer.lit(hit.position, hit.normal, shot.light))
            {
                Vec3::ZERO
            } else {
                scene.shade_point(material, &blends, Mode::Pixel, (hit.triangle, hit.bary, hit.position))
            };
            row[x * 4..x * 4 + 4].copy_from_slice(&[colour.x, colour.y, colour.z, 1.0]);
        }
    });
    frame
}

/// Per vertex, whether the light reaches it (Tong §6 ignores occluded vertices).
pub fn vertex_lit(scene: &Scene, tracer: &Tracer, light: Vec3) -> Vec<bool> {
    let (positions, normals) = (scene.mesh.positions(), scene.normals());
    (0..positions.len())
        .into_par_iter()
        .with_min_len(1024)
        .map(|v| normals[v].dot(light) > 0.0 && tracer.lit(positions[v], normals[v], light))
        .collect()
}

/// Renders every shot of `plan` into `writer`; with `compare`, each frame is put beside the
/// sample on a flat quad ([`Scene::sample_quad`]) seen from the same direction under the
/// same light. Returns the mean seconds per frame (rendering only).
pub fn render_sequence(
    (scene, material): (&Scene, &Material),
    plan: &super::ShotPlan,
    options: RenderOptions,
    compare: bool,
    writer: &mut super::SequenceWriter,
    progress: &dyn crate::progress::Progress,
) -> crate::Result<f64> {
    let tracer = Tracer::new(&scene.mesh);
    let quad = if compare { Some(Scene::sample_quad(material)?) } else { None };
    let quad_tracer = quad.as_ref().map(|q| Tracer::new(&q.mesh));
    let shots = plan.shots(scene.mesh.bounds());
    let quad_shots = quad.as_ref().map(|q| plan.shots(q.mesh.bounds()));
    progress.start("rendering", shots.len() as u64);
    let mut seconds = 0.0;
    for (i, shot) in shots.iter().enumerate() {
        let started = std::time::Instant::now();
        let mut frame = render(scene, material, &tracer, shot, options);
        if let (Some(q), Some(t), Some(qs)) = (&quad, &quad_tracer, &quad_shots) {
            let quad_options = RenderOptions { mode: Mode::Pixel, ..options };
            frame = frame.beside(&render(q, material, t, &qs[i], quad_options));
        }
        seconds += started.elapsed().as_secs_f64();
        writer.push(&frame)?;
        progress.advance(1);
    }
    progress.finish();
    Ok(seconds / shots.len().max(1) as f64)
}
