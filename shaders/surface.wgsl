// The surface pass. Which images a vertex blends and their weights come from the CPU
// (Scene::vertex_blends, the one shading core), and so does the environment's share (per
// vertex a patch of environment-lit texels, Ambient::compute); this shader only fetches
// texels (or computes them from the sample's factors, FactoredStack::rgb) and sums,
// mirroring Material::texel, Material::shade, Scene::predict_uv, Ambient::at and the CPU
// renderer's Shading::ray.

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
    // sample width, height in texels (z, w unused)
    atlas: vec4<u32>,
    // x: one sample texel in model units; y: normal offset of shadow lookups (model units);
    // z: one shadow-map texel in uv units
    params: vec4<f32>,
    // x: strength of the directional light; y: 1 to add the environment's patches
    lighting: vec4<f32>,
    // the sample as factors (w = 1; 0: an atlas of images): groups of four components of
    // channels 0, 1, 2 (FactorLayout)
    factors: vec4<u32>,
    // the factors' colour model: its number (ColourModel::id), 1 if log-encoded
    colour_model: vec4<u32>,
    // the affine map after the model's own decoding: rows R, G, B (xyz), offset (w)
    colour_rows: array<vec4<f32>, 3>,
};

struct Vertex {
    // xyz position, w the texton label (bit pattern)
    pos_label: vec4<f32>,
    // s, then the vertex's sample u
    s_u: vec4<f32>,
    // t, then the vertex's sample v
    t_v: vec4<f32>,
    // n, then the vertex's share in its copy (Scene::belonging)
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
// the atlas of sample images, or the texel factors (layer j: texel (x, y)'s group j)
@group(0) @binding(4) var images: texture_2d_array<f32>;
@group(0) @binding(5) var shadow_map: texture_depth_2d;
@group(0) @binding(6) var shadow_sampler: sampler_comparison;
// per image: for an atlas its layer, then the texel origin of its tile (AtlasLayout::place);
// for factors its groups of image factors, then a vec4 whose x is its scale
@group(0) @binding(7) var<storage, read> places: array<vec4<f32>>;
// per vertex, its environment patch: first texel x, y; width | height << 16; offset into
// patch_texels (in texels)
@group(0) @binding(8) var<storage, read> patches: array<vec4<i32>>;
// the patches' environment-lit texels, RGB
@group(0) @binding(9) var<storage, read> patch_texels: array<f32>;
// Vertex mode: each vertex's colour, written once per vertex by cs_vertex_colours (binding 1)
// and read per corner by vs_surface (binding 0), the same buffer.
@group(1) @binding(0) var<storage, read> vertex_colours: array<vec4<f32>>;
@group(1) @binding(1) var<storage, read_write> vertex_colours_out: array<vec4<f32>>;

struct Varyings {
    // invariant: the depth pre-pass (vs_depth) must produce the same depth bit for bit, since
    // this pass only shades fragments whose depth equals the one the pre-pass kept
    @invariant @builtin(position) clip: vec4<f32>,
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

// Where a bilinear lookup at uv reads in any one image: the two columns and rows (already
// wrapped or clamped, Material::edge) and the weights between them. The same for all 16
// images of a corner, so it is computed once per corner, not once per texel fetched
// (integer division is slow on software rasterisers, which run it lane by lane).
struct Footprint {
    x: vec2<i32>,
    y: vec2<i32>,
    f: vec2<f32>,
};

fn footprint(uv: vec2<f32>) -> Footprint {
    let w = i32(u.atlas.x);
    let h = i32(u.atlas.y);
    let f0 = floor(uv);
    let x0 = i32(f0.x);
    let y0 = i32(f0.y);
    var out: Footprint;
    out.x = vec2<i32>(edge(x0, w), edge(x0 + 1, w));
    out.y = vec2<i32>(edge(y0, h), edge(y0 + 1, h));
    out.f = uv - f0;
    return out;
}

// One texel of an image: read from the atlas, or computed from the factors.
fn value(image: u32, o: vec2<i32>, layer: i32, x: i32, y: i32) -> vec3<f32> {
    if u.factors.w != 0u {
        return factor_value(image, vec2<i32>(x, y));
    }
    return textureLoad(images, o + vec2<i32>(x, y), layer, 0).rgb;
}

// Material::texel: bilinear, integers are texel centres; image's tile from the table of
// places (AtlasLayout::place) rather than divisions.
fn texel(image: u32, at: Footprint) -> vec3<f32> {
    var o = vec2<i32>(0);
    var layer = 0;
    if u.factors.w == 0u {
        let place = places[image];
        o = vec2<i32>(i32(place.y), i32(place.z));
        layer = i32(place.x);
    }
    let a = value(image, o, layer, at.x.x, at.y.x);
    if at.f.x == 0.0 && at.f.y == 0.0 {
        return a;
    }
    let b = value(image, o, layer, at.x.y, at.y.x);
    let c = value(image, o, layer, at.x.x, at.y.y);
    let d = value(image, o, layer, at.x.y, at.y.y);
    let top = mix(a, b, at.f.x);
    let bottom = mix(c, d, at.f.x);
    return mix(top, bottom, at.f.y);
}

// Must equal DRR_EPS (factors::SHADER_EPS).
const EPS: f32 = 1e-5;

// K-term dot product of `groups` groups of four, from texture layer (and image table row
// offset) `first`.
fn dot_groups(row: u32, first: u32, groups: u32, p: vec2<i32>) -> f32 {
    var sum = 0.0;
    for (var j = first; j < first + groups; j++) {
        sum += dot(places[row + j], textureLoad(images, p, i32(j), 0));
    }
    return sum;
}

// FactoredStack::rgb: image's three channel values at texel p, then decode_channels.
fn factor_value(image: u32, p: vec2<i32>) -> vec3<f32> {
    let g = u.factors;
    let row = image * (g.x + g.y + g.z + 1u);
    let v = vec3<f32>(dot_groups(row, 0u, g.x, p), dot_groups(row, g.x, g.y, p), dot_groups(row, g.x + g.y, g.z, p));
    var rgb = colour_to_rgb(v);
    if u.colour_model.y != 0u {
        rgb = exp(rgb) - EPS;
    }
    return rgb * places[row + g.x + g.y + g.z].x;
}

// btflib's signed logarithm decoding (ColourModel::LogYLogUv).
fn signed_log(x: f32) -> f32 {
    return select(-1.0, 1.0, x >= 0.0) * exp(abs(x) + log(EPS));
}

// ColourModel::to_rgb for every model but Lab (refused on the CPU): the model's own
// decoding, then the affine map of the uniforms (identity where the model has none).
fn colour_to_rgb(v: vec3<f32>) -> vec3<f32> {
    var w = v;
    switch u.colour_model.x {
        case 5u: {
            w = vec3<f32>(1.0 - v.y - v.z, v.y, v.z) * v.x;
        }
        case 6u: {
            let sum = 3.0 * v.x;
            w = vec3<f32>(sum - (v.y + v.z) / 3.0, sum + v.y * sum, sum + v.z * sum);
        }
        case 9u: {
            w = vec3<f32>(exp(v.x) - EPS, v.y, v.z);
        }
        case 10u: {
            w = vec3<f32>(exp(v.x) - EPS, signed_log(v.y), signed_log(v.z));
        }
        case 11u: {
            let y = exp(v.x) - EPS;
            w = vec3<f32>(y, v.y * (y + EPS), v.z * (y + EPS));
        }
        case 12u: {
            w = exp(v) - EPS;
        }
        default: {}
    }
    let r = u.colour_rows;
    return vec3<f32>(dot(r[0].xyz, w), dot(r[1].xyz, w), dot(r[2].xyz, w)) + vec3<f32>(r[0].w, r[1].w, r[2].w);
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
    let at = footprint(uv);
    var c = vec3<f32>(0.0);
    for (var k = 0u; k < 16u; k++) {
        let w = blends[v].weight[k];
        if w != 0.0 {
            c += w * texel(blends[v].image[k], at);
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

fn patch_texel(base: i32, width: i32, height: i32, x: f32, y: f32) -> vec3<f32> {
    let i = clamp(i32(x), 0, width - 1);
    let j = clamp(i32(y), 0, height - 1);
    let o = 3 * (base + j * width + i);
    return vec3<f32>(patch_texels[o], patch_texels[o + 1], patch_texels[o + 2]);
}

// Ambient::at: the environment's colour at uv as vertex v sees it, bilinear in its patch.
fn ambient_at(v: u32, uv: vec2<f32>) -> vec3<f32> {
    let p = patches[v];
    let width = p.z & 0xffff;
    let height = p.z >> 16u;
    let local = uv - vec2<f32>(f32(p.x), f32(p.y));
    let f = floor(local);
    let t = local - f;
    let top = mix(patch_texel(p.w, width, height, f.x, f.y), patch_texel(p.w, width, height, f.x + 1.0, f.y), t.x);
    let bottom =
        mix(patch_texel(p.w, width, height, f.x, f.y + 1.0), patch_texel(p.w, width, height, f.x + 1.0, f.y + 1.0), t.x);
    return mix(top, bottom, t.y);
}

// The CPU renderer's vertex colours: the directional light's blend at the vertex's own
// coordinate (black where unlit), plus the environment's share there.
fn vertex_colour(v: u32) -> vec3<f32> {
    let n = vertices[v].n.xyz;
    var c = vec3<f32>(0.0);
    if u.lighting.x > 0.0 && dot(n, u.light.xyz) > 0.0 {
        c = u.lighting.x * shade(v, uv_of(v)) * step(0.5, light_reaches(position(v), n));
    }
    if u.lighting.y != 0.0 {
        c += ambient_at(v, uv_of(v));
    }
    return c;
}

// The camera's clip position of vertex v: the one expression both vs_depth and vs_surface use.
fn clip_of(v: u32) -> vec4<f32> {
    return u.view_proj * vec4<f32>(position(v), 1.0);
}

struct DepthOnly {
    @invariant @builtin(position) clip: vec4<f32>,
};

// The depth pre-pass: only the nearest depth per pixel, so that fs_surface then runs once
// per pixel instead of once per overlapping fragment. Drawn indexed (the index buffer is
// `corners`), so v is the vertex itself and shared corners can be shaded once.
@vertex
fn vs_depth(@builtin(vertex_index) v: u32) -> DepthOnly {
    var out: DepthOnly;
    out.clip = clip_of(v);
    return out;
}

@vertex
fn vs_surface(@builtin(vertex_index) i: u32) -> Varyings {
    let v = corners[i];
    var out: Varyings;
    out.clip = clip_of(v);
    let k = i % 3u;
    out.bary = vec3<f32>(f32(k == 0u), f32(k == 1u), f32(k == 2u));
    out.triangle = i / 3u;
    out.colour = vec3<f32>(0.0);
    if u.flags.x == 0u {
        out.colour = vertex_colours[v].rgb;
    }
    return out;
}

// Vertex mode: vertex_colour of every vertex once, rather than in vs_surface once per corner
// (about 6 corners a vertex, each 16 bilinear lookups and a shadow test). Dispatched as
// rows of `num_workgroups.x` groups of 64.
@compute @workgroup_size(64)
fn cs_vertex_colours(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let v = id.y * groups.x * 64u + id.x;
    if v >= arrayLength(&vertices) {
        return;
    }
    vertex_colours_out[v] = vec4<f32>(vertex_colour(v), 1.0);
}

// Scene::predict_uv: the corner's coordinate plus the offset to p in its tangent frame.
fn predict_uv(v: u32, p: vec3<f32>) -> vec2<f32> {
    let d = p - position(v);
    return uv_of(v) + vec2<f32>(dot(d, vertices[v].s_u.xyz), -dot(d, vertices[v].t_v.xyz)) / u.params.x;
}

// render::scene::AGREE_TEXELS
const AGREE_TEXELS: f32 = 2.0;

// The offset from a to b, across the wrap when the sample tiles (Scene::point_uv's).
fn wrapped_offset(a: vec2<f32>, b: vec2<f32>) -> vec2<f32> {
    let d = b - a;
    if u.flags.w == 0u {
        return d;
    }
    let size = vec2<f32>(f32(u.atlas.x), f32(u.atlas.y));
    return d - size * round(d / size);
}

fn agree(a: vec2<f32>, b: vec2<f32>) -> f32 {
    let d = wrapped_offset(a, b);
    return select(0.0, 1.0, dot(d, d) <= AGREE_TEXELS * AGREE_TEXELS);
}

struct PointUv {
    uv: vec2<f32>,
    // each corner's weight in it (0 outside the chosen group)
    weights: vec3<f32>,
};

// A corner's claim on the point for a group it is (1) or is not (0) in: its weight times its
// share in its copy, or times the rest (Scene::point_uv).
fn claim_of(w: f32, share: f32, agrees: f32) -> f32 {
    return w * select(1.0 - share, share, agrees > 0.0);
}

// Scene::point_uv: the predictions that agree with the lead of the largest claim, interpolated.
fn point_uv(qa: vec2<f32>, qb: vec2<f32>, qc: vec2<f32>, w: vec3<f32>, share: vec3<f32>) -> PointUv {
    let ab = agree(qa, qb);
    let ac = agree(qa, qc);
    let bc = agree(qb, qc);
    let group = vec3<f32>(w.x + ab * w.y + ac * w.z, ab * w.x + w.y + bc * w.z, ac * w.x + bc * w.y + w.z);
    let claim = vec3<f32>(
        claim_of(w.x, share.x, 1.0) + claim_of(w.y, share.y, ab) + claim_of(w.z, share.z, ac),
        claim_of(w.x, share.x, ab) + claim_of(w.y, share.y, 1.0) + claim_of(w.z, share.z, bc),
        claim_of(w.x, share.x, ac) + claim_of(w.y, share.y, bc) + claim_of(w.z, share.z, 1.0),
    );
    // the largest claim, then the larger own weight, then the last (Iterator::max_by)
    var lead = 0u;
    if claim.y > claim.x || (claim.y == claim.x && w.y >= w.x) {
        lead = 1u;
    }
    if claim.z > claim[lead] || (claim.z == claim[lead] && w.z >= w[lead]) {
        lead = 2u;
    }
    var q = array<vec2<f32>, 3>(qa, qb, qc);
    let agrees = array<vec3<f32>, 3>(vec3<f32>(1.0, ab, ac), vec3<f32>(ab, 1.0, bc), vec3<f32>(ac, bc, 1.0));
    let total = group[lead];
    // a group none of whose corners weighs on the point: its corners share it equally
    let members = agrees[lead].x + agrees[lead].y + agrees[lead].z;
    var uv = q[lead];
    var weights = vec3<f32>(0.0);
    for (var j = 0u; j < 3u; j++) {
        if agrees[lead][j] > 0.0 {
            weights[j] = select(1.0 / members, w[j] / total, total > 0.0);
            uv += weights[j] * wrapped_offset(q[lead], q[j]);
        }
    }
    return PointUv(uv, weights);
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
    // one coordinate per pixel (Scene::point_uv); the corners' blends still interpolate
    let share = vec3<f32>(vertices[a].n.w, vertices[b].n.w, vertices[c].n.w);
    let point = point_uv(predict_uv(a, p), predict_uv(b, p), predict_uv(c, p), in.bary, share);
    let uv = point.uv;
    var colour = vec3<f32>(0.0);
    if u.lighting.x > 0.0 && dot(normal, u.light.xyz) > 0.0 {
        let lit = light_reaches(p, normal);
        if lit > 0.0 {
            colour = u.lighting.x * lit
                * (in.bary.x * shade(a, uv) + in.bary.y * shade(b, uv) + in.bary.z * shade(c, uv));
        }
    }
    if u.lighting.y != 0.0 {
        // each vertex's environment patch covers its own copy: the chosen corners' only
        let w = point.weights;
        colour += w.x * ambient_at(a, uv) + w.y * ambient_at(b, uv) + w.z * ambient_at(c, uv);
    }
    return vec4<f32>(colour, 1.0);
}
