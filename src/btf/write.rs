//! Writing a stack as a `btf.json` manifest plus one image per direction pair, atomically,
//! from memory or streamed from a lazy source.

use crate::btf::image_io::{write_exr, write_png};
use crate::btf::load::{Manifest, ManifestImage, MANIFEST};
use crate::btf::{Btf, DirectionPair, ImageSource};
use crate::fsutil::{write_file_atomic, StagedDir};
use crate::progress::Progress;
use crate::{Error, Result};
use half::f16;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Image file format of a written stack.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum ImageFormat {
    /// Half-float OpenEXR, lossless: the stack reads back bit for bit (default).
    #[default]
    Exr,
    /// 8-bit sRGB PNG: smaller, viewable anywhere, quantised and clamped to [0, 1].
    Png,
}

impl ImageFormat {
    fn extension(self) -> &'static str {
        match self {
            ImageFormat::Exr => "exr",
            ImageFormat::Png => "png",
        }
    }
}

/// Writes `btf` into the directory `dir` (created; replaced only if `overwrite`). Images are
/// named Bonn-style (`tl015_pl000_tv030_pv120.exr`) when every angle is a whole degree, so
/// the directory also loads without its manifest; otherwise `image_00042.exr`.
/// `source` is recorded in the manifest.
pub fn write_stack(
    btf: &Btf,
    dir: &Path,
    format: ImageFormat,
    source: Option<serde_json::Value>,
    overwrite: bool,
    progress: &dyn Progress,
) -> Result<PathBuf> {
    write_images(btf, dir, format, source, overwrite, progress)
}

/// [`write_stack`] for any [`ImageSource`]: each image is decoded just before it is
/// written, so a lazy source (a large `.btf` file) is never held in memory whole.
pub fn write_images(
    images: &dyn ImageSource,
    dir: &Path,
    format: ImageFormat,
    source: Option<serde_json::Value>,
    overwrite: bool,
    progress: &dyn Progress,
) -> Result<PathBuf> {
    let staged = StagedDir::new(dir, overwrite)?;
    let names = file_names(images.pairs(), format);
    let (width, height) = (images.width(), images.height());
    progress.start("writing images", names.len() as u64);
    names.par_iter().enumerate().try_for_each_init(
        || vec![f16::ZERO; width * height * 3],
        |data, (i, name)| {
            images.decode_image(i, data)?;
            let path = staged.path().join(name);
            match format {
                ImageFormat::Exr => write_exr(&path, width, height, data)?,
                ImageFormat::Png => write_png(&path, width, height, data)?,
            }
            progress.advance(1);
            Ok::<(), Error>(())
        },
    )?;
    progress.finish();
    let manifest = Manifest {
        images: images
            .pairs()
            .iter()
            .zip(&names)
            .map(|(p, file)| ManifestImage {
                file: file.clone(),
                light: [p.light.theta, p.light.phi],
                view: [p.view.theta, p.view.phi],
            })
            .collect(),
        source,
    };
    let json = serde_json::to_string_pretty(&manifest).map_err(|e| Error::internal(e.to_string()))?;
    write_file_atomic(&staged.path().join(MANIFEST), json.as_bytes())?;
    staged.commit()
}

fn file_names(pairs: &[DirectionPair], format: ImageFormat) -> Vec<String> {
    let whole = |a: f32| a.fract() == 0.0 && a >= 0.0;
    let bonn =
        pairs.iter().all(|p| [p.light.theta, p.light.phi, p.view.theta, p.view.phi].into_iter().all(whole));
    let ext = format.extension();
    pairs
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if bonn {
                format!(
                    "tl{:03}_pl{:03}_tv{:03}_pv{:03}.{ext}",
                    p.light.theta as u32, p.light.phi as u32, p.view.theta as u32, p.view.phi as u32
                )
            } else {
                format!("image_{i:05}.{ext}")
            }
        })
        .collect()
}
