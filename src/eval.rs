//! Quality of a synthesized texton map against its sample: texton-histogram χ², energy and
//! coherence.

use crate::synth::engine::{distance, terms, State};
use crate::synth::sample::SampleLevel;
use crate::synth::target::TargetLevel;
use serde::Serialize;

/// The three measures `btfsynth eval` reports.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Quality {
    /// ½ Σ (p − q)² / (p + q) between the result's and the sample's texton frequencies: 0 for
    /// identical histograms, 1 for disjoint ones.
    pub chi2: f64,
    /// Mean per-vertex distance, through Γ, between the vertex's neighbourhood and the sample
    /// neighbourhood at its coordinate (lower is better; 0 = every neighbourhood copied whole).
    pub energy: f64,
    /// Mean number of vertices per patch copied contiguously from the sample.
    pub coherence: f64,
}

/// χ² distance between two label histograms over `textons` bins.
pub fn chi2(result: &[u16], sample: &[u16], textons: usize) -> f64 {
    let histogram = |labels: &[u16]| {
        let mut h = vec![0.0f64; textons];
        for &l in labels {
            if let Some(bin) = h.get_mut(l as usize) {
                *bin += 1.0;
            }
        }
        let n = labels.len().max(1) as f64;
        h.iter_mut().for_each(|v| *v /= n);
        h
    };
    let (p, q) = (histogram(result), histogram(sample));
    0.5 * p.iter().zip(&q).filter(|(a, b)| *a + *b > 0.0).map(|(a, b)| (a - b).powi(2) / (a + b)).sum::<f64>()
}

/// Mean neighbourhood distance of every vertex to the sample at its coordinate.
pub fn energy(level: &TargetLevel, state: &State, sample: &SampleLevel) -> f64 {
    let total: f64 = (0..level.vertices)
        .map(|v| {
            let own = terms(level.slots_of(v), &state.labels, sample, None);
            let [x, y] = state.uv[v];
            distance(&own, sample, level.template, (x as i64, y as i64), f32::INFINITY) as f64
        })
        .sum();
    total / level.vertices.max(1) as f64
}

/// Mean size of the groups of vertices connected through neighbours (patch vertices at most
/// 1.5 texels away) whose sample coordinates differ by their offset to within a texel, i.e.
/// copied together (differences wrap on tileable samples). Exact on grids, where offsets
/// are whole texels; works for meshes alike.
pub fn coherence(level: &TargetLevel, state: &State, sample: &SampleLevel) -> f64 {
    let mut parent: Vec<usize> = (0..level.vertices).collect();
    fn root(parent: &mut [usize], mut v: usize) -> usize {
        while parent[v] != v {
            parent[v] = parent[parent[v]];
            v = parent[v];
        }
        v
    }
    let wrap = |d: i32, n: usize| {
        if sample.tileable {
            (d + n as i32 / 2).rem_euclid(n as i32) - n as i32 / 2
        } else {
            d
        }
    };
    for v in 0..level.vertices {
        for &(u, [dx, dy]) in level.shifts_of(v) {
            let u = u as usize;
            if u == v || dx * dx + dy * dy > 2.25 {
                continue;
            }
            let ex = wrap(state.uv[u][0] - state.uv[v][0], sample.width) as f32 - dx;
            let ey = wrap(state.uv[u][1] - state.uv[v][1], sample.height) as f32 - dy;
            if ex.abs() < 1.0 && ey.abs() < 1.0 {
                let (a, b) = (root(&mut parent, v), root(&mut parent, u));
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let components = (0..level.vertices).filter(|&v| root(&mut parent, v) == v).count();
    level.vertices as f64 / components.max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_is_zero_for_equal_and_one_for_disjoint_histograms() {
        assert_eq!(chi2(&[0, 1, 1, 2], &[1, 2, 0, 1], 3), 0.0);
        assert!((chi2(&[0, 0], &[1, 1], 2) - 1.0).abs() < 1e-12);
    }
}
