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
    /// The bundled inputs (default: ./data, else the crate's own data/).
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
}

fn data_dir(given: Option<PathBuf>) -> PathBuf {
    given.unwrap_or_else(|| {
        let local = PathBuf::from("data");
        if local.is_dir() {
            local
        } else {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data")
        }
    })
}

pub fn run(args: DemoArgs, bars: &Bars) -> Result<()> {
    std::fs::create_dir_all(&args.output).map_err(|e| crate::Error::io(&args.output, e))?;
    let stack_dir = args.output.join("stack");
    eprintln!("[1/2] generating a 48x48 pebbles BTF on a 16-direction dome (256 images)");
    let params = GenParams { size: 48, directions: DirectionSet::Grid(16), ..GenParams::default() };
    let stack = generate(MaterialKind::Pebbles, &params, bars)?;
    let source = serde_json::json!({
        "generator": "btfsynth demo", "kind": "pebbles", "size": 48, "directions": "grid:16", "seed": 0
    });
    write_stack(&stack, &stack_dir, ImageFormat::Exr, Some(source), true, bars)?;
    let reloaded = load(&stack_dir, &LoadOptions::default(), bars)?;
    println!("{}", serde_json::to_string_pretty(&super::info::stack_json(&stack_dir, &reloaded))?);

    let texture = data_dir(args.data).join("gravel-128.png");
    eprintln!("[2/2] reading the bundled photograph {} as a one-image BTF", texture.display());
    let photo = load(&texture, &LoadOptions::default(), bars)?;
    println!("{}", serde_json::to_string_pretty(&super::info::stack_json(&texture, &photo))?);
    eprintln!(
        "done: the stack is in {} (btf.json lists every image and its directions)",
        stack_dir.display()
    );
    Ok(())
}
