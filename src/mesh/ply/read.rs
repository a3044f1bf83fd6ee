//! Reading PLY: the `vertex` element's `x`, `y`, `z` (any numeric type) and texture
//! coordinates, and the `face` element's `vertex_indices` (or `vertex_index`) list and
//! `texcoord` list; every other property and element is read by its declared type and
//! discarded.

use super::{parse_header, Element, Encoding, Header, Property, Scalar};
use crate::mesh::Soup;
use crate::{Error, Result};
use std::path::Path;

/// Parses a PLY file's bytes: positions and faces only.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Soup> {
    read_mesh(bytes, path).map(|mesh| mesh.soup)
}

/// A PLY mesh as [`read_mesh`] reads it: the one reading of `vertex` and `face` rows, for
/// [`parse`] and for the reader that keeps texture coordinates.
pub(crate) struct PlyMesh {
    /// Positions and fan-triangulated faces.
    pub soup: Soup,
    /// Per vertex, its texture coordinates if its element has a pair of
    /// [`VERTEX_UV_NAMES`].
    pub vertex_uvs: Vec<[f64; 2]>,
    /// Per face corner, in file order, its `texcoord` pair (faces without the list add none).
    pub corner_uvs: Vec<[f64; 2]>,
    /// Per triangle, its corners' indices among every face corner in file order.
    pub corner_triangles: Vec<[i64; 3]>,
    /// Face corners in the file.
    pub corners: usize,
}

/// Names of per-vertex texture coordinate pairs, in order of preference.
pub(crate) const VERTEX_UV_NAMES: [(&str, &str); 3] =
    [("s", "t"), ("texture_u", "texture_v"), ("texture_s", "texture_t")];

/// Reads a PLY file's `vertex` element's `x`, `y`, `z` (and texture coordinates, see
/// [`PlyMesh`]) and its `face` element's `vertex_indices` (or `vertex_index`) list.
pub(crate) fn read_mesh(bytes: &[u8], path: &Path) -> Result<PlyMesh> {
    let mut mesh = PlyMesh {
        soup: Soup::default(),
        vertex_uvs: Vec::new(),
        corner_uvs: Vec::new(),
        corner_triangles: Vec::new(),
        corners: 0,
    };
    let mut polygon = Vec::new();
    visit_rows(bytes, path, |element, _, row| {
        let find = |name: &str| element.properties.iter().position(|p| p.name() == name);
        let first = |k: usize| row[k].first().copied().unwrap_or(0.0);
        match element.name.as_str() {
            "vertex" => {
                let [Some(x), Some(y), Some(z)] = ["x", "y", "z"].map(|c| {
                    element
                        .properties
                        .iter()
                        .position(|p| matches!(p, Property::Scalar { name, .. } if name == c))
                }) else {
                    return Err("the PLY vertex element lacks scalar x, y or z properties".into());
                };
                mesh.soup.positions.push([first(x), first(y), first(z)]);
                if let Some((s, t)) = VERTEX_UV_NAMES.iter().find_map(|(s, t)| Some((find(s)?, find(t)?))) {
                    mesh.vertex_uvs.push([first(s), first(t)]);
                }
            }
            "face" => {
                let k = element
                    .properties
                    .iter()
                    .position(|p| {
                        matches!(p, Property::List { name, .. } if name == "vertex_indices" || name == "vertex_index")
                    })
                    .ok_or("the PLY face element lacks a vertex_indices list")?;
                polygon.clear();
                polygon.extend(row[k].iter().map(|&v| v as i64));
                Soup::fan_triangulate(&polygon, &mut mesh.soup.triangles);
                if let Some(t) = find("texcoord") {
                    if row[t].len() != 2 * polygon.len() {
                        return Err("its texcoord list does not hold two values per corner".into());
                    }
                    mesh.corner_uvs.extend(row[t].chunks_exact(2).map(|c| [c[0], c[1]]));
                }
                let start = mesh.corners as i64;
                let corners: Vec<i64> = (start..start + polygon.len() as i64).collect();
                Soup::fan_triangulate(&corners, &mut mesh.corner_triangles);
                mesh.corners += polygon.len();
            }
            _ => {}
        }
        Ok(())
    })?;
    Ok(mesh)
}

/// Reads every row of every element and hands it to `visit` (the element, the row's index
/// and one value list per property, scalars as one value).
pub(crate) fn visit_rows(
    bytes: &[u8],
    path: &Path,
    mut visit: impl FnMut(&Element, usize, &[Vec<f64>]) -> Result<(), String>,
) -> Result<()> {
    let header = parse_header(bytes).map_err(|m| Error::format(path, m))?;
    let body = bytes.get(header.body_offset..).unwrap_or_default();
    let mut values = Values::new(body, header.encoding).map_err(|m| Error::format(path, m))?;
    check_sizes(&header, body.len()).map_err(|m| Error::format(path, m))?;
    let mut row = Vec::new();
    // An element without properties takes no bytes, whatever its count claims.
    for element in header.elements.iter().filter(|e| !e.properties.is_empty()) {
        for i in 0..element.count {
            let at = || format!("PLY {} {i} of {}", element.name, element.count);
            read_row(element, &mut values, &mut row)
                .map_err(|m| Error::format(path, format!("{}: {m}", at())))?;
            visit(element, i, &row).map_err(|m| Error::format(path, format!("{}: {m}", at())))?;
        }
    }
    Ok(())
}

/// Rejects counts the body cannot hold before anything is allocated for them.
fn check_sizes(header: &Header, body_len: usize) -> Result<(), String> {
    let needed = header.elements.iter().try_fold(0usize, |sum, e| {
        let per = match header.encoding {
            Encoding::Ascii => e.properties.len().min(1), // at least one token each
            _ => e.min_binary_size(),
        };
        e.count.checked_mul(per).and_then(|n| n.checked_add(sum))
    });
    match needed {
        Some(n) if n <= body_len => Ok(()),
        _ => Err("the PLY header declares more data than the file holds".into()),
    }
}

/// Reads one instance of `element`: one value list per property (scalars as one value).
fn read_row(element: &Element, values: &mut Values, row: &mut Vec<Vec<f64>>) -> Result<(), String> {
    row.resize(element.properties.len(), Vec::new());
    for (p, out) in element.properties.iter().zip(row.iter_mut()) {
        out.clear();
        match p {
            Property::Scalar { ty, .. } => out.push(values.next(*ty)?),
            Property::List { count, item, .. } => {
                let n = values.next(*count)?;
                if !(0.0..=1e6).contains(&n) {
                    return Err(format!("list '{}' has an invalid length {n}", p.name()));
                }
                for _ in 0..n as usize {
                    out.push(values.next(*item)?);
                }
            }
        }
    }
    Ok(())
}

/// The body as a stream of numbers.
enum Values<'a> {
    Ascii(std::str::SplitAsciiWhitespace<'a>),
    Binary { bytes: &'a [u8], big_endian: bool },
}

impl<'a> Values<'a> {
    fn new(body: &'a [u8], encoding: Encoding) -> Result<Self, String> {
        Ok(match encoding {
            Encoding::Ascii => {
                let text = std::str::from_utf8(body).map_err(|_| "the ASCII PLY body is not text")?;
                Values::Ascii(text.split_ascii_whitespace())
            }
            Encoding::BinaryLittleEndian => Values::Binary { bytes: body, big_endian: false },
            Encoding::BinaryBigEndian => Values::Binary { bytes: body, big_endian: true },
        })
    }

    /// The next value, converted to `f64` (exact for every PLY integer type).
    fn next(&mut self, ty: Scalar) -> Result<f64, String> {
        match self {
            Values::Ascii(tokens) => {
                let token = tokens.next().ok_or("the file ends early")?;
                let value = if ty.is_integer() {
                    token.parse::<i64>().map(|v| v as f64).ok()
                } else {
                    token.parse::<f64>().ok()
                };
                value.ok_or_else(|| format!("'{token}' is not a valid {ty:?} value"))
            }
            Values::Binary { bytes, big_endian } => {
                let n = ty.size();
                if bytes.len() < n {
                    return Err("the file ends early".into());
                }
                let (head, tail) = bytes.split_at(n);
                *bytes = tail;
                Ok(decode(ty, head, *big_endian))
            }
        }
    }
}

/// Decodes one binary value of `ty` from exactly `ty.size()` bytes.
fn decode(ty: Scalar, b: &[u8], big_endian: bool) -> f64 {
    let mut buf = [0u8; 8];
    buf[..b.len()].copy_from_slice(b);
    if big_endian {
        buf[..b.len()].reverse();
    }
    match ty {
        Scalar::I8 => f64::from(buf[0] as i8),
        Scalar::U8 => f64::from(buf[0]),
        Scalar::I16 => f64::from(i16::from_le_bytes([buf[0], buf[1]])),
        Scalar::U16 => f64::from(u16::from_le_bytes([buf[0], buf[1]])),
        Scalar::I32 => f64::from(i32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]])),
        Scalar::U32 => f64::from(u32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]])),
        Scalar::F32 => f64::from(f32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]])),
        Scalar::F64 => f64::from_le_bytes(buf),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_bytes(b: &[u8]) -> Result<Soup> {
        parse(b, Path::new("t.ply"))
    }

    const ASCII: &str = "ply\nformat ascii 1.0\ncomment square\nelement vertex 4\n\
        property double x\nproperty double y\nproperty double z\nproperty uchar red\n\
        element face 1\nproperty uchar flags\nproperty list uchar uint vertex_index\n\
        element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n\
        0 0 0 255\n1 0 0 0\n1 1 0 0\n0 1 0 0\n7 4 0 1 2 3\n0 1\n";

    #[test]
    fn ascii_polygon_with_extra_properties_and_elements() {
        let s = parse_bytes(ASCII.as_bytes()).expect("parses");
        assert_eq!(s.positions, vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]]);
        assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }

    /// A binary file: vertices `(x: float, w: short, y: float, z: double)`, a `material`
    /// element between vertices and faces, faces `(list int uint, uchar)`.
    fn binary(big_endian: bool) -> Vec<u8> {
        let order = if big_endian { "big" } else { "little" };
        let mut b = format!(
            "ply\nformat binary_{order}_endian 1.0\nelement vertex 3\nproperty float x\n\
             property short w\nproperty float y\nproperty double z\nelement material 2\n\
             property list uchar float rgb\nelement face 1\n\
             property list int uint vertex_indices\nproperty uchar tag\nend_header\n"
        )
        .into_bytes();
        let put = |bytes: &mut Vec<u8>, le: Vec<u8>| {
            bytes.extend(if big_endian { le.into_iter().rev().collect() } else { le })
        };
        for (x, y, z) in [(0.0f32, 0.0f32, 0.0f64), (1.0, 0.0, 0.5), (0.0, 2.0, -1.0)] {
            put(&mut b, x.to_le_bytes().to_vec());
            put(&mut b, 7i16.to_le_bytes().to_vec());
            put(&mut b, y.to_le_bytes().to_vec());
            put(&mut b, z.to_le_bytes().to_vec());
        }
        for n in [2u8, 0] {
            b.push(n);
            for _ in 0..n {
                put(&mut b, 0.25f32.to_le_bytes().to_vec());
            }
        }
        put(&mut b, 3i32.to_le_bytes().to_vec());
        for i in [2u32, 1, 0] {
            put(&mut b, i.to_le_bytes().to_vec());
        }
        b.push(9);
        b
    }

    #[test]
    fn binary_both_endians_skip_other_properties_and_elements() {
        for big in [false, true] {
            let s = parse_bytes(&binary(big)).expect("parses");
            assert_eq!(s.positions, vec![[0., 0., 0.], [1., 0., 0.5], [0., 2., -1.]], "big={big}");
            assert_eq!(s.triangles, vec![[2, 1, 0]]);
        }
    }

    #[test]
    fn truncated_binary_is_an_error_naming_the_element() {
        let b = binary(false);
        let e = parse_bytes(&b[..b.len() - 3]).unwrap_err().to_string();
        assert!(e.starts_with("t.ply: PLY face 0 of 1: the file ends early"), "{e}");
    }

    #[test]
    fn huge_declared_counts_fail_without_allocating() {
        let text = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000000\n\
            property float x\nproperty float y\nproperty float z\nend_header\n";
        let e = parse_bytes(text.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("more data than the file holds"), "{e}");
    }

    #[test]
    fn an_element_without_properties_takes_no_time_whatever_its_count() {
        let text = ASCII.replace("element edge 1", "element nothing 4000000000000\nelement edge 1");
        assert_eq!(parse_bytes(text.as_bytes()).expect("parses").triangles.len(), 2);
    }

    #[test]
    fn missing_coordinates_or_indices_are_errors() {
        let no_z = ASCII.replace("property double z\n", "");
        assert!(parse_bytes(no_z.as_bytes()).is_err());
        let bad_token = ASCII.replace("1 1 0 0", "1 one 0 0");
        let e = parse_bytes(bad_token.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("PLY vertex 2 of 4"), "{e}");
    }
}
