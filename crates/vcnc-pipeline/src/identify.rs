//! Identification of feed drives, one route for simulated machines and measured traces
//! (docs/identification.md): the same options type ([`OptionsFile`]), the same bound rule
//! ([`identifier_options`]), the same result ([`AxisIdentification`]) and summary.
//!
//! - A simulated machine axis: generate its identification program (estimation seed),
//!   interpolate it, run the true drive, identify; validate on a second run (validation seed).
//! - A measured trace: identify on it; its fit is its own.

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::Serialize;
use vcnc_axis::{AxisName, Unit};
use vcnc_drive::{ClosedLoopModel, DriveTrace};
use vcnc_gcode::IdentificationOptions;
use vcnc_identify::{
    FitMetrics, Identification, IdentifyOptions, Regressors, Trace, fit_metrics_with,
};
use vcnc_machine::{Axis, AxisModel, Dynamics, Machine, MachineModels, ModelSet, OptionsFile};

use crate::Error;
use crate::run::AxisSignals;
use crate::summary::{FitSummary, ModelSummary, PoleErrors};

/// The identifier options a run uses: the file's, with the seed overridden when given, and the
/// same two rules for machines and traces (docs/machine-file.md): unless the options set
/// `bounds.p_hz`, the real pole may approach 0 (lower bound 1e-4 Hz), so that drives without
/// integral action ($a_3 = 0$, such as the EMPS benchmark) are identifiable; unless they set
/// `structures`, every model structure is tried (the paper's, without integral action, dead
/// time, first- and second-order reference filter, extra pole), and unless they list `inputs`, both model inputs
/// (smooth and hold); the candidate with the smallest validation error is kept
/// (docs/identification.md).
pub fn identifier_options(file: &OptionsFile, seed: Option<u64>) -> IdentifyOptions {
    let mut opts = file.options.clone();
    if let Some(s) = seed {
        opts.seed = s;
    }
    if !file.sets_p_bounds {
        opts.bounds.p_hz[0] = opts.bounds.p_hz[0].min(1e-4);
    }
    if !file.sets_structures {
        opts.structures = vcnc_identify::ModelStructure::ALL.to_vec();
    }
    if opts.inputs.is_empty() {
        opts.inputs = vec![
            vcnc_identify::ReferenceInput::Smooth,
            vcnc_identify::ReferenceInput::Hold,
        ];
    }
    opts
}

/// The machine's axes named in `names` (all of them when empty), each once, in the order
/// given; an error names any axis the machine lacks.
pub fn select_axes<'m>(machine: &'m Machine, names: &[AxisName]) -> Result<Vec<&'m Axis>, Error> {
    if names.is_empty() {
        return Ok(machine.axes.iter().collect());
    }
    let mut out: Vec<&Axis> = Vec::new();
    for &n in names {
        let a = machine.axis(n).ok_or_else(|| Error::NoSuchAxis {
            axis: n,
            machine: machine.name.clone(),
            file: machine.source.clone(),
            has: machine
                .axis_names()
                .iter()
                .map(|a| a.as_str())
                .collect::<String>(),
        })?;
        if !out.iter().any(|b| b.name == n) {
            out.push(a);
        }
    }
    Ok(out)
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
        Trace::new(
            self.trace.ts,
            self.reference.pos.clone(),
            self.trace.position.clone(),
        )
        .and_then(|t| {
            t.with_reference_derivatives(self.reference.vel.clone(), self.reference.acc.clone())
        })
        .map_err(|e| Error::identify(format!("axis {}", self.reference.name), e))
    }
}

/// Generates the axis' identification program with `seed`, interpolates it and runs it through
/// the true drive.
pub fn excitation_run(machine: &Machine, a: &Axis, seed: u64) -> Result<ExcitationRun, Error> {
    let drive = a.require_drive(machine, "identification on the virtual machine")?;
    let p = &machine.identification.program;
    let opts = IdentificationOptions {
        moves: p.moves,
        range: a.identification_range,
        max_feed: p.max_feed,
        min_feed: p.min_feed,
        seed,
        ..IdentificationOptions::default()
    };
    let name = format!("<identification program of axis {} (seed {seed})>", a.name);
    let program = vcnc_gcode::identification(a.name, &opts).map_err(|e| Error::gcode(&name, e))?;
    let mut iopts = machine.interpolate_options();
    iopts.axes = Some(vec![a.name]);
    let mut limits = machine.limits();
    if let Some(acc) = p.max_acceleration {
        for l in limits.axes.iter_mut() {
            l.max_acc = l.max_acc.min(acc);
        }
    }
    // The excitation opens with `G0 <axis>0` at rest: it starts at its own centre, whatever
    // the machine's start position.
    let interp = vcnc_gcode::InterpOptions {
        start: vcnc_gcode::StartPosition::Machine([0.0; 6]),
        ..machine.interp_options(false)
    };
    let loaded =
        vcnc_gcode::load(&program, &interp, &limits, &iopts).map_err(|e| Error::gcode(&name, e))?;
    // The interpolator outputs exactly the axes it is asked for.
    let track = loaded
        .trajectory
        .axes
        .first()
        .ok_or_else(|| Error::NoTrack {
            program: name.to_string(),
        })?;
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
    // On a machine with the control's nominal-position filters (`[control]`) the drive is
    // identified from what it receives, the filtered reference: its models then take the
    // filters' place nowhere, and a prediction filters the reference before them as before the
    // drives.
    let reference = match &machine.control {
        None => reference,
        Some(f) => {
            let (mut pos, mut vel, mut acc) = (Vec::new(), Vec::new(), Vec::new());
            f.stream()
                .feed(reference.reference(), &mut pos, &mut vel, &mut acc)
                .map_err(|source| Error::Drive {
                    axis: a.name,
                    source,
                })?;
            AxisSignals {
                pos,
                vel,
                acc,
                ..reference
            }
        }
    };
    let trace = drive
        .simulate(reference.reference(), machine.ts)
        .map_err(|source| Error::Drive {
            axis: a.name,
            source,
        })?;
    Ok(ExcitationRun {
        program,
        reference,
        trace,
    })
}

/// Where an identification's data came from.
#[derive(Debug, Clone)]
pub enum IdentificationSource {
    /// A simulated machine axis: its estimation and validation runs and the true model.
    Simulated {
        /// The analytic model of the true drive.
        truth: ClosedLoopModel,
        /// The estimation run.
        estimation: Box<ExcitationRun>,
        /// The validation run.
        validation: Box<ExcitationRun>,
    },
    /// A measured trace (one run: the fit is on it).
    Measured {
        /// The trace's path.
        file: String,
        /// Which channels, units and alignment the axis' samples come from.
        provenance: Box<vcnc_trace::Provenance>,
    },
}

/// The identification of one axis, from either source.
#[derive(Debug, Clone)]
pub struct AxisIdentification {
    /// The axis.
    pub axis: AxisName,
    /// mm or deg.
    pub unit: Unit,
    /// Where the data came from.
    pub source: IdentificationSource,
    /// The options the identifier was given (defaults included).
    pub options: IdentifyOptions,
    /// Everything the identifier produced (refined, paper PSO, LS baseline, history, fits).
    /// The chosen model (`result.model`) carries the stated actual-value latency of the axis'
    /// control: the time by which the logged actual position (what the models predict) trails
    /// the physical axis. Not identified — no record of nominal and logged positions shows it —
    /// but stated: on a simulated machine by its configuration ([`Axis::actual_latency_s`]),
    /// for a trace by the caller (0 until then; `vcnc identify --actual-latency-s`).
    /// `model.toml` writes it (docs/drive-model.md#actual-value-latency).
    pub result: Identification,
    /// The trace the `validation` fits are computed on: the validation run of a simulated
    /// machine, the trace itself for a measurement.
    pub validation_trace: Trace,
    /// Free-run fit of the refined model on `validation_trace`.
    pub validation: FitMetrics,
    /// Free-run fit of the paper-method (PSO) model on `validation_trace`.
    pub validation_paper: FitMetrics,
}

impl AxisIdentification {
    /// The true model, for a simulated machine.
    pub fn truth(&self) -> Option<&ClosedLoopModel> {
        match &self.source {
            IdentificationSource::Simulated { truth, .. } => Some(truth),
            IdentificationSource::Measured { .. } => None,
        }
    }
}

/// Identifies one axis of a simulated machine: estimation run (program seed), identification,
/// validation run (validation seed). `seed` overrides the machine file's seeds (the validation
/// seed keeps its distance to the estimation seed).
pub fn identify_axis(
    machine: &Machine,
    a: &Axis,
    seed: Option<u64>,
) -> Result<AxisIdentification, Error> {
    let p = &machine.identification.program;
    let program_seed = seed.unwrap_or(p.seed);
    let validation_seed = match seed {
        Some(s) => s.wrapping_add(p.validation_seed.wrapping_sub(p.seed).max(1)),
        None => p.validation_seed,
    };
    let opts = identifier_options(&machine.identification.options, seed);
    let (est, val) = rayon::join(
        || excitation_run(machine, a, program_seed),
        || excitation_run(machine, a, validation_seed),
    );
    let (est, val) = (est?, val?);
    let subject = format!("axis {}", a.name);
    let trace = est.identification_trace()?;
    let vtrace = val.identification_trace()?;
    // The structure is chosen by the validation run's error.
    let mut result = vcnc_identify::identify_with_validation(&trace, &vtrace, &opts)
        .map_err(|e| Error::identify(&subject, e))?;
    result.model.actual_latency_s = a.actual_latency_s();
    // One regressor pass over the validation run serves the 7-parameter models.
    let regs = Regressors::build(&vtrace, &opts).map_err(|e| Error::identify(&subject, e))?;
    let validation = if result.model.is_core_only() {
        fit_metrics_with(&result.model.core, &vtrace, &regs)
    } else {
        vcnc_identify::score(&result.model, &vtrace, None, &opts)
    }
    .map_err(|e| Error::identify(&subject, e))?;
    let validation_paper = fit_metrics_with(&result.paper_pso, &vtrace, &regs)
        .map_err(|e| Error::identify(&subject, e))?;
    Ok(AxisIdentification {
        axis: a.name,
        unit: a.unit,
        source: IdentificationSource::Simulated {
            truth: a.true_model(),
            estimation: Box::new(est),
            validation: Box::new(val),
        },
        options: opts,
        result,
        validation_trace: vtrace,
        validation,
        validation_paper,
    })
}

/// Identifies several axes in parallel (results in the order given).
pub fn identify_axes(
    machine: &Machine,
    axes: &[&Axis],
    seed: Option<u64>,
) -> Result<Vec<AxisIdentification>, Error> {
    axes.par_iter()
        .map(|a| identify_axis(machine, a, seed))
        .collect()
}

/// Identifies one axis of a measured trace: `trace` holds its samples (from `axis`, which
/// says where they came from).
pub fn identify_trace(
    trace: Trace,
    axis: &vcnc_trace::AxisTrace,
    options: &OptionsFile,
    seed: Option<u64>,
) -> Result<AxisIdentification, Error> {
    let file = &axis.provenance.file;
    let opts = identifier_options(options, seed);
    let subject = format!("{file} axis {}", axis.axis);
    let result =
        vcnc_identify::identify(&trace, &opts).map_err(|e| Error::identify(&subject, e))?;
    // The chosen model's fit on the whole trace, from its refinement there (its structure was
    // chosen on a held-out part, reported beside it in `structures`).
    let validation = result.chosen().estimation.clone();
    Ok(AxisIdentification {
        axis: axis.axis,
        unit: axis.unit,
        source: IdentificationSource::Measured {
            file: file.to_string(),
            provenance: Box::new(axis.provenance.clone()),
        },
        options: opts,
        validation,
        validation_paper: result.fit_estimation_paper.clone(),
        result,
        validation_trace: trace,
    })
}

/// The model file of identifications (`model.toml`): each axis' chosen model and its stated
/// actual-value latency.
pub fn model_set(machine: &str, description: &str, ids: &[AxisIdentification]) -> ModelSet {
    ModelSet {
        machine: machine.to_string(),
        description: Some(description.to_string()),
        axes: ids
            .iter()
            .map(|r| (r.axis.to_string(), AxisModel::new(r.unit, &r.result.model)))
            .collect(),
    }
}

/// The chosen models of identifications of every axis of `machine` (in its order), as the
/// machine's models; `source` says where they come from ("identified on the fly").
pub fn machine_models(
    machine: &Machine,
    ids: &[AxisIdentification],
    source: &str,
) -> Result<MachineModels, Error> {
    Ok(MachineModels::new(
        machine,
        ids.iter().map(|r| r.result.model).collect(),
        source,
    )?)
}

/// The models a prediction runs: those of the model file at `path` (checked against
/// `machine`); without one, every axis with a virtual drive identified on the fly from the
/// machine's own excitation runs, and every axis known by its identified model that model.
pub fn models_for(
    machine: &Machine,
    path: Option<&std::path::Path>,
) -> Result<MachineModels, Error> {
    if let Some(p) = path {
        return Ok(MachineModels::load(p, machine)?);
    }
    let drives: Vec<&Axis> = machine
        .axes
        .iter()
        .filter(|a| a.drive().is_some())
        .collect();
    if drives.is_empty()
        && let Some(own) = machine.own_models()
    {
        return Ok(own);
    }
    let mut identified = identify_axes(machine, &drives, None)?.into_iter();
    let models = machine
        .axes
        .iter()
        .filter_map(|a| match &a.dynamics {
            Dynamics::Drive(_) => identified.next().map(|r| r.result.model),
            Dynamics::Model(m) => Some(*m),
        })
        .collect();
    let source = if drives.len() == machine.axes.len() {
        "identified on the fly".to_string()
    } else {
        format!(
            "identified on the fly ({}), the machine's models ({})",
            drives
                .iter()
                .map(|a| a.name.as_str())
                .collect::<Vec<_>>()
                .join(" "),
            machine.model_file.as_deref().unwrap_or_default()
        )
    };
    Ok(MachineModels::new(machine, models, source)?)
}

/// The models a command that does not identify runs (`compensate`, `feed-plan`): those of the
/// model file at `path`, or without one the machine's own when every axis is known by its
/// identified model ([`Error::NeedsModels`] otherwise).
pub fn given_models(
    machine: &Machine,
    path: Option<&std::path::Path>,
    command: &'static str,
) -> Result<MachineModels, Error> {
    if let Some(p) = path {
        return Ok(MachineModels::load(p, machine)?);
    }
    machine.own_models().ok_or_else(|| Error::NeedsModels {
        command,
        file: machine.source.clone(),
        drives: machine
            .axes
            .iter()
            .filter(|a| a.drive().is_some())
            .map(|a| a.name.as_str())
            .collect::<Vec<_>>()
            .join(" "),
    })
}

/// The paper's method's models (the equation-error PSO alone) of identifications of every
/// axis of `machine`, without actual-value latency.
pub fn paper_models(machine: &Machine, ids: &[AxisIdentification]) -> Result<MachineModels, Error> {
    Ok(MachineModels::new(
        machine,
        ids.iter().map(|r| r.result.paper_pso.into()).collect(),
        "the paper's method (equation-error PSO)",
    )?)
}

/// PSO figures of a summary.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PsoSummary {
    /// Equation-error cost of the swarm's best (paper eq. 16), axis units².
    pub cost: f64,
    /// Iterations run.
    pub iterations: usize,
}

/// Relative pole errors of the refined and the paper-PSO models against the truth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorsVsTrue {
    /// The errors of the identified model (the one written to `model.toml`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub identified: Option<PoleErrors>,
    /// The errors of the paper structure's refined model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub paper_refined: Option<PoleErrors>,
    /// The paper-PSO model's errors.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub paper_pso: Option<PoleErrors>,
}

/// One axis of an identification summary (docs/cli.md).
#[derive(Debug, Clone, Serialize)]
pub struct AxisIdentifySummary {
    /// `mm` or `deg`.
    pub unit: Unit,
    /// The identified model: the chosen structure's, refined on the whole estimation run, with
    /// its dead time, reference filter or extra pole — what `model.toml` holds.
    pub identified: ModelSummary,
    /// The paper's 7-parameter structure refined by output error (with the chosen model
    /// input): `identified` when the paper structure is the one chosen.
    pub paper_refined: ModelSummary,
    /// The paper's equation-error PSO alone.
    pub paper_pso: ModelSummary,
    /// Unconstrained least squares of the seven parameters (may be unstable).
    pub unconstrained_ls: ModelSummary,
    /// The true drive's analytic model (simulated machines).
    #[serde(rename = "true", skip_serializing_if = "Option::is_none")]
    pub truth: Option<ModelSummary>,
    /// Pole errors against the truth, % (simulated machines).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_percent_vs_true: Option<ErrorsVsTrue>,
    /// The identified model's fit on the validation run (a simulated machine's second run; a
    /// measured trace's own run).
    pub fit: FitSummary,
    /// The identified model's fit on the estimation run (simulated machines).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit_estimation: Option<FitSummary>,
    /// The paper-PSO model's fit on the validation run.
    pub fit_paper_pso: FitSummary,
    /// The paper-PSO model's fit on the estimation run (simulated machines).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit_paper_pso_estimation: Option<FitSummary>,
    /// Swarm figures.
    pub pso: PsoSummary,
    /// Condition number of the column-scaled regressors.
    pub regressor_condition: f64,
    /// Whether the trace was treated as starting in motion (measured traces).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub moving_start: Option<bool>,
    /// Where a measured axis' samples come from (measured traces).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trace: Option<AxisTraceSummary>,
    /// The structure chosen by validation error (`paper`, `no-integral`, `delay`,
    /// `first-order-filter`, `second-order-filter`, `extra-pole`).
    pub structure: vcnc_identify::ModelStructure,
    /// Every structure tried, with its estimation fit and the validation error that chose.
    pub structures: Vec<StructureSummary>,
    /// Standard deviations of the chosen model's parameters (p_hz, wn_hz, zeta, dc, then its
    /// structure's own), from the refinement's Jacobian with the residual's autocorrelation,
    /// widened to the cost profile's for a weakly determined pole.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<Vec<ParameterSummary>>,
    /// Parameters of the chosen model that ended on a bound of their search region.
    pub on_bounds: Vec<vcnc_identify::BoundHit>,
    /// Warnings about this axis' model (parameters on bounds, relative deviations above 10 %).
    pub warnings: Vec<String>,
    /// The chosen model's dead time and reference filter as a machine file's `[control]`
    /// section (TOML), when it has either ([`control_section`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub control_section: Option<String>,
}

/// The chosen model's dead time and reference filter of `id` as the control's nominal-position
/// filters (`[control]`, docs/machine-file.md#control), TOML text: the whole sample periods of
/// the delay (the trace's period), the filter as it is, and a comment line naming what stays in
/// the model (the delay's fraction of a period, when there is one). A machine file with this
/// section and the model with `reference_filter` removed and `delay_s` set to that fraction
/// predicts what the model predicts (the same physics in front of the drive instead of inside
/// its model; tested in crates/vcnc-pipeline/tests/control_filters.rs). `None` when the model
/// has neither.
pub fn control_section(id: &AxisIdentification) -> Option<String> {
    let m = &id.result.model;
    if m.delay_s == 0.0 && m.reference_filter.is_none() {
        return None;
    }
    let ts = id.validation_trace.ts;
    let periods = (m.delay_s / ts).floor();
    let rest = m.delay_s - periods * ts;
    let mut text = format!(
        "# axis {}: in model.toml remove reference_filter and set delay_s = {}\n[control]\ndelay_s = {}\n",
        id.axis,
        fmt_g(rest),
        fmt_g(periods * ts)
    );
    match m.reference_filter {
        None => {}
        Some(vcnc_drive::ReferenceFilter::FirstOrder { tau_s }) => text.push_str(&format!(
            "filters = [{{ kind = \"first-order\", time_constant_s = {} }}]\n",
            fmt_g(tau_s)
        )),
        Some(vcnc_drive::ReferenceFilter::SecondOrder { wn_hz, zeta }) => text.push_str(&format!(
            "filters = [{{ kind = \"second-order\", time_constant_s = {}, zeta = {} }}]\n",
            fmt_g(1.0 / (std::f64::consts::TAU * wn_hz)),
            fmt_g(zeta)
        )),
    }
    Some(text)
}

/// A value with 6 significant digits, as a TOML float.
fn fmt_g(v: f64) -> String {
    let s = format!("{:.6e}", v);
    let parsed: f64 = s.parse().unwrap_or(v);
    let t = format!("{parsed}");
    if t.contains('.') || t.contains('e') {
        t
    } else {
        format!("{t}.0")
    }
}

/// One model structure as identified.
#[derive(Debug, Clone, Serialize)]
pub struct StructureSummary {
    /// The structure.
    pub structure: vcnc_identify::ModelStructure,
    /// Its model.
    pub model: ModelSummary,
    /// Its fit on the estimation run.
    pub fit_estimation: FitSummary,
    /// Its error where the structure was chosen (the validation run, or the held-out end of a
    /// single trace).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit_validation: Option<FitSummary>,
    /// Whether it was refined on the whole estimation trace (the chosen one and the paper's
    /// structure) or only compared on the compared stretch.
    pub whole: bool,
    /// The choice's verdict on it (`chosen`, or why not, with the numbers); absent when
    /// nothing was chosen.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub verdict: Option<vcnc_identify::Verdict>,
    /// Why its parameters are not trusted (on a bound, not determined by the data); empty
    /// when they are.
    pub not_trusted: Vec<String>,
}

/// A parameter and its standard deviation.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterSummary {
    /// `p_hz`, `wn_hz`, `zeta`, `dc` (axis units/s²), `delay_s`, `filter_tau_s`,
    /// `filter_wn_hz`, `filter_zeta`, `extra_pole_hz`.
    pub name: &'static str,
    /// Value, in the parameter's unit.
    pub value: f64,
    /// Standard deviation, same unit (null when undetermined).
    pub std: Option<f64>,
    /// Relative standard deviation, % (null when undetermined).
    pub relative_percent: Option<f64>,
}

/// Relative deviation above which a parameter is called poorly determined.
pub const UNCERTAIN_RELATIVE: f64 = 0.10;

/// The samples of a measured axis: how many, their period, and their channels.
#[derive(Debug, Clone, Serialize)]
pub struct AxisTraceSummary {
    /// Samples identified on.
    pub samples: usize,
    /// Sample period, s.
    pub ts_s: f64,
    /// Channels, units (and where each unit came from), alignment, segment used.
    #[serde(flatten)]
    pub provenance: vcnc_trace::Provenance,
}

impl AxisIdentifySummary {
    /// The summary of one axis.
    pub fn of(r: &AxisIdentification) -> AxisIdentifySummary {
        let id = &r.result;
        let fit = |f: &FitMetrics| FitSummary {
            unit: r.unit,
            fit: f.clone(),
        };
        let truth = r.truth();
        let simulated = truth.is_some();
        AxisIdentifySummary {
            unit: r.unit,
            identified: ModelSummary::of_drive(&id.model),
            paper_refined: ModelSummary::of(&id.identified),
            paper_pso: ModelSummary::of(&id.paper_pso),
            unconstrained_ls: ModelSummary::of(&id.unconstrained_ls.model),
            truth: truth.map(ModelSummary::of),
            error_percent_vs_true: truth.map(|t| ErrorsVsTrue {
                identified: PoleErrors::of_models(t, &id.model.core),
                paper_refined: PoleErrors::of_models(t, &id.identified),
                paper_pso: PoleErrors::of_models(t, &id.paper_pso),
            }),
            fit: fit(&r.validation),
            fit_estimation: simulated.then(|| fit(&id.chosen().estimation)),
            fit_paper_pso: fit(&r.validation_paper),
            fit_paper_pso_estimation: simulated.then(|| fit(&id.fit_estimation_paper)),
            pso: PsoSummary {
                cost: id.pso_cost,
                iterations: id.pso_history.len(),
            },
            regressor_condition: id.condition_number,
            moving_start: (!simulated).then_some(id.moving_start),
            structure: id.structure,
            structures: id
                .structures
                .iter()
                .map(|s| StructureSummary {
                    structure: s.structure,
                    model: ModelSummary::of_drive(&s.model),
                    fit_estimation: fit(&s.estimation),
                    fit_validation: s.validation.as_ref().map(fit),
                    whole: s.whole,
                    verdict: s.verdict.clone(),
                    not_trusted: s.degenerate.iter().map(|d| d.to_string()).collect(),
                })
                .collect(),
            uncertainty: id.uncertainty.as_ref().map(|u| {
                u.parameters
                    .iter()
                    .map(|p| {
                        let finite = |v: f64| v.is_finite().then_some(v);
                        ParameterSummary {
                            name: p.name,
                            value: p.value,
                            std: finite(p.std),
                            relative_percent: finite(100.0 * p.relative()),
                        }
                    })
                    .collect()
            }),
            on_bounds: id.on_bounds.clone(),
            warnings: axis_warnings(r),
            control_section: control_section(r),
            trace: match &r.source {
                IdentificationSource::Measured { provenance, .. } => Some(AxisTraceSummary {
                    samples: r.validation_trace.len(),
                    ts_s: r.validation_trace.ts,
                    provenance: (**provenance).clone(),
                }),
                IdentificationSource::Simulated { .. } => None,
            },
        }
    }
}

/// What a user must know about an axis' model: parameters that ended on a bound of their
/// search region, and parameters whose relative standard deviation exceeds 10 % (they are not
/// determined by the data; dc often is not).
pub fn axis_warnings(r: &AxisIdentification) -> Vec<String> {
    let id = &r.result;
    let mut w: Vec<String> = id
        .on_bounds
        .iter()
        .map(|b| {
            format!(
                "axis {}: {} = {} ended on its {} bound (widen identification.options bounds or check the data)",
                r.axis, b.parameter, b.value, b.bound
            )
        })
        .collect();
    if let Some(u) = &id.uncertainty {
        for name in u.flagged(UNCERTAIN_RELATIVE) {
            if let Some(p) = u.parameters.iter().find(|p| p.name == name) {
                let rel = 100.0 * p.relative();
                w.push(if rel.is_finite() {
                    format!(
                        "axis {}: {name} = {:.4} is poorly determined by the data (± {rel:.0} %)",
                        r.axis, p.value
                    )
                } else {
                    format!(
                        "axis {}: {name} = {:.4} is not determined by the data",
                        r.axis, p.value
                    )
                });
            }
        }
    }
    w
}

/// `summary.json` of `vcnc identify`: a machine's axes, or a trace's.
#[derive(Debug, Clone, Serialize)]
pub struct IdentifySummary {
    /// Machine name (simulated machines).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub machine: Option<String>,
    /// The trace's path (measured traces).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trace: Option<String>,
    /// The trace's format (measured traces).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub format: Option<vcnc_trace::Format>,
    /// Samples of the trace (its first axis; every axis in `axes.<A>.trace`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
    /// Sample period of the trace (its first axis), s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ts_s: Option<f64>,
    /// Unit of the trace's positions after conversion (its first axis).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub units: Option<Unit>,
    /// Per axis.
    pub axes: BTreeMap<String, AxisIdentifySummary>,
    /// What the identifier was told (defaults included), so the run can be repeated
    /// (measured traces).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub identify_options: Option<IdentifyOptions>,
}

impl IdentifySummary {
    /// The summary of a machine's identifications.
    pub fn machine(machine: &str, ids: &[AxisIdentification]) -> IdentifySummary {
        IdentifySummary {
            machine: Some(machine.to_string()),
            trace: None,
            format: None,
            samples: None,
            ts_s: None,
            units: None,
            axes: axes_summary(ids),
            identify_options: None,
        }
    }

    /// The summary of a trace's identifications (one per axis, at least one).
    pub fn trace(
        file: &str,
        format: vcnc_trace::Format,
        ids: &[AxisIdentification],
    ) -> IdentifySummary {
        let first = ids.first();
        IdentifySummary {
            machine: None,
            trace: Some(file.to_string()),
            format: Some(format),
            samples: first.map(|id| id.validation_trace.len()),
            ts_s: first.map(|id| id.validation_trace.ts),
            units: first.map(|id| id.unit),
            axes: axes_summary(ids),
            identify_options: first.map(|id| id.options.clone()),
        }
    }
}

fn axes_summary(ids: &[AxisIdentification]) -> BTreeMap<String, AxisIdentifySummary> {
    ids.iter()
        .map(|r| (r.axis.to_string(), AxisIdentifySummary::of(r)))
        .collect()
}

/// Per-axis pole errors of the identified and paper-PSO models (p, ωn, ζ; %), for the demo's
/// overview (keys `identified_error_percent`, `paper_pso_error_percent`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AxisOverview {
    /// The identified model's errors (null when not writable as poles).
    pub identified_error_percent: Option<PoleErrors>,
    /// The paper-PSO model's errors.
    pub paper_pso_error_percent: Option<PoleErrors>,
}

/// The demo's identification overview, per axis.
pub fn overview(ids: &[AxisIdentification]) -> BTreeMap<String, AxisOverview> {
    ids.iter()
        .map(|r| {
            let errs = |m: &ClosedLoopModel| {
                let t = r.truth()?.poles()?;
                Some(PoleErrors::of(&t, &m.poles()?))
            };
            (
                r.axis.to_string(),
                AxisOverview {
                    identified_error_percent: errs(&r.result.model.core),
                    paper_pso_error_percent: errs(&r.result.paper_pso),
                },
            )
        })
        .collect()
}
