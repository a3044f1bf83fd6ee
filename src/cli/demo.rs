//! `btfsynth demo`: the pipeline on bundled defaults, into demo-out/.

use super::progress::Bars;
use crate::btf::gen::{generate, GenParams, MaterialKind};
use crate::btf::{load, write_stack, DirectionSet, ImageFormat, LoadOptions};
use anyhow::Result;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct DemoArgs {
    /// Where to write the demo's outputs (replaced if it exists).
    #[arg(short, long, default_value = "demo-out", value_name = "DIR")]
    output: PathBuf,
}

pub fn run(args: DemoArgs, bars: &Bars) -> Result<()> {
    std::fs::create_dir_all(&args.output).map_err(|e| crate::Error::io(&args.output, e))?;
    let stack_dir = args.output.join("stack");
    eprintln!("[1/1] generating a 48x48 pebbles BTF on a 16-direction dome (256 images)");
    let params = GenParams {
        size: 48,
        directions: DirectionSet::Grid(16),
        ..GenParams::default()
    };
    let stack = generate(MaterialKind::Pebbles, &params, bars)?;
    let source = serde_json::json!({"generator": "btfsynth demo", "kind": "pebbles", "size": 48, "directions": "grid:16", "seed": 0});
    write_stack(
        &stack,
        &stack_dir,
        ImageFormat::Exr,
        Some(source),
        true,
        bars,
    )?;
    let reloaded = load(&stack_dir, &LoadOptions::default(), bars)?;
    println!(
        "{}",
        serde_json::to_string_pretty(&super::info::stack_json(&stack_dir, &reloaded))?
    );
    eprintln!(
        "done: the stack is in {} (btf.json lists every image and its directions)",
        stack_dir.display()
    );
    Ok(())
}
