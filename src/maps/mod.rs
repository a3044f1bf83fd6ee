//! Material map sets: one synthesis, every channel.
//!
//! A texture photograph often comes with maps of the same patch (normal, roughness,
//! metallic, ambient occlusion, height). Synthesis chooses, per output texel, a coordinate
//! into the sample; copying every map through the same coordinates gives a matching set.
//!
//! - An analysis given maps (a normal map `n.png`, a height map `h.exr`) stores each one beside the
//!   sample images in the analysis directory (`map_normal.png`, `map_height.exr`, cropped like the
//!   sample, at the file's own depth) and lists it in `analysis.json` ([`MapInfo`]).
//! - A synthesized plane is written with `result_<kind>.<png|exr>`, each texel the map's sample at
//!   the plane's coordinate ([`stored::write_plane_maps`]): same depth, same format, same channels.
//! - `export` bakes each map into its glTF slot (see `crate::export`).

pub mod image;
pub mod stored;

pub use image::{Depth, MapImage};

use crate::{Error, Param, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What a map holds, which decides where `export` puts it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MapKind {
    /// Tangent-space normals (x right, y up in the image, z out; OpenGL convention), as RGB
    /// in [0, 1] for integer files, as components in [-1, 1] for float files.
    Normal,
    /// Perceptual roughness in [0, 1] (first channel).
    Roughness,
    /// Metalness in [0, 1] (first channel).
    Metallic,
    /// Ambient occlusion in [0, 1] (first channel).
    Occlusion,
    /// Height or displacement, any unit (first channel).
    Height,
}

impl MapKind {
    /// Every kind, in the order maps are listed.
    pub const ALL: [MapKind; 5] =
        [MapKind::Normal, MapKind::Roughness, MapKind::Metallic, MapKind::Occlusion, MapKind::Height];

    /// The name used on the command line and in file names.
    pub fn name(self) -> &'static str {
        match self {
            MapKind::Normal => "normal",
            MapKind::Roughness => "roughness",
            MapKind::Metallic => "metallic",
            MapKind::Occlusion => "occlusion",
            MapKind::Height => "height",
        }
    }

    /// The kind called `name`.
    pub fn parse(name: &str) -> Result<MapKind> {
        MapKind::ALL.into_iter().find(|k| k.name() == name).ok_or_else(|| {
            Error::out_of_range(
                Param::Maps,
                format!("'{name}'"),
                "unknown map kind: expected normal, roughness, metallic, occlusion or height",
            )
        })
    }
}

/// A map named on the command line: `kind=path`.
#[derive(Clone, Debug, PartialEq)]
pub struct MapSource {
    /// What the map holds.
    pub kind: MapKind,
    /// Its image file.
    pub path: PathBuf,
}

/// Parses `normal=n.png,roughness=r.png,…`; each kind at most once.
pub fn parse_map_list(list: &str) -> Result<Vec<MapSource>> {
    let mut sources: Vec<MapSource> = Vec::new();
    for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (kind, path) = item.split_once('=').ok_or_else(|| {
            Error::out_of_range(Param::Maps, format!("'{item}'"), "expected KIND=FILE, e.g. normal=n.png")
        })?;
        let kind = MapKind::parse(kind.trim())?;
        if sources.iter().any(|s| s.kind == kind) {
            return Err(Error::out_of_range(
                Param::Maps,
                "",
                format!("the {} map is given twice", kind.name()),
            ));
        }
        sources.push(MapSource { kind, path: PathBuf::from(path.trim()) });
    }
    if sources.is_empty() {
        return Err(Error::out_of_range(Param::Maps, "", "none given: expected KIND=FILE[,KIND=FILE…]"));
    }
    Ok(sources)
}

/// A map read for one sample: its kind, where it came from and its pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialMap {
    /// What it holds.
    pub kind: MapKind,
    /// The file it was read from.
    pub source: PathBuf,
    /// Its pixels, at the file's depth.
    pub image: MapImage,
}

impl MaterialMap {
    /// Reads `source` for a sample whose image is `size` (width, height; `None` if unknown)
    /// before `crop` (x, y, w, h), and crops it the same way. A map of another size, or one
    /// the crop does not fit, is an error naming it.
    pub fn load(
        source: &MapSource,
        size: Option<(usize, usize)>,
        crop: Option<(usize, usize, usize, usize)>,
    ) -> Result<MaterialMap> {
        let image = MapImage::read(&source.path)?;
        let (w, h) = (image.width, image.height);
        let kind = source.kind.name();
        if let Some((sw, sh)) = size.filter(|&s| s != (w, h)) {
            return Err(Error::format(
                &source.path,
                format!("the {kind} map is {w}x{h} pixels but the sample is {sw}x{sh}; maps must have the sample's size"),
            ));
        }
        let image = match crop {
            Some((x, y, cw, ch)) if x + cw > w || y + ch > h => {
                return Err(Error::format(
                    &source.path,
                    format!("the crop {x},{y},{cw},{ch} does not fit in the {w}x{h} {kind} map"),
                ))
            }
            Some(c) => image.crop(c),
            None => image,
        };
        Ok(MaterialMap { kind: source.kind, source: source.path.clone(), image })
    }

    /// The file name in an analysis directory: `map_<kind>.<png|exr>`.
    pub fn file_name(&self) -> String {
        format!("map_{}.{}", self.kind.name(), self.image.depth.extension())
    }
}

/// A map's entry in `analysis.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MapInfo {
    /// What it holds.
    pub kind: MapKind,
    /// Its file, relative to the analysis directory.
    pub file: String,
    /// How its samples are stored.
    pub depth: Depth,
    /// Its channel names, in storage order.
    pub channels: Vec<String>,
    /// The file it was read from, as given.
    pub source: String,
}

/// Writes `maps` into the analysis directory being built at `dir`; returns their entries.
pub fn store_maps(dir: &Path, maps: &[MaterialMap]) -> Result<Vec<MapInfo>> {
    maps.iter()
        .map(|m| {
            let file = m.file_name();
            m.image.write(&dir.join(&file))?;
            Ok(MapInfo {
                kind: m.kind,
                file,
                depth: m.image.depth,
                channels: m.image.channels.clone(),
                source: m.source.display().to_string(),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_lists_parse_and_refuse_mistakes() {
        let maps = parse_map_list("normal=n.png, height=dir/h.exr").expect("parses");
        assert_eq!(maps[0], MapSource { kind: MapKind::Normal, path: "n.png".into() });
        assert_eq!(maps[1].kind, MapKind::Height);
        for bad in ["normal", "colour=c.png", "normal=a.png,normal=b.png", ""] {
            assert!(parse_map_list(bad).is_err(), "{bad}");
        }
    }
}
