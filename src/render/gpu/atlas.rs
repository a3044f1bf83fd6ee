//! The sample images on the GPU: a 2D texture array of Rgba16Float atlases (Rgba32Float
//! where the adapter cannot sample half floats), several images per layer as tiles,
//! because a BTF has thousands of images and an array has few layers (256 by default). The
//! shader fetches texels with `textureLoad` and filters by hand.

use crate::render::Material;
use crate::{Error, Result};
use half::f16;

/// Where each image lies: tiles of `width × height` in rows of `tiles_x`, `per_layer` tiles
/// per layer, image i in layer `i / per_layer`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AtlasLayout {
    /// Width of one image tile in texels.
    pub width: u32,
    /// Height of one image tile in texels.
    pub height: u32,
    /// Tiles per row of a layer.
    pub tiles_x: u32,
    /// Rows of tiles per layer.
    pub tiles_y: u32,
    /// Tiles per layer: `tiles_x × tiles_y`.
    pub per_layer: u32,
    /// Layers of the texture array.
    pub layers: u32,
}

impl AtlasLayout {
    /// The smallest layout of `count` images of `width × height` whose layers fit in
    /// `max_dim` texels a side and whose number fits in `max_layers`.
    pub fn new(
        count: u32,
        (width, height): (u32, u32),
        max_dim: u32,
        max_layers: u32,
    ) -> Result<AtlasLayout> {
        if width == 0 || height == 0 || width > max_dim || height > max_dim {
            return Err(Error::gpu(format!(
                "sample images of {width}x{height} do not fit this GPU's {max_dim}-texel textures"
            )));
        }
        // GL guesses a texture's view dimension from its layer count (1: a plain 2D texture,
        // 6 or a multiple of 6: cube maps), so spread the images over at least 2 layers and
        // skip those counts.
        let count = count.max(1);
        let per_layer_wanted = count.div_ceil(2);
        let tiles_x = (max_dim / width).min(per_layer_wanted);
        let tiles_y = (max_dim / height).min(per_layer_wanted.div_ceil(tiles_x));
        let per_layer = tiles_x * tiles_y;
        let mut layers = count.div_ceil(per_layer).max(2);
        if layers % 6 == 0 {
            layers += 1;
        }
        if layers > max_layers {
            return Err(Error::gpu(format!(
                "{count} sample images of {width}x{height} need {layers} texture layers of {max_dim}² \
                 but this GPU allows {max_layers}"
            )));
        }
        Ok(AtlasLayout { width, height, tiles_x, tiles_y, per_layer, layers })
    }

    /// Layer and texel origin of image `i`.
    pub fn place(&self, i: u32) -> (u32, u32, u32) {
        let tile = i % self.per_layer;
        (i / self.per_layer, (tile % self.tiles_x) * self.width, (tile / self.tiles_x) * self.height)
    }

    /// Size of one layer in texels.
    pub fn layer_size(&self) -> (u32, u32) {
        (self.tiles_x * self.width, self.tiles_y * self.height)
    }
}

/// Uploads every image of `material` into a new texture array laid out as `layout`, of
/// `format` (Rgba16Float or Rgba32Float).
pub fn upload(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    material: &Material,
    layout: &AtlasLayout,
    format: wgpu::TextureFormat,
) -> wgpu::Texture {
    let (lw, lh) = layout.layer_size();
    let texture = sampled_array(device, "sample image atlas", (lw, lh, layout.layers), format);
    let half = format == wgpu::TextureFormat::Rgba16Float;
    for i in 0..material.len() {
        let rgb = material.image(i as u32);
        let rgba = rgb.chunks_exact(3).flat_map(|p| [p[0], p[1], p[2], 1.0]);
        let bytes: Vec<u8> = if half {
            rgba.flat_map(|c| f16::from_f32(c).to_le_bytes()).collect()
        } else {
            rgba.flat_map(f32::to_le_bytes).collect()
        };
        let (layer, x, y) = layout.place(i as u32);
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: 0,
                origin: wgpu::Origin3d { x, y, z: layer },
                aspect: wgpu::TextureAspect::All,
            },
            &bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(layout.width * if half { 8 } else { 16 }),
                rows_per_image: None,
            },
            wgpu::Extent3d { width: layout.width, height: layout.height, depth_or_array_layers: 1 },
        );
    }
    texture
}

/// An empty 2D texture array of `layers` layers of `width × height` in `format`, for the
/// shader to sample and the CPU to fill.
pub fn sampled_array(
    device: &wgpu::Device,
    label: &str,
    (width, height, layers): (u32, u32, u32),
    format: wgpu::TextureFormat,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: layers },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn few_images_share_two_compact_layers() {
        let a = AtlasLayout::new(5, (48, 32), 8192, 256).unwrap();
        assert_eq!((a.tiles_x, a.tiles_y, a.per_layer, a.layers), (3, 1, 3, 2));
        assert_eq!(a.layer_size(), (144, 32));
        assert_eq!(a.place(4), (1, 48, 0));
        // One image still makes two layers (GL would take one layer for a plain 2D texture).
        assert_eq!(AtlasLayout::new(1, (48, 32), 8192, 256).unwrap().layers, 2);
    }

    #[test]
    fn many_images_fill_layers_row_by_row() {
        // 6561 images of 256² in 8192² layers: 32 × 32 = 1024 per layer, 7 layers.
        let a = AtlasLayout::new(6561, (256, 256), 8192, 256).unwrap();
        assert_eq!((a.tiles_x, a.tiles_y, a.per_layer, a.layers), (32, 32, 1024, 7));
        assert_eq!(a.place(1024 + 33), (1, 256, 256));
        // 6560 = 6 × 1024 + 416, and 416 = 13 rows of 32: the first tile of row 13.
        assert_eq!(a.place(6560), (6, 0, 13 * 256));
        // Every image has its own tile inside its layer.
        let mut seen = std::collections::HashSet::new();
        for i in 0..6561 {
            let (l, x, y) = a.place(i);
            assert!(l < a.layers && x + 256 <= 8192 && y + 256 <= 8192);
            assert!(seen.insert((l, x, y)));
        }
    }

    #[test]
    fn layer_counts_that_gl_takes_for_cube_maps_are_skipped() {
        // 6 × 1024 images of 256²: six full layers would be a cube map to GL.
        let a = AtlasLayout::new(6 * 1024, (256, 256), 8192, 256).unwrap();
        assert_eq!(a.layers, 7);
    }

    #[test]
    fn too_many_or_too_large_images_are_refused() {
        assert!(AtlasLayout::new(6561, (256, 256), 2048, 64).is_err());
        assert!(AtlasLayout::new(1, (9000, 16), 8192, 256).is_err());
    }
}
