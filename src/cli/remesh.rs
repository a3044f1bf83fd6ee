//! `btfsynth remesh`: isotropic remeshing of a triangle mesh.

use super::progress::Bars;
use anyhow::Result;
use btfsynth::fsutil::{check_not_input, Staged};
use btfsynth::mesh::remesh::{edge_length_stats, remesh, RemeshParams};
use btfsynth::mesh::{self, ply, topology};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
#[command(
    group(clap::ArgGroup::new("target").args(["vertices", "edge"]).required(true)),
    after_help = "Example: btfsynth remesh bunny.obj --vertices 50000 -o bunny-50k.ply"
)]
pub struct RemeshArgs {
    /// The mesh: OBJ, OFF or PLY (ASCII or binary); polygons are triangulated, coincident
    /// vertices welded, degenerate faces dropped.
    mesh: PathBuf,
    /// Output: a binary PLY.
    #[arg(short, long, value_name = "OUT.ply")]
    output: PathBuf,
    /// Target vertex count, 4 to 50,000,000 (met within a few percent). Give this or --edge.
    #[arg(long, value_name = "N", value_parser = super::in_range(4, MAX_VERTICES))]
    vertices: Option<usize>,
    /// Target edge length in model units; it may not make more than 50,000,000 vertices.
    /// Give this or --vertices.
    #[arg(long, value_name = "LENGTH", value_parser = super::positive_number)]
    edge: Option<f32>,
    /// Split / collapse / flip / relax rounds, 1 to 1000. A target with at least four
    /// times the input's vertices is remeshed at twice the edge first, then refined (each
    /// face split in four, three more rounds): much faster, and as even.
    #[arg(long, default_value_t = 10, value_parser = super::in_range(1, 1000))]
    iterations: usize,
    /// Replace the output if it exists.
    #[arg(long)]
    force: bool,
}

/// The most vertices a remesh may make (the remesher's own limit).
const MAX_VERTICES: usize = 50_000_000;

pub fn run(args: RemeshArgs, bars: &Bars) -> Result<()> {
    check_not_input("-o", &args.output, &[&args.mesh])?;
    let staged = Staged::file(&args.output, args.force)?;
    let input = mesh::load(&args.mesh)?;
    let params = match (args.vertices, args.edge) {
        (Some(n), None) => RemeshParams::vertex_count(&input, n),
        (None, Some(l)) => {
            let estimate = 2.0 * input.surface_area() / (3f64.sqrt() * f64::from(l).powi(2));
            if estimate > MAX_VERTICES as f64 {
                return Err(super::usage(format!(
                    "--edge {l}: on {} (area {:.4e}) that makes about {estimate:.3e} vertices, more than \
                     {MAX_VERTICES}; choose a longer edge",
                    args.mesh.display(),
                    input.surface_area()
                )));
            }
            RemeshParams::edge_length(l)
        }
        _ => return Err(super::usage("give one target: --vertices N or --edge LENGTH")),
    };
    let params = RemeshParams { iterations: args.iterations, ..params };
    eprintln!("input   {}", topology::summary(&input));
    let started = Instant::now();
    let output = remesh(&input, &params, bars).map_err(|e| match e {
        btfsynth::Error::InvalidArgument(m) => anyhow::Error::from(btfsynth::Error::format(&args.mesh, m)),
        other => other.into(),
    })?;
    let comment = format!("remeshed by btfsynth {} from {}", env!("CARGO_PKG_VERSION"), args.mesh.display());
    ply::write(staged.path(), &output, &[], &[&comment])?;
    let written = staged.commit()?;
    eprintln!("output  {}", topology::summary(&output));
    eprintln!("edges   {}", edge_length_stats(&output));
    eprintln!("wrote {} in {:.2} s", written.display(), started.elapsed().as_secs_f64());
    Ok(())
}
