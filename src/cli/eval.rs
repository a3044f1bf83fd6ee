//! `btfsynth eval`: quality of a synthesized result against its sample.

use super::progress::Bars;
use super::shots::with_force_hint;
use crate::analysis::store::verify_fingerprint;
use crate::eval::{chi2, coherence, energy, Quality};
use crate::synth::engine::State;
use crate::synth::plane::{read_plane, MANIFEST};
use crate::synth::surface::surface_level;
use crate::synth::surface_map::{read_surface_ply, ANALYSIS_FINGERPRINT_KEY};
use crate::synth::target::{grid_levels, TargetLevel};
use crate::synth::Sample;
use anyhow::{bail, Result};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct EvalArgs {
    /// The analysis directory the result was synthesized from.
    analysis: PathBuf,
    /// A surface map (the PLY from `synth ANALYSIS MESH`) or a plane result directory.
    result: PathBuf,
    /// Print one JSON object {"chi2", "energy", "coherence"}.
    #[arg(long)]
    json: bool,
    /// Evaluate against the analysis even if its fingerprint differs from the one the
    /// result was synthesized from.
    #[arg(long)]
    force_analysis: bool,
}

pub fn run(args: EvalArgs, _bars: &Bars) -> Result<()> {
    let (level, state, what, recorded) = if args.result.join(MANIFEST).is_file() {
        let (width, height, state, manifest) = read_plane(&args.result)?;
        let neighborhood = manifest["params"]["neighborhood"].as_u64().unwrap_or(5) as usize;
        let grid = grid_levels(width, height, 1, neighborhood, 3).remove(0);
        let recorded = manifest["analysis_fingerprint"].as_str().map(str::to_string);
        (grid, state, format!("{width}x{height} plane"), recorded)
    } else if args.result.is_file() {
        let map = read_surface_ply(&args.result)?;
        let neighborhood = map
            .comments
            .iter()
            .find_map(|c| c.strip_prefix("params "))
            .and_then(|p| serde_json::from_str::<serde_json::Value>(p).ok())
            .and_then(|p| p["neighborhood"].as_u64())
            .unwrap_or(5) as usize;
        let level = surface_level(&map.mesh, &map.frames, map.texel, neighborhood)?;
        let what = format!("surface map of {} vertices", map.mesh.vertex_count());
        let recorded = map.comment(ANALYSIS_FINGERPRINT_KEY).map(str::to_string);
        (level, map.state, what, recorded)
    } else {
        bail!("{}: not a result: expected a surface map PLY or a plane directory", args.result.display());
    };
    if !args.force_analysis {
        verify_fingerprint(&args.analysis, &args.result, recorded.as_deref()).map_err(with_force_hint)?;
    }
    let quality = evaluate(&args, &level, &state)?;
    if args.json {
        println!("{}", serde_json::to_string(&quality)?);
    } else {
        println!("{}: {what} from {}", args.result.display(), args.analysis.display());
        println!("  chi2       {:.4}  (texton histograms; 0 = identical)", quality.chi2);
        println!(
            "  energy     {:.4}  (mean neighbourhood distance through Γ; lower is better)",
            quality.energy
        );
        println!("  coherence  {:.1}  (mean vertices per contiguously copied patch)", quality.coherence);
    }
    Ok(())
}

fn evaluate(args: &EvalArgs, level: &TargetLevel, state: &State) -> Result<Quality> {
    let sample = Sample::open(&args.analysis, 1)?;
    let s = &sample.levels[0];
    if state.labels.iter().any(|&l| l as usize >= s.textons)
        || state.uv.iter().any(|&[x, y]| x < 0 || y < 0 || x as usize >= s.width || y as usize >= s.height)
    {
        bail!(
            "{}: its labels or coordinates do not fit the analysis {}",
            args.result.display(),
            args.analysis.display()
        );
    }
    Ok(Quality {
        chi2: chi2(&state.labels, &s.labels, s.textons),
        energy: energy(level, state, s),
        coherence: coherence(level, state, s),
    })
}
