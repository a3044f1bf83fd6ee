//! Standard output and error as a pipeline sees them: a closed stdout (`| head`, `| true`)
//! ends the run quietly, a full one (`> /dev/full`) is one error line, and log lines carry
//! no colour codes when stderr is not a terminal.

use crate::common;

use common::BUNNY;
use std::os::fd::{FromRawFd, OwnedFd};
use std::process::{Command, Output, Stdio};

/// A pipe whose read end is already closed: every write to the other end fails (EPIPE).
fn closed_pipe() -> OwnedFd {
    let mut fds = [0; 2];
    // SAFETY: `fds` has room for the two descriptors pipe(2) returns.
    assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
    // SAFETY: both descriptors were just created and are owned here alone.
    let (read, write) = unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) };
    drop(read);
    write
}

fn run_with_stdout(args: &[&str], stdout: Stdio) -> Output {
    Command::new(env!("CARGO_BIN_EXE_btfsynth"))
        .args(args)
        .env_remove("RUST_LOG")
        .stdout(stdout)
        .stderr(Stdio::piped())
        .output()
        .unwrap()
}

#[test]
fn a_closed_stdout_ends_the_run_quietly() {
    let texture = concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png");
    for args in [
        vec!["synth", "--list-presets"],
        vec!["gen", "--list"],
        vec!["info", BUNNY],
        vec!["info", BUNNY, "--json"],
        vec!["info", texture],
    ] {
        let out = run_with_stdout(&args, Stdio::from(closed_pipe()));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {stderr}");
        assert!(stderr.trim().is_empty(), "{args:?} says nothing: {stderr}");
    }
}

#[test]
fn a_full_stdout_is_one_error_line() {
    for args in [vec!["info", BUNNY, "--json"], vec!["synth", "--list-presets"]] {
        let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
        let out = run_with_stdout(&args, Stdio::from(full));
        common::assert_one_line_error(&out, "cannot write to standard output: No space left on device");
    }
}

#[test]
fn log_lines_carry_no_colour_codes_off_a_terminal() {
    let dir = tempfile::tempdir().unwrap();
    // Two triangles of a square, one written the other way round: loading warns.
    let mesh = dir.path().join("flipped.obj");
    std::fs::write(
        &mesh,
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\nf 2 3 1\nv 2 0 0\nf 2 5 3\nf 1 4 3\n",
    )
    .unwrap();
    let out = run_with_stdout(&["info", mesh.to_str().unwrap()], Stdio::null());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("WARN"), "the mesh gives a warning: {stderr}");
    assert!(!stderr.contains('\u{1b}'), "no ANSI escape codes: {stderr:?}");
}
