//! Hierarchical pattern mapping (`synth --method soler2002`) measured on a photograph and a
//! mesh: wall time, clusters mapped per level, the flattening of every level's clusters,
//! and the patch energy of windows across patch borders against windows inside patches,
//! beside the same patches placed at random.
//!
//!   cargo run --release --example soler_bench -- PHOTO MESH [--crop N] [--across K]
//!       [--threshold T] [--distortion D] [--band B] [--rotations R] [--colour lab|hsv|rgb] [--no-relax]
//!       [--keep-borders]
//!       [--seed S] [--seams N] [--close-ups SHEET.png] [--no-baseline]
//!
//! The sample is the photograph's top-left N×N crop (default 128), mapped at K sample
//! widths across the mesh's largest side (default 4). `--seams N` lists the N seams (borders
//! between two patches) of largest jump, at least a texel long (default 10); `--close-ups`
//! writes a sheet of the matched mapping's listed seams, 41 texels around each, twice: with
//! the borders drawn red, then the texture alone (left to right, top to bottom in the list's
//! order, 4 pixels per texel).

use btfsynth::btf::image_io::srgb_to_linear;
use btfsynth::eval::Picture;
use btfsynth::synth::patches::chart::Flattening;
use btfsynth::synth::patches::fit::{ColourSpace, FitImage};
use btfsynth::synth::patches::graph::SurfaceGraph;
use btfsynth::synth::patches::hierarchy::Hierarchy;
use btfsynth::synth::patches::quality::{
    border_discontinuity, close_up, seam_windows, seams, split, MappedSurface, Seam, SeamWindow,
};
use btfsynth::synth::patches::{map_mesh, PatchMapping, SolerParams};
use rand::SeedableRng;
use std::path::Path;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |name: &str| args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).cloned();
    let has = |name: &str| args.iter().any(|a| a == name);
    let (Some(photo), Some(mesh_path)) = (args.first(), args.get(1)) else {
        eprintln!("usage: soler_bench PHOTO MESH [--crop N] [--across K] [--threshold T] ...");
        std::process::exit(2);
    };
    let crop: usize = flag("--crop").map_or(128, |v| v.parse().expect("--crop N"));
    let across: f32 = flag("--across").map_or(4.0, |v| v.parse().expect("--across K"));
    let image = image::open(photo).expect("photo").to_rgb32f();
    let side = crop.min(image.width() as usize).min(image.height() as usize);
    let at = |x: usize, y: usize| image.get_pixel(x as u32, y as u32).0;
    let sample = Picture {
        width: side,
        height: side,
        rgb: (0..side * side).map(|i| at(i % side, i / side)).collect(),
    };
    let colour = match flag("--colour").as_deref() {
        Some("hsv") => ColourSpace::Hsv,
        Some("rgb") => ColourSpace::Rgb,
        _ => ColourSpace::Lab,
    };
    let fit = FitImage::from_rgb(side, side, |x, y| at(x, y).map(srgb_to_linear), colour, false)
        .expect("fit image");
    let path = Path::new(mesh_path);
    let mesh = btfsynth::mesh::textured::load_textured(path).expect("mesh");
    let (lo, hi) =
        mesh.positions.iter().fold(
            (glam::Vec3::splat(f32::INFINITY), glam::Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
    let scale = across * side as f32 / (hi - lo).max_element();
    let sheet = flag("--close-ups");
    let worst: usize = flag("--seams").map_or(10, |v| v.parse().expect("--seams N"));
    let defaults = SolerParams::default();
    let params = SolerParams {
        texels_per_unit: scale,
        max_fit_error: flag("--threshold")
            .map_or(defaults.max_fit_error, |v| v.parse().expect("--threshold")),
        max_flat_error: flag("--distortion")
            .map_or(defaults.max_flat_error, |v| v.parse().expect("--distortion")),
        band: flag("--band").map_or(defaults.band, |v| v.parse().expect("--band")),
        rotations: flag("--rotations").map_or(defaults.rotations, |v| v.parse().expect("--rotations")),
        relax: !has("--no-relax"),
        move_borders: !has("--keep-borders"),
        seed: flag("--seed").map_or(0, |v| v.parse().expect("--seed")),
        colour,
        ..defaults
    };
    println!("{} faces, {side}² sample, {scale:.1} texels per unit", mesh.triangles.len());

    // The flattening of every level's clusters.
    let graph = SurfaceGraph::new(&mesh.positions, &mesh.triangles, path).expect("graph");
    let h = Hierarchy::build(&graph, &mut rand_chacha::ChaCha8Rng::seed_from_u64(params.seed));
    let flattening = Flattening::new(&graph, &h);
    for (l, level) in h.levels.iter().enumerate() {
        let mut errors = Vec::new();
        let (mut folds, mut none) = (0, 0);
        for &c in level {
            match flattening.chart(&graph, &h, c) {
                Some(chart) => {
                    errors.push(chart.flat_error);
                    folds += usize::from(chart.folds > 0);
                }
                None => none += 1,
            }
        }
        errors.sort_by(f32::total_cmp);
        let q = |f: f32| errors.get(((errors.len() as f32 - 1.0) * f) as usize).copied().unwrap_or(f32::NAN);
        let faces = level.iter().map(|&c| h.clusters[c as usize].faces.len()).sum::<usize>() as f32
            / level.len() as f32;
        println!(
            "  level {l}: {} clusters ({faces:.1} faces each); flattening error median {:.3}, 90% {:.3}; {folds} fold, {none} without a chart",
            level.len(),
            q(0.5),
            q(0.9)
        );
    }

    let run = |matching: bool| {
        let params = SolerParams { matching, ..params.clone() };
        let started = Instant::now();
        let m = map_mesh(
            &mesh.positions,
            &mesh.triangles,
            path,
            fit.clone(),
            &params,
            &btfsynth::progress::Silent,
        )
        .expect("mapped");
        let seconds = started.elapsed().as_secs_f64();
        let surface = MappedSurface {
            positions: &mesh.positions,
            triangles: &mesh.triangles,
            corner_uv: &m.corner_uv,
            cluster: &m.cluster,
            sample: &sample,
            tileable: false,
            texels_per_unit: scale,
        };
        let windows = seam_windows(&surface, (3000, 1)).expect("measured");
        let q = split(&windows);
        breakdown(&windows, &m.level);
        let seams =
            seams(&mesh.positions, &mesh.triangles, &m.corner_uv, &m.cluster, &fit).expect("measured");
        by_jump(&windows, &seams);
        let listed = worst_seams(&seams, &windows, &m, scale, worst);
        if let Some(path) = sheet.as_ref().filter(|_| matching) {
            // Each seam twice: its borders drawn, then the texture alone.
            let pictures: Vec<Picture> = listed
                .iter()
                .flat_map(|&f| [true, false].map(|b| close_up(&surface, (f, 41), b).expect("close-up")))
                .flatten()
                .collect();
            write_sheet(&pictures, path);
        }
        let (jump, n) =
            border_discontinuity(&mesh.positions, &mesh.triangles, &m.corner_uv, &m.cluster, &fit)
                .expect("measured");
        println!("  border discontinuity {:.3} of a random pair's over {} points", jump, n);
        (m, q, seconds)
    };
    let (m, q, seconds) = run(true);
    println!(
        "matched: {seconds:.2} s wall (hierarchy, flattening, transforms, mapping: {:.2?})",
        m.report.seconds
    );
    for l in m.report.levels.iter().filter(|l| l.tried > 0) {
        println!(
            "  level {}: {} to cover, {} mapped ({} at random, {} continuing a neighbour, {} faces), split {} not disc, {} distorted, {} too large, {} poor fit, {} unreached; fit error median {:.3}; {:.2} s",
            l.level, l.tried, l.mapped, l.started, l.continued, l.faces, l.not_disc, l.distorted, l.too_large, l.poor_fit, l.unreached, l.median_fit_error, l.seconds
        );
    }
    println!(
        "  seams: border {:.5} ({} windows), interior {:.5} ({} windows), ratio {:.2}",
        q.border,
        q.border_windows,
        q.interior,
        q.interior_windows,
        q.border / q.interior
    );
    if !has("--no-baseline") {
        let (_, r, _) = run(false);
        println!(
            "random:  border {:.5} ({} windows), interior {:.5} ({} windows), ratio {:.2}",
            r.border,
            r.border_windows,
            r.interior,
            r.interior_windows,
            r.border / r.interior
        );
    }
}

/// Border and interior windows' energies by the stretch of the faces they show and by the
/// level of the patch at their centre: what part of the ratio is distortion, not seams.
fn breakdown(windows: &[SeamWindow], level: &[u8]) {
    let line = |name: String, of: &dyn Fn(&SeamWindow) -> bool| {
        let part: Vec<&SeamWindow> = windows.iter().filter(|w| of(w)).collect();
        let q = split(&part.iter().map(|&w| w.clone()).collect::<Vec<_>>());
        println!(
            "    {name:<22} border {:.5} ({:>4}), interior {:.5} ({:>4}), ratio {:.2}",
            q.border,
            q.border_windows,
            q.interior,
            q.interior_windows,
            q.border / q.interior
        );
    };
    let bins = [0.0, 0.02, 0.05, 0.1, 0.2, f32::INFINITY];
    for pair in bins.windows(2) {
        line(format!("stretch {:.2}..{:.2}", pair[0], pair[1]), &|w| {
            w.stretch >= pair[0] && w.stretch < pair[1]
        });
    }
    for (lo, hi) in [(0.0, 0.1), (0.1, 0.25), (0.25, 1.0)] {
        line(format!("others {lo:.2}..{hi:.2}"), &|w| {
            w.patches.len() == 1 || (w.others > lo && w.others <= hi)
        });
    }
    let mut levels: Vec<u8> = windows.iter().map(|w| level[w.face as usize]).collect();
    levels.sort_unstable();
    levels.dedup();
    for l in levels {
        line(format!("centre on level {l}"), &|w| level[w.face as usize] == l);
    }
}

/// Prints the `n` seams of largest jump at least a texel long, with the energy of the
/// windows that show both their patches; returns a face on each.
fn worst_seams(seams: &[Seam], windows: &[SeamWindow], m: &PatchMapping, scale: f32, n: usize) -> Vec<u32> {
    let mut order: Vec<&Seam> = seams.iter().filter(|s| s.length * scale >= 1.0).collect();
    order.sort_by(|a, b| b.jump.total_cmp(&a.jump));
    let level = |c: u32| m.cluster.iter().position(|&k| k == c).map_or(0, |f| m.level[f]);
    println!("  {} seams; the {} of largest jump:", seams.len(), n.min(order.len()));
    for s in order.iter().take(n) {
        let (a, b) = s.patches;
        let on: Vec<&SeamWindow> =
            windows.iter().filter(|w| w.patches.contains(&a) && w.patches.contains(&b)).collect();
        let energy = on.iter().map(|w| w.energy).sum::<f64>() / on.len().max(1) as f64;
        let stretch = on.iter().map(|w| w.stretch).fold(0f32, f32::max);
        println!(
            "    patches {a} (level {}) | {b} (level {}): {:.0} texels, {} edges, jump {:.3}; {} windows, energy {:.5}, stretch up to {:.2}; face {}",
            level(a), level(b), s.length * scale, s.faces.len(), s.jump, on.len(), energy, stretch, s.faces[0]
        );
    }
    order.iter().take(n).map(|s| s.faces[0]).collect()
}

/// The close-ups side by side, six to a row, each texel 4 pixels.
fn write_sheet(pictures: &[Picture], path: &str) {
    const ZOOM: usize = 4;
    let Some(side) = pictures.first().map(|p| p.width) else { return };
    let (columns, gap) = (6.min(pictures.len()), 4);
    let rows = pictures.len().div_ceil(columns);
    let cell = side * ZOOM + gap;
    let mut sheet = image::RgbImage::new((columns * cell) as u32, (rows * cell) as u32);
    for (i, p) in pictures.iter().enumerate() {
        let (x0, y0) = ((i % columns) * cell, (i / columns) * cell);
        for y in 0..side * ZOOM {
            for x in 0..side * ZOOM {
                let c =
                    p.rgb[(y / ZOOM) * side + x / ZOOM].map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8);
                sheet.put_pixel((x0 + x) as u32, (y0 + y) as u32, image::Rgb(c));
            }
        }
    }
    let tmp = format!("{path}.tmp.png");
    sheet.save(&tmp).expect("sheet");
    std::fs::rename(&tmp, path).expect("sheet");
    println!("  close-ups of {} seams in {path}", pictures.len());
}

/// Border windows by the largest jump of the seams between the patches they show, beside
/// the interior: how much of the ratio the seams' own mismatch explains.
fn by_jump(windows: &[SeamWindow], seams: &[Seam]) {
    let jump: std::collections::HashMap<(u32, u32), f64> =
        seams.iter().map(|s| (s.patches, s.jump)).collect();
    let worst = |w: &SeamWindow| {
        let mut most = f64::NAN;
        for (i, &a) in w.patches.iter().enumerate() {
            for &b in &w.patches[i + 1..] {
                if let Some(&j) = jump.get(&(a.min(b), a.max(b))) {
                    most = if most.is_nan() { j } else { most.max(j) };
                }
            }
        }
        most
    };
    let interior: Vec<SeamWindow> = windows.iter().filter(|w| w.patches.len() == 1).cloned().collect();
    let inside = split(&interior).interior;
    for (lo, hi) in [(0.0, 0.05), (0.05, 0.15), (0.15, 0.3), (0.3, 0.6), (0.6, f64::INFINITY)] {
        let part: Vec<SeamWindow> = windows
            .iter()
            .filter(|w| w.patches.len() > 1 && (worst(w) >= lo && worst(w) < hi))
            .cloned()
            .collect();
        let q = split(&part);
        println!(
            "    seam jump {lo:.2}..{hi:.2}     border {:.5} ({:>4}), ratio to the interior {:.2}",
            q.border,
            q.border_windows,
            q.border / inside
        );
    }
}
