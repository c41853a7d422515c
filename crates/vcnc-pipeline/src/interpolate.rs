//! `vcnc interpolate`: a program's reference at the sample period, handed a piece at a time to
//! a [`Sink`], and the figures of its summary.

use vcnc_axis::Unit;
use vcnc_machine::Machine;

use crate::sink::Sink;
use crate::source::{ReferenceChunk, ReferenceStats, Source};

/// What interpolating a program measured.
#[derive(Debug, Clone)]
pub struct InterpolateOutcome {
    /// Its `summary.json`.
    pub summary: InterpolateSummary,
    /// What handing on the reference measured (rates, which axes moved).
    pub reference: ReferenceStats,
}

/// Hands the reference of `source` to `sink` a piece at a time ([`Source::for_each`]) and
/// returns the summary.
pub fn interpolate<S: Sink<ReferenceChunk>>(
    machine: &Machine,
    source: Source<'_>,
    sink: &mut S,
) -> Result<InterpolateOutcome, S::Error> {
    let reference = source.for_each(machine, &mut |c| sink.piece(c))?;
    Ok(InterpolateOutcome {
        summary: interpolate_summary(machine, &source, &reference),
        reference,
    })
}

/// The tool tip (mm, workpiece frame) of each sample of `c`, by the forward kinematics of its
/// axis positions: the `px py pz` columns of a TCP program's reference table.
pub fn tool_tips(machine: &Machine, c: &ReferenceChunk) -> Result<[Vec<f64>; 3], crate::Error> {
    let kin = machine.require_kinematics()?;
    let pos = c.positions();
    let mut tip: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(c.len()));
    for k in 0..c.len() {
        let q = kin.pose_at(&pos, k);
        for (i, t) in tip.iter_mut().enumerate() {
            t.push(q.p[i]);
        }
    }
    Ok(tip)
}

/// Peak reference rates of one axis.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AxisRates {
    /// `mm` or `deg`.
    pub unit: Unit,
    /// Largest |velocity|, units/s.
    pub max_vel: f64,
    /// Largest |acceleration|, units/s².
    pub max_acc: f64,
}

/// `summary.json` of `vcnc interpolate`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct InterpolateSummary {
    /// Machine name.
    pub machine: String,
    /// Program path.
    pub program: String,
    /// Duration, s.
    pub duration_s: f64,
    /// Time spent in feed moves (G1 G2 G3, cycles' feed parts), s.
    pub feed_duration_s: f64,
    /// The planner's cycle time and its split between feeds, rapids and dwells, s.
    pub cycle_time: vcnc_gcode::CycleTime,
    /// Number of samples.
    pub samples: usize,
    /// Sample period, s.
    pub ts_s: f64,
    /// Whether the program uses tool-centre-point mode.
    pub tcp: bool,
    /// Per axis.
    pub axes: std::collections::BTreeMap<String, AxisRates>,
    /// Warnings of the run.
    pub warnings: Vec<String>,
}

/// `summary.json` of `vcnc interpolate`: the program's figures and what handing on its
/// reference measured (`warnings`: the run's, in order).
pub fn interpolate_summary(
    machine: &Machine,
    source: &Source<'_>,
    stats: &ReferenceStats,
) -> InterpolateSummary {
    let mut warnings = source.warnings().to_vec();
    warnings.extend(stats.warnings.iter().cloned());
    InterpolateSummary {
        machine: machine.name.clone(),
        program: source.file().to_string(),
        duration_s: source.duration_s(),
        feed_duration_s: stats.feed_samples as f64 * source.ts(),
        cycle_time: source.cycle(),
        samples: source.len(),
        ts_s: source.ts(),
        tcp: source.has_tcp(),
        axes: machine
            .axes
            .iter()
            .enumerate()
            .map(|(i, a)| {
                (
                    a.name.to_string(),
                    AxisRates {
                        unit: a.unit,
                        max_vel: stats.max_vel[i],
                        max_acc: stats.max_acc[i],
                    },
                )
            })
            .collect(),
        warnings,
    }
}
