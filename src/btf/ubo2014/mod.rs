//! Bonn University's binary BTF files (`.btf`), the format of the UBO2014 materials, with
//! btflib (Bonn's MATLAB reader) as the reference for the layout.
//!
//! All little-endian: a signature; a meta header (size, version, measurement setup, image
//! sensor, light source, pixels per mm, RGB scale, then by version a cosine flag, an XML
//! description and channel names); the direction table (per view θ, φ in radians, then its
//! lights); the image size; an optional block of frame rotations; then the body:
//!
//! - **DFMF**: per colour channel (after a colour model such as log-Y, U/Y, V/Y) an SVD of
//!   the (lights · views) × (width · height) matrix: S, U and SxV. A texel is
//!   Σₖ U\[l + lights · v\]\[k\] · SxV\[x + width · y\]\[k\], then the colour model is undone.
//! - **FMF**: one SVD whose rows interleave the channels; FMF12 adds a dynamic-range flag
//!   (the data are log(value + ε)) and a height map.
//! - **BDI**: raw half-float ABRDFs, in chunks of scan lines (uncompressed or sparse).
//!
//! Opening a file reads only its header; [`BonnBtf::into_window`] reads the factor rows a
//! crop needs, and images are multiplied out when asked for. Lights may differ from views
//! in number. PVF files and bzip2-compressed BDIs are refused as "not supported yet".

mod bdi;
mod body;
pub mod bytes;
mod factors;
mod header;
pub mod write;

pub use factors::Scalar;
pub use header::{Meta, Rotation, Variant};

use crate::btf::colour::ColourModel;
use crate::btf::factored::{decode_channels, saturating_f16, FactoredStack};
use crate::btf::source::{ensure_fits_in_memory, resolve_crop, ImageSource};
use crate::btf::{Btf, Crop, DirectionPair};
use crate::progress::Progress;
use crate::{Error, Result};
use bdi::BdiBody;
use body::{FactorBody, Shape};
use bytes::{Bytes, Cursor};
use factors::Factors;
use half::f16;
use rayon::prelude::*;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// An opened Bonn BTF file: its header, and where its body's data lie.
pub struct BonnBtf {
    path: PathBuf,
    bytes: Bytes,
    signature: &'static str,
    variant: Variant,
    meta: Meta,
    views: usize,
    lights: usize,
    pairs: Vec<DirectionPair>,
    width: usize,
    height: usize,
    rotations: Vec<Rotation>,
    body: Body,
}

enum Body {
    Factors(FactorBody),
    Bdi(BdiBody),
}

/// True for a file named `*.btf` or one that starts like a Bonn signature.
pub fn is_bonn_file(path: &Path) -> bool {
    if !path.is_file() {
        return false;
    }
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("btf")) {
        return true;
    }
    let mut start = [0u8; 5];
    let read = std::fs::File::open(path).and_then(|mut f| std::io::Read::read_exact(&mut f, &mut start));
    read.is_ok() && [&b"!DFMF"[..], b"!FMF1", b"!FMF0", b"!PVF0", b"!BDIF"].contains(&&start[..])
}

impl BonnBtf {
    /// Opens `path` and reads its header; the body is read later, as needed.
    pub fn open(path: &Path) -> Result<Self> {
        Self::parse(path, Bytes::open(path)?)
    }

    /// Reads a file held in memory (`path` names it in messages).
    pub fn from_bytes(path: &Path, data: Vec<u8>) -> Result<Self> {
        Self::parse(path, Bytes::Memory(data.into()))
    }

    fn parse(path: &Path, bytes: Bytes) -> Result<Self> {
        let mut start = vec![0u8; bytes.size().min(10) as usize];
        bytes.read_at(path, 0, &mut start)?;
        let candidates = header::candidate_signatures(&start);
        let Some(&(first_signature, _)) = candidates.first() else {
            let known: Vec<&str> = header::SIGNATURES.iter().map(|(s, _)| *s).collect();
            return Err(Error::format(
                path,
                format!(
                    "signature: not a Bonn BTF file (it starts with {:?}; expected one of {})",
                    String::from_utf8_lossy(&start),
                    known.join(", ")
                ),
            ));
        };
        let mut first_error = None;
        for &(signature, variant) in &candidates {
            match Self::parse_as(path, &bytes, signature, variant) {
                Ok(parts) => return Ok(parts.into_file(path, bytes, signature, variant)),
                Err(e) if signature == first_signature => first_error = Some(e),
                Err(_) => {}
            }
        }
        Err(first_error.unwrap_or_else(|| Error::format(path, "signature: unreadable")))
    }

    fn parse_as(path: &Path, bytes: &Bytes, signature: &str, variant: Variant) -> Result<Parts> {
        let mut c = Cursor::new(bytes, path, signature.len() as u64);
        if variant == Variant::Pvf {
            return Err(c.error(format!("not supported yet: PVF (per-view factorization, {signature})")));
        }
        let meta = header::read_meta(&mut c)?;
        if meta.channels.len() != 3 {
            return Err(c.error(format!(
                "not supported yet: {}-channel data ({}); btfsynth reads 3-channel (RGB) files",
                meta.channels.len(),
                meta.channels.join(", ")
            )));
        }
        let directions = header::read_directions(&mut c)?;
        let (width, height) = header::read_size(&mut c)?;
        let images = directions.pairs.len();
        let shape = Shape { images: images as u64, pixels: width as u64 * height as u64, channels: 3 };
        let (rotations, body) = match variant {
            Variant::Bdi => {
                let head = bdi::read_head(&mut c, width, height)?;
                let rotations = header::read_rotations(&mut c)?;
                (rotations, Body::Bdi(bdi::read_chunks(&mut c, head, width, 3 * images)?))
            }
            _ => {
                let rotations = match header::has_rotation_block(signature) {
                    true => header::read_rotations(&mut c)?,
                    false => Vec::new(),
                };
                let body = match variant {
                    Variant::Fmf { extended } => body::read_fmf(&mut c, &shape, extended),
                    _ => body::read_dfmf(&mut c, &shape),
                };
                let body = body.map_err(|e| after_rotations(e, signature, rotations.len()))?;
                (rotations, Body::Factors(body))
            }
        };
        if c.remaining() > 0 {
            tracing::warn!("{}: {} bytes after the data are ignored", path.display(), c.remaining());
        }
        Ok(Parts { meta, directions, width, height, rotations, body })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Width of the images in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height of the images in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Every image's (light, view) pair, image `l + lights · v`.
    pub fn pairs(&self) -> &[DirectionPair] {
        &self.pairs
    }

    /// Number of views and of lights per view.
    pub fn views_and_lights(&self) -> (usize, usize) {
        (self.views, self.lights)
    }

    /// The signature the file starts with.
    pub fn signature(&self) -> &'static str {
        self.signature
    }

    /// The meta header.
    pub fn meta(&self) -> &Meta {
        &self.meta
    }

    /// The frame rotations of the rotation block (often none).
    pub fn rotations(&self) -> &[Rotation] {
        &self.rotations
    }

    /// The file described as JSON: its kind, size, directions and factors (what the command
    /// line's `info` prints as JSON).
    pub fn describe(&self) -> serde_json::Value {
        let file_bytes = self.bytes.size();
        let mut d = serde_json::json!({
            "kind": "btf-file",
            "path": self.path.display().to_string(),
            "format": self.variant.name(),
            "signature": self.signature,
            "file_bytes": file_bytes,
            "width": self.width,
            "height": self.height,
            "images": self.pairs.len(),
            "views": self.views,
            "lights": self.lights,
            "rotations": self.rotations.len(),
            "header": {
                "version": self.meta.version,
                "measurement_setup": self.meta.measurement_setup,
                "image_sensor": self.meta.image_sensor,
                "light_source": self.meta.light_source,
                "pixels_per_mm": self.meta.pixels_per_mm,
                "rgb_scale": self.meta.rgb_scale,
                "cosine_flag": self.meta.cosine_flag,
                "channels": self.meta.channels,
                "xml_bytes": self.meta.xml.len(),
            },
        });
        match &self.body {
            Body::Factors(f) => {
                d["components"] = f.channels.iter().map(|c| c.components).collect::<Vec<_>>().into();
                d["scalar"] = format!("{:?}", f.scalar).to_lowercase().into();
                d["colour_model"] = serde_json::json!({"id": f.model.id(), "name": f.model.name()});
                d["dynamic_range_reduction"] = f.log_encoded.into();
                d["height_map"] = f.height_map.map(|(r, c)| [r, c]).into();
            }
            Body::Bdi(b) => {
                d["compression"] = b.compression.into();
                d["scan_lines_per_chunk"] = b.scan_lines_per_chunk.into();
            }
        }
        d
    }

    /// For a factorized file (DFMF, FMF): its colour model, whether its data are
    /// log-encoded, and the components of each channel, read from the header alone.
    pub fn factor_layout(&self) -> Option<(ColourModel, bool, Vec<usize>)> {
        match &self.body {
            Body::Factors(f) => {
                Some((f.model, f.log_encoded, f.channels.iter().map(|c| c.components).collect()))
            }
            Body::Bdi(_) => None,
        }
    }

    /// Prepares decoding of `crop` (the whole sample if `None`): reads the factor rows
    /// the crop needs. Images are decoded when asked for.
    pub fn into_window(self, crop: Option<Crop>) -> Result<Window> {
        let crop = resolve_crop(&self.path, crop, self.width, self.height)?;
        let light_scale = self.light_scale();
        let decoder = match self.body {
            Body::Factors(f) => {
                let rows: Vec<Range<u64>> = (crop.y..crop.y + crop.height)
                    .map(|y| {
                        let start = crop.x as u64 + self.width as u64 * y as u64;
                        start..start + crop.width as u64
                    })
                    .collect();
                let factors =
                    Factors::read(&f.channels, self.pairs.len() as u64, &rows, &self.bytes, &self.path)?;
                Decoder::Factors { factors, model: f.model, log_encoded: f.log_encoded }
            }
            Body::Bdi(b) => Decoder::Bdi(b),
        };
        Ok(Window {
            path: self.path,
            bytes: self.bytes,
            full_width: self.width,
            pairs: self.pairs,
            rotations: self.rotations,
            crop,
            light_scale,
            decoder,
        })
    }

    /// Per image, the factor decoding multiplies by: 1/cos θ_light when the file's cosine
    /// flag says the data hold that cosine (clamped at 0.001 so a horizon light stays
    /// finite), else 1.
    fn light_scale(&self) -> Vec<f32> {
        self.pairs
            .iter()
            .map(|p| match self.meta.cosine_flag {
                true => 1.0 / p.light.theta.to_radians().cos().max(1e-3),
                false => 1.0,
            })
            .collect()
    }
}

/// A body that does not parse may be misread because the rotation count before it is
/// wrong; the message says so, naming the block.
fn after_rotations(e: Error, signature: &str, count: usize) -> Error {
    match e {
        Error::Format { path, message } if header::has_rotation_block(signature) => Error::Format {
            path,
            message: format!(
                "{message} (after a rotation block of {count} matrices: if that count is wrong, everything after it is misread)"
            ),
        },
        other => other,
    }
}

/// A parsed header and body, before they are put together with the bytes.
struct Parts {
    meta: Meta,
    directions: header::Directions,
    width: usize,
    height: usize,
    rotations: Vec<Rotation>,
    body: Body,
}

impl Parts {
    fn into_file(self, path: &Path, bytes: Bytes, signature: &'static str, variant: Variant) -> BonnBtf {
        BonnBtf {
            path: path.to_path_buf(),
            bytes,
            signature,
            variant,
            meta: self.meta,
            views: self.directions.views,
            lights: self.directions.lights,
            pairs: self.directions.pairs,
            width: self.width,
            height: self.height,
            rotations: self.rotations,
            body: self.body,
        }
    }
}

/// A crop of a Bonn file, ready to decode: the factor rows it needs are in memory.
pub struct Window {
    path: PathBuf,
    bytes: Bytes,
    full_width: usize,
    pairs: Vec<DirectionPair>,
    rotations: Vec<Rotation>,
    crop: Crop,
    light_scale: Vec<f32>,
    decoder: Decoder,
}

enum Decoder {
    Factors { factors: Factors, model: ColourModel, log_encoded: bool },
    Bdi(BdiBody),
}

impl Window {
    /// The file's frame rotations (carried over when the stack is written again).
    pub fn rotations(&self) -> &[Rotation] {
        &self.rotations
    }

    /// Turns one texel's channel values into linear RGB: undo the colour model, then the
    /// log encoding, then the cosine.
    fn finish(&self, v: [f32; 3], image: usize) -> [f16; 3] {
        let scale = self.light_scale[image];
        let rgb = match &self.decoder {
            Decoder::Factors { model, log_encoded, .. } => decode_channels(*model, *log_encoded, scale, v),
            Decoder::Bdi(_) => v.map(|x| x * scale),
        };
        rgb.map(saturating_f16)
    }

    /// Whether the file holds factors (DFMF, FMF) rather than images (BDI).
    pub fn is_factored(&self) -> bool {
        matches!(self.decoder, Decoder::Factors { .. })
    }

    /// The crop as its factors (a DFMF or FMF file), with the decoding the images would go
    /// through; an error for a file that holds images (BDI, see [`Window::is_factored`]).
    pub fn into_factored(self) -> Result<FactoredStack> {
        let (width, height) = (self.crop.width as usize, self.crop.height as usize);
        match self.decoder {
            Decoder::Factors { factors: Factors { image, pixel }, model, log_encoded } => FactoredStack::new(
                &self.path,
                (width, height),
                self.pairs,
                image,
                pixel,
                model,
                log_encoded,
                self.light_scale,
            ),
            Decoder::Bdi(_) => Err(Error::format(&self.path, "a BDI file holds images, not factors")),
        }
    }

    /// Bytes of the factor rows this window holds in memory (0 for a BDI).
    pub fn factor_bytes(&self) -> u64 {
        match &self.decoder {
            Decoder::Factors { factors, .. } => {
                factors.image.iter().chain(&factors.pixel).map(|a| a.len() as u64 * 4).sum()
            }
            Decoder::Bdi(_) => 0,
        }
    }

    fn pixels(&self) -> usize {
        self.crop.width as usize * self.crop.height as usize
    }

    /// Decodes the images of `block` into `out` (`[image][pixel][3]`).
    fn decode_factor_block(&self, factors: &Factors, block: Range<usize>, out: &mut [f16]) {
        let values = factors.product(block.clone());
        for (k, (dst, src)) in out.chunks_exact_mut(3).zip(values.chunks_exact(3)).enumerate() {
            let image = block.start + k / self.pixels();
            dst.copy_from_slice(&self.finish([src[0], src[1], src[2]], image));
        }
    }

    fn decode_all_factors(&self, factors: &Factors, out: &mut [f16], progress: &dyn Progress) {
        let (pixels, images) = (self.pixels(), self.pairs.len());
        // Blocks of about 4 M values keep the products' scratch small.
        let block = ((4 << 20) / (pixels * 3).max(1)).clamp(1, images);
        progress.start("decoding images", images as u64);
        out.par_chunks_mut(block * pixels * 3).enumerate().for_each(|(b, chunk)| {
            let start = b * block;
            let n = chunk.len() / (pixels * 3);
            self.decode_factor_block(factors, start..start + n, chunk);
            progress.advance(n as u64);
        });
        progress.finish();
    }

    fn decode_all_bdi(&self, body: &BdiBody, out: &mut [f16], progress: &dyn Progress) -> Result<()> {
        let pixels = self.pixels();
        progress.start("reading ABRDFs", pixels as u64);
        body.for_each_texel(&self.bytes, &self.path, self.full_width, self.crop, |k, abrdf| {
            for (i, v) in abrdf.chunks_exact(3).enumerate() {
                let at = (i * pixels + k) * 3;
                out[at..at + 3].copy_from_slice(&self.finish([v[0], v[1], v[2]], i));
            }
            progress.advance(1);
            Ok(())
        })?;
        progress.finish();
        Ok(())
    }
}

impl ImageSource for Window {
    fn path(&self) -> &Path {
        &self.path
    }

    fn width(&self) -> usize {
        self.crop.width as usize
    }

    fn height(&self) -> usize {
        self.crop.height as usize
    }

    fn pairs(&self) -> &[DirectionPair] {
        &self.pairs
    }

    fn decode_image(&self, i: usize, out: &mut [f16]) -> Result<()> {
        match &self.decoder {
            Decoder::Factors { factors, .. } => self.decode_factor_block(factors, i..i + 1, out),
            Decoder::Bdi(body) => {
                let raw = body.image(&self.bytes, &self.path, self.full_width, self.crop, i)?;
                for (dst, v) in out.chunks_exact_mut(3).zip(raw.chunks_exact(3)) {
                    dst.copy_from_slice(&self.finish([v[0], v[1], v[2]], i));
                }
            }
        }
        Ok(())
    }

    fn decode_all(&self, progress: &dyn Progress) -> Result<Btf> {
        let (pixels, images) = (self.pixels(), self.pairs.len());
        ensure_fits_in_memory(&self.path, images, pixels * 3)?;
        let mut out = vec![f16::ZERO; images * pixels * 3];
        match &self.decoder {
            Decoder::Factors { factors, .. } => self.decode_all_factors(factors, &mut out, progress),
            Decoder::Bdi(body) => self.decode_all_bdi(body, &mut out, progress)?,
        }
        Btf::new(self.width(), self.height(), self.pairs.clone(), out)
    }
}
