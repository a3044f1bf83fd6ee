//! Wavefront OBJ through `tobj`: positions and faces only; polygons are fan-triangulated
//! and negative (relative) indices resolved.
//!
//! Only `v`, `f`, `o` and `g` lines reach `tobj`, and face corners lose their `/vt/vn`
//! parts first. Texture coordinates and normals are not needed (normals are recomputed),
//! and `tobj` trusts them: it drops out-of-range ones silently and can overflow on huge
//! ones. Materials are never opened.

use super::Soup;
use crate::{Error, Result};
use std::path::Path;

/// Parses OBJ text (bytes that are not UTF-8 are replaced, as they can only occur in names
/// and comments of a valid file).
pub fn parse(bytes: &[u8], path: &Path) -> Result<Soup> {
    let text = String::from_utf8_lossy(bytes);
    let geometry = geometry_lines(&text);
    let options =
        tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    let (models, _) =
        tobj::load_obj_buf(&mut geometry.as_bytes(), &options, |_| Err(tobj::LoadError::OpenFileFailed))
            .map_err(|e| Error::format(path, format!("not a valid OBJ file: {e}")))?;
    concatenate(models, path)
}

/// The `v`, `f`, `o`, `g` lines of `text`, face corners reduced to their position index.
fn geometry_lines(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some(kind @ ("v" | "o" | "g")) => {
                out.push_str(kind);
                words.for_each(|w| {
                    out.push(' ');
                    out.push_str(w);
                });
            }
            Some("f") => {
                out.push('f');
                words.for_each(|w| {
                    out.push(' ');
                    out.push_str(w.split('/').next().unwrap_or(w));
                });
            }
            _ => continue,
        }
        out.push('\n');
    }
    out
}

/// Joins tobj's models (one per object or group, each with its own vertex list) into one
/// soup; shared vertices end up duplicated and are welded later.
fn concatenate(models: Vec<tobj::Model>, path: &Path) -> Result<Soup> {
    let mut soup = Soup::default();
    for model in models {
        let m = model.mesh;
        if m.positions.len() % 3 != 0 || m.indices.len() % 3 != 0 || !m.face_arities.is_empty() {
            return Err(Error::format(
                path,
                format!("OBJ object '{}' did not triangulate cleanly", model.name),
            ));
        }
        let offset = soup.positions.len() as i64;
        soup.positions.extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]].map(f64::from)));
        soup.triangles
            .extend(m.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]].map(|i| offset + i64::from(i))));
    }
    Ok(soup)
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

    #[test]
    fn relative_indices_and_vt_vn_parts_are_handled() {
        let s = parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf -3/-1 -2/99/7 -1//3\n").expect("parses");
        assert_eq!(s.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn out_of_range_position_index_is_an_error() {
        let e = parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap_err().to_string();
        assert!(e.starts_with("t.obj: not a valid OBJ file"), "{e}");
        assert!(parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n").is_err());
        assert!(parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n").is_err());
    }

    #[test]
    fn empty_and_garbage_files_have_no_faces() {
        for text in ["", "hello world\n", "# only a comment\nv 1 2 3\n"] {
            let soup = parse_str(text).expect("tobj accepts it");
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
