//! Reading a mesh file, with the format picked by the extension (case-insensitive):
//! `.obj` ([`super::obj`]), `.off` ([`super::off`]), `.ply` ([`super::ply`]).

use super::{obj, off, ply, prepare, topology, Mesh, Soup};
use crate::{Error, Result};
use std::path::Path;

/// How a mesh file is turned into a [`Mesh`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadOptions {
    /// Vertices closer than this fraction of the bounding-box diagonal (and than 1% of the
    /// shortest edge at either of them) are welded into one (default `1e-6`: far below any
    /// real feature, above the rounding of coordinates written with six significant
    /// digits). `0` welds only identical positions.
    pub weld_tolerance: f32,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions { weld_tolerance: 1e-6 }
    }
}

/// Reads the mesh at `path` with the default [`LoadOptions`].
pub fn load(path: &Path) -> Result<Mesh> {
    load_with(path, &LoadOptions::default())
}

/// Reads the mesh at `path`, validates and repairs it (see [`prepare`](mod@super::prepare)),
/// and logs its topology.
pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Mesh> {
    let soup = read_soup(path)?;
    let mesh = prepare::prepare(soup, path, options)?;
    check_fans(&mesh, path)?;
    tracing::info!("{}: {}", path.display(), topology::summary(&mesh));
    Ok(mesh)
}

/// The most triangles one vertex may be a corner of. Polygons are fan-triangulated, so a
/// polygon of thousands of corners gives one vertex that many slivers, on which remeshing
/// takes minutes and gigabytes; no real mesh comes near (a vertex has about six).
pub const MAX_VERTEX_TRIANGLES: usize = 1024;

/// Refuses a vertex in more than [`MAX_VERTEX_TRIANGLES`] triangles.
fn check_fans(mesh: &Mesh, path: &Path) -> Result<()> {
    check_fans_of(mesh.triangles(), mesh.vertex_count(), path)
}

/// Refuses a vertex of `triangles` (over `vertices` vertices, named `path` in errors) in
/// more than [`MAX_VERTEX_TRIANGLES`] of them: every path that meshes or maps a file
/// refuses a huge polygon at once.
pub(crate) fn check_fans_of(triangles: &[[u32; 3]], vertices: usize, path: &Path) -> Result<()> {
    let mut count = vec![0usize; vertices];
    for t in triangles {
        for &i in t {
            count[i as usize] += 1;
        }
    }
    match count.iter().enumerate().find(|&(_, &n)| n > MAX_VERTEX_TRIANGLES) {
        Some((v, &n)) => Err(Error::format(
            path,
            format!(
                "vertex {v} is a corner of {n} triangles, more than {MAX_VERTEX_TRIANGLES} (a polygon of \
                 that many corners, fan-triangulated?); triangulate it evenly first"
            ),
        )),
        None => Ok(()),
    }
}

/// Parses `path` into a triangle soup without validating it.
pub fn read_soup(path: &Path) -> Result<Soup> {
    let parse = parser_for(path)?;
    let bytes = crate::fsutil::read_input(path)?;
    parse(&bytes, path)
}

type Parser = fn(&[u8], &Path) -> Result<Soup>;

fn parser_for(path: &Path) -> Result<Parser> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    match ext.as_str() {
        "obj" => Ok(obj::parse),
        "off" => Ok(off::parse),
        "ply" => Ok(ply::read::parse),
        _ => Err(Error::format(path, "unknown mesh format: expected a .obj, .off or .ply file")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::test_meshes::{bundled, shared};

    #[test]
    fn unknown_extension_is_an_error_naming_the_file() {
        let e = load(Path::new("model.stl")).unwrap_err().to_string();
        assert!(e.starts_with("model.stl: unknown mesh format"), "{e}");
    }

    #[test]
    fn missing_file_is_an_io_error_naming_the_file() {
        let e = load(Path::new("/nonexistent/bunny.OBJ")).unwrap_err().to_string();
        assert!(e.starts_with("/nonexistent/bunny.OBJ:"), "{e}");
    }

    #[test]
    fn extension_is_case_insensitive() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("tri.OFF");
        std::fs::write(&path, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").expect("write");
        assert_eq!(load(&path).expect("loads").face_count(), 1);
    }

    #[test]
    fn the_bundled_bunny_loads_closed_with_its_documented_topology() {
        let bunny = load(&bundled("bunny-1k8.obj")).expect("bunny");
        assert!(crate::mesh::manifold::is_manifold(bunny.triangles()));
        let bunny = topology::summary(&bunny);
        assert_eq!((bunny.vertices, bunny.faces, bunny.boundary_edges), (1839, 3674, 0));
        assert_eq!((bunny.components, bunny.euler_characteristic), (1, 2));
    }

    #[test]
    fn shared_meshes_load_as_manifolds_with_their_documented_topology() {
        let test = "shared_meshes_load_as_manifolds_with_their_documented_topology";
        let (Some(cow), Some(dragon)) = (shared(test, "cow.off"), shared(test, "dragon-10k.off")) else {
            return;
        };
        assert!(crate::mesh::manifold::is_manifold(load(&cow).expect("cow").triangles()));
        let dragon = load(&dragon).expect("dragon");
        assert!(crate::mesh::manifold::is_manifold(dragon.triangles()));
        assert_eq!(topology::summary(&dragon).boundary_edges, 6);
    }

    /// Deterministic pseudo-random bytes (xorshift64).
    fn noise(seed: u64, len: usize) -> Vec<u8> {
        let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        (0..len)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                (x >> 24) as u8
            })
            .collect()
    }

    #[test]
    fn garbage_files_are_one_error_naming_the_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        for ext in ["obj", "off", "ply"] {
            let path = dir.path().join(format!("garbage.{ext}"));
            std::fs::write(&path, noise(7, 4000)).expect("write");
            let e = load(&path).unwrap_err().to_string();
            assert!(e.starts_with(&path.display().to_string()), "{e}");
            assert_eq!(e.lines().count(), 1, "{e}");
        }
    }

    #[test]
    fn nan_and_out_of_range_fail_in_every_format_naming_the_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let cases = [
            ("nan.obj", "v 0 0 0\nv NaN 0 0\nv 0 1 0\nf 1 2 3\n", "non-finite"),
            ("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "refers to vertex 8"),
            (
                "nan.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                 end_header\n0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n",
                "non-finite",
            ),
            (
                "range.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                 end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n",
                "refers to vertex -1",
            ),
        ];
        for (name, text, expected) in cases {
            let path = dir.path().join(name);
            std::fs::write(&path, text).expect("write");
            let e = load(&path).unwrap_err().to_string();
            assert!(e.starts_with(&path.display().to_string()) && e.contains(expected), "{e}");
            assert_eq!(e.lines().count(), 1, "{e}");
        }
    }
}
