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

    let cols = formats::read_table(file, bytes, data_start, delim, decimal_comma, &names, true)?;
    let line_of = |row: usize| formats::row_line(bytes, data_start, true, row);

    let uniform = match time_col {
        Some(tc) => {
            let unit = units[tc]
                .clone()
                .or_else(|| time_name(&names[tc]).flatten())
                .or_else(|| opts.time_unit.clone())
                .unwrap_or(TraceUnit::S);
            let k = match unit.to_base() {
                Some((BaseUnit::S, k)) => k,
                _ => {
                    return Err(Error::Header {
                        file: file.to_string(),
                        line: header_line,
                        what: format!("time column '{}' is in {unit}, not a time unit", names[tc]),
                    });
                }
            };
            let times: std::borrow::Cow<'_, [f64]> = if k == 1.0 {
                std::borrow::Cow::Borrowed(&cols[tc])
            } else {
                cols[tc].iter().map(|t| t * k).collect()
            };
            let u = timebase::uniform(&times, None)
                .map_err(|f| formats::time_error(file, f, header_line, line_of))?;
            Some(u)
        }
        None => None,
    };

    let mut channels = Vec::with_capacity(names.len());
    for (c, samples) in cols.into_iter().enumerate() {
        if Some(c) == time_col {
            continue;
        }
        let mut ch = Channel::new(names[c].clone(), first.no, c);
        ch.unit = units[c].clone();
        ch.samples = samples;
        if let Some(u) = &uniform {
            formats::apply_uniform(&mut ch, u, line_of);
        }
        formats::apply_period_option(file, opts, &mut ch)?;
        formats::infer_channel(&mut ch, &[("name", &names[c])], None);
        channels.push(ch);
    }
    metadata.push(("separator".to_string(), delim.describe().to_string()));
    metadata.push((
        "decimal mark".to_string(),
        if decimal_comma { "','" } else { "'.'" }.to_string(),
    ));
    if let Some(tc) = time_col {
        metadata.push(("time column".to_string(), names[tc].clone()));
    }
    Ok(Trace {
        file: file.to_string(),
        format: Format::Delimited,
        channels,
        metadata,
    })
}
