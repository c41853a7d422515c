//! A description of a trace for people (`vcnc trace info`) and for summaries (serde).

use std::fmt;

use serde::{Deserialize, Serialize};
use vcnc_axis::AxisName;

use crate::model::{Format, Quantity, Trace};

/// One channel, described.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelInfo {
    /// File column (0-based).
    pub column: usize,
    /// Name.
    pub name: String,
    /// Symbol name, NCK path or channel type; empty when none.
    pub description: String,
    /// Axis, when known.
    pub axis: Option<AxisName>,
    /// How the axis was found (empty when unknown).
    pub axis_source: String,
    /// What it measures.
    pub quantity: Quantity,
    /// Unit symbol as stated by the file; empty when none.
    pub unit: String,
    /// Sample period, s, when known.
    pub period_s: Option<f64>,
    /// First sample time, s.
    pub t0_s: f64,
    /// Number of samples.
    pub count: usize,
    /// Number of gaps (lost-sample places).
    pub gaps: usize,
    /// Samples lost in the gaps, when known.
    pub lost: Option<usize>,
    /// Line of the declaration.
    pub line: usize,
}

/// A trace, described.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TraceInfo {
    /// The file.
    pub file: String,
    /// Its format.
    pub format: Format,
    /// File-level fields.
    pub metadata: Vec<(String, String)>,
    /// The channels.
    pub channels: Vec<ChannelInfo>,
}

impl Trace {
    /// The description of every channel.
    pub fn info(&self) -> TraceInfo {
        TraceInfo {
            file: self.file.clone(),
            format: self.format,
            metadata: self.metadata.clone(),
            channels: self
                .channels
                .iter()
                .map(|c| ChannelInfo {
                    column: c.column,
                    name: c.name.clone(),
                    description: c.description.clone(),
                    axis: c.axis,
                    axis_source: c
                        .axis_source
                        .as_ref()
                        .map(ToString::to_string)
                        .unwrap_or_default(),
                    quantity: c.quantity,
                    unit: c.unit.as_ref().map(ToString::to_string).unwrap_or_default(),
                    period_s: c.period_s,
                    t0_s: c.t0_s,
                    count: c.samples.len(),
                    gaps: c.gaps.len(),
                    lost: c.lost_samples(),
                    line: c.line,
                })
                .collect(),
        }
    }
}

/// A period for people: `1 ms`, `600 µs`, `1.25 s`.
pub fn format_period(p: f64) -> String {
    let (v, u) = if p >= 1.0 {
        (p, "s")
    } else if p >= 1e-3 {
        (p * 1e3, "ms")
    } else {
        (p * 1e6, "µs")
    };
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    format!("{s} {u}")
}

impl fmt::Display for TraceInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "file:   {}", self.file)?;
        writeln!(f, "format: {} ({})", self.format, self.format.key())?;
        for (k, v) in &self.metadata {
            writeln!(f, "  {k}: {v}")?;
        }
        let rows: Vec<[String; 9]> = self
            .channels
            .iter()
            .map(|c| {
                [
                    c.column.to_string(),
                    c.name.clone(),
                    c.axis.map_or("-".to_string(), |a| a.to_string()),
                    c.quantity.to_string(),
                    if c.unit.is_empty() {
                        "-".to_string()
                    } else {
                        c.unit.clone()
                    },
                    c.period_s.map_or("?".to_string(), format_period),
                    c.count.to_string(),
                    match (c.gaps, c.lost) {
                        (0, _) => "0".to_string(),
                        (g, Some(l)) => format!("{g} ({l} lost)"),
                        (g, None) => format!("{g} (? lost)"),
                    },
                    if c.axis_source.is_empty() {
                        "-".to_string()
                    } else {
                        c.axis_source.clone()
                    },
                ]
            })
            .collect();
        let head = [
            "col",
            "channel",
            "axis",
            "quantity",
            "unit",
            "period",
            "samples",
            "gaps",
            "axis from",
        ];
        let mut width = head.map(str::len);
        for r in &rows {
            for (w, c) in width.iter_mut().zip(r) {
                *w = (*w).max(c.chars().count());
            }
        }
        let line = |f: &mut fmt::Formatter<'_>, cells: &[&str]| -> fmt::Result {
            let mut s = String::new();
            for (i, (c, w)) in cells.iter().zip(width).enumerate() {
                if i > 0 {
                    s.push_str("  ");
                }
                s.push_str(c);
                if i + 1 < cells.len() {
                    s.extend(std::iter::repeat_n(' ', w - c.chars().count()));
                }
            }
            writeln!(f, "{}", s.trim_end())
        };
        line(f, &head)?;
        for r in &rows {
            let cells: Vec<&str> = r.iter().map(String::as_str).collect();
            line(f, &cells)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periods_print_in_a_readable_unit() {
        assert_eq!(format_period(1e-3), "1 ms");
        assert_eq!(format_period(6e-4), "600 µs");
        assert_eq!(format_period(2.5), "2.5 s");
        assert_eq!(format_period(2e-4), "200 µs");
    }
}
