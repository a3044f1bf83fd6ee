//! `btfsynth eval` as a library: every measure of a plane result, a surface map or a bare
//! picture (another tool's output) against the analysis it should look like.

use super::coords::{coord_quality, CoordQuality};
use super::picture::{
    colour_chi2, contrast, nearest_patch_energy, wrap_seam_energy, Picture, PATCH_SIDE, PATCH_STRIDE,
};
use super::quality::{picture_quality, PictureQuality};
use super::repetition::{texture_mapped_points, SurfacePlaces, SurfaceRecurrences};
use super::surface::{model_figures, TextureFigures};
use super::texton::{chi2, energy, TextonQuality};
use crate::analysis::images::{Probe, SampleImages};
use crate::synth::engine::State;
use crate::synth::plane::read_plane;
use crate::synth::surface::surface_level;
use crate::synth::surface_map::SurfaceMap;
use crate::synth::target::{wrapping_grid_levels, Slot, TargetLevel, OUTSIDE};
use crate::synth::Sample;
use crate::{Error, Result};
use serde::Serialize;
use std::path::Path;

/// Every measure of one result.
#[derive(Clone, Debug, Serialize)]
pub struct Evaluation {
    /// `plane`, `surface`, `uvmap` (texture coordinates on the user's mesh, from
    /// pattern mapping, [`crate::synth::patches`]) or `picture`.
    pub kind: &'static str,
    /// Output vertices (pixels of a plane or picture).
    pub vertices: usize,
    /// Coordinate-map measures (not for a bare picture).
    pub coords: Option<CoordQuality>,
    /// Texton-space measures (not for a bare picture).
    pub textons: Option<TextonQuality>,
    /// Image-space measures per view/light pair.
    pub probes: Vec<ProbeQuality>,
    /// A uvmap only: the patch energy of windows straddling a patch border against windows
    /// inside one patch, on the head-on image.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seams: Option<crate::synth::patches::quality::SeamQuality>,
    /// An exported model, or a surface map exported in memory: its base colour texture on
    /// the surface against the sample at the same scale ([`super::surface`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texture: Option<TextureFigures>,
}

/// The image-space measures under one view/light pair.
#[derive(Clone, Debug, Serialize)]
pub struct ProbeQuality {
    /// The view/light pair the measures are taken under.
    #[serde(flatten)]
    pub probe: Probe,
    /// The image-space measures of the result against the sample under that pair.
    #[serde(flatten)]
    pub quality: PictureQuality,
    /// Tileable planes (synthesized with `tiles`, [`crate::synth::plane::synthesize_plane`]) only:
    /// the patch energy of the result's patches that cross its wrap edge, i.e. of the joins between
    /// repeated copies. About `patch_energy` when the result tiles without a visible seam (the
    /// patches along two lines are a small sample: 0.5–2.4× it over the benchmark's photographs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wrap_seam_energy: Option<f64>,
}

/// A plane result directory (from [`crate::synth::plane::write_plane`]) against the analysis
/// in `analysis_dir`.
pub fn evaluate_plane(analysis_dir: &Path, plane_dir: &Path) -> Result<Evaluation> {
    let (width, height, state, manifest) = read_plane(plane_dir)?;
    let neighborhood = manifest["params"]["neighborhood"].as_u64().unwrap_or(5) as usize;
    let images = SampleImages::open(analysis_dir)?;
    let (sample, tileable) = texton_level(analysis_dir, &state, plane_dir)?;
    let tiles = manifest["tileable_output"].as_bool().unwrap_or(false);
    let level = wrapping_grid_levels(width, height, 1, neighborhood, 3, tiles).remove(0);
    let probes = images
        .default_probes()
        .into_iter()
        .map(|probe| {
            let result = images.through(probe.image, width, height, &state.uv);
            let sample_picture = images.picture(probe.image);
            let quality = picture_quality(&result, &sample_picture, tileable);
            let wrap_seam_energy = tiles.then(|| wrap_seam_energy(&result, &sample_picture, tileable));
            ProbeQuality { probe, quality, wrap_seam_energy }
        })
        .collect();
    Ok(Evaluation {
        kind: "plane",
        vertices: width * height,
        coords: Some(coord_quality(&level, &state, (sample.width, sample.height), tileable)),
        textons: Some(texton_quality(&level, &state, &sample)),
        probes,
        seams: None,
        texture: None,
    })
}

/// A surface map against the analysis in `analysis_dir`, `neighborhood` its template side.
pub fn evaluate_surface(
    analysis_dir: &Path,
    map: &SurfaceMap,
    neighborhood: usize,
    name: &Path,
) -> Result<Evaluation> {
    let level = surface_level(&map.mesh, &map.frames, map.texel, neighborhood)?;
    let patches = surface_level(&map.mesh, &map.frames, map.texel, PATCH_SIDE)?;
    let images = SampleImages::open(analysis_dir)?;
    let (sample, tileable) = texton_level(analysis_dir, &map.state, name)?;
    let places = SurfacePlaces { positions: map.mesh.positions(), frames: &map.frames, texel: map.texel };
    let recurrences = SurfaceRecurrences::of(&places, &map.state.uv, (images.width, images.height));
    let probes = images
        .default_probes()
        .into_iter()
        .map(|probe| {
            let colours = images.through(probe.image, map.mesh.vertex_count(), 1, &map.state.uv);
            let picture = images.picture(probe.image);
            let quality = PictureQuality {
                patch_energy: surface_patch_energy(&patches, &colours, &picture, tileable),
                patch_energy_coarse: f64::NAN,
                colour_chi2: colour_chi2(&colours, &picture),
                contrast: contrast(&colours, &picture),
                repetition: recurrences.score(&picture, tileable),
            };
            ProbeQuality { probe, quality, wrap_seam_energy: None }
        })
        .collect();
    Ok(Evaluation {
        kind: "surface",
        vertices: map.mesh.vertex_count(),
        coords: Some(coord_quality(&level, &map.state, (sample.width, sample.height), tileable)),
        textons: Some(texton_quality(&level, &map.state, &sample)),
        probes,
        seams: None,
        texture: None,
    })
}

/// A texture-mapped mesh (pattern mapping, [`crate::synth::patches`]) against the analysis in
/// `analysis_dir`. It has no texton labels and no per-vertex coordinates, so only the
/// image-space measures and repetition apply, on the surface itself: the patch energy of 7×7 windows
/// resampled on the surface at one sample texel per pixel (3,000 faces drawn with seed 1;
/// see [`crate::synth::patches::quality::seam_quality`]), the colour histogram and contrast of
/// the texture at four points per face, and the repetition of its coordinates at about one
/// point per texel (see `eval::repetition`).
pub fn evaluate_uv_map(
    analysis_dir: &Path,
    map: &crate::synth::patches::output::UvMap,
) -> Result<Evaluation> {
    use crate::synth::patches::quality::{seam_quality, MappedSurface};
    let images = SampleImages::open(analysis_dir)?;
    if (images.width, images.height) != map.sample {
        return Err(Error::invalid(format!(
            "the result maps a {}x{} sample, the analysis {} holds {}x{}",
            map.sample.0,
            map.sample.1,
            analysis_dir.display(),
            images.width,
            images.height
        )));
    }
    let (mesh, scale) = (&map.mesh, 1.0 / map.texel);
    let points = texture_mapped_points(&mesh.positions, &mesh.triangles, &map.corner_uv, map.texel);
    let on = SurfacePlaces { positions: &points.0, frames: &points.1, texel: map.texel };
    let recurrences = SurfaceRecurrences::of(&on, &points.2, map.sample);
    let mut seams = None;
    let probes = images
        .default_probes()
        .into_iter()
        .map(|probe| {
            let picture = images.picture(probe.image);
            let surface = MappedSurface {
                positions: &mesh.positions,
                triangles: &mesh.triangles,
                corner_uv: &map.corner_uv,
                cluster: &map.cluster,
                sample: &picture,
                tileable: map.tileable,
                texels_per_unit: scale,
            };
            let q = seam_quality(&surface, (3000, 1))?;
            let windows = (q.border_windows + q.interior_windows).max(1) as f64;
            let weighted = |e: f64, n: usize| if n > 0 { e * n as f64 } else { 0.0 };
            let patch_energy =
                (weighted(q.border, q.border_windows) + weighted(q.interior, q.interior_windows)) / windows;
            let colours = surface_colours(&map.corner_uv, &picture, map.tileable);
            seams.get_or_insert(q);
            let quality = PictureQuality {
                patch_energy,
                patch_energy_coarse: f64::NAN,
                colour_chi2: colour_chi2(&colours, &picture),
                contrast: contrast(&colours, &picture),
                repetition: recurrences.score(&picture, map.tileable),
            };
            Ok(ProbeQuality { probe, quality, wrap_seam_energy: None })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(Evaluation {
        kind: "uvmap",
        vertices: mesh.positions.len(),
        coords: None,
        textons: None,
        probes,
        seams,
        texture: None,
    })
}

/// The texture at the centroid and three inner points of every face (nearest texel), as a
/// one-row picture.
fn surface_colours(corner_uv: &[[glam::Vec2; 3]], picture: &Picture, tileable: bool) -> Picture {
    let (w, h) = (picture.width as i64, picture.height as i64);
    let at = |p: glam::Vec2| {
        let (x, y) = (p.x.round() as i64, p.y.round() as i64);
        let (x, y) = if tileable {
            (x.rem_euclid(w), y.rem_euclid(h))
        } else {
            (x.clamp(0, w - 1), y.clamp(0, h - 1))
        };
        picture.rgb[(y * w + x) as usize]
    };
    let weights = [
        [1.0 / 3.0; 3],
        [2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0],
        [1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0],
        [1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0],
    ];
    let rgb: Vec<[f32; 3]> = corner_uv
        .iter()
        .flat_map(|uv| weights.iter().map(move |b| at(uv[0] * b[0] + uv[1] * b[1] + uv[2] * b[2])))
        .collect();
    Picture { width: rgb.len(), height: 1, rgb }
}

/// A bare picture (e.g. another synthesizer's output from the same sample) against the
/// analysis' head-on image.
pub fn evaluate_picture(analysis_dir: &Path, path: &Path) -> Result<Evaluation> {
    let result = Picture::read(path)?;
    let (width, height) = (result.width, result.height);
    let images = SampleImages::open(analysis_dir)?;
    let tileable = crate::analysis::store::read_manifest(analysis_dir)?.params.tileable;
    let probe = images.default_probes().remove(0);
    let quality = picture_quality(&result, &images.picture(probe.image), tileable);
    Ok(Evaluation {
        kind: "picture",
        vertices: width * height,
        coords: None,
        textons: None,
        probes: vec![ProbeQuality { probe, quality, wrap_seam_energy: None }],
        seams: None,
        texture: None,
    })
}

/// An exported model (`.glb` or `.gltf`, from [`crate::export`]) against the analysis in
/// `analysis_dir`: its base colour texture on its surface ([`model_figures`]) against the
/// analysis' head-on image. The sample's texel size on the surface is the one the export
/// recorded (`extras.btfsynth.sampleTexel`), or `texel` when given.
pub fn evaluate_model(analysis_dir: &Path, path: &Path, texel: Option<f32>) -> Result<Evaluation> {
    let model = crate::export::read::read_model(path)?;
    let texel = texel.or_else(|| model.extras["btfsynth"]["sampleTexel"].as_f64().map(|t| t as f32));
    let texel = texel.filter(|t| t.is_finite() && *t > 0.0).ok_or_else(|| {
        Error::invalid(format!(
            "{}: the model does not record the sample's texel size on its surface (extras.btfsynth.sampleTexel)",
            path.display()
        ))
    })?;
    model_evaluation(analysis_dir, &model, texel)
}

/// A surface map exported in memory as `export` would (default options, the original mesh
/// its header names), then judged as [`evaluate_model`] judges the file.
pub fn evaluate_surface_export(analysis_dir: &Path, ply: &Path) -> Result<Evaluation> {
    use crate::export::{bake_export, original_mesh, ExportOptions, ExportSource, SourceNames};
    let (scene, _) = crate::render::scene::open_surface(ply, Some(analysis_dir), false)?;
    let material = crate::render::Material::open(analysis_dir)?;
    let mesh_path = original_mesh(ply, None)?;
    let mesh = crate::mesh::textured::load_textured(&mesh_path)?;
    let names = SourceNames { surface: ply, analysis: analysis_dir, mesh: &mesh_path };
    let source = ExportSource { scene: &scene, material: &material, maps: &[], mesh: Some(&mesh), names };
    let exported = bake_export("eval", &source, &ExportOptions::default(), &crate::progress::Silent)?;
    let model = crate::export::read::model_from_bytes(&exported.document.to_glb(), ply)?;
    model_evaluation(analysis_dir, &model, scene.texel)
}

fn model_evaluation(
    analysis_dir: &Path,
    model: &crate::export::read::Model,
    texel: f32,
) -> Result<Evaluation> {
    let images = SampleImages::open(analysis_dir)?;
    let tileable = crate::analysis::store::read_manifest(analysis_dir)?.params.tileable;
    let probe = images.default_probes().remove(0);
    let figures = model_figures(model, &images.picture(probe.image), tileable, texel)?;
    Ok(Evaluation {
        kind: "model",
        vertices: model.positions.len(),
        coords: None,
        textons: None,
        probes: Vec::new(),
        seams: None,
        texture: Some(figures),
    })
}

/// The analysis' finest texton level, checked against the result's labels and coordinates.
fn texton_level(
    analysis_dir: &Path,
    state: &State,
    result: &Path,
) -> Result<(crate::synth::SampleLevel, bool)> {
    let sample = Sample::open(analysis_dir, 1)?.levels.remove(0);
    let fits = state.labels.iter().all(|&l| (l as usize) < sample.textons)
        && state
            .uv
            .iter()
            .all(|&[x, y]| x >= 0 && y >= 0 && (x as usize) < sample.width && (y as usize) < sample.height);
    if !fits {
        return Err(Error::invalid(format!(
            "{}: its labels or coordinates do not fit the analysis {}",
            result.display(),
            analysis_dir.display()
        )));
    }
    let tileable = sample.tileable;
    Ok((sample, tileable))
}

fn texton_quality(level: &TargetLevel, state: &State, sample: &crate::synth::SampleLevel) -> TextonQuality {
    TextonQuality {
        chi2: chi2(&state.labels, &sample.labels, sample.textons),
        energy: energy(level, state, sample),
    }
}

/// Nearest-patch energy of a surface: every [`PATCH_STRIDE`]th vertex whose 7×7 template
/// lies wholly on the surface contributes its template, resampled from the vertex colours
/// (`colours`, one picture row), against the sample's 7×7 patches.
fn surface_patch_energy(patches: &TargetLevel, colours: &Picture, sample: &Picture, tileable: bool) -> f64 {
    let mut scratch = Vec::new();
    let inside = |slots: &[Slot]| slots.iter().all(|s| s.vertices[0] != OUTSIDE);
    let chosen: Vec<usize> = (0..patches.vertices)
        .step_by(PATCH_STRIDE)
        .filter(|&v| inside(patches.slots_of(v, &mut scratch)))
        .collect();
    let dims = PATCH_SIDE * PATCH_SIDE * 3;
    let mut queries = ndarray::Array2::zeros((chosen.len(), dims));
    for (mut row, &v) in queries.rows_mut().into_iter().zip(&chosen) {
        for (i, slot) in patches.slots_of(v, &mut scratch).iter().enumerate() {
            for (&u, &w) in slot.vertices.iter().zip(&slot.weights) {
                let c = colours.rgb[u as usize];
                for k in 0..3 {
                    row[3 * i + k] += w * c[k];
                }
            }
        }
    }
    nearest_patch_energy(&queries, sample, tileable)
}
