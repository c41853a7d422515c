//! Writers of every format the readers take (halscope tables and pairs, halsampler, delimited
//! text, TNCscope in both layouts, Sinumerik servo traces in both layouts, TwinCAT Scope CSV), in the layouts the readers of
//! [`crate::formats`] document, for round trips and for making test traces. Numbers are written
//! in Rust's shortest exact form (not the `%.14f` or `%f` of the LinuxCNC tools), so a written
//! trace reads back bit for bit.

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

/// A TNCscope export as an iTNC 530 writes it (the layout of [`crate::formats::tncscope`]):
/// `%`-prefixed keys, `% ` separator lines after the first line, at the end of `%[GLOBAL]` and
/// after every curve, CRLF line ends. Every curve is recorded at `sampling_us` (its `SAMPLING`
/// and the global one) and must have one value per row; a curve's [`TncCurve::cycle_us`] is
/// written as its `CYCLETIME`, the control cycle, and does not change the rows.
pub fn tncscope_itnc530(
    w: &mut impl Write,
    sampling_us: u64,
    curves: &[TncCurve<'_>],
) -> io::Result<()> {
    let columns: Vec<&[f64]> = curves.iter().map(|c| c.samples).collect();
    check_lengths(&columns)?;
    if sampling_us == 0 {
        return Err(invalid("the recording interval must be positive"));
    }
    let nl = "\r\n";
    write!(
        w,
        "%TNCscopeNT data file{nl}% {nl}%[GLOBAL]{nl}%VERSION=3{nl}"
    )?;
    write!(w, "%CONTROL=iTNC 530{nl}%SAMPLING={sampling_us}{nl}% {nl}")?;
    for (i, c) in curves.iter().enumerate() {
        write!(w, "%[CURVE{}]{nl}%NAME={}{nl}", i + 1, c.name)?;
        write!(
            w,
            "%CHANNELTYPE={}{nl}%AXISTYPE={}{nl}",
            c.channel_type, c.axis_type
        )?;
        write!(
            w,
            "%DIMENSION={}{nl}%COUNT={}{nl}",
            c.dimension,
            c.samples.len()
        )?;
        write!(
            w,
            "%SAMPLING={sampling_us}{nl}%CYCLETIME={}{nl}% {nl}",
            c.cycle_us
        )?;
    }
    write!(w, "%[DATA]{nl}")?;
    let mut line = String::new();
    for r in 0..rows(&columns) {
        line.clear();
        line.push_str(&(r as u64 * sampling_us).to_string());
        line.push(';');
        for c in &columns {
            line.push(' ');
            line.push_str(&num(c[r], false));
            line.push(';');
        }
        write!(w, "{line}{nl}")?;
    }
    Ok(())
}

fn invalid(what: &str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, what.to_string())
}

/// One signal of a Sinumerik servo trace.
#[derive(Debug, Clone, PartialEq)]
pub struct SinumerikSignal<'a> {
    /// `id`: record attribute `f<id>` carries its values.
    pub id: usize,
    /// `name`: the NCK path (`/Nck/ServoTrace/PositionSetpoint[X1]`).
    pub name: &'a str,
    /// `description`: what the trace screen shows (`Position setpoint X1`).
    pub description: &'a str,
    /// `unit`, when given (`mm`, `deg`).
    pub unit: Option<&'a str>,
    /// One value per record time; each must be finite and at most
    /// [`crate::NO_VALUE_ABOVE`] (larger ones mean "no value").
    pub samples: &'a [f64],
}

/// A Sinumerik Operate servo trace (the layout of [`crate::formats::sinumerik`]): the signals
/// declared, then one `rec` per time of `times_s` (s). As the control does, a record lists only
/// the values that changed since the previous record (all of them in the first).
pub fn sinumerik(
    w: &mut impl Write,
    times_s: &[f64],
    signals: &[SinumerikSignal<'_>],
) -> io::Result<()> {
    use quick_xml::escape::escape;
    if signals.iter().any(|s| s.samples.len() != times_s.len()) {
        return Err(invalid("every signal needs one value per record time"));
    }
    if signals
        .iter()
        .flat_map(|s| s.samples)
        .any(|v| !v.is_finite() || *v > crate::NO_VALUE_ABOVE)
    {
        return Err(invalid(
            "values must be finite and below the \"no value\" marker",
        ));
    }
    writeln!(w, r#"<?xml version="1.0" encoding="UTF-8"?>"#)?;
    writeln!(w, r#"<traceFile version="1.0">"#)?;
    writeln!(w, "  <traceData>")?;
    writeln!(w, "    <dataFrame>")?;
    for s in signals {
        write!(
            w,
            r#"      <dataSignal id="{}" name="{}" description="{}""#,
            s.id,
            escape(s.name),
            escape(s.description)
        )?;
        if let Some(u) = s.unit {
            write!(w, r#" unit="{}""#, escape(u))?;
        }
        writeln!(w, "/>")?;
    }
    let mut line = String::new();
    for (k, t) in times_s.iter().enumerate() {
        line.clear();
        line.push_str(&format!(r#"      <rec time="{t}""#));
        for s in signals {
            let v = s.samples[k];
            if k == 0 || v.to_bits() != s.samples[k - 1].to_bits() {
                line.push_str(&format!(r#" f{}="{v}""#, s.id));
            }
        }
        writeln!(w, "{line}/>")?;
    }
    writeln!(w, "    </dataFrame>")?;
    writeln!(w, "  </traceData>")?;
    writeln!(w, "</traceFile>")
}

/// One signal of a Sinumerik Operate V20 servo trace.
#[derive(Debug, Clone, PartialEq)]
pub struct SinumerikServoSignal<'a> {
    /// The servo-data signal, without prefix and axis: `nckServoDataCmdPos2ndEnc64`.
    pub signal: &'a str,
    /// The NCK axis number `N` of `[u1, N]`.
    pub axis_number: u32,
    /// `description` (`Position setpoint (64 bit)`).
    pub description: &'a str,
    /// `unitsType` (`posn`, `velo`, `torque`, …).
    pub units_type: &'a str,
    /// One value per record time (finite, at most [`crate::NO_VALUE_ABOVE`]).
    pub samples: &'a [f64],
}

/// A Sinumerik Operate servo trace as `traceSession version="01.00.03.02"` with
/// `traceCaptureSetup_V20` (the layout of [`crate::formats::sinumerik`]): the signals declared in
/// `signalSettings` (`key="sN"`), repeated in the data frame as `dataSignal key="sN" id="fN"
/// interval=… datapointCount=…`, then one `rec` per sample at `interval_s`, listing only the
/// values that changed since the previous record (all of them in the first).
pub fn sinumerik_v20(
    w: &mut impl Write,
    interval_s: f64,
    signals: &[SinumerikServoSignal<'_>],
) -> io::Result<()> {
    use quick_xml::escape::escape;
    let columns: Vec<&[f64]> = signals.iter().map(|s| s.samples).collect();
    check_lengths(&columns)?;
    if !(interval_s.is_finite() && interval_s > 0.0) {
        return Err(invalid("the interval must be positive"));
    }
    if columns
        .iter()
        .flat_map(|c| c.iter())
        .any(|v| !v.is_finite() || *v > crate::NO_VALUE_ABOVE)
    {
        return Err(invalid(
            "values must be finite and below the \"no value\" marker",
        ));
    }
    let n = rows(&columns);
    writeln!(w, r#"<?xml version="1.0" encoding="UTF-8"?>"#)?;
    writeln!(w, r#"<traceSession version="01.00.03.02">"#)?;
    writeln!(w, "  <traceCaptureSetup_V20>")?;
    writeln!(w, "    <signalSettings>")?;
    for (i, s) in signals.iter().enumerate() {
        writeln!(
            w,
            r#"      <signal key="s{}" unitsType="{}" name="/Nck/!SD/{} [u1, {}]" description="{}"/>"#,
            i + 1,
            escape(s.units_type),
            escape(s.signal),
            s.axis_number,
            escape(s.description)
        )?;
    }
    writeln!(w, "    </signalSettings>")?;
    writeln!(w, "  </traceCaptureSetup_V20>")?;
    writeln!(w, r#"  <traceData dataFrames="1">"#)?;
    writeln!(w, "    <dataFrame>")?;
    writeln!(w, r#"      <frameHeader dropOuts="0"/>"#)?;
    for (i, s) in signals.iter().enumerate() {
        writeln!(
            w,
            r#"      <dataSignal key="s{0}" id="f{0}" unitsType="{1}" interval="{interval_s}" datapointCount="{n}"/>"#,
            i + 1,
            escape(s.units_type)
        )?;
    }
    let mut line = String::new();
    for k in 0..n {
        line.clear();
        line.push_str(&format!(r#"      <rec time="{}""#, k as f64 * interval_s));
        for (i, c) in columns.iter().enumerate() {
            if k == 0 || c[k].to_bits() != c[k - 1].to_bits() {
                line.push_str(&format!(r#" f{}="{}""#, i + 1, c[k]));
            }
        }
        writeln!(w, "{line}/>")?;
    }
    writeln!(w, "    </dataFrame>")?;
    writeln!(w, "  </traceData>")?;
    writeln!(w, "</traceSession>")
}

/// One channel of a TwinCAT Scope export.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinCatChannel<'a> {
    /// `Name` (the channel's name in the scope).
    pub name: &'a str,
    /// `SymbolName` (the PLC or NC symbol, `MAIN.AxisX.NcToPlc.ActPos`).
    pub symbol: &'a str,
    /// `Unit` as the scope writes it (`mm (Millimeter)`, `(None)`).
    pub unit: &'a str,
    /// `SampleTime[ms]`.
    pub sample_ms: f64,
    /// The samples, the first at time 0.
    pub samples: &'a [f64],
}

/// A TwinCAT Scope CSV export in its default layout (the layout of
/// [`crate::formats::twincat`]): header block, channel block with a `Name` column group per
/// channel, data rows of time (ms) and value per channel; channels with fewer samples end with
/// empty cells. `separator` is `;` or tab; `decimal_comma` writes `,` as decimal mark (times,
/// sample times and values), as the export option does.
pub fn twincat(
    w: &mut impl Write,
    scope: &str,
    separator: u8,
    decimal_comma: bool,
    channels: &[TwinCatChannel<'_>],
) -> io::Result<()> {
    if !matches!(separator, b';' | b'\t') {
        return Err(invalid("the separator must be ';' or tab"));
    }
    if channels
        .iter()
        .any(|c| !(c.sample_ms.is_finite() && c.sample_ms > 0.0))
    {
        return Err(invalid("sample times must be positive"));
    }
    let sep = (separator as char).to_string();
    let duration_ms = channels
        .iter()
        .map(|c| c.samples.len().saturating_sub(1) as f64 * c.sample_ms)
        .fold(0.0, f64::max);
    // Windows file times (100 ns since 1601) of an arbitrary start, and of its end.
    let start: u64 = 133_521_660_000_000_000;
    let end = start + (duration_ms * 1e4).round() as u64;
    writeln!(w, "Name{sep}{scope}")?;
    writeln!(w, "File{sep}C:\\TwinCAT\\Scope\\{scope}.csv")?;
    writeln!(w, "Starttime of export{sep}{start}")?;
    writeln!(w, "Endtime of export{sep}{end}")?;
    writeln!(w)?;
    writeln!(w)?;
    let row = |w: &mut dyn Write, key: &str, cell: &dyn Fn(&TwinCatChannel<'_>) -> String| {
        let cells: Vec<String> = channels
            .iter()
            .map(|c| format!("{key}{sep}{}", cell(c)))
            .collect();
        writeln!(w, "{}", cells.join(&sep))
    };
    row(w, "Name", &|c| c.name.to_string())?;
    row(w, "SymbolComment", &|_| String::new())?;
    row(w, "Data-Type", &|_| "REAL64".to_string())?;
    row(w, "SampleTime[ms]", &|c| num(c.sample_ms, decimal_comma))?;
    row(w, "SymbolName", &|c| c.symbol.to_string())?;
    row(w, "ScaleFactor", &|_| "1".to_string())?;
    row(w, "Offset", &|_| "0".to_string())?;
    row(w, "Unit", &|c| c.unit.to_string())?;
    writeln!(w)?;
    let rows = channels.iter().map(|c| c.samples.len()).max().unwrap_or(0);
    let mut line = String::new();
    for k in 0..rows {
        line.clear();
        for (i, c) in channels.iter().enumerate() {
            if i > 0 {
                line.push_str(&sep);
            }
            if let Some(v) = c.samples.get(k) {
                line.push_str(&num(k as f64 * c.sample_ms, decimal_comma));
                line.push_str(&sep);
                line.push_str(&num(*v, decimal_comma));
            } else {
                line.push_str(&sep);
            }
        }
        writeln!(w, "{line}")?;
    }
    Ok(())
}
