//! Fit metrics of a model on a trace (docs/identification.md, "Outputs"): one-step (equation-error)
//! prediction, free-run simulation, and fit % of the tracking error.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use vcnc_drive::{ClosedLoopModel, DriveModel, ModelInput, ModelRun, Reference, SimOptions};

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
    /// For a trace that starts moving: the model's state at the first sample, estimated from
    /// the samples not scored (docs/identification.md, "Traces that start moving"), as the
    /// states of [`DriveModel::realisation`] in deviations from the first reference position;
    /// `None` when the free run starts at rest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_state: Option<Vec<f64>>,
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
/// starting as [`free_run`] does (at rest), with the model's input
/// ([`vcnc_drive::drive_model::ReferenceInput`]): through the exact reference velocity and
/// acceleration when the trace carries them and the model's input is smooth
/// ([`DriveModel::simulate`]), else rebuilt from the positions alone
/// ([`DriveModel::simulate_positions`]: their first-order hold, or their central differences).
/// Returns $\hat x_k$, axis units.
pub fn free_run_model(model: &DriveModel, trace: &Trace) -> Result<Vec<f64>, Error> {
    let (pos, vel, acc, prefixed) = trace.prefixed_reference();
    let opts = SimOptions::default();
    let mut x = if trace.reference_derivatives.is_some() {
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

/// A free run of `model` through the trace's reference with the model's input, from the state
/// `z0` at the first sample (empty: rest), with its friction levels.
fn run_from(model: &DriveModel, trace: &Trace, z0: &[f64]) -> Result<ModelRun, Error> {
    let opts = SimOptions::default();
    match &trace.reference_derivatives {
        Some((vel, acc)) if model.input == vcnc_drive::drive_model::ReferenceInput::Smooth => {
            let r = Reference {
                pos: &trace.xr,
                vel,
                acc,
            };
            Ok(model.simulate_run_from(ModelInput::Derivatives(r), trace.ts, &opts, z0)?)
        }
        _ => {
            let input = model.input_of(&trace.xr, trace.ts);
            Ok(model.simulate_run_from(input.as_input(), trace.ts, &opts, z0)?)
        }
    }
}

/// Free run of `model` through `trace` from the initial state that best explains the
/// measured position over the samples `fit` (docs/identification.md, "Traces that start
/// moving"): the run from rest at the first sample, its residual $x_k - \hat x_k$ regressed on
/// the free responses $c_x \Phi^k e_j$ of the model's realisation (least squares over `fit`),
/// the state corrected and the run repeated, as the friction of the run depends on the state ([`STATE_ROUNDS`] corrections). The samples within the dead time are left out of
/// `fit` (the reference before the first sample is not known). Returns the run, the state and
/// the first sample the state was fitted on: the first the run predicts (before it the state,
/// fitted from later samples, can be anything).
pub(crate) fn run_from_estimated_state(
    model: &DriveModel,
    trace: &Trace,
    fit: std::ops::Range<usize>,
) -> Result<(ModelRun, Vec<f64>, usize), Error> {
    /// Most states of a realisation: filter (2), core (3), extra pole (1).
    const NS: usize = 6;
    let real = model.realisation();
    let ns = real.a.nrows();
    let phi = (&real.a * trace.ts).exp();
    let fit = fit
        .start
        .max(first_predicted(model, trace.ts))
        .min(trace.len())..fit.end.min(trace.len());
    let mut z = vec![0.0; ns];
    let mut run = run_from(model, trace, &[])?;
    if fit.len() < 4 * ns || ns > NS {
        return Ok((run, z, fit.start));
    }
    let phi_t: [[f64; NS]; NS] = std::array::from_fn(|i| {
        std::array::from_fn(|j| if i < ns && j < ns { phi[(j, i)] } else { 0.0 })
    });
    for _ in 0..STATE_ROUNDS {
        // Normal equations of the free responses over `fit`, rows propagated as c_x Phi^k.
        let mut g = [[0.0; NS]; NS];
        let mut b = [0.0; NS];
        let mut row: [f64; NS] = std::array::from_fn(|i| if i < ns { real.cx[i] } else { 0.0 });
        for k in 0..fit.end {
            if k >= fit.start {
                let r = trace.x[k] - run.position[k];
                for i in 0..ns {
                    b[i] += row[i] * r;
                    for j in i..ns {
                        g[i][j] += row[i] * row[j];
                    }
                }
            }
            let mut next = [0.0; NS];
            for (i, v) in next.iter_mut().enumerate().take(ns) {
                *v = (0..ns).map(|j| phi_t[i][j] * row[j]).sum();
            }
            flush_negligible(&mut next);
            row = next;
        }
        let gm = DMatrix::from_fn(ns, ns, |i, j| g[i.min(j)][i.max(j)]);
        let bm = DVector::from_fn(ns, |i, _| b[i]);
        let Some(dz) = solve_spd(&gm, &bm) else {
            break;
        };
        for (zi, d) in z.iter_mut().zip(dz.iter()) {
            *zi += d;
        }
        run = match run_from(model, trace, &z) {
            Ok(r) => r,
            Err(_) => break,
        };
    }
    Ok((run, z, fit.start))
}

/// A free response below this, against the 1 of the first sample's, is nothing a fit can use
/// (its coefficient would have to be $10^{100}$ times the first sample's to matter).
const NEGLIGIBLE_RESPONSE: f64 = 1e-100;

/// Sets each of the free responses `v` (of the modes of a moving start, one sample's) below
/// [`NEGLIGIBLE_RESPONSE`] to zero. Left alone they decay into subnormal numbers and stay there
/// (round-to-nearest keeps the smallest subnormal under a factor near 1), and every product
/// with a subnormal is a microcode assist: on a 570 k-sample moving start 1.7 M of the 4 M
/// values of the fit's columns were subnormal and each evaluation took 11 times as long as the
/// same trace's at rest (perf; `cols.iter().filter(is_subnormal)`). Zero stays zero, at full
/// speed.
pub(crate) fn flush_negligible(v: &mut [f64]) {
    for x in v.iter_mut() {
        if x.abs() < NEGLIGIBLE_RESPONSE {
            *x = 0.0;
        }
    }
}

/// The first sample a run from an estimated state may be fitted on: the first sample and those
/// within the model's dead time depend on the reference before the trace, which is not known.
fn first_predicted(model: &DriveModel, ts: f64) -> usize {
    (model.delay_s / ts).ceil() as usize + 1
}

/// Corrections of the estimated initial state ([`run_from_estimated_state`]): the friction of
/// the run depends on the state, so the linear estimate is repeated once on the corrected run.
const STATE_ROUNDS: usize = 2;

/// Least squares on the upper triangle of a symmetric Gram matrix `g`: column-scaled, solved by
/// a truncated SVD (directions the data do not determine, relative singular value below
/// $10^{-10}$, are left at zero).
fn solve_spd(g: &DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
    let n = g.nrows();
    let d: Vec<f64> = (0..n)
        .map(|i| {
            let v = g[(i, i)];
            if v > 0.0 && v.is_finite() {
                1.0 / v.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let a = DMatrix::from_fn(n, n, |i, j| {
        let (lo, hi) = (i.min(j), i.max(j));
        g[(lo, hi)] * d[i] * d[j]
    });
    let rhs = DVector::from_fn(n, |i, _| b[i] * d[i]);
    let svd = a.svd(true, true);
    let top = svd.singular_values.max();
    let y = svd.solve(&rhs, 1e-10 * top).ok()?;
    let x = DVector::from_fn(n, |i, _| y[i] * d[i]);
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The free run that scores `model` on `trace` over the samples `range` (all: `None`): from
/// rest ([`free_run_model`]) for a trace that starts at rest; for one that starts moving, from
/// the state estimated on the samples before `range` (on all samples when `range` is `None`,
/// as for an estimation run whose fit is its own; from rest when `range` starts at the first
/// sample, the samples after it being the ones a model fitted on them has seen).
pub(crate) fn scored_run(
    model: &DriveModel,
    trace: &Trace,
    range: Option<std::ops::Range<usize>>,
) -> Result<ScoredRun, Error> {
    let n = trace.len();
    let fit = match &range {
        _ if trace.starts_at_rest(crate::trace::REST_SPEED) => None,
        None => Some(0..n),
        Some(r) if r.start > 0 => Some(0..r.start),
        Some(_) => None,
    };
    let range = range.map_or(0..n, |r| r.start.min(n)..r.end.min(n));
    match fit {
        Some(fit) => {
            let (run, z, fitted) = run_from_estimated_state(model, trace, fit)?;
            let first = range.start.max(fitted).min(range.end);
            Ok(ScoredRun {
                position: run.position,
                state: Some(z),
                first,
                range,
            })
        }
        None => Ok(ScoredRun {
            position: free_run_model(model, trace)?,
            state: None,
            first: range.start,
            range,
        }),
    }
}

/// A free run to score ([`scored_run`]).
pub(crate) struct ScoredRun {
    /// The model's positions at every sample.
    position: Vec<f64>,
    /// The estimated initial state of a run that starts moving.
    state: Option<Vec<f64>>,
    /// The samples asked for (all when `None`).
    range: std::ops::Range<usize>,
    /// The first sample of `range` to score: its first, or for a run from an estimated state
    /// the first its state was fitted on ([`run_from_estimated_state`]: were the samples before it scored, a
    /// fast state the fit barely sees, an extra pole far above the sample rate, would count at
    /// the first sample with whatever value fitted the second).
    first: usize,
}

impl ScoredRun {
    /// The run's metrics with the one-step error `onestep_rms`.
    fn metrics(self, trace: &Trace, onestep_rms: f64) -> FitMetrics {
        let mut m = metrics_over(trace, self.position, self.range, self.first, onestep_rms);
        m.initial_state = self.state;
        m
    }
}

/// Scores a model of any structure on any trace (the validation of a model on a recording it
/// was not fitted on): free-run RMS and largest error, one-step RMS, fit % and the tracking
/// error ([`FitMetrics`]), over the samples `range` of the trace (all of them when `None`;
/// the free run always starts at the trace's first sample, so a held-out tail is predicted
/// from the reference alone). A trace that starts moving is run from the state estimated on
/// the samples before `range` (all samples when `None`; [`FitMetrics::initial_state`]) and
/// scored from the first sample it predicts (after the first and the dead time). The one-step
/// error is the equation error of the model's core
/// (paper eq. 7) with the reference shaped by the model's dead time and filter and the
/// measured position freed of its extra pole, on the regressors of `opts`.
pub fn score(
    model: &DriveModel,
    trace: &Trace,
    range: Option<std::ops::Range<usize>>,
    opts: &IdentifyOptions,
) -> Result<FitMetrics, Error> {
    model.validate()?;
    let run = scored_run(model, trace, range)?;
    let scored = run.first..run.range.end;
    let onestep = one_step_shaped(model, trace, &scored, opts).unwrap_or(f64::NAN);
    Ok(run.metrics(trace, onestep))
}

/// The one-step error of an extended model (see [`score`]).
fn one_step_shaped(
    model: &DriveModel,
    trace: &Trace,
    range: &std::ops::Range<usize>,
    opts: &IdentifyOptions,
) -> Result<f64, Error> {
    let sub = |v: &[f64]| v[range.clone()].to_vec();
    if model.delay_s == 0.0 && model.reference_filter.is_none() && model.extra_pole_hz.is_none() {
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
/// reference through: $b_0 = 1$ with $a_i = 0$ gives $\ddot x = \ddot x_{r,f}$, driven by the
/// hold of the positions, whose acceleration impulses integrate back to the positions exactly).
fn shape_reference(unit: &DriveModel, trace: &Trace) -> Result<Vec<f64>, Error> {
    let mut m = *unit;
    m.core.b0 = 1.0;
    m.input = vcnc_drive::drive_model::ReferenceInput::Hold;
    let (pos, _, _, prefixed) = trace.prefixed_reference();
    let mut x = m.simulate_positions(&pos, trace.ts, &SimOptions::default())?;
    if prefixed {
        x.remove(0);
    }
    Ok(x)
}

/// The metrics of the run `xhat` scored over `first..range.end`, its positions kept over `range`.
fn metrics_over(
    trace: &Trace,
    xhat: Vec<f64>,
    range: std::ops::Range<usize>,
    first: usize,
    onestep_rms: f64,
) -> FitMetrics {
    let scored = first..range.end;
    let n = scored.len().max(1);
    let (mut s2, mut mx) = (0.0, 0.0f64);
    for k in scored.clone() {
        let d = trace.x[k] - xhat[k];
        s2 += d * d;
        mx = mx.max(d.abs());
    }
    let e: Vec<f64> = scored.clone().map(|k| trace.xr[k] - trace.x[k]).collect();
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
        samples: scored.len(),
        initial_state: None,
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

/// [`score`] of a model of the paper's structure (any input) over the whole trace, with the
/// trace's regressors already built.
pub(crate) fn score_paper(
    model: &DriveModel,
    trace: &Trace,
    regs: &Regressors,
) -> Result<FitMetrics, Error> {
    model.validate()?;
    Ok(scored_run(model, trace, None)?.metrics(trace, regs.one_step_rms(&model.core)))
}

/// [`fit_metrics`] with the trace's regressors already built (several models on one trace
/// share the filter and Gram pass).
pub fn fit_metrics_with(
    model: &ClosedLoopModel,
    trace: &Trace,
    regs: &Regressors,
) -> Result<FitMetrics, Error> {
    Ok(
        scored_run(&DriveModel::from(*model), trace, None)?
            .metrics(trace, regs.one_step_rms(model)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{MOVES, TS, smooth_moves};
    use vcnc_drive::TABLE1_MODEL;
    use vcnc_drive::drive_model::ReferenceInput;

    #[test]
    fn a_moving_start_is_scored_from_the_first_sample_it_predicts() {
        // Truth: the model itself, with a 2 kHz extra pole at 1 kHz sampling (its mode decays
        // by e^{-4π} ≈ 3.5e-6 in a sample), run through smooth moves and cut to start in the
        // middle of the first; 1e-5 mm of alternating noise on the measured position. The
        // state estimate fits the second sample's noise with an extra-pole state of about
        // 1e-5 / 3.5e-6 ≈ 3 mm, which the first sample shows; scored from the second sample,
        // the error is the noise.
        let model = DriveModel {
            extra_pole_hz: Some(2000.0),
            input: ReferenceInput::Hold,
            ..DriveModel::from(TABLE1_MODEL)
        };
        let n = 3000;
        let (p, _, _) = smooth_moves(n, &MOVES);
        let x = model
            .simulate_positions(&p, TS, &SimOptions::default())
            .unwrap();
        let cut = 220; // the first move (0.1 .. 0.35 s) at full speed
        let noisy: Vec<f64> = x[cut..]
            .iter()
            .enumerate()
            .map(|(k, v)| v + if k % 2 == 0 { 1e-5 } else { -1e-5 })
            .collect();
        let tr = Trace::new(TS, p[cut..].to_vec(), noisy).unwrap();
        assert!(!tr.starts_at_rest(crate::trace::REST_SPEED));
        let m = score(&model, &tr, None, &IdentifyOptions::default()).unwrap();
        assert_eq!(m.predicted_x.len(), tr.len(), "positions at every sample");
        // Measured 1.16e-5 mm (the noise's 1e-5); twice that allowed. Scored from the first
        // sample: 3.64 mm.
        assert!(m.freerun_max < 2.5e-5, "largest error {} mm", m.freerun_max);
        assert_eq!(m.samples, tr.len() - 1, "scored from the second sample");
        // The held-out part alone: scored over the range asked for.
        let part = score(&model, &tr, Some(1000..2000), &IdentifyOptions::default()).unwrap();
        assert_eq!((part.samples, part.predicted_x.len()), (1000, 1000));
    }
}
