//! Synthesis quality, measured the way a user sees it: on real photographs (crops of the
//! shared data, where present, and the bundled gravel photo), on a generated BTF and on a
//! mesh, for every preset and several seeds, no collapse onto a few texels, no smears, no
//! whole-sample copy, no pile-up on the sample's border; and the measures themselves flag a
//! verbatim tiling and a pixel shuffle.

use crate::common;

use btfsynth::synth::Preset;
use common::btfsynth;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Limits the issue sets for every result (planes): share of the output copied from the
/// most-used 1% of texels, and share of adjacent pairs copying the same texel.
const MAX_COLLAPSE: f64 = 0.05;
const MAX_SMEAR: f64 = 0.01;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn run_ok(args: &[&str]) {
    let r = btfsynth(args);
    assert!(r.status.success(), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
}

fn analyse(stack: &Path, crop: &str, out: &Path, extra: &[&str]) -> PathBuf {
    run_ok(&[&["-q", "analyze", s(stack), "--crop", crop, "-o", s(out)], extra].concat());
    out.to_path_buf()
}

fn plane(analysis: &Path, size: &str, out: &Path, extra: &[&str]) -> PathBuf {
    run_ok(&[&["-q", "synth", s(analysis), "--plane", size, "-o", s(out)], extra].concat());
    out.to_path_buf()
}

/// The figures of `result`: a plane through the library (what `eval --json` prints for it,
/// checked in `eval_flags_a_tiled_copy_and_a_pixel_shuffle`), anything else through `eval`.
fn eval(analysis: &Path, result: &Path) -> Value {
    if result.join("plane.json").is_file() {
        let evaluation = btfsynth::eval::report::evaluate_plane(analysis, result).unwrap();
        return serde_json::from_str(&serde_json::to_string(&evaluation).unwrap()).unwrap();
    }
    eval_cli(analysis, result)
}

/// The figures `eval --json` prints for `result`.
fn eval_cli(analysis: &Path, result: &Path) -> Value {
    let r = btfsynth(&["eval", s(analysis), s(result), "--json"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    serde_json::from_slice(&r.stdout).unwrap()
}

/// Asserts the limits on one evaluation of a plane or surface.
fn assert_no_collapse_smear_or_copy(q: &Value, what: &str) {
    let c = &q["coords"];
    let (collapse, smear, copy) =
        (c["collapse"].as_f64().unwrap(), c["smear"].as_f64().unwrap(), c["copy"].as_f64().unwrap());
    assert!(collapse <= MAX_COLLAPSE, "{what}: collapse {collapse} ({q})");
    assert!(smear <= MAX_SMEAR, "{what}: smear {smear} ({q})");
    assert!(copy < 1.0, "{what}: the sample was copied whole ({q})");
    for p in q["probes"].as_array().unwrap() {
        let contrast = p["contrast"].as_f64().unwrap();
        assert!((0.7..1.3).contains(&contrast), "{what}: contrast {contrast} under {} ({q})", p["name"]);
    }
}

/// The photographs of the shared data the issue names, cropped to 96² and synthesized at
/// twice the size with every preset and seeds 0–3.
#[test]
fn photographs_neither_collapse_nor_smear_for_any_preset_or_seed() {
    let dir = tempfile::tempdir().unwrap();
    let photos = ["textures/gimp-Stone_stone33.png", "textures/sh3d-pebbles.jpg"];
    for photo in photos {
        let Some(path) = btfsynth::testdata::shared_data("photographs_neither_collapse_nor_smear", photo)
        else {
            return;
        };
        let name = Path::new(photo).file_stem().unwrap().to_str().unwrap();
        let analysis = analyse(&path, "0,0,96,96", &dir.path().join(name), &[]);
        for preset in Preset::all() {
            for seed in ["0", "1", "2", "3"] {
                let out = dir.path().join(format!("{name}-{}-{seed}", preset.name.as_str()));
                plane(&analysis, "192x192", &out, &["--preset", preset.name.as_str(), "--seed", seed]);
                let q = eval(&analysis, &out);
                assert_no_collapse_smear_or_copy(
                    &q,
                    &format!("{name}, {}, seed {seed}", preset.name.as_str()),
                );
            }
        }
    }
}

/// Upper bound on the default's repetition (`eval`'s figure) on 128² crops of stone33 and
/// pebbles synthesized to 512² (the benchmark's sizes): Resynthesizer scores 0.030 and
/// 0.032 on the same crops, Embark 0.013 and 0.019 (one run each); the default scored
/// 0.087 on stone33 before the fix (a lattice of near-whole-sample copies) and 0.018–0.027
/// after it. The target is at or below Resynthesizer's.
const MAX_REPETITION: f64 = 0.03;

/// The default preset does not look tiled on the photographs the issue names: seeds 0–3.
#[test]
fn the_default_does_not_repeat_the_sample_at_regular_offsets() {
    let crops = [
        ("textures/gimp-Stone_stone33.png", 128, MAX_REPETITION),
        ("textures/sh3d-pebbles.jpg", 128, MAX_REPETITION),
    ];
    assert_default_repetition("the_default_does_not_repeat", &crops);
}

/// The default does not tile a small organic pattern either: a 48² crop of the leaves and
/// the whole 64² terra, synthesized to 4× their side, seeds 0–3 (the size of most pattern
/// libraries, where the default used to come out as a lattice of near-whole copies:
/// 0.09–0.22 on these two). Each bound is Resynthesizer's figure on that sample, run as the
/// quality benchmark runs it (Embark: 0.053 and 0.033). Since a sample under 60² starts on
/// a second level rather than on itself (`synth::session::second_level_side_for`), the
/// leaves score 0.029–0.040 (0.017–0.023 on one level, whose leaves are cut into pieces),
/// the terra 0.016.
#[test]
fn the_default_does_not_tile_small_organic_patterns() {
    let crops = [("textures/gimp-Plant_leaves.png", 48, 0.053), ("textures/gimp-Stone_terra.png", 64, 0.028)];
    assert_default_repetition("the_default_does_not_tile_small_patterns", &crops);
}

/// Nor on a model: the same two crops on the bundled bunny at 128 texels across (46k
/// vertices, the "bunny 40k"), seeds 0–3. `eval` scores a surface map's repetition
/// from its coordinates on the plane's scale (a lattice of pieces on a curved sheet 0.64,
/// the same pieces at random places 0.04: `eval::repetition`'s test), so the bounds are the
/// plane's: Resynthesizer's figure on each sample. Measured: leaves 0.032–0.042, terra
/// 0.018–0.025.
#[test]
fn the_default_does_not_tile_small_organic_patterns_on_a_model() {
    let test = "the_default_does_not_tile_small_organic_patterns_on_a_model";
    let dir = tempfile::tempdir().unwrap();
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/data/bunny-1k8.obj");
    for (photo, side, bound) in
        [("textures/gimp-Plant_leaves.png", 48, 0.053), ("textures/gimp-Stone_terra.png", 64, 0.028)]
    {
        let Some(path) = btfsynth::testdata::shared_data(test, photo) else { return };
        let name = Path::new(photo).file_stem().unwrap().to_str().unwrap();
        let analysis = analyse(&path, &format!("0,0,{side},{side}"), &dir.path().join(name), &[]);
        for seed in ["0", "1", "2", "3"] {
            let out = dir.path().join(format!("{name}-{seed}.ply"));
            run_ok(&[
                "-q",
                "synth",
                s(&analysis),
                bunny,
                "--texels-across",
                "128",
                "--seed",
                seed,
                "-o",
                s(&out),
            ]);
            let r = btfsynth(&["eval", s(&analysis), s(&out), "--no-texture", "--json"]);
            assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
            let q: Value = serde_json::from_slice(&r.stdout).unwrap();
            let repetition = q["probes"][0]["repetition"].as_f64().unwrap();
            assert!(
                repetition <= bound,
                "{name} {side}² on the bunny, seed {seed}: repetition {repetition} ({q})"
            );
        }
    }
}

/// The default's repetition on a `side`² crop of each photograph, synthesized to 4× the
/// side (at most 512), stays at or below its `bound` for seeds 0–3.
fn assert_default_repetition(test: &str, crops: &[(&str, u32, f64)]) {
    let dir = tempfile::tempdir().unwrap();
    for &(photo, side, bound) in crops {
        let Some(path) = btfsynth::testdata::shared_data(test, photo) else {
            return;
        };
        let name = Path::new(photo).file_stem().unwrap().to_str().unwrap();
        let analysis = analyse(&path, &format!("0,0,{side},{side}"), &dir.path().join(name), &[]);
        let out_side = (4 * side).min(512);
        for seed in ["0", "1", "2", "3"] {
            let out = dir.path().join(format!("{name}-{seed}"));
            let out = plane(&analysis, &format!("{out_side}x{out_side}"), &out, &["--seed", seed]);
            let q = eval(&analysis, &out);
            let repetition = q["probes"][0]["repetition"].as_f64().unwrap();
            assert!(repetition <= bound, "{name} {side}², seed {seed}: repetition {repetition} ({q})");
        }
    }
}

/// The analysis of the shared pine board (64×56) in `dir`, or `None` (after one line saying
/// why) without ../shared.
fn pine_analysis(test: &str, dir: &Path) -> Option<PathBuf> {
    let path = btfsynth::testdata::shared_data(test, "textures/gimp-Wood_pine.png")?;
    Some(analyse(&path, "0,0,64,56", &dir.join("pine"), &[]))
}

/// The default's plane of `size` from `analysis` at `seed` (in `dir`): its width and state.
fn plane_state(analysis: &Path, size: &str, dir: &Path, seed: &str) -> (usize, btfsynth::synth::State) {
    let out = plane(analysis, size, &dir.join(seed), &["--seed", seed]);
    let (w, _, state, _) = btfsynth::synth::plane::read_plane(&out).unwrap();
    (w, state)
}

/// A pine board (../shared) is dark along its left side and light along its right: where
/// a patch's copy wrapped across the sample, the two edges met inside it as a bar (3–4 per
/// result). Horizontally adjacent output texels that copy the outermost three columns of
/// opposite sides were 0.14–0.29% of the pairs (seeds 0–3) before patches were
/// kept from wrapping across a sample's own edges, none since; the bound is a third of the
/// fewest before.
#[test]
fn the_default_does_not_join_a_board_s_two_edges() {
    let dir = tempfile::tempdir().unwrap();
    let Some(analysis) = pine_analysis("the_default_does_not_join_a_board_s_two_edges", dir.path()) else {
        return;
    };
    for seed in ["0", "1"] {
        let (w, state) = plane_state(&analysis, "224x224", dir.path(), seed);
        let (left, right) = (|x: i32| x <= 2, |x: i32| x >= 64 - 3);
        let pairs = state.uv.chunks_exact(w).flat_map(|row| row.windows(2));
        let (joined, all) = pairs.fold((0usize, 0usize), |(joined, all), pair| {
            let (a, b) = (pair[0][0], pair[1][0]);
            (joined + usize::from(right(a) && left(b) || left(a) && right(b)), all + 1)
        });
        let share = joined as f64 / all as f64;
        assert!(share < 0.0005, "seed {seed}: {joined} of {all} adjacent pairs join the board's two edges");
    }
}

/// Nor does a plane lay the board's edges along its own sides. A patch cut by the output's
/// edge was moved into the sample the least way, which put its cut side, the output's edge,
/// on the sample's edge; its neighbours along the side then continued the board's bright
/// or dark edge down most of it (a light line down the result's right side). Over seeds
/// 0–7 (256×224), the outermost output columns copied the two outermost candidate columns
/// on the same side in 37% of their rows on average, five of the sixteen sides in over
/// half; since such patches wrap around the places that fit, 20%, one side (a plain grain
/// line down it). The bound lies between.
#[test]
fn a_plane_s_sides_do_not_copy_the_board_s_edges() {
    let dir = tempfile::tempdir().unwrap();
    let Some(analysis) = pine_analysis("a_plane_s_sides_do_not_copy_the_board_s_edges", dir.path()) else {
        return;
    };
    let mut shares = Vec::new();
    for seed in 0..8 {
        let (w, state) = plane_state(&analysis, "256x224", dir.path(), &seed.to_string());
        let rows = || state.uv.chunks_exact(w);
        let share = |on_edge: &dyn Fn(&[[i32; 2]]) -> bool| {
            rows().filter(|row| on_edge(row)).count() as f64 / rows().count() as f64
        };
        shares.push(share(&|row| row[0][0] <= 2));
        shares.push(share(&|row| row[w - 1][0] >= 64 - 3));
    }
    let mean = shares.iter().sum::<f64>() / shares.len() as f64;
    assert!(mean < 0.3, "the plane's sides copy the board's edges in {mean} of their rows: {shares:?}");
}

/// A 50² sample's elements, larger than the template, come out whole rather than cut into
/// fragments: the chocolate swirl's (25-texel swirls) patch energy (`eval`: how far the
/// result's 7×7 patches are from the sample's nearest), 200² outputs, seeds 0–1. Started on
/// the sample itself (one level), a mush of swirl pieces scored 0.0021–0.0022; started on
/// its 25² second level, whole swirls score 0.0014–0.0017 (seeds 0–3; Embark 0.0012 and
/// Resynthesizer 0.0009, both of which wash the swirls into small even strokes). The bound
/// lies between the two.
#[test]
fn a_small_sample_s_elements_are_not_cut_into_fragments() {
    let test = "a_small_sample_s_elements_are_not_cut_into_fragments";
    let Some(path) = btfsynth::testdata::shared_data(test, "textures/gimp-Food_choc_swirl.png") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let analysis = analyse(&path, "0,0,50,50", &dir.path().join("swirl"), &[]);
    for seed in ["0", "1"] {
        let out = plane(&analysis, "200x200", &dir.path().join(seed), &["--seed", seed]);
        let energy = eval(&analysis, &out)["probes"][0]["patch_energy"].as_f64().unwrap();
        assert!(energy < 0.0018, "seed {seed}: patch energy {energy:.5}");
    }
}

/// A tiled floor (3 × 3 tiles, 256²) keeps its tiles whole on one lattice: the output's luma,
/// folded by the period pair near the tiles' (the sample holds three a side: 60–110 texels)
/// that shows it best, keeps its joints' contrast (the standard deviation of the folded
/// cell, on a scale where the image's is 1). Measured on 512² outputs: 0.36–0.49 over seeds
/// 0–3 with lattice cells; 0.22–0.25 without them (tiles cut by patch edges, joints at every
/// phase), Embark's texture-synthesis 0.25, Resynthesizer 0.26.
#[test]
fn the_default_lays_a_tiled_floor_s_tiles_on_one_lattice() {
    let test = "the_default_lays_a_tiled_floor_s_tiles_on_one_lattice";
    let Some(path) = btfsynth::testdata::shared_data(test, "textures/sh3d-redTiles.jpg") else { return };
    let dir = tempfile::tempdir().unwrap();
    let analysis = analyse(&path, "0,0,256,256", &dir.path().join("tiles"), &[]);
    for seed in ["0", "1"] {
        let out = plane(&analysis, "512x512", &dir.path().join(seed), &["--seed", seed]);
        let luma = image::open(out.join("result.png")).unwrap().to_luma32f();
        let (period, contrast) = folded_contrast(&luma, (60, 110), (60, 110));
        assert!(contrast > 0.32, "seed {seed}: folded joints' contrast {contrast:.3} (periods {period:?})");
    }
}

/// The period pair (x, y) within the ranges that folds `image` into the cell of most
/// contrast, and that contrast: the standard deviation of the cell's means over the image's.
fn folded_contrast(
    image: &image::ImageBuffer<image::Luma<f32>, Vec<f32>>,
    xs: (u32, u32),
    ys: (u32, u32),
) -> ((u32, u32), f64) {
    let (w, h) = image.dimensions();
    let values: Vec<f64> = image.pixels().map(|p| f64::from(p.0[0])).collect();
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / values.len() as f64).sqrt();
    let mut best = ((0, 0), f64::MIN);
    for px in xs.0..=xs.1.min(w / 2) {
        for py in ys.0..=ys.1.min(h / 2) {
            let (cw, ch) = (w / px * px, h / py * py);
            let mut cell = vec![0.0; (px * py) as usize];
            for y in 0..ch {
                for x in 0..cw {
                    cell[((y % py) * px + x % px) as usize] += values[(y * w + x) as usize];
                }
            }
            let n = f64::from((cw / px) * (ch / py));
            let cell: Vec<f64> = cell.iter().map(|v| (v / n - mean) / sd).collect();
            let spread = (cell.iter().map(|v| v * v).sum::<f64>() / cell.len() as f64
                - (cell.iter().sum::<f64>() / cell.len() as f64).powi(2))
            .sqrt();
            if spread > best.1 {
                best = ((px, py), spread);
            }
        }
    }
    best
}

/// The bundled (shippable) photograph, so a plain clone checks quality too.
#[test]
fn the_bundled_photograph_neither_collapses_nor_smears() {
    let dir = tempfile::tempdir().unwrap();
    let gravel = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png"));
    let analysis = analyse(gravel, "0,0,96,96", &dir.path().join("gravel"), &[]);
    for preset in Preset::all() {
        let out = plane(
            &analysis,
            "192x192",
            &dir.path().join(preset.name.as_str()),
            &["--preset", preset.name.as_str()],
        );
        assert_no_collapse_smear_or_copy(&eval(&analysis, &out), preset.name.as_str());
    }
}

/// Colour SSD, reached through `--recipe` on every preset's schedule: on the stone photo
/// of the shared data (seeds 0–3), on the bundled photograph, and with a full search.
#[test]
fn colour_recipes_neither_collapse_nor_smear() {
    let dir = tempfile::tempdir().unwrap();
    let gravel = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png"));
    let small = analyse(gravel, "0,0,48,48", &dir.path().join("small"), &["--levels", "2"]);
    let large = analyse(gravel, "0,0,96,96", &dir.path().join("gravel"), &[]);
    let stone = btfsynth::testdata::shared_data(
        "colour_recipes_neither_collapse_nor_smear",
        "textures/gimp-Stone_stone33.png",
    )
    .map(|path| analyse(&path, "0,0,96,96", &dir.path().join("stone"), &[]));
    for preset in common::square_presets() {
        let colour = common::colour_recipe(&preset);
        let recipe = common::write_recipe(&dir.path().join(format!("{}.json", colour.name)), &colour);
        let given = ["--recipe", s(&recipe)];
        let name = colour.name.as_str();
        let out = plane(&large, "192x192", &dir.path().join(format!("gravel-{name}")), &given);
        assert_no_collapse_smear_or_copy(&eval(&large, &out), &format!("gravel, {name}"));
        let out = plane(
            &small,
            "96x96",
            &dir.path().join(format!("full-{name}")),
            &[&given[..], &["--search", "full"]].concat(),
        );
        assert_no_collapse_smear_or_copy(&eval(&small, &out), &format!("{name} full search"));
        for seed in ["0", "1", "2", "3"].iter().filter(|_| stone.is_some()) {
            let stone = stone.as_ref().unwrap();
            let out = plane(
                stone,
                "192x192",
                &dir.path().join(format!("stone-{name}-{seed}")),
                &[&given[..], &["--seed", seed]].concat(),
            );
            assert_no_collapse_smear_or_copy(&eval(stone, &out), &format!("stone33, {name}, seed {seed}"));
        }
    }
}

/// A full search sees every texel, so a faulty objective collapses it first (it used to
/// copy one texel over 69% of a BTF result).
#[test]
fn full_search_does_not_collapse_either() {
    let dir = tempfile::tempdir().unwrap();
    let gravel = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png"));
    let analysis = analyse(gravel, "0,0,48,48", &dir.path().join("gravel"), &["--levels", "2"]);
    for preset in Preset::all() {
        let refused = btfsynth::synth::Search::Full;
        if preset.check_search(refused).is_err() {
            // Refused with one usage error line (tested in tests/suite/presets.rs).
            continue;
        }
        let out = plane(
            &analysis,
            "96x96",
            &dir.path().join(preset.name.as_str()),
            &["--preset", preset.name.as_str(), "--search", "full"],
        );
        assert_no_collapse_smear_or_copy(
            &eval(&analysis, &out),
            &format!("{} full search", preset.name.as_str()),
        );
    }
}

/// A generated BTF, judged under every default view/light pair (head-on, 45°, grazing).
#[test]
fn a_generated_btf_neither_collapses_nor_smears_under_any_light() {
    let dir = tempfile::tempdir().unwrap();
    let stack = dir.path().join("pebbles");
    run_ok(&["-q", "gen", "pebbles", "--size", "48", "--directions", "grid:5", "-o", s(&stack)]);
    let analysis = analyse(&stack, "0,0,48,48", &dir.path().join("analysis"), &["--levels", "2"]);
    for preset in Preset::all() {
        let out = plane(
            &analysis,
            "96x96",
            &dir.path().join(preset.name.as_str()),
            &["--preset", preset.name.as_str()],
        );
        let q = eval(&analysis, &out);
        assert!(q["probes"].as_array().unwrap().len() >= 2, "a BTF is judged under several lights: {q}");
        assert_no_collapse_smear_or_copy(&q, preset.name.as_str());
        for file in ["result.png", "result_tv000_pv000_tl000_pl000.png", "sample_tv000_pv000_tl000_pl000.png"]
        {
            assert!(out.join(file).is_file(), "{file}");
        }
    }
}

/// On a mesh, coordinates shifted past the sample's edge used to be clamped onto its border
/// texels, which then filled whole regions; now no border texel is favoured.
#[test]
fn surface_coordinates_do_not_pile_up_on_the_sample_border() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel(dir.path(), "analysis", "0,0,48,48");
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/data/bunny-1k8.obj");
    for preset in Preset::all() {
        let out = dir.path().join(format!("{}.ply", preset.name.as_str()));
        run_ok(&[
            "-q",
            "synth",
            s(&analysis),
            bunny,
            "--vertices",
            "6000",
            "--preset",
            preset.name.as_str(),
            "-o",
            s(&out),
        ]);
        let map = btfsynth::synth::surface_map::read_surface_ply(&out).unwrap();
        // The 7×7 template keeps coordinates 3 texels inside the 48² sample: the band's
        // outermost ring is 164 of its 1764 texels (9.3%).
        let on_ring = map.state.uv.iter().filter(|&&[x, y]| x == 3 || y == 3 || x == 44 || y == 44).count();
        let share = on_ring as f64 / map.state.uv.len() as f64;
        assert!(
            share < 2.0 * 164.0 / 1764.0,
            "{}: {share} of the vertices on the band's edge",
            preset.name.as_str()
        );
        let q = eval(&analysis, &out);
        let collapse = q["coords"]["collapse"].as_f64().unwrap();
        assert!(collapse <= MAX_COLLAPSE, "{}: collapse {collapse}", preset.name.as_str());
    }
}

/// `eval` flags a verbatim tiling (copy ≥ 1) and a pixel shuffle (high patch energy, same
/// colours), through the real CLI on a real photograph.
#[test]
fn eval_flags_a_tiled_copy_and_a_pixel_shuffle() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel(dir.path(), "analysis", "0,0,48,48");
    let tiled = dir.path().join("tiled");
    std::fs::create_dir(&tiled).unwrap();
    let (w, h) = (96usize, 96usize);
    // Every output pixel copies texel (x mod 42 + 3, y mod 42 + 3): the whole candidate band,
    // tiled.
    let uv: Vec<u32> = (0..w * h).flat_map(|p| [(p % w % 42 + 3) as u32, (p / w % 42 + 3) as u32]).collect();
    btfsynth::analysis::npy::write(&tiled.join("uv.npy"), &[h, w, 2], &uv).unwrap();
    let labels = btfsynth::analysis::npy::read::<u16>(&analysis.join("level0_textons.npy")).unwrap();
    let tiled_labels: Vec<u16> =
        uv.chunks(2).map(|c| labels.data[c[1] as usize * 48 + c[0] as usize]).collect();
    btfsynth::analysis::npy::write(&tiled.join("labels.npy"), &[h, w], &tiled_labels).unwrap();
    let fingerprint = btfsynth::analysis::store::read_manifest(&analysis).unwrap().source.fingerprint;
    let manifest = serde_json::json!({"kind": "plane", "width": w, "height": h,
        "params": {"neighborhood": 7}, "analysis_fingerprint": fingerprint});
    std::fs::write(tiled.join("plane.json"), manifest.to_string()).unwrap();
    let q = eval_cli(&analysis, &tiled);
    assert_eq!(q, eval(&analysis, &tiled), "eval --json prints the library's figures");
    assert!(q["coords"]["copy"].as_f64().unwrap() >= 0.75, "a tiling of the whole band is flagged: {q}");

    // The sample's own pixels, shuffled: same colours, no patch of it exists in the sample.
    let sample = image::open(concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png")).unwrap().to_rgb8();
    let sample = image::imageops::crop_imm(&sample, 0, 0, 48, 48).to_image();
    let original = dir.path().join("original.png");
    sample.save(&original).unwrap();
    let mut pixels: Vec<image::Rgb<u8>> = sample.pixels().copied().collect();
    let mut state = 12345u64;
    for i in (1..pixels.len()).rev() {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        pixels.swap(i, (state >> 33) as usize % (i + 1));
    }
    let shuffled = dir.path().join("shuffled.png");
    image::RgbImage::from_fn(48, 48, |x, y| pixels[(y * 48 + x) as usize]).save(&shuffled).unwrap();
    let (a, b) = (eval(&analysis, &original), eval(&analysis, &shuffled));
    let energy = |q: &Value| q["probes"][0]["patch_energy"].as_f64().unwrap();
    assert!(energy(&a) < 1e-6, "the sample itself: {a}");
    assert!(energy(&b) > 0.005, "a shuffle matches no patch: {b}");
    assert!(b["probes"][0]["colour_chi2"].as_f64().unwrap() < 1e-9, "and keeps the colours: {b}");
}
