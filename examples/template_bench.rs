//! Time of one mesh level's square templates (`synth::surface::surface_level`): the
//! flattened patch around every vertex and its resampled template, best of three runs.
//!
//! `cargo run --release --example template_bench -- MESH TEXEL [TEMPLATE]` where MESH is a
//! level as `synth` builds it, e.g. the PLY that `btfsynth synth ANALYSIS
//! data/bunny-1k8.obj --vertices 250000 -o OUT.ply` writes (its `texel` comment gives
//! TEXEL), and TEMPLATE the side (default 7). Prints a checksum of the slots and shifts,
//! so that a change meant to keep the templates can be checked to keep them.

use btfsynth::mesh::field::{frames, Orientation};
use btfsynth::synth::surface::surface_level;
use btfsynth::synth::target::Neighbourhoods;
use std::time::Instant;

fn main() -> btfsynth::Result<()> {
    let mut args = std::env::args().skip(1);
    let (Some(mesh_path), Some(texel)) = (args.next(), args.next()) else {
        eprintln!("usage: template_bench MESH TEXEL [TEMPLATE]");
        std::process::exit(2);
    };
    let parse_error = |what: &str| btfsynth::Error::invalid(format!("{what} is not a number"));
    let texel: f32 = texel.parse().map_err(|_| parse_error("TEXEL"))?;
    let template: usize = args.next().map_or(Ok(7), |t| t.parse().map_err(|_| parse_error("TEMPLATE")))?;
    let mesh = btfsynth::mesh::load(mesh_path.as_ref())?;
    let field = frames(&mesh, &Orientation::Smooth, 0)?;
    let mut best = f64::INFINITY;
    let mut level = None;
    for _ in 0..3 {
        let start = Instant::now();
        level = Some(surface_level(&mesh, &field, texel, template)?);
        best = best.min(start.elapsed().as_secs_f64());
    }
    let Some(level) = level else { return Ok(()) };
    let Neighbourhoods::Mesh { slots, shifts, .. } = &level.neighbourhoods else { return Ok(()) };
    // FNV-1a over the slots' and shifts' bits.
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |bits: u32| hash = (hash ^ u64::from(bits)).wrapping_mul(0x0100_0000_01b3);
    for slot in slots {
        slot.vertices.iter().for_each(|&v| eat(v));
        slot.weights.iter().for_each(|w| eat(w.to_bits()));
    }
    for (u, offset) in shifts {
        eat(*u);
        offset.iter().for_each(|o| eat(o.to_bits()));
    }
    println!(
        "{} vertices, {template}² templates: {best:.3} s (best of 3), {} shifts, checksum {hash:016x}",
        mesh.vertex_count(),
        shifts.len()
    );
    Ok(())
}
