//! `btfsynth render`: CPU ray-traced frames of a surface map, with shadows.

use super::progress::Bars;
use super::shots::{LightingArgs, OutputArgs, ShotArgs};
use crate::render::cpu::{render_sequence, valid_spp, RenderOptions};
use crate::render::{Material, SequenceWriter};
use anyhow::Result;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  btfsynth render bunny.ply -o frames/ --frames 24 --light-orbit --format png\n  \
btfsynth render bunny.ply -o still/ --size 1024x1024 --light 30,120 --compare\n  \
btfsynth render bunny.ply -o sky/ --env sky --frames 8\n  \
btfsynth render bunny.ply -o studio/ --env studio.hdr --spp 16"
)]
pub struct RenderArgs {
    #[command(flatten)]
    shots: ShotArgs,
    /// Output directory: the frames and contact.png.
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    #[command(flatten)]
    lighting: LightingArgs,
    #[command(flatten)]
    out: OutputArgs,
    /// Rays per pixel, a square number (1, 4, 9, 16, …): stratified and jittered, each
    /// with its own shadow ray.
    #[arg(long, value_name = "N", default_value_t = 4, value_parser = parse_spp)]
    spp: u32,
    /// Trace no shadow rays (every point facing the light is lit).
    #[arg(long)]
    no_shadows: bool,
    /// Put each frame beside the sample BTF on a flat quad, seen from the same direction
    /// under the same light (as Tong et al. compare sample and synthesis).
    #[arg(long)]
    compare: bool,
}

pub fn run(args: RenderArgs, bars: &Bars) -> Result<()> {
    let plan = args.shots.plan();
    let (sun, environment) = args.lighting.lighting()?;
    args.shots.check_output(&args.output, &args.lighting, None)?;
    let mut writer = SequenceWriter::new(&args.output, &[args.out.format], args.out.force)?;
    let (scene, analysis) = args.shots.open_surface()?;
    args.shots.check_output(&args.output, &args.lighting, Some(&analysis))?;
    let material = Material::open(&analysis)?;
    let started = Instant::now();
    let options = RenderOptions { mode: args.shots.mode, shadows: !args.no_shadows, spp: args.spp, sun };
    let per_frame = render_sequence(
        (&scene, &material),
        &plan,
        options,
        environment.as_ref(),
        args.compare,
        &mut writer,
        bars,
    )?;
    let dir = writer.finish()?;
    eprintln!(
        "rendered {} frame(s) of {}x{} ({} vertices, {} mode): {:.3} s per frame, {:.2} s in all",
        plan.frames,
        plan.size.0,
        plan.size.1,
        scene.mesh.vertex_count(),
        args.shots.mode_name(),
        per_frame,
        started.elapsed().as_secs_f64()
    );
    super::print(dir.join("contact.png").display())
}

/// `--spp`: a square number of samples per pixel.
fn parse_spp(s: &str) -> Result<u32, String> {
    match s.trim().parse::<u32>() {
        Ok(n) if valid_spp(n) => Ok(n),
        _ => Err(format!(
            "'{s}': expected a square number of samples per pixel from 1 to 1024 (1, 4, 9, 16, …)"
        )),
    }
}
