//! Siemens Sinumerik Operate servo trace, saved as XML from the trace screen (layout as read by
//! the public Trace-Tools parser, github eliasrhoden/Trace-Tools, `tracetools/tracetools.py`):
//!
//! ```xml
//! <traceData>
//!   <dataFrame>
//!     <dataSignal id="1" name="/Nck/…/X1" description="Position setpoint X1" />
//!     <dataSignal id="2" name="/Nck/…/X1" description="Position actual value X1" />
//!     <rec time="0.000" f1="10.0" f2="9.998" />
//!     <rec time="0.002" f2="9.999" />
//!   </dataFrame>
//! </traceData>
//! ```
//!
//! * Signals: `dataSignal` elements; attribute `fN` of a record refers to the signal with
//!   `id="N"`, or — without ids — to the N-th signal declared. `description` names the channel,
//!   `name` (the NCK path) is its [`crate::Channel::description`]; an optional `unit` attribute
//!   gives the unit.
//! * Records: `rec` elements with `time` in s. A record lists only the signals sampled at that
//!   time: the others keep their last value (carried forward). A value above 9.2e18 (the
//!   controller's "no value" marker, near the largest 64-bit integer 9.22e18) is treated as
//!   absent and carried forward too. A channel starts at the first record that gives it a
//!   value.
//! * The record times must be uniform up to gaps (see [`crate::STEP_TOLERANCE`]).

use quick_xml::Reader;
use quick_xml::events::{BytesStart, Event};

use crate::error::Error;
use crate::formats;
use crate::model::{Channel, Format, ReadOptions, Trace};
use crate::text;
use crate::timebase;
use crate::units::TraceUnit;

/// Largest `dataSignal` id accepted (ids index a table).
const MAX_SIGNAL_ID: usize = 1 << 16;

/// Values above this are the controller's "no value" marker.
pub const NO_VALUE_ABOVE: f64 = 9.2e18;

struct Signal {
    id: Option<usize>,
    name: String,
    description: String,
    unit: Option<TraceUnit>,
    line: usize,
    /// Index of the first record with a value.
    start: Option<usize>,
    samples: Vec<f64>,
    current: Option<f64>,
}

/// Counts lines incrementally as the reader advances.
struct LineCounter<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
}

impl LineCounter<'_> {
    fn at(&mut self, pos: usize) -> usize {
        let pos = pos.min(self.bytes.len());
        if pos >= self.pos {
            self.line += memchr::memchr_iter(b'\n', &self.bytes[self.pos..pos]).count();
        } else {
            self.line = text::line_of_offset(self.bytes, pos);
        }
        self.pos = pos;
        self.line
    }
}

fn attr_text(
    file: &str,
    line: usize,
    reader: &Reader<&[u8]>,
    a: &quick_xml::events::attributes::Attribute<'_>,
) -> Result<String, Error> {
    a.decode_and_unescape_value(reader.decoder())
        .map(|v| v.into_owned())
        .map_err(|e| Error::Xml {
            file: file.to_string(),
            line,
            message: e.to_string(),
        })
}

fn signal(
    file: &str,
    line: usize,
    reader: &Reader<&[u8]>,
    e: &BytesStart<'_>,
) -> Result<Signal, Error> {
    let mut s = Signal {
        id: None,
        name: String::new(),
        description: String::new(),
        unit: None,
        line,
        start: None,
        samples: Vec::new(),
        current: None,
    };
    for a in e.attributes() {
        let a = a.map_err(|err| Error::Xml {
            file: file.to_string(),
            line,
            message: err.to_string(),
        })?;
        match a.key.as_ref() {
            b"id" => {
                let v = attr_text(file, line, reader, &a)?;
                s.id = Some(v.trim().parse().map_err(|_| Error::Header {
                    file: file.to_string(),
                    line,
                    what: format!("dataSignal id '{v}' is not a number"),
                })?);
            }
            b"name" => s.name = attr_text(file, line, reader, &a)?,
            b"description" => s.description = attr_text(file, line, reader, &a)?,
            b"unit" => s.unit = TraceUnit::parse(&attr_text(file, line, reader, &a)?),
            _ => {}
        }
    }
    // "(64 bit)" in descriptions marks the data type, not the quantity.
    s.description = s.description.replace("(64 bit)", "").trim().to_string();
    Ok(s)
}

/// Attribute number N → signal index: the signal with `id="N"`, or the N-th declared.
fn id_table(file: &str, signals: &[Signal]) -> Result<Vec<Option<usize>>, Error> {
    let ids: Vec<usize> = signals
        .iter()
        .enumerate()
        .map(|(i, s)| s.id.unwrap_or(i + 1))
        .collect();
    if let Some(i) = ids.iter().position(|&id| id > MAX_SIGNAL_ID) {
        return Err(Error::Header {
            file: file.to_string(),
            line: signals[i].line,
            what: format!("dataSignal id {} is larger than {MAX_SIGNAL_ID}", ids[i]),
        });
    }
    let mut table = vec![None; ids.iter().copied().max().unwrap_or(0) + 1];
    for (i, &id) in ids.iter().enumerate() {
        if table[id].is_some() {
            return Err(Error::Header {
                file: file.to_string(),
                line: signals[i].line,
                what: format!("dataSignal id {id} is declared twice"),
            });
        }
        table[id] = Some(i);
    }
    Ok(table)
}

/// The records read so far: their times (s) and byte offsets (for lines, counted on demand).
#[derive(Default)]
struct Records {
    times: Vec<f64>,
    offsets: Vec<usize>,
}

/// Reads one `rec` element at byte `pos`: updates the signals' current values (carried forward)
/// and appends a sample to every signal that has one.
fn record(
    file: &str,
    e: &BytesStart<'_>,
    pos: usize,
    lines: &mut LineCounter<'_>,
    (table, signals): (&[Option<usize>], &mut [Signal]),
    records: &mut Records,
) -> Result<(), Error> {
    let mut time = None;
    // Duplicate-attribute checks off: a record is read once, and a repeated fN would only
    // overwrite the value (the last one wins, as carried forward).
    for a in e.attributes().with_checks(false) {
        let a = a.map_err(|err| Error::Xml {
            file: file.to_string(),
            line: lines.at(pos),
            message: err.to_string(),
        })?;
        let key = a.key.as_ref();
        if key == b"time" {
            time = Some(
                text::parse_f64(&a.value, false)
                    .map_err(|er| formats::num_error(file, lines.at(pos), "time", &a.value, er))?,
            );
            continue;
        }
        let Some(num) = key.strip_prefix(b"f") else {
            continue;
        };
        let number = (!num.is_empty() && num.iter().all(u8::is_ascii_digit))
            .then(|| {
                num.iter().try_fold(0usize, |a, d| {
                    a.checked_mul(10)?.checked_add(usize::from(d - b'0'))
                })
            })
            .flatten();
        let Some(idx) = number.and_then(|n| table.get(n).copied().flatten()) else {
            return Err(Error::Header {
                file: file.to_string(),
                line: lines.at(pos),
                what: format!(
                    "record value '{}' refers to no declared dataSignal",
                    text::show(key)
                ),
            });
        };
        let v = text::parse_f64(&a.value, false).map_err(|er| {
            formats::num_error(file, lines.at(pos), &signals[idx].description, &a.value, er)
        })?;
        if v <= NO_VALUE_ABOVE {
            signals[idx].current = Some(v);
        }
    }
    let Some(t) = time else {
        return Err(Error::Header {
            file: file.to_string(),
            line: lines.at(pos),
            what: "record without a time attribute".to_string(),
        });
    };
    let r = records.times.len();
    records.times.push(t);
    records.offsets.push(pos);
    for s in signals.iter_mut() {
        if let Some(v) = s.current {
            s.start.get_or_insert(r);
            s.samples.push(v);
        }
    }
    Ok(())
}

/// The channels of the signals, on the checked record time base.
fn channels(
    file: &str,
    bytes: &[u8],
    opts: &ReadOptions,
    signals: Vec<Signal>,
    records: &Records,
) -> Result<Vec<Channel>, Error> {
    let line_of = |r: usize| text::line_of_offset(bytes, records.offsets[r]);
    let first_line = records
        .offsets
        .first()
        .map_or(1, |&o| text::line_of_offset(bytes, o));
    let u = timebase::uniform(&records.times, None)
        .map_err(|f| formats::time_error(file, f, first_line, line_of))?;
    let mut channels = Vec::with_capacity(signals.len());
    for (i, s) in signals.into_iter().enumerate() {
        let name = if s.description.is_empty() {
            s.name.clone()
        } else {
            s.description.clone()
        };
        let mut ch = Channel::new(name, s.line, s.id.map_or(i, |id| id.saturating_sub(1)));
        ch.description = s.name;
        ch.unit = s.unit;
        let start = s.start.unwrap_or(records.times.len());
        ch.samples = s.samples;
        ch.period_s = u.period_s;
        ch.t0_s = records.times.get(start).copied().unwrap_or(0.0);
        ch.gaps = u
            .gaps
            .iter()
            .filter(|&&(index, _)| index > start)
            .map(|&(index, lost)| crate::Gap {
                index: index - start,
                line: line_of(index),
                lost: Some(lost),
            })
            .collect();
        formats::apply_period_option(file, opts, &mut ch)?;
        let (d, p) = (ch.name.clone(), ch.description.clone());
        formats::infer_channel(&mut ch, &[("description", &d), ("path", &p)], None);
        channels.push(ch);
    }
    Ok(channels)
}

pub(crate) fn read(file: &str, bytes: &[u8], opts: &ReadOptions) -> Result<Trace, Error> {
    let mut reader = Reader::from_reader(bytes);
    let mut lines = LineCounter {
        bytes,
        pos: 0,
        line: 1,
    };
    let mut signals: Vec<Signal> = Vec::new();
    // Built at the first record, when every signal is declared.
    let mut table: Option<Vec<Option<usize>>> = None;
    let mut records = Records::default();
    let mut metadata = Vec::new();
    // Names of the open elements, for the "ends inside" message ("" for records).
    let mut open: Vec<String> = Vec::new();
    loop {
        let pos = reader.buffer_position() as usize;
        let ev = reader.read_event().map_err(|e| Error::Xml {
            file: file.to_string(),
            line: lines.at(reader.error_position() as usize),
            message: e.to_string(),
        })?;
        let e = match ev {
            Event::Start(e) => {
                let name = e.local_name();
                open.push(if name.as_ref() == b"rec" {
                    String::new()
                } else {
                    text::decode(name.as_ref()).into_owned()
                });
                e
            }
            Event::Empty(e) => e,
            Event::End(_) => {
                open.pop();
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        match e.local_name().as_ref() {
            b"dataSignal" => {
                let line = lines.at(pos);
                if table.is_some() {
                    return Err(Error::Header {
                        file: file.to_string(),
                        line,
                        what: "dataSignal declared after the first record".to_string(),
                    });
                }
                signals.push(signal(file, line, &reader, &e)?);
            }
            b"rec" => {
                if table.is_none() {
                    if signals.is_empty() {
                        return Err(Error::Header {
                            file: file.to_string(),
                            line: lines.at(pos),
                            what: "record before any dataSignal declaration".to_string(),
                        });
                    }
                    table = Some(id_table(file, &signals)?);
                }
                let t = table.as_deref().unwrap_or_default();
                record(file, &e, pos, &mut lines, (t, &mut signals), &mut records)?;
            }
            other => {
                if table.is_none() && signals.is_empty() && metadata.is_empty() {
                    metadata.push(("root".to_string(), text::decode(other).into_owned()));
                }
            }
        }
    }
    if let Some(inside) = open.iter().rev().find(|n| !n.is_empty()).or(open.last()) {
        return Err(Error::Truncated {
            file: file.to_string(),
            line: lines.at(bytes.len()),
            what: format!(
                "the XML ends inside <{}>",
                if inside.is_empty() { "rec" } else { inside }
            ),
        });
    }
    if signals.is_empty() {
        return Err(Error::Truncated {
            file: file.to_string(),
            line: lines.at(bytes.len()),
            what: "no dataSignal declaration".to_string(),
        });
    }
    let channels = channels(file, bytes, opts, signals, &records)?;
    Ok(Trace {
        file: file.to_string(),
        format: Format::SinumerikTrace,
        channels,
        metadata,
    })
}
