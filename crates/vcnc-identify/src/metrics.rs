//! Fit metrics of a model on a trace (docs/identification.md, "Outputs"): one-step (equation-error)
//! prediction, free-run simulation, and fit % of the tracking error.

use serde::{Deserialize, Serialize};
use vcnc_drive::{ClosedLoopModel, DriveModel, Reference, SimOptions};

use crate::Error;
use crate::options::IdentifyOptions;
use crate::regress::Regressors;
use crate::trace::Trace;

/// How well a model reproduces one trace. Positions in axis units (mm or deg).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct FitMetrics {
    /// RMS one-step (equation-error) prediction error: $Y_k - \Phi_k\Theta$ of paper eq. 7 on the
    /// prefiltered regressors, axis units.
    pub onestep_rms: f64,
    /// RMS free-run error $x_k - \hat x_k$ of the simulated model ([`free_run`]), axis units.
    pub freerun_rms: f64,
    /// Largest free-run error, axis units.
    pub freerun_max: f64,
    /// Fit of the tracking error $y = x_r - x$:
    /// $100\,(1 - \|y - \hat y\|/\|y - \bar y\|)$, %, with $\hat y = x_r - \hat x$ free-run.
    pub fit_percent: f64,
    /// RMS measured tracking error $x_r - x$, axis units.
    pub tracking_rms: f64,
    /// Peak measured tracking error $|x_r - x|$, axis units.
    pub tracking_peak: f64,
    /// Samples compared.
    pub samples: usize,
    /// Free-run model position $\hat x_k$ at every sample, axis units (for plots; not
    /// serialised).
    #[serde(skip)]
    pub predicted_x: Vec<f64>,
}

impl FitMetrics {
    /// Free-run RMS error relative to the peak measured tracking error.
    pub fn freerun_rms_over_peak(&self) -> f64 {
        self.freerun_rms / self.tracking_peak
    }
}

/// Free-run simulation of `model` driven by the trace's reference, starting at rest at the
/// first sample, or, for a trace that starts moving, at the measured $x_0$ one sample before the
/// first ([`Trace::prefixed_reference`], docs/drive-model.md and docs/reference-numbers.md): exact first-order-hold discretisation, friction sign of the simulated velocity
/// ([`ClosedLoopModel::simulate`] with default options). Returns $\hat x_k$, axis units.
pub fn free_run(model: &ClosedLoopModel, trace: &Trace) -> Result<Vec<f64>, Error> {
    free_run_model(&DriveModel::from(*model), trace)
}

/// Free run of a model of any structure ([`DriveModel`]) driven by the trace's reference,
/// starting as [`free_run`] does. The reference drives it as the identification fits it:
/// through its exact velocity and acceleration when the trace carries them and the model has
/// the paper's structure ([`DriveModel::simulate`]), else through the first-order hold of the
/// positions alone ([`DriveModel::simulate_positions`]: a measured trace's positions are used
/// without differencing). Returns $\hat x_k$, axis units.
pub fn free_run_model(model: &DriveModel, trace: &Trace) -> Result<Vec<f64>, Error> {
    let (pos, vel, acc, prefixed) = trace.prefixed_reference();
    let opts = SimOptions::default();
    let mut x = if trace.reference_derivatives.is_some() && model.is_core_only() {
        let r = Reference {
            pos: &pos,
            vel: &vel,
            acc: &acc,
        };
        model.simulate(r, trace.ts, &opts)?
    } else {
        model.simulate_positions(&pos, trace.ts, &opts)?
    };
    if prefixed {
        x.remove(0);
    }
    Ok(x)
}

/// RMS free-run error of `model` on `trace`, axis units (∞ when not finite).
pub(crate) fn freerun_rms(model: &DriveModel, trace: &Trace) -> Result<f64, Error> {
    let xh = free_run_model(model, trace)?;
    let s2: f64 = xh
        .iter()
        .zip(&trace.x)
        .map(|(a, b)| (a - b) * (a - b))
        .sum();
    let v = (s2 / trace.len().max(1) as f64).sqrt();
    Ok(if v.is_finite() { v } else { f64::INFINITY })
}

/// Scores a model of any structure on any trace (the validation of a model on a recording it
/// was not fitted on): free-run RMS and largest error, one-step RMS, fit % and the tracking
/// error ([`FitMetrics`]), over the samples `range` of the trace (all of them when `None`;
/// the free run always starts at the trace's first sample, so a held-out tail is predicted
/// from the reference alone). The one-step error is the equation error of the model's core
/// (paper eq. 7) with the reference shaped by the model's dead time and filter and the
/// measured position freed of its extra pole, on the regressors of `opts`.
pub fn score(
    model: &DriveModel,
    trace: &Trace,
    range: Option<std::ops::Range<usize>>,
    opts: &IdentifyOptions,
) -> Result<FitMetrics, Error> {
    model.validate()?;
    let xhat = free_run_model(model, trace)?;
    let range = range.unwrap_or(0..trace.len());
    let range = range.start.min(trace.len())..range.end.min(trace.len());
    let onestep = one_step_shaped(model, trace, &range, opts).unwrap_or(f64::NAN);
    Ok(metrics_over(trace, xhat, range, onestep))
}

/// The one-step error of an extended model (see [`score`]).
fn one_step_shaped(
    model: &DriveModel,
    trace: &Trace,
    range: &std::ops::Range<usize>,
    opts: &IdentifyOptions,
) -> Result<f64, Error> {
    let sub = |v: &[f64]| v[range.clone()].to_vec();
    if model.is_core_only() {
        let tr = Trace::new(trace.ts, sub(&trace.xr), sub(&trace.x))?;
        let regs = Regressors::build(&tr, opts)?;
        return Ok(regs.one_step_rms(&model.core));
    }
    // The reference as the core receives it: the model with a unit core (x = shaped xr).
    let unit = DriveModel {
        core: ClosedLoopModel {
            a1: 0.0,
            a2: 0.0,
            a3: 0.0,
            b0: 0.0,
            b1: 0.0,
            b2: 0.0,
            dc: 0.0,
        },
        extra_pole_hz: None,
        ..*model
    };
    let shaped = shape_reference(&unit, trace)?;
    let mut xc = trace.x.clone();
    if let Some(pe) = model.extra_pole_hz {
        // x = P x_c with P = p/(s + p): x_c = x + x'/p (central differences).
        let p = std::f64::consts::TAU * pe;
        let n = xc.len();
        for (k, v) in xc.iter_mut().enumerate().take(n.saturating_sub(1)).skip(1) {
            *v = trace.x[k] + (trace.x[k + 1] - trace.x[k - 1]) / (2.0 * trace.ts * p);
        }
    }
    let tr = Trace::new(trace.ts, sub(&shaped), sub(&xc))?;
    let regs = Regressors::build(&tr, opts)?;
    Ok(regs.one_step_rms(&model.core))
}

/// The reference after a model's dead time and filter, at the samples, axis units: the
/// filter's output, computed with the model's own exact scheme (a core that passes its
/// reference through: $b_0 = 1$ with $a_i = 0$ gives $\ddot x = \ddot x_{r,f}$).
fn shape_reference(unit: &DriveModel, trace: &Trace) -> Result<Vec<f64>, Error> {
    let mut m = *unit;
    m.core.b0 = 1.0;
    let (pos, _, _, prefixed) = trace.prefixed_reference();
    let mut x = m.simulate_positions(&pos, trace.ts, &SimOptions::default())?;
    if prefixed {
        x.remove(0);
    }
    Ok(x)
}

fn metrics_over(
    trace: &Trace,
    xhat: Vec<f64>,
    range: std::ops::Range<usize>,
    onestep_rms: f64,
) -> FitMetrics {
    let n = range.len().max(1);
    let (mut s2, mut mx) = (0.0, 0.0f64);
    for k in range.clone() {
        let d = trace.x[k] - xhat[k];
        s2 += d * d;
        mx = mx.max(d.abs());
    }
    let e: Vec<f64> = range.clone().map(|k| trace.xr[k] - trace.x[k]).collect();
    let mean_e = e.iter().sum::<f64>() / n as f64;
    let var_e: f64 = e.iter().map(|v| (v - mean_e).powi(2)).sum();
    let fit_percent = if var_e > 0.0 && s2.is_finite() {
        100.0 * (1.0 - (s2 / var_e).sqrt())
    } else {
        f64::NEG_INFINITY
    };
    FitMetrics {
        onestep_rms,
        freerun_rms: if s2.is_finite() {
            (s2 / n as f64).sqrt()
        } else {
            f64::INFINITY
        },
        freerun_max: if mx.is_finite() { mx } else { f64::INFINITY },
        fit_percent,
        tracking_rms: (e.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt(),
        tracking_peak: e.iter().fold(0.0, |a, v| a.max(v.abs())),
        samples: range.len(),
        predicted_x: xhat[range].to_vec(),
    }
}

/// Fit metrics of `model` on `trace`, with the prefilter and deadband of `opts` for the
/// one-step prediction.
pub fn fit_metrics(
    model: &ClosedLoopModel,
    trace: &Trace,
    opts: &IdentifyOptions,
) -> Result<FitMetrics, Error> {
    let regs = Regressors::build(trace, opts)?;
    fit_metrics_with(model, trace, &regs)
}

/// [`fit_metrics`] with the trace's regressors already built (several models on one trace
/// share the filter and Gram pass).
pub fn fit_metrics_with(
    model: &ClosedLoopModel,
    trace: &Trace,
    regs: &Regressors,
) -> Result<FitMetrics, Error> {
    let xhat = free_run(model, trace)?;
    Ok(metrics_over(
        trace,
        xhat,
        0..trace.len(),
        regs.one_step_rms(model),
    ))
}
