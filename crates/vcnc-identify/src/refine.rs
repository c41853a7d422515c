//! Output-error refinement (SPEC section 4, the step beyond the paper).
//!
//! The paper fits the equation error (eq. 16), whose regressors hold differentiated, noisy,
//! 1 kHz data: central differences bias the fit as $\omega_n T_s$ grows, and a real pole nearly
//! cancelled by a zero leaves the cost flat along $p$ (SPEC section 4). Here the free-run
//! simulation error of the model is minimised instead, over all seven parameters, within the
//! same pole bounds, so every model found is stable.
//!
//! Separable least squares (variable projection, Golub and Pereyra 1973): for a given friction
//! sign sequence $F$, the free run of the model as [`ClosedLoopModel::simulate`] computes it
//! (SPEC section 3: reference position, velocity and acceleration samples each held
//! first-order, the sign held per sample) is
//! $$ \hat x = \frac{a_3}{D} x_r + \frac{s}{D}\left(b_2 x_r + b_1 \dot x_r + b_0 \ddot x_r - d_c F\right), \qquad D = s^3 + a_1 s^2 + a_2 s + a_3. $$
//! For fixed poles it is linear in $(b_2, b_1, b_0, d_c)$: one pass simulates $x_r$,
//! $\dot x_r$, $\ddot x_r$ and $F$ through $1/D(s)$ (exact discretisation; the states
//! $w, \dot w, \ddot w$ of the companion form are the $s^k/D$-filtered signals), and a 4×4
//! least squares on the column-scaled normal equations gives the rest. The three pole
//! parameters $\sigma = (p, \omega_n, \zeta)$ are found by a bounded Levenberg–Marquardt on the
//! projected residual, with a forward-difference Jacobian whose three columns are evaluated in
//! parallel. Each evaluation is one allocation-free O(N) pass into buffers reused for the whole
//! run.
//!
//! The friction sign: stage A takes it from the measured motion (prefiltered velocity with the
//! deadband, as in the regressors). The model's own free run then switches friction when *its*
//! velocity changes sign, which differs near reversals and while the axis creeps into position;
//! so stage B repeats the fit with the sign of the previous model's free run (its own simulated
//! velocity, deadband of [`vcnc_drive::SimOptions`]), a fixed-point iteration on the full
//! free-run cost. Of the PSO start and every stage, the model with the smallest true free-run
//! RMS error ([`crate::free_run`]) is returned. On the Table 1 drive stage B takes the error of
//! $d_c$ from 7–15 % to 1–4 %.

use nalgebra::{Matrix3, SMatrix, Vector3};
use rayon::prelude::*;
use vcnc_drive::{ClosedLoopModel, Poles};

use crate::options::{PoleBounds, RefineOptions};
use crate::regress::Regressors;
use crate::trace::Trace;
use crate::Error;

/// Result of the output-error refinement.
#[derive(Debug, Clone, PartialEq)]
pub struct RefineResult {
    /// Refined model.
    pub model: ClosedLoopModel,
    /// Its poles (inside the bounds).
    pub poles: Poles,
    /// Output-error cost $\tfrac12\sum_k (x_k - \hat x_k)^2$ at the start of stage A
    /// (measured friction sign), axis units².
    pub start_cost: f64,
    /// Output-error cost of `model` with the friction sign of its stage, axis units².
    pub cost: f64,
    /// RMS output error of `model` with the friction sign of its stage, axis units.
    pub rms: f64,
    /// Cost after each accepted Levenberg–Marquardt step of the stage that produced `model`
    /// (for a convergence plot), axis units².
    pub cost_history: Vec<f64>,
    /// Every candidate considered, in order (the start, stage A, stage B iterations).
    pub stages: Vec<RefineStage>,
    /// Index in `stages` of the one returned.
    pub chosen: usize,
    /// Levenberg–Marquardt iterations made.
    pub iterations: usize,
    /// O(N) evaluations made.
    pub evaluations: usize,
}

/// One candidate of the refinement.
#[derive(Debug, Clone, PartialEq)]
pub struct RefineStage {
    /// Where its friction sign came from.
    pub sign: SignSource,
    /// Its model.
    pub model: ClosedLoopModel,
    /// Output-error cost with that sign, axis units² (NaN for the start).
    pub cost: f64,
    /// RMS error of the model's true free run ([`crate::free_run`]) on the trace, axis units.
    pub freerun_rms: f64,
}

/// Source of the friction sign sequence of a refinement stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignSource {
    /// No refinement: the PSO result itself.
    Start,
    /// Measured motion (stage A).
    Measured,
    /// The previous model's own free run (stage B), with the iteration number from 1.
    Model(usize),
}

/// The output-error problem of one trace, in deviations from the measured $x_0$, with one
/// sample prefixed at rest (index 0), exactly as [`crate::free_run`] simulates: reference
/// position, velocity and acceleration samples (first-order hold on each), measured position,
/// and the friction sign held over each sample interval.
#[derive(Debug, Clone)]
pub struct OutputErrorProblem {
    ts: f64,
    /// $x_r - x_0$, axis units.
    u: Vec<f64>,
    /// $\dot x_r$, axis units/s.
    ud: Vec<f64>,
    /// $\ddot x_r$, axis units/s².
    udd: Vec<f64>,
    /// $x - x_0$, axis units.
    x: Vec<f64>,
    /// Friction sign over $[t_k, t_{k+1}]$.
    f: Vec<f64>,
}

impl OutputErrorProblem {
    /// Builds the problem from a trace and its regressors, with the measured friction sign:
    /// $F_k = \mathrm{sgn}$ of the prefiltered displacement over $[t_k, t_{k+1}]$, with the
    /// deadband.
    pub fn new(trace: &Trace, regs: &Regressors) -> OutputErrorProblem {
        let (pos, ud, udd) = trace.prefixed_reference();
        let x0 = trace.x.first().copied().unwrap_or(0.0);
        let mut f = vec![0.0];
        f.extend(regs.interval_signs());
        let mut x = vec![0.0];
        x.extend(trace.x.iter().map(|v| v - x0));
        OutputErrorProblem {
            ts: trace.ts,
            u: pos.iter().map(|v| v - x0).collect(),
            ud,
            udd,
            x,
            f,
        }
    }

    /// A problem from its parts, all of one length with index 0 the rest sample before the
    /// start: sample period `ts` (s); reference deviation $x_r - x_0$ (axis units), its
    /// velocity and acceleration; measured deviation $x - x_0$; friction sign over each
    /// interval (-1, 0 or 1). Lengths are truncated to the shortest.
    pub fn from_parts(ts: f64, u: Vec<f64>, ud: Vec<f64>, udd: Vec<f64>, x: Vec<f64>, f: Vec<f64>) -> OutputErrorProblem {
        OutputErrorProblem { ts, u, ud, udd, x, f }
    }

    /// Friction sign of the model's own free run, exactly as [`ClosedLoopModel::simulate`]
    /// holds it: $F_k = \mathrm{sgn}(\hat v_k)$ with a deadband of `deadband` axis units/s, where
    /// $\hat v = \tfrac{a_3 s}{D} x_r + \tfrac{s^2}{D}(b_2 x_r + b_1 \dot x_r + b_0 \ddot x_r - d_c F)$
    /// is simulated sample by sample (the sign at $t_k$ is held over $[t_k, t_{k+1}]$). Errors
    /// when the model's poles cannot be discretised.
    pub fn model_signs(&self, model: &ClosedLoopModel, deadband: f64) -> Result<Vec<f64>, Error> {
        let d = model
            .poles()
            .and_then(|p| discretize(&p, self.ts))
            .ok_or(Error::Drive(vcnc_drive::Error::NonFiniteModel))?;
        let n = self.n();
        let (u, ud, udd) = (&self.u[..n], &self.ud[..n], &self.udd[..n]);
        let (om, om2) = (d.om, d.om * d.om);
        let (g0, g1) = ([d.g0[0], d.g0[1], d.g0[2]], [d.g1[0], d.g1[1], d.g1[2]]);
        let a3 = d.a[2];
        let (b0, b1, b2, dc) = (model.b0, model.b1, model.b2, model.dc);
        let (mut yu, mut yv, mut ya, mut yf) = ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3]);
        let mut f = vec![0.0; n];
        for k in 0..n {
            let v = a3 * om * yu[1] + om2 * (b2 * yu[2] + b1 * yv[2] + b0 * ya[2] - dc * yf[2]);
            let fk = vcnc_drive::model::friction_sign(v, deadband);
            f[k] = fk;
            let (du, dv, da) = match (u.get(k + 1), ud.get(k + 1), udd.get(k + 1)) {
                (Some(a), Some(b), Some(c)) => (a - u[k], b - ud[k], c - udd[k]),
                _ => (0.0, 0.0, 0.0),
            };
            let (pu, pv, pa, pf) = (mv(&d.phi, &yu), mv(&d.phi, &yv), mv(&d.phi, &ya), mv(&d.phi, &yf));
            for i in 0..3 {
                yu[i] = pu[i] + g0[i] * u[k] + g1[i] * du;
                yv[i] = pv[i] + g0[i] * ud[k] + g1[i] * dv;
                ya[i] = pa[i] + g0[i] * udd[k] + g1[i] * da;
                yf[i] = pf[i] + g0[i] * fk;
            }
        }
        if f.iter().any(|v| !v.is_finite()) {
            return Err(Error::Drive(vcnc_drive::Error::NonFiniteModel));
        }
        Ok(f)
    }

    /// Replaces the friction sign sequence.
    pub fn set_signs(&mut self, f: Vec<f64>) {
        self.f = f;
    }

    /// The friction sign sequence in use.
    pub fn signs(&self) -> &[f64] {
        &self.f
    }

    fn n(&self) -> usize {
        [self.u.len(), self.ud.len(), self.udd.len(), self.x.len(), self.f.len()]
            .into_iter()
            .min()
            .unwrap_or(0)
    }

    fn k(&self) -> usize {
        4
    }
}

/// Reusable buffers of one evaluation.
struct Work {
    cols: Vec<f64>,
    resid: Vec<f64>,
    cost: f64,
    theta: [f64; 7],
}

impl Work {
    fn new(n: usize, k: usize) -> Work {
        Work {
            cols: vec![0.0; n * k],
            resid: vec![0.0; n],
            cost: f64::INFINITY,
            theta: [0.0; 7],
        }
    }
}

/// Exact discretisation of $1/D(s)$ in time-scaled companion form (states
/// $y_j = w^{(j)}/\omega^j$ with $\omega = \omega_n$, which keeps every matrix entry of order
/// $\omega T_s$): $y_{k+1} = \Phi y_k + \gamma_0 u_k + \gamma_1 (u_{k+1} - u_k)$ for a
/// piecewise-linear input and $\gamma_0$ alone for an input held per sample.
struct Disc {
    phi: Matrix3<f64>,
    g0: Vector3<f64>,
    g1: Vector3<f64>,
    a: [f64; 3],
    om: f64,
}

fn discretize(poles: &Poles, ts: f64) -> Option<Disc> {
    let (a1, a2, a3) = poles.denominator();
    let om = poles.wn;
    if !(om > 0.0 && om.is_finite()) {
        return None;
    }
    let mut m = SMatrix::<f64, 5, 5>::zeros();
    m[(0, 1)] = om * ts;
    m[(1, 2)] = om * ts;
    m[(2, 0)] = -a3 / (om * om) * ts;
    m[(2, 1)] = -a2 / om * ts;
    m[(2, 2)] = -a1 * ts;
    m[(2, 3)] = ts / (om * om);
    m[(3, 4)] = ts;
    let e = m.exp();
    let phi = e.fixed_view::<3, 3>(0, 0).into_owned();
    let g0 = e.fixed_view::<3, 1>(0, 3).into_owned();
    let g1 = e.fixed_view::<3, 1>(0, 4).into_owned() / ts;
    if !(phi.iter().chain(g0.iter()).chain(g1.iter()).all(|v| v.is_finite())) {
        return None;
    }
    Some(Disc {
        phi,
        g0,
        g1,
        a: [a1, a2, a3],
        om,
    })
}

#[inline(always)]
fn mv(p: &Matrix3<f64>, y: &[f64; 3]) -> [f64; 3] {
    [
        p[(0, 0)] * y[0] + p[(0, 1)] * y[1] + p[(0, 2)] * y[2],
        p[(1, 0)] * y[0] + p[(1, 1)] * y[1] + p[(1, 2)] * y[2],
        p[(2, 0)] * y[0] + p[(2, 1)] * y[1] + p[(2, 2)] * y[2],
    ]
}

/// Fills the columns $[\tfrac{s}{D}x_r, \tfrac{s}{D}\dot x_r, \tfrac{s}{D}\ddot x_r, -\tfrac{s}{D}F]$
/// of the separable problem and returns their Gram matrix with the target
/// $x - a_3 \tfrac{1}{D} x_r$ last.
fn pass<const K: usize, const K1: usize>(
    prob: &OutputErrorProblem,
    d: &Disc,
    cols: &mut [f64],
    target: &mut [f64],
) -> [[f64; K1]; K1] {
    let n = prob.n();
    let (u, ud, udd, x, f) = (&prob.u[..n], &prob.ud[..n], &prob.udd[..n], &prob.x[..n], &prob.f[..n]);
    let om = d.om;
    let a3 = d.a[2];
    let (g0, g1) = ([d.g0[0], d.g0[1], d.g0[2]], [d.g1[0], d.g1[1], d.g1[2]]);
    let mut yu = [0.0; 3];
    let mut yv = [0.0; 3];
    let mut ya = [0.0; 3];
    let mut yf = [0.0; 3];
    let mut g = [[0.0; K1]; K1];
    let mut row = [0.0; K1];
    for (k, c) in cols.chunks_exact_mut(K).enumerate().take(n) {
        row[0] = om * yu[1];
        row[1] = om * yv[1];
        row[2] = om * ya[1];
        row[3] = -om * yf[1];
        row[K] = x[k] - a3 * yu[0];
        c.copy_from_slice(&row[..K]);
        if let Some(t) = target.get_mut(k) {
            *t = row[K];
        }
        for i in 0..K1 {
            let ri = row[i];
            for j in i..K1 {
                g[i][j] += ri * row[j];
            }
        }
        // Advance the four simulations to k + 1 (first-order hold; the sign held).
        let (du, dv, da) = match (u.get(k + 1), ud.get(k + 1), udd.get(k + 1)) {
            (Some(a), Some(b), Some(c)) => (a - u[k], b - ud[k], c - udd[k]),
            _ => (0.0, 0.0, 0.0),
        };
        let (pu, pv, pa, pf) = (mv(&d.phi, &yu), mv(&d.phi, &yv), mv(&d.phi, &ya), mv(&d.phi, &yf));
        for i in 0..3 {
            yu[i] = pu[i] + g0[i] * u[k] + g1[i] * du;
            yv[i] = pv[i] + g0[i] * ud[k] + g1[i] * dv;
            ya[i] = pa[i] + g0[i] * udd[k] + g1[i] * da;
            yf[i] = pf[i] + g0[i] * f[k];
        }
    }
    g
}

/// Solves the column-scaled normal equations of a `K`-column Gram matrix (target last) by
/// Cholesky; returns the coefficients.
fn solve_scaled<const K1: usize>(g: &[[f64; K1]; K1], k: usize) -> Option<[f64; 7]> {
    let mut s = [0.0; 8];
    for j in 0..k {
        let d = g[j][j];
        s[j] = if d > 0.0 && d.is_finite() { 1.0 / d.sqrt() } else { 0.0 };
    }
    // Scaled upper-triangular Gram → dense k×k plus rhs.
    let mut a = [[0.0; 8]; 8];
    let mut b = [0.0; 8];
    for i in 0..k {
        for j in i..k {
            let v = g[i][j] * s[i] * s[j];
            a[i][j] = v;
            a[j][i] = v;
        }
        b[i] = g[i][k] * s[i];
        if s[i] == 0.0 {
            a[i][i] = 1.0;
        }
    }
    // Cholesky in place with a tiny ridge on failure.
    let mut l = [[0.0; 8]; 8];
    for ridge in [0.0, 1e-12, 1e-9] {
        let mut ok = true;
        for i in 0..k {
            for j in 0..=i {
                let mut sum = a[i][j] + if i == j { ridge } else { 0.0 };
                for p in 0..j {
                    sum -= l[i][p] * l[j][p];
                }
                if i == j {
                    if !(sum > 0.0) {
                        ok = false;
                        break;
                    }
                    l[i][i] = sum.sqrt();
                } else {
                    l[i][j] = sum / l[j][j];
                }
            }
            if !ok {
                break;
            }
        }
        if ok {
            let mut y = [0.0; 8];
            for i in 0..k {
                let mut sum = b[i];
                for p in 0..i {
                    sum -= l[i][p] * y[p];
                }
                y[i] = sum / l[i][i];
            }
            let mut x = [0.0; 8];
            for i in (0..k).rev() {
                let mut sum = y[i];
                for p in i + 1..k {
                    sum -= l[p][i] * x[p];
                }
                x[i] = sum / l[i][i];
            }
            let mut out = [0.0; 7];
            for j in 0..k.min(7) {
                out[j] = x[j] * s[j];
            }
            return Some(out);
        }
    }
    None
}

impl OutputErrorProblem {
    /// Evaluates the projected residual at poles `sigma` (p Hz, ωn Hz, ζ) into `work`.
    fn evaluate(&self, sigma: [f64; 3], work: &mut Work) {
        work.cost = f64::INFINITY;
        let poles = Poles::from_hz(sigma[0], sigma[1], sigma[2]);
        let Some(d) = discretize(&poles, self.ts) else {
            return;
        };
        let k = self.k();
        let g = pass::<4, 5>(self, &d, &mut work.cols, &mut work.resid);
        let theta = solve_scaled(&g, k);
        let Some(theta) = theta else {
            return;
        };
        // `resid` holds the target x - a3 w from the pass; subtract the fit.
        let mut cost = 0.0;
        for (r, c) in work.resid.iter_mut().zip(work.cols.chunks_exact(k)) {
            let mut pred = 0.0;
            for j in 0..k {
                pred += theta[j] * c[j];
            }
            *r -= pred;
            cost += *r * *r;
        }
        work.cost = if cost.is_finite() { 0.5 * cost } else { f64::INFINITY };
        work.theta = theta;
    }

    /// The model of poles `sigma` (Hz) and separable coefficients `theta`.
    fn model(sigma: [f64; 3], theta: &[f64; 7]) -> (ClosedLoopModel, Poles) {
        let poles = Poles::from_hz(sigma[0], sigma[1], sigma[2]);
        let (a1, a2, a3) = poles.denominator();
        (
            ClosedLoopModel {
                a1,
                a2,
                a3,
                b0: theta[2],
                b1: theta[1],
                b2: theta[0],
                dc: theta[3],
            },
            poles,
        )
    }

    /// Output-error cost $\tfrac12\sum (e_k - \hat e_k)^2$ (axis units²) and the best
    /// $(b_0, b_1, b_2, d_c)$ at poles `sigma` (Hz): the inner problem of the refinement.
    pub fn cost_at(&self, sigma: [f64; 3]) -> (f64, ClosedLoopModel) {
        let mut w = Work::new(self.n(), self.k());
        self.evaluate(sigma, &mut w);
        (w.cost, Self::model(sigma, &w.theta).0)
    }
}

/// Refines a model by output error (see the module documentation): stage A with the measured
/// friction sign from the poles `start` (clamped into the bounds), then
/// `opts.sign_iterations` stages B with the sign of the previous model's free run; returns the
/// candidate (including `start_model`, the PSO result) whose true free run fits the trace
/// best.
pub fn refine(
    trace: &Trace,
    regs: &Regressors,
    start_model: &ClosedLoopModel,
    start: &Poles,
    bounds: &PoleBounds,
    opts: &RefineOptions,
) -> Result<RefineResult, Error> {
    bounds.validate()?;
    opts.validate()?;
    let n = trace.len().max(1) as f64;
    // True free-run RMS; a model that cannot be simulated counts as infinitely bad.
    let freerun_rms = |m: &ClosedLoopModel| -> f64 {
        match crate::metrics::free_run(m, trace) {
            Ok(xh) => {
                let s2: f64 = xh.iter().zip(&trace.x).map(|(a, b)| (a - b) * (a - b)).sum();
                if s2.is_finite() { (s2 / n).sqrt() } else { f64::INFINITY }
            }
            Err(_) => f64::INFINITY,
        }
    };
    let mut stages = vec![RefineStage {
        sign: SignSource::Start,
        model: *start_model,
        cost: f64::NAN,
        freerun_rms: freerun_rms(start_model),
    }];
    let mut runs: Vec<RefineResult> = Vec::new();
    let mut prob = OutputErrorProblem::new(trace, regs);
    // Stage A: measured sign. A failed stage (a model that cannot be discretised) is skipped,
    // leaving the earlier candidates.
    if let Ok(res) = refine_problem(&prob, start, bounds, opts) {
        stages.push(RefineStage {
            sign: SignSource::Measured,
            model: res.model,
            cost: res.cost,
            freerun_rms: freerun_rms(&res.model),
        });
        runs.push(res);
    }
    // Stage B: the sign of the previous model's own free run.
    let sim_deadband = vcnc_drive::SimOptions::default().friction_deadband;
    for it in 1..=opts.sign_iterations {
        let Some(prev) = runs.last() else {
            break;
        };
        let Ok(f) = prob.model_signs(&prev.model, sim_deadband) else {
            break;
        };
        if f == prob.f {
            break;
        }
        let from = prev.poles;
        prob.f = f;
        let Ok(res) = refine_problem(&prob, &from, bounds, opts) else {
            break;
        };
        stages.push(RefineStage {
            sign: SignSource::Model(it),
            model: res.model,
            cost: res.cost,
            freerun_rms: freerun_rms(&res.model),
        });
        runs.push(res);
    }
    // The best true free run; ties go to the earlier candidate.
    let mut chosen = 0;
    for (i, st) in stages.iter().enumerate() {
        if st.freerun_rms < stages[chosen].freerun_rms {
            chosen = i;
        }
    }
    let iterations = runs.iter().map(|r| r.iterations).sum();
    let evaluations = runs.iter().map(|r| r.evaluations).sum();
    let start_cost = runs.first().map_or(f64::NAN, |r| r.start_cost);
    let mut out = match chosen.checked_sub(1) {
        Some(i) if i < runs.len() => runs.swap_remove(i),
        _ => RefineResult {
            model: *start_model,
            poles: start_model.poles().unwrap_or(*start),
            start_cost,
            cost: start_cost,
            rms: (2.0 * start_cost / n).sqrt(),
            cost_history: Vec::new(),
            stages: Vec::new(),
            chosen: 0,
            iterations: 0,
            evaluations: 0,
        },
    };
    out.start_cost = start_cost;
    out.stages = stages;
    out.chosen = chosen;
    out.iterations = iterations;
    out.evaluations = evaluations;
    Ok(out)
}

/// [`refine`] on a prepared problem (for callers that supply their own friction sign).
pub fn refine_problem(
    prob: &OutputErrorProblem,
    start: &Poles,
    bounds: &PoleBounds,
    opts: &RefineOptions,
) -> Result<RefineResult, Error> {
    bounds.validate()?;
    opts.validate()?;
    let (lo, hi) = (bounds.lower(), bounds.upper());
    let clamp = |s: [f64; 3]| -> [f64; 3] { std::array::from_fn(|j| s[j].clamp(lo[j], hi[j])) };
    let mut sigma = clamp([start.p_hz(), start.wn_hz(), start.zeta]);
    let (n, k) = (prob.n(), prob.k());
    let mut base = Work::new(n, k);
    let mut trial = Work::new(n, k);
    let mut jac: Vec<Work> = (0..3).map(|_| Work::new(n, k)).collect();
    prob.evaluate(sigma, &mut base);
    let mut evaluations = 1;
    let start_cost = base.cost;
    let mut cost_history = vec![base.cost];
    let mut lambda = 1e-3;
    let mut iterations = 0;
    if base.cost.is_finite() {
        'outer: for _ in 0..opts.max_iterations {
            iterations += 1;
            // Forward-difference Jacobian of the projected residual, columns in parallel.
            let steps: [f64; 3] = std::array::from_fn(|j| {
                let h = 1e-6 * sigma[j].abs().max(1e-2 * (hi[j] - lo[j]));
                if sigma[j] + h > hi[j] { -h } else { h }
            });
            jac.par_iter_mut().enumerate().for_each(|(j, w)| {
                let mut s = sigma;
                s[j] += steps[j];
                prob.evaluate(s, w);
                let h = steps[j];
                for (r, b) in w.resid.iter_mut().zip(&base.resid) {
                    *r = (*r - b) / h;
                }
            });
            evaluations += 3;
            if jac.iter().any(|w| !w.cost.is_finite()) {
                break;
            }
            let mut hm = [[0.0; 3]; 3];
            let mut g = [0.0; 3];
            for i in 0..3 {
                g[i] = dot(&jac[i].resid, &base.resid);
                for j in i..3 {
                    hm[i][j] = dot(&jac[i].resid, &jac[j].resid);
                    hm[j][i] = hm[i][j];
                }
            }
            let free: [bool; 3] = std::array::from_fn(|j| {
                !((sigma[j] <= lo[j] && g[j] > 0.0) || (sigma[j] >= hi[j] && g[j] < 0.0))
            });
            loop {
                let mut a = Matrix3::<f64>::identity();
                let mut b = Vector3::<f64>::zeros();
                for i in 0..3 {
                    if !free[i] {
                        continue;
                    }
                    b[i] = -g[i];
                    for j in 0..3 {
                        if free[j] {
                            a[(i, j)] = hm[i][j];
                        }
                    }
                    a[(i, i)] = hm[i][i] * (1.0 + lambda) + 1e-300;
                }
                let Some(delta) = a.lu().solve(&b) else {
                    break 'outer;
                };
                let cand = clamp(std::array::from_fn(|j| sigma[j] + delta[j]));
                if cand == sigma {
                    break 'outer;
                }
                prob.evaluate(cand, &mut trial);
                evaluations += 1;
                if trial.cost < base.cost {
                    let rel = (base.cost - trial.cost) / base.cost;
                    std::mem::swap(&mut base, &mut trial);
                    sigma = cand;
                    cost_history.push(base.cost);
                    lambda = (lambda / 5.0).max(1e-12);
                    if rel < opts.tolerance {
                        break 'outer;
                    }
                    break;
                }
                lambda *= 4.0;
                if lambda > 1e12 {
                    break 'outer;
                }
            }
        }
    }
    if !base.cost.is_finite() {
        return Err(Error::IllConditioned {
            condition: f64::INFINITY,
            limit: f64::INFINITY,
        });
    }
    let (model, poles) = OutputErrorProblem::model(sigma, &base.theta);
    Ok(RefineResult {
        model,
        poles,
        start_cost,
        cost: base.cost,
        rms: (2.0 * base.cost / n.max(1) as f64).sqrt(),
        cost_history,
        stages: Vec::new(),
        chosen: 0,
        iterations,
        evaluations,
    })
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::options::IdentifyOptions;
    use vcnc_drive::{Reference, SimOptions};

    /// Rest-to-rest smooth moves with reversals, 1 ms.
    fn reference(n: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let ts = 1e-3;
        let moves = [(0.1, 0.25, 20.0), (0.5, 0.3, -35.0), (0.95, 0.12, 4.0), (1.2, 0.4, 30.0), (1.8, 0.2, -25.0), (2.2, 0.5, 12.0)];
        let (mut p, mut v, mut a) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for k in 0..n {
            let t = k as f64 * ts;
            for &(t0, dur, d) in &moves {
                let s = ((t - t0) / dur).clamp(0.0, 1.0);
                p[k] += d * (3.0 * s * s - 2.0 * s * s * s);
                if (0.0..1.0).contains(&s) && t > t0 {
                    v[k] += d * (6.0 * s - 6.0 * s * s) / dur;
                    a[k] += d * (6.0 - 12.0 * s) / (dur * dur);
                }
            }
        }
        (p, v, a)
    }

    #[test]
    fn recovers_the_generating_model_from_a_bad_start() {
        // Truth: the model that generated the data with the very simulation the refinement
        // fits (exact FOH, friction sign of its own velocity). From poles 30 % off and a
        // PSO-like start, stage B reaches the sign fixed point and the generating parameters.
        let truth = ClosedLoopModel { a1: 238.4335, a2: 48421.586, a3: 2487140.3, b0: 0.2, b1: 117.5424, b2: 37258.98, dc: 47.7 };
        let (p, v, a) = reference(3000);
        let x = truth.simulate(Reference { pos: &p, vel: &v, acc: &a }, 1e-3, &SimOptions::default()).unwrap();
        let tr = Trace::new(1e-3, p, x).unwrap().with_reference_derivatives(v, a).unwrap();
        let opts = IdentifyOptions::default();
        let regs = Regressors::build(&tr, &opts).unwrap();
        let tp = truth.poles().unwrap();
        let start = Poles { p: tp.p * 1.3, wn: tp.wn * 0.7, zeta: 0.8 };
        let start_model = ClosedLoopModel::from_poles(&start, 0.0, 0.0, 0.0, 0.0);
        let r = refine(&tr, &regs, &start_model, &start, &opts.bounds, &opts.refine).unwrap();
        let m = r.model;
        let rel = |a: f64, b: f64| ((a - b) / b).abs();
        assert!(rel(r.poles.p, tp.p) < 1e-4 && rel(r.poles.wn, tp.wn) < 1e-4 && rel(r.poles.zeta, tp.zeta) < 1e-4, "{:?}", r.poles);
        assert!(rel(m.b1, truth.b1) < 1e-3 && rel(m.b2, truth.b2) < 1e-4 && rel(m.dc, truth.dc) < 1e-3, "{m:?}");
        assert!((m.b0 - truth.b0).abs() < 1e-4, "{m:?}");
        assert!(r.stages.len() >= 3 && r.chosen >= 2, "{:?}", r.stages);
        // The measured position is the model's own output: the free run reproduces it.
        assert!(r.stages[r.chosen].freerun_rms < 1e-6, "{:?}", r.stages[r.chosen]);
    }

    #[test]
    fn stays_inside_the_bounds() {
        // Data from a 60 Hz drive, searched in bounds that exclude it: the result is clamped.
        let truth = ClosedLoopModel::from_poles(&Poles::from_hz(20.0, 60.0, 0.5), 0.0, 150.0, 120000.0, 30.0);
        let (p, v, a) = reference(3000);
        let x = truth.simulate(Reference { pos: &p, vel: &v, acc: &a }, 1e-3, &SimOptions::default()).unwrap();
        let tr = Trace::new(1e-3, p, x).unwrap();
        let opts = IdentifyOptions { bounds: PoleBounds { p_hz: [0.2, 500.0], wn_hz: [0.2, 40.0], zeta: [0.2, 2.0] }, ..Default::default() };
        let regs = Regressors::build(&tr, &opts).unwrap();
        let start = Poles::from_hz(10.0, 30.0, 0.7);
        let sm = ClosedLoopModel::from_poles(&start, 0.0, 0.0, 0.0, 0.0);
        let r = refine(&tr, &regs, &sm, &start, &opts.bounds, &opts.refine).unwrap();
        assert!(r.poles.wn_hz() <= 40.0 + 1e-12 && r.poles.p_hz() >= 0.2 && r.poles.zeta >= 0.2);
        assert!(r.model.is_stable());
    }
}
