//! The Polygon File Format (PLY): [`read`] parses ASCII and binary (little- and
//! big-endian) files; [`write`](mod@write) writes binary little-endian files with named per-vertex
//! properties, the form later stages use for their outputs.
//!
//! This module holds the header, which both share.

pub mod read;
pub mod write;

pub use write::{write, PropertyData, VertexProperty};

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    /// Accepts both the old (`uchar`) and the sized (`uint8`) spellings.
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Size in bytes in a binary file.
    pub fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    pub fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

/// One property of an element.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Property {
    Scalar { name: String, ty: Scalar },
    List { name: String, count: Scalar, item: Scalar },
}

impl Property {
    pub fn name(&self) -> &str {
        match self {
            Property::Scalar { name, .. } | Property::List { name, .. } => name,
        }
    }
}

/// One element declaration (`element vertex 8` and its properties).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Element {
    pub name: String,
    pub count: usize,
    pub properties: Vec<Property>,
}

impl Element {
    /// The fewest bytes one instance can take in a binary file (lists may be empty).
    pub fn min_binary_size(&self) -> usize {
        self.properties
            .iter()
            .map(|p| match p {
                Property::Scalar { ty, .. } => ty.size(),
                Property::List { count, .. } => count.size(),
            })
            .sum()
    }
}

/// How the body after the header is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// A parsed header and where the body starts.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Header {
    pub encoding: Encoding,
    pub elements: Vec<Element>,
    pub comments: Vec<String>,
    pub body_offset: usize,
}

/// Parses the header at the start of `bytes`; the message says what is wrong.
pub(crate) fn parse_header(bytes: &[u8]) -> Result<Header, String> {
    let end = find_end_of_header(bytes).ok_or("not a PLY file: no 'end_header' line")?;
    let text = std::str::from_utf8(&bytes[..end]).map_err(|_| "the PLY header is not text")?;
    let mut lines = text.lines().map(str::trim);
    if lines.next() != Some("ply") {
        return Err("not a PLY file: it does not start with 'ply'".into());
    }
    let mut header =
        Header { encoding: Encoding::Ascii, elements: Vec::new(), comments: Vec::new(), body_offset: end };
    let mut format_seen = false;
    for line in lines {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("format") => {
                header.encoding = parse_format(words.next())?;
                format_seen = true;
            }
            Some("comment") => header.comments.push(line["comment".len()..].trim().to_string()),
            Some("obj_info") | Some("end_header") | None => {}
            Some("element") => header.elements.push(parse_element(words)?),
            Some("property") => {
                let property = parse_property(words)?;
                let element = header.elements.last_mut().ok_or("a PLY property precedes every element")?;
                element.properties.push(property);
            }
            Some(other) => return Err(format!("unknown PLY header line '{other}'")),
        }
    }
    if !format_seen {
        return Err("the PLY header has no 'format' line".into());
    }
    Ok(header)
}

/// The byte offset just after the `end_header` line.
fn find_end_of_header(bytes: &[u8]) -> Option<usize> {
    const KEY: &[u8] = b"end_header";
    let start = bytes.windows(KEY.len()).position(|w| w == KEY)?;
    let newline = bytes[start..].iter().position(|&b| b == b'\n')?;
    Some(start + newline + 1)
}

fn parse_format(word: Option<&str>) -> Result<Encoding, String> {
    match word {
        Some("ascii") => Ok(Encoding::Ascii),
        Some("binary_little_endian") => Ok(Encoding::BinaryLittleEndian),
        Some("binary_big_endian") => Ok(Encoding::BinaryBigEndian),
        other => Err(format!("unknown PLY format '{}'", other.unwrap_or(""))),
    }
}

fn parse_element<'a>(mut words: impl Iterator<Item = &'a str>) -> Result<Element, String> {
    let name = words.next().ok_or("a PLY element has no name")?.to_string();
    let count = words
        .next()
        .and_then(|w| w.parse().ok())
        .ok_or_else(|| format!("PLY element '{name}' has no valid count"))?;
    Ok(Element { name, count, properties: Vec::new() })
}

fn parse_property<'a>(mut words: impl Iterator<Item = &'a str>) -> Result<Property, String> {
    let ty = |w: Option<&str>| -> Result<Scalar, String> {
        let w = w.unwrap_or("");
        Scalar::parse(w).ok_or_else(|| format!("unknown PLY property type '{w}'"))
    };
    let first = words.next();
    let property = if first == Some("list") {
        let (count, item) = (ty(words.next())?, ty(words.next())?);
        if !count.is_integer() {
            return Err("a PLY list count must have an integer type".into());
        }
        let name = words.next().ok_or("a PLY list property has no name")?.to_string();
        Property::List { name, count, item }
    } else {
        let ty = ty(first)?;
        let name = words.next().ok_or("a PLY property has no name")?.to_string();
        Property::Scalar { name, ty }
    };
    Ok(property)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_with_lists_comments_and_sized_types() {
        let text = b"ply\r\nformat binary_big_endian 1.0\r\ncomment made by hand\r\n\
            element vertex 3\r\nproperty float32 x\r\nproperty double y\r\nproperty uchar red\r\n\
            element face 1\r\nproperty list uint8 int vertex_indices\r\nend_header\r\nBODY";
        let h = parse_header(text).expect("parses");
        assert_eq!(h.encoding, Encoding::BinaryBigEndian);
        assert_eq!(h.comments, vec!["made by hand"]);
        assert_eq!(h.elements[0].count, 3);
        assert_eq!(h.elements[0].min_binary_size(), 4 + 8 + 1);
        assert_eq!(
            h.elements[1].properties[0],
            Property::List { name: "vertex_indices".into(), count: Scalar::U8, item: Scalar::I32 }
        );
        assert_eq!(&text[h.body_offset..], b"BODY");
    }

    #[test]
    fn malformed_headers_are_rejected() {
        for bad in [
            &b"ply\nelement vertex 3\nend_header\n"[..],
            b"ply\nformat ascii 1.0\nproperty float x\nend_header\n",
            b"ply\nformat ascii 1.0\nelement vertex -3\nend_header\n",
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty half x\nend_header\n",
            b"ply\nformat ascii 1.0\nelement face 1\nproperty list float int v\nend_header\n",
            b"ply\nformat ascii 1.0\nelement vertex 3\n",
            b"obj\nformat ascii 1.0\nend_header\n",
        ] {
            assert!(parse_header(bad).is_err(), "{}", String::from_utf8_lossy(bad));
        }
    }
}
