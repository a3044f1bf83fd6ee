//! `btfsynth eval`: quality of a synthesized result against its sample.

use super::hints::with_force_hint;
use super::progress::Bars;
use anyhow::{bail, Result};
use btfsynth::analysis::store::verify_fingerprint;
use btfsynth::eval::report::{
    evaluate_model, evaluate_picture, evaluate_plane, evaluate_surface, evaluate_surface_export,
    evaluate_uv_map, Evaluation,
};
use btfsynth::synth::patches::output::{read_uv_map, uv_map_comments};
use btfsynth::synth::plane::MANIFEST;
use btfsynth::synth::surface_map::{read_surface_ply, ANALYSIS_FINGERPRINT_KEY};
use std::path::PathBuf;

#[derive(clap::Args)]
#[command(after_help = "What the numbers mean (lower is better unless said):
  patch energy   mean squared difference (sRGB 0-1, per value) of every 4th 7x7 patch of the
                 result to its nearest 7x7 patch of the sample; 'coarse' on both halved
  colour chi2    colour-histogram distance, 0 identical .. 1 disjoint
  contrast       luma standard deviation over the sample's: 1 is right, below 1 washed out
  collapse       share of the output copied from the most-used 1% of sample texels
                 (a tiled copy: 0.01; above 0.05 a few texels are stamped everywhere)
  smear          share of adjacent output pairs copying the very same texel (streaks; want 0)
  copy           largest contiguously copied patch over the sample's area (about 1 or more:
                 the sample was copied whole, a tiling rather than a synthesis)
  coherence      mean output vertices per contiguously copied patch
  repetition     the same sample places recurring at one offset (0: none; a tiling of a piece
                 of the sample 0.4-1; the peers score 0.01-0.03 on organic photographs); on a
                 model, from its coordinates, offsets in texels along each point's frame
  unused, use spread   share of the sample no part of the result comes from; how unevenly
                 the sample is used (both depend on the result's size)
  texton chi2, texton energy   Tong's texton-space figures (histogram, distance through Γ)
  texture (an exported .glb/.gltf, or a surface map exported in memory): its base colour on
    the surface against the sample resampled to the same texels per sample texel:
    smeared      share of 12x12-texel windows flatter than the sample's flattest 5%
                 (the sample itself: 0.05; want no more)
    detail       high-frequency (Laplacian) energy over the sample's: 1 is right
    contrast     luma standard deviation over the sample's: 1 is right
    colour       histogram chi2, and the distance between mean colours (sRGB 0-1)

Examples:
  btfsynth eval stone.analysis/ plane/            a plane result (synth --plane)
  btfsynth eval stone.analysis/ bunny.ply         a surface map
  btfsynth eval stone.analysis/ bunny-uv.ply      texture coordinates (synth --method soler2002)
  btfsynth eval stone.analysis/ bunny.glb         an exported model (btfsynth export)
  btfsynth eval stone.analysis/ other-tool.png    any picture, e.g. another synthesizer's")]
pub struct EvalArgs {
    /// The analysis directory the result was synthesized from (or should look like).
    analysis: PathBuf,
    /// A surface map (the PLY from `synth ANALYSIS MESH`), a texture-mapped mesh (from
    /// `synth --method soler2002`), a plane result directory, or a
    /// PNG/JPEG picture (image-space measures only), or an exported model (.glb/.gltf: its
    /// texture on the surface).
    result: PathBuf,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
    /// Evaluate against the analysis even if its fingerprint differs from the one the
    /// result was synthesized from.
    #[arg(long)]
    force_analysis: bool,
    /// A surface map: leave out the figures of its texture as `export` would bake it
    /// (which reads the original mesh and bakes an atlas in memory).
    #[arg(long)]
    no_texture: bool,
    /// An exported model that does not record it (another tool's): one sample texel in
    /// model units on its surface.
    #[arg(long, value_name = "UNITS")]
    sample_texel: Option<f32>,
}

pub fn run(args: EvalArgs, _bars: &Bars) -> Result<()> {
    if let Some(t) = args.sample_texel.filter(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(super::usage(format!("--sample-texel must be a positive length, not {t}")));
    }
    let evaluation = if args.result.join(MANIFEST).is_file() {
        check_analysis(&args, plane_fingerprint(&args.result).as_deref())?;
        evaluate_plane(&args.analysis, &args.result)?
    } else if args.result.is_file() && uv_map_comments(&args.result).is_some() {
        let map = read_uv_map(&args.result)?;
        check_analysis(&args, map.comment(ANALYSIS_FINGERPRINT_KEY))?;
        evaluate_uv_map(&args.analysis, &map)?
    } else if is_model(&args.result) {
        evaluate_model(&args.analysis, &args.result, args.sample_texel)?
    } else if is_picture(&args.result) {
        evaluate_picture(&args.analysis, &args.result)?
    } else if has_extension(&args.result, &["exr"]) {
        // Most likely a frame `render` or `view` wrote: named as such, not as a damaged PLY.
        bail!(
            "{}: an EXR image (a rendered frame?), not a result eval measures: {EXPECTED}",
            args.result.display()
        );
    } else if args.result.is_file() {
        let map = read_surface_ply(&args.result)?;
        check_analysis(&args, map.comment(ANALYSIS_FINGERPRINT_KEY))?;
        let neighborhood = map
            .comments
            .iter()
            .find_map(|c| c.strip_prefix("params "))
            .and_then(|p| serde_json::from_str::<serde_json::Value>(p).ok())
            .and_then(|p| p["neighborhood"].as_u64())
            .unwrap_or(5) as usize;
        let mut evaluation = evaluate_surface(&args.analysis, &map, neighborhood, &args.result)?;
        if !args.no_texture {
            evaluation.texture = evaluate_surface_export(&args.analysis, &args.result)?.texture;
        }
        evaluation
    } else {
        bail!("{}: not a result: {EXPECTED}", args.result.display());
    };
    if args.json {
        super::print(serde_json::to_string(&evaluation)?)?;
    } else {
        super::print(table(&args, &evaluation))?;
    }
    Ok(())
}

/// What `eval` measures, for messages about what it does not.
const EXPECTED: &str =
    "expected a plane directory, a surface map PLY, a soler2002 uvmap (.ply/.obj), an exported .glb/.gltf or a PNG/JPEG picture";

/// Refuses an analysis of another sample than the one the result records (`recorded`),
/// unless `--force-analysis`. A picture records none.
fn check_analysis(args: &EvalArgs, recorded: Option<&str>) -> Result<()> {
    if args.force_analysis {
        return Ok(());
    }
    verify_fingerprint(&args.analysis, &args.result, recorded).map_err(with_force_hint)
}

/// The analysis fingerprint a plane result's manifest records, if any.
fn plane_fingerprint(dir: &std::path::Path) -> Option<String> {
    let text = std::fs::read_to_string(dir.join(MANIFEST)).ok()?;
    let manifest: serde_json::Value = serde_json::from_str(&text).ok()?;
    manifest["analysis_fingerprint"].as_str().map(str::to_string)
}

fn is_model(path: &std::path::Path) -> bool {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    path.is_file() && matches!(ext.as_deref(), Some("glb" | "gltf"))
}

fn is_picture(path: &std::path::Path) -> bool {
    path.is_file() && has_extension(path, &["png", "jpg", "jpeg"])
}

/// Whether `path` ends in one of `extensions` (lower case; the path's in any case).
fn has_extension(path: &std::path::Path, extensions: &[&str]) -> bool {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    ext.is_some_and(|e| extensions.contains(&e.as_str()))
}

fn table(args: &EvalArgs, e: &Evaluation) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{}: {} of {} vertices, against {}",
        args.result.display(),
        e.kind,
        e.vertices,
        args.analysis.display()
    );
    for p in &e.probes {
        let q = &p.quality;
        let _ = writeln!(out,
            "  {:<10} (view {:.0},{:.0} light {:.0},{:.0}): patch energy {:.5} (coarse {:.5}), colour chi2 {:.4}, contrast {:.3}",
            p.probe.name, p.probe.view[0], p.probe.view[1], p.probe.light[0], p.probe.light[1],
            q.patch_energy, q.patch_energy_coarse, q.colour_chi2, q.contrast
        );
        let r = &q.repetition;
        if r.repetition.is_finite() {
            // A surface's offsets are texels along each vertex's frame, not pixels.
            let unit = if matches!(e.kind, "surface" | "uvmap") { "texels along the frame" } else { "px" };
            let _ = writeln!(
                out,
                "    repetition {:.3} (strongest at {},{} {unit}), unused sample {:.3}, use spread {:.2}",
                r.repetition, r.repeat_offset[0], r.repeat_offset[1], r.unused, r.use_spread
            );
        }
        if let Some(seam) = p.wrap_seam_energy {
            let _ = writeln!(out, "    across the wrap edge (tileable output): patch energy {seam:.5}");
        }
    }
    if let Some(c) = &e.coords {
        let _ = writeln!(
            out,
            "  coordinates: collapse {:.4}, smear {:.4}, copy {:.3}, coherence {:.1}",
            c.collapse, c.smear, c.copy, c.coherence
        );
    }
    if let Some(t) = &e.textons {
        let _ = writeln!(out, "  textons: chi2 {:.4}, energy {:.4}", t.chi2, t.energy);
    }
    if let Some(s) = &e.seams {
        let _ = writeln!(
            out,
            "  seams: patch energy across patch borders {:.5} ({} windows), inside patches {:.5} ({} windows), ratio {:.2}",
            s.border,
            s.border_windows,
            s.interior,
            s.interior_windows,
            s.border / s.interior
        );
    }
    if let Some(t) = &e.texture {
        let _ = writeln!(
            out,
            "  texture on the surface ({:.2} texels per sample texel, {} windows): smeared {:.3} (sample 0.05), detail {:.3}, contrast {:.3}, colour chi2 {:.4}, colour shift {:.4}, patch energy {:.5}",
            t.scale, t.windows, t.smeared, t.detail, t.contrast, t.colour_chi2, t.colour_shift, t.patch_energy
        );
    }
    out.trim_end().to_string()
}
