//! The wgpu renderer: the same scene, material and per-vertex blends as the CPU renderer
//! ([`crate::render::cpu`]), drawn by rasterisation with a shadow map. Blends are computed
//! on the CPU each frame ([`Scene::vertex_blends`]) and uploaded; `shaders/surface.wgsl` only
//! fetches and sums texels.
//!
//! [`GpuRenderer`] renders offscreen into [`Frame`]s; the viewer
//! ([`crate::render::viewer`]) draws the same [`passes::Passes`] into a window.

pub mod atlas;
pub mod context;
pub mod passes;
pub mod pipeline;
pub mod readback;

use super::{Blend16, Frame, Material, Mode, Scene, Shot};
use crate::Result;
use context::Gpu;
use passes::{FrameSettings, Passes};
use rayon::prelude::*;

/// What the surface shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Display {
    /// The BTF: 4 × 4 sample images blended per the view and light.
    #[default]
    Btf,
    /// The sample's first image as a flat texture, times n·l.
    FirstImage,
    /// A colour per texton label, times n·l.
    TextonFalseColour,
}

/// The per-vertex blends of a frame: the BTF's, or for the flat displays image 0 weighted by
/// the vertex's n·l (the false-colour shader reads only that weight).
pub fn display_blends(scene: &Scene, material: &Material, shot: &Shot, display: Display) -> Vec<Blend16> {
    if display == Display::Btf {
        return scene.vertex_blends(material, shot);
    }
    scene
        .normals()
        .par_iter()
        .with_min_len(4096)
        .map(|n| {
            let mut b = Blend16::DARK;
            b.weight[0] = n.dot(shot.light).max(0.0);
            b
        })
        .collect()
}

/// The colour target of offscreen frames: f32, so the frame is linear and unrounded.
const TARGET_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// Renders frames offscreen and reads them back.
pub struct GpuRenderer {
    scene: Scene,
    material: Material,
    gpu: Gpu,
    passes: Passes,
    target: wgpu::Texture,
    depth: wgpu::TextureView,
    staging: wgpu::Buffer,
    size: (u32, u32),
    /// Shadow-map shadows (on by default).
    pub shadows: bool,
}

impl GpuRenderer {
    /// A renderer of `size` (width, height) pixels on the first adapter wgpu finds, with no
    /// window. Fails with one line if there is none.
    pub fn headless(scene: Scene, material: Material, size: (u32, u32)) -> Result<GpuRenderer> {
        let gpu = Gpu::headless()?;
        let max = gpu.device.limits().max_texture_dimension_2d;
        if size.0 > max || size.1 > max {
            return Err(crate::Error::invalid(format!(
                "--size {}x{}: {} renders at most {max}x{max}",
                size.0,
                size.1,
                gpu.name()
            )));
        }
        let passes = Passes::new(&gpu.device, &gpu.queue, &scene, &material, TARGET_FORMAT)?;
        let target = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("frame"),
            size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: TARGET_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let depth = passes::depth_texture(&gpu.device, size, false);
        let staging = readback::staging_buffer(&gpu.device, size);
        Ok(GpuRenderer { scene, material, gpu, passes, target, depth, staging, size, shadows: true })
    }

    /// The adapter's name and backend.
    pub fn adapter_name(&self) -> String {
        self.gpu.name()
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Renders `shot` (whose camera must be of this renderer's size) into a linear RGBA frame.
    pub fn render(&mut self, shot: &Shot, mode: Mode, display: Display) -> Result<Frame> {
        let size = (shot.camera.width, shot.camera.height);
        if size != self.size {
            return Err(crate::Error::invalid(format!(
                "shot of {}x{} on a {}x{} GPU renderer",
                size.0, size.1, self.size.0, self.size.1
            )));
        }
        let blends = display_blends(&self.scene, &self.material, shot, display);
        let settings = FrameSettings {
            mode,
            false_colour: display == Display::TextonFalseColour,
            shadows: self.shadows,
        };
        self.passes.prepare(&self.gpu.queue, shot, &blends, settings);
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        let target = self.target.create_view(&Default::default());
        self.passes.encode(&mut encoder, &target, &self.depth, wgpu::Color::TRANSPARENT);
        readback::copy(&mut encoder, &self.target, &self.staging);
        self.gpu.queue.submit([encoder.finish()]);
        readback::read(&self.gpu.device, &self.staging, self.size)
    }
}
