//! Which of the sample's values a scene uploads (its images as an atlas, or its factors),
//! chosen from their sizes and the adapter's limits before anything is uploaded, and the
//! GPU memory the whole scene will take ([`estimate`]).

use super::atlas::AtlasLayout;
use super::factors::{self, ColourUniform, FactorLayout, Upload, ATLAS_LIMIT};
use super::memory::{self, Estimate};
use super::pipeline::{GpuBlend, TargetFormat, SHADOW_MAP_SIZE};
use crate::analysis::memory::gib;
use crate::btf::factored::FactoredStack;
use crate::render::ambient::TexelRect;
use crate::render::{Material, Scene};
use crate::{Error, Result};

/// The sample a GPU scene shows: the material (blends and the environment's shading are
/// computed on the CPU from it) and, where the analysis stores them, its factors.
pub struct GpuSample {
    /// The sample as the CPU renderer holds it: its images (or factors) and directions.
    pub material: Material,
    /// The factors of a material that was decoded when opened (a factored material keeps
    /// its own, [`Material::factors`]).
    pub factors: Option<FactoredStack>,
    /// Whether its images or its factors go to the GPU.
    pub upload: Upload,
}

impl GpuSample {
    /// `material` alone, uploaded as [`Upload::Auto`] chooses.
    pub fn new(material: Material) -> GpuSample {
        GpuSample { material, factors: None, upload: Upload::Auto }
    }

    /// The factors, if any.
    pub fn factors(&self) -> Option<&FactoredStack> {
        self.material.factors().or(self.factors.as_ref())
    }
}

/// The sample's values on the GPU.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Values {
    /// Every image, tiled into a texture array of `format`.
    Atlas {
        /// Where each image lies in the texture array.
        layout: AtlasLayout,
        /// The texture array's texel format.
        format: wgpu::TextureFormat,
    },
    /// The factors and the colour model.
    Factors {
        /// How the texel factors and the image table lie.
        layout: FactorLayout,
        /// The colour model's decoding, as the shader reads it.
        colour: ColourUniform,
    },
}

impl Values {
    /// Bytes the values take on the GPU, and what they are called in messages.
    pub fn bytes(&self) -> (&'static str, u64) {
        match self {
            Values::Atlas { layout, format } => {
                let (w, h) = layout.layer_size();
                let texel = format.block_copy_size(None).unwrap_or(16) as u64;
                ("sample images as an atlas", layout.layers as u64 * w as u64 * h as u64 * texel)
            }
            Values::Factors { layout, .. } => ("sample factors", layout.texel_bytes() + layout.image_bytes()),
        }
    }

    /// One line for the user: which values, and how large.
    pub fn describe(&self) -> String {
        let (name, bytes) = self.bytes();
        format!("{name}, {}", gib(bytes))
    }
}

/// The values to upload for `sample` on a device of `limits` (images as `format`): what
/// `sample.upload` asks for, and for [`Upload::Auto`] the atlas when the sample has no
/// factors or its atlas fits in [`ATLAS_LIMIT`], else the factors.
pub fn plan(sample: &GpuSample, limits: &wgpu::Limits, format: wgpu::TextureFormat) -> Result<Values> {
    let m = &sample.material;
    let atlas = || {
        let layout = AtlasLayout::new(
            m.len() as u32,
            (m.width() as u32, m.height() as u32),
            limits.max_texture_dimension_2d,
            limits.max_texture_array_layers,
        )?;
        Ok::<_, Error>(Values::Atlas { layout, format })
    };
    let from_factors = |f: &FactoredStack| {
        let layout = FactorLayout::of(f);
        layout.check(limits)?;
        memory::check_binding("the sample's image factors", layout.image_bytes(), limits)?;
        Ok::<_, Error>(Values::Factors { layout, colour: factors::colour_uniform(f.model, f.log_encoded)? })
    };
    match (sample.upload, sample.factors()) {
        (Upload::Images, _) | (Upload::Auto, None) => atlas(),
        (Upload::Factors, None) => Err(Error::out_of_range(
            crate::Param::Upload,
            "factors",
            "this analysis stores its sample as images, not factors (an analysis of a factorized .btf \
             file stores factors)",
        )),
        (Upload::Factors, Some(f)) => from_factors(f),
        (Upload::Auto, Some(f)) => match atlas() {
            Ok(a) if a.bytes().1 <= ATLAS_LIMIT => Ok(a),
            Ok(a) => from_factors(f).or(Ok(a)),
            Err(e) => from_factors(f).map_err(|_| e),
        },
    }
}

/// Everything a scene of `scene` with `values` uploads, drawn into frames of `frame` pixels
/// of `target` (with `patch_texels` environment texels): the sample, the mesh's buffers,
/// the shadow map and the frame buffers.
pub fn estimate(
    scene: &Scene,
    values: &Values,
    (target, frame): (TargetFormat, (u32, u32)),
    patches: Option<&[TexelRect]>,
) -> Estimate {
    let mut e = Estimate::default();
    let (name, bytes) = values.bytes();
    e.add(name, bytes);
    if let Values::Atlas { layout, .. } = values {
        e.add("image places", layout.layers as u64 * layout.per_layer as u64 * 16);
    }
    let vertices = scene.mesh.vertex_count() as u64;
    // vertices, blends, vertex colours and environment patch headers
    e.add("per-vertex buffers", vertices * (64 + std::mem::size_of::<GpuBlend>() as u64 + 16 + 16));
    e.add("corners", scene.mesh.triangles().len() as u64 * 12);
    let texels = patches.map_or(0, |p| p.iter().map(TexelRect::area).sum::<usize>()) as u64;
    e.add("environment texels", texels * 12);
    e.add("shadow map", SHADOW_MAP_SIZE as u64 * SHADOW_MAP_SIZE as u64 * 4);
    let pixels = frame.0 as u64 * frame.1 as u64;
    let colour = target.colour.block_copy_size(None).unwrap_or(16) as u64;
    // multisampled colour and depth, the resolved frame and its read-back copy
    e.add("frame buffers", pixels * (target.samples as u64 * (colour + 4) + 2 * colour));
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ubo2014_atlas_is_thirty_gigabytes_and_its_factors_seventy_megabytes() {
        // 400² texels × 151 × 151 images in 8192² layers of Rgba16Float: 20 × 20 tiles of
        // 400² per layer, 58 layers.
        let layout = AtlasLayout::new(22_801, (400, 400), 8192, 256).unwrap();
        let atlas = Values::Atlas { layout, format: wgpu::TextureFormat::Rgba16Float };
        assert_eq!(atlas.bytes().1, 58 * 8000 * 8000 * 8);
        assert!(atlas.bytes().1 > 100 * ATLAS_LIMIT);
        let colour = factors::colour_uniform(crate::btf::colour::ColourModel::LogYUvOverY, false).unwrap();
        let factors = Values::Factors { layout: FactorLayout::new((400, 400), 22_801, [32; 3]), colour };
        assert_eq!(factors.bytes().1, 25 * 400 * 400 * 16 + 22_801 * 25 * 16);
        assert_eq!(factors.describe(), "sample factors, 70 MiB");
    }
}
