//! Maps as an analysis directory stores them: read back beside the sample, and carried
//! through a plane's coordinates.

use super::{MapImage, MaterialMap};
use crate::analysis::store;
use crate::{Error, Result};
use std::path::Path;

/// Reads the maps an analysis directory lists (none for analyses made without material maps).
pub fn open_maps(analysis_dir: &Path) -> Result<Vec<MaterialMap>> {
    let manifest = store::read_manifest(analysis_dir)?;
    manifest
        .maps
        .iter()
        .map(|info| {
            let path = analysis_dir.join(&info.file);
            let image = MapImage::read(&path)?;
            if (image.width, image.height) != (manifest.width, manifest.height) {
                return Err(Error::format(&path, "the map does not have the sample's size"));
            }
            Ok(MaterialMap { kind: info.kind, source: path, image })
        })
        .collect()
}

/// Writes every map of the analysis in `analysis_dir` through a plane's coordinates
/// (`coordinates[y * width + x]` = sample texel) into `dir` as `result_<kind>.<png|exr>`.
pub fn write_plane_maps(
    analysis_dir: &Path,
    coordinates: &[[i32; 2]],
    (width, height): (usize, usize),
    dir: &Path,
) -> Result<()> {
    for map in open_maps(analysis_dir)? {
        let out = map.image.resample(width, height, coordinates);
        out.write(&dir.join(format!("result_{}.{}", map.kind.name(), out.depth.extension())))?;
    }
    Ok(())
}
