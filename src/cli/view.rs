//! `btfsynth view`: the wgpu renderer, in a window or (`--headless`) offscreen into frames.

use super::progress::Bars;
use super::shots::{OutputArgs, ShotArgs};
use crate::progress::Progress;
use crate::render::gpu::{Display, GpuRenderer};
use crate::render::{viewer, Material, SequenceWriter};
use anyhow::Result;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
#[command(
    override_usage = "btfsynth view [OPTIONS] <SURFACE>\n       \
btfsynth view [OPTIONS] --headless -o <DIR> <SURFACE>",
    after_help = "Examples:\n  btfsynth view bunny.ply\n  \
btfsynth view bunny.ply --headless -o frames/ --frames 24 --size 1024x1024 --format png\n\n\
Without --headless a window opens; its keys are printed when it does."
)]
pub struct ViewArgs {
    #[command(flatten)]
    shots: ShotArgs,
    /// Output directory of --headless: the frames and contact.png.
    #[arg(short, long, value_name = "DIR", required_if_eq("headless", "true"))]
    output: Option<PathBuf>,
    #[command(flatten)]
    out: OutputArgs,
    /// Render the shots offscreen into -o DIR (the same light orbit as `render`) instead of
    /// opening a window; prints the mean frame time and the GPU used.
    #[arg(long)]
    headless: bool,
    /// What the surface shows (headless; in the window, keys B and T switch).
    #[arg(long, value_enum, default_value_t = DisplayArg::Btf)]
    display: DisplayArg,
    /// No shadow map (every point facing the light is lit).
    #[arg(long)]
    no_shadows: bool,
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
/// wrong. Offscreen rendering needs no display: with no session variables set, point the
/// probe at a directory that holds no compositor socket, so it fails quietly.
fn quiet_wayland_probe() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() && std::env::var_os("WAYLAND_DISPLAY").is_none() {
        std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir().join("btfsynth-no-display"));
    }
}

pub fn run(args: ViewArgs, bars: &Bars) -> Result<()> {
    let plan = args.shots.plan();
    if !args.headless {
        let (scene, analysis) = args.shots.open_surface()?;
        let material = Material::open(&analysis)?;
        return Ok(viewer::run(scene, material, &plan, args.shots.mode)?);
    }
    let Some(dir) = &args.output else {
        return Err(super::usage("--headless renders into a directory: give -o DIR"));
    };
    quiet_wayland_probe();
    let mut writer = SequenceWriter::new(dir, &[args.out.format], args.out.force)?;
    let (scene, analysis) = args.shots.open_surface()?;
    let material = Material::open(&analysis)?;
    let vertices = scene.mesh.vertex_count();
    let mut renderer = GpuRenderer::headless(scene, material, plan.size)?;
    renderer.shadows = !args.no_shadows;
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
        "rendered {} frame(s) of {}x{} on {} ({vertices} vertices, {} mode): {:.1} ms per frame",
        shots.len(),
        plan.size.0,
        plan.size.1,
        renderer.adapter_name(),
        args.shots.mode_name(),
        1e3 * seconds / shots.len() as f64
    );
    println!("{}", dir.join("contact.png").display());
    Ok(())
}
