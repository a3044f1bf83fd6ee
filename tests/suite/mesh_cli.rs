//! `remesh` and `info` on meshes through the CLI.

use crate::common;

use common::{assert_one_line_error, btfsynth, entries};

#[test]
fn remesh_writes_a_ply_that_info_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bunny.ply");
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/data/bunny-1k8.obj");
    let r = btfsynth(&["-q", "remesh", bunny, "--vertices", "8000", "-o", out.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let info = btfsynth(&["info", out.to_str().unwrap(), "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(json["kind"], "mesh");
    let vertices = json["vertices"].as_u64().unwrap();
    assert!((7200..=8800).contains(&vertices), "{vertices}");
    assert_eq!((json["components"].as_u64(), json["euler_characteristic"].as_i64()), (Some(1), Some(2)));
}

#[test]
fn bad_meshes_are_one_clear_line() {
    let dir = tempfile::tempdir().unwrap();
    let nan = dir.path().join("nan.obj");
    std::fs::write(&nan, "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n").unwrap();
    assert_one_line_error(&btfsynth(&["info", nan.to_str().unwrap()]), "nan.obj");
    let range = dir.path().join("range.off");
    std::fs::write(&range, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n").unwrap();
    assert_one_line_error(&btfsynth(&["info", range.to_str().unwrap()]), "range.off");
    let out = dir.path().join("out.ply");
    assert_one_line_error(
        &btfsynth(&["remesh", nan.to_str().unwrap(), "--vertices", "100", "-o", out.to_str().unwrap()]),
        "nan.obj",
    );
    assert_eq!(entries(dir.path()), vec!["nan.obj".to_string(), "range.off".to_string()], "nothing written");
}
