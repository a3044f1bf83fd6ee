//! Library errors as Python exceptions: one hierarchy under `btfsynth.Error`, defined in
//! Python (`btfsynth/errors.py`) so that a class can also derive from `ValueError` or
//! `OSError`; each carries the library's one-line message.

use btfsynth::Error;
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;

/// The exception class of `btfsynth.errors` that `e` becomes.
fn class_of(e: &Error) -> &'static str {
    match e {
        Error::Io { .. } | Error::Format { .. } => "FileError",
        Error::OutputExists(_) | Error::OutputRefused { .. } => "OutputError",
        Error::TooLarge { .. } => "TooLargeError",
        Error::OutOfRange { .. }
        | Error::InvalidArgument(_)
        | Error::Recipe { .. }
        | Error::IncompatibleSearch { .. }
        | Error::AnalysisMismatch { .. } => "ParameterError",
        Error::Unavailable { .. } | Error::Gpu(_) => "UnavailableError",
        // A later variant is at least a btfsynth.Error.
        _ => "InternalError",
    }
}

/// `e` as an instance of its `btfsynth.errors` class, with `param` (the parameter at fault)
/// or `filename` (the file) set where the library names one.
pub fn to_py(py: Python<'_>, e: Error) -> PyErr {
    let message = btfsynth::fsutil::without_temporary_names(&e.to_string());
    let built = (|| -> PyResult<PyErr> {
        let class = py.import("btfsynth.errors")?.getattr(class_of(&e))?;
        let value = class.call1((message.clone(),))?;
        match &e {
            Error::OutOfRange { param, .. } => value.setattr("param", param.name())?,
            Error::Io { path, .. } | Error::Format { path, .. } | Error::OutputExists(path) => {
                value.setattr("filename", path.display().to_string())?
            }
            Error::OutputRefused { path, .. } => value.setattr("filename", path.display().to_string())?,
            _ => {}
        }
        Ok(PyErr::from_value(value))
    })();
    // Without the Python half of the package (a bare `_native`), the built-in classes.
    built.unwrap_or_else(|_| match class_of(&e) {
        "ParameterError" | "TooLargeError" => PyValueError::new_err(message),
        _ => PyRuntimeError::new_err(message),
    })
}

/// A `TypeError` naming the argument `name`.
pub fn type_error(name: &str, message: impl std::fmt::Display) -> PyErr {
    PyTypeError::new_err(format!("{name}: {message}"))
}

/// A `ValueError` naming the argument `name` (a `btfsynth.ParameterError`, which is one).
pub fn value_error(py: Python<'_>, name: &str, message: impl std::fmt::Display) -> PyErr {
    let text = format!("{name}: {message}");
    let built = (|| -> PyResult<PyErr> {
        let value = py.import("btfsynth.errors")?.getattr("ParameterError")?.call1((text.clone(),))?;
        value.setattr("param", name)?;
        Ok(PyErr::from_value(value))
    })();
    built.unwrap_or_else(|_| PyValueError::new_err(text))
}

/// A library result as a Python one.
pub trait IntoPy<T> {
    /// Maps the error through [`to_py`].
    fn py(self, py: Python<'_>) -> PyResult<T>;
}

impl<T> IntoPy<T> for btfsynth::Result<T> {
    fn py(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| to_py(py, e))
    }
}
