//! Presets as data: a [`Preset`] is a recipe naming, per level, how the level starts and
//! which passes run over it, and per pass every part the engine is built from (visiting
//! order, neighbourhood and its metric ([`super::neighbourhood`]), candidate source,
//! selection). A pass the engine cannot combine cannot be built; JSON recipes keep the flat
//! form of earlier versions and are checked as they are read.
//! `synth` records the whole recipe in its outputs, so a result says how it was made.

use super::candidates::Search;
use super::neighbourhood::{
    Compared, Mask, MetricKind, Neighbourhood, OwnPixels, ParentNeighbourhood, ParentTemplate, PointMetric,
    SquareMetric, SquareTemplate, Stencil, ISOTROPIC_MARCHED, MAX_CIRCLES,
};
use super::round::RoundStencil;
use super::sample::SampleLevel;
use crate::{Error, Param, Result};

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
        /// The radius on a mesh, where it differs (none: `radius`). A mesh's passes mend
        /// seams less well than a plane's (its templates jitter by up to half a texel), so
        /// fewer, larger patches keep more of the sample whole there.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        surface_radius: Option<f32>,
    },
    /// Each vertex twice its parent's coordinate plus its offset (Tong §5.1, first pass);
    /// only below the coarsest level.
    Inherit,
    /// [`Start::Inherit`], then each vertex's coordinate moved by a seeded random offset
    /// (Lefebvre and Hoppe 2005 §3.2, jittered upsampling): per axis `floor(texels · u +
    /// ½)`, u uniform in [−1, 1), so `texels` of ½ or less moves nothing and 1 moves a vertex
    /// by at most one texel. The offsets are a function of the seed, level and vertex, so
    /// they do not depend on the thread count. Inherited copies continue exactly; jitter
    /// breaks them into pieces that the level's passes then join up again differently,
    /// which varies what a coarse copy becomes at the finer levels. Only below the
    /// coarsest level.
    Jittered {
        /// Jitter amplitude in texels of the level's sample (0 to [`MAX_JITTER`]).
        texels: f32,
    },
}

/// The largest [`Start::Jittered`] amplitude: beyond a few texels a vertex lands in an
/// unrelated part of the sample and the inherited structure is gone.
pub const MAX_JITTER: f32 = 4.0;

/// The most passes one level of a recipe may run: every preset runs at most 4, and each
/// pass costs as much as the first (10,000 coarsest passes took 32 s and 322 MB).
pub const MAX_PASSES: usize = 64;

impl Start {
    /// Whether the level starts from the coarser level's map ([`Start::Inherit`] or
    /// [`Start::Jittered`]).
    pub fn inherits(self) -> bool {
        matches!(self, Start::Inherit | Start::Jittered { .. })
    }
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

/// Where a pass's candidates come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Candidates {
    /// The search given to synthesis (`SynthParams::search`: k-coherence by default, or full).
    Search,
    /// Every candidate texel, whatever the search given.
    Full,
    /// Every candidate texel, found through Castellanos and Williams' dynamic kd-trees
    /// (§6): the eigenvector transform keeps 20 components of each sample neighbourhood
    /// (once per turn), and one tree per use count lets choosy sampling's penalty be
    /// searched tree by tree. The choice is at most 1 + ε times [`Candidates::Full`]'s
    /// (ε-approximate: the transformed distance bounds the full one from below), 6.8×
    /// faster on a 128² level. Only
    /// for isotropic passes under [`Select::UsePenalty`] or [`Select::Argmin`], visited in
    /// a sequential order ([`super::kdtrees`], [`Search::KdTrees`]).
    KdTrees,
}

/// One pass over a level. Its neighbourhood holds only combinations the engine runs; in a
/// recipe it is written as the flat fields of a [`PassRecord`], checked when read.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "PassRecord", into = "PassRecord")]
pub struct Pass {
    /// Visiting order.
    pub order: VisitOrder,
    /// What the pass compares, and by which distance.
    pub neighbourhood: Neighbourhood,
    /// Where candidates come from.
    pub candidates: Candidates,
    /// How a vertex picks among its candidates.
    pub select: Select,
    /// Preference for continuing a copy over starting a new one (see
    /// [`super::engine::PassPlan::coherence_bias`]).
    pub coherence_bias: f32,
}

/// A pass as a recipe writes it: the neighbourhood as four flat parts, as recipes have
/// always been recorded (one recorded before `stencil` existed means the square template).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PassRecord {
    /// Visiting order.
    pub order: VisitOrder,
    /// The own-level neighbourhood's shape.
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
    /// Preference for continuing a copy over starting a new one.
    pub coherence_bias: f32,
}

impl TryFrom<PassRecord> for Pass {
    type Error = String;

    fn try_from(r: PassRecord) -> std::result::Result<Self, String> {
        let neighbourhood = Neighbourhood::from_parts(r.stencil, r.mask, r.parent, r.metric)?;
        let pass = Pass {
            order: r.order,
            neighbourhood,
            candidates: r.candidates,
            select: r.select,
            coherence_bias: r.coherence_bias,
        };
        pass.value_problem().map_or(Ok(pass), Err)
    }
}

impl From<Pass> for PassRecord {
    fn from(p: Pass) -> Self {
        let (stencil, mask, parent, metric) = p.neighbourhood.parts();
        PassRecord {
            order: p.order,
            stencil,
            mask,
            parent,
            candidates: p.candidates,
            metric,
            select: p.select,
            coherence_bias: p.coherence_bias,
        }
    }
}

impl Pass {
    /// This pass with its flat record edited by `edit`, or why the edited one cannot run:
    /// the way to change one part (say the metric) and keep the others.
    pub fn edited(self, edit: impl FnOnce(&mut PassRecord)) -> std::result::Result<Self, String> {
        let mut record = PassRecord::from(self);
        edit(&mut record);
        Pass::try_from(record)
    }

    /// The distance the pass matches with.
    pub fn metric(&self) -> MetricKind {
        self.neighbourhood.metric()
    }

    /// Why a number of the pass is out of range, if one is.
    fn value_problem(&self) -> Option<String> {
        if let Neighbourhood::Round { circles, .. } = self.neighbourhood {
            if !(1..=MAX_CIRCLES).contains(&circles) {
                return Some(format!("a Round stencil has 1 to {MAX_CIRCLES} circles, not {circles}"));
            }
        }
        match self.select {
            Select::Choosy { strength } if !(strength.is_finite() && strength >= 0.0) => {
                return Some(format!("the Choosy strength must be at least 0, not {strength}"))
            }
            Select::UsePenalty { base } if !(base.is_finite() && base >= 1.0) => {
                return Some(format!("the UsePenalty base must be at least 1, not {base}"))
            }
            _ => {}
        }
        if !(self.coherence_bias.is_finite() && self.coherence_bias >= 0.0) {
            return Some(format!("coherence_bias must be at least 0, not {}", self.coherence_bias));
        }
        self.kd_trees_problem()
    }

    /// Why the pass cannot search kd-trees, if it asks to: the trees hold isotropic
    /// neighbourhoods, group texels by one use count (which Choosy's fair share, counting
    /// the vertex's own texel apart, does not), and follow each choice as it is made.
    fn kd_trees_problem(&self) -> Option<String> {
        if self.candidates != Candidates::KdTrees {
            return None;
        }
        if self.neighbourhood.stencil() != Stencil::Isotropic {
            return Some("KdTrees candidates need the Isotropic stencil".into());
        }
        if matches!(self.select, Select::Choosy { .. }) {
            return Some("KdTrees candidates need the UsePenalty or Argmin select, not Choosy".into());
        }
        if self.order == VisitOrder::Interleaved {
            return Some("KdTrees candidates need a sequential order, not Interleaved".into());
        }
        None
    }
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

/// A named recipe: the coarsest level's, then the one every finer level follows. Read from
/// JSON it is checked whole ([`Preset::validate`]), each refused pass named by its level and
/// index.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "PresetRecord")]
pub struct Preset {
    /// The name [`Preset::by_name`] knows it by (for a recipe read from a file, whatever it says).
    pub name: String,
    /// The paper the preset follows, for listing the presets.
    pub paper: String,
    /// The coarsest level (its start may not inherit, [`Start::inherits`]).
    pub coarsest: LevelRecipe,
    /// Every finer level.
    pub finer: LevelRecipe,
    /// Whether the coarsest level's patches keep their interiors through every level's
    /// passes (none: every vertex chooses freely).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub keep_interiors: Option<KeepInteriors>,
    /// On a mesh, each level runs only its first this many passes (none: all of them, as on
    /// a plane).
    ///
    /// Why: a mesh's passes mend its patches' seams less well than a plane's (its templates
    /// jitter by up to half a texel), and past the first two they barely move its figures
    /// while costing half of a 250k-vertex surface's synthesis stage (about 3 s): on
    /// `bunny-1k8` and `cow` at 256 texels across, eleven photograph-and-mesh cases, the
    /// exported texture with 2 passes against 4 had smears 0–0.006 lower on every case,
    /// contrast the same or higher, detail 0.01–0.15 higher (choc swirl 2.44 → 2.59, its
    /// seams alike in Blender); the 250k surface 14.0 s → 11.2 s (docs/surfaces.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface_passes: Option<usize>,
}

/// A cost on leaving a copy, deep inside the patches the coarsest level starts from: there a
/// vertex's distance to any texel but its current one is multiplied by `move_cost`, so it
/// moves only where the move is that much better; near a patch's edge it moves freely, so
/// that the passes still mend the seams.
///
/// Why (docs/surfaces.md, "What eroded a mesh's copies"): on a mesh, vertices inside a copy
/// take other copies' continuations over the passes, so calm copies grow into detailed ones
/// and the result smears. A cost on every move stops that but leaves small patches' seams
/// unmended; the neighbours' predictions cannot tell a copy's inside from its seam on a mesh
/// (offsets summed along the surface are off by a texel here and there), but the start knows
/// each vertex's patch. Only square-template passes (the ones [`super::pass::run_pass`]
/// runs) apply it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeepInteriors {
    /// How far along the surface from its patch's edge a vertex counts as inside, in radii of
    /// the level's template (so at 1 an inside vertex's template lies about wholly in its
    /// own copy, where it matches its own texel exactly and a move is no repair).
    pub depth: f32,
    /// The factor on an inside vertex's distance to any other texel (at least 1).
    pub move_cost: f32,
}

/// A preset as JSON holds it, its passes still flat records.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct PresetRecord {
    name: String,
    paper: String,
    coarsest: LevelRecord,
    finer: LevelRecord,
    #[serde(default)]
    keep_interiors: Option<KeepInteriors>,
    #[serde(default)]
    surface_passes: Option<usize>,
}

/// A level as JSON holds it.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct LevelRecord {
    start: Start,
    passes: Vec<PassRecord>,
}

impl TryFrom<PresetRecord> for Preset {
    type Error = Error;

    fn try_from(r: PresetRecord) -> Result<Self> {
        let name = r.name;
        let level = |which: &str, level: LevelRecord| -> Result<LevelRecipe> {
            let passes = level.passes.into_iter().enumerate().map(|(i, pass)| {
                Pass::try_from(pass).map_err(|why| Error::recipe(&name, format!("{which} pass {i}: {why}")))
            });
            Ok(LevelRecipe { start: level.start, passes: passes.collect::<Result<_>>()? })
        };
        let coarsest = level("coarsest", r.coarsest)?;
        let finer = level("finer", r.finer)?;
        let (keep_interiors, surface_passes) = (r.keep_interiors, r.surface_passes);
        let preset =
            Preset { name: name.clone(), paper: r.paper, coarsest, finer, keep_interiors, surface_passes };
        preset.validate()?;
        Ok(preset)
    }
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
            SquareMetric::Appearance,
        )
    }

    /// Tong et al. 2002: distances through Γ; every finer level inherits from the coarser
    /// one and is refined with two-level neighbourhoods and lists. The coarsest level starts
    /// from random patches rather than the paper's random texels (see [`Start::Patches`]).
    pub fn tong2002() -> Self {
        Self::tong_schedule(
            "tong2002",
            "Tong, Zhang, Liu, Wang, Guo and Shum, SIGGRAPH 2002",
            SquareMetric::Gamma,
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
    ///
    /// On a mesh the patches are 0.35 of the side: there the passes mend seams less well,
    /// and small patches left a 50² sample a mosaic of pieces smaller than its elements
    /// (`bunny-1k8`, 256 texels across, the exported texture: choc swirl contrast 0.84 →
    /// 0.98, cracked stone 0.88 → 0.96, with whole swirls and long cracks in Blender; see
    /// docs/surfaces.md).
    ///
    /// The patches keep their interiors ([`KeepInteriors`]): a move deeper than the
    /// template's radius inside a patch costs 4×. On a mesh (`bunny-1k8`, 256 texels across,
    /// the exported texture) that took the smeared share 0.071 → 0.049 on the cracked stone
    /// and 0.037 → 0.030 on marble, contrast 0.85 → 0.88; on planes it changes little (21
    /// photographs, seeds 0–1: mean repetition 0.0130 → 0.0129, patch energy 0.00111 →
    /// 0.00115). Costs of 4, 11 and 30 measure alike; a depth of 2/3 radius leaves the 50²
    /// choc swirl's seams jagged (docs/surfaces.md).
    fn tong_schedule(name: &'static str, paper: &'static str, metric: SquareMetric) -> Self {
        let pass = |template| Pass {
            order: VisitOrder::Interleaved,
            neighbourhood: Neighbourhood::Square { metric, template },
            candidates: Candidates::Search,
            select: Select::Choosy { strength: 0.3 },
            coherence_bias: 0.5,
        };
        Preset {
            name: name.into(),
            paper: paper.into(),
            coarsest: LevelRecipe {
                start: Start::Patches { radius: 0.15, surface_radius: Some(0.35) },
                passes: vec![pass(SquareTemplate::Own(OwnPixels::Full)); 4],
            },
            finer: LevelRecipe {
                start: Start::Inherit,
                passes: vec![pass(SquareTemplate::OwnAndParent(OwnPixels::Full, ParentTemplate::Narrow)); 2],
            },
            keep_interiors: Some(KeepInteriors { depth: 1.0, move_cost: 4.0 }),
            surface_passes: Some(2),
        }
    }

    /// Turk 2001 §5.2: the coarsest level from random texels, one half-square H(n, 0)
    /// pass in sweep order for the initial pattern; every finer level extrapolated with
    /// F(n, 1) and refined with F(n, 0) + F(3, 1), all in sweep order. Departures (docs/synthesis.md):
    /// appearance vectors for colours, the search given (k-coherence by default; the full
    /// search is the paper's), and choosy selection with a coherence bias.
    pub fn turk2001() -> Self {
        let pass = |template| Pass {
            order: VisitOrder::Sweep,
            neighbourhood: Neighbourhood::Square { metric: SquareMetric::Appearance, template },
            candidates: Candidates::Search,
            select: Select::Choosy { strength: 0.3 },
            coherence_bias: 0.5,
        };
        Preset {
            name: "turk2001".into(),
            paper: "Turk, Texture Synthesis on Surfaces, SIGGRAPH 2001".into(),
            coarsest: LevelRecipe {
                start: Start::Random,
                passes: vec![pass(SquareTemplate::Own(OwnPixels::Half))],
            },
            finer: LevelRecipe {
                start: Start::Inherit,
                passes: vec![
                    pass(SquareTemplate::ParentOnly(ParentTemplate::Wide)),
                    pass(SquareTemplate::OwnAndParent(OwnPixels::Full, ParentTemplate::Narrow)),
                ],
            },
            keep_interiors: None,
            surface_passes: None,
        }
    }

    /// Chen and Dong 2008 (§4–6): every level matched by the adaptive metric on round
    /// neighbourhoods of three circles, in most-constrained-first order. The coarsest
    /// level is synthesized from nothing (only coloured vertices compared, candidates from
    /// those vertices' k-coherence), then refined once; every finer level inherits its
    /// parent's texels (the linked pixels) and is refined from the candidates around them.
    pub fn chen2008() -> Self {
        let pass = |compared| Pass {
            order: VisitOrder::MostConstrained,
            neighbourhood: Neighbourhood::Round { circles: 3, compared },
            candidates: Candidates::Search,
            select: Select::Choosy { strength: 0.3 },
            coherence_bias: 0.5,
        };
        Preset {
            name: "chen2008".into(),
            paper: "Chen and Dong, Adaptive Surface Texture Synthesis Using Round-Shaped Neighbourhoods, CGF 2008".into(),
            coarsest: LevelRecipe { start: Start::Random, passes: vec![pass(Compared::Visited), pass(Compared::Full)] },
            finer: LevelRecipe { start: Start::Inherit, passes: vec![pass(Compared::Full)] },
            keep_interiors: None,
            surface_passes: None,
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
    /// The coarsest level's exhaustive search runs through the paper's dynamic kd-trees over
    /// eigenvector-transformed neighbourhoods (§6, [`Candidates::KdTrees`]), ε-approximate:
    /// 6.8× faster than comparing every candidate, at the same patch energy (1.02×).
    ///
    /// Departures (docs/castellanos.md): the stencil's points on circles of the rings' mean
    /// radii, resampled from the square sample grid, in place of the triangular grid's
    /// faces; the exhaustive search on the coarsest level only, k-coherence candidates (which
    /// follow each neighbour's turn) on the finer ones; the
    /// inversion's blend across seams is not formed (a vertex starts from its inherited
    /// texel's colour, not from the projected colours of its neighbours' parents); and a
    /// coherence bias of 1, which the paper has not: without it 1.02% of adjacent pairs copy
    /// one texel (horizontal streaks on stone33, 96² → 192²), with it 0.25%, and patch
    /// energy falls from 0.0101 to 0.0084 for a colour χ² of 0.0028 against 0.0026.
    pub fn castellanos() -> Self {
        let pass = |candidates| Pass {
            order: VisitOrder::Random,
            neighbourhood: Neighbourhood::Isotropic { metric: PointMetric::Colour, compared: Compared::Full },
            candidates,
            select: Select::UsePenalty { base: 2.0 },
            coherence_bias: 1.0,
        };
        Preset {
            name: "castellanos".into(),
            paper: "Castellanos and Williams, Automatic Synthesis of Isotropic Textures on Surfaces from Sample Images".into(),
            coarsest: LevelRecipe { start: Start::Random, passes: vec![pass(Candidates::KdTrees); 4] },
            finer: LevelRecipe { start: Start::Inherit, passes: vec![pass(Candidates::Search); 2] },
            keep_interiors: None,
            surface_passes: None,
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
        self.all_passes().find_map(|p| p.neighbourhood.stencil().marching())
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
            .any(|p| p.metric() == MetricKind::Adaptive && pass_search(p, search) == Search::Full);
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
            Error::out_of_range(
                Param::Preset,
                format!("'{name}'"),
                format!("unknown preset; available: {}", names.join(", ")),
            )
        })
    }

    /// Every pass the recipe runs on `levels` levels.
    pub fn pass_count(&self, levels: usize) -> usize {
        self.coarsest.passes.len() + levels.saturating_sub(1) * self.finer.passes.len()
    }

    /// The recipe as a mesh runs it: each level's passes cut to [`Self::surface_passes`].
    pub fn on_surface(&self) -> Preset {
        let mut preset = self.clone();
        if let Some(passes) = self.surface_passes {
            preset.coarsest.passes.truncate(passes);
            preset.finer.passes.truncate(passes);
        }
        preset
    }

    /// Whether any pass visits in sweep order (which needs sweep distances).
    pub fn sweeps(&self) -> bool {
        self.all_passes().any(|p| p.order == VisitOrder::Sweep)
    }

    /// Whether any pass matches with `metric`.
    pub fn uses(&self, metric: MetricKind) -> bool {
        self.all_passes().any(|p| p.metric() == metric)
    }

    /// A recipe from JSON in the form [`Self::to_json`] writes (the `recipe` object `synth`
    /// records), checked with [`Self::validate`].
    pub fn from_json(text: &str) -> Result<Self> {
        serde_json::from_str(text).map_err(|e| Error::invalid(e.to_string()))
    }

    /// Refuses a recipe the engine cannot run as written, in what its types leave open: a
    /// coarsest level that inherits (it has no parent), a level without passes or with more
    /// than [`MAX_PASSES`], a parent
    /// neighbourhood on the coarsest level, patches seamed by a round pass, round passes
    /// that disagree on their circles, and numbers out of range. (A recipe read from JSON
    /// has been validated already.)
    pub fn validate(&self) -> Result<()> {
        let refuse = |what: String| Err(Error::recipe(&self.name, what));
        if self.coarsest.start.inherits() {
            return refuse("the coarsest level cannot inherit (it has no coarser level)".into());
        }
        for (level, recipe) in [("coarsest", &self.coarsest), ("finer", &self.finer)] {
            if recipe.passes.is_empty() {
                return refuse(format!("the {level} level has no passes (give at least one)"));
            }
            if recipe.passes.len() > MAX_PASSES {
                return refuse(format!(
                    "the {level} level has {} passes, more than {MAX_PASSES}",
                    recipe.passes.len()
                ));
            }
            if let Start::Patches { radius, surface_radius } = recipe.start {
                for radius in std::iter::once(radius).chain(surface_radius) {
                    if !(radius.is_finite() && radius > 0.0) {
                        return refuse(format!(
                            "the {level} level's patch radius must be positive, not {radius}"
                        ));
                    }
                }
            }
            if let Start::Jittered { texels } = recipe.start {
                if !(0.0..=MAX_JITTER).contains(&texels) {
                    return refuse(format!(
                        "the {level} level's jitter must be 0 to {MAX_JITTER} texels, not {texels}"
                    ));
                }
            }
            if matches!(recipe.start, Start::Patches { .. })
                && recipe.passes[0].metric() == MetricKind::Adaptive
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
        if let Some(keep) = self.keep_interiors {
            keep_problem(self, keep).map_or(Ok(()), refuse)?;
        }
        if self.surface_passes == Some(0) {
            return refuse(
                "surface_passes must be at least 1 (leave it out to run every pass on a mesh)".into(),
            );
        }
        let isotropic = self.all_passes().any(|p| p.neighbourhood.stencil() == Stencil::Isotropic);
        let other = self
            .all_passes()
            .filter_map(|p| p.neighbourhood.stencil().round())
            .find(|&r| r != ISOTROPIC_MARCHED);
        if let (true, Some(round)) = (isotropic, other) {
            return refuse(format!(
                "Isotropic passes march 2 circles, so Round passes beside them must have 2, not {}",
                round.circles
            ));
        }
        let mut rounds = self.all_passes().filter_map(|p| p.neighbourhood.stencil().round());
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
            round_fits(round, coarsest).map_or(Ok(()), |why| Err(Error::recipe(&self.name, why)))?;
        }
        if self.uses(MetricKind::Colour) && levels.iter().any(|l| l.colour.is_none()) {
            return Err(Error::recipe(&self.name, "it matches colours, which Sample::load_colours builds"));
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

/// Why the engine cannot run `pass` as written, if it cannot: its numbers, or a parent
/// neighbourhood on the coarsest level (the one combination that depends on the level).
fn pass_problem(pass: &Pass, coarsest: bool) -> Option<String> {
    if coarsest && pass.neighbourhood.parent() != ParentNeighbourhood::None {
        return Some("the coarsest level has no parent neighbourhood (parent must be None)".into());
    }
    pass.value_problem()
}

/// Why `preset` cannot keep its patches' interiors as `keep` says, if it cannot.
fn keep_problem(preset: &Preset, keep: KeepInteriors) -> Option<String> {
    if !(keep.depth.is_finite() && keep.depth >= 0.0) {
        return Some(format!("keep_interiors' depth must be 0 or more template radii, not {}", keep.depth));
    }
    if !(keep.move_cost.is_finite() && keep.move_cost >= 1.0) {
        return Some(format!("keep_interiors' move_cost must be at least 1, not {}", keep.move_cost));
    }
    if !matches!(preset.coarsest.start, Start::Patches { .. }) {
        return Some(
            "keep_interiors needs patches to keep: the coarsest level must start from Patches".into(),
        );
    }
    let square = preset.all_passes().all(|p| matches!(p.neighbourhood, Neighbourhood::Square { .. }));
    (!square)
        .then(|| "keep_interiors applies to square-template passes only, and this recipe has others".into())
}

/// The candidate search of a pass, given the one asked of `synth`.
pub(crate) fn pass_search(pass: &Pass, asked: Search) -> Search {
    match pass.candidates {
        Candidates::Search => asked,
        Candidates::Full => Search::Full,
        Candidates::KdTrees => Search::KdTrees,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `preset` as recorded, with every pass of `levels` (of "coarsest", "finer") whose index
    /// `pick` accepts edited as its flat record by `edit`, read back.
    fn read_edited(
        preset: &Preset,
        levels: &[&str],
        pick: impl Fn(usize) -> bool,
        edit: impl Fn(&mut PassRecord),
    ) -> Result<Preset> {
        let mut json = preset.to_json();
        for &level in levels {
            for (i, pass) in json[level]["passes"].as_array_mut().unwrap().iter_mut().enumerate() {
                if pick(i) {
                    let mut record: PassRecord = serde_json::from_value(pass.clone()).unwrap();
                    edit(&mut record);
                    *pass = serde_json::to_value(record).unwrap();
                }
            }
        }
        Preset::from_json(&json.to_string())
    }

    /// Why `read_edited` refused, which must say `needle`.
    fn refused_as(read: Result<Preset>, needle: &str) {
        let e = read.expect_err(needle).to_string();
        assert!(e.contains(needle), "{e}");
    }

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
                let round = pass.neighbourhood.stencil().round().is_some();
                assert_eq!(round, pass.metric() == MetricKind::Adaptive, "{}: {pass:?}", p.name);
            }
        }
        assert_eq!(Preset::chen2008().round_stencil(), Some(RoundStencil { circles: 3 }));
        assert_eq!(Preset::appearance().round_stencil(), None);
        let two = read_edited(
            &Preset::chen2008(),
            &["coarsest", "finer"],
            |_| true,
            |r| r.stencil = Stencil::Round { circles: 2 },
        );
        assert_eq!(two.unwrap().round_stencil().unwrap().circles, 2);
    }

    /// A stencil its metric does not match, circles out of range and round passes that
    /// disagree are refused, each with a message that says which.
    #[test]
    fn stencils_the_engine_cannot_run_are_refused() {
        let chen = Preset::chen2008();
        let finer0 = |edit: &dyn Fn(&mut PassRecord)| read_edited(&chen, &["finer"], |i| i == 0, edit);
        refused_as(finer0(&|r| r.stencil = Stencil::Square), "the Adaptive metric matches round");
        refused_as(
            finer0(&|r| r.metric = MetricKind::Appearance),
            "the Appearance metric matches square templates",
        );
        refused_as(finer0(&|r| r.parent = ParentNeighbourhood::Narrow), "a Round pass matches one level");
        refused_as(finer0(&|r| r.stencil = Stencil::Round { circles: 0 }), "not 0");
        let past = MAX_CIRCLES + 1;
        refused_as(finer0(&|r| r.stencil = Stencil::Round { circles: past }), &format!("not {past}"));
        refused_as(finer0(&|r| r.stencil = Stencil::Round { circles: 4 }), "not 3 and 4");
        let all = |circles| {
            read_edited(
                &chen,
                &["coarsest", "finer"],
                |_| true,
                move |r| r.stencil = Stencil::Round { circles },
            )
        };
        assert!(all(1).is_ok() && all(MAX_CIRCLES).is_ok());
        let square = read_edited(
            &Preset::turk2001(),
            &["finer"],
            |i| i == 1,
            |r| r.stencil = Stencil::Round { circles: 3 },
        );
        refused_as(square, "the Appearance metric matches square templates");
        // Serde names a misspelt field inside the stencil.
        let mut json = Preset::chen2008().to_json();
        json["finer"]["passes"][0]["stencil"] = serde_json::json!({"Round": {"circle": 3}});
        let e = Preset::from_json(&json.to_string()).unwrap_err().to_string();
        assert!(e.contains("circle"), "{e}");
    }

    /// Kd-tree candidates: castellanos' coarsest level searches them; they need the
    /// isotropic stencil, a selection with one penalty per use count, and a sequential order.
    #[test]
    fn kd_tree_candidates_the_engine_cannot_run_are_refused() {
        let castellanos = Preset::castellanos();
        assert!(castellanos.coarsest.passes.iter().all(|p| p.candidates == Candidates::KdTrees));
        assert_eq!(castellanos.to_json()["coarsest"]["passes"][0]["candidates"], "KdTrees");
        let coarsest0 =
            |edit: &dyn Fn(&mut PassRecord)| read_edited(&castellanos, &["coarsest"], |i| i == 0, edit);
        refused_as(coarsest0(&|r| r.stencil = Stencil::Square), "need the Isotropic stencil");
        refused_as(coarsest0(&|r| r.select = Select::Choosy { strength: 0.3 }), "not Choosy");
        refused_as(coarsest0(&|r| r.order = VisitOrder::Interleaved), "not Interleaved");
        assert!(coarsest0(&|r| r.select = Select::Argmin).is_ok());
        assert_eq!(
            pass_search(&castellanos.coarsest.passes[0], Search::KCoherence { k: 4 }),
            Search::KdTrees
        );
    }

    /// The isotropic stencil runs with colours or appearance vectors on one level, beside
    /// round passes only of its own 2 circles; castellanos records it, and a recipe
    /// recorded before it (no stencil field) still reads, as the square template.
    #[test]
    fn isotropic_passes_the_engine_cannot_run_are_refused() {
        let castellanos = Preset::castellanos();
        let finer0 = |edit: &dyn Fn(&mut PassRecord)| read_edited(&castellanos, &["finer"], |i| i == 0, edit);
        refused_as(finer0(&|r| r.metric = MetricKind::Gamma), "not Gamma");
        refused_as(finer0(&|r| r.parent = ParentNeighbourhood::Narrow), "parent must be None");
        refused_as(finer0(&|r| r.mask = Mask::Half), "mask Visited or Full");
        let round = |circles| {
            read_edited(
                &castellanos,
                &["finer"],
                |i| i == 1,
                move |r| {
                    r.stencil = Stencil::Round { circles };
                    r.metric = MetricKind::Adaptive;
                },
            )
        };
        refused_as(round(3), "must have 2, not 3");
        assert!(round(2).is_ok());
        let json = Preset::castellanos().to_json();
        assert_eq!(json["finer"]["passes"][0]["stencil"], "Isotropic");
        assert_eq!(Preset::castellanos().round_stencil(), Some(ISOTROPIC_MARCHED));
        let mut old = json.clone();
        for level in ["coarsest", "finer"] {
            old[level]["passes"].as_array_mut().unwrap().iter_mut().for_each(|p| {
                p.as_object_mut().unwrap().remove("stencil");
                // Recipes of that time knew no kd-trees either.
                if p["candidates"] == "KdTrees" {
                    p["candidates"] = "Full".into();
                }
            });
        }
        let read = Preset::from_json(&old.to_string()).unwrap();
        assert!(read.all_passes().all(|p| p.neighbourhood.stencil() == Stencil::Square));
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
        refused(&|p| p.coarsest.start = Start::Jittered { texels: 1.0 }, "coarsest level cannot inherit");
        refused(&|p| p.finer.start = Start::Jittered { texels: MAX_JITTER + 1.0 }, "jitter");
        refused(&|p| p.finer.passes.clear(), "finer level has no passes");
        refused(&|p| p.coarsest.passes.clear(), "coarsest level has no passes");
        let appearance = Preset::appearance();
        let wide =
            read_edited(&appearance, &["coarsest"], |i| i == 1, |r| r.parent = ParentNeighbourhood::Wide);
        refused_as(wide, "coarsest pass 1");
        let nothing = read_edited(
            &appearance,
            &["finer"],
            |i| i == 0,
            |r| {
                r.mask = Mask::Off;
                r.parent = ParentNeighbourhood::None;
            },
        );
        refused_as(nothing, "mask Off compares nothing");
        refused(&|p| p.finer.passes[1].coherence_bias = -1.0, "coherence_bias");
        refused(&|p| p.finer.passes[1].select = Select::Choosy { strength: -0.5 }, "strength");
        refused(&|p| p.finer.passes[1].select = Select::UsePenalty { base: 0.5 }, "base");
        refused(&|p| p.coarsest.start = Start::Patches { radius: 0.0, surface_radius: None }, "patch radius");
        let surface_radius = Some(-0.1);
        refused(&|p| p.coarsest.start = Start::Patches { radius: 0.15, surface_radius }, "patch radius");
        let keep = |depth, move_cost| Some(KeepInteriors { depth, move_cost });
        refused(&|p| p.keep_interiors = keep(-1.0, 4.0), "depth must be 0 or more");
        refused(&|p| p.keep_interiors = keep(1.0, 0.5), "move_cost must be at least 1");
        refused(&|p| p.surface_passes = Some(0), "surface_passes must be at least 1");
        refused(&|p| p.coarsest.start = Start::Random, "needs patches to keep");
        let mut castellanos = Preset::castellanos();
        castellanos.coarsest.start = Start::Patches { radius: 0.15, surface_radius: None };
        castellanos.keep_interiors = keep(1.0, 4.0);
        let e = castellanos.validate().expect_err("isotropic passes").to_string();
        assert!(e.contains("square-template passes only"), "{e}");
        // A recipe built in code is held to the same numbers.
        let mut built = Preset::appearance();
        built.finer.passes[1].coherence_bias = f32::NAN;
        assert!(built.validate().unwrap_err().to_string().contains("coherence_bias"));
        let mut built = Preset::appearance();
        built.finer.start = Start::Jittered { texels: f32::NAN };
        assert!(built.validate().unwrap_err().to_string().contains("jitter"));
    }

    /// Bad JSON is refused with serde's message, which names the field.
    #[test]
    fn malformed_recipes_name_the_field() {
        let mut json = Preset::tong2002().to_json();
        json["finer"]["passes"][0]["metric"] = "Colour".into();
        assert_eq!(
            Preset::from_json(&json.to_string()).unwrap().finer.passes[0].metric(),
            MetricKind::Colour
        );
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

    /// On a mesh the default and tong2002 run two passes a level (their surface_passes);
    /// the papers' presets, which leave it out, run every pass; a plane runs every pass.
    #[test]
    fn a_mesh_runs_a_preset_s_surface_passes() {
        for preset in Preset::all() {
            let surface = preset.on_surface();
            let expected = |passes: usize| preset.surface_passes.map_or(passes, |n| passes.min(n));
            assert_eq!(
                surface.coarsest.passes.len(),
                expected(preset.coarsest.passes.len()),
                "{}",
                preset.name
            );
            assert_eq!(surface.finer.passes.len(), expected(preset.finer.passes.len()), "{}", preset.name);
        }
        assert_eq!(Preset::appearance().on_surface().coarsest.passes.len(), 2);
        assert_eq!(Preset::tong2002().on_surface().coarsest.passes.len(), 2);
        let castellanos = Preset::castellanos();
        assert_eq!(castellanos.on_surface(), castellanos);
    }
}
