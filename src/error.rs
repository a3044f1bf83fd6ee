//! The library's one error type. Every message names the file (or argument) at fault and
//! says what is wrong with it, on one line, so the CLI can print it as a single line.

use std::path::{Path, PathBuf};

/// Everything that can go wrong in btfsynth's library.
///
/// Messages stay on one line: line breaks and other control characters that a file name or
/// a quoted piece of a damaged file brings into them are shown escaped (`\n`).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused to read or write a path.
    #[error("{}: {}", OneLine(.path.display()), OneLine(.source))]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file exists but its contents are not what it claims to be.
    #[error("{}: {}", OneLine(.path.display()), OneLine(.message))]
    Format { path: PathBuf, message: String },
    /// A user-supplied value (a flag, a size, a crop) is out of its domain.
    #[error("{}", OneLine(.0))]
    InvalidArgument(String),
    /// An analysis is not the one a result was synthesized from: the fingerprints of their
    /// samples differ.
    #[error(
        "{} was synthesized from an analysis of another sample ({recorded}), not from {} ({found})",
        OneLine(.result.display()),
        OneLine(.analysis.display())
    )]
    AnalysisMismatch {
        /// The surface map or plane result.
        result: PathBuf,
        /// The analysis directory offered for it.
        analysis: PathBuf,
        /// The fingerprint the result records.
        recorded: String,
        /// The fingerprint of the offered analysis.
        found: String,
    },
}

/// Shorthand used throughout the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io { path: path.as_ref().to_path_buf(), source }
    }

    pub fn format(path: impl AsRef<Path>, message: impl Into<String>) -> Self {
        Error::Format { path: path.as_ref().to_path_buf(), message: message.into() }
    }

    pub fn invalid(message: impl Into<String>) -> Self {
        Error::InvalidArgument(message.into())
    }
}

/// Shows a value with its control characters escaped, so that a message stays on one line.
struct OneLine<T>(T);

impl<T: std::fmt::Display> std::fmt::Display for OneLine<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for c in self.0.to_string().chars() {
            if c.is_control() {
                write!(f, "{}", c.escape_default())?;
            } else {
                write!(f, "{c}")?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_are_one_line_whatever_the_file_name() {
        let e = Error::format("/data/tl\n15.png", "cannot read 'tl\n15'");
        assert_eq!(e.to_string(), "/data/tl\\n15.png: cannot read 'tl\\n15'");
    }
}
