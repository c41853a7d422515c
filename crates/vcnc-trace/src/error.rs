//! The crate's error type: every variant names the file, the line where the file says it (when
//! one does) and the offending value.

use vcnc_axis::AxisName;

use crate::model::{Format, Quantity};

/// One format [`crate::detect()`] tried, and why it did not match.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Attempt {
    /// The format tried.
    pub format: Format,
    /// What the content lacked.
    pub reason: String,
}

fn list_attempts(tried: &[Attempt]) -> String {
    tried
        .iter()
        .map(|a| format!("{} ({}): {}", a.format.key(), a.format, a.reason))
        .collect::<Vec<_>>()
        .join("; ")
}

/// A time for messages: ten significant digits, shortest form (0.0009, not 0.0009000000000000001).
fn secs(v: &f64) -> String {
    format!("{v:.9e}")
        .parse::<f64>()
        .map_or_else(|_| v.to_string(), |r| r.to_string())
}

fn system_name(system: u8) -> &'static str {
    match system {
        1 => "the motor encoder",
        2 => "the direct measuring system",
        _ => "a measuring system",
    }
}

fn list(names: &[String]) -> String {
    if names.is_empty() {
        "none".to_string()
    } else {
        names.join(", ")
    }
}

/// What a refusal of an axis without an axis letter suggests.
fn axis_hint(number: &Option<u32>) -> String {
    match number {
        Some(n) => format!(
            "it is axis number {n} of the file, which no axis map names: pass --axis-map {n}=A \
             (A its machine axis letter), or --axis A alone for a file of one axis"
        ),
        None => "its name holds no axis letter (X Y Z A B C) or joint number: pass --axis A \
                 --xr-col NOMINAL --x-col ACTUAL (names or 0-based columns from `vcnc trace \
                 info`), or --axis A alone for a file of one axis"
            .to_string(),
    }
}

fn describe_lost(l: &Option<usize>) -> String {
    match l {
        Some(1) => "1 sample lost".to_string(),
        Some(n) => format!("{n} samples lost"),
        None => "an unknown number of samples lost".to_string(),
    }
}

/// Errors of trace reading and pairing.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// The file cannot be read.
    #[error("{file}: cannot read: {message}")]
    Io {
        /// The file.
        file: String,
        /// The operating system's message.
        message: String,
    },
    /// A Parquet file the `parquet` crate cannot read (a damaged or cut-short file).
    #[error("{file}: not a readable Parquet table: {what}")]
    Parquet {
        /// The file.
        file: String,
        /// The `parquet` crate's message, or what is missing.
        what: String,
    },
    /// No reader recognises the content.
    #[error("{file}: not a trace format vcnc reads; tried {}", list_attempts(.tried))]
    UnknownFormat {
        /// The file.
        file: String,
        /// Every format tried, in order, with what the content lacked.
        tried: Vec<Attempt>,
    },
    /// A header, metadata block or declaration is malformed.
    #[error("{file}:{line}: {what}")]
    Header {
        /// The file.
        file: String,
        /// The line.
        line: usize,
        /// What is wrong, with the text found.
        what: String,
    },
    /// The file ends before its structure is complete.
    #[error("{file}:{line}: the file ends early: {what}")]
    Truncated {
        /// The file.
        file: String,
        /// The last line.
        line: usize,
        /// What is missing.
        what: String,
    },
    /// A data row has another number of fields than the header declares.
    #[error("{file}:{line}: {found} fields where {expected} are expected")]
    FieldCount {
        /// The file.
        file: String,
        /// The row's line.
        line: usize,
        /// Fields declared.
        expected: usize,
        /// Fields found.
        found: usize,
    },
    /// A channel's declared sample count differs from the samples in the file.
    #[error(
        "{file}:{line}: channel '{channel}' holds {found} samples where {declared} are expected"
    )]
    CountMismatch {
        /// The file.
        file: String,
        /// The line of the declaration.
        line: usize,
        /// The channel.
        channel: String,
        /// Samples declared (TNCscope `COUNT`, or the other channels' count).
        declared: usize,
        /// Samples found.
        found: usize,
    },
    /// A field is not a number.
    #[error("{file}:{line}: {column}: '{text}' is not a number")]
    NotANumber {
        /// The file.
        file: String,
        /// The line.
        line: usize,
        /// The column's or attribute's name.
        column: String,
        /// The field as written.
        text: String,
    },
    /// A field is NaN or infinite.
    #[error("{file}:{line}: {column} is {text}: not a finite number")]
    NotFinite {
        /// The file.
        file: String,
        /// The line.
        line: usize,
        /// The column's or attribute's name.
        column: String,
        /// The field as written.
        text: String,
    },
    /// Time stands still or goes back.
    #[error("{file}:{line}: time does not increase: {} s, then {} s", secs(.t_prev_s), secs(.t_s))]
    TimeNotIncreasing {
        /// The file.
        file: String,
        /// The line of the later sample.
        line: usize,
        /// Time of the sample before, s.
        t_prev_s: f64,
        /// Time of this sample, s.
        t_s: f64,
    },
    /// A time step is neither the sample period nor a whole multiple of it (a gap).
    #[error(
        "{file}:{line}: irregular time step {} s: the sample period is {} s (a step must be within 20 % of a whole number of periods)",
        secs(.dt_s),
        secs(.period_s)
    )]
    IrregularTime {
        /// The file.
        file: String,
        /// The line of the later sample.
        line: usize,
        /// The step, s.
        dt_s: f64,
        /// The sample period, s.
        period_s: f64,
    },
    /// Samples were lost where the pairing needs contiguous ones (gap policy `Refuse`).
    #[error(
        "{file}:{line}: channel '{channel}': {} here; identification across lost samples is refused (use the longest gap-free stretch with --gaps longest, or record again)",
        describe_lost(.lost)
    )]
    Gap {
        /// The file.
        file: String,
        /// The line where the gap shows.
        line: usize,
        /// The channel.
        channel: String,
        /// Samples lost, when known.
        lost: Option<usize>,
    },
    /// A position channel's unit is none vcnc knows.
    #[error(
        "{file}:{line}: channel '{channel}': unknown unit '{unit}' (known: nm µm mm cm m inch deg mdeg rad, and their /s and /min rates); say which it is with --units U"
    )]
    UnknownUnit {
        /// The file.
        file: String,
        /// The line where the unit is stated.
        line: usize,
        /// The channel.
        channel: String,
        /// The unit as written.
        unit: String,
    },
    /// A unit of the wrong kind for the channel's axis (a velocity unit for a position, mm for a
    /// rotary axis, …).
    #[error("{file}:{line}: channel '{channel}' is in {unit}: axis {axis} needs {expected}")]
    WrongUnit {
        /// The file.
        file: String,
        /// The line where the unit is stated.
        line: usize,
        /// The channel.
        channel: String,
        /// The unit.
        unit: String,
        /// The axis.
        axis: AxisName,
        /// The kind of unit needed.
        expected: String,
    },
    /// The caller's units contradict the file's.
    #[error(
        "{file}:{line}: channel '{channel}' is in {file_unit} according to the file, but the units given are {given_unit}: drop --units (it is for files that state no unit)"
    )]
    UnitConflict {
        /// The file.
        file: String,
        /// The line where the file states its unit.
        line: usize,
        /// The channel.
        channel: String,
        /// The file's unit.
        file_unit: String,
        /// The caller's unit.
        given_unit: String,
    },
    /// An axis lacks a nominal or an actual position channel.
    #[error(
        "{file}: no {quantity} channel for axis {axis}; channels: {}; name both with --axis {axis} --xr-col NOMINAL --x-col ACTUAL",
        list(.channels)
    )]
    MissingChannel {
        /// The file.
        file: String,
        /// The axis.
        axis: AxisName,
        /// The quantity looked for.
        quantity: Quantity,
        /// Every channel of the file, with its axis and quantity.
        channels: Vec<String>,
    },
    /// The file has no pair of nominal and actual position channels of one axis.
    #[error(
        "{file}: no axis has both a nominal and an actual position channel; channels: {}; name them explicitly: --axis A --xr-col NOMINAL --x-col ACTUAL (names or 0-based columns from `vcnc trace info`), with --units U where the file states no unit (mm and deg are assumed)",
        list(.channels)
    )]
    NoPositions {
        /// The file.
        file: String,
        /// Every channel of the file, with its axis and quantity.
        channels: Vec<String>,
    },
    /// A position channel whose name matches no axis, and no axis was found.
    #[error(
        "{file}:{line}: channel '{channel}' ({quantity}) matches no axis: {}",
        axis_hint(.axis_number)
    )]
    NoAxis {
        /// The file.
        file: String,
        /// The line of the channel's declaration.
        line: usize,
        /// The channel.
        channel: String,
        /// Its quantity.
        quantity: Quantity,
        /// The axis number the file gives it, if any (a Sinumerik NCK axis number).
        axis_number: Option<u32>,
    },
    /// Several channels qualify for one role.
    #[error(
        "{file}: axis {axis} has several {quantity} channels: {}; choose with --axis {axis} --xr-col NOMINAL --x-col ACTUAL",
        list(.channels)
    )]
    Ambiguous {
        /// The file.
        file: String,
        /// The axis.
        axis: AxisName,
        /// The role.
        quantity: Quantity,
        /// The candidates.
        channels: Vec<String>,
    },
    /// The caller named a channel the file does not have.
    #[error("{file}: no channel {reference}; channels: {}", list(.channels))]
    UnknownChannel {
        /// The file.
        file: String,
        /// The reference as given.
        reference: String,
        /// The file's channels.
        channels: Vec<String>,
    },
    /// A channel has no sample period and none was given.
    #[error(
        "{file}: channel '{channel}' has no sample period (the file states none): give the period with --ts SECONDS (halsampler: the sampler thread's period times its decimation), or name a time column with --t-col NAME"
    )]
    MissingPeriod {
        /// The file.
        file: String,
        /// The channel.
        channel: String,
    },
    /// The period given contradicts the file's.
    #[error(
        "{file}:{line}: channel '{channel}': the file's sample period is {} s, the period given is {} s; drop --ts (it is for files without a time base)",
        secs(.file_s),
        secs(.given_s)
    )]
    PeriodConflict {
        /// The file.
        file: String,
        /// The line stating the period.
        line: usize,
        /// The channel.
        channel: String,
        /// The file's period, s.
        file_s: f64,
        /// The caller's period, s.
        given_s: f64,
    },
    /// The nominal and actual channels of an axis do not overlap in time.
    #[error("{file}: axis {axis}: '{nominal}' and '{actual}' share fewer than two sample times")]
    NoOverlap {
        /// The file.
        file: String,
        /// The axis.
        axis: AxisName,
        /// The nominal channel.
        nominal: String,
        /// The actual channel.
        actual: String,
    },
    /// The XML is not well formed.
    #[error("{file}:{line}: XML: {message}")]
    Xml {
        /// The file.
        file: String,
        /// The line.
        line: usize,
        /// The parser's message.
        message: String,
    },
    /// A setpoint of one measuring system, and no actual position of that system.
    #[error(
        "{file}:{line}: axis {axis}: the setpoint '{setpoint}' is for measuring system {system} ({}), but the file has no actual position of measuring system {system} (actual positions: {}); a setpoint paired with another system's actual would take the lost motion between the systems for drive dynamics: record the actual position of measuring system {system}, or name the channels with --axis {axis} --xr-col NOMINAL --x-col ACTUAL",
        system_name(*.system),
        list(.actuals)
    )]
    NoActualOfSystem {
        /// The file.
        file: String,
        /// The line of the setpoint's declaration.
        line: usize,
        /// The axis.
        axis: AxisName,
        /// The setpoint channel.
        setpoint: String,
        /// Its measuring system (1 motor encoder, 2 direct).
        system: u8,
        /// The axis' actual-position channels, with their systems.
        actuals: Vec<String>,
    },
    /// Lost motion asked of an axis recorded with one measuring system.
    #[error(
        "{file}: axis {axis}: lost motion needs the actual positions of both measuring systems (motor encoder and direct scale); the trace has one"
    )]
    NoOtherSystem {
        /// The file.
        file: String,
        /// The axis.
        axis: AxisName,
    },
    /// Lost motion asked of a trace whose setpoint never reverses.
    #[error(
        "{file}: axis {axis}: the setpoint reverses {reversals} time(s); lost motion is measured at reversals and needs at least one, each after a move of more than {} (axis unit)",
        secs(.hysteresis)
    )]
    NoReversal {
        /// The file.
        file: String,
        /// The axis.
        axis: AxisName,
        /// Reversals found.
        reversals: usize,
        /// The smallest move that counts, axis unit.
        hysteresis: f64,
    },
    /// A command-line option's value is invalid.
    #[error("--{option} {value}: {what}")]
    Argument {
        /// The option, without its dashes (`axis-map`).
        option: &'static str,
        /// The value as given.
        value: String,
        /// What was expected.
        what: String,
    },
    /// A time column named for a format that has a time base of its own.
    #[error(
        "{file}: --t-col {column}: {format} files carry their own time base; --t-col is for delimited text, halsampler and halscope files"
    )]
    TimeColumnNotApplicable {
        /// The file.
        file: String,
        /// The column as given.
        column: String,
        /// The file's format.
        format: Format,
    },
    /// An option is invalid (a non-positive period, a wrong number of channel names, …).
    #[error("{file}: {what}")]
    BadOption {
        /// The file being read.
        file: String,
        /// What is wrong.
        what: String,
    },
}

impl Error {
    /// The line the error points at, when it points at one.
    pub fn line(&self) -> Option<usize> {
        match self {
            Error::Header { line, .. }
            | Error::Truncated { line, .. }
            | Error::FieldCount { line, .. }
            | Error::CountMismatch { line, .. }
            | Error::NotANumber { line, .. }
            | Error::NotFinite { line, .. }
            | Error::TimeNotIncreasing { line, .. }
            | Error::IrregularTime { line, .. }
            | Error::Gap { line, .. }
            | Error::UnknownUnit { line, .. }
            | Error::WrongUnit { line, .. }
            | Error::UnitConflict { line, .. }
            | Error::NoAxis { line, .. }
            | Error::NoActualOfSystem { line, .. }
            | Error::PeriodConflict { line, .. }
            | Error::Xml { line, .. } => Some(*line),
            _ => None,
        }
    }
}
