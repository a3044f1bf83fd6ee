//! Timings behind the rendering benchmarks: per-vertex blends, per-vertex relighting
//! (Tong §6's interactive mode: new colours for a new light, the camera fixed), and CPU
//! frames. Loading and BVH building are not timed.
//!
//! `cargo run --release --example render_bench -- SURFACE.ply [SIZE [ANALYSIS]]`

use btfsynth::render::cpu::{render, vertex_lit, RenderOptions, Tracer};
use btfsynth::render::scene::{open_surface, Relighter};
use btfsynth::render::{Material, Mode, Orbit, ShotPlan};
use std::time::Instant;

fn main() -> btfsynth::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let surface = args.get(1).map(std::path::PathBuf::from).expect("usage: render_bench SURFACE.ply [SIZE]");
    let size: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1024);
    let other = args.get(3).map(std::path::PathBuf::from);
    let (scene, analysis) = open_surface(&surface, other.as_deref())?;
    let material = Material::open(&analysis)?;
    let tracer = Tracer::new(&scene.mesh);
    let frames = 30;
    let plan = ShotPlan { size: (size, size), frames, orbit: Orbit::Light, ..ShotPlan::default() };
    let shots = plan.shots(scene.mesh.bounds());
    println!(
        "{} vertices, {} images of {}x{}",
        scene.mesh.vertex_count(),
        material.len(),
        material.width(),
        material.height()
    );

    let time = |name: &str, n: usize, f: &mut dyn FnMut(usize)| {
        let started = Instant::now();
        (0..n).for_each(&mut *f);
        let per = started.elapsed().as_secs_f64() / n as f64;
        println!("{name:<44} {:8.1} ms  ({:.1} per second)", per * 1e3, 1.0 / per);
    };
    time("per-vertex blends", frames, &mut |i| {
        std::hint::black_box(scene.vertex_blends(&material, &shots[i]));
    });
    let relighter = Relighter::new(&scene, &material, &shots[0].camera);
    time("per-vertex relight (views kept, no shadows)", frames, &mut |i| {
        std::hint::black_box(relighter.colours(&material, shots[i].light));
    });
    time("per-vertex relight with shadow rays", frames, &mut |i| {
        let blends = scene.vertex_blends(&material, &shots[i]);
        let lit = vertex_lit(&scene, &tracer, shots[i].light);
        std::hint::black_box(scene.vertex_colours(&material, &blends, Some(&lit)));
    });
    for (name, mode, shadows) in [
        ("frame, pixel mode, shadows", Mode::Pixel, true),
        ("frame, pixel mode, no shadows", Mode::Pixel, false),
        ("frame, vertex mode, shadows", Mode::Vertex, true),
    ] {
        time(&format!("{name} ({size}²)"), 3, &mut |i| {
            std::hint::black_box(render(
                &scene,
                &material,
                &tracer,
                &shots[i],
                RenderOptions { mode, shadows, spp: 1, sun: 1.0 },
                None,
            ));
        });
    }
    Ok(())
}
