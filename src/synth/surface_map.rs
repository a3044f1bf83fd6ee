//! Surface mode: a surface texton map on a triangle mesh (Tong §5). The mesh is remeshed so
//! that one edge is one sample texel on the finest level and twice as long on each coarser
//! level (independent remeshes, about a quarter of the vertices each); every level gets
//! tangent frames, templates and forward shifts, finer levels are linked to coarser ones,
//! and the engine runs coarse to fine. Output: a binary PLY of the finest mesh.

use super::engine::State;
use super::surface::{link_levels, surface_level};
use super::target::TargetLevel;
use super::{synthesize, LevelReport, Sample, SynthParams};
use crate::analysis::knn::parent_size;
use crate::mesh::field::{frames, Orientation};
use crate::mesh::frames::Frames;
use crate::mesh::ply::{self, PropertyData, VertexProperty};
use crate::mesh::remesh::{edge_length_stats, remesh, EdgeLengthStats, RemeshParams};
use crate::mesh::Mesh;
use crate::progress::Progress;
use crate::{Error, Result};
use std::path::Path;
use std::time::Instant;

/// How large the sample appears on the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Density {
    /// Sample texels per model unit.
    Scale(f32),
    /// Sample texels across the bounding box's largest side.
    TexelsAcross(f32),
    /// Vertices of the finest synthesis mesh (one vertex spacing = one texel).
    Vertices(usize),
}

impl Density {
    /// The finest level's texel size (= target edge length) in model units.
    pub fn texel(&self, mesh: &Mesh) -> Result<f32> {
        let texel = match *self {
            Density::Scale(s) => 1.0 / s,
            Density::TexelsAcross(n) => {
                let (lo, hi) = mesh.bounds();
                (hi - lo).max_element() / n
            }
            Density::Vertices(n) => {
                (2.0 * mesh.surface_area() / (3f64.sqrt() * n.max(1) as f64)).sqrt() as f32
            }
        };
        if !(texel.is_finite() && texel > 0.0) {
            return Err(Error::invalid(format!("{self:?} gives no usable texel size")));
        }
        Ok(texel)
    }
}

/// One level of the synthesis mesh pyramid.
pub struct MeshLevel {
    pub mesh: Mesh,
    pub frames: Frames,
    pub texel: f32,
    pub edges: EdgeLengthStats,
}

/// The synthesis meshes, finest first, with their engine-side levels.
pub struct SurfacePyramid {
    pub levels: Vec<MeshLevel>,
    pub targets: Vec<TargetLevel>,
    /// Seconds spent remeshing, framing and building templates.
    pub seconds: [f64; 3],
}

/// Refuses finest meshes beyond this many vertices (about 1.5 GB of templates).
pub const MAX_VERTICES: usize = 3_000_000;

/// Remeshes `mesh` into `levels` levels and builds every level's templates and links.
pub fn build_pyramid(
    mesh: &Mesh,
    density: Density,
    levels: usize,
    orientation: &Orientation,
    params: &SynthParams,
    progress: &dyn Progress,
) -> Result<SurfacePyramid> {
    let texel = density.texel(mesh)?;
    let estimate = mesh.surface_area() / (3f64.sqrt() / 2.0 * (texel as f64).powi(2));
    if estimate > MAX_VERTICES as f64 {
        return Err(Error::invalid(format!(
            "that density needs about {estimate:.0} vertices (the limit is {MAX_VERTICES}); lower --scale, --texels-across or --vertices"
        )));
    }
    let mut seconds = [0.0; 3];
    let mut meshes = Vec::with_capacity(levels);
    for l in 0..levels {
        let started = Instant::now();
        let edge = texel * (1 << l) as f32;
        // A vertex budget is steered towards as the remesher runs; a scale is a length.
        let target = match density {
            Density::Vertices(n) => RemeshParams::vertex_count(mesh, (n >> (2 * l)).max(4)),
            _ => RemeshParams::edge_length(edge),
        };
        let remeshed = remesh(mesh, &target, progress)?.with_normals();
        seconds[0] += started.elapsed().as_secs_f64();
        let started = Instant::now();
        let level_frames = frames(&remeshed, orientation, params.seed)?;
        seconds[1] += started.elapsed().as_secs_f64();
        let edges = edge_length_stats(&remeshed);
        meshes.push(MeshLevel { mesh: remeshed, frames: level_frames, texel: edge, edges });
    }
    let started = Instant::now();
    let mut targets = meshes
        .iter()
        .map(|m| surface_level(&m.mesh, &m.frames, m.texel, params.neighborhood))
        .collect::<Result<Vec<_>>>()?;
    let parent_template = parent_size(params.neighborhood);
    for l in 0..levels.saturating_sub(1) {
        let (fine, coarse) = (&meshes[l], &meshes[l + 1]);
        let coarse_templates = surface_level(&coarse.mesh, &coarse.frames, coarse.texel, parent_template)?;
        link_levels(
            &fine.mesh,
            &fine.frames,
            &mut targets[l],
            &coarse.mesh,
            &coarse.frames,
            coarse_templates,
            fine.texel,
        )?;
    }
    seconds[2] = started.elapsed().as_secs_f64();
    Ok(SurfacePyramid { levels: meshes, targets, seconds })
}

/// Synthesizes the surface texton map of `pyramid` from `sample`.
pub fn synthesize_surface(
    pyramid: &SurfacePyramid,
    sample: &Sample,
    params: &SynthParams,
    progress: &dyn Progress,
) -> Result<(State, Vec<LevelReport>)> {
    synthesize(&pyramid.targets, sample, params, progress)
}

/// Writes the finest level with its map as a binary PLY: position, normal, frame direction
/// s (`sx sy sz`), `texton`, `u`, `v` (sample texels); the header comments record the
/// analysis, the mesh, the texel size and `params` (which must hold no timings: equal
/// inputs give equal bytes).
pub fn write_surface_ply(
    path: &Path,
    level: &MeshLevel,
    state: &State,
    (analysis, mesh): (&Path, &Path),
    params: &serde_json::Value,
) -> Result<()> {
    let comments = [
        "btfsynth surface".to_string(),
        format!("analysis {}", analysis.display()),
        format!("mesh {}", mesh.display()),
        format!(
            "mesh_absolute {}",
            std::path::absolute(mesh).unwrap_or_else(|_| mesh.to_path_buf()).display()
        ),
        format!("texel {}", level.texel),
        format!("params {params}"),
    ];
    let component = |c: usize| level.frames.s.iter().map(|s| s[c]).collect::<Vec<f32>>();
    let (sx, sy, sz) = (component(0), component(1), component(2));
    let texton: Vec<u32> = state.labels.iter().map(|&l| l as u32).collect();
    let u: Vec<f32> = state.uv.iter().map(|p| p[0] as f32).collect();
    let v: Vec<f32> = state.uv.iter().map(|p| p[1] as f32).collect();
    let properties = [
        VertexProperty { name: "sx", data: PropertyData::Float(&sx) },
        VertexProperty { name: "sy", data: PropertyData::Float(&sy) },
        VertexProperty { name: "sz", data: PropertyData::Float(&sz) },
        VertexProperty { name: "texton", data: PropertyData::UInt(&texton) },
        VertexProperty { name: "u", data: PropertyData::Float(&u) },
        VertexProperty { name: "v", data: PropertyData::Float(&v) },
    ];
    let comments: Vec<&str> = comments.iter().map(String::as_str).collect();
    ply::write(path, &level.mesh, &properties, &comments)
}

/// A surface map read back from a PLY written by [`write_surface_ply`].
pub struct SurfaceMap {
    pub mesh: Mesh,
    pub frames: Frames,
    pub state: State,
    /// Texel size in model units (from the header).
    pub texel: f32,
    /// The header's `comment` lines.
    pub comments: Vec<String>,
}

/// Reads a surface map: the vertex properties by name, faces as triangles.
pub fn read_surface_ply(path: &Path) -> Result<SurfaceMap> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let bad = |m: &str| Error::format(path, format!("not a btfsynth surface map: {m}"));
    let end = bytes.windows(11).position(|w| w == b"end_header\n").ok_or_else(|| bad("no PLY header"))?;
    let header = String::from_utf8_lossy(&bytes[..end]).into_owned();
    let comments: Vec<String> =
        header.lines().filter_map(|l| l.strip_prefix("comment ")).map(str::to_string).collect();
    if !comments.iter().any(|c| c == "btfsynth surface") || !header.contains("binary_little_endian") {
        return Err(bad("no 'comment btfsynth surface' in a binary little-endian header"));
    }
    let count = |name: &str| {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {name} ")))
            .and_then(|n| n.trim().parse::<usize>().ok())
    };
    let (vertices, faces) =
        (count("vertex").ok_or_else(|| bad("no vertices"))?, count("face").ok_or_else(|| bad("no faces"))?);
    let names: Vec<&str> = header
        .lines()
        .skip_while(|l| !l.starts_with("element vertex"))
        .skip(1)
        .take_while(|l| l.starts_with("property") && !l.contains(" list "))
        .filter_map(|l| l.split_whitespace().nth(2))
        .collect();
    let stride = 4 * names.len();
    let body = &bytes[end + 11..];
    if body.len() < vertices * stride {
        return Err(bad("truncated vertex data"));
    }
    let column = |name: &str| -> Result<Vec<[u8; 4]>> {
        let k = names
            .iter()
            .position(|n| *n == name)
            .ok_or_else(|| bad(&format!("no vertex property {name}")))?;
        Ok((0..vertices)
            .map(|v| {
                let o = v * stride + 4 * k;
                [body[o], body[o + 1], body[o + 2], body[o + 3]]
            })
            .collect())
    };
    let float =
        |name: &str| -> Result<Vec<f32>> { Ok(column(name)?.into_iter().map(f32::from_le_bytes).collect()) };
    let (x, y, z) = (float("x")?, float("y")?, float("z")?);
    let (sx, sy, sz) = (float("sx")?, float("sy")?, float("sz")?);
    let labels: Vec<u16> =
        column("texton")?.into_iter().map(|b| u32::from_le_bytes(b).min(u16::MAX as u32) as u16).collect();
    let (u, v) = (float("u")?, float("v")?);
    let triangles =
        read_triangles(&body[vertices * stride..], faces).ok_or_else(|| bad("faces are not triangles"))?;
    let positions = (0..vertices).map(|i| glam::Vec3::new(x[i], y[i], z[i])).collect();
    let mesh = Mesh::new(positions, triangles)?.with_normals();
    let directions: Vec<glam::Vec3> = (0..vertices).map(|i| glam::Vec3::new(sx[i], sy[i], sz[i])).collect();
    let frames = Frames::from_directions(mesh.normals().unwrap_or(&[]), &directions);
    if mesh.vertex_count() != vertices {
        return Err(bad("the mesh changed on reading (non-manifold or degenerate faces)"));
    }
    let texel = comments
        .iter()
        .find_map(|c| c.strip_prefix("texel "))
        .and_then(|t| t.trim().parse::<f32>().ok())
        .ok_or_else(|| bad("no texel comment"))?;
    let uv = u.iter().zip(&v).map(|(&a, &b)| [a.round() as i32, b.round() as i32]).collect();
    Ok(SurfaceMap { mesh, frames, state: State { labels, uv }, texel, comments })
}

/// `faces` triangles written as `uchar 3, int a, int b, int c`.
fn read_triangles(body: &[u8], faces: usize) -> Option<Vec<[u32; 3]>> {
    (0..faces)
        .map(|f| {
            let o = f * 13;
            let record = body.get(o..o + 13)?;
            let index = |k: usize| {
                u32::from_le_bytes([
                    record[1 + 4 * k],
                    record[2 + 4 * k],
                    record[3 + 4 * k],
                    record[4 + 4 * k],
                ])
            };
            (record[0] == 3).then(|| [index(0), index(1), index(2)])
        })
        .collect()
}
