//! Read the traces CNC scopes save, and pair them per axis for identification. The user's view
//! (formats, units, periods, gaps, channel mapping, measured accuracy): `docs/traces.md`.
//!
//! ```text
//! file bytes ──► detect (content signatures, fixed order) ──► Format
//!      │
//!      └──► reader of that format ──► Trace { channels: name, axis, quantity, unit,
//!                                              period, t0, samples, gaps }
//!                                        │
//!                 Trace::info ◄──────────┤  (vcnc trace info)
//!                                        ▼
//!                   pair (choose, convert units, align, gap policy)
//!                                        │
//!                                        ▼
//!            Paired { axes: AxisTrace { axis, ts_s, nominal, actual, provenance } }
//! ```
//!
//! 1. [`detect()`]: the format from the content, never the file name; its documentation has the
//!    order and the signatures. An unrecognised file is [`Error::UnknownFormat`], listing every
//!    format tried and what the content lacked.
//! 2. The readers, one per [`Format`], each documented in [`formats`] with the public description
//!    it follows: LinuxCNC halscope logs (2.9+ table and the older name–value pairs), LinuxCNC
//!    halsampler output, Heidenhain TNCscope text exports, Siemens Sinumerik Operate servo traces
//!    (XML), Beckhoff TwinCAT Scope CSV exports, generic delimited text, and Parquet tables (what
//!    `vcnc simulate` writes beyond 200 000 rows). Each returns the
//!    same [`Trace`]. Data rows are parsed from byte slices into reused buffers, without
//!    allocating per row (`cargo bench -p vcnc-trace`: 1 M samples × 4 channels in 0.2–0.6 s on a shared 2-core VM).
//! 3. Each [`Channel`]'s axis and quantity are inferred from its name and the file's fields (the
//!    rules are in [`infer`]: axis letters, LinuxCNC joint numbers through
//!    [`ReadOptions::joints`], TNCscope `CHANNELTYPE`/`AXISTYPE`, TwinCAT symbol names, Sinumerik
//!    descriptions), its unit from the file ([`TraceUnit`], with its conversion table).
//! 4. Time columns are checked uniform up to gaps (a step within [`STEP_TOLERANCE`] of a whole
//!    number of periods); lost samples (halsampler `overrun`, jumps in time) become [`Gap`]s. The
//!    readers keep them, so `trace info` can list them; [`pair()`] refuses to identify across
//!    them unless told to use the longest gap-free stretch ([`GapPolicy`]).
//! 5. [`pair()`]: per axis the nominal and actual position channels, in mm or deg, on one time
//!    grid, with their [`Provenance`]; a setpoint of a named measuring system with the actual
//!    position of that system, the other system kept beside it, and [`lost_motion()`] between
//!    the two at the setpoint's reversals.
//! 6. [`TraceArgs`]: the command line's trace options as typed, checked into [`ReadOptions`]
//!    and [`PairOptions`] with errors that name the option ([`AxisNumberMap`]: `--axis-map`).
//!
//! ```
//! use vcnc_trace::{pair, read_bytes, Format, PairOptions, ReadOptions};
//!
//! let log = "# Sampling period is 1000000 ns\n\
//!            joint.0.motor-pos-cmd;joint.0.motor-pos-fb\n\
//!            0.0;0.0\n0.5;0.1\n1.0;0.4\n";
//! let trace = read_bytes("run.log", log.as_bytes(), &ReadOptions::default()).unwrap();
//! assert_eq!(trace.format, Format::HalscopeTable);
//! let paired = pair(&trace, &PairOptions::default()).unwrap();
//! let x = &paired.axes[0];
//! assert_eq!(x.axis.to_string(), "X");
//! assert_eq!(x.ts_s, 1e-3);
//! assert_eq!(x.actual, [0.0, 0.1, 0.4]);
//! ```
//!
//! Units at the boundary: times in s, positions in the axis unit (mm for X Y Z, deg for A B C)
//! after pairing, channel samples in the unit the file states ([`Channel::unit`]).

mod detect;
mod error;
pub mod formats;
pub mod infer;
mod info;
mod lost_motion;
mod model;
mod options;
mod pair;
mod text;
mod timebase;
mod units;
pub mod write;

use std::path::Path;

pub use detect::{EXAMINED_BYTES, detect, detect_format};
pub use error::{Attempt, Error};
pub use formats::delimited::from_columns;
pub use formats::sinumerik::NO_VALUE_ABOVE;
pub use info::{ChannelInfo, TraceInfo, format_period};
pub use lost_motion::{LostMotion, REVERSAL_HYSTERESIS, Reversal, lost_motion};
pub use model::{AxisSource, Channel, ChannelRef, Format, Gap, Quantity, ReadOptions, Trace};
pub use options::{AxisNumberMap, TraceArgs};
pub use pair::{
    AxisMap, AxisTrace, ChannelUse, GapPolicy, PairOptions, Paired, Provenance, Segment, Skipped,
    UnitSource, pair,
};
pub use timebase::{DECLARED_TOLERANCE, STEP_TOLERANCE};
pub use units::{BaseUnit, TraceUnit};

/// Reads a trace file: its format detected from the content (or forced by
/// [`ReadOptions::format`]), then read into a [`Trace`].
pub fn read_path(path: &Path, opts: &ReadOptions) -> Result<Trace, Error> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| Error::Io {
        file: file.clone(),
        message: e.to_string(),
    })?;
    read_bytes(&file, &bytes, opts)
}

/// Reads a trace from memory; `file` names it in errors.
pub fn read_bytes(file: &str, bytes: &[u8], opts: &ReadOptions) -> Result<Trace, Error> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    if opts.joints.is_empty() {
        return Err(Error::BadOption {
            file: file.to_string(),
            what: "the joint map is empty".to_string(),
        });
    }
    let format = match opts.format {
        Some(f) => f,
        None => detect_format(file, bytes)?,
    };
    if let Some(c) = &opts.time_column
        && !matches!(
            format,
            Format::Delimited | Format::Halsampler | Format::Parquet
        )
    {
        return Err(Error::TimeColumnNotApplicable {
            file: file.to_string(),
            column: match c {
                ChannelRef::Name(n) => n.clone(),
                ChannelRef::Column(i) => i.to_string(),
            },
            format,
        });
    }
    match format {
        Format::SinumerikTrace => formats::sinumerik::read(file, bytes, opts),
        Format::TncScope => formats::tncscope::read(file, bytes, opts),
        Format::HalscopeTable => formats::halscope::read_table(file, bytes, opts),
        Format::HalscopeInterlaced => formats::halscope::read_pairs(file, bytes, opts),
        Format::TwinCatScope => formats::twincat::read(file, bytes, opts),
        Format::Halsampler => formats::halsampler::read(file, bytes, opts),
        Format::Delimited => formats::delimited::read(file, bytes, opts),
        Format::Parquet => formats::parquet::read(file, bytes, opts),
    }
}
