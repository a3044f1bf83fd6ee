//! The result of hierarchical pattern mapping as a file a user can open anywhere: the
//! user's mesh, its vertices and faces as the file gave them (polygons fan-triangulated),
//! with texture coordinates into the sample at every face corner.
//!
//! - **PLY** (binary little-endian): `x y z` per vertex; per face `vertex_indices`, a
//!   `texcoord` list of six floats (u, v per corner, as MeshLab writes them), the `cluster`
//!   that textured it and that cluster's `level`. A vertex on a seam between patches keeps
//!   one position and has a coordinate per face.
//! - **OBJ**: `v` lines as given, one `vt` per distinct (vertex, coordinate), `f v/vt`
//!   faces: vertices split at seams only in texture space, as OBJ does.
//!
//! Coordinates are normalised to the sample (u = (x + ½) / width, v = 1 − (y + ½) / height
//! for texel (x, y), texel centres at integers): v runs up as in OBJ and PLY, so the sample
//! image itself is the texture. A tileable sample's coordinates may leave [0, 1] (the
//! texture repeats); a sample that does not tile is never left. Header comments (`#`
//! lines in OBJ) record `btfsynth uvmap`, the analysis, the mesh, the texel size, the
//! sample's size and whether it tiles, and the parameters.

use super::PatchMapping;
use crate::mesh::textured::{load_textured, TexturedMesh};
use crate::synth::surface_map::{comment_value, input_comments};
use crate::{Error, Result};
use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

/// The first comment of a texture-mapped result.
pub const UV_MAP_COMMENT: &str = "btfsynth uvmap";

/// What a result records besides the mesh and its coordinates.
pub struct Provenance<'a> {
    /// The analysis the sample comes from.
    pub analysis: &'a Path,
    /// The user's mesh the coordinates are on.
    pub mesh: &'a Path,
    /// Sample width and height in texels.
    pub sample: (usize, usize),
    /// Whether the sample tiles (coordinates may pass its edges).
    pub tileable: bool,
    /// One sample texel in model units.
    pub texel: f32,
    /// The parameters (no timings: equal inputs give equal bytes).
    pub params: serde_json::Value,
}

/// Sample texel coordinate → file coordinate (see the module documentation).
pub fn to_file_uv(s: Vec2, (w, h): (usize, usize)) -> Vec2 {
    Vec2::new((s.x + 0.5) / w as f32, 1.0 - (s.y + 0.5) / h as f32)
}

/// File coordinate → sample texel coordinate.
pub fn from_file_uv(uv: Vec2, (w, h): (usize, usize)) -> Vec2 {
    Vec2::new(uv.x * w as f32 - 0.5, (1.0 - uv.y) * h as f32 - 0.5)
}

/// Writes `mapping` of the mesh (`positions`, `triangles`: the file's) as the output `path`,
/// a `.ply` or `.obj`, into the file `into` (the caller's staged temporary, renamed to
/// `path` when every output is complete; the comments name `path`).
pub fn write_uv_map(
    (path, into): (&Path, &Path),
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    mapping: &PatchMapping,
    provenance: &Provenance,
) -> Result<()> {
    let comments = comments(path, provenance);
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let bytes = match ext.as_str() {
        "ply" => ply_bytes(positions, triangles, mapping, provenance.sample, &comments),
        "obj" => obj_bytes(positions, triangles, mapping, provenance.sample, &comments),
        _ => {
            return Err(Error::output_refused(
                path,
                format!("{}: the output must be a .ply or .obj file", path.display()),
            ))
        }
    };
    std::fs::write(into, &bytes).map_err(|e| Error::io(path, e))
}

fn comments(path: &Path, p: &Provenance) -> Vec<String> {
    let mut comments = vec![UV_MAP_COMMENT.to_string()];
    comments.extend(input_comments(p.analysis, p.mesh, path));
    comments.extend([
        format!("texel {}", p.texel),
        format!("sample {}x{}", p.sample.0, p.sample.1),
        format!("tileable {}", p.tileable),
        format!("params {}", p.params),
    ]);
    comments
}

fn ply_bytes(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    mapping: &PatchMapping,
    sample: (usize, usize),
    comments: &[String],
) -> Vec<u8> {
    let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
    for c in comments {
        let _ = writeln!(header, "comment {c}");
    }
    let _ = write!(
        header,
        "element vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\n\
         property list uchar int vertex_indices\nproperty list uchar float texcoord\nproperty int cluster\n\
         property uchar level\nend_header\n",
        positions.len(),
        triangles.len()
    );
    let mut out = header.into_bytes();
    for p in positions {
        for c in p.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for (f, t) in triangles.iter().enumerate() {
        out.push(3);
        for &i in t {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
        out.push(6);
        for s in mapping.corner_uv[f] {
            for c in to_file_uv(s, sample).to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        out.extend_from_slice(&(mapping.cluster[f] as i32).to_le_bytes());
        out.push(mapping.level[f]);
    }
    out
}

fn obj_bytes(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    mapping: &PatchMapping,
    sample: (usize, usize),
    comments: &[String],
) -> Vec<u8> {
    let mut text = String::new();
    for c in comments {
        let _ = writeln!(text, "# {c}");
    }
    for p in positions {
        let _ = writeln!(text, "v {} {} {}", p.x, p.y, p.z);
    }
    let mut index: HashMap<(u32, [u32; 2]), usize> = HashMap::new();
    let mut faces = String::new();
    for (f, t) in triangles.iter().enumerate() {
        faces.push('f');
        for (&vertex, &corner_uv) in t.iter().zip(&mapping.corner_uv[f]) {
            let uv = to_file_uv(corner_uv, sample);
            let next = index.len() + 1;
            let vt = *index.entry((vertex, uv.to_array().map(f32::to_bits))).or_insert_with(|| {
                let _ = writeln!(text, "vt {} {}", uv.x, uv.y);
                next
            });
            let _ = write!(faces, " {}/{vt}", vertex + 1);
        }
        faces.push('\n');
    }
    text.push_str(&faces);
    text.into_bytes()
}

/// A texture-mapped result read back.
#[derive(Clone, Debug)]
pub struct UvMap {
    /// The mesh with its per-corner coordinates (as the file writes them).
    pub mesh: TexturedMesh,
    /// Per face, per corner, the sample coordinate in texels.
    pub corner_uv: Vec<[Vec2; 3]>,
    /// Per face, the level of the cluster that textured it (0 where the file does not say).
    pub level: Vec<u8>,
    /// Per face, that cluster (`u32::MAX` where the file does not say).
    pub cluster: Vec<u32>,
    /// The header's comments.
    pub comments: Vec<String>,
    /// Sample width and height.
    pub sample: (usize, usize),
    /// One texel in model units.
    pub texel: f32,
    /// Whether the sample tiles (coordinates may pass its edges).
    pub tileable: bool,
}

impl UvMap {
    /// The value of the comment `KEY value`.
    pub fn comment(&self, key: &str) -> Option<&str> {
        comment_value(&self.comments, key)
    }
}

/// The comments of a PLY header or the leading `#` lines of an OBJ, if `path` is a
/// texture-mapped result (else None).
pub fn uv_map_comments(path: &Path) -> Option<Vec<String>> {
    use std::io::Read;
    let mut head = Vec::new();
    std::fs::File::open(path).ok()?.take(1 << 20).read_to_end(&mut head).ok()?;
    let comments: Vec<String> = if head.starts_with(b"ply") {
        crate::mesh::ply::parse_header(&head).ok()?.comments
    } else {
        String::from_utf8_lossy(&head)
            .lines()
            .map_while(|l| l.strip_prefix('#'))
            .map(|c| c.trim().to_string())
            .collect()
    };
    comments.first().is_some_and(|c| c == UV_MAP_COMMENT).then_some(comments)
}

/// Reads a texture-mapped result written by [`write_uv_map`].
pub fn read_uv_map(path: &Path) -> Result<UvMap> {
    let bad = |m: &str| Error::format(path, format!("not a btfsynth uvmap: {m}"));
    let comments = uv_map_comments(path).ok_or_else(|| bad("no 'btfsynth uvmap' comment at its start"))?;
    let mut mesh = load_textured(path)?;
    let uvs = mesh.uvs.as_ref().ok_or_else(|| bad("its faces have no texture coordinates"))?;
    // Corners of one vertex with the same coordinate share it (a PLY writes one per corner),
    // so that a patch is one piece and only seams split vertices.
    let mut shared: HashMap<(u32, [u32; 2]), u32> = HashMap::new();
    let mut coords = Vec::new();
    let corners: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .zip(&uvs.corners)
        .map(|(t, c)| {
            std::array::from_fn(|k| {
                let uv = uvs.coords[c[k] as usize];
                *shared.entry((t[k], uv.to_array().map(f32::to_bits))).or_insert_with(|| {
                    coords.push(uv);
                    (coords.len() - 1) as u32
                })
            })
        })
        .collect();
    mesh.uvs = Some(crate::mesh::textured::UvLayer { coords, corners });
    let uvs = mesh.uvs.as_ref().ok_or_else(|| bad("its faces have no texture coordinates"))?;
    let value = |key: &str| comment_value(&comments, key);
    let sample = value("sample")
        .and_then(|s| s.split_once('x'))
        .and_then(|(w, h)| Some((w.parse::<usize>().ok()?, h.parse::<usize>().ok()?)))
        .filter(|&(w, h)| w > 0 && h > 0)
        .ok_or_else(|| bad("no 'sample WxH' comment"))?;
    let texel = value("texel")
        .and_then(|t| t.parse::<f32>().ok())
        .filter(|t| t.is_finite() && *t > 0.0)
        .ok_or_else(|| bad("no positive 'texel' comment"))?;
    let tileable = value("tileable") == Some("true");
    let corner_uv: Vec<[Vec2; 3]> =
        uvs.corners.iter().map(|c| c.map(|i| from_file_uv(uvs.coords[i as usize], sample))).collect();
    if let Some(f) =
        corner_uv.iter().position(|c| c.iter().any(|s| !s.is_finite() || s.abs().max_element() > 1e7))
    {
        return Err(bad(&format!("face {f} has a texture coordinate far outside the sample")));
    }
    let faces = mesh.triangles.len();
    let (mut level, mut cluster) = (vec![0u8; faces], vec![u32::MAX; faces]);
    if !comments.is_empty() && path.extension().is_some_and(|e| e.eq_ignore_ascii_case("ply")) {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let mut f = 0usize;
        crate::mesh::ply::read::visit_rows(&bytes, path, |element, _, row| {
            if element.name != "face" {
                return Ok(());
            }
            let find = |name: &str| element.properties.iter().position(|p| p.name() == name);
            // One row per polygon; a triangle is one face (this writer writes triangles).
            if f < faces {
                if let Some(k) = find("level") {
                    level[f] = row[k].first().copied().unwrap_or(0.0).clamp(0.0, 255.0) as u8;
                }
                if let Some(k) = find("cluster") {
                    cluster[f] = row[k].first().copied().unwrap_or(-1.0).max(-1.0) as i64 as u32;
                }
            }
            f += 1;
            Ok(())
        })?;
    }
    Ok(UvMap { mesh, corner_uv, level, cluster, comments, sample, texel, tileable })
}
