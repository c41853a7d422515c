//! The readers, one module per format, each documenting the layout it reads and the public
//! description it follows (the sample files and their sources are listed in
//! `crates/vcnc-trace/tests/data/README.md`). They are used through [`crate::read_path`].

pub mod delimited;
pub mod halsampler;
pub mod halscope;
pub mod parquet;
pub mod sinumerik;
pub mod tncscope;
pub mod twincat;

use vcnc_axis::AxisName;

use crate::error::Error;
use crate::infer;
use crate::model::{Channel, Gap, Quantity, ReadOptions};
use crate::text::{self, Lines, NumError};
use crate::timebase::{TimeFault, Uniform};

/// The error for a field that failed to parse.
pub(crate) fn num_error(file: &str, line: usize, column: &str, field: &[u8], e: NumError) -> Error {
    match e {
        NumError::Syntax => Error::NotANumber {
            file: file.to_string(),
            line,
            column: column.to_string(),
            text: text::show(field),
        },
        NumError::NotFinite => Error::NotFinite {
            file: file.to_string(),
            line,
            column: column.to_string(),
            text: text::show(field),
        },
    }
}

/// The error for a time fault; `line_of_row` gives the line of a row of the time column.
pub(crate) fn time_error(
    file: &str,
    fault: TimeFault,
    declared_line: usize,
    line_of_row: impl Fn(usize) -> usize,
) -> Error {
    match fault {
        TimeFault::NotIncreasing { row, t_prev, t } => Error::TimeNotIncreasing {
            file: file.to_string(),
            line: line_of_row(row),
            t_prev_s: t_prev,
            t_s: t,
        },
        TimeFault::Irregular { row, dt, period } => Error::IrregularTime {
            file: file.to_string(),
            line: line_of_row(row),
            dt_s: dt,
            period_s: period,
        },
        TimeFault::Mismatch { mean, declared } => Error::Header {
            file: file.to_string(),
            line: declared_line,
            what: format!(
                "the time column advances {mean} s per sample on average, but the declared sample period is {declared} s"
            ),
        },
    }
}

/// Sets `ch`'s time base from a checked time column.
pub(crate) fn apply_uniform(ch: &mut Channel, u: &Uniform, line_of_row: impl Fn(usize) -> usize) {
    ch.t0_s = u.t0_s;
    ch.period_s = u.period_s;
    ch.gaps = u
        .gaps
        .iter()
        .map(|&(index, lost)| Gap {
            index,
            line: line_of_row(index),
            lost: Some(lost),
        })
        .collect();
}

/// Sets axis and quantity of `ch` from its name fields, tried in order: the first field naming an
/// axis gives the axis, the first field naming a quantity other than [`Quantity::Other`] gives the
/// quantity. `joints` enables LinuxCNC joint numbers.
pub(crate) fn infer_channel(
    ch: &mut Channel,
    fields: &[(&str, &str)],
    joints: Option<&[AxisName]>,
) {
    let mut suffix = String::new();
    for (field, text) in fields {
        if let Some((axis, source, s)) = infer::axis_of(text, field, joints) {
            ch.axis = Some(axis);
            ch.axis_source = Some(source);
            suffix = s;
            break;
        }
    }
    for (_, text) in fields {
        let q = infer::quantity_of(text, &suffix);
        if q != Quantity::Other {
            ch.quantity = q;
            break;
        }
    }
}

/// Applies [`ReadOptions::period_s`] to a channel: fills a missing period, refuses a
/// contradicting one.
pub(crate) fn apply_period_option(
    file: &str,
    opts: &ReadOptions,
    ch: &mut Channel,
) -> Result<(), Error> {
    let Some(given) = opts.period_s else {
        return Ok(());
    };
    if !(given.is_finite() && given > 0.0) {
        return Err(Error::BadOption {
            file: file.to_string(),
            what: format!("the sample period given ({given} s) must be positive"),
        });
    }
    match ch.period_s {
        None => ch.period_s = Some(given),
        Some(p) if (p / given - 1.0).abs() > 1e-3 => {
            return Err(Error::PeriodConflict {
                file: file.to_string(),
                line: ch.line,
                channel: ch.name.clone(),
                file_s: p,
                given_s: given,
            });
        }
        Some(_) => {}
    }
    Ok(())
}

/// How the fields of a data row are separated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Delim {
    /// One byte (`,` `;` tab).
    Byte(u8),
    /// Runs of white space.
    Whitespace,
}

impl Delim {
    pub(crate) fn describe(self) -> &'static str {
        match self {
            Delim::Byte(b',') => "','",
            Delim::Byte(b';') => "';'",
            Delim::Byte(b'\t') => "tab",
            Delim::Byte(_) => "a separator",
            Delim::Whitespace => "white space",
        }
    }
}

/// Where data rows start: byte offset and its line number.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Start {
    pub offset: usize,
    pub line: usize,
}

/// Data lines from `start`: blank lines and (with `comments`) `#` lines skipped.
pub(crate) fn data_lines(
    bytes: &[u8],
    start: Start,
    comments: bool,
) -> impl Iterator<Item = text::Line<'_>> {
    Lines::starting_at(bytes, start.offset, start.line).filter(move |l| {
        !(text::is_blank(l.text) || (comments && text::trim(l.text).first() == Some(&b'#')))
    })
}

/// Line of data row `row` (0-based), for error messages (rescans: errors are rare).
pub(crate) fn row_line(bytes: &[u8], start: Start, comments: bool, row: usize) -> usize {
    data_lines(bytes, start, comments)
        .nth(row)
        .map_or(start.line, |l| l.no)
}

/// Reads data rows of `names.len()` numeric fields into one vector per column.
///
/// A trailing separator is allowed. A row with another number of fields is an error
/// ([`Error::FieldCount`], or [`Error::Truncated`] for a short last line without a line end).
pub(crate) fn read_table(
    file: &str,
    bytes: &[u8],
    start: Start,
    delim: Delim,
    decimal_comma: bool,
    names: &[String],
    comments: bool,
) -> Result<Vec<Vec<f64>>, Error> {
    let ncols = names.len();
    let mut lines = data_lines(bytes, start, comments).peekable();
    let capacity = match lines.peek() {
        Some(l) => (bytes.len() - l.offset) / (l.text.len() + 1) + 1,
        None => 0,
    };
    let mut cols: Vec<Vec<f64>> = (0..ncols).map(|_| Vec::with_capacity(capacity)).collect();
    // One reused vector of field slices: no allocation per row.
    let mut fields: Vec<&[u8]> = Vec::with_capacity(ncols + 1);
    for l in lines {
        fields.clear();
        match delim {
            Delim::Byte(d) => fields.extend(text::split_delim(l.text, d)),
            Delim::Whitespace => text::split_ws_into(l.text, &mut fields),
        }
        if fields.len() == ncols + 1 && text::trim(fields[ncols]).is_empty() {
            fields.pop();
        }
        if fields.len() != ncols {
            return Err(if fields.len() < ncols && !l.terminated {
                Error::Truncated {
                    file: file.to_string(),
                    line: l.no,
                    what: format!("the last row has {} of {ncols} fields", fields.len()),
                }
            } else {
                Error::FieldCount {
                    file: file.to_string(),
                    line: l.no,
                    expected: ncols,
                    found: fields.len(),
                }
            });
        }
        for (i, (field, col)) in fields.iter().zip(cols.iter_mut()).enumerate() {
            match text::parse_f64(field, decimal_comma) {
                Ok(v) => col.push(v),
                Err(e) if i + 1 == ncols && !l.terminated && e == NumError::Syntax => {
                    return Err(Error::Truncated {
                        file: file.to_string(),
                        line: l.no,
                        what: format!(
                            "the last row stops inside column '{}' ('{}')",
                            names[i],
                            text::show(field)
                        ),
                    });
                }
                Err(e) => return Err(num_error(file, l.no, &names[i], field, e)),
            }
        }
    }
    Ok(cols)
}
