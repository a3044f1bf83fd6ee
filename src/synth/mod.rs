//! Surface texton map synthesis (Tong et al. 2002 §5): per target vertex, a texton label and
//! a coordinate into the sample, chosen coarse to fine by neighbourhood matching through Γ.
//!
//! The engine is a set of parts (see DESIGN.md): the visiting [`VisitOrder`], the
//! neighbourhood (per pass a [`Stencil`]: square templates of surface textons, [`target`],
//! or Chen–Dong's round ones, [`round`]), the candidate [`Search`], the distance (through Γ,
//! [`engine`]) and the level schedule ([`Preset`]).
//! Targets are a level stack of [`target::TargetLevel`]s; plane mode builds them from a
//! regular grid ([`target::grid_levels`]).

pub mod adaptive;
pub mod candidates;
pub mod constrained;
pub mod device;
pub mod engine;
pub(crate) mod flatten;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod isotropic;
pub mod isotropic_stencil;
pub(crate) mod job;
pub mod kdtrees;
pub mod lattice;
pub mod metric;
pub mod neighbourhood;
pub mod pass;
pub mod patches;
pub mod plane;
pub mod pyramid_cache;
pub mod recipe;
pub mod round;
pub mod round_pass;
pub mod sample;
pub mod session;
pub mod slot;
pub mod square_pass;
pub mod start;
pub mod state;
pub mod surface;
pub mod surface_map;
pub mod sweep;
pub mod target;

pub use candidates::Search;
pub use device::Device;
pub use engine::{Select, State, VisitOrder};
pub use neighbourhood::{
    Compared, Mask, MetricKind, Neighbourhood, OwnPixels, ParentNeighbourhood, ParentTemplate, PointMetric,
    SquareMetric, SquareTemplate, Stencil,
};
pub use recipe::{Candidates, LevelRecipe, Pass, PassRecord, Preset, Start};
use sample::AppearanceMap;
pub use sample::{Sample, SampleLevel};

use crate::progress::Progress;
use crate::{Error, Result};
use engine::{visit_order, PassPlan, PassStats};
use metric::{AppearanceMetric, GammaMetric, Metric};
use pass::{Colouring, Schedule};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use recipe::pass_search;
use round::{RoundSample, RoundStencil};
use round_pass::RoundTarget;
use square_pass::{Parent, SquareMatch};
use std::sync::OnceLock;
use std::time::{Duration, Instant};
use target::TargetLevel;

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
    /// Where the passes run (default [`Device::Auto`]); the result is the same on either.
    pub device: Device,
}

impl Default for SynthParams {
    fn default() -> Self {
        SynthParams {
            preset: Preset::appearance(),
            search: Search::KCoherence { k: 11 },
            neighborhood: 7,
            seed: 0,
            device: Device::Auto,
        }
    }
}

/// What happened on one level.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LevelReport {
    /// Pyramid level, 0 the finest.
    pub level: usize,
    /// Output vertices on the level (pixels, for a plane).
    pub vertices: usize,
    /// Passes run on the level, inheriting from the coarser level counted as one.
    pub passes: usize,
    /// Wall time spent on the level, in seconds.
    pub seconds: f64,
    /// Mean candidate-set size of the last pass.
    pub mean_candidates: f64,
    /// Mean best neighbourhood distance of the last pass.
    pub mean_best_distance: f64,
    /// Where the level's passes ran: "cpu", "gpu (adapter)", or both with the reason the
    /// others had no GPU form ([`device`]). Left out of outputs, which do not depend on it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub device: Option<String>,
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
    let last = &sample.levels[targets.len() - 1];
    if params.neighborhood > last.width.min(last.height) {
        return Err(Error::out_of_range(
            crate::Param::Neighbourhood,
            params.neighborhood,
            format!(
                "a {0}x{0} neighbourhood does not fit in the coarsest sample level in use ({1}x{2})",
                params.neighborhood, last.width, last.height
            ),
        ));
    }
    let on_mesh = matches!(targets[0].neighbourhoods, target::Neighbourhoods::Mesh { .. });
    let surface_preset = on_mesh.then(|| params.preset.on_surface());
    let preset = surface_preset.as_ref().unwrap_or(&params.preset);
    preset.validate()?;
    preset.check_search(params.search)?;
    preset.check_sample(&sample.levels[..targets.len()])?;
    let levels = &sample.levels[..targets.len()];
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let sweep = preset.sweeps().then(|| sweep::sweep_distances(targets, params.seed));
    let coarsest = targets.len() - 1;
    progress.start("synthesizing", preset.pass_count(targets.len()) as u64);
    let r = params.neighborhood / 2;
    let mut reports = Vec::new();
    let mut runner =
        device::Runner::open(params.device, device::why_auto_keeps_the_cpu(preset, params.search))?;
    let mut state: Option<State> = None;
    // Each vertex's patch, where the coarsest level started from patches whose interiors the
    // recipe keeps.
    let mut owner: Option<Vec<u32>> = None;
    // Where the finest level of a surface started from patches: each vertex's copied texel
    // and its place within it, kept for the vertices the passes leave there.
    let mut patch_places: Option<StartPlaces> = None;
    // The coarser level's turns, where isotropic passes matched it.
    let mut coarse_turns: Option<isotropic::Turns> = None;
    // The greedy colouring of a level runs on one core (on the finest level of a 250k
    // surface for a third of a second): the finer levels' are built beside the coarser
    // levels' passes, and a level whose colouring is not done yet builds or awaits it.
    let colourings: Vec<OnceLock<Option<Colouring>>> = targets.iter().map(|_| OnceLock::new()).collect();
    let interleaves =
        |recipe: &recipe::LevelRecipe| recipe.passes.iter().any(|p| p.order == VisitOrder::Interleaved);
    rayon::in_place_scope(|scope| -> Result<(State, Vec<LevelReport>)> {
        if interleaves(&preset.finer) {
            for (colouring, target) in colourings.iter().zip(targets).take(coarsest) {
                scope.spawn(move |_| {
                    colouring.get_or_init(|| Colouring::of(target));
                });
            }
        }
        for l in (0..=coarsest).rev() {
            let started = Instant::now();
            let recipe = if l == coarsest { &preset.coarsest } else { &preset.finer };
            let (target, level_sample) = (&targets[l], &levels[l]);
            let margin = target.candidate_margin(r);
            let coarse = state.take();
            let mut turns = None;
            let mut current = match (recipe.start, &coarse) {
                (Start::Inherit | Start::Jittered { .. }, Some(coarse)) => {
                    let inherited = match coarse_turns.take() {
                        Some(coarse_turns) => {
                            let (inherited, level_turns) =
                                isotropic::inherit(target, coarse, &coarse_turns, level_sample, margin);
                            turns = Some(level_turns);
                            inherited
                        }
                        None => start::inherit(target, coarse, level_sample, margin),
                    };
                    match recipe.start {
                        Start::Jittered { texels } => {
                            start::jitter(inherited, level_sample, margin, texels, rng.random())
                        }
                        _ => inherited,
                    }
                }
                (Start::Random, _) => {
                    owner = None;
                    start::random_state(target, level_sample, margin, &mut rng)
                }
                (Start::Patches { radius, surface_radius }, _) => {
                    let radius = if on_mesh { surface_radius.unwrap_or(radius) } else { radius };
                    // A patch narrower than the template is all seam: the templates that judge
                    // its placement mostly see its neighbours (and a small periodic sample's
                    // phases then never line up).
                    let patch =
                        (radius * level_sample.width.min(level_sample.height) as f32).max((r + 1) as f32);
                    let search = capped(
                        recipe.passes.first().map_or(params.search, |p| pass_search(p, params.search)),
                        level_sample,
                    );
                    let k = search.list_length(level_sample);
                    let metric = recipe.passes.first().map_or(MetricKind::Gamma, |p| p.metric());
                    let start = patches(
                        metric,
                        target,
                        (level_sample, &sample.levels),
                        (margin, patch, k),
                        &mut rng,
                    )?;
                    if l == 0 && on_mesh {
                        patch_places = Some((start.state.uv.clone(), start.subtexel()));
                    }
                    owner = preset.keep_interiors.map(|_| start.owner);
                    start.state
                }
                (Start::Inherit | Start::Jittered { .. }, None) => {
                    unreachable!("checked above: the coarsest level does not inherit")
                }
            };
            if let (Some(coarse_owner), true) = (&owner, recipe.start.inherits()) {
                owner = Some(start::inherit_owner(target, coarse_owner));
            }
            tracing::debug!("level {l}: start in {:.2?}{}", started.elapsed(), smear_note(target, &current));
            let move_costs = preset
                .keep_interiors
                .zip(owner.as_deref())
                .map(|(keep, owner)| start::move_costs(target, owner, keep));
            tracing::debug!("level {l}: start and move costs in {:.2?}", started.elapsed());
            let mut stats = PassStats::default();
            let rounds = round_inputs(recipe, preset.round_stencil(), target, level_sample)?;
            let isotropic_level =
                recipe.passes.iter().any(|p| matches!(p.neighbourhood, Neighbourhood::Isotropic { .. }));
            let turns =
                isotropic_level.then(|| turns.unwrap_or_else(|| isotropic::Turns::zeros(target.vertices)));
            let iso = match &turns {
                Some(turns) => Some(isotropic_inputs(recipe, target, level_sample, turns)?),
                None => None,
            };
            let colouring = if interleaves(recipe) {
                colourings[l].get_or_init(|| Colouring::of(target)).as_ref()
            } else {
                None
            };
            for p in &recipe.passes {
                let schedule = match (colouring, p.order) {
                    (Some(colouring), VisitOrder::Interleaved) => {
                        Schedule::Interleaved { colouring, seed: rng.random() }
                    }
                    _ => Schedule::Order(visit_order(
                        target,
                        p.order,
                        sweep.as_ref().map(|s| s[l].as_slice()),
                        &mut rng,
                    )),
                };
                let level = LevelInputs {
                    targets,
                    levels,
                    l,
                    coarse: coarse.as_ref(),
                    rounds: rounds.as_ref(),
                    iso: iso.as_ref(),
                    move_costs: move_costs.as_deref(),
                };
                let job = job::PassJob {
                    pass: p,
                    search: capped(pass_search(p, params.search), level_sample),
                    level: l,
                    target,
                    coarser: targets.get(l + 1),
                    sample: level_sample,
                    coarse_sample: levels.get(l + 1),
                    coarse: coarse.as_ref(),
                    schedule: &schedule,
                    move_costs: move_costs.as_deref(),
                };
                stats = match runner.pass(&job, &mut current)? {
                    Some(stats) => stats,
                    None => run_pass(p, &level, &mut current, params, &schedule, &mut rng)?,
                };
                tracing::debug!(
                    "level {l}: a pass done at {:.2?}{}",
                    started.elapsed(),
                    smear_note(target, &current)
                );
                progress.advance(1);
            }
            let passes = recipe.passes.len() + usize::from(recipe.start.inherits());
            let mut level_report = report(l, target, passes, started.elapsed(), stats);
            level_report.device = Some(runner.level_done());
            reports.push(level_report);
            state = Some(current);
            drop(iso);
            coarse_turns = turns;
        }
        progress.finish();
        let mut state = state.expect("at least one level");
        if let Some((started, subtexel)) = patch_places {
            state.subtexel = kept_places(&state.uv, &started, subtexel);
        }
        Ok((state, reports))
    })
}

/// The coordinate map's smear ([`crate::eval::coords::smear`]) for a debug line, so a
/// surface's log says which step makes its smeared stretches; empty unless debugging.
fn smear_note(target: &TargetLevel, state: &State) -> String {
    if tracing::enabled!(tracing::Level::DEBUG) {
        format!(", smear {:.4}", crate::eval::coords::smear(target, state))
    } else {
        String::new()
    }
}

/// Each vertex's texel on the start's patches, and its place within it.
type StartPlaces = (Vec<[i32; 2]>, Vec<[f32; 2]>);

/// Each vertex's place within its texel from the start (`subtexel`), where it still copies
/// the texel it `started` on; the centre where a pass moved it (its new texel is a
/// neighbour's continuation, whole).
fn kept_places(uv: &[[i32; 2]], started: &[[i32; 2]], mut subtexel: Vec<[f32; 2]>) -> Vec<[f32; 2]> {
    for ((place, now), then) in subtexel.iter_mut().zip(uv).zip(started) {
        if now != then {
            *place = [0.0; 2];
        }
    }
    subtexel
}

/// What a pass on level `l` reads besides its own state.
struct LevelInputs<'a> {
    targets: &'a [TargetLevel],
    levels: &'a [SampleLevel],
    l: usize,
    /// The coarser level's final state (none on the coarsest level).
    coarse: Option<&'a State>,
    /// The level's round neighbourhoods and the sample's, when a pass matches them.
    rounds: Option<&'a (RoundTarget<'a>, RoundSample)>,
    /// The level's isotropic neighbourhoods, when a pass matches them.
    iso: Option<&'a isotropic::IsoLevel<'a>>,
    /// Per vertex, the factor on moving ([`PassPlan::move_cost`]), where the recipe keeps
    /// its patches' interiors.
    move_costs: Option<&'a [f32]>,
}

/// What a level's isotropic passes compare: the grid's points or the mesh level's marching,
/// the sample level's neighbourhoods (of the map the first isotropic pass matches), and
/// every vertex's turn.
fn isotropic_inputs<'a>(
    recipe: &LevelRecipe,
    target: &'a TargetLevel,
    sample: &SampleLevel,
    turns: &'a isotropic::Turns,
) -> Result<isotropic::IsoLevel<'a>> {
    let round = match (&target.neighbourhoods, &target.round) {
        (&target::Neighbourhoods::Grid { width, height, wraps, .. }, _) => {
            RoundTarget::Grid { width, height, wraps }
        }
        (_, Some(m)) if m.marching.stencil == isotropic::MARCHED => {
            RoundTarget::Mesh { marching: &m.marching, starts: &m.starts }
        }
        (_, _) => {
            return Err(Error::invalid("isotropic neighbourhoods on a mesh need its marching of 2 circles"))
        }
    };
    let metric = recipe.passes.iter().find_map(|p| match p.neighbourhood {
        Neighbourhood::Isotropic { metric, .. } => Some(metric),
        _ => None,
    });
    let map = isotropic_map(metric.unwrap_or(PointMetric::Colour), sample)?;
    let sample = isotropic::IsoSample::new(map, sample.width, sample.height);
    Ok(isotropic::IsoLevel { target: round, sample, turns })
}

/// The map an isotropic pass under `metric` compares.
fn isotropic_map(metric: PointMetric, sample: &SampleLevel) -> Result<&AppearanceMap> {
    let map = match metric {
        PointMetric::Colour => sample.colour.as_ref(),
        PointMetric::Appearance => sample.appearance.as_ref(),
    };
    map.ok_or_else(|| Error::invalid(format!("an isotropic pass needs the {metric:?} map of the sample")))
}

/// The round neighbourhoods of `stencil` (the recipe's, [`Preset::round_stencil`]) a
/// level's round passes compare (none if it has no such pass): the grid's own or the mesh
/// level's marching, and the sample level's, resampled once here.
fn round_inputs<'a>(
    recipe: &LevelRecipe,
    stencil: Option<RoundStencil>,
    target: &'a TargetLevel,
    sample: &SampleLevel,
) -> Result<Option<(RoundTarget<'a>, RoundSample)>> {
    let rounds = recipe.passes.iter().any(|p| matches!(p.neighbourhood, Neighbourhood::Round { .. }));
    let Some(stencil) = stencil.filter(|_| rounds) else {
        return Ok(None);
    };
    let round = match (&target.neighbourhoods, &target.round) {
        (&target::Neighbourhoods::Grid { width, height, wraps, .. }, _) => {
            RoundTarget::Grid { width, height, wraps }
        }
        (_, Some(m)) if m.marching.stencil == stencil => {
            RoundTarget::Mesh { marching: &m.marching, starts: &m.starts }
        }
        (_, Some(m)) => {
            return Err(Error::invalid(format!(
                "the mesh level was marched for {} circles, but the recipe's round neighbourhoods have {}",
                m.marching.stencil.circles, stencil.circles
            )))
        }
        (_, None) => return Err(Error::invalid("round neighbourhoods on a mesh need its marching")),
    };
    let map = sample.appearance.as_ref().expect("checked in synthesize");
    Ok(Some((round, RoundSample::new(map, sample.width, sample.height, stencil)?)))
}

/// Runs one pass, dispatching once on its neighbourhood so the candidate loop is
/// monomorphised.
fn run_pass(
    p: &Pass,
    inputs: &LevelInputs,
    state: &mut State,
    params: &SynthParams,
    order: &Schedule,
    rng: &mut ChaCha8Rng,
) -> Result<PassStats> {
    let (target, sample) = (&inputs.targets[inputs.l], &inputs.levels[inputs.l]);
    let search = capped(pass_search(p, params.search), sample);
    let (select, bias) = (p.select, p.coherence_bias);
    match p.neighbourhood {
        Neighbourhood::Isotropic { metric, compared } => {
            let iso = inputs.iso.expect("built for every level with an isotropic pass");
            let map = isotropic_map(metric, sample)?;
            let how = (search, compared, select, bias);
            Ok(isotropic::isotropic_pass(target, iso, state, sample, map, how, order, rng))
        }
        Neighbourhood::Round { compared, .. } => {
            let (round, round_sample) = inputs.rounds.expect("built for every level with a round pass");
            let how = (search, compared, select, bias);
            round_pass::adaptive_pass(target, round, state, sample, round_sample, how, order, rng)
        }
        Neighbourhood::Square { metric, template } => {
            let (mask, move_cost) = (template.mask(), inputs.move_costs);
            let plan = PassPlan { search, mask, select, coherence_bias: bias, move_cost };
            let square = (inputs, template, &plan);
            Ok(match metric {
                SquareMetric::Gamma => {
                    square_pass(square, state, order, rng, |s, t| GammaMetric { sample: s, template: t })
                }
                SquareMetric::Appearance => square_pass(square, state, order, rng, |s, t| AppearanceMetric {
                    map: s.appearance.as_ref().expect("checked in synthesize"),
                    template: t,
                }),
                SquareMetric::Colour => square_pass(square, state, order, rng, |s, t| AppearanceMetric {
                    map: s.colour.as_ref().expect("checked in synthesize"),
                    template: t,
                }),
            })
        }
    }
}

/// Runs a square-template pass whose own and parent templates `metric` builds.
fn square_pass<'a, M: Metric + Sync>(
    (inputs, template, plan): (&LevelInputs<'a>, SquareTemplate, &PassPlan),
    state: &mut State,
    order: &Schedule,
    rng: &mut ChaCha8Rng,
    metric: impl Fn(&'a SampleLevel, usize) -> M,
) -> PassStats {
    let (l, target, level_sample) = (inputs.l, &inputs.targets[inputs.l], &inputs.levels[inputs.l]);
    let own = metric(level_sample, target.template);
    let parent = match (template.parent(), inputs.coarse) {
        (Some(ParentTemplate::Narrow), Some(coarse)) => Some(Parent {
            state: coarse,
            metric: metric(&inputs.levels[l + 1], target.parent_template),
            wide: None,
        }),
        (Some(ParentTemplate::Wide), Some(coarse)) => {
            let coarser = &inputs.targets[l + 1];
            Some(Parent {
                state: coarse,
                metric: metric(&inputs.levels[l + 1], coarser.template),
                wide: Some(coarser),
            })
        }
        _ => None,
    };
    let make = || SquareMatch::new(target, level_sample, &own, parent.as_ref(), plan.mask);
    pass::run_scheduled_pass(target, state, level_sample, make, plan, order, rng)
}

/// Random patches on `target`, their seams matched with the metric `kind`; whether the
/// sample has edges of its own is judged on the `finest` level, whose texels are the
/// sample's own rather than averages reaching across its border.
fn patches<'a>(
    kind: MetricKind,
    target: &TargetLevel,
    (sample, levels): (&'a SampleLevel, &'a [SampleLevel]),
    sizes: (usize, f32, usize),
    rng: &mut ChaCha8Rng,
) -> Result<start::PatchStart> {
    let template = target.template;
    let margin = sizes.0;
    let finest = &levels[0];
    let coarser = finest.width as f32 / sample.width as f32;
    // On a mesh a lattice cannot be laid all around the surface, so its patches are not the
    // lattice's cells; each is still placed in phase with a placed neighbour's continuation,
    // and inside the sample, so that joints meet across its seams (docs/surfaces.md).
    let layout = |own_edges, lattice: &dyn Fn() -> Option<lattice::Lattice>| start::Layout {
        own_edges,
        lattice: lattice().map(|l| l.scaled(coarser)),
    };
    Ok(match kind {
        MetricKind::Gamma => {
            let metric = |level| GammaMetric { sample: level, template };
            let edges = start::own_edges(finest, &metric(finest), margin);
            let layout = layout(edges, &|| lattice::detect(levels, |l| Some(metric(l))));
            start::patch_state(target, sample, &metric(sample), sizes, layout, rng)
        }
        MetricKind::Appearance | MetricKind::Colour => {
            let metric_if_mapped = |level: &'a SampleLevel| {
                let map = if kind == MetricKind::Colour { &level.colour } else { &level.appearance };
                map.as_ref().map(|map| AppearanceMetric { map, template })
            };
            let metric = |level| metric_if_mapped(level).expect("checked in synthesize");
            let edges = start::own_edges(finest, &metric(finest), margin);
            let layout = layout(edges, &|| lattice::detect(levels, metric_if_mapped));
            start::patch_state(target, sample, &metric(sample), sizes, layout, rng)
        }
        MetricKind::Adaptive => {
            return Err(Error::invalid(
                "random patches are seamed with square templates, not adaptive passes",
            ))
        }
    })
}

/// The k-coherence k is capped by the lists the analysis stored.
fn capped(search: Search, sample: &SampleLevel) -> Search {
    match search {
        Search::KCoherence { k } => Search::KCoherence { k: k.min(sample.k) },
        other => other,
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
        device: None,
    }
}

#[cfg(test)]
mod tests {
    use super::kept_places;

    /// A vertex keeps the start's place within its texel only while it copies the texel it
    /// started on.
    #[test]
    fn a_moved_vertex_loses_its_place_within_the_texel() {
        let started = [[4, 4], [5, 4], [6, 4]];
        let now = [[4, 4], [9, 1], [6, 4]];
        let places = vec![[0.25, -0.1], [0.4, 0.4], [-0.3, 0.2]];
        assert_eq!(kept_places(&now, &started, places), [[0.25, -0.1], [0.0, 0.0], [-0.3, 0.2]]);
    }
}
