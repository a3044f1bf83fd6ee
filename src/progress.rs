//! Progress reporting without terminal code in the library: long operations take a
//! `&dyn Progress`, the CLI passes a progress bar, tests and library users pass [`Silent`].

/// Receives progress of long-running work. Implementations must be cheap and thread-safe:
/// `advance` is called from rayon workers.
pub trait Progress: Sync {
    /// A new stage begins with `total` units of work.
    fn start(&self, stage: &str, total: u64);
    /// `units` more units of the current stage are done.
    fn advance(&self, units: u64);
    /// The current stage is complete.
    fn finish(&self);
}

/// Discards all progress reports.
pub struct Silent;

impl Progress for Silent {
    fn start(&self, _stage: &str, _total: u64) {}
    fn advance(&self, _units: u64) {}
    fn finish(&self) {}
}
