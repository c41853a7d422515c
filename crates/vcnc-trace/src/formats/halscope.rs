//! LinuxCNC halscope logs ("Save log" of halscope; LinuxCNC `src/hal/utils/scope_files.c`,
//! `write_log_file`).
//!
//! Since 2.9 (table):
//! ```text
//! # Sampling period is 1000000 ns
//! joint.0.motor-pos-cmd;joint.0.motor-pos-fb
//! # Position: 0.500000;0.500000
//! # Scale: 0;0
//! 0.00000000000000;0.00000000000000
//! ```
//! The `# Position:` and `# Scale:` lines hold display settings (trace position on screen, scale
//! index), not a scaling of the values: they are kept as metadata. Values are written with
//! `%.14f` in the C locale.
//!
//! Before 2.9 (pairs): a first line `Sampling period is N ns`, then per sample one line of
//! `name value` pairs (`%s %+.14f `), or — the non-interlaced order — one pair per line, channel
//! after channel. Both orders are read.
//!
//! Neither form carries units (the machine's `LINEAR_UNITS`/`ANGULAR_UNITS` are in its INI file)
//! or a time column: sample $k$ is at $kT$.

use crate::error::Error;
use crate::formats::{self, Delim, Start};
use crate::model::{Channel, Format, ReadOptions, Trace};
use crate::text::{self, Lines};

/// Channels of a halscope (16 in every LinuxCNC version).
const MAX_CHANNELS: usize = 16;

/// The period in ns of a `[# ]Sampling period is N ns` line, if it is one.
pub(crate) fn sampling_period_ns(line: &str, hash: bool) -> Option<Result<f64, String>> {
    let mut t = line.trim();
    if hash {
        t = t.strip_prefix('#')?.trim_start();
    }
    let rest = t.strip_prefix("Sampling period is")?.trim();
    let num = rest.strip_suffix("ns").map(str::trim).unwrap_or(rest);
    Some(match num.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(num.to_string()),
    })
}

fn period_line(file: &str, bytes: &[u8], hash: bool) -> Result<(f64, usize), Error> {
    let first = Lines::new(bytes).next();
    let (text, next) = match first {
        Some(l) => (text::decode(l.text).into_owned(), l.next),
        None => (String::new(), 0),
    };
    match sampling_period_ns(&text, hash) {
        Some(Ok(ns)) => Ok((ns * 1e-9, next)),
        Some(Err(v)) => Err(Error::Header {
            file: file.to_string(),
            line: 1,
            what: format!("sampling period '{v}' is not a positive number of ns"),
        }),
        None => Err(Error::Header {
            file: file.to_string(),
            line: 1,
            what: format!(
                "expected '{}Sampling period is N ns', found '{}'",
                if hash { "# " } else { "" },
                text.trim()
            ),
        }),
    }
}

fn finish(
    file: &str,
    opts: &ReadOptions,
    format: Format,
    period_s: f64,
    names: Vec<(String, usize)>,
    cols: Vec<Vec<f64>>,
    metadata: Vec<(String, String)>,
) -> Result<Trace, Error> {
    let mut channels = Vec::with_capacity(names.len());
    for (c, ((name, line), samples)) in names.into_iter().zip(cols).enumerate() {
        let mut ch = Channel::new(name, line, c);
        ch.period_s = Some(period_s);
        ch.samples = samples;
        formats::apply_period_option(file, opts, &mut ch)?;
        let n = ch.name.clone();
        formats::infer_channel(&mut ch, &[("name", &n)], Some(&opts.joints));
        channels.push(ch);
    }
    Ok(Trace {
        file: file.to_string(),
        format,
        channels,
        metadata,
    })
}

/// The 2.9+ table form.
pub(crate) fn read_table(file: &str, bytes: &[u8], opts: &ReadOptions) -> Result<Trace, Error> {
    let (period_s, after) = period_line(file, bytes, true)?;
    let mut lines = Lines::starting_at(bytes, after, 2);
    let header = loop {
        match lines.next() {
            Some(l) if text::is_blank(l.text) => continue,
            Some(l) => break l,
            None => {
                return Err(Error::Truncated {
                    file: file.to_string(),
                    line: 1,
                    what: "no channel-name line after the sampling period".to_string(),
                });
            }
        }
    };
    let header_text = text::decode(header.text);
    let names: Vec<(String, usize)> = header_text
        .split(';')
        .map(|n| (n.trim().to_string(), header.no))
        .collect();
    if let Some(i) = names
        .iter()
        .position(|(n, _)| n.is_empty() || n.starts_with('#'))
    {
        return Err(Error::Header {
            file: file.to_string(),
            line: header.no,
            what: format!("channel {} has no name in '{}'", i + 1, header_text.trim()),
        });
    }
    let mut metadata = vec![("sampling period".to_string(), format!("{period_s} s"))];
    let mut start = Start {
        offset: header.next,
        line: header.no + 1,
    };
    // The optional display lines.
    for l in Lines::starting_at(bytes, header.next, header.no + 1) {
        let t = text::decode(text::trim(l.text));
        if let Some(rest) = t.strip_prefix('#') {
            if let Some((k, v)) = rest.split_once(':') {
                metadata.push((k.trim().to_string(), v.trim().to_string()));
            }
        } else if !t.is_empty() {
            break;
        }
        start = Start {
            offset: l.next,
            line: l.no + 1,
        };
    }
    let column_names: Vec<String> = names.iter().map(|(n, _)| n.clone()).collect();
    let cols = formats::read_table(
        file,
        bytes,
        start,
        Delim::Byte(b';'),
        false,
        &column_names,
        true,
    )?;
    finish(
        file,
        opts,
        Format::HalscopeTable,
        period_s,
        names,
        cols,
        metadata,
    )
}

/// The pre-2.9 `name value` pair form (interlaced or not).
pub(crate) fn read_pairs(file: &str, bytes: &[u8], opts: &ReadOptions) -> Result<Trace, Error> {
    let (period_s, after) = period_line(file, bytes, false)?;
    let mut names: Vec<(String, usize)> = Vec::new();
    let mut cols: Vec<Vec<f64>> = Vec::new();
    // Index of the channel the next pair is expected for (fast path: names repeat in order).
    let mut next = 0usize;
    let mut last_line = 1;
    for l in Lines::starting_at(bytes, after, 2) {
        last_line = l.no;
        let mut toks = text::split_ws(l.text);
        while let Some(name) = toks.next() {
            let Some(value) = toks.next() else {
                return Err(if l.terminated {
                    Error::Header {
                        file: file.to_string(),
                        line: l.no,
                        what: format!("channel '{}' has no value", text::show(name)),
                    }
                } else {
                    Error::Truncated {
                        file: file.to_string(),
                        line: l.no,
                        what: format!("the last pair '{}' has no value", text::show(name)),
                    }
                });
            };
            let idx = if names.get(next).is_some_and(|(n, _)| n.as_bytes() == name) {
                next
            } else if let Some(i) = names.iter().position(|(n, _)| n.as_bytes() == name) {
                i
            } else {
                if names.len() == MAX_CHANNELS {
                    return Err(Error::Header {
                        file: file.to_string(),
                        line: l.no,
                        what: format!(
                            "channel '{}' would be number {}: halscope records at most {MAX_CHANNELS}",
                            text::show(name),
                            MAX_CHANNELS + 1
                        ),
                    });
                }
                names.push((text::decode(name).into_owned(), l.no));
                cols.push(Vec::new());
                names.len() - 1
            };
            let v = text::parse_f64(value, false)
                .map_err(|e| formats::num_error(file, l.no, &names[idx].0, value, e))?;
            cols[idx].push(v);
            next = (idx + 1) % names.len();
        }
    }
    if names.is_empty() {
        return Err(Error::Truncated {
            file: file.to_string(),
            line: last_line,
            what: "no samples after the sampling period".to_string(),
        });
    }
    let n0 = cols[0].len();
    if let Some(i) = cols.iter().position(|c| c.len() != n0) {
        return Err(Error::CountMismatch {
            file: file.to_string(),
            line: names[i].1,
            channel: names[i].0.clone(),
            declared: n0,
            found: cols[i].len(),
        });
    }
    let metadata = vec![("sampling period".to_string(), format!("{period_s} s"))];
    finish(
        file,
        opts,
        Format::HalscopeInterlaced,
        period_s,
        names,
        cols,
        metadata,
    )
}
