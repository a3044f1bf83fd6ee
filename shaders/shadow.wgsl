// Depth-only pass from the directional light: the shadow map the surface pass compares
// against. Corners are fetched like in surface.wgsl (non-indexed draw, 3 per triangle).

struct Vertex {
    // xyz position, w the texton label (bit pattern)
    pos_label: vec4<f32>,
    s_u: vec4<f32>,
    t_v: vec4<f32>,
    n: vec4<f32>,
};

@group(0) @binding(0) var<uniform> light_view_proj: mat4x4<f32>;
@group(0) @binding(1) var<storage, read> vertices: array<Vertex>;
@group(0) @binding(2) var<storage, read> corners: array<u32>;

@vertex
fn vs_shadow(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let v = corners[i];
    return light_view_proj * vec4<f32>(vertices[v].pos_label.xyz, 1.0);
}
