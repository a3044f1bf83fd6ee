//! The `btfsynth` command line: parses arguments and prints; the work is in the library.

fn main() -> std::process::ExitCode {
    btfsynth::cli::main()
}
