//! `btfsynth relight`: the sample itself, rectified, under any view and light.

use super::progress::Bars;
use super::shots::LightingArgs;
use anyhow::Result;
use btfsynth::btf::Direction;
use btfsynth::render::ambient::AmbientLight;
use btfsynth::render::relight::relight;
use btfsynth::render::{FrameFormat, Material};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
#[command(after_help = "Angles are in the sample's own frame (Bonn convention): θ from the normal, \
φ from the tangent s (image columns) towards t (up the image). For --env, the sample lies flat \
facing +Y with s along +X.\n\nExamples:\n  btfsynth relight analysis/ --view 30,90 --light 45,0 -o novel.exr\n  \
btfsynth relight stack/ --view 0,0 --light 82,45 -o grazing.png\n  \
btfsynth relight stack/ --view 15,0 --env sky --light 40,200 -o sky.png")]
pub struct RelightArgs {
    /// An analysis directory or a BTF stack (a directory, a btf.json or one image).
    input: PathBuf,
    /// View direction θ,φ in degrees, θ from 0 to 90.
    #[arg(long, value_name = "θ,φ", value_parser = parse_local)]
    view: (f32, f32),
    /// Directional light θ,φ in degrees, θ from 0 to 90 [default: none, with --env].
    #[arg(long, value_name = "θ,φ", value_parser = parse_local)]
    light: Option<(f32, f32)>,
    #[command(flatten)]
    lighting: LightingArgs,
    /// The image to write: .png (8-bit sRGB) or .exr (linear f32).
    #[arg(short, long, value_name = "OUT.png|OUT.exr")]
    output: PathBuf,
    /// Replace the output if it exists.
    #[arg(long)]
    force: bool,
}

/// θ,φ with θ in [0, 90].
fn parse_local(s: &str) -> Result<(f32, f32), String> {
    let angles = super::shots::parse_angles(s)?;
    if angles.0 > 90.0 {
        return Err(format!("'{s}': θ is at most 90° (the sample's horizon)"));
    }
    Ok(angles)
}

fn format_of(path: &Path) -> Result<FrameFormat> {
    match path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).as_deref() {
        Some("png") => Ok(FrameFormat::Png),
        Some("exr") => Ok(FrameFormat::Exr),
        _ => Err(super::usage(format!("-o {}: the output is a .png or .exr file", path.display()))),
    }
}

pub fn run(args: RelightArgs, bars: &Bars) -> Result<()> {
    let format = format_of(&args.output)?;
    let (sun, environment) = args.lighting.lighting()?;
    let sun_direction = match (args.light, sun > 0.0, &environment) {
        (Some(l), _, _) => Some(l),
        (None, true, Some(_)) => {
            return Err(super::usage("--env sky puts its sun along --light: give --light θ,φ"))
        }
        (None, _, None) => {
            return Err(super::usage("nothing lights the sample: give --light θ,φ, --env or --ambient"))
        }
        (None, _, Some(_)) => None,
    };
    let env_file = args.lighting.env_file();
    // A stack's manifest folder and every image it names are inputs too.
    let stack_inputs = btfsynth::btf::load::input_paths(&args.input);
    let inputs: Vec<&Path> = stack_inputs.iter().map(PathBuf::as_path).chain(env_file).collect();
    btfsynth::fsutil::check_not_input("-o", &args.output, &inputs)?;
    let staged = btfsynth::fsutil::Staged::file(&args.output, args.force)?;
    let material = Material::open_any(&args.input, bars)?;
    let view = Direction::new(args.view.0, args.view.1)?.unit();
    let light = match sun_direction {
        Some((theta, phi)) => Some((Direction::new(theta, phi)?.unit(), 1.0)),
        None => None,
    };
    let ambient = environment.map(|e| AmbientLight::new(&material, e));
    let frame = relight(&material, view, light, ambient.as_ref());
    frame.save(staged.path(), format)?;
    let written = staged.commit()?;
    eprintln!(
        "relit the {}x{} sample ({} images) seen from θ={}° φ={}°",
        material.width(),
        material.height(),
        material.len(),
        args.view.0,
        args.view.1
    );
    super::print(written.display())?;
    Ok(())
}
