//! A directory of marchings kept between runs (a directory the caller names, kept from run to run).
//!
//! The marching of a mesh level depends only on the level's positions, triangles and
//! normals, the texel and the stencil, never on the texture direction. Each is stored in a
//! file named by a 64-bit hash of exactly those inputs (and the format version), so a run
//! with another frame orientation on the same mesh and density finds the marching of every level
//! and only recomputes the start points.
//!
//! Files are [`crate::cache`]'s, their payload [`SurfaceMarching::write_to`]'s bytes. A
//! file that is damaged, truncated or belongs to other inputs is never an error: it is
//! reported with a warning, recomputed and overwritten.

use super::{RoundStencil, SurfaceMarching};
pub use crate::cache::Source as MarchingSource;
use crate::cache::{CacheDir, Fnv1a, Kind};
use crate::mesh::Mesh;
use crate::Result;
use glam::Vec3;
use std::path::{Path, PathBuf};

/// The cache files of marchings. Raise the version whenever the layout or what
/// [`SurfaceMarching::new`] computes changes.
const MARCHING: Kind = Kind { magic: b"BTFMARCH", version: 1, name: "marching" };

/// How a level's marching was obtained: its source and the seconds it took (hashing, reading
/// or marching, and storing).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MarchingOrigin {
    /// Whether the marching was computed, read from the cache or recomputed.
    pub source: MarchingSource,
    /// Seconds spent hashing, reading or marching, and storing.
    pub seconds: f64,
}

/// A directory of cached marchings, checked writable when opened.
#[derive(Clone, Debug)]
pub struct MarchingCache {
    dir: CacheDir,
}

impl MarchingCache {
    /// Opens `dir`, creating it if missing. Fails (before any long work) when it cannot be
    /// created or written in.
    pub fn open(dir: &Path) -> Result<Self> {
        Ok(MarchingCache { dir: CacheDir::open(dir)? })
    }

    /// Marchings kept in `dir`, beside whatever else it holds.
    pub fn in_dir(dir: CacheDir) -> Self {
        MarchingCache { dir }
    }

    /// The key of a marching: a hash of everything [`SurfaceMarching::new`] reads.
    pub fn key(mesh: &Mesh, normals: &[Vec3], texel: f32, stencil: RoundStencil) -> u64 {
        let mut h = Fnv1a::of_kind(MARCHING);
        h.write(&(stencil.circles as u64).to_le_bytes());
        h.write(&texel.to_le_bytes());
        h.write(&(mesh.vertex_count() as u64).to_le_bytes());
        h.write_f32s(mesh.positions().iter().chain(normals).flat_map(|p| p.to_array()));
        h.write(&(mesh.triangles().len() as u64).to_le_bytes());
        h.write_u32s(mesh.triangles().iter().flatten().copied());
        h.finish()
    }

    /// The file that holds (or will hold) the marching of `key`.
    pub fn path(&self, key: u64) -> PathBuf {
        self.dir.path(MARCHING, key)
    }

    /// The marching of these inputs: read from the cache if it holds a valid one, else
    /// marched and stored (a failure to store is a warning: the marching is still right).
    pub fn marching(
        &self,
        mesh: &Mesh,
        normals: &[Vec3],
        texel: f32,
        stencil: RoundStencil,
    ) -> Result<(SurfaceMarching, MarchingSource)> {
        let key = Self::key(mesh, normals, texel, stencil);
        self.dir.get_or_compute(
            (MARCHING, key),
            |payload| {
                SurfaceMarching::read_from(payload).and_then(|m| fits(m, mesh.vertex_count(), texel, stencil))
            },
            || SurfaceMarching::new(mesh, normals, texel, stencil),
            |marching| {
                let mut payload = Vec::new();
                marching.write_to(&mut payload);
                payload
            },
        )
    }
}

/// `marching` if it was made for a mesh of `vertices` vertices with this texel and stencil
/// (guards against a hash collision as much as against a mislabelled file).
fn fits(
    marching: SurfaceMarching,
    vertices: usize,
    texel: f32,
    stencil: RoundStencil,
) -> std::result::Result<SurfaceMarching, String> {
    if marching.vertices() != vertices
        || marching.texel.to_bits() != texel.to_bits()
        || marching.stencil != stencil
    {
        return Err(format!(
            "made for {} vertices, texel {}, {} circles",
            marching.vertices(),
            marching.texel,
            marching.stencil.circles
        ));
    }
    Ok(marching)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::surface::tests::bunny;

    const STENCIL: RoundStencil = RoundStencil { circles: 2 };

    /// A stored marching is found again by the same inputs, is equal to a fresh one, and any
    /// changed input (a normal, the texel, the stencil) names another file.
    #[test]
    fn the_cache_returns_what_it_stored_for_the_same_inputs_only() {
        let dir = tempfile::tempdir().unwrap();
        let cache = MarchingCache::open(&dir.path().join("new/cache")).unwrap();
        let (mesh, frames, texel) = bunny();
        let (first, source) = cache.marching(&mesh, &frames.n, texel, STENCIL).unwrap();
        assert_eq!(source, MarchingSource::Computed);
        let (again, source) = cache.marching(&mesh, &frames.n, texel, STENCIL).unwrap();
        assert_eq!(source, MarchingSource::Cached);
        assert_eq!(again, first);
        let key = MarchingCache::key(&mesh, &frames.n, texel, STENCIL);
        let mut normals = frames.n.clone();
        normals[7] = -normals[7];
        assert_ne!(MarchingCache::key(&mesh, &normals, texel, STENCIL), key);
        assert_ne!(MarchingCache::key(&mesh, &frames.n, texel * 1.0001, STENCIL), key);
        assert_ne!(MarchingCache::key(&mesh, &frames.n, texel, RoundStencil { circles: 3 }), key);
    }

    /// A truncated file (decoding refuses any damage, `crate::cache`'s tests) is
    /// recomputed and overwritten.
    #[test]
    fn a_damaged_file_is_refused_then_recomputed() {
        let (mesh, frames, texel) = bunny();
        let marching = SurfaceMarching::new(&mesh, &frames.n, texel, STENCIL).unwrap();
        let mut payload = Vec::new();
        marching.write_to(&mut payload);
        let bytes = crate::cache::encode(MARCHING, &payload, 42);
        let dir = tempfile::tempdir().unwrap();
        let cache = MarchingCache::open(dir.path()).unwrap();
        let path = cache.path(MarchingCache::key(&mesh, &frames.n, texel, STENCIL));
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        let (got, source) = cache.marching(&mesh, &frames.n, texel, STENCIL).unwrap();
        assert_eq!((source, &got), (MarchingSource::Recomputed, &marching));
        assert_eq!(cache.marching(&mesh, &frames.n, texel, STENCIL).unwrap().1, MarchingSource::Cached);
    }

    #[test]
    fn an_unwritable_directory_is_refused_when_opened() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a-file");
        std::fs::write(&file, b"x").unwrap();
        assert!(MarchingCache::open(&file.join("cache")).is_err());
        assert!(MarchingCache::open(&file).is_err());
    }
}
