//! The parameters of an analysis ([`AnalysisParams`]), their defaults and their checks
//! against a sample's size: what `analyze`, the memory estimates and the stored manifest
//! all read.

use super::filters::FilterBank;
use super::pyramid::level_sizes;
use crate::{Error, Param, Remedy, Result};

/// Parameters of an analysis; defaults follow Tong et al. 2002.
#[derive(Clone, Debug)]
pub struct AnalysisParams {
    /// Textons at the finest level (default 400, the paper's n_t; capped by the pixel count).
    /// Each coarser level gets a quarter as many.
    pub textons: usize,
    /// Representative images (default 400, the paper's n_s; capped by the image count).
    pub selected: usize,
    /// Pyramid levels (default 3).
    pub levels: usize,
    /// Length of every kNN list, the pixel itself included (default 11; 1 = Ashikhmin).
    pub k: usize,
    /// Side of the square neighbourhood of the kNN search, odd (default 5).
    pub neighborhood: usize,
    /// Whether the sample wraps around: filters and neighbourhoods wrap (default false).
    pub tileable: bool,
    /// Most principal images filtered per level (default 32; see `analysis::basis`).
    pub basis_rank: usize,
    /// Dimensions of the per-pixel appearance vectors (default 8; see `analysis::appearance`).
    pub appearance_dims: usize,
    /// Seed of every random choice (default 0).
    pub seed: u64,
    /// The filter bank (default Leung–Malik 48, `filters/lm48.toml`).
    pub filters: FilterBank,
}

impl Default for AnalysisParams {
    fn default() -> Self {
        AnalysisParams {
            textons: 400,
            selected: 400,
            levels: 3,
            k: 11,
            neighborhood: 5,
            tileable: false,
            basis_rank: 32,
            appearance_dims: super::appearance::DEFAULT_DIMS,
            seed: 0,
            filters: FilterBank::lm48(),
        }
    }
}

impl AnalysisParams {
    /// Checks every parameter against the sample size; errors name the [`Param`] at fault.
    pub fn validate(&self, width: usize, height: usize) -> Result<()> {
        let positive = [
            (Param::Textons, self.textons),
            (Param::SelectedImages, self.selected),
            (Param::Levels, self.levels),
            (Param::K, self.k),
            (Param::BasisRank, self.basis_rank),
            (Param::AppearanceDims, self.appearance_dims),
        ];
        for (param, value) in positive {
            if value == 0 {
                return Err(Error::out_of_range(param, value, "must be at least 1"));
            }
        }
        let n = self.neighborhood;
        if n < 3 || n % 2 == 0 {
            return Err(Error::out_of_range(Param::Neighbourhood, n, "must be odd and at least 3"));
        }
        let need = self.neighborhood + 4;
        let sizes = level_sizes(width, height, self.levels);
        let (w, h) = sizes[sizes.len() - 1];
        if w.min(h) < need {
            let fit = (1..=self.levels)
                .take_while(|&l| {
                    let (w, h) = level_sizes(width, height, l)[l - 1];
                    w.min(h) >= need
                })
                .count();
            if fit == 0 {
                return Err(Error::out_of_range(
                    Param::Neighbourhood,
                    n,
                    format!(
                        "the sample is {width}x{height} pixels, but a {n}x{n} neighbourhood search needs at least {need}x{need}; analyse a larger sample or use a smaller neighbourhood"
                    ),
                ));
            }
            return Err(Error::OutOfRange {
                param: Param::Levels,
                value: self.levels.to_string(),
                message: format!(
                    "the coarsest level would be {w}x{h} pixels, but a {n}x{n} neighbourhood search needs at least {need}x{need}"
                ),
                remedy: Some(Remedy::FewerLevels(fit)),
            });
        }
        Ok(())
    }
}
