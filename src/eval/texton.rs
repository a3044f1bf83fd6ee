//! Texton-space quality (Tong's own terms): the texton-histogram χ² and the mean
//! neighbourhood distance through Γ.

use crate::synth::engine::State;
use crate::synth::metric::{GammaMetric, Metric};
use crate::synth::sample::SampleLevel;
use crate::synth::target::TargetLevel;
use serde::Serialize;

/// The texton-space measures.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct TextonQuality {
    /// ½ Σ (p − q)² / (p + q) between the result's and the sample's texton frequencies: 0 for
    /// identical histograms, 1 for disjoint ones.
    pub chi2: f64,
    /// Mean per-vertex distance, through Γ, between the vertex's neighbourhood and the sample
    /// neighbourhood at its coordinate (lower is better; 0 = every neighbourhood copied whole).
    pub energy: f64,
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
    let metric = GammaMetric { sample, template: level.template };
    let (mut query, mut slots) = (Vec::new(), Vec::new());
    let total: f64 = (0..level.vertices)
        .map(|v| {
            metric.prepare(level.slots_of(v, &mut slots), state, None, &mut query);
            let [x, y] = state.uv[v];
            metric.cost(&query, x as i64, y as i64, f32::INFINITY) as f64
        })
        .sum();
    total / level.vertices.max(1) as f64
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
