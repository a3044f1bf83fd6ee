//! Stacks whose images are decoded on request.
//!
//! A measured BTF file can hold far more than memory: a 400×400 UBO2014 material is
//! 22,801 images, 22 GB as f16. An [`ImageSource`] knows its size and directions up front
//! and decodes image `i` when asked, so `info` reads only a header, `convert` streams image
//! by image, and a crop decodes only its rectangle. [`crate::btf::stack_file::open`] gives the
//! lazy source of a `.btf` file or a zip archive; [`Btf`] itself is the in-memory source.

use crate::btf::{Btf, Crop, DirectionPair};
use crate::progress::Progress;
use crate::{Error, Remedy, Result};
use half::f16;
use rayon::prelude::*;
use std::path::Path;

/// A stack that decodes its images on request (linear RGB, `[height][width][3]`).
pub trait ImageSource: Sync {
    /// Where the images come from (for messages).
    fn path(&self) -> &Path;
    /// Width of every image (after any crop).
    fn width(&self) -> usize;
    /// Height of every image (after any crop).
    fn height(&self) -> usize;
    /// The (light, view) pair of every image.
    fn pairs(&self) -> &[DirectionPair];
    /// Decodes image `i` into `out` (`width × height × 3` values).
    fn decode_image(&self, i: usize, out: &mut [f16]) -> Result<()>;

    /// Decodes every image into one in-memory stack (after checking that it fits in
    /// memory). Sources with a faster whole-stack path override this.
    fn decode_all(&self, progress: &dyn Progress) -> Result<Btf> {
        let per_image = self.width() * self.height() * 3;
        ensure_fits_in_memory(self.path(), self.pairs().len(), per_image)?;
        let mut pixels = vec![f16::ZERO; per_image * self.pairs().len()];
        progress.start("decoding images", self.pairs().len() as u64);
        pixels.par_chunks_mut(per_image).enumerate().try_for_each(|(i, out)| {
            self.decode_image(i, out)?;
            progress.advance(1);
            Ok::<(), Error>(())
        })?;
        progress.finish();
        Btf::new(self.width(), self.height(), self.pairs().to_vec(), pixels)
    }
}

impl ImageSource for Btf {
    fn path(&self) -> &Path {
        Path::new("(in memory)")
    }

    fn width(&self) -> usize {
        Btf::width(self)
    }

    fn height(&self) -> usize {
        Btf::height(self)
    }

    fn pairs(&self) -> &[DirectionPair] {
        Btf::pairs(self)
    }

    fn decode_image(&self, i: usize, out: &mut [f16]) -> Result<()> {
        out.copy_from_slice(self.image(i));
        Ok(())
    }

    fn decode_all(&self, _progress: &dyn Progress) -> Result<Btf> {
        Ok(self.clone())
    }
}

/// Fails, suggesting a crop, when `images` decoded images of
/// `per_image` f16 values would not fit in the memory budget ([`memory_budget`]).
pub fn ensure_fits_in_memory(path: &Path, images: usize, per_image: usize) -> Result<()> {
    let needed = (images as u128 * per_image as u128 * 2).min(u64::MAX as u128) as u64;
    match memory_budget()? {
        Some((budget, source)) if needed > budget => Err(Error::too_large(
            format!(
                "{}: decoding all {images} images would take {}, more than the {} budget ({source})",
                path.display(),
                gib(needed),
                gib(budget)
            ),
            Remedy::Crop,
        )),
        _ => Ok(()),
    }
}

/// The environment variable that overrides the memory budget.
pub const MEMORY_ENV: &str = "BTFSYNTH_MEMORY";

/// The memory work may use, in bytes, and where the figure comes from (for messages):
/// 80% of `MemAvailable` (the rest is left for everything else the process and the
/// machine need), or `BTFSYNTH_MEMORY` (`6G`, `512M`, bytes; `unlimited` turns checks
/// off). `None` when there is nothing to check against (no /proc/meminfo).
pub fn memory_budget() -> Result<Option<(u64, String)>> {
    match std::env::var(MEMORY_ENV) {
        Ok(text) => parse_size_env(MEMORY_ENV, &text),
        Err(_) => Ok(available_memory().map(|a| {
            (a / 10 * 8, format!("80% of the {:.1} GiB available", a as f64 / (1u64 << 30) as f64))
        })),
    }
}

/// The value `text` of the size variable `name`: `6G`, `512M`, `64K`, plain bytes, or
/// `unlimited` (`None`); with it, the `NAME=value` that messages quote.
pub(crate) fn parse_size_env(name: &str, text: &str) -> Result<Option<(u64, String)>> {
    let t = text.trim();
    if t.eq_ignore_ascii_case("unlimited") {
        return Ok(None);
    }
    let split = t.find(|c: char| !c.is_ascii_digit() && c != '.').unwrap_or(t.len());
    let (digits, unit) = (&t[..split], t[split..].trim());
    let scale: u64 = match unit.to_ascii_uppercase().trim_end_matches("IB").trim_end_matches('B') {
        "" => 1,
        "K" => 1 << 10,
        "M" => 1 << 20,
        "G" => 1 << 30,
        "T" => 1 << 40,
        _ => 0,
    };
    match digits.parse::<f64>() {
        Ok(v) if scale > 0 && v.is_finite() && v > 0.0 => {
            Ok(Some(((v * scale as f64) as u64, format!("{name}={t}"))))
        }
        _ => Err(Error::invalid(format!(
            "{name}='{text}': expected a size such as 6G, 512M or a number of bytes, or 'unlimited'"
        ))),
    }
}

/// `MemAvailable` from /proc/meminfo, in bytes.
pub(crate) fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Checks that `crop` fits a `width × height` sample; the whole sample if `None`.
pub fn resolve_crop(path: &Path, crop: Option<Crop>, width: usize, height: usize) -> Result<Crop> {
    let c = crop.unwrap_or(Crop { x: 0, y: 0, width: width as u32, height: height as u32 });
    let fits = c.x as u64 + c.width as u64 <= width as u64 && c.y as u64 + c.height as u64 <= height as u64;
    if !fits {
        return Err(Error::format(
            path,
            format!(
                "crop {},{},{},{} does not fit in the {width}x{height} sample",
                c.x, c.y, c.width, c.height
            ),
        ));
    }
    Ok(c)
}

/// Sizes for messages: `3.2 GiB`, `640 MiB`, `12 KiB`, `1 byte` (a budget of a few bytes
/// must not read as `0.0 GiB`).
pub fn gib(bytes: u64) -> String {
    let ceil = |unit: u64| (bytes as f64 / unit as f64).ceil();
    match bytes {
        b if b >= 1 << 30 => format!("{:.1} GiB", b as f64 / (1u64 << 30) as f64),
        b if b >= 1 << 20 => format!("{:.0} MiB", ceil(1 << 20)),
        b if b >= 1 << 10 => format!("{:.0} KiB", ceil(1 << 10)),
        1 => "1 byte".into(),
        b => format!("{b} bytes"),
    }
}
