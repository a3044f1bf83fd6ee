//! Converting stacks between layouts: any readable stack to a folder (manifest plus EXR or
//! PNG images) or to a DFMF `.btf` file, reporting how far the compressed file is from the
//! original.

use crate::btf::colour::ColourModel;
use crate::btf::factorize::{factorize, Factorization};
use crate::btf::source::ImageSource;
use crate::btf::ubo2014::write::{write_dfmf, DfmfGeometry, DfmfOptions};
use crate::btf::ubo2014::{BonnBtf, Rotation, Scalar};
use crate::btf::{load, Btf, Crop, LoadOptions};
use crate::progress::Progress;
use crate::Result;
use half::f16;
use std::path::Path;

/// Opens any stack lazily where its format allows (`.btf`, zip), else reads it whole.
pub fn open_stack(path: &Path, crop: Option<Crop>, progress: &dyn Progress) -> Result<Box<dyn ImageSource>> {
    match crate::btf::stack_file::open(path, crop)? {
        Some(lazy) => Ok(lazy),
        None => Ok(Box::new(load(path, &LoadOptions { crop }, progress)?)),
    }
}

/// The frame rotations of a Bonn file (none for other stacks), to carry into a new file.
pub fn rotations_of(path: &Path) -> Result<Vec<Rotation>> {
    match crate::btf::ubo2014::is_bonn_file(path) {
        true => Ok(BonnBtf::open(path)?.rotations().to_vec()),
        false => Ok(Vec::new()),
    }
}

/// How a stack becomes a DFMF file.
#[derive(Clone, Debug)]
pub struct ToBtfOptions {
    /// Components kept per channel (capped by the matrix size).
    pub components: usize,
    /// The colour model: [`ColourModel::Rgb`] or [`ColourModel::LogYUvOverY`].
    pub model: ColourModel,
    /// Half or float scalars.
    pub scalar: Scalar,
    /// Write the rotation block (`!DFMF08FCR`), with these rotations.
    pub rotation_block: bool,
    /// The frame rotations the block holds (usually none).
    pub rotations: Vec<Rotation>,
    /// Seed of the randomized SVD.
    pub seed: u64,
}

/// What [`to_btf`] did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ToBtfReport {
    /// Images in the stack (views × lights).
    pub images: usize,
    /// Distinct view directions.
    pub views: usize,
    /// Distinct light directions.
    pub lights: usize,
    /// Width of the images in texels.
    pub width: usize,
    /// Height of the images in texels.
    pub height: usize,
    /// Components per channel.
    pub components: Vec<usize>,
    /// Per channel, in the colour model's space: the error the discarded singular values
    /// predict, ‖M − U·SxVᵀ‖ / ‖M‖.
    pub predicted_error: [f64; 3],
    /// ‖original − decoded‖ / ‖original‖ over all linear RGB values, decoding the file
    /// as written (so it includes the scalar precision).
    pub relative_error: f64,
    /// Size of the written file in bytes.
    pub file_bytes: u64,
}

/// Writes `stack` as a DFMF file at `path` and measures the file against the stack.
pub fn to_btf(
    stack: &Btf,
    path: &Path,
    options: &ToBtfOptions,
    progress: &dyn Progress,
) -> Result<ToBtfReport> {
    let f = factorize(stack, options.model, options.components, options.seed, progress)?;
    let dfmf = DfmfOptions {
        model: options.model,
        scalar: options.scalar,
        rotation_block: options.rotation_block,
        rotations: options.rotations.clone(),
        measurement_setup: format!("btfsynth {} convert", env!("CARGO_PKG_VERSION")),
    };
    let geometry = DfmfGeometry {
        views: &f.grid.views,
        lights: &f.grid.lights,
        width: stack.width(),
        height: stack.height(),
    };
    write_dfmf(path, &geometry, &f.channels, &dfmf)?;
    let relative_error = measure(stack, &f, path, progress)?;
    let file_bytes = std::fs::metadata(path).map_err(|e| crate::Error::io(path, e))?.len();
    Ok(ToBtfReport {
        images: stack.len(),
        views: f.grid.views.len(),
        lights: f.grid.lights.len(),
        width: stack.width(),
        height: stack.height(),
        components: f.channels.iter().map(|c| c.singular_values.len()).collect(),
        predicted_error: f.relative_error,
        relative_error,
        file_bytes,
    })
}

/// ‖stack − file‖ / ‖stack‖, decoding the written file image by image.
fn measure(stack: &Btf, f: &Factorization, path: &Path, progress: &dyn Progress) -> Result<f64> {
    let window = BonnBtf::open(path)?.into_window(None)?;
    let mut decoded = vec![f16::ZERO; stack.width() * stack.height() * 3];
    let (mut diff, mut total) = (0f64, 0f64);
    progress.start("measuring the error", f.grid.order.len() as u64);
    for (i, &original) in f.grid.order.iter().enumerate() {
        window.decode_image(i, &mut decoded)?;
        for (a, b) in stack.image(original).iter().zip(&decoded) {
            let (a, b) = (a.to_f64(), b.to_f64());
            diff += (a - b) * (a - b);
            total += a * a;
        }
        progress.advance(1);
    }
    progress.finish();
    Ok(if total > 0.0 { (diff / total).sqrt() } else { diff.sqrt() })
}
