//! `btfsynth analyze`: texton analysis of a stack.

use super::progress::Bars;
use super::usage;
use crate::analysis::filters::FilterBank;
use crate::analysis::pipeline::{analyze, AnalysisParams};
use crate::analysis::store;
use crate::btf::image_io::is_image_path;
use crate::btf::{load, Crop, LoadOptions};
use crate::fsutil::{check_apart, check_not_input, commit_all, Staged};
use crate::maps::{self, MapSource, MaterialMap};
use anyhow::Result;
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
#[command(after_help = "Example: btfsynth analyze pebbles/ -o pebbles.analysis/")]
pub struct AnalyzeArgs {
    /// The BTF stack: a directory (btf.json or Bonn/UTIA-named images), a btf.json, or one image.
    stack: PathBuf,
    /// Output directory: analysis.json, .npy arrays and PNG previews.
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// Textons at the finest level (capped by the pixel count); each coarser level gets a quarter.
    #[arg(long, default_value_t = 400, value_parser = super::at_least(1))]
    textons: usize,
    /// Representative images clustered into textons (capped by the image count).
    #[arg(long, default_value_t = 400, value_parser = super::at_least(1))]
    selected: usize,
    /// Pyramid levels (each half the size of the finer one; the coarsest must be at least
    /// the neighbourhood + 4 pixels wide).
    #[arg(long, default_value_t = 3, value_parser = super::at_least(1))]
    levels: usize,
    /// Length of each kNN list, the pixel itself included (1 = Ashikhmin's coherence
    /// search), 1 to 256 and at most the coarsest level's pixel count.
    #[arg(long, default_value_t = 11, value_parser = super::in_range(1, 256))]
    k: usize,
    /// Side of the square neighbourhood used by the kNN search (odd, 3 to 63).
    #[arg(long, default_value_t = 5, value_parser = super::odd_side)]
    neighborhood: usize,
    /// The sample tiles: filters and neighbourhoods wrap around instead of mirroring.
    #[arg(long)]
    tileable: bool,
    /// Most principal images filtered per level, 1 to 1024 (more = closer to filtering
    /// every image).
    #[arg(long, default_value_t = 32, value_name = "N", value_parser = super::in_range(1, 1024))]
    basis: usize,
    /// Dimensions of the per-pixel appearance vectors (PCA of the filter responses) that the
    /// appearance-space synthesis metric compares, 1 to 64.
    #[arg(long, default_value_t = crate::analysis::appearance::DEFAULT_DIMS, value_name = "N", value_parser = super::in_range(1, 64))]
    appearance_dims: usize,
    /// A filter bank TOML file, at most 256 filters (default: the built-in Leung–Malik 48,
    /// filters/lm48.toml).
    #[arg(long, value_name = "FILE")]
    filters: Option<PathBuf>,
    /// Analyse only this rectangle of the sample: x,y,w,h in pixels.
    #[arg(long, value_name = "X,Y,W,H")]
    crop: Option<Crop>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Material maps of the same patch, stored beside the sample at their own depth (8-bit,
    /// 16-bit PNG or float EXR) and carried through synthesis: KIND=FILE pairs separated by
    /// commas; kinds: normal, roughness, metallic, occlusion, height.
    #[arg(long, value_name = "KIND=FILE,…", value_parser = parse_maps)]
    maps: Option<MapList>,
    /// Also write the time each stage took and the peak memory here (analysis.json holds
    /// only what the same inputs always give).
    #[arg(long, value_name = "FILE.json")]
    report: Option<PathBuf>,
    /// Replace the output directory (and the report) if it exists.
    #[arg(long)]
    force: bool,
}

/// The `--maps` list as clap hands it over.
#[derive(Clone, Debug)]
struct MapList(Vec<MapSource>);

fn parse_maps(s: &str) -> Result<MapList, String> {
    maps::parse_map_list(s).map(MapList).map_err(|e| e.to_string())
}

/// The parameters against the sample's size: a sample too small for any analysis is a
/// bad input (exit 1, naming it); one too small for these flags is a usage error; a kNN
/// list longer than the coarsest level has pixels is refused.
fn check_sample_size(args: &AnalyzeArgs, params: &AnalysisParams, (w, h): (usize, usize)) -> Result<()> {
    if let Err(e) = params.validate(w, h) {
        let smallest = AnalysisParams { levels: 1, neighborhood: 3, ..params.clone() };
        if smallest.validate(w, h).is_err() {
            let what = if args.crop.is_some() { "the crop" } else { "the sample" };
            return Err(crate::Error::format(
                &args.stack,
                format!("{what} is {w}x{h} pixels, too small to analyse (the smallest neighbourhood search, 3x3, needs 7x7)"),
            )
            .into());
        }
        return Err(usage(e));
    }
    let sizes = crate::analysis::pyramid::level_sizes(w, h, params.levels);
    let (cw, ch) = sizes[sizes.len() - 1];
    if params.k > cw * ch {
        return Err(usage(format!(
            "--k {}: a kNN list holds at most the {cw}x{ch} = {} pixels of the coarsest level",
            params.k,
            cw * ch
        )));
    }
    Ok(())
}

/// Bytes the analysis allocates beyond the decoded stack at its peak: every image as rows
/// of f32 and a centred copy (the principal images of the whole stack, when there are more
/// images than `selected`), the same for the selected images, and the filter responses of
/// the principal images at every pixel of the finest level. Measured peaks (`analyze
/// --report`, generated 576-image stacks) were 0.8 to 1.0 times this plus ~95 MB.
fn analysis_bytes(images: usize, (w, h): (usize, usize), params: &AnalysisParams) -> u64 {
    let f32s = std::mem::size_of::<f32>() as u64;
    let rows = |n: usize| (n as u64).saturating_mul((w * h * 3) as u64 * f32s);
    let whole = if images > params.selected { rows(images).saturating_mul(2) } else { 0 };
    let selected = rows(images.min(params.selected)).saturating_mul(2);
    let rank = params.basis_rank.min(images) as u64;
    let responses = ((w * h) as u64 * 3 * f32s).saturating_mul(rank * params.filters.len() as u64);
    whole.saturating_add(selected).saturating_add(responses)
}

/// Refuses, before the analysis starts, one that would need more than `budget` bytes (80%
/// of the memory available; `None` where the platform does not say): it would otherwise
/// be killed for memory after minutes of work.
fn check_memory(stack: &Path, needed: u64, budget: Option<u64>) -> Result<()> {
    match budget {
        Some(budget) if needed > budget => Err(crate::Error::format(
            stack,
            format!(
                "analysing it would take {:.1} GiB beyond the decoded images, more than the {:.1} GiB budget \
                 (80% of the memory available); analyse a part with --crop x,y,w,h, or fewer images",
                needed as f64 / (1u64 << 30) as f64,
                budget as f64 / (1u64 << 30) as f64
            ),
        )
        .into()),
        _ => Ok(()),
    }
}

/// The maps of `--maps`, checked against the stack and cropped like it.
fn load_maps(args: &AnalyzeArgs, stack: &crate::btf::Btf) -> Result<Vec<MaterialMap>> {
    let Some(MapList(sources)) = &args.maps else { return Ok(Vec::new()) };
    // Maps match the uncropped image: known for a one-image stack, else only the crop's fit
    // can be checked.
    let size = match args.crop {
        None => Some((stack.width(), stack.height())),
        Some(_) if is_image_path(&args.stack) => {
            image::image_dimensions(&args.stack).ok().map(|(w, h)| (w as usize, h as usize))
        }
        Some(_) => None,
    };
    let crop = args.crop.map(|c| (c.x as usize, c.y as usize, c.width as usize, c.height as usize));
    Ok(sources.iter().map(|s| MaterialMap::load(s, size, crop)).collect::<crate::Result<_>>()?)
}

pub fn run(args: AnalyzeArgs, bars: &Bars) -> Result<()> {
    // A manifest's images lie in its directory: that is the input.
    let stack_dir = args.stack.parent().filter(|_| args.stack.extension().is_some_and(|e| e == "json"));
    let map_files: Vec<&Path> = args.maps.iter().flat_map(|m| m.0.iter().map(|s| s.path.as_path())).collect();
    let inputs: Vec<&Path> = [Some(args.stack.as_path()), stack_dir, args.filters.as_deref()]
        .into_iter()
        .flatten()
        .chain(map_files.iter().copied())
        .collect();
    check_not_input("-o", &args.output, &inputs)?;
    let staged_output = Staged::dir(&args.output, args.force)?;
    let staged_report = match &args.report {
        Some(report) => {
            check_not_input("--report", report, &inputs)?;
            check_apart("--report", report, &args.output)?;
            Some(Staged::file(report, args.force)?)
        }
        None => None,
    };
    let filters = match &args.filters {
        Some(path) => FilterBank::from_file(path)?,
        None => FilterBank::lm48(),
    };
    let params = AnalysisParams {
        textons: args.textons,
        selected: args.selected,
        levels: args.levels,
        k: args.k,
        neighborhood: args.neighborhood,
        tileable: args.tileable,
        basis_rank: args.basis,
        appearance_dims: args.appearance_dims,
        seed: args.seed,
        filters,
    };
    let stack = load(&args.stack, &LoadOptions { crop: args.crop }, bars)?;
    let maps = load_maps(&args, &stack)?;
    check_sample_size(&args, &params, (stack.width(), stack.height()))?;
    let budget = crate::btf::source::available_memory().map(|a| a / 10 * 8);
    check_memory(&args.stack, analysis_bytes(stack.len(), (stack.width(), stack.height()), &params), budget)?;
    let analysis = analyze(&stack, &params, bars)?;
    let crop = args.crop.map(|c| [c.x, c.y, c.width, c.height]);
    store::write_with_maps(&analysis, &stack, (&args.stack, crop), &maps, staged_output.path(), false)?;
    let mut outputs = vec![staged_output];
    if let Some(report) = staged_report {
        let text = serde_json::to_string_pretty(&store::timings_json(&analysis))?;
        std::fs::write(report.path(), text).map_err(|e| crate::Error::io(report.target(), e))?;
        outputs.push(report);
    }
    let written = commit_all(outputs)?.remove(0);
    let t = &analysis.timings;
    let sizes: Vec<String> = analysis
        .levels
        .iter()
        .map(|l| {
            format!(
                "{}x{}: {} textons, d={}",
                l.textons.map.width,
                l.textons.map.height,
                l.textons.textons,
                l.textons.embedding.ncols()
            )
        })
        .collect();
    eprintln!(
        "analysed {} images ({} selected) into {}",
        stack.len(),
        analysis.selected.len(),
        written.display()
    );
    eprintln!("  levels    {}", sizes.join("; "));
    if !maps.is_empty() {
        let names: Vec<String> =
            maps.iter().map(|m| format!("{} ({:?})", m.kind.name(), m.image.depth)).collect();
        eprintln!("  maps      {}", names.join(", "));
    }
    eprintln!(
        "  time      {:.1} s (selection {:.1}, filtering {:.1}, k-means {:.1}, Γ {:.1}, kNN {:.1})",
        t.total.as_secs_f64(),
        t.selection.as_secs_f64(),
        t.filtering.as_secs_f64(),
        t.kmeans.as_secs_f64(),
        t.gamma.as_secs_f64(),
        t.knn.as_secs_f64()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_analysis_peak_counts_the_whole_stack_twice_only_when_representatives_are_chosen() {
        let params = AnalysisParams::default();
        // The UBO2014 case of issue #23 (killed at 24 GB): 22,801 images, a 192² crop.
        let peak = analysis_bytes(22_801, (192, 192), &params) as f64 / (1u64 << 30) as f64;
        assert!((19.0..21.0).contains(&peak), "{peak} GiB");
        let few = analysis_bytes(256, (64, 64), &params);
        let responses = 64 * 64 * 3 * 4 * 32 * params.filters.len() as u64;
        assert_eq!(few, 2 * 256 * 64 * 64 * 12 + responses, "no choice: the stack's rows once, centred once");
    }

    #[test]
    fn an_analysis_beyond_the_budget_is_refused_naming_the_stack() {
        let stack = Path::new("big.btf");
        let e = check_memory(stack, 20 << 30, Some(8 << 30)).unwrap_err().to_string();
        assert!(e.contains("big.btf") && e.contains("20.0 GiB") && e.contains("--crop"), "{e}");
        assert!(check_memory(stack, 4 << 30, Some(8 << 30)).is_ok());
        assert!(check_memory(stack, u64::MAX, None).is_ok(), "no figure from the platform: no refusal");
    }
}
