//! Reading and writing single images as linear RGB `f16`.
//!
//! 8-bit and 16-bit PNG/JPEG are sRGB-decoded; EXR is linear and its R, G, B channels are
//! looked up by name (a luminance-only `Y` image is read as grey).

use crate::btf::Crop;
use crate::{Error, Result};
use half::f16;
use std::path::Path;

/// A linear RGB image, row-major, RGB interleaved.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width × height × 3` values, row `y` at `3 · y · width`.
    pub data: Vec<f16>,
}

/// File types the loaders recognise by extension (case-insensitive).
pub fn is_image_path(path: &Path) -> bool {
    matches!(extension(path).as_deref(), Some("png" | "jpg" | "jpeg" | "exr"))
}

fn extension(path: &Path) -> Option<String> {
    path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase())
}

/// Reads an image as linear RGB and applies `crop`.
pub fn read_rgb(path: &Path, crop: Option<Crop>) -> Result<RgbImage> {
    if !is_image_path(path) {
        return Err(Error::format(path, "not a PNG, JPEG or EXR file"));
    }
    let bytes = crate::fsutil::read_input(path)?;
    let image = decode_rgb(&bytes, path)?;
    match crop {
        Some(c) => crop_image(&image, c).map_err(|m| Error::format(path, m)),
        None => Ok(image),
    }
}

/// Decodes the bytes of an image file as linear RGB; `path` names the file in errors and
/// its extension picks EXR (else PNG/JPEG, told apart by their contents).
pub fn decode_rgb(bytes: &[u8], path: &Path) -> Result<RgbImage> {
    match extension(path).as_deref() {
        Some("exr") => decode_exr(bytes, path),
        _ => decode_8_or_16_bit(bytes, path),
    }
}

/// Decoded bytes per file byte that no PNG, JPEG or EXR can exceed: deflate (PNG, EXR's ZIP)
/// expands at most 1032-fold, a JPEG spends at least a bit on every 8×8 block, EXR's other
/// codecs expand less. A header declaring more pixels than this is damaged, and is refused
/// before the decoder allocates them.
const MAX_EXPANSION: u64 = 1100;

/// Refuses `width`×`height` pixels of `bits_per_pixel` if the `file_len` bytes they come
/// from could not hold them.
fn check_expansion(
    path: &Path,
    (width, height): (u64, u64),
    bits_per_pixel: u64,
    file_len: usize,
) -> Result<()> {
    let raw = width.saturating_mul(height).saturating_mul(bits_per_pixel) / 8;
    if raw > MAX_EXPANSION.saturating_mul(file_len as u64) + (1 << 16) {
        return Err(Error::format(
            path,
            format!(
                "the header declares {width}x{height} pixels, more than a file of {file_len} bytes can hold"
            ),
        ));
    }
    Ok(())
}

fn decode_8_or_16_bit(bytes: &[u8], path: &Path) -> Result<RgbImage> {
    use image::ImageDecoder;
    let cannot = |e: image::ImageError| Error::format(path, format!("cannot decode image: {e}"));
    let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    if !matches!(reader.format(), Some(image::ImageFormat::Png | image::ImageFormat::Jpeg)) {
        return Err(Error::format(path, "not a PNG or JPEG image (nor an EXR with the .exr extension)"));
    }
    if reader.format() == Some(image::ImageFormat::Jpeg) {
        check_jpeg_complete(bytes).map_err(|m| Error::format(path, m))?;
    }
    let decoder = reader.into_decoder().map_err(cannot)?;
    let (w, h) = decoder.dimensions();
    let bits = u64::from(decoder.original_color_type().bits_per_pixel());
    check_expansion(path, (w.into(), h.into()), bits, bytes.len())?;
    let decoded = image::DynamicImage::from_decoder(decoder).map_err(cannot)?;
    Ok(decoded_to_linear(decoded, false))
}

pub(crate) use super::jpeg_check::check_jpeg_complete;

/// A decoded image as linear f16 RGB: `linear` images (EXR) as they are, 8- and 16-bit
/// ones through the sRGB curve (a lookup table for 8 bits).
pub fn decoded_to_linear(decoded: image::DynamicImage, linear: bool) -> RgbImage {
    let (width, height) = (decoded.width() as usize, decoded.height() as usize);
    let data: Vec<f16> = if linear {
        decoded.to_rgb32f().into_raw().into_iter().map(f16::from_f32).collect()
    } else if decoded.color().bytes_per_pixel() / decoded.color().channel_count() > 1 {
        decoded
            .to_rgb16()
            .into_raw()
            .into_iter()
            .map(|v| f16::from_f32(srgb_to_linear(v as f32 / 65535.0)))
            .collect()
    } else {
        let lut: Vec<f16> = (0..=255u8).map(|v| f16::from_f32(srgb_to_linear(v as f32 / 255.0))).collect();
        decoded.to_rgb8().into_raw().into_iter().map(|v| lut[v as usize]).collect()
    };
    RgbImage { width, height, data }
}

fn decode_exr(bytes: &[u8], path: &Path) -> Result<RgbImage> {
    use exr::prelude::{read, MetaData, ReadChannels, ReadLayers, ReadSpecificChannel, Vec2};
    let bad = |e: exr::error::Error| Error::format(path, format!("cannot read EXR: {e}"));
    let meta = MetaData::read_from_buffered(bytes, false).map_err(bad)?;
    let header = meta.headers.first().ok_or_else(|| Error::format(path, "EXR has no layers"))?;
    let has = |name: &str| header.channels.list.iter().any(|c| c.name == *name);
    let rgb = has("R") && has("G") && has("B");
    if !rgb && !has("Y") {
        return Err(Error::format(path, "EXR has neither R, G, B nor Y channels"));
    }
    let (width, height) = (header.layer_size.width(), header.layer_size.height());
    for header in &meta.headers {
        let size = header.layer_size;
        let bits: usize = header.channels.list.iter().map(|c| 8 * c.sample_type.bytes_per_sample()).sum();
        check_expansion(path, (size.width() as u64, size.height() as u64), bits as u64, bytes.len())?;
    }
    type Pixels = (usize, Vec<f16>);
    let create = |size: Vec2<usize>| -> Pixels { (size.width(), vec![f16::ZERO; size.area() * 3]) };
    fn put((w, px): &mut Pixels, pos: Vec2<usize>, v: [f16; 3]) {
        let o = (pos.y() * *w + pos.x()) * 3;
        px[o..o + 3].copy_from_slice(&v);
    }
    let source = std::io::Cursor::new(bytes);
    let (_, data) = if rgb {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .specific_channels()
            .required("R")
            .required("G")
            .required("B")
            .collect_pixels(
                |size, _| create(size),
                move |px, pos, (r, g, b): (f16, f16, f16)| put(px, pos, [r, g, b]),
            )
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(source)
            .map_err(bad)?
            .layer_data
            .channel_data
            .pixels
    } else {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .specific_channels()
            .required("Y")
            .collect_pixels(|size, _| create(size), move |px, pos, (y,): (f16,)| put(px, pos, [y, y, y]))
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(source)
            .map_err(bad)?
            .layer_data
            .channel_data
            .pixels
    };
    if data.len() != width * height * 3 {
        return Err(Error::format(path, "EXR's first valid layer is not its first layer"));
    }
    if data.iter().any(|v| !v.is_finite()) {
        return Err(Error::format(path, "EXR contains NaN or infinite values"));
    }
    Ok(RgbImage { width, height, data })
}

/// Cuts `crop` out of `image`; the message says how the crop misses the image.
pub fn crop_image(image: &RgbImage, crop: Crop) -> Result<RgbImage, String> {
    let (x, y, w, h) = (crop.x as usize, crop.y as usize, crop.width as usize, crop.height as usize);
    if x + w > image.width || y + h > image.height {
        return Err(format!(
            "crop {x},{y},{w},{h} does not fit in the {}x{} image",
            image.width, image.height
        ));
    }
    let mut data = Vec::with_capacity(w * h * 3);
    for row in y..y + h {
        let start = (row * image.width + x) * 3;
        data.extend_from_slice(&image.data[start..start + w * 3]);
    }
    Ok(RgbImage { width: w, height: h, data })
}

/// Writes linear RGB as a half-float EXR (lossless ZIP): exact for `f16` data.
pub fn write_exr(path: &Path, width: usize, height: usize, data: &[f16]) -> Result<()> {
    use exr::prelude::{Encoding, Image, SpecificChannels, Vec2, WritableImage};
    let channels = SpecificChannels::rgb(|Vec2(x, y)| {
        let o = (y * width + x) * 3;
        (data[o], data[o + 1], data[o + 2])
    });
    Image::from_encoded_channels((width, height), Encoding::SMALL_LOSSLESS, channels)
        .write()
        .non_parallel()
        .to_file(path)
        .map_err(|e| Error::format(path, format!("cannot write EXR: {e}")))
}

/// Writes linear RGB as an 8-bit sRGB PNG (values clamped to [0, 1]).
pub fn write_png(path: &Path, width: usize, height: usize, data: &[f16]) -> Result<()> {
    let bytes: Vec<u8> = data.iter().map(|v| linear_to_srgb8(v.to_f32())).collect();
    write_png8(path, width, height, &bytes, image::ExtendedColorType::Rgb8)
}

/// Writes 8-bit pixels (`Rgb8` or `Rgba8`, rows top to bottom) as PNG.
pub fn write_png8(
    path: &Path,
    width: usize,
    height: usize,
    bytes: &[u8],
    colour: image::ExtendedColorType,
) -> Result<()> {
    image::save_buffer_with_format(path, bytes, width as u32, height as u32, colour, image::ImageFormat::Png)
        .map_err(|e| Error::format(path, format!("cannot write PNG: {e}")))
}

/// The sRGB transfer function's inverse.
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear to 8-bit sRGB, clamped and rounded.
pub fn linear_to_srgb8(v: f32) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    let s = if v <= 0.003_130_8 { v * 12.92 } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_8_bit_value() {
        for v in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb_to_linear(v as f32 / 255.0)), v);
        }
    }

    #[test]
    fn crop_outside_the_image_is_an_error() {
        let img = RgbImage { width: 4, height: 3, data: (0..36).map(|v| f16::from_f32(v as f32)).collect() };
        let c = crop_image(&img, Crop { x: 1, y: 1, width: 2, height: 2 }).unwrap();
        assert_eq!(c.data[0].to_f32(), 15.0);
        assert_eq!(c.data[3].to_f32(), 18.0);
        assert_eq!(c.data[6].to_f32(), 27.0);
        assert!(crop_image(&img, Crop { x: 3, y: 0, width: 2, height: 1 }).is_err());
    }
}
