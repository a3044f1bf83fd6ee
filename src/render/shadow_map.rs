//! A shadow map on the CPU, for per-vertex relighting at interactive rates: the mesh
//! rasterised along the light once per light direction, then one lookup per vertex instead
//! of a shadow ray.
//!
//! The map keeps, per texel, the height towards the light of the highest triangle facing
//! *away* from the light. On a closed surface the first thing a shadow ray enters on its way
//! to the light is such a triangle (it enters a solid through a face whose outward normal
//! points against it), while the lit surface a point lies on faces the light: so lit points
//! are not shadowed by their own surface (no "acne") without a large bias. Meshes with
//! boundary edges (open sheets, which have no far side) also rasterise the triangles facing
//! the light into a second layer, compared with a slope-scaled bias. Resolution limits
//! precision: points within about a texel of a shadow edge may come out on the other side,
//! where a ray would decide exactly.

use crate::mesh::Mesh;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// A map side for a mesh of `vertices` vertices: about as many texels across the model as
/// vertices, so a texel is about an edge long (per-vertex shading resolves no finer).
pub fn shadow_map_size(vertices: usize) -> usize {
    ((vertices as f64).sqrt() * 1.2).clamp(256.0, 2048.0) as usize
}

/// One layer of the map: per texel the largest height towards the light, or −∞.
type Layer = Vec<f32>;

/// The mesh seen from a directional light.
pub struct ShadowMap {
    /// Unit vector towards the light; heights are `p · light`.
    light: Vec3,
    /// Map axes (orthonormal, both perpendicular to `light`).
    right: Vec3,
    up: Vec3,
    /// Map coordinates of texel (0, 0)'s corner, and texels per model unit.
    origin: Vec2,
    scale: f32,
    size: usize,
    /// Triangles facing away from the light.
    back: Layer,
    /// Triangles facing the light (only for meshes with boundary edges).
    front: Option<Layer>,
}

/// What a shadow map is rasterised from, kept across light directions: each triangle's
/// corners and normal, stored together and in a space-filling-curve order, so that a map
/// streams through them instead of jumping around the vertex array, and writes nearby texels
/// one after another.
pub struct ShadowCaster {
    triangles: Vec<CasterTriangle>,
    /// The mesh has boundary edges: rasterise the triangles facing the light too.
    open: bool,
    bounds: (Vec3, Vec3),
}

#[derive(Clone, Copy)]
struct CasterTriangle {
    corners: [Vec3; 3],
    /// Unnormalised geometric normal (its sign is all that matters).
    normal: Vec3,
}

impl ShadowCaster {
    /// Prepares `mesh`.
    pub fn new(mesh: &Mesh) -> ShadowCaster {
        let bounds = mesh.bounds();
        let extent = (bounds.1 - bounds.0).max(Vec3::splat(1e-12));
        let mut keyed: Vec<(u64, CasterTriangle)> = (0..mesh.face_count())
            .into_par_iter()
            .map(|f| {
                let corners = mesh.triangle_positions(f);
                let normal = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
                let centre = (corners[0] + corners[1] + corners[2]) / 3.0;
                let cell = ((centre - bounds.0) / extent * 1023.0).as_uvec3();
                (morton(cell.x, cell.y, cell.z), CasterTriangle { corners, normal })
            })
            .collect();
        keyed.par_sort_unstable_by_key(|k| k.0);
        let open = !crate::mesh::topology::boundary_edges(mesh).is_empty();
        ShadowCaster { triangles: keyed.into_iter().map(|k| k.1).collect(), open, bounds }
    }

    /// True if the mesh has boundary edges (see the module notes).
    pub fn is_open(&self) -> bool {
        self.open
    }

    /// The shadow map for a light towards `light` (a unit vector), `size × size` texels.
    pub fn map(&self, light: Vec3, size: usize) -> ShadowMap {
        let light = light.normalize();
        let helper = if light.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
        let right = helper.cross(light).normalize();
        let up = light.cross(right);
        // The bounding box's corners bound the map.
        let (lo, hi) = (0..8).fold((Vec2::MAX, Vec2::MIN), |(lo, hi), k| {
            let (a, b) = self.bounds;
            let c = Vec3::new(
                if k & 1 == 0 { a.x } else { b.x },
                if k & 2 == 0 { a.y } else { b.y },
                if k & 4 == 0 { a.z } else { b.z },
            );
            let p = Vec2::new(c.dot(right), c.dot(up));
            (lo.min(p), hi.max(p))
        });
        let size = size.max(2);
        let extent = (hi - lo).max_element().max(1e-12);
        // Half a texel of margin on each side, so every point falls inside.
        let scale = (size as f32 - 1.0) / extent;
        let origin = lo - Vec2::splat(0.5 / scale);
        let mut map = ShadowMap { light, right, up, origin, scale, size, back: Vec::new(), front: None };
        map.back = map.rasterise(&self.triangles, false);
        if self.open {
            map.front = Some(map.rasterise(&self.triangles, true));
        }
        map
    }
}

/// The Morton code of a 10-bit cell: its bits interleaved.
fn morton(x: u32, y: u32, z: u32) -> u64 {
    let spread = |v: u32| {
        let mut v = v as u64 & 0x3ff;
        v = (v | v << 16) & 0x0300_00ff;
        v = (v | v << 8) & 0x0300_f00f;
        v = (v | v << 4) & 0x030c_30c3;
        (v | v << 2) & 0x0924_9249
    };
    spread(x) | spread(y) << 1 | spread(z) << 2
}

impl ShadowMap {
    /// Rasterises `mesh` along `light` (a unit vector towards it) into `size × size`
    /// texels (see [`ShadowCaster`], which keeps the preparation for the next light).
    pub fn new(mesh: &Mesh, light: Vec3, size: usize) -> ShadowMap {
        ShadowCaster::new(mesh).map(light, size)
    }

    /// One texel's side in model units.
    pub fn texel(&self) -> f32 {
        1.0 / self.scale
    }

    /// The layer of the triangles facing the light (`facing`) or away from it.
    fn rasterise(&self, triangles: &[CasterTriangle], facing: bool) -> Layer {
        let empty = || vec![f32::NEG_INFINITY; self.size * self.size];
        // One chunk per thread: each fills its own layer, merged once at the end.
        let chunk = triangles.len().div_ceil(rayon::current_num_threads()).max(1);
        triangles
            .par_chunks(chunk)
            .fold(empty, |mut layer, chunk| {
                for t in chunk {
                    let towards = t.normal.dot(self.light);
                    if (towards > 0.0) == facing && towards != 0.0 {
                        let project =
                            |p: Vec3| Vec3::new(p.dot(self.right), p.dot(self.up), p.dot(self.light));
                        let [a, b, c] = t.corners.map(project);
                        let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
                        if area != 0.0 {
                            self.fill(&mut layer, [a, b, c], area);
                        }
                    }
                }
                layer
            })
            .reduce(empty, |mut a, b| {
                a.iter_mut().zip(b).for_each(|(x, y)| *x = x.max(y));
                a
            })
    }

    /// Writes the triangle's height at every texel centre it covers (edges shared by two
    /// triangles cover their centres once or twice, never zero times).
    fn fill(&self, layer: &mut Layer, [a, b, c]: [Vec3; 3], area: f32) {
        let to_texel = |p: Vec3| (p.truncate() - self.origin) * self.scale;
        let (ta, tb, tc) = (to_texel(a), to_texel(b), to_texel(c));
        let lo = ta.min(tb).min(tc);
        let hi = ta.max(tb).max(tc);
        let (x0, y0) = ((lo.x - 0.5).ceil().max(0.0) as usize, (lo.y - 0.5).ceil().max(0.0) as usize);
        let (x1, y1) = ((hi.x - 0.5).floor() as isize, (hi.y - 0.5).floor() as isize);
        let last = self.size as isize - 1;
        let (x1, y1) = (x1.min(last), y1.min(last));
        if x1 < x0 as isize || y1 < y0 as isize {
            return;
        }
        // Edge functions over the signed area: the barycentric weights, whatever the winding.
        let inv = 1.0 / (area * self.scale * self.scale);
        let edge = |p: Vec2, q: Vec2, r: Vec2| (q.x - p.x) * (r.y - p.y) - (q.y - p.y) * (r.x - p.x);
        for y in y0..=y1 as usize {
            for x in x0..=x1 as usize {
                let s = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let (wa, wb, wc) = (edge(tb, tc, s) * inv, edge(tc, ta, s) * inv, edge(ta, tb, s) * inv);
                if wa >= 0.0 && wb >= 0.0 && wc >= 0.0 {
                    let h = wa * a.z + wb * b.z + wc * c.z;
                    let t = &mut layer[y * self.size + x];
                    *t = t.max(h);
                }
            }
        }
    }

    /// True if the light reaches `p`, a point on a surface with unit normal `normal` facing
    /// the light.
    pub fn lit(&self, p: Vec3, normal: Vec3) -> bool {
        let at = (Vec2::new(p.dot(self.right), p.dot(self.up)) - self.origin) * self.scale;
        let (x, y) = (at.x.max(0.0) as usize, at.y.max(0.0) as usize);
        let i = y.min(self.size - 1) * self.size + x.min(self.size - 1);
        let h = p.dot(self.light);
        let texel = self.texel();
        if self.back[i] > h + 0.5 * texel {
            return false;
        }
        let Some(front) = &self.front else { return true };
        // A surface facing the light rises across a texel by texel × tan(angle to the light).
        let cos = normal.dot(self.light).clamp(1e-3, 1.0);
        let slope = ((1.0 - cos * cos).sqrt() / cos).min(16.0);
        front[i] <= h + texel * (1.0 + 1.5 * slope)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed box [lo, hi], triangles wound counter-clockwise seen from outside.
    fn cube(lo: Vec3, hi: Vec3, positions: &mut Vec<Vec3>, triangles: &mut Vec<[u32; 3]>) {
        let base = positions.len() as u32;
        for k in 0..8 {
            positions.push(Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            ));
        }
        let faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        for f in faces {
            triangles.push([base + f[0], base + f[1], base + f[2]]);
            triangles.push([base + f[0], base + f[2], base + f[3]]);
        }
    }

    #[test]
    fn a_box_above_a_box_shadows_the_top_of_the_lower_one_below_it_only() {
        let (mut positions, mut triangles) = (Vec::new(), Vec::new());
        cube(Vec3::new(-4.0, -1.0, -4.0), Vec3::new(4.0, 0.0, 4.0), &mut positions, &mut triangles);
        cube(Vec3::new(-1.0, 2.0, -1.0), Vec3::new(1.0, 3.0, 1.0), &mut positions, &mut triangles);
        let mesh = Mesh::new(positions, triangles).unwrap();
        assert!(!ShadowCaster::new(&mesh).is_open());
        for light in [Vec3::Y, Vec3::new(0.01, 1.0, -0.02).normalize()] {
            let map = ShadowMap::new(&mesh, light, 256);
            for (x, z) in [(0.0, 0.0), (0.9, -0.9), (-0.5, 0.7)] {
                assert!(!map.lit(Vec3::new(x, 0.0, z), Vec3::Y), "({x}, {z}) lies under the upper box");
            }
            for (x, z) in [(1.2, 0.0), (3.5, 3.5), (-2.0, 1.0)] {
                assert!(map.lit(Vec3::new(x, 0.0, z), Vec3::Y), "({x}, {z}) is open to the sky");
            }
            // The tops of both boxes see the light: nothing shadows a surface itself.
            assert!(map.lit(Vec3::new(0.3, 3.0, 0.2), Vec3::Y));
        }
    }

    #[test]
    fn an_open_sheet_casts_a_shadow_from_its_front_layer() {
        // A square sheet facing the light above a point.
        let positions = vec![
            Vec3::new(-1.0, 2.0, -1.0),
            Vec3::new(1.0, 2.0, -1.0),
            Vec3::new(1.0, 2.0, 1.0),
            Vec3::new(-1.0, 2.0, 1.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.1, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.1),
        ];
        let mesh = Mesh::new(positions, vec![[0, 2, 1], [0, 3, 2], [4, 6, 5]]).unwrap();
        assert!(ShadowCaster::new(&mesh).is_open());
        let map = ShadowMap::new(&mesh, Vec3::Y, 64);
        assert!(!map.lit(Vec3::new(0.0, 0.0, 0.0), Vec3::Y), "under the sheet");
        assert!(map.lit(Vec3::new(0.5, 2.0, 0.5), Vec3::Y), "the sheet itself");
        assert!(map.lit(Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)) == map.lit(Vec3::ZERO, Vec3::Y));
    }
}
