//! A description of a trace for people (`vcnc trace info`) and for summaries (serde).

use std::fmt;

use serde::{Deserialize, Serialize};
use vcnc_axis::AxisName;

use crate::lost_motion::{LostMotion, lost_motion};
use crate::model::{Channel, Format, Quantity, Trace};
use crate::pair::{GapPolicy, PairOptions, pair};

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
    /// The axis number the file gives it (Sinumerik NCK axis), when it does.
    pub axis_number: Option<u32>,
    /// What it measures.
    pub quantity: Quantity,
    /// Its measuring system (1 motor encoder, 2 direct), when the file says.
    pub measuring_system: Option<u8>,
    /// Unit symbol as stated by the file; empty when none.
    pub unit: String,
    /// Sample period (recording interval), s, when known.
    pub period_s: Option<f64>,
    /// The signal's own control cycle, s, when the file states it apart (TNCscope `CYCLETIME`).
    pub cycle_s: Option<f64>,
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
    /// Lost motion between the two measuring systems of each axis recorded with both.
    pub lost_motion: Vec<LostMotion>,
    /// Why a lost motion was not measured, per axis (or axis number) with two systems.
    pub notes: Vec<String>,
}

impl Trace {
    /// The lost motion of every axis recorded with two measuring systems ([`lost_motion`], on
    /// the longest gap-free stretch, units as [`crate::pair`] assumes them), and for each such
    /// axis or axis number where it cannot be measured, why.
    pub fn lost_motions(&self) -> (Vec<LostMotion>, Vec<String>) {
        let (mut found, mut notes) = (Vec::new(), Vec::new());
        let two_systems = |chs: Vec<&Channel>| {
            let mut m: Vec<u8> = chs.iter().filter_map(|c| c.measuring_system).collect();
            m.sort_unstable();
            m.dedup();
            m.len() >= 2
        };
        let actuals = || {
            self.channels
                .iter()
                .filter(|c| c.quantity == Quantity::ActualPosition)
        };
        for axis in AxisName::ALL {
            if !two_systems(actuals().filter(|c| c.axis == Some(axis)).collect()) {
                continue;
            }
            let opts = PairOptions {
                axes: vec![axis],
                gaps: GapPolicy::LongestSegment,
                ..PairOptions::default()
            };
            match pair(self, &opts).and_then(|p| lost_motion(&p.axes[0])) {
                Ok(l) => found.push(l),
                Err(e) => notes.push(format!("lost motion of axis {axis} not measured: {e}")),
            }
        }
        let mut numbers: Vec<u32> = actuals()
            .filter(|c| c.axis.is_none())
            .filter_map(|c| c.axis_number)
            .collect();
        numbers.sort_unstable();
        numbers.dedup();
        for n in numbers {
            let chs = actuals()
                .filter(|c| c.axis.is_none() && c.axis_number == Some(n))
                .collect();
            if two_systems(chs) {
                notes.push(format!(
                    "axis number {n} has two measuring systems; for its lost motion name its axis with --axis-map {n}=A"
                ));
            }
        }
        (found, notes)
    }

    /// The description of every channel, and the lost motion between measuring systems.
    pub fn info(&self) -> TraceInfo {
        let (lost_motion, notes) = self.lost_motions();
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
                    axis_number: c.axis_number,
                    quantity: c.quantity,
                    measuring_system: c.measuring_system,
                    unit: c.unit.as_ref().map(ToString::to_string).unwrap_or_default(),
                    period_s: c.period_s,
                    cycle_s: c.cycle_s,
                    t0_s: c.t0_s,
                    count: c.samples.len(),
                    gaps: c.gaps.len(),
                    lost: c.lost_samples(),
                    line: c.line,
                })
                .collect(),
            lost_motion,
            notes,
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
                    match c.measuring_system {
                        Some(m) => format!("{} (system {m})", c.quantity),
                        None => c.quantity.to_string(),
                    },
                    if c.unit.is_empty() {
                        "-".to_string()
                    } else {
                        c.unit.clone()
                    },
                    match (c.period_s, c.cycle_s) {
                        (None, _) => "?".to_string(),
                        (Some(p), Some(cy)) if (cy - p).abs() > 1e-9 * p => {
                            format!("{} (cycle {})", format_period(p), format_period(cy))
                        }
                        (Some(p), _) => format_period(p),
                    },
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
        if !self.lost_motion.is_empty() {
            writeln!(
                f,
                "lost motion between the measuring systems at reversals of the setpoint:"
            )?;
            for l in &self.lost_motion {
                writeln!(f, "  {l}")?;
            }
        }
        for n in &self.notes {
            writeln!(f, "note: {n}")?;
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
