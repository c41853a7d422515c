//! LinuxCNC halsampler output (halsampler(1), LinuxCNC `src/hal/components/sampler_usr.c`): one line
//! per sample, the values of the sampler's pins in the order of its `cfg` string separated by
//! spaces (floats `%f`, bits `0`/`1`, integers), preceded by the sample number with `-t`; a line
//! `overrun` where the FIFO overflowed and samples were lost.
//!
//! The file names no channel and states no period. Names come from
//! [`ReadOptions::channel_names`], else from a first `#` comment line with one name per column
//! (the convention of the public `sampler_tools` wrapper, which writes the sampled nets as the
//! log's first line), else `pin.0`, `pin.1`, … (the sampler's pins). The period comes from
//! [`ReadOptions::period_s`] (the sampler thread's period × decimation).
//!
//! Sample numbers (`-t`) are recognised when the first column of the first 200 lines holds
//! integers and the first two count up by one (or jump after an `overrun`). With them an
//! overrun's lost samples are counted, and a number that does not increase is an error; without
//! them the gap's size is unknown.
//!
//! A column holding time (a sampled clock pin, in s or [`ReadOptions::time_unit`]) can be named
//! with [`ReadOptions::time_column`] (`--t-col`): it is then the time base, checked uniform up
//! to gaps, and gives the period and the lost samples.
//!
//! Gap policy: an `overrun` becomes a [`crate::Gap`] of every channel. The reader does not
//! refuse the file (`vcnc trace info` lists the gaps); pairing refuses to identify across a gap
//! unless asked to use the longest gap-free stretch ([`crate::GapPolicy`]).

use crate::error::Error;
use crate::formats;
use crate::model::{Channel, ChannelRef, Format, Gap, ReadOptions, Trace};
use crate::text::{self, Lines};
use crate::timebase;
use crate::units::TraceUnit;

fn is_overrun(t: &[u8]) -> bool {
    text::trim(t).eq_ignore_ascii_case(b"overrun")
}

fn parse_int(f: &[u8]) -> Option<i64> {
    let (neg, digits) = match f.first()? {
        b'-' => (true, &f[1..]),
        _ => (false, f),
    };
    if digits.is_empty() || digits.len() > 18 || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    let v = digits
        .iter()
        .fold(0i64, |a, &d| a * 10 + i64::from(d - b'0'));
    Some(if neg { -v } else { v })
}

/// Whether the first column holds sample numbers (see the module documentation): integers in
/// the first 200 lines, the first two of them consecutive. Later steps are checked while reading.
fn tagged(bytes: &[u8], start: usize, line: usize) -> bool {
    let mut firsts: Vec<(i64, bool)> = Vec::new();
    let mut overrun = false;
    for l in Lines::starting_at(bytes, start, line) {
        if text::is_blank(l.text) || text::trim(l.text).first() == Some(&b'#') {
            continue;
        }
        if is_overrun(l.text) {
            overrun = true;
            continue;
        }
        let mut f = text::split_ws(l.text);
        let (Some(first), Some(_)) = (f.next(), f.next()) else {
            return false;
        };
        let Some(n) = parse_int(first) else {
            return false;
        };
        firsts.push((n, overrun));
        overrun = false;
        if firsts.len() == 200 {
            break;
        }
    }
    match firsts.as_slice() {
        [(a, _), (b, false), ..] => *b == a + 1,
        [(a, _), (b, true), ..] => b > a,
        _ => false,
    }
}

pub(crate) fn read(file: &str, bytes: &[u8], opts: &ReadOptions) -> Result<Trace, Error> {
    let mut comments: Vec<(String, usize)> = Vec::new();
    let (first, _) = text::first_content_line(bytes, is_overrun, |c, no| comments.push((c, no)));
    let Some(first) = first else {
        return Err(Error::Truncated {
            file: file.to_string(),
            line: 1,
            what: "no sample line".to_string(),
        });
    };
    let nf = text::split_ws(first.text).count();
    let tag = tagged(bytes, first.offset, first.no);
    let ncols = nf - usize::from(tag);
    let (names, names_line): (Vec<String>, usize) = if !opts.channel_names.is_empty() {
        if opts.channel_names.len() != ncols {
            return Err(Error::BadOption {
                file: file.to_string(),
                what: format!(
                    "{} channel names given for {ncols} value columns{}",
                    opts.channel_names.len(),
                    if tag {
                        " (after the sample number)"
                    } else {
                        ""
                    }
                ),
            });
        }
        (opts.channel_names.clone(), first.no)
    } else if let Some((c, line)) = comments
        .iter()
        .find(|(c, _)| c.split_whitespace().count() == ncols)
    {
        (c.split_whitespace().map(str::to_string).collect(), *line)
    } else {
        ((0..ncols).map(|i| format!("pin.{i}")).collect(), first.no)
    };

    let capacity = (bytes.len() - first.offset) / (first.text.len() + 1) + 1;
    let mut cols: Vec<Vec<f64>> = (0..ncols).map(|_| Vec::with_capacity(capacity)).collect();
    let mut gaps: Vec<Gap> = Vec::new();
    let mut pending_overrun: Option<usize> = None;
    let mut prev_tag: Option<i64> = None;
    let mut fields: Vec<&[u8]> = Vec::with_capacity(nf);
    // Line of every sample row, kept only for a time column's messages.
    let mut row_lines: Vec<usize> = Vec::new();
    for l in Lines::starting_at(bytes, first.offset, first.no) {
        let t = text::trim(l.text);
        if t.is_empty() || t[0] == b'#' {
            continue;
        }
        if is_overrun(t) {
            pending_overrun = Some(l.no);
            continue;
        }
        fields.clear();
        text::split_ws_into(l.text, &mut fields);
        if fields.len() != nf {
            return Err(if fields.len() < nf && !l.terminated {
                Error::Truncated {
                    file: file.to_string(),
                    line: l.no,
                    what: format!("the last line has {} of {nf} fields", fields.len()),
                }
            } else {
                Error::FieldCount {
                    file: file.to_string(),
                    line: l.no,
                    expected: nf,
                    found: fields.len(),
                }
            });
        }
        let index = cols[0].len();
        if opts.time_column.is_some() {
            row_lines.push(l.no);
        }
        if tag {
            let n = parse_int(fields[0]).ok_or_else(|| Error::NotANumber {
                file: file.to_string(),
                line: l.no,
                column: "sample number".to_string(),
                text: text::show(fields[0]),
            })?;
            if let Some(p) = prev_tag {
                if n <= p {
                    return Err(Error::Header {
                        file: file.to_string(),
                        line: l.no,
                        what: format!("sample number {n} does not follow {p}"),
                    });
                }
                if n > p + 1 {
                    gaps.push(Gap {
                        index,
                        line: pending_overrun.unwrap_or(l.no),
                        lost: Some((n - p - 1) as usize),
                    });
                } else if let Some(line) = pending_overrun {
                    // halsampler numbers the samples it writes, not the ones the realtime
                    // sampler took, so an overrun need not make the numbers jump: the samples
                    // lost there are not counted.
                    gaps.push(Gap {
                        index,
                        line,
                        lost: None,
                    });
                }
            }
            prev_tag = Some(n);
        } else if let Some(line) = pending_overrun
            && index > 0
        {
            gaps.push(Gap {
                index,
                line,
                lost: None,
            });
        }
        pending_overrun = None;
        for (i, f) in fields[usize::from(tag)..].iter().enumerate() {
            match text::parse_f64(f, false) {
                Ok(v) => cols[i].push(v),
                Err(text::NumError::Syntax) if !l.terminated && i + 1 == ncols => {
                    return Err(Error::Truncated {
                        file: file.to_string(),
                        line: l.no,
                        what: format!("the last line stops inside '{}'", text::show(f)),
                    });
                }
                Err(e) => return Err(formats::num_error(file, l.no, &names[i], f, e)),
            }
        }
    }

    // A time column: the time base, its gaps replacing the overruns' (it counts the loss).
    let time_col = match &opts.time_column {
        None => None,
        Some(r) => {
            let found = match r {
                ChannelRef::Name(n) => names.iter().position(|m| m == n),
                ChannelRef::Column(c) => c.checked_sub(usize::from(tag)).filter(|&i| i < ncols),
            };
            Some(found.ok_or_else(|| Error::UnknownChannel {
                file: file.to_string(),
                reference: format!("{r} (time column)"),
                channels: names.clone(),
            })?)
        }
    };
    let uniform = match time_col {
        Some(tc) => {
            let k = opts
                .time_unit
                .as_ref()
                .and_then(TraceUnit::to_base)
                .map_or(1.0, |(_, k)| k);
            let times: Vec<f64> = cols[tc].iter().map(|t| t * k).collect();
            let line_of = |row: usize| row_lines.get(row).copied().unwrap_or(names_line);
            Some(
                timebase::uniform(&times, None)
                    .map_err(|f| formats::time_error(file, f, names_line, line_of))?,
            )
        }
        None => None,
    };
    let mut channels = Vec::with_capacity(ncols);
    for (c, (name, samples)) in names.into_iter().zip(cols).enumerate() {
        if Some(c) == time_col {
            continue;
        }
        let mut ch = Channel::new(name, names_line, c + usize::from(tag));
        ch.samples = samples;
        ch.gaps = gaps.clone();
        if let Some(u) = &uniform {
            formats::apply_uniform(&mut ch, u, |row| {
                row_lines.get(row).copied().unwrap_or(names_line)
            });
        }
        formats::apply_period_option(file, opts, &mut ch)?;
        let n = ch.name.clone();
        formats::infer_channel(&mut ch, &[("name", &n)], Some(&opts.joints));
        channels.push(ch);
    }
    let mut metadata: Vec<(String, String)> = comments
        .into_iter()
        .map(|(c, _)| ("comment".to_string(), c))
        .collect();
    metadata.push((
        "sample numbers".to_string(),
        if tag { "yes" } else { "no" }.to_string(),
    ));
    Ok(Trace {
        file: file.to_string(),
        format: Format::Halsampler,
        channels,
        metadata,
    })
}
