//! Where a Bonn file's bytes come from, and a cursor that reads its header fields with the
//! name of the section being read, so that every error says where the file went wrong.
//!
//! Nothing here allocates from a count before checking that the file holds that many
//! bytes: a 20-byte file claiming 2³² views fails on the check, not on the allocation.

use crate::{Error, Result};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// The bytes of one file: read on demand from disk (large files are never read whole), or
/// held in memory (tests, and files small enough to not matter).
pub enum Bytes {
    /// A file on disk; reads seek under the lock.
    File {
        /// The open file, locked for each seek and read.
        file: Mutex<File>,
        /// The file's length in bytes, from its metadata at opening.
        len: u64,
    },
    /// Bytes already in memory.
    Memory(Arc<[u8]>),
}

impl Bytes {
    /// Opens `path` for reading on demand.
    pub fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        Ok(Bytes::File { file: Mutex::new(file), len })
    }

    /// The file's length in bytes.
    pub fn size(&self) -> u64 {
        match self {
            Bytes::File { len, .. } => *len,
            Bytes::Memory(b) => b.len() as u64,
        }
    }

    /// Fills `buf` from `offset`; the caller has checked that the range lies in the file.
    pub fn read_at(&self, path: &Path, offset: u64, buf: &mut [u8]) -> Result<()> {
        match self {
            Bytes::Memory(b) => {
                let range = usize::try_from(offset)
                    .ok()
                    .and_then(|start| Some(start..start.checked_add(buf.len())?))
                    .filter(|r| r.end <= b.len())
                    .ok_or_else(|| Error::format(path, format!("read past the end at offset {offset}")))?;
                buf.copy_from_slice(&b[range]);
                Ok(())
            }
            Bytes::File { file, .. } => {
                // A poisoned lock only means another reader panicked; the file is still valid.
                let mut file = file.lock().unwrap_or_else(|p| p.into_inner());
                file.seek(SeekFrom::Start(offset)).map_err(|e| Error::io(path, e))?;
                file.read_exact(buf).map_err(|e| Error::io(path, e))
            }
        }
    }
}

/// Reads a header front to back, checking every length against the bytes that remain.
pub struct Cursor<'a> {
    bytes: &'a Bytes,
    path: PathBuf,
    pos: u64,
    section: &'static str,
}

impl<'a> Cursor<'a> {
    /// A cursor at `pos`.
    pub fn new(bytes: &'a Bytes, path: &Path, pos: u64) -> Self {
        Cursor { bytes, path: path.to_path_buf(), pos, section: "signature" }
    }

    /// Names the section that the following reads belong to (used in error messages).
    pub fn section(&mut self, name: &'static str) {
        self.section = name;
    }

    /// The current offset.
    pub fn pos(&self) -> u64 {
        self.pos
    }

    /// Bytes left after the current offset.
    pub fn remaining(&self) -> u64 {
        self.bytes.size().saturating_sub(self.pos)
    }

    /// An error about the current section, naming the file.
    pub fn error(&self, message: impl std::fmt::Display) -> Error {
        Error::format(&self.path, format!("{}: {message}", self.section))
    }

    /// Fails unless `count` items of `size` bytes remain.
    pub fn need(&self, count: u64, size: u64, what: &str) -> Result<u64> {
        let bytes = count.checked_mul(size).filter(|&b| b <= self.remaining());
        bytes.ok_or_else(|| {
            self.error(format!(
                "truncated: {what} needs {count} × {size} bytes at offset {} but only {} remain",
                self.pos,
                self.remaining()
            ))
        })
    }

    /// Reads `n` bytes (after checking they exist).
    pub fn take(&mut self, n: u64, what: &str) -> Result<Vec<u8>> {
        self.need(n, 1, what)?;
        let mut buf = vec![0u8; n as usize];
        self.bytes.read_at(&self.path, self.pos, &mut buf)?;
        self.pos += n;
        Ok(buf)
    }

    /// Moves past `n` bytes (after checking they exist).
    pub fn skip(&mut self, n: u64, what: &str) -> Result<()> {
        self.need(n, 1, what)?;
        self.pos += n;
        Ok(())
    }

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        self.need(N as u64, 1, what)?;
        let mut buf = [0u8; N];
        self.bytes.read_at(&self.path, self.pos, &mut buf)?;
        self.pos += N as u64;
        Ok(buf)
    }

    /// One byte; `what` names the field in errors.
    pub fn u8(&mut self, what: &str) -> Result<u8> {
        Ok(self.array::<1>(what)?[0])
    }

    /// A little-endian u32; `what` names the field in errors.
    pub fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }

    /// A little-endian i32; `what` names the field in errors.
    pub fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }

    /// A little-endian f32; `what` names the field in errors.
    pub fn f32(&mut self, what: &str) -> Result<f32> {
        Ok(f32::from_le_bytes(self.array(what)?))
    }

    /// `N` little-endian f32 values.
    pub fn f32s<const N: usize>(&mut self, what: &str) -> Result<[f32; N]> {
        let mut out = [0f32; N];
        for v in &mut out {
            *v = self.f32(what)?;
        }
        Ok(out)
    }

    /// A fixed-size character field, up to its first NUL, as text.
    pub fn text(&mut self, n: u64, what: &str) -> Result<String> {
        let raw = self.take(n, what)?;
        let end = raw.iter().position(|&b| b == 0).unwrap_or(raw.len());
        Ok(String::from_utf8_lossy(&raw[..end]).trim_end().to_string())
    }
}
