//! `btfsynth render`: CPU ray-traced frames of a surface map, with shadows.

use super::progress::Bars;
use super::shots::{OutputArgs, ShotArgs};
use crate::render::cpu::{render_sequence, RenderOptions};
use crate::render::{Material, SequenceWriter};
use anyhow::Result;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  btfsynth render bunny.ply -o frames/ --frames 24 --light-orbit --format png\n  \
btfsynth render bunny.ply -o still/ --size 1024x1024 --light 30,120 --compare"
)]
pub struct RenderArgs {
    #[command(flatten)]
    shots: ShotArgs,
    /// Output directory: the frames and contact.png.
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    #[command(flatten)]
    out: OutputArgs,
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
    let mut writer = SequenceWriter::new(&args.output, &[args.out.format], args.out.force)?;
    let (scene, analysis) = args.shots.open_surface()?;
    let material = Material::open(&analysis)?;
    let started = Instant::now();
    let options = RenderOptions { mode: args.shots.mode, shadows: !args.no_shadows };
    let per_frame = render_sequence((&scene, &material), &plan, options, args.compare, &mut writer, bars)?;
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
    println!("{}", dir.join("contact.png").display());
    Ok(())
}
