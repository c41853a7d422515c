//! The pipeline's error: every stage's typed error, kept with its kind up to the binary, which
//! decides the exit code from [`Error::is_bad_input`] (2: the user's input; 1: a runtime
//! failure).

use vcnc_axis::AxisName;
use vcnc_gcode::Diagnostic;

/// Every failure of a run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A machine, model or options file.
    #[error(transparent)]
    Machine(#[from] vcnc_machine::Error),
    /// An input file could not be read.
    #[error("{file}: cannot read: {message}")]
    Io {
        /// The path.
        file: String,
        /// The system's message.
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
    /// The program cannot be interpolated (limits, length, an option).
    #[error("{file}: {source}")]
    Gcode {
        /// The program's path (or generator name).
        file: String,
        /// The interpolator's error.
        source: vcnc_gcode::Error,
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
        axis: AxisName,
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
    /// Kinematics: a pose unreachable, a row of poses that cannot be inverted.
    #[error("{context}: {source}")]
    Kinematics {
        /// File or stage.
        context: String,
        /// The kinematics' error.
        source: vcnc_kinematics::Error,
    },
    /// A drive could not be simulated.
    #[error("axis {axis}: {source}")]
    Drive {
        /// The axis.
        axis: AxisName,
        /// The simulator's error.
        source: vcnc_drive::Error,
    },
    /// Identification refused (the data) or failed (the numerics) for an axis or a trace.
    #[error(
        "{subject}: identification {}: {source}",
        if source.is_bad_input() { "refused" } else { "failed" }
    )]
    Identify {
        /// `axis X`, or the trace's path.
        subject: String,
        /// The identifier's error.
        source: vcnc_identify::Error,
    },
    /// Contour errors could not be evaluated.
    #[error("contour error evaluation failed: {0}")]
    Contour(#[from] vcnc_contour::Error),
    /// A trace file cannot be read or paired (format, units, channels, time base).
    #[error(transparent)]
    Trace(#[from] vcnc_trace::Error),
    /// A table file (CSV) is malformed.
    #[error("{file}:{line}: {message}")]
    Table {
        /// The path.
        file: String,
        /// Line, from 1 (0 when unknown).
        line: u64,
        /// What is wrong.
        message: String,
    },
    /// A compensated or re-planned reference would exceed an axis limit
    /// (docs/compensation.md#limits).
    #[error(
        "axis {axis}: the {what} reaches {value:.3} {unit}, {:.2} % above its limit {limit} {unit}; {advice}",
        100.0 * (value / limit - 1.0)
    )]
    Limit {
        /// The axis.
        axis: AxisName,
        /// What exceeds (e.g. `compensated reference velocity`).
        what: &'static str,
        /// The peak reached, in `unit`.
        value: f64,
        /// The axis limit, in `unit`.
        limit: f64,
        /// `mm/s`, `deg/s²`, …
        unit: String,
        /// What the user can do.
        advice: String,
    },
    /// An option or argument that does not fit the inputs (an axis the machine lacks, a bad
    /// `--set` or `--shard`).
    #[error("{0}")]
    Usage(String),
    /// A failure of vcnc itself (a broken internal promise), never the user's input.
    #[error("internal error: {0}")]
    Internal(String),
    /// Every configuration of a sweep failed.
    #[error("all {configurations} configurations of the sweep failed; first: {first}")]
    SweepFailed {
        /// How many ran.
        configurations: usize,
        /// The first configuration's error.
        first: String,
    },
}

impl Error {
    /// True when the input (files, options, data) is at fault: exit code 2; false for a
    /// runtime failure: exit code 1. Decided by the kind of the error (and, for a wrapped
    /// stage error, by that error's own kind).
    pub fn is_bad_input(&self) -> bool {
        match self {
            Error::Machine(e) => e.is_bad_input(),
            Error::Gcode { source, .. } => source.is_bad_input(),
            Error::Kinematics { source, .. } => source.is_bad_input(),
            Error::Drive { source, .. } => source.is_bad_input(),
            Error::Identify { source, .. } => source.is_bad_input(),
            Error::Contour(e) => e.is_bad_input(),
            Error::Io { .. }
            | Error::Program { .. }
            | Error::Travel { .. }
            | Error::Table { .. }
            | Error::Trace(_)
            | Error::Limit { .. }
            | Error::Usage(_) => true,
            Error::SweepFailed { .. } | Error::Internal(_) => false,
        }
    }

    /// An identification error about `subject` (`axis X` or a file).
    pub fn identify(subject: impl std::fmt::Display, source: vcnc_identify::Error) -> Error {
        Error::Identify {
            subject: subject.to_string(),
            source,
        }
    }

    /// A G-code error of the program `file`: its diagnostics, or the interpolator's error.
    pub fn gcode(file: &str, e: vcnc_gcode::Error) -> Error {
        match e {
            vcnc_gcode::Error::Program { diagnostics } => Error::Program {
                file: file.to_string(),
                diagnostics,
            },
            source => Error::Gcode {
                file: file.to_string(),
                source,
            },
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_exit_code_follows_the_kind_of_the_wrapped_error() {
        let data = Error::identify(
            "t.csv",
            vcnc_identify::Error::TooFewSamples {
                got: 3,
                needed: 100,
            },
        );
        assert!(data.is_bad_input());
        assert!(
            data.to_string().contains("identification refused"),
            "{data}"
        );
        let numeric = Error::identify(
            "axis X",
            vcnc_identify::Error::Drive(vcnc_drive::Error::NonFiniteModel),
        );
        assert!(!numeric.is_bad_input());
        assert!(
            numeric.to_string().contains("identification failed"),
            "{numeric}"
        );
        let gains = Error::Drive {
            axis: AxisName::X,
            source: vcnc_drive::Error::TooStiff {
                norm: 1e300,
                limit: 1e15,
            },
        };
        assert!(gains.is_bad_input());
        let signal = Error::Drive {
            axis: AxisName::X,
            source: vcnc_drive::Error::EmptySignal,
        };
        assert!(!signal.is_bad_input());
        assert!(!Error::Internal("x".into()).is_bad_input());
        let m: Error = vcnc_machine::Error::NoKinematics {
            file: "m.toml".into(),
        }
        .into();
        assert!(m.is_bad_input());
    }
}
