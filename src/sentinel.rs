//! Index sentinels the analysis and the synthesis engine share. A leaf: it uses nothing,
//! so both can name it without an import cycle.

/// Marks a neighbourhood slot outside the sample or patch: an index no vertex or pixel has.
pub const OUTSIDE: u32 = u32::MAX;
