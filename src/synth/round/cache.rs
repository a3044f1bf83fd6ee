//! A directory of marchings kept between runs (a directory the caller names, kept from run to run).
//!
//! The marching of a mesh level depends only on the level's positions, triangles and
//! normals, the texel and the stencil, never on the texture direction. Each is stored in a
//! file named by a 64-bit hash of exactly those inputs (and the format version), so a run
//! with another frame orientation on the same mesh and density finds the marching of every level
//! and only recomputes the start points.
//!
//! A file is `MAGIC`, the format version, the key, the payload's length, the payload
//! ([`SurfaceMarching::write_to`]) and an FNV-1a checksum of the payload, all little-endian.
//! A file that is damaged, truncated or belongs to other inputs is never an error: it is
//! reported with a warning, recomputed and overwritten.

use super::{RoundStencil, SurfaceMarching};
use crate::fsutil::{check_target, write_file_atomic};
use crate::mesh::Mesh;
use crate::{Error, Result};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// The first bytes of every cache file.
const MAGIC: &[u8; 8] = b"BTFMARCH";

/// Raise whenever the file layout or what [`SurfaceMarching::new`] computes changes: the
/// version is part of the key, so files of an older build are simply not found.
const FORMAT_VERSION: u32 = 1;

/// Where a level's marching came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum MarchingSource {
    /// Marched in this run (no cache, or the cache had no file for these inputs).
    Computed,
    /// Read from the cache.
    Cached,
    /// The cache's file for these inputs was unusable (damaged, truncated, foreign): marched
    /// again and the file overwritten.
    Recomputed,
}

impl std::fmt::Display for MarchingSource {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(match self {
            MarchingSource::Computed => "computed",
            MarchingSource::Cached => "read from the cache",
            MarchingSource::Recomputed => "recomputed (the cached file was unusable)",
        })
    }
}

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
    dir: PathBuf,
}

impl MarchingCache {
    /// Opens `dir`, creating it if missing. Fails (before any long work) when it cannot be
    /// created or written in.
    pub fn open(dir: &Path) -> Result<Self> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        check_target(&dir.join("marching"), true)?;
        Ok(MarchingCache { dir: dir.to_path_buf() })
    }

    /// The key of a marching: a hash of everything [`SurfaceMarching::new`] reads.
    pub fn key(mesh: &Mesh, normals: &[Vec3], texel: f32, stencil: RoundStencil) -> u64 {
        let mut h = Fnv1a::new();
        h.write(MAGIC);
        h.write(&FORMAT_VERSION.to_le_bytes());
        h.write(&(stencil.circles as u64).to_le_bytes());
        h.write(&texel.to_le_bytes());
        h.write(&(mesh.vertex_count() as u64).to_le_bytes());
        for p in mesh.positions().iter().chain(normals) {
            p.to_array().iter().for_each(|x| h.write(&x.to_le_bytes()));
        }
        h.write(&(mesh.triangles().len() as u64).to_le_bytes());
        for t in mesh.triangles() {
            t.iter().for_each(|i| h.write(&i.to_le_bytes()));
        }
        h.finish()
    }

    /// The file that holds (or will hold) the marching of `key`.
    pub fn path(&self, key: u64) -> PathBuf {
        self.dir.join(format!("marching-{key:016x}.bin"))
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
        let path = self.path(key);
        let source = match std::fs::read(&path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => MarchingSource::Computed,
            read => {
                let decoded = read
                    .map_err(|e| e.to_string())
                    .and_then(|bytes| decode(&bytes, key))
                    .and_then(|m| fits(m, mesh.vertex_count(), texel, stencil));
                match decoded {
                    Ok(marching) => return Ok((marching, MarchingSource::Cached)),
                    Err(why) => {
                        tracing::warn!("marching cache {}: {why}; marching again", path.display());
                        MarchingSource::Recomputed
                    }
                }
            }
        };
        let marching = SurfaceMarching::new(mesh, normals, texel, stencil)?;
        if let Err(e) = write_file_atomic(&path, &encode(&marching, key)) {
            tracing::warn!("cannot store the marching in the cache: {e}");
        }
        Ok((marching, source))
    }
}

/// The file bytes of `marching` under `key`.
fn encode(marching: &SurfaceMarching, key: u64) -> Vec<u8> {
    let mut payload = Vec::new();
    marching.write_to(&mut payload);
    let mut out = Vec::with_capacity(payload.len() + 36);
    out.extend(MAGIC);
    out.extend(FORMAT_VERSION.to_le_bytes());
    out.extend(key.to_le_bytes());
    out.extend((payload.len() as u64).to_le_bytes());
    out.extend(&payload);
    out.extend(Fnv1a::of(&payload).to_le_bytes());
    out
}

/// The marching in the file `bytes`, if it is a whole, undamaged file for `key`.
fn decode(bytes: &[u8], key: u64) -> std::result::Result<SurfaceMarching, String> {
    let header = MAGIC.len() + 4 + 8 + 8;
    if bytes.len() < header + 8 || &bytes[..MAGIC.len()] != MAGIC {
        return Err("not a marching cache file".into());
    }
    let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"));
    let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    if version != FORMAT_VERSION {
        return Err(format!("format version {version}, not {FORMAT_VERSION}"));
    }
    if word(12) != key {
        return Err(format!("holds the marching of other inputs (key {:016x})", word(12)));
    }
    let payload = &bytes[header..bytes.len() - 8];
    if word(20) != payload.len() as u64 {
        return Err(format!("{} bytes of marching where the header says {}", payload.len(), word(20)));
    }
    if word(bytes.len() - 8) != Fnv1a::of(payload) {
        return Err("the checksum does not match (the file is damaged)".into());
    }
    SurfaceMarching::read_from(payload)
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

/// The 64-bit FNV-1a hash: stable across builds and platforms (std's hasher promises
/// neither), which a key that names files must be.
struct Fnv1a(u64);

impl Fnv1a {
    fn new() -> Self {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    fn finish(&self) -> u64 {
        self.0
    }

    fn of(bytes: &[u8]) -> u64 {
        let mut h = Fnv1a::new();
        h.write(bytes);
        h.finish()
    }
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

    /// One flipped byte anywhere in a file, or a file of another key, is refused by decoding
    /// and, through the cache, recomputed and overwritten.
    #[test]
    fn a_damaged_file_is_refused_then_recomputed() {
        let (mesh, frames, texel) = bunny();
        let marching = SurfaceMarching::new(&mesh, &frames.n, texel, STENCIL).unwrap();
        let bytes = encode(&marching, 42);
        assert_eq!(decode(&bytes, 42).unwrap(), marching);
        assert!(decode(&bytes, 43).is_err());
        for at in (0..bytes.len()).step_by(bytes.len() / 61) {
            let mut damaged = bytes.clone();
            damaged[at] ^= 0x10;
            assert!(decode(&damaged, 42).is_err(), "byte {at} flipped");
        }
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
