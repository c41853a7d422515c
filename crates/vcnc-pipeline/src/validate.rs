//! `vcnc validate`: an identified model scored on a measured trace it was not fitted on
//! (docs/identification.md#validation).
//!
//! ```text
//!   model.toml ──AxisModel──┐
//!   trace file ──read, pair─┴─▶ per axis: free run of the model from the nominal position
//!                                 ──▶ free-run / one-step errors, fit %, tracking error
//! ```
//!
//! The model runs from the trace's nominal position alone, started where the trace starts (a
//! trace that starts in motion is prefixed the way identification prefixes it), so its error is
//! the error a user would see predicting that run with the model: nothing of the measured
//! position enters the free run. The one-step error is the equation error of paper eq. 7 with
//! the measured position, reported beside it.

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::Serialize;
use vcnc_axis::{AxisName, Unit};
use vcnc_drive::DriveModel;
use vcnc_identify::{FitMetrics, IdentifyOptions, Trace};
use vcnc_machine::ModelSet;

use crate::Error;
use crate::summary::{FitSummary, ModelSummary};
use crate::traces::MeasuredTrace;

/// Decay rates below this (rad/s, 0.5 Hz) are left out of the start-transient window: they are
/// the near-integrator pole of a drive without integral action ($p \to 0$), whose share of the
/// response is negligible, and would stretch the window past the trace.
const SETTLE_MIN_RATE: f64 = std::f64::consts::PI;

/// One axis of a trace scored with its model.
#[derive(Debug, Clone)]
pub struct AxisValidation {
    /// The axis.
    pub axis: AxisName,
    /// mm or deg.
    pub unit: Unit,
    /// The model scored.
    pub model: DriveModel,
    /// The measured samples.
    pub trace: Trace,
    /// Its scores (with the model's free-run positions).
    pub fit: FitMetrics,
    /// A trace that starts in motion: the model starts at rest (it cannot know the drive's
    /// state), so its first samples carry a start transient. The scores after that transient
    /// has decayed (five time constants of the model's slowest pole faster than 0.5 Hz), and
    /// where they start.
    pub settled: Option<(usize, FitMetrics)>,
    /// Whether the trace starts in motion (the model starts at rest: a start transient).
    pub moving_start: bool,
    /// Where the samples come from.
    pub provenance: vcnc_trace::Provenance,
}

/// Scores the model of every paired axis of `m` (or of the `axes` named) from `models`
/// (`model_file` names it in messages). Every axis scored must have a model of its unit; an
/// axis named but absent from the trace or the model file is refused.
pub fn validate_measured(
    m: &MeasuredTrace,
    models: &ModelSet,
    model_file: &str,
    axes: &[AxisName],
) -> Result<Vec<AxisValidation>, Error> {
    let file = &m.paired.file;
    let in_models = |a: AxisName| models.axes.get(&a.to_string());
    let model_axes = || models.axes.keys().cloned().collect::<Vec<_>>().join(" ");
    let trace_axes = || {
        m.paired
            .axes
            .iter()
            .map(|a| a.axis.to_string())
            .collect::<Vec<_>>()
            .join(" ")
    };
    for a in axes {
        if !m.paired.axes.iter().any(|t| t.axis == *a) {
            return Err(Error::AxisNotInTrace {
                file: file.to_string(),
                axis: *a,
                has: trace_axes(),
            });
        }
        if in_models(*a).is_none() {
            return Err(Error::NoModelFor {
                file: model_file.to_string(),
                axis: *a,
                has: model_axes(),
            });
        }
    }
    // Each chosen axis with its model (an axis named is in both: checked above).
    let chosen: Vec<(&vcnc_trace::AxisTrace, &vcnc_machine::AxisModel)> = m
        .paired
        .axes
        .iter()
        .filter(|t| axes.is_empty() || axes.contains(&t.axis))
        .filter_map(|t| Some((t, in_models(t.axis)?)))
        .collect();
    if chosen.is_empty() {
        return Err(Error::NothingToValidate {
            file: file.to_string(),
            trace_axes: trace_axes(),
            model_file: model_file.to_string(),
            model_axes: model_axes(),
        });
    }
    let opts = IdentifyOptions::default();
    chosen
        .par_iter()
        .map(|(t, am)| {
            let subject = format!("{file} axis {}", t.axis);
            if am.unit != t.unit {
                return Err(Error::UnitMismatch {
                    file: model_file.to_string(),
                    axis: t.axis,
                    model: am.unit,
                    trace: t.unit,
                });
            }
            let model = am.model();
            let trace = Trace::new(t.ts_s, t.nominal.clone(), t.actual.clone())
                .map_err(|e| Error::identify(&subject, e))?;
            let fit = vcnc_identify::score(&model, &trace, None, &opts)
                .map_err(|e| Error::identify(&subject, e))?;
            let moving_start = !trace.starts_at_rest(vcnc_identify::REST_SPEED);
            let settle = model
                .slowest_decay_rate(SETTLE_MIN_RATE)
                .map(|r| ((5.0 / r + model.delay_s) / trace.ts).ceil() as usize)
                .filter(|k| moving_start && *k < trace.len() / 2);
            let settled = match settle {
                Some(k) => Some((
                    k,
                    vcnc_identify::score(&model, &trace, Some(k..trace.len()), &opts)
                        .map_err(|e| Error::identify(&subject, e))?,
                )),
                None => None,
            };
            if !fit.freerun_rms.is_finite() {
                return Err(Error::FreeRunDiverges {
                    subject,
                    ts_s: t.ts_s,
                });
            }
            Ok(AxisValidation {
                axis: t.axis,
                unit: t.unit,
                model,
                trace,
                fit,
                settled,
                moving_start,
                provenance: t.provenance.clone(),
            })
        })
        .collect()
}

/// `summary.json` of `vcnc validate`.
#[derive(Debug, Clone, Serialize)]
pub struct ValidateSummary {
    /// The trace file.
    pub trace: String,
    /// Its format.
    pub format: vcnc_trace::Format,
    /// The model file.
    pub models: String,
    /// Per axis.
    pub axes: BTreeMap<String, AxisValidateSummary>,
}

/// One axis in `summary.json` of `vcnc validate`.
#[derive(Debug, Clone, Serialize)]
pub struct AxisValidateSummary {
    /// mm or deg.
    pub unit: Unit,
    /// The model scored, with its structure.
    pub model: ModelSummary,
    /// Free-run and one-step errors, fit %, tracking error (µm or mdeg by the unit, named in
    /// the keys: `freerun_rms_um`, `freerun_max_um`, `onestep_rms_um`, `fit_percent`,
    /// `tracking_rms_um`, `tracking_peak_um`, `samples`).
    pub fit: FitSummary,
    /// Whether the trace starts in motion (the model starts at rest: a start transient).
    pub moving_start: bool,
    /// Traces that start in motion: the scores from `settled_from_s` on, after the model's
    /// start transient has decayed (five time constants of its slowest pole).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit_settled: Option<FitSummary>,
    /// Where `fit_settled` starts, s from the first sample.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub settled_from_s: Option<f64>,
    /// Sample period, s.
    pub ts_s: f64,
    /// Channels, units, alignment, segment used.
    #[serde(flatten)]
    pub provenance: vcnc_trace::Provenance,
}

impl ValidateSummary {
    /// Of scored axes.
    pub fn of(m: &MeasuredTrace, model_file: &str, v: &[AxisValidation]) -> ValidateSummary {
        ValidateSummary {
            trace: m.paired.file.clone(),
            format: m.paired.format,
            models: model_file.to_string(),
            axes: v
                .iter()
                .map(|a| {
                    (
                        a.axis.to_string(),
                        AxisValidateSummary {
                            unit: a.unit,
                            model: ModelSummary::of_drive(&a.model),
                            fit: FitSummary {
                                unit: a.unit,
                                fit: a.fit.clone(),
                            },
                            moving_start: a.moving_start,
                            fit_settled: a.settled.as_ref().map(|(_, f)| FitSummary {
                                unit: a.unit,
                                fit: f.clone(),
                            }),
                            settled_from_s: a.settled.as_ref().map(|(k, _)| *k as f64 * a.trace.ts),
                            ts_s: a.trace.ts,
                            provenance: a.provenance.clone(),
                        },
                    )
                })
                .collect(),
        }
    }
}
