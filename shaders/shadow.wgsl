// Depth-only pass from the directional light: the shadow map the surface pass compares
// against. Drawn indexed with `corners` as the index buffer, so the vertex index is the
// vertex (the surface pass draws non-indexed and fetches corners itself).

struct Vertex {
    // xyz position, w the texton label (bit pattern)
    pos_label: vec4<f32>,
    s_u: vec4<f32>,
    t_v: vec4<f32>,
    n: vec4<f32>,
};

@group(0) @binding(0) var<uniform> light_view_proj: mat4x4<f32>;
@group(0) @binding(1) var<storage, read> vertices: array<Vertex>;

@vertex
fn vs_shadow(@builtin(vertex_index) v: u32) -> @builtin(position) vec4<f32> {
    return light_view_proj * vec4<f32>(vertices[v].pos_label.xyz, 1.0);
}
