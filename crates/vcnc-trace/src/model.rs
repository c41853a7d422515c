//! The typed trace every reader returns: channels with their axis, quantity, unit, sampling and
//! samples; and the options that steer reading.

use std::fmt;

use serde::{Deserialize, Serialize};
use vcnc_axis::AxisName;

use crate::options::AxisNumberMap;
use crate::units::TraceUnit;

/// The file formats vcnc reads, in the order [`crate::detect`] tries them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Format {
    /// Siemens Sinumerik Operate servo trace, XML (`<dataSignal>` declarations, `<rec>` records).
    SinumerikTrace,
    /// Heidenhain TNCscope text export (`%TNCscopeNT data file`, `%[CURVEn]` blocks, `%[DATA]`).
    TncScope,
    /// LinuxCNC halscope log, the `;`-separated table written since 2.9
    /// (`# Sampling period is N ns`, channel names, `# Position:`/`# Scale:`).
    HalscopeTable,
    /// LinuxCNC halscope log before 2.9: `Sampling period is N ns`, then `name value` pairs.
    HalscopeInterlaced,
    /// Beckhoff TwinCAT Scope CSV export (header block, per-channel metadata rows, time/value
    /// column groups).
    TwinCatScope,
    /// LinuxCNC halsampler output: white-space columns, optional sample number, `overrun` lines.
    Halsampler,
    /// Generic delimited text (`,` `;` tab or spaces; optional header; either decimal mark).
    Delimited,
    /// Apache Parquet table, one numeric column per channel (vcnc's own tables).
    Parquet,
}

impl Format {
    /// Every format, in detection order.
    pub const ALL: [Format; 8] = [
        Format::Parquet,
        Format::SinumerikTrace,
        Format::TncScope,
        Format::HalscopeTable,
        Format::HalscopeInterlaced,
        Format::TwinCatScope,
        Format::Halsampler,
        Format::Delimited,
    ];

    /// A short stable key (`halscope`, `tncscope`, …) for summaries and command-line options.
    pub const fn key(self) -> &'static str {
        match self {
            Format::SinumerikTrace => "sinumerik",
            Format::TncScope => "tncscope",
            Format::HalscopeTable => "halscope",
            Format::HalscopeInterlaced => "halscope-pairs",
            Format::TwinCatScope => "twincat",
            Format::Halsampler => "halsampler",
            Format::Delimited => "delimited",
            Format::Parquet => "parquet",
        }
    }

    /// The format whose [`Format::key`] is `key`.
    pub fn from_key(key: &str) -> Option<Format> {
        Format::ALL.into_iter().find(|f| f.key() == key)
    }

    /// The name people know it by.
    pub const fn describe(self) -> &'static str {
        match self {
            Format::SinumerikTrace => "Siemens Sinumerik Operate servo trace (XML)",
            Format::TncScope => "Heidenhain TNCscope text export",
            Format::HalscopeTable => "LinuxCNC halscope log (table, 2.9+)",
            Format::HalscopeInterlaced => "LinuxCNC halscope log (name-value pairs, before 2.9)",
            Format::TwinCatScope => "Beckhoff TwinCAT Scope CSV export",
            Format::Halsampler => "LinuxCNC halsampler output",
            Format::Delimited => "delimited text",
            Format::Parquet => "Apache Parquet table",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.describe())
    }
}

/// What a channel measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Quantity {
    /// The commanded (reference, set-point) position $x_r$.
    NominalPosition,
    /// The measured (feedback) position $x$.
    ActualPosition,
    /// The commanded velocity.
    NominalVelocity,
    /// The measured velocity.
    ActualVelocity,
    /// A motor current (commanded or measured).
    Current,
    /// Anything else (following error, acceleration, torque, digital signals, …).
    Other,
}

impl Quantity {
    /// Lower-case words (`nominal position`, …).
    pub const fn describe(self) -> &'static str {
        match self {
            Quantity::NominalPosition => "nominal position",
            Quantity::ActualPosition => "actual position",
            Quantity::NominalVelocity => "nominal velocity",
            Quantity::ActualVelocity => "actual velocity",
            Quantity::Current => "current",
            Quantity::Other => "other",
        }
    }

    /// Whether the quantity is a position (nominal or actual).
    pub const fn is_position(self) -> bool {
        matches!(self, Quantity::NominalPosition | Quantity::ActualPosition)
    }
}

impl fmt::Display for Quantity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.describe())
    }
}

/// How a channel's axis was found.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum AxisSource {
    /// An axis letter (optionally with digits, `X1`, or a quantity suffix, `xr`) among the words
    /// of a name field: `field` says which (`name`, `symbol`, `description`, `path`).
    Token {
        /// The field the word came from.
        field: String,
        /// The word, as written.
        token: String,
    },
    /// A LinuxCNC joint number (`joint.N.…`, or `axis.N.…` before 2.8) through the joint-to-axis
    /// map of [`ReadOptions::joints`].
    Joint {
        /// The joint number N.
        joint: usize,
        /// The joint map used, as letters (`XYZABC`).
        map: String,
    },
    /// An axis field of the file (TNCscope `AXISTYPE`).
    Declared {
        /// The key of the field.
        key: String,
        /// Its value.
        value: String,
    },
    /// An axis number of the file (the servo's NCK axis number `N` of a Sinumerik path
    /// `…[u1, N]`) through the caller's axis map ([`ReadOptions::axis_map`]).
    Number {
        /// The axis number N.
        number: u32,
        /// The axis map used, as written (`1=X,2=Y`).
        map: String,
    },
    /// Assigned by the caller ([`crate::AxisMap`], or the one `--axis` of a file whose position
    /// channels belong to one unnamed axis).
    Caller,
}

impl fmt::Display for AxisSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AxisSource::Token { field, token } => write!(f, "{field} word '{token}'"),
            AxisSource::Joint { joint, map } => write!(f, "joint {joint} (joint map {map})"),
            AxisSource::Declared { key, value } => write!(f, "{key}={value}"),
            AxisSource::Number { number, map } => {
                write!(f, "axis number {number} (axis map {map})")
            }
            AxisSource::Caller => f.write_str("caller"),
        }
    }
}

/// Samples lost inside a channel: the samples before index `index` and from it on are not
/// contiguous.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Gap {
    /// Index (into [`Channel::samples`]) of the first sample after the gap.
    pub index: usize,
    /// Line of the file where the gap shows (the `overrun` line, or the row after the jump in
    /// time).
    pub line: usize,
    /// How many samples were lost, when the file tells (a time column, a sample number); `None`
    /// for a halsampler `overrun` without sample numbers.
    pub lost: Option<usize>,
}

/// One recorded signal.
///
/// Samples are uniform: sample $k$ was taken at $t_0 + (k + L_k)\,T$, where $T$ is
/// [`Channel::period_s`] and $L_k$ the samples lost in the [`Channel::gaps`] before $k$.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Channel {
    /// The channel's name in the file (halscope pin/signal, TNCscope `NAME`, Sinumerik
    /// description, TwinCAT `Name`, column header).
    pub name: String,
    /// Further identification from the file, empty when none: TwinCAT `SymbolName`, Sinumerik NCK
    /// path, TNCscope `CHANNELTYPE`.
    pub description: String,
    /// The machine axis, when the file's names or fields tell (see [`AxisSource`]).
    pub axis: Option<AxisName>,
    /// How [`Channel::axis`] was found.
    pub axis_source: Option<AxisSource>,
    /// The axis number the file gives, when it numbers axes rather than naming them (the NCK
    /// axis number `N` of a Sinumerik path `/Nck/!SD/nckServoData…[u1, N]`); mapped to
    /// [`Channel::axis`] through [`ReadOptions::axis_map`].
    pub axis_number: Option<u32>,
    /// What the channel measures.
    pub quantity: Quantity,
    /// The measuring system a position belongs to, when the file says: 1 the motor encoder,
    /// 2 the direct measuring system (scale). A Sinumerik setpoint `CmdPos2ndEnc` is the
    /// setpoint for system 2 and is paired with the actual position `ActPos2ndEnc`
    /// ([`crate::pair`]).
    pub measuring_system: Option<u8>,
    /// The unit the file states; `None` when it states none (halscope, halsampler, Sinumerik,
    /// headers without units): the caller's units then decide ([`crate::PairOptions`]).
    pub unit: Option<TraceUnit>,
    /// Sample period $T$, s — the recording interval; `None` when the file carries none and the
    /// caller gave none (halsampler, delimited text without a time column).
    pub period_s: Option<f64>,
    /// The control cycle the signal is computed at, s, where the file states it apart from the
    /// recording interval (TNCscope `CYCLETIME`: 100 µs for a current, 3 ms for a position);
    /// informative only, samples are at [`Channel::period_s`].
    pub cycle_s: Option<f64>,
    /// Time of the first sample $t_0$, s (0 when the file has no time column).
    pub t0_s: f64,
    /// The samples, in [`Channel::unit`].
    pub samples: Vec<f64>,
    /// Places where samples were lost (empty for a contiguous record).
    pub gaps: Vec<Gap>,
    /// Line of the file where the channel is declared (header row, `%[CURVEn]` block,
    /// `<dataSignal>` element); 1-based.
    pub line: usize,
    /// Column of the channel's values in the file's data rows, 0-based and counting time
    /// columns (the `fN` number minus one for a Sinumerik trace).
    pub column: usize,
}

impl Channel {
    /// A channel with no axis, quantity [`Quantity::Other`], no unit, no period, no samples.
    pub fn new(name: impl Into<String>, line: usize, column: usize) -> Channel {
        Channel {
            name: name.into(),
            description: String::new(),
            axis: None,
            axis_source: None,
            axis_number: None,
            quantity: Quantity::Other,
            measuring_system: None,
            unit: None,
            period_s: None,
            cycle_s: None,
            t0_s: 0.0,
            samples: Vec::new(),
            gaps: Vec::new(),
            line,
            column,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether the channel holds no sample.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Samples lost in all gaps, `None` when one gap's count is unknown.
    pub fn lost_samples(&self) -> Option<usize> {
        self.gaps
            .iter()
            .try_fold(0, |acc, g| g.lost.map(|l| acc + l))
    }
}

/// A trace file read into channels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trace {
    /// The file, as given to the reader (used in every error message).
    pub file: String,
    /// The format found.
    pub format: Format,
    /// The channels, in file order.
    pub channels: Vec<Channel>,
    /// File-level fields (TNCscope `%[GLOBAL]` keys, TwinCAT header rows, halscope comment lines),
    /// in file order.
    pub metadata: Vec<(String, String)>,
}

/// A channel named by the caller: by name (exact, else case-insensitive) or by file column.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum ChannelRef {
    /// The channel's [`Channel::name`] (or its [`Channel::description`]).
    Name(String),
    /// The channel's [`Channel::column`], 0-based.
    Column(usize),
}

impl fmt::Display for ChannelRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ChannelRef::Name(n) => write!(f, "'{n}'"),
            ChannelRef::Column(c) => write!(f, "column {c}"),
        }
    }
}

impl ChannelRef {
    /// Reads a command-line reference: a number is a column, anything else a name.
    pub fn parse(s: &str) -> ChannelRef {
        match s.trim().parse::<usize>() {
            Ok(c) => ChannelRef::Column(c),
            Err(_) => ChannelRef::Name(s.to_string()),
        }
    }
}

/// Options of [`crate::read_path`]; [`ReadOptions::default`] suits files that describe
/// themselves.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadOptions {
    /// Read as this format instead of detecting it from the content.
    pub format: Option<Format>,
    /// Sample period, s, for files that carry none (halsampler; delimited text without a time
    /// column). A file that states a period keeps it; if this differs from it by more than 0.1 %,
    /// reading fails (`Error::PeriodConflict`).
    pub period_s: Option<f64>,
    /// LinuxCNC joint-to-axis map: joint `i` is axis `joints[i]`. Default `X Y Z A B C`
    /// (trivkins' default coordinates); a table-tilting A/C machine with five joints is
    /// `X Y Z A C`.
    pub joints: Vec<AxisName>,
    /// Axis numbers to axes, for files that number their axes (Sinumerik NCK axis numbers
    /// `[u1, N]`); empty: numbered channels get no axis (`--axis-map 1=X,2=Y`).
    pub axis_map: AxisNumberMap,
    /// Channel names for files without names (halsampler columns, headerless delimited text),
    /// in column order (a halsampler sample-number column not counted).
    pub channel_names: Vec<String>,
    /// The time column, for files whose time is a column like any other: delimited text
    /// (default: a column named `t`, `time`, `zeit` or `timestamp`, with or without a unit) and
    /// halsampler output (a sampled time signal, in s; default none). Formats with a time base
    /// of their own (halscope, TNCscope, Sinumerik, TwinCAT) refuse it
    /// (`Error::TimeColumnNotApplicable`).
    pub time_column: Option<ChannelRef>,
    /// Unit of the time column when the file states none (default s).
    pub time_unit: Option<TraceUnit>,
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions {
            format: None,
            period_s: None,
            joints: AxisName::ALL.to_vec(),
            axis_map: AxisNumberMap::default(),
            channel_names: Vec::new(),
            time_column: None,
            time_unit: None,
        }
    }
}
