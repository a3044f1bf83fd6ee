//! `btfsynth eval`: quality of a synthesized result against its sample.

use super::progress::Bars;
use crate::eval::{chi2, energy, grid_coherence, Quality};
use crate::synth::plane::{read_plane, MANIFEST};
use crate::synth::target::grid_levels;
use crate::synth::Sample;
use anyhow::{bail, Result};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct EvalArgs {
    /// The analysis directory the result was synthesized from.
    analysis: PathBuf,
    /// A plane result directory (from `synth --plane`).
    result: PathBuf,
    /// Print one JSON object {"chi2", "energy", "coherence"}.
    #[arg(long)]
    json: bool,
}

pub fn run(args: EvalArgs, _bars: &Bars) -> Result<()> {
    if !args.result.join(MANIFEST).is_file() {
        bail!(
            "{}: not a plane result (no {MANIFEST}); eval reads the output of `synth --plane`",
            args.result.display()
        );
    }
    let (width, height, state, manifest) = read_plane(&args.result)?;
    let sample = Sample::open(&args.analysis, 1)?;
    let level = &sample.levels[0];
    if state.labels.iter().any(|&l| l as usize >= level.textons)
        || state
            .uv
            .iter()
            .any(|&[x, y]| x < 0 || y < 0 || x as usize >= level.width || y as usize >= level.height)
    {
        bail!(
            "{}: its labels or coordinates do not fit the analysis {}",
            args.result.display(),
            args.analysis.display()
        );
    }
    let neighborhood = manifest["params"]["neighborhood"].as_u64().unwrap_or(5) as usize;
    let grid = grid_levels(width, height, 1, neighborhood, 3);
    let quality = Quality {
        chi2: chi2(&state.labels, &level.labels, level.textons),
        energy: energy(&grid[0], &state, level),
        coherence: grid_coherence(width, height, &state, level),
    };
    if args.json {
        println!("{}", serde_json::to_string(&quality)?);
    } else {
        println!("{}: {width}x{height} plane from {}", args.result.display(), args.analysis.display());
        println!("  chi2       {:.4}  (texton histograms; 0 = identical)", quality.chi2);
        println!(
            "  energy     {:.4}  (mean neighbourhood distance through Γ; lower is better)",
            quality.energy
        );
        println!("  coherence  {:.1}  (mean vertices per contiguously copied patch)", quality.coherence);
    }
    Ok(())
}
