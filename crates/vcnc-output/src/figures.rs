//! The figures of each kind of result, drawn by vcnc-report in its one style and listed in the
//! run's report: identification (frequency responses, PSO convergence, validation), prediction
//! (the tool-tip path coloured by contour error, the errors along it, tracking errors),
//! simulation (tracking errors), frequency responses and sweeps.
//!
//! Every curve gets the role of what it is — true machine, measurement, vcnc model, paper's
//! method — with the same legend label in every command ([`TRUE_MACHINE`] …), so a role has one
//! colour and one name across all reports. Errors are drawn in µm (linear axes), mdeg (rotary
//! axes) and mrad (orientation), every axis names its quantity.

use vcnc_pipeline::frf::{BodeData, standard_freqs};
use vcnc_pipeline::stats::{scaled_diff, scaled_diff_max_rms};
use vcnc_pipeline::sweep::SweepOutcome;
use vcnc_pipeline::{
    AxisIdentification, AxisName, AxisTracking, DriveModel, Frf, IdentificationSource, Machine,
    Measured, PredictPiece, PredictionRecord, ReferenceChunk, SimulatePiece, Sink, Unit,
};
pub use vcnc_report::Role;
use vcnc_report::style::units;
use vcnc_report::vtp::{PointScalars, Vectors, VtpEncoding, VtpPath, write_vtp};
use vcnc_report::{
    self as vr, Axis, AxisErrors, BodeCurve, BodeGroup, ColouredPath, Comparison, HeatMap, Mark,
    PathErrors, PathViewOptions, Quantity, Series,
};

use crate::Result;
use crate::files::write_csv;
use crate::report::RunReport;

/// Legend label of the true machine (the simulated plant, the truth of a virtual experiment).
pub const TRUE_MACHINE: &str = "true machine";
/// Legend label of a measured trace.
pub const MEASUREMENT: &str = "measurement";
/// Legend label of vcnc's identified model (refined).
pub const VCNC_MODEL: &str = "vcnc model";
/// Legend label of the paper's method (equation-error PSO alone).
pub const PAPER: &str = "paper's method";

/// How many of the worst blocks the contour figures mark.
const WORST_BLOCKS: usize = 5;

/// The 3-D export of a prediction (VTK PolyData).
pub const TOOLPATH_VTP: &str = "toolpath.vtp";

/// Section headings of the reports.
pub mod section {
    /// Identification figures.
    pub const IDENTIFICATION: &str = "Identification";
    /// Contour-error figures.
    pub const CONTOUR: &str = "Contour errors";
    /// Tracking-error figures.
    pub const TRACKING: &str = "Tracking errors";
    /// Frequency responses.
    pub const FRF: &str = "Frequency responses";
    /// Sweep results.
    pub const SWEEP: &str = "Sweep";
}

/// The file name of a program for titles (`spiral.ngc`).
pub fn program_name(file: &str) -> &str {
    file.rsplit(['/', '\\']).next().unwrap_or(file)
}

fn times(n: usize, ts: f64) -> Vec<f64> {
    (0..n).map(|k| k as f64 * ts).collect()
}

/// One model in a frequency-response file and figure: its column tag in the CSV (the CSV's
/// contract, docs/cli.md), its legend label and role.
pub struct FrfModel<'a> {
    /// Column tag in `frf_<AXIS>.csv` (`true`, `identified`, `paper_PSO`, `model`).
    pub tag: &'a str,
    /// Legend label.
    pub label: &'a str,
    /// Role of the curve.
    pub role: Role,
    /// The model.
    pub model: DriveModel,
}

/// A measured frequency response drawn beside the models' (tracking group only).
pub struct MeasuredFrf<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Role of the curve.
    pub role: Role,
    /// The response (its lines need not be the models' frequencies).
    pub frf: &'a Frf,
}

/// Writes `<prefix>.csv` (tracking and disturbance Bode data of each model) into the report's
/// folder and adds `<prefix>.svg`: magnitude and phase of both responses over a log frequency
/// axis.
pub fn frf(
    report: &mut RunReport,
    prefix: &str,
    axis: AxisName,
    models: &[FrfModel],
    section: &str,
) -> Result<()> {
    frf_with_measured(report, prefix, axis, models, None, section)
}

/// [`frf`] with a measured tracking response too: its curve in the tracking panels, and three
/// columns appended to `<prefix>.csv` — `measured_f_hz`, `measured_track_mag_db`,
/// `measured_track_phase_deg`, one row per measured line (empty below the last line: the lines
/// are the multisine's, not the models' grid).
pub fn frf_with_measured(
    report: &mut RunReport,
    prefix: &str,
    axis: AxisName,
    models: &[FrfModel],
    measured: Option<MeasuredFrf>,
    section: &str,
) -> Result<()> {
    let freqs = standard_freqs();
    let data: Vec<BodeData> = models
        .iter()
        .map(|m| BodeData::of(&m.model, &freqs))
        .collect();
    let measured_db: Vec<f64> = measured
        .as_ref()
        .map(|m| m.frf.magnitude.iter().map(|g| 20.0 * g.log10()).collect())
        .unwrap_or_default();
    let mut header = vec!["f_hz".to_string()];
    let mut cols: Vec<&[f64]> = vec![&freqs];
    for (m, d) in models.iter().zip(&data) {
        for (suffix, col) in [
            ("track_mag_db", &d.track_mag),
            ("track_phase_deg", &d.track_phase),
            ("dist_mag_db", &d.dist_mag),
            ("dist_phase_deg", &d.dist_phase),
        ] {
            header.push(format!("{}_{suffix}", m.tag));
            cols.push(col);
        }
    }
    if let Some(m) = &measured {
        header.extend(
            [
                "measured_f_hz",
                "measured_track_mag_db",
                "measured_track_phase_deg",
            ]
            .map(String::from),
        );
        cols.extend([
            m.frf.freq_hz.as_slice(),
            measured_db.as_slice(),
            m.frf.phase_deg.as_slice(),
        ]);
    }
    write_csv(&report.dir().join(format!("{prefix}.csv")), &header, &cols)?;
    let group = |name: &str, pick: fn(&BodeData) -> (&Vec<f64>, &Vec<f64>)| BodeGroup {
        name: name.to_string(),
        curves: models
            .iter()
            .zip(&data)
            .map(|(m, d)| {
                let (mag, phase) = pick(d);
                BodeCurve {
                    label: m.label.to_string(),
                    role: m.role,
                    freq_hz: &freqs,
                    mag_db: mag,
                    phase_deg: phase,
                }
            })
            .collect(),
    };
    let mut tracking = group("tracking x/x_r", |d| (&d.track_mag, &d.track_phase));
    if let Some(m) = &measured {
        // Drawn first: the measurement under the models.
        tracking.curves.insert(
            0,
            BodeCurve {
                label: m.label.to_string(),
                role: m.role,
                freq_hz: &m.frf.freq_hz,
                mag_db: &measured_db,
                phase_deg: &m.frf.phase_deg,
            },
        );
    }
    let groups = [
        tracking,
        group("disturbance x/d (d: acceleration)", |d| {
            (&d.dist_mag, &d.dist_phase)
        }),
    ];
    let mut names: Vec<&str> = models.iter().map(|m| m.label).collect();
    if let Some(m) = &measured {
        names.push(m.label);
    }
    report.figure(
        &format!("{prefix}.svg"),
        vr::bode(
            &format!("axis {axis}: closed-loop frequency responses"),
            &groups,
        ),
        &format!(
            "Axis {axis}: tracking response x/x_r and disturbance response x/d (d an \
             acceleration), magnitude and phase, of the {}. Data in {prefix}.csv.",
            names.join(", the ")
        ),
        section,
    )
}

/// The truth of an identification: the true machine for a simulated axis, the measurement for
/// a trace.
fn truth_of(r: &AxisIdentification) -> (&'static str, Role) {
    match r.source {
        IdentificationSource::Simulated { .. } => (TRUE_MACHINE, Role::TrueMachine),
        IdentificationSource::Measured { .. } => (MEASUREMENT, Role::Measurement),
    }
}

/// The figures of one identified axis, written into the report's folder: `frf_<AXIS>.csv` and
/// `.svg` (true machine when known, vcnc model, paper's method), `pso_<AXIS>.svg` (the swarm's
/// convergence), `validation_<AXIS>.svg` (tracking error measured and predicted, and the
/// difference).
pub fn identification(report: &mut RunReport, r: &AxisIdentification) -> Result<()> {
    let a = r.axis;
    let mut models = Vec::new();
    if let Some(t) = r.truth() {
        models.push(FrfModel {
            tag: "true",
            label: TRUE_MACHINE,
            role: Role::TrueMachine,
            model: DriveModel::from(*t),
        });
    }
    models.push(FrfModel {
        tag: "identified",
        label: VCNC_MODEL,
        role: Role::Model,
        model: r.result.model,
    });
    models.push(FrfModel {
        tag: "paper_PSO",
        label: PAPER,
        role: Role::Paper,
        model: DriveModel::from(r.result.paper_pso),
    });
    frf(
        report,
        &format!("frf_{a}"),
        a,
        &models,
        section::IDENTIFICATION,
    )?;
    convergence(report, r)?;
    validation(report, r)
}

fn convergence(report: &mut RunReport, r: &AxisIdentification) -> Result<()> {
    let h = &r.result.pso_history;
    let it: Vec<f64> = h.iter().map(|e| e.iteration as f64).collect();
    let best: Vec<f64> = h.iter().map(|e| e.best_cost).collect();
    let mean: Vec<f64> = h.iter().map(|e| e.mean_cost).collect();
    let unit = format!("{}²", r.unit.as_str());
    report.figure(
        &format!("pso_{}.svg", r.axis),
        vr::convergence(
            &format!(
                "axis {}: PSO convergence (the paper's method, equation-error cost)",
                r.axis
            ),
            &Quantity::new("equation-error cost", unit),
            &[
                Series::line("global best", Role::Other(0), &it, &best),
                Series::line("swarm mean", Role::Other(1), &it, &mean),
            ],
        ),
        &format!(
            "Axis {}: cost of the swarm's best particle and the swarm's mean cost at each \
             iteration of the stability-constrained PSO (paper section 3), log scale. The vcnc \
             model refines the swarm's best by output-error minimisation (docs/identification.md).",
            r.axis
        ),
        section::IDENTIFICATION,
    )
}

fn validation(report: &mut RunReport, r: &AxisIdentification) -> Result<()> {
    let trace = &r.validation_trace;
    let (k, u) = (r.unit.micro_factor(), r.unit.micro_symbol());
    let t = times(trace.len(), trace.ts);
    let measured = scaled_diff(&trace.xr, &trace.x, k);
    let model = scaled_diff(&trace.xr, &r.validation.predicted_x, k);
    let paper = scaled_diff(&trace.xr, &r.validation_paper.predicted_x, k);
    let (truth, role) = truth_of(r);
    let (title, what) = match r.source {
        IdentificationSource::Simulated { .. } => (
            format!("axis {}: validation run", r.axis),
            "the validation run (a second excitation program, not used to identify)",
        ),
        IdentificationSource::Measured { .. } => (
            format!("axis {}: fit on the measured trace", r.axis),
            "the measured trace (the one run there is)",
        ),
    };
    let note = format!(
        "free-run error RMS / max: {VCNC_MODEL} {:.3} / {:.3} {u}, {PAPER} {:.3} / {:.3} {u}",
        r.validation.freerun_rms * k,
        r.validation.freerun_max * k,
        r.validation_paper.freerun_rms * k,
        r.validation_paper.freerun_max * k,
    );
    report.figure(
        &format!("validation_{}.svg", r.axis),
        vr::comparison_figure(
            &title,
            &note,
            Axis::linear("time t", units::S),
            &[Comparison {
                title: None,
                y: Axis::linear("tracking error x_r − x", u),
                truth: Series::line(truth, role, &t, &measured),
                others: vec![
                    Series::line(VCNC_MODEL, Role::Model, &t, &model),
                    Series::line(PAPER, Role::Paper, &t, &paper),
                ],
                difference: Some(Quantity::new(format!("model − {truth}"), u)),
            }],
            Vec::new(),
        ),
        &format!(
            "Axis {}: tracking error x_r − x on {what}, of the {truth} and as the models predict \
             it in free run; below, each model's tracking error minus the {truth}'s.",
            r.axis
        ),
        section::IDENTIFICATION,
    )
}

/// `validation_<AXIS>.svg` of `vcnc validate`: the measured tracking error and the model's
/// free-run prediction of it on a trace it was not fitted on, and the residual below.
pub fn validation_measured(
    report: &mut RunReport,
    v: &vcnc_pipeline::validate::AxisValidation,
) -> Result<()> {
    let trace = &v.trace;
    let (k, u) = (v.unit.micro_factor(), v.unit.micro_symbol());
    let t = times(trace.len(), trace.ts);
    let measured = scaled_diff(&trace.xr, &trace.x, k);
    let model = scaled_diff(&trace.xr, &v.fit.predicted_x, k);
    let note = format!(
        "free-run error RMS / max {:.3} / {:.3} {u}, fit {:.2} %, tracking error RMS {:.3} {u}",
        v.fit.freerun_rms * k,
        v.fit.freerun_max * k,
        v.fit.fit_percent,
        v.fit.tracking_rms * k,
    );
    report.figure(
        &format!("validation_{}.svg", v.axis),
        vr::comparison_figure(
            &format!("axis {}: model on the measured trace", v.axis),
            &note,
            Axis::linear("time t", units::S),
            &[Comparison {
                title: None,
                y: Axis::linear("tracking error x_r − x", u),
                truth: Series::line(MEASUREMENT, Role::Measurement, &t, &measured),
                others: vec![Series::line(VCNC_MODEL, Role::Model, &t, &model)],
                difference: Some(Quantity::new(format!("model − {MEASUREMENT}"), u)),
            }],
            Vec::new(),
        ),
        &format!(
            "Axis {}: tracking error x_r − x measured, and as the model predicts it in free run \
             from the nominal position alone; below, the residual (model − measurement).",
            v.axis
        ),
        section::IDENTIFICATION,
    )
}

/// Tracking errors x_r − x of the axes the program moves: the truth (`tracking[i].error`) and
/// each model (`model_error` of each list); `reference` holds each axis' reference positions
/// (sample period `ts`).
pub fn tracking(
    report: &mut RunReport,
    file: &str,
    (program, ts, reference): (&str, f64, &[Vec<f64>]),
    truth: (&str, Role),
    models: &[(&str, Role, &[AxisTracking])],
    caption: &str,
) -> Result<()> {
    let Some(&(_, _, first)) = models.first() else {
        return Ok(());
    };
    let t = times(reference.first().map_or(0, Vec::len), ts);
    let axes: Vec<AxisErrors> = first
        .iter()
        .enumerate()
        .map(|(i, a)| AxisErrors {
            axis: a.axis,
            reference: &reference[i],
            truth: Series::line(truth.0, truth.1, &t, &a.error),
            models: models
                .iter()
                .filter_map(|(label, role, tr)| {
                    tr.get(i)
                        .and_then(|m| m.model_error.as_deref())
                        .map(|e| Series::line(*label, *role, &t, e))
                })
                .collect(),
        })
        .collect();
    report.figure(
        file,
        vr::tracking_errors(
            &format!(
                "{}: tracking errors x_r − x per axis",
                program_name(program)
            ),
            &axes,
        ),
        caption,
        section::TRACKING,
    )
}

/// `tracking.svg` of a simulation, every sample: the true drives (encoder) and, when
/// simulated, the model (`reference`: each axis' reference positions).
pub fn simulation_tracking(
    report: &mut RunReport,
    (program, ts, reference): (&str, f64, &[Vec<f64>]),
    tr: &[AxisTracking],
) -> Result<()> {
    let has_model = tr.iter().any(|a| a.model_error.is_some());
    tracking(
        report,
        "tracking.svg",
        (program, ts, reference),
        (TRUE_MACHINE, Role::TrueMachine),
        &[(VCNC_MODEL, Role::Model, tr)],
        if has_model {
            "Tracking error x_r − x of each axis the program moves: the true drive (encoder \
             reading) and the identified model; below each, model − true machine."
        } else {
            "Tracking error x_r − x of each axis the program moves, true drive (encoder reading)."
        },
    )
}

/// One axis of the reference figure: its velocity at the times `t` (every sample, or a
/// streamed run's min/max envelope).
pub struct ReferenceAxis<'a> {
    /// The axis.
    pub name: AxisName,
    /// mm or deg.
    pub unit: Unit,
    /// The program moves it (else it is listed, not drawn).
    pub moved: bool,
    /// Times, s.
    pub t: &'a [f64],
    /// Velocity, units/s.
    pub vel: &'a [f64],
}

/// `reference.svg`: the velocity of each moved axis.
pub fn reference_axes(
    report: &mut RunReport,
    file: &str,
    axes: &[ReferenceAxis<'_>],
) -> Result<()> {
    let (moved, still): (Vec<_>, Vec<_>) = axes.iter().partition(|a| a.moved);
    let panels: Vec<vr::Panel> = moved
        .iter()
        .map(|a| {
            vr::Panel::new(
                Axis::linear(
                    format!("{} velocity", a.name),
                    format!("{}/s", a.unit.as_str()),
                ),
                vec![Series::line("reference", Role::Reference, a.t, a.vel)],
            )
        })
        .collect();
    let mut fig = vr::LineFigure::new(
        format!("{}: reference velocity per axis", program_name(file)),
        Axis::linear("time t", units::S),
        panels,
    );
    fig.note = still_note(still.iter().map(|a| a.name));
    report.figure(
        "reference.svg",
        vr::line_figure(&fig),
        "Velocity of the reference of each axis the program moves, as interpolated at the sample \
         period (trapezoidal profiles, look-ahead, and in tool-centre-point mode the inverse \
         kinematics).",
        "Reference",
    )
}

/// Points as `[x, y, z]` per sample.
type Points = Vec<[f64; 3]>;

/// Tool tips (mm) of the path of `pos` (axis positions per machine axis).
fn tips(machine: &Machine, pos: &[&[f64]], n: usize) -> Result<Points> {
    let kin = machine.require_kinematics()?;
    Ok((0..n)
        .map(|k| {
            let q = kin.pose_at(pos, k);
            [q.p.x, q.p.y, q.p.z]
        })
        .collect())
}

/// `v` scaled by `k` in place (mm → µm, rad → mrad), taken out of its owner.
fn scaled_in_place(v: &mut Vec<f64>, k: f64) -> Vec<f64> {
    let mut v = std::mem::take(v);
    v.iter_mut().for_each(|x| *x *= k);
    v
}

/// A model set of a prediction as the figures label it.
#[derive(Debug, Clone, Copy)]
pub struct ModelLabel<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Role.
    pub role: Role,
}

/// Which of a prediction's outputs [`prediction`] makes from its record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PredictionDrawing {
    /// The SVG figures (`toolpath_contour.svg`, `tracking_errors.svg`).
    pub figures: bool,
    /// `contour_error.svg` from the record (off where [`ContourEnvelopes`] draw it from every
    /// sample while the record keeps every N-th).
    pub along_path: bool,
    /// `toolpath.vtp`.
    pub vtp: bool,
}

impl Default for PredictionDrawing {
    fn default() -> PredictionDrawing {
        PredictionDrawing {
            figures: true,
            along_path: true,
            vtp: true,
        }
    }
}

/// The figures and the 3-D export of a prediction, models first to last as given (the first
/// is the vcnc model; the demo adds the paper's method):
/// - `toolpath_contour.svg`: the true machine's tool-tip path in 3-D (isometric view and the
///   two best projections) coloured by its contour error on a scale clipped at the 99.5th
///   percentile, the worst blocks marked by their G-code lines;
/// - `contour_error.svg`: contour error and orientation error against the arc length of the
///   reference path, with model − true machine under each;
/// - `tracking_errors.svg`: the axes the program moves;
/// - `toolpath.vtp`: the path with both errors, the tool axis and the block lines (ParaView).
///
/// `measured` selects the samples whose blocks may be marked as worst (feed moves unless
/// `--include-rapids`); `labels` names the record's model sets, in order. The record is
/// consumed: each series is computed in the memory of the one it comes from, so that a long
/// run's figures cost little beyond its prediction (docs/performance.md).
pub fn prediction(
    report: &mut RunReport,
    machine: &Machine,
    (program, ts): (&str, f64),
    mut record: PredictionRecord,
    measured: &[bool],
    labels: &[ModelLabel<'_>],
    draw: &PredictionDrawing,
) -> Result<()> {
    if record.models.is_empty() {
        return Ok(());
    }
    let name = program_name(program);
    let n = record.len();
    // The true machine's errors in µm and mrad, and its tool tips by the forward kinematics
    // (a prediction keeps axis positions, not poses).
    let tip_t = scaled_in_place(&mut record.truth.tip_mm, 1e3);
    let or_t = scaled_in_place(&mut record.truth.orientation_rad, 1e3);
    let true_tip = tips(machine, &record.truth.positions(), n)?;
    let (tip_m, or_m): (Vec<Vec<f64>>, Vec<Vec<f64>>) = record
        .models
        .iter_mut()
        .map(|m| {
            (
                scaled_in_place(&mut m.tip_mm, 1e3),
                scaled_in_place(&mut m.orientation_rad, 1e3),
            )
        })
        .unzip();
    {
        // The figures draw the samples the statistics cover (feed moves unless
        // --include-rapids): the others are gaps, so a figure's peak is the table's maximum.
        let masked = |v: &[f64]| -> Vec<f64> {
            v.iter()
                .zip(measured)
                .map(|(x, m)| if *m { *x } else { f64::NAN })
                .collect()
        };
        let (tip_t, or_t) = (masked(&tip_t), masked(&or_t));
        let tip_m: Vec<Vec<f64>> = tip_m.iter().map(|v| masked(v)).collect();
        let or_m: Vec<Vec<f64>> = or_m.iter().map(|v| masked(v)).collect();
        // The worst blocks are marked among the measured samples only, as summary.json's
        // worst_blocks; line 0 is left unmarked.
        let lines: Vec<u32> = record
            .lines
            .iter()
            .zip(measured)
            .map(|(l, m)| if *m { *l } else { 0 })
            .collect();
        let lines = &lines;
        let opts = PathViewOptions {
            worst_blocks: WORST_BLOCKS,
            ..PathViewOptions::default()
        };
        if draw.figures {
            report.figure(
                "toolpath_contour.svg",
                vr::contour_path_views(
                    &format!("{name}: tool-tip path coloured by the true machine's contour error"),
                    &ColouredPath {
                        points_mm: &true_tip,
                        values: &tip_t,
                        value: Quantity::new("contour error", units::UM),
                        block_line: Some(lines),
                    },
                    &opts,
                ),
                &format!(
                    "The true machine's tool-tip path in the workpiece frame (isometric view and the \
                     two projections that show it best), coloured by its contour error; the colour \
                     scale ends at the {}th percentile so that one spike does not darken the part \
                     (larger values take the top colour). The {} worst blocks are marked with their \
                     G-code line numbers.",
                    opts.clip_percentile, opts.worst_blocks
                ),
                section::CONTOUR,
            )?;
        }
        if draw.figures && draw.along_path {
            // The arc length of the reference tool-tip path, its poses computed one at a time.
            let kin = machine.require_kinematics()?;
            let ref_pos = record.reference_positions();
            let s = vr::arc_length_mm_of((0..n).map(|k| {
                let q = kin.pose_at(&ref_pos, k);
                [q.p.x, q.p.y, q.p.z]
            }));
            fn series<'a>(
                models: &[ModelLabel<'a>],
                s: &'a [f64],
                v: &'a [Vec<f64>],
            ) -> Vec<Series<'a>> {
                models
                    .iter()
                    .zip(v)
                    .map(|(m, y)| Series::line(m.label, m.role, s, y))
                    .collect()
            }
            let models = labels;
            let labels: Vec<&str> = models.iter().map(|m| m.label).collect();
            report.figure(
                "contour_error.svg",
                vr::error_along_path(
                    &format!("{name}: contour and orientation errors along the path"),
                    &PathErrors {
                        arc_length_mm: &s,
                        contour_truth: Series::line(TRUE_MACHINE, Role::TrueMachine, &s, &tip_t),
                        contour_models: series(models, &s, &tip_m),
                        orientation_truth: Series::line(TRUE_MACHINE, Role::TrueMachine, &s, &or_t),
                        orientation_models: series(models, &s, &or_m),
                        block_line: Some(lines),
                        worst_blocks: WORST_BLOCKS,
                        points_mm: Some(&true_tip),
                    },
                ),
                &format!(
                    "Tool-tip contour error (µm) and tool-orientation error (mrad) against the arc \
                 length of the reference tool-tip path, of the true machine and as predicted by \
                 the {}; under each, model − true machine. Dashed lines mark the {WORST_BLOCKS} \
                 worst blocks by their G-code line numbers.",
                    labels.join(" and the ")
                ),
                section::CONTOUR,
            )?;
        }
    }

    if draw.vtp {
        // The 3-D export: the true machine's path with its errors, the models' errors beside
        // them. Written before the tracking figure (the file list keeps its order), which
        // takes the axis positions' memory; the tool axes are computed per point as written.
        let kin = machine.require_kinematics()?;
        let true_pos = record.truth.positions();
        let tool_axis = |k: usize| {
            let q = kin.pose_at(&true_pos, k);
            [q.o.x, q.o.y, q.o.z]
        };
        let axes = Vectors::Computed {
            len: n,
            at: &tool_axis,
        };
        let mut vtp = VtpPath::contour_with(&true_tip, &tip_t, &or_t, axes, Some(&record.lines));
        let tags: Vec<String> = labels
            .iter()
            .map(|m| m.label.replace('\'', "").replace(' ', "_"))
            .collect();
        for ((tag, tip), or) in tags.iter().zip(&tip_m).zip(&or_m) {
            vtp.scalars.push(PointScalars {
                name: format!("{tag}_contour_error_um"),
                values: tip,
            });
            vtp.scalars.push(PointScalars {
                name: format!("{tag}_orientation_error_mrad"),
                values: or,
            });
        }
        write_vtp(&report.dir().join(TOOLPATH_VTP), &vtp, VtpEncoding::Base64)?;
        report.file(
            TOOLPATH_VTP,
            "VTK PolyData (ParaView): the true machine's tool-tip path (mm, workpiece frame) with \
             contour_error_um, orientation_error_mrad, the tool_axis vectors and block_line per \
             point, and each model's errors",
        );
    }
    drop((true_tip, tip_t, or_t, tip_m, or_m));
    if !draw.figures {
        return Ok(());
    }

    // Tracking errors: each model set's axis positions become its errors in place.
    let tracks = prediction_tracking(machine, &mut record);
    let model_tracking: Vec<(&str, Role, &[AxisTracking])> = labels
        .iter()
        .zip(&tracks)
        .map(|(m, t)| (m.label, m.role, t.as_slice()))
        .collect();
    tracking(
        report,
        "tracking_errors.svg",
        (program, ts, &record.reference),
        (TRUE_MACHINE, Role::TrueMachine),
        &model_tracking,
        "Tracking error x_r − x of each axis the program moves (axes it leaves still are left \
         out): the true drives and the models; below each, model − true machine.",
    )?;
    Ok(())
}

/// The tracking errors of a prediction, per model set and machine axis, in µm or mdeg: the true
/// drives' (the same in every set) and the set's, each axis' figures with the set's departure
/// from the true drive. The model sets' positions become their errors in place.
fn prediction_tracking(machine: &Machine, record: &mut PredictionRecord) -> Vec<Vec<AxisTracking>> {
    let true_error: Vec<Vec<f64>> = machine
        .axes
        .iter()
        .enumerate()
        .map(|(i, a)| {
            scaled_diff(
                &record.reference[i],
                &record.truth.positions[i],
                a.unit.micro_factor(),
            )
        })
        .collect();
    let mut out = Vec::new();
    for set in &mut record.models {
        let axes = machine
            .axes
            .iter()
            .enumerate()
            .map(|(i, axis)| {
                let k = axis.unit.micro_factor();
                let mut model = std::mem::take(&mut set.positions[i]);
                let vs = scaled_diff_max_rms(&model, &record.truth.positions[i], k);
                for (x, r) in model.iter_mut().zip(&record.reference[i]) {
                    *x = (r - *x) * k;
                }
                AxisTracking::new(axis, true_error[i].clone(), Some((model, vs)))
            })
            .collect();
        out.push(axes);
    }
    out
}

/// What a swept machine-file key is, as an axis quantity: the key and, where its name alone
/// fixes it, its unit (docs/machine-file.md).
pub fn key_quantity(key: &str) -> Quantity {
    let leaf = key.rsplit('.').next().unwrap_or(key);
    let axis_unit = key
        .strip_prefix("axes.")
        .and_then(|r| r.split('.').next())
        .and_then(|a| a.parse::<AxisName>().ok())
        .map(AxisName::unit);
    let per = |suffix: &str| axis_unit.map(|u: Unit| format!("{}{suffix}", u.as_str()));
    let unit = match leaf {
        l if l.ends_with("_hz") => Some("Hz".to_string()),
        l if l.ends_with("_s") => Some("s".to_string()),
        "j" => Some("kg·m²".into()),
        "b" => Some("N·m·s/rad".into()),
        "ka" => Some("A/V".into()),
        "kt" => Some("N·m/A".into()),
        "coulomb_torque" => Some("N·m".into()),
        "u_max" => Some("V".into()),
        "lambda" => Some("1/s".into()),
        "max_velocity" => per("/s"),
        "max_acceleration" => per("/s²"),
        _ => None,
    };
    Quantity::new(key, unit.unwrap_or_default())
}

/// File name of a key's sweep figure: `sweep_<key>.svg`, dots and slashes as `_`.
fn key_file(key: &str) -> String {
    format!("sweep_{}.svg", key.replace(['.', '/'], "_"))
}

/// The figures of a sweep: one key, the result against the key's value (`sweep_<key>.svg`);
/// two keys, a heat map of the result over both (`sweep_map.svg`); more keys, one figure per key
/// with every configuration as a dot and the best over the other keys as a line.
pub fn sweep(report: &mut RunReport, keys: &[String], outcome: &SweepOutcome) -> Result<()> {
    let result = Quantity::new("max contour error, true machine", units::UM);
    let z: Vec<f64> = outcome.points.iter().map(|p| p.1).collect();
    let col = |i: usize| -> Vec<f64> { outcome.points.iter().map(|p| p.0[i]).collect() };
    match keys {
        [] => Ok(()),
        [key] => {
            let mut pts: Vec<(f64, f64)> = col(0).into_iter().zip(z.iter().copied()).collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (x, y): (Vec<f64>, Vec<f64>) = pts.into_iter().unzip();
            report.figure(
                &key_file(key),
                vr::sweep_line(
                    &format!("sweep: max contour error against {key}"),
                    &key_quantity(key),
                    &result,
                    &[Series::line("configurations", Role::Other(0), &x, &y)],
                ),
                &format!(
                    "The true machine's largest tool-tip contour error over the program for each \
                     value of {key}."
                ),
                section::SWEEP,
            )
        }
        [kx, ky] => {
            let grid = vr::grid_from_rows(&col(0), &col(1), &z);
            let fig = grid.and_then(|g| {
                vr::sweep_heatmap(
                    &format!("sweep: max contour error over {kx} and {ky}"),
                    &HeatMap {
                        x_key: key_quantity(kx),
                        x_values: &g.x_values,
                        y_key: key_quantity(ky),
                        y_values: &g.y_values,
                        result: result.clone(),
                        values: &g.values,
                    },
                )
            });
            report.figure(
                "sweep_map.svg",
                fig,
                &format!(
                    "The true machine's largest tool-tip contour error over the program for each \
                     configuration of {kx} (columns) and {ky} (rows); the best configuration is \
                     outlined, configurations without a result are hatched."
                ),
                section::SWEEP,
            )
        }
        _ => {
            for (i, key) in keys.iter().enumerate() {
                let x = col(i);
                // The best result over the other keys at each value of this one.
                let mut best: Vec<(f64, f64)> = Vec::new();
                for (v, r) in x.iter().zip(&z) {
                    match best.iter_mut().find(|b| b.0 == *v) {
                        Some(b) => b.1 = b.1.min(*r),
                        None => best.push((*v, *r)),
                    }
                }
                best.sort_by(|a, b| a.0.total_cmp(&b.0));
                let (bx, by): (Vec<f64>, Vec<f64>) = best.into_iter().unzip();
                let all = Series {
                    mark: Mark::Dots,
                    ..Series::line("every configuration", Role::Other(0), &x, &z)
                };
                report.figure(
                    &key_file(key),
                    vr::sweep_line(
                        &format!("sweep: max contour error against {key}"),
                        &key_quantity(key),
                        &result,
                        &[
                            all,
                            Series::line("best over the other keys", Role::Other(1), &bx, &by),
                        ],
                    ),
                    &format!(
                        "The true machine's largest tool-tip contour error against {key}: every \
                         configuration (dots; the other {} keys vary among them) and, through \
                         them, the best over the other keys at each value.",
                        keys.len() - 1
                    ),
                    section::SWEEP,
                )?;
            }
            Ok(())
        }
    }
}

/// Min/max envelope of a signal over fixed time buckets: what a plot of a long signal needs, a
/// spike never lost (each bucket keeps its extremes).
#[derive(Debug, Clone)]
pub struct Envelope {
    bucket: usize,
    min: Vec<f64>,
    max: Vec<f64>,
}

/// Time buckets of a streamed run's figures: about one per pixel column.
pub const ENVELOPE_COLUMNS: usize = 2000;

impl Envelope {
    /// An envelope of `samples` samples in about `columns` buckets.
    pub fn new(samples: usize, columns: usize) -> Self {
        let bucket = samples.div_ceil(columns.max(1)).max(1);
        let n = samples.div_ceil(bucket);
        Envelope {
            bucket,
            min: vec![f64::INFINITY; n],
            max: vec![f64::NEG_INFINITY; n],
        }
    }

    /// Add samples `first..first + values.len()`.
    pub fn add(&mut self, first: usize, values: impl IntoIterator<Item = f64>) {
        for (k, v) in values.into_iter().enumerate() {
            let b = (first + k) / self.bucket;
            if b < self.min.len() {
                self.min[b] = self.min[b].min(v);
                self.max[b] = self.max[b].max(v);
            }
        }
    }

    /// The envelope as a polyline: per bucket its minimum then its maximum, at the bucket's
    /// first sample time (`ts` per sample).
    pub fn polyline(&self, ts: f64) -> (Vec<f64>, Vec<f64>) {
        let mut t = Vec::with_capacity(2 * self.min.len());
        let mut v = Vec::with_capacity(2 * self.min.len());
        for (b, (lo, hi)) in self.min.iter().zip(&self.max).enumerate() {
            if lo.is_finite() {
                let tb = (b * self.bucket) as f64 * ts;
                t.extend([tb, tb]);
                v.extend([*lo, *hi]);
            }
        }
        (t, v)
    }
}

/// The reference figure of a streamed run, piece by piece: each axis' velocity envelope.
pub struct ReferenceEnvelopes {
    velocity: Vec<Envelope>,
}

impl ReferenceEnvelopes {
    /// Envelopes of `axes` axes over `samples` samples.
    pub fn new(axes: usize, samples: usize) -> ReferenceEnvelopes {
        ReferenceEnvelopes {
            velocity: (0..axes)
                .map(|_| Envelope::new(samples, ENVELOPE_COLUMNS))
                .collect(),
        }
    }

    /// Draws `reference.svg` into `report`: `moved` says which axes the program moves.
    pub fn finish(
        self,
        report: &mut RunReport,
        machine: &Machine,
        (program, ts): (&str, f64),
        moved: &[bool],
    ) -> Result<()> {
        let lines: Vec<(Vec<f64>, Vec<f64>)> =
            self.velocity.iter().map(|e| e.polyline(ts)).collect();
        let axes: Vec<ReferenceAxis<'_>> = machine
            .axes
            .iter()
            .zip(&lines)
            .zip(moved)
            .map(|((a, (t, v)), moved)| ReferenceAxis {
                name: a.name,
                unit: a.unit,
                moved: *moved,
                t,
                vel: v,
            })
            .collect();
        reference_axes(report, program, &axes)
    }
}

impl Sink<ReferenceChunk> for ReferenceEnvelopes {
    type Error = crate::Error;
    fn piece(&mut self, c: &ReferenceChunk) -> Result<()> {
        for (e, v) in self.velocity.iter_mut().zip(&c.vel) {
            e.add(c.first, v.iter().copied());
        }
        Ok(())
    }
}

/// The contour-error figure of a streamed prediction, piece by piece: min/max envelopes of the
/// true machine's and the first model set's errors and of their difference, tool tip in µm and
/// orientation in mrad.
pub struct ContourEnvelopes {
    /// True tip, model tip, |Δ tip|, true orientation, model orientation, |Δ orientation|.
    env: [Envelope; 6],
    /// The samples drawn: those the statistics cover.
    measured: Measured,
}

impl ContourEnvelopes {
    /// Envelopes over `samples` samples, of the samples `measured` selects (those the
    /// statistics cover: the figure's peak is the table's maximum).
    pub fn new(samples: usize, measured: Measured) -> ContourEnvelopes {
        ContourEnvelopes {
            env: std::array::from_fn(|_| Envelope::new(samples, ENVELOPE_COLUMNS)),
            measured,
        }
    }

    /// Draws `contour_error.svg` into `report`.
    pub fn finish(self, report: &mut RunReport, (program, ts): (&str, f64)) -> Result<()> {
        let [tt, pt, dt, to, po, dor] = self.env.map(|e| e.polyline(ts));
        prediction_streamed(report, program, [tt, pt, dt, to, po, dor])
    }
}

impl Sink<PredictPiece> for ContourEnvelopes {
    type Error = crate::Error;
    fn piece(&mut self, p: &PredictPiece) -> Result<()> {
        let Some(m) = p.models.first() else {
            return Ok(());
        };
        let mask = self.measured.mask(&p.classes);
        let [tt, pt, dt, to, po, dor] = &mut self.env;
        let t = &p.truth;
        // µm or mrad of the measured samples; NaN (left out of the envelope) elsewhere.
        let scaled = |v: &[f64]| -> Vec<f64> {
            v.iter()
                .zip(&mask)
                .map(|(x, m)| if *m { x * 1e3 } else { f64::NAN })
                .collect()
        };
        let diff = |a: &[f64], b: &[f64]| -> Vec<f64> {
            a.iter().zip(b).map(|(x, y)| (y - x).abs()).collect()
        };
        tt.add(p.first, scaled(&t.tip_mm));
        pt.add(p.first, scaled(&m.tip_mm));
        dt.add(p.first, scaled(&diff(&t.tip_mm, &m.tip_mm)));
        to.add(p.first, scaled(&t.orientation_rad));
        po.add(p.first, scaled(&m.orientation_rad));
        dor.add(
            p.first,
            scaled(&diff(&t.orientation_rad, &m.orientation_rad)),
        );
        Ok(())
    }
}

/// The tracking figure of a streamed simulation, piece by piece: per axis the min/max envelope
/// of the true drive's tracking error (encoder reading) and of the model's, µm or mdeg.
pub struct TrackingEnvelopes {
    truth: Vec<Envelope>,
    model: Vec<Envelope>,
    scale: Vec<f64>,
    models: bool,
}

impl TrackingEnvelopes {
    /// Envelopes of `machine`'s axes over `samples` samples, with the models' when `models`.
    pub fn new(machine: &Machine, samples: usize, models: bool) -> TrackingEnvelopes {
        let axes = machine.axes.len();
        let env = || {
            (0..axes)
                .map(|_| Envelope::new(samples, ENVELOPE_COLUMNS))
                .collect()
        };
        TrackingEnvelopes {
            truth: env(),
            model: env(),
            scale: machine.axes.iter().map(|a| a.unit.micro_factor()).collect(),
            models,
        }
    }

    /// Draws `tracking.svg` into `report`: `moved` says which axes the program moves.
    pub fn finish(
        self,
        report: &mut RunReport,
        machine: &Machine,
        (program, ts): (&str, f64),
        moved: &[bool],
    ) -> Result<()> {
        let truth: Vec<(Vec<f64>, Vec<f64>)> = self.truth.iter().map(|e| e.polyline(ts)).collect();
        let model: Vec<(Vec<f64>, Vec<f64>)> = self.model.iter().map(|e| e.polyline(ts)).collect();
        let axes: Vec<StreamedAxis<'_>> = machine
            .axes
            .iter()
            .enumerate()
            .map(|(i, a)| StreamedAxis {
                name: a.name,
                unit: a.unit,
                moved: moved[i],
                truth: (&truth[i].0, &truth[i].1),
                model: self
                    .models
                    .then(|| (model[i].0.as_slice(), model[i].1.as_slice())),
            })
            .collect();
        simulation_tracking_streamed(report, program, &axes)
    }
}

impl Sink<SimulatePiece> for TrackingEnvelopes {
    type Error = crate::Error;
    fn piece(&mut self, p: &SimulatePiece) -> Result<()> {
        for (i, k) in self.scale.iter().enumerate() {
            let r = &p.reference[i];
            let x = &p.traces[i].position;
            self.truth[i].add(p.first, r.iter().zip(x).map(|(r, x)| (r - x) * k));
            if let Some(pred) = &p.predicted {
                self.model[i].add(p.first, r.iter().zip(&pred[i]).map(|(r, x)| (r - x) * k));
            }
        }
        Ok(())
    }
}

/// `contour_error.svg` of a streamed prediction: the errors against time, each drawn from its
/// min/max envelope per pixel column (every extreme kept), as polylines `(t, value)`: true
/// machine, model and |model − true machine|, tool tip (µm) then orientation (mrad).
fn prediction_streamed(
    report: &mut RunReport,
    file: &str,
    [tt, pt, dt, to, po, dor]: [(Vec<f64>, Vec<f64>); 6],
) -> Result<()> {
    fn line<'a>(label: &'static str, role: Role, s: &'a (Vec<f64>, Vec<f64>)) -> Series<'a> {
        Series::line(label, role, &s.0, &s.1)
    }
    let panels = vec![
        vr::Panel::new(
            Axis::linear("tool-tip contour error", units::UM),
            vec![
                line(TRUE_MACHINE, Role::TrueMachine, &tt),
                line(VCNC_MODEL, Role::Model, &pt),
            ],
        ),
        vr::Panel::new(
            Axis::linear("|model − true machine|, tool tip", units::UM),
            vec![line(VCNC_MODEL, Role::Model, &dt)],
        ),
        vr::Panel::new(
            Axis::linear("orientation contour error", "mrad"),
            vec![
                line(TRUE_MACHINE, Role::TrueMachine, &to),
                line(VCNC_MODEL, Role::Model, &po),
            ],
        ),
        vr::Panel::new(
            Axis::linear("|model − true machine|, orientation", "mrad"),
            vec![line(VCNC_MODEL, Role::Model, &dor)],
        ),
    ];
    let fig = vr::LineFigure::new(
        format!("{}: contour and orientation errors", program_name(file)),
        Axis::linear("time t", units::S),
        panels,
    );
    report.figure(
        "contour_error.svg",
        vr::line_figure(&fig),
        "Tool-tip contour error (µm) and tool-orientation error (mrad) against time, of the true \
         machine and as predicted by the vcnc model, and model − true machine under each. The \
         program was predicted streamed (docs/performance.md): each curve is the minimum and \
         maximum of its samples in each of about 2 000 time buckets, so no spike is lost; the \
         table holds every sample.",
        section::CONTOUR,
    )
}

/// One axis of a streamed simulation's tracking figure: min/max envelopes over time of its
/// tracking error (and the model's), µm or mdeg.
struct StreamedAxis<'a> {
    /// The axis.
    pub name: AxisName,
    /// mm or deg.
    pub unit: Unit,
    /// The program moves it (else it is listed, not drawn).
    pub moved: bool,
    /// The true drive's tracking error envelope `(t, value)`.
    pub truth: (&'a [f64], &'a [f64]),
    /// The model's, when simulated.
    pub model: Option<(&'a [f64], &'a [f64])>,
}

/// `tracking.svg` of a streamed simulation: per moved axis the tracking error x_r − x of the
/// true drive (encoder reading) and of the model, each from its min/max envelope over time.
fn simulation_tracking_streamed(
    report: &mut RunReport,
    file: &str,
    axes: &[StreamedAxis<'_>],
) -> Result<()> {
    let (moved, still): (Vec<_>, Vec<_>) = axes.iter().partition(|a| a.moved);
    let panels: Vec<vr::Panel> = moved
        .iter()
        .map(|a| {
            let mut series = vec![Series::line(
                TRUE_MACHINE,
                Role::TrueMachine,
                a.truth.0,
                a.truth.1,
            )];
            if let Some((t, v)) = a.model {
                series.push(Series::line(VCNC_MODEL, Role::Model, t, v));
            }
            vr::Panel::new(
                Axis::linear(
                    format!("axis {} x_r − x", a.name),
                    vr::style::error_unit(a.unit),
                ),
                series,
            )
        })
        .collect();
    let mut fig = vr::LineFigure::new(
        format!("{}: tracking errors x_r − x per axis", program_name(file)),
        Axis::linear("time t", units::S),
        panels,
    );
    fig.note = still_note(still.iter().map(|a| a.name));
    report.figure(
        "tracking.svg",
        vr::line_figure(&fig),
        "Tracking error x_r − x of each axis the program moves: the true drive (encoder reading) \
         and, when given, the model. The program was simulated streamed (docs/performance.md): \
         each curve is the minimum and maximum of its samples in each of about 2 000 time \
         buckets, so no spike is lost; the table holds every sample.",
        section::TRACKING,
    )
}

/// A figure's note naming the axes the program leaves still (not drawn); empty when it moves
/// them all.
fn still_note(still: impl Iterator<Item = AxisName>) -> String {
    let names: Vec<&str> = still.map(|a| a.as_str()).collect();
    if names.is_empty() {
        String::new()
    } else {
        format!("not moved by the program, not shown: {}", names.join(", "))
    }
}
