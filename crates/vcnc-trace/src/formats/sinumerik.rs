//! Siemens Sinumerik Operate servo trace, saved as XML from the trace screen.
//!
//! Two layouts are read. Sinumerik Operate (Solution Line) writes `traceSession
//! version="01.00.03.02"`: the signals are declared in the capture setup, and the data frame
//! repeats each with the attribute name its values take in the records:
//!
//! ```xml
//! <traceSession version="01.00.03.02">
//!   <traceCaptureSetup_V20>
//!     <signalSettings>
//!       <signal key="s1" unitsType="posn" name="/Nck/!SD/nckServoDataCmdPos2ndEnc64 [u1, 1]"
//!               description="Position setpoint (64 bit)"/>
//!       <signal key="s2" unitsType="posn" name="/Nck/!SD/nckServoDataActPos1stEnc64 [u1, 1]" …/>
//!     </signalSettings>
//!   </traceCaptureSetup_V20>
//!   <traceData dataFrames="1">
//!     <dataFrame>
//!       <frameHeader startTime="…" dropOuts="0"/>
//!       <dataSignal key="s1" id="f1" interval="0.002000" datapointCount="7199"/>
//!       <dataSignal key="s2" id="f2" interval="0.002000" datapointCount="7199"/>
//!       <rec time="0.000000" f1="-300.0" f2="-1100.17"/>
//!       <rec time="0.002000" f2="-1100.18"/>
//!     </dataFrame>
//!   </traceData>
//! </traceSession>
//! ```
//!
//! The older layout (as read by the public Trace-Tools parser, github eliasrhoden/Trace-Tools,
//! `tracetools/tracetools.py`) declares name and description on the `dataSignal` itself, with a
//! numeric `id="N"` (values in attribute `fN`) or none (the N-th declared).
//!
//! * **Signals.** A `dataSignal` gets its NCK path (`name`), `description` and `unitsType` from
//!   the `signal` of the same `key` in `signalSettings` where it does not carry them. Its record
//!   attribute is its `id` (`f1`), `fN` for a numeric id `N`, or `fN` for the N-th declared. The
//!   channel is named by the description without its `(64 bit)` data-type note (descriptions
//!   that repeat — one per axis — get the path's `[u1, N]` appended); the path is its
//!   [`crate::Channel::description`]. An optional `unit` attribute gives the unit; V20 files
//!   state none (`unitsType="posn"` is a kind, not a unit: the machine's mm or inch), so
//!   `--units` or mm/deg decide.
//! * **Servo signals** `/Nck/!SD/nckServoData<signal>[32|64] [u1, N]`: `N` is the NCK axis
//!   number ([`crate::Channel::axis_number`]), mapped to an axis by the caller's
//!   [`crate::ReadOptions::axis_map`] (`--axis-map 1=X`). The signal gives the quantity and the
//!   measuring system: `CmdPos1stEnc`/`CmdPos2ndEnc` the position setpoint for measuring system 1
//!   (motor encoder) / 2 (direct scale), `ActPos1stEnc`/`ActPos2ndEnc` their actual positions,
//!   `Cmd…Vel…`/`Cmd…Speed…` the velocity setpoint, `Act…Vel…` actual velocities, `ActCurr` the
//!   current i(q); control and contour deviation, load, torque and the active-system flag are
//!   "other". Other signals are inferred from their description and path like any name
//!   ("measuring system 2" / "Messsystem 2" gives the system).
//! * **Records.** `rec` elements with `time` in s. A record lists only the signals whose value
//!   changed: the others keep their last value (carried forward). A value above 9.2e18 (the
//!   controller's "no value" marker, near the largest 64-bit integer 9.22e18) is treated as
//!   absent and carried forward too. A channel starts at the first record that gives it a value.
//!   An attribute that is neither `time` nor a declared signal is refused (a damaged file, or a
//!   signal missing from the declarations): its value cannot be placed.
//! * **Time.** Record times must be uniform up to gaps (see [`crate::STEP_TOLERANCE`]); the
//!   signals' `interval` (s) is the declared period, checked against them. A signal whose
//!   interval is `k` records takes every `k`-th record from its first. `datapointCount` must
//!   equal the records the signal spans: fewer records are a file cut short.
//! * **Text.** Attribute values are UTF-8, or Latin-1 where they are not (files declared
//!   `ISO-8859-1`: `Meßsystem`).

use quick_xml::Reader;
use quick_xml::events::attributes::Attribute;
use quick_xml::events::{BytesStart, Event};

use crate::error::Error;
use crate::formats;
use crate::infer;
use crate::model::{AxisSource, Channel, Format, Quantity, ReadOptions, Trace};
use crate::text;
use crate::timebase;
use crate::units::TraceUnit;

/// Largest numeric signal id accepted (ids index a table).
const MAX_SIGNAL_ID: usize = 1 << 16;

/// Values above this are the controller's "no value" marker.
pub const NO_VALUE_ABOVE: f64 = 9.2e18;

/// A `signal` of the capture setup's `signalSettings`.
#[derive(Default)]
struct Declared {
    key: String,
    name: String,
    description: String,
    units_type: String,
}

/// A `dataSignal` of the data frame, and its samples.
struct Signal {
    /// The `id` attribute as written.
    id: Option<String>,
    key: String,
    name: String,
    description: String,
    units_type: String,
    unit: Option<TraceUnit>,
    /// `interval`, s.
    interval: Option<f64>,
    /// `datapointCount`.
    count: Option<usize>,
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

fn xml_error(file: &str, line: usize, message: impl ToString) -> Error {
    Error::Xml {
        file: file.to_string(),
        line,
        message: message.to_string(),
    }
}

/// An attribute's text: UTF-8, else Latin-1; entities resolved.
fn attr_text(file: &str, line: usize, a: &Attribute<'_>) -> Result<String, Error> {
    let raw = text::decode(&a.value);
    quick_xml::escape::unescape(&raw)
        .map(|v| v.into_owned())
        .map_err(|e| xml_error(file, line, e))
}

/// The attributes of an element as (key, text) pairs.
fn attrs(file: &str, line: usize, e: &BytesStart<'_>) -> Result<Vec<(Vec<u8>, String)>, Error> {
    e.attributes()
        .map(|a| {
            let a = a.map_err(|err| xml_error(file, line, err))?;
            Ok((a.key.as_ref().to_vec(), attr_text(file, line, &a)?))
        })
        .collect()
}

fn declared(file: &str, line: usize, e: &BytesStart<'_>) -> Result<Declared, Error> {
    let mut d = Declared::default();
    for (k, v) in attrs(file, line, e)? {
        match k.as_slice() {
            b"key" => d.key = v,
            b"name" => d.name = v,
            b"description" => d.description = v,
            b"unitsType" => d.units_type = v,
            _ => {}
        }
    }
    Ok(d)
}

fn positive(file: &str, line: usize, what: &str, v: &str) -> Result<f64, Error> {
    match text::parse_f64(v.as_bytes(), false) {
        Ok(x) if x > 0.0 => Ok(x),
        _ => Err(Error::Header {
            file: file.to_string(),
            line,
            what: format!("dataSignal {what} '{v}' is not a positive number"),
        }),
    }
}

fn signal(file: &str, line: usize, e: &BytesStart<'_>) -> Result<Signal, Error> {
    let mut s = Signal {
        id: None,
        key: String::new(),
        name: String::new(),
        description: String::new(),
        units_type: String::new(),
        unit: None,
        interval: None,
        count: None,
        line,
        start: None,
        samples: Vec::new(),
        current: None,
    };
    for (k, v) in attrs(file, line, e)? {
        match k.as_slice() {
            b"id" => s.id = Some(v.trim().to_string()),
            b"key" => s.key = v,
            b"name" => s.name = v,
            b"description" => s.description = v,
            b"unitsType" => s.units_type = v,
            b"unit" => s.unit = TraceUnit::parse(&v),
            b"interval" => s.interval = Some(positive(file, line, "interval", &v)?),
            b"datapointCount" => {
                s.count = Some(v.trim().parse().map_err(|_| Error::Header {
                    file: file.to_string(),
                    line,
                    what: format!("dataSignal datapointCount '{v}' is not a count"),
                })?);
            }
            _ => {}
        }
    }
    Ok(s)
}

/// The record attribute of each signal: numeric ones (`fN`) in a table indexed by N, others by
/// name.
struct Ids {
    numeric: Vec<Option<usize>>,
    named: Vec<(Vec<u8>, usize)>,
}

impl Ids {
    fn get(&self, key: &[u8]) -> Option<usize> {
        if let Some(n) = f_number(key) {
            return self.numeric.get(n).copied().flatten();
        }
        self.named.iter().find(|(k, _)| k == key).map(|&(_, i)| i)
    }
}

/// N of an attribute `fN`.
fn f_number(key: &[u8]) -> Option<usize> {
    let num = key.strip_prefix(b"f")?;
    if num.is_empty() || !num.iter().all(u8::is_ascii_digit) {
        return None;
    }
    num.iter().try_fold(0usize, |a, d| {
        a.checked_mul(10)?.checked_add(usize::from(d - b'0'))
    })
}

/// The attribute name of signal `i` (see the module documentation).
fn attribute_of(s: &Signal, i: usize) -> String {
    match &s.id {
        Some(id) if !id.is_empty() && id.bytes().all(|b| b.is_ascii_digit()) => format!("f{id}"),
        Some(id) if !id.is_empty() => id.clone(),
        _ => format!("f{}", i + 1),
    }
}

fn id_table(file: &str, signals: &[Signal]) -> Result<Ids, Error> {
    let mut ids = Ids {
        numeric: Vec::new(),
        named: Vec::new(),
    };
    let mut seen: Vec<String> = Vec::with_capacity(signals.len());
    for (i, s) in signals.iter().enumerate() {
        let attr = attribute_of(s, i);
        if seen.contains(&attr) {
            return Err(Error::Header {
                file: file.to_string(),
                line: s.line,
                what: format!("dataSignal id '{attr}' is declared twice"),
            });
        }
        match f_number(attr.as_bytes()) {
            Some(n) if n > MAX_SIGNAL_ID => {
                return Err(Error::Header {
                    file: file.to_string(),
                    line: s.line,
                    what: format!("dataSignal id '{attr}' is larger than f{MAX_SIGNAL_ID}"),
                });
            }
            Some(n) => {
                if ids.numeric.len() <= n {
                    ids.numeric.resize(n + 1, None);
                }
                ids.numeric[n] = Some(i);
            }
            None => ids.named.push((attr.clone().into_bytes(), i)),
        }
        seen.push(attr);
    }
    Ok(ids)
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
    (ids, signals): (&Ids, &mut [Signal]),
    records: &mut Records,
) -> Result<(), Error> {
    let mut time = None;
    // Duplicate-attribute checks off: a record is read once, and a repeated fN would only
    // overwrite the value (the last one wins, as carried forward).
    for a in e.attributes().with_checks(false) {
        let a = a.map_err(|err| xml_error(file, lines.at(pos), err))?;
        let key = a.key.as_ref();
        if key == b"time" {
            time = Some(
                text::parse_f64(&a.value, false)
                    .map_err(|er| formats::num_error(file, lines.at(pos), "time", &a.value, er))?,
            );
            continue;
        }
        let Some(idx) = ids.get(key) else {
            let declared: Vec<String> = signals
                .iter()
                .enumerate()
                .map(|(i, s)| attribute_of(s, i))
                .collect();
            return Err(Error::Header {
                file: file.to_string(),
                line: lines.at(pos),
                what: format!(
                    "record attribute '{}' is neither 'time' nor a declared dataSignal (declared: {}); the file is damaged, or a signal's declaration is missing",
                    text::show(key),
                    declared.join(", ")
                ),
            });
        };
        let v = text::parse_f64(&a.value, false).map_err(|er| {
            let column = if signals[idx].description.is_empty() {
                &signals[idx].name
            } else {
                &signals[idx].description
            };
            formats::num_error(file, lines.at(pos), column, &a.value, er)
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

/// What a servo-data signal (`nckServoData<signal>[32|64]`) measures, and its measuring system.
fn servo_signal(path: &str) -> Option<(Quantity, Option<u8>)> {
    let at = path.find("nckServoData")?;
    let rest = &path[at + "nckServoData".len()..];
    let end = rest
        .find(|c: char| !c.is_ascii_alphanumeric())
        .unwrap_or(rest.len());
    let core = rest[..end].trim_end_matches(|c: char| c.is_ascii_digit());
    let core = core
        .strip_suffix("64")
        .or_else(|| core.strip_suffix("32"))
        .unwrap_or(core);
    let system = if core.contains("1stEnc") {
        Some(1)
    } else if core.contains("2ndEnc") {
        Some(2)
    } else {
        None
    };
    let q = if core.starts_with("CmdPos") {
        Quantity::NominalPosition
    } else if core.starts_with("ActPos") {
        Quantity::ActualPosition
    } else if core.starts_with("Cmd") && (core.contains("Vel") || core.contains("Speed")) {
        Quantity::NominalVelocity
    } else if core.starts_with("Act") && (core.contains("Vel") || core.contains("Speed")) {
        Quantity::ActualVelocity
    } else if core.starts_with("ActCurr") || core.starts_with("CmdCurr") {
        Quantity::Current
    } else {
        // Deviations (ContDev, CtrlDev), load, torque, the active measuring system, OEM slots.
        Quantity::Other
    };
    let system = system.filter(|_| q.is_position() || q == Quantity::ActualVelocity);
    Some((q, system))
}

/// The NCK axis number `N` of a path `…[u1, N]` (also written `[u1; N]`, `[u1 N]`).
fn axis_number(path: &str) -> Option<u32> {
    let open = path.rfind('[')?;
    let inner = &path[open + 1..path[open..].find(']').map_or(path.len(), |c| open + c)];
    let mut parts = inner
        .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
        .filter(|p| !p.is_empty());
    let area = parts.next()?;
    if !area.starts_with(['u', 'U']) {
        return None;
    }
    parts.next()?.parse().ok()
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
    let declared = signals
        .iter()
        .filter_map(|s| s.interval)
        .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.min(v))));
    let declared_line = signals
        .iter()
        .find(|s| s.interval.is_some() && s.interval == declared)
        .map_or(first_line, |s| s.line);
    let u = timebase::uniform(&records.times, declared)
        .map_err(|f| formats::time_error(file, f, declared_line, line_of))?;
    // Names: the description without its data-type note; repeated ones get the path's axis.
    let base: Vec<String> = signals
        .iter()
        .map(|s| {
            let d = s
                .description
                .replace("(64 bit)", "")
                .replace("(32 bit)", "");
            let d = d.trim();
            if d.is_empty() {
                s.name.clone()
            } else {
                d.to_string()
            }
        })
        .collect();
    let mut names = base.clone();
    for (i, s) in signals.iter().enumerate() {
        if base.iter().filter(|b| **b == base[i]).count() > 1
            && let Some(open) = s.name.rfind('[')
        {
            names[i] = format!("{} {}", base[i], &s.name[open..]);
        }
    }
    for i in 0..names.len() {
        if names.iter().filter(|n| **n == names[i]).count() > 1 {
            names[i] = format!("{} ({})", names[i], attribute_of(&signals[i], i));
        }
    }
    let mut channels = Vec::with_capacity(signals.len());
    for (i, (s, name)) in signals.into_iter().zip(names).enumerate() {
        let column = f_number(attribute_of(&s, i).as_bytes()).map_or(i, |n| n.saturating_sub(1));
        let mut ch = Channel::new(name, s.line, column);
        ch.description = s.name;
        ch.unit = s.unit;
        let start = s.start.unwrap_or(records.times.len());
        let period = u.period_s;
        // A signal recorded every k-th record: its own samples only.
        let k = match (s.interval, period) {
            (Some(iv), Some(p)) => {
                let r = iv / p;
                if (r - r.round()).abs() > 1e-3 * r || r.round() < 1.0 {
                    return Err(Error::Header {
                        file: file.to_string(),
                        line: s.line,
                        what: format!(
                            "dataSignal interval {iv} s is not a whole number of record periods ({p} s)"
                        ),
                    });
                }
                r.round() as usize
            }
            _ => 1,
        };
        ch.samples = if k == 1 {
            s.samples
        } else {
            s.samples.into_iter().step_by(k).collect()
        };
        ch.period_s = period.map(|p| p * k as f64);
        ch.t0_s = records.times.get(start).copied().unwrap_or(0.0);
        if let Some(count) = s.count {
            let spanned = records.times.len().div_ceil(k);
            if spanned < count {
                return Err(Error::Truncated {
                    file: file.to_string(),
                    line: records
                        .offsets
                        .last()
                        .map_or(s.line, |&o| text::line_of_offset(bytes, o)),
                    what: format!(
                        "signal '{}' declares {count} datapoints (line {}), the records hold {spanned}: the file is cut short",
                        ch.name, s.line
                    ),
                });
            }
            if spanned > count {
                return Err(Error::CountMismatch {
                    file: file.to_string(),
                    line: s.line,
                    channel: ch.name.clone(),
                    declared: count,
                    found: spanned,
                });
            }
        }
        ch.gaps = u
            .gaps
            .iter()
            .filter(|&&(index, _)| index > start)
            .map(|&(index, lost)| crate::Gap {
                index: (index - start).div_ceil(k),
                line: line_of(index),
                lost: Some(lost / k),
            })
            .collect();
        formats::apply_period_option(file, opts, &mut ch)?;
        let (d, p) = (ch.name.clone(), ch.description.clone());
        formats::infer_channel(&mut ch, &[("description", &d), ("path", &p)], None);
        ch.measuring_system = infer::measuring_system_of(&d);
        if let Some((q, system)) = servo_signal(&p) {
            ch.quantity = q;
            ch.measuring_system = system;
        }
        if !ch.quantity.is_position() && ch.quantity != Quantity::ActualVelocity {
            ch.measuring_system = None;
        }
        ch.axis_number = axis_number(&p);
        if let Some(n) = ch.axis_number
            && let Some(axis) = opts.axis_map.get(n)
        {
            ch.axis = Some(axis);
            ch.axis_source = Some(AxisSource::Number {
                number: n,
                map: opts.axis_map.to_string(),
            });
        }
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
    let mut capture: Vec<Declared> = Vec::new();
    let mut signals: Vec<Signal> = Vec::new();
    // Built at the first record, when every signal is declared.
    let mut ids: Option<Ids> = None;
    let mut records = Records::default();
    let mut metadata = Vec::new();
    // Names of the open elements, for the "ends inside" message ("" for records).
    let mut open: Vec<String> = Vec::new();
    loop {
        let pos = reader.buffer_position() as usize;
        let ev = reader
            .read_event()
            .map_err(|e| xml_error(file, lines.at(reader.error_position() as usize), e))?;
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
            b"rec" => {
                if ids.is_none() {
                    if signals.is_empty() {
                        return Err(Error::Header {
                            file: file.to_string(),
                            line: lines.at(pos),
                            what: "record before any dataSignal declaration".to_string(),
                        });
                    }
                    resolve_keys(&mut signals, &capture);
                    ids = Some(id_table(file, &signals)?);
                }
                if let Some(t) = &ids {
                    record(file, &e, pos, &mut lines, (t, &mut signals), &mut records)?;
                }
            }
            b"dataSignal" => {
                let line = lines.at(pos);
                if ids.is_some() {
                    return Err(Error::Header {
                        file: file.to_string(),
                        line,
                        what: "dataSignal declared after the first record".to_string(),
                    });
                }
                signals.push(signal(file, line, &e)?);
            }
            b"signal" => {
                let line = lines.at(pos);
                capture.push(declared(file, line, &e)?);
            }
            other => {
                let line = lines.at(pos);
                let keep: &[&[u8]] = match other {
                    b"traceSession" | b"traceFile" => &[b"version"],
                    b"sessionSettings" => &[b"sessionName"],
                    b"frameHeader" => &[b"startTime", b"dropOuts"],
                    _ => &[],
                };
                if metadata.is_empty() {
                    metadata.push(("root".to_string(), text::decode(other).into_owned()));
                }
                for (k, v) in attrs(file, line, &e)? {
                    if keep.contains(&k.as_slice()) {
                        metadata.push((text::decode(&k).into_owned(), v));
                    }
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
    if ids.is_none() {
        resolve_keys(&mut signals, &capture);
    }
    let channels = channels(file, bytes, opts, signals, &records)?;
    Ok(Trace {
        file: file.to_string(),
        format: Format::SinumerikTrace,
        channels,
        metadata,
    })
}

/// Fills each data signal's path, description and kind from the capture signal of its key.
fn resolve_keys(signals: &mut [Signal], capture: &[Declared]) {
    for s in signals.iter_mut() {
        let Some(d) = capture.iter().find(|d| !s.key.is_empty() && d.key == s.key) else {
            continue;
        };
        if s.name.is_empty() {
            s.name = d.name.clone();
        }
        if s.description.is_empty() {
            s.description = d.description.clone();
        }
        if s.units_type.is_empty() {
            s.units_type = d.units_type.clone();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn servo_signals_give_quantity_system_and_axis_number() {
        let p = "/Nck/!SD/nckServoDataCmdPos2ndEnc64 [u1, 1]";
        assert_eq!(servo_signal(p), Some((Quantity::NominalPosition, Some(2))));
        assert_eq!(axis_number(p), Some(1));
        assert_eq!(
            servo_signal("/Nck/!SD/nckServoDataActPos1stEnc64 [u1, 3]"),
            Some((Quantity::ActualPosition, Some(1)))
        );
        assert_eq!(
            axis_number("/Nck/!SD/nckServoDataActCurr32 [u1; 11]"),
            Some(11)
        );
        assert_eq!(
            axis_number("/Nck/!SD/nckServoDataActPos2ndEnc64 [u1  2]"),
            Some(2)
        );
        assert_eq!(axis_number("/Nck/ServoTrace/PositionSetpoint[X1]"), None);
        assert_eq!(
            servo_signal("/Nck/!SD/nckServoDataActCurr64 [u1, 1]"),
            Some((Quantity::Current, None))
        );
        assert_eq!(
            servo_signal("/Nck/!SD/nckServoDataActVelMot64 [u1, 1]"),
            Some((Quantity::ActualVelocity, None))
        );
        for other in [
            "CtrlDev64",
            "ContDev64",
            "DrvLoad64",
            "CmdTorque64",
            "ActEnc64",
        ] {
            assert_eq!(
                servo_signal(&format!("/Nck/!SD/nckServoData{other} [u1, 1]")),
                Some((Quantity::Other, None)),
                "{other}"
            );
        }
        assert_eq!(servo_signal("/Nck/!SEMA/measPosDev [u1, 1]"), None);
    }
}
