//! `btfsynth convert`: any readable stack to a folder stack or a DFMF `.btf` file.

use super::progress::Bars;
use anyhow::Result;
use btfsynth::btf::colour::ColourModel;
use btfsynth::btf::convert::{open_stack, rotations_of, to_btf, ToBtfOptions};
use btfsynth::btf::ubo2014::Scalar;
use btfsynth::btf::{write_images, Crop, ImageFormat};
use btfsynth::fsutil::{check_not_input, Staged};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args)]
#[command(after_help = "Examples:
  btfsynth convert wool.zip -o wool/                       # UBO2003 archive to EXR folder
  btfsynth convert carpet.btf --crop 0,0,64,64 -o carpet/  # decode a crop of a UBO2014 file
  btfsynth convert pebbles/ -o pebbles.btf --components 32 # folder to DFMF (lossy)")]
pub struct ConvertArgs {
    /// The stack: a folder (btf.json or Bonn/UTIA-named images), a btf.json, one image, a
    /// Bonn .btf file (DFMF, FMF, BDI) or a zip of UBO2003/ATRIUM images.
    input: PathBuf,
    /// Output: a folder (btf.json plus one image per pair) or, with --to btf, a .btf file.
    #[arg(short, long, value_name = "OUT")]
    output: PathBuf,
    /// Output kind (default: btf when OUT ends in .btf, else folder).
    #[arg(long, value_enum)]
    to: Option<Target>,
    /// Image format of a folder output.
    #[arg(long, value_enum, default_value_t = ImageFormat::Exr)]
    format: ImageFormat,
    /// Components kept per colour channel in a .btf, 1 to 1024 (more = closer, larger).
    #[arg(long, default_value_t = 32, value_name = "K", value_parser = super::in_range(1, 1024))]
    components: usize,
    /// Colour model of a .btf: 0 (RGB: the error is what the discarded singular values
    /// predict) or 11 (log-Y, U/Y, V/Y, as the UBO2014 files; suits measured data without
    /// pure black).
    #[arg(long, value_enum, default_value_t = ModelArg::Rgb)]
    colour_model: ModelArg,
    /// Scalars of a .btf: half (2 bytes, as the UBO2014 files) or float (4 bytes).
    #[arg(long, value_enum, default_value_t = Precision::Half)]
    precision: Precision,
    /// Write a .btf without the rotation block (signature !DFMF08FC, which btf-extractor
    /// reads but btflib does not).
    #[arg(long)]
    no_rotation_block: bool,
    /// Convert only this rectangle of the sample: x,y,w,h in pixels (a .btf input decodes
    /// only these texels).
    #[arg(long, value_name = "X,Y,W,H")]
    crop: Option<Crop>,
    /// Seed of the randomized SVD (large stacks).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Replace the output if it exists.
    #[arg(long)]
    force: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Target {
    /// A folder: btf.json plus one EXR or PNG per image.
    Folder,
    /// A Bonn DFMF .btf file (lossy: a truncated SVD per channel).
    Btf,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum ModelArg {
    /// RGB, factorized as is.
    #[value(name = "0", alias = "rgb")]
    Rgb,
    /// log-Y, U/Y, V/Y: luminance in log space, chromaticity as ratios.
    #[value(name = "11", alias = "log-yuv")]
    LogYuv,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Precision {
    Half,
    Float,
}

pub fn run(args: ConvertArgs, bars: &Bars) -> Result<()> {
    let target = args.to.unwrap_or(match has_btf_extension(&args.output) {
        true => Target::Btf,
        false => Target::Folder,
    });
    // A manifest's folder and every image it names are inputs too.
    let stack_inputs = btfsynth::btf::load::input_paths(&args.input);
    let inputs: Vec<&Path> = stack_inputs.iter().map(PathBuf::as_path).collect();
    check_not_input("-o", &args.output, &inputs)?;
    // The output is complete, and checked, before it replaces anything: the last step.
    let staged = match target {
        Target::Folder => Staged::dir(&args.output, args.force)?,
        Target::Btf => Staged::file(&args.output, args.force)?,
    };
    let started = Instant::now();
    let stack = open_stack(&args.input, args.crop, bars)?;
    match target {
        Target::Folder => {
            let source = serde_json::json!({
                "converted_from": args.input.display().to_string(),
                "crop": args.crop.map(|c| [c.x, c.y, c.width, c.height]),
            });
            write_images(stack.as_ref(), staged.path(), args.format, Some(source), false, bars)?;
            let (images, width, height) = (stack.pairs().len(), stack.width(), stack.height());
            let written = staged.commit()?;
            eprintln!(
                "wrote {images} images of {width}x{height} to {} in {:.1} s",
                written.display(),
                started.elapsed().as_secs_f64()
            );
        }
        Target::Btf => {
            check_complete(&args.input, stack.pairs())?;
            let model = match args.colour_model {
                ModelArg::LogYuv => ColourModel::LogYUvOverY,
                ModelArg::Rgb => ColourModel::Rgb,
            };
            let options = ToBtfOptions {
                components: args.components,
                model,
                scalar: match args.precision {
                    Precision::Half => Scalar::F16,
                    Precision::Float => Scalar::F32,
                },
                rotation_block: !args.no_rotation_block,
                rotations: rotations_of(&args.input)?,
                seed: args.seed,
            };
            let decoded = stack.decode_all(bars)?;
            drop(stack);
            // Written and decoded back to measure it under the temporary name.
            let r = to_btf(&decoded, staged.path(), &options, bars)?;
            let written = staged.commit()?;
            eprintln!(
                "wrote {} ({} views × {} lights, {}x{}, {:?} components, colour model {}) in {:.1} s",
                written.display(),
                r.views,
                r.lights,
                r.width,
                r.height,
                r.components,
                model.id(),
                started.elapsed().as_secs_f64()
            );
            eprintln!(
                "  size      {:.1} MiB ({:.1}% of the images as f16)",
                r.file_bytes as f64 / (1u64 << 20) as f64,
                100.0 * r.file_bytes as f64 / (r.images * r.width * r.height * 6).max(1) as f64
            );
            eprintln!("  error     {:.3e} relative (RGB, decoding the file as written)", r.relative_error);
            eprintln!(
                "  predicted {:.3e}, {:.3e}, {:.3e} per channel (discarded singular values, {} space)",
                r.predicted_error[0],
                r.predicted_error[1],
                r.predicted_error[2],
                model.name()
            );
        }
    }
    Ok(())
}

/// A DFMF file holds every view under every light: refuses a stack that lacks a pair
/// before anything is decoded.
fn check_complete(input: &Path, pairs: &[btfsynth::btf::DirectionPair]) -> Result<()> {
    use btfsynth::btf::directions::distinct;
    let views = distinct(pairs.iter().map(|p| p.view)).len();
    let lights = distinct(pairs.iter().map(|p| p.light)).len();
    if views * lights != pairs.len() {
        return Err(btfsynth::Error::format(
            input,
            format!(
                "a DFMF file needs every view × light pair: this stack has {} images, but its {views} views \
                 × {lights} lights make {}",
                pairs.len(),
                views * lights
            ),
        )
        .into());
    }
    Ok(())
}

fn has_btf_extension(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("btf"))
}
