//! Argument parsing, progress display and error printing: the only terminal code.

mod analyze;
mod demo;
mod eval;
mod gen;
mod info;
mod progress;
mod relight;
mod remesh;
mod render;
mod shots;
mod synth;
mod view;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// btfsynth: put real-world materials on 3D models.
///
/// A BTF (bidirectional texture function) is a stack of photos of one material patch
/// under many view and light directions. btfsynth reads, generates, analyses and
/// synthesizes BTFs on triangle meshes (Tong et al., SIGGRAPH 2002).
#[derive(Parser)]
#[command(name = "btfsynth", version, about, long_about, propagate_version = true)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Hide progress bars.
    #[arg(short, long, global = true)]
    quiet: bool,
    /// More log output (-v: info, -vv: debug); RUST_LOG overrides.
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
    /// Worker threads (default: one per core).
    #[arg(long, global = true, value_name = "N")]
    threads: Option<usize>,
}

#[derive(Subcommand)]
enum Command {
    /// Ray-trace a synthetic BTF stack from a procedural height field.
    Gen(gen::GenArgs),
    /// Texton analysis of a stack: filter bank, textons, Γ, pyramid, kNN lists (Tong §4, §5.2).
    Analyze(analyze::AnalyzeArgs),
    /// Synthesize a surface texton map on a mesh (or, with --plane, on a regular grid).
    Synth(synth::SynthArgs),
    /// Quality of a synthesized result: texton χ², energy, coherence.
    Eval(eval::EvalArgs),
    /// Remesh a triangle mesh to near-uniform edge length (OBJ/OFF/PLY in, binary PLY out).
    Remesh(remesh::RemeshArgs),
    /// Render a surface map on the CPU: ray-traced frames with shadows (EXR or PNG) and a contact sheet.
    Render(render::RenderArgs),
    /// Render a surface map on the GPU (wgpu): an interactive window, or --headless frames.
    View(view::ViewArgs),
    /// The sample itself, rectified, under any view and light (or environment), measured or not.
    Relight(relight::RelightArgs),
    /// Describe a path: a BTF stack (manifest, Bonn/UTIA images or a single image) or an analysis.
    Info(info::InfoArgs),
    /// Run the pipeline on bundled data into demo-out/.
    Demo(demo::DemoArgs),
}

/// Runs the CLI; every error becomes one line on stderr and exit code 1.
pub fn main() -> ExitCode {
    install_panic_hook();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return usage_error(e),
    };
    init_logging(cli.verbose);
    if let Some(threads) = cli.threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build_global() {
            eprintln!("error: cannot start {threads} threads: {e}");
            return ExitCode::FAILURE;
        }
    }
    let bars = progress::Bars::new(cli.quiet);
    let result = match cli.command {
        Command::Gen(args) => gen::run(args, &bars),
        Command::Analyze(args) => analyze::run(args, &bars),
        Command::Synth(args) => synth::run(args, &bars),
        Command::Eval(args) => eval::run(args, &bars),
        Command::Remesh(args) => remesh::run(args, &bars),
        Command::Render(args) => render::run(args, &bars),
        Command::View(args) => view::run(args, &bars),
        Command::Relight(args) => relight::run(args, &bars),
        Command::Info(args) => info::run(args, &bars),
        Command::Demo(args) => demo::run(args, &bars),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", one_line(&e));
            ExitCode::FAILURE
        }
    }
}

/// Help and version go to stdout as clap prints them; a usage error becomes one line and
/// exit code 2 (other errors exit 1).
fn usage_error(e: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        let _ = e.print();
        return if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
            ExitCode::FAILURE
        } else {
            ExitCode::SUCCESS
        };
    }
    let text = e.render().to_string();
    let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("invalid arguments");
    let first = first.strip_prefix("error: ").unwrap_or(first);
    eprintln!("error: {first} (see --help)");
    ExitCode::from(2)
}

/// The error and its causes on one line, without repeating a cause a message already quotes.
fn one_line(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if !line.contains(&text) {
            if !line.is_empty() {
                line.push_str(": ");
            }
            line.push_str(&text);
        }
    }
    line.replace('\n', " ")
}

fn init_logging(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .without_time()
        .try_init();
}

/// A bug must still end in one line, not a backtrace.
fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let message = info.to_string().replace('\n', " ");
        eprintln!("error: internal error ({message}); please report this at the project's issue tracker");
    }));
}
