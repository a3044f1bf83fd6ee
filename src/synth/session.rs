//! The per-vertex engine's front door: a synthesis set up and checked before any work.
//!
//! [`SynthSessionBuilder`]'s setters each say their default; [`SynthSessionBuilder::build`]
//! checks every choice against the analysis it will run on (its manifest: levels, k, level
//! sizes) and against the preset, into typed errors, so that a synthesis started from the
//! session fails on no parameter. The session holds the engine's [`SynthParams`] and
//! records its own provenance for the outputs.
//!
//! ```
//! use btfsynth::analysis::pipeline::{analyze, AnalysisParams};
//! use btfsynth::btf::{self, gen::{GenParams, MaterialKind}, DirectionSet};
//! use btfsynth::progress::Silent;
//! use btfsynth::synth::{plane::synthesize_plane, session::SynthSessionBuilder, Preset, Sample};
//!
//! let params = GenParams { size: 24, samples_per_pixel: 1, directions: DirectionSet::Grid(2), ..GenParams::default() };
//! let stack = btf::gen::generate(MaterialKind::Pebbles, &params, &Silent)?;
//! let analysis = analyze(&stack, &AnalysisParams { textons: 32, levels: 2, ..AnalysisParams::default() }, &Silent)?;
//! let sample = Sample::from_analysis(&analysis, &stack, 2)?;
//! // Three levels of a two-level analysis: refused before any work.
//! assert!(SynthSessionBuilder::new().levels(3).build(&sample.manifest).is_err());
//! let session = SynthSessionBuilder::new().preset(Preset::tong2002()).seed(3).build(&sample.manifest)?;
//! session.check_sample(&sample)?;
//! let plane = synthesize_plane(&sample, (32, 32), false, session.params(), &Silent)?;
//! assert_eq!(plane.state.uv.len(), 32 * 32);
//! assert_eq!(session.provenance()["seed"], 3);
//! # Ok::<(), btfsynth::Error>(())
//! ```

use super::sample::AppearanceMap;
use super::{Device, Preset, Search, SynthParams};
use crate::analysis::store::Manifest;
use crate::error::{Param, Remedy};
use crate::{Error, Result};

/// How candidates are found, before the analysis' `k` is known.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SearchChoice {
    /// k-coherence (Tong §5.2) with the analysis' `k`, or the one set.
    #[default]
    KCoherence,
    /// Every texel of the level (slow; the papers' exhaustive search).
    Full,
}

/// The choices of a synthesis, unchecked (see the [module documentation](self)).
#[derive(Clone, Debug)]
pub struct SynthSessionBuilder {
    preset: Preset,
    search: SearchChoice,
    k: Option<usize>,
    levels: Option<usize>,
    surface: bool,
    neighbourhood: usize,
    seed: u64,
    device: Device,
}

impl Default for SynthSessionBuilder {
    fn default() -> Self {
        let defaults = SynthParams::default();
        SynthSessionBuilder {
            preset: defaults.preset,
            search: SearchChoice::KCoherence,
            k: None,
            levels: None,
            surface: false,
            neighbourhood: defaults.neighborhood,
            seed: defaults.seed,
            device: defaults.device,
        }
    }
}

impl SynthSessionBuilder {
    /// The defaults below.
    pub fn new() -> Self {
        Self::default()
    }

    /// The recipe the engine runs. Default: [`Preset::appearance`].
    pub fn preset(mut self, preset: Preset) -> Self {
        self.preset = preset;
        self
    }

    /// How candidates are found. Default: [`SearchChoice::KCoherence`].
    pub fn search(mut self, search: SearchChoice) -> Self {
        self.search = search;
        self
    }

    /// Candidates per neighbour for k-coherence, 1 to the analysis' own `k`. Default: the
    /// analysis' `k`.
    pub fn k(mut self, k: usize) -> Self {
        self.k = Some(k);
        self
    }

    /// Pyramid levels used, finest first, 1 to the analysis' levels. Default: on a plane, as
    /// many as keep the coarsest level in use at least [`coarsest_side_for`] texels a side
    /// ([`default_levels`]); on a surface, see [`default_surface_levels`].
    pub fn levels(mut self, levels: usize) -> Self {
        self.levels = Some(levels);
        self
    }

    /// Whether the synthesis covers a mesh rather than a plane (only the default levels
    /// differ, [`default_surface_levels`]). Default: a plane.
    pub fn surface(mut self, surface: bool) -> Self {
        self.surface = surface;
        self
    }

    /// Side of the square neighbourhood template in texels (odd). Default: 7.
    pub fn neighbourhood(mut self, side: usize) -> Self {
        self.neighbourhood = side;
        self
    }

    /// Seed of every random choice; equal seeds give equal results at any thread count.
    /// Default: 0.
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// Where the passes run: [`Device::Auto`] (default) uses a hardware GPU where there is
    /// one, [`Device::Gpu`] any GPU (failing where wgpu finds none), [`Device::Cpu`] the
    /// CPU. The result is the same on either; only the time differs.
    pub fn device(mut self, device: Device) -> Self {
        self.device = device;
        self
    }

    /// Checks every choice against the analysis described by `manifest` and the preset:
    /// the levels exist, `k` is within the analysis' lists, the coarsest level in use holds
    /// a whole neighbourhood, and the preset can run the search.
    pub fn build(self, manifest: &Manifest) -> Result<SynthSession> {
        let available = manifest.levels.len();
        let levels = self.levels.unwrap_or_else(|| match self.surface {
            true => default_surface_levels(&self.preset, manifest, self.neighbourhood),
            false => default_levels(manifest, self.neighbourhood),
        });
        if !(1..=available).contains(&levels) {
            let message = format!("the analysis has {available} level(s)");
            return Err(Error::out_of_range(Param::Levels, levels, message));
        }
        let k = self.k.unwrap_or(manifest.k);
        if !(1..=manifest.k).contains(&k) {
            let message = format!("must be between 1 and the analysis' k = {}", manifest.k);
            return Err(Error::out_of_range(Param::K, k, message));
        }
        check_neighbourhood(self.neighbourhood, manifest, levels)?;
        let search = match self.search {
            SearchChoice::KCoherence => Search::KCoherence { k },
            SearchChoice::Full => Search::Full,
        };
        self.preset.check_search(search)?;
        let params = SynthParams {
            preset: self.preset,
            search,
            neighborhood: self.neighbourhood,
            seed: self.seed,
            device: self.device,
        };
        Ok(SynthSession { params, choice: self.search, k, levels })
    }
}

/// The least side (texels) of the coarsest sample level the default synthesis starts on,
/// for an `n`×`n` neighbourhood: a band of candidate texels (the side less the `n` − 1
/// texels whose neighbourhood would leave the sample) that holds three of the smallest
/// patches (radius (n + 1)/2, see [`super::Start::Patches`]) a side, 4n + 2 texels (30 for
/// the default 7×7).
///
/// Why: the coarsest level's patches are copied up the whole pyramid. On a coarsest level
/// whose band holds fewer, every patch is most of the band, so the output is a lattice of
/// near-whole copies of the sample at the band's period (a 64² sample's third level is 16²:
/// a band of 10 texels against patches of 8). Halving stops early instead: a 64² sample
/// starts at 32², a 50² one at 25² ([`second_level_side_for`]).
pub fn coarsest_side_for(n: usize) -> usize {
    4 * n + 2
}

/// The least side of a second level that a sample too small for [`coarsest_side_for`]
/// still starts on: a band that holds two of the smallest patches a side, 3n + 1 texels (22
/// for the default 7×7).
///
/// Why: on one level nothing larger than the template is matched, and elements larger
/// than it come out cut into fragments: a 50² chocolate swirl's 25-texel swirls became a
/// mush of pieces (patch energy 0.0021–0.0022, Embark's 0.0012), a 64×56 pine board's
/// knots faint. Its 25² second level keeps them whole (patch energy 0.0014–0.0017) at
/// repetition 0.016–0.022, still at or below Resynthesizer's 0.022 and Embark's 0.033
/// (seeds 0–3, 4× the side; leaves at 50²: 0.027–0.043 against both peers' 0.047). A
/// third level at this size was measured and is not taken: on a 96² wood and a 100² stone
/// (two levels already) it raised repetition above Resynthesizer's (0.031–0.049 against
/// 0.029, 0.018–0.026 against 0.024).
pub fn second_level_side_for(n: usize) -> usize {
    3 * n + 1
}

/// The levels a synthesis uses by default: the most (up to the analysis') whose coarsest
/// level is at least [`coarsest_side_for`] the neighbourhood `n` a side, or two where only
/// one is and the second is at least [`second_level_side_for`] `n`; at least one.
pub fn default_levels(manifest: &Manifest, n: usize) -> usize {
    let side = |l: usize| manifest.levels[l - 1].width.min(manifest.levels[l - 1].height);
    let available = manifest.levels.len();
    match (1..=available).rev().find(|&l| side(l) >= coarsest_side_for(n)).unwrap_or(1) {
        1 if available >= 2 && side(2) >= second_level_side_for(n) => 2,
        levels => levels,
    }
}

/// The levels a synthesis on a surface uses by default: one for a recipe whose coarsest level
/// starts from patches (as every preset but the papers' random starts does), else
/// [`default_levels`].
///
/// Why: a mesh's templates are its vertices resampled onto a grid, each template pixel
/// the nearest vertex's (vertices sit up to half a texel off the grid their coordinates
/// assume), so a copy never matches its own source exactly, while the sample's calm places
/// match jittered templates about as well as exact ones: every pass drifts a little toward
/// calm places, and every coarser level adds a rounded inheritance and two more passes.
/// The patches carry the sample's structure whole; on one level, the passes only mend their
/// seams. Measured (docs/surfaces.md), exported textures at 256 texels across the bunny, the
/// default recipe on three levels → one: smeared windows 13.2% → 7.1% and contrast 0.65 →
/// 0.85 of the sample's on a 144² cracked stone, 5.7% → 4.4% and 0.79 → 0.86 on a 256² tile
/// photo, 6.1% → 4.6% and 0.96 → 1.01 on walnut, 4.2% → 3.7% and 0.90 → 0.88 on marble.
/// A random start has no structure to keep and needs the coarser levels to build it.
pub fn default_surface_levels(preset: &Preset, manifest: &Manifest, n: usize) -> usize {
    match preset.coarsest.start {
        super::Start::Patches { .. } => 1,
        _ => default_levels(manifest, n),
    }
}

/// The widest neighbourhood a synthesis takes: what the appearance maps' border holds.
pub const MAX_NEIGHBOURHOOD: usize = 2 * AppearanceMap::PAD + 1;

/// Refuses a neighbourhood that is even, narrower than 3 or wider than
/// [`MAX_NEIGHBOURHOOD`], or larger than the coarsest level in use: no sample texel there
/// would have a whole neighbourhood to copy.
fn check_neighbourhood(n: usize, manifest: &Manifest, levels: usize) -> Result<()> {
    if n % 2 == 0 || !(3..=MAX_NEIGHBOURHOOD).contains(&n) {
        let message = format!("must be odd, from 3 to {MAX_NEIGHBOURHOOD}");
        return Err(Error::out_of_range(Param::Neighbourhood, n, message));
    }
    let Some(coarsest) = manifest.levels.get(levels - 1) else { return Ok(()) };
    let side = coarsest.width.min(coarsest.height);
    if n <= side {
        return Ok(());
    }
    let fit = if side % 2 == 1 { side } else { side.saturating_sub(1) };
    Err(Error::OutOfRange {
        param: Param::Neighbourhood,
        value: n.to_string(),
        message: format!(
            "the analysis' coarsest level in use (level {}) is {}x{} texels, which hold no whole \
             {n}x{n} neighbourhood (at most {fit}x{fit})",
            levels - 1,
            coarsest.width,
            coarsest.height
        ),
        remedy: (levels > 1).then(|| Remedy::FewerLevels(levels - 1)),
    })
}

/// A checked synthesis: the engine's parameters and the levels to use.
#[derive(Clone, Debug)]
pub struct SynthSession {
    params: SynthParams,
    choice: SearchChoice,
    k: usize,
    levels: usize,
}

impl SynthSession {
    /// What the engine runs with.
    pub fn params(&self) -> &SynthParams {
        &self.params
    }

    /// Pyramid levels to use (open the sample with as many).
    pub fn levels(&self) -> usize {
        self.levels
    }

    /// Refuses a sample whose levels lack what the preset's metrics need (see
    /// [`Preset::check_sample`]).
    pub fn check_sample(&self, sample: &super::Sample) -> Result<()> {
        self.params.preset.check_sample(&sample.levels)
    }

    /// The provenance the outputs record: preset and whole recipe, search, k, levels,
    /// neighbourhood and seed (no timings, so equal inputs give equal bytes).
    pub fn provenance(&self) -> serde_json::Value {
        let search = match self.choice {
            SearchChoice::KCoherence => "kcoherence",
            SearchChoice::Full => "full",
        };
        serde_json::json!({
            "preset": self.params.preset.name, "recipe": self.params.preset.to_json(), "search": search,
            "k": self.k, "levels": self.levels, "neighborhood": self.params.neighborhood, "seed": self.params.seed,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::pipeline::{analyze, AnalysisParams};
    use crate::btf::{gen, DirectionSet};
    use crate::progress::Silent;

    fn manifest() -> Manifest {
        let params = gen::GenParams {
            size: 24,
            samples_per_pixel: 1,
            directions: DirectionSet::Grid(2),
            ..Default::default()
        };
        let stack = gen::generate(gen::MaterialKind::Pebbles, &params, &Silent).unwrap();
        let analysis = analyze(
            &stack,
            &AnalysisParams { textons: 16, levels: 2, k: 5, ..AnalysisParams::default() },
            &Silent,
        )
        .unwrap();
        super::super::Sample::from_analysis(&analysis, &stack, 2).unwrap().manifest
    }

    /// Each refusal names its parameter; a good session takes the analysis' k and the levels
    /// whose coarsest is large enough for the neighbourhood.
    #[test]
    fn a_session_refuses_what_the_analysis_or_the_preset_cannot_run() {
        let m = manifest();
        let param = |b: SynthSessionBuilder| match b.build(&m) {
            Err(Error::OutOfRange { param, .. }) => Some(param),
            _ => None,
        };
        assert_eq!(param(SynthSessionBuilder::new().levels(3)), Some(Param::Levels));
        assert_eq!(param(SynthSessionBuilder::new().levels(0)), Some(Param::Levels));
        assert_eq!(param(SynthSessionBuilder::new().k(6)), Some(Param::K));
        assert_eq!(param(SynthSessionBuilder::new().neighbourhood(13).levels(2)), Some(Param::Neighbourhood));
        for n in [0, 1, 4, 65] {
            assert_eq!(param(SynthSessionBuilder::new().neighbourhood(n)), Some(Param::Neighbourhood), "{n}");
        }
        let chen = SynthSessionBuilder::new().preset(Preset::chen2008()).search(SearchChoice::Full).build(&m);
        assert!(matches!(chen, Err(Error::IncompatibleSearch { .. })), "{chen:?}");
        // 24² has a 12² second level, under the 22² a 5² neighbourhood wants: one level.
        let session = SynthSessionBuilder::new().build(&m).unwrap();
        assert_eq!((session.levels(), session.params().search), (1, Search::KCoherence { k: 5 }));
        assert_eq!(SynthSessionBuilder::new().levels(2).build(&m).unwrap().levels(), 2);
        assert_eq!(session.provenance()["search"], "kcoherence");
    }

    /// A plane's default keeps its coarsest level at least 4n + 2 texels a side (30 for
    /// 7×7), and takes a second level of at least 3n + 1 (22) rather than run on one.
    #[test]
    fn a_plane_s_coarsest_level_holds_three_patches_or_two_on_a_second_level() {
        let mut m = manifest();
        m.levels.push(m.levels[1].clone());
        for (sides, levels) in [
            ([256, 128, 64], 3),
            ([128, 64, 32], 3),
            ([96, 48, 24], 2),
            ([64, 32, 16], 2),
            ([50, 25, 12], 2),
            ([44, 22, 11], 2),
            ([42, 21, 10], 1),
        ] {
            for (level, side) in m.levels.iter_mut().zip(sides) {
                (level.width, level.height) = (side, side);
            }
            assert_eq!(default_levels(&m, 7), levels, "{sides:?}");
        }
        m.levels.truncate(1);
        assert_eq!(default_levels(&m, 7), 1, "one level analysed");
    }

    /// On a surface a recipe that starts from patches runs one level by default, one that
    /// starts from random texels the plane's levels; a level count given is kept.
    #[test]
    fn a_surface_starts_from_patches_on_one_level_and_from_random_texels_on_the_planes() {
        let mut m = manifest();
        for (level, side) in m.levels.iter_mut().zip([128, 64]) {
            (level.width, level.height) = (side, side);
        }
        let levels = |b: SynthSessionBuilder| b.build(&m).unwrap().levels();
        for preset in Preset::all() {
            let patches = matches!(preset.coarsest.start, super::super::Start::Patches { .. });
            let with = || SynthSessionBuilder::new().preset(preset.clone());
            assert_eq!(levels(with()), 2, "{} on a plane", preset.name);
            assert_eq!(
                levels(with().surface(true)),
                if patches { 1 } else { 2 },
                "{} on a surface",
                preset.name
            );
            assert_eq!(levels(with().surface(true).levels(2)), 2, "{} given 2 levels", preset.name);
        }
        assert!(Preset::all()
            .iter()
            .any(|p| matches!(p.coarsest.start, super::super::Start::Patches { .. })));
    }
}
