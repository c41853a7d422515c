//! A machine whose drives are not the 7-parameter model's own structure (`vcnc demo
//! --realistic`): identification accuracy, the prediction discrepancy of the paper's method and
//! of vcnc's best model, and the effect budget — which drive effect costs how much prediction
//! accuracy (docs/machine-file.md#drive-effects names the effects).
//!
//! # The evaluation
//!
//! 1. Every axis is identified from its excitation run through the true drive, every effect on
//!    ([`crate::identify::identify_axes`], the machine's own identifier options: by default all
//!    model structures, the one with the smallest validation error chosen).
//! 2. The program runs through the true drives, through vcnc's chosen models
//!    (`result.model`) and through the paper's method (`result.paper_pso`: equation-error PSO,
//!    the paper's 7-parameter structure); [`ContourFigures`] compare the contour errors.
//! 3. vcnc's chosen models once more, each axis' positions advanced by the actual-value latency
//!    its control's configuration states (`feedback.dead_time_cycles` / `servo_rate_hz`,
//!    [`vcnc_machine::Axis::actual_latency_s`]; [`crate::latency`]). The models predict the
//!    logged actual position, which trails the physical axis by that latency; no
//!    identification can see it (a delay in the measurement and in the actuation give the same
//!    record), so this figure uses a number the user states, not one identified. The paper's
//!    method is evaluated as the paper does, without it.
//!
//! # The effect budget
//!
//! The same evaluation on the machine with ONE effect group at a time: each axis' drive is the
//! ideal one ([`vcnc_drive::DriveParams::ideal`]: same plant, gains and encoder resolution, no
//! encoder noise, no effect table) plus that group as the machine file sets it
//! ([`EffectGroup`]). The row of the ideal drive is the floor of the method itself; a group's
//! discrepancy above it is what that effect costs.

use rayon::prelude::*;
use serde::Serialize;
use vcnc_axis::{AxisName, Unit};
use vcnc_drive::{DriveParams, Feedback};
use vcnc_identify::ModelStructure;
use vcnc_machine::{Dynamics, Machine};

use crate::Error;
use crate::identify::{self, AxisIdentification};
use crate::predict::{self, ContourFigures, PredictOutcome, PredictPiece};
use crate::sink::{Discard, Sink};
use crate::source::Source;
use crate::summary::{FitSummary, ModelSummary, PoleErrors};

/// The target for vcnc's prediction of a realistic machine: largest tool-tip
/// discrepancy |predicted − true| over the feed moves, µm.
pub const TARGET_TIP_UM: f64 = 2.0;
/// The target's largest orientation discrepancy, mrad.
pub const TARGET_ORIENTATION_MRAD: f64 = 0.02;

/// One group of drive effects (docs/machine-file.md#drive-effects), as the budget
/// switches them on one at a time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum EffectGroup {
    /// `[compliance]` without its backlash: the two-mass transmission.
    Compliance,
    /// `[friction]`: Stribeck, direction-dependent and pre-sliding friction.
    Friction,
    /// `[compliance]` with its backlash (backlash is a dead zone in the transmission, so it
    /// comes with it: the cost of backlash is this row minus the compliance row).
    Backlash,
    /// `[current_loop]`: current-loop dynamics and torque limit.
    CurrentLoop,
    /// The encoder's noise and `[feedback]` without its dead time: sensor, velocity filter,
    /// motor encoder.
    NoiseFeedback,
    /// `feedback.dead_time_cycles` alone.
    DeadTime,
    /// `[reference]`: nominal-position filter and interpolation delay.
    ReferenceShaping,
}

impl EffectGroup {
    /// Every group, in the budget's order.
    pub const ALL: [EffectGroup; 7] = [
        EffectGroup::Compliance,
        EffectGroup::Friction,
        EffectGroup::Backlash,
        EffectGroup::CurrentLoop,
        EffectGroup::NoiseFeedback,
        EffectGroup::DeadTime,
        EffectGroup::ReferenceShaping,
    ];

    /// The name in tables and summaries.
    pub fn name(self) -> &'static str {
        match self {
            EffectGroup::Compliance => "compliance",
            EffectGroup::Friction => "friction",
            EffectGroup::Backlash => "compliance + backlash",
            EffectGroup::CurrentLoop => "current loop",
            EffectGroup::NoiseFeedback => "noise + feedback",
            EffectGroup::DeadTime => "dead time",
            EffectGroup::ReferenceShaping => "reference shaping",
        }
    }

    /// `p` (a drive with effects) reduced to the ideal drive plus this group.
    pub fn keep_only(self, p: &DriveParams) -> DriveParams {
        let mut q = ideal(p);
        match self {
            EffectGroup::Compliance => {
                q.compliance = p.compliance.clone().map(|mut c| {
                    c.backlash = 0.0;
                    c
                });
            }
            EffectGroup::Backlash => q.compliance = p.compliance.clone(),
            EffectGroup::Friction => q.friction = p.friction.clone(),
            EffectGroup::CurrentLoop => q.current_loop = p.current_loop.clone(),
            EffectGroup::NoiseFeedback => {
                q.encoder.noise_std = p.encoder.noise_std;
                q.feedback = p.feedback.clone().map(|f| Feedback {
                    dead_time_cycles: 0,
                    // A second (motor) encoder exists only on a two-mass drive.
                    motor_resolution: None,
                    motor_noise_std: 0.0,
                    ..f
                });
            }
            EffectGroup::DeadTime => {
                q.feedback = p.feedback.as_ref().map(|f| Feedback {
                    dead_time_cycles: f.dead_time_cycles,
                    ..Feedback::default()
                });
            }
            EffectGroup::ReferenceShaping => q.reference = p.reference.clone(),
        }
        q
    }
}

/// The ideal drive of the budget: `p` without effect tables and without encoder noise (its
/// resolution kept).
pub fn ideal(p: &DriveParams) -> DriveParams {
    let mut q = p.ideal();
    q.encoder.noise_std = 0.0;
    q
}

/// `machine` with every axis' drive replaced by `f(its parameters)`, checked.
pub fn machine_with(
    machine: &Machine,
    f: impl Fn(&DriveParams) -> DriveParams,
) -> Result<Machine, Error> {
    let mut m = machine.clone();
    for a in &mut m.axes {
        let params = a
            .require_drive(machine, "a variant of the machine's drives")?
            .params();
        let drive = f(&params).validate().map_err(|source| Error::Drive {
            axis: a.name,
            source,
        })?;
        a.dynamics = Dynamics::Drive(drive);
    }
    Ok(m)
}

/// Identification and prediction of one machine.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// Per axis, in machine order.
    pub ids: Vec<AxisIdentification>,
    /// The prediction of the program with three model sets, in this order ([`set`]): vcnc's
    /// chosen models (`result.model`) with their positions taken as the physical axes' (no
    /// actual-value latency); the same models with each axis' stated actual-value latency
    /// ([`Evaluation::actual_latency_s`]): the physical axes, the models' positions advanced by
    /// it; the paper's method (`result.paper_pso`).
    pub outcome: PredictOutcome,
    /// The actual-value latency stated per axis (machine order), s: the machine's control
    /// configuration ([`vcnc_machine::Axis::actual_latency_s`]), not identified.
    pub actual_latency_s: Vec<f64>,
}

/// Which model set of [`Evaluation::outcome`] is which.
pub mod set {
    /// vcnc's chosen models, no latency.
    pub const MODEL: usize = 0;
    /// vcnc's chosen models with the stated latency.
    pub const MODEL_STATED: usize = 1;
    /// The paper's method.
    pub const PAPER: usize = 2;
}

/// Identifies every axis of `machine` and predicts the program of `source` with vcnc's models
/// (without and with the stated actual-value latency) and the paper's method, the prediction's
/// pieces handed to `sink`.
pub fn evaluate<S: Sink<PredictPiece>>(
    machine: &Machine,
    source: Source<'_>,
    sink: &mut S,
) -> Result<Evaluation, S::Error> {
    let axes = identify::select_axes(machine, &[])?;
    let ids = identify::identify_axes(machine, &axes, None)?;
    let stated = identify::machine_models(machine, &ids, "identified")?;
    let latency: Vec<f64> = stated.latencies().collect();
    let best = stated.with_latencies(latency.iter().map(|_| 0.0));
    let paper = identify::paper_models(machine, &ids)?;
    let sets = [&best, &stated, &paper];
    let opts = predict::PredictOptions::default();
    let outcome = predict::predict(machine, source, &sets, &opts, sink)?;
    Ok(Evaluation {
        ids,
        outcome,
        actual_latency_s: latency,
    })
}

/// The contour statistics of a model set on a run (feed moves), in a summary's units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Discrepancy {
    /// Largest tool-tip |predicted − true|, µm.
    pub tip_max_um: f64,
    /// RMS tool-tip |predicted − true|, µm.
    pub tip_rms_um: f64,
    /// Largest orientation |predicted − true|, mrad.
    pub orientation_max_mrad: f64,
    /// RMS orientation |predicted − true|, mrad.
    pub orientation_rms_mrad: f64,
}

impl Discrepancy {
    /// The discrepancy rows of contour figures.
    pub fn of(f: &ContourFigures) -> Discrepancy {
        Discrepancy {
            tip_max_um: f.discrepancy_max.tip_um,
            tip_rms_um: f.discrepancy_rms.tip_um,
            orientation_max_mrad: f.discrepancy_max.orientation_mrad,
            orientation_rms_mrad: f.discrepancy_rms.orientation_mrad,
        }
    }

    /// Whether it meets [`TARGET_TIP_UM`] and [`TARGET_ORIENTATION_MRAD`].
    pub fn meets_target(&self) -> bool {
        self.tip_max_um <= TARGET_TIP_UM && self.orientation_max_mrad <= TARGET_ORIENTATION_MRAD
    }
}

/// A structure's free-run error on the validation run.
#[derive(Debug, Clone, Serialize)]
pub struct StructureValidation {
    /// The structure.
    pub structure: ModelStructure,
    /// Its free-run fit on the validation run (`freerun_max_um` …; µm or mdeg).
    pub validation: Option<FitSummary>,
}

/// One axis of a realistic machine's identification: the core poles against the true drive's
/// (the rigid 7-parameter model of its plant and gains: the "truth" a structured model's core
/// should approach, not the whole truth), and every structure's validation error.
#[derive(Debug, Clone, Serialize)]
pub struct RealisticAxis {
    /// `mm` or `deg`.
    pub unit: Unit,
    /// The true drive's rigid closed-loop model (docs/drive-model.md).
    #[serde(rename = "true")]
    pub truth: ModelSummary,
    /// The structure chosen by validation error.
    pub structure: ModelStructure,
    /// The chosen model.
    pub model: ModelSummary,
    /// Its core's pole errors against the truth, % (null when not writable as poles).
    pub model_error_percent: Option<PoleErrors>,
    /// The paper's method's model.
    pub paper_pso: ModelSummary,
    /// Its pole errors against the truth, %.
    pub paper_pso_error_percent: Option<PoleErrors>,
    /// Free-run fit of the chosen model on the validation run.
    pub model_validation: FitSummary,
    /// Free-run fit of the paper's method on the validation run.
    pub paper_pso_validation: FitSummary,
    /// Every structure tried and its validation error.
    pub structures: Vec<StructureValidation>,
}

impl RealisticAxis {
    /// The summary of one identified axis of a simulated machine.
    pub fn of(r: &AxisIdentification) -> Option<RealisticAxis> {
        let t = r.truth()?;
        let fit = |f: &vcnc_identify::FitMetrics| FitSummary {
            unit: r.unit,
            fit: f.clone(),
        };
        Some(RealisticAxis {
            unit: r.unit,
            truth: ModelSummary::of(t),
            structure: r.result.structure,
            model: ModelSummary::of_drive(&r.result.model),
            model_error_percent: PoleErrors::of_models(t, &r.result.model.core),
            paper_pso: ModelSummary::of(&r.result.paper_pso),
            paper_pso_error_percent: PoleErrors::of_models(t, &r.result.paper_pso),
            model_validation: fit(&r.validation),
            paper_pso_validation: fit(&r.validation_paper),
            structures: r
                .result
                .structures
                .iter()
                .map(|s| StructureValidation {
                    structure: s.structure,
                    validation: s.validation.as_ref().map(fit),
                })
                .collect(),
        })
    }
}

/// One row of the effect budget.
#[derive(Debug, Clone, Serialize)]
pub struct BudgetRow {
    /// `ideal`, or the group's name ([`EffectGroup::name`]).
    pub effect: &'static str,
    /// Largest true tool-tip contour error over the feed moves, µm.
    pub true_max_um: f64,
    /// vcnc's chosen models.
    pub model: Discrepancy,
    /// vcnc's chosen models with the stated actual-value latency
    /// (set [`set::MODEL_STATED`] of [`Evaluation::outcome`]).
    pub model_stated_latency: Discrepancy,
    /// The paper's method.
    pub paper_pso: Discrepancy,
    /// The structure chosen per axis.
    pub structures: Vec<(AxisName, ModelStructure)>,
}

impl BudgetRow {
    fn of(effect: &'static str, e: &Evaluation) -> BudgetRow {
        let f = &e.outcome.figures;
        BudgetRow {
            effect,
            true_max_um: f[set::MODEL].true_max.tip_um,
            model: Discrepancy::of(&f[set::MODEL]),
            model_stated_latency: Discrepancy::of(&f[set::MODEL_STATED]),
            paper_pso: Discrepancy::of(&f[set::PAPER]),
            structures: e.ids.iter().map(|r| (r.axis, r.result.structure)).collect(),
        }
    }
}

/// The effect budget of `machine` on the program of `source` (module documentation): the ideal
/// drives, then each [`EffectGroup`] alone. Configurations run in parallel, rows in that fixed
/// order.
pub fn effect_budget(machine: &Machine, source: Source<'_>) -> Result<Vec<BudgetRow>, Error> {
    let configs: Vec<Option<EffectGroup>> = std::iter::once(None)
        .chain(EffectGroup::ALL.into_iter().map(Some))
        .collect();
    configs
        .par_iter()
        .map(|g| {
            let m = match g {
                None => machine_with(machine, ideal)?,
                Some(g) => machine_with(machine, |p| g.keep_only(p))?,
            };
            let e = evaluate(&m, source, &mut Discard)?;
            Ok(BudgetRow::of(g.map_or("ideal", |g| g.name()), &e))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_group_keeps_only_its_own_tables_and_every_drive_is_valid() {
        // Truth: the tables of machines/nmv5000-realistic.toml (axis A has every effect,
        // backlash included).
        let m = Machine::embedded_nmv5000_realistic().unwrap();
        let p = m.axes[3].drive().expect("a drive").params();
        assert_eq!(m.axes[3].name.to_string(), "A");
        let base = ideal(&p);
        assert!(base.validate().unwrap().effects().is_ideal() && base.encoder.noise_std == 0.0);
        assert_eq!(base.encoder.resolution, p.encoder.resolution);
        for g in EffectGroup::ALL {
            let q = g.keep_only(&p);
            q.validate().unwrap_or_else(|e| panic!("{}: {e}", g.name()));
            let t = q.effect_tables();
            let on = [
                t.compliance.is_some(),
                t.friction.is_some(),
                t.current_loop.is_some(),
                t.feedback.is_some(),
                t.reference.is_some(),
            ];
            let want = match g {
                EffectGroup::Compliance | EffectGroup::Backlash => {
                    [true, false, false, false, false]
                }
                EffectGroup::Friction => [false, true, false, false, false],
                EffectGroup::CurrentLoop => [false, false, true, false, false],
                EffectGroup::NoiseFeedback | EffectGroup::DeadTime => {
                    [false, false, false, true, false]
                }
                EffectGroup::ReferenceShaping => [false, false, false, false, true],
            };
            assert_eq!(on, want, "{}", g.name());
            let noisy = q.encoder.noise_std != 0.0;
            assert_eq!(noisy, g == EffectGroup::NoiseFeedback, "{}", g.name());
        }
        let c = EffectGroup::Compliance.keep_only(&p).compliance.unwrap();
        assert_eq!(c.backlash, 0.0);
        let b = EffectGroup::Backlash.keep_only(&p).compliance.unwrap();
        assert!((b.backlash - 0.0011).abs() < 1e-12, "{}", b.backlash);
        let d = EffectGroup::DeadTime.keep_only(&p).feedback.unwrap();
        assert_eq!((d.dead_time_cycles, d.velocity_filter_hz), (2, None));
        let n = EffectGroup::NoiseFeedback.keep_only(&p).feedback.unwrap();
        assert_eq!(n.dead_time_cycles, 0);
        assert!(n.velocity_filter_hz.is_some());
        // The whole machine reduces and checks.
        machine_with(&m, ideal).unwrap();
        for g in EffectGroup::ALL {
            machine_with(&m, |p| g.keep_only(p)).unwrap();
        }
    }
}
