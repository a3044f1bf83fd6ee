//! Surface texton map synthesis (Tong et al. 2002 §5): per target vertex, a texton label and
//! a coordinate into the sample, chosen coarse to fine by neighbourhood matching through Γ.
//!
//! The engine is a set of parts (see DESIGN.md): the visiting [`VisitOrder`], the
//! neighbourhood (square templates of surface textons, [`target`]), the candidate
//! [`Search`], the distance (through Γ, [`engine`]) and the level schedule ([`Preset`]).
//! Targets are a level stack of [`target::TargetLevel`]s; plane mode builds them from a
//! regular grid ([`target::grid_levels`]).

pub mod candidates;
pub mod engine;
pub(crate) mod metric;
pub mod plane;
pub mod sample;
pub mod start;
pub mod surface;
pub mod surface_map;
pub mod target;

pub use candidates::Search;
pub use engine::{Select, State, VisitOrder};
pub use sample::{Sample, SampleLevel};

use crate::progress::Progress;
use crate::{Error, Result};
use engine::{pass, visit_order, Parent, PassPlan, PassStats};
use metric::{AppearanceMetric, GammaMetric, Metric};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::{Duration, Instant};
use target::TargetLevel;

/// The neighbourhood distance a preset matches with.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum MetricKind {
    /// Surface textons through Γ (Tong §5.1).
    Gamma,
    /// Appearance vectors by SSD (Lefebvre and Hoppe 2006); needs an analysis that stores
    /// them.
    Appearance,
}

/// How the coarsest level starts.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum Start {
    /// Every vertex a random texel (Tong §5.1).
    Random,
    /// Random coherent patches of this radius, as a fraction of the coarsest sample level's
    /// smaller side (see `start::patch_state`).
    Patches { radius: f32 },
}

/// A named combination of the engine's parts.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Preset {
    pub name: &'static str,
    /// The paper the preset follows, for `--list-presets`.
    pub paper: &'static str,
    /// The neighbourhood distance.
    pub metric: MetricKind,
    /// How the coarsest level starts.
    pub start: Start,
    /// Full-neighbourhood passes on the coarsest level after the start.
    pub coarse_passes: usize,
    /// Passes on every finer level after it inherits from the coarser one.
    pub fine_passes: usize,
    /// Whether finer levels match two-level neighbourhoods with two-level kNN lists.
    pub two_level: bool,
    /// Order of every pass.
    pub order: VisitOrder,
    /// How a vertex picks among its candidates.
    pub select: Select,
    /// Preference for continuing a copy over starting a new one (see
    /// [`engine::PassPlan::coherence_bias`]).
    pub coherence_bias: f32,
}

impl Preset {
    /// The default: Tong's engine matched on appearance vectors, from random patches, with
    /// a preference for continuing copies and choosy selection. Every departure from the paper
    /// is measured on eleven 128² photographs → 512² against Embark's texture-synthesis
    /// (README, Synthesis quality).
    pub fn appearance() -> Self {
        Preset {
            name: "appearance",
            paper: "Tong et al. 2002, matched on appearance vectors (Lefebvre and Hoppe 2006)",
            metric: MetricKind::Appearance,
            start: Start::Patches { radius: 0.35 },
            coarse_passes: 4,
            fine_passes: 2,
            two_level: true,
            order: VisitOrder::Random,
            select: Select::Choosy { strength: 0.3 },
            coherence_bias: 0.5,
        }
    }

    /// Tong et al. 2002: distances through Γ; every finer level inherits from the coarser
    /// one and is refined with two-level neighbourhoods and lists. The coarsest level starts
    /// from random patches rather than the paper's random texels (see [`Start::Patches`]).
    pub fn tong2002() -> Self {
        Preset {
            name: "tong2002",
            paper: "Tong, Zhang, Liu, Wang, Guo and Shum, SIGGRAPH 2002",
            metric: MetricKind::Gamma,
            ..Self::appearance()
        }
    }

    /// Every preset, the default first.
    pub fn all() -> Vec<Self> {
        vec![Self::appearance(), Self::tong2002()]
    }

    /// Presets by name, for `--preset`.
    pub fn by_name(name: &str) -> Result<Self> {
        Self::all().into_iter().find(|p| p.name == name).ok_or_else(|| {
            let names: Vec<&str> = Self::all().iter().map(|p| p.name).collect();
            Error::invalid(format!("unknown preset '{name}': available: {}", names.join(", ")))
        })
    }
}

/// Parameters of one synthesis.
#[derive(Clone, Debug)]
pub struct SynthParams {
    /// The engine's parts (default [`Preset::appearance`]).
    pub preset: Preset,
    /// Candidate search (default k-coherence with k = 11, capped by the analysis' lists).
    pub search: Search,
    /// Side of the square neighbourhood template, odd (default 7: measured on photographs,
    /// 5 leaves 25% more nearest-patch energy).
    pub neighborhood: usize,
    /// Seed of every random choice (default 0).
    pub seed: u64,
}

impl Default for SynthParams {
    fn default() -> Self {
        SynthParams {
            preset: Preset::appearance(),
            search: Search::KCoherence { k: 11 },
            neighborhood: 7,
            seed: 0,
        }
    }
}

/// What happened on one level.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LevelReport {
    pub level: usize,
    pub vertices: usize,
    pub passes: usize,
    pub seconds: f64,
    /// Mean candidate-set size of the last pass.
    pub mean_candidates: f64,
    /// Mean best neighbourhood distance of the last pass.
    pub mean_best_distance: f64,
}

/// Synthesizes every level of `targets` (finest first, as many as `sample` has levels in
/// use), returning the finest level's state and a report per level, coarsest first.
pub fn synthesize(
    targets: &[TargetLevel],
    sample: &Sample,
    params: &SynthParams,
    progress: &dyn Progress,
) -> Result<(State, Vec<LevelReport>)> {
    if targets.is_empty() || targets.len() > sample.levels.len() {
        return Err(Error::invalid("synthesis needs one target level per sample level"));
    }
    let levels = &sample.levels[..targets.len()];
    match params.preset.metric {
        MetricKind::Gamma => {
            run(targets, levels, params, progress, |s, t| Ok(GammaMetric { sample: s, template: t }))
        }
        MetricKind::Appearance => run(targets, levels, params, progress, |s, t| {
            let map = s.appearance.as_ref().ok_or_else(|| {
                Error::invalid(format!(
                    "preset '{}' matches appearance vectors, which this analysis lacks (written by an older btfsynth): re-run analyze, or use --preset tong2002",
                    params.preset.name
                ))
            })?;
            Ok(AppearanceMetric { map, template: t })
        }),
    }
}

/// The level schedule with one metric type throughout, so every pass is monomorphised.
fn run<'a, M: Metric>(
    targets: &[TargetLevel],
    levels: &'a [SampleLevel],
    params: &SynthParams,
    progress: &dyn Progress,
    metric: impl Fn(&'a SampleLevel, usize) -> Result<M>,
) -> Result<(State, Vec<LevelReport>)> {
    let preset = &params.preset;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let coarsest = targets.len() - 1;
    progress.start("synthesizing", (preset.coarse_passes + coarsest * preset.fine_passes) as u64);
    let r = params.neighborhood / 2;
    let mut reports = Vec::new();

    let started = Instant::now();
    let (target, level_sample) = (&targets[coarsest], &levels[coarsest]);
    let own = metric(level_sample, target.template)?;
    let mut state = match preset.start {
        Start::Random => start::random_state(target, level_sample, r, &mut rng),
        Start::Patches { radius } => {
            let patch = (radius * level_sample.width.min(level_sample.height) as f32).max(1.0);
            let k = search_for(params, level_sample).list_length(level_sample);
            start::patch_state(target, level_sample, &own, (r, patch, k), &mut rng)
        }
    };
    let plan = PassPlan {
        search: search_for(params, level_sample),
        causal: false,
        select: preset.select,
        coherence_bias: preset.coherence_bias,
    };
    let mut stats = PassStats::default();
    for _ in 0..preset.coarse_passes {
        let order = visit_order(target, preset.order, &mut rng);
        stats = pass(target, &mut state, level_sample, &own, None, &plan, &order, &mut rng);
        progress.advance(1);
    }
    reports.push(report(coarsest, target, preset.coarse_passes, started.elapsed(), stats));

    for l in (0..coarsest).rev() {
        let started = Instant::now();
        let (target, level_sample) = (&targets[l], &levels[l]);
        let coarse = state;
        state = start::inherit(target, &coarse, level_sample, r);
        let own = metric(level_sample, target.template)?;
        let parent = Parent { state: &coarse, metric: metric(&levels[l + 1], target.parent_template)? };
        let parent = preset.two_level.then_some(&parent);
        let plan = PassPlan {
            search: search_for(params, level_sample),
            causal: false,
            select: preset.select,
            coherence_bias: preset.coherence_bias,
        };
        let mut stats = PassStats::default();
        for _ in 0..preset.fine_passes {
            let order = visit_order(target, preset.order, &mut rng);
            stats = pass(target, &mut state, level_sample, &own, parent, &plan, &order, &mut rng);
            progress.advance(1);
        }
        reports.push(report(l, target, 1 + preset.fine_passes, started.elapsed(), stats));
    }
    progress.finish();
    Ok((state, reports))
}

/// The k-coherence k is capped by the lists the analysis stored.
fn search_for(params: &SynthParams, sample: &SampleLevel) -> Search {
    match params.search {
        Search::KCoherence { k } => Search::KCoherence { k: k.min(sample.k) },
        Search::Full => Search::Full,
    }
}

fn report(
    level: usize,
    target: &TargetLevel,
    passes: usize,
    elapsed: Duration,
    stats: PassStats,
) -> LevelReport {
    LevelReport {
        level,
        vertices: target.vertices,
        passes,
        seconds: elapsed.as_secs_f64(),
        mean_candidates: stats.mean_candidates,
        mean_best_distance: stats.mean_best,
    }
}
