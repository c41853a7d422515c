//! Writers for the simple formats, for round trips and for making test traces. Numbers are
//! written in Rust's shortest exact form (not the `%.14f` or `%f` of the LinuxCNC tools), so a
//! written trace reads back bit for bit.

use std::io::{self, Write};

/// A number with `,` as decimal mark when asked.
fn num(v: f64, decimal_comma: bool) -> String {
    let s = format!("{v}");
    if decimal_comma {
        s.replace('.', ",")
    } else {
        s
    }
}

fn rows(columns: &[&[f64]]) -> usize {
    columns.iter().map(|c| c.len()).max().unwrap_or(0)
}

fn check_lengths(columns: &[&[f64]]) -> io::Result<()> {
    let n = rows(columns);
    if columns.iter().any(|c| c.len() != n) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "all columns must have the same length",
        ));
    }
    Ok(())
}

/// A LinuxCNC 2.9+ halscope log: period, names, `# Position:`/`# Scale:` display lines, rows.
pub fn halscope_table(
    w: &mut impl Write,
    period_ns: u64,
    names: &[&str],
    columns: &[&[f64]],
) -> io::Result<()> {
    check_lengths(columns)?;
    writeln!(w, "# Sampling period is {period_ns} ns")?;
    writeln!(w, "{}", names.join(";"))?;
    writeln!(w, "# Position: {}", vec!["0.500000"; names.len()].join(";"))?;
    writeln!(w, "# Scale: {}", vec!["0"; names.len()].join(";"))?;
    for k in 0..rows(columns) {
        let row: Vec<String> = columns.iter().map(|c| num(c[k], false)).collect();
        writeln!(w, "{}", row.join(";"))?;
    }
    Ok(())
}

/// A LinuxCNC halscope log of before 2.9: period line, then `name value` pairs per sample.
pub fn halscope_pairs(
    w: &mut impl Write,
    period_ns: u64,
    names: &[&str],
    columns: &[&[f64]],
) -> io::Result<()> {
    check_lengths(columns)?;
    // The trailing space is LinuxCNC's.
    writeln!(w, "Sampling period is {period_ns} ns ")?;
    for k in 0..rows(columns) {
        writeln!(w)?;
        for (n, c) in names.iter().zip(columns) {
            write!(w, "{n} {:+} ", c[k])?;
        }
    }
    writeln!(w)
}

/// halsampler output: optional sample numbers, `overrun` before every sample index in
/// `overruns` (with sample numbers, `lost` samples are skipped in the numbering there).
pub fn halsampler(
    w: &mut impl Write,
    tagged: bool,
    columns: &[&[f64]],
    overruns: &[(usize, usize)],
) -> io::Result<()> {
    check_lengths(columns)?;
    let mut number = 0usize;
    for k in 0..rows(columns) {
        if let Some(&(_, lost)) = overruns.iter().find(|(i, _)| *i == k) {
            writeln!(w, "overrun")?;
            number += lost;
        }
        if tagged {
            write!(w, "{number} ")?;
        }
        for c in columns {
            write!(w, "{} ", num(c[k], false))?;
        }
        writeln!(w)?;
        number += 1;
    }
    Ok(())
}

/// Delimited text with an optional header line.
pub fn delimited(
    w: &mut impl Write,
    separator: u8,
    decimal_comma: bool,
    header: Option<&[&str]>,
    columns: &[&[f64]],
) -> io::Result<()> {
    check_lengths(columns)?;
    if decimal_comma && separator == b',' {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "',' cannot be both separator and decimal mark",
        ));
    }
    let sep = (separator as char).to_string();
    if let Some(h) = header {
        writeln!(w, "{}", h.join(&sep))?;
    }
    let mut line = String::new();
    for k in 0..rows(columns) {
        line.clear();
        for (i, c) in columns.iter().enumerate() {
            if i > 0 {
                line.push_str(&sep);
            }
            line.push_str(&num(c[k], decimal_comma));
        }
        writeln!(w, "{line}")?;
    }
    Ok(())
}

/// One curve of a TNCscope file.
#[derive(Debug, Clone, PartialEq)]
pub struct TncCurve<'a> {
    /// `NAME`.
    pub name: &'a str,
    /// `CHANNELTYPE` (`s soll`, `s ist`, …).
    pub channel_type: &'a str,
    /// `AXISTYPE`.
    pub axis_type: &'a str,
    /// `DIMENSION` (unit).
    pub dimension: &'a str,
    /// `CYCLETIME`, µs; a whole multiple of the shortest cycle.
    pub cycle_us: u64,
    /// The samples.
    pub samples: &'a [f64],
}

/// A TNCscope text export. Rows come at the shortest cycle; a curve with a `k` times longer
/// cycle has a value on every `k`-th row and empty cells between.
pub fn tncscope(w: &mut impl Write, control: &str, curves: &[TncCurve<'_>]) -> io::Result<()> {
    let base = curves.iter().map(|c| c.cycle_us).min().unwrap_or(1).max(1);
    if curves.iter().any(|c| c.cycle_us % base != 0) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "cycle times must be whole multiples of the shortest",
        ));
    }
    writeln!(w, "%TNCscopeNT data file")?;
    writeln!(w, "%[GLOBAL]")?;
    writeln!(w, "CONTROL={control}")?;
    writeln!(w, "CURVES={}", curves.len())?;
    for (i, c) in curves.iter().enumerate() {
        writeln!(w, "%[CURVE{}]", i + 1)?;
        writeln!(w, "NAME={}", c.name)?;
        writeln!(w, "CHANNELTYPE={}", c.channel_type)?;
        writeln!(w, "AXISTYPE={}", c.axis_type)?;
        writeln!(w, "DIMENSION={}", c.dimension)?;
        writeln!(w, "COUNT={}", c.samples.len())?;
        writeln!(w, "CYCLETIME={}", c.cycle_us)?;
    }
    writeln!(w, "%[DATA]")?;
    let rows = curves
        .iter()
        .map(|c| (c.samples.len().saturating_sub(1)) as u64 * (c.cycle_us / base) + 1)
        .max()
        .unwrap_or(0);
    let mut line = String::new();
    for r in 0..rows {
        line.clear();
        line.push_str(&(r * base).to_string());
        line.push(';');
        for c in curves {
            let k = c.cycle_us / base;
            line.push(' ');
            if r % k == 0
                && let Some(v) = c.samples.get((r / k) as usize)
            {
                line.push_str(&num(*v, false));
            }
            line.push(';');
        }
        writeln!(w, "{line}")?;
    }
    Ok(())
}
