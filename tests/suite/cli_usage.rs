//! What a new user meets first: usage errors that say what is missing and exit 2, help
//! that shows what each command needs, outputs that cannot be written refused before any
//! work, no Rust `Debug` text, and a README that lists every command (docs/ explain each).

use crate::common;

use common::{assert_one_line_error, assert_usage_error, btfsynth, entries, BUNNY};

fn help(command: &str) -> String {
    let out = btfsynth(&[command, "--help"]);
    assert!(out.status.success());
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The `Usage:` lines of a help text (the first and its continuations).
fn usage_lines(help: &str) -> Vec<String> {
    let mut lines = help.lines().skip_while(|l| !l.starts_with("Usage:"));
    let first = lines.next().unwrap_or_default().to_string();
    std::iter::once(first).chain(lines.take_while(|l| l.starts_with("       ")).map(str::to_string)).collect()
}

#[test]
fn missing_arguments_are_named_and_usage_errors_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let texture = concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png");
    let r = btfsynth(&["analyze", texture]);
    assert_usage_error(&r, "the following required arguments were not provided: --output <DIR>");
    assert_usage_error(&btfsynth(&["gen", "pebbles"]), "--output <DIR>");
    assert_usage_error(&btfsynth(&["render", "x.ply"]), "--output <DIR>");
    assert_usage_error(&btfsynth(&["remesh", BUNNY, "-o", "x.ply"]), "--vertices");
    assert_usage_error(&btfsynth(&["remesh", BUNNY, "--vertices", "3", "-o", "x.ply"]), "from 4");
    let r = btfsynth(&["--threads", "0", "info", texture]);
    assert_usage_error(&r, "--threads");
    let bare = btfsynth(&[]);
    assert_eq!(bare.status.code(), Some(2), "no command is a usage error");
    assert!(String::from_utf8_lossy(&bare.stderr).contains("Usage:"), "and shows the overview");
    assert!(entries(dir.path()).is_empty());
}

#[test]
fn help_shows_what_each_command_needs() {
    let gen = usage_lines(&help("gen"));
    assert!(gen[0].contains("-o <DIR> <KIND>") && !gen[0].contains("[KIND]"), "{gen:?}");
    assert!(gen.iter().any(|l| l.contains("gen --list")), "{gen:?}");
    let render = usage_lines(&help("render"));
    assert!(render[0].contains("--output <DIR>") && !render[0].contains("[--output"), "{render:?}");
    let view = usage_lines(&help("view"));
    assert!(view.iter().any(|l| l.contains("--headless -o <DIR>")), "{view:?}");
    let remesh = usage_lines(&help("remesh"));
    assert!(remesh[0].contains("--vertices") && remesh[0].contains("--edge"), "{remesh:?}");
    let synth = help("synth");
    for flag in ["--scale", "--texels-across", "--vertices"] {
        let line =
            synth.lines().skip_while(|l| !l.trim_start().starts_with(flag)).take(4).collect::<String>();
        assert!(line.contains("xclude"), "{flag} says what it excludes: {line}");
    }
    let preset =
        synth.lines().skip_while(|l| !l.trim_start().starts_with("--preset")).take(3).collect::<String>();
    assert!(preset.contains("tong2002 ("), "--preset lists its values: {preset}");
}

#[test]
fn an_output_that_cannot_be_written_is_refused_before_any_work() {
    // The inputs do not exist either: the output is checked first, so that a long run never
    // ends in a failed write, and the message never shows a temporary name.
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing");
    let m = missing.to_str().unwrap();
    let out = "/proc/btfsynth-out";
    for args in [
        vec!["analyze", m, "-o", out],
        vec!["gen", "pebbles", "-o", out],
        vec!["synth", m, BUNNY, "-o", out],
        vec!["remesh", m, "--vertices", "100", "-o", out],
        vec!["render", m, "-o", out],
    ] {
        let r = btfsynth(&args);
        assert_one_line_error(&r, "/proc/btfsynth-out: cannot write in /proc");
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert!(!stderr.contains(".tmp-") && !stderr.contains(".probe-"), "{args:?}: {stderr}");
    }
}

#[test]
fn messages_carry_no_rust_debug_text() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    let ply = dir.path().join("bunny.ply");
    let a = analysis.to_str().unwrap();
    let r = btfsynth(&["synth", a, BUNNY, "--vertices", "1500", "-o", ply.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let frames = dir.path().join("frames");
    let r = btfsynth(&["render", ply.to_str().unwrap(), "--size", "16x16", "-o", frames.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success() && stderr.contains("pixel mode") && !stderr.contains("Pixel"), "{stderr}");
    // A rendered frame given to eval is named as what it is, not as a damaged PLY.
    let frame = std::fs::read_dir(&frames).unwrap().map(|e| e.unwrap().path());
    let frame = frame.filter(|p| p.extension().is_some_and(|e| e == "exr")).min().expect("an EXR frame");
    let r = btfsynth(&["eval", a, frame.to_str().unwrap()]);
    assert_one_line_error(&r, "an EXR image (a rendered frame?), not a result eval measures");
    let header = std::fs::read(&ply).unwrap();
    let header =
        String::from_utf8_lossy(&header[..header.windows(10).position(|w| w == b"end_header").unwrap()]);
    assert!(header.contains("1500 vertices") && !header.contains("Vertices("), "{header}");
    // A sample smaller than one neighbourhood search: no "use --levels 0 or fewer".
    let tiny = dir.path().join("tiny.png");
    common::write_png(&tiny, 6, 6, common::pattern(1));
    let r = btfsynth(&[
        "analyze",
        tiny.to_str().unwrap(),
        "--levels",
        "1",
        "-o",
        dir.path().join("t").to_str().unwrap(),
    ]);
    // Too small for any analysis: the input is at fault (exit 1, naming it), not a flag.
    assert_one_line_error(&r, "tiny.png: the sample is 6x6 pixels, too small to analyse");
    assert!(!String::from_utf8_lossy(&r.stderr).contains("--levels 0"));
}

#[test]
fn every_value_has_a_range_checked_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    let a = analysis.to_str().unwrap();
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    let ply = dir.path().join("out.ply");
    let p = ply.to_str().unwrap();
    let texture = concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png");
    let small = dir.path().join("small.png");
    common::write_png(&small, 12, 12, common::pattern(2));
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--threads", "100000", "info", texture], "--threads"),
        (vec!["analyze", texture, "--k", "100000", "-o", o], "--k"),
        (
            vec![
                "analyze",
                small.to_str().unwrap(),
                "--levels",
                "1",
                "--neighborhood",
                "3",
                "--k",
                "200",
                "-o",
                o,
            ],
            "--k 200",
        ),
        (vec!["analyze", texture, "--appearance-dims", "100000", "-o", o], "--appearance-dims"),
        (vec!["analyze", texture, "--basis", "100000", "-o", o], "--basis"),
        (vec!["synth", a, "--plane", "16x16", "--neighborhood", "10001", "-o", o], "--neighborhood"),
        // The analysis' second level is 24x24 texels.
        (
            vec!["synth", a, "--plane", "16x16", "--levels", "2", "--neighborhood", "25", "-o", o],
            "--neighborhood 25",
        ),
        (
            vec!["synth", a, BUNNY, "--levels", "2", "--neighborhood", "25", "--preset", "turk2001", "-o", p],
            "--neighborhood 25",
        ),
        (vec!["synth", a, "--plane", "16x16", "--neighborhood", "49", "-o", o], "--neighborhood 49"),
        (vec!["synth", a, "--plane", "100000x100000", "-o", o], "--plane"),
        (vec!["synth", a, BUNNY, "--orient", "axis:0,0,0", "-o", p], "--orient"),
        (vec!["synth", a, BUNNY, "--orient", "axis:nan,0,0", "-o", p], "--orient"),
        (vec!["synth", a, BUNNY, "--orient", "bogus", "-o", p], "--orient"),
        (vec!["render", p, "--frames", "100000", "-o", o], "--frames"),
        (vec!["remesh", BUNNY, "--iterations", "100000000", "--vertices", "100", "-o", p], "--iterations"),
        (vec!["remesh", BUNNY, "--vertices", "100000000", "-o", p], "--vertices"),
        (vec!["remesh", BUNNY, "--edge", "1e-9", "-o", p], "vertices, more than 50000000"),
        (vec!["convert", texture, "--components", "0", "-o", o], "--components"),
        (vec!["relight", texture, "--view", "0,-720", "--light", "0,0", "-o", o], "--view"),
        (vec!["relight", texture, "--view", "0,1e30", "--light", "0,0", "-o", o], "--view"),
    ];
    for (args, needle) in cases {
        let started = std::time::Instant::now();
        assert_usage_error(&btfsynth(&args), needle);
        assert!(started.elapsed().as_secs() < 30, "{args:?} is refused at once");
    }
    assert!(!out.exists() && !ply.exists(), "nothing written");
    // As wide as the one level in use allows, or as the CLI allows: a synthesis.
    for (n, crop) in [("47", "0,0,48,48"), ("63", "0,0,64,64")] {
        let wide = common::analyze_gravel(dir.path(), &format!("wide{n}"), crop);
        let args = ["-q", "synth", wide.to_str().unwrap(), "--plane", "16x16", "--levels", "1"];
        let r = btfsynth(&[&args[..], &["--neighborhood", n, "-o", o]].concat());
        assert!(r.status.success(), "--neighborhood {n}: {}", String::from_utf8_lossy(&r.stderr));
        let _ = std::fs::remove_dir_all(&out).or_else(|_| std::fs::remove_file(&out));
    }
}

#[test]
fn a_neighbourhood_beyond_the_coarsest_level_is_an_error_in_the_library_too() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    let sample = btfsynth::synth::Sample::open(&analysis, 2).unwrap();
    let params = btfsynth::synth::SynthParams { neighborhood: 25, ..Default::default() };
    let silent = btfsynth::progress::Silent;
    let r = btfsynth::synth::plane::synthesize_plane(&sample, (32, 32), false, &params, &silent);
    let e = r.err().expect("refused, not a panic").to_string();
    assert!(e.contains("25x25 neighbourhood does not fit"), "{e}");
}

#[test]
fn the_readme_documents_every_command() {
    let overview = String::from_utf8_lossy(&btfsynth(&["--help"]).stdout).into_owned();
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let commands: Vec<&str> = overview
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .collect();
    assert!(commands.len() >= 9, "{overview}");
    let root = env!("CARGO_MANIFEST_DIR");
    let reference: String = ["docs/commands.md", "docs/synthesis.md"]
        .iter()
        .map(|f| std::fs::read_to_string(format!("{root}/{f}")).unwrap())
        .collect();
    for command in commands {
        assert!(
            readme.contains(&format!("| `btfsynth {command}")),
            "README's table has no row for {command}"
        );
        assert!(reference.contains(&format!("# `btfsynth {command}")), "docs/ have no section for {command}");
    }
    assert!(readme.contains("cargo test --release"), "the README's test command shares the demo's build");
}

/// Every environment variable btfsynth reads is parsed before any command starts: a bad
/// value is one line naming it, exit 2, whichever command runs (most never reach the place
/// where a given one is used).
#[test]
fn a_bad_environment_variable_is_refused_by_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let commands: [&[&str]; 6] = [
        &["info", BUNNY],
        &["synth", "analysis", "--plane", "8x8", "-o", "plane"],
        &["export", "surface.ply", "-o", "surface.glb"],
        &["convert", "stack", "-o", "converted"],
        &["relight", "stack", "--view", "0,0", "--light", "0,0", "-o", "relit.png"],
        &["remesh", BUNNY, "--vertices", "300", "-o", "remeshed.ply"],
    ];
    let mut bad = vec![("BTFSYNTH_MEMORY", "lots"), ("BTFSYNTH_DECODE_LIMIT", "6X")];
    if cfg!(feature = "gpu") {
        bad.extend([("BTFSYNTH_GPU_MEMORY", "-1G"), ("WGPU_BACKEND", "bogus")]);
    }
    for (name, value) in bad {
        for args in commands {
            let r = std::process::Command::new(env!("CARGO_BIN_EXE_btfsynth"))
                .args(args)
                .current_dir(dir.path())
                .env(name, value)
                .output()
                .unwrap();
            assert_usage_error(&r, &format!("{name}='{value}'"));
        }
    }
    assert!(entries(dir.path()).is_empty(), "nothing written");
}
