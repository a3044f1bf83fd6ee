//! Where tests find the real meshes and photographs that may not ship with btfsynth.
//!
//! They live in `../shared/data` beside the checkout (our CI and working setup); a user's
//! clone has no such folder. A test that needs them calls [`shared_data`] and returns early
//! on `None`: one line on stderr says what was skipped and why. CI sets
//! `BTFSYNTH_REQUIRE_SHARED=1`, which turns a missing file into a failure, so the tests
//! can never be skipped there silently.

use std::path::{Path, PathBuf};

/// The environment variable that makes missing shared data a failure (set by `.ci/run`).
pub const REQUIRE_SHARED: &str = "BTFSYNTH_REQUIRE_SHARED";

/// The folder of shared data, whether or not it exists.
pub fn shared_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data")
}

/// `../shared/data/<relative>` if it exists. If not, prints `skipped: <test>: …` and
/// returns `None`, or panics when [`REQUIRE_SHARED`] is `1`.
pub fn shared_data(test: &str, relative: &str) -> Option<PathBuf> {
    shared_data_in(&shared_root(), test, relative, std::env::var(REQUIRE_SHARED).is_ok_and(|v| v == "1"))
}

/// [`shared_data`] against an explicit root and requirement (so the skip path is testable).
pub fn shared_data_in(root: &Path, test: &str, relative: &str, required: bool) -> Option<PathBuf> {
    let path = root.join(relative);
    if path.exists() {
        return Some(path);
    }
    let why = format!("{} is absent (real data that may not ship; see README, Tests)", path.display());
    if required {
        panic!("{test}: {why}, and {REQUIRE_SHARED}=1 requires it");
    }
    eprintln!("skipped: {test}: {why}");
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_file_skips_unless_required() {
        let root = Path::new("/nonexistent-btfsynth-shared");
        assert_eq!(shared_data_in(root, "t", "meshes/x.obj", false), None);
        let required = std::panic::catch_unwind(|| shared_data_in(root, "t", "meshes/x.obj", true));
        assert!(required.is_err(), "a required missing file must fail the test");
        let here = Path::new(env!("CARGO_MANIFEST_DIR"));
        assert_eq!(shared_data_in(here, "t", "Cargo.toml", true), Some(here.join("Cargo.toml")));
    }
}
