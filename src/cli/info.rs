//! `btfsynth info`: say what a path is.

use super::progress::Bars;
use crate::analysis::store::{self, Manifest};
use crate::btf::{load, Btf, Crop, Direction, LoadOptions};
use anyhow::Result;
use std::path::{Path, PathBuf};

/// `writeln!` into a `String` (which cannot fail).
macro_rules! say {
    ($out:expr, $($arg:tt)*) => {{
        use std::fmt::Write as _;
        let _ = writeln!($out, $($arg)*);
    }};
}

#[derive(clap::Args)]
pub struct InfoArgs {
    /// A BTF stack (a directory with btf.json or Bonn/UTIA-named images, a btf.json, one
    /// image, a Bonn .btf file or a zip of UBO2003/ATRIUM images), an analysis directory, or
    /// a mesh (OBJ, OFF, PLY). A .btf file is described from its header unless --crop asks
    /// to decode a part.
    path: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// Describe only this rectangle of the sample: x,y,w,h in pixels.
    #[arg(long, value_name = "X,Y,W,H")]
    crop: Option<Crop>,
}

pub fn run(args: InfoArgs, bars: &Bars) -> Result<()> {
    if args.path.join(store::MANIFEST).is_file() {
        let manifest = store::read_manifest(&args.path)?;
        if args.json {
            super::print(analysis_json(&manifest))?;
        } else {
            super::print(describe_analysis(&args.path, &manifest))?;
        }
        return Ok(());
    }
    if let Some(surface) = surface_header(&args.path)? {
        if args.json {
            super::print(surface)?;
        } else {
            super::print(format_args!(
                "{}: surface texton map of {} vertices, {} faces, from the analysis {}",
                args.path.display(),
                surface["vertices"],
                surface["faces"],
                surface["analysis"].as_str().unwrap_or("")
            ))?;
        }
        return Ok(());
    }
    if crate::btf::ubo2014::is_bonn_file(&args.path) && args.crop.is_none() {
        let file = crate::btf::ubo2014::BonnBtf::open(&args.path)?;
        if args.json {
            super::print(file.describe())?;
        } else {
            super::print(describe_bonn_file(&file))?;
        }
        return Ok(());
    }
    if is_mesh_path(&args.path) {
        let mesh = crate::mesh::load(&args.path)?;
        let summary = crate::mesh::topology::summary(&mesh);
        if args.json {
            super::print(serde_json::json!({
                "kind": "mesh", "path": args.path.display().to_string(), "vertices": summary.vertices,
                "faces": summary.faces, "edges": summary.edges, "boundary_edges": summary.boundary_edges,
                "components": summary.components, "euler_characteristic": summary.euler_characteristic,
            }))?;
        } else {
            super::print(format_args!(
                "{}: triangle mesh (after welding and validation)\n  {summary}",
                args.path.display()
            ))?;
        }
        return Ok(());
    }
    let stack = load(&args.path, &LoadOptions { crop: args.crop }, bars)?;
    if args.json {
        super::print(stack_json(&args.path, &stack))?;
    } else {
        super::print(describe_stack(&args.path, &stack))?;
    }
    Ok(())
}

/// The stack's description as JSON; the keys are documented in docs/commands.md (`info`).
pub fn stack_json(path: &Path, stack: &Btf) -> serde_json::Value {
    let (views, lights) = (stack.views(), stack.lights());
    let mean = mean_rgb(stack);
    serde_json::json!({
        "kind": "stack",
        "path": path.display().to_string(),
        "width": stack.width(),
        "height": stack.height(),
        "images": stack.len(),
        "views": views.len(),
        "lights": lights.len(),
        "complete": views.len() * lights.len() == stack.len(),
        "max_view_theta": max_theta(&views),
        "max_light_theta": max_theta(&lights),
        "mean_rgb": mean,
        "bytes": std::mem::size_of_val(stack.pixels()),
    })
}

fn describe_stack(path: &Path, stack: &Btf) -> String {
    let mut out = String::new();
    let (views, lights) = (stack.views(), stack.lights());
    let complete = if views.len() * lights.len() == stack.len() {
        "every view × light pair"
    } else {
        "a subset of view × light pairs"
    };
    let mean = mean_rgb(stack);
    say!(out, "{}: BTF stack", path.display());
    say!(out, "  size    {} x {} pixels", stack.width(), stack.height());
    say!(out, "  images  {} ({complete})", stack.len());
    say!(out, "  views   {} distinct, θ up to {}°", views.len(), max_theta(&views));
    say!(out, "  lights  {} distinct, θ up to {}°", lights.len(), max_theta(&lights));
    say!(out, "  mean    linear RGB ({:.3}, {:.3}, {:.3})", mean[0], mean[1], mean[2]);
    say!(out, "  memory  {:.1} MiB as f16", std::mem::size_of_val(stack.pixels()) as f64 / (1 << 20) as f64);
    out.trim_end().to_string()
}

/// A Bonn `.btf` file from its header alone (nothing is decoded).
fn describe_bonn_file(file: &crate::btf::ubo2014::BonnBtf) -> String {
    let mut out = String::new();
    let d = file.describe();
    let (views, lights) = file.views_and_lights();
    say!(
        out,
        "{}: Bonn {} BTF file ({})",
        file.path().display(),
        d["format"].as_str().unwrap_or(""),
        file.signature()
    );
    say!(
        out,
        "  size    {} x {} pixels, {} images ({views} views × {lights} lights)",
        file.width(),
        file.height(),
        file.pairs().len()
    );
    if let Some(components) = d["components"].as_array() {
        let k: Vec<String> = components.iter().map(|c| c.to_string()).collect();
        say!(
            out,
            "  factors {} components per channel, {} scalars",
            k.join(", "),
            d["scalar"].as_str().unwrap_or("")
        );
        say!(
            out,
            "  colour  model {} ({})",
            d["colour_model"]["id"],
            d["colour_model"]["name"].as_str().unwrap_or("")
        );
    }
    let meta = file.meta();
    say!(
        out,
        "  header  version {}, setup {:?}, sensor {:?}, light {:?}",
        meta.version,
        meta.measurement_setup,
        meta.image_sensor,
        meta.light_source
    );
    say!(
        out,
        "  file    {:.1} MiB; decoded whole it would take {:.1} MiB as f16",
        d["file_bytes"].as_f64().unwrap_or(0.0) / (1u64 << 20) as f64,
        (file.pairs().len() * file.width() * file.height() * 6) as f64 / (1u64 << 20) as f64
    );
    out.trim_end().to_string()
}

fn max_theta(dirs: &[Direction]) -> f32 {
    dirs.iter().map(|d| d.theta).fold(0.0, f32::max)
}

fn mean_rgb(stack: &Btf) -> [f64; 3] {
    let mut sum = [0.0f64; 3];
    for px in stack.pixels().chunks_exact(3) {
        for c in 0..3 {
            sum[c] += px[c].to_f64();
        }
    }
    let n = (stack.pixels().len() / 3).max(1) as f64;
    sum.map(|s| (s / n * 1e4).round() / 1e4)
}

/// The analysis' description as JSON; the keys are documented in docs/commands.md (`info`).
pub fn analysis_json(m: &Manifest) -> serde_json::Value {
    let levels: Vec<serde_json::Value> = m
        .levels
        .iter()
        .map(|l| serde_json::json!({"width": l.width, "height": l.height, "textons": l.textons, "embedding_dims": l.embedding_dims}))
        .collect();
    serde_json::json!({
        "kind": "analysis",
        "levels": levels,
        "k": m.k,
        "selected": m.selected.len(),
        "images": m.images,
        "width": m.width,
        "height": m.height,
        "source": m.source.path,
        "fingerprint": m.source.fingerprint,
    })
}

fn describe_analysis(path: &Path, m: &Manifest) -> String {
    let mut out = String::new();
    say!(out, "{}: texton analysis of {}", path.display(), m.source.path);
    say!(
        out,
        "  sample  {} x {} pixels, {} images, {} selected",
        m.width,
        m.height,
        m.images,
        m.selected.len()
    );
    for (i, l) in m.levels.iter().enumerate() {
        say!(
            out,
            "  level {i} {} x {}: {} textons, embedding d = {}, basis {} images ({:.2}% of variance)",
            l.width,
            l.height,
            l.textons,
            l.embedding_dims,
            l.basis_rank,
            100.0 * l.basis_energy
        );
    }
    say!(
        out,
        "  kNN     k = {}, {}x{} neighbourhoods{}",
        m.k,
        m.params.neighborhood,
        m.params.neighborhood,
        if m.params.tileable { ", tileable" } else { "" }
    );
    out.trim_end().to_string()
}

fn is_mesh_path(path: &Path) -> bool {
    path.is_file()
        && path.extension().is_some_and(|e| ["obj", "off", "ply"].iter().any(|m| e.eq_ignore_ascii_case(m)))
}

/// The description of a PLY written by `synth` (recognised by its header comment), or None.
fn surface_header(path: &Path) -> Result<Option<serde_json::Value>> {
    if !path.is_file() || !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("ply")) {
        return Ok(None);
    }
    let bytes = std::fs::read(path).map_err(|e| crate::Error::io(path, e))?;
    let end = bytes.windows(10).position(|w| w == b"end_header").unwrap_or(bytes.len().min(4096));
    let header = String::from_utf8_lossy(&bytes[..end]);
    if !header.lines().any(|l| l.trim() == "comment btfsynth surface") {
        return Ok(None);
    }
    let field = |prefix: &str| header.lines().find_map(|l| l.strip_prefix(prefix)).map(str::trim);
    let count =
        |name: &str| field(&format!("element {name} ")).and_then(|n| n.parse::<u64>().ok()).unwrap_or(0);
    let params: serde_json::Value =
        field("comment params ").and_then(|p| serde_json::from_str(p).ok()).unwrap_or_default();
    Ok(Some(serde_json::json!({
        "kind": "surface",
        "path": path.display().to_string(),
        "vertices": count("vertex"),
        "faces": count("face"),
        "analysis": field("comment analysis ").unwrap_or(""),
        "analysis_absolute": field("comment analysis-absolute ").unwrap_or(""),
        "analysis_fingerprint": field("comment analysis-fingerprint ").unwrap_or(""),
        "mesh": field("comment mesh ").unwrap_or(""),
        "params": params,
    })))
}
