//! Every image-space measure of one result picture against its sample, in one pass over
//! the result's patches: patch energy, colour, contrast and repetition.

use super::picture::{
    colour_chi2, contrast, mean_energy, nearest_patches, patch_energy, patch_matrix, patch_positions,
    Picture, PATCH_STRIDE,
};
use super::repetition::{repetition, Repetition};
use serde::Serialize;

/// The image-space measures of one result picture against the sample picture.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PictureQuality {
    /// Mean over the result's 7×7 patches (every [`PATCH_STRIDE`]th pixel) of the squared
    /// difference to the nearest 7×7 patch of the sample, per value (sRGB, 0–1). 0 when every
    /// patch exists in the sample; a copy with seams or smears scores above a coherent one,
    /// and noise far above.
    pub patch_energy: f64,
    /// The same on both pictures halved (7×7 patches of 2×2 means): structure at twice the
    /// scale, e.g. whole stones.
    pub patch_energy_coarse: f64,
    /// ½ Σ (p − q)² / (p + q) between 8×8×8-bin colour histograms: 0 identical, 1 disjoint.
    pub colour_chi2: f64,
    /// Standard deviation of the result's luma over the sample's: 1 keeps the sample's
    /// contrast, below 1 is washed out (blur, collapse onto flat texels).
    pub contrast: f64,
    /// How strongly sample places recur at regular offsets, and how evenly the sample is
    /// used ([`super::repetition`]).
    #[serde(flatten)]
    pub repetition: Repetition,
}

/// Every measure of `result` against `sample`. `tileable`: the sample wraps, so its patches
/// may cross its border.
pub fn picture_quality(result: &Picture, sample: &Picture, tileable: bool) -> PictureQuality {
    let (result_half, sample_half) = (result.half(), sample.half());
    let positions = patch_positions(result, PATCH_STRIDE, false);
    let nearest = nearest_patches(&patch_matrix(result, &positions), sample, tileable);
    let sources: Vec<u32> = nearest.iter().map(|n| n.0).collect();
    PictureQuality {
        patch_energy: mean_energy(&nearest),
        patch_energy_coarse: patch_energy(&result_half, &sample_half, PATCH_STRIDE / 2, tileable),
        colour_chi2: colour_chi2(result, sample),
        contrast: contrast(result, sample),
        repetition: repetition(result, &positions, &sources, sample, tileable),
    }
}
