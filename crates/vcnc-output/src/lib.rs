//! The outputs of vcnc's runs: what the command line chooses to keep of a run and how it is
//! written (docs/cli.md, "Output files").
//!
//! A run of `vcnc-pipeline` hands its pieces to sinks ([`vcnc_pipeline::Sink`]); this crate
//! has the sinks that make files of them and the writers of whole results:
//!
//! | module | does |
//! |---|---|
//! | [`files`] | atomic files (a temporary file renamed into place), `summary.json` with sorted keys, small CSV tables |
//! | [`table`] | per-sample tables (`reference`, `trace`, `contour`) written piece by piece as CSV or Parquet ([`table::TableWriter`]), and the sinks that write each run's table |
//! | [`report`] | the manifest of an output folder and its `report.html` ([`report::RunReport`]) |
//! | [`compensation`] | the tables and figure of `vcnc compensate` |
//! | [`demo`] | the tables of `vcnc demo` (realistic drives, stated latency, effect budget) |
//! | [`feed_plan`] | the tables and figure of `vcnc feed-plan` |
//! | [`figures`] | the figures of each kind of result (drawn by `vcnc-report` in its one style), full-resolution or from a streamed run's min/max envelopes ([`figures::Envelope`]) |
//! | [`identification`] | the files, tables and report of identifications |
//! | [`runs`] | the report of a run on a machine and a program, contour tables |
//! | [`text`] | plain-text tables for the terminal |
//!
//! Every file is written to a temporary file in its folder and renamed into place when
//! finished, so a reader (or a run killed midway) never sees half a file.

pub mod compensation;
pub mod demo;
pub mod feed_plan;
pub mod figures;
pub mod files;
pub mod identification;
pub mod report;
pub mod runs;
pub mod table;
pub mod text;

use std::path::PathBuf;

/// What can go wrong making a run's outputs.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The run itself (its error keeps its kind).
    #[error(transparent)]
    Pipeline(#[from] vcnc_pipeline::Error),
    /// A file or folder could not be created, written or moved into place.
    #[error("{message}")]
    Io {
        /// What was being done, with the path.
        message: String,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// A figure could not be drawn (not an empty one: that is a note in the report).
    #[error("cannot draw {file}")]
    Draw {
        /// The figure's file.
        file: String,
        /// The drawing's error.
        #[source]
        source: vcnc_report::Error,
    },
    /// The report page or a `.vtp` export could not be made (its error names the file).
    #[error(transparent)]
    Report(#[from] vcnc_report::Error),
    /// A folder whose report is to be rebuilt lacks a valid manifest, or the summary or a
    /// figure it names (its error names the file).
    #[error("{0}")]
    Folder(vcnc_report::Error),
    /// A summary or table could not be encoded (JSON, CSV, Parquet).
    #[error("{}: cannot encode: {message}", path.display())]
    Encode {
        /// The file.
        path: PathBuf,
        /// The encoder's message.
        message: String,
    },
    /// `--columns` names a column the table does not have.
    #[error("--columns {pattern}: the {table} table has no such column; it has {available}")]
    UnknownColumn {
        /// The pattern given.
        pattern: String,
        /// The table (`contour`, `trace`, `reference`).
        table: String,
        /// Its columns, space-separated.
        available: String,
    },
    /// A table was handed columns that do not fit it (vcnc's own failure).
    #[error(
        "{table}: internal error: {columns} columns of unequal length for a {width}-column table"
    )]
    Columns {
        /// The table.
        table: String,
        /// Columns handed over.
        columns: usize,
        /// The table's width.
        width: usize,
    },
    /// The test hook `VCNC_FAIL_WRITE` failed this file on purpose ([`files::fail_point`]).
    #[error("injected write failure for {} (VCNC_FAIL_WRITE)", path.display())]
    InjectedFailure {
        /// The file.
        path: PathBuf,
    },
}

impl From<vcnc_pipeline::MachineError> for Error {
    fn from(e: vcnc_pipeline::MachineError) -> Error {
        Error::Pipeline(e.into())
    }
}

impl Error {
    /// An I/O failure: `message` says what was being done, with the path.
    pub fn io(message: String, source: std::io::Error) -> Error {
        Error::Io { message, source }
    }

    /// True when the user's input is at fault (exit code 2), false for a runtime failure
    /// (exit code 1).
    pub fn is_bad_input(&self) -> bool {
        match self {
            Error::Pipeline(e) => e.is_bad_input(),
            Error::UnknownColumn { .. } | Error::Folder(_) => true,
            Error::Io { .. }
            | Error::Report(_)
            | Error::Draw { .. }
            | Error::Encode { .. }
            | Error::Columns { .. }
            | Error::InjectedFailure { .. } => false,
        }
    }
}

/// This crate's results.
pub type Result<T, E = Error> = std::result::Result<T, E>;
