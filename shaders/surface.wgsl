// The surface pass. Which images a vertex blends and their weights come from the CPU
// (Scene::vertex_blends, the one shading core); this shader only fetches texels and sums,
// mirroring Material::texel, Material::shade, Scene::predict_uv and Scene::shade_point.

struct Uniforms {
    light_view_proj: mat4x4<f32>,
    view_proj: mat4x4<f32>,
    // xyz: unit vector towards the light
    light: vec4<f32>,
    // xyz: camera position; w: 1 perspective, 0 orthographic
    eye: vec4<f32>,
    // xyz: unit vector towards the viewer (used when orthographic)
    towards_eye: vec4<f32>,
    // mode (0 vertex, 1 pixel), display (0 BTF / first image, 1 texton false colour),
    // shadows (0/1), tileable (0/1)
    flags: vec4<u32>,
    // sample image width, height; tiles per atlas row; tiles per layer
    atlas: vec4<u32>,
    // x: one sample texel in model units; y: normal offset of shadow lookups (model units);
    // z: one shadow-map texel in uv units
    params: vec4<f32>,
};

struct Vertex {
    // xyz position, w the texton label (bit pattern)
    pos_label: vec4<f32>,
    // s, then the vertex's sample u
    s_u: vec4<f32>,
    // t, then the vertex's sample v
    t_v: vec4<f32>,
    n: vec4<f32>,
};

struct Blend {
    image: array<u32, 16>,
    weight: array<f32, 16>,
};

@group(0) @binding(0) var<uniform> u: Uniforms;
@group(0) @binding(1) var<storage, read> vertices: array<Vertex>;
@group(0) @binding(2) var<storage, read> corners: array<u32>;
@group(0) @binding(3) var<storage, read> blends: array<Blend>;
@group(0) @binding(4) var images: texture_2d_array<f32>;
@group(0) @binding(5) var shadow_map: texture_depth_2d;
@group(0) @binding(6) var shadow_sampler: sampler_comparison;

struct Varyings {
    @builtin(position) clip: vec4<f32>,
    // perspective-correct barycentric weights of the triangle's corners
    @location(0) bary: vec3<f32>,
    @location(1) @interpolate(flat) triangle: u32,
    // vertex mode: the corner colours, interpolated like the CPU's bary-weighted sum
    @location(2) colour: vec3<f32>,
};

fn edge(i: i32, n: i32) -> i32 {
    if u.flags.w != 0u {
        return ((i % n) + n) % n;
    }
    return clamp(i, 0, n - 1);
}

fn fetch(image: u32, x: i32, y: i32) -> vec3<f32> {
    let w = i32(u.atlas.x);
    let h = i32(u.atlas.y);
    let tile = image % u.atlas.w;
    let origin = vec2<i32>(i32(tile % u.atlas.z) * w, i32(tile / u.atlas.z) * h);
    let at = origin + vec2<i32>(edge(x, w), edge(y, h));
    return textureLoad(images, at, i32(image / u.atlas.w), 0).rgb;
}

// Material::texel: bilinear, integers are texel centres.
fn texel(image: u32, uv: vec2<f32>) -> vec3<f32> {
    let f0 = floor(uv);
    let f = uv - f0;
    let x0 = i32(f0.x);
    let y0 = i32(f0.y);
    if f.x == 0.0 && f.y == 0.0 {
        return fetch(image, x0, y0);
    }
    let top = mix(fetch(image, x0, y0), fetch(image, x0 + 1, y0), f.x);
    let bottom = mix(fetch(image, x0, y0 + 1), fetch(image, x0 + 1, y0 + 1), f.x);
    return mix(top, bottom, f.y);
}

// A colour per texton label, for the false-colour display.
fn label_colour(label: u32) -> vec3<f32> {
    var h = label * 2654435761u;
    h = (h ^ (h >> 15u)) * 2246822519u;
    h = h ^ (h >> 13u);
    return vec3<f32>(f32(h & 255u), f32((h >> 8u) & 255u), f32((h >> 16u) & 255u)) / 255.0 * 0.8 + 0.1;
}

// Material::shade, or in false colour the label's colour times the blend's one weight (n·l).
fn shade(v: u32, uv: vec2<f32>) -> vec3<f32> {
    if u.flags.y == 1u {
        return label_colour(bitcast<u32>(vertices[v].pos_label.w)) * blends[v].weight[0];
    }
    var c = vec3<f32>(0.0);
    for (var k = 0u; k < 16u; k++) {
        let w = blends[v].weight[k];
        if w != 0.0 {
            c += w * texel(blends[v].image[k], uv);
        }
    }
    return c;
}

// Fraction of the light reaching `p` (on a surface with unit normal `n`): 4 filtered
// comparison taps around its shadow-map position.
fn light_reaches(p: vec3<f32>, n: vec3<f32>) -> f32 {
    if u.flags.z == 0u {
        return 1.0;
    }
    let clip = u.light_view_proj * vec4<f32>(p + n * u.params.y, 1.0);
    let ndc = clip.xyz / clip.w;
    let at = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
    let d = u.params.z * 0.5;
    var sum = 0.0;
    sum += textureSampleCompareLevel(shadow_map, shadow_sampler, at + vec2<f32>(-d, -d), ndc.z);
    sum += textureSampleCompareLevel(shadow_map, shadow_sampler, at + vec2<f32>(d, -d), ndc.z);
    sum += textureSampleCompareLevel(shadow_map, shadow_sampler, at + vec2<f32>(-d, d), ndc.z);
    sum += textureSampleCompareLevel(shadow_map, shadow_sampler, at + vec2<f32>(d, d), ndc.z);
    return sum * 0.25;
}

fn position(v: u32) -> vec3<f32> {
    return vertices[v].pos_label.xyz;
}

fn uv_of(v: u32) -> vec2<f32> {
    return vec2<f32>(vertices[v].s_u.w, vertices[v].t_v.w);
}

// Scene::vertex_colours: the vertex's blend at its own coordinate, black where unlit.
fn vertex_colour(v: u32) -> vec3<f32> {
    let n = vertices[v].n.xyz;
    if dot(n, u.light.xyz) <= 0.0 {
        return vec3<f32>(0.0);
    }
    return shade(v, uv_of(v)) * step(0.5, light_reaches(position(v), n));
}

@vertex
fn vs_surface(@builtin(vertex_index) i: u32) -> Varyings {
    let v = corners[i];
    var out: Varyings;
    out.clip = u.view_proj * vec4<f32>(position(v), 1.0);
    let k = i % 3u;
    out.bary = vec3<f32>(f32(k == 0u), f32(k == 1u), f32(k == 2u));
    out.triangle = i / 3u;
    out.colour = vec3<f32>(0.0);
    if u.flags.x == 0u {
        out.colour = vertex_colour(v);
    }
    return out;
}

// Scene::predict_uv: the corner's coordinate plus the offset to p in its tangent frame.
fn predict_uv(v: u32, p: vec3<f32>) -> vec2<f32> {
    let d = p - position(v);
    return uv_of(v) + vec2<f32>(dot(d, vertices[v].s_u.xyz), -dot(d, vertices[v].t_v.xyz)) / u.params.x;
}

@fragment
fn fs_surface(in: Varyings) -> @location(0) vec4<f32> {
    let a = corners[in.triangle * 3u];
    let b = corners[in.triangle * 3u + 1u];
    let c = corners[in.triangle * 3u + 2u];
    let normal = normalize(cross(position(b) - position(a), position(c) - position(a)));
    let p = in.bary.x * position(a) + in.bary.y * position(b) + in.bary.z * position(c);
    var towards_eye = u.towards_eye.xyz;
    if u.eye.w != 0.0 {
        towards_eye = u.eye.xyz - p;
    }
    let black = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    if dot(normal, towards_eye) <= 0.0 {
        return black;
    }
    if u.flags.x == 0u {
        return vec4<f32>(in.colour, 1.0);
    }
    if dot(normal, u.light.xyz) <= 0.0 {
        return black;
    }
    let lit = light_reaches(p, normal);
    if lit <= 0.0 {
        return black;
    }
    let colour = in.bary.x * shade(a, predict_uv(a, p)) + in.bary.y * shade(b, predict_uv(b, p))
        + in.bary.z * shade(c, predict_uv(c, p));
    return vec4<f32>(colour * lit, 1.0);
}
