//! Neighbourhood distances: how well the sample neighbourhood around a candidate pixel
//! matches a vertex's template. One trait, two metrics, chosen once per pass so that the
//! candidate loop is monomorphised:
//!
//! - [`GammaMetric`] (Tong §5.1): template pixels are surface textons, Σ wₐ t(labelₐ), and
//!   the distance Σ ‖s − t‖² is evaluated through Γ.
//! - [`AppearanceMetric`] (beyond the paper, after Lefebvre and Hoppe 2006): template pixels
//!   are the barycentric blend of the vertices' appearance vectors, compared by plain SSD
//!   with the sample's vectors. Continuous, so neighbourhoods do not tie on quantized labels.
//!   The colour metric ([`super::MetricKind::Colour`], Turk's colour SSD) is the same
//!   distance over a map of the sample's linear RGB ([`super::SampleLevel::colour`]).

use super::engine::State;
use super::sample::{AppearanceMap, SampleLevel};
use super::target::{Slot, OUTSIDE};

/// A neighbourhood distance on one level: the part of a square-template match
/// ([`super::square_pass::SquareMatch`]) that says how far a candidate's sample neighbourhood
/// is from a vertex's template.
pub trait Metric {
    /// A vertex's template, prepared once so each candidate costs as little as possible.
    type Query: Default;

    /// Prepares the template `slots` under `state`. With `known`, vertices not synthesized
    /// yet are left out (their weight goes to the slot's other vertices; a slot with none
    /// known is not compared).
    fn prepare(&self, slots: &[Slot], state: &State, known: Option<&[bool]>, query: &mut Self::Query);

    /// Distance to the sample neighbourhood centred at (x, y); may stop early, returning
    /// anything above `bound`, once it exceeds it.
    fn cost(&self, query: &Self::Query, x: i64, y: i64, bound: f32) -> f32;

    /// Distance between two single texels of the sample (one template pixel's worth).
    fn texel_distance(&self, a: [i32; 2], b: [i32; 2]) -> f32;
}

/// The template slots' vertices and weights with unknown vertices removed: `(slot index,
/// [(vertex, weight)], count)`; slots outside the patch keep `OUTSIDE` as their vertex.
pub(crate) fn known_parts<'a>(
    slots: &'a [Slot],
    known: Option<&'a [bool]>,
) -> impl Iterator<Item = (usize, [(u32, f32); 3], usize)> + 'a {
    slots.iter().enumerate().filter_map(move |(i, slot)| {
        if slot.weights == [1.0, 0.0, 0.0] {
            // On one vertex (every pixel of a plane): what the loop below finds, without it.
            let vertex = slot.vertices[0];
            let seen = vertex == OUTSIDE || known.is_none_or(|k| k[vertex as usize]);
            return seen.then_some((i, [(vertex, 1.0), (OUTSIDE, 0.0), (OUTSIDE, 0.0)], 1));
        }
        let mut parts = [(OUTSIDE, 0.0f32); 3];
        let (mut count, mut total) = (0, 0.0);
        for (&vertex, &weight) in slot.vertices.iter().zip(&slot.weights) {
            if weight == 0.0 || (vertex != OUTSIDE && known.is_some_and(|k| !k[vertex as usize])) {
                continue;
            }
            parts[count] = (vertex, weight);
            count += 1;
            total += weight;
        }
        (count > 0).then(|| {
            parts[..count].iter_mut().for_each(|p| p.1 /= total);
            (i, parts, count)
        })
    })
}

/// Tong's distance through Γ.
pub struct GammaMetric<'a> {
    /// The sample level whose texton map and Γ the templates are compared with.
    pub sample: &'a SampleLevel,
    /// The template's side, in texels (odd).
    pub template: usize,
}

/// One template pixel for [`GammaMetric`]: s = Σ wₐ t(textonsₐ) and s·s.
#[derive(Clone, Copy)]
pub struct Term {
    dx: i64,
    dy: i64,
    textons: [u16; 3],
    weights: [f32; 3],
    count: usize,
    ss: f32,
}

impl Metric for GammaMetric<'_> {
    type Query = Vec<Term>;

    fn prepare(&self, slots: &[Slot], state: &State, known: Option<&[bool]>, query: &mut Vec<Term>) {
        let (sample, r) = (self.sample, (self.template / 2) as i64);
        query.clear();
        for (i, parts, count) in known_parts(slots, known) {
            let mut term = Term {
                dx: (i % self.template) as i64 - r,
                dy: (i / self.template) as i64 - r,
                textons: [sample.default_texton(); 3],
                weights: [0.0; 3],
                count,
                ss: 0.0,
            };
            for (a, &(vertex, weight)) in parts[..count].iter().enumerate() {
                term.textons[a] =
                    if vertex == OUTSIDE { sample.default_texton() } else { state.labels[vertex as usize] };
                term.weights[a] = weight;
            }
            for a in 0..count {
                for b in 0..count {
                    term.ss +=
                        term.weights[a] * term.weights[b] * sample.dot(term.textons[a], term.textons[b]);
                }
            }
            query.push(term);
        }
    }

    fn texel_distance(&self, a: [i32; 2], b: [i32; 2]) -> f32 {
        let s = self.sample;
        let (ta, tb) = (s.label_at(a[0] as i64, a[1] as i64), s.label_at(b[0] as i64, b[1] as i64));
        s.texton_distance(ta, tb)
    }

    fn cost(&self, query: &Vec<Term>, x: i64, y: i64, bound: f32) -> f32 {
        let sample = self.sample;
        let mut d = 0.0;
        for term in query {
            let t = sample.label_at(x + term.dx, y + term.dy);
            let mut st = 0.0;
            for a in 0..term.count {
                st += term.weights[a] * sample.dot(term.textons[a], t);
            }
            d += term.ss - 2.0 * st + sample.dot(t, t);
            if d > bound {
                break;
            }
        }
        d.max(0.0)
    }
}

/// Plain SSD of appearance vectors (or of colours, through a map of three dimensions).
pub struct AppearanceMetric<'a> {
    /// The sample level's vectors ([`SampleLevel::appearance`] or [`SampleLevel::colour`]).
    pub map: &'a AppearanceMap,
    /// The template's side, in texels (odd).
    pub template: usize,
}

/// A prepared template for [`AppearanceMetric`]: per compared pixel its offset into the
/// map's values and its vector.
#[derive(Default)]
pub struct Vectors {
    offsets: Vec<isize>,
    values: Vec<f32>,
}

impl Metric for AppearanceMetric<'_> {
    type Query = Vectors;

    fn prepare(&self, slots: &[Slot], state: &State, known: Option<&[bool]>, query: &mut Vectors) {
        let (map, r, dims) = (self.map, (self.template / 2) as i64, self.map.dims);
        query.offsets.clear();
        query.values.clear();
        for (i, parts, count) in known_parts(slots, known) {
            // Outside the patch, Tong's default texton is the mean; vectors are centred, so 0.
            let start = query.values.len();
            let offset = map.offset((i % self.template) as i64 - r, (i / self.template) as i64 - r);
            if let (1, [(vertex, weight), ..]) = (count, parts) {
                // A pixel on one vertex (every pixel of a plane) is that vertex's vector: the
                // sum below would give the same, but +0.0 for −0.0, which no difference tells
                // apart.
                if weight == 1.0 && vertex != OUTSIDE {
                    let [u, v] = state.uv[vertex as usize];
                    push_vector(&mut query.values, map.at(u as i64, v as i64));
                    query.offsets.push(offset);
                    continue;
                }
            }
            query.values.resize(start + dims, 0.0);
            for &(vertex, weight) in &parts[..count] {
                if vertex == OUTSIDE {
                    continue;
                }
                let [u, v] = state.uv[vertex as usize];
                for (q, &a) in query.values[start..].iter_mut().zip(map.at(u as i64, v as i64)) {
                    *q += weight * a;
                }
            }
            query.offsets.push(offset);
        }
    }

    fn texel_distance(&self, a: [i32; 2], b: [i32; 2]) -> f32 {
        let (va, vb) = (self.map.at(a[0] as i64, a[1] as i64), self.map.at(b[0] as i64, b[1] as i64));
        lane_ssd(va, vb)
    }

    fn cost(&self, query: &Vectors, x: i64, y: i64, bound: f32) -> f32 {
        let (values, base) = (self.map.values(), self.map.index(x, y) as isize);
        match self.map.dims {
            3 => ssd_within::<3>(values, base, query, bound),
            8 => ssd_within::<8>(values, base, query, bound),
            16 => ssd_within::<16>(values, base, query, bound),
            dims => {
                let mut d = 0.0;
                for (&offset, target) in query.offsets.iter().zip(query.values.chunks_exact(dims)) {
                    let o = (base + offset) as usize;
                    d += lane_ssd(&values[o..o + dims], target);
                    if d > bound {
                        break;
                    }
                }
                d
            }
        }
    }
}

/// Appends `vector` to `values`, its length known to the compiler for the usual dimensions:
/// copied through `memmove`, the vectors cost as much as the rest of a plane's templates.
#[inline]
fn push_vector(values: &mut Vec<f32>, vector: &[f32]) {
    if let Ok(v) = <&[f32; 16]>::try_from(vector) {
        values.extend_from_slice(v);
    } else if let Ok(v) = <&[f32; 8]>::try_from(vector) {
        values.extend_from_slice(v);
    } else if let Ok(v) = <&[f32; 3]>::try_from(vector) {
        values.extend_from_slice(v);
    } else {
        values.extend_from_slice(vector);
    }
}

/// The squared distance of two vectors, term k added into lane k mod 4 (each lane in
/// order) and the lanes summed as (0 + 2) + (1 + 3): the order of four-wide SIMD, which
/// the compiler then uses without reassociating anything, where one running sum made each
/// pixel a chain of dependent additions (a quarter of the CPU of a 250k-vertex surface run). The GPU passes
/// (`shaders/synth_pass.wgsl`, `lane_sum`) add in the same order, for the same bits.
#[inline(always)]
fn lane_ssd(a: &[f32], b: &[f32]) -> f32 {
    let mut lanes = [0.0f32; 4];
    let (whole, rest) = (a.len() / 4 * 4, a.len() % 4);
    for (x, y) in a[..whole].chunks_exact(4).zip(b[..whole].chunks_exact(4)) {
        for l in 0..4 {
            let e = x[l] - y[l];
            lanes[l] += e * e;
        }
    }
    for l in 0..rest {
        let e = a[whole + l] - b[whole + l];
        lanes[l] += e * e;
    }
    (lanes[0] + lanes[2]) + (lanes[1] + lanes[3])
}

/// [`AppearanceMetric::cost`] with `D` values per vector known to the compiler (colours and
/// the analysis' usual appearance dimensions), so that each pixel's sum is unrolled and its
/// slices unchecked: the candidate loop's cost was a quarter of a plane synthesis. Each
/// pixel's terms are added in the general loop's order, so the distances are the same bits.
#[inline]
fn ssd_within<const D: usize>(values: &[f32], base: isize, query: &Vectors, bound: f32) -> f32 {
    let mut d = 0.0;
    for (&offset, target) in query.offsets.iter().zip(query.values.chunks_exact(D)) {
        let o = (base + offset) as usize;
        let vector: &[f32; D] = values[o..o + D].try_into().expect("a slice of D values");
        let target: &[f32; D] = target.try_into().expect("a chunk of D values");
        d += lane_ssd(vector, target);
        if d > bound {
            break;
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::target::grid_levels;

    /// The colour metric (SSD of linear RGB, through an [`AppearanceMap`] of three
    /// dimensions): zero for an exact copy, and growing with a colour change.
    #[test]
    fn colour_distance_is_zero_for_a_copy_and_grows_with_the_colour_change() {
        let (w, h) = (16usize, 16usize);
        // A ramp: texel (x, y) has red x/16, so moving a coordinate by d changes red by d/16.
        let colours: Vec<f32> =
            (0..w * h).flat_map(|p| [(p % w) as f32 / 16.0, (p / w) as f32 / 16.0, 0.5]).collect();
        let map = AppearanceMap::new(w, h, 3, &colours, false);
        let metric = AppearanceMetric { map: &map, template: 7 };
        let level = &grid_levels(w, h, 1, 7, 3)[0];
        let copy = State::new(vec![0; w * h], (0..w * h).map(|p| [(p % w) as i32, (p / w) as i32]).collect());
        let (v, centre) = (8 * w + 8, (8i64, 8i64));
        let distance = |state: &State| {
            let (mut slots, mut query) = (Vec::new(), Vectors::default());
            metric.prepare(level.slots_of(v, &mut slots), state, None, &mut query);
            metric.cost(&query, centre.0, centre.1, f32::INFINITY)
        };
        assert_eq!(distance(&copy), 0.0, "an exact copy");
        let shifted = |d: i32| {
            let mut s = copy.clone();
            s.uv[v + 1][0] += d;
            distance(&s)
        };
        let ds: Vec<f32> = [1, 2, 4].into_iter().map(shifted).collect();
        assert!(ds[0] > 0.0 && ds[0] < ds[1] && ds[1] < ds[2], "{ds:?}");
        // Squared: twice the colour change costs four times as much.
        assert!((ds[1] / ds[0] - 4.0).abs() < 1e-3, "{ds:?}");
    }
}
