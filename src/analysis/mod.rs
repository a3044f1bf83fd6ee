//! Texton analysis (Tong et al. 2002, §4; the pyramid of §5.1 and the kNN lists of §5.2).
//!
//! - [`filters`]: filter banks defined in TOML (`filters/lm48.toml`, Leung and Malik's 48).
//! - [`convolve`]: every image filtered with a whole bank by FFT.
//! - [`kmeans`]: seeded, thread-count-independent k-means for textons and representative
//!   images.
//! - [`basis`]: principal images, so that only a few basis images need filtering.
//! - [`gamma`]: Γ, texton distances and the spectral embedding.
//! - [`pyramid`]: Gaussian image pyramids.
//! - [`knn`]: k-coherence candidate lists.
//! - [`npy`]: NumPy arrays, the analysis' storage format.

pub mod basis;
pub mod convolve;
pub mod features;
pub mod filters;
pub mod gamma;
pub mod kmeans;
pub mod knn;
pub mod npy;
pub mod pipeline;
pub mod pyramid;
pub mod select;
pub mod store;
pub mod textons;

pub use convolve::{convolve_bank, BankConvolver, Padding};
pub use filters::{Filter, FilterBank, FilterKind, FilterSpec, Rgb8Image};
pub use kmeans::{assign, kmeans, Assignment, Clustering, KMeansOptions};
