//! Hierarchical pattern mapping (Soler, Cani and Angelidis, *Hierarchical Pattern Mapping*,
//! SIGGRAPH 2002): texture coordinates into the sample itself, at the corners of the user's
//! own mesh. Nothing is remeshed and no texture is made: patches of the sample, of many
//! sizes and orientations, are placed on the surface from coarse to fine so that each
//! matches its textured neighbours.
//!
//! - [`graph`]: the file's triangles joined where their corners coincide; non-manifold
//!   input is refused.
//! - [`hierarchy`]: the face-cluster hierarchy (§3.1), discs down to single faces.
//! - [`chart`]: control polygons and recursive barycentric coordinates (§3.2, Eq. 1),
//!   finished by a near-isometric flattening of each cluster's faces (`arap`).
//! - [`fit`]: mask fitting by FFT correlation over rotations of the sample (§4.2).
//! - [`mapping`]: the coarse-to-fine priority queue (§2.2) and the masks (§4.1);
//!   [`relax`]: the relaxation along borders (§4.4); once every face is mapped, `cut`: the
//!   minimum-error cut through a band of faces along each border between two patches, and
//!   `borders`: border faces moved to the neighbouring patch whose texture they continue
//!   better.
//! - [`output`]: the result as a PLY (or OBJ) with per-corner texture coordinates, and
//!   reading it back for `render` and `export`.
//!
//! ```no_run
//! use btfsynth::synth::patches::{self, fit::{ColourSpace, FitImage}, SolerParams};
//! use btfsynth::mesh::textured::load_textured;
//! use std::path::Path;
//!
//! let path = Path::new("bunny.obj");
//! let mesh = load_textured(path)?;
//! let photo = image::open("pebbles.png").unwrap().to_rgb32f();
//! let (w, h) = photo.dimensions();
//! let sample = FitImage::from_rgb(w as usize, h as usize, |x, y| photo.get_pixel(x as u32, y as u32).0, ColourSpace::Lab, false)?;
//! let params = SolerParams { texels_per_unit: 400.0, ..SolerParams::default() };
//! let result = patches::map_mesh(&mesh.positions, &mesh.triangles, path, sample, &params, &btfsynth::progress::Silent)?;
//! println!("{} faces mapped, {} levels", result.corner_uv.len(), result.report.levels.len());
//! # Ok::<(), btfsynth::Error>(())
//! ```

mod arap;
mod borders;
pub mod chart;
mod cut;
pub mod fit;
pub mod graph;
pub mod hierarchy;
pub mod mapper;
pub mod mapping;
pub mod output;
pub mod prepare;
pub mod quality;
pub mod relax;

use crate::progress::Progress;
use crate::{Error, Param, Result};
use fit::{ColourSpace, FitImage, Fitter};
use glam::{Vec2, Vec3};
use graph::{SurfaceGraph, NONE};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;
use std::time::Instant;

/// The method's parameters.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SolerParams {
    /// Sample texels per model unit: the texture's size on the surface (no default that fits
    /// every mesh; the CLI derives one from the mesh's size).
    pub texels_per_unit: f32,
    /// Rotations of the sample tried per fit (default 19, the paper's).
    pub rotations: usize,
    /// Width of the mask's band along textured borders, in texels (default 6). Wider bands
    /// carry a pattern's orientation further (the paper widens them for anisotropic ones)
    /// and cost nothing extra per fit.
    pub band: f32,
    /// Largest flattening error |r − 1| a cluster may have and be mapped as one patch
    /// (default 0.1: about 10% more area on the surface than in the sample).
    pub max_flat_error: f32,
    /// Largest output error a cluster may have and be mapped as one patch (§4.4): the mean
    /// squared difference along its shared edges with textured neighbours once placed and
    /// relaxed, as a fraction of two random texels' (default 0.3). Lower: more, smaller
    /// patches with fainter seams; higher: larger patches, more visible seams.
    pub max_fit_error: f32,
    /// The colour space masks are compared in (default L*a*b*; the paper's is HSV).
    pub colour: ColourSpace,
    /// Relax the coordinates along textured borders after each fit (§4.4; default on).
    pub relax: bool,
    /// Once every face is mapped, cut each pair of neighbouring patches where their
    /// textures, continued over a band of faces either side of their border, differ least,
    /// then move single border faces to the patch across an edge wherever its texture,
    /// continued over them, lowers the jump along their edges (default on). Borders then
    /// run where the patches' textures agree.
    pub move_borders: bool,
    /// Match each patch to its neighbours (default on). Off, every patch is placed at
    /// random where it fits: the baseline that measures what matching buys.
    pub matching: bool,
    /// Seed of every random choice (default 0).
    pub seed: u64,
    /// The file face the first patch must hold (§5: the user may choose it); by default
    /// the flattest cluster of the coarsest level that has a flat enough one.
    pub first_face: Option<usize>,
    /// The orientation of the first patch of each piece of surface (§5), in degrees: the
    /// sample's up (decreasing rows) points this far counter-clockwise, seen from outside,
    /// from the model's +Y axis as it lies on the patch (+X where the patch faces along Y).
    /// By default a random angle.
    pub orientation: Option<f32>,
}

impl Default for SolerParams {
    fn default() -> Self {
        SolerParams {
            texels_per_unit: 100.0,
            rotations: 19,
            band: 6.0,
            max_flat_error: 0.1,
            max_fit_error: 0.3,
            colour: ColourSpace::Lab,
            relax: true,
            move_borders: true,
            matching: true,
            seed: 0,
            first_face: None,
            orientation: None,
        }
    }
}

impl SolerParams {
    /// Checks every field.
    pub fn validate(&self) -> Result<()> {
        let positive = |v: f32| v.is_finite() && v > 0.0;
        if !positive(self.texels_per_unit) {
            return Err(Error::out_of_range(crate::Param::Scale, self.texels_per_unit, "must be positive"));
        }
        if !(1..=90).contains(&self.rotations) {
            return Err(Error::out_of_range(crate::Param::Rotations, self.rotations, "between 1 and 90"));
        }
        if !positive(self.band) || self.band > 64.0 {
            return Err(Error::out_of_range(crate::Param::Band, self.band, "between 0 and 64 texels"));
        }
        if !positive(self.max_flat_error) {
            return Err(Error::out_of_range(Param::MaxDistortion, self.max_flat_error, "must be positive"));
        }
        if !positive(self.max_fit_error) {
            return Err(Error::out_of_range(Param::FitThreshold, self.max_fit_error, "must be positive"));
        }
        if self.orientation.is_some_and(|d| !d.is_finite()) {
            return Err(Error::out_of_range(Param::PatchOrientation, "", "a finite angle in degrees"));
        }
        Ok(())
    }
}

/// The most texels a mapped texture may cover on the surface (its area × texels per unit²):
/// 2²⁶, as many as the largest plane (8192²). The mapping's time grows with it (the bundled
/// bunny: 0.15 M texels at the default 4 × the sample's width across, 2.1 s; 9.3 M, 14.6 s),
/// and so do its single faces' masks: 10⁶ texels per unit asked a terabyte for one.
pub const MAX_SURFACE_TEXELS: f64 = (1u64 << 26) as f64;

/// The largest coordinate a mapped mesh may have: the mapping squares lengths in single
/// precision, which holds squares up to 3.4·10³⁸ (the bunny scaled by 10²⁰ came out as NaN
/// texture coordinates; by 10¹⁹, whole).
pub const MAX_COORDINATE: f32 = 1e18;

/// Refuses, before any work, what the mapping of a `sample` (width, height, channels) onto
/// `triangles` over `positions` (a file's, named `path` in errors) cannot do. The file's
/// fault ([`Error::Format`]): a corner beyond [`MAX_COORDINATE`], or no face with an area at
/// all. The scale's: more than [`MAX_SURFACE_TEXELS`] on the surface ([`Param::Scale`]), or
/// a peak beyond the memory budget ([`Error::TooLarge`], see
/// [`crate::analysis::memory::budget`]).
pub fn check_size(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    path: &Path,
    params: &SolerParams,
    (width, height, channels): (usize, usize, usize),
) -> Result<()> {
    params.validate()?;
    let (mut area, mut widest) = (0f64, 0f64);
    for (f, t) in triangles.iter().enumerate() {
        let corner = |k: usize| {
            positions.get(t[k] as usize).copied().ok_or_else(|| {
                Error::invalid(format!("{}: face {f} names vertex {}, past the mesh's", path.display(), t[k]))
            })
        };
        let corners = [corner(0)?, corner(1)?, corner(2)?];
        if let Some(far) =
            corners.iter().map(|p| p.abs().max_element()).find(|&c| c.is_nan() || c > MAX_COORDINATE)
        {
            return Err(Error::format(
                path,
                format!(
                    "face {f} has a corner {far:e} from the origin, beyond the {MAX_COORDINATE:e} whose square \
                     single precision holds; scale the mesh down"
                ),
            ));
        }
        let [a, b, c] = corners.map(|p| p.as_dvec3());
        area += (b - a).cross(c - a).length() / 2.0;
        widest = widest.max(b.distance(a).max(c.distance(b)).max(a.distance(c)));
    }
    if area == 0.0 {
        return Err(Error::format(path, "no face has an area (are all its vertices at one point?)"));
    }
    let scale = f64::from(params.texels_per_unit);
    let texels = area * scale * scale;
    if texels.is_nan() || texels > MAX_SURFACE_TEXELS {
        let value = params.texels_per_unit;
        return Err(Error::out_of_range(
            Param::Scale,
            if value < 1e6 { value.to_string() } else { format!("{value:e}") },
            format!(
                "puts {texels:.2e} texels on the surface of {}, more than 2^26 (8192²); lower it",
                path.display()
            ),
        ));
    }
    // The sample's transforms at every rotation (complex halves of frames up to twice its
    // side), and the largest mask: a cluster's spans at most the sample's diagonal, a single
    // face's its own width, each with the band around it.
    let (w, h, channels) = (width as f64, height as f64, channels as f64);
    let frame = 2.0 * w.max(h);
    let transforms = params.rotations as f64 * (channels + 1.0) * frame * (frame / 2.0 + 1.0) * 8.0;
    let side = (w.hypot(h)).max(widest * scale) + 2.0 * f64::from(params.band) + 2.0;
    let mask = side * side * (channels + 2.0) * 4.0;
    let stage = crate::analysis::memory::Stage {
        name: "the sample's rotated transforms and the largest mask".into(),
        bytes: (transforms + mask) as u64,
    };
    let what = format!("mapping the sample at {} texels per unit", params.texels_per_unit);
    crate::analysis::memory::check(path, &what, &[stage], crate::Remedy::LowerDensity)
}

/// What happened on one level of the hierarchy.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct LevelReport {
    /// The level, 0 the coarsest (the whole surface's clusters).
    pub level: usize,
    /// Clusters on the level.
    pub clusters: usize,
    /// Clusters the level had to cover (the children of those the level above gave up).
    pub tried: usize,
    /// Mapped as one patch.
    pub mapped: usize,
    /// Of those, placed at random (no textured neighbour: a start).
    pub started: usize,
    /// Of those, placed as the exact continuation of a textured neighbour (no seam on that
    /// side) rather than by the mask's fit.
    pub continued: usize,
    /// Faces mapped on this level.
    pub faces: usize,
    /// Given up, left to the next level: not a disc, or without a simple control polygon.
    pub not_disc: usize,
    /// Given up: flattened with more distortion than the limit allows, or folded.
    pub distorted: usize,
    /// Given up: larger than a sample that does not tile allows.
    pub too_large: usize,
    /// Given up: its best fit's error was over the threshold.
    pub poor_fit: usize,
    /// Given up: no textured neighbour on a piece of the surface already started.
    pub unreached: usize,
    /// Median output error of the level's fits (along shared edges, relaxed, as a fraction
    /// of two random texels'; NaN without fits).
    pub median_fit_error: f32,
    /// Seconds the level took to map.
    pub seconds: f64,
}

/// The whole run.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Report {
    /// Per level of the hierarchy, coarsest first.
    pub levels: Vec<LevelReport>,
    /// Seconds: hierarchy, flattening (polygons and coordinates), sample transforms, mapping.
    pub seconds: [f64; 4],
    /// Faces of the mesh.
    pub faces: usize,
    /// Faces without area in the graph, given their neighbours' coordinates.
    pub carried_faces: usize,
    /// Clusters in the whole hierarchy.
    pub clusters: usize,
}

/// The result on the file's own faces.
#[derive(Clone, Debug)]
pub struct PatchMapping {
    /// Per file face, per corner (in the file's order), the sample coordinate (texels,
    /// texel centres at integers, x along columns, y down rows).
    pub corner_uv: Vec<[Vec2; 3]>,
    /// Per file face, the cluster that textured it.
    pub cluster: Vec<u32>,
    /// Per file face, that cluster's level.
    pub level: Vec<u8>,
    /// What each level did and how long it took.
    pub report: Report,
}

/// Maps `sample` onto the triangles of a file (`path`, named in errors): see the module
/// documentation.
pub fn map_mesh(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    path: &Path,
    sample: FitImage,
    params: &SolerParams,
    progress: &dyn Progress,
) -> Result<PatchMapping> {
    check_size(positions, triangles, path, params, (sample.width, sample.height, sample.channels))?;
    let mut seconds = [0.0; 4];
    let started = Instant::now();
    let graph = SurfaceGraph::new(positions, triangles, path)?;
    let first_face = match params.first_face {
        None => None,
        Some(f) if f >= triangles.len() => {
            return Err(Error::out_of_range(
                Param::FirstFace,
                f,
                format!(
                    "{} has {} faces (0 to {})",
                    path.display(),
                    triangles.len(),
                    triangles.len().saturating_sub(1)
                ),
            ))
        }
        Some(f) if graph.graph_face[f] == NONE => {
            return Err(Error::out_of_range(
                Param::FirstFace,
                f,
                format!("that face of {} has no area; choose another", path.display()),
            ))
        }
        Some(f) => Some(graph.graph_face[f]),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let hierarchy = hierarchy::Hierarchy::build(&graph, &mut rng);
    seconds[0] = started.elapsed().as_secs_f64();
    let started = Instant::now();
    let flattening = chart::Flattening::new(&graph, &hierarchy);
    seconds[1] = started.elapsed().as_secs_f64();
    let started = Instant::now();
    let fitter = Fitter::new(sample, params.rotations)?;
    seconds[2] = started.elapsed().as_secs_f64();
    let started = Instant::now();
    let mapper = mapper::Mapper {
        graph: &graph,
        hierarchy: &hierarchy,
        flattening: &flattening,
        fitter: &fitter,
        params,
        first_face,
    };
    let (mapping, levels) = mapper.run(&mut rng, progress)?;
    seconds[3] = started.elapsed().as_secs_f64();
    let (corner_uv, cluster) = on_file_faces(&graph, &mapping, triangles);
    if corner_uv.iter().flatten().any(|uv| !uv.is_finite()) {
        // check_size keeps the arithmetic finite; never write NaN coordinates regardless.
        return Err(Error::internal(format!(
            "{}: the mapping gave non-finite texture coordinates",
            path.display()
        )));
    }
    let level = cluster
        .iter()
        .map(|&c| if c == NONE { 0 } else { hierarchy.clusters[c as usize].level.min(255) as u8 })
        .collect();
    let report = Report {
        levels,
        seconds,
        faces: triangles.len(),
        carried_faces: triangles.len() - graph.face_count(),
        clusters: hierarchy.clusters.len(),
    };
    Ok(PatchMapping { corner_uv, cluster, level, report })
}

/// The graph faces' coordinates on the file's faces, in the file's corner order; a face
/// without area takes, per corner, the coordinate its vertex has in the graph face that
/// shares most of its corners (else in any face around the vertex).
fn on_file_faces(
    graph: &SurfaceGraph,
    mapping: &mapper::Mapping,
    triangles: &[[u32; 3]],
) -> (Vec<[Vec2; 3]>, Vec<u32>) {
    let faces = triangles.len();
    let mut uv = vec![[Vec2::ZERO; 3]; faces];
    let mut cluster = vec![NONE; faces];
    for (f, &g) in graph.graph_face.iter().enumerate() {
        if g == NONE {
            continue;
        }
        let order = graph.file_corner[g as usize];
        for k in 0..3 {
            uv[f][order[k] as usize] = mapping.face_uv[g as usize][k];
        }
        cluster[f] = mapping.mapped_by[g as usize];
    }
    for (f, &g) in graph.graph_face.iter().enumerate() {
        if g != NONE {
            continue;
        }
        // The welded corners of the file face.
        let corners = triangles[f].map(|i| graph.weld[i as usize]);
        let host = corners
            .iter()
            .filter(|&&v| v != NONE)
            .flat_map(|&v| graph.faces_of(v).iter().copied())
            .max_by_key(|&h| {
                (corners.iter().filter(|&&v| graph.corner_of(h, v).is_some()).count(), std::cmp::Reverse(h))
            });
        for k in 0..3 {
            let v = corners[k];
            if v == NONE {
                continue;
            }
            let in_host = host.and_then(|h| graph.corner_of(h, v).map(|i| (h, i)));
            let any = graph.faces_of(v).first().map(|&h| (h, graph.corner_of(h, v).unwrap_or(0)));
            if let Some((h, i)) = in_host.or(any) {
                uv[f][k] = mapping.face_uv[h as usize][i];
            }
        }
        cluster[f] = host.map_or(NONE, |h| mapping.mapped_by[h as usize]);
    }
    (uv, cluster)
}
