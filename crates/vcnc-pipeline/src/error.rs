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
    /// A LinuxCNC tool table (`.tbl`) has a wrong line (its file and line are in the message).
    #[error("{0}")]
    ToolTable(vcnc_gcode::Error),
    /// A program without motion where a run needs some.
    #[error(
        "{file}: the program moves no axis ({samples} samples at rest); nothing to predict: give a program with G0/G1/G2/G3 moves"
    )]
    NoMotion {
        /// The program's path.
        file: String,
        /// Samples of its reference.
        samples: usize,
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
    /// An axis reference cannot be compensated with its model.
    #[error("axis {axis}: {source}")]
    Compensate {
        /// The axis.
        axis: AxisName,
        /// The compensation's error.
        source: vcnc_compensate::Error,
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
    /// A command-line argument of the wrong form.
    #[error("{option} {value}: expected {expected}")]
    Argument {
        /// The option (`--set`, `--shard`).
        option: &'static str,
        /// The value given.
        value: String,
        /// What it must be.
        expected: String,
    },
    /// `--axis` names an axis the machine lacks.
    #[error("--axis {axis}: machine \"{machine}\" ({file}) has no axis {axis}; it has {has}")]
    NoSuchAxis {
        /// The axis named.
        axis: AxisName,
        /// The machine's name.
        machine: String,
        /// Its file.
        file: String,
        /// The axes it has.
        has: String,
    },
    /// A sweep larger than vcnc runs in one go.
    #[error("the sweep has {total} configurations; split it (at most {max})")]
    TooManyConfigurations {
        /// Configurations of the product.
        total: usize,
        /// The most one sweep runs.
        max: usize,
    },
    /// A shard's `sweep.csv` that cannot be merged.
    #[error("{file}: {problem}")]
    Shard {
        /// The file.
        file: String,
        /// What is wrong.
        problem: &'static str,
    },
    /// A configuration in two shards.
    #[error("configuration {index} appears in more than one shard")]
    DuplicateConfiguration {
        /// Its index.
        index: usize,
    },
    /// `sweep-merge` without shard folders.
    #[error("no shard folders given")]
    NoShards,
    /// A program generator's parameter out of range.
    #[error("{program}: {what} must be positive and finite, not {value}")]
    Generator {
        /// The generator.
        program: &'static str,
        /// The parameter.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// A generated program could not be written to its output.
    #[error("{program}: cannot write the text")]
    GeneratorOutput {
        /// The generator.
        program: &'static str,
    },
    /// A feed-planning option out of range.
    #[error("feed planning: {what} must be {expected}, got {value}")]
    FeedPlanOption {
        /// The option.
        what: &'static str,
        /// Its value.
        value: f64,
        /// Its range.
        expected: &'static str,
    },
    /// The control's nominal-position filters cannot be folded into the models a
    /// compensation inverts.
    #[error(
        "{machine}: compensate cannot invert the control's filters ([control]): {what}; it folds a delay and one first- or second-order filter into models without a reference filter of their own"
    )]
    ControlFilters {
        /// The machine file.
        machine: String,
        /// What stands in the way.
        what: String,
    },
    /// A program without feed moves to plan.
    #[error(
        "{file}: the program has no feed moves (G1, G2, G3 with an F word) whose feed could be planned"
    )]
    NothingToPlan {
        /// The program.
        file: String,
    },
    /// No feed scale meets the tolerance.
    #[error(
        "feed planning: even at {min_factor} times the programmed feeds the predicted contour \
         error on the feed moves is {tip_um:.3} µm and {orientation_mrad:.4} mrad, {excess:.2} \
         times the tolerance"
    )]
    ToleranceUnreachable {
        /// The smallest feed factor tried.
        min_factor: f64,
        /// The predicted tool-tip contour error there on the feed moves (the samples held to
        /// the tolerance), µm.
        tip_um: f64,
        /// The predicted orientation error there on the feed moves, mrad.
        orientation_mrad: f64,
        /// Its ratio to the tolerance.
        excess: f64,
    },
    /// A program too large for the memory available.
    #[error(
        "{file}: the program is {bytes} bytes; preparing it needs about {:.1} GB of memory (about \
         {} bytes per byte of G-code: the parser and the interpreter hold the whole program, \
         then its samples) and {:.1} GB are available; split it",
        *need_bytes as f64 / 1e9,
        crate::run::PROGRAM_MEMORY_PER_BYTE,
        *available_bytes as f64 / 1e9
    )]
    ProgramTooLarge {
        /// The program.
        file: String,
        /// Its size, bytes.
        bytes: u64,
        /// The memory preparing it needs, bytes.
        need_bytes: u64,
        /// The memory available, bytes.
        available_bytes: u64,
    },
    /// A program with more blocks than the parser takes.
    #[error(
        "{file}: the program has {lines} non-blank lines, more than the {max} blocks vcnc \
         parses; split it"
    )]
    TooManyBlocks {
        /// The program.
        file: String,
        /// Its non-blank lines.
        lines: usize,
        /// The parser's block limit.
        max: usize,
    },
    /// A table lacks a column it needs.
    #[error("{file}: missing column '{column}' (the header has: {header}){hint}")]
    MissingColumn {
        /// The file.
        file: String,
        /// The column.
        column: String,
        /// The columns it has.
        header: String,
        /// What to do.
        hint: String,
    },
    /// An axis named for validation is not in the trace.
    #[error("{file}: no axis {axis} in the trace (it has: {has})")]
    AxisNotInTrace {
        /// The trace.
        file: String,
        /// The axis.
        axis: AxisName,
        /// The trace's axes.
        has: String,
    },
    /// A command that runs identified models got none, on a machine with virtual drives.
    #[error(
        "{command} needs identified models: give --model model.toml (written by `vcnc identify`); only a machine made of identified models ({file} has virtual drives on {drives}) supplies its own"
    )]
    NeedsModels {
        /// The command.
        command: &'static str,
        /// The machine file.
        file: String,
        /// The axes with virtual drives.
        drives: String,
    },
    /// A model file without a model of an axis named.
    #[error("{file}: no model for axis {axis} (it has: {has})")]
    NoModelFor {
        /// The model file.
        file: String,
        /// The axis.
        axis: AxisName,
        /// The axes it has models of.
        has: String,
    },
    /// No axis of a trace has a model.
    #[error(
        "no axis of {file} ({trace_axes}) has a model in {model_file} ({model_axes}); name the \
         trace's axis with --axis, or its columns with --xr-col/--x-col and --axis"
    )]
    NothingToValidate {
        /// The trace.
        file: String,
        /// Its axes.
        trace_axes: String,
        /// The model file.
        model_file: String,
        /// Its axes.
        model_axes: String,
    },
    /// A model in another unit than the trace's axis.
    #[error("{file}: the model of axis {axis} is in {model}, the trace's axis in {trace}")]
    UnitMismatch {
        /// The model file.
        file: String,
        /// The axis.
        axis: AxisName,
        /// The model's unit.
        model: vcnc_axis::Unit,
        /// The trace's unit.
        trace: vcnc_axis::Unit,
    },
    /// A model's free run diverges on a trace.
    #[error(
        "{subject}: the model's free run diverges on this trace (is the model stable, and the \
         trace's sample period {ts_s} s right?)"
    )]
    FreeRunDiverges {
        /// The trace and axis.
        subject: String,
        /// The trace's sample period, s.
        ts_s: f64,
    },
    /// A velocity headroom outside (0, 1].
    #[error("the velocity headroom must lie in (0, 1], got {headroom}")]
    Headroom {
        /// The headroom given.
        headroom: f64,
    },
    /// A program without samples to compensate.
    #[error("{file}: the program has no samples")]
    EmptyProgram {
        /// The program.
        file: String,
    },
    /// A model whose inverse settles too slowly to compensate with.
    #[error(
        "axis {axis}: the model's inverse needs {lead_s:.3} s of lead and {tail_s:.3} s of tail \
         to settle, more than {max_s} s (a zero of the sampled model lies close to the unit circle)"
    )]
    SlowInverse {
        /// The axis.
        axis: AxisName,
        /// Lead needed, s.
        lead_s: f64,
        /// Tail needed, s.
        tail_s: f64,
        /// The most allowed, s.
        max_s: f64,
    },
    /// A compensated program read back runs another number of samples than its set-points
    /// (vcnc's own failure).
    #[error(
        "internal error: the compensated program runs {program} samples, the set-points have \
         {set_points}"
    )]
    SampleCount {
        /// Samples of the program read back.
        program: usize,
        /// Set-points written.
        set_points: usize,
    },
    /// The interpolator returned no track for an identification program (vcnc's own failure).
    #[error("internal error: {program}: the interpolator returned no track")]
    NoTrack {
        /// The program.
        program: String,
    },
    /// A compensated program read back does not give the set-points it was written from
    /// (vcnc's own failure).
    #[error(
        "internal error: {program} does not reproduce the set-points of axis {axis} (off by {off:e}, written within {bound:e})"
    )]
    NotReproduced {
        /// The compensated program.
        program: String,
        /// The first axis off.
        axis: AxisName,
        /// Its largest position difference, axis units.
        off: f64,
        /// The largest the writer measured (rounding and chord error), axis units.
        bound: f64,
    },
    /// A run ended before every sample was finished (vcnc's own failure).
    #[error("internal error: the {run} finished {finished} of {samples} samples")]
    Unfinished {
        /// Which run.
        run: &'static str,
        /// Samples finished.
        finished: usize,
        /// Samples of the program.
        samples: usize,
    },
    /// Configurations of a sweep whose machine cannot be built (an unreachable controller
    /// design, a value out of its range), found before anything runs.
    #[error(
        "{count} of {total} configurations of the sweep cannot be built, e.g. #{first_index} {first_set}: {first}; narrow the swept ranges to values the machine accepts, or pass --keep-going to record them as failed rows"
    )]
    InvalidConfigurations {
        /// How many cannot be built.
        count: usize,
        /// Configurations of the shard.
        total: usize,
        /// Index of the first.
        first_index: usize,
        /// Its values (`key=value ...`).
        first_set: String,
        /// Its error.
        first: String,
    },
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
            Error::Compensate { source, .. } => source.is_bad_input(),
            Error::Io { .. }
            | Error::ToolTable(_)
            | Error::NoMotion { .. }
            | Error::Program { .. }
            | Error::Travel { .. }
            | Error::Table { .. }
            | Error::Trace(_)
            | Error::Limit { .. }
            | Error::Argument { .. }
            | Error::NoSuchAxis { .. }
            | Error::TooManyConfigurations { .. }
            | Error::Shard { .. }
            | Error::DuplicateConfiguration { .. }
            | Error::NoShards
            | Error::Generator { .. }
            | Error::FeedPlanOption { .. }
            | Error::NothingToPlan { .. }
            | Error::ControlFilters { .. }
            | Error::ToleranceUnreachable { .. }
            | Error::ProgramTooLarge { .. }
            | Error::TooManyBlocks { .. }
            | Error::MissingColumn { .. }
            | Error::AxisNotInTrace { .. }
            | Error::NeedsModels { .. }
            | Error::NoModelFor { .. }
            | Error::NothingToValidate { .. }
            | Error::UnitMismatch { .. }
            | Error::FreeRunDiverges { .. }
            | Error::Headroom { .. }
            | Error::EmptyProgram { .. }
            | Error::SlowInverse { .. }
            | Error::InvalidConfigurations { .. } => true,
            Error::SweepFailed { .. }
            | Error::GeneratorOutput { .. }
            | Error::SampleCount { .. }
            | Error::NoTrack { .. }
            | Error::Unfinished { .. }
            | Error::NotReproduced { .. } => false,
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
        assert!(
            !Error::Unfinished {
                run: "prediction",
                finished: 1,
                samples: 2
            }
            .is_bad_input()
        );
        let m: Error = vcnc_machine::Error::NoKinematics {
            file: "m.toml".into(),
        }
        .into();
        assert!(m.is_bad_input());
    }
}
