//! Which format a file is, from its content (see [`detect`]).

use crate::error::{Attempt, Error};
use crate::formats::delimited;
use crate::formats::halscope::sampling_period_ns;
use crate::model::Format;
use crate::text::{self, Lines};

/// How much of a file detection looks at.
pub const EXAMINED_BYTES: usize = 64 * 1024;

fn first_line(head: &[u8]) -> String {
    Lines::new(head)
        .next()
        .map(|l| text::decode(l.text).into_owned())
        .unwrap_or_default()
}

fn check(format: Format, head: &[u8]) -> Result<(), String> {
    match format {
        Format::Parquet => {
            if head.starts_with(crate::formats::parquet::MAGIC) {
                Ok(())
            } else {
                Err("does not start with the Parquet magic 'PAR1'".to_string())
            }
        }
        Format::SinumerikTrace => {
            let start = head.iter().find(|b| !b.is_ascii_whitespace());
            if start != Some(&b'<') {
                return Err("does not start with '<' (not XML)".to_string());
            }
            if memchr::memmem::find(head, b"<dataSignal").is_some()
                || memchr::memmem::find(head, b"<traceData").is_some()
                || memchr::memmem::find(head, b"<traceSession").is_some()
            {
                Ok(())
            } else {
                Err("XML without <traceSession>, <traceData> or <dataSignal>".to_string())
            }
        }
        Format::TncScope => {
            let line = Lines::new(head)
                .find(|l| !text::is_blank(l.text))
                .map(|l| text::decode(text::trim(l.text)).into_owned())
                .unwrap_or_default();
            if line.to_ascii_lowercase().starts_with("%tncscope") {
                Ok(())
            } else {
                Err("first line is not '%TNCscope…'".to_string())
            }
        }
        Format::HalscopeTable => match sampling_period_ns(&first_line(head), true) {
            Some(_) => Ok(()),
            None => Err("first line is not '# Sampling period is N ns'".to_string()),
        },
        Format::HalscopeInterlaced => match sampling_period_ns(&first_line(head), false) {
            Some(_) => Ok(()),
            None => Err("first line is not 'Sampling period is N ns'".to_string()),
        },
        Format::TwinCatScope => {
            let first = Lines::new(head).next().map(|l| l.text).unwrap_or_default();
            let sep_ok = first
                .strip_prefix(b"Name")
                .and_then(|r| r.first())
                .is_some_and(|s| matches!(s, b';' | b'\t' | b',' | b':'));
            if !sep_ok {
                return Err("first line is not 'Name' and a separator".to_string());
            }
            if Lines::new(head)
                .take(60)
                .any(|l| l.text.starts_with(b"SampleTime"))
            {
                Ok(())
            } else {
                Err("no 'SampleTime' metadata row in the first 60 lines".to_string())
            }
        }
        Format::Halsampler => {
            // The first two sample lines: numbers (finite or not) separated by white space.
            let mut seen = 0;
            for l in Lines::new(head) {
                let t = text::trim(l.text);
                if t.is_empty() || t[0] == b'#' || t.eq_ignore_ascii_case(b"overrun") {
                    continue;
                }
                if !l.terminated && l.next >= head.len() && seen > 0 {
                    break; // possibly cut by the examined window
                }
                if t.iter().any(|&b| b == b';' || b == b',') {
                    return Err(format!("line {} has ';' or ','", l.no));
                }
                if let Some(f) = text::split_ws(t).find(|f| !text::looks_numeric(f)) {
                    return Err(format!(
                        "line {}: '{}' is not a number (halsampler output has no header)",
                        l.no,
                        text::show(f)
                    ));
                }
                seen += 1;
                if seen == 2 {
                    break;
                }
            }
            if seen == 0 {
                Err("no sample line".to_string())
            } else {
                Ok(())
            }
        }
        Format::Delimited => {
            // A first line (header or numbers), then — if there is one — a data line with as
            // many fields, all numbers. Later lines are left to the reader, which names the line
            // of any fault.
            let mut lines = Lines::new(head).filter(|l| {
                let t = text::trim(l.text);
                !(t.is_empty() || t[0] == b'#')
            });
            let Some(first) = lines.next() else {
                return Err("no line other than blanks and '#' comments".to_string());
            };
            let delim = delimited::choose_delim(first.text);
            let n = delimited::fields(first.text, delim).len();
            match lines.next() {
                None if n >= 2 => Ok(()),
                None => Err("one field and no data rows".to_string()),
                Some(l) => {
                    let f = delimited::fields(l.text, delim);
                    if f.len() != n {
                        Err(format!(
                            "line {} has {} fields separated by {}, line {} has {n}",
                            l.no,
                            f.len(),
                            delim.describe(),
                            first.no
                        ))
                    } else if let Some(x) = f.iter().find(|x| !text::looks_numeric(x)) {
                        Err(format!(
                            "line {}: '{}' is not a number",
                            l.no,
                            text::show(x)
                        ))
                    } else {
                        Ok(())
                    }
                }
            }
        }
    }
}

/// The format of `bytes`, from its content (never a file name), or every format tried with what
/// the content lacked.
///
/// The first 64 KiB are examined; a UTF-8 byte-order mark is skipped. Formats are tried in the
/// order of [`Format::ALL`], most specific signature first, and the first match wins:
///
/// | # | format | signature |
/// |---|--------|-----------|
/// | 0 | Apache Parquet | starts with `PAR1` (binary; the only format that may hold NUL bytes) |
/// | 1 | Sinumerik servo trace | first non-blank character `<`, and `<traceSession`, `<traceData` or `<dataSignal` in the examined part |
/// | 2 | TNCscope | first non-blank line starts with `%TNCscope` (any case) |
/// | 3 | halscope table (2.9+) | first line `# Sampling period is N ns` |
/// | 4 | halscope pairs (before 2.9) | first line `Sampling period is N ns` |
/// | 5 | TwinCAT Scope | first line `Name` + `;`/tab/`,`/`:`, and a row starting `SampleTime` within the first 60 lines |
/// | 6 | halsampler | no header: the first two lines other than `#` comments and `overrun` hold white-space separated numbers |
/// | 7 | delimited text | a first non-comment line (header or numbers), then a line of as many fields, all numbers (or none: a header of two or more fields alone) |
///
/// Signatures look at the first lines only: a fault further down (a ragged row, a NaN) is left to
/// the reader, which reports it with its line instead of refusing the whole file.
///
/// Content with NUL bytes is binary and matches none but Parquet. When nothing matches, the error lists each
/// format with what the content lacked.
pub fn detect(bytes: &[u8]) -> Result<Format, Vec<Attempt>> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let head = &bytes[..bytes.len().min(EXAMINED_BYTES)];
    if check(Format::Parquet, head).is_ok() {
        return Ok(Format::Parquet);
    }
    if head.contains(&0) {
        return Err(Format::ALL
            .iter()
            .map(|&format| Attempt {
                format,
                reason: match format {
                    Format::Parquet => "does not start with the Parquet magic 'PAR1'",
                    _ => "binary content (NUL bytes)",
                }
                .to_string(),
            })
            .collect());
    }
    let mut tried = Vec::new();
    for format in Format::ALL {
        match check(format, head) {
            Ok(()) => return Ok(format),
            Err(reason) => tried.push(Attempt { format, reason }),
        }
    }
    Err(tried)
}

/// [`detect`], with the failure as an [`Error::UnknownFormat`] naming `file`.
pub fn detect_format(file: &str, bytes: &[u8]) -> Result<Format, Error> {
    detect(bytes).map_err(|tried| Error::UnknownFormat {
        file: file.to_string(),
        tried,
    })
}
