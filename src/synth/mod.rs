//! Surface texton map synthesis (Tong et al. 2002 §5): per target vertex, a texton label and
//! a coordinate into the sample, chosen coarse to fine by neighbourhood matching through Γ.
//!
//! The engine is a set of parts (see DESIGN.md): the visiting [`VisitOrder`], the
//! neighbourhood (square templates of surface textons, [`target`]), the candidate
//! [`Search`], the distance (through Γ, [`engine`]) and the level schedule ([`Preset`]).
//! Targets are a level stack of [`target::TargetLevel`]s; plane mode builds them from a
//! regular grid ([`target::grid_levels`]).

pub mod engine;
pub mod plane;
pub mod sample;
pub mod surface;
pub mod surface_map;
pub mod target;

pub use engine::{Search, State, VisitOrder};
pub use sample::{Sample, SampleLevel};

use crate::progress::Progress;
use crate::{Error, Result};
use engine::{inherit, pass, random_state, visit_order, Parent, PassContext, PassStats};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::{Duration, Instant};
use target::TargetLevel;

/// A named combination of the engine's parts.
#[derive(Clone, Debug, PartialEq)]
pub struct Preset {
    pub name: &'static str,
    /// Order of the causal first pass on the coarsest level.
    pub grow_order: VisitOrder,
    /// Order of every other pass.
    pub order: VisitOrder,
    /// Passes on the coarsest level: the first grows the map causally from random seeds
    /// (only synthesized vertices count), the rest use full neighbourhoods.
    pub coarse_passes: usize,
    /// Whether finer levels' second pass uses two-level neighbourhoods and lists.
    pub two_level: bool,
}

impl Preset {
    /// Tong et al. 2002: the coarsest level grown by one causal pass (breadth-first from a
    /// random vertex) and refined by a full-neighbourhood pass in random order; every finer level inherits from the coarser one (first pass) and is
    /// refined with two-level neighbourhoods and two-level kNN lists (second pass).
    pub fn tong2002() -> Self {
        Preset {
            name: "tong2002",
            grow_order: VisitOrder::Grow,
            order: VisitOrder::Random,
            coarse_passes: 2,
            two_level: true,
        }
    }

    /// Presets by name, for `--preset`.
    pub fn by_name(name: &str) -> Result<Self> {
        match name {
            "tong2002" => Ok(Self::tong2002()),
            _ => Err(Error::invalid(format!("unknown preset '{name}': available: tong2002"))),
        }
    }
}

/// Parameters of one synthesis.
#[derive(Clone, Debug)]
pub struct SynthParams {
    /// The engine's parts (default [`Preset::tong2002`]).
    pub preset: Preset,
    /// Candidate search (default k-coherence with the analysis' k).
    pub search: Search,
    /// Side of the square neighbourhood template, odd (default 5; 7 also common).
    pub neighborhood: usize,
    /// Seed of every random choice (default 0).
    pub seed: u64,
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
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let coarsest = targets.len() - 1;
    let total_passes = params.preset.coarse_passes + coarsest;
    progress.start("synthesizing", total_passes as u64);
    let r = params.neighborhood / 2;
    let mut reports = Vec::new();

    let started = Instant::now();
    let (target, level_sample) = (&targets[coarsest], &sample.levels[coarsest]);
    let mut state = random_state(target.vertices, level_sample, r, &mut rng);
    let mut stats = PassStats::default();
    for p in 0..params.preset.coarse_passes {
        let order = visit_order(
            target,
            if p == 0 { params.preset.grow_order } else { params.preset.order },
            &mut rng,
        );
        let context = PassContext { parent: None, search: search_for(params, level_sample), causal: p == 0 };
        stats = pass(target, &mut state, level_sample, &context, &order, &mut rng);
        progress.advance(1);
    }
    reports.push(report(coarsest, target, params.preset.coarse_passes, started.elapsed(), stats));

    for l in (0..coarsest).rev() {
        let started = Instant::now();
        let (target, level_sample) = (&targets[l], &sample.levels[l]);
        let coarse = state;
        state = inherit(target, &coarse, level_sample);
        let parent = Parent { state: &coarse, sample: &sample.levels[l + 1] };
        let order = visit_order(target, params.preset.order, &mut rng);
        let context = PassContext {
            parent: params.preset.two_level.then_some(&parent),
            search: search_for(params, level_sample),
            causal: false,
        };
        let stats = pass(target, &mut state, level_sample, &context, &order, &mut rng);
        progress.advance(1);
        reports.push(report(l, target, 2, started.elapsed(), stats));
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
