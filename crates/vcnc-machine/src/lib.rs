//! The vcnc machine file: raw TOML → checked machine, and the other TOML files of vcnc.
//!
//! - [`MachineFile`] is the TOML document as written (docs/machine-file.md); [`MachineDocument`]
//!   a file as read (its table, text and base folder); [`Machine`] the checked machine: every
//!   axis' drive validated (gains designed, closed loop stable), the kinematic chain loaded from
//!   its URDF with the roles of its axes resolved, limits known. Errors name the file, line and
//!   key.
//! - [`ModelSet`] is an identified model file (`model.toml`), read by `--model`.
//! - [`OptionsFile`] holds identifier options: a machine file's `[identification.options]` or an
//!   `--options` file of their own (the same keys, the same type).
//!
//! Only this crate knows TOML. Runs (interpolation, simulation, identification, prediction,
//! sweeps) are `vcnc-pipeline`'s.

mod file;
mod locate;
mod machine;
mod models;
mod options_file;
mod sweep;

pub use file::{
    AxisFile, FamilyFile, GcodeFile, IdentificationFile, KinematicsFile, MachineFile, PlannerFile,
    ProfileFile, ProgramFile, TiltFile, TrajectoryFile, Unit,
};
pub use locate::{LineCol, line_col, locate_key};
pub use machine::{Axis, Dynamics, IdentificationSettings, Kinematics, Machine, MachineDocument};
pub use models::{AxisModel, MachineModels, ModelSet};
pub use options_file::OptionsFile;

/// The embedded default machine (NMV5000, the paper's Table 3 drives) and its URDF, so that
/// `vcnc demo` runs from anywhere.
pub mod embedded {
    /// `machines/nmv5000.toml`.
    pub const NMV5000_TOML: &str = include_str!("../../../machines/nmv5000.toml");
    /// `machines/nmv5000-realistic.toml`: the same machine with every drive effect of
    /// docs/machine-file.md#drive-effects (it uses `machines/nmv5000.urdf` too).
    pub const NMV5000_REALISTIC_TOML: &str =
        include_str!("../../../machines/nmv5000-realistic.toml");
    /// `machines/nmv5000.urdf`.
    pub const NMV5000_URDF: &str = include_str!("../../../machines/nmv5000.urdf");
    /// `gcode/spiral.ngc`, the 5-axis spiral of docs/contour.md.
    pub const SPIRAL_NGC: &str = include_str!("../../../gcode/spiral.ngc");
}

/// Errors of the machine, model and options files. Every variant but [`Error::Write`] is the
/// user's input (exit code 2); each names the file, and the line and key where known.
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
    #[error(
        "{file}:{}{}{message}",
        at.map(|a| format!("{a}: ")).unwrap_or_default(),
        if key.is_empty() { " ".to_string() } else { format!("{key}: ") }
    )]
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
    /// The URDF chain is unusable.
    #[error("{context}: {message}")]
    Kinematics {
        /// File and key.
        context: String,
        /// What is wrong.
        message: String,
    },
    /// The machine file has no `[kinematics]` section but the run needs one.
    #[error(
        "{file}: the machine file has no [kinematics] section (needed for TCP programs, poses and contour errors)"
    )]
    NoKinematics {
        /// The machine file.
        file: String,
    },
    /// A run that needs a virtual drive on an axis known only by its identified model.
    #[error(
        "{file}: axis {axis} has no plant and controller (it is known by its identified model), but {what} needs a virtual drive: give [axes.{axis}] a plant and controller, or use the model where a model will do (predict, simulate, compensate, feed-plan, frf)"
    )]
    NoDrive {
        /// The machine file.
        file: String,
        /// The axis.
        axis: vcnc_axis::AxisName,
        /// What needs the drive (e.g. "identification on the virtual machine").
        what: String,
    },
    /// A model file that does not fit the machine (axis missing, unit mismatch).
    #[error("{file}: {message}")]
    ModelMismatch {
        /// The model file.
        file: String,
        /// What does not fit.
        message: String,
    },
    /// vcnc made a set of models whose count is not the machine's axes' (vcnc's own failure).
    #[error("internal error: {models} models for the {axes} axes of machine \"{machine}\"")]
    ModelCount {
        /// The machine's name.
        machine: String,
        /// Its axes.
        axes: usize,
        /// The models made.
        models: usize,
    },
    /// A document could not be serialised (not the user's input).
    #[error("cannot write {what}: {message}")]
    Write {
        /// What was being written.
        what: String,
        /// The serialiser's message.
        message: String,
    },
}

impl Error {
    /// True when the input (a file) is at fault: exit code 2.
    pub fn is_bad_input(&self) -> bool {
        !matches!(self, Error::Write { .. } | Error::ModelCount { .. })
    }
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
