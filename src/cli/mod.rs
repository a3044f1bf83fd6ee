//! Argument parsing, progress display and error printing: the only terminal code.

mod analyze;
mod convert;
mod demo;
mod eval;
mod export;
mod gen;
mod hints;
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
    /// Worker threads, 1 to 256 (default: one per core).
    #[arg(long, global = true, value_name = "N", value_parser = in_range(1, MAX_THREADS))]
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
    // Every variable the library reads, whichever command runs: a bad value is a mistake in
    // the invocation, refused before any work.
    if let Err(e) = btfsynth::env::check() {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
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
        // Whoever reads stdout has stopped reading (`| head`): nothing more to say, as
        // ripgrep and the other line tools do.
        Err(e) if is_closed_stdout(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", btfsynth::fsutil::without_temporary_names(&one_line(&e)));
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

/// A library error that a flag caused, as a usage error naming the flag ([`hints`]).
pub(crate) fn usage_of(e: btfsynth::Error) -> anyhow::Error {
    usage(hints::text(&e))
}

/// The most worker threads `--threads` starts: all start before any work, and hundreds
/// more than there are cores only take turns spinning (1024 on two cores: 50 s to start).
pub(crate) const MAX_THREADS: usize = 256;

/// Writes `text` and a line break to stdout. A closed pipe or a full device is an error
/// (see [`StdoutError`]) instead of the panic of `println!`.
pub(crate) fn print(text: impl std::fmt::Display) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{text}").and_then(|()| out.flush()).map_err(|e| anyhow::Error::new(StdoutError(e)))
}

/// Stdout could not be written: a closed pipe ends the run quietly, anything else (a full
/// disk, `> /dev/full`) is one error line.
#[derive(Debug)]
pub(crate) struct StdoutError(std::io::Error);

impl std::fmt::Display for StdoutError {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "cannot write to standard output: {}", self.0)
    }
}

impl std::error::Error for StdoutError {}

fn is_closed_stdout(e: &anyhow::Error) -> bool {
    e.downcast_ref::<StdoutError>().is_some_and(|s| s.0.kind() == std::io::ErrorKind::BrokenPipe)
}

/// A parser for a whole number from `min` to `max`.
pub(crate) fn in_range(
    min: usize,
    max: usize,
) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync + 'static {
    move |s| match s.trim().parse::<usize>() {
        Ok(v) if (min..=max).contains(&v) => Ok(v),
        _ => Err(format!("expected a whole number from {min} to {max}")),
    }
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

/// The largest neighbourhood side any flag accepts (the synthesis' widest); the sample's
/// levels bound it further.
pub(crate) const MAX_NEIGHBOURHOOD: usize = btfsynth::synth::session::MAX_NEIGHBOURHOOD;

/// A parser for the side of a square neighbourhood: odd, from 3 to [`MAX_NEIGHBOURHOOD`].
pub(crate) fn odd_side(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(v) if (3..=MAX_NEIGHBOURHOOD).contains(&v) && v % 2 == 1 => Ok(v),
        _ => Err(format!("expected an odd whole number from 3 to {MAX_NEIGHBOURHOOD} (3, 5, 7, …)")),
    }
}

/// SIGINT, SIGTERM and SIGHUP remove every unfinished output before the process exits, so
/// an interrupted run leaves nothing hidden behind; the message names the outputs that were
/// already complete (commits come last, so that is rare and only ever whole outputs).
fn clean_up_when_interrupted() {
    let installed = ctrlc::set_handler(|| {
        let committed = btfsynth::fsutil::remove_staged();
        // On a terminal the line starts after the echoed ^C.
        let start = if std::io::IsTerminal::is_terminal(&std::io::stderr()) { "\n" } else { "" };
        eprintln!("{start}{}", interrupted_message(&committed));
        std::process::exit(130);
    });
    if let Err(e) = installed {
        tracing::warn!("cannot clean up on Ctrl-C: {e}");
    }
}

/// The line an interrupted run ends with, after `committed` outputs were written.
fn interrupted_message(committed: &[std::path::PathBuf]) -> String {
    if committed.is_empty() {
        return "error: interrupted; unfinished outputs were removed".into();
    }
    let names: Vec<String> = committed.iter().map(|p| p.display().to_string()).collect();
    format!("error: interrupted after writing {}; unfinished outputs were removed", names.join(", "))
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

/// The error and its causes on one line, without repeating a cause a message already
/// quotes; the library's errors name flags ([`hints`]).
fn one_line(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = hints::text(cause);
        if !line.contains(&text) && !line.contains(&cause.to_string()) {
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
        // wgpu's backend layer reports its drivers' probing at error level when built with
        // debug assertions (an EGL display whose DRI driver does not load, while another
        // adapter is found and used): noise before the one line a failure gets. `-v` and
        // RUST_LOG show it.
        0 => "warn,wgpu_hal=off",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
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
