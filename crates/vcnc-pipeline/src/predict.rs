//! Tool-tip and orientation contour errors of a run with the true drives and with identified
//! models (docs/contour.md).

use std::collections::BTreeMap;

use serde::Serialize;
use vcnc_contour::{ContourPath, ContourReport, ContourSearch, SearchWindow, contour_errors};
use vcnc_drive::{DriveModel, DriveTrace};
use vcnc_kinematics::Pose;
use vcnc_machine::Machine;

use crate::run::{Measured, Run, forward_poses};
use crate::simulate::{simulate_model, simulate_models};
use crate::stats::{max_abs, rms, scaled_diff_max_rms};
use crate::{Error, latency};

/// Contour errors of actual axis positions (per machine axis, mm / deg) against the run's
/// reference poses.
pub fn contour(
    machine: &Machine,
    run: &Run,
    actual: &[&[f64]],
) -> Result<(Vec<Pose>, ContourReport), Error> {
    let reference = run.reference_poses(machine)?;
    let poses = forward_poses(machine, actual)?;
    let report = contour_errors(&reference, &poses)?;
    Ok((poses, report))
}

/// Tool-tip and orientation contour errors with the true and the predicted drives.
#[derive(Debug, Clone)]
pub struct Prediction {
    /// True drives per axis: their true positions (`true_position`, `ts`, `saturated_ticks`);
    /// the other channels are left empty (docs/performance.md).
    pub true_traces: Vec<DriveTrace>,
    /// Identified models: positions per axis.
    pub predicted: Vec<Vec<f64>>,
    /// Contour errors with the true drives (without foot points: `foot` is empty).
    pub true_contour: ContourReport,
    /// Contour errors with the identified models (without foot points).
    pub predicted_contour: ContourReport,
}

impl Prediction {
    /// The true drives' positions per machine axis (axis units).
    pub fn true_positions(&self) -> Vec<&[f64]> {
        self.true_traces
            .iter()
            .map(|t| t.true_position.as_slice())
            .collect()
    }

    /// The models' positions per machine axis (axis units).
    pub fn predicted_positions(&self) -> Vec<&[f64]> {
        self.predicted.iter().map(Vec::as_slice).collect()
    }

    /// Per-sample |predicted − true| tool-tip contour error, mm.
    pub fn tip_discrepancy(&self) -> Vec<f64> {
        self.true_contour
            .tip_mm
            .iter()
            .zip(&self.predicted_contour.tip_mm)
            .map(|(a, b)| (a - b).abs())
            .collect()
    }

    /// Per-sample |predicted − true| orientation contour error, rad.
    pub fn orientation_discrepancy(&self) -> Vec<f64> {
        self.true_contour
            .orientation_rad
            .iter()
            .zip(&self.predicted_contour.orientation_rad)
            .map(|(a, b)| (a - b).abs())
            .collect()
    }

    /// Per-axis tracking errors of the true drives (their true, not encoder, positions) and of
    /// the models.
    pub fn tracking(&self, machine: &Machine, run: &Run) -> Vec<crate::AxisTracking> {
        let actual: Vec<&[f64]> = self
            .true_traces
            .iter()
            .map(|t| t.true_position.as_slice())
            .collect();
        crate::simulate::tracking_of(machine, run, &actual, Some(&self.predicted))
    }

    /// [`Prediction::tracking`] computed in place: each axis' true and predicted positions
    /// become its tracking errors, so that a long run needs no memory for them beyond the
    /// prediction's own (docs/performance.md). Bit-identical to [`Prediction::tracking`].
    /// The contour reports are dropped.
    pub fn into_tracking(self, machine: &Machine, run: &Run) -> Vec<crate::AxisTracking> {
        machine
            .axes
            .iter()
            .zip(&run.axes)
            .zip(self.true_traces.into_iter().zip(self.predicted))
            .map(|((axis, a), (t, model))| {
                let k = a.unit.micro_factor();
                let mut error = t.true_position;
                let vs = scaled_diff_max_rms(&model, &error, k);
                let to_error = |x: &mut Vec<f64>| {
                    for (x, r) in x.iter_mut().zip(&a.pos) {
                        *x = (r - *x) * k;
                    }
                };
                to_error(&mut error);
                let mut model_error = model;
                to_error(&mut model_error);
                crate::AxisTracking::new(axis, a, error, Some((model_error, vs)))
            })
            .collect()
    }

    /// The six contour statistics over the samples `mask` selects (every sample when it is
    /// all true), tool tip in µm and orientation in mrad.
    pub fn figures(&self, mask: &[bool]) -> ContourFigures {
        let (t, q) = (&self.true_contour, &self.predicted_contour);
        let (d_tip, d_or) = (self.tip_discrepancy(), self.orientation_discrepancy());
        let pick = |v: &[f64]| -> Vec<f64> {
            v.iter()
                .zip(mask)
                .filter_map(|(x, m)| m.then_some(*x))
                .collect()
        };
        let pair = |tip: &[f64], or: &[f64], f: fn(&[f64]) -> f64| Figure {
            tip_um: f(&pick(tip)) * 1e3,
            orientation_mrad: f(&pick(or)) * 1e3,
        };
        ContourFigures {
            true_max: pair(&t.tip_mm, &t.orientation_rad, max_abs),
            true_rms: pair(&t.tip_mm, &t.orientation_rad, rms),
            predicted_max: pair(&q.tip_mm, &q.orientation_rad, max_abs),
            predicted_rms: pair(&q.tip_mm, &q.orientation_rad, rms),
            discrepancy_max: pair(&d_tip, &d_or, max_abs),
            discrepancy_rms: pair(&d_tip, &d_or, rms),
        }
    }

    /// The `n` blocks (source lines) with the largest true tool-tip contour error among the
    /// samples `mask` selects, worst first.
    pub fn worst_blocks(&self, run: &Run, mask: &[bool], n: usize) -> Vec<WorstBlock> {
        worst_blocks(
            &run.lines,
            &self.true_contour.tip_mm,
            &self.true_contour.orientation_rad,
            mask,
            n,
        )
    }
}

/// A block of the program and its largest contour errors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WorstBlock {
    /// Source line of the block.
    pub line: u32,
    /// Its largest tool-tip contour error, µm.
    pub contour_max_um: f64,
    /// Its largest orientation contour error, mrad.
    pub orientation_max_mrad: f64,
}

/// The `n` source lines with the largest tool-tip error (mm) among the samples `mask` selects,
/// worst first (ties: the earlier line); their orientation error (rad) beside it.
pub fn worst_blocks(
    lines: &[u32],
    tip_mm: &[f64],
    orientation_rad: &[f64],
    mask: &[bool],
    n: usize,
) -> Vec<WorstBlock> {
    let mut per_line: BTreeMap<u32, (f64, f64)> = BTreeMap::new();
    for k in 0..lines.len().min(tip_mm.len()).min(mask.len()) {
        if !mask[k] || lines[k] == 0 {
            continue;
        }
        let e = per_line.entry(lines[k]).or_insert((0.0, 0.0));
        e.0 = e.0.max(tip_mm[k]);
        e.1 = e.1.max(orientation_rad.get(k).copied().unwrap_or(0.0));
    }
    ranked_blocks(per_line, n)
}

/// The `n` lines of `per_line` (line → largest tool-tip error mm, orientation error rad) with
/// the largest tool-tip error in µm, worst first (ties: the earlier line).
pub(crate) fn ranked_blocks(per_line: BTreeMap<u32, (f64, f64)>, n: usize) -> Vec<WorstBlock> {
    let mut v: Vec<WorstBlock> = per_line
        .into_iter()
        .map(|(line, (t, o))| WorstBlock {
            line,
            contour_max_um: t * 1e3,
            orientation_max_mrad: o * 1e3,
        })
        .collect();
    v.sort_by(|a, b| {
        b.contour_max_um
            .total_cmp(&a.contour_max_um)
            .then(a.line.cmp(&b.line))
    });
    v.truncate(n);
    v
}

/// One statistic of the tool-tip (µm) and orientation (mrad) contour errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figure {
    /// Tool tip, µm.
    pub tip_um: f64,
    /// Orientation, mrad.
    pub orientation_mrad: f64,
}

/// The contour statistics of a prediction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContourFigures {
    /// Max with the true drives.
    pub true_max: Figure,
    /// RMS with the true drives.
    pub true_rms: Figure,
    /// Max with the models.
    pub predicted_max: Figure,
    /// RMS with the models.
    pub predicted_rms: Figure,
    /// Max of |predicted − true|.
    pub discrepancy_max: Figure,
    /// RMS of |predicted − true|.
    pub discrepancy_rms: Figure,
}

impl ContourFigures {
    /// `(table label, summary key, figure)`, in table order.
    pub fn rows(&self) -> [(&'static str, &'static str, Figure); 6] {
        [
            ("true max", "true_max", self.true_max),
            ("true RMS", "true_rms", self.true_rms),
            ("predicted max", "predicted_max", self.predicted_max),
            ("predicted RMS", "predicted_rms", self.predicted_rms),
            ("|pred - true| max", "discrepancy_max", self.discrepancy_max),
            ("|pred - true| RMS", "discrepancy_rms", self.discrepancy_rms),
        ]
    }
}

/// The contour part of a summary: `contour_um.{true_max …}`, `orientation_mrad.{…}`,
/// `samples`, `measured`, `measured_samples`, `worst_blocks`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContourSummary {
    /// Tool-tip contour error statistics, µm.
    pub contour_um: BTreeMap<&'static str, f64>,
    /// Orientation contour error statistics, mrad.
    pub orientation_mrad: BTreeMap<&'static str, f64>,
    /// Number of samples of the run.
    pub samples: usize,
    /// Which samples the statistics cover: `feed` (feed moves, the default) or `all`.
    pub measured: &'static str,
    /// How many samples they cover.
    pub measured_samples: usize,
    /// The blocks with the largest true contour errors, worst first.
    pub worst_blocks: Vec<WorstBlock>,
}

/// Blocks listed in a summary's `worst_blocks`.
pub const WORST_BLOCKS: usize = 10;

impl ContourSummary {
    /// The summary of a prediction over the samples `which` selects.
    pub fn of(p: &Prediction, run: &Run, which: Measured) -> ContourSummary {
        let mask = run.measured(which);
        let rows = p.figures(&mask).rows();
        ContourSummary {
            contour_um: rows.iter().map(|(_, k, f)| (*k, f.tip_um)).collect(),
            orientation_mrad: rows
                .iter()
                .map(|(_, k, f)| (*k, f.orientation_mrad))
                .collect(),
            samples: p.true_contour.tip_mm.len(),
            measured: match which {
                Measured::Feed => "feed",
                Measured::All => "all",
            },
            measured_samples: mask.iter().filter(|m| **m).count(),
            worst_blocks: p.worst_blocks(run, &mask, WORST_BLOCKS),
        }
    }
}

/// `summary.json` of `vcnc predict`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PredictSummary {
    /// The contour figures.
    #[serde(flatten)]
    pub contour: ContourSummary,
    /// Machine name.
    pub machine: String,
    /// Program path.
    pub program: String,
    /// Where the models come from (a file, or "identified on the fly").
    pub models: String,
    /// The actual-value latency stated per axis (axis letter → s) by which the models'
    /// positions were advanced (docs/drive-model.md#actual-value-latency); 0 for an axis
    /// without one.
    pub actual_latency_s: BTreeMap<String, f64>,
    /// Warnings of the run.
    pub warnings: Vec<String>,
}

impl PredictSummary {
    /// The summary of a prediction of `program` on `machine` with models from `models`,
    /// advanced by the per-axis `actual_latency_s` (in the machine's axis order).
    pub fn new(
        machine: &Machine,
        program: &str,
        contour: ContourSummary,
        models: String,
        actual_latency_s: &[f64],
        warnings: Vec<String>,
    ) -> PredictSummary {
        PredictSummary {
            contour,
            machine: machine.name.clone(),
            program: program.to_string(),
            models,
            actual_latency_s: machine
                .axes
                .iter()
                .zip(actual_latency_s)
                .map(|(a, l)| (a.name.to_string(), *l))
                .collect(),
            warnings,
        }
    }
}

/// Runs `run` through the true drives and through `models`, and evaluates both contour errors.
pub fn predict(machine: &Machine, run: &Run, models: &[DriveModel]) -> Result<Prediction, Error> {
    let mut all = predict_many(machine, run, &[models])?;
    Ok(all.remove(0))
}

/// [`contour`] as a prediction computes it: each actual pose is computed by the forward
/// kinematics, searched for and dropped (a long run never holds them), and no foot points
/// are kept (only the compensation, through [`contour`], needs them). Bit-identical to
/// [`contour`]'s errors: the same poses in the same order through the same search.
fn prediction_contour(
    machine: &Machine,
    path: &ContourPath,
    actual: &[&[f64]],
) -> Result<ContourReport, Error> {
    let kin = machine.require_kinematics()?;
    let n = actual.first().map_or(0, |p| p.len());
    let mut search = ContourSearch::new(path, &SearchWindow::default(), false, n)?;
    for k in 0..n {
        search.push(&kin.model.forward(&kin.axes.at(actual, k)))?;
    }
    Ok(search.finish()?)
}

/// Tool poses (mm, unit tool axis; workpiece frame) of axis positions given per machine axis
/// (mm, deg) at the samples `rows`, by the closed-form forward kinematics: a prediction keeps
/// axis positions, and its poses are computed a chunk at a time where they are written.
pub fn poses_at(
    machine: &Machine,
    axis_pos: &[&[f64]],
    rows: std::ops::Range<usize>,
) -> Result<Vec<Pose>, Error> {
    let kin = machine.require_kinematics()?;
    Ok(rows
        .map(|k| kin.model.forward(&kin.axes.at(axis_pos, k)))
        .collect())
}

/// [`predict`] for several model sets (for example the refined and the paper-PSO models) on
/// one run: the true drives, the costly half, are simulated and evaluated once and shared.
/// The models' positions are taken as the physical axes' (no actual-value latency:
/// [`predict_many_with_latency`]).
pub fn predict_many(
    machine: &Machine,
    run: &Run,
    model_sets: &[&[DriveModel]],
) -> Result<Vec<Prediction>, Error> {
    let sets: Vec<(&[DriveModel], &[f64])> = model_sets.iter().map(|m| (*m, &[][..])).collect();
    predict_many_with_latency(machine, run, &sets)
}

/// [`predict_many`] with each model set's stated actual-value latency (s, per machine axis;
/// empty: none): a model predicts the logged actual position, and the physical axis is that
/// prediction advanced by its latency ([`crate::latency`], docs/drive-model.md#actual-value-latency).
/// A set may appear twice with different latencies (with and without it stated).
pub fn predict_many_with_latency(
    machine: &Machine,
    run: &Run,
    model_sets: &[(&[DriveModel], &[f64])],
) -> Result<Vec<Prediction>, Error> {
    for (_, l) in model_sets {
        latency::check(l, run.axes.len())?;
    }
    let models: Vec<&[DriveModel]> = model_sets.iter().map(|(m, _)| *m).collect();
    let mut sims = simulate_all(machine, run, &models)?;
    advance_by_latency(&mut sims, model_sets, run.ts)?;
    contours(machine, run, sims, model_sets.len())
}

/// Each model set's positions (per axis, in `sims`) advanced by its stated latency.
fn advance_by_latency(
    sims: &mut [AxisSims],
    model_sets: &[(&[DriveModel], &[f64])],
    ts: f64,
) -> Result<(), Error> {
    for (set, (_, l)) in model_sets.iter().enumerate() {
        if l.iter().all(|t| *t == 0.0) {
            continue;
        }
        let logged: Vec<Vec<f64>> = sims
            .iter_mut()
            .map(|(_, m)| std::mem::take(&mut m[set]))
            .collect();
        let physical = latency::physical_positions(logged, l, ts)?;
        for ((_, m), x) in sims.iter_mut().zip(physical) {
            m[set] = x;
        }
    }
    Ok(())
}

/// [`predict`] for a run that is not needed whole afterwards: the reference velocities and
/// accelerations are dropped once the drives and models have been simulated
/// (`run.axes[i].vel` and `.acc` are left empty; the positions stay), so that a long run never
/// holds them next to the contour search's path and the contour errors
/// (docs/performance.md). With `actual_latency_s` (s, per machine axis; empty: none) the
/// models' positions are advanced by it, as [`predict_many_with_latency`] does; without, the
/// prediction is bit-identical to [`predict`]'s.
pub fn predict_releasing_rates(
    machine: &Machine,
    run: &mut Run,
    models: &[DriveModel],
    actual_latency_s: &[f64],
) -> Result<Prediction, Error> {
    latency::check(actual_latency_s, run.axes.len())?;
    let mut sims = simulate_all(machine, run, &[models])?;
    advance_by_latency(&mut sims, &[(models, actual_latency_s)], run.ts)?;
    for a in &mut run.axes {
        a.vel = Vec::new();
        a.acc = Vec::new();
    }
    let mut all = contours(machine, run, sims, 1)?;
    Ok(all.remove(0))
}

/// One axis simulated: the true drive's trace as a prediction keeps it, and the axis'
/// positions with each model set.
type AxisSims = (DriveTrace, Vec<Vec<f64>>);

/// Every axis through its true drive and through each model set, one task each (the true
/// drives, at the servo rate, are the costly ones), collected in axis order: per axis, the
/// true drive's trace as a prediction keeps it (its true position alone: the encoder reading,
/// velocity, control, motor position and torque are never logged; no output of a prediction
/// needs them, and on a long run they would be most of its memory, docs/performance.md) and
/// axis `i` of each model set's positions.
fn simulate_all(
    machine: &Machine,
    run: &Run,
    model_sets: &[&[DriveModel]],
) -> Result<Vec<AxisSims>, Error> {
    use rayon::prelude::*;
    if let Some(m) = model_sets.iter().find(|m| m.len() != run.axes.len()) {
        return Err(Error::Usage(format!(
            "{} models for {} axes",
            m.len(),
            run.axes.len()
        )));
    }
    let (axes, ts) = (run.axes.len().min(machine.axes.len()), run.ts);
    // The true drives that share a loop structure run several at a time in SIMD lanes
    // (vcnc_drive::batch: each trace bit for bit the drive's alone); a drive in no batch runs
    // alone, keeping its true position only.
    let jobs = crate::simulate::true_drive_jobs(machine, run);
    let groups = vcnc_drive::batch_groups(&jobs, ts);
    let truth_of = |t: (Vec<f64>, u64)| DriveTrace {
        true_position: t.0,
        saturated_ticks: t.1,
        ts,
        ..DriveTrace::default()
    };
    // Task t: true-drive group t (t < g), else axis u % axes of model set u / axes (u = t - g).
    let g = groups.len();
    let mut out = (0..g + axes * model_sets.len())
        .into_par_iter()
        .map(|t| match t.checked_sub(g) {
            None => {
                let group = &groups[t];
                let results = if let [i] = group[..] {
                    let (drive, r) = jobs[i];
                    vec![drive.simulate_true_position(r, ts).map(truth_of)]
                } else {
                    let sub: Vec<_> = group.iter().map(|i| jobs[*i]).collect();
                    vcnc_drive::simulate_batch(&sub, ts)
                        .into_iter()
                        .map(|r| r.map(|t| truth_of((t.true_position, t.saturated_ticks))))
                        .collect()
                };
                group
                    .iter()
                    .zip(results)
                    .map(|(i, r)| {
                        r.map(|trace| (*i, trace)).map_err(|source| Error::Drive {
                            axis: machine.axes[*i].name,
                            source,
                        })
                    })
                    .collect::<Result<Vec<(usize, DriveTrace)>, Error>>()
            }
            Some(u) => {
                let (i, set) = (u % axes, u / axes);
                simulate_model(&model_sets[set][i], &run.axes[i], ts).map(|x| {
                    vec![(
                        i,
                        DriveTrace {
                            true_position: x,
                            ts,
                            ..DriveTrace::default()
                        },
                    )]
                })
            }
        })
        .collect::<Result<Vec<Vec<(usize, DriveTrace)>>, Error>>()?
        .into_iter();
    let mut truth: Vec<Option<DriveTrace>> = (0..axes).map(|_| None).collect();
    for (i, trace) in out.by_ref().take(g).flatten() {
        truth[i] = Some(trace);
    }
    let truth: Vec<DriveTrace> = truth.into_iter().map(Option::unwrap_or_default).collect();
    let out = out.flatten().map(|(_, trace)| trace);
    let mut models: Vec<Vec<Vec<f64>>> = (0..axes).map(|_| Vec::new()).collect();
    for (t, m) in out.enumerate() {
        models[t % axes].push(m.true_position);
    }
    Ok(truth.into_iter().zip(models).collect())
}

/// The contour errors of the simulated axes (per axis: the true trace and each model set's
/// positions): the true machine's search and each model set's, in parallel, along one
/// reference path built once and shared.
fn contours(
    machine: &Machine,
    run: &Run,
    sims: Vec<AxisSims>,
    sets: usize,
) -> Result<Vec<Prediction>, Error> {
    use rayon::prelude::*;
    let mut true_traces = Vec::with_capacity(sims.len());
    let mut predicted: Vec<Vec<Vec<f64>>> = (0..sets).map(|_| Vec::new()).collect();
    for (t, models) in sims {
        true_traces.push(t);
        for (set, x) in predicted.iter_mut().zip(models) {
            set.push(x);
        }
    }
    let path = run.reference_path(machine)?;
    let mut positions: Vec<Vec<&[f64]>> = vec![
        true_traces
            .iter()
            .map(|t| t.true_position.as_slice())
            .collect(),
    ];
    positions.extend(
        predicted
            .iter()
            .map(|set| set.iter().map(Vec::as_slice).collect()),
    );
    let mut reports = positions
        .par_iter()
        .map(|pos| prediction_contour(machine, &path, pos))
        .collect::<Result<Vec<_>, Error>>()?
        .into_iter();
    drop(positions);
    drop(path);
    let mut true_contour = reports.next().expect("the true machine's report");
    let n = predicted.len();
    predicted
        .into_iter()
        .zip(reports)
        .enumerate()
        .map(|(i, (predicted, predicted_contour))| {
            // The last prediction takes the truth, the others a copy: one model set, no copy.
            let (true_traces, true_contour) = if i + 1 == n {
                (
                    std::mem::take(&mut true_traces),
                    std::mem::take(&mut true_contour),
                )
            } else {
                (true_traces.clone(), true_contour.clone())
            };
            Ok(Prediction {
                true_traces,
                predicted,
                true_contour,
                predicted_contour,
            })
        })
        .collect()
}

/// Models run on a program: axis positions, tool poses and contour errors.
#[derive(Debug, Clone)]
pub struct ModelRun {
    /// Axis positions per machine axis.
    pub positions: Vec<Vec<f64>>,
    /// Tool poses.
    pub poses: Vec<Pose>,
    /// Contour errors against the run's reference.
    pub contour: ContourReport,
}

/// The models' axis positions, poses and contour errors on `run`: the physical axes, each
/// model's positions advanced by its axis' stated actual-value latency (`actual_latency_s`, s,
/// per machine axis; empty: none; [`crate::latency`]).
pub fn model_contour(
    machine: &Machine,
    run: &Run,
    models: &[DriveModel],
    actual_latency_s: &[f64],
) -> Result<ModelRun, Error> {
    let positions =
        latency::physical_positions(simulate_models(models, run)?, actual_latency_s, run.ts)?;
    let pos: Vec<&[f64]> = positions.iter().map(Vec::as_slice).collect();
    let (poses, contour) = contour(machine, run, &pos)?;
    Ok(ModelRun {
        positions,
        poses,
        contour,
    })
}
