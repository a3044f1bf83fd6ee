//! Ctrl-C (SIGINT) or SIGTERM in the middle of a run: the process removes its unfinished
//! outputs (hidden `.NAME.tmp-PID` siblings) and exits with code 130, leaving the output
//! directory as it was.
//!
//! `render` and `gen` are interrupted while they write files into their staging
//! directories. `analyze` and `synth` stage their outputs only for the moment it takes to
//! write them, so those runs set `BTFSYNTH_TEST_HOLD_STAGING_MS`, which keeps each
//! temporary on disk a while once it exists, and the signal is sent then.

use crate::common;

use common::{btfsynth, entries, BUNNY};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Hidden entries of `dir` (where the staged outputs live).
fn hidden(dir: &Path) -> Vec<String> {
    entries(dir).into_iter().filter(|e| e.starts_with('.')).collect()
}

/// Runs `btfsynth args` in `dir` until `ready(dir)` holds, sends `signal`, and checks that
/// the run ends with code 130, one line saying so, and `dir` as it was before the run.
fn interrupt(dir: &Path, args: &[&str], signal: &str, hold: bool, ready: impl Fn(&Path) -> bool) {
    let before = entries(dir);
    let mut command = Command::new(env!("CARGO_BIN_EXE_btfsynth"));
    command.args(args).current_dir(dir).stdout(Stdio::null()).stderr(Stdio::piped());
    if hold {
        command.env(btfsynth::fsutil::HOLD_STAGING_ENV, "20000");
    }
    let mut child = command.spawn().unwrap();
    let deadline = Instant::now() + Duration::from_secs(300);
    while !ready(dir) {
        if let Some(status) = child.try_wait().unwrap() {
            let out = child.wait_with_output().unwrap();
            panic!(
                "{args:?} ended ({status}) before it could be interrupted: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        assert!(Instant::now() < deadline, "{args:?}: never reached the point to interrupt");
        std::thread::sleep(Duration::from_millis(2));
    }
    let killed = Command::new("kill").args([signal, &child.id().to_string()]).status().unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{args:?} after {signal}: {stderr}");
    let last = stderr.lines().rfind(|l| !l.trim().is_empty());
    assert_eq!(last, Some("error: interrupted; unfinished outputs were removed"), "{stderr}");
    // Off a terminal there is no ^C echo to step past: no blank line.
    assert!(!stderr.lines().any(|l| l.trim().is_empty()), "no blank line: {stderr:?}");
    assert!(!stderr.contains("panicked") && !stderr.contains("internal error"), "{stderr}");
    assert_eq!(entries(dir), before, "{args:?}: nothing left behind after {signal}");
}

/// True once a temporary output (`.NAME.tmp-PID`) exists in `dir`.
fn staged(dir: &Path) -> bool {
    hidden(dir).iter().any(|h| h.contains(".tmp-"))
}

/// True once a hidden directory in `dir` holds at least one file.
fn staging_has_files(dir: &Path) -> bool {
    hidden(dir).iter().any(|h| !entries(&dir.join(h)).is_empty())
}

#[test]
fn an_interrupted_render_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    let r = btfsynth(&[
        "-q",
        "synth",
        analysis.to_str().unwrap(),
        BUNNY,
        "--vertices",
        "1500",
        "-o",
        dir.path().join("bunny.ply").to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // Interrupted once a few frames of a long orbit are on disk, by Ctrl-C and by SIGTERM.
    let args = ["-q", "render", "bunny.ply", "--size", "256x256", "--frames", "400", "-o", "frames"];
    interrupt(dir.path(), &args, "-INT", false, staging_has_files);
    interrupt(dir.path(), &args, "-TERM", false, staging_has_files);
}

#[test]
fn an_interrupted_gen_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    // 6561 small images: interrupted while they are being written.
    let args = ["-q", "gen", "pebbles", "--size", "8", "--spp", "1", "--format", "png", "-o", "stack"];
    interrupt(dir.path(), &args, "-INT", false, staging_has_files);
}

#[test]
fn an_interrupted_analyze_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let texture = concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png");
    let args = [
        "-q",
        "analyze",
        texture,
        "--crop",
        "0,0,48,48",
        "--textons",
        "32",
        "--levels",
        "2",
        "-o",
        "analysis",
    ];
    interrupt(dir.path(), &args, "-INT", true, staged);
}

#[test]
fn an_interrupted_synth_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    let a = analysis.to_str().unwrap();
    let surface = ["-q", "synth", a, BUNNY, "--vertices", "1500", "-o", "bunny.ply"];
    interrupt(dir.path(), &surface, "-INT", true, staged);
    let plane = ["-q", "synth", a, "--plane", "32x32", "-o", "plane"];
    interrupt(dir.path(), &plane, "-TERM", true, staged);
}

#[test]
fn an_interrupted_conversion_keeps_the_old_output() {
    let dir = tempfile::tempdir().unwrap();
    let gen = ["-q", "gen", "pebbles", "--size", "16", "--directions", "grid:3", "--spp", "1", "-o", "stack"];
    let r = common::btfsynth_in(dir.path(), &gen);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let r =
        common::btfsynth_in(dir.path(), &["-q", "convert", "stack", "-o", "old.btf", "--components", "2"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let old = std::fs::read(dir.path().join("old.btf")).unwrap();
    // The new file is written, then decoded back to measure it, then put in place: a
    // signal before the end leaves the old file.
    let args = ["-q", "convert", "stack", "-o", "old.btf", "--components", "4", "--force"];
    interrupt(dir.path(), &args, "-TERM", true, staged);
    assert_eq!(std::fs::read(dir.path().join("old.btf")).unwrap(), old, "the old output is intact");
}

#[test]
fn an_interrupted_demo_leaves_nothing_and_keeps_an_earlier_one() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("demo-out")).unwrap();
    std::fs::write(dir.path().join("demo-out").join("bunny.ply"), b"an earlier demo").unwrap();
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/data");
    interrupt(dir.path(), &["-q", "demo", "--data", data], "-INT", true, staged);
    let kept = std::fs::read(dir.path().join("demo-out").join("bunny.ply")).unwrap();
    assert_eq!(kept, b"an earlier demo");
    assert_eq!(entries(&dir.path().join("demo-out")), ["bunny.ply"], "nothing merged into it");
}

#[test]
fn an_interrupt_after_the_commit_says_what_was_written() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_btfsynth"))
        .args(["-q", "remesh", BUNNY, "--vertices", "300", "-o", "out.ply"])
        .current_dir(dir.path())
        .env(btfsynth::fsutil::HOLD_COMMITTED_ENV, "20000")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(120);
    while !dir.path().join("out.ply").exists() {
        assert!(child.try_wait().unwrap().is_none(), "remesh ended before it could be interrupted");
        assert!(Instant::now() < deadline, "remesh never wrote its output");
        std::thread::sleep(Duration::from_millis(2));
    }
    let killed = Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    let last = stderr.lines().rfind(|l| !l.trim().is_empty());
    assert_eq!(
        last,
        Some("error: interrupted after writing out.ply; unfinished outputs were removed"),
        "the message is true: {stderr}"
    );
    assert_eq!(entries(dir.path()), ["out.ply"], "the whole output, nothing else");
    assert!(std::fs::read(dir.path().join("out.ply")).unwrap().starts_with(b"ply\n"));
}

/// A child killed (and reaped) however the test ends.
struct Reaped(std::process::Child);

impl Drop for Reaped {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Whether the process `pid` is blocked opening a FIFO: its main thread waits for the FIFO's
/// other end (Linux names the wait `wait_for_partner`), or sits in `openat`.
fn opening_a_fifo(pid: u32) -> bool {
    let proc = |file: &str| std::fs::read_to_string(format!("/proc/{pid}/{file}")).unwrap_or_default();
    let wchan = proc("wchan");
    let openat = match std::env::consts::ARCH {
        "x86_64" => "257",
        "aarch64" => "56",
        _ => "",
    };
    wchan.contains("partner")
        || wchan.contains("fifo")
        || (!openat.is_empty() && proc("syscall").split_whitespace().next() == Some(openat))
}

/// An output into a FIFO nobody reads blocks in the commit; Ctrl-C then still ends the run
/// (the commit does not hold what the signal handler needs while it waits), with code 130 and
/// no temporary left.
#[test]
fn an_interrupt_while_a_fifo_output_waits_for_a_reader_ends_the_run() {
    let dir = tempfile::tempdir().unwrap();
    assert!(Command::new("mkfifo").arg(dir.path().join("f")).status().unwrap().success());
    let mut child = Reaped(
        Command::new(env!("CARGO_BIN_EXE_btfsynth"))
            .args(["-q", "remesh", BUNNY, "--vertices", "300", "-o", "f"])
            .current_dir(dir.path())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let pid = child.0.id();
    // Blocked once the temporary is written and the open of the FIFO waits (seen twice, so
    // that a passing `openat` of another file does not count).
    let blocked = || staged(dir.path()) && opening_a_fifo(pid);
    let deadline = Instant::now() + Duration::from_secs(120);
    while !(blocked() && {
        std::thread::sleep(Duration::from_millis(50));
        blocked()
    }) {
        assert!(child.0.try_wait().unwrap().is_none(), "remesh ended before it waited for a reader");
        assert!(Instant::now() < deadline, "remesh never came to wait for a reader");
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(Command::new("kill").args(["-INT", &pid.to_string()]).status().unwrap().success());
    let deadline = Instant::now() + Duration::from_secs(20);
    let status = loop {
        if let Some(status) = child.0.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "Ctrl-C did not end a run waiting for a FIFO's reader");
        std::thread::sleep(Duration::from_millis(5));
    };
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.0.stderr.take().unwrap(), &mut stderr).unwrap();
    assert_eq!(status.code(), Some(130), "{stderr}");
    assert_eq!(stderr.lines().last(), Some("error: interrupted; unfinished outputs were removed"));
    assert_eq!(entries(dir.path()), ["f"], "the FIFO, and no temporary");
}
