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

/// A copy of the analysis `from` in `to`, with the array `name` (f32 or f16 per `half`)
/// changed by `edit`.
fn damaged_analysis(from: &std::path::Path, to: &std::path::Path, name: &str, edit: impl Fn(&mut Vec<f32>)) {
    use btfsynth::analysis::npy;
    std::fs::create_dir(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, to.join(path.file_name().unwrap())).unwrap();
    }
    let path = to.join(name);
    let bytes = std::fs::read(&path).unwrap();
    if let Ok(a) = npy::decode::<f32>(&bytes) {
        let mut data = a.data;
        edit(&mut data);
        std::fs::write(&path, npy::encode(&a.shape, &data).unwrap()).unwrap();
    } else {
        let a = npy::decode::<half::f16>(&bytes).unwrap();
        let mut data: Vec<f32> = a.data.iter().map(|v| v.to_f32()).collect();
        edit(&mut data);
        let data: Vec<half::f16> = data.into_iter().map(half::f16::from_f32).collect();
        std::fs::write(&path, npy::encode(&a.shape, &data).unwrap()).unwrap();
    }
}

/// A damaged analysis' name, the array damaged and how.
type Damage = (&'static str, &'static str, fn(&mut Vec<f32>));

#[test]
fn nan_and_out_of_range_arrays_are_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "a");
    let cases: [Damage; 6] = [
        ("nan-appearance", "level0_appearance.npy", |d| d[5] = f32::NAN),
        // Level 0: the one a 16x16 plane uses by default (a level not in use is not read).
        ("inf-gamma", "level0_gamma.npy", |d| d[1] = f32::INFINITY),
        ("nan-embedding", "level0_embedding.npy", |d| d[0] = f32::NAN),
        ("nan-images", "images.npy", |d| d[7] = f32::NAN),
        ("nan-direction", "directions.npy", |d| d[0] = f32::NAN),
        ("theta-500", "directions.npy", |d| d[2] = 500.0),
    ];
    for (name, file, edit) in cases {
        let damaged = dir.path().join(name);
        damaged_analysis(&analysis, &damaged, file, edit);
        let out = dir.path().join(format!("{name}-plane"));
        let r =
            btfsynth(&["synth", damaged.to_str().unwrap(), "--plane", "16x16", "-o", out.to_str().unwrap()]);
        assert_one_line_error(&r, &format!("{name}/{file}"));
        assert!(!out.exists(), "{name}: nothing written");
    }
    // render reads the images and directions too.
    let damaged = dir.path().join("nan-images");
    let material = btfsynth::render::Material::open(&damaged);
    let e = material.err().expect("refused").to_string();
    assert!(e.contains("nan-images/images.npy") && e.contains("NaN"), "{e}");
}

#[test]
fn a_damaged_knn_list_is_reported_as_itself() {
    use btfsynth::analysis::npy;
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "a");
    let damaged = dir.path().join("knn");
    damaged_analysis(&analysis, &damaged, "level0_gamma.npy", |_| {});
    let knn: npy::NpyArray<u32> = npy::read(&damaged.join("level0_knn.npy")).unwrap();
    let mut data = knn.data;
    data[3] = 1 << 30;
    std::fs::write(damaged.join("level0_knn.npy"), npy::encode(&knn.shape, &data).unwrap()).unwrap();
    let out = dir.path().join("plane");
    let r = btfsynth(&["synth", damaged.to_str().unwrap(), "--plane", "16x16", "-o", out.to_str().unwrap()]);
    assert_one_line_error(&r, "knn/level0_knn.npy");
    let shape = [knn.shape[0], knn.shape[1] - 1, knn.shape[2]];
    let fewer = vec![0u32; shape.iter().product()];
    std::fs::write(damaged.join("level0_knn.npy"), npy::encode(&shape, &fewer).unwrap()).unwrap();
    let r = btfsynth(&["synth", damaged.to_str().unwrap(), "--plane", "16x16", "-o", out.to_str().unwrap()]);
    assert_one_line_error(&r, "knn/level0_knn.npy: shape");
}

#[test]
fn a_truncated_jpeg_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let img = image::RgbImage::from_fn(64, 48, |x, y| image::Rgb([(x * 4) as u8, (y * 5) as u8, 90]));
    let path = dir.path().join("photo.jpg");
    img.save(&path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let r = btfsynth(&["info", path.to_str().unwrap()]);
    assert!(r.status.success(), "the whole JPEG loads: {}", String::from_utf8_lossy(&r.stderr));
    for keep in [bytes.len() - 2, bytes.len() / 2, 700] {
        std::fs::write(&path, &bytes[..keep]).unwrap();
        assert_one_line_error(
            &btfsynth(&["info", path.to_str().unwrap()]),
            "photo.jpg: the JPEG is truncated",
        );
    }
}

#[test]
fn a_zip_with_two_members_of_one_name_is_refused() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let png = |seed| {
        let img = image::RgbImage::from_fn(4, 4, |x, y| image::Rgb(pattern(seed)(x, y)));
        let mut bytes = std::io::Cursor::new(Vec::new());
        img.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
        bytes.into_inner()
    };
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let stored = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for (name, seed) in [("tl000 pl000 tv000 pv000.png", 0), ("tl015 pl000 tv000 pv000.png", 1)] {
        zip.start_file(name, stored).unwrap();
        zip.write_all(&png(seed)).unwrap();
    }
    let mut bytes = zip.finish().unwrap().into_inner();
    let path = dir.path().join("stack.zip");
    std::fs::write(&path, &bytes).unwrap();
    let r = btfsynth(&["info", path.to_str().unwrap(), "--json"]);
    assert!(r.status.success(), "two distinct members load: {}", String::from_utf8_lossy(&r.stderr));
    // The second member renamed to the first's name, in its local header and the directory.
    let (from, to) = (b"tl015 pl000", b"tl000 pl000");
    while let Some(at) = bytes.windows(from.len()).position(|w| w == from) {
        bytes[at..at + from.len()].copy_from_slice(to);
    }
    std::fs::write(&path, &bytes).unwrap();
    assert_one_line_error(
        &btfsynth(&["info", path.to_str().unwrap()]),
        "two members named 'tl000 pl000 tv000 pv000.png'",
    );
}

#[test]
fn a_stray_far_triangle_does_not_collapse_the_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let bunny = std::fs::read_to_string(common::BUNNY).unwrap();
    let vertices = bunny.lines().filter(|l| l.starts_with("v ")).count();
    let mesh = dir.path().join("stray.obj");
    let n = vertices + 1;
    std::fs::write(
        &mesh,
        format!("{bunny}\nv 1e6 1e6 1e6\nv 1000001 1e6 1e6\nv 1e6 1000001 1e6\nf {n} {} {}\n", n + 1, n + 2),
    )
    .unwrap();
    let r = btfsynth(&["info", mesh.to_str().unwrap(), "--json"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let json: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(
        (json["vertices"].as_u64(), json["faces"].as_u64()),
        (Some(1839 + 3), Some(3674 + 1)),
        "{json}"
    );
    assert_eq!(json["components"].as_u64(), Some(2));
}

#[test]
fn a_mesh_that_is_mostly_degenerate_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("slivers.obj");
    let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    for i in 0..10 {
        text.push_str(&format!("v {} 0 0\nf 1 2 {}\n", 0.05 * f64::from(i + 1), i + 4));
    }
    std::fs::write(&mesh, text).unwrap();
    assert_one_line_error(&btfsynth(&["info", mesh.to_str().unwrap()]), "10 of 11 faces are degenerate");
}

/// Writes a disc of one `n`-sided polygon to `path`.
fn write_disc(path: &std::path::Path, n: usize) {
    let mut text = String::new();
    for i in 0..n {
        let a = i as f64 / n as f64 * std::f64::consts::TAU;
        text.push_str(&format!("v {} {} 0\n", a.cos(), a.sin()));
    }
    text.push('f');
    for i in 1..=n {
        text.push_str(&format!(" {i}"));
    }
    text.push('\n');
    std::fs::write(path, text).unwrap();
}

#[test]
fn a_huge_polygon_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("disc.obj");
    write_disc(&mesh, 10_000);
    let started = std::time::Instant::now();
    let out = dir.path().join("out.ply");
    let r = btfsynth(&["remesh", mesh.to_str().unwrap(), "--vertices", "500", "-o", out.to_str().unwrap()]);
    assert_one_line_error(&r, "disc.obj: vertex 0 is a corner of");
    assert!(started.elapsed().as_secs() < 20, "refused before any remeshing");
}

#[test]
fn devices_are_refused_as_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let link = |name: &str, target: &str| {
        let link = dir.path().join(name);
        std::os::unix::fs::symlink(target, &link).unwrap();
        link.to_str().unwrap().to_string()
    };
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    let zero = link("zero.obj", "/dev/zero");
    assert_one_line_error(
        &btfsynth(&["remesh", &zero, "--vertices", "100", "-o", o]),
        "zero.obj: a device, not a file",
    );
    let random = link("random.png", "/dev/urandom");
    assert_one_line_error(&btfsynth(&["info", &random]), "random.png: a device, not a file");
    let analysis = dir.path().join("a");
    std::fs::create_dir(&analysis).unwrap();
    std::os::unix::fs::symlink("/dev/zero", analysis.join("analysis.json")).unwrap();
    let r = btfsynth(&["synth", analysis.to_str().unwrap(), "--plane", "8x8", "-o", o]);
    assert_one_line_error(&r, "analysis.json: a device, not a file");
    let filters = link("bank.toml", "/dev/zero");
    let texture = concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png");
    assert_one_line_error(
        &btfsynth(&["analyze", texture, "--filters", &filters, "-o", o]),
        "a device, not a file",
    );
    assert!(!out.exists());
}

#[test]
fn a_filter_bank_of_thousands_is_refused_before_it_is_built() {
    let dir = tempfile::tempdir().unwrap();
    let bank = dir.path().join("big.toml");
    let mut text = String::from("support = 9\n");
    for i in 0..20_000 {
        text.push_str(&format!(
            "[[filters]]\nkind = \"gaussian\"\nsigma = {}\n",
            1.0 + f64::from(i % 7) * 0.1
        ));
    }
    std::fs::write(&bank, text).unwrap();
    let texture = concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png");
    let out = dir.path().join("out");
    let r = btfsynth(&["analyze", texture, "--filters", bank.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_one_line_error(&r, "big.toml: 20000 filters; a bank holds at most 256");
}

#[test]
fn converting_an_incomplete_stack_to_a_btf_file_names_the_stack() {
    let dir = tempfile::tempdir().unwrap();
    let stack = dir.path().join("stack");
    std::fs::create_dir(&stack).unwrap();
    // Two views and two lights, but the fourth pair is missing.
    for name in ["tl000_pl000_tv000_pv000", "tl015_pl000_tv000_pv000", "tl000_pl000_tv015_pv000"] {
        write_png(&stack.join(format!("{name}.png")), 8, 8, pattern(0));
    }
    let out = dir.path().join("s.btf");
    let r = btfsynth(&["convert", stack.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_one_line_error(&r, "stack: a DFMF file needs every view × light pair: this stack has 3 images");
    assert!(!out.exists(), "nothing written");
}

/// A photo given where an analysis goes (a new user's first guess) is named as a file that
/// is not an analysis, with the command that makes one; nothing is written.
#[test]
fn a_photo_in_place_of_an_analysis() {
    let dir = tempfile::tempdir().unwrap();
    let photo = concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png");
    let out = dir.path().join("plane");
    let r = btfsynth(&["synth", photo, "--plane", "32x32", "-o", out.to_str().unwrap()]);
    assert_one_line_error(&r, "not an analysis directory (make one with `btfsynth analyze");
    assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
}

#[test]
fn a_surface_synthesis_that_would_not_fit_in_memory_is_refused_before_remeshing() {
    // Issue #21's reliability rule for synthesis: the finest mesh's vertex count sets the
    // peak (benches/big_btf.sh measured it), so a density beyond the budget is one line,
    // not a run the kernel kills.
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "gravel");
    let mesh = concat!(env!("CARGO_MANIFEST_DIR"), "/data/bunny-1k8.obj");
    let out = dir.path().join("bunny.ply");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_btfsynth"))
        .args([
            "synth",
            analysis.to_str().unwrap(),
            mesh,
            "--vertices",
            "200000",
            "-o",
            out.to_str().unwrap(),
        ])
        .env("BTFSYNTH_MEMORY", "100M")
        .output()
        .unwrap();
    assert_one_line_error(&run, "at synthesis' peak, more than the 100 MiB budget (BTFSYNTH_MEMORY=100M)");
    assert!(!out.exists(), "nothing is written");
}

/// soler2002 refuses in one line, before any work, what it cannot map, as the vertex engine
/// does: a texture too large for the surface (the flag's mistake, exit 2, naming it) or for
/// the memory budget, a huge polygon, coordinates beyond single precision, a mesh of one
/// point (exit 1). A recipe of more passes than any run needs is refused too.
#[test]
fn every_path_refuses_what_it_cannot_do_before_any_work() {
    use common::{analyze_gravel_crop, assert_usage_error, BUNNY};
    let dir = tempfile::tempdir().unwrap();
    let analysis = analyze_gravel_crop(dir.path(), "gravel");
    let out = dir.path().join("out.ply");
    let soler = |mesh: &str, extra: &[&str], memory: &str| {
        let args =
            ["synth", analysis.to_str().unwrap(), mesh, "--method", "soler2002", "-o", out.to_str().unwrap()];
        std::process::Command::new(env!("CARGO_BIN_EXE_btfsynth"))
            .args(args)
            .args(extra)
            .env("BTFSYNTH_MEMORY", memory)
            .output()
            .unwrap()
    };
    assert_usage_error(&soler(BUNNY, &["--scale", "1e6"], "unlimited"), "--scale 1e6: puts");
    assert_usage_error(&soler(BUNNY, &["--scale", "1e30"], "unlimited"), "more than 2^26");
    assert_usage_error(
        &soler(BUNNY, &["--texels-across", "1e9"], "unlimited"),
        "--texels-across 1000000000: puts",
    );
    // Beyond the memory budget: exit 1, as the vertex engine's refusal.
    assert_one_line_error(&soler(BUNNY, &[], "1K"), "more than the 1 KiB budget (BTFSYNTH_MEMORY=1K)");
    assert_usage_error(&soler(BUNNY, &["--device", "gpu"], "unlimited"), "--device gpu");

    let bunny = std::fs::read_to_string(BUNNY).unwrap();
    let scaled = |f: &dyn Fn(f64) -> f64| {
        let line = |l: &str| match l.strip_prefix("v ") {
            Some(v) => format!(
                "v {}",
                v.split_whitespace().map(|x| f(x.parse().unwrap()).to_string()).collect::<Vec<_>>().join(" ")
            ),
            None => l.to_string(),
        };
        bunny.lines().map(line).collect::<Vec<_>>().join("\n")
    };
    let (far, point, disc) =
        (dir.path().join("far.obj"), dir.path().join("point.obj"), dir.path().join("disc.obj"));
    std::fs::write(&far, scaled(&|x| x * 1e30)).unwrap();
    std::fs::write(&point, scaled(&|_| 1.0)).unwrap();
    write_disc(&disc, 2_000);
    let file = |p: &std::path::PathBuf| p.to_str().unwrap().to_string();
    assert_one_line_error(&soler(&file(&far), &[], "unlimited"), "whose square single precision holds");
    assert_one_line_error(&soler(&file(&point), &[], "unlimited"), "no extent");
    assert_one_line_error(&soler(&file(&point), &["--scale", "10"], "unlimited"), "no face has an area");
    assert_one_line_error(&soler(&file(&disc), &[], "unlimited"), "vertex 0 is a corner of 1998 triangles");
    assert!(!out.exists());

    let mut recipe = btfsynth::synth::Preset::appearance();
    recipe.coarsest.passes = vec![recipe.coarsest.passes[0]; 65];
    let recipe = common::write_recipe(&dir.path().join("recipe.json"), &recipe);
    let plane = dir.path().join("plane");
    let args =
        ["synth", analysis.to_str().unwrap(), "--plane", "16x16", "--recipe", recipe.to_str().unwrap()];
    let r = btfsynth(&[&args[..], &["-o", plane.to_str().unwrap()]].concat());
    assert_usage_error(&r, "the coarsest level has 65 passes, more than 64");
    assert!(!plane.exists());
}
