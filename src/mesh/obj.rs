//! Wavefront OBJ: the one reader of `v`, `vt`, `f`, `o` and `g` lines (everything else is
//! ignored; materials are never opened). Polygons are fan-triangulated, negative (relative)
//! indices resolved, and texture coordinates kept where every face has them.
//!
//! Two views of one parse: [`parse`] gives [`load`](super::load()) a soup whose vertices are
//! numbered per object in the order faces first use them (the order meshes have always
//! loaded in, so results stay the same), and [`super::textured::read_obj`] keeps the
//! file's own arrays, which export writes back with the file's UV seams.

use super::Soup;
use crate::{Error, Result};
use glam::Vec2;
use std::collections::HashMap;
use std::path::Path;

/// An OBJ file as it is written: indices into the file's own arrays, counted from 0.
pub(crate) struct ObjFile {
    /// Every `v` line and the fan-triangulated faces.
    pub soup: Soup,
    /// Every `vt` line and, per triangle, its corners' indices into them, if every face
    /// has texture coordinates.
    pub uvs: Option<(Vec<Vec2>, Vec<[i64; 3]>)>,
    /// The first triangle of each object or group after the first (an `o` or `g` line
    /// that follows faces).
    objects: Vec<usize>,
}

/// Parses OBJ text for [`load`](super::load()): per object, the vertices its faces use, in
/// the order they first use them; shared vertices end up duplicated and are welded later.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Soup> {
    read(bytes, path)?.per_object(path)
}

/// Parses OBJ text (bytes that are not UTF-8 are replaced, as they can only occur in names
/// and comments of a valid file). Out-of-range indices are left for the caller to report.
pub(crate) fn read(bytes: &[u8], path: &Path) -> Result<ObjFile> {
    let text = String::from_utf8_lossy(bytes);
    let mut soup = Soup::default();
    let mut coords: Vec<Vec2> = Vec::new();
    let mut uv_corners: Vec<[i64; 3]> = Vec::new();
    let mut objects = Vec::new();
    let mut every_face_has_uvs = true;
    for (n, line) in text.lines().enumerate() {
        let bad = |m: String| Error::format(path, format!("line {}: {m}", n + 1));
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => soup.positions.push(numbers::<3>(words, 3).map_err(bad)?.map(f64::from)),
            Some("vt") => {
                let [u, v] = numbers::<2>(words, 1).map_err(bad)?;
                coords.push(Vec2::new(u, v));
            }
            Some("o" | "g") if objects.last().copied().unwrap_or(0) < soup.triangles.len() => {
                objects.push(soup.triangles.len())
            }
            Some("f") => {
                let (mut polygon, mut uvs) = (Vec::new(), Vec::new());
                for corner in words {
                    let mut parts = corner.split('/');
                    let v = parts.next().unwrap_or_default();
                    polygon.push(index(v, soup.positions.len()).map_err(bad)?);
                    match parts.next().filter(|t| !t.is_empty()) {
                        Some(t) => uvs.push(index(t, coords.len()).map_err(bad)?),
                        None => every_face_has_uvs = false,
                    }
                }
                if polygon.len() < 3 {
                    return Err(bad("a face needs at least three corners".into()));
                }
                Soup::fan_triangulate(&polygon, &mut soup.triangles);
                Soup::fan_triangulate(&uvs, &mut uv_corners);
            }
            _ => {}
        }
    }
    let uvs = (every_face_has_uvs && !coords.is_empty()).then_some((coords, uv_corners));
    Ok(ObjFile { soup, uvs, objects })
}

impl ObjFile {
    /// The soup [`parse`] gives: each object's vertices numbered in the order its faces
    /// first use them (vertices no face uses are left out).
    fn per_object(self, path: &Path) -> Result<Soup> {
        let n = self.soup.positions.len();
        let mut out = Soup {
            positions: Vec::with_capacity(n),
            triangles: Vec::with_capacity(self.soup.triangles.len()),
        };
        let mut starts = vec![0];
        starts.extend(&self.objects);
        starts.push(self.soup.triangles.len());
        for range in starts.windows(2) {
            let mut local: HashMap<i64, i64> = HashMap::new();
            for (f, t) in self.soup.triangles[range[0]..range[1]].iter().enumerate() {
                let mut corners = [0; 3];
                for (corner, &i) in corners.iter_mut().zip(t) {
                    if !usize::try_from(i).is_ok_and(|i| i < n) {
                        return Err(Error::format(
                            path,
                            format!("face {} refers to vertex {i} (counting from 0), but the file has {n} vertices", range[0] + f),
                        ));
                    }
                    *corner = *local.entry(i).or_insert_with(|| {
                        out.positions.push(self.soup.positions[i as usize]);
                        out.positions.len() as i64 - 1
                    });
                }
                out.triangles.push(corners);
            }
        }
        Ok(out)
    }
}

/// The first `N` numbers of an OBJ line (at least `required` of them; missing ones are 0),
/// read as `f32`, the precision meshes are kept at.
fn numbers<'a, const N: usize>(
    words: impl Iterator<Item = &'a str>,
    required: usize,
) -> Result<[f32; N], String> {
    let mut out = [0.0; N];
    let mut count = 0;
    for (k, w) in words.take(N).enumerate() {
        out[k] = w.parse().map_err(|_| format!("'{w}' is not a number"))?;
        count += 1;
    }
    if count < required {
        return Err(format!("expected at least {required} numbers"));
    }
    Ok(out)
}

/// A 1-based OBJ index (negative: counting back from the `seen` items so far) as 0-based.
fn index(word: &str, seen: usize) -> Result<i64, String> {
    let i: i64 = word.parse().map_err(|_| format!("'{word}' is not an index"))?;
    match i {
        0 => Err("index 0 (OBJ counts from 1)".into()),
        i if i > 0 => Ok(i - 1),
        i => Ok(seen as i64 + i),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{load, test_meshes::bundled, test_meshes::shared, topology};

    fn parse_str(s: &str) -> Result<Soup> {
        parse(s.as_bytes(), Path::new("t.obj"))
    }

    #[test]
    fn quads_and_polygons_are_fan_triangulated() {
        let s =
            parse_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 2 0\nf 1 2 3 4\nf 4 3 5\n").expect("parses");
        assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3], [3, 2, 4]]);
        let p = parse_str("v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 4 5\n").expect("parses");
        assert_eq!(p.triangles.len(), 3);
    }

    /// Per object, vertices are numbered as its faces first use them, and a vertex two
    /// objects share is duplicated (welding joins it again).
    #[test]
    fn each_object_numbers_the_vertices_its_faces_use() {
        let s = parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 9 9 9\nv 1 1 0\no a\nf 3 1 2\ng b\nf 2 5 3\n")
            .expect("parses");
        assert_eq!(s.triangles, vec![[0, 1, 2], [3, 4, 5]]);
        let p = |i: usize| s.positions[i];
        assert_eq!([p(0), p(1), p(2)], [[0.0, 1.0, 0.0], [0.0; 3], [1.0, 0.0, 0.0]]);
        assert_eq!([p(3), p(4), p(5)], [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]);
        assert_eq!(s.positions.len(), 6, "the unused vertex is left out");
    }

    #[test]
    fn relative_indices_and_vt_vn_parts_are_handled() {
        let s = parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf -3/-1 -2/99/7 -1//3\n").expect("parses");
        assert_eq!(s.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn out_of_range_position_index_is_an_error() {
        let e = parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap_err().to_string();
        assert!(e.starts_with("t.obj: face 0 refers to vertex 3"), "{e}");
        assert!(parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n").is_err());
        assert!(parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n").is_err());
    }

    #[test]
    fn empty_and_garbage_files_have_no_faces() {
        for text in ["", "hello world\n", "# only a comment\nv 1 2 3\n"] {
            let soup = parse_str(text).expect("parses: no face is no error yet");
            assert!(soup.triangles.is_empty());
        }
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("empty.obj");
        std::fs::write(&path, "# nothing\n").expect("write");
        let e = load(&path).unwrap_err().to_string();
        assert!(e.contains("empty.obj: the file has no faces"), "{e}");
    }

    #[test]
    fn bunny10k_with_negative_indices_loads_as_one_surface() {
        let Some(path) = shared("bunny10k_with_negative_indices_loads_as_one_surface", "bunny10k-uv.obj")
        else {
            return;
        };
        let mesh = load(&path).expect("loads");
        let s = topology::summary(&mesh);
        // Positions are shared across the UV atlas's charts, so the surface is one piece
        // whose boundary is the bunny's own (its holes), not the 6,451-UV chart seams.
        assert_eq!((s.vertices, s.faces), (5051, 9999));
        assert_eq!(s.boundary_edges, 109);
        assert!(crate::mesh::manifold::is_manifold(mesh.triangles()));
    }

    #[test]
    fn teapot_patches_weld_into_its_four_surfaces() {
        // The file holds 32 separate patches (792 vertices, 528 boundary edges). Welding
        // leaves the surfaces the Utah teapot is made of: body, handle, spout and lid. They
        // share no seam: the spout and the lid stand 1.1 and 0.5 units (3 % and 1.5 % of the
        // bounding-box diagonal) from the body, and the handle touches it at one vertex,
        // which is split because a vertex joining two surfaces has no single one-ring.
        let soup = crate::mesh::load::read_soup(&bundled("teapot.obj")).expect("parses");
        assert_eq!(soup.positions.len(), 792);
        let mesh = load(&bundled("teapot.obj")).expect("loads");
        let s = topology::summary(&mesh);
        assert_eq!((s.vertices, s.faces), (529 + 1, 992), "{s}");
        assert_eq!((s.components, s.boundary_edges), (4, 64), "{s}");
        assert!(crate::mesh::manifold::is_manifold(mesh.triangles()));
    }
}
