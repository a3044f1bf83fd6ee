//! NumPy `.npy` arrays (format version 1.0, little-endian, C order): every array that
//! `analyze` stores opens with `numpy.load`, and later stages read them back with [`read`].

use crate::fsutil::write_with_temp;
use crate::{Error, Result};
use half::f16;
use std::io::Write;
use std::path::Path;

/// Element types that btfsynth stores.
pub trait Element: Copy + Default {
    /// NumPy's dtype descriptor, e.g. `<f4`.
    const DESCR: &'static str;
    /// Appends the element's little-endian bytes to `out`.
    fn put(self, out: &mut Vec<u8>);
    /// The element from its little-endian bytes (exactly `size_of::<Self>()` of them).
    fn get(bytes: &[u8]) -> Self;
    /// False for NaN and ±∞ (never for integers): no array btfsynth stores holds them, so
    /// a file that does is damaged.
    fn is_finite(self) -> bool {
        true
    }
}

macro_rules! element {
    ($t:ty, $descr:literal) => {
        element!($t, $descr, |_v: $t| true);
    };
    ($t:ty, $descr:literal, $finite:expr) => {
        impl Element for $t {
            const DESCR: &'static str = $descr;
            fn is_finite(self) -> bool {
                ($finite)(self)
            }
            fn put(self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes());
            }
            fn get(bytes: &[u8]) -> Self {
                let mut a = [0u8; std::mem::size_of::<$t>()];
                a.copy_from_slice(bytes);
                <$t>::from_le_bytes(a)
            }
        }
    };
}

element!(u16, "<u2");
element!(u32, "<u4");
element!(f32, "<f4", f32::is_finite);
element!(f16, "<f2", f16::is_finite);

/// An n-dimensional array read from a `.npy` file.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray<T> {
    /// Length of each axis, outermost first (C order).
    pub shape: Vec<usize>,
    /// The values in C order (last axis fastest), as many as the product of `shape`.
    pub data: Vec<T>,
}

/// Encodes `data` with `shape` as `.npy` bytes.
pub fn encode<T: Element>(shape: &[usize], data: &[T]) -> Result<Vec<u8>> {
    let mut out = header::<T>(shape, data.len())?;
    out.reserve(std::mem::size_of_val(data));
    for &v in data {
        v.put(&mut out);
    }
    Ok(out)
}

/// The `.npy` header of an array of `T` with `shape`, which `len` values must fill.
fn header<T: Element>(shape: &[usize], len: usize) -> Result<Vec<u8>> {
    if shape.iter().product::<usize>() != len {
        return Err(Error::invalid(format!("{len} values do not fill an array of shape {shape:?}")));
    }
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let tuple = if dims.len() == 1 { format!("({},)", dims[0]) } else { format!("({})", dims.join(", ")) };
    let mut header = format!("{{'descr': '{}', 'fortran_order': False, 'shape': {tuple}, }}", T::DESCR);
    // Magic (6) + version (2) + length (2) + header + newline, padded to 64 bytes.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    Ok(out)
}

/// Values encoded per write: a stack's images are hundreds of MB, never copied whole.
const WRITE_CHUNK: usize = 1 << 16;

/// Writes an array atomically.
pub fn write<T: Element>(path: &Path, shape: &[usize], data: &[T]) -> Result<()> {
    let header = header::<T>(shape, data.len())?;
    write_with_temp(path, |tmp| {
        let mut f = std::fs::File::create(tmp).map_err(|e| Error::io(path, e))?;
        f.write_all(&header).map_err(|e| Error::io(path, e))?;
        let mut bytes = Vec::with_capacity(WRITE_CHUNK * std::mem::size_of::<T>());
        for chunk in data.chunks(WRITE_CHUNK) {
            bytes.clear();
            chunk.iter().for_each(|&v| v.put(&mut bytes));
            f.write_all(&bytes).map_err(|e| Error::io(path, e))?;
        }
        Ok(())
    })
}

/// Reads an array whose dtype must be `T`'s.
pub fn read<T: Element>(path: &Path) -> Result<NpyArray<T>> {
    let bytes = crate::fsutil::read_input(path)?;
    decode(&bytes).map_err(|m| Error::format(path, m))
}

/// Parses `.npy` bytes; the message says what is wrong.
pub fn decode<T: Element>(bytes: &[u8]) -> Result<NpyArray<T>, String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("not a .npy file".into());
    }
    let (header_len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => {
            (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12)
        }
        v => return Err(format!("unsupported .npy version {v}")),
    };
    let header = bytes
        .get(start..start + header_len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or("truncated .npy header")?;
    let descr = quoted_value(header, "descr").ok_or("no dtype in the .npy header")?;
    if descr != T::DESCR {
        return Err(format!("dtype {descr}, expected {}", T::DESCR));
    }
    if header.contains("'fortran_order': True") {
        return Err("Fortran-ordered arrays are not supported".into());
    }
    let shape = parse_shape(header).ok_or("no shape in the .npy header")?;
    let size = std::mem::size_of::<T>();
    let body = &bytes[start + header_len..];
    // Checked: a damaged shape must not wrap around to the body's length.
    let expected = shape.iter().try_fold(size, |n, &d| n.checked_mul(d));
    if expected != Some(body.len()) {
        let expected = expected.map_or("more than fits in memory".to_string(), |n| n.to_string());
        return Err(format!("{} data bytes for shape {shape:?}, expected {expected}", body.len()));
    }
    let data: Vec<T> = body.chunks_exact(size).map(T::get).collect();
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        let bad = data.iter().filter(|v| !v.is_finite()).count();
        return Err(format!("value {i} is NaN or infinite ({bad} of {} values are)", data.len()));
    }
    Ok(NpyArray { shape, data })
}

fn quoted_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let rest = &header[header.find(&format!("'{key}'"))? + key.len() + 2..];
    let rest = &rest[rest.find('\'')? + 1..];
    Some(&rest[..rest.find('\'')?])
}

fn parse_shape(header: &str) -> Option<Vec<usize>> {
    let rest = &header[header.find("'shape'")?..];
    let rest = &rest[rest.find('(')? + 1..];
    let inner = &rest[..rest.find(')')?];
    inner.split(',').map(str::trim).filter(|s| !s.is_empty()).map(|s| s.parse().ok()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_pads_the_header() {
        let data: Vec<f32> = (0..24).map(|v| v as f32 * 0.5).collect();
        let bytes = encode(&[2, 3, 4], &data).unwrap();
        let header_end = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!(header_end % 64, 0);
        assert_eq!(bytes[header_end - 1], b'\n');
        let back: NpyArray<f32> = decode(&bytes).unwrap();
        assert_eq!(back, NpyArray { shape: vec![2, 3, 4], data });
        let one: NpyArray<u16> = decode(&encode(&[3], &[1u16, 2, 3]).unwrap()).unwrap();
        assert_eq!(one.shape, vec![3]);
    }

    #[test]
    fn rejects_wrong_dtype_and_truncation() {
        let bytes = encode(&[2], &[1u32, 2]).unwrap();
        assert!(decode::<f32>(&bytes).unwrap_err().contains("dtype"));
        assert!(decode::<u32>(&bytes[..bytes.len() - 1]).is_err());
        assert!(decode::<u32>(b"garbage").is_err());
        assert!(encode(&[3], &[1u32]).is_err());
    }
}
