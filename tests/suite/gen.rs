//! `gen`: the generated stacks read back exactly, and their mesostructure is real
//! (shadows that lengthen with the light's elevation, parallax between views).

use crate::common;

use btfsynth::btf::gen::{generate, generate_pairs, GenParams, MaterialKind};
use btfsynth::btf::{load, write_stack, Btf, Direction, DirectionSet, ImageFormat, LoadOptions};
use btfsynth::progress::Silent;

fn small(kind: MaterialKind, directions: usize) -> Btf {
    let params = GenParams { size: 32, directions: DirectionSet::Grid(directions), ..GenParams::default() };
    generate(kind, &params, &Silent).expect("generation succeeds")
}

#[test]
fn gen_then_load_round_trips_directions_and_pixels_exactly() {
    let stack = small(MaterialKind::Weave, 5);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("stack");
    write_stack(&stack, &out, ImageFormat::Exr, None, false, &Silent).unwrap();
    let loaded = load(&out, &LoadOptions::default(), &Silent).unwrap();
    assert_eq!(loaded.pairs(), stack.pairs());
    assert!(loaded.pixels() == stack.pixels(), "pixels differ after the EXR round trip");
    assert_eq!(common::entries(dir.path()), vec!["stack".to_string()], "no temporary left behind");
}

#[test]
fn generation_is_deterministic_for_a_seed_and_differs_across_seeds() {
    let a = small(MaterialKind::Pebbles, 3);
    let b = small(MaterialKind::Pebbles, 3);
    assert!(a == b);
    let params = GenParams { size: 32, directions: DirectionSet::Grid(3), seed: 9, ..GenParams::default() };
    let c = generate(MaterialKind::Pebbles, &params, &Silent).unwrap();
    assert!(a.pixels() != c.pixels());
}

/// Fraction of pixels of image `i` darker than a shadowed pixel can be lit.
fn dark_fraction(stack: &Btf, i: usize) -> f64 {
    let image = stack.image(i);
    let dark = image.chunks_exact(3).filter(|p| p.iter().all(|v| v.to_f32() < 0.01)).count();
    dark as f64 / (image.len() / 3) as f64
}

#[test]
fn shadows_grow_as_the_light_descends() {
    // Seen from above, lit from one azimuth (oblique to the brick rows) at θ = 0, 15, …, 75°.
    let views = [Direction::NORMAL];
    let lights: Vec<Direction> = (0..6).map(|k| Direction::new(15.0 * k as f32, 30.0).unwrap()).collect();
    for kind in [MaterialKind::Pebbles, MaterialKind::Weave, MaterialKind::Bricks] {
        let params = GenParams { size: 32, ..GenParams::default() };
        let stack = generate_pairs(kind, &params, &views, &lights, &Silent).unwrap();
        let fractions: Vec<f64> = (0..6).map(|light| dark_fraction(&stack, light)).collect();
        assert!(fractions[0] < 0.01, "{kind:?}: overhead light casts no shadow: {fractions:?}");
        assert!(fractions[5] > fractions[0] + 0.1, "{kind:?}: grazing light must shadow: {fractions:?}");
        for w in fractions.windows(2) {
            assert!(w[1] >= w[0], "{kind:?}: shadowed fraction should grow with θ: {fractions:?}");
        }
    }
}

#[test]
fn views_of_the_same_patch_differ_by_parallax_and_occlusion() {
    let stack = small(MaterialKind::Bricks, 4);
    let n = 4;
    // Same light (the normal), view along the normal vs. the most grazing view.
    let (top, grazing) = (stack.image(0), stack.image((n - 1) * n));
    let diff: f64 =
        top.iter().zip(grazing).map(|(a, b)| (a.to_f64() - b.to_f64()).abs()).sum::<f64>() / top.len() as f64;
    let mean: f64 = top.iter().map(|v| v.to_f64()).sum::<f64>() / top.len() as f64;
    assert!(
        diff > 0.1 * mean,
        "a 75° view should shift and hide parts of the relief: diff {diff}, mean {mean}"
    );
    // A flat, un-occluded surface would look the same from everywhere under an overhead
    // light; brick tops (above the reference plane) must move against the mortar.
    let shift = best_shift(stack.image(0), stack.image((n - 1) * n), 32);
    assert!(shift != (0, 0), "the grazing view should be shifted relative to the top view");
}

/// The integer translation that best aligns two images (a parallax estimate).
fn best_shift(a: &[half::f16], b: &[half::f16], size: i64) -> (i64, i64) {
    let lum = |img: &[half::f16], x: i64, y: i64| {
        let o = ((y.rem_euclid(size) * size + x.rem_euclid(size)) * 3) as usize;
        img[o].to_f32() + img[o + 1].to_f32() + img[o + 2].to_f32()
    };
    let mut best = ((0, 0), f32::MAX);
    for dy in -4..=4 {
        for dx in -4..=4 {
            let mut err = 0.0;
            for y in 4..size - 4 {
                for x in 4..size - 4 {
                    err += (lum(a, x, y) - lum(b, x + dx, y + dy)).powi(2);
                }
            }
            if err < best.1 {
                best = ((dx, dy), err);
            }
        }
    }
    best.0
}

#[test]
fn gen_cli_writes_a_stack_that_info_describes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bricks");
    let run = common::btfsynth(&[
        "-q",
        "gen",
        "bricks",
        "--size",
        "16",
        "--directions",
        "grid:3",
        "--format",
        "png",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let info = common::btfsynth(&["info", out.to_str().unwrap(), "--json"]);
    assert!(info.status.success());
    let json: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(json["kind"], "stack");
    assert_eq!((json["width"].as_u64(), json["height"].as_u64()), (Some(16), Some(16)));
    assert_eq!(
        (json["images"].as_u64(), json["views"].as_u64(), json["lights"].as_u64()),
        (Some(9), Some(3), Some(3))
    );
    // Refuses to overwrite without --force and leaves the stack alone.
    let again = common::btfsynth(&[
        "-q",
        "gen",
        "bricks",
        "--size",
        "16",
        "--directions",
        "grid:3",
        "-o",
        out.to_str().unwrap(),
    ]);
    common::assert_one_line_error(&again, "already exists");
    assert_eq!(common::entries(&out).len(), 10);
}

#[test]
fn gen_list_names_every_kind() {
    let out = common::btfsynth(&["gen", "--list"]);
    let text = String::from_utf8_lossy(&out.stdout);
    for kind in ["pebbles", "weave", "bricks"] {
        assert!(text.contains(kind), "{text}");
    }
}
