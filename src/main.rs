//! The `btfsynth` command line: parses arguments and prints; the work is in the library.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
