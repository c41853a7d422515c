//! The summaries of `vcnc demo` (the NMV5000 and the spiral: identification and prediction
//! with the identified models and the paper's) and of `vcnc demo --realistic`
//! ([`crate::realistic`]).

use std::collections::BTreeMap;

use serde::Serialize;

use crate::identify::AxisOverview;
use crate::predict::ContourSummary;
use crate::realistic::{
    BudgetRow, Discrepancy, Evaluation, RealisticAxis, TARGET_ORIENTATION_MRAD, TARGET_TIP_UM, set,
};

/// What both demos' `summary.json` open with: vcnc's models' prediction (its keys at the top
/// level), the run's names and the paper-PSO models' prediction.
#[derive(Debug, Clone, Serialize)]
pub struct DemoPrediction {
    /// vcnc's models' prediction.
    #[serde(flatten)]
    pub contour: ContourSummary,
    pub machine: String,
    pub program: &'static str,
    /// How vcnc's models were made.
    pub models: &'static str,
    /// The paper-PSO models' prediction.
    pub paper_pso: ContourSummary,
}

/// `summary.json` of the demo.
#[derive(Debug, Clone, Serialize)]
pub struct DemoSummary {
    /// The refined models' prediction.
    #[serde(flatten)]
    pub prediction: DemoPrediction,
    /// Per axis: pole errors of both model sets, %.
    pub identification: BTreeMap<String, AxisOverview>,
}

/// `summary.json` of `vcnc demo --realistic`.
#[derive(Debug, Clone, Serialize)]
pub struct RealisticSummary {
    /// vcnc's chosen models' prediction and the paper's method's.
    #[serde(flatten)]
    pub prediction: DemoPrediction,
    /// vcnc's chosen models with the actual-value latency stated from the machine's control
    /// configuration.
    pub stated_latency: StatedLatency,
    /// Per axis: poles against the rigid truth, structures and their validation errors.
    pub identification: BTreeMap<String, RealisticAxis>,
    /// The target and whether vcnc's models meet it.
    pub target: Target,
    /// One effect group at a time (`--budget`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub effect_budget: Option<Vec<BudgetRow>>,
}

/// The prediction of vcnc's models with a stated actual-value latency.
#[derive(Debug, Clone, Serialize)]
pub struct StatedLatency {
    /// Where the latency comes from.
    pub source: &'static str,
    /// Per axis, s.
    pub actual_latency_s: BTreeMap<String, f64>,
    /// The contour figures.
    #[serde(flatten)]
    pub contour: ContourSummary,
}

/// Where the realistic demo's stated latency comes from.
pub const STATED_LATENCY_SOURCE: &str = "stated, not identified: the machine's control      configuration, feedback.dead_time_cycles / servo_rate_hz (the logged actual position is the      reading the position loop used); the models' positions advanced by it (docs/drive-model.md)";

/// The realistic demo's target ([`TARGET_TIP_UM`], [`TARGET_ORIENTATION_MRAD`]) and whether
/// vcnc's models meet it.
#[derive(Debug, Clone, Serialize)]
pub struct Target {
    /// Largest tool-tip discrepancy allowed, µm.
    pub tip_max_um: f64,
    /// Largest orientation discrepancy allowed, mrad.
    pub orientation_max_mrad: f64,
    /// vcnc's discrepancy.
    pub model: Discrepancy,
    /// vcnc's discrepancy with the stated actual-value latency.
    pub model_stated_latency: Discrepancy,
    /// The paper's method's.
    pub paper_pso: Discrepancy,
    /// Whether vcnc's models meet both.
    pub reached: bool,
    /// Whether vcnc's models with the stated latency meet both.
    pub reached_with_stated_latency: bool,
}

impl RealisticSummary {
    /// The summary of an evaluation of the realistic machine `machine` on the program
    /// `program`, with the effect budget when it was run.
    pub fn new(
        machine: &str,
        program: &'static str,
        e: &Evaluation,
        effect_budget: Option<Vec<BudgetRow>>,
    ) -> RealisticSummary {
        let s = &e.outcome.summaries;
        let f = &e.outcome.figures;
        let (model, stated) = (
            Discrepancy::of(&f[set::MODEL]),
            Discrepancy::of(&f[set::MODEL_STATED]),
        );
        RealisticSummary {
            prediction: DemoPrediction {
                contour: s[set::MODEL].clone(),
                machine: machine.to_string(),
                program,
                models: "identified, structure chosen by validation error (PSO + output-error refinement)",
                paper_pso: s[set::PAPER].clone(),
            },
            stated_latency: StatedLatency {
                source: STATED_LATENCY_SOURCE,
                actual_latency_s: e
                    .ids
                    .iter()
                    .zip(&e.actual_latency_s)
                    .map(|(r, l)| (r.axis.to_string(), *l))
                    .collect(),
                contour: s[set::MODEL_STATED].clone(),
            },
            identification: e
                .ids
                .iter()
                .filter_map(|r| Some((r.axis.to_string(), RealisticAxis::of(r)?)))
                .collect(),
            target: Target {
                tip_max_um: TARGET_TIP_UM,
                orientation_max_mrad: TARGET_ORIENTATION_MRAD,
                model,
                model_stated_latency: stated,
                paper_pso: Discrepancy::of(&f[set::PAPER]),
                reached: model.meets_target(),
                reached_with_stated_latency: stated.meets_target(),
            },
            effect_budget,
        }
    }
}
