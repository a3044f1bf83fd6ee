//! The adaptive similarity metric of Chen and Dong 2008 (§5.2) on round neighbourhoods:
//! candidates are compared by SSD over growing neighbourhoods (the centre and circle 1, then
//! circle 2 added, …, the paper's 3×3, 5×5, …), the SSDs of every size summed. At each size
//! only the candidates at the low end of the distribution stay (at or below mean − one
//! standard deviation), until one is left: that size is the vertex's local top size. Within
//! one comparison, a pixel pair whose difference lies beyond two standard deviations of the
//! neighbourhood's pair differences is an outlier and left out.

use super::round::{RoundSample, RoundStencil};

/// A vertex's round neighbourhood: `points × dims` values in the order of
/// [`RoundStencil::layout`], and which points are known (synthesized; the paper's
/// "coloured" points). Unknown points are left out of every comparison.
#[derive(Clone, Debug, Default)]
pub struct RoundQuery {
    /// `points × dims` values, point by point (unknown points' values are not read).
    pub values: Vec<f32>,
    /// Per point, whether it is synthesized and so compared.
    pub known: Vec<bool>,
}

/// What the adaptive metric chose for one vertex.
#[derive(Clone, Debug, PartialEq)]
pub struct AdaptiveChoice {
    /// The chosen texel (an entry of the candidate list).
    pub texel: u32,
    /// The neighbourhood size (number of circles) at which one candidate was left, or the
    /// largest size when several still tied there.
    pub top_size: usize,
    /// The candidate set's size after each neighbourhood size, from size 1.
    pub kept: Vec<usize>,
}

/// Reusable buffers for [`choose`].
#[derive(Default)]
pub struct Scratch {
    set: Vec<(u32, f32)>,
    pairs: Vec<f32>,
}

/// The adaptive choice among `candidates` (texels y · width + x of `sample`'s level) for
/// `query`; `None` without candidates.
pub fn choose(
    query: &RoundQuery,
    sample: &RoundSample,
    candidates: &[u32],
    scratch: &mut Scratch,
) -> Option<AdaptiveChoice> {
    choose_weighted(query, sample, candidates, |_| 1.0, scratch)
}

/// [`choose`] with each candidate's distance multiplied by `factor(texel)` at every size
/// (choosy selection's usage penalty, [`super::engine::Select::Choosy`]).
pub fn choose_weighted(
    query: &RoundQuery,
    sample: &RoundSample,
    candidates: &[u32],
    factor: impl Fn(u32) -> f32,
    scratch: &mut Scratch,
) -> Option<AdaptiveChoice> {
    let first = *candidates.first()?;
    let Scratch { set, pairs } = scratch;
    set.clear();
    set.extend(candidates.iter().map(|&q| (q, 0.0f32)));
    let mut kept = Vec::with_capacity(sample.stencil.circles);
    let mut top_size = sample.stencil.circles;
    for size in 1..=sample.stencil.circles {
        for entry in set.iter_mut() {
            let texel = sample.at(entry.0 as usize % sample.width, entry.0 as usize / sample.width);
            let ssd = robust_ssd(query, texel, sample.dims, RoundStencil::points_within(size), pairs);
            entry.1 += factor(entry.0) * ssd;
        }
        keep_low_end(set);
        kept.push(set.len());
        if set.len() == 1 {
            top_size = size;
            break;
        }
    }
    let best = set.iter().min_by(|a, b| a.1.total_cmp(&b.1)).map_or(first, |e| e.0);
    Some(AdaptiveChoice { texel: best, top_size, kept })
}

/// Keeps the entries at or below mean − σ of their distances (always the smallest).
fn keep_low_end(set: &mut Vec<(u32, f32)>) {
    let n = set.len() as f64;
    let mean = set.iter().map(|e| e.1 as f64).sum::<f64>() / n;
    let sigma = (set.iter().map(|e| (e.1 as f64 - mean).powi(2)).sum::<f64>() / n).sqrt();
    let low = (mean - sigma) as f32;
    let least = set.iter().map(|e| e.1).fold(f32::INFINITY, f32::min);
    set.retain(|e| e.1 <= low.max(least));
}

/// SSD between the first `points` points of `query` and `texel`'s round neighbourhood, over
/// known points, outlier pairs (beyond mean + 2σ of the pair differences) left out.
pub fn robust_ssd(
    query: &RoundQuery,
    texel: &[f32],
    dims: usize,
    points: usize,
    pairs: &mut Vec<f32>,
) -> f32 {
    pairs.clear();
    for p in (0..points).filter(|&p| query.known[p]) {
        let (a, b) = (&query.values[p * dims..(p + 1) * dims], &texel[p * dims..(p + 1) * dims]);
        pairs.push(a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum());
    }
    without_outliers(pairs)
}

/// The sum of `pairs` without those beyond two standard deviations above their mean.
pub fn without_outliers(pairs: &[f32]) -> f32 {
    if pairs.is_empty() {
        return 0.0;
    }
    let n = pairs.len() as f64;
    let mean = pairs.iter().map(|&d| d as f64).sum::<f64>() / n;
    let sigma = (pairs.iter().map(|&d| (d as f64 - mean).powi(2)).sum::<f64>() / n).sqrt();
    let limit = mean + 2.0 * sigma;
    pairs.iter().filter(|&&d| d as f64 <= limit).map(|&d| d as f64).sum::<f64>() as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::sample::AppearanceMap;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const STENCIL: RoundStencil = RoundStencil { circles: 3 };

    /// A 32² sample of smoothed noise in 3 channels: structure at several scales.
    fn noise_sample() -> RoundSample {
        let (w, h) = (32usize, 32usize);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let raw: Vec<f32> = (0..w * h * 3).map(|_| rng.random::<f32>()).collect();
        let smooth: Vec<f32> = (0..w * h * 3)
            .map(|i| {
                let (p, d) = (i / 3, i % 3);
                let (x, y) = (p % w, p / w);
                let right = (y * w + (x + 1) % w) * 3 + d;
                let down = (((y + 1) % h) * w + x) * 3 + d;
                (raw[i] + raw[right] + raw[down]) / 3.0
            })
            .collect();
        let map = AppearanceMap::new(w, h, 3, &smooth, true);
        RoundSample::new(&map, w, h, STENCIL).unwrap()
    }

    fn query_of(sample: &RoundSample, x: usize, y: usize, noise: f32, rng: &mut ChaCha8Rng) -> RoundQuery {
        let values = sample.at(x, y).iter().map(|v| v + noise * (rng.random::<f32>() - 0.5)).collect();
        RoundQuery { values, known: vec![true; STENCIL.points()] }
    }

    #[test]
    fn the_candidate_set_shrinks_with_the_size_to_the_match() {
        let sample = noise_sample();
        let candidates: Vec<u32> = (0..(sample.width * sample.height) as u32).collect();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut scratch = Scratch::default();
        let mut top_sizes = [0usize; 4];
        for t in 0..40 {
            let (x, y) = ((t * 7) % 32, (t * 13) % 32);
            let query = query_of(&sample, x, y, 0.05, &mut rng);
            // Every texel, and a short list like the k-coherence one the paper searches.
            let mut short: Vec<u32> = (0..15).map(|_| rng.random_range(0..32 * 32)).collect();
            short.push((y * 32 + x) as u32);
            for (list, name) in [(&candidates, "all"), (&short, "short")] {
                let choice = choose(&query, &sample, list, &mut scratch).unwrap();
                assert_eq!(choice.texel as usize, y * 32 + x, "query {t}, {name}: {choice:?}");
                assert!(choice.kept.windows(2).all(|w| w[1] <= w[0]), "{:?}", choice.kept);
                assert!(choice.kept[0] < list.len() / 2, "{name}: {:?}", choice.kept);
                assert_eq!(choice.kept.len(), choice.top_size);
                if name == "short" {
                    top_sizes[choice.top_size] += 1;
                }
            }
        }
        // The top size is region dependent: neither always the smallest nor the largest.
        assert!(top_sizes[3] < 40 && top_sizes[1] < 40, "{top_sizes:?}");
    }

    #[test]
    fn outlier_pairs_are_left_out() {
        let mut pairs = vec![1.0f32; 48];
        pairs.push(100.0);
        assert_eq!(without_outliers(&pairs), 48.0);
        // Without an outstanding pair nothing is dropped.
        let even: Vec<f32> = (0..49).map(|i| i as f32).collect();
        assert_eq!(without_outliers(&even), even.iter().sum::<f32>());
        // One wrong pixel in an otherwise exact neighbourhood does not cost the match.
        let sample = noise_sample();
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let mut query = query_of(&sample, 9, 4, 0.0, &mut rng);
        query.values[20 * 3..21 * 3].fill(50.0);
        let candidates: Vec<u32> = (0..(32 * 32) as u32).collect();
        let choice = choose(&query, &sample, &candidates, &mut Scratch::default()).unwrap();
        assert_eq!(choice.texel, 4 * 32 + 9);
    }

    #[test]
    fn unknown_points_are_not_compared() {
        let sample = noise_sample();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut query = query_of(&sample, 20, 11, 0.0, &mut rng);
        // Half the points unknown and garbage: the known half still finds the texel.
        for p in (1..STENCIL.points()).step_by(2) {
            query.known[p] = false;
            query.values[p * 3..(p + 1) * 3].fill(-9.0);
        }
        let candidates: Vec<u32> = (0..(32 * 32) as u32).collect();
        let choice = choose(&query, &sample, &candidates, &mut Scratch::default()).unwrap();
        assert_eq!(choice.texel, 11 * 32 + 20);
        assert!(choose(&query, &sample, &[], &mut Scratch::default()).is_none());
    }
}
