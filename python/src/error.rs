//! `segloc.SegLocError`: every error of the library, raised with its message.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::PyErr;

create_exception!(
    segloc,
    SegLocError,
    PyException,
    "Bad input or a failed call: the message names the file (and line) and the problem."
);

/// A library error as a `SegLocError` carrying its message (with its sources).
pub fn to_py(e: impl std::fmt::Display) -> PyErr {
    SegLocError::new_err(e.to_string())
}
