//! Writing a mesh as binary little-endian PLY with named per-vertex properties and header
//! comments, atomically (a temporary sibling renamed into place).

use crate::fsutil::write_with_temp;
use crate::mesh::Mesh;
use crate::{Error, Result};
use std::io::Write;
use std::path::Path;

/// The values of one per-vertex property, one per vertex.
#[derive(Clone, Copy, Debug)]
pub enum PropertyData<'a> {
    /// Written as PLY `float`.
    Float(&'a [f32]),
    /// Written as PLY `uint`.
    UInt(&'a [u32]),
    /// Written as PLY `uchar`.
    UChar(&'a [u8]),
}

impl PropertyData<'_> {
    fn len(&self) -> usize {
        match self {
            PropertyData::Float(v) => v.len(),
            PropertyData::UInt(v) => v.len(),
            PropertyData::UChar(v) => v.len(),
        }
    }

    fn type_name(&self) -> &'static str {
        match self {
            PropertyData::Float(_) => "float",
            PropertyData::UInt(_) => "uint",
            PropertyData::UChar(_) => "uchar",
        }
    }

    fn write_value(&self, i: usize, out: &mut Vec<u8>) {
        match self {
            PropertyData::Float(v) => out.extend_from_slice(&v[i].to_le_bytes()),
            PropertyData::UInt(v) => out.extend_from_slice(&v[i].to_le_bytes()),
            PropertyData::UChar(v) => out.push(v[i]),
        }
    }
}

/// A named per-vertex property, such as a texton label or a texture coordinate.
#[derive(Clone, Copy, Debug)]
pub struct VertexProperty<'a> {
    /// The property name in the header: ASCII letters, digits and `_`, not one of the
    /// names the writer uses itself (`x y z nx ny nz`).
    pub name: &'a str,
    /// One value per vertex.
    pub data: PropertyData<'a>,
}

/// Writes `mesh` to `path`: `x y z` (float), `nx ny nz` if the mesh has normals, then
/// `properties` in order; faces as `list uchar int vertex_indices`. Each comment becomes a
/// `comment` line. Fails before touching `path` if a property's length differs from the
/// vertex count, a name is invalid or repeated, or a comment spans lines.
pub fn write(path: &Path, mesh: &Mesh, properties: &[VertexProperty], comments: &[&str]) -> Result<()> {
    check(path, mesh, properties, comments)?;
    let header = header(mesh, properties, comments);
    write_with_temp(path, |tmp| {
        let file = std::fs::File::create(tmp).map_err(|e| Error::io(path, e))?;
        let mut out = std::io::BufWriter::new(file);
        out.write_all(header.as_bytes()).map_err(|e| Error::io(path, e))?;
        write_body(&mut out, mesh, properties).map_err(|e| Error::io(path, e))?;
        out.into_inner().map(|_| ()).map_err(|e| Error::io(path, e.into_error()))
    })
}

const RESERVED: [&str; 6] = ["x", "y", "z", "nx", "ny", "nz"];

fn check(path: &Path, mesh: &Mesh, properties: &[VertexProperty], comments: &[&str]) -> Result<()> {
    let invalid = |m: String| Err(Error::invalid(format!("{}: {m}", path.display())));
    for (k, p) in properties.iter().enumerate() {
        let valid_name = !p.name.is_empty()
            && p.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            && !RESERVED.contains(&p.name);
        if !valid_name {
            return invalid(format!("'{}' is not a usable PLY property name", p.name));
        }
        if properties[..k].iter().any(|q| q.name == p.name) {
            return invalid(format!("the PLY property '{}' is given twice", p.name));
        }
        if p.data.len() != mesh.vertex_count() {
            return invalid(format!(
                "the PLY property '{}' has {} values for {} vertices",
                p.name,
                p.data.len(),
                mesh.vertex_count()
            ));
        }
    }
    if let Some(c) = comments.iter().find(|c| c.contains(['\n', '\r'])) {
        return invalid(format!("a PLY comment cannot span lines: {c:?}"));
    }
    Ok(())
}

fn header(mesh: &Mesh, properties: &[VertexProperty], comments: &[&str]) -> String {
    let mut h = String::from("ply\nformat binary_little_endian 1.0\n");
    for c in comments {
        h += &format!("comment {c}\n");
    }
    h += &format!("element vertex {}\n", mesh.vertex_count());
    let coordinates = if mesh.normals().is_some() { &RESERVED[..] } else { &RESERVED[..3] };
    for name in coordinates {
        h += &format!("property float {name}\n");
    }
    for p in properties {
        h += &format!("property {} {}\n", p.data.type_name(), p.name);
    }
    h += &format!("element face {}\nproperty list uchar int vertex_indices\nend_header\n", mesh.face_count());
    h
}

fn write_body(out: &mut impl Write, mesh: &Mesh, properties: &[VertexProperty]) -> std::io::Result<()> {
    let mut row = Vec::with_capacity(64);
    for (i, p) in mesh.positions().iter().enumerate() {
        row.clear();
        let normal = mesh.normals().map(|n| n[i].to_array());
        for c in p.to_array().into_iter().chain(normal.into_iter().flatten()) {
            row.extend_from_slice(&c.to_le_bytes());
        }
        for prop in properties {
            prop.data.write_value(i, &mut row);
        }
        out.write_all(&row)?;
    }
    for t in mesh.triangles() {
        row.clear();
        row.push(3);
        for &i in t {
            row.extend_from_slice(&(i as i32).to_le_bytes());
        }
        out.write_all(&row)?;
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::ply::{parse_header, read, Property, Scalar};
    use crate::mesh::test_meshes::{cube, grid};

    #[test]
    fn round_trip_through_the_reader_is_exact() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("grid.ply");
        let mesh = grid(4);
        let n = mesh.vertex_count();
        let u: Vec<f32> = (0..n).map(|i| i as f32 * 0.5).collect();
        let label: Vec<u32> = (0..n as u32).collect();
        let flag = vec![7u8; n];
        let props = [
            VertexProperty { name: "u", data: PropertyData::Float(&u) },
            VertexProperty { name: "texton", data: PropertyData::UInt(&label) },
            VertexProperty { name: "flag", data: PropertyData::UChar(&flag) },
        ];
        write(&path, &mesh, &props, &["btfsynth test", "seed 7"]).expect("writes");
        let bytes = std::fs::read(&path).expect("reads");
        let soup = read::parse(&bytes, &path).expect("parses");
        let positions: Vec<[f64; 3]> = mesh.positions().iter().map(|p| p.to_array().map(f64::from)).collect();
        assert_eq!(soup.positions, positions);
        let triangles: Vec<[i64; 3]> = mesh.triangles().iter().map(|t| t.map(i64::from)).collect();
        assert_eq!(soup.triangles, triangles);
        let header = parse_header(&bytes).expect("header");
        assert_eq!(header.comments, vec!["btfsynth test", "seed 7"]);
        let names: Vec<&str> = header.elements[0].properties.iter().map(|p| p.name()).collect();
        assert_eq!(names, ["x", "y", "z", "nx", "ny", "nz", "u", "texton", "flag"]);
        assert_eq!(
            header.elements[0].properties[7],
            Property::Scalar { name: "texton".into(), ty: Scalar::U32 }
        );
        let leftovers: Vec<_> = std::fs::read_dir(dir.path()).expect("dir").collect();
        assert_eq!(leftovers.len(), 1, "no temporary file is left behind");
    }

    #[test]
    fn bad_properties_fail_before_writing() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("cube.ply");
        let mesh = cube();
        let short = [1.0f32; 3];
        let ok = [0u8; 8];
        let cases: [(&[VertexProperty], &[&str]); 4] = [
            (&[VertexProperty { name: "u", data: PropertyData::Float(&short) }], &[]),
            (&[VertexProperty { name: "has space", data: PropertyData::UChar(&ok) }], &[]),
            (&[VertexProperty { name: "x", data: PropertyData::UChar(&ok) }], &[]),
            (&[], &["two\nlines"]),
        ];
        for (props, comments) in cases {
            let e = write(&path, &mesh, props, comments).unwrap_err().to_string();
            assert!(e.contains("cube.ply"), "{e}");
            assert!(!path.exists());
        }
    }
}
