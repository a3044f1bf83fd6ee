//! `btfsynth eval` as a library: every measure of a plane result, a surface map or a bare
//! picture (another tool's output) against the analysis it should look like.

use super::coords::{coord_quality, CoordQuality};
use super::picture::{
    colour_chi2, contrast, nearest_patch_energy, picture_quality, wrap_seam_energy, Picture, PictureQuality,
    PATCH_SIDE, PATCH_STRIDE,
};
use super::repetition::Repetition;
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
    /// `plane`, `surface` or `picture`.
    pub kind: &'static str,
    /// Output vertices (pixels of a plane or picture).
    pub vertices: usize,
    /// Coordinate-map measures (not for a bare picture).
    pub coords: Option<CoordQuality>,
    /// Texton-space measures (not for a bare picture).
    pub textons: Option<TextonQuality>,
    /// Image-space measures per view/light pair.
    pub probes: Vec<ProbeQuality>,
}

/// The image-space measures under one view/light pair.
#[derive(Clone, Debug, Serialize)]
pub struct ProbeQuality {
    #[serde(flatten)]
    pub probe: Probe,
    #[serde(flatten)]
    pub quality: PictureQuality,
    /// Tileable planes (`synth --tileable-output`) only: the patch energy of the result's
    /// patches that cross its wrap edge, i.e. of the joins between repeated copies. About
    /// `patch_energy` when the result tiles without a visible seam (the patches along two
    /// lines are a small sample: 0.5–2.4× it over the benchmark's photographs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wrap_seam_energy: Option<f64>,
}

/// A plane result directory (from `synth --plane`) against the analysis in `analysis_dir`.
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
                // A surface has no image-space offsets; its renders are scored as pictures.
                repetition: Repetition::NAN,
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
    })
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
