//! The render pipelines (depth-only shadow pass from the light; depth pre-pass and surface
//! pass from the camera) and the bind group layouts they use.

/// A vertex's blend as the shader reads it (here, beside the pipelines that read it, so that
/// the memory estimate can size it without depending on the passes).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuBlend {
    pub(crate) image: [u32; 16],
    pub(crate) weight: [f32; 16],
}

/// Default side of the square shadow map, in texels.
pub const SHADOW_MAP_SIZE: u32 = 2048;

/// What the camera passes draw into: the colour and depth formats and the samples per
/// pixel (4 with multisampling, resolved into the colour target).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TargetFormat {
    /// Format of the colour target.
    pub colour: wgpu::TextureFormat,
    /// Format of the depth buffer.
    pub depth: wgpu::TextureFormat,
    /// Samples per pixel: 1, or 4 with multisampling.
    pub samples: u32,
}

/// The layout of `surface.wgsl`'s group 0 (`shadow.wgsl` uses its first two bindings).
pub fn bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    use wgpu::{BindingType as B, ShaderStages as S};
    let both = S::VERTEX | S::FRAGMENT | S::COMPUTE;
    let storage = B::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: true },
        has_dynamic_offset: false,
        min_binding_size: None,
    };
    let entry = |binding, ty| wgpu::BindGroupLayoutEntry { binding, visibility: both, ty, count: None };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("surface bindings"),
        entries: &[
            entry(
                0,
                B::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
            ),
            entry(1, storage),
            entry(2, storage),
            entry(3, storage),
            entry(
                4,
                B::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2Array,
                    multisampled: false,
                },
            ),
            entry(
                5,
                B::Texture {
                    sample_type: wgpu::TextureSampleType::Depth,
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
            ),
            entry(6, B::Sampler(wgpu::SamplerBindingType::Comparison)),
            entry(7, storage),
            entry(8, storage),
            entry(9, storage),
        ],
    })
}

/// The layouts of `surface.wgsl`'s group 1, the vertex colours: read by the surface pass
/// (binding 0), written by the vertex-colour compute pass (binding 1).
pub fn vertex_colour_layouts(device: &wgpu::Device) -> (wgpu::BindGroupLayout, wgpu::BindGroupLayout) {
    let layout = |binding, visibility, read_only| {
        device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vertex colours"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding,
                visibility,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        })
    };
    (layout(0, wgpu::ShaderStages::VERTEX, true), layout(1, wgpu::ShaderStages::COMPUTE, false))
}

/// The layout of `shadow.wgsl`'s group 0.
pub fn shadow_bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    use wgpu::BindingType as B;
    let storage = B::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: true },
        has_dynamic_offset: false,
        min_binding_size: None,
    };
    let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX,
        ty,
        count: None,
    };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("shadow bindings"),
        entries: &[
            entry(
                0,
                B::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
            ),
            entry(1, storage),
        ],
    })
}

fn layout(device: &wgpu::Device, bindings: &wgpu::BindGroupLayout) -> wgpu::PipelineLayout {
    groups_layout(device, &[bindings])
}

fn groups_layout(device: &wgpu::Device, groups: &[&wgpu::BindGroupLayout]) -> wgpu::PipelineLayout {
    let groups: Vec<_> = groups.iter().map(|g| Some(*g)).collect();
    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: None,
        bind_group_layouts: &groups,
        immediate_size: 0,
    })
}

/// Vertex mode's per-vertex colours (`cs_vertex_colours`), run before the camera passes.
pub fn vertex_colours(
    device: &wgpu::Device,
    bindings: &wgpu::BindGroupLayout,
    colours: &wgpu::BindGroupLayout,
) -> wgpu::ComputePipeline {
    let module = surface_module(device);
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("vertex colours"),
        layout: Some(&groups_layout(device, &[bindings, colours])),
        module: &module,
        entry_point: Some("cs_vertex_colours"),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// Depth from the light; both faces cast shadows (like the CPU's shadow rays), and the
/// slope-scaled bias keeps lit surfaces from shadowing themselves.
pub fn shadow(
    device: &wgpu::Device,
    bindings: &wgpu::BindGroupLayout,
    depth: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("shadow.wgsl"),
        source: wgpu::ShaderSource::Wgsl(include_str!("../../../shaders/shadow.wgsl").into()),
    });
    let bias = wgpu::DepthBiasState { constant: 2, slope_scale: 2.0, clamp: 0.0 };
    let target = TargetFormat { colour: wgpu::TextureFormat::Rgba8Unorm, depth, samples: 1 };
    depth_only(device, bindings, (&module, "vs_shadow"), "shadow pass", bias, target)
}

/// A pipeline that writes depth only (less-than test), from vertex entry point `entry`.
fn depth_only(
    device: &wgpu::Device,
    bindings: &wgpu::BindGroupLayout,
    (module, entry): (&wgpu::ShaderModule, &str),
    label: &str,
    bias: wgpu::DepthBiasState,
    target: TargetFormat,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&layout(device, bindings)),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: target.depth,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias,
        }),
        multisample: wgpu::MultisampleState { count: target.samples, ..Default::default() },
        fragment: None,
        multiview_mask: None,
        cache: None,
    })
}

fn surface_module(device: &wgpu::Device) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("surface.wgsl"),
        source: wgpu::ShaderSource::Wgsl(include_str!("../../../shaders/surface.wgsl").into()),
    })
}

/// The camera's depth only (`vs_depth`, the same clip position as `vs_surface`), so that the
/// surface pass shades each pixel once: on a software rasteriser the fragment shader's 48
/// bilinear lookups are most of a frame, and overlapping fragments multiplied them.
pub fn depth_prepass(
    device: &wgpu::Device,
    bindings: &wgpu::BindGroupLayout,
    target: TargetFormat,
) -> wgpu::RenderPipeline {
    let module = surface_module(device);
    depth_only(device, bindings, (&module, "vs_depth"), "depth pre-pass", Default::default(), target)
}

/// The surface pass into `target` (a float format offscreen, the window's format in the
/// viewer); no culling, the shader blackens back faces as the CPU does.
/// It runs after [`depth_prepass`] and shades only the fragments at the depth that pass kept
/// (`Equal`, no depth writes; `@invariant` positions make the depths identical).
pub fn surface(
    device: &wgpu::Device,
    bindings: &wgpu::BindGroupLayout,
    colours: &wgpu::BindGroupLayout,
    target: TargetFormat,
) -> wgpu::RenderPipeline {
    let module = surface_module(device);
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("surface pass"),
        layout: Some(&groups_layout(device, &[bindings, colours])),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_surface"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: target.depth,
            depth_write_enabled: Some(false),
            depth_compare: Some(wgpu::CompareFunction::Equal),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: wgpu::MultisampleState { count: target.samples, ..Default::default() },
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_surface"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: target.colour,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

#[cfg(test)]
mod tests {
    use wgpu::naga;

    /// The surface shader parses and validates without an adapter (a machine without a GPU
    /// would otherwise first find a mistake in it at run time).
    #[test]
    fn the_surface_shader_validates() {
        let source = include_str!("../../../shaders/surface.wgsl");
        let module =
            naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)));
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
            .validate(&module)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)));
    }
}
