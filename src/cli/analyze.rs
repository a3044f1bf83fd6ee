//! `btfsynth analyze`: texton analysis of a stack.

use super::progress::Bars;
use super::usage;
use anyhow::Result;
use btfsynth::analysis::filters::FilterBank;
use btfsynth::analysis::pipeline::AnalysisParams;
use btfsynth::analysis::{input, store};
use btfsynth::btf::image_io::is_image_path;
use btfsynth::btf::Crop;
use btfsynth::fsutil::{check_apart, check_not_input, commit_all, Staged};
use btfsynth::maps::{self, MapSource, MaterialMap};
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
    #[arg(long, default_value_t = btfsynth::analysis::appearance::DEFAULT_DIMS, value_name = "N", value_parser = super::in_range(1, 64))]
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
    /// Analyse decoded images even where the stack is a factorized .btf file or too large
    /// to decode (then refused): by default a DFMF/FMF file is analysed from its factors and
    /// a stack too large to decode through a streamed basis.
    #[arg(long)]
    decoded: bool,
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
            return Err(btfsynth::Error::format(
                &args.stack,
                format!("{what} is {w}x{h} pixels, too small to analyse (the smallest neighbourhood search, 3x3, needs 7x7)"),
            )
            .into());
        }
        return Err(super::usage_of(e));
    }
    let sizes = btfsynth::analysis::pyramid::level_sizes(w, h, params.levels);
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

/// The maps of `--maps`, checked against the stack and cropped like it.
fn load_maps(args: &AnalyzeArgs, (width, height): (usize, usize)) -> Result<Vec<MaterialMap>> {
    let Some(MapList(sources)) = &args.maps else { return Ok(Vec::new()) };
    // Maps match the uncropped image: known for a one-image stack, else only the crop's fit
    // can be checked.
    let size = match args.crop {
        None => Some((width, height)),
        Some(_) if is_image_path(&args.stack) => {
            image::image_dimensions(&args.stack).ok().map(|(w, h)| (w as usize, h as usize))
        }
        Some(_) => None,
    };
    let crop = args.crop.map(|c| (c.x as usize, c.y as usize, c.width as usize, c.height as usize));
    Ok(sources.iter().map(|s| MaterialMap::load(s, size, crop)).collect::<btfsynth::Result<_>>()?)
}

pub fn run(args: AnalyzeArgs, bars: &Bars) -> Result<()> {
    // A manifest's folder and every image it names are inputs too.
    let stack_inputs = btfsynth::btf::load::input_paths(&args.stack);
    let map_files: Vec<&Path> = args.maps.iter().flat_map(|m| m.0.iter().map(|s| s.path.as_path())).collect();
    let inputs: Vec<&Path> = stack_inputs
        .iter()
        .map(PathBuf::as_path)
        .chain(args.filters.as_deref())
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
    // The memory estimate of the path taken is checked inside, before anything is decoded.
    let mode = if args.decoded { input::Mode::Decoded } else { input::Mode::Auto };
    let stack = input::open(&args.stack, args.crop, mode, &params, bars)?;
    let maps = load_maps(&args, stack.size())?;
    check_sample_size(&args, &params, stack.size())?;
    let analysed = input::run(&stack, &params, bars)?;
    let analysis = &analysed.analysis;
    let crop = args.crop.map(|c| [c.x, c.y, c.width, c.height]);
    store::write_analysed(&analysed, &stack, (&args.stack, crop), &maps, staged_output.path(), false)?;
    let mut outputs = vec![staged_output];
    if let Some(report) = staged_report {
        let text = serde_json::to_string_pretty(&store::timings_json(analysis))?;
        std::fs::write(report.path(), text).map_err(|e| btfsynth::Error::io(report.target(), e))?;
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
        "analysed {} images ({} selected, from {}) into {}",
        stack.len(),
        analysis.selected.len(),
        input::describe(&stack),
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
