//! Surface mode: a surface texton map on a triangle mesh (Tong §5). The mesh is remeshed so
//! that one edge is one sample texel on the finest level and twice as long on each coarser
//! level (the coarsest remeshed from the input, each finer one refining the one above, with
//! four times its vertices); every level gets tangent frames, templates and forward shifts,
//! finer levels are linked to coarser ones, and the engine runs coarse to fine. Output: a
//! binary PLY of the finest mesh.

use super::engine::State;
use super::pyramid_cache::{
    refine_key, remesh_key, remeshed, templates, templates_key, LevelFit, LevelShape, MeshFit,
};
use super::round::{MarchedLevel, MarchingCache};
use super::surface::{link_levels, narrowed, surface_level};
use super::target::TargetLevel;
use super::{synthesize, LevelReport, Sample, SynthParams};
use crate::analysis::knn::parent_size;
use crate::cache::{CacheDir, Source};
use crate::mesh::field::{frames, Orientation};
use crate::mesh::frames::Frames;
use crate::mesh::ply::{self, PropertyData, VertexProperty};
use crate::mesh::remesh::{edge_length_stats, refine, remesh, EdgeLengthStats, RemeshParams};
use crate::mesh::Mesh;
use crate::progress::{Progress, Silent};
use crate::{Error, Result};
use std::path::{Path, PathBuf};
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
            return Err(Error::invalid(format!("{self} gives no usable texel size")));
        }
        Ok(texel)
    }
}

impl std::fmt::Display for Density {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match *self {
            Density::Scale(s) => write!(f, "a scale of {s} texels per model unit"),
            Density::TexelsAcross(n) => write!(f, "{n} texels across the mesh"),
            Density::Vertices(n) => write!(f, "{n} vertices"),
        }
    }
}

/// One level of the synthesis mesh pyramid.
pub struct MeshLevel {
    /// The level's remeshed surface.
    pub mesh: Mesh,
    /// One tangent frame per vertex.
    pub frames: Frames,
    /// Size of one sample texel on this level in model units (also the remeshing's target
    /// edge length).
    pub texel: f32,
    /// Edge lengths of the remeshed surface.
    pub edges: EdgeLengthStats,
}

impl MeshLevel {
    /// What the level's templates are flattened from.
    pub fn shape(&self) -> LevelShape<'_> {
        LevelShape { mesh: &self.mesh, frames: &self.frames, texel: self.texel }
    }
}

/// The synthesis meshes, finest first, with their engine-side levels.
pub struct SurfacePyramid {
    /// The meshes, finest first.
    pub levels: Vec<MeshLevel>,
    /// The engine's levels, one per mesh level, finest first.
    pub targets: Vec<TargetLevel>,
    /// Seconds spent remeshing, framing and building templates, each summed over the
    /// levels; the coarser levels' stages run beside the finest level's remeshing, so the
    /// three may add up to more than the time the pyramid took.
    pub seconds: [f64; 3],
    /// Per level, where its remeshing and its templates came from (computed, or read from
    /// a cache).
    pub sources: Vec<[Source; 2]>,
}

/// Refuses finest meshes beyond this many vertices (about 14 GB at synthesis' peak).
pub const MAX_VERTICES: usize = 3_000_000;

/// What one vertex of the finest mesh costs at synthesis' peak, with the coarser levels,
/// their templates and the engine's state, at the default 7×7 neighbourhood: measured
/// 1.07 GiB for 250,000 vertices (bunny-37k.off from the full 400² × 22,801-image
/// analysis, `benches/big_btf.sh`, its `use` step) and 1.11 GB from a 64² BTF (`benches/speed.sh`).
pub const BYTES_PER_VERTEX: u64 = 4_600;

/// Refuses a finest mesh of about `vertices` whose synthesis would not fit the memory
/// budget ([`crate::btf::source::memory_budget`]), before any remeshing.
fn check_memory(vertices: f64) -> Result<()> {
    use crate::analysis::memory::gib;
    let need = (vertices * BYTES_PER_VERTEX as f64) as u64;
    match crate::btf::source::memory_budget()? {
        Some((limit, source)) if need > limit => Err(Error::too_large(
            format!(
                "that density needs about {vertices:.0} vertices, about {} at synthesis' peak, more than the {} budget ({source})",
                gib(need),
                gib(limit)
            ),
            crate::Remedy::LowerDensity,
        )),
        _ => Ok(()),
    }
}

/// Remeshes `mesh` into `levels` levels and builds every level's templates and links.
pub fn build_pyramid(
    mesh: &Mesh,
    density: Density,
    levels: usize,
    orientation: &Orientation,
    params: &SynthParams,
    progress: &dyn Progress,
) -> Result<SurfacePyramid> {
    build_pyramid_cached(mesh, density, levels, orientation, params, None, progress)
}

/// As [`build_pyramid`], reading and storing in `cache` each level's remeshing, templates
/// and links ([`super::pyramid_cache`]) and, for presets with round neighbourhoods, its
/// marching ([`super::round::MarchingCache`]).
pub fn build_pyramid_cached(
    mesh: &Mesh,
    density: Density,
    levels: usize,
    orientation: &Orientation,
    params: &SynthParams,
    cache: Option<&CacheDir>,
    progress: &dyn Progress,
) -> Result<SurfacePyramid> {
    if levels == 0 {
        return Err(Error::invalid("a surface pyramid needs at least one level"));
    }
    let texel = density.texel(mesh)?;
    let estimate = mesh.surface_area() / (3f64.sqrt() / 2.0 * (texel as f64).powi(2));
    if estimate > MAX_VERTICES as f64 {
        return Err(Error::too_large(
            format!("that density needs about {estimate:.0} vertices (the limit is {MAX_VERTICES})"),
            crate::Remedy::LowerDensity,
        ));
    }
    check_memory(estimate)?;
    let input = PyramidInput { mesh, density, texel, orientation, params, cache };
    // Only the coarsest level is remeshed from the input; each finer one refines the level
    // above it. The finest, four times the next, takes most of the time, so the coarser
    // levels get their templates on the other core meanwhile (without a progress bar of
    // their own: they end first).
    let mut coarser = input.coarser_meshes(levels)?;
    // A copy, as the templates are added to the levels beside the refinement.
    let above = coarser.first().map(|b| b.level.mesh.clone());
    let finest = match &above {
        Some(above) => {
            let (finest, templates) = rayon::join(
                || input.level(0, Some(above), progress),
                || (0..coarser.len()).rev().try_for_each(|l| input.add_templates(&mut coarser, l)),
            );
            templates?;
            finest?
        }
        None => input.level(0, None, progress)?,
    };
    let mut built = vec![finest];
    built.extend(coarser);
    input.add_templates(&mut built, 0)?;
    let mut seconds = [0.0; 3];
    for b in &built {
        (0..3).for_each(|k| seconds[k] += b.seconds[k]);
    }
    let sources = built.iter().map(|b| b.sources).collect();
    let (meshes, mut targets): (Vec<MeshLevel>, Vec<TargetLevel>) =
        built.into_iter().map(|b| (b.level, b.target.expect("every level has its templates"))).unzip();
    let started = Instant::now();
    if params.preset.rounds() {
        // The expensive part of round neighbourhoods, once per level (Chen-Dong §4).
        let marchings = cache.map(|dir| MarchingCache::in_dir(dir.clone()));
        for (target, m) in targets.iter_mut().zip(&meshes) {
            let stencil = params.preset.round_stencil().expect("rounds() found one");
            let marched = MarchedLevel::with_cache(&m.mesh, &m.frames, m.texel, stencil, marchings.as_ref());
            target.round = Some(marched?);
        }
    }
    seconds[2] += started.elapsed().as_secs_f64();
    Ok(SurfacePyramid { levels: meshes, targets, seconds, sources })
}

/// What every level of one pyramid is built from.
struct PyramidInput<'a> {
    mesh: &'a Mesh,
    density: Density,
    /// The finest level's texel; each coarser level's is twice the one below.
    texel: f32,
    orientation: &'a Orientation,
    params: &'a SynthParams,
    cache: Option<&'a CacheDir>,
}

/// One level while the pyramid is built.
struct BuiltLevel {
    level: MeshLevel,
    /// Its templates, once built.
    target: Option<TargetLevel>,
    /// Where its remeshing and its templates came from.
    sources: [Source; 2],
    /// Seconds remeshing, framing and building its templates took.
    seconds: [f64; 3],
}

impl PyramidInput<'_> {
    /// Level `l` with its frames: the level `above` it refined, or at the coarsest level the
    /// input remeshed.
    fn level(&self, l: usize, above: Option<&Mesh>, progress: &dyn Progress) -> Result<BuiltLevel> {
        let started = Instant::now();
        let edge = self.texel * (1 << l) as f32;
        let (remeshed, source) = match above {
            Some(above) => {
                // Half the edge of the level above: four times its vertices (3.93 to 4.02
                // measured on the bunny's levels).
                let fit = MeshFit { reference: self.mesh, edge, vertices: Some(4 * above.vertex_count()) };
                let key = (refine_key(self.mesh, above, edge), fit);
                remeshed(self.cache, key, || refine(above, self.mesh, edge, progress))?
            }
            None => {
                // A vertex budget is steered towards as the remesher runs; a scale is a length.
                let target = match self.density {
                    Density::Vertices(n) => RemeshParams::vertex_count(self.mesh, (n >> (2 * l)).max(4)),
                    _ => RemeshParams::edge_length(edge),
                };
                let fit = MeshFit {
                    reference: self.mesh,
                    edge: target.target_edge_length,
                    vertices: target.vertex_count,
                };
                remeshed(self.cache, (remesh_key(self.mesh, &target), fit), || {
                    remesh(self.mesh, &target, progress)
                })?
            }
        };
        let remeshed = remeshed.with_normals();
        let remesh_seconds = started.elapsed().as_secs_f64();
        let started = Instant::now();
        let level_frames = frames(&remeshed, self.orientation, self.params.seed)?;
        let frames_seconds = started.elapsed().as_secs_f64();
        let edges = edge_length_stats(&remeshed);
        Ok(BuiltLevel {
            level: MeshLevel { mesh: remeshed, frames: level_frames, texel: edge, edges },
            target: None,
            sources: [source, Source::Computed],
            seconds: [remesh_seconds, frames_seconds, 0.0],
        })
    }

    /// Levels 1 to `levels − 1` (finest first) with their frames: the coarsest remeshed
    /// from the input, each finer one refining the one above.
    fn coarser_meshes(&self, levels: usize) -> Result<Vec<BuiltLevel>> {
        let mut built: Vec<BuiltLevel> = Vec::new();
        for l in (1..levels).rev() {
            let level = self.level(l, built.last().map(|b| &b.level.mesh), &Silent)?;
            built.push(level);
        }
        built.reverse();
        Ok(built)
    }

    /// Gives `built[l]` its templates (the level after it is the next coarser, if any, and
    /// has its own already).
    fn add_templates(&self, built: &mut [BuiltLevel], l: usize) -> Result<()> {
        let started = Instant::now();
        let coarse =
            built.get(l + 1).map(|b| (&b.level, b.target.as_ref().expect("coarser levels come first")));
        let (target, source) = self.templates(&built[l].level, coarse)?;
        built[l].seconds[2] = started.elapsed().as_secs_f64();
        built[l].target = Some(target);
        built[l].sources[1] = source;
        Ok(())
    }

    /// The templates of level `fine` and, below the coarsest level, its links to `coarse`
    /// and its parent templates (narrowed from the coarse level's own), through the cache
    /// where one is given.
    fn templates(
        &self,
        fine: &MeshLevel,
        coarse: Option<(&MeshLevel, &TargetLevel)>,
    ) -> Result<(TargetLevel, Source)> {
        let template = self.params.neighborhood;
        let parent_template = parent_size(template);
        let key = templates_key(fine.shape(), template, coarse.map(|(c, _)| (c.shape(), parent_template)));
        let fit = LevelFit {
            vertices: fine.mesh.vertex_count(),
            template,
            coarse: coarse.map(|(c, _)| (c.mesh.vertex_count(), parent_template)),
        };
        templates(self.cache, (key, fit), || {
            let mut target = surface_level(&fine.mesh, &fine.frames, fine.texel, template)?;
            if let Some((c, coarse_own)) = coarse {
                let coarse_templates = narrowed(coarse_own, parent_template)?;
                link_levels(
                    &fine.mesh,
                    &fine.frames,
                    &mut target,
                    &c.mesh,
                    &c.frames,
                    coarse_templates,
                    fine.texel,
                )?;
            }
            Ok(target)
        })
    }
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

/// The first header comment of a surface map.
pub const SURFACE_COMMENT: &str = "btfsynth surface";
/// Header key of the analysis directory, relative to the surface map's own directory.
pub const ANALYSIS_KEY: &str = "analysis";
/// Header key of the analysis directory's absolute path (used if the relative one fails).
pub const ANALYSIS_ABSOLUTE_KEY: &str = "analysis-absolute";
/// Header key of the analysed sample's fingerprint (see [`crate::analysis::store::fingerprint`]).
pub const ANALYSIS_FINGERPRINT_KEY: &str = "analysis-fingerprint";

/// Writes the finest level with its map as a binary PLY: position, normal, frame direction
/// s (`sx sy sz`), `texton`, `u`, `v` (sample texels, with the place within the texel where
/// the synthesis knows it: [`State::subtexel`]); the header comments record the
/// analysis (relative to the PLY, absolute, and its fingerprint), the mesh, the texel size
/// and `params` (which must hold no timings: equal inputs give equal bytes).
pub fn write_surface_ply(
    path: &Path,
    level: &MeshLevel,
    state: &State,
    (analysis, mesh): (&Path, &Path),
    params: &serde_json::Value,
) -> Result<()> {
    let mut comments = vec![SURFACE_COMMENT.to_string()];
    comments.extend(input_comments(analysis, mesh, path));
    comments.extend([format!("texel {}", level.texel), format!("params {params}")]);
    let component = |c: usize| level.frames.s.iter().map(|s| s[c]).collect::<Vec<f32>>();
    let (sx, sy, sz) = (component(0), component(1), component(2));
    let texton: Vec<u32> = state.labels.iter().map(|&l| l as u32).collect();
    let (u, v): (Vec<f32>, Vec<f32>) = (0..state.uv.len()).map(|k| state.coordinate(k).into()).unzip();
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

/// Header key of the original mesh, as it was given.
pub const MESH_KEY: &str = "mesh";
/// Header key of the original mesh's absolute path.
pub const MESH_ABSOLUTE_KEY: &str = "mesh_absolute";

/// The header comments that name a result's inputs: the analysis relative to the result
/// `output` and absolute, and its fingerprint; the mesh as given and absolute. Paths are
/// written by [`escape_path`], so that any name comes back whole ([`comment_paths`]).
pub(crate) fn input_comments(analysis: &Path, mesh: &Path, output: &Path) -> Vec<String> {
    let (relative, absolute) = analysis_paths(analysis, output);
    let mut comments = vec![format!("{ANALYSIS_KEY} {}", escape_path(&relative))];
    if let Some(absolute) = absolute {
        comments.push(format!("{ANALYSIS_ABSOLUTE_KEY} {}", escape_path(&absolute)));
    }
    if let Ok(manifest) = crate::analysis::store::read_manifest(analysis) {
        comments.push(format!("{ANALYSIS_FINGERPRINT_KEY} {}", manifest.source.fingerprint));
    }
    let mesh_absolute = std::path::absolute(mesh).unwrap_or_else(|_| mesh.to_path_buf());
    comments.push(format!("{MESH_KEY} {}", escape_path(mesh)));
    comments.push(format!("{MESH_ABSOLUTE_KEY} {}", escape_path(&mesh_absolute)));
    comments
}

/// `path` as a header comment holds it: its characters, with `%`, control characters
/// (line breaks included), bytes that are not UTF-8 and white space at either end (which
/// readers trim) written as `%XX` per byte. Every name comes back whole through
/// [`comment_paths`]; an ordinary one reads as it is.
pub fn escape_path(path: &Path) -> String {
    use std::os::unix::ffi::OsStrExt;
    // Each character's bytes, or a byte that is no character, and whether to escape it.
    let mut pieces: Vec<(&[u8], bool)> = Vec::new();
    for chunk in path.as_os_str().as_bytes().utf8_chunks() {
        let valid = chunk.valid();
        for (at, c) in valid.char_indices() {
            pieces.push((&valid.as_bytes()[at..at + c.len_utf8()], c == '%' || c.is_control()));
        }
        pieces.extend(chunk.invalid().iter().map(|b| (std::slice::from_ref(b), true)));
    }
    let blank =
        |p: &&mut (&[u8], bool)| std::str::from_utf8(p.0).is_ok_and(|c| c.chars().all(char::is_whitespace));
    pieces.iter_mut().take_while(blank).for_each(|p| p.1 = true);
    pieces.iter_mut().rev().take_while(blank).for_each(|p| p.1 = true);
    let mut out = String::new();
    for (bytes, escape) in pieces {
        match escape {
            true => bytes.iter().for_each(|b| out.push_str(&format!("%{b:02X}"))),
            false => out.push_str(&String::from_utf8_lossy(bytes)),
        }
    }
    out
}

/// The paths a header comment's `value` may name, most likely first: [`escape_path`]'s
/// form decoded, then the value as written if that differs (a map written before paths were
/// escaped holds them raw, and a raw name may hold a `%`).
pub fn comment_paths(value: &str) -> Vec<PathBuf> {
    use std::os::unix::ffi::OsStringExt;
    let bytes = value.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = bytes.get(i + 1..i + 3).and_then(|h| std::str::from_utf8(h).ok());
        match hex.filter(|_| bytes[i] == b'%').and_then(|h| u8::from_str_radix(h, 16).ok()) {
            Some(b) => {
                decoded.push(b);
                i += 3;
            }
            None => {
                decoded.push(bytes[i]);
                i += 1;
            }
        }
    }
    let decoded = PathBuf::from(std::ffi::OsString::from_vec(decoded));
    let raw = PathBuf::from(value);
    if decoded == raw {
        vec![decoded]
    } else {
        vec![decoded, raw]
    }
}

/// The analysis directory relative to the directory `ply` is written into (so the pair can
/// be moved together), and its absolute path (so the map can be moved alone). Falls back to
/// the path as given where the directories cannot be resolved.
pub(crate) fn analysis_paths(analysis: &Path, ply: &Path) -> (PathBuf, Option<PathBuf>) {
    let absolute = std::fs::canonicalize(analysis).ok();
    let ply_dir = match ply.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let relative = match (&absolute, std::fs::canonicalize(ply_dir)) {
        (Some(a), Ok(d)) => crate::fsutil::relative_path(a, &d),
        _ => analysis.to_path_buf(),
    };
    (relative, absolute)
}

/// A surface map read back from a PLY written by [`write_surface_ply`].
pub struct SurfaceMap {
    /// The mesh as stored.
    pub mesh: Mesh,
    /// One tangent frame per vertex, as stored.
    pub frames: Frames,
    /// Per vertex, the texton label and sample coordinate.
    pub state: State,
    /// Texel size in model units (from the header).
    pub texel: f32,
    /// The header's `comment` lines.
    pub comments: Vec<String>,
}

impl SurfaceMap {
    /// The surface map of a synthesis held in memory: `state` on the finest `level`, as
    /// [`read_surface_ply`] reads it back from [`write_surface_ply`]'s file (no comments).
    pub fn from_synthesis(level: &MeshLevel, state: &State) -> SurfaceMap {
        // The normals a reader recomputes, not the level's own, so both ways agree.
        let mesh = level.mesh.clone().with_normals();
        let frames = Frames::from_directions(mesh.normals().unwrap_or(&[]), &level.frames.s);
        SurfaceMap { mesh, frames, state: state.clone(), texel: level.texel, comments: Vec::new() }
    }

    /// The value of the header comment `KEY value`, if there is one.
    pub fn comment(&self, key: &str) -> Option<&str> {
        comment_value(&self.comments, key)
    }

    /// The analysis this map was synthesized from, for a map read from `ply`: the header's
    /// `analysis` path relative to the map's directory, else its absolute path, else the
    /// `analysis` path as written (maps written before both were recorded named it relative
    /// to the working directory) — the first that holds an `analysis.json`.
    pub fn find_analysis(&self, ply: &Path) -> Option<PathBuf> {
        find_analysis(&self.comments, ply)
    }
}

/// The value of the header comment `KEY value` among `comments`, if there is one.
pub fn comment_value<'a>(comments: &'a [String], key: &str) -> Option<&'a str> {
    comments.iter().find_map(|c| c.strip_prefix(key)?.strip_prefix(' ')).map(str::trim)
}

/// The analysis a result read from `ply` names in its `comments` (see
/// [`SurfaceMap::find_analysis`]; texture-mapped results record it the same way).
pub fn find_analysis(comments: &[String], ply: &Path) -> Option<PathBuf> {
    let named = |key: &str| comment_value(comments, key).map(comment_paths).unwrap_or_default();
    let written = named(ANALYSIS_KEY);
    let beside = written.iter().filter(|w| w.is_relative()).map(|w| match ply.parent() {
        Some(dir) => dir.join(w),
        None => w.clone(),
    });
    let beside: Vec<PathBuf> = beside.collect();
    beside
        .into_iter()
        .chain(named(ANALYSIS_ABSOLUTE_KEY))
        .chain(written)
        .find(|dir| dir.join(crate::analysis::store::MANIFEST).is_file())
}

/// Reads a surface map: the vertex properties by name, faces as triangles.
pub fn read_surface_ply(path: &Path) -> Result<SurfaceMap> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse_surface_ply(&bytes, path)
}

/// Vertex properties a surface map must have, all 4-byte scalars (`texton` an integer,
/// the others `float`).
const SURFACE_PROPERTIES: [&str; 9] = ["x", "y", "z", "sx", "sy", "sz", "texton", "u", "v"];

/// Sample coordinates beyond this many texels are damage, not a sample (and would
/// overflow the renderers' texel arithmetic).
const MAX_COORDINATE: f32 = (1 << 24) as f32;

/// Parses the bytes of a surface map read from `path` (named in errors). Every count is
/// checked against the bytes present before anything is allocated for it.
pub fn parse_surface_ply(bytes: &[u8], path: &Path) -> Result<SurfaceMap> {
    use crate::mesh::ply::{parse_header, Encoding, Property, Scalar};
    let bad = |m: &str| Error::format(path, format!("not a btfsynth surface map: {m}"));
    let header = parse_header(bytes).map_err(|m| bad(&m))?;
    if !header.comments.iter().any(|c| c == SURFACE_COMMENT)
        || header.encoding != Encoding::BinaryLittleEndian
    {
        return Err(bad("no 'comment btfsynth surface' in a binary little-endian header"));
    }
    let [vertex, face] = &header.elements[..] else {
        return Err(bad("expected a vertex and a face element"));
    };
    let triangle_list =
        Property::List { name: "vertex_indices".into(), count: Scalar::U8, item: Scalar::I32 };
    if vertex.name != "vertex" || face.name != "face" || face.properties != [triangle_list] {
        return Err(bad("expected vertices, then faces as 'list uchar int vertex_indices'"));
    }
    let mut names = Vec::with_capacity(vertex.properties.len());
    for p in &vertex.properties {
        match p {
            Property::Scalar { name, ty }
                if *ty == Scalar::F32 || (name == "texton" && ty.is_integer() && ty.size() == 4) =>
            {
                names.push(name.as_str())
            }
            _ => {
                return Err(bad(&format!(
                    "vertex property '{}' is not a float (or a 4-byte integer texton)",
                    p.name()
                )))
            }
        }
    }
    if let Some(missing) = SURFACE_PROPERTIES.iter().find(|n| !names.contains(n)) {
        return Err(bad(&format!("no vertex property {missing}")));
    }
    let body = &bytes[header.body_offset..];
    let stride = 4 * names.len();
    let vertex_bytes = vertex.count.checked_mul(stride).filter(|&n| n <= body.len());
    let vertex_bytes =
        vertex_bytes.ok_or_else(|| bad("the header declares more vertices than the file holds"))?;
    let faces = &body[vertex_bytes..];
    if face.count.checked_mul(13).is_none_or(|n| n > faces.len()) {
        return Err(bad("the header declares more faces than the file holds"));
    }
    let column = |name: &str| -> Vec<[u8; 4]> {
        let k = names.iter().position(|n| *n == name).unwrap_or(0);
        body[..vertex_bytes]
            .chunks_exact(stride)
            .map(|row| [row[4 * k], row[4 * k + 1], row[4 * k + 2], row[4 * k + 3]])
            .collect()
    };
    let float = |name: &str| -> Vec<f32> { column(name).into_iter().map(f32::from_le_bytes).collect() };
    let (x, y, z) = (float("x"), float("y"), float("z"));
    let (sx, sy, sz) = (float("sx"), float("sy"), float("sz"));
    let labels: Vec<u16> =
        column("texton").into_iter().map(|b| u32::from_le_bytes(b).min(u16::MAX as u32) as u16).collect();
    let (u, v) = (float("u"), float("v"));
    // A vertex copying texel 0 may lie up to half a texel before its centre (not a whole
    // half: that rounds to texel -1).
    let valid = |x: f32| x > -0.5 && x < MAX_COORDINATE;
    if let Some(i) = (0..u.len()).find(|&i| !valid(u[i]) || !valid(v[i])) {
        return Err(bad(&format!("vertex {i} has the sample coordinate ({}, {})", u[i], v[i])));
    }
    let triangles = read_triangles(faces, face.count).ok_or_else(|| bad("faces are not triangles"))?;
    let positions = (0..vertex.count).map(|i| glam::Vec3::new(x[i], y[i], z[i])).collect();
    let mesh = Mesh::new(positions, triangles).map_err(|e| bad(&e.to_string()))?.with_normals();
    if mesh.vertex_count() != vertex.count {
        return Err(bad("the mesh changed on reading (non-manifold or degenerate faces)"));
    }
    let directions: Vec<glam::Vec3> =
        (0..vertex.count).map(|i| glam::Vec3::new(sx[i], sy[i], sz[i])).collect();
    let frames = Frames::from_directions(mesh.normals().unwrap_or(&[]), &directions);
    let comments = header.comments;
    let texel = comments
        .iter()
        .find_map(|c| c.strip_prefix("texel "))
        .and_then(|t| t.trim().parse::<f32>().ok())
        .filter(|t| t.is_finite() && *t > 0.0)
        .ok_or_else(|| bad("no positive 'texel' comment"))?;
    Ok(SurfaceMap { mesh, frames, state: coordinates_state(labels, &u, &v), texel, comments })
}

/// The state of coordinates `u`, `v` as written: each rounded to its texel, and where any
/// lies between texels, every vertex's place within its texel.
fn coordinates_state(labels: Vec<u16>, u: &[f32], v: &[f32]) -> State {
    let uv: Vec<[i32; 2]> = u.iter().zip(v).map(|(&a, &b)| [a.round() as i32, b.round() as i32]).collect();
    let mut state = State::new(labels, uv);
    let within = |k: usize| [u[k] - state.uv[k][0] as f32, v[k] - state.uv[k][1] as f32];
    if (0..u.len()).any(|k| within(k) != [0.0; 2]) {
        state.subtexel = (0..u.len()).map(within).collect();
    }
    state
}

/// `faces` triangles written as `uchar 3, int a, int b, int c`; negative indices are left
/// to the mesh validation as out of range.
fn read_triangles(body: &[u8], faces: usize) -> Option<Vec<[u32; 3]>> {
    body.chunks_exact(13)
        .take(faces)
        .map(|record| {
            let index = |k: usize| {
                i32::from_le_bytes([
                    record[1 + 4 * k],
                    record[2 + 4 * k],
                    record[3 + 4 * k],
                    record[4 + 4 * k],
                ])
            };
            let corners = [index(0), index(1), index(2)];
            (record[0] == 3).then(|| corners.map(|i| u32::try_from(i).unwrap_or(u32::MAX)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::ffi::OsStrExt;

    /// Every name a file system takes comes back whole through a header comment, and an
    /// ordinary one is written as it is.
    #[test]
    fn paths_round_trip_through_header_comments() {
        let names: [&[u8]; 8] = [
            b"an sp ",
            b" lead",
            b"two\nlines",
            b"tab\tand\rreturn",
            b"latin1 \xe9t\xe9",
            b"50% done",
            "caf\u{e9} \u{a0}".as_bytes(),
            b"plain/dir.analysis",
        ];
        for name in names {
            let path = Path::new(std::ffi::OsStr::from_bytes(name));
            let escaped = escape_path(path);
            assert!(!escaped.contains(['\n', '\r']) && escaped.trim() == escaped, "{escaped:?}");
            // A header line is trimmed and read as UTF-8 text, losing nothing now.
            let comment = format!("{ANALYSIS_KEY} {escaped}");
            let read = comment_value(std::slice::from_ref(&comment), ANALYSIS_KEY).expect("a value");
            assert_eq!(comment_paths(read)[0], path, "{escaped:?}");
        }
        assert_eq!(escape_path(Path::new("plain/dir.analysis")), "plain/dir.analysis");
        // A map written before paths were escaped named them raw: tried too.
        assert_eq!(comment_paths("50%25 done"), [PathBuf::from("50% done"), PathBuf::from("50%25 done")]);
    }

    /// Coordinates written between texels come back as the texel and the place within
    /// it, to the bit; whole ones come back as whole texels with no places.
    #[test]
    fn places_within_texels_come_back_as_written() {
        let (u, v) = ([0.0, 3.49, 7.0, 12.51, -0.49], [2.0, 0.3, 5.0, 9.5, 4.0]);
        let state = coordinates_state(vec![0; 5], &u, &v);
        assert_eq!(state.uv, [[0, 2], [3, 0], [7, 5], [13, 10], [0, 4]]);
        for k in 0..5 {
            assert_eq!(state.coordinate(k), [u[k], v[k]], "vertex {k}");
        }
        let whole = coordinates_state(vec![0; 2], &[1.0, 2.0], &[3.0, 4.0]);
        assert!(whole.subtexel.is_empty());
        assert_eq!(whole.coordinate(1), [2.0, 4.0]);
    }

    /// A map whose vertex lies half a texel or more before texel 0 is refused (it would
    /// name texel −1); one just short of that is read.
    #[test]
    fn a_place_before_the_first_texel_is_refused() {
        let (mesh, frames) = crate::synth::surface::tests::flat_grid(3, 3, 0.1);
        let level = MeshLevel { edges: edge_length_stats(&mesh), mesh, frames, texel: 0.1 };
        let dir = tempfile::tempdir().expect("tempdir");
        let ply = dir.path().join("map.ply");
        let written = |first: f32| {
            let mut state = State::new(vec![0; 9], vec![[1, 1]; 9]);
            state.uv[0] = [0, 0];
            state.subtexel = vec![[0.0; 2]; 9];
            state.subtexel[0] = [first, 0.25];
            let (analysis, mesh) = (Path::new("an"), Path::new("grid.obj"));
            write_surface_ply(&ply, &level, &state, (analysis, mesh), &serde_json::json!({}))
                .expect("writes");
            read_surface_ply(&ply)
        };
        let read = written(-0.49).expect("a place within the texel");
        assert_eq!((read.state.uv[0], read.state.coordinate(0)), ([0, 0], [-0.49, 0.25]));
        let refused = written(-0.5).err().expect("refused").to_string();
        assert!(refused.contains("sample coordinate (-0.5, 0.25)"), "{refused}");
    }
}
