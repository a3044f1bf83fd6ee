//! One map image at the depth its file has: 8- or 16-bit PNG (JPEG reads as 8-bit and is
//! written back as PNG, losslessly), half or float EXR, with its channels as they are (grey,
//! grey + alpha, RGB, RGBA, or any named EXR channels). Values are data, not colour: no
//! sRGB transfer is applied either way.

use crate::fsutil::write_with_temp;
use crate::{Error, Result};
use exr::prelude::{
    read, AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, ReadChannels,
    ReadLayers, SmallVec, WritableImage,
};
use half::f16;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// How a map's samples are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Depth {
    /// 8-bit unsigned integers (PNG or JPEG), 0–255.
    U8,
    /// 16-bit unsigned integers (PNG), 0–65535.
    U16,
    /// 16-bit floats (EXR).
    F16,
    /// 32-bit floats (EXR).
    F32,
}

impl Depth {
    /// The file extension a map of this depth is written with.
    pub fn extension(self) -> &'static str {
        match self {
            Depth::U8 | Depth::U16 => "png",
            Depth::F16 | Depth::F32 => "exr",
        }
    }

    /// The stored value that means 1.0 (integers are normalised; floats are not).
    pub fn unit(self) -> f32 {
        match self {
            Depth::U8 => 255.0,
            Depth::U16 => 65535.0,
            Depth::F16 | Depth::F32 => 1.0,
        }
    }

    /// True for EXR depths, whose values are taken as they are.
    pub fn is_float(self) -> bool {
        matches!(self, Depth::F16 | Depth::F32)
    }
}

/// A map image. Every stored value (an 8- or 16-bit integer, a half or a float) is held
/// exactly in an `f32`, so reading and writing back gives the same samples.
#[derive(Clone, Debug, PartialEq)]
pub struct MapImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Channel names, in storage order: `Y`, `YA`, `RGB`, `RGBA` for PNG; the file's names
    /// for EXR, with R, G, B, A first and Y next when present.
    pub channels: Vec<String>,
    /// How the samples are stored.
    pub depth: Depth,
    /// `[height][width][channels]` stored values (see [`MapImage`]).
    pub data: Vec<f32>,
}

impl MapImage {
    /// Reads a PNG, JPEG or EXR map.
    pub fn read(path: &Path) -> Result<MapImage> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
        let image = match ext.as_str() {
            "png" | "jpg" | "jpeg" => read_integer(path)?,
            "exr" => read_exr(path)?,
            _ => return Err(Error::format(path, "a map must be a PNG, JPEG or EXR image")),
        };
        if image.width == 0 || image.height == 0 {
            return Err(Error::format(path, "the map has no pixels"));
        }
        Ok(image)
    }

    /// Writes the map at its depth: PNG for integers, EXR (lossless ZIP) for floats. The
    /// extension of `path` should be [`Depth::extension`].
    pub fn write(&self, path: &Path) -> Result<()> {
        write_with_temp(path, |tmp| {
            if self.depth.is_float() {
                self.write_exr(tmp, path)
            } else {
                self.write_png(tmp, path)
            }
        })
    }

    /// Number of channels.
    pub fn channel_count(&self) -> usize {
        self.channels.len()
    }

    /// The stored values of pixel (x, y).
    pub fn pixel(&self, x: usize, y: usize) -> &[f32] {
        let n = self.channel_count();
        let o = (y * self.width + x) * n;
        &self.data[o..o + n]
    }

    /// The rectangle `(x, y, w, h)`, which must lie inside the image.
    pub fn crop(&self, (x, y, w, h): (usize, usize, usize, usize)) -> MapImage {
        let n = self.channel_count();
        let mut data = Vec::with_capacity(w * h * n);
        for row in y..y + h {
            let start = (row * self.width + x) * n;
            data.extend_from_slice(&self.data[start..start + w * n]);
        }
        MapImage { width: w, height: h, channels: self.channels.clone(), depth: self.depth, data }
    }

    /// A `width × height` map whose pixel i is this map's pixel at `coordinates[i]` (sample
    /// texels, brought inside by clamping): the map copied through a synthesized coordinate
    /// map, sample for sample.
    pub fn resample(&self, width: usize, height: usize, coordinates: &[[i32; 2]]) -> MapImage {
        let n = self.channel_count();
        let mut data = Vec::with_capacity(width * height * n);
        for &[x, y] in coordinates.iter().take(width * height) {
            let x = x.clamp(0, self.width as i32 - 1) as usize;
            let y = y.clamp(0, self.height as i32 - 1) as usize;
            data.extend_from_slice(self.pixel(x, y));
        }
        MapImage { width, height, channels: self.channels.clone(), depth: self.depth, data }
    }

    /// The first three channels (the first repeated for one- and two-channel maps) as
    /// normalised values (integers / their maximum, floats as they are), row-major RGB.
    pub fn normalised_rgb(&self) -> Vec<f32> {
        let (n, unit) = (self.channel_count(), self.depth.unit());
        let pick = |c: usize| if n >= 3 { c } else { 0 };
        self.data.chunks_exact(n).flat_map(|p| [0, 1, 2].map(|c| p[pick(c)] / unit)).collect()
    }

    fn write_png(&self, tmp: &Path, path: &Path) -> Result<()> {
        use image::ExtendedColorType as C;
        let colour = match (self.depth, self.channel_count()) {
            (Depth::U8, 1) => C::L8,
            (Depth::U8, 2) => C::La8,
            (Depth::U8, 3) => C::Rgb8,
            (Depth::U8, 4) => C::Rgba8,
            (Depth::U16, 1) => C::L16,
            (Depth::U16, 2) => C::La16,
            (Depth::U16, 3) => C::Rgb16,
            (Depth::U16, 4) => C::Rgba16,
            _ => return Err(Error::invalid(format!("{}: cannot store this map as PNG", path.display()))),
        };
        let bytes: Vec<u8> = if self.depth == Depth::U8 {
            self.data.iter().map(|&v| v as u8).collect()
        } else {
            // The PNG encoder takes 16-bit samples in native byte order.
            self.data.iter().flat_map(|&v| (v as u16).to_ne_bytes()).collect()
        };
        let (w, h) = (self.width as u32, self.height as u32);
        image::save_buffer_with_format(tmp, &bytes, w, h, colour, image::ImageFormat::Png)
            .map_err(|e| Error::format(path, format!("cannot write PNG: {e}")))
    }

    fn write_exr(&self, tmp: &Path, path: &Path) -> Result<()> {
        let n = self.channel_count();
        let channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = (0..n)
            .map(|c| {
                let values = self.data.iter().skip(c).step_by(n).copied();
                let samples = match self.depth {
                    Depth::F16 => FlatSamples::F16(values.map(f16::from_f32).collect()),
                    _ => FlatSamples::F32(values.collect()),
                };
                AnyChannel::new(self.channels[c].as_str(), samples)
            })
            .collect();
        let layer = Layer::new(
            (self.width, self.height),
            LayerAttributes::default(),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(channels),
        );
        Image::from_layer(layer)
            .write()
            .non_parallel()
            .to_file(tmp)
            .map_err(|e| Error::format(path, format!("cannot write EXR: {e}")))
    }
}

fn read_integer(path: &Path) -> Result<MapImage> {
    use image::ColorType as C;
    let reader = image::ImageReader::open(path)
        .map_err(|e| Error::io(path, e))?
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    let decoded = reader.decode().map_err(|e| Error::format(path, format!("cannot decode image: {e}")))?;
    let (width, height) = (decoded.width() as usize, decoded.height() as usize);
    let (names, depth) = match decoded.color() {
        C::L8 => ("Y", Depth::U8),
        C::La8 => ("YA", Depth::U8),
        C::Rgb8 => ("RGB", Depth::U8),
        C::Rgba8 => ("RGBA", Depth::U8),
        C::L16 => ("Y", Depth::U16),
        C::La16 => ("YA", Depth::U16),
        C::Rgb16 => ("RGB", Depth::U16),
        C::Rgba16 => ("RGBA", Depth::U16),
        other => return Err(Error::format(path, format!("unsupported map pixel type {other:?}"))),
    };
    let data: Vec<f32> = if depth == Depth::U8 {
        decoded.into_bytes().into_iter().map(f32::from).collect()
    } else {
        let wide = match decoded {
            image::DynamicImage::ImageLuma16(i) => i.into_raw(),
            image::DynamicImage::ImageLumaA16(i) => i.into_raw(),
            image::DynamicImage::ImageRgb16(i) => i.into_raw(),
            image::DynamicImage::ImageRgba16(i) => i.into_raw(),
            _ => return Err(Error::format(path, "unsupported 16-bit map layout")),
        };
        wide.into_iter().map(f32::from).collect()
    };
    let channels = names.chars().map(String::from).collect();
    Ok(MapImage { width, height, channels, depth, data })
}

fn read_exr(path: &Path) -> Result<MapImage> {
    let bad = |e: exr::error::Error| Error::format(path, format!("cannot read EXR: {e}"));
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_file(path)
        .map_err(bad)?;
    let layer = image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let mut list: Vec<&AnyChannel<FlatSamples>> = layer.channel_data.list.iter().collect();
    list.sort_by_key(|c| (channel_rank(&c.name.to_string()), c.name.to_string()));
    let mut depth = Depth::F16;
    for c in &list {
        match c.sample_data {
            FlatSamples::F16(_) => {}
            FlatSamples::F32(_) => depth = Depth::F32,
            FlatSamples::U32(_) => return Err(Error::format(path, "integer EXR channels are not supported")),
        }
        if c.sample_data.len() != width * height {
            return Err(Error::format(path, "subsampled EXR channels are not supported"));
        }
    }
    let n = list.len();
    let mut data = vec![0.0f32; width * height * n];
    for (k, c) in list.iter().enumerate() {
        for (i, v) in c.sample_data.values_as_f32().enumerate() {
            data[i * n + k] = v;
        }
    }
    if data.iter().any(|v| !v.is_finite()) {
        return Err(Error::format(path, "the EXR map contains NaN or infinite values"));
    }
    let channels = list.iter().map(|c| c.name.to_string()).collect();
    Ok(MapImage { width, height, channels, depth, data })
}

/// R, G, B, A first (in that order), then Y, then the rest by name.
fn channel_rank(name: &str) -> usize {
    ["R", "G", "B", "A", "Y"].iter().position(|&n| n == name).unwrap_or(5)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(depth: Depth, channels: &[&str], w: usize, h: usize) -> MapImage {
        let n = channels.len();
        let data = (0..w * h * n)
            .map(|i| match depth {
                Depth::U8 => (i * 37 % 256) as f32,
                Depth::U16 => (i * 7919 % 65536) as f32,
                Depth::F16 => f16::from_f32(i as f32 * 0.013 - 2.0).to_f32(),
                Depth::F32 => i as f32 * 0.0137 - 1.5e-3,
            })
            .collect();
        MapImage {
            width: w,
            height: h,
            channels: channels.iter().map(|c| c.to_string()).collect(),
            depth,
            data,
        }
    }

    #[test]
    fn every_depth_and_layout_round_trips_exactly() {
        let dir = tempfile::tempdir().expect("temp dir");
        let cases = [
            (Depth::U8, &["Y"][..]),
            (Depth::U8, &["R", "G", "B"][..]),
            (Depth::U16, &["Y", "A"][..]),
            (Depth::U16, &["R", "G", "B", "A"][..]),
            (Depth::F16, &["Y"][..]),
            (Depth::F32, &["R", "G", "B"][..]),
            (Depth::F32, &["height"][..]),
        ];
        for (k, (depth, channels)) in cases.into_iter().enumerate() {
            let map = ramp(depth, channels, 7, 5);
            let path = dir.path().join(format!("map{k}.{}", depth.extension()));
            map.write(&path).expect("writes");
            let back = MapImage::read(&path).expect("reads");
            let expected_names: Vec<String> = if depth.is_float() {
                map.channels.clone()
            } else {
                channels.concat().chars().map(String::from).collect()
            };
            assert_eq!(back.channels, expected_names, "{depth:?}");
            assert_eq!((back.depth, back.width, back.height), (depth, 7, 5));
            assert_eq!(back.data, map.data, "{depth:?} {channels:?}");
        }
    }

    #[test]
    fn resampling_copies_samples_through_coordinates() {
        let map = ramp(Depth::U16, &["Y"], 4, 3);
        let out = map.resample(2, 1, &[[3, 2], [-5, 9]]);
        assert_eq!(out.data, vec![map.pixel(3, 2)[0], map.pixel(0, 2)[0]]);
        let crop = map.crop((1, 1, 2, 2));
        assert_eq!(crop.pixel(1, 1), map.pixel(2, 2));
    }
}
