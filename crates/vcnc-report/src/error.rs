//! The crate's one error type.

use std::path::PathBuf;

/// Everything that can go wrong building a figure, the report or the `.vtp` export. Each
/// variant carries what a user needs to find the offending input.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Two arrays that must have one entry per sample differ in length.
    #[error("{what}: {found} values, expected {expected} (one per sample)")]
    LengthMismatch {
        /// Which array.
        what: String,
        /// The length it must have.
        expected: usize,
        /// The length it has.
        found: usize,
    },
    /// A figure was asked for with nothing to draw.
    #[error("{what}: no data to draw")]
    Empty {
        /// Which figure or series.
        what: String,
    },
    /// A value that must be finite is not (a coordinate, a frequency).
    #[error("{what}: value {value} at index {index} is not finite")]
    NonFinite {
        /// Which array.
        what: String,
        /// Index of the value.
        index: usize,
        /// The value.
        value: f64,
    },
    /// An option outside its allowed range.
    #[error("{what} = {value}: {expected}")]
    InvalidOption {
        /// The option.
        what: String,
        /// Its value, as text.
        value: String,
        /// What is allowed.
        expected: String,
    },
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A JSON file (manifest, summary) is malformed.
    #[error("{}:{line}:{column}: {message}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// Line, 1-based (0 when unknown).
        line: usize,
        /// Column, 1-based (0 when unknown).
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// The manifest names a figure file the folder does not have, or one that is not an SVG
    /// document.
    #[error("{}: figure '{file}' listed in the manifest: {problem}", manifest.display())]
    BadFigure {
        /// The manifest.
        manifest: PathBuf,
        /// The figure file as listed.
        file: String,
        /// What is wrong with it.
        problem: String,
    },
}

impl Error {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Error {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}
