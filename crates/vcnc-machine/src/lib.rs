//! The vcnc machine file and pipeline.
//!
//! - [`MachineFile`] is the TOML document as written (docs/machine-file.md); [`Machine`] is the checked
//!   machine: every axis' drive validated (gains designed, closed loop stable), the kinematic
//!   chain loaded from its URDF, limits known. Errors name the file, line and key.
//! - [`ModelSet`] is an identified model file (`model.toml`), read by `--model`.
//! - [`pipeline`]: program → reference trajectory → (inverse kinematics) → axis references →
//!   true drives / identified models → (forward kinematics) → tool poses → contour errors; and
//!   identification of each axis on its excitation program.
//! - [`sweep`]: machine-file keys set by dotted path, cartesian products and shards.
//!
//! Only this crate knows TOML; only the binary knows the command line and plotting.

mod file;
mod locate;
mod machine;
mod models;
mod options_file;
pub mod pipeline;
pub mod sweep;

pub use file::{
    AxisFile, GcodeFile, IdentificationFile, KinematicsFile, MachineFile, ProgramFile,
    TrajectoryFile, Unit,
};
pub use locate::{LineCol, line_col, locate_key};
pub use machine::{Axis, Machine};
pub use models::{AxisModel, ModelSet};
pub use options_file::OptionsFile;

use vcnc_gcode::Diagnostic;

/// The embedded default machine (NMV5000, the paper's Table 3 drives) and its URDF, so that `vcnc demo`
/// runs from anywhere.
pub mod embedded {
    /// `machines/nmv5000.toml`.
    pub const NMV5000_TOML: &str = include_str!("../../../machines/nmv5000.toml");
    /// `machines/nmv5000.urdf`.
    pub const NMV5000_URDF: &str = include_str!("../../../machines/nmv5000.urdf");
    /// `gcode/spiral.ngc`, the 5-axis spiral of docs/contour.md.
    pub const SPIRAL_NGC: &str = include_str!("../../../gcode/spiral.ngc");
}

/// Errors of the machine crate and pipeline. [`Error::is_bad_input`] tells the binary which exit
/// code to use (2 for bad input, 1 for a runtime failure).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A file could not be read.
    #[error("{file}: cannot read: {message}")]
    Io {
        /// The path.
        file: String,
        /// The system's message.
        message: String,
    },
    /// TOML syntax, an unknown or missing key, a wrong type.
    #[error("{file}:{at}: {message}")]
    Toml {
        /// The path.
        file: String,
        /// Where.
        at: LineCol,
        /// What is wrong.
        message: String,
    },
    /// A value that parses but makes no sense (negative inertia, unstable gains, ...).
    #[error("{file}:{}{key}: {message}", at.map(|a| format!("{a}: ")).unwrap_or_default())]
    Invalid {
        /// The path.
        file: String,
        /// Where the key is written, when known.
        at: Option<LineCol>,
        /// Dotted key, e.g. `axes.X.plant.j`.
        key: String,
        /// What is wrong, with the value.
        message: String,
    },
    /// G-code errors, every one with its line and column.
    #[error("{}", format_diagnostics(file, diagnostics))]
    Program {
        /// The program's path.
        file: String,
        /// Every diagnostic (errors and warnings).
        diagnostics: Vec<Diagnostic>,
    },
    /// The program cannot be interpolated (limits, too long, infeasible inverse-time feed).
    #[error("{file}: {message}")]
    Interpolation {
        /// The program's path.
        file: String,
        /// What is wrong.
        message: String,
    },
    /// An axis leaves its travel.
    #[error(
        "{file}:{line}: axis {axis} reaches {value:.4} {unit}, beyond its travel {lower} ..= {upper} {unit} (at t = {t_s:.3} s){}",
        target.map(|t| format!("; the block moves it to {t} {unit}")).unwrap_or_default()
    )]
    Travel {
        /// The program's path.
        file: String,
        /// Source line of the block that moves there.
        line: u32,
        /// The axis.
        axis: vcnc_axis::AxisName,
        /// Position reached, axis units.
        value: f64,
        /// Lower travel limit.
        lower: f64,
        /// Upper travel limit.
        upper: f64,
        /// Unit label.
        unit: &'static str,
        /// Time of the first sample beyond travel, s.
        t_s: f64,
        /// The block's programmed end position of the axis (axis-coordinate programs).
        target: Option<f64>,
    },
    /// Kinematics: the chain is unusable, a pose unreachable.
    #[error("{context}: {message}")]
    Kinematics {
        /// File or stage.
        context: String,
        /// What is wrong.
        message: String,
    },
    /// Identification refused or failed for an axis.
    #[error("axis {axis}: identification failed: {message}")]
    Identify {
        /// Axis letter or trace name.
        axis: String,
        /// Why.
        message: String,
        /// True when the data are at fault (exit code 2), false for a numerical failure.
        bad_input: bool,
    },
    /// A model file that does not fit the machine (axis missing, unit mismatch).
    #[error("{file}: {message}")]
    ModelMismatch {
        /// The model file.
        file: String,
        /// What does not fit.
        message: String,
    },
    /// Numerical or internal failure (not the user's input).
    #[error("{0}")]
    Runtime(String),
}

impl Error {
    /// True when the input (files, options, data) is at fault: exit code 2.
    pub fn is_bad_input(&self) -> bool {
        match self {
            Error::Runtime(_) => false,
            Error::Identify { bad_input, .. } => *bad_input,
            _ => true,
        }
    }
}

fn format_diagnostics(file: &str, diagnostics: &[Diagnostic]) -> String {
    let mut lines: Vec<String> = diagnostics
        .iter()
        .filter(|d| d.is_error())
        .map(|d| format!("{file}:{d}"))
        .collect();
    if lines.is_empty() {
        lines.push(format!("{file}: the program has errors"));
    }
    lines.join("\n")
}

/// Reads a text file: its display name (for messages) and contents, or [`Error::Io`] naming it.
pub(crate) fn read_text(path: &std::path::Path) -> Result<(String, String), Error> {
    let file = path.display().to_string();
    match std::fs::read_to_string(path) {
        Ok(src) => Ok((file, src)),
        Err(e) => Err(Error::Io {
            file,
            message: e.to_string(),
        }),
    }
}
