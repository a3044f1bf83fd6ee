//! The wgpu renderer: the same scene, material and per-vertex blends as the CPU renderer
//! ([`crate::render::cpu`]), drawn by rasterisation with a shadow map. Blends are computed
//! on the CPU each frame ([`Scene::vertex_blends`]) and uploaded; `shaders/surface.wgsl` only
//! fetches texels (or computes them from the sample's factors) and sums them.
//!
//! [`GpuRenderer`] renders offscreen into [`Frame`]s; the viewer
//! ([`crate::render::viewer`]) draws the same [`passes::Passes`] into a window.
//!
//! The sample goes up as its images ([`atlas`]) or, when those would be large and the
//! analysis stores factors, as its factors ([`factors`]); [`sample::plan`] chooses, and
//! [`sample::estimate`] counts the GPU memory of the whole scene before anything is
//! uploaded ([`memory`]).

pub mod atlas;
pub mod context;
pub mod factors;
pub mod memory;
pub mod overlay;
pub mod passes;
pub mod pipeline;
pub mod readback;
pub mod sample;

pub use factors::Upload;
pub use sample::GpuSample;

use super::ambient::{self, AmbientCache};
use super::tracer::Tracer;
use super::{Blend16, Camera, Environment, Frame, Material, Mode, Scene, Shot};
use crate::Result;
use context::Gpu;
use passes::{FrameSettings, FrameTargets, Passes};
use pipeline::TargetFormat;
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

/// How a GPU renderer lights the model.
#[derive(Clone, Debug, Default)]
pub struct GpuLighting {
    /// Strength of the directional light (1: the sample's own light; 0: off).
    pub sun: f32,
    /// Light from every direction (see [`crate::render::ambient`]).
    pub environment: Option<Environment>,
    /// Shadow-map shadows for the directional light, and per-vertex light-cell shadows
    /// (traced on the CPU, as `render` does) for the environment.
    pub shadows: bool,
}

impl GpuLighting {
    /// The directional light alone, with shadows.
    pub fn sun() -> GpuLighting {
        GpuLighting { sun: 1.0, environment: None, shadows: true }
    }
}

/// The scene on one GPU: its passes, formats and the environment's shading.
pub struct GpuScene {
    /// The device and queue everything is uploaded to.
    pub gpu: Gpu,
    /// The shadow, depth, surface and vertex-colour pipelines with their buffers and bindings.
    pub passes: Passes,
    /// The formats the camera passes draw into.
    pub target: TargetFormat,
    /// The scene as the CPU holds it (mesh, frames, sample coordinates).
    pub scene: Scene,
    /// The sample, whose blends and environment shading are computed on the CPU.
    pub material: Material,
    /// The directional light, environment and shadows the frames are lit with.
    pub lighting: GpuLighting,
    /// Which of the sample's values went to the GPU.
    pub values: sample::Values,
    ambient: Option<AmbientCache>,
    /// The scene's BVH, for the environment's shadows and for which vertices a camera shows.
    tracer: Option<Tracer>,
}

impl GpuScene {
    /// Uploads `scene` and `sample` to `gpu` (the sample's images or its factors, as
    /// [`sample::plan`] chooses), for frames of `colour` format (multisampled where the
    /// adapter can) of `frame` pixels; the environment's cell shadows are traced now. Any
    /// wgpu error is one line, and so is a scene whose GPU memory ([`sample::estimate`])
    /// exceeds the limit ([`memory::limit`]), refused before anything is uploaded.
    pub fn new(
        gpu: Gpu,
        (scene, sample): (Scene, GpuSample),
        (colour, frame): (Option<wgpu::TextureFormat>, (u32, u32)),
        lighting: GpuLighting,
    ) -> Result<GpuScene> {
        let formats = gpu.formats()?;
        let colour = colour.unwrap_or(formats.target);
        let target =
            TargetFormat { colour, depth: formats.depth, samples: gpu.msaa_samples(colour, formats.depth) };
        let values = sample::plan(&sample, &gpu.device.limits(), formats.images)?;
        let rects = lighting.environment.as_ref().map(|_| ambient::patch_rects(&scene));
        let advice = match values {
            sample::Values::Atlas { .. } if sample.factors().is_some() => crate::Remedy::UploadFactors,
            _ => crate::Remedy::SmallerScene,
        };
        let estimate = sample::estimate(&scene, &values, (target, frame), rects.as_deref());
        estimate.check(&gpu.name(), memory::limit(gpu.adapter.get_info().device_type)?, advice)?;
        let passes = gpu.scoped("draw this scene", || {
            Passes::new(
                &gpu.device,
                &gpu.queue,
                (&scene, &sample.material, sample.factors()),
                target,
                &values,
                rects.as_deref(),
            )
        })?;
        let material = sample.material;
        let ambient =
            lighting.environment.clone().map(|e| AmbientCache::new(&scene, &material, e, lighting.shadows));
        let tracer = (ambient.is_some() && lighting.shadows).then(|| Tracer::new(&scene.mesh));
        Ok(GpuScene { gpu, passes, target, scene, material, lighting, values, ambient, tracer })
    }

    /// Uploads what `shot` needs (blends, uniforms, and the environment's shading for
    /// `environment_camera` if that moved: the shot's camera, or in a window the camera
    /// where a drag began, since the environment costs more to shade than a frame).
    pub fn prepare(&mut self, shot: &Shot, mode: Mode, display: Display, environment_camera: &Camera) {
        let sun = if display == Display::Btf { self.lighting.sun } else { 1.0 };
        let blends = if sun > 0.0 {
            display_blends(&self.scene, &self.material, shot, display)
        } else {
            vec![Blend16::DARK; self.scene.mesh.vertex_count()]
        };
        let environment = display == Display::Btf && self.ambient.is_some();
        if let (true, Some(cache)) = (environment, self.ambient.as_mut()) {
            let scene = (&self.scene, &self.material);
            let (ambient, fresh) = cache.for_camera(scene, environment_camera, self.tracer.as_ref());
            if fresh {
                self.passes.upload_ambient(&self.gpu.queue, ambient);
            }
        }
        let settings = FrameSettings {
            mode,
            false_colour: display == Display::TextonFalseColour,
            shadows: self.lighting.shadows,
            sun,
            environment,
        };
        self.passes.prepare(&self.gpu.queue, shot, &blends, settings);
    }
}

/// Renders frames offscreen and reads them back.
pub struct GpuRenderer {
    inner: GpuScene,
    target: wgpu::Texture,
    targets: FrameTargets,
    staging: wgpu::Buffer,
    size: (u32, u32),
}

impl GpuRenderer {
    /// A renderer of `size` (width, height) pixels on the first adapter wgpu finds, with no
    /// window. Fails with one line if there is none, or if it cannot render this scene.
    pub fn headless(
        scene: Scene,
        sample: GpuSample,
        size: (u32, u32),
        lighting: GpuLighting,
    ) -> Result<GpuRenderer> {
        let gpu = Gpu::headless()?;
        let max = gpu.device.limits().max_texture_dimension_2d;
        if size.0 > max || size.1 > max {
            return Err(crate::Error::out_of_range(
                crate::Param::FrameSize,
                format!("{}x{}", size.0, size.1),
                format!("{} renders at most {max}x{max}", gpu.name()),
            ));
        }
        let inner = GpuScene::new(gpu, (scene, sample), (None, size), lighting)?;
        let (gpu, format) = (&inner.gpu, inner.target);
        let (target, targets, staging) = gpu.scoped("make its frame buffers", || {
            let target = gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("frame"),
                size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: format.colour,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            });
            let targets = FrameTargets::new(&gpu.device, size, format);
            Ok((target, targets, readback::staging_buffer(&gpu.device, size, format.colour)))
        })?;
        Ok(GpuRenderer { inner, target, targets, staging, size })
    }

    /// The adapter's name and backend.
    pub fn adapter_name(&self) -> String {
        self.inner.gpu.name()
    }

    /// The colour format and samples per pixel frames are drawn with.
    pub fn target_format(&self) -> TargetFormat {
        self.inner.target
    }

    /// The scene drawn.
    pub fn scene(&self) -> &Scene {
        &self.inner.scene
    }

    /// Which of the sample's values are on the GPU, and their size.
    pub fn values(&self) -> sample::Values {
        self.inner.values
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
        self.inner.prepare(shot, mode, display, &shot.camera);
        let gpu = &self.inner.gpu;
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let target = self.target.create_view(&Default::default());
        self.inner.passes.encode(&mut encoder, &target, &self.targets, wgpu::Color::TRANSPARENT);
        readback::copy(&mut encoder, &self.target, &self.staging);
        gpu.queue.submit([encoder.finish()]);
        let frame = readback::read(&gpu.device, &self.staging, self.size, self.inner.target.colour);
        gpu.check()?;
        frame
    }
}
