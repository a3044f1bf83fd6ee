//! The library's one error type. Every message names the file (or argument) at fault and
//! says what is wrong with it, so the CLI can print it as a single line.

use std::path::{Path, PathBuf};

/// Everything that can go wrong in btfsynth's library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused to read or write a path.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file exists but its contents are not what it claims to be.
    #[error("{}: {message}", path.display())]
    Format { path: PathBuf, message: String },
    /// A user-supplied value (a flag, a size, a crop) is out of its domain.
    #[error("{0}")]
    InvalidArgument(String),
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
