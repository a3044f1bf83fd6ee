//! The synthesis-quality benchmark: btfsynth (defaults) beside two peers, Embark's
//! `texture-synthesis` and Resynthesizer (the engine of GIMP's plug-in), all on defaults, on
//! every photograph of `../shared/data/textures` twice — at its own size (cropped to 256²
//! where larger) → 4× its side (at most 512), and as a 128² crop → 512² — and on generated
//! BTFs (`gen pebbles|weave|bricks`, 64² → 256²), with wall time, CPU time, peak memory and
//! every quality measure of `btfsynth eval` (repetition included), one table, a summary of
//! repetition per sample-size band (≤ 64, 65–128, > 128 texels a side) against each peer,
//! and one montage per sample (sample | Embark | Resynthesizer | btfsynth). Not a test:
//! figures are reported, never asserted.
//!
//! ```text
//! benches/quality.sh            # installs the peers into target/peer, then runs this
//! cargo run --release --example quality -- --peer PATH [--resynth COMMAND] [--out DIR] [--seeds N] [--only NAME] [--set own|crops|gen|all]
//! ```
//!
//! `--resynth` is a command (its words split on spaces) that takes `SAMPLE.png OUT.png SIDE`
//! (`scripts/resynth_peer.py` under a Python that has the `resynthesizer` package); without
//! it the Resynthesizer column is left out. Resynthesizer is GPL and only ever run as that
//! outside program.
//!
//! btfsynth runs as its release binary (`target/release/btfsynth`), the peer as given; each
//! run is timed through `wait4` in a small re-executed copy of this program (Linux counts
//! the RSS of the process that forked a child into the child's peak, so the benchmark's
//! own pictures would otherwise inflate every figure), so CPU time and peak memory are the
//! measured program's own.

use btfsynth::analysis::images::SampleImages;
use btfsynth::eval::report::evaluate_plane;
use btfsynth::eval::{coord_quality, picture_quality, CoordQuality, Picture, PictureQuality};
use btfsynth::synth::target::grid_levels;
use btfsynth::synth::State;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// One measured run of a child process.
#[derive(Clone, Copy, Default)]
struct Cost {
    wall: f64,
    cpu: f64,
    peak_mb: f64,
}

impl std::ops::Add for Cost {
    type Output = Cost;
    fn add(self, o: Cost) -> Cost {
        Cost { wall: self.wall + o.wall, cpu: self.cpu + o.cpu, peak_mb: self.peak_mb.max(o.peak_mb) }
    }
}

/// What one tool produced on one sample.
struct Row {
    sample: String,
    /// The sample's width and height in texels.
    size: (usize, usize),
    tool: String,
    cost: Cost,
    picture: PictureQuality,
    coords: Option<CoordQuality>,
}

struct Options {
    peer: PathBuf,
    resynth: Option<String>,
    out: PathBuf,
    seeds: u64,
    only: Option<String>,
    set: String,
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some(MEASURE) {
        std::process::exit(measure_child(&args[2..]));
    }
    if let Err(e) = run(options()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn options() -> Options {
    let mut o = Options {
        peer: PathBuf::from("texture-synthesis"),
        resynth: None,
        out: "bench-out/quality".into(),
        seeds: 1,
        only: None,
        set: "all".into(),
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().unwrap_or_else(|| usage(&format!("{a} needs a value")));
        match a.as_str() {
            "--peer" => o.peer = value().into(),
            "--resynth" => o.resynth = Some(value()),
            "--out" => o.out = value().into(),
            "--seeds" => o.seeds = value().parse().unwrap_or_else(|_| usage("--seeds takes a number")),
            "--only" => o.only = Some(value()),
            "--set" => o.set = value(),
            _ => usage(&format!("unknown argument {a}")),
        }
    }
    o
}

fn usage(message: &str) -> ! {
    eprintln!("error: {message}\nusage: quality [--peer PATH] [--resynth COMMAND] [--out DIR] [--seeds N] [--only NAME] [--set own|crops|gen|all]");
    std::process::exit(2);
}

type Result<T> = std::result::Result<T, String>;

fn run(o: Options) -> Result<()> {
    let btfsynth = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/release/btfsynth");
    if !btfsynth.is_file() {
        return Err(format!("{} is missing: build it first (cargo build --release)", btfsynth.display()));
    }
    std::fs::create_dir_all(&o.out).map_err(|e| format!("{}: {e}", o.out.display()))?;
    let mut rows = Vec::new();
    for (name, stack, out_side) in samples(&o, &btfsynth)? {
        if o.only.as_ref().is_some_and(|only| !name.contains(only.as_str())) {
            continue;
        }
        eprintln!("== {name}");
        let dir = o.out.join(&name);
        rows.extend(sample_rows(&o, &btfsynth, &name, &stack, out_side, &dir)?);
    }
    let table = table(&rows) + "\n" + &size_bands(&rows);
    std::fs::write(o.out.join("quality.md"), &table).map_err(|e| e.to_string())?;
    println!("{table}");
    Ok(())
}

/// (name, stack path, output side) of every sample: each photograph at its own size (at
/// most 256² of it) and as a 128² crop, and the generated BTFs, as `--set` asks.
fn samples(o: &Options, btfsynth: &Path) -> Result<Vec<(String, PathBuf, usize)>> {
    let textures = btfsynth::testdata::shared_root().join("textures");
    let mut out = Vec::new();
    let mut files: Vec<PathBuf> = std::fs::read_dir(&textures)
        .map_err(|e| format!("{}: {e} (the photographs live in ../shared/data)", textures.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    files.sort();
    let wanted = |set: &str| o.set == "all" || o.set == set;
    for file in files {
        let name = file.file_stem().unwrap_or_default().to_string_lossy().into_owned();
        let image = image::open(&file).map_err(|e| format!("{}: {e}", file.display()))?.to_rgb8();
        let crop = |tag: &str, side: u32| -> Result<(String, PathBuf, usize)> {
            let (w, h) = (image.width().min(side), image.height().min(side));
            let path = o.out.join(format!("{name}-{tag}.png"));
            image::imageops::crop_imm(&image, 0, 0, w, h)
                .to_image()
                .save(&path)
                .map_err(|e| e.to_string())?;
            Ok((format!("{name}-{tag}"), path, (4 * w.min(h) as usize).min(512)))
        };
        if wanted("own") {
            out.push(crop("own", 256)?);
        }
        if wanted("crops") {
            out.push(crop("128", 128)?);
        }
    }
    if !wanted("gen") {
        return Ok(out);
    }
    for material in ["pebbles", "weave", "bricks"] {
        let stack = o.out.join(format!("gen-{material}"));
        if !stack.join("btf.json").is_file() {
            eprintln!("generating {material} (64² × 6561 images)");
            let (ok, _) = timed(
                Command::new(btfsynth)
                    .args(["-q", "gen", material, "--size", "64", "--directions", "ubo81", "--force", "-o"])
                    .arg(&stack),
            )?;
            ok.then_some(()).ok_or(format!("gen {material} failed"))?;
        }
        out.push((format!("gen-{material}"), stack, 256));
    }
    Ok(out)
}

/// btfsynth for every seed and the peer once on one sample; writes the montage.
fn sample_rows(
    o: &Options,
    btfsynth: &Path,
    name: &str,
    stack: &Path,
    side: usize,
    dir: &Path,
) -> Result<Vec<Row>> {
    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    let analysis = dir.join("analysis");
    let (ok, analyse) = timed(
        Command::new(btfsynth).args(["-q", "analyze"]).arg(stack).arg("--force").arg("-o").arg(&analysis),
    )?;
    ok.then_some(()).ok_or(format!("analyze {name} failed"))?;
    let images = SampleImages::open(&analysis).map_err(|e| e.to_string())?;
    let head_on = images.default_probes()[0].image;
    let sample = images.picture(head_on);
    let size = (sample.width, sample.height);
    let tileable = false;
    let mut rows = Vec::new();
    for seed in 0..o.seeds {
        let plane = dir.join(format!("btfsynth-{seed}"));
        let out_size = format!("{side}x{side}");
        let (ok, synth) = timed(
            Command::new(btfsynth)
                .args(["-q", "synth"])
                .arg(&analysis)
                .args(["--plane", &out_size, "--seed", &seed.to_string(), "--force", "-o"])
                .arg(&plane),
        )?;
        ok.then_some(()).ok_or(format!("synth {name} failed"))?;
        let e = evaluate_plane(&analysis, &plane).map_err(|e| e.to_string())?;
        rows.push(Row {
            sample: name.into(),
            size,
            tool: format!("btfsynth (seed {seed})"),
            cost: analyse + synth,
            picture: e.probes[0].quality,
            coords: e.coords,
        });
    }
    let mut peer = peer_row(o, name, &sample, side, dir, tileable)?;
    peer.size = size;
    rows.push(peer);
    let mut pictures = vec![dir.join("embark.png")];
    if let Some(command) = &o.resynth {
        let mut resynth = resynth_row(command, name, &sample, side, dir, tileable)?;
        resynth.size = size;
        rows.push(resynth);
        pictures.push(dir.join("resynthesizer.png"));
    }
    pictures.push(dir.join("btfsynth-0/result.png"));
    montage(&sample, &pictures, &o.out.join(format!("montage-{name}.png")))?;
    Ok(rows)
}

/// Resynthesizer through `command SAMPLE OUT SIDE` on the head-on sample image (no
/// coordinate map: it reports none).
fn resynth_row(
    command: &str,
    name: &str,
    sample: &Picture,
    side: usize,
    dir: &Path,
    tileable: bool,
) -> Result<Row> {
    let (input, out) = (dir.join("sample.png"), dir.join("resynthesizer.png"));
    save(sample, &input)?;
    let mut words = command.split_whitespace();
    let program = words.next().ok_or("--resynth is empty")?;
    let (ok, cost) = timed(Command::new(program).args(words).arg(&input).arg(&out).arg(side.to_string()))?;
    ok.then_some(()).ok_or(format!("Resynthesizer on {name} failed"))?;
    Ok(Row {
        sample: name.into(),
        size: (sample.width, sample.height),
        tool: "Resynthesizer".into(),
        cost,
        picture: picture_quality(&load(&out)?, sample, tileable),
        coords: None,
    })
}

/// Embark's texture-synthesis on the head-on sample image, and its coordinate map recovered
/// by replaying its transform on an image whose pixels spell their own coordinates.
fn peer_row(
    o: &Options,
    name: &str,
    sample: &Picture,
    side: usize,
    dir: &Path,
    tileable: bool,
) -> Result<Row> {
    let input = dir.join("sample.png");
    save(sample, &input)?;
    let (out, transform) = (dir.join("embark.png"), dir.join("embark.xform"));
    let size = side.to_string();
    let (ok, cost) = timed(
        Command::new(&o.peer)
            .args(["--no-progress", "--out"])
            .arg(&out)
            .args(["--out-size", &size, "generate", "--save-transform"])
            .arg(&transform)
            .arg(&input),
    )?;
    ok.then_some(()).ok_or(format!("texture-synthesis on {name} failed"))?;
    let coords_in = dir.join("coordinates.png");
    image::RgbImage::from_fn(sample.width as u32, sample.height as u32, |x, y| {
        image::Rgb([x as u8, y as u8, 0])
    })
    .save(&coords_in)
    .map_err(|e| e.to_string())?;
    let coords_out = dir.join("embark-coordinates.png");
    let (ok, _) = timed(
        Command::new(&o.peer)
            .args(["--no-progress", "--out"])
            .arg(&coords_out)
            .args(["repeat", "--transform"])
            .arg(&transform)
            .arg(&coords_in),
    )?;
    let result = load(&out)?;
    let coords = if ok {
        let map = image::open(&coords_out).map_err(|e| e.to_string())?.to_rgb8();
        let uv: Vec<[i32; 2]> = map.pixels().map(|p| [p[0] as i32, p[1] as i32]).collect();
        let level = &grid_levels(map.width() as usize, map.height() as usize, 1, 7, 3)[0];
        let state = State::new(vec![0; uv.len()], uv);
        Some(coord_quality(level, &state, (sample.width, sample.height), tileable))
    } else {
        None
    };
    Ok(Row {
        sample: name.into(),
        size: (sample.width, sample.height),
        tool: "Embark texture-synthesis".into(),
        cost,
        picture: picture_quality(&result, sample, tileable),
        coords,
    })
}

/// Runs `command`, returning whether it succeeded and its wall time, CPU time (user +
/// system) and peak resident memory.
/// The first argument that makes this program the measuring middleman (see [`timed`]).
const MEASURE: &str = "--measure-child";

/// Runs `command` through a fresh copy of this program, which runs it, waits for it and
/// writes its CPU seconds and peak RSS to a file: a direct child of this (large) process
/// would report this process's size as its peak.
fn timed(command: &mut Command) -> Result<(bool, Cost)> {
    let report = tempfile::NamedTempFile::new().map_err(|e| e.to_string())?;
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let started = std::time::Instant::now();
    let status = Command::new(exe)
        .arg(MEASURE)
        .arg(report.path())
        .arg(command.get_program())
        .args(command.get_args())
        .stdout(std::process::Stdio::null())
        .status()
        .map_err(|e| format!("{command:?}: {e}"))?;
    let text = std::fs::read_to_string(report.path()).map_err(|e| e.to_string())?;
    let mut figures = text.split_whitespace().map(|f| f.parse::<f64>().unwrap_or(f64::NAN));
    let (cpu, peak_kb) = (figures.next().unwrap_or(f64::NAN), figures.next().unwrap_or(f64::NAN));
    let cost = Cost { wall: started.elapsed().as_secs_f64(), cpu, peak_mb: peak_kb / 1024.0 };
    Ok((status.success(), cost))
}

/// `MEASURE REPORT PROGRAM ARGS…`: runs the program, writes "cpu_seconds peak_kb" to REPORT
/// and exits with its status.
fn measure_child(args: &[String]) -> i32 {
    let [report, program, rest @ ..] = args else {
        return 2;
    };
    let Ok(child) = Command::new(program).args(rest).spawn() else {
        eprintln!("error: cannot run {program}");
        return 127;
    };
    let mut status = 0;
    // SAFETY: an all-zero rusage is valid; wait4 writes it and `status` for our own child.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let pid = unsafe { libc::wait4(child.id() as libc::pid_t, &mut status, 0, &mut usage) };
    if pid < 0 {
        return 1;
    }
    let seconds = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    let cpu = seconds(usage.ru_utime) + seconds(usage.ru_stime);
    if std::fs::write(report, format!("{cpu} {}", usage.ru_maxrss)).is_err() {
        return 1;
    }
    if libc::WIFEXITED(status) {
        libc::WEXITSTATUS(status)
    } else {
        1
    }
}

fn load(path: &Path) -> Result<Picture> {
    Picture::read(path).map_err(|e| e.to_string())
}

fn save(picture: &Picture, path: &Path) -> Result<()> {
    let to8 = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    image::RgbImage::from_fn(picture.width as u32, picture.height as u32, |x, y| {
        image::Rgb(picture.rgb[y as usize * picture.width + x as usize].map(to8))
    })
    .save(path)
    .map_err(|e| e.to_string())
}

/// sample (1:1) | each of `results`, 8 white pixels apart.
fn montage(sample: &Picture, results: &[PathBuf], out: &Path) -> Result<()> {
    let tmp = out.with_extension("sample.png");
    save(sample, &tmp)?;
    let pictures: Vec<image::RgbImage> = std::iter::once(&tmp)
        .chain(results)
        .map(|p| image::open(p).map(|i| i.to_rgb8()).map_err(|e| format!("{}: {e}", p.display())))
        .collect::<Result<_>>()?;
    let _ = std::fs::remove_file(&tmp);
    let width = pictures.iter().map(|p| p.width() + 8).sum::<u32>() - 8;
    let height = pictures.iter().map(|p| p.height()).max().unwrap_or(0);
    let mut sheet = image::RgbImage::from_pixel(width, height, image::Rgb([255, 255, 255]));
    let mut x = 0;
    for p in &pictures {
        image::imageops::replace(&mut sheet, p, x, 0);
        x += i64::from(p.width()) + 8;
    }
    sheet.save(out).map_err(|e| e.to_string())
}

fn table(rows: &[Row]) -> String {
    let mut t = String::from(
        "| sample | size | tool | wall s | CPU s | peak MB | patch energy | coarse | colour χ² | contrast | repetition | unused | use spread | collapse | smear | copy |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let (p, c) = (&r.picture, r.coords);
        let coord =
            |f: fn(&CoordQuality) -> f64| c.as_ref().map_or("–".to_string(), |c| format!("{:.4}", f(c)));
        let _ = writeln!(
            t,
            "| {} | {}×{} | {} | {:.1} | {:.1} | {:.0} | {:.5} | {:.5} | {:.4} | {:.3} | {:.3} | {:.3} | {:.2} | {} | {} | {} |",
            r.sample,
            r.size.0,
            r.size.1,
            r.tool,
            r.cost.wall,
            r.cost.cpu,
            r.cost.peak_mb,
            p.patch_energy,
            p.patch_energy_coarse,
            p.colour_chi2,
            p.contrast,
            p.repetition.repetition,
            p.repetition.unused,
            p.repetition.use_spread,
            coord(|c| c.collapse),
            coord(|c| c.smear),
            coord(|c| c.copy)
        );
    }
    t
}

/// Per band of sample sizes (the smaller side: ≤ 64, 65–128, > 128 texels): the mean
/// repetition of btfsynth (every seed) and of each peer over the band's samples, the
/// ratio to each peer, and on how many samples btfsynth's worst seed is at or below
/// Resynthesizer's.
fn size_bands(rows: &[Row]) -> String {
    let mut t = String::from(
        "| sample side | samples | btfsynth | Embark | Resynthesizer | ÷ Embark | ÷ Resynthesizer | worst seed ≤ Resynthesizer |\n|---|---|---|---|---|---|---|---|\n",
    );
    let band_of = |r: &Row| match r.size.0.min(r.size.1) {
        0..=64 => 0,
        65..=128 => 1,
        _ => 2,
    };
    for (band, label) in ["≤ 64", "65–128", "> 128"].iter().enumerate() {
        let in_band: Vec<&Row> = rows.iter().filter(|r| band_of(r) == band).collect();
        let mut samples: Vec<&str> = in_band.iter().map(|r| r.sample.as_str()).collect();
        samples.dedup();
        let repetition = |r: &&Row| r.picture.repetition.repetition;
        let mean = |tool: &dyn Fn(&str) -> bool| {
            let v: Vec<f64> = in_band.iter().filter(|r| tool(&r.tool)).map(repetition).collect();
            v.iter().sum::<f64>() / v.len().max(1) as f64
        };
        let (ours, embark, resynth) = (
            mean(&|t| t.starts_with("btfsynth")),
            mean(&|t| t.starts_with("Embark")),
            mean(&|t| t == "Resynthesizer"),
        );
        let at_or_below = samples
            .iter()
            .filter(|&&name| {
                let of = |tool: fn(&str) -> bool| -> Vec<f64> {
                    in_band.iter().filter(|r| r.sample == name && tool(&r.tool)).map(repetition).collect()
                };
                let worst = of(|t| t.starts_with("btfsynth")).into_iter().fold(f64::NAN, f64::max);
                of(|t| t == "Resynthesizer").first().is_some_and(|&peer| worst <= peer)
            })
            .count();
        let _ = writeln!(
            t,
            "| {label} | {} | {ours:.4} | {embark:.4} | {resynth:.4} | {:.2} | {:.2} | {at_or_below} of {} |",
            samples.len(),
            ours / embark,
            ours / resynth,
            samples.len()
        );
    }
    t
}
