//! The scene on the GPU and the passes that draw it: buffers (vertices, corners,
//! blends, uniforms), the shadow map, bind groups, and the per-frame uploads.

use super::atlas;
use super::factors;
use super::memory::check_binding;
use super::pipeline::{self, GpuBlend, TargetFormat, SHADOW_MAP_SIZE};
use super::sample::Values;
use crate::btf::factored::FactoredStack;
use crate::render::ambient::{Ambient, TexelRect};
use crate::render::camera::{Camera, Projection};
use crate::render::{Blend16, Material, Mode, Scene, Shot};
use crate::{Error, Result};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use wgpu::util::DeviceExt;

/// One vertex as `surface.wgsl` reads it (WGSL's vec3 takes 16 bytes with the scalar after it).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuVertex {
    position: [f32; 3],
    label: u32,
    s: [f32; 3],
    u: f32,
    t: [f32; 3],
    v: f32,
    n: [f32; 3],
    /// The vertex's share in its copy ([`Scene::belonging`]).
    belonging: f32,
}

/// `surface.wgsl`'s `Uniforms` (the shadow pass reads only the first matrix).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Uniforms {
    light_view_proj: [[f32; 4]; 4],
    view_proj: [[f32; 4]; 4],
    light: [f32; 4],
    eye: [f32; 4],
    towards_eye: [f32; 4],
    flags: [u32; 4],
    atlas: [u32; 4],
    params: [f32; 4],
    lighting: [f32; 4],
    factors: [u32; 4],
    colour_model: [u32; 4],
    colour_rows: [[f32; 4]; 3],
}

/// What a frame shows besides the shot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameSettings {
    /// How points between vertices are shaded (per vertex or per pixel).
    pub mode: Mode,
    /// Colour each texton label instead of fetching texels.
    pub false_colour: bool,
    /// Whether the directional light casts shadow-map shadows.
    pub shadows: bool,
    /// Strength of the directional light (0: off).
    pub sun: f32,
    /// Add the environment's share uploaded by [`Passes::upload_ambient`].
    pub environment: bool,
}

/// Where the camera passes draw: a multisampled colour texture resolved into the caller's
/// target (when multisampling), and the depth buffer.
pub struct FrameTargets {
    multisampled: Option<wgpu::TextureView>,
    depth: wgpu::TextureView,
}

impl FrameTargets {
    /// Targets of `size` pixels for `format`.
    pub fn new(device: &wgpu::Device, size: (u32, u32), format: TargetFormat) -> FrameTargets {
        let multisampled = (format.samples > 1).then(|| {
            device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some("multisampled colour"),
                    size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: format.samples,
                    dimension: wgpu::TextureDimension::D2,
                    format: format.colour,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                    view_formats: &[],
                })
                .create_view(&Default::default())
        });
        let depth = depth_texture(device, size, format.depth, false, format.samples);
        FrameTargets { multisampled, depth }
    }
}

/// Everything the passes need that lives on the GPU.
pub struct Passes {
    shadow_pipeline: wgpu::RenderPipeline,
    depth_pipeline: wgpu::RenderPipeline,
    surface_pipeline: wgpu::RenderPipeline,
    colour_pipeline: wgpu::ComputePipeline,
    shadow_bindings: wgpu::BindGroup,
    surface_bindings: wgpu::BindGroup,
    /// The vertex colours as the surface pass reads them and as the compute pass writes them.
    colours_read: wgpu::BindGroup,
    colours_write: wgpu::BindGroup,
    vertex_count: u32,
    /// Whether the last [`Passes::prepare`] was for vertex mode (then `encode` computes the
    /// vertex colours first).
    vertex_mode: bool,
    uniforms: wgpu::Buffer,
    blends: wgpu::Buffer,
    shadow_map: wgpu::TextureView,
    /// The triangles' corners, 3 per triangle: a storage buffer for the surface pass, the
    /// index buffer of the depth-only passes.
    corners: wgpu::Buffer,
    corner_count: u32,
    /// Per vertex, its environment patch: x, y, width | height << 16, offset.
    patch_texels: wgpu::Buffer,
    values: Values,
    /// The sample's width and height in texels.
    sample_size: (u32, u32),
    tileable: bool,
    texel: f32,
    /// Bounding ball of the model, which the light's orthographic view is fitted to.
    ball: (Vec3, f32),
}

impl Passes {
    /// Uploads the scene and the sample's `values` (the material's images, or `factors`,
    /// as [`super::sample::plan`] chose) and builds the pipelines for `target`; with
    /// `patches` (the environment's patch of every vertex,
    /// [`crate::render::ambient::patch_rects`]), room for the environment's texels.
    /// [`super::sample::estimate`] counts the same uploads.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        (scene, material, factors): (&Scene, &Material, Option<&FactoredStack>),
        target: TargetFormat,
        values: &Values,
        patches: Option<&[TexelRect]>,
    ) -> Result<Passes> {
        let limits = device.limits();
        let blend_bytes = (scene.mesh.vertex_count() * std::mem::size_of::<GpuBlend>()) as u64;
        check_binding(&format!("{} vertices' blends", scene.mesh.vertex_count()), blend_bytes, &limits)?;
        let texel_count = patches.map_or(0, |p| p.iter().map(TexelRect::area).sum::<usize>());
        let texel_bytes = texel_count as u64 * 12;
        check_binding("the environment's texels", texel_bytes, &limits)?;
        let (images, image_table) = sample_values(device, queue, (material, factors), values)?;
        let images = images.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let places = storage(device, "image table", bytemuck::cast_slice(&image_table));
        let vertices = storage(device, "vertices", bytemuck::cast_slice(&gpu_vertices(scene, material)));
        let corners: Vec<u32> = scene.mesh.triangles().iter().flatten().copied().collect();
        // also the index buffer of the depth-only passes
        let corner_buffer = buffer(
            device,
            "corners",
            bytemuck::cast_slice(&corners),
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDEX,
        );
        let blends = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("blends"),
            size: blend_bytes.max(4),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("uniforms"),
            size: std::mem::size_of::<Uniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let shadow_map = depth_texture(device, (SHADOW_MAP_SIZE, SHADOW_MAP_SIZE), target.depth, true, 1);
        let headers = patch_headers(patches.unwrap_or(&[]));
        let patch_headers = storage(device, "environment patches", bytemuck::cast_slice(&headers));
        let patch_texels = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("environment texels"),
            size: texel_bytes.max(16),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("shadow comparison"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });
        let vertex_colours = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vertex colours"),
            size: (scene.mesh.vertex_count() as u64 * 16).max(16),
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let (colours_read_layout, colours_write_layout) = pipeline::vertex_colour_layouts(device);
        let colour_group = |layout, binding| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vertex colours"),
                layout,
                entries: &[buffer_entry(binding, &vertex_colours)],
            })
        };
        let colours_read = colour_group(&colours_read_layout, 0);
        let colours_write = colour_group(&colours_write_layout, 1);
        let surface_layout = pipeline::bind_group_layout(device);
        let shadow_layout = pipeline::shadow_bind_group_layout(device);
        let buffers = [&uniforms, &vertices, &corner_buffer, &blends];
        let surface_bindings = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("surface bindings"),
            layout: &surface_layout,
            entries: &[
                buffer_entry(0, buffers[0]),
                buffer_entry(1, buffers[1]),
                buffer_entry(2, buffers[2]),
                buffer_entry(3, buffers[3]),
                wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(&images) },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: wgpu::BindingResource::TextureView(&shadow_map),
                },
                wgpu::BindGroupEntry { binding: 6, resource: wgpu::BindingResource::Sampler(&sampler) },
                buffer_entry(7, &places),
                buffer_entry(8, &patch_headers),
                buffer_entry(9, &patch_texels),
            ],
        });
        let shadow_bindings = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shadow bindings"),
            layout: &shadow_layout,
            entries: &[buffer_entry(0, buffers[0]), buffer_entry(1, buffers[1])],
        });
        let (lo, hi) = scene.mesh.bounds();
        Ok(Passes {
            shadow_pipeline: pipeline::shadow(device, &shadow_layout, target.depth),
            depth_pipeline: pipeline::depth_prepass(device, &surface_layout, target),
            surface_pipeline: pipeline::surface(device, &surface_layout, &colours_read_layout, target),
            colour_pipeline: pipeline::vertex_colours(device, &surface_layout, &colours_write_layout),
            shadow_bindings,
            surface_bindings,
            colours_read,
            colours_write,
            vertex_count: scene.mesh.vertex_count() as u32,
            vertex_mode: false,
            uniforms,
            blends,
            shadow_map,
            corner_count: corners.len() as u32,
            corners: corner_buffer,
            patch_texels,
            values: *values,
            sample_size: (material.width() as u32, material.height() as u32),
            tileable: material.tileable,
            texel: scene.texel,
            ball: (0.5 * (lo + hi), (0.5 * (hi - lo).length()).max(1e-6)),
        })
    }

    /// Uploads the environment's texels (for the patches given to [`Passes::new`]).
    pub fn upload_ambient(&self, queue: &wgpu::Queue, ambient: &Ambient) {
        let texels: Vec<f32> = ambient.texels().iter().flat_map(|t| t.to_array()).collect();
        if !texels.is_empty() {
            queue.write_buffer(&self.patch_texels, 0, bytemuck::cast_slice(&texels));
        }
    }

    /// Writes this frame's blends (one per vertex) and uniforms.
    pub fn prepare(&mut self, queue: &wgpu::Queue, shot: &Shot, blends: &[Blend16], settings: FrameSettings) {
        let gpu: Vec<GpuBlend> =
            blends.iter().map(|b| GpuBlend { image: b.image, weight: b.weight }).collect();
        queue.write_buffer(&self.blends, 0, bytemuck::cast_slice(&gpu));
        queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&self.uniforms_for(shot, settings)));
        self.vertex_mode = settings.mode == Mode::Vertex;
    }

    fn uniforms_for(&self, shot: &Shot, settings: FrameSettings) -> Uniforms {
        let camera = &shot.camera;
        let perspective = matches!(camera.projection, Projection::Perspective { .. });
        let radius = self.ball.1;
        let (factor_groups, colour) = match &self.values {
            Values::Factors { layout: l, colour } => ([l.groups[0], l.groups[1], l.groups[2], 1], *colour),
            Values::Atlas { .. } => ([0; 4], factors::ColourUniform { model: [0; 4], rows: [[0.0; 4]; 3] }),
        };
        Uniforms {
            light_view_proj: self.light_camera(shot.light).view_proj().to_cols_array_2d(),
            view_proj: camera.view_proj().to_cols_array_2d(),
            light: shot.light.extend(0.0).to_array(),
            eye: camera.eye.extend(if perspective { 1.0 } else { 0.0 }).to_array(),
            towards_eye: (camera.eye - camera.target).normalize().extend(0.0).to_array(),
            flags: [
                (settings.mode == Mode::Pixel) as u32,
                settings.false_colour as u32,
                settings.shadows as u32,
                self.tileable as u32,
            ],
            atlas: [self.sample_size.0, self.sample_size.1, 0, 0],
            params: [self.texel, 2.0 * radius / SHADOW_MAP_SIZE as f32, 1.0 / SHADOW_MAP_SIZE as f32, 0.0],
            lighting: [settings.sun, settings.environment as u32 as f32, 0.0, 0.0],
            factors: factor_groups,
            colour_model: colour.model,
            colour_rows: colour.rows,
        }
    }

    /// An orthographic camera looking along the light at the model's bounding ball.
    fn light_camera(&self, light: Vec3) -> Camera {
        let (centre, radius) = self.ball;
        let r = radius * 1.02;
        Camera {
            eye: centre + light * 2.0 * r,
            target: centre,
            up: if light.y.abs() > 0.999 { Vec3::NEG_Z } else { Vec3::Y },
            projection: Projection::Orthographic { half_height: r },
            width: SHADOW_MAP_SIZE,
            height: SHADOW_MAP_SIZE,
            near: 0.5 * r,
            far: 3.5 * r,
        }
    }

    /// Records the shadow pass, the camera's depth pre-pass and the surface pass into
    /// `target` (cleared to `clear`; drawn through `targets`' multisampled texture if any).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        targets: &FrameTargets,
        clear: wgpu::Color,
    ) {
        let depth = &targets.depth;
        let (view, resolve_target) = match &targets.multisampled {
            Some(m) => (m, Some(target)),
            None => (target, None),
        };
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("shadow pass"),
                color_attachments: &[],
                depth_stencil_attachment: Some(depth_attachment(&self.shadow_map)),
                ..Default::default()
            });
            pass.set_pipeline(&self.shadow_pipeline);
            pass.set_bind_group(0, &self.shadow_bindings, &[]);
            pass.set_index_buffer(self.corners.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..self.corner_count, 0, 0..1);
        }
        if self.vertex_mode && self.vertex_count > 0 {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("vertex colours"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.colour_pipeline);
            pass.set_bind_group(0, &self.surface_bindings, &[]);
            pass.set_bind_group(1, &self.colours_write, &[]);
            // rows of at most 65535 groups of 64 (the least limit on a dispatch's side)
            let groups = self.vertex_count.div_ceil(64);
            let row = groups.min(65535);
            pass.dispatch_workgroups(row, groups.div_ceil(row), 1);
        }
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("depth pre-pass"),
                color_attachments: &[],
                depth_stencil_attachment: Some(depth_attachment(depth)),
                ..Default::default()
            });
            pass.set_pipeline(&self.depth_pipeline);
            pass.set_bind_group(0, &self.surface_bindings, &[]);
            pass.set_index_buffer(self.corners.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..self.corner_count, 0, 0..1);
        }
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("surface pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target,
                // the multisampled texture is only needed until it is resolved
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
                    store: if resolve_target.is_some() {
                        wgpu::StoreOp::Discard
                    } else {
                        wgpu::StoreOp::Store
                    },
                },
            })],
            // the pre-pass's depths, read only: nothing after this pass needs them
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: depth,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Load, store: wgpu::StoreOp::Discard }),
                stencil_ops: None,
            }),
            ..Default::default()
        });
        pass.set_pipeline(&self.surface_pipeline);
        pass.set_bind_group(0, &self.surface_bindings, &[]);
        pass.set_bind_group(1, &self.colours_read, &[]);
        pass.draw(0..self.corner_count, 0..1);
    }
}

/// The sample's values on the GPU: the texture the shader's `images` binding reads (the
/// atlas, or the texel factors) and its image table (per image its atlas tile, or its
/// factor row and scale).
fn sample_values(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    (material, factors): (&Material, Option<&FactoredStack>),
    values: &Values,
) -> Result<(wgpu::Texture, Vec<[f32; 4]>)> {
    match values {
        Values::Atlas { layout, format } => {
            let texture = atlas::upload(device, queue, material, layout, *format);
            // small integers, exact as f32
            let places = (0..material.len() as u32)
                .map(|i| {
                    let (layer, x, y) = layout.place(i);
                    [layer as f32, x as f32, y as f32, 0.0]
                })
                .collect();
            Ok((texture, places))
        }
        Values::Factors { layout, .. } => {
            let f =
                factors.ok_or_else(|| Error::internal("the sample's factors were not kept for the GPU"))?;
            Ok((factors::upload_texels(device, queue, f, layout), factors::image_table(f, layout)))
        }
    }
}

fn gpu_vertices(scene: &Scene, material: &Material) -> Vec<GpuVertex> {
    let (p, f) = (scene.mesh.positions(), &scene.frames);
    // Unused by a texture-mapped scene's shader path (its corners are interpolated).
    let belonging = if scene.mapped { &[][..] } else { scene.belonging(material) };
    (0..p.len())
        .map(|v| GpuVertex {
            position: p[v].to_array(),
            label: scene.labels.get(v).copied().unwrap_or(0) as u32,
            s: f.s[v].to_array(),
            u: scene.uv[v].x,
            t: f.t[v].to_array(),
            v: scene.uv[v].y,
            n: f.n[v].to_array(),
            belonging: belonging.get(v).copied().unwrap_or(1.0),
        })
        .collect()
}

fn storage(device: &wgpu::Device, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    buffer(device, label, bytes, wgpu::BufferUsages::STORAGE)
}

fn buffer(device: &wgpu::Device, label: &str, bytes: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
    // An empty binding is invalid (and an array binding needs one element, up to 16 bytes).
    let bytes = if bytes.is_empty() { &[0u8; 16][..] } else { bytes };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytes,
        usage,
    })
}

fn buffer_entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
}

fn depth_attachment(view: &wgpu::TextureView) -> wgpu::RenderPassDepthStencilAttachment<'_> {
    wgpu::RenderPassDepthStencilAttachment {
        view,
        depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
        stencil_ops: None,
    }
}

/// Per vertex, where its environment patch lies: x, y, width | height << 16, offset.
fn patch_headers(rects: &[TexelRect]) -> Vec<[i32; 4]> {
    let mut offset = 0;
    rects
        .iter()
        .map(|r| {
            let header = [r.x, r.y, (r.width | r.height << 16) as i32, offset as i32];
            offset += r.area();
            header
        })
        .collect()
}

/// A depth texture of `size` and `format`; `sampled` for the shadow map, which the surface
/// pass reads.
pub fn depth_texture(
    device: &wgpu::Device,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    sampled: bool,
    samples: u32,
) -> wgpu::TextureView {
    let mut usage = wgpu::TextureUsages::RENDER_ATTACHMENT;
    if sampled {
        usage |= wgpu::TextureUsages::TEXTURE_BINDING;
    }
    device
        .create_texture(&wgpu::TextureDescriptor {
            label: Some("depth"),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: samples,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
        .create_view(&Default::default())
}
