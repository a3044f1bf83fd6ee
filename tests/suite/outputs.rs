//! "Nothing is lost": the rules every output follows, `-o` and `--report` alike. An output
//! that is, holds or lies inside an input is refused; an existing output is replaced only
//! with `--force`; a device or FIFO is written into (or refused), never renamed over; a
//! directory that replaces a file leaves nothing hidden behind; and the same inputs give the
//! same bytes, with wall-clock times only in `--report`.

use crate::common;

use common::{assert_one_line_error, btfsynth, entries, BUNNY};
use std::os::unix::fs::FileTypeExt;
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Every file under `dir` with its bytes, sorted by path (to see that nothing changed).
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((p.display().to_string(), std::fs::read(&p).unwrap_or_default()));
            }
        }
    }
    out.sort();
    out
}

/// A 4-image generated stack in `dir/name`.
fn small_stack(dir: &Path, name: &str) -> std::path::PathBuf {
    let out = dir.join(name);
    let r = btfsynth(&[
        "-q",
        "gen",
        "pebbles",
        "--size",
        "16",
        "--directions",
        "grid:2",
        "--spp",
        "1",
        "-o",
        s(&out),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    out
}

#[test]
fn an_output_that_is_holds_or_lies_inside_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "a");
    let a = s(&analysis);
    let before = snapshot(&analysis);
    let r = btfsynth(&["synth", a, "--plane", "16x16", "-o", a, "--force"]);
    assert_one_line_error(&r, "is the input");
    let r = btfsynth(&["synth", a, "--plane", "16x16", "-o", &format!("{a}/plane")]);
    assert_one_line_error(&r, "lies inside the input");
    let r = btfsynth(&["synth", a, "--plane", "16x16", "-o", &format!("{a}/../a/"), "--force"]);
    assert_one_line_error(&r, "is the input");
    let r = btfsynth(&["analyze", a, "-o", a, "--force"]);
    assert_one_line_error(&r, "is the input");
    assert_eq!(snapshot(&analysis), before, "the analysis is untouched");

    let stack = small_stack(dir.path(), "st");
    let st = s(&stack);
    let before = snapshot(&stack);
    assert_one_line_error(&btfsynth(&["analyze", st, "-o", st, "--force"]), "is the input");
    let manifest = stack.join("btf.json");
    let r = btfsynth(&["analyze", s(&manifest), "-o", &format!("{st}/analysis")]);
    assert_one_line_error(&r, "lies inside the input");
    assert_one_line_error(&btfsynth(&["convert", st, "-o", st, "--force"]), "is the input");
    assert_eq!(snapshot(&stack), before, "the stack is untouched");

    // A picture, and the directory holding it.
    let photos = dir.path().join("photos");
    std::fs::create_dir(&photos).unwrap();
    let image = photos.join("i.png");
    common::write_png(&image, 16, 16, common::pattern(3));
    let bytes = std::fs::read(&image).unwrap();
    let r = btfsynth(&["relight", s(&image), "--view", "0,0", "--light", "30,0", "-o", s(&image), "--force"]);
    assert_one_line_error(&r, "is the input");
    let r = btfsynth(&["analyze", s(&image), "--levels", "1", "-o", s(&photos), "--force"]);
    assert_one_line_error(&r, "holds the input");
    assert_eq!(std::fs::read(&image).unwrap(), bytes);

    // A mesh: remesh over its own input.
    let mesh = dir.path().join("m.obj");
    std::fs::copy(BUNNY, &mesh).unwrap();
    let r = btfsynth(&["remesh", s(&mesh), "--vertices", "300", "-o", s(&mesh), "--force"]);
    assert_one_line_error(&r, "is the input");
    assert_eq!(std::fs::read(&mesh).unwrap(), std::fs::read(BUNNY).unwrap());

    // The analysis a surface map names is an input of export and render, given or not.
    let ply = dir.path().join("s.ply");
    let r = btfsynth(&["-q", "synth", a, BUNNY, "--vertices", "1500", "-o", s(&ply)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let before = snapshot(&analysis);
    let r = btfsynth(&["export", s(&ply), "-o", &format!("{a}/x.glb")]);
    assert_one_line_error(&r, "lies inside the input");
    let r = btfsynth(&["render", s(&ply), "--size", "16x16", "-o", &format!("{a}/frames")]);
    assert_one_line_error(&r, "lies inside the input");
    assert_eq!(snapshot(&analysis), before, "the analysis is untouched");
}

#[test]
fn a_report_follows_the_outputs_rules() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "a");
    let a = s(&analysis);
    let manifest = std::fs::read(analysis.join("analysis.json")).unwrap();
    let plane = dir.path().join("p");
    let p = s(&plane);
    let r = btfsynth(&["synth", a, "--plane", "16x16", "-o", p, "--report", &format!("{a}/analysis.json")]);
    assert_one_line_error(&r, "lies inside the input");
    assert_eq!(std::fs::read(analysis.join("analysis.json")).unwrap(), manifest, "the analysis is untouched");
    let mesh = dir.path().join("m.obj");
    std::fs::copy(BUNNY, &mesh).unwrap();
    let ply = dir.path().join("s.ply");
    let r = btfsynth(&["synth", a, s(&mesh), "--vertices", "1500", "-o", s(&ply), "--report", s(&mesh)]);
    assert_one_line_error(&r, "is the input");
    let r = btfsynth(&["synth", a, s(&mesh), "--vertices", "1500", "-o", s(&ply), "--report", s(&ply)]);
    assert_one_line_error(&r, "is the output");
    std::fs::create_dir(&plane).unwrap();
    let r = btfsynth(&[
        "synth",
        a,
        "--plane",
        "16x16",
        "-o",
        p,
        "--report",
        &format!("{p}/report.json"),
        "--force",
    ]);
    assert_one_line_error(&r, "lies inside the output");
    std::fs::remove_dir(&plane).unwrap();
    assert_eq!(std::fs::read(&mesh).unwrap(), std::fs::read(BUNNY).unwrap(), "the mesh is untouched");
    assert!(!ply.exists() && !plane.exists());

    // An existing report is replaced only with --force, like -o.
    let report = dir.path().join("r.json");
    std::fs::write(&report, b"keep").unwrap();
    let r = btfsynth(&["synth", a, "--plane", "16x16", "-o", p, "--report", s(&report)]);
    assert_one_line_error(&r, "already exists (pass --force");
    assert_eq!(std::fs::read(&report).unwrap(), b"keep");
    assert!(!plane.exists(), "nothing was written");
    let r = btfsynth(&["-q", "synth", a, "--plane", "16x16", "-o", p, "--report", s(&report), "--force"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert!(json["levels"][0]["seconds"].as_f64().is_some(), "the timings are in the report: {json}");
    let hidden: Vec<String> = entries(dir.path()).into_iter().filter(|e| e.starts_with('.')).collect();
    assert!(hidden.is_empty(), "{hidden:?}");
}

/// Makes a FIFO at `path`.
fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: `c` is a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0, "mkfifo {}", path.display());
}

fn is_fifo(path: &Path) -> bool {
    std::fs::symlink_metadata(path).unwrap().file_type().is_fifo()
}

#[test]
fn devices_and_fifos_are_written_into_or_refused_never_replaced() {
    let dir = tempfile::tempdir().unwrap();
    // An existing device is an existing output: a file output goes into /dev/null with
    // --force only.
    let r = btfsynth(&["-q", "remesh", BUNNY, "--vertices", "300", "-o", "/dev/null"]);
    assert_one_line_error(&r, "/dev/null already exists (pass --force");
    let r = btfsynth(&["-q", "remesh", BUNNY, "--vertices", "300", "-o", "/dev/null", "--force"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(
        std::fs::metadata("/dev/null").unwrap().file_type().is_char_device(),
        "/dev/null is still a device"
    );
    // A full device is one error line.
    let r = btfsynth(&["-q", "remesh", BUNNY, "--vertices", "300", "-o", "/dev/full", "--force"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(
        errors,
        ["error: /dev/full: cannot write into this device: No space left on device (os error 28)"]
    );
    // A directory output cannot go into a device.
    let r =
        btfsynth(&["gen", "pebbles", "--size", "8", "--directions", "grid:2", "-o", "/dev/null", "--force"]);
    assert_one_line_error(&r, "/dev/null is a device");
    assert!(std::fs::metadata("/dev/null").unwrap().file_type().is_char_device());

    // A FIFO: a file output streams into it, a directory output is refused.
    let fifo = dir.path().join("fifo");
    mkfifo(&fifo);
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(&fifo).unwrap())
    };
    let r = btfsynth(&["-q", "remesh", BUNNY, "--vertices", "300", "-o", s(&fifo)]);
    if !r.status.success() {
        // Let the reader go before failing.
        let _ = std::fs::OpenOptions::new().write(true).open(&fifo);
        panic!("{}", String::from_utf8_lossy(&r.stderr));
    }
    let streamed = reader.join().unwrap();
    assert!(streamed.starts_with(b"ply\n"), "the PLY went through the FIFO");
    assert!(is_fifo(&fifo), "the FIFO is still a FIFO");
    let r = btfsynth(&["gen", "pebbles", "--size", "8", "--directions", "grid:2", "-o", s(&fifo), "--force"]);
    assert_one_line_error(&r, "is a FIFO");
    assert!(is_fifo(&fifo));
    assert_eq!(entries(dir.path()), ["fifo"], "nothing left behind");
}

#[test]
fn a_directory_output_replaces_a_file_and_a_file_output_never_replaces_a_directory() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::write(&out, b"a file").unwrap();
    let r = btfsynth(&["-q", "gen", "pebbles", "--size", "8", "--directions", "grid:2", "-o", s(&out)]);
    assert_one_line_error(&r, "already exists (pass --force");
    let r = btfsynth(&[
        "-q",
        "gen",
        "pebbles",
        "--size",
        "8",
        "--directions",
        "grid:2",
        "-o",
        s(&out),
        "--force",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(out.join("btf.json").is_file());
    assert_eq!(entries(dir.path()), ["out"], "no .out.old-PID left behind");
    // A mesh output over the directory: refused, the directory stays.
    let r = btfsynth(&["-q", "remesh", BUNNY, "--vertices", "300", "-o", s(&out), "--force"]);
    assert_one_line_error(&r, "is a directory");
    assert!(out.join("btf.json").is_file());
}

#[test]
fn the_same_inputs_give_the_same_bytes_whatever_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let texture = concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png");
    let analyze = |name: &str, threads: &str| {
        let out = dir.path().join(name);
        let args = ["-q", "--threads", threads, "analyze", texture, "--crop", "0,0,48,48", "--textons", "32"];
        let r = btfsynth(&[&args[..], &["--levels", "2", "-o", s(&out)]].concat());
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        out
    };
    let (a1, a2) = (analyze("a1", "1"), analyze("a2", "2"));
    let manifest = |d: &Path| std::fs::read_to_string(d.join("analysis.json")).unwrap();
    assert_eq!(manifest(&a1), manifest(&a2).replace("/a2", "/a1"), "analysis.json is the same bytes");
    assert!(!manifest(&a1).contains("timings") && !manifest(&a1).contains("peak_memory"));
    let plane = |name: &str, threads: &str| {
        let out = dir.path().join(name);
        let r = btfsynth(&["-q", "--threads", threads, "synth", s(&a1), "--plane", "24x24", "-o", s(&out)]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        std::fs::read_to_string(out.join("plane.json")).unwrap()
    };
    assert_eq!(plane("p1", "1"), plane("p2", "2"), "plane.json is the same bytes");
    // The times are in the report.
    let report = dir.path().join("report.json");
    let out = dir.path().join("a3");
    let r = btfsynth(&[
        "-q",
        "analyze",
        texture,
        "--crop",
        "0,0,48,48",
        "--textons",
        "32",
        "--levels",
        "2",
        "--report",
        s(&report),
        "-o",
        s(&out),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert!(json["timings_s"]["total"].as_f64().is_some(), "{json}");
}

#[test]
fn a_demo_replaces_only_an_earlier_demo() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mine");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("thesis.tex"), b"years of work").unwrap();
    let r = btfsynth(&["demo", "-o", s(&out)]);
    assert_one_line_error(&r, "holds files the demo does not write (thesis.tex)");
    assert_eq!(std::fs::read(out.join("thesis.tex")).unwrap(), b"years of work");
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/data");
    let r = btfsynth(&["demo", "--data", data, "-o", &format!("{data}/demo-out")]);
    assert_one_line_error(&r, "lies inside the input");
}

/// Every image a `btf.json` names is an input of every command that reads the stack,
/// wherever it lies (`"file": "../a.png"`, outside the manifest's folder, or beside the
/// manifest): no output replaces one, `--force` or not.
#[test]
fn every_image_a_manifest_names_is_an_input_of_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("m");
    std::fs::create_dir(&folder).unwrap();
    let (outside, inside) = (dir.path().join("outside_a.png"), folder.join("b.png"));
    common::write_png(&outside, 16, 16, common::pattern(1));
    common::write_png(&inside, 16, 16, common::pattern(2));
    let manifest = folder.join("btf.json");
    let images = r#"{"images": [{"file": "../outside_a.png", "light": [0, 0], "view": [0, 0]},
        {"file": "b.png", "light": [30, 0], "view": [0, 0]}]}"#;
    std::fs::write(&manifest, images).unwrap();
    let before = [std::fs::read(&outside).unwrap(), std::fs::read(&inside).unwrap()];
    for stack in [&manifest, &folder] {
        for out in [&outside, &inside] {
            let light = ["--view", "0,0", "--light", "0,0"];
            for command in [&["analyze"][..], &["convert"], &[&["relight"][..], &light[..]].concat()] {
                let args = [command, &[s(stack), "-o", s(out), "--force"]].concat();
                assert_one_line_error(&btfsynth(&args), "inputs are never replaced");
            }
        }
    }
    assert_eq!([std::fs::read(&outside).unwrap(), std::fs::read(&inside).unwrap()], before);
    assert_eq!(entries(dir.path()), ["m", "outside_a.png"], "nothing left behind");
    assert_eq!(entries(&folder), ["b.png", "btf.json"]);
}
