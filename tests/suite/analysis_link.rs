//! A result and the analysis it was synthesized from: a surface map finds its analysis from
//! any working directory (relative to the map, else at its absolute path), and a result
//! offered the analysis of another sample is refused unless `--force-analysis`.

use crate::common;

use common::{assert_one_line_error, btfsynth, btfsynth_in, entries, BUNNY};
use std::path::Path;

/// Renders `ply` (a path as seen from `cwd`) into `cwd/frames-N`; returns the run.
fn render_in(cwd: &Path, ply: &str, extra: &[&str]) -> std::process::Output {
    let out = format!("frames-{}", entries(cwd).len());
    let args = [&["-q", "render", ply, "--size", "24x24", "-o", &out][..], extra].concat();
    btfsynth_in(cwd, &args)
}

#[test]
fn a_surface_map_finds_its_analysis_from_any_directory() {
    let dir = tempfile::tempdir().unwrap();
    let top = dir.path();
    std::fs::create_dir(top.join("work")).unwrap();
    common::analyze_gravel_crop(&top.join("work"), "analysis");
    // Synthesized from the parent directory, with paths relative to it (as the demo does).
    let r = btfsynth_in(
        top,
        &["-q", "synth", "work/analysis", BUNNY, "--vertices", "1500", "-o", "work/bunny.ply"],
    );
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    std::fs::create_dir(top.join("elsewhere")).unwrap();
    let elsewhere = top.join("elsewhere");

    let r = render_in(&elsewhere, "../work/bunny.ply", &[]);
    assert!(r.status.success(), "from another directory: {}", String::from_utf8_lossy(&r.stderr));

    // The map alone, copied away: found at the analysis' absolute path.
    std::fs::copy(top.join("work/bunny.ply"), elsewhere.join("alone.ply")).unwrap();
    let r = render_in(&elsewhere, "alone.ply", &[]);
    assert!(r.status.success(), "a copied map: {}", String::from_utf8_lossy(&r.stderr));

    // The map and its analysis moved together: found relative to the map.
    std::fs::rename(top.join("work"), top.join("moved")).unwrap();
    let r = render_in(&elsewhere, "../moved/bunny.ply", &[]);
    assert!(r.status.success(), "a moved pair: {}", String::from_utf8_lossy(&r.stderr));

    // Neither place holds it any more: one line, naming what is missing and the way out.
    let r = render_in(&elsewhere, "alone.ply", &[]);
    assert_one_line_error(&r, "--analysis DIR");
    assert!(String::from_utf8_lossy(&r.stderr).contains("analysis"), "names the analysis");
}

#[test]
fn an_analysis_of_another_sample_is_refused_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let own = common::analyze_gravel(dir.path(), "own", "0,0,48,48");
    let other = common::analyze_gravel(dir.path(), "other", "64,64,48,48");
    let (own_s, other_s) = (own.to_str().unwrap(), other.to_str().unwrap());
    let ply = dir.path().join("bunny.ply");
    let r = btfsynth(&["-q", "synth", own_s, BUNNY, "--vertices", "1500", "-o", ply.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let plane = dir.path().join("plane");
    let r = btfsynth(&["-q", "synth", own_s, "--plane", "24x24", "-o", plane.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let (ply_s, plane_s) = (ply.to_str().unwrap(), plane.to_str().unwrap());
    let frames = dir.path().join("frames");
    let f = frames.to_str().unwrap();

    let mismatch = "synthesized from an analysis of another sample";
    let refused = [
        btfsynth(&["render", ply_s, "--analysis", other_s, "--size", "24x24", "-o", f]),
        btfsynth(&["view", ply_s, "--analysis", other_s, "--headless", "-o", f]),
        btfsynth(&["eval", other_s, ply_s]),
        btfsynth(&["eval", other_s, plane_s]),
    ];
    for r in &refused {
        assert_one_line_error(r, mismatch);
        assert_one_line_error(r, "--force-analysis");
    }
    assert!(!frames.exists(), "nothing rendered");

    let forced = btfsynth(&[
        "-q",
        "render",
        ply_s,
        "--analysis",
        other_s,
        "--force-analysis",
        "--size",
        "24x24",
        "-o",
        f,
    ]);
    assert!(forced.status.success(), "{}", String::from_utf8_lossy(&forced.stderr));
    for result in [ply_s, plane_s] {
        let r = btfsynth(&["eval", other_s, result, "--force-analysis", "--json"]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let matched = btfsynth(&["eval", own_s, result, "--json"]);
        assert!(matched.status.success(), "its own analysis: {}", String::from_utf8_lossy(&matched.stderr));
    }
}

/// Names a header line cannot hold as they are (spaces at the end, a line break, bytes that
/// are not UTF-8) are recorded whole: a surface map and a soler2002 result find their own
/// analysis, not one whose name differs only there, and export finds the original mesh.
#[test]
fn odd_names_come_back_whole_from_a_results_header() {
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().unwrap();
    let gravel = common::analyze_gravel_crop(dir.path(), "gravel");
    let named = |bytes: &[u8]| dir.path().join(std::ffi::OsStr::from_bytes(bytes));
    // The analysis under an odd name, and a decoy under the name a lossy reading gives.
    let (odd, decoy) = (named(b"an sp \n\xe9 "), named(b"an sp"));
    for copy in [&odd, &decoy] {
        std::fs::create_dir(copy).unwrap();
        for file in std::fs::read_dir(&gravel).unwrap() {
            let file = file.unwrap().path();
            std::fs::copy(&file, copy.join(file.file_name().unwrap())).unwrap();
        }
    }
    let mesh = named(b"bu\nny \xe9 .obj");
    std::fs::copy(BUNNY, &mesh).unwrap();
    let run = |args: &[&std::ffi::OsStr]| {
        let r =
            std::process::Command::new(env!("CARGO_BIN_EXE_btfsynth")).arg("-q").args(args).output().unwrap();
        assert!(r.status.success(), "{:?}: {}", args, String::from_utf8_lossy(&r.stderr));
    };
    let (surface, uv) = (dir.path().join("surface.ply"), dir.path().join("uv.ply"));
    let os = |p: &Path| p.as_os_str().to_owned();
    let synth = |extra: &[&str], out: &Path| {
        let mut args: Vec<std::ffi::OsString> =
            vec!["synth".into(), os(&odd), os(&mesh), "-o".into(), os(out)];
        args.extend(extra.iter().map(|e| e.into()));
        run(&args.iter().map(|a| a.as_os_str()).collect::<Vec<_>>());
    };
    synth(&["--vertices", "1500"], &surface);
    synth(&["--method", "soler2002", "--texels-across", "64"], &uv);
    let map = btfsynth::synth::surface_map::read_surface_ply(&surface).unwrap();
    assert_eq!(map.find_analysis(&surface), Some(odd.clone()));
    let comments = btfsynth::synth::patches::output::read_uv_map(&uv).unwrap().comments;
    assert_eq!(btfsynth::synth::surface_map::find_analysis(&comments, &uv), Some(odd.clone()));
    assert_eq!(btfsynth::export::original_mesh(&surface, None).unwrap(), mesh);
    // And the command line uses them: render finds the map's analysis from its header.
    let frames = dir.path().join("frames");
    let o = std::ffi::OsStr::new;
    run(&[o("render"), surface.as_os_str(), o("--size"), o("16x16"), o("-o"), frames.as_os_str()]);
}
