//! What tests may find missing on a user's machine, and how they skip without it.
//!
//! **Shared data.** The real meshes and photographs that may not ship with btfsynth live in
//! `../shared/data` beside the checkout (our CI and working setup); a user's clone has no
//! such folder. A test that needs them calls [`shared_data`] and returns early on `None`:
//! one line on stderr says what was skipped and why. CI sets `BTFSYNTH_REQUIRE_SHARED=1`,
//! which turns a missing file into a failure, so the tests can never be skipped there
//! silently.
//!
//! **A GPU.** Tests of the wgpu renderer need an adapter (Mesa's lavapipe or llvmpipe is
//! enough). Where a run reports none, [`gpu_missing`] prints one line and the test returns;
//! CI sets `BTFSYNTH_REQUIRE_GPU=1`, which turns a missing adapter into a failure.
//! `BTFSYNTH_SKIP_GPU=1` skips the GPU tests outright ([`gpu_skipped`]).

use std::io::Write;
use std::path::{Path, PathBuf};

/// Prints `skipped: <test>: <why>` straight to the process's stderr. `eprintln!` would be
/// captured by the test harness and shown only for failing tests, so a user running
/// `cargo test` would never learn that a test skipped.
pub fn announce_skip(test: &str, why: &str) {
    let _ = writeln!(std::io::stderr(), "skipped: {test}: {why}");
}

/// The environment variable that makes missing shared data a failure (set by `.ci/run`).
pub const REQUIRE_SHARED: &str = "BTFSYNTH_REQUIRE_SHARED";

/// The folder of shared data, whether or not it exists.
pub fn shared_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data")
}

/// `../shared/data/<relative>` if it exists. If not, prints `skipped: <test>: …` and
/// returns `None`, or panics when [`REQUIRE_SHARED`] is `1`.
pub fn shared_data(test: &str, relative: &str) -> Option<PathBuf> {
    match shared_data_in(&shared_root(), test, relative, env_is_one(REQUIRE_SHARED)) {
        Ok(path) => Some(path),
        Err(why) => {
            announce_skip(test, &why);
            None
        }
    }
}

/// [`shared_data`] against an explicit root and requirement, silent (so the skip path is
/// testable): the path, or why the test skips.
pub fn shared_data_in(root: &Path, test: &str, relative: &str, required: bool) -> Result<PathBuf, String> {
    let path = root.join(relative);
    if path.exists() {
        return Ok(path);
    }
    let why = format!("{} is absent (real data that may not ship; see docs/testing.md)", path.display());
    if required {
        panic!("{test}: {why}, and {REQUIRE_SHARED}=1 requires it");
    }
    Err(why)
}

/// The environment variable that makes a missing GPU adapter a failure (set by `.ci/run`).
pub const REQUIRE_GPU: &str = "BTFSYNTH_REQUIRE_GPU";

/// The environment variable that skips the GPU tests without trying the GPU.
pub const SKIP_GPU: &str = "BTFSYNTH_SKIP_GPU";

/// What `btfsynth view` says when wgpu finds no adapter (the start of its error line).
pub const NO_ADAPTER_MESSAGE: &str = "no GPU adapter found";

fn env_is_one(name: &str) -> bool {
    std::env::var(name).is_ok_and(|v| v == "1")
}

/// True (after printing `skipped: <test>: …`) if [`SKIP_GPU`] asks to skip the GPU tests
/// and [`REQUIRE_GPU`] does not forbid it.
pub fn gpu_skipped(test: &str) -> bool {
    let skip = env_is_one(SKIP_GPU) && !env_is_one(REQUIRE_GPU);
    if skip {
        announce_skip(test, &format!("{SKIP_GPU}=1"));
    }
    skip
}

/// True (after printing `skipped: <test>: …`) if a GPU run failed with `stderr` because
/// there is no adapter; panics instead when [`REQUIRE_GPU`] is `1`. False for any other
/// outcome, which the test then judges itself.
pub fn gpu_missing(test: &str, stderr: &str) -> bool {
    let why = gpu_missing_in(test, stderr, env_is_one(REQUIRE_GPU));
    if let Some(why) = why {
        announce_skip(test, why);
    }
    why.is_some()
}

/// [`gpu_missing`] with an explicit requirement, silent (so the skip path is testable): why
/// the test skips, if it does.
pub fn gpu_missing_in(test: &str, stderr: &str, required: bool) -> Option<&'static str> {
    if !stderr.contains(NO_ADAPTER_MESSAGE) {
        return None;
    }
    let why = "wgpu found no adapter (install Mesa's software drivers: apt-get install mesa-vulkan-drivers \
               libvulkan1 libegl1 libegl-mesa0 libgl1-mesa-dri)";
    if required {
        panic!("{test}: {why}, and {REQUIRE_GPU}=1 requires one; {stderr}");
    }
    Some(why)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_file_skips_unless_required() {
        let root = Path::new("/nonexistent-btfsynth-shared");
        let why = shared_data_in(root, "t", "meshes/x.obj", false).unwrap_err();
        assert!(why.contains("meshes/x.obj is absent"), "{why}");
        let required = std::panic::catch_unwind(|| shared_data_in(root, "t", "meshes/x.obj", true));
        assert!(required.is_err(), "a required missing file must fail the test");
        let here = Path::new(env!("CARGO_MANIFEST_DIR"));
        assert_eq!(shared_data_in(here, "t", "Cargo.toml", true), Ok(here.join("Cargo.toml")));
    }

    #[test]
    fn a_missing_adapter_skips_unless_required() {
        let none = format!("error: {NO_ADAPTER_MESSAGE} (wgpu found no Vulkan, Metal, DX12 or GL device)");
        assert!(gpu_missing_in("t", &none, false).is_some_and(|why| why.contains("no adapter")));
        let required = std::panic::catch_unwind(|| gpu_missing_in("t", &none, true));
        assert!(required.is_err(), "a required missing adapter must fail the test");
        assert_eq!(
            gpu_missing_in("t", "error: Format Rgba32Float is not renderable", false),
            None,
            "other failures are not skips"
        );
        assert_eq!(gpu_missing_in("t", "", true), None, "a run that found an adapter is not a skip");
    }
}
