//! Generic delimited text: `,` `;` tab or white-space separated columns, `#` comment lines, an
//! optional header line, either decimal mark.
//!
//! * Separator: the first of `;`, tab, `,` found in the first non-comment line, else white space.
//! * Decimal mark: `,` when the separator is not `,` and a field of the first 20 data rows holds
//!   a `,`; else `.`.
//! * Header: the first non-comment line when any of its fields is not a number; its fields name
//!   the columns, a unit in brackets after the name (`x [mm]`, `t (ms)`) is the column's unit.
//!   Without a header the columns are named by [`ReadOptions::channel_names`], else `col0`,
//!   `col1`, ….
//! * Time column: [`ReadOptions::time_column`], else the column named `t`, `time`, `zeit` or
//!   `timestamp` (a `_s`, `_ms`, `_us` suffix gives its unit); in s unless its header or
//!   [`ReadOptions::time_unit`] says otherwise. It must be uniform up to gaps
//!   (see [`crate::STEP_TOLERANCE`]). Without one, [`ReadOptions::period_s`] gives the period.

use crate::error::Error;
use crate::formats::{self, Delim, Start};
use crate::model::{Channel, ChannelRef, Format, ReadOptions, Trace};
use crate::text;
use crate::timebase;
use crate::units::{BaseUnit, TraceUnit};

/// A column name and the unit written after it, if any.
pub(crate) fn split_unit(header: &str) -> (String, Option<TraceUnit>) {
    let h = header.trim().trim_matches('"').trim();
    for (open, close) in [('[', ']'), ('(', ')')] {
        if let Some(stripped) = h.strip_suffix(close)
            && let Some(i) = stripped.rfind(open)
        {
            let name = stripped[..i].trim();
            if !name.is_empty() {
                return (name.to_string(), TraceUnit::parse(&stripped[i + 1..]));
            }
        }
    }
    (h.to_string(), None)
}

/// The separator of a line (see the module documentation).
pub(crate) fn choose_delim(line: &[u8]) -> Delim {
    for d in [b';', b'\t', b','] {
        if line.contains(&d) {
            return Delim::Byte(d);
        }
    }
    Delim::Whitespace
}

pub(crate) fn fields(line: &[u8], delim: Delim) -> Vec<&[u8]> {
    let mut v: Vec<&[u8]> = match delim {
        Delim::Byte(d) => text::split_delim(line, d).collect(),
        Delim::Whitespace => text::split_ws(line).collect(),
    };
    if v.len() > 1 && v.last().is_some_and(|f| text::trim(f).is_empty()) {
        v.pop();
    }
    v
}

/// The time column's unit implied by its name (`t_ms` → ms), and whether the name is a time
/// column's.
fn time_name(name: &str) -> Option<Option<TraceUnit>> {
    let n = name.trim().to_ascii_lowercase();
    for base in ["t", "time", "zeit", "timestamp"] {
        if n == base {
            return Some(None);
        }
        if let Some(suffix) = n.strip_prefix(base).and_then(|s| s.strip_prefix('_')) {
            let unit = match suffix {
                "s" => TraceUnit::S,
                "ms" => TraceUnit::Ms,
                "us" => TraceUnit::Us,
                _ => continue,
            };
            return Some(Some(unit));
        }
    }
    None
}

pub(crate) fn read(file: &str, bytes: &[u8], opts: &ReadOptions) -> Result<Trace, Error> {
    let mut metadata = Vec::new();
    let (first, last_line) = text::first_content_line(
        bytes,
        |_| false,
        |c, _| metadata.push(("comment".to_string(), c)),
    );
    let Some(first) = first else {
        return Err(Error::Truncated {
            file: file.to_string(),
            line: last_line,
            what: "no header and no data rows".to_string(),
        });
    };
    let delim = choose_delim(first.text);
    let head = fields(first.text, delim);
    let has_header = head.iter().any(|f| !text::looks_numeric(f));
    let data_start = if has_header {
        Start {
            offset: first.next,
            line: first.no + 1,
        }
    } else {
        Start {
            offset: first.offset,
            line: first.no,
        }
    };
    let decimal_comma = delim != Delim::Byte(b',')
        && formats::data_lines(bytes, data_start, true)
            .take(20)
            .any(|l| fields(l.text, delim).iter().any(|f| f.contains(&b',')));

    let mut names = Vec::with_capacity(head.len());
    let mut units = Vec::with_capacity(head.len());
    if has_header {
        for f in &head {
            let (n, u) = split_unit(&text::decode(f));
            names.push(n);
            units.push(u);
        }
    } else if !opts.channel_names.is_empty() {
        if opts.channel_names.len() != head.len() {
            return Err(Error::BadOption {
                file: file.to_string(),
                what: format!(
                    "{} channel names given for {} columns",
                    opts.channel_names.len(),
                    head.len()
                ),
            });
        }
        names = opts.channel_names.clone();
        units = vec![None; head.len()];
    } else {
        names = (0..head.len()).map(|i| format!("col{i}")).collect();
        units = vec![None; head.len()];
    }
    let header_line = if has_header { first.no } else { 0 };

    let cols = formats::read_table(file, bytes, data_start, delim, decimal_comma, &names, true)?;
    let line_of = |row: usize| formats::row_line(bytes, data_start, true, row);
    let header = Header {
        first_line: first.no,
        line: header_line,
        names,
        units,
    };
    let (channels, time_column) = named_channels(file, header, cols, line_of, opts)?;
    metadata.push(("separator".to_string(), delim.describe().to_string()));
    metadata.push((
        "decimal mark".to_string(),
        if decimal_comma { "','" } else { "'.'" }.to_string(),
    ));
    if let Some(name) = time_column {
        metadata.push(("time column".to_string(), name));
    }
    Ok(Trace {
        file: file.to_string(),
        format: Format::Delimited,
        channels,
        metadata,
    })
}

/// A table's header: the line of its first row of content, the line of its names (0: none), and
/// its columns' names and units.
pub(crate) struct Header {
    pub first_line: usize,
    pub line: usize,
    pub names: Vec<String>,
    pub units: Vec<Option<TraceUnit>>,
}

/// The channels of a table of named columns `cols` (one per name, in order) and the name of its
/// time column, if any (module documentation: [`ReadOptions::time_column`], else a time name);
/// `line_of` gives the line of a row. The delimited reader and the Parquet reader end here.
pub(crate) fn named_channels(
    file: &str,
    header: Header,
    cols: Vec<Vec<f64>>,
    line_of: impl Fn(usize) -> usize,
    opts: &ReadOptions,
) -> Result<(Vec<Channel>, Option<String>), Error> {
    let Header {
        first_line,
        line: header_line,
        names,
        units,
    } = header;
    let time_col = match &opts.time_column {
        Some(ChannelRef::Column(c)) if *c < names.len() => Some(*c),
        Some(ChannelRef::Name(n)) if names.iter().any(|m| m == n) => {
            names.iter().position(|m| m == n)
        }
        Some(r) => {
            return Err(Error::UnknownChannel {
                file: file.to_string(),
                reference: format!("{r} (time column)"),
                channels: names.clone(),
            });
        }
        None => names.iter().position(|n| time_name(n).is_some()),
    };
    let mut times = None;
    let mut columns = Vec::with_capacity(names.len());
    for (c, ((name, unit), samples)) in names.into_iter().zip(units).zip(cols).enumerate() {
        if Some(c) != time_col {
            columns.push(Column {
                name,
                unit,
                samples,
                column: c,
            });
            continue;
        }
        let unit = unit
            .or_else(|| time_name(&name).flatten())
            .or_else(|| opts.time_unit.clone())
            .unwrap_or(TraceUnit::S);
        let k = match unit.to_base() {
            Some((BaseUnit::S, k)) => k,
            _ => {
                return Err(Error::Header {
                    file: file.to_string(),
                    line: header_line,
                    what: format!("time column '{name}' is in {unit}, not a time unit"),
                });
            }
        };
        let mut t = samples;
        if k != 1.0 {
            t.iter_mut().for_each(|v| *v *= k);
        }
        times = Some((name, t));
    }
    let channels = channels(
        file,
        first_line,
        times.as_ref().map(|(_, t)| t.as_slice()),
        columns,
        header_line,
        line_of,
        opts,
    )?;
    Ok((channels, times.map(|(name, _)| name)))
}

/// A column of samples with its name, unit and place in the file (0-based, counting a time
/// column).
pub(crate) struct Column {
    pub name: String,
    pub unit: Option<TraceUnit>,
    pub samples: Vec<f64>,
    pub column: usize,
}

/// The channels of `columns`, their time base checked from `times` (s) when given, else from
/// [`ReadOptions::period_s`]; `header_line` is the line a fault of the time base as a whole
/// is reported on and `line_of` gives the line of a row. Both the reader and
/// [`crate::from_columns`] end here: one law for time columns and names.
#[allow(clippy::too_many_arguments)]
pub(crate) fn channels(
    file: &str,
    line: usize,
    times: Option<&[f64]>,
    columns: Vec<Column>,
    header_line: usize,
    line_of: impl Fn(usize) -> usize,
    opts: &ReadOptions,
) -> Result<Vec<Channel>, Error> {
    let uniform = match times {
        Some(t) => Some(
            timebase::uniform(t, None)
                .map_err(|f| formats::time_error(file, f, header_line, &line_of))?,
        ),
        None => None,
    };
    let mut channels = Vec::with_capacity(columns.len());
    for c in columns {
        let mut ch = Channel::new(c.name, line, c.column);
        ch.unit = c.unit;
        ch.samples = c.samples;
        if let Some(u) = &uniform {
            formats::apply_uniform(&mut ch, u, &line_of);
        }
        formats::apply_period_option(file, opts, &mut ch)?;
        let name = ch.name.clone();
        formats::infer_channel(&mut ch, &[("name", &name)], None);
        channels.push(ch);
    }
    Ok(channels)
}

/// A trace of columns held in memory (numpy arrays from Python): named columns of samples,
/// with `times` (s) for their time column or, without one, [`ReadOptions::period_s`] for their
/// period. The columns go through the delimited reader's law (time base, names, units), so
/// that they read exactly as the text file with a header row `t,<names…>` and one row per
/// sample would: sample `k` (from 0) is reported as line `k + 2` of `file`. Non-finite values
/// and columns of unequal length are refused, as the reader refuses them.
pub fn from_columns(
    file: &str,
    times: Option<&[f64]>,
    columns: Vec<(String, Vec<f64>)>,
    opts: &ReadOptions,
) -> Result<Trace, Error> {
    let offset = usize::from(times.is_some());
    let n = times.map_or_else(|| columns.first().map_or(0, |c| c.1.len()), <[f64]>::len);
    let mut named: Vec<(&str, &[f64])> = times.map(|t| ("t", t)).into_iter().collect();
    named.extend(
        columns
            .iter()
            .map(|(name, v)| (name.as_str(), v.as_slice())),
    );
    if named.iter().any(|(_, v)| v.len() != n) || n == 0 {
        let lengths: Vec<String> = named
            .iter()
            .map(|(c, v)| format!("{c} {}", v.len()))
            .collect();
        return Err(Error::BadOption {
            file: file.to_string(),
            what: format!(
                "the columns must hold one non-zero number of samples; they hold {}",
                lengths.join(", ")
            ),
        });
    }
    for (name, v) in named {
        if let Some(k) = v.iter().position(|x| !x.is_finite()) {
            return Err(Error::NotFinite {
                file: file.to_string(),
                line: k + 2,
                column: name.to_string(),
                text: v[k].to_string(),
            });
        }
    }
    let columns = columns
        .into_iter()
        .enumerate()
        .map(|(c, (name, samples))| {
            let (name, unit) = split_unit(&name);
            Column {
                name,
                unit,
                samples,
                column: c + offset,
            }
        })
        .collect();
    let mut metadata = Vec::new();
    if times.is_some() {
        metadata.push(("time column".to_string(), "t".to_string()));
    }
    Ok(Trace {
        file: file.to_string(),
        format: Format::Delimited,
        channels: channels(file, 1, times, columns, 1, |row| row + 2, opts)?,
        metadata,
    })
}
