//! `btfsynth view`: the wgpu renderer, in a window or (`--headless`) offscreen into frames.

use super::progress::Bars;
use super::shots::{LightingArgs, OutputArgs, ShotArgs};
use anyhow::Result;
use btfsynth::analysis::store;
use btfsynth::progress::Progress;
use btfsynth::render::gpu::factors::ATLAS_LIMIT;
use btfsynth::render::gpu::{Display, GpuLighting, GpuRenderer, GpuSample, Upload};
use btfsynth::render::material::decode_limit;
use btfsynth::render::{viewer, Material, SequenceWriter};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args)]
#[command(
    override_usage = "btfsynth view [OPTIONS] <SURFACE>\n       \
btfsynth view [OPTIONS] --headless -o <DIR> <SURFACE>",
    after_help = "Examples:\n  btfsynth view bunny.ply\n  \
btfsynth view bunny.ply --headless -o frames/ --frames 24 --size 1024x1024 --format png\n\n\
Without --headless a window opens; its keys are printed when it does. The window shows the frame \
rate, the light and the mode; S saves the frame into --save-dir.\n\n\
The GPU memory the scene needs is counted first: a scene over the limit (BTFSYNTH_GPU_MEMORY, e.g. 6G; \
by default btfsynth's memory budget on a software adapter, else at most 4 GiB) or over the adapter's \
texture and buffer limits is refused with one line."
)]
pub struct ViewArgs {
    #[command(flatten)]
    shots: ShotArgs,
    /// Output directory of --headless: the frames and contact.png.
    #[arg(short, long, value_name = "DIR", required_if_eq("headless", "true"))]
    output: Option<PathBuf>,
    #[command(flatten)]
    lighting: LightingArgs,
    #[command(flatten)]
    out: OutputArgs,
    /// Render the shots offscreen into -o DIR (the same light orbit as `render`) instead of
    /// opening a window; prints the mean frame time and the GPU used.
    #[arg(long)]
    headless: bool,
    /// What the surface shows (headless; in the window, keys B and T switch).
    #[arg(long, value_enum, default_value_t = DisplayArg::Btf)]
    display: DisplayArg,
    /// No shadow map (every point facing the light is lit), and no shadows of the
    /// environment's light cells.
    #[arg(long)]
    no_shadows: bool,
    /// Where the window's S key saves frames (view-0000.png, view-0001.png, …).
    #[arg(long, value_name = "DIR", default_value = ".")]
    save_dir: PathBuf,
    /// What of the sample goes to the GPU: `images` (an atlas of every image: one read per
    /// value), `factors` (an analysis that stores its sample as factors, e.g. of a .btf file:
    /// the shader computes each value, a K-term product per channel), or `auto` (the images
    /// while their atlas takes at most 256 MiB, else the factors where there are any).
    #[arg(long, value_enum, default_value_t = UploadArg::Auto)]
    upload: UploadArg,
}

/// `--upload` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum UploadArg {
    /// The images while their atlas is at most 256 MiB, else the factors.
    Auto,
    /// An atlas of every image.
    Images,
    /// The sample's factors.
    Factors,
}

impl From<UploadArg> for Upload {
    fn from(u: UploadArg) -> Upload {
        match u {
            UploadArg::Auto => Upload::Auto,
            UploadArg::Images => Upload::Images,
            UploadArg::Factors => Upload::Factors,
        }
    }
}

/// The sample of `analysis` for the GPU: its material, and the factors of one stored as
/// factors that the material decoded when opened (a factored material keeps its own), read
/// even for `--upload images` so that a refusal can point to them.
fn open_sample(analysis: &Path, upload: Upload) -> Result<GpuSample> {
    // Decoded only where `auto` would upload the atlas (its half floats take 8 bytes a
    // texel and image, the decoded values 12): a larger sample goes up as factors, and
    // decoding it on the CPU first (up to the renderer's 2 GiB) would be wasted.
    let atlas_sized = ATLAS_LIMIT / 8 * 12;
    let material = Material::open_within(analysis, decode_limit()?.min(atlas_sized))?;
    let mut sample = GpuSample { material, factors: None, upload };
    if sample.factors().is_none() {
        let manifest = store::read_manifest(analysis)?;
        if manifest.sample.is_some() {
            sample.factors = Some(store::read_factors(analysis, &manifest)?);
        }
    }
    Ok(sample)
}

/// `--display` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum DisplayArg {
    /// The BTF, 4 × 4 sample images blended per view and light.
    Btf,
    /// The sample's first image as a flat texture, times n·l.
    FirstImage,
    /// A colour per texton label, times n·l.
    Textons,
}

impl From<DisplayArg> for Display {
    fn from(d: DisplayArg) -> Display {
        match d {
            DisplayArg::Btf => Display::Btf,
            DisplayArg::FirstImage => Display::FirstImage,
            DisplayArg::Textons => Display::TextonFalseColour,
        }
    }
}

/// Some Vulkan drivers try to reach a Wayland compositor while listing devices, and
/// libwayland then prints "error: XDG_RUNTIME_DIR is invalid or not set" although nothing is
/// wrong. Offscreen rendering needs no display, and a window without WAYLAND_DISPLAY opens
/// on X11: with no session variables set, point the probe at a directory that holds no
/// compositor socket, so it fails quietly.
fn quiet_wayland_probe() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() && std::env::var_os("WAYLAND_DISPLAY").is_none() {
        std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir().join("btfsynth-no-display"));
    }
}

pub fn run(args: ViewArgs, bars: &Bars) -> Result<()> {
    let plan = args.shots.plan();
    let (sun, environment) = args.lighting.lighting()?;
    let lighting = GpuLighting { sun, environment, shadows: !args.no_shadows };
    quiet_wayland_probe();
    if !args.headless {
        if !args.save_dir.is_dir() {
            anyhow::bail!("--save-dir {}: not a directory", args.save_dir.display());
        }
        let (scene, analysis) = args.shots.open_surface()?;
        let sample = open_sample(&analysis, args.upload.into())?;
        let options = viewer::ViewerOptions { mode: args.shots.mode, lighting, save_dir: args.save_dir };
        return Ok(viewer::run(scene, sample, &plan, options)?);
    }
    let Some(dir) = &args.output else {
        return Err(super::usage("--headless renders into a directory: give -o DIR"));
    };
    args.shots.check_output(dir, &args.lighting, None)?;
    let mut writer = SequenceWriter::new(dir, &[args.out.format], args.out.force)?;
    let (scene, analysis) = args.shots.open_surface()?;
    args.shots.check_output(dir, &args.lighting, Some(&analysis))?;
    let sample = open_sample(&analysis, args.upload.into())?;
    let vertices = scene.mesh.vertex_count();
    let mut renderer = GpuRenderer::headless(scene, sample, plan.size, lighting)?;
    let shots = plan.shots(renderer.scene().mesh.bounds());
    bars.start("rendering", shots.len() as u64);
    let mut seconds = 0.0;
    for shot in &shots {
        let started = Instant::now();
        let frame = renderer.render(shot, args.shots.mode, args.display.into())?;
        seconds += started.elapsed().as_secs_f64();
        writer.push(&frame)?;
        bars.advance(1);
    }
    bars.finish();
    let dir = writer.finish()?;
    eprintln!(
        "rendered {} frame(s) of {}x{} on {} ({vertices} vertices, {} mode, {} samples per pixel, {}): \
         {:.1} ms per frame",
        shots.len(),
        plan.size.0,
        plan.size.1,
        renderer.adapter_name(),
        args.shots.mode_name(),
        renderer.target_format().samples,
        renderer.values().describe(),
        1e3 * seconds / shots.len() as f64
    );
    super::print(dir.join("contact.png").display())
}
