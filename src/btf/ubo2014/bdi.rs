//! Bidirectional image files (BDI, btflib's `read_ubo_bdi`): the raw ABRDF of every texel,
//! half floats ordered channel-fastest, then light, then view; texels x-fastest in chunks
//! of whole scan lines, each chunk after a u32 byte count. Sparse files store only the
//! texels their mask marks. Bzip2-compressed chunks are not read yet.

use super::bytes::{Bytes, Cursor};
use crate::btf::Crop;
use crate::{Error, Result};
use half::f16;
use std::path::Path;

/// Where a BDI's texels lie.
#[derive(Clone, Debug, PartialEq)]
pub struct BdiBody {
    /// 0: every texel stored; 2: only the texels the mask marks.
    pub compression: u8,
    pub scan_lines_per_chunk: u32,
    /// Per texel `x + width·y`: its index in storage order, or `None` (not stored: black).
    storage: Vec<Option<u32>>,
    /// File offset of each chunk's data.
    chunk_offsets: Vec<u64>,
    abrdfs_per_chunk: u64,
    /// Values per texel: channels × images.
    abrdf_values: usize,
}

/// The part between the image size and the rotation block: scan lines per chunk, the
/// compression byte and the texel mask.
pub struct BdiHead {
    scan_lines: u32,
    compression: u8,
    storage: Vec<Option<u32>>,
}

/// Reads the scan-line count, the compression byte and the mask of a `width × height` BDI.
pub fn read_head(c: &mut Cursor, width: usize, height: usize) -> Result<BdiHead> {
    c.section("BDI chunk layout");
    let scan_lines = c.u32("the scan lines per chunk")?;
    if scan_lines == 0 {
        return Err(c.error("0 scan lines per chunk"));
    }
    let compression = c.u8("the compression type")?;
    match compression {
        0 | 2 => {}
        1 => return Err(c.error("not supported yet: BDI with bzip2-compressed chunks (compression 1)")),
        other => return Err(c.error(format!("unknown compression type {other} (0, 1 or 2)"))),
    }
    c.section("BDI mask");
    let texels = width as u64 * height as u64;
    if texels > u32::MAX as u64 {
        return Err(c.error(format!("{width}x{height} texels are more than a BDI can index")));
    }
    let mask = c.take(c.need(texels, 1, "the texel mask")?, "the texel mask")?;
    // The mask is stored x-major (btflib reads it as a width × height matrix).
    let mut storage = vec![None; texels as usize];
    let mut next = 0u32;
    for y in 0..height {
        for x in 0..width {
            let stored = compression == 0 || mask[x * height + y] != 0;
            if stored {
                storage[x + width * y] = Some(next);
                next += 1;
            }
        }
    }
    Ok(BdiHead { scan_lines, compression, storage })
}

/// Walks the chunks after the rotation block: each must declare exactly the bytes its
/// texels take.
pub fn read_chunks(c: &mut Cursor, head: BdiHead, width: usize, abrdf_values: usize) -> Result<BdiBody> {
    c.section("BDI chunks");
    let stored = head.storage.iter().filter(|s| s.is_some()).count() as u64;
    let abrdfs_per_chunk = width as u64 * head.scan_lines as u64;
    let abrdf_bytes = abrdf_values as u64 * 2;
    let chunks = stored.div_ceil(abrdfs_per_chunk);
    // Each chunk takes at least its 4-byte count.
    c.need(chunks, 4, "the chunk headers")?;
    let mut chunk_offsets = Vec::with_capacity(chunks as usize);
    for k in 0..chunks {
        let texels = abrdfs_per_chunk.min(stored - k * abrdfs_per_chunk);
        let declared = c.u32("a chunk size")? as u64;
        let expected = texels * abrdf_bytes;
        if declared != expected {
            return Err(c.error(format!(
                "chunk {k} declares {declared} bytes but its {texels} texels take {expected}"
            )));
        }
        chunk_offsets.push(c.pos());
        c.skip(declared, &format!("chunk {k}"))?;
    }
    Ok(BdiBody {
        compression: head.compression,
        scan_lines_per_chunk: head.scan_lines,
        storage: head.storage,
        chunk_offsets,
        abrdfs_per_chunk,
        abrdf_values,
    })
}

impl BdiBody {
    /// File offset of texel `p`'s ABRDF, or `None` for a texel the file does not store.
    fn abrdf_offset(&self, p: usize) -> Option<u64> {
        let s = self.storage[p]? as u64;
        let chunk = (s / self.abrdfs_per_chunk) as usize;
        Some(self.chunk_offsets[chunk] + (s % self.abrdfs_per_chunk) * self.abrdf_values as u64 * 2)
    }

    /// Calls `texel(k, abrdf)` with the raw values of every crop texel `k` (rows top to
    /// bottom); unstored texels are all zeros.
    pub fn for_each_texel(
        &self,
        bytes: &Bytes,
        path: &Path,
        width: usize,
        crop: Crop,
        mut texel: impl FnMut(usize, &[f32]) -> Result<()>,
    ) -> Result<()> {
        let mut raw = vec![0u8; self.abrdf_values * 2];
        let mut values = vec![0f32; self.abrdf_values];
        for (k, p) in crop_texels(width, crop).enumerate() {
            match self.abrdf_offset(p) {
                Some(offset) => {
                    bytes.read_at(path, offset, &mut raw)?;
                    for (v, b) in values.iter_mut().zip(raw.chunks_exact(2)) {
                        *v = f16::from_le_bytes([b[0], b[1]]).to_f32();
                    }
                    if values.iter().any(|v| !v.is_finite()) {
                        return Err(non_finite(path, p, width));
                    }
                }
                None => values.fill(0.0),
            }
            texel(k, &values)?;
        }
        Ok(())
    }

    /// The raw values of one image (channels interleaved) at every crop texel.
    pub fn image(&self, bytes: &Bytes, path: &Path, width: usize, crop: Crop, i: usize) -> Result<Vec<f32>> {
        let channels = 3;
        let mut out = Vec::with_capacity(crop.width as usize * crop.height as usize * channels);
        let mut raw = [0u8; 6];
        for p in crop_texels(width, crop) {
            match self.abrdf_offset(p) {
                Some(offset) => {
                    bytes.read_at(path, offset + (i * channels * 2) as u64, &mut raw)?;
                    for b in raw.chunks_exact(2) {
                        let v = f16::from_le_bytes([b[0], b[1]]).to_f32();
                        if !v.is_finite() {
                            return Err(non_finite(path, p, width));
                        }
                        out.push(v);
                    }
                }
                None => out.extend([0.0; 3]),
            }
        }
        Ok(out)
    }
}

fn non_finite(path: &Path, p: usize, width: usize) -> Error {
    Error::format(
        path,
        format!("BDI chunks: texel ({}, {}) holds a value that is not a finite number", p % width, p / width),
    )
}

/// Texel indices `x + width·y` of a crop, rows top to bottom.
fn crop_texels(width: usize, crop: Crop) -> impl Iterator<Item = usize> {
    let (x0, y0) = (crop.x as usize, crop.y as usize);
    (y0..y0 + crop.height as usize)
        .flat_map(move |y| (x0..x0 + crop.width as usize).map(move |x| x + width * y))
}
