//! `btfsynth synth`: texton map synthesis on a mesh (surface mode) or a grid (plane mode).

use super::progress::Bars;
use super::{usage, usage_of};
use anyhow::{Context, Result};
use btfsynth::cache::CacheDir;
use btfsynth::fsutil::{check_apart, check_not_input, check_workspace, commit_all, Staged};
use btfsynth::mesh::field::Orientation;
use btfsynth::synth::plane::{synthesize_plane, write_plane};
use btfsynth::synth::round::MarchingOrigin;
use btfsynth::synth::session::{SearchChoice, SynthSessionBuilder};
use btfsynth::synth::surface_map::{
    build_pyramid_cached, synthesize_surface, write_surface_ply, Density, MAX_VERTICES,
};
use btfsynth::synth::{Device, LevelReport, MetricKind, Preset, Sample, SynthParams};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum SearchKind {
    /// k-coherence search over the analysis' kNN lists (Tong §5.2).
    Kcoherence,
    /// Every sample pixel (slow; for comparison, Tong Table 2).
    Full,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum DeviceKind {
    /// A hardware GPU where the machine has one (full searches excepted), else the CPU.
    Auto,
    /// The CPU.
    Cpu,
    /// A GPU through wgpu, software ones (Mesa's lavapipe, llvmpipe) included.
    Gpu,
}

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  btfsynth synth pebbles.analysis/ bunny.obj --texels-across 256 -o bunny.ply\n  \
btfsynth synth pebbles.analysis/ --plane 128x128 -o plane/\n  \
btfsynth synth pebbles.analysis/ bunny.obj --method soler2002 -o bunny-uv.ply   # UVs on the mesh as it is"
)]
pub struct SynthArgs {
    /// The analysis directory (from `btfsynth analyze`).
    #[arg(required_unless_present = "list_presets")]
    analysis: Option<PathBuf>,
    /// The mesh to cover (OBJ, OFF, PLY); omit with --plane.
    #[arg(required_unless_present_any = ["plane", "list_presets"], conflicts_with = "plane")]
    mesh: Option<PathBuf>,
    /// Synthesize on a regular W×H grid instead of a mesh (2D texture synthesis).
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    plane: Option<(usize, usize)>,
    /// With --plane: also show the result under this view θ,φ (degrees from the normal;
    /// repeatable; every --view with every --light, each the nearest measured image)
    /// [default: head-on, light at 45° and grazing light].
    #[arg(long = "view", value_name = "θ,φ", value_parser = super::shots::parse_angles, requires = "plane")]
    views: Vec<(f32, f32)>,
    /// With --plane: also show the result under this light θ,φ (see --view).
    #[arg(long = "light", value_name = "θ,φ", value_parser = super::shots::parse_angles, requires = "plane")]
    lights: Vec<(f32, f32)>,
    /// With --plane: make the result tile seamlessly (its neighbourhoods wrap around the
    /// plane's edges), for use as a repeating texture; eval then reports the patch energy
    /// across the wrap edge as `wrap_seam_energy`.
    #[arg(long, requires = "plane")]
    tileable_output: bool,
    /// Output: a binary PLY for a mesh, a directory for --plane.
    #[arg(short, long, value_name = "OUT", required_unless_present = "list_presets")]
    output: Option<PathBuf>,
    /// Sample texels per model unit (the texture's size on the surface). One of --scale,
    /// --texels-across and --vertices sets the size; they exclude each other.
    #[arg(long, group = "density", value_parser = super::positive_number)]
    scale: Option<f32>,
    /// Sample texels across the mesh's largest bounding-box side [default: 4 × the sample
    /// width]. Excludes --scale and --vertices.
    #[arg(long, group = "density", value_parser = super::positive_number)]
    texels_across: Option<f32>,
    /// Vertices of the finest synthesis mesh (one vertex spacing = one texel); at least 4 on
    /// the coarsest level, 4 times more per finer level, and one neighbourhood (64 for 3
    /// levels). Excludes --scale and --texels-across.
    #[arg(long, group = "density")]
    vertices: Option<usize>,
    /// Tangent directions: smooth (a seeded field relaxed over a vertex hierarchy, turning as
    /// little as the surface allows), axis:x,y,z (a world direction projected), or a JSON
    /// file of constraints {"constraints": [{"vertex"|"point", "direction"}]}.
    #[arg(long, default_value = "smooth")]
    orient: String,
    /// Candidates per kNN list (at most the analysis' k; default: the analysis' k).
    #[arg(long, value_parser = super::at_least(1))]
    k: Option<usize>,
    /// Pyramid levels to use (at most the analysis' levels). Default on a plane: as many as
    /// keep the coarsest level at least 4n + 2 texels a side for an n×n --neighborhood, 30
    /// for 7×7, so that a small sample is not copied whole on a lattice, or two where that
    /// leaves one and the second is at least 3n + 1 (22), so that elements larger than the
    /// neighbourhood are not cut into fragments. Default on a mesh:
    /// one for presets that start from patches (all but turk2001, chen2008 and
    /// castellanos), whose passes then only mend the patches' seams; more levels smear a
    /// mesh's texture (docs/surfaces.md).
    #[arg(long, value_parser = super::at_least(1))]
    levels: Option<usize>,
    /// Side of the square neighbourhood template (odd, 3 to 63; at most the coarsest level in
    /// use a side).
    #[arg(long, default_value_t = 7, value_parser = super::odd_side)]
    neighborhood: usize,
    /// Candidate search.
    #[arg(long, value_enum, default_value_t = SearchKind::Kcoherence)]
    search: SearchKind,
    /// The engine's recipe, named after its paper: appearance (default: Tong's engine
    /// matched on appearance vectors), tong2002 (Tong's texton distances through Γ),
    /// turk2001 (Turk's sweep, half-square start, extrapolate and refine passes), chen2008
    /// (Chen and Dong's round neighbourhoods, adaptive metric, most-constrained-first order) or
    /// castellanos (Castellanos and Williams' choosy sampling of colour neighbourhoods, random
    /// order, an exhaustive coarsest level). The whole recipe is recorded in the output. See
    /// --list-presets.
    #[arg(long, default_value = "appearance")]
    preset: String,
    /// Run the recipe in this JSON file instead of a preset: the form `synth` records as
    /// `params.recipe` in plane.json, the PLY header and --report (copy that object out and
    /// edit it). Its passes may match with the Colour metric (SSD of the sample's linear
    /// RGB), which only a recipe reaches. docs/synthesis.md, Recipes, lists every value.
    #[arg(long, value_name = "FILE.json", conflicts_with = "preset")]
    recipe: Option<PathBuf>,
    /// Print one line per preset (its name and paper) and exit.
    #[arg(long)]
    list_presets: bool,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Where the passes run: auto (a hardware GPU where there is one; software adapters
    /// such as lavapipe are slower than the CPU and not used, and so is the GPU for --search
    /// full, which the CPU runs faster), cpu, or gpu (any wgpu
    /// adapter; an error where there is none; WGPU_BACKEND=vulkan|gl picks the backend).
    /// The result is the same byte for byte. Passes without a GPU form (all but the
    /// interleaved square-template passes of appearance and tong2002, on a plane or a mesh)
    /// run on the CPU. The log and --report say per level which ran where.
    #[arg(long, value_enum, default_value_t = DeviceKind::Auto)]
    device: DeviceKind,
    /// Also write timings, candidate-set sizes and mean best distances per level here.
    #[arg(long, value_name = "FILE.json")]
    report: Option<PathBuf>,
    /// Keep each mesh level's remeshing, templates and (for presets with round
    /// neighbourhoods, chen2008) marching in this directory (created if missing), and reuse
    /// them on later runs with the same mesh and density: another analysis of the same size,
    /// preset or seed skips the remeshing, and the same frames (same seed, or the same
    /// --orient axis or constraints) skip the templates too. Files are named by a hash of
    /// exactly what each depends on (about 2.3 KB per vertex of the finest mesh for
    /// remeshing and templates, 4.5 KB more for marchings); nothing is pruned; a damaged file
    /// is recomputed with a warning. Surface mode only; ignored on planes.
    #[arg(long, value_name = "DIR", alias = "marching-cache")]
    cache: Option<PathBuf>,
    /// Replace the output if it exists.
    #[arg(long)]
    force: bool,
    /// How the sample is put on the mesh: vertex (the per-vertex engine, --preset) or
    /// soler2002 (hierarchical pattern mapping: the mesh as it is, with texture coordinates
    /// into the sample; --scale or --texels-across size it).
    #[arg(long, value_enum, default_value_t = super::soler::Method::Vertex)]
    method: super::soler::Method,
    #[command(flatten)]
    soler: super::soler::SolerArgs,
}

/// The most cells a plane may have (the library's limit, 2^26 = 8192 × 8192).
const MAX_PLANE_AREA: usize = 1 << 26;

fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("'{s}': expected WxH with positive integers and W × H at most 2^26, e.g. 128x128");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    match (w.trim().parse::<usize>(), h.trim().parse::<usize>()) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 && w.checked_mul(h).is_some_and(|a| a <= MAX_PLANE_AREA) => {
            Ok((w, h))
        }
        _ => Err(bad()),
    }
}

/// Level reports as an output file records them: without wall-clock times or the device,
/// so that the same seed gives the same bytes (both go to `--report`; times serialized as
/// null).
pub(super) fn untimed(reports: &mut [LevelReport]) {
    for r in reports {
        r.seconds = f64::NAN;
        r.device = None;
    }
}

pub fn run(args: SynthArgs, bars: &Bars) -> Result<()> {
    if args.list_presets {
        let lines: Vec<String> =
            Preset::all().iter().map(|p| format!("{:<12} {}", p.name, p.paper)).collect();
        return super::print(lines.join("\n"));
    }
    // clap drops `requires = "plane"` once MESH (which conflicts with --plane) is given.
    if args.mesh.is_some() && (args.tileable_output || !args.views.is_empty() || !args.lights.is_empty()) {
        return Err(usage("--tileable-output, --view and --light need --plane"));
    }
    let (Some(analysis), Some(output)) = (args.analysis.clone(), args.output.clone()) else {
        return Err(usage("give an ANALYSIS and -o OUT"));
    };
    // Every output is checked (and reserved under a temporary name) before any work; they
    // are moved into place together at the very end.
    let orient_file = Some(Path::new(&args.orient)).filter(|p| p.exists());
    let inputs: Vec<&Path> =
        [Some(analysis.as_path()), args.mesh.as_deref(), args.recipe.as_deref(), orient_file]
            .into_iter()
            .flatten()
            .collect();
    check_not_input("-o", &output, &inputs)?;
    if let (Some(cache), Some(_)) = (&args.cache, &args.mesh) {
        let outputs: Vec<&Path> =
            [Some(output.as_path()), args.report.as_deref()].into_iter().flatten().collect();
        check_workspace("--cache", cache, &inputs, &outputs).map_err(usage_of)?;
    }
    let staged_output = match args.plane {
        Some(_) => Staged::dir(&output, args.force)?,
        None => Staged::file(&output, args.force)?,
    };
    let staged_report = match &args.report {
        Some(report) => {
            check_not_input("--report", report, &inputs)?;
            check_apart("--report", report, &output)?;
            Some(Staged::file(report, args.force)?)
        }
        None => None,
    };
    if args.method == super::soler::Method::Soler2002 {
        return soler2002(&args, &analysis, (staged_output, staged_report), bars);
    }
    let orientation = match &args.mesh {
        // A bad value is a usage error; a constraints file that cannot be read is not.
        Some(_) => Some(Orientation::parse(&args.orient).map_err(|e| match e {
            btfsynth::Error::OutOfRange { .. } => usage_of(e),
            other => other.into(),
        })?),
        None => None,
    };
    let manifest = btfsynth::analysis::store::read_manifest(&analysis)?;
    let preset = match &args.recipe {
        Some(file) => read_recipe(file)?,
        None => Preset::by_name(&args.preset).map_err(usage_of)?,
    };
    let mut session =
        SynthSessionBuilder::new().preset(preset).neighbourhood(args.neighborhood).seed(args.seed).device(
            match args.device {
                DeviceKind::Auto => Device::Auto,
                DeviceKind::Cpu => Device::Cpu,
                DeviceKind::Gpu => Device::Gpu,
            },
        );
    session = session.search(match args.search {
        SearchKind::Kcoherence => SearchChoice::KCoherence,
        SearchKind::Full => SearchChoice::Full,
    });
    session = session.surface(args.mesh.is_some());
    if let Some(levels) = args.levels {
        session = session.levels(levels);
    }
    if let Some(k) = args.k {
        session = session.k(k);
    }
    // Every refusal comes before any remeshing, and is a usage error.
    let session = session.build(&manifest).map_err(usage_of)?;
    let levels = session.levels();
    if let Some(n) = args.vertices {
        check_vertices(n, "--vertices", levels, args.neighborhood)?;
    }
    btfsynth::analysis::store::verify_levels(&analysis, &manifest, levels)?;
    let mut sample = Sample::open(&analysis, levels)?;
    if session.params().preset.uses(MetricKind::Colour) {
        sample.load_colours(&analysis)?;
    }
    session.check_sample(&sample).map_err(usage_of)?;
    let params = session.params().clone();
    let cache = match &args.cache {
        Some(dir) if args.mesh.is_some() => {
            Some(CacheDir::open(dir).map_err(|e| usage(format!("--cache: {e}")))?)
        }
        _ => None,
    };
    let mut params_json = session.provenance();
    let started = Instant::now();
    let (reports, written) = match (&args.mesh, args.plane, orientation) {
        (Some(mesh), None, Some(orientation)) => {
            let density = density(&args, manifest.width);
            params_json["orient"] = args.orient.clone().into();
            params_json["density"] = density.to_string().into();
            let (reports, vertices) = surface(
                &args,
                (&analysis, staged_output.path()),
                (mesh, &orientation),
                &sample,
                (&params, cache.as_ref()),
                density,
                levels,
                &mut params_json,
                bars,
            )?;
            (reports, format!("({vertices} vertices) in {:.1} s", started.elapsed().as_secs_f64()))
        }
        (None, Some(size), _) => {
            let mut result = synthesize_plane(&sample, size, args.tileable_output, &params, bars)?;
            let probes = shown_probes(&args, &analysis)?;
            let reports = result.reports.clone();
            untimed(&mut result.reports);
            write_plane(&result, &analysis, &probes, params_json.clone(), staged_output.path(), false)?;
            print_reports(&reports);
            (reports, format!("(a {}x{} plane)", size.0, size.1))
        }
        _ => return Err(usage("give either a MESH or --plane WxH")),
    };
    let mut outputs = vec![staged_output];
    if let Some(report) = staged_report {
        let json = serde_json::json!({"params": params_json, "levels": reports});
        std::fs::write(report.path(), serde_json::to_string_pretty(&json)?)
            .map_err(|e| btfsynth::Error::io(report.target(), e))?;
        outputs.push(report);
    }
    let committed = commit_all(outputs)?;
    eprintln!("wrote {} {written}", committed[0].display());
    if let Some(report) = committed.get(1) {
        eprintln!("wrote {}", report.display());
    }
    Ok(())
}

/// `--method soler2002`: the mesh is mapped as it is, so the per-vertex engine's flags do not apply.
fn soler2002(
    args: &SynthArgs,
    analysis: &Path,
    (output, report): (Staged, Option<Staged>),
    bars: &Bars,
) -> Result<()> {
    let Some(mesh) = &args.mesh else { return Err(usage("--method soler2002 maps a MESH (not --plane)")) };
    if args.vertices.is_some() || args.recipe.is_some() || args.preset != "appearance" || args.cache.is_some()
    {
        return Err(usage("--method soler2002 takes --scale or --texels-across, not --vertices, --preset, --recipe or --cache"));
    }
    if args.device == DeviceKind::Gpu {
        return Err(usage("--method soler2002 runs on the CPU; --device gpu is for the vertex engine"));
    }
    let common = super::soler::Common {
        analysis,
        mesh,
        output,
        scale: args.scale,
        texels_across: args.texels_across,
        seed: args.seed,
        report,
    };
    super::soler::run(common, &args.soler, bars)
}

/// The recipe in `file` (see `--recipe`), checked; any problem is a usage error naming the file.
fn read_recipe(file: &Path) -> Result<Preset> {
    let text = btfsynth::fsutil::read_input_text(file)
        .map_err(|e| usage(format!("--recipe {}: cannot read it: {e}", file.display())))?;
    Preset::from_json(&text).map_err(|e| usage(format!("--recipe {}: {e}", file.display())))
}

/// The view/light pairs asked for with --view/--light (empty: the defaults).
fn shown_probes(args: &SynthArgs, analysis: &Path) -> Result<Vec<btfsynth::analysis::images::Probe>> {
    if args.views.is_empty() && args.lights.is_empty() {
        return Ok(Vec::new());
    }
    let views = if args.views.is_empty() { vec![(0.0, 0.0)] } else { args.views.clone() };
    let lights = if args.lights.is_empty() { vec![(0.0, 0.0)] } else { args.lights.clone() };
    let pairs: Vec<([f32; 2], [f32; 2])> =
        views.iter().flat_map(|&(vt, vp)| lights.iter().map(move |&(lt, lp)| ([vt, vp], [lt, lp]))).collect();
    Ok(btfsynth::analysis::images::SampleImages::open(analysis)?.probes_for(&pairs))
}

fn density(args: &SynthArgs, sample_width: usize) -> Density {
    match (args.scale, args.texels_across, args.vertices) {
        (Some(s), _, _) => Density::Scale(s),
        (_, _, Some(n)) => Density::Vertices(n),
        (_, Some(n), _) => Density::TexelsAcross(n),
        _ => Density::TexelsAcross(4.0 * sample_width as f32),
    }
}

/// Synthesizes on the mesh and writes the surface map to `ply` (the output's temporary
/// name); returns the level reports and the finest mesh's vertex count.
#[allow(clippy::too_many_arguments)]
fn surface(
    args: &SynthArgs,
    (analysis, ply): (&Path, &Path),
    (mesh_path, orientation): (&Path, &Orientation),
    sample: &Sample,
    (params, cache): (&SynthParams, Option<&CacheDir>),
    density: Density,
    levels: usize,
    params_json: &mut serde_json::Value,
    bars: &Bars,
) -> Result<(Vec<LevelReport>, usize)> {
    let mesh = btfsynth::mesh::load(mesh_path)?;
    if !matches!(density, Density::Vertices(_)) {
        let texel = density.texel(&mesh).map_err(usage_of)?;
        let estimate = mesh.surface_area() / (3f64.sqrt() / 2.0 * f64::from(texel).powi(2));
        let flag = if args.scale.is_some() { "--scale" } else { "--texels-across" };
        check_vertices(estimate.round() as usize, flag, levels, args.neighborhood)
            .with_context(|| format!("{} at {density}", mesh_path.display()))?;
    }
    let pyramid = build_pyramid_cached(&mesh, density, levels, orientation, params, cache, bars)
        .with_context(|| format!("preparing {}", mesh_path.display()))?;
    let marchings: Vec<Option<MarchingOrigin>> =
        pyramid.targets.iter().map(|t| t.round.as_ref().map(|r| r.origin)).collect();
    for (l, level) in pyramid.levels.iter().enumerate() {
        let mut marching = match marchings[l] {
            Some(o) => format!(", marching {} in {:.2} s", o.source, o.seconds),
            None => String::new(),
        };
        if cache.is_some() {
            let [remeshing, templates] = pyramid.sources[l];
            marching = format!(", remeshing {remeshing}, templates {templates}{marching}");
        }
        eprintln!(
            "  mesh level {l}: {} vertices, texel {:.4e}, {}{marching}",
            level.mesh.vertex_count(),
            level.texel,
            level.edges
        );
    }
    let (state, reports) = synthesize_surface(&pyramid, sample, params, bars)?;
    print_reports(&reports);
    // Timings go to the report only, after the PLY is written.
    write_surface_ply(ply, &pyramid.levels[0], &state, (analysis, mesh_path), params_json)?;
    params_json["prepare_seconds"] = serde_json::json!({"remesh": pyramid.seconds[0], "frames": pyramid.seconds[1], "templates": pyramid.seconds[2]});
    params_json["mesh_levels"] = pyramid
        .levels
        .iter()
        .zip(&pyramid.sources)
        .map(|(l, [remeshing, templates])| serde_json::json!({"vertices": l.mesh.vertex_count(), "texel": l.texel, "edge_mean": l.edges.mean, "edge_min": l.edges.min, "edge_max": l.edges.max, "edge_cv": l.edges.coefficient_of_variation, "remeshing": remeshing, "templates": templates}))
        .collect();
    if marchings.iter().any(Option::is_some) {
        params_json["marching"] = serde_json::json!(marchings);
    }
    Ok((reports, pyramid.levels[0].mesh.vertex_count()))
}

/// Refuses a finest mesh of `vertices` (set by `flag`) too small to synthesize `levels`
/// levels on (each coarser level has a quarter of the vertices and the coarsest needs 4, as
/// `remesh` does; the finest must hold at least one neighbourhood template) or beyond
/// [`MAX_VERTICES`].
fn check_vertices(vertices: usize, flag: &str, levels: usize, neighborhood: usize) -> Result<()> {
    let least = (4usize << (2 * (levels.max(1) - 1)).min(60)).max(neighborhood * neighborhood);
    if vertices < least {
        return Err(usage(format!(
            "{flag} gives a finest mesh of {vertices} vertices; {levels} level(s) with a \
             {neighborhood}x{neighborhood} neighbourhood need at least {least}"
        )));
    }
    if vertices > MAX_VERTICES {
        return Err(usage(format!(
            "{flag} gives a finest mesh of about {vertices} vertices; the limit is {MAX_VERTICES}"
        )));
    }
    Ok(())
}

fn print_reports(reports: &[LevelReport]) {
    for r in reports {
        let on = r.device.as_deref().map(|d| format!(", on {d}")).unwrap_or_default();
        eprintln!(
            "  level {}: {} vertices, {:.2} s, {:.1} candidates, mean best distance {:.4}{on}",
            r.level, r.vertices, r.seconds, r.mean_candidates, r.mean_best_distance
        );
    }
}
