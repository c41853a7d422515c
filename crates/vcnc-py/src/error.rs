//! Errors into Python exceptions, by the kind the command line decides its exit code from: the
//! user's input at fault (exit code 2) is a `ValueError`, anything else (exit code 1) a
//! `RuntimeError`. The message is the command line's: the error and each cause, one per line.

use pyo3::PyErr;
use pyo3::exceptions::{PyRuntimeError, PyValueError};

/// The command line's rendering of `e`: its message, then `caused by:` each source.
fn render(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        s.push_str("\n  caused by: ");
        s.push_str(&c.to_string());
        cause = c.source();
    }
    s
}

fn mapped(e: &dyn std::error::Error, bad_input: bool) -> PyErr {
    if bad_input {
        PyValueError::new_err(render(e))
    } else {
        PyRuntimeError::new_err(render(e))
    }
}

/// A run's error (every other library error converts into it, as at the command line).
pub(crate) fn pipeline(e: impl Into<vcnc_pipeline::Error>) -> PyErr {
    let e = e.into();
    mapped(&e, e.is_bad_input())
}

/// A model simulation's error.
pub(crate) fn drive(e: vcnc_drive::Error) -> PyErr {
    mapped(&e, e.is_bad_input())
}

/// A kinematics error.
pub(crate) fn kinematics(e: vcnc_kinematics::Error) -> PyErr {
    mapped(&e, e.is_bad_input())
}

/// An argument the binding itself refuses (the command line's `bad_input`).
pub(crate) fn bad_input(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// A summary that does not serialise: an internal failure.
pub(crate) fn internal(e: impl std::fmt::Display) -> PyErr {
    PyRuntimeError::new_err(e.to_string())
}
