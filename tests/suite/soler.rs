//! `synth --method soler2002` (hierarchical pattern mapping): the user's mesh comes back
//! with every face, its vertices where they were, texture coordinates at every corner that
//! stay inside a sample that does not tile and agree across every edge inside a patch;
//! `render` draws it and `export` writes the sample itself as its texture.

use crate::common;

use btfsynth::synth::patches::output::{read_uv_map, UvMap};
use common::{analyze_gravel, assert_one_line_error, assert_usage_error, btfsynth, BUNNY};
use glam::Vec2;
use serde_json::Value;
use std::collections::HashMap;
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

fn run(args: &[&str]) -> std::process::Output {
    let out = btfsynth(args);
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    out
}

/// Every face kept in order, every corner inside the sample, and the corners of faces of
/// one cluster agreeing at every shared vertex (a patch has no seam inside). An OBJ does not
/// record the clusters (`clusters` false): its whole mesh is then checked as one.
fn check_map(map: &UvMap, mesh: &Path, clusters: bool) {
    let original = btfsynth::mesh::textured::load_textured(mesh).expect("mesh");
    assert_eq!(map.mesh.triangles, original.triangles, "the faces are the file's, in order");
    assert_eq!(map.mesh.positions, original.positions, "the vertices are the file's");
    let (w, h) = (map.sample.0 as f32, map.sample.1 as f32);
    for (f, corners) in map.corner_uv.iter().enumerate() {
        for s in corners {
            assert!(s.x >= -0.01 && s.y >= -0.01 && s.x <= w - 0.99 && s.y <= h - 0.99, "face {f}: {s}");
        }
        if clusters {
            assert_ne!(map.cluster[f], u32::MAX, "face {f} has no cluster");
        }
    }
    let mut at: HashMap<(u32, u32), Vec2> = HashMap::new();
    for (f, t) in map.mesh.triangles.iter().enumerate() {
        for (&vertex, &uv) in t.iter().zip(&map.corner_uv[f]) {
            let seen = *at.entry((map.cluster[f], vertex)).or_insert(uv);
            assert!(
                seen.distance(uv) < 1e-3,
                "vertex {vertex} has two coordinates in cluster {}",
                map.cluster[f]
            );
        }
    }
}

#[test]
fn the_bunny_keeps_every_face_renders_and_exports_the_sample_itself() {
    let dir = tempfile::tempdir().expect("temp dir");
    let analysis = analyze_gravel(dir.path(), "gravel", "0,0,64,64");
    let out = dir.path().join("bunny-uv.ply");
    let report = dir.path().join("report.json");
    run(&[
        "-q",
        "synth",
        s(&analysis),
        BUNNY,
        "--method",
        "soler2002",
        "-o",
        s(&out),
        "--report",
        s(&report),
    ]);
    let map = read_uv_map(&out).expect("a uvmap");
    assert_eq!(map.mesh.triangles.len(), 3674);
    assert_eq!(map.sample, (64, 64));
    check_map(&map, Path::new(BUNNY), true);
    let report: Value = serde_json::from_slice(&std::fs::read(&report).expect("report")).expect("JSON");
    let levels = report["levels"].as_array().expect("levels");
    let faces: u64 = levels.iter().map(|l| l["faces"].as_u64().unwrap()).sum();
    assert_eq!(faces, 3674, "every face is mapped on exactly one level");
    assert!(
        levels
            .iter()
            .any(|l| l["mapped"].as_u64().unwrap() > 0
                && l["level"].as_u64().unwrap() + 1 < levels.len() as u64),
        "some patches are larger than one face"
    );
    // The same inputs give the same bytes.
    let again = dir.path().join("again.ply");
    run(&["-q", "synth", s(&analysis), BUNNY, "--method", "soler2002", "-o", s(&again)]);
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&again).unwrap());

    // render reads it.
    let frames = dir.path().join("frames");
    run(&["-q", "render", s(&out), "-o", s(&frames), "--size", "64x64", "--spp", "1", "--format", "png"]);
    assert!(frames.join("contact.png").is_file());

    // export writes the mesh with its faces and the sample as the texture.
    let glb = dir.path().join("bunny.gltf");
    run(&["-q", "export", s(&out), "-o", s(&glb)]);
    let gltf: Value = serde_json::from_slice(&std::fs::read(&glb).expect("gltf")).expect("JSON");
    let indices = gltf["meshes"][0]["primitives"][0]["indices"].as_u64().unwrap() as usize;
    assert_eq!(gltf["accessors"][indices]["count"], 3 * 3674);
    let image = gltf["images"][0]["uri"].as_str().expect("an image file");
    let texture = image::open(dir.path().join(image)).expect("the texture").to_rgb8();
    assert_eq!(texture.dimensions(), (64, 64), "the texture is the sample at full resolution");
    assert_eq!(gltf["samplers"][0]["wrapS"], 33071, "a sample that does not tile is clamped");
}

#[test]
fn a_plane_maps_as_one_undistorted_patch_and_an_obj_is_written_too() {
    let dir = tempfile::tempdir().expect("temp dir");
    let analysis = analyze_gravel(dir.path(), "gravel", "0,0,64,64");
    // A 10×10-quad plane two units wide: with 20 texels per unit it is 40 texels across,
    // and fits in the 64² sample as one patch.
    let plane = dir.path().join("grid.obj");
    let mut text = String::new();
    let n = 10;
    for j in 0..=n {
        for i in 0..=n {
            text += &format!("v {} {} 0\n", 0.2 * i as f32, 0.2 * j as f32);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i + 1;
            text += &format!("f {} {} {}\nf {} {} {}\n", a, a + 1, a + n + 2, a, a + n + 2, a + n + 1);
        }
    }
    std::fs::write(&plane, text).expect("plane");
    for ext in ["ply", "obj"] {
        let out = dir.path().join(format!("plane.{ext}"));
        run(&[
            "-q",
            "synth",
            s(&analysis),
            s(&plane),
            "--method",
            "soler2002",
            "--scale",
            "20",
            "-o",
            s(&out),
        ]);
        let map = read_uv_map(&out).expect("a uvmap");
        check_map(&map, &plane, ext == "ply");
        if ext == "ply" {
            assert!(map.cluster.iter().all(|&c| c == map.cluster[0]), "one patch covers the plane");
        }
        // Isometric at the scale: every edge is 0.2 × 20 = 4 texels (diagonals 4√2).
        for corners in &map.corner_uv {
            for k in 0..3 {
                let d = corners[k].distance(corners[(k + 1) % 3]);
                assert!((d - 4.0).abs() < 0.05 || (d - 4.0 * 2f32.sqrt()).abs() < 0.05, "{d}");
            }
        }
    }
}

#[test]
fn the_teapots_open_patches_are_mapped_and_non_manifold_input_is_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let analysis = analyze_gravel(dir.path(), "gravel", "0,0,48,48");
    let teapot = concat!(env!("CARGO_MANIFEST_DIR"), "/data/teapot.obj");
    let out = dir.path().join("teapot.ply");
    run(&["-q", "synth", s(&analysis), teapot, "--method", "soler2002", "-o", s(&out)]);
    let map = read_uv_map(&out).expect("a uvmap");
    check_map(&map, Path::new(teapot), true);

    let bad = dir.path().join("fin.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n")
        .unwrap();
    let refused = btfsynth(&[
        "-q",
        "synth",
        s(&analysis),
        s(&bad),
        "--method",
        "soler2002",
        "-o",
        s(&dir.path().join("x.ply")),
    ]);
    assert_one_line_error(&refused, "not a manifold surface");
    assert!(!dir.path().join("x.ply").exists());
    // A fresh output: outputs are checked (and reserved) before the flags, as for the
    // per-vertex method, so an existing one would be refused first.
    let fresh = dir.path().join("flags.ply");
    let usage = btfsynth(&[
        "-q",
        "synth",
        s(&analysis),
        teapot,
        "--method",
        "soler2002",
        "--vertices",
        "5000",
        "-o",
        s(&fresh),
    ]);
    assert_usage_error(&usage, "--method soler2002");
    assert!(!fresh.exists());
}
