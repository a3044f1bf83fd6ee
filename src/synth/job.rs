//! One pass with everything it reads, as the synthesis loop hands it to the device that
//! runs it ([`super::device`]): a leaf, so that the dispatch and the GPU passes
//! (`super::gpu`, feature `gpu`) both name it without using each other.

use super::candidates::Search;
use super::engine::State;
use super::pass::Schedule;
use super::recipe::Pass;
use super::sample::SampleLevel;
use super::target::TargetLevel;

/// One pass as the GPU sees it: the pass, its capped search, its level and what it reads.
#[cfg_attr(not(feature = "gpu"), allow(dead_code))]
pub(crate) struct PassJob<'a> {
    /// The pass.
    pub pass: &'a Pass,
    /// Its search, the k-coherence k capped by the analysis' lists.
    pub search: Search,
    /// The level's index (0 the finest).
    pub level: usize,
    /// The level.
    pub target: &'a TargetLevel,
    /// The next coarser level, if any.
    pub coarser: Option<&'a TargetLevel>,
    /// The sample level matched.
    pub sample: &'a SampleLevel,
    /// The next coarser sample level, if any.
    pub coarse_sample: Option<&'a SampleLevel>,
    /// The coarser level's final state (none on the coarsest level).
    pub coarse: Option<&'a State>,
    /// How the pass visits the level.
    pub schedule: &'a Schedule<'a>,
    /// Per vertex, the factor on moving ([`super::engine::PassPlan::move_cost`]).
    pub move_costs: Option<&'a [f32]>,
}
