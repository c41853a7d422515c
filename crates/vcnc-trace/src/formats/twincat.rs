//! Beckhoff TwinCAT Scope CSV export (TwinCAT 3 Scope View, "Export" to CSV; layout as in the two
//! BSD-licensed sample exports of `tests/data/twincat`, and as read by the public pytcs reader,
//! github CagtayFabry/pytcs).
//!
//! ```text
//! Name;scope name                              ← header block: one key per row
//! File;C:\…\export.csv
//! Starttime of export;132959733843760000;…
//! Endtime of export;132959733853750000;…
//!                                              ← blank line(s)
//! Name;var_BIT;Name;var_INT8                   ← channel block: "Name" starts a column group
//! SampleTime[ms];1;SampleTime[ms];1            ← metadata rows, same layout
//! Unit;(None);Unit;mm (Millimeter)
//! SymbolName;MAIN.var_BOOL;SymbolName;MAIN.AxisX.NcToPlc.ActPos
//!                                              ← blank line
//! 0;0;0;0                                      ← data: per group a time column (ms), then
//! 1;1;1;1                                          its channels' values
//! ```
//!
//! * The separator is the character after the first `Name` (`;`, tab, `,` or `:`); the decimal
//!   mark is `,` when a sample time or a data field of the first 50 rows holds one and the
//!   separator is not `,`.
//! * In the channel block, every cell `Name` starts a group: its column is the group's time
//!   column (ms), the cells up to the next `Name` are the channels sharing it. The default export
//!   gives each channel its own time column; other export options share one time column between
//!   channels of one sample time.
//! * Groups may have different lengths: a group ends at the first row whose time cell is empty
//!   (or `EOF`); its value cells must end there too.
//! * Used metadata: `SampleTime[ms]` (the period, checked against the time column), `Unit`
//!   (`(None)` is no unit; `mm (Millimeter)` is mm), `SymbolName` (the channel's description).
//!   Values are exported already scaled (in the sample file the channel with `Unit ScaleFactor`
//!   −10 and `Unit Offset` 10 holds 10, 0, −10, … where the raw counter holds 0, 1, 2), so
//!   `ScaleFactor`, `Offset`, `Unit ScaleFactor` and `Unit Offset` are not applied.
//! * A metadata row whose key cells do not line up with the channel block is ignored, unless it
//!   is one of the rows used (the sample exports have such a `SymbolComment` row).

use crate::error::Error;
use crate::formats::{self, Start};
use crate::model::{Channel, Format, ReadOptions, Trace};
use crate::text::{self, Line, Lines};
use crate::timebase;
use crate::units::TraceUnit;

const USED_KEYS: [&str; 4] = ["SampleTime[ms]", "SampleTime", "Unit", "SymbolName"];

struct Group {
    time_col: usize,
    cols: Vec<usize>,
}

fn header(file: &str, line: usize, what: String) -> Error {
    Error::Header {
        file: file.to_string(),
        line,
        what,
    }
}

fn cells(line: &[u8], sep: u8) -> Vec<String> {
    text::split_delim(line, sep)
        .map(|c| text::decode(text::trim(c)).into_owned())
        .collect()
}

/// The header block: its separator, its fields, and the channel block's `Name` row.
struct Header<'a> {
    sep: u8,
    metadata: Vec<(String, String)>,
    block: Line<'a>,
}

fn read_header<'a>(file: &str, lines: &mut Lines<'a>) -> Result<Header<'a>, Error> {
    let first = lines.next().ok_or_else(|| Error::Truncated {
        file: file.to_string(),
        line: 1,
        what: "empty file".to_string(),
    })?;
    let sep = match first.text.strip_prefix(b"Name").and_then(|r| r.first()) {
        Some(&s) if matches!(s, b';' | b'\t' | b',' | b':') => s,
        _ => {
            return Err(header(
                file,
                1,
                format!(
                    "expected 'Name' and a separator (';', tab, ',' or ':'), found '{}'",
                    text::show(first.text)
                ),
            ));
        }
    };
    let mut metadata = Vec::new();
    let mut push_meta = |t: &[u8]| {
        if let Some((k, v)) = cells(t, sep).split_first() {
            metadata.push((k.clone(), v.join(" ").trim().to_string()));
        }
    };
    push_meta(first.text);
    let mut seen_blank = false;
    let mut last = first.no;
    for l in lines.by_ref() {
        last = l.no;
        if text::is_blank(l.text) {
            seen_blank = true;
            continue;
        }
        if seen_blank && l.text.starts_with(b"Name") && l.text.get(4) == Some(&sep) {
            return Ok(Header {
                sep,
                metadata,
                block: l,
            });
        }
        push_meta(l.text);
    }
    Err(Error::Truncated {
        file: file.to_string(),
        line: last,
        what: "no channel block (a 'Name' row after a blank line)".to_string(),
    })
}

/// The column groups of the channel block: every `Name` cell starts one.
fn groups(file: &str, line: usize, names: &[String]) -> Result<Vec<Group>, Error> {
    let mut groups: Vec<Group> = Vec::new();
    for (c, cell) in names.iter().enumerate() {
        if cell == "Name" {
            groups.push(Group {
                time_col: c,
                cols: Vec::new(),
            });
        } else if cell.is_empty() && c + 1 == names.len() {
            // A trailing separator.
        } else if let Some(g) = groups.last_mut() {
            g.cols.push(c);
        }
    }
    if let Some(g) = groups.iter().find(|g| g.cols.is_empty()) {
        return Err(header(
            file,
            line,
            format!(
                "the 'Name' in column {} is followed by no channel",
                g.time_col + 1
            ),
        ));
    }
    Ok(groups)
}

/// A metadata row: key, cells, line.
type MetaRow = (String, Vec<String>, usize);

/// The metadata rows up to the blank line, and where the data may start.
fn read_metadata(
    file: &str,
    lines: &mut Lines<'_>,
    sep: u8,
    groups: &[Group],
    block_line: usize,
) -> Result<(Vec<MetaRow>, Start), Error> {
    let mut rows = Vec::new();
    let mut last = block_line;
    for l in lines.by_ref() {
        last = l.no;
        if text::is_blank(l.text) {
            let start = Start {
                offset: l.next,
                line: l.no + 1,
            };
            return Ok((rows, start));
        }
        let c = cells(l.text, sep);
        let key = c.first().cloned().unwrap_or_default();
        if groups.iter().all(|g| c.get(g.time_col) == Some(&key)) {
            rows.push((key, c, l.no));
        } else if USED_KEYS.contains(&key.as_str()) {
            return Err(header(
                file,
                l.no,
                format!("metadata row '{key}' does not line up with the channel block"),
            ));
        }
    }
    Err(Error::Truncated {
        file: file.to_string(),
        line: last,
        what: "no data after the channel block".to_string(),
    })
}

/// Per group its times (s), per column its values.
struct Data {
    times: Vec<Vec<f64>>,
    values: Vec<Vec<f64>>,
}

/// The data rows. A group ends at its first empty (or `EOF`) time cell.
fn read_data(
    file: &str,
    bytes: &[u8],
    start: Start,
    (sep, decimal_comma): (u8, bool),
    groups: &[Group],
    names: &[String],
) -> Result<Data, Error> {
    let ncols = names.len();
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); groups.len()];
    let mut values: Vec<Vec<f64>> = vec![Vec::new(); ncols];
    let mut ended = vec![false; groups.len()];
    let mut row: Vec<&[u8]> = Vec::with_capacity(ncols + 1);
    for l in formats::data_lines(bytes, start, false) {
        row.clear();
        row.extend(text::split_delim(l.text, sep));
        if row.len() > ncols && row[ncols..].iter().all(|c| text::trim(c).is_empty()) {
            row.truncate(ncols);
        }
        if row.len() > ncols {
            return Err(Error::FieldCount {
                file: file.to_string(),
                line: l.no,
                expected: ncols,
                found: row.len(),
            });
        }
        let cell = |c: usize| row.get(c).map_or(&b""[..], |f| text::trim(f));
        for (gi, g) in groups.iter().enumerate() {
            let t = cell(g.time_col);
            if ended[gi] || t.is_empty() || t == b"EOF" {
                ended[gi] = true;
                if let Some(&c) = g
                    .cols
                    .iter()
                    .find(|&&c| !cell(c).is_empty() && cell(c) != b"EOF")
                {
                    return Err(header(
                        file,
                        l.no,
                        format!(
                            "channel '{}' has a value where its time column (column {}) has none",
                            names[c],
                            g.time_col + 1
                        ),
                    ));
                }
                continue;
            }
            let tv = text::parse_f64(t, decimal_comma)
                .map_err(|e| formats::num_error(file, l.no, "time [ms]", t, e))?;
            times[gi].push(tv * 1e-3);
            for &c in &g.cols {
                let f = cell(c);
                match text::parse_f64(f, decimal_comma) {
                    Ok(v) => values[c].push(v),
                    Err(_) if f.is_empty() && !l.terminated => {
                        return Err(Error::Truncated {
                            file: file.to_string(),
                            line: l.no,
                            what: format!("the last row stops before channel '{}'", names[c]),
                        });
                    }
                    Err(e) => return Err(formats::num_error(file, l.no, &names[c], f, e)),
                }
            }
        }
    }
    Ok(Data { times, values })
}

/// The sample time a group's channels declare (s) and its line; they must agree.
fn declared_period(
    file: &str,
    sample_times: Option<&MetaRow>,
    g: &Group,
    names: &[String],
    decimal_comma: bool,
) -> Result<Option<(f64, usize)>, Error> {
    let Some((_, cells, line)) = sample_times else {
        return Ok(None);
    };
    let mut declared: Option<(f64, usize)> = None;
    for &c in &g.cols {
        let v = cells.get(c).map(String::as_str).unwrap_or("");
        let ms = text::parse_f64(v.as_bytes(), decimal_comma).map_err(|_| {
            header(
                file,
                *line,
                format!("SampleTime '{v}' of '{}' is not a number", names[c]),
            )
        })?;
        match declared {
            Some((d, _)) if (d - ms * 1e-3).abs() > 1e-12 => {
                return Err(header(
                    file,
                    *line,
                    format!(
                        "channels sharing time column {} declare different sample times",
                        g.time_col + 1
                    ),
                ));
            }
            _ => declared = Some((ms * 1e-3, *line)),
        }
    }
    Ok(declared)
}

pub(crate) fn read(file: &str, bytes: &[u8], opts: &ReadOptions) -> Result<Trace, Error> {
    let mut lines = Lines::new(bytes);
    let Header {
        sep,
        metadata,
        block,
    } = read_header(file, &mut lines)?;
    let names = cells(block.text, sep);
    let groups = groups(file, block.no, &names)?;
    let (meta_rows, data_from) = read_metadata(file, &mut lines, sep, &groups, block.no)?;
    let meta = |key: &str| meta_rows.iter().find(|(k, _, _)| k == key);
    let sample_times = meta("SampleTime[ms]").or_else(|| meta("SampleTime"));

    // First data row: the first line whose first cell is a number.
    let data_start = formats::data_lines(bytes, data_from, false)
        .find(|l| {
            text::split_delim(l.text, sep)
                .next()
                .is_some_and(text::looks_numeric)
        })
        .map_or(
            Start {
                offset: bytes.len(),
                line: data_from.line,
            },
            |l| Start {
                offset: l.offset,
                line: l.no,
            },
        );
    let decimal_comma = sep != b','
        && (sample_times.is_some_and(|(_, c, _)| c.iter().any(|v| v.contains(',')))
            || formats::data_lines(bytes, data_start, false)
                .take(50)
                .any(|l| text::split_delim(l.text, sep).any(|f| f.contains(&b','))));
    let Data { times, mut values } = read_data(
        file,
        bytes,
        data_start,
        (sep, decimal_comma),
        &groups,
        &names,
    )?;

    let line_of = |r: usize| formats::row_line(bytes, data_start, false, r);
    let mut channels = Vec::new();
    for (gi, g) in groups.iter().enumerate() {
        let declared = declared_period(file, sample_times, g, &names, decimal_comma)?;
        let u = timebase::uniform(&times[gi], declared.map(|d| d.0)).map_err(|f| {
            formats::time_error(file, f, declared.map_or(block.no, |d| d.1), line_of)
        })?;
        for &c in &g.cols {
            let mut ch = Channel::new(names[c].clone(), block.no, c);
            ch.samples = std::mem::take(&mut values[c]);
            formats::apply_uniform(&mut ch, &u, line_of);
            if let Some((_, cells, _)) = meta("Unit") {
                ch.unit = cells.get(c).and_then(|u| TraceUnit::parse(u));
            }
            if let Some((_, cells, _)) = meta("SymbolName") {
                ch.description = cells.get(c).cloned().unwrap_or_default();
            }
            formats::apply_period_option(file, opts, &mut ch)?;
            let (n, s) = (ch.name.clone(), ch.description.clone());
            formats::infer_channel(&mut ch, &[("name", &n), ("symbol", &s)], None);
            channels.push(ch);
        }
    }
    Ok(Trace {
        file: file.to_string(),
        format: Format::TwinCatScope,
        channels,
        metadata,
    })
}
