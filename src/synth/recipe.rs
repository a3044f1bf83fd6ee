//! Presets as data: a [`Preset`] is a recipe naming, per level, how the level starts and
//! which passes run over it, and per pass every part the engine is built from (visiting
//! order, neighbourhood stencil and mask, parent neighbourhood, candidate source, metric,
//! selection).
//! `synth` records the whole recipe in its outputs, so a result says how it was made.

use super::candidates::Search;
use super::round::RoundStencil;
use super::sample::{AppearanceMap, SampleLevel};
use crate::{Error, Result};

/// The circles a mesh level is marched for under [`Stencil::Isotropic`]: its two rings.
pub const ISOTROPIC_MARCHED: RoundStencil = RoundStencil { circles: 2 };

/// The neighbourhood distance a pass matches with.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum MetricKind {
    /// Surface textons through Γ (Tong §5.1).
    Gamma,
    /// Appearance vectors by SSD (Lefebvre and Hoppe 2006); needs an analysis that stores
    /// them. For a photograph they are its colour neighbourhoods reduced by PCA, the
    /// nearest the engine has to Turk's colour SSD.
    Appearance,
    /// Turk's colour SSD: the sample's linear RGB per texel, compared by plain SSD. For a
    /// BTF, the mean of the analysis' selected images; every level's colours are that mean
    /// taken down the analysis' own pyramid, centred and scaled to unit variance like the
    /// appearance vectors (so that levels weigh alike in two-level distances). Built only
    /// when a recipe uses it ([`super::Sample::load_colours`]).
    Colour,
    /// Chen and Dong 2008 §5: round neighbourhoods of appearance vectors compared by the
    /// adaptive metric ([`super::adaptive`], [`super::round_pass`]). Such a pass ignores
    /// the parent neighbourhood field (the linked pixels enter through the inherited
    /// texels' candidates); choosy selection and the coherence bias weigh its distances.
    Adaptive,
}

/// How a level's map starts before its passes.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Start {
    /// Every vertex a random texel (Tong §5.1, Turk §5.2).
    Random,
    /// Random coherent patches of this radius, as a fraction of the coarsest sample level's
    /// smaller side, and at least the template's radius + 1 texels (see
    /// `start::patch_state`).
    Patches {
        /// Patch radius as a fraction of the coarsest sample level's smaller side.
        radius: f32,
    },
    /// Each vertex twice its parent's coordinate plus its offset (Tong §5.1, first pass);
    /// only below the coarsest level.
    Inherit,
}

/// The most circles a round neighbourhood may have: the sample's appearance maps keep a
/// border of [`AppearanceMap::PAD`] texels, and the round resampling reads one texel beyond
/// the outer circle (bilinear), so `circles + 1` must fit in it.
pub const MAX_CIRCLES: usize = AppearanceMap::PAD - 1;

/// The shape of a pass's own-level neighbourhood: which offsets around a vertex it reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Stencil {
    /// The square template of Tong, Turk and Wei–Levoy: `SynthParams::neighborhood` texels a
    /// side (default 7), every offset weighted alike. The pass's [`Mask`] shapes it: `Full` the
    /// whole square, `Visited` the causal part, `Half` Turk's half square, `Off` none of it.
    /// Matched by the `Gamma`, `Appearance` and `Colour` metrics. A recipe that names no
    /// stencil (one recorded before the field existed) means this one.
    #[default]
    Square,
    /// Chen and Dong's round neighbourhood (2008 §4): the centre and `circles` concentric
    /// circles one texel apart (circle c holds 8c points), grown circle by circle by the
    /// `Adaptive` metric, which alone matches it. Chen and Dong use 3 (the 7×7 square's
    /// reach); 1 to [`MAX_CIRCLES`], and each candidate keeps a border of `circles + 1`
    /// texels, which the coarsest sample level in use must hold unless it tiles.
    Round {
        /// Concentric circles around the centre, one texel apart.
        circles: usize,
    },
    /// Castellanos and Williams' isotropic neighbourhood (§3.12, [`super::isotropic`]): 12
    /// points one texel from the vertex and 24 two texels away, centre excluded, weighted
    /// by proximity (Eq. 7), and compared with the sample's neighbourhood turned by 0°, 60°
    /// and 120°, the least distance counting. Matched by the `Colour` and `Appearance`
    /// metrics, on one level (no parent neighbourhood); mesh levels are marched for it as
    /// for round neighbourhoods of 2 circles.
    Isotropic,
}

/// Order in which a pass visits the vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum VisitOrder {
    /// A fresh seeded permutation every pass.
    Random,
    /// Vertex index order (scanline order on a plane).
    Sequential,
    /// Increasing sweep distance along the texture direction (Turk §4.2, [`super::sweep`]).
    Sweep,
    /// The unvisited vertex with the most visited neighbours next (Chen and Dong §6,
    /// [`super::constrained`]).
    MostConstrained,
    /// Order-independent (Lefebvre and Hoppe 2005): sub-passes, one per colour of a
    /// colouring in which no vertex reads another of its colour, each matched in parallel
    /// ([`super::pass::run_interleaved_pass`]). The same result at any thread count. A level
    /// whose colouring needs more than [`super::pass::MAX_COLOURS`] colours is visited in a
    /// seeded random order instead.
    Interleaved,
}

/// How a vertex picks among its candidates.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Select {
    /// The smallest distance (Tong §5.1).
    Argmin,
    /// Choosy sampling (Castellanos and Williams §3.11, adapted): the distance is multiplied
    /// by 1 + strength · excess², excess being how far beyond its fair share (output
    /// vertices over candidate texels) the texel is already used on this level. Exact matches
    /// (distance 0) keep winning, so coherent copies are untouched; among inexact ones, the
    /// texels the level leans on too often lose, which keeps the first-order statistics.
    Choosy {
        /// How hard overused texels are penalised (0 is argmin).
        strength: f32,
    },
    /// Castellanos and Williams' choosy sampling as written (§3.11, Algorithm 2): the
    /// distance is multiplied by `base`^(c_j − c_min), c_j being how many times texel j was
    /// chosen so far in this pass (every visit's choice counts, kept or not) and c_min the
    /// least count over the level's candidate texels. The paper's base is 2: a soft
    /// sampling without replacement, so the output's colour histogram follows the sample's.
    UsePenalty {
        /// The penalty's base per choice beyond the least-used candidate (the paper's 2).
        base: f32,
    },
}

/// Which of the level's own template pixels a pass compares.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Mask {
    /// Every pixel: Turk's full square F(n, 0), Tong's template.
    Full,
    /// Only pixels of vertices already visited in this pass (Wei and Levoy's causal
    /// neighbourhood on any visiting order).
    Visited,
    /// Turk's half square H(n, 0): only the columns upstream of the vertex along the
    /// texture direction (template x < 0), the side a sweep has already coloured; forward
    /// shifts are taken from those columns too.
    Half,
    /// None of them: the pass matches on the parent neighbourhood alone (Turk's
    /// extrapolating F(n, 1)).
    Off,
}

/// The coarser level's neighbourhood joining a pass's distance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ParentNeighbourhood {
    /// No parent neighbourhood.
    None,
    /// The narrow parent template (`parent_size(n)`: 3 for n = 7), matched with two-level
    /// kNN lists: Tong's two-level neighbourhood, Turk's F(3, 1).
    Narrow,
    /// The parent vertex's own full-size template on the coarser level: Turk's F(n, 1).
    Wide,
}

/// Where a pass's candidates come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Candidates {
    /// The search given to synthesis (`SynthParams::search`: k-coherence by default, or full).
    Search,
    /// Every candidate texel, whatever the search given.
    Full,
}

/// One pass over a level.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pass {
    /// Visiting order.
    pub order: VisitOrder,
    /// The own-level neighbourhood's shape: square or round.
    #[serde(default)]
    pub stencil: Stencil,
    /// Which own-level template pixels are compared.
    pub mask: Mask,
    /// Whether and how the coarser level's neighbourhood joins the distance.
    pub parent: ParentNeighbourhood,
    /// Where candidates come from.
    pub candidates: Candidates,
    /// The neighbourhood distance.
    pub metric: MetricKind,
    /// How a vertex picks among its candidates.
    pub select: Select,
    /// Preference for continuing a copy over starting a new one (see
    /// [`super::engine::PassPlan::coherence_bias`]).
    pub coherence_bias: f32,
}

/// How one level is synthesized: its start, then its passes in order.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LevelRecipe {
    /// How the level's map starts.
    pub start: Start,
    /// The passes over the level, in order (at least one).
    pub passes: Vec<Pass>,
}

/// A named recipe: the coarsest level's, then the one every finer level follows.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Preset {
    /// The name [`Preset::by_name`] knows it by (for a recipe read from a file, whatever it says).
    pub name: String,
    /// The paper the preset follows, for listing the presets.
    pub paper: String,
    /// The coarsest level (its start may not be [`Start::Inherit`]).
    pub coarsest: LevelRecipe,
    /// Every finer level.
    pub finer: LevelRecipe,
}

impl Preset {
    /// The default: Tong's engine matched on appearance vectors, from random patches, with
    /// a preference for continuing copies and choosy selection. Every departure from the paper
    /// is measured on eleven 128² photographs → 512² against Embark's texture-synthesis
    /// (docs/quality.md).
    pub fn appearance() -> Self {
        Self::tong_schedule(
            "appearance",
            "Tong et al. 2002, matched on appearance vectors (Lefebvre and Hoppe 2006)",
            MetricKind::Appearance,
        )
    }

    /// Tong et al. 2002: distances through Γ; every finer level inherits from the coarser
    /// one and is refined with two-level neighbourhoods and lists. The coarsest level starts
    /// from random patches rather than the paper's random texels (see [`Start::Patches`]).
    pub fn tong2002() -> Self {
        Self::tong_schedule(
            "tong2002",
            "Tong, Zhang, Liu, Wang, Guo and Shum, SIGGRAPH 2002",
            MetricKind::Gamma,
        )
    }

    /// Tong's schedule with `metric`: random patches and four full passes on the coarsest
    /// level; inheritance and two two-level passes on every finer one; interleaved
    /// (order-independent, parallel) visiting, choosy selection and a coherence bias
    /// throughout.
    ///
    /// Tong visits vertices one after the other in random order; the interleaved sub-passes
    /// of Lefebvre and Hoppe run each sub-pass on every core and give the same bytes at any
    /// thread count. Measured on 128² crops of stone33 and pebbles → 512², seeds 0–1: patch
    /// energy, colour χ² and repetition within ±0.001 of the random order's (stone33
    /// repetition 0.025/0.022 against 0.026/0.023), synthesis 1.8× faster on 2 cores.
    ///
    /// The patches' radius is 0.15 of the coarsest level's side. At 0.35 (before) each
    /// patch, inherited up the pyramid, copied ~80% of the sample, so every distinctive
    /// feature recurred once per patch on a near-regular lattice: `eval`'s repetition 0.087
    /// on stone33 (128² → 512²) against Resynthesizer's 0.030; at 0.15 (with varied seed
    /// spacing) 0.020–0.027 over seeds 0–3, at the cost of 30% more patch energy (0.0020 →
    /// 0.0026, Embark 0.0029). A sample that holds a single element (one tile) loses whole
    /// elements at this size; a recipe with a larger radius keeps them
    /// (docs/quality.md).
    fn tong_schedule(name: &'static str, paper: &'static str, metric: MetricKind) -> Self {
        let pass = |parent| Pass {
            order: VisitOrder::Interleaved,
            stencil: Stencil::Square,
            mask: Mask::Full,
            parent,
            candidates: Candidates::Search,
            metric,
            select: Select::Choosy { strength: 0.3 },
            coherence_bias: 0.5,
        };
        Preset {
            name: name.into(),
            paper: paper.into(),
            coarsest: LevelRecipe {
                start: Start::Patches { radius: 0.15 },
                passes: vec![pass(ParentNeighbourhood::None); 4],
            },
            finer: LevelRecipe { start: Start::Inherit, passes: vec![pass(ParentNeighbourhood::Narrow); 2] },
        }
    }

    /// Turk 2001 §5.2: the coarsest level from random texels, one half-square H(n, 0)
    /// pass in sweep order for the initial pattern; every finer level extrapolated with
    /// F(n, 1) and refined with F(n, 0) + F(3, 1), all in sweep order. Departures (docs/synthesis.md):
    /// appearance vectors for colours, the search given (k-coherence by default; the full
    /// search is the paper's), and choosy selection with a coherence bias.
    pub fn turk2001() -> Self {
        let pass = |mask, parent| Pass {
            order: VisitOrder::Sweep,
            stencil: Stencil::Square,
            mask,
            parent,
            candidates: Candidates::Search,
            metric: MetricKind::Appearance,
            select: Select::Choosy { strength: 0.3 },
            coherence_bias: 0.5,
        };
        Preset {
            name: "turk2001".into(),
            paper: "Turk, Texture Synthesis on Surfaces, SIGGRAPH 2001".into(),
            coarsest: LevelRecipe {
                start: Start::Random,
                passes: vec![pass(Mask::Half, ParentNeighbourhood::None)],
            },
            finer: LevelRecipe {
                start: Start::Inherit,
                passes: vec![
                    pass(Mask::Off, ParentNeighbourhood::Wide),
                    pass(Mask::Full, ParentNeighbourhood::Narrow),
                ],
            },
        }
    }

    /// Chen and Dong 2008 (§4–6): every level matched by the adaptive metric on round
    /// neighbourhoods of three circles, in most-constrained-first order. The coarsest
    /// level is synthesized from nothing (only coloured vertices compared, candidates from
    /// those vertices' k-coherence), then refined once; every finer level inherits its
    /// parent's texels (the linked pixels) and is refined from the candidates around them.
    pub fn chen2008() -> Self {
        let pass = |mask| Pass {
            order: VisitOrder::MostConstrained,
            stencil: Stencil::Round { circles: 3 },
            mask,
            parent: ParentNeighbourhood::None,
            candidates: Candidates::Search,
            metric: MetricKind::Adaptive,
            select: Select::Choosy { strength: 0.3 },
            coherence_bias: 0.5,
        };
        Preset {
            name: "chen2008".into(),
            paper: "Chen and Dong, Adaptive Surface Texture Synthesis Using Round-Shaped Neighbourhoods, CGF 2008".into(),
            coarsest: LevelRecipe { start: Start::Random, passes: vec![pass(Mask::Visited), pass(Mask::Full)] },
            finer: LevelRecipe { start: Start::Inherit, passes: vec![pass(Mask::Full)] },
        }
    }

    /// Castellanos and Williams (§3.2, §3.11–3.13, Algorithm 1–2): the coarsest level from
    /// random texels, then every level refined by choosy sampling as the paper writes it
    /// ([`Select::UsePenalty`], base 2), visiting in a fresh random order each iteration and
    /// matching colour neighbourhoods of a single level (no parent neighbourhood). Every
    /// finer level starts from its parent's chosen texels and their children, the
    /// coordinate form of copying the four Laplacian children (Algorithm 2) and adding them
    /// to the projected coarser level.
    ///
    /// The neighbourhood is the paper's isotropic one ([`Stencil::Isotropic`]): two rings of
    /// 12 and 24 points, proximity weights and the least distance over three 60° turns of
    /// the sample's neighbourhood, so a striped sample gives an isotropic result.
    ///
    /// Departures (docs/castellanos.md): the stencil's points on circles of the rings' mean
    /// radii, resampled from the square sample grid, in place of the triangular grid's
    /// faces; the exhaustive search on the coarsest level only, k-coherence candidates (which
    /// follow each neighbour's turn) on the finer ones (the paper's exhaustive search there
    /// needs its kd-trees, §6); the
    /// inversion's blend across seams is not formed (a vertex starts from its inherited
    /// texel's colour, not from the projected colours of its neighbours' parents); and a
    /// coherence bias of 1, which the paper has not: without it 1.02% of adjacent pairs copy
    /// one texel (horizontal streaks on stone33, 96² → 192²), with it 0.25%, and patch
    /// energy falls from 0.0101 to 0.0084 for a colour χ² of 0.0028 against 0.0026.
    pub fn castellanos() -> Self {
        let pass = |candidates| Pass {
            order: VisitOrder::Random,
            stencil: Stencil::Isotropic,
            mask: Mask::Full,
            parent: ParentNeighbourhood::None,
            candidates,
            metric: MetricKind::Colour,
            select: Select::UsePenalty { base: 2.0 },
            coherence_bias: 1.0,
        };
        Preset {
            name: "castellanos".into(),
            paper: "Castellanos and Williams, Automatic Synthesis of Isotropic Textures on Surfaces from Sample Images".into(),
            coarsest: LevelRecipe { start: Start::Random, passes: vec![pass(Candidates::Full); 4] },
            finer: LevelRecipe { start: Start::Inherit, passes: vec![pass(Candidates::Search); 2] },
        }
    }

    /// Whether any pass matches round neighbourhoods (which need a marching on meshes).
    pub fn rounds(&self) -> bool {
        self.round_stencil().is_some()
    }

    /// The circles the recipe's round and isotropic passes share (a mesh level is marched
    /// for them once, and each sample level resampled once), or none without such passes.
    /// [`Self::validate`] refuses passes that disagree; here the first one's is taken.
    pub fn round_stencil(&self) -> Option<RoundStencil> {
        self.all_passes().find_map(|p| p.stencil.marching())
    }

    /// Every pass of the recipe, the coarsest level's first.
    pub fn all_passes(&self) -> impl Iterator<Item = &Pass> {
        self.coarsest.passes.iter().chain(&self.finer.passes)
    }

    /// Every pass of the recipe, for editing.
    pub fn all_passes_mut(&mut self) -> impl Iterator<Item = &mut Pass> {
        self.coarsest.passes.iter_mut().chain(&mut self.finer.passes)
    }

    /// Refuses a search the recipe cannot run well: adaptive passes take their candidates
    /// around the linked texels (k-coherence), as Chen and Dong do; a full search there
    /// smeared 1.2% of stone33's adjacent pairs onto one texel at 60× the time (docs/synthesis.md;
    /// measured before the adaptive passes had the coherence bias).
    pub fn check_search(&self, search: Search) -> Result<()> {
        let adaptive_full = self
            .all_passes()
            .any(|p| p.metric == MetricKind::Adaptive && pass_search(p, search) == Search::Full);
        if adaptive_full {
            return Err(Error::IncompatibleSearch { preset: self.name.clone() });
        }
        Ok(())
    }

    /// Every preset, the default first.
    pub fn all() -> Vec<Self> {
        vec![Self::appearance(), Self::tong2002(), Self::turk2001(), Self::chen2008(), Self::castellanos()]
    }

    /// Presets by name ([`Preset::name`]).
    pub fn by_name(name: &str) -> Result<Self> {
        Self::all().into_iter().find(|p| p.name == name).ok_or_else(|| {
            let names: Vec<String> = Self::all().into_iter().map(|p| p.name).collect();
            Error::invalid(format!("unknown preset '{name}': available: {}", names.join(", ")))
        })
    }

    /// Every pass the recipe runs on `levels` levels.
    pub fn pass_count(&self, levels: usize) -> usize {
        self.coarsest.passes.len() + levels.saturating_sub(1) * self.finer.passes.len()
    }

    /// Whether any pass visits in sweep order (which needs sweep distances).
    pub fn sweeps(&self) -> bool {
        self.all_passes().any(|p| p.order == VisitOrder::Sweep)
    }

    /// Whether any pass matches with `metric`.
    pub fn uses(&self, metric: MetricKind) -> bool {
        self.all_passes().any(|p| p.metric == metric)
    }

    /// A recipe from JSON in the form [`Self::to_json`] writes (the `recipe` object `synth`
    /// records), checked with [`Self::validate`].
    pub fn from_json(text: &str) -> Result<Self> {
        let preset: Preset = serde_json::from_str(text).map_err(|e| Error::invalid(e.to_string()))?;
        preset.validate()?;
        Ok(preset)
    }

    /// Refuses a recipe the engine cannot run as written: a coarsest level that inherits
    /// (it has no parent), a level without passes, a parent neighbourhood on the coarsest
    /// level, a pass that compares nothing (mask off without a parent neighbourhood), a
    /// stencil its metric does not match, round passes that disagree on their circles, and
    /// numbers out of range.
    pub fn validate(&self) -> Result<()> {
        let refuse = |what: String| Err(Error::invalid(format!("recipe '{}': {what}", self.name)));
        if self.coarsest.start == Start::Inherit {
            return refuse("the coarsest level cannot inherit (it has no coarser level)".into());
        }
        for (level, recipe) in [("coarsest", &self.coarsest), ("finer", &self.finer)] {
            if recipe.passes.is_empty() {
                return refuse(format!("the {level} level has no passes (give at least one)"));
            }
            if let Start::Patches { radius } = recipe.start {
                if !(radius.is_finite() && radius > 0.0) {
                    return refuse(format!(
                        "the {level} level's patch radius must be positive, not {radius}"
                    ));
                }
            }
            if matches!(recipe.start, Start::Patches { .. })
                && recipe.passes[0].metric == MetricKind::Adaptive
            {
                return refuse(format!(
                    "the {level} level's patches are seamed by its first pass, which must match square templates, not Adaptive"
                ));
            }
            for (i, pass) in recipe.passes.iter().enumerate() {
                pass_problem(pass, level == "coarsest")
                    .map_or(Ok(()), |why| refuse(format!("{level} pass {i}: {why}")))?;
            }
        }
        let isotropic = self.all_passes().any(|p| p.stencil == Stencil::Isotropic);
        let other = self.all_passes().filter_map(|p| p.stencil.round()).find(|&r| r != ISOTROPIC_MARCHED);
        if let (true, Some(round)) = (isotropic, other) {
            return refuse(format!(
                "Isotropic passes march 2 circles, so Round passes beside them must have 2, not {}",
                round.circles
            ));
        }
        let mut rounds = self.all_passes().filter_map(|p| p.stencil.round());
        if let Some(first) = rounds.next() {
            if let Some(other) = rounds.find(|&r| r != first) {
                return refuse(format!(
                    "every Round pass must have the same circles (a level's round neighbourhoods are built once for all its passes), not {} and {}",
                    first.circles, other.circles
                ));
            }
        }
        Ok(())
    }

    /// Refuses a recipe whose metrics need what `levels` (finest first) lack: appearance
    /// vectors (analyses written before they existed), colours (not loaded with
    /// [`super::Sample::load_colours`]), or a coarsest level that holds no whole round
    /// neighbourhood.
    pub fn check_sample(&self, levels: &[SampleLevel]) -> Result<()> {
        let needs_appearance = self.uses(MetricKind::Appearance) || self.uses(MetricKind::Adaptive);
        if needs_appearance && levels.iter().any(|l| l.appearance.is_none()) {
            return Err(Error::unavailable(
                format!(
                    "preset '{}' matches appearance vectors, which this analysis lacks (written by an older btfsynth)",
                    self.name
                ),
                crate::Remedy::Reanalyze,
            ));
        }
        if let (Some(round), Some(coarsest)) = (self.round_stencil(), levels.last()) {
            round_fits(round, coarsest)
                .map_or(Ok(()), |why| Err(Error::invalid(format!("recipe '{}': {why}", self.name))))?;
        }
        if self.uses(MetricKind::Colour) && levels.iter().any(|l| l.colour.is_none()) {
            return Err(Error::invalid(format!(
                "recipe '{}' matches colours, which Sample::load_colours builds",
                self.name
            )));
        }
        Ok(())
    }

    /// The whole recipe as JSON, for the outputs. Numbers are written as their f32 reads
    /// (0.3, not `to_value`'s widened 0.30000001192092896), so that a recipe copied out for
    /// editing reads as it was written.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_string(self)
            .and_then(|text| serde_json::from_str(&text))
            .unwrap_or(serde_json::Value::Null)
    }
}

impl Stencil {
    /// The round neighbourhood, for a round stencil.
    pub fn round(&self) -> Option<RoundStencil> {
        match *self {
            Stencil::Round { circles } => Some(RoundStencil { circles }),
            Stencil::Square | Stencil::Isotropic => None,
        }
    }

    /// The circles a mesh level is marched for: a round stencil's, or the isotropic
    /// stencil's two.
    pub fn marching(&self) -> Option<RoundStencil> {
        match *self {
            Stencil::Isotropic => Some(ISOTROPIC_MARCHED),
            _ => self.round(),
        }
    }
}

/// Why `sample` (the coarsest level in use) cannot serve round neighbourhoods of `round`, if
/// it cannot: a candidate texel keeps `circles + 1` texels of border on every side (the
/// resampling reads one beyond the outer circle), so a level that does not tile needs
/// `2 (circles + 1) + 1` texels on its smaller side, or no texel is a whole candidate.
fn round_fits(round: RoundStencil, sample: &SampleLevel) -> Option<String> {
    let side = sample.width.min(sample.height);
    let need = 2 * (round.circles + 1) + 1;
    if sample.tileable || side >= need {
        return None;
    }
    let fit = (side.saturating_sub(1) / 2).saturating_sub(1);
    let advice = if fit == 0 {
        "use fewer levels".to_string()
    } else {
        format!("use at most {fit} circles or fewer levels")
    };
    Some(format!(
        "round neighbourhoods of {} circles need {need}x{need} texels around each candidate, but the coarsest sample level in use is {}x{}: {advice}",
        round.circles, sample.width, sample.height
    ))
}

/// Why the engine cannot run `pass` as written, if it cannot.
fn pass_problem(pass: &Pass, coarsest: bool) -> Option<String> {
    if coarsest && pass.parent != ParentNeighbourhood::None {
        return Some("the coarsest level has no parent neighbourhood (parent must be None)".into());
    }
    if pass.mask == Mask::Off && pass.parent == ParentNeighbourhood::None {
        return Some("mask Off compares nothing without a parent neighbourhood".into());
    }
    match (pass.metric, pass.stencil) {
        (MetricKind::Adaptive, Stencil::Square) => {
            return Some("the Adaptive metric matches round neighbourhoods (stencil {\"Round\": {\"circles\": 3}}), not Square".into())
        }
        (MetricKind::Adaptive, Stencil::Round { circles }) if !(1..=MAX_CIRCLES).contains(&circles) => {
            return Some(format!(
                "a Round stencil has 1 to {MAX_CIRCLES} circles (the sample's border holds circles + 1 texels), not {circles}"
            ))
        }
        (MetricKind::Adaptive | MetricKind::Gamma, Stencil::Isotropic) => {
            return Some(format!(
                "the isotropic stencil compares colours or appearance vectors (metric Colour or Appearance), not {:?}",
                pass.metric
            ))
        }
        (_, Stencil::Isotropic) if pass.parent != ParentNeighbourhood::None => {
            return Some("an Isotropic pass matches one level (parent must be None)".into())
        }
        (_, Stencil::Isotropic) if !matches!(pass.mask, Mask::Visited | Mask::Full) => {
            return Some(
                "an Isotropic pass compares visited vertices or all of them (mask Visited or Full)".into(),
            )
        }
        (metric, Stencil::Round { .. }) if metric != MetricKind::Adaptive => {
            return Some(format!(
                "the {metric:?} metric matches square templates (stencil Square); round neighbourhoods need the Adaptive metric"
            ))
        }
        _ => {}
    }
    if pass.metric == MetricKind::Adaptive && !matches!(pass.mask, Mask::Visited | Mask::Full) {
        return Some(
            "an Adaptive pass compares visited vertices or all of them (mask Visited or Full)".into(),
        );
    }
    if let Select::Choosy { strength } = pass.select {
        if !(strength.is_finite() && strength >= 0.0) {
            return Some(format!("the Choosy strength must be at least 0, not {strength}"));
        }
    }
    if let Select::UsePenalty { base } = pass.select {
        if !(base.is_finite() && base >= 1.0) {
            return Some(format!("the UsePenalty base must be at least 1, not {base}"));
        }
    }
    if !(pass.coherence_bias.is_finite() && pass.coherence_bias >= 0.0) {
        return Some(format!("coherence_bias must be at least 0, not {}", pass.coherence_bias));
    }
    None
}

/// The candidate search of a pass, given the one asked of `synth`.
pub(crate) fn pass_search(pass: &Pass, asked: Search) -> Search {
    match pass.candidates {
        Candidates::Search => asked,
        Candidates::Full => Search::Full,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recipes_serialize_whole() {
        let json = Preset::turk2001().to_json();
        assert_eq!(json["name"], "turk2001");
        assert_eq!(json["coarsest"]["start"], "Random");
        assert_eq!(json["coarsest"]["passes"][0]["mask"], "Half");
        assert_eq!(json["finer"]["passes"][0]["parent"], "Wide");
        assert_eq!(json["finer"]["passes"][1]["order"], "Sweep");
        assert_eq!(Preset::appearance().to_json()["finer"]["passes"].as_array().unwrap().len(), 2);
        assert_eq!(json["finer"]["passes"][1]["select"]["Choosy"]["strength"], 0.3);
        let chen = Preset::chen2008().to_json();
        assert_eq!(chen["coarsest"]["passes"][0]["metric"], "Adaptive");
        assert_eq!(chen["coarsest"]["passes"][0]["mask"], "Visited");
        assert_eq!(chen["finer"]["passes"][0]["order"], "MostConstrained");
        assert!(Preset::chen2008().rounds() && !Preset::turk2001().rounds());
        assert_eq!(chen["finer"]["passes"][0]["stencil"]["Round"]["circles"], 3);
        assert_eq!(json["finer"]["passes"][1]["stencil"], "Square");
    }

    /// Every preset names its stencil: round for Chen and Dong's adaptive metric, square for
    /// the others; the recipe's round stencil is the one its round passes share.
    #[test]
    fn every_preset_matches_its_metric_on_its_stencil() {
        for p in Preset::all() {
            for pass in p.all_passes() {
                let round = pass.stencil.round().is_some();
                assert_eq!(round, pass.metric == MetricKind::Adaptive, "{}: {pass:?}", p.name);
            }
        }
        assert_eq!(Preset::chen2008().round_stencil(), Some(RoundStencil { circles: 3 }));
        assert_eq!(Preset::appearance().round_stencil(), None);
        let mut two = Preset::chen2008();
        two.all_passes_mut().for_each(|pass| pass.stencil = Stencil::Round { circles: 2 });
        assert_eq!(
            Preset::from_json(&two.to_json().to_string()).unwrap().round_stencil().unwrap().circles,
            2
        );
    }

    /// A stencil its metric does not match, circles out of range and round passes that
    /// disagree are refused, each with a message that says which.
    #[test]
    fn stencils_the_engine_cannot_run_are_refused() {
        let edited = |edit: &dyn Fn(&mut Preset)| {
            let mut p = Preset::chen2008();
            edit(&mut p);
            Preset::from_json(&p.to_json().to_string())
        };
        let refused = |edit: &dyn Fn(&mut Preset), needle: &str| {
            let e = edited(edit).expect_err(needle).to_string();
            assert!(e.contains(needle), "{e}");
        };
        refused(
            &|p| p.finer.passes[0].stencil = Stencil::Square,
            "finer pass 0: the Adaptive metric matches round",
        );
        refused(
            &|p| p.finer.passes[0].metric = MetricKind::Appearance,
            "the Appearance metric matches square templates",
        );
        refused(&|p| p.finer.passes[0].stencil = Stencil::Round { circles: 0 }, "not 0");
        let past = MAX_CIRCLES + 1;
        refused(&|p| p.finer.passes[0].stencil = Stencil::Round { circles: past }, &format!("not {past}"));
        refused(&|p| p.finer.passes[0].stencil = Stencil::Round { circles: 4 }, "not 3 and 4");
        let all = |circles| {
            move |p: &mut Preset| p.all_passes_mut().for_each(|q| q.stencil = Stencil::Round { circles })
        };
        assert!(edited(&all(1)).is_ok() && edited(&all(MAX_CIRCLES)).is_ok());
        let mut square = Preset::turk2001();
        square.finer.passes[1].stencil = Stencil::Round { circles: 3 };
        let e = Preset::from_json(&square.to_json().to_string()).unwrap_err().to_string();
        assert!(e.contains("finer pass 1: the Appearance metric matches square templates"), "{e}");
        // Serde names a misspelt field inside the stencil.
        let mut json = Preset::chen2008().to_json();
        json["finer"]["passes"][0]["stencil"] = serde_json::json!({"Round": {"circle": 3}});
        let e = Preset::from_json(&json.to_string()).unwrap_err().to_string();
        assert!(e.contains("circle"), "{e}");
    }

    /// The isotropic stencil runs with colours or appearance vectors on one level, beside
    /// round passes only of its own 2 circles; castellanos records it, and a recipe
    /// recorded before it (no stencil field) still reads, as the square template.
    #[test]
    fn isotropic_passes_the_engine_cannot_run_are_refused() {
        let refused = |edit: &dyn Fn(&mut Preset), needle: &str| {
            let mut p = Preset::castellanos();
            edit(&mut p);
            let e = Preset::from_json(&p.to_json().to_string()).expect_err(needle).to_string();
            assert!(e.contains(needle), "{e}");
        };
        refused(&|p| p.finer.passes[0].metric = MetricKind::Gamma, "not Gamma");
        refused(&|p| p.finer.passes[0].parent = ParentNeighbourhood::Narrow, "parent must be None");
        refused(&|p| p.finer.passes[0].mask = Mask::Half, "mask Visited or Full");
        let round = |circles| {
            move |p: &mut Preset| {
                p.finer.passes[1] = Pass {
                    stencil: Stencil::Round { circles },
                    metric: MetricKind::Adaptive,
                    ..p.finer.passes[1]
                }
            }
        };
        refused(&round(3), "must have 2, not 3");
        let mut mixed = Preset::castellanos();
        round(2)(&mut mixed);
        assert!(Preset::from_json(&mixed.to_json().to_string()).is_ok());
        let json = Preset::castellanos().to_json();
        assert_eq!(json["finer"]["passes"][0]["stencil"], "Isotropic");
        assert_eq!(Preset::castellanos().round_stencil(), Some(ISOTROPIC_MARCHED));
        let mut old = json.clone();
        for level in ["coarsest", "finer"] {
            old[level]["passes"].as_array_mut().unwrap().iter_mut().for_each(|p| {
                p.as_object_mut().unwrap().remove("stencil");
            });
        }
        let read = Preset::from_json(&old.to_string()).unwrap();
        assert!(read.all_passes().all(|p| p.stencil == Stencil::Square));
    }

    /// A candidate keeps circles + 1 texels of border: a 16² level that does not tile holds
    /// round neighbourhoods of up to 6 circles (15² texels), a tiling one any.
    #[test]
    fn round_neighbourhoods_must_fit_the_coarsest_level() {
        let mut sample = crate::synth::engine::tests::periodic_sample(4);
        sample.tileable = false;
        assert_eq!(round_fits(RoundStencil { circles: 6 }, &sample), None);
        let e = round_fits(RoundStencil { circles: 7 }, &sample).unwrap();
        assert!(e.contains("17x17") && e.contains("16x16") && e.contains("at most 6 circles"), "{e}");
        sample.tileable = true;
        assert_eq!(round_fits(RoundStencil { circles: 7 }, &sample), None);
    }

    #[test]
    fn names_are_unique_and_found() {
        let all = Preset::all();
        for p in &all {
            assert_eq!(Preset::by_name(&p.name).unwrap(), *p);
            assert_eq!(all.iter().filter(|q| q.name == p.name).count(), 1);
            assert_ne!(p.coarsest.start, Start::Inherit, "{}: the coarsest level has no parent", p.name);
        }
        assert!(Preset::by_name("nope").is_err());
        assert!(Preset::chen2008().check_search(Search::Full).is_err());
        assert!(Preset::chen2008().check_search(Search::KCoherence { k: 4 }).is_ok());
        assert!(Preset::turk2001().check_search(Search::Full).is_ok());
    }

    #[test]
    fn every_preset_reads_back_from_its_recorded_json() {
        for p in Preset::all() {
            let text = serde_json::to_string_pretty(&p.to_json()).unwrap();
            assert_eq!(Preset::from_json(&text).unwrap(), p, "{text}");
        }
    }

    /// A recipe the engine cannot run is refused with a message that says what is wrong.
    #[test]
    fn recipes_the_engine_cannot_run_are_refused() {
        let refused = |edit: &dyn Fn(&mut Preset), needle: &str| {
            let mut p = Preset::appearance();
            edit(&mut p);
            let text = p.to_json().to_string();
            let e = Preset::from_json(&text).expect_err(needle).to_string();
            assert!(e.contains(needle), "{e}");
        };
        refused(&|p| p.coarsest.start = Start::Inherit, "coarsest level cannot inherit");
        refused(&|p| p.finer.passes.clear(), "finer level has no passes");
        refused(&|p| p.coarsest.passes.clear(), "coarsest level has no passes");
        refused(&|p| p.coarsest.passes[1].parent = ParentNeighbourhood::Wide, "coarsest pass 1");
        refused(
            &|p| {
                p.finer.passes[0] =
                    Pass { mask: Mask::Off, parent: ParentNeighbourhood::None, ..p.finer.passes[0] }
            },
            "mask Off compares nothing",
        );
        refused(&|p| p.finer.passes[1].coherence_bias = -1.0, "coherence_bias");
        refused(&|p| p.finer.passes[1].select = Select::Choosy { strength: -0.5 }, "strength");
        refused(&|p| p.finer.passes[1].select = Select::UsePenalty { base: 0.5 }, "base");
        refused(&|p| p.coarsest.start = Start::Patches { radius: 0.0 }, "patch radius");
    }

    /// Bad JSON is refused with serde's message, which names the field.
    #[test]
    fn malformed_recipes_name_the_field() {
        let mut json = Preset::tong2002().to_json();
        json["finer"]["passes"][0]["metric"] = "Colour".into();
        assert_eq!(Preset::from_json(&json.to_string()).unwrap().finer.passes[0].metric, MetricKind::Colour);
        json["finer"]["passes"][0]["metric"] = "Colr".into();
        let e = Preset::from_json(&json.to_string()).unwrap_err().to_string();
        assert!(e.contains("Colr") && e.contains("Colour"), "{e}");
        json["finer"]["passes"][0]["metric"] = "Colour".into();
        json["finer"]["passes"][0]["masks"] = "Full".into();
        let e = Preset::from_json(&json.to_string()).unwrap_err().to_string();
        assert!(e.contains("masks"), "{e}");
        json["finer"]["passes"][0].as_object_mut().unwrap().remove("masks");
        json["finer"]["passes"][0].as_object_mut().unwrap().remove("order");
        let e = Preset::from_json(&json.to_string()).unwrap_err().to_string();
        assert!(e.contains("missing field `order`"), "{e}");
    }
}
