//! The sample side of synthesis: per pyramid level, the texton map, Γ and the kNN lists,
//! read from an analysis directory.

use crate::analysis::npy;
use crate::analysis::store::{read_manifest, Manifest};
use crate::{Error, Result};
use std::path::Path;

/// One level of the analysed sample.
#[derive(Clone, Debug)]
pub struct SampleLevel {
    pub width: usize,
    pub height: usize,
    /// Texton label per pixel, row-major.
    pub labels: Vec<u16>,
    /// Γ, `textons × textons` row-major; the last texton is the default texton.
    pub gamma: Vec<f32>,
    pub textons: usize,
    /// `[pixels][k]` kNN lists, the pixel itself first.
    pub knn: Vec<u32>,
    /// Lists by two-level neighbourhoods; absent on the coarsest analysed level.
    pub knn_two_level: Option<Vec<u32>>,
    pub k: usize,
    pub tileable: bool,
}

/// The analysed sample: its levels, finest first, and the manifest they came from.
#[derive(Clone, Debug)]
pub struct Sample {
    pub levels: Vec<SampleLevel>,
    pub manifest: Manifest,
}

impl Sample {
    /// Reads the first `levels` levels of the analysis in `dir`.
    pub fn open(dir: &Path, levels: usize) -> Result<Self> {
        let manifest = read_manifest(dir)?;
        if levels == 0 || levels > manifest.levels.len() {
            return Err(Error::invalid(format!(
                "--levels {levels}: the analysis {} has {} level(s)",
                dir.display(),
                manifest.levels.len()
            )));
        }
        let read_level = |info: &crate::analysis::store::LevelInfo| -> Result<SampleLevel> {
            let labels: npy::NpyArray<u16> = npy::read(&dir.join(&info.files.textons))?;
            let gamma: npy::NpyArray<f32> = npy::read(&dir.join(&info.files.gamma))?;
            let knn: npy::NpyArray<u32> = npy::read(&dir.join(&info.files.knn))?;
            let knn_two_level = match &info.files.knn_two_level {
                Some(name) => Some(npy::read::<u32>(&dir.join(name))?.data),
                None => None,
            };
            let textons = info.textons + 1;
            let level = SampleLevel {
                width: info.width,
                height: info.height,
                labels: labels.data,
                gamma: gamma.data,
                textons,
                k: knn.shape.get(2).copied().unwrap_or(0),
                knn: knn.data,
                knn_two_level,
                tileable: manifest.params.tileable,
            };
            level.check().map_err(|m| Error::format(dir.join(&info.files.textons), m))?;
            Ok(level)
        };
        let levels = manifest.levels[..levels].iter().map(read_level).collect::<Result<_>>()?;
        Ok(Sample { levels, manifest })
    }
}

impl SampleLevel {
    /// Array sizes agree and every label and list entry is in range.
    fn check(&self) -> Result<(), String> {
        let pixels = self.width * self.height;
        if self.labels.len() != pixels || self.gamma.len() != self.textons * self.textons || self.k == 0 {
            return Err("the analysis arrays do not match analysis.json".into());
        }
        if self.knn.len() != pixels * self.k
            || self.knn_two_level.as_ref().is_some_and(|l| l.len() != pixels * self.k)
        {
            return Err("the kNN lists do not match the texton map".into());
        }
        if self.labels.iter().any(|&l| l as usize >= self.textons) {
            return Err("a texton label is out of range".into());
        }
        let lists = self.knn.iter().chain(self.knn_two_level.iter().flatten());
        if lists.into_iter().any(|&p| p as usize >= pixels) {
            return Err("a kNN entry is out of range".into());
        }
        Ok(())
    }

    /// Index of the default texton.
    pub fn default_texton(&self) -> u16 {
        (self.textons - 1) as u16
    }

    /// Γ entry.
    #[inline]
    pub fn dot(&self, a: u16, b: u16) -> f32 {
        self.gamma[a as usize * self.textons + b as usize]
    }

    /// The label at (x, y), wrapping on tileable samples and clamping otherwise.
    #[inline]
    pub fn label_at(&self, x: i64, y: i64) -> u16 {
        let (x, y) = self.bring_inside(x, y);
        self.labels[y * self.width + x]
    }

    /// (x, y) wrapped (tileable) or clamped into the sample.
    pub fn bring_inside(&self, x: i64, y: i64) -> (usize, usize) {
        let (w, h) = (self.width as i64, self.height as i64);
        if self.tileable {
            (x.rem_euclid(w) as usize, y.rem_euclid(h) as usize)
        } else {
            (x.clamp(0, w - 1) as usize, y.clamp(0, h - 1) as usize)
        }
    }

    /// (x, y) brought to the nearest pixel whose `radius` neighbourhood lies inside the
    /// sample (wrapped on tileable samples): where a copied neighbourhood can be read whole.
    pub fn candidate_pixel(&self, x: i64, y: i64, radius: usize) -> usize {
        let (w, h) = (self.width as i64, self.height as i64);
        let r = radius as i64;
        let (x, y) = if self.tileable {
            (x.rem_euclid(w), y.rem_euclid(h))
        } else if w > 2 * r && h > 2 * r {
            (x.clamp(r, w - 1 - r), y.clamp(r, h - 1 - r))
        } else {
            (x.clamp(0, w - 1), y.clamp(0, h - 1))
        };
        (y * w + x) as usize
    }

    /// The first `k` entries of pixel `p`'s list (two-level lists when asked and present).
    pub fn list(&self, p: usize, k: usize, two_level: bool) -> &[u32] {
        let lists = if two_level { self.knn_two_level.as_ref().unwrap_or(&self.knn) } else { &self.knn };
        &lists[p * self.k..p * self.k + k.min(self.k)]
    }
}
