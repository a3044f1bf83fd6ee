// One sub-pass of an interleaved square-template correction pass on a plane or a mesh
// (src/synth/gpu): one invocation per vertex of the sub-pass's colour. It gathers the
// vertex's candidates
// (k-coherence, or every candidate texel) as src/synth/candidates.rs does, scores them with
// the pass's metric as src/synth/metric.rs and src/synth/square_pass.rs do, in the same
// order, with the same early exits, and keeps the same winner: the CPU's coordinates to the
// bit. Every float operation is one the CPU performs, in its order:
//
// - products that feed a sum go through `opaque`, so no compiler fuses them into an FMA
//   (Rust never contracts; a GPU compiler may);
// - a sum of three written-out terms passes its first partial sum through `opaque`, so no
//   compiler reassociates it (llvmpipe's GL did: a mesh pixel's blend of three vertices
//   came out up to 3 ulps off, where Vulkan kept the order);
// - the one division (the early-exit bound, best / factor) is done exactly in integers,
//   rounded to nearest even, since WGSL's `/` may be off by 2.5 ulp;
// - everything else is +, −, × and comparisons, which WGSL rounds exactly.
//
// A plane's templates and forward shifts are its grid around the vertex; a mesh's are read
// from tables: each template pixel's vertices and weights (as metric::known_parts leaves
// them, normalised on the CPU), and each vertex's patch vertices with their offsets.
//
// A sub-pass is four entry points, dispatched in turn over its vertices: `gather` (the
// candidate list), `score` (repeatedly: at most `P.batch` candidates per vertex each time,
// resuming from the best so far; Mesa's llvmpipe ends every loop of a shader invocation
// after 65535 iterations in all), `finish` (the vertex takes its winner; no vertex reads
// another of its colour, so it is written straight into `state`) and `apply_counts` (the
// choosy use counts move, once every vertex of the sub-pass has chosen).

const PAD: i32 = 31;             // AppearanceMap::PAD
const KEY: u32 = 0x1fffffffu;    // texel + 1 in a slot
const LISTED: u32 = 0x20000000u; // a shift pixel whose list was gathered
const CANDIDATE: u32 = 0x40000000u;
const SHIFT: u32 = 0x80000000u;  // a forward shift of the vertex (continues a copy)
const CONTINUES: u32 = 0x80000000u; // on a listed candidate: it continues a copy
const NONE: u32 = 0xffffffffu;
const OUTSIDE: u32 = 0xffffffffu; // a mesh pixel's vertex outside the patch (its value is 0)
const SKIP: u32 = 0xfffffffeu;    // a mesh pixel not compared
const SLOT_WORDS: u32 = 6u;      // a mesh pixel: three vertices, three weights

struct Params {
    // The target grid.
    grid_w: u32, grid_h: u32, side: u32, wraps: u32,
    // The sample level.
    sw: u32, sh: u32, tileable: u32, margin: u32,
    list_k: u32, list_stride: u32, metric: u32, dims: u32,
    map_stride: u32, textons: u32, parent: u32, p_side: u32,
    // The parent: its grid, its sample level.
    p_grid_w: u32, p_grid_h: u32, p_wraps: u32, p_sw: u32,
    p_sh: u32, p_map_stride: u32, p_textons: u32, choosy: u32,
    fresh: f32, full: u32, zero: u32, off_knn: u32,
    // Word offsets of the level's tables in `tables`.
    off_labels: u32, off_gamma: u32, off_map: u32, off_p_labels: u32,
    off_p_gamma: u32, off_p_map: u32, off_parents: u32, off_classes: u32,
    // Word offsets in `pass_data`; this dispatch's vertices.
    off_draws: u32, off_table: u32, class_offset: u32, class_count: u32,
    groups_x: u32, full_count: u32, stamp: u32, off_full: u32,
    // Candidates a score dispatch takes per vertex; on a mesh (mesh = 1) the word offsets
    // of the level's pixel tables, the parent's, and the forward shifts (CSR).
    batch: u32, mesh: u32, off_slots: u32, off_p_slots: u32,
    off_shift_start: u32, off_shifts: u32,
    // An invocation's candidate table (2^cap_bits slots) and list (entries words), and its
    // scratch words in all (2 · 2^cap_bits + entries + 5).
    cap_bits: u32, entries: u32, stride: u32,
    // On a mesh under k-coherence: each candidate's pixel costs are computed side by side
    // (`pixel_costs`) before `score` sums them in order. On a mesh, the scratch words per
    // template pixel that `prepare` leaves; the default texton (outside the patch) of the
    // sample level and of the parent's.
    split: u32, query_words: u32, fallback: u32, p_fallback: u32,
    off_move: u32, _pad1: u32, _pad2: u32,
}

// A score dispatch's candidates: [start, start + P.batch) of each vertex's.
struct Batch {
    start: u32,
    _pad0: u32, _pad1: u32, _pad2: u32,
}

@group(0) @binding(0) var<uniform> P: Params;
// Per vertex: x | y << 16, label.
@group(0) @binding(1) var<storage, read_write> state: array<u32>;
// The coarser level's final state, same layout.
@group(0) @binding(2) var<storage, read> coarse: array<u32>;
@group(0) @binding(3) var<storage, read> tables: array<u32>;
@group(0) @binding(4) var<storage, read> pass_data: array<u32>;
// Per sample texel: the vertices whose coordinate it is (choosy selection).
@group(0) @binding(5) var<storage, read_write> counts: array<atomic<u32>>;
// Per vertex: best distance (bits), candidates compared, old texel, new texel (or NONE).
@group(0) @binding(6) var<storage, read_write> outs: array<u32>;
// Per invocation of a dispatch, P.stride words: its candidate table (two words per slot: see
// find_slot), its candidate list (P.entries), its count, whether the list is the full one,
// the best so far (found, distance bits, texel), and on a mesh its templates' blended
// vectors (own, then parent).
@group(0) @binding(7) var<storage, read_write> scratch: array<u32>;
@group(0) @binding(8) var<uniform> B: Batch;

// A product no compiler can fuse with the sum it feeds: P.zero is 0, unknown at compile time.
fn opaque(x: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(x) ^ P.zero);
}

// A squared distance's four lanes (term j in lane j mod 4, each in order) summed as the
// CPU's metric::lane_ssd sums them, (0 + 2) + (1 + 3).
fn lane_sum(lanes: vec4<f32>) -> f32 {
    return (lanes.x + lanes.z) + (lanes.y + lanes.w);
}

// a mod n in [0, n), for n > 0. In unsigned arithmetic: GLSL leaves % of a negative
// operand undefined, and naga's GL backend writes WGSL's % as GLSL's.
fn rem_euclid(a: i32, n: i32) -> i32 {
    if (a >= 0) {
        return i32(u32(a) % u32(n));
    }
    let m = i32(u32(-a) % u32(n));
    return select(0, n - m, m != 0);
}

// The grid vertex at (x, y), or −1 past the edge of a grid that does not wrap.
fn grid_vertex(x: i32, y: i32, w: u32, h: u32, wraps: u32) -> i32 {
    let wi = i32(w);
    let hi = i32(h);
    var sx = x;
    var sy = y;
    if (wraps != 0u) {
        sx = rem_euclid(x, wi);
        sy = rem_euclid(y, hi);
    }
    if (sx < 0 || sx >= wi || sy < 0 || sy >= hi) {
        return -1;
    }
    return sy * wi + sx;
}

fn inside_band(v: i32, n: u32) -> bool {
    let ni = i32(n);
    let r = min(i32(P.margin), (ni - 1) / 2);
    return v >= r && v < ni - r;
}

// SampleLevel::is_candidate.
fn is_candidate(x: i32, y: i32) -> bool {
    return P.tileable != 0u || (inside_band(x, P.sw) && inside_band(y, P.sh));
}

// SampleLevel::candidate_pixel.
fn candidate_pixel(x: i32, y: i32) -> u32 {
    let w = i32(P.sw);
    let h = i32(P.sh);
    let r = i32(P.margin);
    var cx: i32;
    var cy: i32;
    if (P.tileable != 0u) {
        cx = rem_euclid(x, w);
        cy = rem_euclid(y, h);
    } else if (w > 2 * r && h > 2 * r) {
        cx = clamp(x, r, w - 1 - r);
        cy = clamp(y, r, h - 1 - r);
    } else {
        cx = clamp(x, 0, w - 1);
        cy = clamp(y, 0, h - 1);
    }
    return u32(cy * w + cx);
}

// SampleLevel::label_at on a level of `w × h`.
fn label_at(off: u32, x: i32, y: i32, w: u32, h: u32) -> u32 {
    let wi = i32(w);
    let hi = i32(h);
    var sx: i32;
    var sy: i32;
    if (P.tileable != 0u) {
        sx = rem_euclid(x, wi);
        sy = rem_euclid(y, hi);
    } else {
        sx = clamp(x, 0, wi - 1);
        sy = clamp(y, 0, hi - 1);
    }
    return tables[off + u32(sy * wi + sx)];
}

fn f(word: u32) -> f32 {
    return bitcast<f32>(word);
}

// AppearanceMap::index (in floats) of (x, y) in a map of row stride `stride`.
fn map_index(x: i32, y: i32, stride: u32) -> u32 {
    return (u32(y + PAD) * stride + u32(x + PAD)) * P.dims;
}

// f32 a / b correctly rounded (to nearest, ties to even), for finite a ≥ 0 and a normal
// b > 0: what the CPU's division gives. Integer long division, 7 bits at a time (no loop).
fn div_exact(a: f32, b: f32) -> f32 {
    if (a == 0.0 || b == 1.0) {
        return a;
    }
    let ua = bitcast<u32>(a);
    let ub = bitcast<u32>(b);
    var ea = i32((ua >> 23u) & 0xffu);
    var ma = ua & 0x7fffffu;
    if (ea == 0) {
        // A subnormal dividend: normalise its significand.
        let s = 23u - firstLeadingBit(ma);
        ma = ma << s;
        ea = 1 - i32(s);
    } else {
        ma = ma | 0x800000u;
    }
    let eb = i32((ub >> 23u) & 0xffu);
    let mb = (ub & 0x7fffffu) | 0x800000u;
    var e = ea - eb + 127;
    if (ma < mb) {
        ma = ma << 1u;
        e = e - 1;
    }
    // ma / mb in [1, 2): q gets 1 + 4 · 7 bits, r the rest (r < mb < 2^24, so r << 7 fits).
    var q = 1u;
    var r = ma - mb;
    var d: u32;
    r = r << 7u; d = r / mb; q = (q << 7u) | d; r = r - d * mb;
    r = r << 7u; d = r / mb; q = (q << 7u) | d; r = r - d * mb;
    r = r << 7u; d = r / mb; q = (q << 7u) | d; r = r - d * mb;
    r = r << 7u; d = r / mb; q = (q << 7u) | d; r = r - d * mb;
    // q in [2^28, 2^29): the quotient is q · 2^(e − 6) units of 2^−149.
    var sticky = r != 0u;
    var sh = 5u;
    if (e < 1) {
        let lost = u32(1 - e);
        if (lost > 24u) {
            return 0.0;
        }
        sh = 5u + lost;
    }
    var m = q >> sh;
    let guard = (q >> (sh - 1u)) & 1u;
    sticky = sticky || (q & ((1u << (sh - 1u)) - 1u)) != 0u;
    if (guard == 1u && (sticky || (m & 1u) == 1u)) {
        m = m + 1u;
    }
    if (e < 1) {
        // Subnormal (or, rounded up to 2^23, the least normal: the same bits).
        return bitcast<f32>(m);
    }
    if (m == 0x1000000u) {
        m = m >> 1u;
        e = e + 1;
    }
    if (e >= 255) {
        return bitcast<f32>(0x7f800000u);
    }
    return bitcast<f32>((u32(e) << 23u) | (m & 0x7fffffu));
}

// A template as the metric prepares it (vertex `centre`'s window of side `side` on a grid,
// pixels past the edge of a grid that does not wrap left out), compared with the sample
// neighbourhood at (x, y): Metric::cost, stopping once above `bound` if `bounded` (an
// unbounded search is the CPU's bound of +∞). The window is read afresh for each candidate
// (no per-vertex arrays: software drivers turn dynamically indexed ones into branch ladders).
struct Window {
    centre: i32,
    side: u32,
    grid: vec3<u32>,     // width, height, wraps
    coarse: bool,        // read from `coarse` (the parent level) rather than `state`
    slots: u32,          // on a mesh: the word offset of the vertex's pixels; NONE on a plane
    query: u32,          // on a mesh: where in `scratch` its pixels' blended vectors lie
    costs: u32,          // under P.split: where the candidate's pixel costs lie; else NONE
}

struct Level {
    labels: u32,
    gamma: u32,
    map: u32,
    stride: u32,
    size: vec3<u32>,     // width, height, textons
    fallback: u32,       // the default texton, for a mesh pixel's part outside the patch
}

fn cost(win: Window, lv: Level, x: i32, y: i32, bounded: bool, bound: f32) -> f32 {
    if (win.slots != NONE) {
        return mesh_cost(win, lv, x, y, bounded, bound);
    }
    let t = win.side;
    let r = i32(t / 2u);
    let cx = win.centre % i32(win.grid.x);
    let cy = win.centre / i32(win.grid.x);
    var d = 0.0;
    let base = lv.map + map_index(x, y, lv.stride);
    for (var i = 0u; i < t * t; i = i + 1u) {
        let dx = i32(i % t) - r;
        let dy = i32(i / t) - r;
        let u = grid_vertex(cx + dx, cy + dy, win.grid.x, win.grid.y, win.grid.z);
        if (u < 0) {
            continue;
        }
        var packed: u32;
        var label: u32;
        if (win.coarse) {
            packed = coarse[2u * u32(u)];
            label = coarse[2u * u32(u) + 1u];
        } else {
            packed = state[2u * u32(u)];
            label = state[2u * u32(u) + 1u];
        }
        if (P.metric == 0u) {
            // One vertex of weight 1: s·s = Γ(l, l), s·t = Γ(l, t).
            let ss = 0.0 + f(tables[lv.gamma + label * lv.size.z + label]);
            let t = label_at(lv.labels, x + dx, y + dy, lv.size.x, lv.size.y);
            let st = 0.0 + f(tables[lv.gamma + label * lv.size.z + t]);
            let tt = f(tables[lv.gamma + t * lv.size.z + t]);
            d = d + ((ss - 2.0 * st) + tt);
        } else {
            let o = base + u32((dy * i32(lv.stride) + dx) * i32(P.dims));
            let q = lv.map + map_index(i32(packed & 0xffffu), i32(packed >> 16u), lv.stride);
            var lanes = vec4<f32>(0.0);
            for (var j = 0u; j < P.dims; j = j + 1u) {
                let e = f(tables[o + j]) - f(tables[q + j]);
                lanes[j % 4u] = lanes[j % 4u] + opaque(e * e);
            }
            d = d + lane_sum(lanes);
        }
        if (bounded && d > bound) {
            break;
        }
    }
    if (P.metric == 0u) {
        return max(d, 0.0);
    }
    return d;
}

// The packed coordinate of vertex u on the window's level.
fn packed_of(u: u32, on_coarse: bool) -> u32 {
    if (on_coarse) {
        return coarse[2u * u];
    }
    return state[2u * u];
}

// Value j of part `a` of the mesh pixel at `slot` (weight × the vector at its vertex's
// coordinate), or 0 for a part outside the patch.
fn part(slot: u32, a: u32, j: u32, lv: Level, on_coarse: bool) -> f32 {
    let u = tables[slot + a];
    if (u == OUTSIDE) {
        return 0.0;
    }
    let packed = packed_of(u, on_coarse);
    let m = lv.map + map_index(i32(packed & 0xffffu), i32(packed >> 16u), lv.stride);
    return opaque(f(tables[slot + 3u + a]) * f(tables[m + j]));
}

// What each candidate compares `win`'s mesh pixels with, into `scratch` at win.query, once
// per vertex before its candidates are scored: under Γ each compared pixel's textons and
// s·s, else its vertices' vectors blended, AppearanceMetric::prepare's sum in its order (the
// parts unrolled: llvmpipe counts loop iterations).
fn prepare(win: Window, lv: Level) {
    if (P.metric == 0u) {
        prepare_terms(win, lv);
        return;
    }
    for (var i = 0u; i < win.side * win.side; i = i + 1u) {
        let slot = win.slots + SLOT_WORDS * i;
        if (tables[slot] == SKIP) {
            continue;
        }
        for (var j = 0u; j < P.dims; j = j + 1u) {
            let q = opaque(opaque(0.0 + part(slot, 0u, j, lv, win.coarse)) + part(slot, 1u, j, lv, win.coarse))
                + part(slot, 2u, j, lv, win.coarse);
            scratch[win.query + i * P.dims + j] = bitcast<u32>(q);
        }
    }
}

// The texton of part `a` of the mesh pixel at `slot`: its vertex's label, or the level's
// default texton outside the patch (or for a part the pixel lacks, whose weight is 0).
fn part_texton(slot: u32, a: u32, lv: Level, on_coarse: bool) -> u32 {
    let u = tables[slot + a];
    if (u == OUTSIDE) {
        return lv.fallback;
    }
    if (on_coarse) {
        return coarse[2u * u + 1u];
    }
    return state[2u * u + 1u];
}

// Γ(a, b) on level `lv`.
fn gamma_of(lv: Level, a: u32, b: u32) -> f32 {
    return f(tables[lv.gamma + a * lv.size.z + b]);
}

// GammaMetric::prepare's terms of `win`'s mesh pixels: each compared pixel's three textons
// and s·s = Σₐ Σ_b wₐ w_b Γ(tₐ, t_b), in its order. A part the pixel lacks has weight 0 and
// adds only zeros, which change no sum.
fn prepare_terms(win: Window, lv: Level) {
    for (var i = 0u; i < win.side * win.side; i = i + 1u) {
        let slot = win.slots + SLOT_WORDS * i;
        if (tables[slot] == SKIP) {
            continue;
        }
        let t = vec3<u32>(part_texton(slot, 0u, lv, win.coarse), part_texton(slot, 1u, lv, win.coarse),
            part_texton(slot, 2u, lv, win.coarse));
        let w = vec3<f32>(f(tables[slot + 3u]), f(tables[slot + 4u]), f(tables[slot + 5u]));
        let ss = ss_row(ss_row(ss_row(0.0, lv, w, t, 0u), lv, w, t, 1u), lv, w, t, 2u);
        let q = win.query + 4u * i;
        scratch[q] = t[0];
        scratch[q + 1u] = t[1];
        scratch[q + 2u] = t[2];
        scratch[q + 3u] = bitcast<u32>(ss);
    }
}

// `ss` plus row `a` of s·s's terms, wₐ w_b Γ(tₐ, t_b) for b = 0, 1, 2 (unrolled, as
// llvmpipe counts loop iterations).
fn ss_row(ss: f32, lv: Level, w: vec3<f32>, t: vec3<u32>, a: u32) -> f32 {
    return opaque(opaque(ss + opaque((w[a] * w[0]) * gamma_of(lv, t[a], t[0])))
        + opaque((w[a] * w[1]) * gamma_of(lv, t[a], t[1])))
        + opaque((w[a] * w[2]) * gamma_of(lv, t[a], t[2]));
}

// One mesh pixel's cost under Γ (GammaMetric::cost's term): its prepared textons and s·s
// against the sample's texton t at (x, y), s·t summed over the parts in order.
fn term_cost(win: Window, lv: Level, i: u32, x: i32, y: i32) -> f32 {
    let slot = win.slots + SLOT_WORDS * i;
    let q = win.query + 4u * i;
    let t = label_at(lv.labels, x, y, lv.size.x, lv.size.y);
    let st = opaque(opaque(0.0 + opaque(f(tables[slot + 3u]) * gamma_of(lv, scratch[q], t)))
        + opaque(f(tables[slot + 4u]) * gamma_of(lv, scratch[q + 1u], t)))
        + opaque(f(tables[slot + 5u]) * gamma_of(lv, scratch[q + 2u], t));
    return (f(scratch[q + 3u]) - 2.0 * st) + gamma_of(lv, t, t);
}

// Mesh pixel i's cost against the sample neighbourhood centred at (x, y), under the pass's
// metric.
fn mesh_pixel_cost(win: Window, lv: Level, i: u32, x: i32, y: i32) -> f32 {
    let r = i32(win.side / 2u);
    let dx = i32(i % win.side) - r;
    let dy = i32(i / win.side) - r;
    if (P.metric == 0u) {
        return term_cost(win, lv, i, x + dx, y + dy);
    }
    let o = lv.map + map_index(x, y, lv.stride) + u32((dy * i32(lv.stride) + dx) * i32(P.dims));
    return pixel_cost(win, i, o);
}

// One pixel's cost on a mesh (appearance or colour SSD): its blended vector against the
// sample's at `o`, the terms summed in AppearanceMetric::cost's order.
fn pixel_cost(win: Window, i: u32, o: u32) -> f32 {
    var lanes = vec4<f32>(0.0);
    for (var j = 0u; j < P.dims; j = j + 1u) {
        let e = f(tables[o + j]) - f(scratch[win.query + i * P.dims + j]);
        lanes[j % 4u] = lanes[j % 4u] + opaque(e * e);
    }
    return lane_sum(lanes);
}

// `cost` on a mesh, against what `prepare` left; under P.split from the pixel costs
// `pixel_costs` left (a pixel not compared left 0, which changes no sum). Under Γ, at least
// 0, as GammaMetric::cost returns.
fn mesh_cost(win: Window, lv: Level, x: i32, y: i32, bounded: bool, bound: f32) -> f32 {
    var d = 0.0;
    for (var i = 0u; i < win.side * win.side; i = i + 1u) {
        if (win.costs != NONE) {
            d = d + f(scratch[win.costs + i]);
        } else if (tables[win.slots + SLOT_WORDS * i] != SKIP) {
            d = d + mesh_pixel_cost(win, lv, i, x, y);
        } else {
            continue;
        }
        if (bounded && d > bound) {
            break;
        }
    }
    if (P.metric == 0u) {
        return max(d, 0.0);
    }
    return d;
}

// The candidate table of this invocation: 2^P.cap_bits slots of (stamp, texel + 1 | flags) in
// `scratch` from `base`, open addressing; a slot whose stamp is not this sub-pass part's is
// empty, so the table needs no clearing.
fn find_slot(base: u32, q: u32) -> u32 {
    var h = (q * 2654435761u) >> (32u - P.cap_bits);
    loop {
        let at = base + 2u * h;
        if (scratch[at] != P.stamp || (scratch[at + 1u] & KEY) == q + 1u) {
            return at;
        }
        h = (h + 1u) & ((1u << P.cap_bits) - 1u);
    }
    return 0u;
}

fn entry(at: u32) -> u32 {
    return select(0u, scratch[at + 1u], scratch[at] == P.stamp);
}

fn set_entry(at: u32, e: u32) {
    scratch[at] = P.stamp;
    scratch[at + 1u] = e;
}

// The best so far, as SquareMatch::choose keeps it.
struct Best {
    found: bool,
    d: f32,
    q: u32,
}

// Scores candidate q (SquareMatch::choose's `score`) and keeps it if strictly better.
fn consider(best: ptr<function, Best>, own: Window, up: Window, q: u32, factor: f32) {
    let x = i32(q % P.sw);
    let y = i32(q / P.sw);
    let own_level = level_of(false);
    let p_level = level_of(true);
    if (!(*best).found) {
        // Bound +∞: nothing stops early, the parent always joins.
        var d = cost(own, own_level, x, y, false, 0.0);
        if (P.parent != 0u) {
            d = d + cost(up, p_level, x / 2, y / 2, false, 0.0);
        }
        let s = d * factor;
        if (s <= 3.40282347e38) {
            (*best).found = true;
            (*best).d = s;
            (*best).q = q;
        }
        return;
    }
    let bound = div_exact((*best).d, factor);
    var d = cost(own, own_level, x, y, true, bound);
    if (P.parent != 0u && d < bound) {
        d = d + cost(up, p_level, x / 2, y / 2, true, bound - d);
    }
    let s = d * factor;
    if (s < (*best).d) {
        (*best).d = s;
        (*best).q = q;
    }
}

// The sample level the vertex's own template (or its parent template) is compared on.
fn level_of(parent: bool) -> Level {
    if (parent) {
        return Level(P.off_p_labels, P.off_p_gamma, P.off_p_map, P.p_map_stride, vec3<u32>(P.p_sw, P.p_sh, P.p_textons), P.p_fallback);
    }
    return Level(P.off_labels, P.off_gamma, P.off_map, P.map_stride, vec3<u32>(P.sw, P.sh, P.textons), P.fallback);
}

// selection_factor: the choosy penalty times the coherence bias on a fresh copy, times the
// vertex's factor on moving (PassPlan::move_cost) for any texel but its current one.
fn factor_of(v: u32, q: u32, current: u32, continues: bool) -> f32 {
    var usage = 1.0;
    if (P.choosy != 0u) {
        let n = atomicLoad(&counts[q]);
        let own_use = select(0u, 1u, q == current);
        usage = f(pass_data[P.off_table + n - own_use]);
    }
    let moved = select(f(pass_data[P.off_move + v]), 1.0, q == current);
    return usage * select(P.fresh, 1.0, continues) * moved;
}

// Window pixel k of vertex (vx, vy): its vertex's coordinate shifted back by the pixel's
// offset, as a candidate texel, or NONE (off the grid, or not on a candidate texel).
fn shift_pixel(vx: i32, vy: i32, k: u32) -> u32 {
    let t = P.side;
    let r = i32(t / 2u);
    let dx = i32(k % t) - r;
    let dy = i32(k / t) - r;
    let u = grid_vertex(vx + dx, vy + dy, P.grid_w, P.grid_h, P.wraps);
    if (u < 0) {
        return NONE;
    }
    let su = state[2u * u32(u)];
    let x = i32(su & 0xffffu) - dx;
    let y = i32(su >> 16u) - dy;
    if (!is_candidate(x, y)) {
        return NONE;
    }
    return candidate_pixel(x, y);
}

// candidates::round_to_i64: to nearest, halves away from zero.
fn round_away(t: f32) -> i32 {
    let whole = i32(t);
    let fraction = t - f32(whole);
    return whole + select(0, 1, fraction >= 0.5) - select(0, 1, fraction <= -0.5);
}

// Forward shift k of mesh vertex v (its k-th patch vertex's coordinate moved back by the
// offset), as a candidate texel, or NONE (not on a candidate texel).
fn mesh_shift_pixel(v: u32, k: u32) -> u32 {
    let e = P.off_shifts + 3u * (tables[P.off_shift_start + v] + k);
    let su = state[2u * tables[e]];
    let x = round_away(f32(su & 0xffffu) - f(tables[e + 1u]));
    let y = round_away(f32(su >> 16u) - f(tables[e + 2u]));
    if (!is_candidate(x, y)) {
        return NONE;
    }
    return candidate_pixel(x, y);
}

// Shift k of vertex v (a window pixel on a plane, a patch vertex on a mesh), or NONE.
fn shift_of(v: u32, k: u32) -> u32 {
    if (P.mesh != 0u) {
        return mesh_shift_pixel(v, k);
    }
    return shift_pixel(i32(v % P.grid_w), i32(v / P.grid_w), k);
}

// How many shifts vertex v has (some may be NONE).
fn shift_count(v: u32) -> u32 {
    if (P.mesh != 0u) {
        return tables[P.off_shift_start + v + 1u] - tables[P.off_shift_start + v];
    }
    return P.side * P.side;
}

// This invocation's index in its dispatch, or NONE past the dispatch's vertices.
fn index_of(gid: vec3<u32>) -> u32 {
    let i = gid.x + gid.y * P.groups_x * 64u;
    return select(NONE, i, i < P.class_count);
}

fn vertex_of(i: u32) -> u32 {
    return tables[P.off_classes + P.class_offset + i];
}

fn current_of(v: u32) -> u32 {
    let packed = state[2u * v];
    return (packed >> 16u) * P.sw + (packed & 0xffffu);
}

// Scratch layout of invocation i.
fn table_base(i: u32) -> u32 {
    return i * P.stride;
}
fn list_base(i: u32) -> u32 {
    return i * P.stride + (2u << P.cap_bits);
}
fn meta_base(i: u32) -> u32 {
    return i * P.stride + (2u << P.cap_bits) + P.entries;
}
// On a mesh: what `prepare` leaves of the vertex's template, then of its parent template.
fn query_base(i: u32) -> u32 {
    return meta_base(i) + 5u;
}
// Pixels of the vertex's template and parent template.
fn pixels() -> u32 {
    return P.side * P.side + select(0u, P.p_side * P.p_side, P.parent != 0u);
}
// Under P.split: per candidate, its pixel costs (own template, then parent template).
fn costs_base(i: u32) -> u32 {
    return query_base(i) + pixels() * P.query_words;
}

// Invocation i's vertex v's template (and parent template, or a copy of the own where there
// is none), as `cost` reads them.
fn own_window(v: u32, i: u32) -> Window {
    var own = Window(i32(v), P.side, vec3<u32>(P.grid_w, P.grid_h, P.wraps), false, NONE, 0u, NONE);
    if (P.mesh != 0u) {
        own.slots = P.off_slots + v * P.side * P.side * SLOT_WORDS;
        own.query = query_base(i);
    }
    return own;
}
fn up_window(v: u32, i: u32) -> Window {
    if (P.parent == 0u) {
        return own_window(v, i);
    }
    let pv = tables[P.off_parents + v];
    var up = Window(i32(pv), P.p_side, vec3<u32>(P.p_grid_w, P.p_grid_h, P.p_wraps), true, NONE, 0u, NONE);
    if (P.mesh != 0u) {
        up.slots = P.off_p_slots + pv * P.p_side * P.p_side * SLOT_WORDS;
        up.query = query_base(i) + P.side * P.side * P.query_words;
    }
    return up;
}

// The vertex's forward shifts (Coherence::gather): each window vertex's (on a mesh, patch
// vertex's) coordinate shifted back by its offset, where it lands on a candidate texel, all
// marked in the table; then its candidates: the first list_k entries of each shift's list,
// each texel once, in gathering order (or, for a full search, every candidate texel, listed
// in `tables`); on a mesh, last, its templates' blended vectors.
@compute @workgroup_size(64)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index_of(gid);
    if (i == NONE) {
        return;
    }
    let v = vertex_of(i);
    let base = table_base(i);
    let list = list_base(i);
    let n = shift_count(v);
    var shifts = 0u;
    for (var k = 0u; k < n; k = k + 1u) {
        let p = shift_of(v, k);
        if (p == NONE) {
            continue;
        }
        let at = find_slot(base, p);
        if (entry(at) == 0u) {
            set_entry(at, (p + 1u) | SHIFT);
        }
        shifts = shifts + 1u;
    }
    var count = 0u;
    var full = 0u;
    if (P.full != 0u) {
        count = P.full_count;
        full = select(0u, 1u, count > 0u);
    } else if (shifts > 0u) {
        // A shift that lands where an earlier one did adds nothing new.
        for (var k = 0u; k < n; k = k + 1u) {
            let p = shift_of(v, k);
            if (p == NONE) {
                continue;
            }
            let at = find_slot(base, p);
            let e = entry(at);
            if ((e & LISTED) != 0u) {
                continue;
            }
            set_entry(at, e | LISTED);
            let knn = P.off_knn + p * P.list_stride;
            for (var j = 0u; j < P.list_k; j = j + 1u) {
                let q = tables[knn + j];
                let qat = find_slot(base, q);
                let qe = entry(qat);
                if ((qe & CANDIDATE) != 0u) {
                    continue;
                }
                set_entry(qat, (q + 1u) | CANDIDATE | (qe & (SHIFT | LISTED)));
                scratch[list + count] = q | select(0u, CONTINUES, (qe & SHIFT) != 0u);
                count = count + 1u;
            }
        }
    }
    if (count == 0u) {
        // Nothing to judge by: the texel drawn for this vertex (on the CPU, by its seed).
        scratch[list] = pass_data[P.off_draws + v];
        count = 1u;
    }
    if (P.mesh != 0u) {
        prepare(own_window(v, i), level_of(false));
        if (P.parent != 0u) {
            prepare(up_window(v, i), level_of(true));
        }
    }
    let info = meta_base(i);
    scratch[info] = count;
    scratch[info + 1u] = full;
    scratch[info + 2u] = 0u;
    scratch[info + 3u] = 0u;
    scratch[info + 4u] = 0u;
    outs[4u * v + 1u] = count;
}

// The cost of each compared pixel of candidate gid.x of the part's vertex gid.y, own
// template then parent template, each summed as `cost` would: one invocation per candidate,
// so that a mesh's few hundred vertices per sub-pass still fill the GPU. `score` then adds
// them up in order, stopping where the CPU stops.
@compute @workgroup_size(64)
fn pixel_costs(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.y;
    let j = gid.x;
    if (i >= P.class_count || j >= scratch[meta_base(i)]) {
        return;
    }
    let v = vertex_of(i);
    let q = scratch[list_base(i) + j] & ~CONTINUES;
    let out = costs_base(i) + j * pixels();
    pixel_costs_of(own_window(v, i), level_of(false), i32(q % P.sw), i32(q / P.sw), out);
    if (P.parent != 0u) {
        let up = up_window(v, i);
        pixel_costs_of(up, level_of(true), i32(q % P.sw) / 2, i32(q / P.sw) / 2, out + P.side * P.side);
    }
}

// The pixel costs of `win` against the sample at (x, y), into `scratch` from `out`.
fn pixel_costs_of(win: Window, lv: Level, x: i32, y: i32, out: u32) {
    for (var i = 0u; i < win.side * win.side; i = i + 1u) {
        var s = 0.0;
        if (tables[win.slots + SLOT_WORDS * i] != SKIP) {
            s = mesh_pixel_cost(win, lv, i, x, y);
        }
        scratch[out + i] = bitcast<u32>(s);
    }
}

// Candidates [B.start, B.start + P.batch) of the vertex's, scored against the best so far.
@compute @workgroup_size(64)
fn score(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index_of(gid);
    if (i == NONE) {
        return;
    }
    let info = meta_base(i);
    let count = scratch[info];
    if (B.start >= count) {
        return;
    }
    let v = vertex_of(i);
    let current = current_of(v);
    var own = own_window(v, i);
    var up = up_window(v, i);
    let full = scratch[info + 1u] != 0u;
    var best = Best(scratch[info + 2u] != 0u, f(scratch[info + 3u]), scratch[info + 4u]);
    if (!best.found) {
        best.q = current;
    }
    let end = min(count, B.start + P.batch);
    let list = list_base(i);
    let base = table_base(i);
    for (var j = B.start; j < end; j = j + 1u) {
        var q: u32;
        var continues: bool;
        if (full) {
            q = tables[P.off_full + j];
            continues = (entry(find_slot(base, q)) & SHIFT) != 0u;
        } else {
            q = scratch[list + j] & ~CONTINUES;
            continues = (scratch[list + j] & CONTINUES) != 0u;
        }
        if (P.split != 0u) {
            own.costs = costs_base(i) + j * pixels();
            up.costs = own.costs + P.side * P.side;
        }
        consider(&best, own, up, q, factor_of(v, q, current, continues));
    }
    scratch[info + 2u] = select(0u, 1u, best.found);
    scratch[info + 3u] = bitcast<u32>(best.d);
    scratch[info + 4u] = best.q;
}

// The vertex takes its winner (and records what the pass reports).
@compute @workgroup_size(64)
fn finish(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index_of(gid);
    if (i == NONE) {
        return;
    }
    let v = vertex_of(i);
    let info = meta_base(i);
    let current = current_of(v);
    outs[4u * v + 2u] = current;
    if (scratch[info + 2u] != 0u) {
        let q = scratch[info + 4u];
        outs[4u * v] = scratch[info + 3u];
        outs[4u * v + 3u] = q;
        state[2u * v] = (q % P.sw) | ((q / P.sw) << 16u);
        state[2u * v + 1u] = tables[P.off_labels + q];
    } else {
        outs[4u * v] = 0u;
        outs[4u * v + 3u] = NONE;
    }
}

// After a sub-pass: every vertex that took a texel moves its use count (Usage::moved).
@compute @workgroup_size(64)
fn apply_counts(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index_of(gid);
    if (i == NONE) {
        return;
    }
    let v = vertex_of(i);
    let to = outs[4u * v + 3u];
    if (to == NONE) {
        return;
    }
    atomicSub(&counts[outs[4u * v + 2u]], 1u);
    atomicAdd(&counts[to], 1u);
}
