//! The sample BTF as a material: its images, its view and light domes, and the one
//! shading core that both renderers use: which 16 images a (view, light) pair blends
//! ([`Material::blend`], run on the CPU for the GPU too) and a bilinear lookup in them.

use super::blend::{DirectionIndex, Nearest4};
use crate::analysis::{npy, store};
use crate::btf::factored::FactoredStack;
use crate::btf::{directions, Direction, DirectionPair};
use crate::{Error, Result};
use glam::Vec3;
use half::f16;
use rayon::prelude::*;
use std::path::Path;

/// Images a (view, light) query blends, with weights. Weights sum to 1 when the point is
/// lit (times n·l for a one-light sample, see [`Material::blend`]; times the cosine ratio
/// for a light beyond the dome, see [`Material::light_weights`]) and to 0 when not.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blend16 {
    /// Indices of the blended images in the stack.
    pub image: [u32; 16],
    /// The weight of each of those images; unused entries have weight 0.
    pub weight: [f32; 16],
}

impl Blend16 {
    /// No light: every weight 0.
    pub const DARK: Blend16 = Blend16 { image: [0; 16], weight: [0.0; 16] };
}

/// A BTF sample ready for shading: f32 RGB images, direction indices and the table from
/// (view, light) to image.
///
/// The pixels are kept texel-major: all images' values at one texel side by side. A blend
/// reads its 16 images at the same texel (or the same four bilinear taps), so its reads fall
/// in one small block instead of 16 image planes a fixed stride apart, which thrash the cache.
///
/// A sample stored as factors (an analysis of a factorized `.btf` or of a streamed basis,
/// see `analysis::input`) is decoded into that layout when it is small
/// ([`DECODE_LIMIT`]); a larger one keeps its factors and computes each value it is asked
/// for (a K-term product per channel, then the colour model), with the same offsets.
pub struct Material {
    width: usize,
    height: usize,
    /// `[height][width][n][3]` linear RGB, or the factors that compute them.
    pixels: Texels,
    pairs: Vec<DirectionPair>,
    views: DirectionIndex,
    lights: DirectionIndex,
    /// `image_of[view * lights + light]`: the image taken under that pair, if any.
    image_of: Vec<Option<u32>>,
    /// Lookups wrap around the edges (the sample tiles) rather than clamp.
    pub tileable: bool,
}

/// Factored samples whose texel-major f32 values take at most this many bytes (and fit
/// the memory budget) are decoded when opened: a lookup is then one read instead of a
/// K-term product per channel. Above it (e.g. the full 400² × 22,801 images, 41 GiB) the
/// factors stay and values are computed on the fly. Time always favours decoding where it
/// fits: a 1024² render with shadows (4 samples per pixel, 32 components per channel) from
/// 32², 48² and 64² crops of 22,801 images took 2.7, 3.5 and 4.7 s decoded (0.26–1.04 GiB
/// of values) against 18.6, 18.3 and 20.6 s from the factors (`benches/big_btf.sh`, its `use` step),
/// so the limit is set by memory: 2 GiB, which keeps a render's peak near 2.3 GB.
/// `BTFSYNTH_DECODE_LIMIT` (a size, as `BTFSYNTH_MEMORY`) overrides it for
/// [`Material::open`]: `0` keeps every factored sample as factors, `unlimited` decodes
/// every one that fits the memory budget.
pub const DECODE_LIMIT: u64 = 2 << 30;

/// The environment variable that overrides [`DECODE_LIMIT`].
pub const DECODE_LIMIT_ENV: &str = "BTFSYNTH_DECODE_LIMIT";

/// [`DECODE_LIMIT`], or [`DECODE_LIMIT_ENV`]'s value where it is set (`0` is allowed here:
/// never decode).
pub fn decode_limit() -> Result<u64> {
    match std::env::var(DECODE_LIMIT_ENV) {
        Err(_) => Ok(DECODE_LIMIT),
        Ok(text) if text.trim() == "0" => Ok(0),
        Ok(text) => {
            Ok(crate::btf::source::parse_size_env(DECODE_LIMIT_ENV, &text)?.map_or(u64::MAX, |(b, _)| b))
        }
    }
}

/// The material's values.
enum Texels {
    /// `[height][width][n][3]` linear RGB.
    Decoded(Vec<f32>),
    /// The factors; value offsets as in `Decoded`.
    Factors(Box<FactoredStack>),
}

impl Material {
    /// A material from images (`[n][height][width][3]` linear RGB) and their direction pairs.
    pub fn new(width: usize, height: usize, pixels: Vec<f32>, pairs: Vec<DirectionPair>) -> Result<Material> {
        if pairs.is_empty() || width == 0 || height == 0 || pixels.len() != pairs.len() * width * height * 3 {
            return Err(Error::invalid(format!(
                "material: {} values for {} images of {width}x{height}",
                pixels.len(),
                pairs.len()
            )));
        }
        Material::from_image_major(width, height, pairs, |i| pixels[i])
    }

    /// A material whose image-major value `i` (of `[n][height][width][3]`) is `value(i)`.
    fn from_image_major(
        width: usize,
        height: usize,
        pairs: Vec<DirectionPair>,
        value: impl Fn(usize) -> f32 + Sync,
    ) -> Result<Material> {
        let (n, plane) = (pairs.len(), width * height * 3);
        let pixels = (0..width * height)
            .into_par_iter()
            .flat_map_iter(|t| (0..n).flat_map(move |i| (0..3).map(move |c| (i, t, c))))
            .map(|(i, t, c)| value(i * plane + t * 3 + c))
            .collect();
        Material::with_texels(width, height, pairs, Texels::Decoded(pixels))
    }

    /// A material of these values: the direction indices and the pair table.
    fn with_texels(
        width: usize,
        height: usize,
        pairs: Vec<DirectionPair>,
        pixels: Texels,
    ) -> Result<Material> {
        let views = directions::distinct(pairs.iter().map(|p| p.view));
        let lights = directions::distinct(pairs.iter().map(|p| p.light));
        let mut image_of = vec![None; views.len() * lights.len()];
        for (i, pair) in pairs.iter().enumerate() {
            let v = views.iter().position(|d| d.same_as(&pair.view)).expect("distinct() kept it");
            let l = lights.iter().position(|d| d.same_as(&pair.light)).expect("distinct() kept it");
            image_of[v * lights.len() + l].get_or_insert(i as u32);
        }
        let index = |dirs: &[Direction]| DirectionIndex::new(dirs.iter().map(Direction::unit).collect());
        Ok(Material {
            width,
            height,
            pixels,
            views: index(&views),
            lights: index(&lights),
            pairs,
            image_of,
            tileable: false,
        })
    }

    /// The material of an analysis directory (`images.npy`, `directions.npy`, and whether
    /// it was analysed as tileable); a factored sample is decoded up to [`decode_limit`].
    pub fn open(analysis_dir: &Path) -> Result<Material> {
        Material::open_within(analysis_dir, decode_limit()?)
    }

    /// [`Material::open`], decoding a factored sample only if its values take at most
    /// `decode_limit` bytes.
    pub fn open_within(analysis_dir: &Path, decode_limit: u64) -> Result<Material> {
        let manifest = store::read_manifest(analysis_dir)?;
        if manifest.sample.is_some() && !analysis_dir.join("images.npy").exists() {
            let factors = store::read_factors(analysis_dir, &manifest)?;
            let mut material = Material::from_factors_within(factors, decode_limit)?;
            material.tileable = manifest.params.tileable;
            return Ok(material);
        }
        let images: npy::NpyArray<f16> = npy::read(&analysis_dir.join("images.npy"))?;
        let dirs: npy::NpyArray<f32> = npy::read(&analysis_dir.join("directions.npy"))?;
        let [n, h, w, 3] = images.shape[..] else {
            return Err(Error::format(analysis_dir.join("images.npy"), "expected shape [n, h, w, 3]"));
        };
        if dirs.shape != [n, 4] {
            return Err(Error::format(
                analysis_dir.join("directions.npy"),
                format!("shape {:?} does not match {n} images", dirs.shape),
            ));
        }
        let pairs = dirs
            .data
            .chunks_exact(4)
            .map(|d| {
                Ok(DirectionPair { light: Direction::new(d[0], d[1])?, view: Direction::new(d[2], d[3])? })
            })
            .collect::<Result<Vec<_>>>()
            .map_err(|e| Error::format(analysis_dir.join("directions.npy"), e.to_string()))?;
        if images.data.len() != n * h * w * 3 || n == 0 || w == 0 || h == 0 {
            return Err(Error::format(
                analysis_dir.join("images.npy"),
                "no images, or fewer values than its shape",
            ));
        }
        let mut material = Material::from_image_major(w, h, pairs, |i| images.data[i].to_f32())?;
        material.tileable = manifest.params.tileable;
        Ok(material)
    }

    /// The material of a factored sample: decoded texel-major when that takes at most
    /// [`DECODE_LIMIT`] bytes, else the factors themselves (see [`Material`]).
    pub fn from_factors(f: FactoredStack) -> Result<Material> {
        Material::from_factors_within(f, DECODE_LIMIT)
    }

    /// [`Material::from_factors`] with another limit on the decoded values' bytes.
    pub fn from_factors_within(f: FactoredStack, decode_limit: u64) -> Result<Material> {
        let (w, h, n) = (f.width(), f.height(), f.len());
        let decoded_bytes = (w * h * n * 3 * 4) as u64;
        // A raised limit never decodes beyond the memory budget: the factors always fit.
        let budget = crate::btf::source::memory_budget()?.map_or(u64::MAX, |(b, _)| b);
        if decoded_bytes > decode_limit.min(budget) {
            let pairs = f.pairs().to_vec();
            return Material::with_texels(w, h, pairs, Texels::Factors(Box::new(f)));
        }
        // A block of texels at a time: one product per channel gives every image's values.
        const BLOCK: usize = 256;
        let texels = w * h;
        let mut pixels = vec![0f32; texels * n * 3];
        pixels.par_chunks_mut(BLOCK * n * 3).enumerate().for_each(|(b, out)| {
            let range = b * BLOCK..b * BLOCK + out.len() / (n * 3);
            let values: Vec<ndarray::Array2<f32>> = (0..3)
                .map(|c| f.texel[c].slice(ndarray::s![range.clone(), ..]).dot(&f.image[c].t()))
                .collect();
            for (k, px) in out.chunks_exact_mut(3).enumerate() {
                let (t, i) = (k / n, k % n);
                let v = [values[0][[t, i]], values[1][[t, i]], values[2][[t, i]]];
                px.copy_from_slice(&crate::btf::factored::decode_channels(
                    f.model,
                    f.log_encoded,
                    f.scale[i],
                    v,
                ));
            }
        });
        Material::with_texels(w, h, f.pairs().to_vec(), Texels::Decoded(pixels))
    }

    /// Whether values are computed from factors on the fly (see [`Material`]).
    pub fn is_factored(&self) -> bool {
        matches!(self.pixels, Texels::Factors(_))
    }

    /// The factors values are computed from, if they are (see [`Material::is_factored`]).
    pub fn factors(&self) -> Option<&FactoredStack> {
        match &self.pixels {
            Texels::Factors(f) => Some(f),
            Texels::Decoded(_) => None,
        }
    }

    /// The material of a BTF stack as loaded (not tileable).
    pub fn from_btf(btf: &crate::btf::Btf) -> Result<Material> {
        let pixels = btf.pixels();
        Material::from_image_major(btf.width(), btf.height(), btf.pairs().to_vec(), |i| pixels[i].to_f32())
    }

    /// Opens an analysis directory (see [`Material::open`]) or, for any other path, loads a
    /// BTF stack (a stack directory, a `btf.json` or a single image).
    pub fn open_any(path: &Path, progress: &dyn crate::progress::Progress) -> Result<Material> {
        if path.join(store::MANIFEST).is_file() {
            return Material::open(path);
        }
        Material::from_btf(&crate::btf::load(path, &Default::default(), progress)?)
    }

    /// Sample width in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Sample height in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Number of images.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// True if there are no images (never, by construction).
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// The (light, view) pair of every image.
    pub fn pairs(&self) -> &[DirectionPair] {
        &self.pairs
    }

    /// Image `image`'s pixels, `[height][width][3]` linear RGB (a copy).
    pub fn image(&self, image: u32) -> Vec<f32> {
        let n = self.pairs.len();
        (0..self.width * self.height).flat_map(|t| self.at((t * n + image as usize) * 3).to_array()).collect()
    }

    /// The images to blend for a view and a light given in the local frame (x along s,
    /// y along t, z along n; unit vectors). A light at or below the horizon lights nothing.
    /// A sample with a single light direction is a texture photographed under that light,
    /// so it is scaled by n·l, the cosine a flat texture would receive.
    pub fn blend(&self, view: Vec3, light: Vec3) -> Blend16 {
        match self.light_weights(light) {
            Some(nl) => self.combine(&self.view_weights(view), &nl, light.z),
            None => Blend16::DARK,
        }
    }

    /// The 4 nearest sampled views of a local view direction, weighted. A camera that does
    /// not move can keep these per vertex while the light moves ([`Material::combine`]).
    pub fn view_weights(&self, view: Vec3) -> Nearest4 {
        self.views.nearest4(view)
    }

    /// The 4 nearest sampled lights of a local light direction, weighted; `None` at or
    /// below the horizon. Beyond the dome's largest θ the light blends the outermost ring
    /// ([`super::blend`]) and its weights are scaled by cos θ / cos θ_max: the outermost
    /// images already hold the cosine of their own θ, and a plane receives that much less
    /// light from further down. (A one-light sample is scaled by n·l instead.)
    pub fn light_weights(&self, light: Vec3) -> Option<Nearest4> {
        if light.z <= 0.0 {
            return None;
        }
        let mut nl = self.lights.nearest4(light);
        if self.lights.len() > 1 {
            let ratio = self.lights.beyond_cosine_ratio(light);
            nl.weight.iter_mut().for_each(|w| *w *= ratio);
        }
        Some(nl)
    }

    /// The sampled view directions.
    pub fn view_index(&self) -> &DirectionIndex {
        &self.views
    }

    /// The sampled light directions.
    pub fn light_index(&self) -> &DirectionIndex {
        &self.lights
    }

    /// The image taken under sampled view `view` and sampled light `light` (indices into
    /// [`Material::view_index`] and [`Material::light_index`]), if the stack has it.
    pub fn image_of(&self, view: u32, light: u32) -> Option<u32> {
        self.image_of[view as usize * self.lights.len() + light as usize]
    }

    /// RGB of texel (x, y) of image `image`, with wrapping or clamping of out-of-range
    /// texels as in the bilinear lookup.
    pub fn pixel(&self, image: u32, x: i64, y: i64) -> Vec3 {
        self.at(self.texel_block(x, y) + image as usize * 3)
    }

    /// Where texel (x, y)'s values start (wrapped or clamped into the sample).
    pub fn texel_block(&self, x: i64, y: i64) -> usize {
        (self.edge(y, self.height) * self.width + self.edge(x, self.width)) * self.pairs.len() * 3
    }

    /// The RGB at value offset `o` of the texel-major pixels (a texel block plus 3 × image).
    #[inline]
    pub fn at(&self, o: usize) -> Vec3 {
        match &self.pixels {
            Texels::Decoded(p) => Vec3::new(p[o], p[o + 1], p[o + 2]),
            Texels::Factors(f) => {
                let per_texel = self.pairs.len() * 3;
                Vec3::from_array(f.rgb(o % per_texel / 3, o / per_texel))
            }
        }
    }

    /// The 16 images of a view and a light selection; `cos_light` is the light's n·l,
    /// which scales a one-light sample (see [`Material::blend`]).
    pub fn combine(&self, nv: &Nearest4, nl: &Nearest4, cos_light: f32) -> Blend16 {
        let mut out = Blend16::DARK;
        let (mut k, mut present) = (0, 0.0);
        for a in 0..4 {
            for b in 0..4 {
                let w = nv.weight[a] * nl.weight[b];
                if w <= 0.0 {
                    continue;
                }
                if let Some(image) =
                    self.image_of[nv.index[a] as usize * self.lights.len() + nl.index[b] as usize]
                {
                    out.image[k] = image;
                    out.weight[k] = w;
                    present += w;
                    k += 1;
                }
            }
        }
        if present <= 0.0 {
            out = self.nearest_pair(nv, nl);
            present = 1.0;
        }
        // Beyond the dome the light weights sum to less than 1 (the cosine ratio): keep that.
        let attenuation = nl.weight.iter().sum::<f32>().min(1.0);
        let cosine = if self.lights.len() == 1 { cos_light.max(0.0) } else { attenuation };
        out.weight.iter_mut().for_each(|w| *w *= cosine / present);
        out
    }

    /// For a stack that is not a full view × light product: the image whose pair is
    /// nearest the best view and light (sum of angles).
    fn nearest_pair(&self, nv: &Nearest4, nl: &Nearest4) -> Blend16 {
        let (v, l) = (self.views.units()[nv.index[0] as usize], self.lights.units()[nl.index[0] as usize]);
        let cost = |p: &DirectionPair| {
            super::blend::angle(p.view.unit(), v) + super::blend::angle(p.light.unit(), l)
        };
        let best =
            (0..self.pairs.len()).min_by(|&a, &b| cost(&self.pairs[a]).total_cmp(&cost(&self.pairs[b])));
        let mut out = Blend16::DARK;
        out.image[0] = best.unwrap_or(0) as u32;
        out.weight[0] = 1.0;
        out
    }

    /// Bilinear RGB of image `image` at sample coordinate (u, v) in texels (integers are
    /// texel centres; u along columns, v along rows), wrapping or clamping at the edges.
    pub fn texel(&self, image: u32, u: f32, v: f32) -> Vec3 {
        self.filtered(image, &self.taps(u, v))
    }

    /// The four bilinear taps at (u, v): texel blocks and their weights (computed once and
    /// shared by the 16 images of a blend).
    fn taps(&self, u: f32, v: f32) -> [(usize, f32); 4] {
        let (x0, y0) = (u.floor(), v.floor());
        let (fx, fy) = (u - x0, v - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let at = |x: i64, y: i64| self.texel_block(x, y);
        [
            (at(x0, y0), (1.0 - fx) * (1.0 - fy)),
            (at(x0 + 1, y0), fx * (1.0 - fy)),
            (at(x0, y0 + 1), (1.0 - fx) * fy),
            (at(x0 + 1, y0 + 1), fx * fy),
        ]
    }

    fn filtered(&self, image: u32, taps: &[(usize, f32); 4]) -> Vec3 {
        let mut c = Vec3::ZERO;
        for &(block, weight) in taps {
            if weight != 0.0 {
                c += weight * self.at(block + image as usize * 3);
            }
        }
        c
    }

    fn edge(&self, i: i64, n: usize) -> usize {
        if self.tileable {
            i.rem_euclid(n as i64) as usize
        } else {
            i.clamp(0, n as i64 - 1) as usize
        }
    }

    /// The colour of a blend at texel (x, y) exactly (inside the sample): the vertex-mode
    /// lookup, without the bilinear weights.
    fn shade_texel(&self, blend: &Blend16, x: usize, y: usize) -> Vec3 {
        let block = (y * self.width + x) * self.pairs.len() * 3;
        let mut c = Vec3::ZERO;
        for k in 0..16 {
            if blend.weight[k] != 0.0 {
                c += blend.weight[k] * self.at(block + blend.image[k] as usize * 3);
            }
        }
        c
    }

    /// The texel (x, y) that (u, v) names exactly, if it is a texel centre inside the sample.
    fn texel_at(&self, u: f32, v: f32) -> Option<(usize, usize)> {
        let inside = u >= 0.0 && v >= 0.0 && u < self.width as f32 && v < self.height as f32;
        (inside && u.fract() == 0.0 && v.fract() == 0.0).then_some((u as usize, v as usize))
    }

    /// The colour of a blend at (u, v).
    pub fn shade(&self, blend: &Blend16, u: f32, v: f32) -> Vec3 {
        // Vertex coordinates are texel centres: one read per image instead of four taps.
        if let Some((x, y)) = self.texel_at(u, v) {
            return self.shade_texel(blend, x, y);
        }
        let taps = self.taps(u, v);
        let mut c = Vec3::ZERO;
        for k in 0..16 {
            if blend.weight[k] != 0.0 {
                c += blend.weight[k] * self.filtered(blend.image[k], &taps);
            }
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::DirectionSet;

    /// A 2×2 ubo81 material whose image i is the constant i + 1 (in every channel).
    fn indexed_material() -> Material {
        let pairs = DirectionSet::Ubo81.pairs();
        let pixels = (0..pairs.len()).flat_map(|i| std::iter::repeat_n((i + 1) as f32, 12)).collect();
        Material::new(2, 2, pixels, pairs).unwrap()
    }

    #[test]
    fn a_sampled_pair_returns_its_image_exactly() {
        let m = indexed_material();
        for (i, p) in m.pairs().iter().enumerate().step_by(37) {
            let b = m.blend(p.view.unit(), p.light.unit());
            let c = m.shade(&b, 0.5, 0.5);
            assert_eq!(c, Vec3::splat((i + 1) as f32), "pair {p}");
        }
    }

    #[test]
    fn weights_sum_to_one_where_lit_and_zero_where_not() {
        let m = indexed_material();
        for k in 0..300 {
            let t = k as f32 * 0.004;
            let view = Vec3::new(t.sin() * 0.3, 0.2, 1.0).normalize();
            let light = Vec3::new((3.0 * t).cos(), (3.0 * t).sin(), 0.2 + t).normalize();
            let b = m.blend(view, light);
            // Beyond the dome (θ > 75°) the weights sum to the cosine ratio.
            let expected = (light.z / 75f32.to_radians().cos()).min(1.0);
            assert!((b.weight.iter().sum::<f32>() - expected).abs() < 1e-5, "{light}");
        }
        assert_eq!(m.blend(Vec3::Z, Vec3::new(1.0, 0.0, -0.1).normalize()), Blend16::DARK);
    }

    #[test]
    fn the_blend_moves_continuously_with_the_light() {
        // Each image shows the index of its light: any jump in the light weights shows.
        let pairs = DirectionSet::Ubo81.pairs();
        let lights = directions::distinct(pairs.iter().map(|p| p.light));
        let value = |p: &DirectionPair| lights.iter().position(|l| l.same_as(&p.light)).unwrap() as f32;
        let pixels = pairs.iter().flat_map(|p| std::iter::repeat_n(value(p), 12)).collect();
        let m = Material::new(2, 2, pixels, pairs).unwrap();
        let view = Vec3::new(0.2, -0.1, 1.0).normalize();
        let worst_step = |steps: usize| {
            let colour = |k: usize| {
                let a = k as f32 / steps as f32 * std::f32::consts::TAU;
                let light = Vec3::new(a.cos() * 0.8, a.sin() * 0.8, 0.6).normalize();
                m.shade(&m.blend(view, light), 0.0, 0.0).x
            };
            (1..=steps).map(|k| (colour(k) - colour(k - 1)).abs()).fold(0.0, f32::max)
        };
        // Continuous: halving the step halves the largest change. A jump would not shrink.
        let (coarse, fine) = (worst_step(10_000), worst_step(20_000));
        assert!(fine < 0.6 * coarse, "largest step {coarse} at 10k steps, {fine} at 20k");
    }

    #[test]
    fn a_light_beyond_the_dome_is_never_brighter_than_the_outermost_ring() {
        let pairs = DirectionSet::Ubo81.pairs();
        let pixels = (0..pairs.len() * 12).map(|i| crate::seeded::unit(9, i as i64, 0, 0)).collect();
        let m = Material::new(2, 2, pixels, pairs).unwrap();
        let lights = m.light_index();
        for view_index in [0u32, 17, 52, 80] {
            let view = m.view_index().units()[view_index as usize];
            for k in 0..200 {
                let theta = (75.0 + 15.0 * crate::seeded::unit(10, k, 0, 0)).to_radians();
                let phi = crate::seeded::unit(10, k, 1, 0) * std::f32::consts::TAU;
                let light = Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
                let b = m.blend(view, light);
                for (u, v) in [(0.0, 0.0), (1.0, 0.0), (0.3, 0.8)] {
                    let c = m.shade(&b, u, v);
                    let brightest = lights
                        .rim()
                        .iter()
                        .map(|&l| m.texel(m.image_of(view_index, l).unwrap(), u, v))
                        .fold(Vec3::ZERO, Vec3::max);
                    assert!(c.cmple(brightest + 1e-6).all(), "light θ={theta}: {c} > {brightest}");
                }
            }
        }
    }

    #[test]
    fn one_image_material_is_its_texture_times_n_dot_l() {
        let pair = DirectionPair { light: Direction::NORMAL, view: Direction::NORMAL };
        let m = Material::new(1, 1, vec![0.5, 0.25, 1.0], vec![pair]).unwrap();
        let light = Vec3::new(0.6, 0.0, 0.8);
        let c = m.shade(&m.blend(Vec3::new(0.0, 0.3, 0.9).normalize(), light), 0.0, 0.0);
        assert!((c - Vec3::new(0.4, 0.2, 0.8)).length() < 1e-6);
    }

    /// A 5×4 ubo81 sample as factors (3 components, colour model 11, so the decoding is
    /// not linear) and the same sample decoded when opened.
    fn factored_pair() -> (Material, Material) {
        use crate::btf::colour::ColourModel;
        let pairs = DirectionSet::Ubo81.pairs();
        let n = pairs.len();
        let factor = |seed: u64, rows: usize| {
            ndarray::Array2::from_shape_fn((rows, 3), |(r, k)| {
                0.3 * crate::seeded::unit(seed, r as i64, k as i64, 0) - if k == 0 { 0.5 } else { 0.1 }
            })
        };
        let image = (0..3).map(|c| factor(20 + c, n)).collect();
        let texel = (0..3).map(|c| factor(30 + c, 20)).collect();
        let scale = (0..n).map(|i| 1.0 + (i % 3) as f32).collect();
        let f = FactoredStack::new(
            std::path::Path::new("t"),
            (5, 4),
            pairs,
            image,
            texel,
            ColourModel::LogYUvOverY,
            false,
            scale,
        )
        .unwrap();
        let on_the_fly =
            Material::with_texels(5, 4, f.pairs().to_vec(), Texels::Factors(Box::new(f.clone()))).unwrap();
        (Material::from_factors(f).unwrap(), on_the_fly)
    }

    #[test]
    fn a_factored_material_shades_as_its_decoded_values() {
        let (decoded, factored) = factored_pair();
        assert!(!decoded.is_factored() && factored.is_factored());
        for i in [0u32, 40, 80] {
            for (a, b) in decoded.image(i).iter().zip(factored.image(i)) {
                assert!((a - b).abs() <= 1e-5 * a.abs().max(1.0), "image {i}: {a} vs {b}");
            }
        }
        for k in 0..50 {
            let angle = |j| crate::seeded::unit(11, k, j, 0);
            let view = Vec3::new(0.5 * angle(0) - 0.25, 0.5 * angle(1) - 0.25, 1.0).normalize();
            let light = Vec3::new(angle(2) - 0.5, angle(3) - 0.5, 0.7).normalize();
            let (u, v) = (angle(4), angle(5));
            let (a, b) = (
                decoded.shade(&decoded.blend(view, light), u, v),
                factored.shade(&factored.blend(view, light), u, v),
            );
            assert!((a - b).length() <= 1e-5 * a.length().max(1.0), "{a} vs {b}");
            assert!(a.length() > 0.0);
        }
    }

    #[test]
    fn bilinear_lookup_wraps_or_clamps() {
        let pair = DirectionPair { light: Direction::NORMAL, view: Direction::NORMAL };
        let pixels = vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
        let mut m = Material::new(2, 1, pixels, vec![pair]).unwrap();
        assert_eq!(m.texel(0, 0.25, 0.0).x, 0.25);
        assert_eq!(m.texel(0, 1.5, 0.0).x, 1.0);
        m.tileable = true;
        assert_eq!(m.texel(0, 1.5, 0.0).x, 0.5);
        assert_eq!(m.texel(0, -1.0, 0.0).x, 1.0);
    }
}
