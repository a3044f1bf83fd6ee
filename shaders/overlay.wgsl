// The viewer's text overlay: one textured rectangle at the window's top-left corner,
// blended over the frame. The text image is drawn on the CPU (render::overlay).

struct Placement {
    // the overlay's size in pixels, then the window's
    sizes: vec4<f32>,
};

@group(0) @binding(0) var<uniform> placement: Placement;
@group(0) @binding(1) var text: texture_2d<f32>;

struct Varyings {
    @builtin(position) clip: vec4<f32>,
    @location(0) pixel: vec2<f32>,
};

@vertex
fn vs_overlay(@builtin(vertex_index) i: u32) -> Varyings {
    // two triangles: (0,0) (1,0) (0,1), (0,1) (1,0) (1,1)
    let corner = vec2<f32>(f32(i == 1u || i == 4u || i == 5u), f32(i == 2u || i == 3u || i == 5u));
    let pixel = corner * placement.sizes.xy;
    let ndc = vec2<f32>(pixel.x / placement.sizes.z * 2.0 - 1.0, 1.0 - pixel.y / placement.sizes.w * 2.0);
    var out: Varyings;
    out.clip = vec4<f32>(ndc, 0.0, 1.0);
    out.pixel = pixel;
    return out;
}

@fragment
fn fs_overlay(in: Varyings) -> @location(0) vec4<f32> {
    let size = vec2<i32>(placement.sizes.xy);
    let at = clamp(vec2<i32>(in.pixel), vec2<i32>(0), size - vec2<i32>(1));
    return textureLoad(text, at, 0);
}
