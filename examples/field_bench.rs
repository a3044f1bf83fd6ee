//! Time and smoothness of a direction field (`mesh::field::frames`) on one mesh: the
//! wall-clock time of the best of three runs, and the mean angle between neighbouring
//! vertices' `s` (lower is smoother), for the orientation given as on the command line
//! (`smooth`, `axis:x,y,z` or a constraints file).
//!
//! `cargo run --release --example field_bench -- MESH ORIENTATION [FIELD.txt]` where MESH
//! is e.g. `btfsynth remesh data/bunny-1k8.obj --vertices 250000 -o bunny-250k.ply`. With
//! FIELD.txt, each vertex's position, normal and `s` are written there, one vertex a line
//! (`x y z nx ny nz sx sy sz`), for plotting.

use btfsynth::mesh::field::{frames, Orientation};
use btfsynth::mesh::topology::one_rings;
use std::time::Instant;

fn main() -> btfsynth::Result<()> {
    let mut args = std::env::args().skip(1);
    let (Some(mesh_path), Some(orientation), dump) = (args.next(), args.next(), args.next()) else {
        eprintln!("usage: field_bench MESH ORIENTATION [FIELD.txt]");
        std::process::exit(2);
    };
    let mesh = btfsynth::mesh::load(mesh_path.as_ref())?;
    let orientation = Orientation::parse(&orientation)?;
    let mut best = f64::INFINITY;
    let mut field = None;
    for _ in 0..3 {
        let start = Instant::now();
        field = Some(frames(&mesh, &orientation, 0)?);
        best = best.min(start.elapsed().as_secs_f64());
    }
    let Some(field) = field else { return Ok(()) };
    if let Some(dump) = dump {
        let lines: String = (0..field.len())
            .map(|v| {
                let [p, n, s] = [mesh.positions()[v], field.n[v], field.s[v]];
                format!("{} {} {} {} {} {} {} {} {}\n", p.x, p.y, p.z, n.x, n.y, n.z, s.x, s.y, s.z)
            })
            .collect();
        std::fs::write(&dump, lines).map_err(|e| btfsynth::Error::io(&dump, e))?;
    }
    let s = field.s;
    let rings = one_rings(&mesh);
    let (mut sum, mut count) = (0.0f64, 0usize);
    for v in 0..mesh.vertex_count() {
        for &w in rings.ring(v) {
            sum += f64::from(s[v].dot(s[w as usize]).clamp(-1.0, 1.0).acos().to_degrees());
            count += 1;
        }
    }
    println!(
        "{} vertices: frames in {best:.3} s (best of 3), mean neighbour angle {:.2}°",
        mesh.vertex_count(),
        sum / count.max(1) as f64
    );
    Ok(())
}
