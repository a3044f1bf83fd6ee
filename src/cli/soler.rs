//! `btfsynth synth ANALYSIS MESH --method soler2002`: hierarchical pattern mapping (Soler,
//! Cani and Angelidis 2002), texture coordinates into the sample on the user's own mesh.

use super::progress::Bars;
use super::usage;
use anyhow::{Context, Result};
use btfsynth::analysis::images::SampleImages;
use btfsynth::fsutil::{commit_all, Staged};
use btfsynth::synth::patches::fit::ColourSpace;
use btfsynth::synth::patches::output::{write_uv_map, Provenance};
use btfsynth::synth::patches::prepare::{fit_sample, recorded_params, texels_per_unit, Matching};
use btfsynth::synth::patches::{check_size, map_mesh, SolerParams};
use std::path::Path;
use std::time::Instant;

/// How `synth` puts the sample on the mesh.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// The per-vertex engine (its recipe from --preset): a texton map synthesized on a
    /// remeshed copy of the mesh.
    #[default]
    Vertex,
    /// Soler, Cani and Angelidis 2002, hierarchical pattern mapping: patches of the sample
    /// itself mapped onto the mesh as it is (no remesh, no new texture); the output is the
    /// mesh with texture coordinates at every face corner (.ply or .obj).
    Soler2002,
}

/// The space colours are matched in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum ColourArg {
    /// CIE L*a*b*.
    Lab,
    /// HSV, the paper's.
    Hsv,
    /// Linear RGB.
    Rgb,
    /// The analysis' appearance vectors (for a BTF stack: every image's texel at once).
    Appearance,
}

#[derive(clap::Args, Debug)]
#[command(next_help_heading = "Hierarchical pattern mapping (--method soler2002)")]
pub struct SolerArgs {
    /// Rotations of the sample tried for every patch (evenly spaced; the paper's 19).
    #[arg(long, default_value_t = 19, value_parser = super::at_least(1))]
    rotations: usize,
    /// Width of the band of textured neighbours a patch is matched against, in texels.
    #[arg(long, default_value_t = 6.0, value_parser = super::positive_number)]
    band: f32,
    /// Largest flattening error |r − 1| of one patch (r: surface over flattened area);
    /// a cluster above it is split into smaller ones.
    #[arg(long, default_value_t = 0.1, value_parser = super::positive_number)]
    max_distortion: f32,
    /// Largest output error of one patch: the mean squared difference along its borders
    /// with textured neighbours once fitted and relaxed, as a fraction of two random
    /// texels'; a cluster above it is split. Lower: smaller patches, fainter seams.
    #[arg(long, default_value_t = 0.3, value_parser = super::positive_number)]
    fit_threshold: f32,
    /// The space colours are matched in.
    #[arg(long, value_enum, default_value_t = ColourArg::Lab)]
    colour_space: ColourArg,
    /// Do not relax texture coordinates along patch borders after each fit.
    #[arg(long)]
    no_relax: bool,
    /// Keep patch borders where the cluster hierarchy put them, instead of cutting each
    /// border, once every face is mapped, where the two patches' textures differ least and
    /// moving border faces to the neighbouring patch they continue better.
    #[arg(long)]
    keep_borders: bool,
    /// The face (0-based, in the file's order) the first patch holds: the mapping grows
    /// from there (default: the flattest large cluster).
    #[arg(long, value_name = "N")]
    first_face: Option<usize>,
    /// The first patch's orientation in degrees: the sample's up points this far
    /// counter-clockwise (seen from outside) from the model's +Y axis on the patch
    /// (+X where the patch faces along Y). Default: random.
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    orientation: Option<f32>,
}

/// The `synth` arguments the method uses.
pub struct Common<'a> {
    pub analysis: &'a Path,
    pub mesh: &'a Path,
    /// The output, reserved under a temporary name.
    pub output: Staged,
    pub scale: Option<f32>,
    pub texels_across: Option<f32>,
    pub seed: u64,
    pub report: Option<Staged>,
}

pub fn run(common: Common, args: &SolerArgs, bars: &Bars) -> Result<()> {
    let output = common.output.target().to_path_buf();
    let output = output.as_path();
    let ext = output.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if ext != "ply" && ext != "obj" {
        return Err(usage(format!("-o {}: --method soler2002 writes a .ply or .obj mesh", output.display())));
    }
    let started = Instant::now();
    let manifest = btfsynth::analysis::store::read_manifest(common.analysis)?;
    let tileable = manifest.params.tileable;
    // The sample's size as the analysis records it, for the bounds below.
    let (w, h) = (manifest.width, manifest.height);
    let matching = match args.colour_space {
        ColourArg::Lab => Matching::Colour(ColourSpace::Lab),
        ColourArg::Hsv => Matching::Colour(ColourSpace::Hsv),
        ColourArg::Rgb => Matching::Colour(ColourSpace::Rgb),
        ColourArg::Appearance => Matching::Appearance,
    };
    // The mesh and the size are checked before the sample is read: nothing is worked on
    // that a bound then refuses.
    let mesh = btfsynth::mesh::textured::load_textured(common.mesh)?;
    let texels_per_unit =
        texels_per_unit(&mesh.positions, common.scale, common.texels_across, w, common.mesh)?;
    let params = SolerParams {
        texels_per_unit,
        rotations: args.rotations,
        band: args.band,
        max_flat_error: args.max_distortion,
        max_fit_error: args.fit_threshold,
        colour: matching.colour_space(),
        relax: !args.no_relax,
        move_borders: !args.keep_borders,
        matching: true,
        seed: common.seed,
        first_face: args.first_face,
        orientation: args.orientation,
    };
    params.validate().map_err(super::usage_of)?;
    if let Some(f) = args.first_face.filter(|&f| f >= mesh.triangles.len()) {
        return Err(usage(format!(
            "--first-face {f}: {} has {} faces (0 to {})",
            common.mesh.display(),
            mesh.triangles.len(),
            mesh.triangles.len().saturating_sub(1)
        )));
    }
    let channels = match args.colour_space {
        ColourArg::Appearance => Matching::APPEARANCE_DIMS,
        _ => 3,
    };
    check_size(&mesh.positions, &mesh.triangles, common.mesh, &params, (w, h, channels))
        .map_err(|e| size_error(e, &common))?;
    let images = SampleImages::open(common.analysis)?;
    // The levels are read only for their appearance vectors.
    let finest = match matching {
        Matching::Appearance => Some(btfsynth::synth::Sample::open(common.analysis, 1)?),
        Matching::Colour(_) => None,
    };
    let appearance = finest.as_ref().and_then(|s| s.levels[0].appearance.as_ref());
    let (sample, shown) =
        fit_sample(&images, appearance, matching, tileable, common.analysis).map_err(super::usage_of)?;
    let result = map_mesh(&mesh.positions, &mesh.triangles, common.mesh, sample, &params, bars)?;
    let mut params_json = recorded_params(&params, matching, shown);
    let provenance = Provenance {
        analysis: common.analysis,
        mesh: common.mesh,
        sample: (w, h),
        tileable,
        texel: 1.0 / texels_per_unit,
        params: params_json.clone(),
    };
    write_uv_map((output, common.output.path()), &mesh.positions, &mesh.triangles, &result, &provenance)
        .with_context(|| format!("writing {}", output.display()))?;
    let report = &result.report;
    let [hierarchy, flattening, transforms, mapping] = report.seconds;
    eprintln!(
        "  {} faces ({} without area, carried), {} clusters on {} levels; hierarchy {hierarchy:.2} s, \
         flattening {flattening:.2} s, {} rotations of the {w}x{h} sample {transforms:.2} s, mapping {mapping:.2} s",
        report.faces,
        report.carried_faces,
        report.clusters,
        report.levels.len(),
        params.rotations
    );
    for l in report.levels.iter().filter(|l| l.tried > 0) {
        eprintln!(
            "  level {}: {} clusters, {} to cover, {} mapped ({} started at random, {} faces); \
             split: {} not discs, {} distorted, {} too large, {} poor fits, {} unreached; {:.2} s",
            l.level,
            l.clusters,
            l.tried,
            l.mapped,
            l.started,
            l.faces,
            l.not_disc,
            l.distorted,
            l.too_large,
            l.poor_fit,
            l.unreached,
            l.seconds
        );
    }
    let mut outputs = vec![common.output];
    if let Some(staged) = common.report {
        params_json["seconds"] = serde_json::json!(report.seconds);
        let json = serde_json::json!({"params": params_json, "faces": report.faces, "carried_faces": report.carried_faces,
            "clusters": report.clusters, "levels": report.levels, "seconds": started.elapsed().as_secs_f64()});
        std::fs::write(staged.path(), serde_json::to_string_pretty(&json)?)
            .map_err(|e| btfsynth::Error::io(staged.target(), e))?;
        outputs.push(staged);
    }
    let committed = commit_all(outputs)?;
    eprintln!(
        "wrote {} ({} faces of the original mesh, {:.1} texels per unit) in {:.1} s",
        committed[0].display(),
        mesh.triangles.len(),
        texels_per_unit,
        started.elapsed().as_secs_f64()
    );
    if let Some(report) = committed.get(1) {
        eprintln!("wrote {}", report.display());
    }
    Ok(())
}

/// A refusal of [`check_size`]: a size beyond the limit as a usage error naming the flag
/// that set it (`--texels-across`, also where its default was taken); the file's fault, or
/// the memory budget's (as the vertex engine's), as it is.
fn size_error(e: btfsynth::Error, common: &Common) -> anyhow::Error {
    match e {
        btfsynth::Error::OutOfRange { param: btfsynth::Param::Scale, message, remedy, .. }
            if common.scale.is_none() =>
        {
            let across = common.texels_across.map_or("its default".to_string(), |a| a.to_string());
            let e = btfsynth::Error::OutOfRange {
                param: btfsynth::Param::TexelsAcross,
                value: across,
                message,
                remedy,
            };
            super::usage_of(e)
        }
        e @ btfsynth::Error::OutOfRange { .. } => super::usage_of(e),
        e => e.into(),
    }
}
