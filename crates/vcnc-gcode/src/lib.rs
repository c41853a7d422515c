//! G-code front end of vcnc: parsing, interpretation, trapezoidal interpolation at the sample
//! period, and the program generators (docs/gcode.md). The language — RS274/NGC as LinuxCNC
//! runs it, with parameters, expressions, O-word control flow, offsets, canned cycles and cutter
//! radius compensation — is
//! described in docs/gcode.md, and checked against LinuxCNC's own interpreter
//! (`tests/linuxcnc.rs`).
//!
//! The stages are kept apart (STYLE, the gcode-rs model):
//!
//! | module | input → output | main type |
//! |---|---|---|
//! | [`syntax`] | text → blocks, words, expressions, O-words, comments with spans; every diagnostic | [`Program`] |
//! | [`interp`] | blocks → moves in mm and degrees, machine coordinates (parameters, control flow, modal state, offsets, cycles, arcs, feeds, cutter compensation) | [`Toolpath`] |
//! | [`tables`] | LinuxCNC parameter file and tool table → typed tables | [`ParameterTable`], [`ToolTable`] |
//! | [`interpolate`](mod@interpolate) | moves + limits → samples of position, velocity, acceleration, with each sample's source line and move class | [`Trajectory`] |
//! | [`generate`] | options → G-code text (identification excitation, 5-axis spiral) | `String` |
//!
//! ```
//! use vcnc_gcode::{load, InterpOptions, InterpolateOptions, Limits};
//!
//! let src = "G21 G90 G61\nG0 X0\nG1 X10 F600\nM2\n";
//! let limits = Limits::uniform(250.0, 2500.0);
//! let run = load(src, &InterpOptions::default(), &limits, &InterpolateOptions::default()).unwrap();
//! // 10 mm at 10 mm/s with 2500 mm/s²: T = L/V + V/A = 1.004 s.
//! assert!((run.trajectory.duration_s() - 1.004).abs() < 1e-9);
//! assert_eq!(run.trajectory.axis(vcnc_gcode::AxisName::X).unwrap().pos.last(), Some(&10.0));
//! ```

pub mod diag;
pub mod generate;
pub mod interp;
pub mod interpolate;
pub mod syntax;
pub mod tables;
pub mod write;

pub use diag::{Diagnostic, DiagnosticKind, Severity, Span};
pub use generate::{
    IdentificationOptions, SpiralOptions, TcpProgramOptions, TipPose, identification,
    spiral_points, tcp_program,
};
pub use interp::{
    ArcMove, ChunkInterp, Feed, InterpOptions, Move, MoveKind, PathMode, Plane, ProgramRead,
    StartPosition, Toolpath, interpret,
};
pub use interpolate::planner::FINE_BLOCK_MAX_SAMPLES;
pub use interpolate::stream::{ProgramSource, SampleChunk, StreamOptions, StreamPlan, plan};
pub use interpolate::{
    AxisLimits, AxisTrack, BlockSpan, CycleTime, InterpolateOptions, Limits, MoveClass,
    PlannerRules, Profile, Slowdown, Trajectory, interpolate,
};
pub use syntax::{
    Assignment, BinOp, Block, ChunkParser, Comment, CommentKind, Expr, ExprId, ExprKind, Func,
    LineNumber, NameId, OLabel, OStatement, OWord, ParamRef, ParseOptions, Program, Word, parse,
    parse_bytes, parse_with,
};
pub use tables::{
    LengthUnit, ParameterTable, Tool, ToolTable, parse_parameter_file, parse_tool_table,
};

/// Axis names; their order ([`AxisName::ALL`]) is that of every `[f64; 6]` position: X Y Z
/// (mm), A B C (deg).
pub use vcnc_axis::AxisName;

/// Errors of this crate. Each carries the values needed to act on it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// The program has errors (parse or interpretation); all of them are listed.
    #[error("the program has {} error(s); first: {}", count_errors(.diagnostics), first_error(.diagnostics))]
    Program {
        /// Every diagnostic, errors and warnings, in order.
        diagnostics: Vec<Diagnostic>,
    },
    /// A limit is negative or not finite.
    #[error("limit {name} of {} is {value:?}; it must be a finite number ≥ 0", axis_label(*.axis))]
    InvalidLimit {
        /// The axis (`None` for the tool-tip path limits).
        axis: Option<AxisName>,
        /// Which limit.
        name: &'static str,
        /// The offending value.
        value: f64,
    },
    /// An option is out of its range.
    #[error("option {name} = {value:?} is invalid: expected {expected}")]
    InvalidOption {
        /// Option name.
        name: &'static str,
        /// The offending value.
        value: f64,
        /// What is accepted.
        expected: &'static str,
    },
    /// The jerk-limited profile was asked for without a jerk limit on any axis.
    #[error("the jerk-limited profile needs a jerk limit (max_jerk) on the axes; none is given")]
    NoJerkLimit,
    /// A move needs an axis whose limit is zero.
    #[error("line {line}: {} must move but its {what} limit is 0", axis_label(*.axis))]
    AxisCannotMove {
        /// The axis (`None` for the tool-tip path).
        axis: Option<AxisName>,
        /// `"velocity"` or `"acceleration"`.
        what: &'static str,
        /// Source line of the move.
        line: u32,
    },
    /// The trajectory would exceed [`InterpolateOptions::max_samples`].
    #[error(
        "the trajectory needs {samples:.0} samples ({duration_s:.3} s), more than the limit of {max}"
    )]
    TooManySamples {
        /// Samples needed (at least).
        samples: f64,
        /// The limit.
        max: usize,
        /// Duration reached, s.
        duration_s: f64,
    },
    /// A computed quantity is not finite (degenerate input).
    #[error("line {line}: {what} is not finite or not positive")]
    NonFinite {
        /// Source line.
        line: u32,
        /// What was computed.
        what: &'static str,
    },
    /// A line of a LinuxCNC parameter file (`.var`) is wrong.
    #[error("{file}:{line}: {reason}: '{text}'")]
    ParameterFile {
        /// The file's name, as given.
        file: String,
        /// Line number, 1-based.
        line: u32,
        /// The offending line (trimmed).
        text: String,
        /// What is wrong.
        reason: String,
    },
    /// A line of a LinuxCNC tool table (`.tbl`) is wrong.
    #[error("{file}:{line}: {reason}: '{text}'")]
    ToolTable {
        /// The file's name, as given.
        file: String,
        /// Line number, 1-based.
        line: u32,
        /// The offending word or line.
        text: String,
        /// What is wrong.
        reason: String,
    },
    /// The program file could not be read.
    #[error("cannot read the program: {message}")]
    Read {
        /// The operating system's message.
        message: String,
    },
    /// A generator option is out of range.
    #[error("generator option {name} = {value:?} is invalid: expected {expected}")]
    InvalidGenerator {
        /// Option name.
        name: &'static str,
        /// The offending value.
        value: f64,
        /// What is accepted.
        expected: &'static str,
    },
}

impl Error {
    /// Every error of this crate is about the program, the limits or the options it was given
    /// (exit code 2).
    pub fn is_bad_input(&self) -> bool {
        match self {
            Error::Program { .. }
            | Error::InvalidLimit { .. }
            | Error::InvalidOption { .. }
            | Error::NoJerkLimit
            | Error::AxisCannotMove { .. }
            | Error::TooManySamples { .. }
            | Error::NonFinite { .. }
            | Error::ParameterFile { .. }
            | Error::ToolTable { .. }
            | Error::InvalidGenerator { .. } => true,
            Error::Read { .. } => false,
        }
    }
}

/// `axis X`, or `the tool-tip path` for `None`.
fn axis_label(axis: Option<AxisName>) -> String {
    axis.map_or_else(|| "the tool-tip path".to_string(), |a| format!("axis {a}"))
}

fn count_errors(d: &[Diagnostic]) -> usize {
    d.iter().filter(|d| d.is_error()).count()
}

fn first_error(d: &[Diagnostic]) -> String {
    d.iter()
        .find(|d| d.is_error())
        .map_or_else(String::new, ToString::to_string)
}

/// Everything [`load`] produces.
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded {
    /// The syntax tree.
    pub program: Program,
    /// The interpreted moves.
    pub toolpath: Toolpath,
    /// The samples.
    pub trajectory: Trajectory,
    /// Every warning (parser, interpreter, interpolator), in that order.
    pub warnings: Vec<Diagnostic>,
}

/// Parse, interpret and interpolate `src` in one call.
///
/// [`InterpOptions::lenient`] also makes the parser lenient. Any error diagnostic gives
/// [`Error::Program`] with all diagnostics of the failing stage (and the parser's).
pub fn load(
    src: &str,
    interp_opts: &InterpOptions,
    limits: &Limits,
    opts: &InterpolateOptions,
) -> Result<Loaded, Error> {
    let (program, toolpath, diags) = parse_and_interpret(src, interp_opts)?;
    load_toolpath(program, toolpath, diags, limits, opts)
}

/// The first two stages of [`load`]: parse and interpret, returning the program, the toolpath
/// and the warnings so far. Callers that check the toolpath (for example against a machine's
/// axes) before interpolating use this and then [`load_toolpath`], instead of parsing twice.
pub fn parse_and_interpret(
    src: &str,
    interp_opts: &InterpOptions,
) -> Result<(Program, Toolpath, Vec<Diagnostic>), Error> {
    let parse_opts = ParseOptions {
        lenient: interp_opts.lenient,
        ..ParseOptions::default()
    };
    let (program, mut diags) = parse_with(src, &parse_opts);
    if diags.iter().any(Diagnostic::is_error) {
        return Err(Error::Program { diagnostics: diags });
    }
    match interpret(&program, interp_opts) {
        Ok((toolpath, warnings)) => {
            diags.extend(warnings);
            Ok((program, toolpath, diags))
        }
        Err(more) => {
            diags.extend(more);
            Err(Error::Program { diagnostics: diags })
        }
    }
}

/// The last stage of [`load`]: interpolates `toolpath` and gathers every warning.
pub fn load_toolpath(
    program: Program,
    toolpath: Toolpath,
    mut diags: Vec<Diagnostic>,
    limits: &Limits,
    opts: &InterpolateOptions,
) -> Result<Loaded, Error> {
    let trajectory = interpolate(&toolpath, limits, opts)?;
    diags.extend(trajectory.warnings.iter().cloned());
    Ok(Loaded {
        program,
        toolpath,
        trajectory,
        warnings: diags,
    })
}
