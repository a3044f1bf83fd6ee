//! The texture layout an export bakes into: the user's own UVs, or a generated atlas.
//!
//! **Generated atlases** come from [uvunwrap], a pure-Rust implementation of xatlas'
//! pipeline (charts grown within a normal cone, LSCM + ARAP flattening with flip, overlap
//! and distortion checks, shape packing with padding). We chose it over the xatlas C++
//! library's Rust binding (`xatlas-rs`) because that binding wraps a 2019 snapshot of
//! xatlas, has not been updated since, returns slices whose lifetimes are not tied to the
//! atlas, ignores xatlas' error codes and needs a C++ toolchain; uvunwrap is maintained,
//! safe Rust, and its output is bit-identical whatever the thread count (our determinism
//! rule). It guarantees charts at least 2 × padding texels apart, which the gutter fill
//! relies on (see [`super::raster`]).
//!
//! glTF texture coordinates run right and *down* (v = 0 is the image's first row), OBJ and
//! PLY ones right and up; [`AtlasMesh::uv`] is in glTF's convention, and the user's UVs
//! are flipped (v ↦ 1 − v) on the way in, exactly.
//!
//! [uvunwrap]: https://docs.rs/uvunwrap

use crate::mesh::textured::{TexturedMesh, UvLayer};
use crate::progress::Progress;
use crate::{Error, Remedy, Result};
use glam::{Vec2, Vec3, Vec4};
use std::collections::HashMap;

/// The mesh as it is written to glTF: vertices split wherever a file vertex has several
/// texture coordinates, so each output vertex has one.
#[derive(Clone, Debug, PartialEq)]
pub struct AtlasMesh {
    /// Per output vertex, the file vertex it comes from.
    pub source_vertex: Vec<u32>,
    /// Per output vertex, its texture coordinate (glTF convention: u right, v down, the
    /// atlas spanning [0, 1]²).
    pub uv: Vec<Vec2>,
    /// The file's triangles, in order, over output vertices.
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle, its chart (a UV island: triangles joined through shared UVs).
    pub chart: Vec<u32>,
    /// True if the layout was generated (else it is the file's).
    pub generated: bool,
}

/// How a generated atlas is laid out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasOptions {
    /// Atlas width and height in texels.
    pub size: u32,
    /// Empty texels around each chart (charts are at least twice this apart).
    pub padding: u32,
}

impl AtlasMesh {
    /// The layout of the file's own UVs: one output vertex per distinct (vertex, UV) pair
    /// of the file, in order of first use.
    pub fn from_file_uvs(mesh: &TexturedMesh, uvs: &UvLayer) -> AtlasMesh {
        let mut index: HashMap<(u32, u32), u32> = HashMap::new();
        let (mut source_vertex, mut uv) = (Vec::new(), Vec::new());
        let triangles = mesh
            .triangles
            .iter()
            .zip(&uvs.corners)
            .map(|(t, c)| {
                std::array::from_fn(|k| {
                    *index.entry((t[k], c[k])).or_insert_with(|| {
                        source_vertex.push(t[k]);
                        let file = uvs.coords[c[k] as usize];
                        uv.push(Vec2::new(file.x, 1.0 - file.y));
                        (uv.len() - 1) as u32
                    })
                })
            })
            .collect();
        let chart = uv_islands(&uvs.corners, uvs.coords.len());
        AtlasMesh { source_vertex, uv, triangles, chart, generated: false }
    }

    /// A generated atlas (see the module documentation).
    pub fn generate(
        mesh: &TexturedMesh,
        options: AtlasOptions,
        progress: &dyn Progress,
    ) -> Result<AtlasMesh> {
        let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
        let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        let unwrap_options = uvunwrap::Options {
            density: uvunwrap::Density::Auto { page_size: options.size },
            padding: options.padding,
            ..uvunwrap::Options::default()
        };
        let mesh = uvunwrap::MeshInput::new(&positions, &indices);
        let atlas = uvunwrap::generate_with_progress(&[mesh], &unwrap_options, forward(progress))
            .map_err(|e| Error::invalid(format!("cannot generate a UV atlas: {e}")));
        progress.finish();
        let atlas = atlas?;
        if atlas.page_count > 1 {
            return Err(Error::too_large(
                format!("the generated atlas needs {} pages of {}² texels", atlas.page_count, options.size),
                Remedy::LargerAtlas,
            ));
        }
        let out = atlas.meshes.into_iter().next().unwrap_or_default();
        // The page is cropped to the rows it uses; keep texel rows where they are in a
        // square size × size image.
        let v_scale = atlas.height as f32 / options.size as f32;
        let source_vertex = out.vertices.iter().map(|v| v.xref).collect();
        let uv = out.vertices.iter().map(|v| Vec2::new(v.uv[0], v.uv[1] * v_scale)).collect();
        let triangles: Vec<[u32; 3]> = out.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        let chart = triangles
            .iter()
            .map(|t| t.iter().find_map(|&i| out.vertices[i as usize].chart).unwrap_or(u32::MAX))
            .collect();
        Ok(AtlasMesh { source_vertex, uv, triangles, chart, generated: true })
    }

    /// Number of output vertices.
    pub fn vertex_count(&self) -> usize {
        self.uv.len()
    }

    /// The summed area of the triangles in UV space (1 = the whole atlas).
    pub fn uv_area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.uv[i as usize]);
                0.5 * f64::from((b - a).perp_dot(c - a).abs())
            })
            .sum()
    }
}

/// uvunwrap's progress reports as ours: a stage per unwrapping stage.
fn forward(progress: &dyn Progress) -> impl Fn(uvunwrap::Progress) -> bool + Sync + '_ {
    let last = std::sync::Mutex::new(None::<(uvunwrap::Stage, usize)>);
    move |report| {
        let Ok(mut last) = last.lock() else { return true };
        let done = match *last {
            Some((stage, done)) if stage == report.stage => done,
            previous => {
                if previous.is_some() {
                    progress.finish();
                }
                let name = match report.stage {
                    uvunwrap::Stage::Segmenting => "segmenting",
                    uvunwrap::Stage::Parameterizing => "flattening",
                    uvunwrap::Stage::Packing => "packing",
                    _ => "unwrapping",
                };
                progress.start(name, report.total.unwrap_or(0) as u64);
                0
            }
        };
        progress.advance(report.done.saturating_sub(done) as u64);
        *last = Some((report.stage, report.done));
        true
    }
}

/// Per triangle, the island of its UVs: triangles sharing a UV index are one island.
fn uv_islands(corners: &[[u32; 3]], coords: usize) -> Vec<u32> {
    let mut parent: Vec<u32> = (0..coords as u32).collect();
    fn root(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            parent[i as usize] = parent[parent[i as usize] as usize];
            i = parent[i as usize];
        }
        i
    }
    for c in corners {
        for k in 1..3 {
            let (a, b) = (root(&mut parent, c[0]), root(&mut parent, c[k]));
            parent[a.max(b) as usize] = a.min(b);
        }
    }
    corners.iter().map(|c| root(&mut parent, c[0])).collect()
}

/// Unit normals per output vertex: the area-weighted mean of the faces around every file
/// vertex at the same position (so vertices split at UV seams share one normal and seams
/// do not show in the shading).
pub fn vertex_normals(mesh: &TexturedMesh, atlas: &AtlasMesh) -> Vec<Vec3> {
    let mut slot: HashMap<[u32; 3], usize> = HashMap::new();
    let position_slot: Vec<usize> = mesh
        .positions
        .iter()
        .map(|p| {
            let n = slot.len();
            *slot.entry(p.to_array().map(f32::to_bits)).or_insert(n)
        })
        .collect();
    let mut sum = vec![Vec3::ZERO; slot.len()];
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        let n = (b - a).cross(c - a);
        for &i in t {
            sum[position_slot[i as usize]] += n;
        }
    }
    atlas
        .source_vertex
        .iter()
        .map(|&v| sum[position_slot[v as usize]].try_normalize().unwrap_or(Vec3::Z))
        .collect()
}

/// glTF tangents per output vertex: xyz the unit direction of increasing u, w = ±1 such
/// that `w · (normal × tangent)` is the direction of *decreasing* glTF v, which is "up" in
/// the image and the +Y of a tangent-space normal map (glTF's normalTexture convention,
/// which Blender and the Khronos sample viewer follow). Mirrored charts get w = −1.
pub fn vertex_tangents(mesh: &TexturedMesh, atlas: &AtlasMesh, normals: &[Vec3]) -> Vec<Vec4> {
    let n = atlas.vertex_count();
    let (mut along_u, mut image_up) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
    for t in &atlas.triangles {
        let [p0, p1, p2] = t.map(|i| mesh.positions[atlas.source_vertex[i as usize] as usize]);
        let [q0, q1, q2] = t.map(|i| atlas.uv[i as usize]);
        let (e1, e2, d1, d2) = (p1 - p0, p2 - p0, q1 - q0, q2 - q0);
        let det = d1.perp_dot(d2);
        if det.abs() <= f32::EPSILON * (d1.length_squared() + d2.length_squared()) {
            continue;
        }
        // dP/du and dP/dv from the triangle's edges; weighting by |det| (its UV area) is
        // implicit in the unnormalised sums.
        let dpdu = (e1 * d2.y - e2 * d1.y) * det.signum();
        let dpdv = (e2 * d1.x - e1 * d2.x) * det.signum();
        for &i in t {
            along_u[i as usize] += dpdu;
            image_up[i as usize] -= dpdv;
        }
    }
    (0..n)
        .map(|i| {
            let normal = normals[i];
            let t = along_u[i] - normal * normal.dot(along_u[i]);
            let t = t.try_normalize().unwrap_or_else(|| normal.any_orthonormal_vector());
            let w = if normal.cross(t).dot(image_up[i]) < 0.0 { -1.0 } else { 1.0 };
            t.extend(w)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit quad in z = 0 with UVs (x, y): u along +X, file v along +Y.
    fn quad() -> TexturedMesh {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let coords = positions.iter().map(|p| p.truncate()).collect();
        let triangles = vec![[0, 1, 2], [0, 2, 3]];
        TexturedMesh { positions, uvs: Some(UvLayer { coords, corners: triangles.clone() }), triangles }
    }

    #[test]
    fn file_uvs_are_flipped_into_gltf_convention_and_shared() {
        let mesh = quad();
        let atlas = AtlasMesh::from_file_uvs(&mesh, mesh.uvs.as_ref().expect("uvs"));
        assert_eq!(atlas.vertex_count(), 4);
        assert_eq!(atlas.uv[2], Vec2::new(1.0, 0.0));
        assert_eq!(atlas.chart, vec![0, 0]);
        assert!((atlas.uv_area() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn tangents_follow_u_and_their_sign_follows_image_up() {
        let mesh = quad();
        let atlas = AtlasMesh::from_file_uvs(&mesh, mesh.uvs.as_ref().expect("uvs"));
        let normals = vertex_normals(&mesh, &atlas);
        assert!(normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
        // File v runs along +Y, so image up (decreasing glTF v) is +Y = Z × X: w = +1.
        for t in vertex_tangents(&mesh, &atlas, &normals) {
            assert!((t - Vec4::new(1.0, 0.0, 0.0, 1.0)).length() < 1e-6, "{t}");
        }
        // Mirrored in v: image up is −Y, so w = −1.
        let mut mirrored = mesh.clone();
        for c in &mut mirrored.uvs.as_mut().expect("uvs").coords {
            c.y = 1.0 - c.y;
        }
        let atlas = AtlasMesh::from_file_uvs(&mirrored, mirrored.uvs.as_ref().expect("uvs"));
        for t in vertex_tangents(&mirrored, &atlas, &normals) {
            assert!((t - Vec4::new(1.0, 0.0, 0.0, -1.0)).length() < 1e-6, "{t}");
        }
    }

    #[test]
    fn islands_are_joined_through_shared_uvs_only() {
        let corners = [[0, 1, 2], [2, 1, 3], [4, 5, 6]];
        assert_eq!(uv_islands(&corners, 7), vec![0, 0, 4]);
    }

    #[test]
    fn a_generated_atlas_covers_every_triangle_inside_the_unit_square() {
        let mesh = crate::mesh::textured::load_textured(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/data/bunny-1k8.obj"
        )))
        .expect("the bundled bunny loads");
        let atlas =
            AtlasMesh::generate(&mesh, AtlasOptions { size: 256, padding: 2 }, &crate::progress::Silent)
                .expect("unwraps");
        assert!(atlas.generated);
        assert_eq!(atlas.triangles.len(), mesh.triangles.len());
        assert!(atlas.uv.iter().all(|uv| (0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y)));
        assert!(atlas.chart.iter().all(|&c| c != u32::MAX));
        let charts: std::collections::HashSet<u32> = atlas.chart.iter().copied().collect();
        assert!(
            charts.len() > 1 && atlas.uv_area() > 0.2,
            "{} charts, area {}",
            charts.len(),
            atlas.uv_area()
        );
    }
}
