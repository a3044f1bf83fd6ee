//! Texton analysis (Tong et al. 2002 §4, §5.1 pyramid, §5.2 kNN lists).

pub mod basis;
pub mod gamma;
pub mod knn;
pub mod npy;
pub mod pyramid;
