//! Files of work kept between runs, in a directory the caller names: each file holds one
//! result under a 64-bit key, a hash of exactly the inputs that result depends on, so that
//! a later run with the same inputs reads it instead of computing it again.
//!
//! A file is the kind's 8-byte magic, its format version, the key, the payload's length, the
//! payload and an FNV-1a checksum of the payload, all little-endian. A file that is damaged,
//! truncated or of other inputs is never an error: [`Lookup::Unusable`] says why, and the
//! caller computes the result again and overwrites it.

use crate::fsutil::{check_target, store_file};
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// One kind of result a cache directory holds: how its files are named and marked.
#[derive(Clone, Copy, Debug)]
pub struct Kind {
    /// The first bytes of its files.
    pub magic: &'static [u8; 8],
    /// Raised whenever the layout or what is computed changes: it is part of every key,
    /// so the files of an older build are simply not found.
    pub version: u32,
    /// The start of its file names (`NAME-KEY.bin`).
    pub name: &'static str,
}

/// What a cache directory held for a key.
#[derive(Debug)]
pub enum Lookup {
    /// No file for the key.
    Missing,
    /// The payload of a whole, undamaged file for the key.
    Found(Vec<u8>),
    /// A file that cannot be used, and why.
    Unusable(String),
}

/// Where a cached result came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// Computed in this run (no cache, or the cache had no file for these inputs).
    Computed,
    /// Read from the cache.
    Cached,
    /// The cache's file for these inputs was unusable (damaged, truncated, foreign):
    /// computed again and the file overwritten.
    Recomputed,
}

impl std::fmt::Display for Source {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(match self {
            Source::Computed => "computed",
            Source::Cached => "read from the cache",
            Source::Recomputed => "recomputed (the cached file was unusable)",
        })
    }
}

/// A directory of cached results, checked writable when opened.
#[derive(Clone, Debug)]
pub struct CacheDir {
    dir: PathBuf,
}

impl CacheDir {
    /// Opens `dir`, creating it if missing. Fails (before any long work) when it cannot be
    /// created or written in.
    pub fn open(dir: &Path) -> Result<Self> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        check_target(&dir.join("probe"), true)?;
        Ok(CacheDir { dir: dir.to_path_buf() })
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The file that holds (or will hold) the result of `kind` under `key`.
    pub fn path(&self, kind: Kind, key: u64) -> PathBuf {
        self.dir.join(format!("{}-{key:016x}.bin", kind.name))
    }

    /// The payload stored for `key`, if a whole file holds it.
    pub fn read(&self, kind: Kind, key: u64) -> Lookup {
        match read_regular(&self.path(kind, key)) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Lookup::Missing,
            Err(e) => Lookup::Unusable(e.to_string()),
            // The payload is most of the file (tens of MB for a level's templates): cut the
            // file's own buffer down to it rather than copying it.
            Ok(mut bytes) => match payload_range(kind, &bytes, key) {
                Ok(range) => {
                    bytes.truncate(range.end);
                    bytes.drain(..range.start);
                    Lookup::Found(bytes)
                }
                Err(why) => Lookup::Unusable(why),
            },
        }
    }

    /// The result of `kind` under `key`: decoded from its file if the cache holds a usable
    /// one, else computed and stored. A file that cannot be used is a warning, and is
    /// overwritten.
    pub fn get_or_compute<T>(
        &self,
        (kind, key): (Kind, u64),
        decode: impl FnOnce(&[u8]) -> std::result::Result<T, String>,
        compute: impl FnOnce() -> Result<T>,
        encode: impl FnOnce(&T) -> Vec<u8>,
    ) -> Result<(T, Source)> {
        let unusable = match self.read(kind, key) {
            Lookup::Missing => None,
            Lookup::Found(payload) => match decode(&payload) {
                Ok(value) => return Ok((value, Source::Cached)),
                Err(why) => Some(why),
            },
            Lookup::Unusable(why) => Some(why),
        };
        if let Some(why) = &unusable {
            tracing::warn!(
                "{} cache {}: {why}; computing it again",
                kind.name,
                self.path(kind, key).display()
            );
        }
        let value = compute()?;
        self.write(kind, key, &encode(&value));
        Ok((value, if unusable.is_some() { Source::Recomputed } else { Source::Computed }))
    }

    /// Stores `payload` under `key`, replacing whatever is there (a device or FIFO in its
    /// place too); a failure is a warning (the result is still right).
    pub fn write(&self, kind: Kind, key: u64, payload: &[u8]) {
        if let Err(e) = store_file(&self.path(kind, key), &encode(kind, payload, key)) {
            tracing::warn!("cannot store the {} in the cache: {e}", kind.name);
        }
    }
}

/// The bytes of the regular file at `path`. Anything else in its place (a device such as
/// /dev/zero, which never ends, a FIFO, which blocks until written, a directory) is an error,
/// found before it is opened and checked again once open.
fn read_regular(path: &Path) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let not_a_file = || std::io::Error::other("not a regular file (a device, FIFO or directory)");
    if !std::fs::metadata(path)?.is_file() {
        return Err(not_a_file());
    }
    let mut file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(not_a_file());
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// The file bytes of `payload` under `key`.
pub(crate) fn encode(kind: Kind, payload: &[u8], key: u64) -> Vec<u8> {
    let mut out = Vec::with_capacity(payload.len() + 36);
    out.extend(kind.magic);
    out.extend(kind.version.to_le_bytes());
    out.extend(key.to_le_bytes());
    out.extend((payload.len() as u64).to_le_bytes());
    out.extend(payload);
    out.extend(Fnv1a::of(payload).to_le_bytes());
    out
}

/// The payload in the file `bytes`, if it is a whole, undamaged file of `kind` for `key`.
#[cfg(test)]
pub(crate) fn decode(kind: Kind, bytes: &[u8], key: u64) -> std::result::Result<&[u8], String> {
    payload_range(kind, bytes, key).map(|range| &bytes[range])
}

/// Where [`decode`]'s payload lies in `bytes`.
fn payload_range(kind: Kind, bytes: &[u8], key: u64) -> std::result::Result<std::ops::Range<usize>, String> {
    let header = kind.magic.len() + 4 + 8 + 8;
    if bytes.len() < header + 8 || &bytes[..kind.magic.len()] != kind.magic {
        return Err(format!("not a {} cache file", kind.name));
    }
    let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"));
    let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    if version != kind.version {
        return Err(format!("format version {version}, not {}", kind.version));
    }
    if word(12) != key {
        return Err(format!("holds the {} of other inputs (key {:016x})", kind.name, word(12)));
    }
    let payload = &bytes[header..bytes.len() - 8];
    if word(20) != payload.len() as u64 {
        return Err(format!("{} bytes of payload where the header says {}", payload.len(), word(20)));
    }
    if word(bytes.len() - 8) != Fnv1a::of(payload) {
        return Err("the checksum does not match (the file is damaged)".into());
    }
    Ok(header..bytes.len() - 8)
}

/// The 64-bit FNV-1a hash: stable across builds and platforms (std's hasher promises
/// neither), which a key that names files must be.
pub struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    /// The hash of nothing yet, marked with `kind` (its magic and version), so that keys of
    /// different kinds and versions never meet.
    pub fn of_kind(kind: Kind) -> Self {
        let mut h = Fnv1a::default();
        h.write(kind.magic);
        h.write(&kind.version.to_le_bytes());
        h
    }

    /// Adds `bytes`.
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// Adds each value's little-endian bytes.
    pub fn write_f32s(&mut self, values: impl IntoIterator<Item = f32>) {
        values.into_iter().for_each(|x| self.write(&x.to_le_bytes()));
    }

    /// Adds each value's little-endian bytes.
    pub fn write_u32s(&mut self, values: impl IntoIterator<Item = u32>) {
        values.into_iter().for_each(|x| self.write(&x.to_le_bytes()));
    }

    /// The hash so far.
    pub fn finish(&self) -> u64 {
        self.0
    }

    /// The hash of `bytes` alone.
    pub fn of(bytes: &[u8]) -> u64 {
        let mut h = Fnv1a::default();
        h.write(bytes);
        h.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KIND: Kind = Kind { magic: b"BTFTESTS", version: 3, name: "test" };

    /// One flipped byte anywhere in a file, or a file of another key, is refused.
    #[test]
    fn a_damaged_or_foreign_file_is_refused() {
        let payload: Vec<u8> = (0..200u8).collect();
        let bytes = encode(KIND, &payload, 42);
        assert_eq!(decode(KIND, &bytes, 42).unwrap(), &payload[..]);
        assert!(decode(KIND, &bytes, 43).is_err());
        for at in 0..bytes.len() {
            let mut damaged = bytes.clone();
            damaged[at] ^= 0x10;
            assert!(decode(KIND, &damaged, 42).is_err(), "byte {at} flipped");
        }
        assert!(decode(KIND, &bytes[..bytes.len() - 1], 42).is_err());
    }

    /// A device or FIFO in a file's place is neither read (/dev/zero never ends, a FIFO
    /// blocks) nor written into: it is unusable, and the result computed again replaces it.
    #[test]
    fn special_files_in_the_cache_are_replaced_never_read() {
        let dir = tempfile::tempdir().unwrap();
        let cache = CacheDir::open(dir.path()).unwrap();
        std::os::unix::fs::symlink("/dev/zero", cache.path(KIND, 1)).unwrap();
        let made = std::process::Command::new("mkfifo").arg(cache.path(KIND, 2)).status().unwrap();
        assert!(made.success());
        for key in [1, 2] {
            assert!(matches!(cache.read(KIND, key), Lookup::Unusable(_)), "key {key}");
            let decode = |p: &[u8]| Ok(p.to_vec());
            let (value, source) =
                cache.get_or_compute((KIND, key), decode, || Ok(vec![7u8]), |v| v.clone()).unwrap();
            assert_eq!((value, source), (vec![7], Source::Recomputed));
            assert!(std::fs::symlink_metadata(cache.path(KIND, key)).unwrap().is_file());
            assert!(matches!(cache.read(KIND, key), Lookup::Found(p) if p == [7]));
        }
    }

    #[test]
    fn what_is_written_is_read_back_and_an_unwritable_directory_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let cache = CacheDir::open(&dir.path().join("new/cache")).unwrap();
        assert!(matches!(cache.read(KIND, 7), Lookup::Missing));
        cache.write(KIND, 7, b"payload");
        assert!(matches!(cache.read(KIND, 7), Lookup::Found(p) if p == b"payload"));
        std::fs::write(cache.path(KIND, 7), b"BTFTESTS").unwrap();
        assert!(matches!(cache.read(KIND, 7), Lookup::Unusable(_)));
        let file = dir.path().join("a-file");
        std::fs::write(&file, b"x").unwrap();
        assert!(CacheDir::open(&file.join("cache")).is_err());
        assert!(CacheDir::open(&file).is_err());
    }
}
