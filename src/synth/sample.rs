//! The sample side of synthesis: per pyramid level, the texton map, Γ and the kNN lists,
//! taken from an analysis in memory or read from its directory.

use crate::analysis::npy;
use crate::analysis::pipeline::{Analysis, AnalysisLevel};
use crate::analysis::store::{manifest_of, read_manifest, Manifest, MANIFEST};
use crate::btf::Btf;
use crate::{Error, Result};
use std::path::Path;

/// One level of the analysed sample.
#[derive(Clone, Debug)]
pub struct SampleLevel {
    /// Width of the level in texels.
    pub width: usize,
    /// Height of the level in texels.
    pub height: usize,
    /// Texton label per pixel, row-major.
    pub labels: Vec<u16>,
    /// Γ, `textons × textons` row-major; the last texton is the default texton.
    pub gamma: Vec<f32>,
    /// Rows of Γ: the level's textons plus the default texton.
    pub textons: usize,
    /// `[pixels][k]` kNN lists, the pixel itself first.
    pub knn: Vec<u32>,
    /// Lists by two-level neighbourhoods; absent on the coarsest analysed level.
    pub knn_two_level: Option<Vec<u32>>,
    /// Length of every kNN list.
    pub k: usize,
    /// Whether the sample wraps around (it was analysed as tileable).
    pub tileable: bool,
    /// Per-pixel appearance vectors, if the analysis has them (written since they exist).
    pub appearance: Option<AppearanceMap>,
    /// Per-pixel linear RGB for [`super::MetricKind::Colour`], once
    /// [`Sample::load_colours`] has built it.
    pub colour: Option<AppearanceMap>,
}

/// One level's appearance vectors, scaled to unit total variance per pixel (so that levels
/// weigh alike in two-level distances) and stored with a border of [`AppearanceMap::PAD`]
/// texels (wrapped on tileable samples, the edge repeated otherwise) so that neighbourhood
/// lookups never need a bounds check.
#[derive(Clone, Debug)]
pub struct AppearanceMap {
    /// Values per texel.
    pub dims: usize,
    stride: usize,
    values: Vec<f32>,
}

impl AppearanceMap {
    /// Border kept around the map: enough for templates up to 2·PAD + 1 texels wide, the
    /// 63 texels the CLI and recipes accept (one level may be the whole synthesis, so a
    /// wide template meets the map on its finest level too).
    pub const PAD: usize = 31;

    /// From `[pixels][dims]` vectors of a `width × height` level.
    pub fn new(width: usize, height: usize, dims: usize, vectors: &[f32], tileable: bool) -> Self {
        let pixels = (width * height).max(1);
        let mean: Vec<f64> = (0..dims)
            .map(|d| vectors.iter().skip(d).step_by(dims).map(|&v| v as f64).sum::<f64>() / pixels as f64)
            .collect();
        let variance: f64 =
            vectors.iter().enumerate().map(|(i, &v)| (v as f64 - mean[i % dims]).powi(2)).sum::<f64>()
                / pixels as f64;
        let scale = if variance > 0.0 { (1.0 / variance.sqrt()) as f32 } else { 1.0 };
        let pad = Self::PAD as i64;
        let stride = width + 2 * Self::PAD;
        let mut values = Vec::with_capacity(stride * (height + 2 * Self::PAD) * dims);
        for y in -pad..height as i64 + pad {
            for x in -pad..width as i64 + pad {
                let (sx, sy) = if tileable {
                    (x.rem_euclid(width as i64), y.rem_euclid(height as i64))
                } else {
                    (x.clamp(0, width as i64 - 1), y.clamp(0, height as i64 - 1))
                };
                let o = (sy as usize * width + sx as usize) * dims;
                values.extend(
                    vectors[o..o + dims].iter().enumerate().map(|(d, &v)| (v - mean[d] as f32) * scale),
                );
            }
        }
        AppearanceMap { dims, stride, values }
    }

    /// The vector at (x, y), which may lie up to [`Self::PAD`] texels outside the level.
    #[inline]
    pub fn at(&self, x: i64, y: i64) -> &[f32] {
        let o = ((y + Self::PAD as i64) as usize * self.stride + (x + Self::PAD as i64) as usize) * self.dims;
        &self.values[o..o + self.dims]
    }

    /// Offset in floats of (dx, dy) from a vector, for reading a neighbourhood from one base.
    #[inline]
    pub fn offset(&self, dx: i64, dy: i64) -> isize {
        (dy as isize * self.stride as isize + dx as isize) * self.dims as isize
    }

    /// Index in floats of the vector at (x, y).
    #[inline]
    pub fn index(&self, x: i64, y: i64) -> usize {
        ((y + Self::PAD as i64) as usize * self.stride + (x + Self::PAD as i64) as usize) * self.dims
    }

    /// Every stored value (border included), for reading at [`Self::index`] + [`Self::offset`].
    #[inline]
    pub fn values(&self) -> &[f32] {
        &self.values
    }
}

/// The analysed sample: its levels, finest first, and the manifest they came from.
#[derive(Clone, Debug)]
pub struct Sample {
    /// The levels of the sample, finest first.
    pub levels: Vec<SampleLevel>,
    /// The analysis manifest the levels came from.
    pub manifest: Manifest,
}

impl Sample {
    /// The first `levels` levels of `analysis` of `btf`, straight from memory: what
    /// [`Sample::open`] reads back after [`crate::analysis::store::write`], without the disk.
    pub fn from_analysis(analysis: &Analysis, btf: &Btf, levels: usize) -> Result<Self> {
        let manifest = manifest_of(analysis, btf, Path::new("(in memory)"), None);
        check_level_count(levels, &manifest, "the analysis in memory")?;
        let tileable = manifest.params.tileable;
        let level = |level: &AnalysisLevel| -> Result<SampleLevel> {
            let t = &level.textons;
            let (width, height) = (t.map.width, t.map.height);
            let appearance = t.appearance.as_slice().filter(|_| t.appearance.ncols() > 0);
            let level = SampleLevel {
                width,
                height,
                labels: t.map.labels.clone(),
                gamma: t.gamma.iter().copied().collect(),
                textons: t.textons + 1,
                k: level.knn.len() / (width * height).max(1),
                knn: level.knn.clone(),
                knn_two_level: level.knn_two_level.clone(),
                tileable,
                appearance: appearance
                    .map(|a| AppearanceMap::new(width, height, t.appearance.ncols(), a, tileable)),
                colour: None,
            };
            level.check().map_err(Error::invalid)?;
            Ok(level)
        };
        let levels = analysis.levels[..levels].iter().map(level).collect::<Result<_>>()?;
        Ok(Sample { levels, manifest })
    }

    /// Reads the first `levels` levels of the analysis in `dir`.
    pub fn open(dir: &Path, levels: usize) -> Result<Self> {
        let manifest = read_manifest(dir)?;
        check_level_count(levels, &manifest, &dir.display().to_string())?;
        let read_level = |info: &crate::analysis::store::LevelInfo| -> Result<SampleLevel> {
            let labels: npy::NpyArray<u16> = npy::read(&dir.join(&info.files.textons))?;
            let gamma: npy::NpyArray<f32> = npy::read(&dir.join(&info.files.gamma))?;
            let knn: npy::NpyArray<u32> = npy::read(&dir.join(&info.files.knn))?;
            let knn_two_level = match &info.files.knn_two_level {
                Some(name) => Some(npy::read::<u32>(&dir.join(name))?.data),
                None => None,
            };
            let textons = info.textons + 1;
            let appearance = match &info.files.appearance {
                Some(name) => {
                    let path = dir.join(name);
                    let a: npy::NpyArray<f32> = npy::read(&path)?;
                    let dims = a.shape.get(2).copied().unwrap_or(0);
                    if a.shape.len() != 3 || a.shape[..2] != [info.height, info.width] || dims == 0 {
                        return Err(Error::format(path, "appearance vectors do not match the texton map"));
                    }
                    Some(AppearanceMap::new(info.width, info.height, dims, &a.data, manifest.params.tileable))
                }
                None => None,
            };
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
                appearance,
                colour: None,
            };
            level.check().map_err(|m| Error::format(dir.join(&info.files.textons), m))?;
            Ok(level)
        };
        let levels = manifest.levels[..levels].iter().map(read_level).collect::<Result<_>>()?;
        Ok(Sample { levels, manifest })
    }

    /// Builds every level's colours for [`super::MetricKind::Colour`] from the analysis in
    /// `dir`: the mean of the selected images (the photograph itself for a one-image BTF),
    /// taken down the pyramid the analysis built its levels with. Read only when a recipe
    /// matches colours, since a BTF's images are large.
    pub fn load_colours(&mut self, dir: &Path) -> Result<()> {
        let images = crate::analysis::images::SampleImages::open(dir)?;
        self.colours_from(&images).map_err(|(file, message)| Error::format(dir.join(file), message))
    }

    /// [`Sample::load_colours`] from the sample's images already in memory
    /// ([`crate::analysis::images::SampleImages::from_btf`] for an analysis never written).
    pub fn set_colours(&mut self, images: &crate::analysis::images::SampleImages) -> Result<()> {
        self.colours_from(images).map_err(|(_, message)| Error::invalid(message))
    }

    /// The colours of every level; an error names the analysis file at fault and the fault.
    fn colours_from(
        &mut self,
        images: &crate::analysis::images::SampleImages,
    ) -> std::result::Result<(), (&'static str, &'static str)> {
        let (w, h) = (self.manifest.width, self.manifest.height);
        let selected = &self.manifest.selected;
        if (images.width, images.height) != (w, h) || selected.iter().any(|&i| i >= images.len()) {
            return Err(("images.npy", "the images do not match analysis.json"));
        }
        let mut mean = vec![0.0f32; w * h * 3];
        for &i in selected {
            for (p, rgb) in mean.chunks_exact_mut(3).enumerate() {
                let c = images.rgb(i, p % w, p / w);
                rgb.iter_mut().zip(c).for_each(|(m, v)| *m += v / selected.len() as f32);
            }
        }
        let tileable = self.manifest.params.tileable;
        let (mut colours, mut size) = (mean, (w, h));
        for level in &mut self.levels {
            if (level.width, level.height) != size {
                let (down, dw, dh) =
                    crate::analysis::pyramid::downsample(&colours, size.0, size.1, 3, tileable);
                (colours, size) = (down, (dw, dh));
            }
            if (level.width, level.height) != size {
                return Err((MANIFEST, "the level sizes do not halve"));
            }
            level.colour = Some(AppearanceMap::new(size.0, size.1, 3, &colours, tileable));
        }
        Ok(())
    }
}

fn check_level_count(levels: usize, manifest: &Manifest, name: &str) -> Result<()> {
    if levels == 0 || levels > manifest.levels.len() {
        return Err(Error::out_of_range(
            crate::Param::Levels,
            levels,
            format!("the analysis {name} has {} level(s)", manifest.levels.len()),
        ));
    }
    Ok(())
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

    /// The distance ‖t_a − t_b‖² of two textons ([`crate::analysis::gamma::texton_distance`]).
    #[inline]
    pub fn texton_distance(&self, a: u16, b: u16) -> f32 {
        crate::analysis::gamma::texton_distance(self.dot(a, a), self.dot(b, b), self.dot(a, b))
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

    /// (x, y) brought to the nearest candidate texel, `margin` texels inside the sample's
    /// edges (any texel, wrapped, on tileable samples). The margin is the target's
    /// ([`super::target::TargetLevel::candidate_margin`]): the template's radius, where a
    /// copied neighbourhood can be read whole, or less on a plane.
    pub fn candidate_pixel(&self, x: i64, y: i64, margin: usize) -> usize {
        let (w, h) = (self.width as i64, self.height as i64);
        let r = margin as i64;
        let (x, y) = if self.tileable {
            (x.rem_euclid(w), y.rem_euclid(h))
        } else if w > 2 * r && h > 2 * r {
            (x.clamp(r, w - 1 - r), y.clamp(r, h - 1 - r))
        } else {
            (x.clamp(0, w - 1), y.clamp(0, h - 1))
        };
        (y * w + x) as usize
    }

    /// The margin on a side of `n` texels: `margin`, or less where the side is too short.
    fn side_margin(&self, n: usize, margin: usize) -> i64 {
        if self.tileable {
            0
        } else {
            (margin as i64).min((n as i64 - 1) / 2)
        }
    }

    /// Candidate texels across a side of `n` texels (the level's width or height) whose
    /// edges keep `margin` texels out: the band patches wrap around.
    pub fn band(&self, n: usize, margin: usize) -> usize {
        (n as i64 - 2 * self.side_margin(n, margin)).max(1) as usize
    }

    /// (x, y) folded into the candidate texels (`margin` inside the edges): wrapped on
    /// tileable samples, mirrored at the band's edges otherwise. Unlike clamping, mirroring
    /// never sends a whole run of coordinates onto one edge texel (where a smear or streak
    /// would start).
    pub fn fold_into_candidates(&self, x: i64, y: i64, margin: usize) -> [i32; 2] {
        let fold = |v: i64, n: usize| -> i64 {
            if self.tileable {
                return v.rem_euclid(n as i64);
            }
            let r = self.side_margin(n, margin);
            let (lo, hi) = (r, n as i64 - 1 - r);
            if hi <= lo {
                return lo;
            }
            let period = 2 * (hi - lo);
            let m = (v - lo).rem_euclid(period);
            lo + if m <= hi - lo { m } else { period - m }
        };
        [fold(x, self.width) as i32, fold(y, self.height) as i32]
    }

    /// (x, y) wrapped around the band of candidate texels (`margin` inside the edges; the
    /// whole sample when it tiles), as if that band tiled.
    pub fn wrap_into_candidates(&self, x: i64, y: i64, margin: usize) -> [i32; 2] {
        let wrap = |v: i64, n: usize| -> i64 {
            let r = self.side_margin(n, margin);
            r + (v - r).rem_euclid(self.band(n, margin) as i64)
        };
        [wrap(x, self.width) as i32, wrap(y, self.height) as i32]
    }

    /// The first and last candidate texel across a side of `n` texels (the band patches
    /// wrap around), on a sample that does not tile.
    pub fn band_ends(&self, n: usize, margin: usize) -> (i64, i64) {
        let r = self.side_margin(n, margin);
        (r, n as i64 - 1 - r)
    }

    /// Whether (x, y) is a candidate texel: `margin` inside the sample's edges (any texel of
    /// a tileable sample).
    pub fn is_candidate(&self, x: i64, y: i64, margin: usize) -> bool {
        let inside = |v: i64, n: usize| {
            let r = self.side_margin(n, margin);
            (r..n as i64 - r).contains(&v)
        };
        self.tileable || (inside(x, self.width) && inside(y, self.height))
    }

    /// The first `k` entries of pixel `p`'s list (two-level lists when asked and present).
    pub fn list(&self, p: usize, k: usize, two_level: bool) -> &[u32] {
        let lists = if two_level { self.knn_two_level.as_ref().unwrap_or(&self.knn) } else { &self.knn };
        &lists[p * self.k..p * self.k + k.min(self.k)]
    }
}
