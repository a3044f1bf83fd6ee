//! `synth --cache DIR` (once `--marching-cache`): every mesh level's remeshing, templates
//! and, for round neighbourhoods, marching are computed once, stored, and read back by a
//! later run on the same mesh, which then writes exactly the bytes a run without the cache
//! writes.

use crate::common;

use common::{analyze_gravel_crop, assert_usage_error, btfsynth, BUNNY};
use std::path::{Path, PathBuf};

/// Runs chen2008 on the bundled bunny (3,000 vertices, 2 levels) with `orient`, through
/// `cache` if given; returns the output PLY, the report's `marching` entries' sources and
/// stderr.
fn synth(
    dir: &Path,
    analysis: &Path,
    name: &str,
    orient: &str,
    cache: Option<&Path>,
) -> (PathBuf, Vec<String>, String) {
    let (out, report) = (dir.join(format!("{name}.ply")), dir.join(format!("{name}.json")));
    let mut args = vec![
        "synth",
        analysis.to_str().unwrap(),
        BUNNY,
        "--preset",
        "chen2008",
        "--vertices",
        "3000",
        "--levels",
        "2",
        "--orient",
        orient,
        "-o",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ];
    if let Some(cache) = cache {
        args.extend(["--cache", cache.to_str().unwrap()]);
    }
    let r = btfsynth(&args);
    let stderr = String::from_utf8_lossy(&r.stderr).into_owned();
    assert!(r.status.success(), "{stderr}");
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let marching = report["params"]["marching"].as_array().expect("a marching entry per level");
    let sources = marching.iter().map(|m| m["source"].as_str().unwrap().to_string()).collect();
    (out, sources, stderr)
}

/// The cache's marching files, sorted, with their bytes.
fn cached_files(cache: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    cached(cache, "marching-")
}

/// The cache's files whose name starts with `kind`, sorted, with their bytes.
fn cached(cache: &Path, kind: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(cache)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with(kind))
        .collect();
    files.sort();
    files.into_iter().map(|p| (p.clone(), std::fs::read(p).unwrap())).collect()
}

#[test]
fn a_new_direction_reads_the_cached_marching_and_writes_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = analyze_gravel_crop(dir.path(), "gravel");
    let cache = dir.path().join("cache/new");
    let (_, cold, stderr) = synth(dir.path(), &analysis, "cold", "axis:0,1,0", Some(&cache));
    assert_eq!(cold, ["computed", "computed"]);
    assert_eq!(stderr.matches("marching computed in").count(), 2, "{stderr}");
    let stored = cached_files(&cache);
    assert_eq!(stored.len(), 2, "one file per mesh level: {stored:?}");

    let (warm, sources, stderr) = synth(dir.path(), &analysis, "warm", "axis:1,0,0", Some(&cache));
    assert_eq!(sources, ["cached", "cached"]);
    assert_eq!(stderr.matches("marching read from the cache").count(), 2, "{stderr}");
    assert!(!stderr.contains("WARN"), "{stderr}");
    assert_eq!(cached_files(&cache), stored, "reading the cache leaves it as it was");

    let (plain, sources, _) = synth(dir.path(), &analysis, "plain", "axis:1,0,0", None);
    assert_eq!(sources, ["computed", "computed"]);
    let (warm, plain) = (std::fs::read(warm).unwrap(), std::fs::read(plain).unwrap());
    assert!(warm == plain, "the cached marching gave other bytes than a fresh one");
    let cold = std::fs::read(dir.path().join("cold.ply")).unwrap();
    assert!(cold != warm, "the two directions should give different maps");
}

#[test]
fn a_damaged_cache_file_is_recomputed_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = analyze_gravel_crop(dir.path(), "gravel");
    let cache = dir.path().join("cache");
    synth(dir.path(), &analysis, "first", "axis:0,1,0", Some(&cache));
    let stored = cached_files(&cache);
    // One file cut short, the other with one byte flipped in the middle.
    std::fs::write(&stored[0].0, &stored[0].1[..stored[0].1.len() / 3]).unwrap();
    let mut flipped = stored[1].1.clone();
    let middle = flipped.len() / 2;
    flipped[middle] ^= 0x01;
    std::fs::write(&stored[1].0, flipped).unwrap();

    let (out, sources, stderr) = synth(dir.path(), &analysis, "again", "axis:0,1,0", Some(&cache));
    assert_eq!(sources, ["recomputed", "recomputed"]);
    assert_eq!(stderr.matches("WARN").count(), 2, "one warning per damaged file: {stderr}");
    assert!(!stderr.contains("error"), "{stderr}");
    assert_eq!(cached_files(&cache), stored, "the damaged files are overwritten with good ones");
    let first = std::fs::read(dir.path().join("first.ply")).unwrap();
    assert!(std::fs::read(out).unwrap() == first);
}

#[test]
fn an_unwritable_cache_directory_is_a_usage_error_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = analyze_gravel_crop(dir.path(), "gravel");
    let file = dir.path().join("a-file");
    std::fs::write(&file, b"not a directory").unwrap();
    let out = dir.path().join("out.ply");
    let cache = file.join("cache");
    let args = ["synth", analysis.to_str().unwrap(), BUNNY, "--preset", "chen2008", "--vertices", "3000"];
    let r = btfsynth(
        &[&args[..], &["--marching-cache", cache.to_str().unwrap(), "-o", out.to_str().unwrap()]].concat(),
    );
    assert_usage_error(&r, "--cache");
    assert!(!out.exists());
}

/// Planes have no mesh: the flag leaves no directory there. On a mesh, a preset without
/// round neighbourhoods stores remeshings and templates only; another seed reads the
/// remeshings (its frames, and so its templates, are its own), and the same seed reads
/// both; every cached run writes the bytes of a run without the cache.
#[test]
fn remeshings_and_templates_are_read_back_by_runs_that_share_them() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = analyze_gravel_crop(dir.path(), "gravel");
    let (out, cache) = (dir.path().join("plane"), dir.path().join("cache"));
    let a = analysis.to_str().unwrap();
    let r = btfsynth(&[
        "synth",
        a,
        "--plane",
        "32x32",
        "--cache",
        cache.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(!cache.exists());
    let run = |name: &str, seed: &str, cached: bool| {
        let (out, report) = (dir.path().join(format!("{name}.ply")), dir.path().join(format!("{name}.json")));
        let mut args = vec!["synth", a, BUNNY, "--vertices", "3000", "--levels", "2", "--seed", seed];
        args.extend(["-o", out.to_str().unwrap(), "--report", report.to_str().unwrap()]);
        if cached {
            args.extend(["--cache", cache.to_str().unwrap()]);
        }
        let r = btfsynth(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
        let levels = report["params"]["mesh_levels"].as_array().unwrap().clone();
        let sources: Vec<String> = levels
            .iter()
            .map(|l| format!("{} {}", l["remeshing"], l["templates"]).replace('"', ""))
            .collect();
        (std::fs::read(out).unwrap(), sources)
    };
    let (cold, sources) = run("cold", "1", true);
    assert_eq!(sources, ["computed computed"; 2]);
    assert_eq!((cached(&cache, "remesh-").len(), cached(&cache, "templates-").len()), (2, 2));
    assert!(cached_files(&cache).is_empty(), "no marching without round neighbourhoods");
    let (other_seed, sources) = run("other-seed", "2", true);
    assert_eq!(sources, ["cached computed"; 2]);
    let (warm, sources) = run("warm", "1", true);
    assert_eq!(sources, ["cached cached"; 2]);
    assert!(warm == cold, "the cached templates gave other bytes than fresh ones");
    let (plain, _) = run("plain", "2", false);
    assert!(plain == other_seed, "the cached remeshing gave other bytes than a fresh one");
}

/// `file` rewritten to hold `payload` under its own name's key, with a right checksum: a
/// file of other inputs renamed into this run's place, which only its payload betrays.
fn forge(file: &Path, payload_of: &Path) {
    let (mine, theirs) = (std::fs::read(file).unwrap(), std::fs::read(payload_of).unwrap());
    let payload = &theirs[28..theirs.len() - 8];
    let mut forged = mine[..20].to_vec();
    forged.extend((payload.len() as u64).to_le_bytes());
    forged.extend(payload);
    forged.extend(btfsynth::cache::Fnv1a::of(payload).to_le_bytes());
    std::fs::write(file, forged).unwrap();
}

/// A cache file whose key and checksum are right but whose payload is another level's (a
/// remeshing or templates of another size), a link to /dev/zero or a FIFO in a file's place:
/// each is recomputed with a warning (never indexed past its end, read whole or written
/// into), and the output is the bytes of a run without the cache. A cache directory inside an
/// input, or at the output, is refused before any work.
#[test]
fn a_foreign_payload_or_a_special_file_in_the_cache_is_recomputed() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = analyze_gravel_crop(dir.path(), "gravel");
    let (a, cache) = (analysis.to_str().unwrap(), dir.path().join("cache"));
    let run = |name: &str, cache: Option<&Path>| {
        let out = dir.path().join(format!("{name}.ply"));
        let mut args =
            vec!["synth", a, BUNNY, "--vertices", "1000", "--levels", "2", "-o", out.to_str().unwrap()];
        if let Some(cache) = cache {
            args.extend(["--cache", cache.to_str().unwrap()]);
        }
        let r = btfsynth(&args);
        let stderr = String::from_utf8_lossy(&r.stderr).into_owned();
        assert!(r.status.success(), "{stderr}");
        assert!(!stderr.contains("error") && !stderr.contains("panicked"), "{stderr}");
        (std::fs::read(out).unwrap(), stderr)
    };
    let (plain, _) = run("plain", None);
    run("cold", Some(&cache));
    for kind in ["remesh-", "templates-"] {
        // The finer level's file holds the coarser's payload, and the other way round.
        let mut files: Vec<PathBuf> = cached(&cache, kind).into_iter().map(|(p, _)| p).collect();
        files.sort_by_key(|p| std::fs::metadata(p).unwrap().len());
        assert_eq!(files.len(), 2, "{kind}");
        let saved = dir.path().join("saved");
        std::fs::copy(&files[0], &saved).unwrap();
        forge(&files[0], &files[1]);
        forge(&files[1], &saved);
    }
    let (forged, stderr) = run("forged", Some(&cache));
    assert_eq!(stderr.matches("computing it again").count(), 4, "a warning per file: {stderr}");
    assert!(forged == plain, "a forged cache changed the output");

    let stored: Vec<PathBuf> = cached(&cache, "").into_iter().map(|(p, _)| p).collect();
    std::fs::remove_file(&stored[0]).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &stored[0]).unwrap();
    std::fs::remove_file(&stored[1]).unwrap();
    assert!(std::process::Command::new("mkfifo").arg(&stored[1]).status().unwrap().success());
    let (special, stderr) = run("special", Some(&cache));
    assert_eq!(stderr.matches("not a regular file").count(), 2, "{stderr}");
    assert!(special == plain);
    assert!(stored.iter().all(|p| std::fs::symlink_metadata(p).unwrap().is_file()), "replaced by files");

    // Inside the input analysis, or where the output goes: refused, nothing written.
    let out = dir.path().join("x.ply");
    for cache in [analysis.join("cache"), out.clone()] {
        let args = ["synth", a, BUNNY, "--vertices", "1000", "-o", out.to_str().unwrap()];
        let r = btfsynth(&[&args[..], &["--cache", cache.to_str().unwrap()]].concat());
        assert_usage_error(&r, "--cache");
        assert!(!cache.exists() && !out.exists());
    }
}
