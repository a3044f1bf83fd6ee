//! UTIA's BTF layout: one `tv###_pv###/` folder per view whose EXR images hold CIE XYZ
//! (D65 white) in half floats. They are converted to linear sRGB here; EXRs elsewhere are
//! read as RGB unless their channels are named X, Y and Z. PNGs are sRGB as everywhere.
//!
//! Where UTIA moved the light away from the camera (coincident directions), the angles in
//! the file names are used as given.

use crate::btf::colour::xyz_to_linear_srgb_in_place;
use crate::btf::image_io::{crop_image, read_rgb, RgbImage};
use crate::btf::Crop;
use crate::{Error, Result};
use half::f16;
use std::path::Path;

/// Reads an image of a stack as linear RGB, converting UTIA's XYZ EXRs.
pub fn read_stack_image(file: &Path, crop: Option<Crop>) -> Result<RgbImage> {
    if !is_exr(file) {
        return read_rgb(file, crop);
    }
    let channels = exr_channels(file)?;
    let has = |n: &str| channels.iter().any(|c| c == n);
    if has("X") && has("Y") && has("Z") {
        let image = read_xyz_channels(file)?;
        return match crop {
            Some(c) => crop_image(&image, c).map_err(|m| Error::format(file, m)),
            None => Ok(image),
        };
    }
    let mut image = read_rgb(file, crop)?;
    if in_utia_view_folder(file) {
        xyz_to_linear_srgb_in_place(&mut image.data);
    }
    Ok(image)
}

fn is_exr(file: &Path) -> bool {
    file.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"))
}

/// True if the image's folder is named like `tv030_pv090` (UTIA's per-view folders).
pub fn in_utia_view_folder(file: &Path) -> bool {
    let Some(folder) =
        file.parent().and_then(|p| p.file_name()).map(|n| n.to_string_lossy().to_ascii_lowercase())
    else {
        return false;
    };
    let tokens: Vec<&str> = folder.split(['_', ' ']).filter(|t| !t.is_empty()).collect();
    let angle = |t: &str, tag: &str| {
        t.strip_prefix(tag).is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
    };
    tokens.len() == 2 && angle(tokens[0], "tv") && angle(tokens[1], "pv")
}

fn exr_channels(file: &Path) -> Result<Vec<String>> {
    let meta = exr::prelude::MetaData::read_from_file(file, false)
        .map_err(|e| Error::format(file, format!("cannot read EXR: {e}")))?;
    let header = meta.headers.first().ok_or_else(|| Error::format(file, "EXR has no layers"))?;
    Ok(header.channels.list.iter().map(|c| c.name.to_string()).collect())
}

/// An EXR whose X, Y, Z channels hold CIE XYZ, as linear sRGB.
fn read_xyz_channels(file: &Path) -> Result<RgbImage> {
    use exr::prelude::{read, ReadChannels, ReadLayers, ReadSpecificChannel, Vec2};
    type Pixels = (usize, Vec<f16>);
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .specific_channels()
        .required("X")
        .required("Y")
        .required("Z")
        .collect_pixels(
            |size: Vec2<usize>, _| -> Pixels { (size.width(), vec![f16::ZERO; size.area() * 3]) },
            |(w, px): &mut Pixels, pos: Vec2<usize>, (x, y, z): (f16, f16, f16)| {
                let o = (pos.y() * *w + pos.x()) * 3;
                px[o..o + 3].copy_from_slice(&[x, y, z]);
            },
        )
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_file(file)
        .map_err(|e| Error::format(file, format!("cannot read EXR: {e}")))?;
    let size = image.layer_data.size;
    let (_, mut data) = image.layer_data.channel_data.pixels;
    if data.iter().any(|v| !v.is_finite()) {
        return Err(Error::format(file, "EXR contains NaN or infinite values"));
    }
    xyz_to_linear_srgb_in_place(&mut data);
    Ok(RgbImage { width: size.width(), height: size.height(), data })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utia_view_folders_are_recognised() {
        assert!(in_utia_view_folder(Path::new("s/tv030_pv090/tl015_pl000.exr")));
        assert!(in_utia_view_folder(Path::new("s/TV000_PV000/a.exr")));
        assert!(!in_utia_view_folder(Path::new("s/tl015_pl000_tv000_pv000.exr")));
        assert!(!in_utia_view_folder(Path::new("stack/tl015_pl000_tv000_pv000.exr")));
        assert!(!in_utia_view_folder(Path::new("s/tv030_pv090_extra/a.exr")));
    }
}
