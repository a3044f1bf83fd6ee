//! `synth --recipe FILE`: a recipe in the form `synth` records runs exactly like the preset
//! it came from, a hand-edited one runs and is recorded as given, and a recipe the engine
//! cannot run is refused with one line.

use crate::common;

use btfsynth::synth::{Mask, ParentNeighbourhood, Preset, Stencil};
use common::{assert_usage_error, btfsynth, entries};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn run_ok(args: &[&str]) {
    let r = btfsynth(args);
    assert!(r.status.success(), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
}

fn write_json(path: &Path, json: &Value) -> PathBuf {
    std::fs::write(path, serde_json::to_string_pretty(json).unwrap()).unwrap();
    path.to_path_buf()
}

/// A plane's labels and coordinates, byte for byte, and its manifest.
fn plane_bytes(out: &Path) -> (Vec<u8>, Vec<u8>, Value) {
    let manifest = serde_json::from_slice(&std::fs::read(out.join("plane.json")).unwrap()).unwrap();
    (std::fs::read(out.join("labels.npy")).unwrap(), std::fs::read(out.join("uv.npy")).unwrap(), manifest)
}

/// A 40×32 plane of `analysis` at seed 5, made as `how` says (`--preset NAME` or `--recipe
/// FILE`), into `out`: its labels and coordinates bytes and its plane.json.
fn seeded_plane(analysis: &Path, how: &[&str], out: &Path) -> (Vec<u8>, Vec<u8>, Value) {
    let args =
        [&["-q", "synth", s(analysis), "--plane", "40x32", "--seed", "5", "-o", s(out)][..], how].concat();
    run_ok(&args);
    plane_bytes(out)
}

/// The 3000-vertex bunny synthesized by the recipe in `file`, into `ply`.
fn synth_bunny_by_recipe(analysis: &Path, file: &Path, ply: &Path) {
    run_ok(&[
        "-q",
        "synth",
        s(analysis),
        common::BUNNY,
        "--vertices",
        "3000",
        "--recipe",
        s(file),
        "-o",
        s(ply),
    ]);
}

/// Every preset, recorded by `synth`, copied out of plane.json and given back with
/// --recipe, gives the same bytes.
#[test]
fn every_recorded_recipe_gives_back_its_presets_output() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    for preset in Preset::all() {
        let name = preset.name.as_str();
        let (labels, uv, manifest) =
            seeded_plane(&analysis, &["--preset", name], &dir.path().join(format!("{name}-preset")));
        let file = write_json(&dir.path().join(format!("{name}.json")), &manifest["params"]["recipe"]);
        let by_recipe = dir.path().join(format!("{name}-recipe"));
        let (labels2, uv2, manifest2) = seeded_plane(&analysis, &["--recipe", s(&file)], &by_recipe);
        assert!(labels == labels2 && uv == uv2, "{name}: the recipe's output differs from the preset's");
        assert_eq!(manifest2["params"]["recipe"], manifest["params"]["recipe"], "{name}");
        assert_eq!(manifest2["params"]["preset"], name);
        if !preset.rounds() {
            older_recipe_gives_the_same_output(
                &analysis,
                &manifest["params"]["recipe"],
                (&labels, &uv),
                name,
            );
        }
    }
}

/// A square-template recipe recorded before passes named their stencil still runs, as the
/// same preset.
fn older_recipe_gives_the_same_output(
    analysis: &Path,
    recipe: &Value,
    (labels, uv): (&[u8], &[u8]),
    name: &str,
) {
    let mut older = recipe.clone();
    for level in ["coarsest", "finer"] {
        for pass in older[level]["passes"].as_array_mut().unwrap() {
            pass.as_object_mut().unwrap().remove("stencil");
        }
    }
    let dir = analysis.parent().unwrap();
    let file = write_json(&dir.join(format!("{name}-older.json")), &older);
    let (labels2, uv2, manifest) =
        seeded_plane(analysis, &["--recipe", s(&file)], &dir.join(format!("{name}-older")));
    assert!(labels == labels2 && uv == uv2, "{name}: a recipe without stencils differs");
    assert_eq!(manifest["params"]["recipe"], *recipe, "{name}: recorded with its stencils");
}

/// The default with one coarsest pass less, renamed: it runs, differs from the default, and
/// plane.json, --report and a PLY header record it as given.
#[test]
fn a_hand_edited_recipe_runs_and_is_recorded_as_given() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    let mut recipe = Preset::appearance().to_json();
    recipe["name"] = "three-coarse-passes".into();
    recipe["coarsest"]["passes"].as_array_mut().unwrap().pop();
    let file = write_json(&dir.path().join("edited.json"), &recipe);
    let (out, default, report) =
        (dir.path().join("edited"), dir.path().join("default"), dir.path().join("report.json"));
    let args = ["-q", "synth", s(&analysis), "--plane", "40x32", "--seed", "5"];
    run_ok(&[&args[..], &["--recipe", s(&file), "-o", s(&out), "--report", s(&report)]].concat());
    run_ok(&[&args[..], &["-o", s(&default)]].concat());
    let (labels, uv, manifest) = plane_bytes(&out);
    assert_eq!(manifest["params"]["recipe"], recipe);
    assert_eq!(manifest["params"]["preset"], "three-coarse-passes");
    let report: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(report["params"]["recipe"], recipe);
    assert_eq!(report["levels"][0]["passes"], 3, "the coarsest level ran the passes given: {report}");
    let (default_labels, default_uv, _) = plane_bytes(&default);
    assert!(labels != default_labels || uv != default_uv, "the edited recipe was not the one run");

    let ply = dir.path().join("bunny.ply");
    synth_bunny_by_recipe(&analysis, &file, &ply);
    let map = btfsynth::synth::surface_map::read_surface_ply(&ply).unwrap();
    let params: Value = serde_json::from_str(map.comment("params").unwrap()).unwrap();
    assert_eq!(params["recipe"], recipe);
}

/// Each recipe the engine cannot run: one `error:` line naming the file and the problem,
/// exit 2, nothing written.
#[test]
fn bad_recipes_are_refused_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    let out = dir.path().join("out");
    let synth = |recipe: &Path| {
        btfsynth(&["synth", s(&analysis), "--plane", "16x16", "--recipe", s(recipe), "-o", s(&out)])
    };
    let edited = |name: &str, edit: &dyn Fn(&mut Value)| {
        let mut recipe = Preset::appearance().to_json();
        edit(&mut recipe);
        write_json(&dir.path().join(name), &recipe)
    };
    assert_usage_error(&synth(&dir.path().join("missing.json")), "missing.json: cannot read it");
    let broken = dir.path().join("broken.json");
    std::fs::write(&broken, "{\"name\": \"x\",").unwrap();
    assert_usage_error(&synth(&broken), "broken.json: EOF while parsing");
    let typo = edited("typo.json", &|r| r["finer"]["passes"][0]["metrc"] = "Colour".into());
    assert_usage_error(&synth(&typo), "unknown field `metrc`");
    let variant = edited("variant.json", &|r| r["finer"]["passes"][0]["metric"] = "Color".into());
    assert_usage_error(&synth(&variant), "unknown variant `Color`");
    let inherits = edited("inherits.json", &|r| r["coarsest"]["start"] = "Inherit".into());
    assert_usage_error(&synth(&inherits), "the coarsest level cannot inherit");
    let empty = edited("empty.json", &|r| r["finer"]["passes"] = Value::Array(vec![]));
    assert_usage_error(&synth(&empty), "the finer level has no passes");
    let blind = edited("blind.json", &|r| {
        r["finer"]["passes"][0]["mask"] = serde_json::to_value(Mask::Off).unwrap();
        r["finer"]["passes"][0]["parent"] = serde_json::to_value(ParentNeighbourhood::None).unwrap();
    });
    assert_usage_error(&synth(&blind), "finer pass 0: mask Off compares nothing");
    let orphan = edited("orphan.json", &|r| r["coarsest"]["passes"][0]["parent"] = "Narrow".into());
    assert_usage_error(&synth(&orphan), "the coarsest level has no parent neighbourhood");
    let round =
        edited("round.json", &|r| r["finer"]["passes"][1]["stencil"] = json!({"Round": {"circles": 3}}));
    assert_usage_error(&synth(&round), "finer pass 1: the Appearance metric matches square templates");
    let chen = |name: &str, edit: &dyn Fn(&mut Value)| {
        let mut recipe = Preset::chen2008().to_json();
        edit(&mut recipe);
        write_json(&dir.path().join(name), &recipe)
    };
    // A recipe recorded before passes named their stencil means square templates, which a
    // round-neighbourhood pass refuses.
    let unshaped = chen("unshaped.json", &|r| {
        r["finer"]["passes"][0].as_object_mut().unwrap().remove("stencil");
    });
    assert_usage_error(&synth(&unshaped), "the Adaptive metric matches round neighbourhoods");
    let square = chen("square.json", &|r| r["finer"]["passes"][0]["stencil"] = "Square".into());
    assert_usage_error(&synth(&square), "the Adaptive metric matches round neighbourhoods");
    for (circles, needle) in [(0, "not 0"), (9, "1 to 7 circles")] {
        let wide = chen("circles.json", &|r| {
            r["finer"]["passes"][0]["stencil"]["Round"]["circles"] = circles.into()
        });
        assert_usage_error(&synth(&wide), needle);
    }
    let disagree =
        chen("disagree.json", &|r| r["finer"]["passes"][0]["stencil"]["Round"]["circles"] = 2.into());
    assert_usage_error(&synth(&disagree), "not 3 and 2");
    let both = btfsynth(&[
        "synth",
        s(&analysis),
        "--plane",
        "16x16",
        "--recipe",
        s(&typo),
        "--preset",
        "tong2002",
        "-o",
        s(&out),
    ]);
    assert_usage_error(&both, "--preset");

    // An analysis written before appearance vectors existed cannot feed that metric.
    let old = dir.path().join("old");
    std::fs::create_dir(&old).unwrap();
    for entry in std::fs::read_dir(&analysis).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, old.join(path.file_name().unwrap())).unwrap();
    }
    let mut manifest: Value =
        serde_json::from_slice(&std::fs::read(old.join("analysis.json")).unwrap()).unwrap();
    for level in manifest["levels"].as_array_mut().unwrap() {
        level["files"].as_object_mut().unwrap().remove("appearance");
    }
    write_json(&old.join("analysis.json"), &manifest);
    let fine = write_json(&dir.path().join("fine.json"), &Preset::appearance().to_json());
    let r = btfsynth(&["synth", s(&old), "--plane", "16x16", "--recipe", s(&fine), "-o", s(&out)]);
    assert_usage_error(&r, "appearance vectors, which this analysis lacks");

    // Three levels (asked for: the default stops at 48²) of the 48² crop leave a 12²
    // coarsest level, which holds no candidate's whole round neighbourhood of 6 circles (15²
    // texels): refused before any work.
    let small = dir.path().join("small");
    let texture = concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png");
    run_ok(&[
        "-q",
        "analyze",
        texture,
        "--crop",
        "0,0,48,48",
        "--textons",
        "32",
        "--levels",
        "3",
        "-o",
        s(&small),
    ]);
    let six = chen("six.json", &|r| {
        for level in ["coarsest", "finer"] {
            for pass in r[level]["passes"].as_array_mut().unwrap() {
                pass["stencil"]["Round"]["circles"] = 6.into();
            }
        }
    });
    let six_args =
        ["synth", s(&small), "--plane", "16x16", "--levels", "3", "--recipe", s(&six), "-o", s(&out)];
    let r = btfsynth(&six_args);
    assert_usage_error(&r, "the coarsest sample level in use is 12x12: use at most 4 circles");
    let mut names = entries(dir.path());
    names.retain(|n| !n.ends_with(".json"));
    assert_eq!(names, ["analysis", "old", "small"], "nothing written");
}

/// chen2008's recipe with round neighbourhoods of 2 circles instead of 3 runs on a plane
/// and a mesh (marched for 2 circles), is recorded as given, and gives another result.
#[test]
fn the_round_stencil_is_the_recipes() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    let mut two = Preset::chen2008();
    two.name = "chen2008-two-circles".into();
    two.all_passes_mut().for_each(|p| *p = p.edited(|r| r.stencil = Stencil::Round { circles: 2 }).unwrap());
    let file = common::write_recipe(&dir.path().join("two.json"), &two);
    let plane = ["-q", "synth", s(&analysis), "--plane", "40x32", "--seed", "5"];
    let (by_two, by_three) = (dir.path().join("two"), dir.path().join("three"));
    run_ok(&[&plane[..], &["--recipe", s(&file), "-o", s(&by_two)]].concat());
    run_ok(&[&plane[..], &["--preset", "chen2008", "-o", s(&by_three)]].concat());
    let (labels, uv, manifest) = plane_bytes(&by_two);
    let (labels3, uv3, manifest3) = plane_bytes(&by_three);
    assert_eq!(
        manifest["params"]["recipe"]["finer"]["passes"][0]["stencil"],
        json!({"Round": {"circles": 2}})
    );
    assert_eq!(
        manifest3["params"]["recipe"]["finer"]["passes"][0]["stencil"],
        json!({"Round": {"circles": 3}})
    );
    assert!(labels != labels3 || uv != uv3, "2 circles gave 3 circles' plane");

    let mesh = ["-q", "synth", s(&analysis), common::BUNNY, "--vertices", "3000", "--seed", "5"];
    let (ply2, ply3) = (dir.path().join("two.ply"), dir.path().join("three.ply"));
    run_ok(&[&mesh[..], &["--recipe", s(&file), "-o", s(&ply2)]].concat());
    run_ok(&[&mesh[..], &["--preset", "chen2008", "-o", s(&ply3)]].concat());
    let (map2, map3) = (
        btfsynth::synth::surface_map::read_surface_ply(&ply2).unwrap(),
        btfsynth::synth::surface_map::read_surface_ply(&ply3).unwrap(),
    );
    let params: Value = serde_json::from_str(map2.comment("params").unwrap()).unwrap();
    assert_eq!(params["recipe"], two.to_json());
    assert!(map2.state.uv != map3.state.uv, "2 circles gave 3 circles' surface map");

    // A marching cache filled by 3 circles is not read back for 2: the run gives the
    // uncached 2-circle map (a 3-circle marching would be refused by the engine).
    let cache = dir.path().join("cache");
    let (cached3, cached) = (dir.path().join("cached3.ply"), dir.path().join("cached.ply"));
    run_ok(
        &[&mesh[..], &["--preset", "chen2008", "--marching-cache", s(&cache), "-o", s(&cached3)]].concat(),
    );
    run_ok(&[&mesh[..], &["--recipe", s(&file), "--marching-cache", s(&cache), "-o", s(&cached)]].concat());
    let map = btfsynth::synth::surface_map::read_surface_ply(&cached).unwrap();
    assert!(map.state.uv == map2.state.uv && map.state.labels == map2.state.labels);
}

/// The colour metric reached through a recipe: every preset's schedule matched on colour
/// SSD runs on a plane (both searches) and on a mesh, and an analysis of a BTF builds its
/// colours from the mean of its selected images.
#[test]
fn colour_recipes_run_on_planes_meshes_and_btfs() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    for preset in common::square_presets() {
        let file = write_json(
            &dir.path().join(format!("{}.json", preset.name)),
            &common::colour_recipe(&preset).to_json(),
        );
        for search in ["kcoherence", "full"] {
            let out = dir.path().join(format!("{}-{search}", preset.name));
            run_ok(&[
                "-q",
                "synth",
                s(&analysis),
                "--plane",
                "24x24",
                "--recipe",
                s(&file),
                "--search",
                search,
                "-o",
                s(&out),
            ]);
            assert_eq!(plane_bytes(&out).2["params"]["recipe"], common::colour_recipe(&preset).to_json());
        }
        let ply = dir.path().join(format!("{}.ply", preset.name));
        synth_bunny_by_recipe(&analysis, &file, &ply);
        assert!(btfsynth::synth::surface_map::read_surface_ply(&ply).is_ok());
    }
    let stack = dir.path().join("pebbles");
    run_ok(&["-q", "gen", "pebbles", "--size", "32", "--directions", "grid:3", "-o", s(&stack)]);
    let btf = dir.path().join("btf-analysis");
    run_ok(&["-q", "analyze", s(&stack), "--levels", "2", "-o", s(&btf)]);
    let file =
        write_json(&dir.path().join("btf.json"), &common::colour_recipe(&Preset::appearance()).to_json());
    run_ok(&[
        "-q",
        "synth",
        s(&btf),
        "--plane",
        "24x24",
        "--recipe",
        s(&file),
        "-o",
        s(&dir.path().join("btf-plane")),
    ]);
}

/// Jittered upsampling (Lefebvre and Hoppe 2005): the default with its finer levels
/// jittered by one texel runs on a plane and a surface, gives the same bytes at 1 and 2
/// threads, and differs from the default; half a texel moves nothing, so gives the default.
#[test]
fn jittered_upsampling_runs_at_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    let jittered = |texels: f64, name: &str| {
        let mut recipe = Preset::appearance().to_json();
        recipe["name"] = name.into();
        recipe["finer"]["start"] = json!({"Jittered": {"texels": texels}});
        write_json(&dir.path().join(format!("{name}.json")), &recipe)
    };
    let (one, half) = (jittered(1.0, "jitter-1"), jittered(0.5, "jitter-half"));
    let plane = |how: &[&str], threads: &str, out: &str| {
        // Two levels, asked for: the default synthesizes this 48² crop on one, and jitter
        // moves only the finer levels' coordinates.
        let levels = ["--levels", "2", "--threads", threads];
        seeded_plane(&analysis, &[&levels[..], how].concat(), &dir.path().join(out))
    };
    let (labels1, uv1, _) = plane(&["--recipe", s(&one)], "1", "j1");
    let (labels2, uv2, manifest) = plane(&["--recipe", s(&one)], "2", "j2");
    assert!(labels1 == labels2 && uv1 == uv2, "jittered planes differ between 1 and 2 threads");
    assert_eq!(manifest["params"]["recipe"]["finer"]["start"], json!({"Jittered": {"texels": 1.0}}));
    let (default_labels, default_uv, _) = plane(&[], "2", "default");
    assert!(uv1 != default_uv, "a one-texel jitter changed nothing");
    let (half_labels, half_uv, _) = plane(&["--recipe", s(&half)], "2", "half");
    assert!(half_labels == default_labels && half_uv == default_uv, "half a texel moved something");
    synth_bunny_by_recipe(&analysis, &one, &dir.path().join("bunny.ply"));
}
