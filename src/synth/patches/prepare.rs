//! What the method takes from an analysis and a mesh, made the same way by every front end
//! (the command line and the Python package), so that equal inputs give equal bytes: the
//! image patches are fitted against, the texture's scale on the mesh, and the parameters a
//! result records.

use super::fit::{ColourSpace, FitImage};
use super::SolerParams;
use crate::analysis::images::SampleImages;
use crate::synth::sample::AppearanceMap;
use crate::{Error, Param, Result};
use glam::Vec3;
use std::path::Path;

/// What patches are matched on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Matching {
    /// The sample's head-on image in a colour space.
    Colour(ColourSpace),
    /// The analysis' finest appearance vectors (for a BTF stack: every image's texel at once),
    /// at most [`Matching::APPEARANCE_DIMS`] of them.
    Appearance,
}

impl Matching {
    /// The appearance dimensions fitted at most (the leading ones carry most variance).
    pub const APPEARANCE_DIMS: usize = 8;

    /// `lab`, `hsv`, `rgb` or `appearance`.
    pub fn parse(name: &str) -> Result<Matching> {
        match name {
            "appearance" => Ok(Matching::Appearance),
            _ => ColourSpace::parse(name).map(Matching::Colour).map_err(|_| {
                Error::out_of_range(
                    Param::ColourSpace,
                    format!("'{name}'"),
                    "expected lab, hsv, rgb or appearance",
                )
            }),
        }
    }

    /// The name [`Matching::parse`] takes, as a result records it.
    pub fn name(self) -> &'static str {
        match self {
            Matching::Colour(ColourSpace::Lab) => "lab",
            Matching::Colour(ColourSpace::Hsv) => "hsv",
            Matching::Colour(ColourSpace::Rgb) => "rgb",
            Matching::Appearance => "appearance",
        }
    }

    /// The colour space masks are compared in (L*a*b* for appearance vectors).
    pub fn colour_space(self) -> ColourSpace {
        match self {
            Matching::Colour(space) => space,
            Matching::Appearance => ColourSpace::Lab,
        }
    }
}

/// The sample as patches are fitted against it, and the index of the image shown (the one
/// nearest head-on: a photograph's only image). `appearance` is the analysis' finest
/// level's appearance vectors (read only for [`Matching::Appearance`]); `analysis` names the
/// analysis in errors.
pub fn fit_sample(
    images: &SampleImages,
    appearance: Option<&AppearanceMap>,
    matching: Matching,
    tileable: bool,
    analysis: &Path,
) -> Result<(FitImage, usize)> {
    let shown = images.default_probes()[0].image;
    let (w, h) = (images.width, images.height);
    let image = match matching {
        Matching::Colour(space) => FitImage::from_rgb(w, h, |x, y| images.rgb(shown, x, y), space, tileable)?,
        Matching::Appearance => {
            let map = appearance.ok_or_else(|| {
                let message = "this analysis has no appearance vectors (re-run analyze)";
                Error::invalid(format!("{}: {message}", analysis.display()))
            })?;
            let dims = map.dims.min(Matching::APPEARANCE_DIMS);
            let mut values = Vec::with_capacity(w * h * dims);
            for y in 0..h as i64 {
                for x in 0..w as i64 {
                    values.extend_from_slice(&map.at(x, y)[..dims]);
                }
            }
            FitImage::new(w, h, dims, values, tileable)?
        }
    };
    Ok((image, shown))
}

/// Sample texels per model unit: `scale` itself, else `texels_across` (default 4 × the
/// sample's `width`) over the mesh's largest side. `mesh` names the file in errors.
pub fn texels_per_unit(
    positions: &[Vec3],
    scale: Option<f32>,
    texels_across: Option<f32>,
    width: usize,
    mesh: &Path,
) -> Result<f32> {
    if let Some(s) = scale {
        return Ok(s);
    }
    let (lo, hi) = crate::mesh::bounds_of(positions);
    let side = (hi - lo).max_element();
    // NaN fails too: a mesh without finite extent. The file's fault, not a flag's.
    if side.is_nan() || side <= 0.0 {
        let why = "the mesh has no extent to scale a texture to (are all its vertices at one point?)";
        return Err(Error::format(mesh, why));
    }
    let texels_per_unit = texels_across.unwrap_or(4.0 * width as f32) / side;
    if !texels_per_unit.is_finite() {
        let why = format!("the mesh is {side:e} across, too small to scale a texture to in single precision");
        return Err(Error::format(mesh, why));
    }
    Ok(texels_per_unit)
}

/// The parameters a result records (no timings: equal inputs give equal bytes); `shown` is
/// the image [`fit_sample`] chose.
pub fn recorded_params(params: &SolerParams, matching: Matching, shown: usize) -> serde_json::Value {
    serde_json::json!({
        "method": "soler2002", "texels_per_unit": params.texels_per_unit, "rotations": params.rotations,
        "band": params.band, "max_distortion": params.max_flat_error, "fit_threshold": params.max_fit_error,
        "colour_space": matching.name(), "relax": params.relax,
        "move_borders": params.move_borders, "seed": params.seed, "image": shown,
        "first_face": params.first_face, "orientation": params.orientation,
    })
}
