//! Heidenhain TNCscope text export, as the iTNC 530 (NC software 606420) and the TNC 640 write it.
//!
//! ```text
//! %TNCscopeNT data file
//! %␠
//! %[GLOBAL]
//! %VERSION=3
//! %CONTROL=iTNC 530
//! %SAMPLING=3000
//! %␠
//! %[CURVE1]
//! %NAME=s soll/Y
//! %CHANNELTYPE=s soll
//! %AXISTYPE=Y
//! %DIMENSION=mm
//! %COUNT=2000
//! %SAMPLING=3000
//! %CYCLETIME=3000
//! %␠
//! %[CURVE2]
//! …
//! %[DATA]
//! 0; -299.9800; -299.9800;
//! 3000; -299.9800; -299.9797;
//! ```
//!
//! Header lines are `KEY=VALUE` (a leading `%` allowed, keys in any case); a line that is `%`
//! alone or followed by white space (`%␠`, as real exports write after the first line, at the end
//! of `%[GLOBAL]` and between curves) separates blocks and is skipped; so are blank lines, in the
//! data too. Keys vcnc does not use (`DIAGTYPE`, `RECORDEDBY`, `BGCOLOR`, `COLOR`, `DRAWOFFS`,
//! `DRAWMULT`, `LOGIC`, `BIT`, …) are kept: global ones as the trace's metadata, curve ones
//! unused (`DRAWOFFS`/`DRAWMULT` are display settings, not a scaling of the values).
//!
//! Per curve: `NAME` (`s soll/Y`: quantity and axis), `CHANNELTYPE` (`s soll`/`s ist`
//! nominal/actual position, `v soll`/`v ist` velocities, `I soll`/`I ist` current), `AXISTYPE`,
//! `DIMENSION` (the unit: mm, µm, deg, mm/min, Ampere, …), `COUNT` (samples, required),
//! `SAMPLING` (the recording interval, µs) and `CYCLETIME` (the control cycle the signal is
//! computed at, µs: 100 µs for the current `I ist`, 3000 µs for positions). **Samples are at the
//! recording interval**: the curve's `SAMPLING`, else the global `SAMPLING`, else — in exports
//! that state no recording interval — its `CYCLETIME`; one of them is required. A curve's
//! `CYCLETIME` is kept as [`crate::Channel::cycle_s`]. (Read at a current's 100 µs cycle, a
//! recording at 3 ms would seem to have lost 29 of every 30 samples.)
//!
//! Curve `n` is column `n` of the data rows, after the time `t` in µs. Channels may have
//! different recording intervals. Rows come at the shortest one; a channel whose interval is `k`
//! times longer has its samples on every `k`-th row counted from the first row (its other cells
//! may be empty or repeat a value; they are not read). A channel whose on-grid cells are empty
//! from some row on ended there (channels may cover different durations). An interval that is
//! not a whole multiple of the shortest, an empty cell followed by more samples of the channel,
//! and a `COUNT` other than the samples found are errors; a file that ends inside a curve block,
//! or whose data stop before every curve has its `COUNT`, is truncated ([`Error::Truncated`]).
//! Pairing later aligns nominal and actual positions of different intervals on one period.
//!
//! The axis is `AXISTYPE` when it names one (`X`, `X1`, `X axis`), else a word of `NAME`.

use vcnc_axis::AxisName;

use crate::error::Error;
use crate::formats::{self, Start};
use crate::infer;
use crate::model::{AxisSource, Channel, Format, Gap, ReadOptions, Trace};
use crate::text::{self, Lines};
use crate::timebase;
use crate::units::TraceUnit;

struct Curve {
    number: usize,
    line: usize,
    keys: Vec<(String, String, usize)>,
}

impl Curve {
    fn get(&self, key: &str) -> Option<(&str, usize)> {
        self.keys
            .iter()
            .find(|(k, _, _)| k == key)
            .map(|(_, v, l)| (v.as_str(), *l))
    }
}

fn header(file: &str, line: usize, what: String) -> Error {
    Error::Header {
        file: file.to_string(),
        line,
        what,
    }
}

/// The header: `%[GLOBAL]` keys, `%[CURVEn]` blocks in curve order, and where `%[DATA]` rows
/// start.
struct Header {
    metadata: Vec<(String, String)>,
    /// Line of each metadata entry.
    metadata_lines: Vec<usize>,
    curves: Vec<Curve>,
    data: Start,
}

fn read_header(file: &str, bytes: &[u8]) -> Result<Header, Error> {
    let mut lines = Lines::new(bytes);
    match lines.by_ref().find(|l| !text::is_blank(l.text)) {
        Some(l)
            if text::decode(text::trim(l.text))
                .to_ascii_lowercase()
                .starts_with("%tncscope") => {}
        Some(l) => {
            return Err(header(
                file,
                l.no,
                format!("expected '%TNCscope…', found '{}'", text::show(l.text)),
            ));
        }
        None => {
            return Err(Error::Truncated {
                file: file.to_string(),
                line: 1,
                what: "empty file".to_string(),
            });
        }
    }
    let mut in_curve = false;
    let mut metadata = Vec::new();
    let mut metadata_lines = Vec::new();
    let mut curves: Vec<Curve> = Vec::new();
    let mut last = 1;
    for l in lines {
        last = l.no;
        let t = text::decode(text::trim(l.text)).into_owned();
        if t.is_empty() || t == "%" {
            // Blank lines and the `% ` separators of real exports.
            continue;
        }
        if let Some(name) = t.strip_prefix("%[").and_then(|r| r.strip_suffix(']')) {
            let upper = name.trim().to_ascii_uppercase();
            in_curve = false;
            if upper == "DATA" {
                curves.sort_by_key(|c| c.number);
                check_numbering(file, l.no, &curves)?;
                return Ok(Header {
                    metadata,
                    metadata_lines,
                    curves,
                    data: Start {
                        offset: l.next,
                        line: l.no + 1,
                    },
                });
            } else if let Some(n) = upper.strip_prefix("CURVE") {
                let number = n.trim().parse::<usize>().map_err(|_| {
                    header(file, l.no, format!("curve section '{name}' has no number"))
                })?;
                if curves.iter().any(|c| c.number == number) {
                    return Err(header(
                        file,
                        l.no,
                        format!("curve {number} is declared twice"),
                    ));
                }
                curves.push(Curve {
                    number,
                    line: l.no,
                    keys: Vec::new(),
                });
                in_curve = true;
            } else if upper != "GLOBAL" {
                metadata.push(("section".to_string(), name.to_string()));
                metadata_lines.push(l.no);
            }
            continue;
        }
        let kv = t.strip_prefix('%').unwrap_or(&t);
        let Some((k, v)) = kv.split_once('=') else {
            return Err(header(
                file,
                l.no,
                format!("expected KEY=VALUE, a %[SECTION] line or a '%' separator, found '{t}'"),
            ));
        };
        let (k, v) = (k.trim().to_ascii_uppercase(), v.trim().to_string());
        match curves.last_mut() {
            Some(c) if in_curve => c.keys.push((k, v, l.no)),
            _ => {
                metadata.push((k, v));
                metadata_lines.push(l.no);
            }
        }
    }
    Err(Error::Truncated {
        file: file.to_string(),
        line: last,
        what: match curves.last() {
            Some(c) if in_curve => format!(
                "it stops inside %[CURVE{}] (line {}), before %[DATA]: no %[DATA] section (the export is incomplete; export again)",
                c.number, c.line
            ),
            _ => "no %[DATA] section (the export is incomplete; export again)".to_string(),
        },
    })
}

/// Curves must be numbered 1, 2, … without holes.
fn check_numbering(file: &str, data_line: usize, curves: &[Curve]) -> Result<(), Error> {
    if curves.is_empty() {
        return Err(header(
            file,
            data_line,
            "no %[CURVEn] block before %[DATA]".to_string(),
        ));
    }
    for (i, c) in curves.iter().enumerate() {
        if c.number != i + 1 {
            return Err(header(
                file,
                c.line,
                format!(
                    "curves must be numbered 1, 2, …: curve {} is missing",
                    i + 1
                ),
            ));
        }
    }
    Ok(())
}

/// A curve's required declarations.
struct Decl {
    name: String,
    count: usize,
    count_line: usize,
    /// The recording interval, s, and the line that states it.
    period_s: f64,
    period_line: usize,
    /// The control cycle (`CYCLETIME`), s, when stated.
    cycle_s: Option<f64>,
}

/// A `SAMPLING` or `CYCLETIME` value, µs → s.
fn micros(file: &str, key: &str, name: &str, (v, l): (&str, usize)) -> Result<(f64, usize), Error> {
    match text::parse_f64(v.as_bytes(), true) {
        Ok(us) if us > 0.0 => Ok((us / 1e6, l)),
        _ => Err(header(
            file,
            l,
            format!("{key} '{v}' of curve '{name}' is not a positive number of µs"),
        )),
    }
}

fn declaration(
    file: &str,
    c: &Curve,
    global_sampling: Option<(&str, usize)>,
) -> Result<Decl, Error> {
    let name = c
        .get("NAME")
        .map(|(v, _)| v.to_string())
        .unwrap_or_else(|| format!("CURVE{}", c.number));
    let (count, count_line) = match c.get("COUNT") {
        Some((v, l)) => (
            v.parse::<usize>().map_err(|_| {
                header(
                    file,
                    l,
                    format!("COUNT '{v}' of curve '{name}' is not a sample count"),
                )
            })?,
            l,
        ),
        None => return Err(header(file, c.line, format!("curve '{name}' has no COUNT"))),
    };
    let cycle = c
        .get("CYCLETIME")
        .map(|v| micros(file, "CYCLETIME", &name, v))
        .transpose()?;
    let sampling = match c.get("SAMPLING") {
        Some(v) => Some(micros(file, "SAMPLING", &name, v)?),
        None => global_sampling
            .map(|v| micros(file, "SAMPLING", &name, v))
            .transpose()?,
    };
    let Some((period_s, period_line)) = sampling.or(cycle) else {
        return Err(header(
            file,
            c.line,
            format!("curve '{name}' has no SAMPLING (recording interval) and no CYCLETIME"),
        ));
    };
    Ok(Decl {
        name,
        count,
        count_line,
        period_s,
        period_line,
        cycle_s: cycle.map(|(s, _)| s),
    })
}

/// The data lines: blank lines and `%` separators skipped.
fn rows(bytes: &[u8], start: Start) -> impl Iterator<Item = text::Line<'_>> {
    formats::data_lines(bytes, start, false).filter(|l| text::trim(l.text) != b"%")
}

/// The data rows: time (s) and one cell per curve, NaN where a cell is empty.
fn read_rows(
    file: &str,
    bytes: &[u8],
    start: Start,
    decls: &[Decl],
) -> Result<(Vec<f64>, Vec<Vec<f64>>), Error> {
    let n = decls.len();
    let decimal_comma = rows(bytes, start).take(20).any(|l| l.text.contains(&b','));
    let mut times: Vec<f64> = Vec::new();
    let mut cells: Vec<Vec<f64>> = vec![Vec::new(); n];
    let mut fields: Vec<&[u8]> = Vec::with_capacity(n + 2);
    for l in rows(bytes, start) {
        fields.clear();
        fields.extend(text::split_delim(l.text, b';'));
        if fields.len() > n + 1 && fields.last().is_some_and(|f| text::trim(f).is_empty()) {
            fields.pop();
        }
        if fields.len() != n + 1 {
            return Err(if fields.len() < n + 1 && !l.terminated {
                Error::Truncated {
                    file: file.to_string(),
                    line: l.no,
                    what: format!("the last row has {} of {} fields", fields.len(), n + 1),
                }
            } else {
                Error::FieldCount {
                    file: file.to_string(),
                    line: l.no,
                    expected: n + 1,
                    found: fields.len(),
                }
            });
        }
        let t = text::parse_f64(fields[0], decimal_comma)
            .map_err(|e| formats::num_error(file, l.no, "t [µs]", fields[0], e))?;
        times.push(t * 1e-6);
        for (i, f) in fields[1..].iter().enumerate() {
            let v = if text::trim(f).is_empty() {
                f64::NAN
            } else {
                text::parse_f64(f, decimal_comma)
                    .map_err(|e| formats::num_error(file, l.no, &decls[i].name, f, e))?
            };
            cells[i].push(v);
        }
    }
    Ok((times, cells))
}

/// The row grid: global sample index of every row (lost rows counted), first time and the
/// shortest cycle, s.
struct Grid<'a> {
    g: &'a [usize],
    t0_s: f64,
    base_s: f64,
}

/// The channel of curve `c` (file column `column`): its samples on every k-th row of the grid,
/// its gaps, unit, quantity and axis.
fn channel(
    file: &str,
    (c, d, column): (&Curve, &Decl, usize),
    cells: &[f64],
    grid: &Grid<'_>,
    line_of: &dyn Fn(usize) -> usize,
) -> Result<Channel, Error> {
    let (g, t0_s, base_s) = (grid.g, grid.t0_s, grid.base_s);
    let ratio = d.period_s / base_s;
    let k = ratio.round();
    if (ratio - k).abs() > 1e-6 * ratio {
        return Err(header(
            file,
            d.period_line,
            format!(
                "the recording interval of curve '{}' ({} µs) is not a whole multiple of the shortest one ({} µs)",
                d.name,
                d.period_s * 1e6,
                base_s * 1e6
            ),
        ));
    }
    let k = k as usize;
    let mut ch = Channel::new(d.name.clone(), c.line, column);
    ch.period_s = Some(d.period_s);
    ch.cycle_s = d.cycle_s;
    ch.samples = Vec::with_capacity(d.count.min(cells.len()));
    let mut prev_g: Option<usize> = None;
    // Row of the first empty on-grid cell: the channel ended there (shorter recordings end
    // before the longer ones); a later value is an error.
    let mut ended: Option<usize> = None;
    for (r, &gr) in g.iter().enumerate() {
        if gr % k != 0 {
            continue;
        }
        let v = cells[r];
        if v.is_nan() {
            ended.get_or_insert(r);
            continue;
        }
        if let Some(e) = ended {
            return Err(Error::NotANumber {
                file: file.to_string(),
                line: line_of(e),
                column: d.name.clone(),
                text: String::new(),
            });
        }
        match prev_g {
            Some(p) if gr - p > k => ch.gaps.push(Gap {
                index: ch.samples.len(),
                line: line_of(r),
                lost: Some((gr - p) / k - 1),
            }),
            Some(_) => {}
            None => ch.t0_s = t0_s + gr as f64 * base_s,
        }
        prev_g = Some(gr);
        ch.samples.push(v);
    }
    if ch.samples.len() < d.count && ended.is_none() {
        return Err(Error::Truncated {
            file: file.to_string(),
            line: g.len().checked_sub(1).map_or(c.line, line_of),
            what: format!(
                "the data stop after {} of the {} samples curve '{}' declares (COUNT, line {}): the export is cut short",
                ch.samples.len(),
                d.count,
                d.name,
                d.count_line
            ),
        });
    }
    if ch.samples.len() != d.count {
        return Err(Error::CountMismatch {
            file: file.to_string(),
            line: d.count_line,
            channel: d.name.clone(),
            declared: d.count,
            found: ch.samples.len(),
        });
    }
    if let Some((dim, _)) = c.get("DIMENSION") {
        ch.unit = TraceUnit::parse(dim);
    }
    let channel_type = c.get("CHANNELTYPE").map(|(v, _)| v.to_string());
    ch.description = channel_type.clone().unwrap_or_default();
    formats::infer_channel(&mut ch, &[("NAME", &d.name)], None);
    if let Some(q) = channel_type.as_deref().and_then(infer::tnc_channel_type) {
        ch.quantity = q;
    }
    if let Some((at, _)) = c.get("AXISTYPE") {
        let declared = at
            .parse::<AxisName>()
            .ok()
            .or_else(|| infer::axis_of(at, "AXISTYPE", None).map(|(a, _, _)| a));
        if let Some(axis) = declared {
            ch.axis = Some(axis);
            ch.axis_source = Some(AxisSource::Declared {
                key: "AXISTYPE".to_string(),
                value: at.to_string(),
            });
        }
    }
    Ok(ch)
}

pub(crate) fn read(file: &str, bytes: &[u8], opts: &ReadOptions) -> Result<Trace, Error> {
    let h = read_header(file, bytes)?;
    let decls = h
        .curves
        .iter()
        .map(|c| {
            let global = h
                .metadata
                .iter()
                .position(|(k, _)| k == "SAMPLING")
                .map(|i| (h.metadata[i].1.as_str(), h.metadata_lines[i]));
            declaration(file, c, global)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let (times, cells) = read_rows(file, bytes, h.data, &decls)?;
    // Rows come at the shortest cycle; the time column must be uniform at it, up to gaps.
    let line_of = |row: usize| rows(bytes, h.data).nth(row).map_or(h.data.line, |l| l.no);
    let base_s = decls
        .iter()
        .map(|d| d.period_s)
        .fold(f64::INFINITY, f64::min);
    let base_line = decls
        .iter()
        .find(|d| d.period_s == base_s)
        .map_or(h.data.line, |d| d.period_line);
    let u = timebase::uniform(&times, Some(base_s))
        .map_err(|f| formats::time_error(file, f, base_line, line_of))?;
    // Global sample index of every row (rows lost in gaps counted).
    let mut g = Vec::with_capacity(times.len());
    let mut lost = 0usize;
    let mut gaps = u.gaps.iter().peekable();
    for r in 0..times.len() {
        if let Some(&&(index, l)) = gaps.peek()
            && index == r
        {
            lost = lost.saturating_add(l);
            gaps.next();
        }
        g.push(r.saturating_add(lost));
    }
    let mut channels = Vec::with_capacity(decls.len());
    let grid = Grid {
        g: &g,
        t0_s: u.t0_s,
        base_s,
    };
    for (i, (c, d)) in h.curves.iter().zip(&decls).enumerate() {
        let mut ch = channel(file, (c, d, i + 1), &cells[i], &grid, &line_of)?;
        formats::apply_period_option(file, opts, &mut ch)?;
        channels.push(ch);
    }
    Ok(Trace {
        file: file.to_string(),
        format: Format::TncScope,
        channels,
        metadata: h.metadata,
    })
}
