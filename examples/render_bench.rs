//! Timings behind the rendering benchmarks: per-vertex blends, per-vertex relighting
//! (Tong §6's interactive mode: new colours for a new light, the camera fixed), and CPU
//! frames. Loading and BVH building are not timed.
//!
//! `cargo run --release --example render_bench -- SURFACE.ply [SIZE [ANALYSIS]]`
//!
//! Each line gives the wall time per call and, on Linux, the CPU time of all threads per
//! call: on a machine shared with other work, CPU time ÷ cores is what the wall time would
//! be with the cores to itself.

use btfsynth::render::ambient::AmbientCache;
use btfsynth::render::cpu::{render, vertex_lit, RenderOptions, Tracer};
use btfsynth::render::scene::{open_surface, Relighter, Shadows};
use btfsynth::render::shadow_map::{shadow_map_size, ShadowCaster};
use btfsynth::render::{Environment, Material, Mode, Orbit, ShotPlan};
use glam::Vec3;
use std::time::Instant;

fn main() -> btfsynth::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let surface = args.get(1).map(std::path::PathBuf::from).expect("usage: render_bench SURFACE.ply [SIZE]");
    let size: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1024);
    let other = args.get(3).map(std::path::PathBuf::from);
    // A benchmark may time any analysis of the sample, so the fingerprint is not checked.
    let (scene, analysis) = open_surface(&surface, other.as_deref(), false)?;
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
        let (started, cpu) = (Instant::now(), cpu_seconds());
        (0..n).for_each(&mut *f);
        let per = started.elapsed().as_secs_f64() / n as f64;
        let cpu = cpu.zip(cpu_seconds()).map(|(a, b)| (b - a) / n as f64);
        let cpu = cpu.map_or(String::new(), |c| format!(", CPU {:.1} ms", c * 1e3));
        println!("{name:<48} {:8.1} ms  ({:.1} per second{cpu})", per * 1e3, 1.0 / per);
    };
    time("per-vertex blends", frames, &mut |i| {
        std::hint::black_box(scene.vertex_blends(&material, &shots[i]));
    });
    let relighter = Relighter::new(&scene, &material, &shots[0].camera, None);
    time("per-vertex relight (views kept, no shadows)", frames, &mut |i| {
        std::hint::black_box(relighter.colours(&material, shots[i].light, Shadows::None));
    });
    let started = Instant::now();
    let culled = Relighter::new(&scene, &material, &shots[0].camera, Some(&tracer));
    println!(
        "{:<48} {:8.1} ms  ({} of {} vertices can show)",
        "  setup per camera: which vertices can show",
        started.elapsed().as_secs_f64() * 1e3,
        culled.relit(),
        scene.mesh.vertex_count()
    );
    time("per-vertex relight, those vertices, shadow rays", frames, &mut |i| {
        std::hint::black_box(culled.colours(&material, shots[i].light, Shadows::Rays(&tracer)));
    });
    let map_size = shadow_map_size(scene.mesh.vertex_count());
    let started = Instant::now();
    let caster = ShadowCaster::new(&scene.mesh);
    println!("{:<48} {:8.1} ms", "  setup per model: shadow casters", started.elapsed().as_secs_f64() * 1e3);
    time(&format!("  shadow map alone ({map_size}²)"), frames, &mut |i| {
        std::hint::black_box(caster.map(shots[i].light, map_size));
    });
    time("per-vertex relight, those vertices, shadow map", frames, &mut |i| {
        let map = caster.map(shots[i].light, map_size);
        std::hint::black_box(culled.colours(&material, shots[i].light, Shadows::Map(&map)));
    });
    let disagree: usize = (0..frames)
        .map(|i| {
            let map = caster.map(shots[i].light, map_size);
            let by_map = culled.colours(&material, shots[i].light, Shadows::Map(&map));
            let by_rays = culled.colours(&material, shots[i].light, Shadows::Rays(&tracer));
            by_map.iter().zip(&by_rays).filter(|(a, b)| (**a == Vec3::ZERO) != (**b == Vec3::ZERO)).count()
        })
        .sum();
    println!(
        "{:<48} {:8.2} %  of the relit vertices (map vs rays, over the orbit)",
        "  shadow map disagreement",
        100.0 * disagree as f64 / (frames * culled.relit()) as f64
    );
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
        time(&format!("{name} ({size}², 1 spp)"), 3, &mut |i| {
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
    time(&format!("frame, pixel mode, shadows ({size}², 4 spp)"), 3, &mut |i| {
        std::hint::black_box(render(&scene, &material, &tracer, &shots[i], RenderOptions::default(), None));
    });
    let mut sky = AmbientCache::new(&scene, &material, Environment::sky(), true);
    time("sky: first camera (cell shadow rays, patches)", 1, &mut |_| {
        std::hint::black_box(sky.for_camera((&scene, &material), &shots[0].camera, Some(&tracer)));
    });
    time("sky: next camera (patches only)", 1, &mut |_| {
        let mut camera = shots[0].camera;
        camera.eye.x += 1e-3 * (camera.eye - camera.target).length();
        std::hint::black_box(sky.for_camera((&scene, &material), &camera, Some(&tracer)));
    });
    let ambient = sky.for_camera((&scene, &material), &shots[0].camera, Some(&tracer)).0;
    time(&format!("frame, sun and sky, shadows ({size}², 4 spp)"), 3, &mut |i| {
        let options = RenderOptions::default();
        std::hint::black_box(render(&scene, &material, &tracer, &shots[i], options, Some(ambient)));
    });
    Ok(())
}

/// User + system CPU seconds of this process so far (Linux: /proc/self/stat, 10 ms ticks),
/// to tell work from waiting on a machine other processes share.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (in parentheses): utime and stime are the 12th and 13th.
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}
