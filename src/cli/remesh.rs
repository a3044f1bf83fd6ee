//! `btfsynth remesh`: isotropic remeshing of a triangle mesh.

use super::progress::Bars;
use crate::fsutil::check_target;
use crate::mesh::remesh::{edge_length_stats, remesh, RemeshParams};
use crate::mesh::{self, ply, topology};
use anyhow::Result;
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
    /// Target vertex count, at least 4 (met within a few percent). Give this or --edge.
    #[arg(long, value_name = "N", value_parser = super::at_least(4))]
    vertices: Option<usize>,
    /// Target edge length in model units. Give this or --vertices.
    #[arg(long, value_name = "LENGTH", value_parser = super::positive_number)]
    edge: Option<f32>,
    /// Split / collapse / flip / relax rounds.
    #[arg(long, default_value_t = 10)]
    iterations: usize,
    /// Replace the output if it exists.
    #[arg(long)]
    force: bool,
}

pub fn run(args: RemeshArgs, bars: &Bars) -> Result<()> {
    check_target(&args.output, args.force)?;
    let input = mesh::load(&args.mesh)?;
    let params = match (args.vertices, args.edge) {
        (Some(n), None) => RemeshParams::vertex_count(&input, n),
        (None, Some(l)) => RemeshParams::edge_length(l),
        _ => return Err(super::usage("give one target: --vertices N or --edge LENGTH")),
    };
    let params = RemeshParams { iterations: args.iterations, ..params };
    eprintln!("input   {}", topology::summary(&input));
    let started = Instant::now();
    let output = remesh(&input, &params, bars)?;
    let comment = format!("remeshed by btfsynth {} from {}", env!("CARGO_PKG_VERSION"), args.mesh.display());
    ply::write(&args.output, &output, &[], &[&comment])?;
    eprintln!("output  {}", topology::summary(&output));
    eprintln!("edges   {}", edge_length_stats(&output));
    eprintln!("wrote {} in {:.2} s", args.output.display(), started.elapsed().as_secs_f64());
    Ok(())
}
