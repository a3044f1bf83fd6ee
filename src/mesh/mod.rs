//! Triangle meshes: the surface that synthesis puts a texture on.
//!
//! - [`Mesh`]: positions, triangles and optional area-weighted vertex normals. Every `Mesh`
//!   is valid by construction: indices in range, finite coordinates, no degenerate faces,
//!   coincident vertices welded, every edge shared by at most two consistently oriented
//!   faces and every vertex a single fan (see [`prepare`]).
//! - [`load`](mod@load): OBJ, OFF and PLY (ASCII and binary), picked by extension.
//! - [`topology`]: edges, one-rings, boundaries, connected components.
//! - [`field`]: per-vertex direction fields (smooth, one axis, or user constraints) and
//!   the tangent frames they give.
//! - [`remesh`]: isotropic remeshing to a target edge length or vertex count
//!   (Botsch & Kobbelt 2004), which gives synthesis evenly spaced samples.
//! - [`ply::write`](mod@ply::write): binary PLY output with named per-vertex properties.
//! - [`textured`]: a mesh exactly as its file gives it, with its texture coordinates (for
//!   `export`).
//!
//! ```no_run
//! use btfsynth::mesh::{self, remesh};
//!
//! let bunny = mesh::load(std::path::Path::new("bunny.obj"))?;
//! let fine = remesh::remesh_to_vertex_count(&bunny, 50_000)?;
//! println!("{:?}", remesh::edge_length_stats(&fine));
//! # Ok::<(), btfsynth::Error>(())
//! ```

pub mod bvh;
pub mod field;
mod field_hierarchy;
pub mod frames;
pub mod layout;
pub mod load;
mod manifold;
pub mod obj;
pub mod off;
pub mod ply;
pub mod prepare;
pub mod remesh;
pub mod textured;
pub mod topology;
pub(crate) mod weld;

pub use load::{load, load_with, LoadOptions};
pub use prepare::Soup;

use crate::Result;
use glam::Vec3;

/// A valid triangle mesh. Faces are counter-clockwise seen from outside (where the input
/// was orientable, faces that disagreed with their neighbours have been flipped).
#[derive(Clone, Debug)]
pub struct Mesh {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    normals: Option<Vec<Vec3>>,
}

impl Mesh {
    /// Builds a mesh from vertex positions and triangles, repairing what can be repaired
    /// exactly as the loaders do (see [`prepare::prepare`], default [`LoadOptions`]).
    /// Errors name `"<in-memory mesh>"` as the file.
    pub fn new(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Result<Mesh> {
        let soup = Soup {
            positions: positions.iter().map(|p| p.as_dvec3().to_array()).collect(),
            triangles: triangles.iter().map(|t| t.map(i64::from)).collect(),
        };
        prepare::prepare(soup, std::path::Path::new("<in-memory mesh>"), &LoadOptions::default())
    }

    /// For code in this module that has already established every invariant of `Mesh`.
    pub(crate) fn from_valid_parts(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Mesh {
        Mesh { positions, triangles, normals: None }
    }

    /// A mesh to render, not to process: it may hold coincident vertices (texture seams
    /// split apart) and zero-area faces, and keeps the given `normals` (one per vertex).
    pub(crate) fn from_split_parts(
        positions: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        normals: Vec<Vec3>,
    ) -> Mesh {
        Mesh { positions, triangles, normals: Some(normals) }
    }

    /// Vertex positions.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Triangles as counter-clockwise vertex index triples.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Unit vertex normals, if computed ([`Mesh::compute_normals`]); loaders and the
    /// remesher compute them.
    pub fn normals(&self) -> Option<&[Vec3]> {
        self.normals.as_deref()
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn face_count(&self) -> usize {
        self.triangles.len()
    }

    /// The three corner positions of triangle `f` (panics if `f` is out of range, like
    /// slice indexing; `f` comes from this mesh, not from a user).
    pub fn triangle_positions(&self, f: usize) -> [Vec3; 3] {
        self.triangles[f].map(|i| self.positions[i as usize])
    }

    /// Axis-aligned bounds `(min, max)`; a mesh always has at least one face, so they exist.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        bounds_of(&self.positions)
    }

    /// Total surface area.
    pub fn surface_area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|f| {
                let [a, b, c] = self.triangle_positions(f);
                0.5 * f64::from((b - a).cross(c - a).length())
            })
            .sum()
    }

    /// Computes unit vertex normals as the area-weighted mean of the incident face
    /// normals (the unnormalised cross product is twice the area times the normal, so
    /// summing it weights by area for free). An isolated or fully degenerate fan gets +Z.
    pub fn compute_normals(&mut self) {
        let mut sum = vec![Vec3::ZERO; self.positions.len()];
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| self.positions[i as usize]);
            let n = (b - a).cross(c - a);
            for &i in t {
                sum[i as usize] += n;
            }
        }
        self.normals = Some(sum.into_iter().map(|n| n.try_normalize().unwrap_or(Vec3::Z)).collect());
    }

    /// The mesh with its normals computed.
    pub fn with_normals(mut self) -> Mesh {
        self.compute_normals();
        self
    }

    /// Splits the mesh into positions, triangles and normals.
    pub fn into_parts(self) -> (Vec<Vec3>, Vec<[u32; 3]>, Option<Vec<Vec3>>) {
        (self.positions, self.triangles, self.normals)
    }
}

/// Axis-aligned bounds of a point set; `(+inf, -inf)` for an empty one.
pub fn bounds_of(points: &[Vec3]) -> (Vec3, Vec3) {
    points.iter().fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(lo, hi), &p| {
        (lo.min(p), hi.max(p))
    })
}

#[cfg(test)]
pub(crate) mod test_meshes {
    //! Small meshes built in code, shared by the tests of this module's submodules.
    use super::Mesh;
    use glam::Vec3;

    /// Path of a mesh bundled in `data/` (shipped with the crate, so always there).
    pub fn bundled(name: &str) -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data").join(name)
    }

    /// Path of a mesh in the shared test data, or None (with a line saying `test` was
    /// skipped) where it is absent; see [`crate::testdata`].
    pub fn shared(test: &str, name: &str) -> Option<std::path::PathBuf> {
        crate::testdata::shared_data(test, &format!("meshes/{name}"))
    }

    /// An axis-aligned unit cube, 8 vertices and 12 outward-facing triangles.
    pub fn cube() -> Mesh {
        let p =
            (0..8).map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32)).collect();
        #[rustfmt::skip]
        let t = vec![
            [0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], // z = 0, z = 1
            [0, 1, 4], [1, 5, 4], [2, 6, 3], [3, 6, 7], // y = 0, y = 1
            [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5], // x = 0, x = 1
        ];
        Mesh::new(p, t).expect("the cube is valid")
    }

    /// An `n`×`n`-quad grid on the unit square in the z = 0 plane (an open disc).
    pub fn grid(n: u32) -> Mesh {
        let mut p = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                p.push(Vec3::new(i as f32 / n as f32, j as f32 / n as f32, 0.0));
            }
        }
        let mut t = Vec::new();
        let at = |i: u32, j: u32| j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                t.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                t.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        Mesh::new(p, t).expect("the grid is valid")
    }
}

#[cfg(test)]
mod tests {
    use super::test_meshes::*;
    use super::*;

    #[test]
    fn cube_normals_point_outwards_along_diagonals() {
        let cube = cube().with_normals();
        let normals = cube.normals().expect("computed");
        for (p, n) in cube.positions().iter().zip(normals) {
            let outward = (*p - Vec3::splat(0.5)).normalize();
            assert!(n.dot(outward) > 0.9, "{p} has normal {n}");
        }
    }

    #[test]
    fn area_and_bounds_of_the_unit_cube() {
        let cube = cube();
        assert!((cube.surface_area() - 6.0).abs() < 1e-9);
        assert_eq!(cube.bounds(), (Vec3::ZERO, Vec3::ONE));
    }

    #[test]
    fn area_weighting_favours_the_large_face() {
        // A big triangle in z = 0 and a small one tilted up share the edge 0–1.
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.5, -10.0, 0.0),
            Vec3::new(0.5, 0.1, 0.1),
        ];
        let m = Mesh::new(p, vec![[0, 2, 1], [0, 1, 3]]).expect("valid").with_normals();
        let n0 = m.normals().expect("computed")[0];
        assert!(n0.z > 0.99, "the large face's normal dominates: {n0}");
    }
}
