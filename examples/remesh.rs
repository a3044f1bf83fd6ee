//! Remeshes a mesh file to a vertex count and prints the time taken and the edge-length
//! statistics; optionally writes the result as PLY.
//!
//! ```text
//! RUST_LOG=btfsynth=debug \
//! cargo run --release --example remesh -- ../shared/data/meshes/bunny-1k8.obj 50000 [out.ply]
//! ```

use btfsynth::mesh::{self, ply, remesh, topology};
use std::path::Path;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
    let args: Vec<String> = std::env::args().collect();
    let (Some(input), Some(count)) = (args.get(1), args.get(2)) else {
        anyhow::bail!("usage: remesh INPUT VERTEX_COUNT [OUTPUT.ply]");
    };
    let count: usize = count.parse()?;
    let start = Instant::now();
    let mesh = mesh::load(Path::new(input))?;
    println!("loaded {input} in {:.2?}: {}", start.elapsed(), topology::summary(&mesh));
    let start = Instant::now();
    let fine = remesh::remesh_to_vertex_count(&mesh, count)?;
    let elapsed = start.elapsed();
    println!(
        "remeshed in {elapsed:.2?} on {} threads: {}",
        rayon::current_num_threads(),
        topology::summary(&fine)
    );
    println!("edge lengths: {}", remesh::edge_length_stats(&fine));
    if let Some(output) = args.get(3) {
        ply::write(Path::new(output), &fine, &[], &["remeshed by btfsynth"])?;
    }
    Ok(())
}
