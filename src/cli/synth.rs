//! `btfsynth synth`: texton map synthesis (plane mode).

use super::progress::Bars;
use crate::fsutil::{check_target, write_file_atomic};
use crate::synth::plane::{synthesize_plane, write_plane};
use crate::synth::{Preset, Sample, Search, SynthParams};
use anyhow::{bail, Result};
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum SearchKind {
    /// k-coherence search over the analysis' kNN lists (Tong §5.2).
    Kcoherence,
    /// Every sample pixel (slow; for comparison, Tong Table 2).
    Full,
}

#[derive(clap::Args)]
#[command(after_help = "Example: btfsynth synth pebbles.analysis/ --plane 128x128 -o plane/\n\n\
Surface synthesis on meshes is not in this version yet; --plane synthesizes on a regular grid.")]
pub struct SynthArgs {
    /// The analysis directory (from `btfsynth analyze`).
    analysis: PathBuf,
    /// Synthesize on a regular W×H grid (2D texture synthesis), e.g. 128x128.
    #[arg(long, value_name = "WxH", required = true, value_parser = parse_size)]
    plane: (usize, usize),
    /// Output directory.
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// Candidates per kNN list (at most the analysis' k; default: the analysis' k).
    #[arg(long)]
    k: Option<usize>,
    /// Pyramid levels to use (at most the analysis' levels; default: all).
    #[arg(long)]
    levels: Option<usize>,
    /// Side of the square neighbourhood template (odd).
    #[arg(long, default_value_t = 5)]
    neighborhood: usize,
    /// Candidate search.
    #[arg(long, value_enum, default_value_t = SearchKind::Kcoherence)]
    search: SearchKind,
    /// The engine's parts, named after their paper.
    #[arg(long, default_value = "tong2002")]
    preset: String,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Also write timings, candidate-set sizes and mean best distances per level here.
    #[arg(long, value_name = "FILE.json")]
    report: Option<PathBuf>,
    /// Replace the output if it exists.
    #[arg(long)]
    force: bool,
}

fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("'{s}': expected WxH with positive integers, e.g. 128x128");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    match (w.trim().parse::<usize>(), h.trim().parse::<usize>()) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 => Ok((w, h)),
        _ => Err(bad()),
    }
}

pub fn run(args: SynthArgs, bars: &Bars) -> Result<()> {
    check_target(&args.output, args.force)?;
    if let Some(report) = &args.report {
        check_target(report, true)?;
    }
    if args.neighborhood < 3 || args.neighborhood % 2 == 0 {
        bail!("--neighborhood {} must be odd and at least 3", args.neighborhood);
    }
    let manifest = crate::analysis::store::read_manifest(&args.analysis)?;
    let levels = args.levels.unwrap_or(manifest.levels.len());
    let sample = Sample::open(&args.analysis, levels)?;
    let k = args.k.unwrap_or(manifest.k);
    if k == 0 || k > manifest.k {
        bail!("--k {k}: must be between 1 and the analysis' k = {}", manifest.k);
    }
    let search = match args.search {
        SearchKind::Kcoherence => Search::KCoherence { k },
        SearchKind::Full => Search::Full,
    };
    let params = SynthParams {
        preset: Preset::by_name(&args.preset)?,
        search,
        neighborhood: args.neighborhood,
        seed: args.seed,
    };
    let result = synthesize_plane(&sample, args.plane, &params, bars)?;
    let params_json = serde_json::json!({
        "preset": params.preset.name, "search": format!("{:?}", args.search).to_lowercase(), "k": k,
        "levels": levels, "neighborhood": args.neighborhood, "seed": args.seed,
    });
    let written = write_plane(&result, &args.analysis, params_json.clone(), &args.output, args.force)?;
    if let Some(report) = &args.report {
        let json = serde_json::json!({"params": params_json, "levels": result.reports});
        write_file_atomic(report, serde_json::to_string_pretty(&json)?.as_bytes())?;
    }
    for r in &result.reports {
        eprintln!(
            "  level {}: {} vertices, {:.2} s, {:.1} candidates, mean best distance {:.4}",
            r.level, r.vertices, r.seconds, r.mean_candidates, r.mean_best_distance
        );
    }
    eprintln!("wrote a {}x{} plane to {}", args.plane.0, args.plane.1, written.display());
    Ok(())
}
