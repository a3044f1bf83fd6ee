//! Reading a mesh file, with the format picked by the extension (case-insensitive):
//! `.obj` ([`super::obj`]), `.off` ([`super::off`]), `.ply` ([`super::ply`]).

use super::{obj, off, ply, prepare, topology, Mesh, Soup};
use crate::{Error, Result};
use std::path::Path;

/// How a mesh file is turned into a [`Mesh`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadOptions {
    /// Vertices closer than this fraction of the bounding-box diagonal are welded into one
    /// (default `1e-6`: far below any real feature, above the rounding of coordinates
    /// written with six significant digits). `0` welds only identical positions.
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
    tracing::info!("{}: {}", path.display(), topology::summary(&mesh));
    Ok(mesh)
}

/// Parses `path` into a triangle soup without validating it.
pub fn read_soup(path: &Path) -> Result<Soup> {
    let parse = parser_for(path)?;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
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
    use crate::mesh::test_meshes::shared;

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
    fn all_shared_meshes_load_as_manifolds() {
        for name in ["bunny-1k8.obj", "cow.off", "dragon-10k.off"] {
            let m = load(&shared(name)).expect(name);
            assert!(topology::is_manifold(&m), "{name}");
        }
    }

    #[test]
    fn shared_meshes_have_their_documented_topology() {
        let bunny = topology::summary(&load(&shared("bunny-1k8.obj")).expect("bunny"));
        assert_eq!((bunny.vertices, bunny.faces, bunny.boundary_edges), (1839, 3674, 0));
        assert_eq!((bunny.components, bunny.euler_characteristic), (1, 2));
        let dragon = topology::summary(&load(&shared("dragon-10k.off")).expect("dragon"));
        assert_eq!(dragon.boundary_edges, 6);
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

    fn valid_files() -> Vec<(&'static str, Vec<u8>)> {
        let dir = tempfile::tempdir().expect("temp dir");
        let binary = dir.path().join("grid.ply");
        crate::mesh::ply::write(&binary, &crate::mesh::test_meshes::grid(2), &[], &["c"]).expect("writes");
        vec![
            ("obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 2 4 -2\n".to_vec()),
            ("off", b"OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n".to_vec()),
            (
                "ply",
                b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                  property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                  end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
                    .to_vec(),
            ),
            ("ply", std::fs::read(&binary).expect("reads")),
        ]
    }

    /// Parses and prepares `bytes` as a file with extension `ext`; only a panic fails.
    fn survive(ext: &str, bytes: &[u8]) -> Option<Mesh> {
        let path = std::path::PathBuf::from(format!("fuzz.{ext}"));
        let parse = parser_for(&path).expect("known extension");
        let soup = parse(bytes, &path).ok()?;
        prepare::prepare(soup, &path, &LoadOptions::default()).ok()
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
    fn random_and_mutated_bytes_never_panic() {
        for (k, (ext, valid)) in valid_files().into_iter().enumerate() {
            assert!(survive(ext, &valid).is_some(), "the unmutated {ext} file loads");
            for seed in 0..300u64 {
                let _ = survive(ext, &noise(seed + 1000 * k as u64, (seed as usize * 13) % 700));
                let r = noise(seed, 8);
                let mut mutated = valid.clone();
                for j in 0..1 + (r[0] % 4) as usize {
                    let at = usize::from(r[1 + j]) * 7 % mutated.len();
                    mutated[at] = r[5 + j % 3];
                }
                let _ = survive(ext, &mutated);
                let cut = usize::from(r[7]) * 3 % valid.len();
                let _ = survive(ext, &valid[..cut]);
            }
        }
    }

    #[test]
    fn nan_and_out_of_range_fail_in_every_format_naming_the_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let cases = [
            ("nan.obj", "v 0 0 0\nv NaN 0 0\nv 0 1 0\nf 1 2 3\n", "non-finite"),
            ("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "not a valid OBJ"),
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
