//! Chen and Dong's claim (2008 §4): the marching of the round neighbourhoods is computed
//! once per vertex, so a new texture direction is cheap. This times, on one mesh:
//!
//! * **marching**: `SurfaceMarching::new` (flattening every vertex's patch and cutting its
//!   circles into arcs), done once;
//! * **per direction**: for each of two directions, the start points and every vertex's
//!   round neighbourhood read from the marching;
//! * **square templates**: `surface_level` for each direction (what a direction change
//!   costs where the templates are resampled from scratch, as the square-template presets do).
//!
//! `cargo run --release --example round_marching -- MESH [CIRCLES]` (texel: the mean edge).

use btfsynth::mesh::frames::Frames;
use btfsynth::synth::round::{RoundStencil, SurfaceMarching};
use btfsynth::synth::surface::surface_level;
use glam::Vec3;
use std::time::Instant;

fn main() -> btfsynth::Result<()> {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("usage: round_marching MESH [CIRCLES]");
    let circles: usize = args.next().map_or(3, |c| c.parse().expect("CIRCLES is a count"));
    let mesh = btfsynth::mesh::load(path.as_ref())?.with_normals();
    let normals = mesh.normals().expect("computed").to_vec();
    let p = mesh.positions();
    let edges = btfsynth::mesh::topology::edges(&mesh);
    let texel =
        edges.iter().map(|[a, b]| p[*a as usize].distance(p[*b as usize])).sum::<f32>() / edges.len() as f32;
    println!("{path}: {} vertices, texel {texel:.5}, {circles} circles", mesh.vertex_count());
    let stencil = RoundStencil { circles };
    let started = Instant::now();
    let marching = SurfaceMarching::new(&mesh, &normals, texel, stencil)?;
    println!("marching (once):               {:8.3} s", started.elapsed().as_secs_f64());
    let mut slots = Vec::new();
    for (name, direction) in [("x", Vec3::X), ("y", Vec3::Y)] {
        let frames = Frames::from_directions(&normals, &vec![direction; normals.len()]);
        let started = Instant::now();
        let starts = marching.start_points(&frames);
        let mut weight = 0.0f64;
        for (v, &start) in starts.iter().enumerate() {
            marching.slots(v, start, &mut slots);
            weight += slots.iter().map(|s| s.weights[0] as f64).sum::<f64>();
        }
        let round = started.elapsed().as_secs_f64();
        let started = Instant::now();
        let level = surface_level(&mesh, &frames, texel, 2 * circles + 1)?;
        let square = started.elapsed().as_secs_f64();
        println!(
            "direction {name}: round from the marching {round:8.3} s, square templates {square:8.3} s ({} vertices, checksum {weight:.1})",
            level.vertices
        );
    }
    Ok(())
}
