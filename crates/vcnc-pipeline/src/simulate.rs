//! A program's reference through the true drives and, optionally, through identified models
//! (docs/performance.md, "Streamed simulation"): [`simulate`] takes the reference a piece at a
//! time from its [`Source`] and hands each piece ([`SimulatePiece`]: every channel of the true
//! drives, the models' logged positions) to a [`Sink`], accumulating the tracking figures of
//! `summary.json` on the way. [`SimulationRecord`] is the sink that keeps what the
//! full-resolution tracking figure needs.

use serde::Serialize;
use vcnc_axis::{AxisName, Unit};
use vcnc_drive::{Channels, ClosedLoopModel, DriveTrace};
use vcnc_machine::{Machine, MachineModels};

use crate::drives::{ModelRuns, TrueDrives};
use crate::run::Run;
use crate::sink::Sink;
use crate::source::{ReferenceChunk, ReferenceStats, Source};
use crate::stats::{MaxRms, max_abs, rms};
use crate::summary::ModelSummary;

/// A piece of a simulation, samples `first..first + len()`.
#[derive(Debug, Clone, Default)]
pub struct SimulatePiece {
    /// Index of the first sample.
    pub first: usize,
    /// Per machine axis: the reference position, mm or deg.
    pub reference: Vec<Vec<f64>>,
    /// Per machine axis: the true drive's trace of these samples (every channel).
    pub traces: Vec<DriveTrace>,
    /// Per machine axis: the model's (logged) position, when models are simulated.
    pub predicted: Option<Vec<Vec<f64>>>,
}

impl SimulatePiece {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.reference.first().map_or(0, Vec::len)
    }

    /// `true` without samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// What a simulation measured.
#[derive(Debug, Clone)]
pub struct SimulateOutcome {
    /// Per machine axis: the tracking figures.
    pub tracking: Vec<AxisFigures>,
    /// Per machine axis: servo ticks at which the true drive's command saturated.
    pub saturated_ticks: Vec<u64>,
    /// What handing on the reference measured (rates, which axes moved).
    pub reference: ReferenceStats,
    /// Every warning of the run, in order.
    pub warnings: Vec<String>,
}

/// Runs the reference of `source` through the true drives (every channel) and, with `models`,
/// through the models (their logged positions: no actual-value latency), handing each piece to
/// `sink` in order. The tracking figures compare the encoder readings (what a control sees)
/// with the reference, and the models with the encoder readings, in µm or mdeg, summed in
/// sample order.
pub fn simulate<S: Sink<SimulatePiece>>(
    machine: &Machine,
    source: Source<'_>,
    models: Option<&MachineModels>,
    sink: &mut S,
) -> Result<SimulateOutcome, S::Error> {
    let axes = machine.axes.len();
    let ts = source.ts();
    let mut drives = TrueDrives::new(machine, ts, Channels::All)?;
    let sets: Vec<&MachineModels> = models.into_iter().collect();
    let mut model_runs = ModelRuns::new(machine, &sets, ts, false)?;
    let mut piece = SimulatePiece {
        reference: vec![Vec::new(); axes],
        predicted: models.map(|_| vec![Vec::new(); axes]),
        ..SimulatePiece::default()
    };
    let mut tracking = vec![MaxRms::default(); axes];
    let mut model_vs_true = vec![MaxRms::default(); axes];
    let mut on_chunk = |c: &ReferenceChunk| -> Result<(), S::Error> {
        let (a, b) = rayon::join(|| drives.feed(machine, c), || model_runs.feed(machine, c));
        a?;
        b?;
        piece.first = c.first;
        for (r, p) in piece.reference.iter_mut().zip(&c.pos) {
            r.clear();
            r.extend_from_slice(p);
        }
        std::mem::swap(&mut piece.traces, &mut drives.traces);
        if let (Some(p), Some(out)) = (piece.predicted.as_mut(), model_runs.out.first_mut()) {
            std::mem::swap(p, out);
        }
        for (i, a) in machine.axes.iter().enumerate() {
            let k = a.unit.micro_factor();
            let x = &piece.traces[i].position;
            for (r, x) in piece.reference[i].iter().zip(x) {
                tracking[i].add((r - x) * k);
            }
            if let Some(p) = piece.predicted.as_ref() {
                for (m, x) in p[i].iter().zip(x) {
                    model_vs_true[i].add((m - x) * k);
                }
            }
        }
        sink.piece(&piece)?;
        std::mem::swap(&mut piece.traces, &mut drives.traces);
        if let (Some(p), Some(out)) = (piece.predicted.as_mut(), model_runs.out.first_mut()) {
            std::mem::swap(p, out);
        }
        Ok(())
    };
    let reference = source.for_each(machine, &mut on_chunk)?;
    let (saturated_ticks, _) = drives.finish(machine)?;
    model_runs.finish(machine)?;
    let tracking = (0..axes)
        .map(|i| AxisFigures {
            tracking: tracking[i].max_rms(),
            model_vs_true: models.map(|_| model_vs_true[i].max_rms()),
        })
        .collect();
    let mut warnings = source.warnings().to_vec();
    warnings.extend(reference.warnings.iter().cloned());
    Ok(SimulateOutcome {
        tracking,
        saturated_ticks,
        reference,
        warnings,
    })
}

/// The true drives' traces (every channel) of a prepared run, every sample: the simulate run
/// with the sink that keeps everything.
pub fn true_traces(machine: &Machine, run: &Run) -> Result<Vec<DriveTrace>, crate::Error> {
    let mut keep = TraceRecord(vec![DriveTrace::default(); machine.axes.len()]);
    let outcome = simulate(machine, Source::Prepared(run), None, &mut keep)?;
    for ((t, s), a) in keep
        .0
        .iter_mut()
        .zip(outcome.saturated_ticks)
        .zip(&machine.axes)
    {
        t.ts = run.ts;
        t.saturated_ticks = s;
        // An axis known by its model logged its model's positions as both; its physical
        // position is them advanced by the model's stated latency (as in a prediction).
        if let vcnc_machine::Dynamics::Model(m) = &a.dynamics {
            t.true_position = crate::latency::shifted(&t.position, m.actual_latency_s, run.ts);
        }
    }
    Ok(keep.0)
}

/// Keeps every channel of every piece.
struct TraceRecord(Vec<DriveTrace>);

impl Sink<SimulatePiece> for TraceRecord {
    type Error = crate::Error;
    fn piece(&mut self, p: &SimulatePiece) -> Result<(), crate::Error> {
        for (t, piece) in self.0.iter_mut().zip(&p.traces) {
            for (all, part) in [
                (&mut t.position, &piece.position),
                (&mut t.true_position, &piece.true_position),
                (&mut t.velocity, &piece.velocity),
                (&mut t.control, &piece.control),
                (&mut t.motor_position, &piece.motor_position),
                (&mut t.motor_torque, &piece.motor_torque),
            ] {
                all.extend_from_slice(part);
            }
        }
        Ok(())
    }
}

/// The positions of a prepared run's axes through `models` (one per machine axis): the logged
/// positions the models predict, or with `physical` each advanced by its model's stated
/// actual-value latency ([`crate::latency`]). The models' part of the simulate and predict
/// runs, every sample kept.
pub fn model_positions(
    machine: &Machine,
    models: &MachineModels,
    run: &Run,
    physical: bool,
) -> Result<Vec<Vec<f64>>, crate::Error> {
    let mut runs = ModelRuns::new(machine, &[models], run.ts, physical)?;
    let mut out: Vec<Vec<f64>> = vec![Vec::with_capacity(run.len()); machine.axes.len()];
    Source::Prepared(run).for_each(machine, &mut |c: &ReferenceChunk| {
        runs.feed(machine, c)?;
        for (o, y) in out.iter_mut().zip(&runs.out[0]) {
            o.extend_from_slice(y);
        }
        Ok::<(), crate::Error>(())
    })?;
    for (o, y) in out.iter_mut().zip(&runs.finish(machine)?[0]) {
        o.extend_from_slice(y);
    }
    Ok(out)
}

/// Tracking figures of one axis of a simulation, in µm (linear axes) or millidegrees.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisTracking {
    /// The axis.
    pub axis: AxisName,
    /// mm or deg.
    pub unit: Unit,
    /// Controller kind of the true drive (`p-pi`, `pid`, `smc`).
    pub controller: &'static str,
    /// The true drive's analytic closed-loop model.
    pub true_model: ClosedLoopModel,
    /// Tracking error $x_r - x$ of the true drive per sample, µm or mdeg.
    pub error: Vec<f64>,
    /// Tracking error of the model per sample, µm or mdeg, when a model was simulated.
    pub model_error: Option<Vec<f64>>,
    /// max |x_r − x|, µm or mdeg.
    pub tracking_max: f64,
    /// RMS of x_r − x, µm or mdeg.
    pub tracking_rms: f64,
    /// max |x_model − x|, µm or mdeg.
    pub model_vs_true_max: Option<f64>,
    /// RMS of x_model − x, µm or mdeg.
    pub model_vs_true_rms: Option<f64>,
}

impl AxisTracking {
    /// The figures of machine axis `axis` from its tracking error and, with
    /// a model, the model's tracking error and (max, RMS) of the model's departure from the
    /// true drive, all in µm or mdeg.
    pub fn new(
        axis: &vcnc_machine::Axis,
        error: Vec<f64>,
        model: Option<(Vec<f64>, (f64, f64))>,
    ) -> AxisTracking {
        let (model_error, vs) = model.unzip();
        AxisTracking {
            axis: axis.name,
            unit: axis.unit,
            controller: axis.controller_kind(),
            true_model: axis.true_model(),
            tracking_max: max_abs(&error),
            tracking_rms: rms(&error),
            model_error,
            model_vs_true_max: vs.map(|v| v.0),
            model_vs_true_rms: vs.map(|v| v.1),
            error,
        }
    }
}

/// What the full-resolution tracking figure of a simulation needs, every sample: the sink
/// that keeps the tracking errors of the true drives (encoder readings) and of the models, in
/// µm or mdeg, and the reference positions.
#[derive(Debug, Clone, Default)]
pub struct SimulationRecord {
    /// Per machine axis: the reference positions.
    pub reference: Vec<Vec<f64>>,
    /// Per machine axis: the tracking error $x_r - x$ of the true drive (encoder), µm or mdeg.
    pub error: Vec<Vec<f64>>,
    /// Per machine axis: the model's tracking error, when models are simulated.
    pub model_error: Option<Vec<Vec<f64>>>,
    /// Per machine axis: µm or mdeg per axis unit.
    scale: Vec<f64>,
}

impl SimulationRecord {
    /// A record of `machine`'s axes.
    pub fn new(machine: &Machine) -> SimulationRecord {
        let n = machine.axes.len();
        SimulationRecord {
            reference: vec![Vec::new(); n],
            error: vec![Vec::new(); n],
            model_error: None,
            scale: machine.axes.iter().map(|a| a.unit.micro_factor()).collect(),
        }
    }

    /// The tracking figures of each axis (the arrays moved into them).
    pub fn into_tracking(self, machine: &Machine, outcome: &SimulateOutcome) -> Vec<AxisTracking> {
        let mut models = self.model_error.map(|m| m.into_iter());
        machine
            .axes
            .iter()
            .zip(self.error)
            .zip(&outcome.tracking)
            .map(|((axis, error), f)| {
                let model = models
                    .as_mut()
                    .and_then(Iterator::next)
                    .zip(f.model_vs_true);
                AxisTracking::new(axis, error, model)
            })
            .collect()
    }
}

impl Sink<SimulatePiece> for SimulationRecord {
    type Error = crate::Error;
    fn piece(&mut self, p: &SimulatePiece) -> Result<(), crate::Error> {
        for (i, k) in self.scale.iter().enumerate() {
            let r = &p.reference[i];
            self.reference[i].extend_from_slice(r);
            self.error[i].extend(
                r.iter()
                    .zip(&p.traces[i].position)
                    .map(|(r, x)| (r - x) * k),
            );
            if let Some(pred) = &p.predicted {
                let m = self
                    .model_error
                    .get_or_insert_with(|| vec![Vec::new(); self.scale.len()]);
                m[i].extend(r.iter().zip(&pred[i]).map(|(r, x)| (r - x) * k));
            }
        }
        Ok(())
    }
}

/// `summary.json` of `vcnc simulate` (keys sorted when written).
#[derive(Debug, Clone, Serialize)]
pub struct SimulateSummary {
    /// Machine name.
    pub machine: String,
    /// Program path.
    pub program: String,
    /// The identified model file given with `--model`, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub models: Option<String>,
    /// Number of samples.
    pub samples: usize,
    /// Program duration, s.
    pub duration_s: f64,
    /// Per axis.
    pub axes: std::collections::BTreeMap<String, SimulateAxisSummary>,
}

/// One axis of [`SimulateSummary`]. Error keys end in `_um` (linear axes) or `_mdeg` (rotary).
#[derive(Debug, Clone)]
pub struct SimulateAxisSummary {
    /// mm or deg.
    pub unit: Unit,
    /// Tracking error max / RMS, µm or mdeg.
    pub tracking: (f64, f64),
    /// The true drive's analytic model (key `true_model`).
    pub true_model: ModelSummary,
    /// The model given with `--model` (key `model`).
    pub model: Option<ModelSummary>,
    /// |model − true| max / RMS, µm or mdeg.
    pub model_vs_true: Option<(f64, f64)>,
    /// Controller kind.
    pub controller: &'static str,
}

impl Serialize for SimulateAxisSummary {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let u = self.unit.micro_label();
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("unit", self.unit.as_str())?;
        m.serialize_entry(&format!("tracking_max_{u}"), &self.tracking.0)?;
        m.serialize_entry(&format!("tracking_rms_{u}"), &self.tracking.1)?;
        m.serialize_entry("true_model", &self.true_model)?;
        if let Some(model) = &self.model {
            m.serialize_entry("model", model)?;
        }
        if let Some((max, rms)) = self.model_vs_true {
            m.serialize_entry(&format!("model_vs_true_max_{u}"), &max)?;
            m.serialize_entry(&format!("model_vs_true_rms_{u}"), &rms)?;
        }
        m.serialize_entry("controller", self.controller)?;
        m.end()
    }
}

/// The tracking figures of one axis, µm or mdeg: max and RMS of the tracking error, and of the
/// model's departure from the true drive when a model was simulated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisFigures {
    /// max |x_r − x|, RMS of x_r − x.
    pub tracking: (f64, f64),
    /// max |x_model − x|, RMS of x_model − x.
    pub model_vs_true: Option<(f64, f64)>,
}

/// `summary.json` of `vcnc simulate` from the figures of each machine axis (`figures`, in machine order) of
/// the program `(path, samples, duration s)`.
pub fn simulate_summary_of(
    machine: &Machine,
    (program, samples, duration_s): (&str, usize, f64),
    figures: &[AxisFigures],
    models: Option<&MachineModels>,
) -> SimulateSummary {
    let axes = machine
        .axes
        .iter()
        .zip(figures)
        .enumerate()
        .map(|(i, (axis, f))| {
            (
                axis.name.to_string(),
                SimulateAxisSummary {
                    unit: axis.unit,
                    tracking: f.tracking,
                    true_model: ModelSummary::of(&axis.true_model()),
                    model: models.map(|m| ModelSummary::of_drive(m.get(i))),
                    model_vs_true: f.model_vs_true,
                    controller: axis.controller_kind(),
                },
            )
        })
        .collect();
    SimulateSummary {
        machine: machine.name.clone(),
        program: program.to_string(),
        models: models.map(|m| m.source().to_string()),
        samples,
        duration_s,
        axes,
    }
}
