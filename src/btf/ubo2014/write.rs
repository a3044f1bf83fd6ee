//! Writing DFMF files (btflib's `write_ubo_dfmf` layout) from per-channel factors.

use super::factors::Scalar;
use super::header::Rotation;
use crate::btf::colour::ColourModel;
use crate::btf::Direction;
use crate::fsutil::write_with_temp;
use crate::{Error, Result};
use half::f16;
use ndarray::Array2;
use std::io::{BufWriter, Write};
use std::path::Path;

/// One channel's truncated SVD: image `l + lights · v` at pixel `x + width · y` is
/// Σₖ `u[image][k] · sxv[pixel][k]`.
#[derive(Clone, Debug)]
pub struct ChannelFactors {
    /// The singular values σₖ (informational: they are already in `sxv`).
    pub singular_values: Vec<f32>,
    /// `[images][components]`, orthonormal columns.
    pub u: Array2<f32>,
    /// `[pixels][components]`: σₖ times the right singular vectors.
    pub sxv: Array2<f32>,
}

/// How a DFMF file is written.
#[derive(Clone, Debug)]
pub struct DfmfOptions {
    /// How the three channels encode RGB (the factors are of the encoded values).
    pub model: ColourModel,
    /// Half (2 bytes, as the UBO2014 files) or float (4 bytes) scalars.
    pub scalar: Scalar,
    /// Write the rotation block (signature `!DFMF08FCR`, which btflib requires); without
    /// it the signature is `!DFMF08FC`, which btf-extractor also reads.
    pub rotation_block: bool,
    /// The frame rotations the block holds (usually none).
    pub rotations: Vec<Rotation>,
    /// Free text for the meta header's "measurement setup" (at most 79 bytes are kept).
    pub measurement_setup: String,
}

/// The stack's geometry: `views` directions, each with the same `lights`, and the size.
pub struct DfmfGeometry<'a> {
    /// The view directions, in the file's order.
    pub views: &'a [Direction],
    /// The light directions, shared by every view, in the file's order.
    pub lights: &'a [Direction],
    /// Width of the images in texels.
    pub width: usize,
    /// Height of the images in texels.
    pub height: usize,
}

/// Writes a DFMF file atomically (a temporary sibling renamed into place).
pub fn write_dfmf(
    path: &Path,
    geometry: &DfmfGeometry,
    channels: &[ChannelFactors],
    options: &DfmfOptions,
) -> Result<()> {
    let images = geometry.views.len() * geometry.lights.len();
    let pixels = geometry.width * geometry.height;
    for (c, ch) in channels.iter().enumerate() {
        let k = ch.singular_values.len();
        if ch.u.dim() != (images, k) || ch.sxv.dim() != (pixels, k) || k == 0 {
            return Err(Error::invalid(format!(
                "channel {c}: factors of shape {:?} and {:?} do not fit {images} images of {pixels} pixels with {k} components",
                ch.u.dim(),
                ch.sxv.dim()
            )));
        }
    }
    if channels.len() != 3 {
        return Err(Error::invalid(format!("a DFMF file needs 3 channels, got {}", channels.len())));
    }
    write_with_temp(path, |tmp| {
        let file = std::fs::File::create(tmp).map_err(|e| Error::io(path, e))?;
        let mut w = BufWriter::new(file);
        write_all(&mut w, geometry, channels, options).map_err(|e| Error::io(path, e))?;
        w.flush().map_err(|e| Error::io(path, e))
    })
}

fn write_all(
    w: &mut impl Write,
    geometry: &DfmfGeometry,
    channels: &[ChannelFactors],
    options: &DfmfOptions,
) -> std::io::Result<()> {
    let signature: &[u8] = if options.rotation_block { b"!DFMF08FCR" } else { b"!DFMF08FC" };
    w.write_all(signature)?;
    write_meta(w, options)?;
    write_directions(w, geometry)?;
    put_u32(w, geometry.width as u32)?;
    put_u32(w, geometry.height as u32)?;
    if options.rotation_block {
        put_u32(w, options.rotations.len() as u32)?;
        for r in &options.rotations {
            for v in r.iter().flatten() {
                w.write_all(&v.to_le_bytes())?;
            }
        }
    }
    let max_components = channels.iter().map(|c| c.singular_values.len()).max().unwrap_or(0);
    put_u32(w, max_components as u32)?;
    w.write_all(&options.model.id().to_le_bytes())?;
    let (mean, transform) = match options.model {
        ColourModel::Pca { mean, transform } => (mean, transform),
        _ => ([0.0; 3], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
    };
    for v in mean.iter().chain(transform.iter().flatten()) {
        w.write_all(&v.to_le_bytes())?;
    }
    for ch in channels {
        write_channel(w, ch, options.scalar)?;
    }
    Ok(())
}

/// Meta header version 4: setup, sensor and light-source text, pixels per mm, RGB scale,
/// cosine flag (0), XML (empty) and the channel names.
fn write_meta(w: &mut impl Write, options: &DfmfOptions) -> std::io::Result<()> {
    let names: [&str; 3] = match options.model {
        ColourModel::LogYUvOverY => ["log Y", "U/Y", "V/Y"],
        _ => ["R", "G", "B"],
    };
    let mut xml = String::new();
    let size = |xml: &str| {
        4 + 4 + 240 + 4 + 12 + 4 + 4 + xml.len() + 4 + names.iter().map(|n| 4 + n.len()).sum::<usize>()
    };
    // Without the rotation block the byte after the signature must not read as its `R`.
    if !options.rotation_block && size(&xml) as u8 == b'R' {
        xml.push(' ');
    }
    put_u32(w, size(&xml) as u32)?;
    put_u32(w, 4)?;
    for text in [options.measurement_setup.as_str(), "", ""] {
        let mut field = [0u8; 80];
        let bytes = text.as_bytes();
        let n = bytes.len().min(79);
        field[..n].copy_from_slice(&bytes[..n]);
        w.write_all(&field)?;
    }
    w.write_all(&0f32.to_le_bytes())?;
    for v in [1f32; 3] {
        w.write_all(&v.to_le_bytes())?;
    }
    put_u32(w, 0)?;
    put_u32(w, xml.len() as u32)?;
    w.write_all(xml.as_bytes())?;
    put_u32(w, names.len() as u32)?;
    for n in names {
        put_u32(w, n.len() as u32)?;
        w.write_all(n.as_bytes())?;
    }
    Ok(())
}

/// Per view its (θ, φ) in radians, the light count and every light's (θ, φ).
fn write_directions(w: &mut impl Write, geometry: &DfmfGeometry) -> std::io::Result<()> {
    let radians = |d: &Direction| [d.theta.to_radians(), d.phi.to_radians()];
    put_u32(w, geometry.views.len() as u32)?;
    for view in geometry.views {
        for v in radians(view) {
            w.write_all(&v.to_le_bytes())?;
        }
        put_u32(w, geometry.lights.len() as u32)?;
        for light in geometry.lights {
            for v in radians(light) {
                w.write_all(&v.to_le_bytes())?;
            }
        }
    }
    Ok(())
}

fn write_channel(w: &mut impl Write, ch: &ChannelFactors, scalar: Scalar) -> std::io::Result<()> {
    let k = ch.singular_values.len();
    w.write_all(&[scalar.size() as u8])?;
    put_u32(w, k as u32)?;
    put_u32(w, ch.u.nrows() as u32)?;
    put_u32(w, ch.sxv.nrows() as u32)?;
    put_scalars(w, ch.singular_values.iter().copied(), scalar)?;
    put_scalars(w, ch.u.iter().copied(), scalar)?;
    put_scalars(w, ch.sxv.iter().copied(), scalar)
}

fn put_scalars(w: &mut impl Write, values: impl Iterator<Item = f32>, scalar: Scalar) -> std::io::Result<()> {
    for v in values {
        match scalar {
            Scalar::F16 => w.write_all(&f16::from_f32(v).to_le_bytes())?,
            Scalar::F32 => w.write_all(&v.to_le_bytes())?,
            Scalar::F64 => w.write_all(&(v as f64).to_le_bytes())?,
        }
    }
    Ok(())
}

fn put_u32(w: &mut impl Write, v: u32) -> std::io::Result<()> {
    w.write_all(&v.to_le_bytes())
}
