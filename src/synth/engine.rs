//! The per-vertex synthesis engine's vocabulary (Tong §5): the state a pass rewrites, the
//! order it visits vertices in, how a vertex picks among candidates, and what a pass
//! reports. The pass loop itself is [`super::pass`].

use super::candidates::{full_candidates, Coherence, Search};
use super::recipe::Mask;
use super::sample::SampleLevel;
use super::target::TargetLevel;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

/// The surface texton map of one level: per vertex a texton label and a sample coordinate.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    pub labels: Vec<u16>,
    pub uv: Vec<[i32; 2]>,
}

/// Order in which a pass visits the vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum VisitOrder {
    /// A fresh seeded permutation every pass.
    Random,
    /// Vertex index order (scanline order on a plane).
    Sequential,
    /// Increasing sweep distance along the texture direction (Turk §4.2, [`super::sweep`]).
    Sweep,
    /// The unvisited vertex with the most visited neighbours next (Chen and Dong §6,
    /// [`super::constrained`]).
    MostConstrained,
}

/// What one pass found.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassStats {
    /// Mean over vertices of the best candidate's neighbourhood distance.
    pub mean_best: f64,
    /// Mean candidate-set size.
    pub mean_candidates: f64,
}

/// How a vertex picks among its candidates.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Select {
    /// The smallest distance (Tong §5.1).
    Argmin,
    /// Choosy sampling (Castellanos and Williams §3.11, adapted): the distance is multiplied
    /// by 1 + strength · excess², excess being how far beyond its fair share (output
    /// vertices over candidate texels) the texel is already used on this level. Exact matches
    /// (distance 0) keep winning, so coherent copies are untouched; among inexact ones, the
    /// texels the level leans on too often lose, which keeps the first-order statistics.
    Choosy { strength: f32 },
}

/// How a pass runs.
#[derive(Clone, Copy, Debug)]
pub struct PassPlan {
    pub search: Search,
    pub select: Select,
    /// Distances of candidates that start a new copy (not a patch vertex's forward shift)
    /// are multiplied by 1 + this (Ashikhmin's and Hertzmann's coherence preference).
    pub coherence_bias: f32,
    /// Which template pixels count, in distances and as sources of candidates. With
    /// [`Mask::Visited`] and [`Mask::Half`], a vertex with no source of candidates starts from
    /// a random texel.
    pub mask: Mask,
}

/// The factor on candidate `q`'s distance for a vertex now at `current`: choosy
/// selection's usage penalty times the coherence bias on candidates that start a new copy.
#[inline]
pub(crate) fn selection_factor(
    usage: &Usage,
    coherence: &Coherence,
    q: u32,
    current: [i32; 2],
    bias: f32,
) -> f32 {
    let fresh = if coherence.continues(q) { 1.0 } else { 1.0 + bias };
    usage.factor(q, current) * fresh
}

/// How often each texel is in use on the level, for [`Select::Choosy`].
pub(crate) struct Usage {
    width: usize,
    /// Per texel, the vertices whose coordinate it is (empty for [`Select::Argmin`]).
    count: Vec<u32>,
    fair: f32,
    strength: f32,
}

impl Usage {
    pub(crate) fn new(sample: &SampleLevel, state: &State, radius: usize, select: Select) -> Self {
        let Select::Choosy { strength } = select else {
            return Usage { width: sample.width, count: Vec::new(), fair: 1.0, strength: 0.0 };
        };
        let mut count = vec![0u32; sample.width * sample.height];
        for &[x, y] in &state.uv {
            count[y as usize * sample.width + x as usize] += 1;
        }
        let candidates = full_candidates(sample, radius).len().max(1);
        Usage {
            width: sample.width,
            count,
            fair: (state.uv.len() as f32 / candidates as f32).max(1.0),
            strength,
        }
    }

    /// The factor on texel `q`'s distance for a vertex now at `current`.
    #[inline]
    pub(crate) fn factor(&self, q: u32, current: [i32; 2]) -> f32 {
        let Some(&n) = self.count.get(q as usize) else { return 1.0 };
        let own = u32::from(current[1] as usize * self.width + current[0] as usize == q as usize);
        let excess = ((n - own) as f32 / self.fair - 1.0).max(0.0);
        1.0 + self.strength * excess * excess
    }

    pub(crate) fn moved(&mut self, from: [i32; 2], to: [i32; 2]) {
        if !self.count.is_empty() {
            self.count[from[1] as usize * self.width + from[0] as usize] -= 1;
            self.count[to[1] as usize * self.width + to[0] as usize] += 1;
        }
    }
}

/// The visiting order of one pass over `level`; [`VisitOrder::Sweep`] needs the level's
/// sweep distances (without them it falls back to index order).
pub fn visit_order(
    level: &TargetLevel,
    order: VisitOrder,
    sweep: Option<&[f32]>,
    rng: &mut ChaCha8Rng,
) -> Vec<u32> {
    let mut ids: Vec<u32> = (0..level.vertices as u32).collect();
    match (order, sweep) {
        (VisitOrder::Random, _) => ids.shuffle(rng),
        (VisitOrder::Sweep, Some(s)) => ids.sort_by(|&a, &b| s[a as usize].total_cmp(&s[b as usize])),
        (VisitOrder::MostConstrained, _) => return super::constrained::most_constrained_order(level, rng),
        _ => {}
    }
    ids
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A tileable 16×16 sample of 4 orthonormal textons (Γ = I, default texton = their mean)
    /// in an aperiodic-looking but periodic layout.
    pub(crate) fn periodic_sample(k: usize) -> SampleLevel {
        let (w, h, n) = (16usize, 16usize, 5usize);
        let labels: Vec<u16> = (0..w * h)
            .map(|p| (((p % w) / 2 + (p / w) / 3 * 3 + (p % w) * (p / w) % 3) % 4) as u16)
            .collect();
        let mut gamma = vec![0.0f32; n * n];
        for i in 0..4 {
            gamma[i * n + i] = 1.0;
            gamma[i * n + 4] = 0.25;
            gamma[4 * n + i] = 0.25;
        }
        gamma[4 * n + 4] = 0.25;
        // Exhaustive kNN lists by plain label comparison of 5×5 wrapped neighbourhoods.
        let patch = |p: usize| -> Vec<u16> {
            let (x, y) = ((p % w) as i64, (p / w) as i64);
            (-2..=2)
                .flat_map(|dy| (-2..=2).map(move |dx| (dx, dy)))
                .map(|(dx, dy)| {
                    labels
                        [((y + dy).rem_euclid(h as i64) * w as i64 + (x + dx).rem_euclid(w as i64)) as usize]
                })
                .collect()
        };
        let mut knn = Vec::new();
        for p in 0..w * h {
            let mut others: Vec<(usize, usize)> = (0..w * h)
                .filter(|&q| q != p)
                .map(|q| (patch(p).iter().zip(patch(q)).filter(|(a, b)| **a != *b).count(), q))
                .collect();
            others.sort();
            knn.push(p as u32);
            knn.extend(others.iter().take(k - 1).map(|&(_, q)| q as u32));
        }
        SampleLevel {
            width: w,
            height: h,
            labels,
            gamma,
            textons: n,
            knn,
            knn_two_level: None,
            k,
            tileable: true,
            appearance: None,
            colour: None,
        }
    }
}
