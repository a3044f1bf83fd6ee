//! Texton analysis (Tong et al. 2002, §4): the numeric core that turns a BTF stack into
//! filter responses and clusters them.
//!
//! - [`filters`]: filter banks defined in TOML (`filters/lm48.toml`, Leung and Malik's 48).
//! - [`convolve`]: every image filtered with a whole bank by FFT.
//! - [`kmeans`]: seeded, thread-count-independent k-means for textons and representative
//!   images.

pub mod convolve;
pub mod filters;
pub mod kmeans;

pub use convolve::{convolve_bank, BankConvolver, Padding};
pub use filters::{Filter, FilterBank, FilterKind, FilterSpec, Rgb8Image};
pub use kmeans::{assign, kmeans, Assignment, Clustering, KMeansOptions};
