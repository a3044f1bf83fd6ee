//! Plane mode: synthesis on a regular W×H grid, the 2D case used to compare with texture
//! synthesis tools. Output: a directory with the maps as arrays and images.
//!
//! | file | content |
//! |---|---|
//! | `plane.json` | the analysis used, the size, the parameters and the per-level report |
//! | `labels.npy` | u16 [h, w] texton labels (level 0) |
//! | `uv.npy` | u32 [h, w, 2] sample coordinates (x, y) in texels |
//! | `textons.png` | the labels in the analysis' false colours |
//! | `uv.png` | x and y as red and green, scaled to the sample size |
//! | `result.png` | the sample image closest to normal view and light, copied through `uv` |
//! | `result_tv…_pv…_tl…_pl….png` | the same under each shown view/light pair (see [`write_plane`]) |
//! | `sample_tv…_pv…_tl…_pl….png` | the sample image of that pair, to compare with |
//! | `result_<kind>.png\|exr` | each material map of the analysis copied through `uv` ([`crate::maps`]) |

use super::engine::State;
use super::target::wrapping_grid_levels;
use super::{synthesize, LevelReport, Sample, SynthParams};
use crate::analysis::images::{Probe, SampleImages};
use crate::analysis::knn::parent_size;
use crate::analysis::npy;
use crate::analysis::store::{false_colours, save_png};
use crate::eval::Picture;
use crate::fsutil::{write_file_atomic, StagedDir};
use crate::progress::Progress;
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// The manifest of a plane result.
pub const MANIFEST: &str = "plane.json";

/// A synthesized plane.
pub struct PlaneResult {
    /// Width of the plane in sample texels.
    pub width: usize,
    /// Height of the plane in sample texels.
    pub height: usize,
    /// The plane was synthesized on a wrapping grid: it repeats without a seam.
    pub tiles: bool,
    /// The finest level's texton labels and sample coordinates, one per pixel, row-major.
    pub state: State,
    /// What happened on each level, coarsest first.
    pub reports: Vec<LevelReport>,
}

/// Synthesizes a `width × height` plane from `sample`; with `tiles`, on a grid whose edges
/// wrap, so that copies of the result laid side by side join without a seam.
pub fn synthesize_plane(
    sample: &Sample,
    (width, height): (usize, usize),
    tiles: bool,
    params: &SynthParams,
    progress: &dyn Progress,
) -> Result<PlaneResult> {
    if width == 0 || height == 0 || width * height > 1 << 26 {
        return Err(Error::out_of_range(
            crate::Param::PlaneSize,
            format!("{width}x{height}"),
            "sides must be at least 1 and the area at most 2^26",
        ));
    }
    let targets = wrapping_grid_levels(
        width,
        height,
        sample.levels.len(),
        params.neighborhood,
        parent_size(params.neighborhood),
        tiles,
    );
    let (state, reports) = synthesize(&targets, sample, params, progress)?;
    Ok(PlaneResult { width, height, tiles, state, reports })
}

/// Writes `result` (synthesized from the analysis in `analysis_dir`) into the directory `out`,
/// showing it under `probes` (the sample's default view/light pairs when empty: head-on,
/// light at 45° and grazing light, where the stack has them).
pub fn write_plane(
    result: &PlaneResult,
    analysis_dir: &Path,
    probes: &[Probe],
    params_json: serde_json::Value,
    out: &Path,
    overwrite: bool,
) -> Result<PathBuf> {
    let staged = StagedDir::new(out, overwrite)?;
    let dir = staged.path();
    let (w, h) = (result.width, result.height);
    npy::write(&dir.join("labels.npy"), &[h, w], &result.state.labels)?;
    let uv: Vec<u32> = result.state.uv.iter().flat_map(|&[x, y]| [x as u32, y as u32]).collect();
    npy::write(&dir.join("uv.npy"), &[h, w, 2], &uv)?;
    write_texton_picture(&result.state.labels, (w, h), analysis_dir, &dir.join("textons.png"))?;

    let images = SampleImages::open(analysis_dir)?;
    let (sw, sh) = (images.width, images.height);
    let uv_rgb: Vec<u8> = result
        .state
        .uv
        .iter()
        .flat_map(|&[x, y]| {
            [
                (x as usize * 255 / sw.max(2).saturating_sub(1)) as u8,
                (y as usize * 255 / sh.max(2).saturating_sub(1)) as u8,
                0,
            ]
        })
        .collect();
    save_png(&dir.join("uv.png"), w, h, &uv_rgb)?;
    let defaults = images.default_probes();
    save_picture(&images.through(defaults[0].image, w, h, &result.state.uv), &dir.join("result.png"))?;
    let shown = if probes.is_empty() { defaults } else { probes.to_vec() };
    for probe in &shown {
        let tag = probe.angles_tag();
        save_picture(
            &images.through(probe.image, w, h, &result.state.uv),
            &dir.join(format!("result_{tag}.png")),
        )?;
        save_picture(&images.picture(probe.image), &dir.join(format!("sample_{tag}.png")))?;
    }
    crate::maps::stored::write_plane_maps(analysis_dir, &result.state.uv, (w, h), dir)?;

    let fingerprint = crate::analysis::store::read_manifest(analysis_dir)?.source.fingerprint;
    let manifest = serde_json::json!({
        "kind": "plane",
        "analysis": analysis_dir.display().to_string(),
        "analysis_fingerprint": fingerprint,
        "width": w,
        "height": h,
        "tileable_output": result.tiles,
        "params": params_json,
        "shown": shown,
        "levels": result.reports,
    });
    let text = serde_json::to_string_pretty(&manifest).map_err(|e| Error::internal(e.to_string()))?;
    write_file_atomic(&dir.join(MANIFEST), text.as_bytes())?;
    staged.commit()
}

/// The labels in the analysis' false colours.
fn write_texton_picture(
    labels: &[u16],
    (w, h): (usize, usize),
    analysis_dir: &Path,
    path: &Path,
) -> Result<()> {
    let embedding: npy::NpyArray<f32> = npy::read(&analysis_dir.join("level0_embedding.npy"))?;
    let dims = embedding.shape.get(1).copied().unwrap_or(0);
    let embedding = ndarray::Array2::from_shape_vec((embedding.shape[0], dims), embedding.data)
        .map_err(|e| Error::format(analysis_dir.join("level0_embedding.npy"), e.to_string()))?;
    let colours = false_colours(&embedding);
    let rgb: Vec<u8> =
        labels.iter().flat_map(|&l| colours.get(l as usize).copied().unwrap_or([0; 3])).collect();
    save_png(path, w, h, &rgb)
}

/// An sRGB picture as an 8-bit PNG.
fn save_picture(picture: &Picture, path: &Path) -> Result<()> {
    let rgb: Vec<u8> = picture.rgb.iter().flat_map(|p| p.map(|v| (v * 255.0).round() as u8)).collect();
    save_png(path, picture.width, picture.height, &rgb)
}

/// Reads a plane result's labels and coordinates back.
pub fn read_plane(dir: &Path) -> Result<(usize, usize, State, serde_json::Value)> {
    let path = dir.join(MANIFEST);
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    let manifest: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| Error::format(&path, e.to_string()))?;
    let labels: npy::NpyArray<u16> = npy::read(&dir.join("labels.npy"))?;
    let uv: npy::NpyArray<u32> = npy::read(&dir.join("uv.npy"))?;
    let [h, w] = labels.shape[..] else {
        return Err(Error::format(dir.join("labels.npy"), "expected shape [h, w]"));
    };
    if uv.shape != [h, w, 2] {
        return Err(Error::format(
            dir.join("uv.npy"),
            format!("shape {:?} does not match labels [{h}, {w}]", uv.shape),
        ));
    }
    let uv = uv.data.chunks_exact(2).map(|c| [c[0] as i32, c[1] as i32]).collect();
    Ok((w, h, State::new(labels.data, uv), manifest))
}
