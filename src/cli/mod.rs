//! Argument parsing, progress display and error printing: the only terminal code.

mod analyze;
mod convert;
mod demo;
mod eval;
mod export;
mod gen;
mod info;
mod progress;
mod relight;
mod remesh;
mod render;
mod shots;
mod soler;
mod synth;
#[cfg(feature = "gpu")]
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
    /// Worker threads, at least 1 (default: one per core).
    #[arg(long, global = true, value_name = "N", value_parser = at_least(1))]
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
    /// How much a result looks like its sample: patch energy, colour χ², collapse, smear, copy.
    Eval(eval::EvalArgs),
    /// Remesh a triangle mesh to near-uniform edge length (OBJ/OFF/PLY in, binary PLY out).
    Remesh(remesh::RemeshArgs),
    /// Render a surface map on the CPU: ray-traced frames with shadows (EXR or PNG) and a contact sheet.
    Render(render::RenderArgs),
    /// Render a surface map on the GPU (wgpu): an interactive window, or --headless frames.
    #[cfg(feature = "gpu")]
    View(view::ViewArgs),
    /// The sample itself, rectified, under any view and light (or environment), measured or not.
    Relight(relight::RelightArgs),
    /// Convert a stack: to a folder of EXR/PNG images, or to a DFMF .btf file (--to btf).
    Convert(convert::ConvertArgs),
    /// Describe a path: a BTF stack (manifest, Bonn/UTIA images or a single image) or an analysis.
    Info(info::InfoArgs),
    /// Run the pipeline on bundled data into demo-out/.
    Demo(demo::DemoArgs),
    /// Write a surface map on the original mesh as glTF (.glb/.gltf) with baked textures.
    Export(export::ExportArgs),
}

/// Runs the CLI; every error becomes one line on stderr and exit code 1 (2 for a mistake
/// on the command line, 130 when interrupted).
pub fn main() -> ExitCode {
    install_panic_hook();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return usage_error(e),
    };
    init_logging(cli.verbose);
    clean_up_when_interrupted();
    if let Some(threads) = cli.threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(threads).build_global() {
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
        #[cfg(feature = "gpu")]
        Command::View(args) => view::run(args, &bars),
        Command::Relight(args) => relight::run(args, &bars),
        Command::Convert(args) => convert::run(args, &bars),
        Command::Info(args) => info::run(args, &bars),
        Command::Demo(args) => demo::run(args, &bars),
        Command::Export(args) => export::run(args, &bars),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", crate::fsutil::without_temporary_names(&one_line(&e)));
            if e.downcast_ref::<UsageError>().is_some() {
                ExitCode::from(2)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

/// A mistake on the command line found after parsing (a value out of range for the input
/// at hand, a missing or conflicting flag): like clap's own errors, it exits with code 2.
#[derive(Debug)]
pub(crate) struct UsageError(String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// A usage error with `message` (see [`UsageError`]).
pub(crate) fn usage(message: impl std::fmt::Display) -> anyhow::Error {
    anyhow::Error::new(UsageError(message.to_string()))
}

/// A parser for a whole-number flag of at least `min`.
pub(crate) fn at_least(min: usize) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync + 'static {
    move |s| match s.trim().parse::<usize>() {
        Ok(v) if v >= min => Ok(v),
        _ => Err(format!("expected a whole number of at least {min}")),
    }
}

/// A parser for a positive, finite number.
pub(crate) fn positive_number(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err("expected a positive number".into()),
    }
}

/// A parser for the side of a square neighbourhood: odd and at least 3.
pub(crate) fn odd_side(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(v) if v >= 3 && v % 2 == 1 => Ok(v),
        _ => Err("expected an odd whole number of at least 3 (3, 5, 7, …)".into()),
    }
}

/// SIGINT, SIGTERM and SIGHUP remove every unfinished output before the process exits, so
/// an interrupted run leaves nothing hidden behind.
fn clean_up_when_interrupted() {
    let installed = ctrlc::set_handler(|| {
        crate::fsutil::remove_staged();
        eprintln!("\nerror: interrupted; unfinished outputs were removed");
        std::process::exit(130);
    });
    if let Err(e) = installed {
        tracing::warn!("cannot clean up on Ctrl-C: {e}");
    }
}

/// Help and version go to stdout as clap prints them; a usage error becomes one line and
/// exit code 2 (other errors exit 1).
fn usage_error(e: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    match e.kind() {
        ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => {
            let _ = e.print();
            return ExitCode::SUCCESS;
        }
        // `btfsynth` alone: the overview is the most useful answer, but it is still a
        // command line that does nothing.
        ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            let _ = e.print();
            return ExitCode::from(2);
        }
        _ => {}
    }
    eprintln!("error: {} (see --help)", first_paragraph(&e.render().to_string()));
    ExitCode::from(2)
}

/// clap's message up to its first blank line, on one line: "the following required
/// arguments were not provided:" is followed by the arguments themselves.
fn first_paragraph(text: &str) -> String {
    let lines: Vec<&str> = text
        .lines()
        .skip_while(|l| l.trim().is_empty())
        .take_while(|l| !l.trim().is_empty())
        .map(str::trim)
        .collect();
    let joined = match lines.split_first() {
        Some((first, rest)) if first.ends_with(':') && !rest.is_empty() => {
            format!("{first} {}", rest.join(", "))
        }
        Some((first, _)) => first.to_string(),
        None => "invalid arguments".to_string(),
    };
    joined.strip_prefix("error: ").unwrap_or(&joined).to_string()
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
