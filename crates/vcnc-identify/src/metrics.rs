//! Fit metrics of a model on a trace (docs/identification.md, "Outputs"): one-step (equation-error)
//! prediction, free-run simulation, and fit % of the tracking error.

use serde::{Deserialize, Serialize};
use vcnc_drive::{ClosedLoopModel, Reference, SimOptions};

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
    let (pos, vel, acc, prefixed) = trace.prefixed_reference();
    let r = Reference {
        pos: &pos,
        vel: &vel,
        acc: &acc,
    };
    let mut x = model.simulate(r, trace.ts, &SimOptions::default())?;
    if prefixed {
        x.remove(0);
    }
    Ok(x)
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
    let n = trace.len();
    let (mut s2, mut mx) = (0.0, 0.0f64);
    for (x, xh) in trace.x.iter().zip(&xhat) {
        let d = x - xh;
        s2 += d * d;
        mx = mx.max(d.abs());
    }
    let mean_e = trace
        .xr
        .iter()
        .zip(&trace.x)
        .map(|(r, x)| r - x)
        .sum::<f64>()
        / n as f64;
    let var_e: f64 = trace
        .xr
        .iter()
        .zip(&trace.x)
        .map(|(r, x)| (r - x - mean_e).powi(2))
        .sum();
    let fit_percent = if var_e > 0.0 && s2.is_finite() {
        100.0 * (1.0 - (s2 / var_e).sqrt())
    } else {
        f64::NEG_INFINITY
    };
    Ok(FitMetrics {
        onestep_rms: regs.one_step_rms(model),
        freerun_rms: if s2.is_finite() {
            (s2 / n as f64).sqrt()
        } else {
            f64::INFINITY
        },
        freerun_max: if mx.is_finite() { mx } else { f64::INFINITY },
        fit_percent,
        tracking_rms: trace.tracking_rms(),
        tracking_peak: trace.tracking_peak(),
        samples: n,
        predicted_x: xhat,
    })
}
