//! The pipeline (ARCHITECTURE.md): program → reference trajectory → (inverse kinematics) → axis
//! references → true drives and identified models → (forward kinematics) → tool poses → contour
//! errors; and, on the side, identification of each axis from its excitation run.
//!
//! Every function is deterministic: axes run in parallel (rayon) but results are collected in
//! axis order, and every random number comes from a seeded generator.

use rayon::prelude::*;
use vcnc_contour::{ContourReport, contour_errors};
use vcnc_drive::{ClosedLoopModel, DriveTrace, Reference, SimOptions};
use vcnc_gcode::{Diagnostic, IdentificationOptions, Loaded, Severity};
use vcnc_identify::{FitMetrics, Identification, Regressors, Trace, fit_metrics_with};
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{Axes, Pose, TcpMotion};

use vcnc_axis::AxisName;

use crate::file::Unit;
use crate::{Error, Machine};

const DEG: f64 = std::f64::consts::PI / 180.0;

/// Reference signals of one machine axis, at the sample period (axis units, units/s, units/s²).
#[derive(Debug, Clone, PartialEq)]
pub struct AxisSignals {
    /// The axis.
    pub name: AxisName,
    /// mm or deg.
    pub unit: Unit,
    /// Position.
    pub pos: Vec<f64>,
    /// Velocity (analytic, from the profile and the kinematics' derivatives).
    pub vel: Vec<f64>,
    /// Acceleration (analytic).
    pub acc: Vec<f64>,
}

impl AxisSignals {
    /// As a drive/model reference.
    pub fn reference(&self) -> Reference<'_> {
        Reference {
            pos: &self.pos,
            vel: &self.vel,
            acc: &self.acc,
        }
    }
}

/// A program prepared for a machine: interpolated, turned into axis references, checked against
/// travel.
#[derive(Debug, Clone)]
pub struct Run {
    /// The program's path (for messages).
    pub file: String,
    /// Parse tree, moves, trajectory and warnings.
    pub loaded: Loaded,
    /// Sample period, s.
    pub ts: f64,
    /// Axis references in machine order.
    pub axes: Vec<AxisSignals>,
    /// Reference tool poses in the workpiece frame (mm), when the machine has kinematics.
    pub poses: Option<Vec<Pose>>,
    /// Warnings for the user (G-code warnings, limit excursions of IK'd references).
    pub warnings: Vec<String>,
}

impl Run {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.axes.first().map_or(0, |a| a.pos.len())
    }

    /// True if the run has no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Time of sample k, s.
    pub fn time(&self, k: usize) -> f64 {
        k as f64 * self.ts
    }
}

/// Interpolates `src` (the program at `file`) on `machine` and prepares the axis references.
///
/// In TCP mode (G43.4) the trajectory carries the tool tip in the workpiece frame and the rotary
/// angles; inverse kinematics turns every sample into X Y Z with analytic velocity and
/// acceleration (chain rule, [`vcnc_kinematics::TableTiltingAc::inverse_tcp_motion`]). Every
/// sample is checked against the axis travels.
pub fn prepare(machine: &Machine, src: &str, file: &str, lenient: bool) -> Result<Run, Error> {
    let interp = machine.interp_options(lenient);
    let gcode_error = |e: vcnc_gcode::Error| match e {
        vcnc_gcode::Error::Program { diagnostics } => Error::Program {
            file: file.to_string(),
            diagnostics,
        },
        other => Error::Interpolation {
            file: file.to_string(),
            message: other.to_string(),
        },
    };
    let (program, toolpath, diags) =
        vcnc_gcode::parse_and_interpret(src, &interp).map_err(gcode_error)?;
    // Axes the program moves but the machine lacks: a clear error before interpolation.
    for m in &toolpath.moves {
        for (i, name) in AxisName::ALL.iter().enumerate() {
            if m.end[i] != m.start[i] && machine.axis(*name).is_none() {
                return Err(Error::Program {
                    file: file.to_string(),
                    diagnostics: vec![Diagnostic {
                        line: m.line,
                        col: m.col,
                        severity: Severity::Error,
                        kind: vcnc_gcode::DiagnosticKind::Motion,
                        message: format!(
                            "the program moves axis {name}, which machine \"{}\" does not have (axes: {})",
                            machine.name,
                            machine
                                .axis_names()
                                .iter()
                                .map(|a| a.as_str())
                                .collect::<String>()
                        ),
                    }],
                });
            }
        }
    }
    let loaded = vcnc_gcode::load_toolpath(
        program,
        toolpath,
        diags,
        &machine.limits(),
        &machine.interpolate_options(),
    )
    .map_err(gcode_error)?;
    let mut warnings: Vec<String> = loaded
        .warnings
        .iter()
        .map(|d| format!("{file}:{}:{}: warning: {}", d.line, d.col, d.message))
        .collect();
    let traj = &loaded.trajectory;
    let n = traj.len();
    let any_tcp = traj.tcp.iter().any(|t| *t);
    let track = |name: AxisName| traj.axis(name);
    let mut axes: Vec<AxisSignals> = machine
        .axes
        .iter()
        .map(|a| {
            let t = track(a.name);
            AxisSignals {
                name: a.name,
                unit: a.unit,
                pos: t.map_or_else(|| vec![0.0; n], |t| t.pos.clone()),
                vel: t.map_or_else(|| vec![0.0; n], |t| t.vel.clone()),
                acc: t.map_or_else(|| vec![0.0; n], |t| t.acc.clone()),
            }
        })
        .collect();
    if any_tcp {
        let kin = machine.kinematics_model()?;
        let idx = |c: AxisName| machine.axes.iter().position(|a| a.name == c);
        let (Some(ix), Some(iy), Some(iz), Some(ia), Some(ic)) = (
            idx(AxisName::X),
            idx(AxisName::Y),
            idx(AxisName::Z),
            idx(AxisName::A),
            idx(AxisName::C),
        ) else {
            return Err(Error::Kinematics {
                context: machine.source.clone(),
                message: "TCP mode needs axes X Y Z A C".into(),
            });
        };
        for k in 0..n {
            if !traj.tcp[k] {
                continue;
            }
            let v3 = |f: &dyn Fn(&AxisSignals) -> f64| {
                Vector3::new(f(&axes[ix]), f(&axes[iy]), f(&axes[iz]))
            };
            let m = TcpMotion {
                p_w: v3(&|s| s.pos[k]),
                p_w_dot: v3(&|s| s.vel[k]),
                p_w_ddot: v3(&|s| s.acc[k]),
                a: axes[ia].pos[k] * DEG,
                a_dot: axes[ia].vel[k] * DEG,
                a_ddot: axes[ia].acc[k] * DEG,
                c: axes[ic].pos[k] * DEG,
                c_dot: axes[ic].vel[k] * DEG,
                c_ddot: axes[ic].acc[k] * DEG,
            };
            let mm = kin.inverse_tcp_motion(&m);
            for (j, i) in [ix, iy, iz].into_iter().enumerate() {
                axes[i].pos[k] = mm.pm[j];
                axes[i].vel[k] = mm.pm_dot[j];
                axes[i].acc[k] = mm.pm_ddot[j];
            }
        }
    }
    // Travel, and limit excursions of kinematically transformed references (warnings).
    for (a, s) in machine.axes.iter().zip(&axes) {
        let [lo, hi] = a.travel;
        if let Some(k) = s.pos.iter().position(|v| !(*v >= lo && *v <= hi)) {
            let block = traj.block_at(k);
            let target = block
                .filter(|b| !b.tcp)
                .and_then(|b| run_moves_end(&loaded, b.move_index, a.name.index()));
            return Err(Error::Travel {
                file: file.to_string(),
                line: traj.block_at(k).map_or(0, |b| b.line),
                axis: a.name,
                value: s.pos[k],
                lower: lo,
                upper: hi,
                unit: a.unit.as_str(),
                t_s: k as f64 * traj.ts,
                target,
            });
        }
        if any_tcp {
            let vmax = s.vel.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let amax = s.acc.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if vmax > a.max_velocity * (1.0 + 1e-9) {
                warnings.push(format!(
                    "{file}: warning: axis {} reference reaches {vmax:.1} {}/s, above its velocity limit {} {}/s",
                    a.name,
                    a.unit.as_str(),
                    a.max_velocity,
                    a.unit.as_str()
                ));
            }
            if amax > a.max_acceleration * (1.0 + 1e-9) {
                warnings.push(format!(
                    "{file}: warning: axis {} reference reaches {amax:.1} {}/s², above its acceleration limit {} {}/s²",
                    a.name,
                    a.unit.as_str(),
                    a.max_acceleration,
                    a.unit.as_str()
                ));
            }
        }
    }
    let poses = match machine.kinematics.as_ref() {
        Some(_) => Some(forward_poses(
            machine,
            &axes.iter().map(|a| a.pos.as_slice()).collect::<Vec<_>>(),
        )?),
        None => None,
    };
    Ok(Run {
        file: file.to_string(),
        ts: traj.ts,
        loaded,
        axes,
        poses,
        warnings,
    })
}

/// Programmed end of axis `i` of move `index`.
fn run_moves_end(loaded: &Loaded, index: usize, i: usize) -> Option<f64> {
    loaded.toolpath.moves.get(index).map(|m| m.end[i])
}

/// Tool poses in the workpiece frame (mm, unit tool axis) of axis positions given per machine
/// axis (mm, deg), by the closed-form forward kinematics.
pub fn forward_poses(machine: &Machine, axis_pos: &[&[f64]]) -> Result<Vec<Pose>, Error> {
    let kin = machine.kinematics_model()?;
    let idx = |c: AxisName| machine.axes.iter().position(|a| a.name == c);
    let (Some(ix), Some(iy), Some(iz), Some(ia), Some(ic)) = (
        idx(AxisName::X),
        idx(AxisName::Y),
        idx(AxisName::Z),
        idx(AxisName::A),
        idx(AxisName::C),
    ) else {
        return Err(Error::Kinematics {
            context: machine.source.clone(),
            message: "forward kinematics needs axes X Y Z A C".into(),
        });
    };
    let n = axis_pos.first().map_or(0, |p| p.len());
    Ok((0..n)
        .map(|k| {
            kin.forward(&Axes::new(
                axis_pos[ix][k],
                axis_pos[iy][k],
                axis_pos[iz][k],
                axis_pos[ia][k] * DEG,
                axis_pos[ic][k] * DEG,
            ))
        })
        .collect())
}

/// Runs every axis reference through its true drive (axes in parallel, results in axis order).
pub fn simulate_true(machine: &Machine, run: &Run) -> Result<Vec<DriveTrace>, Error> {
    machine
        .axes
        .par_iter()
        .zip(run.axes.par_iter())
        .map(|(axis, s)| {
            axis.drive.simulate(s.reference(), run.ts).map_err(|e| {
                Error::Runtime(format!("axis {}: drive simulation failed: {e}", axis.name))
            })
        })
        .collect()
}

/// Runs every axis reference through a closed-loop model (one per machine axis, in order).
pub fn simulate_models(models: &[ClosedLoopModel], run: &Run) -> Result<Vec<Vec<f64>>, Error> {
    if models.len() != run.axes.len() {
        return Err(Error::Runtime(format!(
            "{} models for {} axes",
            models.len(),
            run.axes.len()
        )));
    }
    models
        .par_iter()
        .zip(run.axes.par_iter())
        .map(|(m, s)| {
            m.simulate(s.reference(), run.ts, &SimOptions::default())
                .map_err(|e| {
                    Error::Runtime(format!("axis {}: model simulation failed: {e}", s.name))
                })
        })
        .collect()
}

/// Contour errors of actual axis positions against the run's reference poses.
pub fn contour(
    machine: &Machine,
    run: &Run,
    actual: &[&[f64]],
) -> Result<(Vec<Pose>, ContourReport), Error> {
    let reference = run.poses.as_ref().ok_or_else(|| Error::Kinematics {
        context: machine.source.clone(),
        message: "contour errors need the machine's kinematics".into(),
    })?;
    let poses = forward_poses(machine, actual)?;
    let report = contour_errors(reference, &poses)
        .map_err(|e| Error::Runtime(format!("contour error evaluation failed: {e}")))?;
    Ok((poses, report))
}

/// Tool-tip and orientation contour errors with the true and the predicted drives.
#[derive(Debug, Clone)]
pub struct Prediction {
    /// True drives: encoder traces per axis.
    pub true_traces: Vec<DriveTrace>,
    /// Identified models: positions per axis.
    pub predicted: Vec<Vec<f64>>,
    /// Tool poses with the true drives.
    pub true_poses: Vec<Pose>,
    /// Tool poses with the identified models.
    pub predicted_poses: Vec<Pose>,
    /// Contour errors with the true drives.
    pub true_contour: ContourReport,
    /// Contour errors with the identified models.
    pub predicted_contour: ContourReport,
}

impl Prediction {
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
}

/// Runs `run` through the true drives and through `models`, and evaluates both contour errors.
pub fn predict(
    machine: &Machine,
    run: &Run,
    models: &[ClosedLoopModel],
) -> Result<Prediction, Error> {
    let mut all = predict_many(machine, run, &[models])?;
    Ok(all.remove(0))
}

/// [`predict`] for several model sets (for example the refined and the paper-PSO models) on
/// one run: the true drives, the costly half, are simulated and evaluated once and shared.
pub fn predict_many(
    machine: &Machine,
    run: &Run,
    model_sets: &[&[ClosedLoopModel]],
) -> Result<Vec<Prediction>, Error> {
    let truth = || -> Result<_, Error> {
        let traces = simulate_true(machine, run)?;
        let pos: Vec<&[f64]> = traces.iter().map(|t| t.true_position.as_slice()).collect();
        let (poses, report) = contour(machine, run, &pos)?;
        Ok((traces, poses, report))
    };
    let model_half = |models: &[ClosedLoopModel]| -> Result<_, Error> {
        let predicted = simulate_models(models, run)?;
        let pos: Vec<&[f64]> = predicted.iter().map(Vec::as_slice).collect();
        let (poses, report) = contour(machine, run, &pos)?;
        Ok((predicted, poses, report))
    };
    let (truth, halves) = rayon::join(truth, || {
        model_sets
            .par_iter()
            .map(|m| model_half(m))
            .collect::<Vec<_>>()
    });
    let (true_traces, true_poses, true_contour) = truth?;
    halves
        .into_iter()
        .map(|h| {
            let (predicted, predicted_poses, predicted_contour) = h?;
            Ok(Prediction {
                true_traces: true_traces.clone(),
                predicted,
                true_poses: true_poses.clone(),
                predicted_poses,
                true_contour: true_contour.clone(),
                predicted_contour,
            })
        })
        .collect()
}

/// The excitation run of one axis: program text, reference and true-drive trace.
#[derive(Debug, Clone)]
pub struct ExcitationRun {
    /// The generated G-code.
    pub program: String,
    /// Reference signals of the axis (centre offset applied).
    pub reference: AxisSignals,
    /// The true drive's response.
    pub trace: DriveTrace,
}

impl ExcitationRun {
    /// The identification trace: reference and encoder position, with the interpolator's exact
    /// reference velocity and acceleration attached (a simulated machine knows them; a measured
    /// trace falls back to central differences, which smear the acceleration steps of the
    /// trapezoids and cost accuracy when $b_0 \ne 0$).
    pub fn identification_trace(&self) -> Result<Trace, Error> {
        let err = |e: vcnc_identify::Error| Error::Identify {
            axis: self.reference.name.to_string(),
            message: e.to_string(),
            bad_input: true,
        };
        Trace::new(
            self.trace.ts,
            self.reference.pos.clone(),
            self.trace.position.clone(),
        )
        .and_then(|t| {
            t.with_reference_derivatives(self.reference.vel.clone(), self.reference.acc.clone())
        })
        .map_err(err)
    }
}

/// Generates the axis' identification program with `seed`, interpolates it and runs it through
/// the true drive.
pub fn excitation_run(
    machine: &Machine,
    axis: AxisName,
    seed: u64,
) -> Result<ExcitationRun, Error> {
    let a = machine.axis(axis).ok_or_else(|| Error::Invalid {
        file: machine.source.clone(),
        at: None,
        key: format!("axes.{axis}"),
        message: format!("machine \"{}\" has no axis {axis}", machine.name),
    })?;
    let p = &machine.program;
    let opts = IdentificationOptions {
        moves: p.moves,
        range: a.identification_range,
        max_feed: p.max_feed,
        min_feed: p.min_feed,
        seed,
        ..IdentificationOptions::default()
    };
    let program = vcnc_gcode::identification(a.name, &opts).map_err(|e| Error::Invalid {
        file: machine.source.clone(),
        at: None,
        key: "identification.program".into(),
        message: e.to_string(),
    })?;
    let name = format!("<identification program of axis {} (seed {seed})>", a.name);
    let mut iopts = machine.interpolate_options();
    iopts.axes = Some(vec![a.name]);
    let mut limits = machine.limits();
    if let Some(acc) = p.max_acceleration {
        for l in limits.axes.iter_mut() {
            l.max_acc = l.max_acc.min(acc);
        }
    }
    let loaded = vcnc_gcode::load(&program, &machine.interp_options(false), &limits, &iopts)
        .map_err(|e| Error::Interpolation {
            file: name.clone(),
            message: e.to_string(),
        })?;
    let track = loaded
        .trajectory
        .axis(a.name)
        .ok_or_else(|| Error::Runtime(format!("{name}: no track")))?;
    let reference = AxisSignals {
        name: a.name,
        unit: a.unit,
        pos: track
            .pos
            .iter()
            .map(|v| v + a.identification_centre)
            .collect(),
        vel: track.vel.clone(),
        acc: track.acc.clone(),
    };
    let trace = a
        .drive
        .simulate(reference.reference(), machine.ts)
        .map_err(|e| Error::Runtime(format!("axis {}: drive simulation failed: {e}", a.name)))?;
    Ok(ExcitationRun {
        program,
        reference,
        trace,
    })
}

/// Identification of one axis of a simulated machine, with validation.
#[derive(Debug, Clone)]
pub struct AxisIdentification {
    /// The axis.
    pub axis: AxisName,
    /// mm or deg.
    pub unit: Unit,
    /// The analytic model of the true drive.
    pub truth: ClosedLoopModel,
    /// Everything the identifier produced (refined, paper PSO, LS baseline, history, fits).
    pub result: Identification,
    /// Free-run fit of the refined model on the validation run.
    pub validation: FitMetrics,
    /// Free-run fit of the paper-method (PSO) model on the validation run.
    pub validation_paper: FitMetrics,
    /// The estimation run.
    pub estimation_run: ExcitationRun,
    /// The validation run.
    pub validation_run: ExcitationRun,
}

/// Identifies one axis: estimation run (program seed), identification, validation run
/// (validation seed).
pub fn identify_axis(
    machine: &Machine,
    axis: AxisName,
    seed: Option<u64>,
) -> Result<AxisIdentification, Error> {
    let a = machine.axis(axis).ok_or_else(|| Error::Invalid {
        file: machine.source.clone(),
        at: None,
        key: format!("axes.{axis}"),
        message: format!("machine \"{}\" has no axis {axis}", machine.name),
    })?;
    let program_seed = seed.unwrap_or(machine.program.seed);
    let validation_seed = match seed {
        Some(s) => s.wrapping_add(
            machine
                .program
                .validation_seed
                .wrapping_sub(machine.program.seed)
                .max(1),
        ),
        None => machine.program.validation_seed,
    };
    let mut opts = machine.identify.clone();
    if let Some(s) = seed {
        opts.seed = s;
    }
    let (est, val) = rayon::join(
        || excitation_run(machine, a.name, program_seed),
        || excitation_run(machine, a.name, validation_seed),
    );
    let (est, val) = (est?, val?);
    let trace = est.identification_trace()?;
    let result = vcnc_identify::identify(&trace, &opts).map_err(|e| identify_error(a.name, e))?;
    let vtrace = val.identification_trace()?;
    // One regressor pass over the validation run serves both models.
    let regs = Regressors::build(&vtrace, &opts).map_err(|e| identify_error(a.name, e))?;
    let validation = fit_metrics_with(&result.identified, &vtrace, &regs)
        .map_err(|e| identify_error(a.name, e))?;
    let validation_paper = fit_metrics_with(&result.paper_pso, &vtrace, &regs)
        .map_err(|e| identify_error(a.name, e))?;
    Ok(AxisIdentification {
        axis: a.name,
        unit: a.unit,
        truth: a.true_model(),
        result,
        validation,
        validation_paper,
        estimation_run: est,
        validation_run: val,
    })
}

/// Identifies several axes in parallel (results in the order given).
pub fn identify_axes(
    machine: &Machine,
    axes: &[AxisName],
    seed: Option<u64>,
) -> Result<Vec<AxisIdentification>, Error> {
    axes.par_iter()
        .map(|a| identify_axis(machine, *a, seed))
        .collect()
}

/// Maps an identification error, telling bad data from numerical failure.
pub fn identify_error(axis: impl std::fmt::Display, e: vcnc_identify::Error) -> Error {
    Error::Identify {
        axis: axis.to_string(),
        message: e.to_string(),
        bad_input: true,
    }
}
