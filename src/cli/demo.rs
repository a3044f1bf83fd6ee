//! `btfsynth demo`: the pipeline on bundled defaults, into demo-out/.

use super::progress::Bars;
use crate::analysis::pipeline::{analyze, AnalysisParams};
use crate::analysis::store;
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
    eprintln!("[1/3] generating a 48x48 pebbles BTF on a 16-direction dome (256 images)");
    let params = GenParams { size: 48, directions: DirectionSet::Grid(16), ..GenParams::default() };
    let stack = generate(MaterialKind::Pebbles, &params, bars)?;
    let source = serde_json::json!({
        "generator": "btfsynth demo", "kind": "pebbles", "size": 48, "directions": "grid:16", "seed": 0
    });
    write_stack(&stack, &stack_dir, ImageFormat::Exr, Some(source), true, bars)?;
    let reloaded = load(&stack_dir, &LoadOptions::default(), bars)?;
    println!("{}", serde_json::to_string_pretty(&super::info::stack_json(&stack_dir, &reloaded))?);

    let analysis_dir = args.output.join("analysis");
    eprintln!("[2/3] texton analysis: 200 textons, 3 levels, k = 11");
    let analysis_params = AnalysisParams { textons: 200, ..AnalysisParams::default() };
    let analysis = analyze(&reloaded, &analysis_params, bars)?;
    store::write(&analysis, &reloaded, &stack_dir, None, &analysis_dir, true)?;
    println!(
        "{}",
        serde_json::to_string_pretty(&super::info::analysis_json(&store::read_manifest(&analysis_dir)?))?
    );

    let texture = data_dir(args.data).join("gravel-128.png");
    eprintln!("[3/3] reading the bundled photograph {} as a one-image BTF", texture.display());
    let photo = load(&texture, &LoadOptions::default(), bars)?;
    println!("{}", serde_json::to_string_pretty(&super::info::stack_json(&texture, &photo))?);
    eprintln!(
        "done: see {}/ (btf.json lists every image), {}/level0_textons.png (the texton map) and {}/filters.png",
        stack_dir.display(),
        analysis_dir.display(),
        analysis_dir.display()
    );
    Ok(())
}
