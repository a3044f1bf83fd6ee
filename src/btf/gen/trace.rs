//! Ray-tracing a material's height field into BTF images, the way the paper's Fig. 8 made
//! its synthetic ground truth: the field as a triangle mesh in an obvhs BVH, an
//! orthographic camera along each view direction, a directional light with shadow rays.

use super::materials::Material;
use glam::{Vec3, Vec3A};
use obvhs::cwbvh::{builder::build_cwbvh_from_tris, CwBvh};
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;

/// Mesh vertices per texel: fine enough that the mesh follows the analytic field closely.
const MESH_RESOLUTION: f32 = 2.0;
/// Pushes secondary rays off the surface so they do not hit their own triangle.
const RAY_OFFSET: f32 = 2e-3;

/// The traced height field: triangles, their BVH and the material they came from.
pub struct HeightField<'m> {
    material: &'m dyn Material,
    triangles: Vec<Triangle>,
    bvh: CwBvh,
    /// Height of the reference plane on which the images are rectified.
    reference: f32,
}

/// What a primary ray sees: shading inputs at the first hit.
#[derive(Clone, Copy)]
pub struct Hit {
    /// The hit point: x, y in the sample window, z the height, all in texels.
    pub position: Vec3,
    /// Unit surface normal at the hit.
    pub normal: Vec3,
    /// Linear diffuse albedo (RGB) at the hit.
    pub albedo: Vec3,
    /// Strength of the glossy (Blinn-Phong) lobe at the hit.
    pub gloss: f32,
}

/// The BVH's slab test computes 0 × ∞ = NaN for a direction component that is exactly zero
/// (every ray along the normal), and NaN reads as a miss: nudge such components.
pub(crate) fn robust(direction: Vec3) -> Vec3A {
    let nudge = |c: f32| {
        if c.abs() < 1e-6 {
            1e-6f32.copysign(c)
        } else {
            c
        }
    };
    Vec3A::new(nudge(direction.x), nudge(direction.y), nudge(direction.z))
}

impl<'m> HeightField<'m> {
    /// Meshes `material` over the sample window `[0, size)²` plus a margin wide enough for
    /// views up to `max_theta_deg` from the normal.
    pub fn new(material: &'m dyn Material, size: usize, max_theta_deg: f32) -> Self {
        let reach = material.max_height() * max_theta_deg.clamp(0.0, 80.0).to_radians().tan();
        let margin = reach.ceil() + 2.0;
        let (lo, span) = (-margin, size as f32 + 2.0 * margin);
        let n = (span * MESH_RESOLUTION).ceil() as usize;
        let step = span / n as f32;
        let mut grid = Vec::with_capacity((n + 1) * (n + 1));
        let mut height_sum = 0.0f64;
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (lo + i as f32 * step, lo + j as f32 * step);
                let h = material.height(x, y);
                height_sum += h as f64;
                grid.push(Vec3A::new(x, y, h));
            }
        }
        let mut triangles = Vec::with_capacity(2 * n * n);
        for j in 0..n {
            for i in 0..n {
                let k = j * (n + 1) + i;
                let (a, b, c, d) = (grid[k], grid[k + 1], grid[k + n + 1], grid[k + n + 2]);
                triangles.push(Triangle { v0: a, v1: b, v2: d });
                triangles.push(Triangle { v0: a, v1: d, v2: c });
            }
        }
        let bvh = build_cwbvh_from_tris(&triangles, BvhBuildParams::medium_build(), &mut Default::default());
        let reference = (height_sum / grid.len() as f64) as f32;
        HeightField { material, triangles, bvh, reference }
    }

    /// The surface seen through sample-window point (x, y) of the reference plane, looking
    /// back along `view` (a unit vector towards the camera).
    pub fn primary(&self, x: f32, y: f32, view: Vec3) -> Option<Hit> {
        let height = self.material.max_height() + 1.0 - self.reference;
        let origin = Vec3::new(x, y, self.reference) + view * (height / view.z.max(0.05));
        let ray = Ray::new_inf(origin.into(), robust(-view));
        let mut hit = RayHit::none();
        let found = self.bvh.ray_traverse(ray, &mut hit, |ray, slot| {
            self.triangles[self.bvh.primitive_indices[slot] as usize].intersect(ray)
        });
        if !found {
            return None;
        }
        let position = origin - view * hit.t;
        Some(Hit {
            position,
            normal: self.normal(position.x, position.y),
            albedo: self.material.albedo(position.x, position.y),
            gloss: self.material.gloss(position.x, position.y),
        })
    }

    /// True if nothing blocks the way from `hit` towards `light`.
    pub fn lit(&self, hit: &Hit, light: Vec3) -> bool {
        let origin = hit.position + (hit.normal + light) * RAY_OFFSET;
        let ray = Ray::new_inf(origin.into(), robust(light));
        self.bvh.ray_traverse_miss(ray, |ray, slot| {
            self.triangles[self.bvh.primitive_indices[slot] as usize].intersect(ray)
        })
    }

    /// Radiance towards `view` under a unit directional light from `light`: Lambert plus a
    /// normalised Blinn-Phong lobe; zero in shadow.
    pub fn shade(&self, hit: &Hit, view: Vec3, light: Vec3) -> Vec3 {
        let cos_light = hit.normal.dot(light);
        if cos_light <= 0.0 || !self.lit(hit, light) {
            return Vec3::ZERO;
        }
        let half = (view + light).normalize();
        let shininess = self.material.shininess();
        let lobe = hit.gloss * (shininess + 8.0) / 8.0 * hit.normal.dot(half).max(0.0).powf(shininess);
        (hit.albedo + Vec3::splat(lobe)) * cos_light
    }

    /// The analytic normal of the field by central differences: smoother than the facets.
    fn normal(&self, x: f32, y: f32) -> Vec3 {
        let e = 0.25 / MESH_RESOLUTION;
        let h = |dx: f32, dy: f32| self.material.height(x + dx, y + dy);
        let gx = (h(e, 0.0) - h(-e, 0.0)) / (2.0 * e);
        let gy = (h(0.0, e) - h(0.0, -e)) / (2.0 * e);
        Vec3::new(-gx, -gy, 1.0).normalize()
    }

    /// Number of triangles traced.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }
}
