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

pub(crate) fn read(file: &str, bytes: &[u8], opts: &ReadOptions) -> Result<Trace, Error> {
    let mut reader = Reader::from_reader(bytes);
    let mut lines = LineCounter {
        bytes,
        pos: 0,
        line: 1,
    };
    let mut signals: Vec<Signal> = Vec::new();
    // Attribute number N → signal index, built at the first record.
    let mut by_number: Vec<Option<usize>> = Vec::new();
    let mut times: Vec<f64> = Vec::new();
    let mut record_offsets: Vec<usize> = Vec::new();
    let mut metadata = Vec::new();
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
                // Element names kept for the "ends inside" message; records need none.
                open.push(if e.local_name().as_ref() == b"rec" {
                    String::new()
                } else {
                    text::decode(e.local_name().as_ref()).into_owned()
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
        // Lines are counted only where needed: a record's line only for its errors.
        match e.local_name().as_ref() {
            b"dataSignal" => {
                let line = lines.at(pos);
                if !times.is_empty() {
                    return Err(Error::Header {
                        file: file.to_string(),
                        line,
                        what: "dataSignal declared after the first record".to_string(),
                    });
                }
                signals.push(signal(file, line, &reader, &e)?);
            }
            b"rec" => {
                if times.is_empty() {
                    if signals.is_empty() {
                        return Err(Error::Header {
                            file: file.to_string(),
                            line: lines.at(pos),
                            what: "record before any dataSignal declaration".to_string(),
                        });
                    }
                    let ids: Vec<usize> = signals
                        .iter()
                        .enumerate()
                        .map(|(i, s)| s.id.unwrap_or(i + 1))
                        .collect();
                    let max = ids.iter().copied().max().unwrap_or(0);
                    if let Some(i) = ids.iter().position(|&id| id > MAX_SIGNAL_ID) {
                        return Err(Error::Header {
                            file: file.to_string(),
                            line: signals[i].line,
                            what: format!(
                                "dataSignal id {} is larger than {MAX_SIGNAL_ID}",
                                ids[i]
                            ),
                        });
                    }
                    by_number = vec![None; max + 1];
                    for (i, &id) in ids.iter().enumerate() {
                        if by_number[id].is_some() {
                            return Err(Error::Header {
                                file: file.to_string(),
                                line: signals[i].line,
                                what: format!("dataSignal id {id} is declared twice"),
                            });
                        }
                        by_number[id] = Some(i);
                    }
                }
                let mut time = None;
                // Duplicate-attribute checks off: a record is read once, and a repeated fN
                // would only overwrite the value (the last one wins, as carried forward).
                for a in e.attributes().with_checks(false) {
                    let a = a.map_err(|err| Error::Xml {
                        file: file.to_string(),
                        line: lines.at(pos),
                        message: err.to_string(),
                    })?;
                    let key = a.key.as_ref();
                    if key == b"time" {
                        time = Some(text::parse_f64(&a.value, false).map_err(|er| {
                            formats::num_error(file, lines.at(pos), "time", &a.value, er)
                        })?);
                    } else if let Some(num) = key.strip_prefix(b"f") {
                        let number = (!num.is_empty() && num.iter().all(u8::is_ascii_digit))
                            .then(|| {
                                num.iter().try_fold(0usize, |a, d| {
                                    a.checked_mul(10)?.checked_add(usize::from(d - b'0'))
                                })
                            })
                            .flatten();
                        let Some(idx) = number.and_then(|n| by_number.get(n).copied().flatten())
                        else {
                            return Err(Error::Header {
                                file: file.to_string(),
                                line: lines.at(pos),
                                what: format!(
                                    "record value '{}' refers to no declared dataSignal",
                                    text::show(key)
                                ),
                            });
                        };
                        let name = &signals[idx].description;
                        let v = match text::parse_f64(&a.value, false) {
                            Ok(v) => v,
                            Err(er) => {
                                return Err(formats::num_error(
                                    file,
                                    lines.at(pos),
                                    name,
                                    &a.value,
                                    er,
                                ));
                            }
                        };
                        if v <= NO_VALUE_ABOVE {
                            signals[idx].current = Some(v);
                        }
                    }
                }
                let Some(t) = time else {
                    return Err(Error::Header {
                        file: file.to_string(),
                        line: lines.at(pos),
                        what: "record without a time attribute".to_string(),
                    });
                };
                let r = times.len();
                times.push(t);
                record_offsets.push(pos);
                for s in &mut signals {
                    if let Some(v) = s.current {
                        if s.start.is_none() {
                            s.start = Some(r);
                        }
                        s.samples.push(v);
                    }
                }
            }
            other => {
                if times.is_empty() && signals.is_empty() && metadata.is_empty() {
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
    let u = timebase::uniform(&times, None).map_err(|f| {
        formats::time_error(
            file,
            f,
            record_offsets
                .first()
                .map_or(1, |&o| text::line_of_offset(bytes, o)),
            |r| text::line_of_offset(bytes, record_offsets[r]),
        )
    })?;
    let mut channels = Vec::with_capacity(signals.len());
    for (i, s) in signals.into_iter().enumerate() {
        let name = if s.description.is_empty() {
            s.name.clone()
        } else {
            s.description.clone()
        };
        let mut ch = Channel::new(name, s.line, s.id.map_or(i, |id| id - 1));
        ch.description = s.name;
        ch.unit = s.unit;
        let start = s.start.unwrap_or(times.len());
        ch.samples = s.samples;
        ch.period_s = u.period_s;
        ch.t0_s = times.get(start).copied().unwrap_or(0.0);
        ch.gaps = u
            .gaps
            .iter()
            .filter(|&&(index, _)| index > start)
            .map(|&(index, lost)| crate::Gap {
                index: index - start,
                line: text::line_of_offset(bytes, record_offsets[index]),
                lost: Some(lost),
            })
            .collect();
        formats::apply_period_option(file, opts, &mut ch)?;
        let (d, p) = (ch.name.clone(), ch.description.clone());
        formats::infer_channel(&mut ch, &[("description", &d), ("path", &p)], None);
        channels.push(ch);
    }
    Ok(Trace {
        file: file.to_string(),
        format: Format::SinumerikTrace,
        channels,
        metadata,
    })
}
