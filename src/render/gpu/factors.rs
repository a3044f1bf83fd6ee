//! The sample as its factors on the GPU, for samples whose images would not fit an atlas:
//! the texel factors as a texture array (Rgba32Float, four components per layer), the image
//! factors as a small storage buffer, and the colour model as uniforms. `surface.wgsl`
//! then computes each value it blends as `Material` does on the CPU: per channel a K-term
//! dot product, then the colour model, the log encoding and the image's scale.
//!
//! A UBO2014 material (400² texels × 22,801 images, 32 components per channel) takes
//! 29.2 GiB as an Rgba16Float atlas and 70 MiB here (see [`FactorLayout`]).

use crate::btf::colour::{ColourModel, DRR_EPS};
use crate::btf::factored::FactoredStack;
use crate::{Error, Result};

/// Which of the sample's values go to the GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Upload {
    /// The images while their atlas takes at most [`ATLAS_LIMIT`], else the factors (when
    /// the analysis stores them).
    #[default]
    Auto,
    /// Every image, in the atlas ([`super::atlas`]).
    Images,
    /// The factors (an analysis that stores its sample as factors only).
    Factors,
}

/// Atlases up to this many bytes are uploaded even when the sample has factors: a lookup
/// in an atlas is one read, where the factors cost three K-term products per texel and
/// image (on lavapipe, 48² texels × 22,801 images with 32 components per channel: 2.0 s
/// per 512² frame from a 408 MiB atlas, 4.6–5.8 s from 10 MiB of factors), so the atlas is
/// worth its memory while that memory is small. GPU memory is scarcer than the CPU's, so
/// the limit is lower than the CPU renderer's decoding limit
/// ([`crate::render::material::DECODE_LIMIT`], 2 GiB); it is a choice rather than a
/// measured crossover.
pub const ATLAS_LIMIT: u64 = 256 << 20;

/// How the factors lie on the GPU.
///
/// Channel c's K_c components are padded to groups of four; texel (x, y)'s group j is the
/// texel (x, y) of layer j of the texture array (channel 0's groups first). Image i's row
/// of the image table is its groups in the same order, then one vec4 whose x is its scale.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FactorLayout {
    /// Width of the sample in texels.
    pub width: u32,
    /// Height of the sample in texels.
    pub height: u32,
    /// Number of images (rows of the image table).
    pub images: u32,
    /// Groups of four components per channel.
    pub groups: [u32; 3],
    /// Layers of the texture array: the groups, at least 2 and never a multiple of 6 (GL
    /// would take those for a plain texture or cube maps, as in [`super::atlas`]).
    pub layers: u32,
}

impl FactorLayout {
    /// The layout of `images` images of `width × height` with `components` per channel.
    pub fn new((width, height): (u32, u32), images: u32, components: [usize; 3]) -> FactorLayout {
        let groups = components.map(|k| k.div_ceil(4) as u32);
        let mut layers = groups.iter().sum::<u32>().max(2);
        if layers % 6 == 0 {
            layers += 1;
        }
        FactorLayout { width, height, images, groups, layers }
    }

    /// The layout of `f`'s factors.
    pub fn of(f: &FactoredStack) -> FactorLayout {
        FactorLayout::new((f.width() as u32, f.height() as u32), f.len() as u32, f.components())
    }

    /// vec4s per image row of the image table: the groups, then the scale.
    pub fn row(&self) -> u32 {
        self.groups.iter().sum::<u32>() + 1
    }

    /// Bytes of the texel factors' texture.
    pub fn texel_bytes(&self) -> u64 {
        self.layers as u64 * self.width as u64 * self.height as u64 * 16
    }

    /// Bytes of the image table.
    pub fn image_bytes(&self) -> u64 {
        self.images as u64 * self.row() as u64 * 16
    }

    /// Fails with one line where the texture does not fit `limits`.
    pub fn check(&self, limits: &wgpu::Limits) -> Result<()> {
        let max = limits.max_texture_dimension_2d;
        if self.width > max || self.height > max || self.layers > limits.max_texture_array_layers {
            return Err(Error::gpu(format!(
                "the sample's texel factors need {} texture layers of {}x{} but this GPU allows {} layers of \
                 at most {max}x{max}",
                self.layers, self.width, self.height, limits.max_texture_array_layers
            )));
        }
        Ok(())
    }
}

/// The colour model as `surface.wgsl` reads it: which decoding runs before the affine map
/// (the model's number, and 1 when log-encoded), and that map's rows (xyz, then the offset
/// in w).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColourUniform {
    /// x: the colour model's number, y: 1 when log-encoded; z, w unused (0).
    pub model: [u32; 4],
    /// Row c: the decoded channels' weights in xyz and the offset in w, for RGB channel c.
    pub rows: [[f32; 4]; 3],
}

/// The uniforms of `model`; Lab (model 2) is refused, since its decoding (a cube, a
/// matrix and the sRGB curve) has no counterpart in the shader.
pub fn colour_uniform(model: ColourModel, log_encoded: bool) -> Result<ColourUniform> {
    let yuv = ColourModel::Yuv.affine().expect("YUV is affine");
    let identity = ColourModel::Rgb.affine().expect("RGB is affine");
    let (m, t) = match model {
        ColourModel::Lab => {
            return Err(Error::unavailable(
                "the sample's colour model 2 (CIE Lab) cannot be decoded on the GPU",
                crate::Remedy::UploadImages,
            ))
        }
        ColourModel::LogYUv | ColourModel::LogYLogUv | ColourModel::LogYUvOverY => yuv,
        other => other.affine().unwrap_or(identity),
    };
    let rows = [0, 1, 2].map(|r| [m[r][0], m[r][1], m[r][2], t[r]]);
    Ok(ColourUniform { model: [model.id() as u32, log_encoded as u32, 0, 0], rows })
}

/// The shader's ε of the log models and of the log encoding (must equal [`DRR_EPS`]).
pub const SHADER_EPS: f32 = 1e-5;
const _: () = assert!(SHADER_EPS == DRR_EPS);

/// Uploads `f`'s texel factors as a texture array laid out as `layout`.
pub fn upload_texels(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    f: &FactoredStack,
    layout: &FactorLayout,
) -> wgpu::Texture {
    let (w, h) = (layout.width, layout.height);
    let format = wgpu::TextureFormat::Rgba32Float;
    let texture = super::atlas::sampled_array(device, "sample texel factors", (w, h, layout.layers), format);
    let groups = group_channels(layout);
    for (layer, &(c, first)) in groups.iter().enumerate() {
        let texels = &f.texel[c];
        let k = texels.ncols();
        let values: Vec<f32> = (0..(w * h) as usize)
            .flat_map(|p| (first..first + 4).map(move |j| if j < k { texels[[p, j]] } else { 0.0 }))
            .collect();
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: 0,
                origin: wgpu::Origin3d { x: 0, y: 0, z: layer as u32 },
                aspect: wgpu::TextureAspect::All,
            },
            bytemuck::cast_slice(&values),
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(w * 16), rows_per_image: None },
            wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        );
    }
    texture
}

/// Per group of four components, in layer order: its channel and first component.
fn group_channels(layout: &FactorLayout) -> Vec<(usize, usize)> {
    (0..3).flat_map(|c| (0..layout.groups[c] as usize).map(move |g| (c, 4 * g))).collect()
}

/// The image table: per image its factor groups (as [`FactorLayout`] says), then its scale.
pub fn image_table(f: &FactoredStack, layout: &FactorLayout) -> Vec<[f32; 4]> {
    let groups = group_channels(layout);
    (0..f.len())
        .flat_map(|i| {
            let row = groups.iter().map(move |&(c, first)| {
                let k = f.image[c].ncols();
                [0, 1, 2, 3].map(|e| if first + e < k { f.image[c][[i, first + e]] } else { 0.0 })
            });
            row.chain(std::iter::once([f.scale[i], 0.0, 0.0, 0.0]))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ubo2014_material_is_a_few_dozen_mebibytes_of_factors() {
        // 400² texels, 151 × 151 images, 32 components per channel.
        let l = FactorLayout::new((400, 400), 22_801, [32; 3]);
        // 24 groups would be a multiple of 6 layers: one more.
        assert_eq!((l.groups, l.layers, l.row()), ([8; 3], 25, 25));
        assert_eq!(l.texel_bytes(), 25 * 400 * 400 * 16);
        assert_eq!(l.image_bytes(), 22_801 * 25 * 16);
        assert!(l.texel_bytes() + l.image_bytes() < 80 << 20);
    }

    #[test]
    fn uneven_components_are_padded_to_groups_of_four() {
        let l = FactorLayout::new((3, 2), 5, [5, 1, 8]);
        assert_eq!((l.groups, l.layers, l.row()), ([2, 1, 2], 5, 6));
        assert_eq!(group_channels(&l), vec![(0, 0), (0, 4), (1, 0), (2, 0), (2, 4)]);
    }

    #[test]
    fn the_colour_uniforms_are_the_models_affine_maps() {
        let yuv = colour_uniform(ColourModel::LogYUvOverY, false).unwrap();
        assert_eq!(yuv.model, [11, 0, 0, 0]);
        assert_eq!(yuv.rows[2][1], ColourModel::Yuv.affine().unwrap().0[2][1]);
        let pca = ColourModel::Pca {
            mean: [0.1, 0.2, 0.3],
            transform: [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]],
        };
        let u = colour_uniform(pca, true).unwrap();
        // rgb_j = Σ_i v_i · transform[i][j] + mean_j: row j holds column j of the transform.
        assert_eq!((u.rows[1], u.model[1]), ([2.0, 5.0, 8.0, 0.2], 1));
        assert!(colour_uniform(ColourModel::Lab, false).is_err());
    }
}
