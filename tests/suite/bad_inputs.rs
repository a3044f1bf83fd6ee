//! Bad input: one clear line naming the file, exit code 1, no panic, nothing written.

use crate::common;

use common::{assert_one_line_error, btfsynth, entries, pattern, write_png};

fn info(path: &std::path::Path) -> std::process::Output {
    btfsynth(&["info", path.to_str().unwrap()])
}

#[test]
fn missing_path() {
    let dir = tempfile::tempdir().unwrap();
    let out = info(&dir.path().join("nope"));
    assert_one_line_error(&out, "nope");
}

#[test]
fn empty_directory() {
    let dir = tempfile::tempdir().unwrap();
    assert_one_line_error(&info(dir.path()), "no images found");
}

#[test]
fn one_corrupt_image() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("tl000_pl000_tv000_pv000.png"), 4, 4, pattern(0));
    std::fs::write(dir.path().join("tl015_pl000_tv000_pv000.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
    assert_one_line_error(&info(dir.path()), "tl015_pl000_tv000_pv000.png");
    std::fs::write(dir.path().join("tl015_pl000_tv000_pv000.png"), b"").unwrap();
    assert_one_line_error(&info(dir.path()), "tl015_pl000_tv000_pv000.png");
    let exr = dir.path().join("broken.exr");
    std::fs::write(&exr, b"v/1\x01garbage").unwrap();
    assert_one_line_error(&info(&exr), "broken.exr");
}

#[test]
fn mismatched_sizes() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("tl000_pl000_tv000_pv000.png"), 4, 4, pattern(0));
    write_png(&dir.path().join("tl015_pl000_tv000_pv000.png"), 5, 4, pattern(1));
    assert_one_line_error(&info(dir.path()), "this image is 5x4 pixels");
}

#[test]
fn unparseable_name() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("tl000_pl000_tv000_pv000.png"), 4, 4, pattern(0));
    write_png(&dir.path().join("holiday.png"), 4, 4, pattern(1));
    assert_one_line_error(&info(dir.path()), "holiday.png");
}

#[test]
fn duplicate_directions() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("tl000_pl000_tv000_pv000.png"), 4, 4, pattern(0));
    std::fs::create_dir(dir.path().join("tv000_pv000")).unwrap();
    write_png(&dir.path().join("tv000_pv000").join("tl000_pl090.png"), 4, 4, pattern(1));
    assert_one_line_error(&info(dir.path()), "same light and view directions");
}

#[test]
fn manifest_problems() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("a.png"), 4, 4, pattern(0));
    let manifest = dir.path().join("btf.json");
    let cases = [
        (r#"{"images": [{"file": "a.png", "view": [0, 0]}]}"#, "missing field `light`"),
        (r#"{"images": [{"file": "a.png", "light": [NaN, 0], "view": [0, 0]}]}"#, "btf.json"),
        (r#"{"images": [{"file": "a.png", "light": [null, 0], "view": [0, 0]}]}"#, "btf.json"),
        (r#"{"images": [{"file": "a.png", "light": [95, 0], "view": [0, 0]}]}"#, "outside 0–90°"),
        (r#"{"images": [{"file": "b.png", "light": [0, 0], "view": [0, 0]}]}"#, "b.png"),
        (r#"{"images": []}"#, "lists no images"),
        ("not json", "btf.json"),
    ];
    for (text, needle) in cases {
        std::fs::write(&manifest, text).unwrap();
        assert_one_line_error(&info(dir.path()), needle);
    }
}

#[test]
fn gen_rejects_bad_arguments_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    common::assert_usage_error(
        &btfsynth(&["gen", "pebbles", "--size", "0", "--directions", "grid:2", "-o", o]),
        "size 0",
    );
    common::assert_usage_error(
        &btfsynth(&["gen", "pebbles", "--spp", "3", "--directions", "grid:2", "-o", o]),
        "square",
    );
    assert_one_line_error(
        &btfsynth(&["gen", "pebbles", "-o", dir.path().join("a/b").to_str().unwrap()]),
        "does not exist",
    );
    common::assert_usage_error(&btfsynth(&["gen", "--directions", "grid:2", "-o", o]), "<KIND>");
    let clap = btfsynth(&["gen", "pebbles", "--directions", "dome", "-o", o]);
    assert_eq!(clap.status.code(), Some(2), "usage errors exit 2");
    assert!(String::from_utf8_lossy(&clap.stderr).contains("ubo81"));
    assert!(entries(dir.path()).is_empty(), "nothing written: {:?}", entries(dir.path()));
}
