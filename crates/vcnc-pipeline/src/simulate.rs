//! Axis references through the true drives and through identified models.

use rayon::prelude::*;
use serde::Serialize;
use vcnc_axis::{AxisName, Unit};
use vcnc_drive::{ClosedLoopModel, DriveModel, DriveTrace, SimOptions};
use vcnc_machine::Machine;

use crate::Error;
use crate::run::AxisSignals;
use crate::run::Run;
use crate::stats::{max_abs, rms, scaled_diff, scaled_diff_max_rms};
use crate::summary::ModelSummary;

/// Runs every axis reference through its true drive (results in axis order): the drives that
/// share a loop structure several at a time in SIMD lanes ([`vcnc_drive::batch`]: each trace
/// bit for bit the drive's alone), the groups in parallel.
pub fn simulate_true(machine: &Machine, run: &Run) -> Result<Vec<DriveTrace>, Error> {
    let jobs = true_drive_jobs(machine, run);
    let groups = vcnc_drive::batch_groups(&jobs, run.ts);
    let done: Vec<Vec<Result<DriveTrace, vcnc_drive::Error>>> = groups
        .par_iter()
        .map(|g| {
            let sub: Vec<_> = g.iter().map(|i| jobs[*i]).collect();
            vcnc_drive::simulate_batch(&sub, run.ts)
        })
        .collect();
    let mut out: Vec<Option<Result<DriveTrace, vcnc_drive::Error>>> =
        jobs.iter().map(|_| None).collect();
    for (g, results) in groups.iter().zip(done) {
        for (i, r) in g.iter().zip(results) {
            out[*i] = Some(r);
        }
    }
    out.into_iter()
        .zip(&machine.axes)
        .map(|(r, axis)| {
            r.unwrap_or(Err(vcnc_drive::Error::EmptySignal))
                .map_err(|source| Error::Drive {
                    axis: axis.name,
                    source,
                })
        })
        .collect()
}

/// Each machine axis' true drive with its axis reference of `run` (as many as both have).
pub(crate) fn true_drive_jobs<'a>(
    machine: &'a Machine,
    run: &'a Run,
) -> Vec<(&'a vcnc_drive::Drive, vcnc_drive::Reference<'a>)> {
    machine
        .axes
        .iter()
        .zip(&run.axes)
        .map(|(axis, s)| (&axis.drive, s.reference()))
        .collect()
}

/// Runs every axis reference through its model (one per machine axis, in order). A model
/// without dead time, reference filter or extra pole runs as the 7-parameter
/// [`ClosedLoopModel::simulate`].
pub fn simulate_models(models: &[DriveModel], run: &Run) -> Result<Vec<Vec<f64>>, Error> {
    if models.len() != run.axes.len() {
        return Err(Error::Usage(format!(
            "{} models for {} axes",
            models.len(),
            run.axes.len()
        )));
    }
    models
        .par_iter()
        .zip(run.axes.par_iter())
        .map(|(m, s)| simulate_model(m, s, run.ts))
        .collect()
}

/// One axis reference (period `ts`, s) through its model: the positions, axis units.
pub fn simulate_model(
    m: &DriveModel,
    s: &crate::run::AxisSignals,
    ts: f64,
) -> Result<Vec<f64>, Error> {
    let opts = SimOptions::default();
    if m.is_core_only() {
        m.core.simulate(s.reference(), ts, &opts)
    } else {
        m.simulate(s.reference(), ts, &opts)
    }
    .map_err(|source| Error::Drive {
        axis: s.name,
        source,
    })
}

/// `vcnc simulate`: the true drives' traces and, optionally, the models' positions.
#[derive(Debug, Clone)]
pub struct Simulation {
    /// True drives: encoder traces per axis.
    pub traces: Vec<DriveTrace>,
    /// Models' positions per axis, when models were given.
    pub predicted: Option<Vec<Vec<f64>>>,
}

/// Simulates the true drives, and the models when given.
pub fn simulate(
    machine: &Machine,
    run: &Run,
    models: Option<&[DriveModel]>,
) -> Result<Simulation, Error> {
    let traces = simulate_true(machine, run)?;
    let predicted = models.map(|m| simulate_models(m, run)).transpose()?;
    Ok(Simulation { traces, predicted })
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
    /// The figures of machine axis `axis` (run signals `a`) from its tracking error and, with
    /// a model, the model's tracking error and (max, RMS) of the model's departure from the
    /// true drive, all in µm or mdeg.
    pub fn new(
        axis: &vcnc_machine::Axis,
        a: &AxisSignals,
        error: Vec<f64>,
        model: Option<(Vec<f64>, (f64, f64))>,
    ) -> AxisTracking {
        let (model_error, vs) = model.unzip();
        AxisTracking {
            axis: a.name,
            unit: a.unit,
            controller: axis.drive.controller().kind(),
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

/// Per-axis tracking figures of a simulation (the encoder positions, as a control sees them).
pub fn tracking(machine: &Machine, run: &Run, sim: &Simulation) -> Vec<AxisTracking> {
    let actual: Vec<&[f64]> = sim.traces.iter().map(|t| t.position.as_slice()).collect();
    tracking_of(machine, run, &actual, sim.predicted.as_deref())
}

/// Per-axis tracking figures of `actual` axis positions (one series per machine axis) and,
/// optionally, of model positions, against the run's references.
pub fn tracking_of(
    machine: &Machine,
    run: &Run,
    actual: &[&[f64]],
    models: Option<&[Vec<f64>]>,
) -> Vec<AxisTracking> {
    machine
        .axes
        .iter()
        .zip(run.axes.iter().zip(actual))
        .enumerate()
        .map(|(i, (axis, (a, x)))| {
            let k = a.unit.micro_factor();
            AxisTracking::new(
                axis,
                a,
                scaled_diff(&a.pos, x, k),
                models.map(|p| {
                    (
                        scaled_diff(&a.pos, &p[i], k),
                        scaled_diff_max_rms(&p[i], x, k),
                    )
                }),
            )
        })
        .collect()
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

/// The summary of a simulation.
pub fn simulate_summary(
    machine: &Machine,
    run: &Run,
    tracking: &[AxisTracking],
    models: Option<(&str, &[DriveModel])>,
) -> SimulateSummary {
    let figures: Vec<AxisFigures> = tracking
        .iter()
        .map(|t| AxisFigures {
            tracking: (t.tracking_max, t.tracking_rms),
            model_vs_true: t.model_vs_true_max.zip(t.model_vs_true_rms),
        })
        .collect();
    simulate_summary_of(
        machine,
        (&run.file, run.len(), run.duration_s()),
        &figures,
        models,
    )
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

/// [`simulate_summary`] from the figures of each machine axis (`figures`, in machine order) of
/// the program `(path, samples, duration s)`.
pub fn simulate_summary_of(
    machine: &Machine,
    (program, samples, duration_s): (&str, usize, f64),
    figures: &[AxisFigures],
    models: Option<(&str, &[DriveModel])>,
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
                    model: models.map(|(_, m)| ModelSummary::of_drive(&m[i])),
                    model_vs_true: f.model_vs_true,
                    controller: axis.drive.controller().kind(),
                },
            )
        })
        .collect();
    SimulateSummary {
        machine: machine.name.clone(),
        program: program.to_string(),
        models: models.map(|(f, _)| f.to_string()),
        samples,
        duration_s,
        axes,
    }
}
