//! Texton analysis (Tong et al. 2002, §4; the pyramid of §5.1 and the kNN lists of §5.2).
//!
//! - [`filters`]: filter banks defined in TOML (`filters/lm48.toml`, Leung and Malik's 48).
//! - [`convolve`]: every image filtered with a whole bank by FFT.
//! - [`kmeans`](mod@kmeans): seeded, thread-count-independent k-means for textons and representative
//!   images.
//! - [`elkan`]: bounds that let Lloyd's iterations skip points whose centre cannot change.
//! - [`basis`]: principal images, so that only a few basis images need filtering.
//! - [`products`]: matrix products split over rayon tasks with the bits of one product.
//! - [`gamma`]: Γ, texton distances and the spectral embedding.
//! - [`pyramid`]: Gaussian image pyramids.
//! - [`knn`]: k-coherence candidate lists.
//! - [`npy`]: NumPy arrays, the analysis' storage format.

pub mod appearance;
pub mod basis;
pub mod convolve;
pub mod elkan;
pub mod features;
pub mod filters;
pub mod gamma;
pub mod images;
pub mod input;
pub mod kmeans;
pub mod knn;
pub mod memory;
pub mod npy;
pub mod params;
pub mod pipeline;
pub mod products;
pub mod pyramid;
pub mod reduce;
pub mod select;
pub mod store;
pub mod textons;

pub use convolve::{convolve_bank, BankConvolver, Padding};
pub use filters::{Filter, FilterBank, FilterKind, FilterSpec, Rgb8Image};
pub use kmeans::{assign, kmeans, Assignment, Clustering, KMeansOptions};

/// Timings of the two hot paths, measured, never asserted (DESIGN: benchmarks). Run them
/// in a release build as ignored tests, with their output shown (the test harness'
/// `ignored` and `nocapture` options), filtered to `analysis::bench`.
#[cfg(test)]
mod bench {
    use super::*;
    use crate::progress::Silent;
    use ndarray::Array2;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use std::time::Instant;

    fn median_ms(mut f: impl FnMut(), reps: usize) -> f64 {
        let mut times: Vec<f64> = (0..reps)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        times.sort_by(f64::total_cmp);
        times[reps / 2]
    }

    #[test]
    #[ignore = "benchmark: run in release, as an ignored test, with its output shown"]
    fn bench_filtering_and_kmeans() {
        let threads = rayon::current_num_threads();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let channels: Vec<Vec<f32>> =
            (0..3).map(|_| (0..64 * 64).map(|_| rng.random::<f32>()).collect()).collect();
        let planes: Vec<&[f32]> = channels.iter().map(Vec::as_slice).collect();
        let conv = BankConvolver::new(FilterBank::lm48());
        let t = Instant::now();
        conv.filter_many(&planes, 64, 64, Padding::Mirror, &Silent).unwrap();
        let cold = t.elapsed().as_secs_f64() * 1e3;
        let warm = median_ms(
            || {
                conv.filter_many(&planes, 64, 64, Padding::Mirror, &Silent).unwrap();
            },
            21,
        );
        println!("filter 64x64 x 3 channels x 48 filters ({threads} threads): first call {cold:.2} ms (builds kernel spectra), then {warm:.2} ms");

        let (n, d, k) = (4096, 1000, 400);
        let planted = Array2::from_shape_fn((k, d), |_| rng.random::<f32>());
        // A continuum (points on an 8-dimensional subspace, as filter responses of natural
        // images roughly are) keeps Lloyd's iterations busy; planted clusters settle fast.
        let latent = Array2::from_shape_fn((n, 8), |_| rng.random::<f32>());
        let basis = Array2::from_shape_fn((8, d), |_| rng.random::<f32>() - 0.5);
        let datasets = [
            ("8-dim continuum", latent.dot(&basis)),
            (
                "400 planted clusters",
                Array2::from_shape_fn((n, d), |(i, j)| {
                    planted[[i % k, j]] + 0.3 * (rng.random::<f32>() - 0.5)
                }),
            ),
        ];
        for (name, data) in &datasets {
            bench_kmeans(name, data, k);
        }
    }

    fn bench_kmeans(name: &str, data: &Array2<f32>, k: usize) {
        let (threads, (n, d)) = (rayon::current_num_threads(), data.dim());
        let t = Instant::now();
        let seeds = kmeans::kmeans_plus_plus(data.view(), k, 1).unwrap();
        let seeding = t.elapsed().as_secs_f64();
        let options = KMeansOptions { k, max_iterations: 10, tolerance: 0.0, ..KMeansOptions::default() };
        let t = Instant::now();
        let result = kmeans(data.view(), &options, &Silent).unwrap();
        let total = t.elapsed().as_secs_f64();
        println!(
            "k-means {name}, k={k}, {n} points x {d} dims ({threads} threads): k-means++ {seeding:.2} s; \
             k-means++ then {} iterations {total:.2} s ({:.3} s per iteration); {} centres",
            result.iterations,
            (total - seeding) / result.iterations.max(1) as f64,
            seeds.nrows()
        );
    }
}
