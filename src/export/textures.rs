//! Baked buffers as the image files glTF slots take.
//!
//! | slot | file | content |
//! |---|---|---|
//! | `baseColorTexture` | `baseColor.png` | 8-bit sRGB RGB |
//! | `normalTexture` | `normal.png` | tangent-space normal, (n + 1) / 2, linear RGB |
//! | `metallicRoughnessTexture`, `occlusionTexture` | `occlusionRoughnessMetallic.png` | R occlusion, G roughness, B metalness (one texture for both slots, as glTF allows) |
//! | `extras.btfsynth.height` | `height.png` | 16-bit grey, (h − min) / (max − min) |
//! | `extras.btfsynth.sampleCoordinates` | `sampleCoordinates.png` or `.exr` | see [`coordinate_image`] |
//!
//! Slot textures are 8-bit unless a map behind them was 16-bit or float; then 16-bit.

use super::gltf::ImageData;
use crate::btf::image_io::linear_to_srgb8;
use crate::{Error, Result};
use glam::{Vec2, Vec3};
use std::io::Cursor;

/// How the sample-coordinate map is stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CoordinateFormat {
    /// 16-bit RGB PNG, normalised (see [`coordinate_image`]).
    #[default]
    Png,
    /// 32-bit float RGB EXR, in texels.
    Exr,
}

/// The base colour: linear RGB as 8-bit sRGB.
pub fn base_colour_image(width: usize, height: usize, colour: &[Vec3]) -> Result<ImageData> {
    let bytes: Vec<u8> = colour.iter().flat_map(|c| c.to_array().map(linear_to_srgb8)).collect();
    png("baseColor", width, height, Samples::Eight(bytes), 3)
}

/// Linear values in [0, 1] (three per texel) as RGB, 8- or 16-bit.
pub fn linear_image(
    name: &str,
    width: usize,
    height: usize,
    values: &[Vec3],
    wide: bool,
) -> Result<ImageData> {
    let flat = values.iter().flat_map(|v| v.to_array());
    let samples = if wide {
        Samples::Sixteen(flat.map(|v| (v.clamp(0.0, 1.0) * 65535.0).round() as u16).collect())
    } else {
        Samples::Eight(flat.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8).collect())
    };
    png(name, width, height, samples, 3)
}

/// A height map's first channel as 16-bit grey, scaled from its (min, max), which are
/// returned to be recorded beside it.
pub fn height_image(width: usize, height: usize, values: &[Vec3]) -> Result<(ImageData, f32, f32)> {
    let (lo, hi) =
        values.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| (lo.min(v.x), hi.max(v.x)));
    let range = if hi > lo { hi - lo } else { 1.0 };
    let samples = values.iter().map(|v| ((v.x - lo) / range * 65535.0).round() as u16).collect();
    Ok((png("height", width, height, Samples::Sixteen(samples), 1)?, lo, hi))
}

/// The sample-coordinate map, for engines that do their own BTF lookups: per texel the
/// sample coordinate (u, v) in texels (texel centres at integers, u along columns, v down
/// rows) and whether the texel was baked from a triangle (else it is gutter fill).
/// PNG: R = (u + ½) / width, G = (v + ½) / height, B = 1 if baked, as 16-bit unsigned
/// normalised. EXR: R = u, G = v, B = 1 or 0, as 32-bit floats.
pub fn coordinate_image(
    format: CoordinateFormat,
    (width, height): (usize, usize),
    coordinates: &[Vec2],
    covered: &[bool],
    sample: (usize, usize),
) -> Result<ImageData> {
    let flag = |k: usize| if covered[k] { 1.0 } else { 0.0 };
    match format {
        CoordinateFormat::Png => {
            let (sw, sh) = (sample.0 as f32, sample.1 as f32);
            let unorm = |v: f32| (v.clamp(0.0, 1.0) * 65535.0).round() as u16;
            let samples = coordinates
                .iter()
                .enumerate()
                .flat_map(|(k, c)| [unorm((c.x + 0.5) / sw), unorm((c.y + 0.5) / sh), unorm(flag(k))])
                .collect();
            png("sampleCoordinates", width, height, Samples::Sixteen(samples), 3)
        }
        CoordinateFormat::Exr => {
            let rgb: Vec<[f32; 3]> =
                coordinates.iter().enumerate().map(|(k, c)| [c.x, c.y, flag(k)]).collect();
            exr("sampleCoordinates", width, height, &rgb)
        }
    }
}

/// Samples of a PNG, 8- or 16-bit.
enum Samples {
    Eight(Vec<u8>),
    Sixteen(Vec<u16>),
}

fn png(name: &str, width: usize, height: usize, samples: Samples, channels: usize) -> Result<ImageData> {
    use image::ExtendedColorType as C;
    use image::ImageEncoder;
    let (bytes, colour) = match (samples, channels) {
        (Samples::Eight(b), 1) => (b, C::L8),
        (Samples::Eight(b), _) => (b, C::Rgb8),
        // The encoder takes 16-bit samples in native byte order.
        (Samples::Sixteen(s), 1) => (s.iter().flat_map(|v| v.to_ne_bytes()).collect(), C::L16),
        (Samples::Sixteen(s), _) => (s.iter().flat_map(|v| v.to_ne_bytes()).collect(), C::Rgb16),
    };
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&bytes, width as u32, height as u32, colour)
        .map_err(|e| Error::invalid(format!("cannot encode the {name} texture: {e}")))?;
    Ok(ImageData { name: name.to_string(), mime: "image/png", extension: "png", bytes: out })
}

fn exr(name: &str, width: usize, height: usize, rgb: &[[f32; 3]]) -> Result<ImageData> {
    use exr::prelude::{Encoding, Image, SpecificChannels, Vec2 as Size, WritableImage};
    let channels = SpecificChannels::rgb(|Size(x, y)| {
        let [r, g, b] = rgb[y * width + x];
        (r, g, b)
    });
    let mut out = Cursor::new(Vec::new());
    Image::from_encoded_channels((width, height), Encoding::SMALL_LOSSLESS, channels)
        .write()
        .non_parallel()
        .to_buffered(&mut out)
        .map_err(|e| Error::invalid(format!("cannot encode the {name} texture: {e}")))?;
    Ok(ImageData { name: name.to_string(), mime: "image/x-exr", extension: "exr", bytes: out.into_inner() })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(image: &ImageData) -> image::DynamicImage {
        image::load_from_memory(&image.bytes).expect("decodes")
    }

    #[test]
    fn coordinates_round_trip_at_16_bits() {
        let coords = [Vec2::new(0.0, 63.0), Vec2::new(31.25, 7.5)];
        let png = coordinate_image(CoordinateFormat::Png, (2, 1), &coords, &[true, false], (64, 64))
            .expect("encodes");
        let rgb = decode(&png).to_rgb16();
        for (k, c) in coords.iter().enumerate() {
            let p = rgb.get_pixel(k as u32, 0).0;
            let u = p[0] as f32 / 65535.0 * 64.0 - 0.5;
            let v = p[1] as f32 / 65535.0 * 64.0 - 0.5;
            assert!((u - c.x).abs() < 1e-3 && (v - c.y).abs() < 1e-3, "{u} {v} vs {c}");
        }
        assert_eq!((rgb.get_pixel(0, 0).0[2], rgb.get_pixel(1, 0).0[2]), (65535, 0));
        let exr = coordinate_image(CoordinateFormat::Exr, (2, 1), &coords, &[true, false], (64, 64))
            .expect("encodes");
        let back = decode(&exr).to_rgb32f();
        assert_eq!(back.get_pixel(1, 0).0, [31.25, 7.5, 0.0]);
    }

    #[test]
    fn height_is_scaled_from_its_range() {
        let (png, lo, hi) =
            height_image(3, 1, &[Vec3::splat(-2.0), Vec3::splat(0.0), Vec3::splat(6.0)]).expect("encodes");
        assert_eq!((lo, hi), (-2.0, 6.0));
        let grey = decode(&png).to_luma16();
        assert_eq!(grey.as_raw(), &vec![0, 16384, 65535]);
    }
}
