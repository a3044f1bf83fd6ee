//! The mesh in a BVH ([obvhs]): first hits of primary rays and shadow tests, which the CPU
//! renderer, the ambient-occlusion cache and the scene's visibility all trace. A leaf of the
//! renderer, so that none of them depends on another for it.
//!
//! [obvhs]: https://crates.io/crates/obvhs

use crate::btf::gen::trace::robust;
use crate::mesh::Mesh;
use glam::{Vec3, Vec3A};
use obvhs::cwbvh::{builder::build_cwbvh_from_tris, CwBvh};
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;

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
    /// Index of the triangle hit (a face of the mesh).
    pub triangle: usize,
    /// The hit point in world units.
    pub position: Vec3,
    /// Barycentric weights of the triangle's three corners.
    pub bary: Vec3,
    /// The triangle's unit geometric normal.
    pub normal: Vec3,
}

impl Tracer {
    /// Builds the BVH of `mesh`'s triangles.
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
