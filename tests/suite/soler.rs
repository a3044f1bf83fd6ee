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

    // eval scores it on the surface itself.
    let scored = run(&["eval", s(&analysis), s(&out), "--json"]);
    let e: Value = serde_json::from_slice(&scored.stdout).expect("eval JSON");
    assert_eq!(e["kind"], "uvmap");
    assert_eq!(e["vertices"], map.mesh.positions.len());
    let energy = e["probes"][0]["patch_energy"].as_f64().expect("a patch energy");
    assert!(energy > 0.0 && energy < 0.1, "{energy}");
    let seams = &e["seams"];
    assert!(
        seams["border_windows"].as_u64().unwrap() > 50 && seams["interior_windows"].as_u64().unwrap() > 50
    );
    assert!(seams["border"].as_f64().unwrap() > 0.0 && seams["interior"].as_f64().unwrap() > 0.0);
    // Against an analysis of another sample size, one line.
    let other = analyze_gravel(dir.path(), "gravel48", "0,0,48,48");
    let refused = btfsynth(&["eval", s(&other), s(&out), "--json", "--force-analysis"]);
    assert_one_line_error(&refused, "48x48");
}

/// The grid plane of `n × n` quads `0.2 n` units wide, in z = 0, counter-clockwise from +Z.
fn grid_plane(path: &Path, n: usize) {
    let mut text = String::new();
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
    std::fs::write(path, text).expect("plane");
}

#[test]
fn the_user_chooses_the_first_face_and_the_orientation() {
    let dir = tempfile::tempdir().expect("temp dir");
    let analysis = analyze_gravel(dir.path(), "gravel", "0,0,64,64");
    // The first patch holds the chosen face: the coarsest level with a start is its level.
    for face in [100usize, 3000] {
        let out = dir.path().join(format!("first{face}.ply"));
        let report = dir.path().join(format!("first{face}.json"));
        let face_arg = face.to_string();
        run(&[
            "-q",
            "synth",
            s(&analysis),
            BUNNY,
            "--method",
            "soler2002",
            "--first-face",
            &face_arg,
            "-o",
            s(&out),
            "--report",
            s(&report),
        ]);
        let map = read_uv_map(&out).expect("a uvmap");
        let report: Value = serde_json::from_slice(&std::fs::read(&report).expect("report")).expect("JSON");
        let first = report["levels"]
            .as_array()
            .unwrap()
            .iter()
            .find(|l| l["started"].as_u64().unwrap() > 0)
            .map(|l| l["level"].as_u64().unwrap())
            .expect("a start");
        assert_eq!(u64::from(map.level[face]), first, "face {face} is in the first patch");
        let starts = map.cluster.iter().filter(|&&c| c == map.cluster[face]).count();
        assert!(starts > 1, "the first patch is more than the face itself ({starts})");
    }
    let refused = btfsynth(&[
        "-q",
        "synth",
        s(&analysis),
        BUNNY,
        "--method",
        "soler2002",
        "--first-face",
        "3674",
        "-o",
        s(&dir.path().join("no.ply")),
    ]);
    assert_usage_error(&refused, "--first-face 3674");
    assert!(!dir.path().join("no.ply").exists());

    // On a plane mapped as one patch, the sample's up follows the model's +Y turned by the
    // angle: steps of 0.2 units are 4 texels at --scale 20.
    let plane = dir.path().join("grid.obj");
    grid_plane(&plane, 10);
    for (degrees, along_x, along_y) in
        [("0", Vec2::new(4.0, 0.0), Vec2::new(0.0, -4.0)), ("90", Vec2::new(0.0, 4.0), Vec2::new(4.0, 0.0))]
    {
        let out = dir.path().join(format!("plane{degrees}.ply"));
        run(&[
            "-q",
            "synth",
            s(&analysis),
            s(&plane),
            "--method",
            "soler2002",
            "--scale",
            "20",
            "--orientation",
            degrees,
            "-o",
            s(&out),
        ]);
        let map = read_uv_map(&out).expect("a uvmap");
        // Face 0's corners: (0, 0), (0.2, 0), (0.2, 0.2).
        let uv = map.corner_uv[0];
        let (dx, dy) = (uv[1] - uv[0], uv[2] - uv[1]);
        assert!(dx.distance(along_x) < 0.05 && dy.distance(along_y) < 0.05, "{degrees}°: +X {dx}, +Y {dy}");
    }
}

#[test]
fn a_plane_maps_as_one_undistorted_patch_and_an_obj_is_written_too() {
    let dir = tempfile::tempdir().expect("temp dir");
    let analysis = analyze_gravel(dir.path(), "gravel", "0,0,64,64");
    // A 10×10-quad plane two units wide: with 20 texels per unit it is 40 texels across,
    // and fits in the 64² sample as one patch.
    let plane = dir.path().join("grid.obj");
    grid_plane(&plane, 10);
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
