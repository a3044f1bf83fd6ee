//! Baking: per atlas texel, the surface point it shows on the user's mesh, the nearest point
//! of the synthesized surface, the sample coordinate there, and the material looked up.
//!
//! The lookup is the renderer's pixel mode ([`crate::render::Mode::Pixel`]): one coordinate
//! per texel ([`Scene::point_uv`]: the corners' predictions interpolated where they show one
//! copy of the sample, the heavier side taken whole at a seam), and one lookup there through
//! the shared shading core ([`Material::shade`]), so the texture is as crisp as the sample
//! and a seam is a cut, never a blend of two copies: only its edge is spread over one
//! sample texel, as the sample's own edges are where the atlas magnifies it. The
//! *coordinate map* holds the coordinate.
//!
//! **Normal maps** are re-oriented by the corners' frames: the sample's tangent-space normal
//! (x along the sample's s, y along t = image up, z along n) is turned into a world
//! direction with the synthesized frames (s, t, n) of the corners whose copy it shows, and the
//! result is expressed in the atlas' tangent frame at the texel (the glTF tangent, bitangent
//! and normal interpolated from the mesh's vertices, see [`super::layout::vertex_tangents`]).
//! A sample laid on the surface rotated by 90° thus gets its normals' x and y rotated by
//! 90°, and mirrored charts get y flipped, as the renderer that reads the map expects.

use super::layout::AtlasMesh;
use super::raster::{barycentric, fill_gutters, gutter_sources, Coverage};
use crate::btf::{Direction, DirectionPair};
use crate::maps::{MapKind, MaterialMap};
use crate::mesh::bvh::TriangleBvh;
use crate::mesh::textured::TexturedMesh;
use crate::progress::Progress;
use crate::render::scene::one_copy;
use crate::render::{Blend16, Material, Scene};
use crate::{Error, Result};
use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;

/// The image a baked colour shows: the sample seen head-on under `light` (in the sample's
/// frame), or with `None` the stack's image nearest head-on view and light (least θ_view +
/// θ_light; a one-image BTF's only image).
pub fn bake_blend(material: &Material, light: Option<Direction>) -> Blend16 {
    match light {
        Some(light) => material.blend(Vec3::Z, light.unit()),
        None => {
            let frontal = |p: &DirectionPair| p.view.theta + p.light.theta;
            let best = (0..material.len())
                .min_by(|&a, &b| frontal(&material.pairs()[a]).total_cmp(&frontal(&material.pairs()[b])))
                .unwrap_or(0);
            let mut blend = Blend16::DARK;
            blend.image[0] = best as u32;
            blend.weight[0] = 1.0;
            blend
        }
    }
}

/// A material map ready for lookups: its values (normalised; normals decoded to [-1, 1])
/// as a one-image material, so the lookup is the shading core's bilinear one.
pub struct MapLookup {
    /// What the map holds.
    pub kind: MapKind,
    /// The depth the map was stored at (a slot texture is 8-bit only if every map behind
    /// it is).
    pub depth: crate::maps::Depth,
    lookup: Material,
}

impl MapLookup {
    /// Prepares `map`; lookups wrap like the sample when `tileable`.
    pub fn new(map: &MaterialMap, tileable: bool) -> Result<MapLookup> {
        let image = &map.image;
        let mut values = image.normalised_rgb();
        if map.kind == MapKind::Normal && !image.depth.is_float() {
            values.iter_mut().for_each(|v| *v = 2.0 * *v - 1.0);
        }
        let frontal = DirectionPair { light: Direction::NORMAL, view: Direction::NORMAL };
        let mut lookup = Material::new(image.width, image.height, values, vec![frontal])
            .map_err(|e| Error::format(&map.source, e.to_string()))?;
        lookup.tileable = tileable;
        Ok(MapLookup { kind: map.kind, depth: image.depth, lookup })
    }

    pub(crate) fn at(&self, uv: Vec2) -> Vec3 {
        self.lookup.texel(0, uv.x, uv.y)
    }
}

/// The surface being textured: the user's mesh in its atlas, with the per-vertex glTF frame
/// that normal maps are expressed in.
pub struct Target<'a> {
    /// The user's mesh (positions).
    pub mesh: &'a TexturedMesh,
    /// Its texture layout.
    pub atlas: &'a AtlasMesh,
    /// Unit normals per atlas vertex.
    pub normals: &'a [Vec3],
    /// glTF tangents per atlas vertex (empty when no normal map is baked).
    pub tangents: &'a [Vec4],
}

/// The synthesized surface and what is looked up on it.
pub struct Source<'a> {
    /// The surface map (dense mesh, frames, sample coordinates).
    pub scene: &'a Scene,
    /// Its nearest-point hierarchy.
    pub bvh: &'a TriangleBvh,
    /// The BTF.
    pub material: &'a Material,
    /// The image the colour shows ([`bake_blend`]).
    pub blend: Blend16,
    /// Material maps baked alongside.
    pub maps: &'a [MapLookup],
}

/// Baked textures of one atlas, every gutter texel filled from its nearest baked texel.
#[derive(Clone, Debug)]
pub struct Baked {
    /// Atlas width in texels.
    pub width: usize,
    /// Atlas height in texels.
    pub height: usize,
    /// Per texel: true if baked from a triangle, false in a gutter.
    pub covered: Vec<bool>,
    /// Per texel: linear RGB.
    pub colour: Vec<Vec3>,
    /// Per texel: the sample coordinate (texels, inside the sample).
    pub coordinate: Vec<Vec2>,
    /// Per map, in the order given: per texel its value (a unit tangent-space vector for
    /// normals; the map's first three channels otherwise).
    pub maps: Vec<Vec<Vec3>>,
}

/// Bakes `source` into `target`'s texels listed by `coverage`.
pub fn bake(target: &Target, source: &Source, coverage: &Coverage, progress: &dyn Progress) -> Result<Baked> {
    let (w, h) = (coverage.width, coverage.height);
    let sources = gutter_sources(coverage).ok_or_else(|| {
        Error::invalid("no triangle of the mesh covers a texel of the atlas (are its UVs all degenerate?)")
    })?;
    // One interleaved row of floats per texel (colour, coordinate, maps), filled in
    // parallel by rows, then split into one buffer per texture.
    let stride = 5 + 3 * source.maps.len();
    let mut values = vec![0.0f32; w * h * stride];
    progress.start("baking", h as u64);
    values.par_chunks_mut(w * stride).enumerate().for_each(|(y, row)| {
        // Neighbouring texels are near one another on the surface: the previous texel's
        // triangle bounds the nearest-point search from the start.
        let mut hint = 0u32;
        for (x, out) in row.chunks_exact_mut(stride).enumerate() {
            let i = y * w + x;
            if coverage.triangle[i] != Coverage::NONE {
                let texel = (coverage.triangle[i] as usize, coverage.bary[i]);
                bake_texel(target, source, texel, (w, h), &mut hint, out);
            }
        }
        progress.advance(1);
    });
    progress.finish();
    let column = |offset: usize| -> Vec<Vec3> {
        let mut c: Vec<Vec3> =
            values.chunks_exact(stride).map(|t| Vec3::from_slice(&t[offset..offset + 3])).collect();
        fill_gutters(&mut c, &sources);
        c
    };
    let mut coordinate: Vec<Vec2> = values.chunks_exact(stride).map(|t| Vec2::new(t[3], t[4])).collect();
    fill_gutters(&mut coordinate, &sources);
    Ok(Baked {
        width: w,
        height: h,
        covered: coverage.triangle.iter().map(|&t| t != Coverage::NONE).collect(),
        colour: column(0),
        coordinate,
        maps: (0..source.maps.len()).map(|m| column(5 + 3 * m)).collect(),
    })
}

/// Bakes one texel, showing point `bary` of atlas triangle `triangle`, into `out`: colour
/// (3), coordinate (2), then 3 values per map.
fn bake_texel(
    target: &Target,
    source: &Source,
    (triangle, bary): (usize, Vec3),
    atlas_size: (usize, usize),
    hint: &mut u32,
    out: &mut [f32],
) {
    let corners = target.atlas.triangles[triangle];
    let look = |bary: Vec3, hint: &mut u32| surface_point(target, source, corners, bary, hint);
    let SurfacePoint { uv, chosen, dense } = look(bary, hint);
    let scene = source.scene;
    let mut colour = source.material.shade(&source.blend, uv.x, uv.y);
    let belonging = scene.belonging(source.material);
    if dense.iter().any(|&v| belonging[v] < 1.0) {
        // A seam may pass within a sample texel of the texel (a corner has a neighbour
        // of another copy). Its cut on the atlas' grid would be a staircase of texels,
        // which a close view magnifies into teeth, and where the atlas magnifies the
        // sample, a step sharper than any edge of the sample. Each side's share of a
        // footprint of one atlas texel, or one sample texel where that is larger, makes it
        // an edge as soft as the sample's own; a place on the centre's side counts as the
        // centre, so that no copy is blurred inside.
        if let Some(steps) = texel_steps(target, corners, atlas_size) {
            let steps = seam_footprint(target, corners, steps, scene.texel);
            let centre = colour;
            let mut sum = Vec3::ZERO;
            for [dx, dy] in SEAM_SAMPLES {
                let there = look(bary + dx * steps[0] + dy * steps[1], hint).uv;
                sum += if one_copy(source.material, uv, there) {
                    centre
                } else {
                    source.material.shade(&source.blend, there.x, there.y)
                };
            }
            colour = sum / SEAM_SAMPLES.len() as f32;
        }
    }
    out[..3].copy_from_slice(&colour.to_array());
    out[3..5].copy_from_slice(&inside(source.material, uv).to_array());
    for (map, out) in source.maps.iter().zip(out[5..].chunks_exact_mut(3)) {
        let value = map.at(uv);
        let value = match map.kind {
            MapKind::Normal => {
                // The sample's normal turned into the world by the frames of the corners
                // whose copy the point shows.
                let f = &scene.frames;
                let world: Vec3 = (0..3)
                    .map(|k| {
                        chosen[k]
                            * (value.x * f.s[dense[k]] + value.y * f.t[dense[k]] + value.z * f.n[dense[k]])
                    })
                    .sum();
                to_tangent_space(world, target, corners, bary)
            }
            _ => value,
        };
        out.copy_from_slice(&value.to_array());
    }
}

/// `steps` (one atlas texel along each axis) widened to one sample texel (`texel` model
/// units) where the atlas magnifies the sample: a seam is then as soft as an edge of the
/// sample itself, which a bilinear lookup spreads over one sample texel.
fn seam_footprint(target: &Target, corners: [u32; 3], steps: [Vec3; 2], texel: f32) -> [Vec3; 2] {
    let position = |k: usize| target.mesh.positions[target.atlas.source_vertex[corners[k] as usize] as usize];
    let at = |b: Vec3| position(0) * b.x + position(1) * b.y + position(2) * b.z;
    // Steps sum to no weight, so they map to displacements.
    let length = |b: Vec3| at(b).length();
    let atlas_texel = (length(steps[0]) * length(steps[1])).sqrt();
    let widen = if atlas_texel > 0.0 { (texel / atlas_texel).max(1.0) } else { 1.0 };
    steps.map(|s| s * widen)
}

/// Where in a seam's footprint it is looked up (a rotated grid, in footprints from its
/// centre).
const SEAM_SAMPLES: [[f32; 2]; 4] = [[-0.125, -0.375], [0.375, -0.125], [0.125, 0.375], [-0.375, 0.125]];

/// What the synthesized surface shows at a point of the user's mesh.
struct SurfacePoint {
    /// The sample coordinate.
    uv: Vec2,
    /// The weight of each corner of the dense triangle in it ([`Scene::point_uv`]).
    chosen: [f32; 3],
    /// The dense triangle's corners.
    dense: [usize; 3],
}

/// What the synthesized surface shows at point `bary` of atlas triangle `corners` (`hint`:
/// the dense triangle nearest the last point looked up).
fn surface_point(
    target: &Target,
    source: &Source,
    corners: [u32; 3],
    bary: Vec3,
    hint: &mut u32,
) -> SurfacePoint {
    let position = |k: usize| target.mesh.positions[target.atlas.source_vertex[corners[k] as usize] as usize];
    let p = position(0) * bary.x + position(1) * bary.y + position(2) * bary.z;
    let nearest = source.bvh.closest_point_near(p, *hint);
    *hint = nearest.triangle;
    let scene = source.scene;
    let dense = scene.mesh.triangles()[nearest.triangle as usize].map(|v| v as usize);
    let [a, b, c] = dense.map(|v| scene.mesh.positions()[v]);
    let weights = barycentric(nearest.point, a, b, c);
    let (uv, chosen) = scene.point_uv(source.material, dense.map(|v| v as u32), weights, nearest.point);
    SurfacePoint { uv, chosen, dense }
}

/// The change in barycentric weights on atlas triangle `corners` for one texel along the
/// atlas' columns and one along its rows (none for a triangle of no area in the atlas).
fn texel_steps(target: &Target, corners: [u32; 3], (width, height): (usize, usize)) -> Option<[Vec3; 2]> {
    let size = Vec2::new(width as f32, height as f32);
    let [u0, u1, u2] = corners.map(|c| target.atlas.uv[c as usize] * size);
    let (e1, e2) = (u1 - u0, u2 - u0);
    let det = e1.x * e2.y - e2.x * e1.y;
    if det.abs() < 1e-9 {
        return None;
    }
    // (b1, b2) = M⁻¹ (x − u0) with M = [e1 e2]; b0 = 1 − b1 − b2.
    let step = |d: Vec2| {
        let (b1, b2) = ((d.x * e2.y - e2.x * d.y) / det, (e1.x * d.y - d.x * e1.y) / det);
        Vec3::new(-b1 - b2, b1, b2)
    };
    Some([step(Vec2::X), step(Vec2::Y)])
}

/// A world direction in the atlas' tangent frame at a point of an atlas triangle: (along
/// the tangent, along the bitangent, along the normal), normalised.
fn to_tangent_space(world: Vec3, target: &Target, corners: [u32; 3], bary: Vec3) -> Vec3 {
    let b = bary.to_array();
    let normal: Vec3 = (0..3).map(|k| b[k] * target.normals[corners[k] as usize]).sum();
    let normal = normal.try_normalize().unwrap_or(Vec3::Z);
    let tangent: Vec3 = (0..3).map(|k| b[k] * target.tangents[corners[k] as usize].truncate()).sum();
    let tangent = (tangent - normal * normal.dot(tangent))
        .try_normalize()
        .unwrap_or_else(|| normal.any_orthonormal_vector());
    let nearest = (0..3).max_by(|&i, &j| b[i].total_cmp(&b[j])).unwrap_or(0);
    let bitangent = normal.cross(tangent) * target.tangents[corners[nearest] as usize].w;
    Vec3::new(world.dot(tangent), world.dot(bitangent), world.dot(normal)).try_normalize().unwrap_or(Vec3::Z)
}

/// A sample coordinate brought inside the sample the way lookups do: wrapped on a tileable
/// sample, clamped to the outermost texel centres otherwise.
fn inside(material: &Material, uv: Vec2) -> Vec2 {
    let size = Vec2::new(material.width() as f32, material.height() as f32);
    if material.tileable {
        Vec2::new(uv.x.rem_euclid(size.x), uv.y.rem_euclid(size.y))
    } else {
        uv.clamp(Vec2::ZERO, size - 1.0)
    }
}

/// Per vertex of the synthesized surface, its colour under `blend` (Tong §6's vertex mode).
pub fn vertex_colours(scene: &Scene, material: &Material, blend: &Blend16) -> Vec<Vec3> {
    scene.uv.par_iter().with_min_len(4096).map(|uv| material.shade(blend, uv.x, uv.y)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::layout::AtlasMesh;
    use crate::mesh::textured::TexturedMesh;

    #[test]
    fn a_texel_step_moves_a_point_one_texel_across_the_atlas() {
        let uv = vec![Vec2::new(0.1, 0.2), Vec2::new(0.7, 0.25), Vec2::new(0.3, 0.9)];
        let mesh = TexturedMesh { positions: vec![Vec3::ZERO; 3], triangles: vec![[0, 1, 2]], uvs: None };
        let atlas = AtlasMesh {
            source_vertex: vec![0, 1, 2],
            uv,
            triangles: vec![[0, 1, 2]],
            chart: vec![0],
            generated: true,
        };
        let target = Target { mesh: &mesh, atlas: &atlas, normals: &[], tangents: &[] };
        let (width, height) = (64, 32);
        let size = Vec2::new(width as f32, height as f32);
        let [dx, dy] = texel_steps(&target, [0, 1, 2], (width, height)).unwrap();
        let at = |b: Vec3| (0..3).map(|k| b[k] * atlas.uv[k] * size).sum::<Vec2>();
        let centre = Vec3::new(0.3, 0.3, 0.4);
        assert!((at(centre + dx) - at(centre) - Vec2::X).length() < 1e-4);
        assert!((at(centre + dy) - at(centre) - Vec2::Y).length() < 1e-4);
        assert!((dx.element_sum()).abs() < 1e-6 && (dy.element_sum()).abs() < 1e-6, "weights still sum to 1");
        let flat = AtlasMesh { uv: vec![Vec2::ZERO; 3], ..atlas.clone() };
        let target = Target { atlas: &flat, ..target };
        assert!(texel_steps(&target, [0, 1, 2], (width, height)).is_none());
    }
}
