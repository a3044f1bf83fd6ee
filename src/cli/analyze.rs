//! `btfsynth analyze`: texton analysis of a stack.

use super::progress::Bars;
use super::usage;
use crate::analysis::filters::FilterBank;
use crate::analysis::pipeline::AnalysisParams;
use crate::analysis::{input, store};
use crate::btf::image_io::is_image_path;
use crate::btf::Crop;
use crate::fsutil::check_target;
use crate::maps::{self, MapSource, MaterialMap};
use anyhow::Result;
use std::path::PathBuf;

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
    /// Length of each kNN list, the pixel itself included (1 = Ashikhmin's coherence search).
    #[arg(long, default_value_t = 11, value_parser = super::at_least(1))]
    k: usize,
    /// Side of the square neighbourhood used by the kNN search (odd, at least 3).
    #[arg(long, default_value_t = 5, value_parser = super::odd_side)]
    neighborhood: usize,
    /// The sample tiles: filters and neighbourhoods wrap around instead of mirroring.
    #[arg(long)]
    tileable: bool,
    /// Most principal images filtered per level (more = closer to filtering every image).
    #[arg(long, default_value_t = 32, value_name = "N", value_parser = super::at_least(1))]
    basis: usize,
    /// Dimensions of the per-pixel appearance vectors (PCA of the filter responses) that the
    /// appearance-space synthesis metric compares.
    #[arg(long, default_value_t = crate::analysis::appearance::DEFAULT_DIMS, value_name = "N")]
    appearance_dims: usize,
    /// A filter bank TOML file (default: the built-in Leung–Malik 48, filters/lm48.toml).
    #[arg(long, value_name = "FILE")]
    filters: Option<PathBuf>,
    /// Analyse only this rectangle of the sample: x,y,w,h in pixels.
    #[arg(long, value_name = "X,Y,W,H")]
    crop: Option<Crop>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Analyse decoded images even where the stack is a factorized .btf file or too large
    /// to decode (then refused): by default a DFMF/FMF file is analysed from its factors and
    /// a stack too large to decode through a streamed basis.
    #[arg(long)]
    decoded: bool,
    /// Material maps of the same patch, stored beside the sample at their own depth (8-bit,
    /// 16-bit PNG or float EXR) and carried through synthesis: KIND=FILE pairs separated by
    /// commas; kinds: normal, roughness, metallic, occlusion, height.
    #[arg(long, value_name = "KIND=FILE,…", value_parser = parse_maps)]
    maps: Option<MapList>,
    /// Replace the output directory if it exists.
    #[arg(long)]
    force: bool,
}

/// The `--maps` list as clap hands it over.
#[derive(Clone, Debug)]
struct MapList(Vec<MapSource>);

fn parse_maps(s: &str) -> Result<MapList, String> {
    maps::parse_map_list(s).map(MapList).map_err(|e| e.to_string())
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
    Ok(sources.iter().map(|s| MaterialMap::load(s, size, crop)).collect::<crate::Result<_>>()?)
}

pub fn run(args: AnalyzeArgs, bars: &Bars) -> Result<()> {
    check_target(&args.output, args.force)?;
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
    let mode = if args.decoded { input::Mode::Decoded } else { input::Mode::Auto };
    let stack = input::open(&args.stack, args.crop, mode, &params, bars)?;
    let (width, height) = stack.size();
    let maps = load_maps(&args, (width, height))?;
    params.validate(width, height).map_err(usage)?;
    let analysed = input::run(&stack, &params, bars)?;
    let crop = args.crop.map(|c| [c.x, c.y, c.width, c.height]);
    let written =
        store::write_analysed(&analysed, &stack, (&args.stack, crop), &maps, &args.output, args.force)?;
    let analysis = &analysed.analysis;
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
