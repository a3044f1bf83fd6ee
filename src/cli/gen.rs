//! `btfsynth gen`: ray-trace a synthetic stack.

use super::progress::Bars;
use super::usage;
use anyhow::Result;
use btfsynth::btf::gen::{generate, GenParams, MaterialKind};
use btfsynth::btf::{write_stack, DirectionSet, ImageFormat};
use btfsynth::fsutil::check_dir_target;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
#[command(
    override_usage = "btfsynth gen [OPTIONS] -o <DIR> <KIND>\n       btfsynth gen --list",
    after_help = "Example: btfsynth gen pebbles --size 64 --directions ubo81 -o pebbles/"
)]
pub struct GenArgs {
    /// Material to generate (see --list).
    #[arg(value_enum, required_unless_present = "list")]
    kind: Option<MaterialKind>,
    /// Output directory: btf.json plus one image per (light, view) pair.
    #[arg(short, long, value_name = "DIR", required_unless_present = "list")]
    output: Option<PathBuf>,
    /// Sample width and height in pixels, 4 to 2048.
    #[arg(long, default_value_t = 64)]
    size: usize,
    /// Dome for views and lights: ubo81 (Bonn UBO2003, 6561 images), ubo151 (UBO2014,
    /// 22801 images) or grid:N (N directions, N×N images).
    #[arg(long, default_value = "ubo81", value_parser = parse_directions)]
    directions: DirectionSet,
    /// Seed of the material's random layout.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Image format of the stack.
    #[arg(long, value_enum, default_value_t = ImageFormat::Exr)]
    format: ImageFormat,
    /// Samples per pixel (a square number: 1, 4, 9, 16, … 64).
    #[arg(long, default_value_t = 4)]
    spp: usize,
    /// Replace the output directory if it exists.
    #[arg(long)]
    force: bool,
    /// List the material kinds and exit.
    #[arg(long)]
    list: bool,
}

fn parse_directions(s: &str) -> Result<DirectionSet, String> {
    s.parse().map_err(|e: btfsynth::Error| e.to_string())
}

pub fn run(args: GenArgs, bars: &Bars) -> Result<()> {
    if args.list {
        let lines: Vec<String> =
            MaterialKind::ALL.iter().map(|(kind, about)| format!("{:<8} {about}", kind.name())).collect();
        super::print(lines.join("\n"))?;
        return Ok(());
    }
    let Some(kind) = args.kind else {
        return Err(usage("name a material kind: pebbles, weave or bricks (see gen --list)"));
    };
    let Some(output) = args.output else { return Err(usage("name the output directory with -o DIR")) };
    let params = GenParams {
        size: args.size,
        directions: args.directions,
        seed: args.seed,
        samples_per_pixel: args.spp,
    };
    params.validate().map_err(super::usage_of)?;
    check_dir_target(&output, args.force)?;
    let started = Instant::now();
    let stack = generate(kind, &params, bars)?;
    let source = serde_json::json!({
        "generator": format!("btfsynth {} gen", env!("CARGO_PKG_VERSION")),
        "kind": kind.name(),
        "size": args.size,
        "directions": args.directions.to_string(),
        "seed": args.seed,
        "samples_per_pixel": args.spp,
    });
    let written = write_stack(&stack, &output, args.format, Some(source), args.force, bars)?;
    eprintln!(
        "wrote {} images of {}x{} {} to {} in {:.1} s",
        stack.len(),
        stack.width(),
        stack.height(),
        kind.name(),
        written.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
