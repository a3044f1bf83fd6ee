//! A mesh exactly as its file gives it, with its texture coordinates: what `export` writes
//! back in the user's own UV layout.
//!
//! [`load`](super::load()) welds, repairs and re-orients a mesh for synthesis, which would
//! lose the file's UV seams; this reader keeps the file's vertices, faces and UVs as they
//! are and only validates them. Texture coordinates are read from OBJ `vt` (faces
//! `f v/vt …`, relative indices included) and from PLY per-vertex `s t`, `texture_u
//! texture_v` or `texture_s texture_t`, or per-corner face lists `texcoord` (as MeshLab
//! writes them). An OFF file has no texture coordinates.

use super::Soup;
use crate::{Error, Result};
use glam::{Vec2, Vec3};
use std::path::Path;

/// A mesh as its file gives it (polygons fan-triangulated), with texture coordinates if
/// every face has them.
#[derive(Clone, Debug, PartialEq)]
pub struct TexturedMesh {
    /// Vertex positions, in file order.
    pub positions: Vec<Vec3>,
    /// Triangles as indices into `positions`, in file order.
    pub triangles: Vec<[u32; 3]>,
    /// Texture coordinates of every triangle corner, if the file has them for every face.
    pub uvs: Option<UvLayer>,
}

/// Texture coordinates per triangle corner, shared between corners as the file shares them
/// (so UV seams stay where the file puts them).
#[derive(Clone, Debug, PartialEq)]
pub struct UvLayer {
    /// (u, v) as the file writes them: v runs up, as in OBJ, PLY and OpenGL (an image's
    /// first row is at v = 1).
    pub coords: Vec<Vec2>,
    /// Per triangle, the index into `coords` of each of its three corners.
    pub corners: Vec<[u32; 3]>,
}

/// Reads `path` (`.obj`, `.ply` or `.off`, by extension) with its texture coordinates.
pub fn load_textured(path: &Path) -> Result<TexturedMesh> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let mesh = match ext.as_str() {
        "obj" => {
            let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
            read_obj(&bytes, path)?
        }
        "ply" => {
            let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
            read_ply(&bytes, path)?
        }
        "off" => from_soup(super::load::read_soup(path)?, None, path)?,
        _ => return Err(Error::format(path, "unknown mesh format: expected a .obj, .off or .ply file")),
    };
    Ok(mesh)
}

/// Parses OBJ text with [`super::obj`]'s reader, keeping the file's own vertex and texture
/// coordinate arrays as written (relative indices resolved, polygons fan-triangulated).
pub fn read_obj(bytes: &[u8], path: &Path) -> Result<TexturedMesh> {
    let file = super::obj::read(bytes, path)?;
    let uvs = file.uvs.map(|(coords, corners)| UvLayer {
        coords,
        corners: corners.iter().map(|t| t.map(|i| u32::try_from(i).unwrap_or(u32::MAX))).collect(),
    });
    from_soup(file.soup, uvs, path)
}

/// Parses a PLY file with per-vertex (`s t`, `texture_u texture_v`, `texture_s texture_t`)
/// or per-corner (face list `texcoord`) texture coordinates, through
/// [`super::ply::read`]'s one reading of its rows.
pub fn read_ply(bytes: &[u8], path: &Path) -> Result<TexturedMesh> {
    let mesh = super::ply::read::read_mesh(bytes, path)?;
    let uv = |c: &[f64; 2]| Vec2::new(c[0] as f32, c[1] as f32);
    // Per-corner coordinates count only if every face had them; else per-vertex ones.
    let uvs = if !mesh.corner_uvs.is_empty() && mesh.corner_uvs.len() == mesh.corners {
        Some(UvLayer {
            coords: mesh.corner_uvs.iter().map(uv).collect(),
            corners: mesh.corner_triangles.iter().map(|t| t.map(|i| i as u32)).collect(),
        })
    } else if !mesh.vertex_uvs.is_empty() && mesh.vertex_uvs.len() == mesh.soup.positions.len() {
        let corners =
            mesh.soup.triangles.iter().map(|t| t.map(|i| u32::try_from(i).unwrap_or(u32::MAX))).collect();
        Some(UvLayer { coords: mesh.vertex_uvs.iter().map(uv).collect(), corners })
    } else {
        None
    };
    from_soup(mesh.soup, uvs, path)
}

/// Validates a parsed mesh: faces exist, coordinates are finite, indices in range.
fn from_soup(soup: Soup, uvs: Option<UvLayer>, path: &Path) -> Result<TexturedMesh> {
    if soup.triangles.is_empty() {
        return Err(Error::format(path, "the file has no faces (is it a mesh?)"));
    }
    let positions: Vec<Vec3> =
        soup.positions.iter().map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)).collect();
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::format(path, format!("vertex {i} has a non-finite coordinate")));
    }
    let n = positions.len();
    let mut triangles = Vec::with_capacity(soup.triangles.len());
    for (f, t) in soup.triangles.iter().enumerate() {
        if let Some(&i) = t.iter().find(|&&i| !usize::try_from(i).is_ok_and(|i| i < n)) {
            return Err(Error::format(
                path,
                format!("face {f} refers to vertex {i} (counting from 0), but the file has {n} vertices"),
            ));
        }
        triangles.push(t.map(|i| i as u32));
    }
    if let Some(uv) = &uvs {
        if let Some(i) = uv.coords.iter().position(|c| !c.is_finite()) {
            return Err(Error::format(path, format!("texture coordinate {i} is not finite")));
        }
        if uv.corners.len() != triangles.len()
            || uv.corners.iter().flatten().any(|&i| i as usize >= uv.coords.len())
        {
            return Err(Error::format(path, "the texture coordinates do not match the faces"));
        }
    }
    Ok(TexturedMesh { positions, triangles, uvs })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obj(text: &str) -> Result<TexturedMesh> {
        read_obj(text.as_bytes(), Path::new("t.obj"))
    }

    #[test]
    fn obj_corners_keep_their_own_vt_with_relative_indices_and_polygons() {
        let m = obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n\
                     f -4/-5 -3/-4 -2/-3 -1/-2\nf 1/5 3/5 4/5\n")
        .expect("parses");
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
        let uv = m.uvs.expect("every face has vt");
        let at = |t: usize| uv.corners[t].map(|i| uv.coords[i as usize]);
        assert_eq!(at(0), [Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0)]);
        assert_eq!(at(1), [Vec2::new(0.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)]);
        assert_eq!(at(2), [Vec2::splat(0.5); 3]);
    }

    #[test]
    fn obj_without_vt_on_every_face_has_no_uvs() {
        assert!(obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").expect("parses").uvs.is_none());
        let e = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/2\n").unwrap_err().to_string();
        assert!(e.starts_with("t.obj: the texture coordinates"), "{e}");
        let e = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n").unwrap_err().to_string();
        assert!(e.starts_with("t.obj: line 4: 'x' is not an index"), "{e}");
    }

    #[test]
    fn ply_vertex_and_corner_texture_coordinates() {
        let vertex = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
            property float z\nproperty float s\nproperty float t\nelement face 1\n\
            property list uchar int vertex_indices\nend_header\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n";
        let m = read_ply(vertex.as_bytes(), Path::new("t.ply")).expect("parses");
        let uv = m.uvs.expect("s, t");
        assert_eq!(uv.corners, vec![[0, 1, 2]]);
        assert_eq!(uv.coords[2], Vec2::new(0.0, 1.0));
        let corners = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
            property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
            property list uchar float texcoord\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n\
            4 0 1 2 3 8 0 0 0.5 0 0.5 0.5 0 0.5\n";
        let m = read_ply(corners.as_bytes(), Path::new("t.ply")).expect("parses");
        let uv = m.uvs.expect("texcoord lists");
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(uv.corners, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(uv.coords[3], Vec2::new(0.0, 0.5));
        let bad = corners.replace("8 0 0 0.5 0 0.5 0.5 0 0.5", "2 0 0");
        let e = read_ply(bad.as_bytes(), Path::new("t.ply")).unwrap_err().to_string();
        assert!(e.contains("texcoord list"), "{e}");
    }

    #[test]
    fn out_of_range_and_non_finite_are_errors_naming_the_file() {
        let e = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 5\n").unwrap_err().to_string();
        assert!(e.starts_with("t.obj"), "{e}");
        let e = obj("v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n").unwrap_err().to_string();
        assert!(e.starts_with("t.obj") && e.contains("non-finite"), "{e}");
    }

    #[test]
    fn bunny10k_keeps_its_atlas() {
        let Some(path) = crate::testdata::shared_data("bunny10k_keeps_its_atlas", "meshes/bunny10k-uv.obj")
        else {
            return;
        };
        let m = load_textured(&path).expect("loads");
        assert_eq!((m.positions.len(), m.triangles.len()), (5051, 9999));
        let uv = m.uvs.expect("the file has vt on every face");
        assert_eq!(uv.coords.len(), 6451);
        // The first face is `f -4706/-6079 -2971/-3335 -4371/-5618`, read after all
        // 5051 v and 6451 vt lines.
        assert_eq!(m.triangles[0], [5051 - 4706, 5051 - 2971, 5051 - 4371]);
        let text = std::fs::read_to_string(&path).expect("reads");
        let vt: Vec<Vec2> = text
            .lines()
            .filter_map(|l| l.strip_prefix("vt "))
            .map(|l| {
                let c: Vec<f32> = l.split_whitespace().map(|w| w.parse().expect("number")).collect();
                Vec2::new(c[0], c[1])
            })
            .collect();
        let corner = uv.corners[0].map(|i| uv.coords[i as usize]);
        assert_eq!(corner, [6451 - 6079, 6451 - 3335, 6451 - 5618].map(|i| vt[i]));
    }
}
