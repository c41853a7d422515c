//! Reference pre-compensation with identified drive models (docs/compensation.md): the axis
//! references that make each model — and so, as far as the model is right, each drive — follow
//! the programmed path.
//!
//! ```text
//!   desired axis positions y_d (the run's references, at T_s)
//!        │  lead and tail at rest (pre-actuation, settling)
//!        ▼
//!   SampledModel: the model as a fine-block program drives it, H(z) = z B(z⁻¹) / A(z⁻¹)
//!        │  StableInverse: partial fractions over the zeros of B,
//!        │  inside the unit circle run forward, outside run backward (exact, bounded)
//!        ▼
//!   r⁰ = H⁻¹ y_d ──▶ ILC on the model with friction: r ← r + H⁻¹ (y_d − M(r))
//!        ▼
//!   compensated positions r (velocity, acceleration by time_exact_rates), limit margins,
//!   the fine-block G-code program (G93 G64, one block per sample)
//! ```
//!
//! **The model as the control runs it.** The compensated program is a chain of fine blocks,
//! one per sample period, which the interpolator runs time-exactly (docs/gcode.md): the drive
//! receives positions $r_k$ at the samples and the velocity and acceleration of their central
//! differences ([`time_exact_rates`]). Through the model's exact first-order-hold discretisation
//! (docs/drive-model.md) the map from $r$ to the model's position $y$ is, friction aside, linear
//! and time-invariant:
//! $$ H(z) = z\,\frac{B(z^{-1})}{A(z^{-1})}, \qquad A(z^{-1}) = \prod_i \big(1 - e^{p_i T_s} z^{-1}\big), $$
//! with $p_i$ the model's poles (a pole at $s = 0$, cancelled by the numerator, left out) and
//! $B$ of degree $n_A + 2$; the factor $z$ is the one sample of preview of the central
//! difference. $B = A \cdot z^{-1}H$ is read off the model's own impulse response (friction
//! off), so the inverse is the inverse of exactly what the model simulates.
//!
//! **Stable inversion.** $R = z^{-1} A(z^{-1}) / B(z^{-1})\,Y = \frac{z\,a(z)}{b(z)}\,Y$ is
//! expanded in partial fractions $\sum_i c_i / (z - \zeta_i)$ over the zeros $\zeta_i$ of $b$.
//! A mode with $|\zeta_i| < 1$ is run forward, $w_{k+1} = \zeta_i w_k + c_i y_k$; a mode with
//! $|\zeta_i| > 1$ (a non-minimum-phase zero: an identified $b_0 < 0$, or a sampling zero) is
//! run backward from the end, $w_k = (w_{k+1} - c_i y_k)/\zeta_i$. The sum is the exact,
//! bounded, non-causal inverse (stable inversion, Devasia, Chen and Paden, IEEE TAC 41(7), 1996,
//! here in discrete time, where it needs no approximation — the continuous-time ZPETC's mirrored
//! zeros and preview delay are not needed because the whole path is known in advance). The
//! backward modes act before the motion they serve (pre-actuation): the program is given a
//! *lead* at rest in which they decay, and a *tail* in which the forward modes settle.
//!
//! **Iterative learning control on the model.** Coulomb friction with sticking makes the model
//! nonlinear. With $M$ the model's simulation (friction and sticking included),
//! $$ r^{0} = H^{-1} y_d, \qquad r^{j+1} = r^{j} + H^{-1}\big(y_d - M(r^{j})\big), $$
//! stopping once $\max_k |y_d - M(r^j)|$ is below the tolerance. On the linear part the
//! learning operator is the exact inverse, so the error after an iteration is only the change
//! of the friction force between iterations; the first correction is the friction feed-forward
//! $H^{-1} H_f\,f$ of the friction $f$ the model meets on the desired motion. The history of
//! the error is returned.
//!
//! Everything is computed on deviations from the first sample (the model starts at rest
//! there).

use rayon::prelude::*;
use serde::Serialize;
use vcnc_axis::{AxisName, Unit};
use vcnc_drive::{ClosedLoopModel, DriveModel, Reference, SimOptions};
use vcnc_gcode::interpolate::time_exact_rates;
use vcnc_kinematics::nalgebra::{Complex, DMatrix};
use vcnc_machine::Machine;

use crate::Error;
use crate::run::{AxisSignals, Run};
use crate::stats::max_abs;

/// A polynomial, highest power first.
type Poly = Vec<f64>;

/// `p` without leading coefficients below `1e-14` of its largest one.
fn trim(p: &[f64]) -> Poly {
    let scale = p.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    let first = p
        .iter()
        .position(|c| c.abs() > 1e-14 * scale)
        .unwrap_or(p.len().saturating_sub(1));
    p[first..].to_vec()
}

/// Polynomial division `num / den = q + r / den`, deg r < deg den.
fn divide(num: &[f64], den: &[f64]) -> (Poly, Poly) {
    let (num, den) = (trim(num), trim(den));
    if num.len() < den.len() {
        return (vec![0.0], num);
    }
    let mut r = num.clone();
    let mut q = vec![0.0; num.len() - den.len() + 1];
    for i in 0..q.len() {
        let c = r[i] / den[0];
        q[i] = c;
        for (j, d) in den.iter().enumerate() {
            r[i + j] -= c * d;
        }
    }
    let rem = r[q.len()..].to_vec();
    (q, if rem.is_empty() { vec![0.0] } else { rem })
}

/// Value of a polynomial at a complex point (Horner).
fn eval(p: &[f64], z: Complex<f64>) -> Complex<f64> {
    p.iter().fold(Complex::new(0.0, 0.0), |acc, c| {
        acc * z + Complex::new(*c, 0.0)
    })
}

/// Derivative of a polynomial.
fn derivative(p: &[f64]) -> Poly {
    let n = p.len();
    if n <= 1 {
        return vec![0.0];
    }
    p[..n - 1]
        .iter()
        .enumerate()
        .map(|(i, c)| c * (n - 1 - i) as f64)
        .collect()
}

/// Roots of a polynomial (companion-matrix eigenvalues); none for a constant.
fn roots(p: &[f64]) -> Vec<Complex<f64>> {
    let p = trim(p);
    let n = p.len().saturating_sub(1);
    if n == 0 {
        return Vec::new();
    }
    let mut c = DMatrix::<f64>::zeros(n, n);
    for j in 0..n {
        c[(0, j)] = -p[j + 1] / p[0];
    }
    for i in 1..n {
        c[(i, i - 1)] = 1.0;
    }
    c.complex_eigenvalues().iter().copied().collect()
}

/// The real polynomial $\prod_i (z - \lambda_i)$ of roots closed under conjugation.
fn from_roots(rs: &[Complex<f64>]) -> Poly {
    let mut out = vec![Complex::new(1.0, 0.0)];
    for r in rs {
        let mut next = vec![Complex::new(0.0, 0.0); out.len() + 1];
        for (i, c) in out.iter().enumerate() {
            next[i] += c;
            next[i + 1] -= c * r;
        }
        out = next;
    }
    out.iter().map(|c| c.re).collect()
}

/// A closed-loop model as a compensated (fine-block) program drives it: the transfer function
/// from the reference positions at the samples to the model's position, friction off
/// (module documentation):
/// $$ H(z) = z\,\frac{\beta_0 + \beta_1 z^{-1} + \dots + \beta_{n_A+2} z^{-(n_A+2)}}{1 + \alpha_1 z^{-1} + \dots + \alpha_{n_A} z^{-n_A}}. $$
#[derive(Debug, Clone, PartialEq)]
pub struct SampledModel {
    /// Sample period, s.
    pub ts: f64,
    /// $\alpha_0 = 1, \alpha_1, \dots$ (dimensionless).
    pub den: Vec<f64>,
    /// $\beta_0, \beta_1, \dots$ (dimensionless).
    pub num: Vec<f64>,
}

impl SampledModel {
    /// The sampled model of `model` at the period `ts` (s).
    pub fn of(model: &ClosedLoopModel, ts: f64) -> Result<SampledModel, Error> {
        SampledModel::of_drive(&DriveModel::from(*model), ts)
    }

    /// The sampled model of a model with a structure (dead time, reference filter, extra
    /// pole) at the period `ts` (s): the filter's and the extra pole's poles join the
    /// denominator, and a dead time of $d$ samples raises the numerator's degree by
    /// $\lceil d \rceil$ (its first coefficients are then zero: the inverse advances).
    pub fn of_drive(drive: &DriveModel, ts: f64) -> Result<SampledModel, Error> {
        let model = &drive.core;
        let fail = |m: String| Error::Usage(format!("cannot invert the model: {m}"));
        if !(model.is_finite() && drive.is_marginally_stable()) {
            return Err(fail(format!("the model {drive:?} is not stable")));
        }
        // Discrete poles: e^{p T}, without the pole at s = 0 of a drive without integral
        // action (the numerator's constant a3 = 0 cancels it).
        let poles: Vec<Complex<f64>> = drive
            .roots()
            .iter()
            .filter(|p| !(model.a3 == 0.0 && p.norm() <= 1e-9 * model.a1.abs().max(1.0)))
            .map(|p| (p * ts).exp())
            .collect();
        let den = from_roots(&poles);
        let na = den.len() - 1;
        let delay = drive.delay_s / ts;
        let delay_samples = if (delay - delay.round()).abs() < 1e-9 {
            delay.round() as usize
        } else {
            delay.ceil() as usize
        };
        let nb = na + 2 + delay_samples;
        // Impulse response of the linear model to one unit sample of the reference position,
        // velocity and acceleration by the time-exact rule; the response starts one sample
        // before the impulse (central differences look one sample ahead).
        let k0 = 2;
        let len = k0 + nb + 12;
        let mut pos = vec![0.0; len];
        pos[k0] = 1.0;
        let (vel, acc) = time_exact_rates(&pos, ts);
        let linear = DriveModel {
            core: ClosedLoopModel { dc: 0.0, ..*model },
            ..*drive
        };
        let reference = Reference {
            pos: &pos,
            vel: &vel,
            acc: &acc,
        };
        let y = if drive.is_core_only() {
            linear.core.simulate(reference, ts, &SimOptions::default())
        } else {
            linear.simulate(reference, ts, &SimOptions::default())
        }
        .map_err(|e| fail(e.to_string()))?;
        let g: Vec<f64> = y[k0 - 1..].to_vec();
        let conv = |j: usize| -> f64 { (0..=na.min(j)).map(|i| den[i] * g[j - i]).sum::<f64>() };
        let num: Vec<f64> = (0..=nb).map(conv).collect();
        // Beyond degree nb the product must vanish: the model is what the formula says.
        let scale = max_abs(&num).max(f64::MIN_POSITIVE);
        let residual = (nb + 1..g.len())
            .map(conv)
            .fold(0.0f64, |m, v| m.max(v.abs()));
        if residual.is_nan() || residual > 1e-7 * scale {
            return Err(Error::Internal(format!(
                "the sampled model of {drive:?} is not of the expected order (residual {residual:e} of {scale:e})"
            )));
        }
        Ok(SampledModel { ts, den, num })
    }

    /// Zeros of $H$: the roots of $b(z) = \beta_0 z^{n_B} + \dots + \beta_{n_B}$.
    pub fn zeros(&self) -> Vec<Complex<f64>> {
        roots(&self.num)
    }

    /// Frequency response $H(e^{j\omega T_s})$ at `w_rad_s`.
    pub fn response(&self, w_rad_s: f64) -> Complex<f64> {
        let zi = Complex::new(0.0, -w_rad_s * self.ts).exp();
        let poly = |c: &[f64]| {
            c.iter().rev().fold(Complex::new(0.0, 0.0), |acc, v| {
                acc * zi + Complex::new(*v, 0.0)
            })
        };
        poly(&self.num) / poly(&self.den) / zi
    }
}

/// One first-order mode $c/(z - \zeta)$ of the inverse.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Mode {
    c: Complex<f64>,
    zeta: Complex<f64>,
    /// A conjugate pair, counted twice (real part doubled).
    pair: bool,
}

/// The exact bounded inverse of a [`SampledModel`] (module documentation): a polynomial part in
/// the shift $z$ and first-order modes, forward inside the unit circle, backward outside.
#[derive(Debug, Clone, PartialEq)]
pub struct StableInverse {
    /// Polynomial part, highest power of $z$ first (applied with future samples).
    poly: Poly,
    modes: Vec<Mode>,
}

/// Closest a zero may come to the unit circle, $||\zeta| - 1|$: a mode closer than this would
/// take more than ~70 000 samples to decay by 10⁻¹².
pub const UNIT_CIRCLE_GAP: f64 = 4e-4;

impl StableInverse {
    /// The inverse of `h`. Refused when a zero of $H$ lies on (or within
    /// [`UNIT_CIRCLE_GAP`] of) the unit circle, or zeros repeat.
    pub fn of(h: &SampledModel) -> Result<StableInverse, Error> {
        let fail = |m: String| Error::Usage(format!("cannot invert the sampled model: {m}"));
        // z a(z): the denominator coefficients read as a polynomial in z, times z.
        // H = z^{1+na-nb} b(z)/a(z), so H^{-1} = z^{nb-na-1} a(z)/b(z).
        let mut num: Poly = h.den.clone();
        num.extend(std::iter::repeat_n(
            0.0,
            (h.num.len() - h.den.len()).saturating_sub(1),
        ));
        let den = trim(&h.num);
        if den.len() < 2 {
            return Err(fail("its numerator is a constant".into()));
        }
        let (poly, rem) = divide(&num, &den);
        let dprime = derivative(&den);
        let zs = roots(&den);
        let mut modes = Vec::new();
        for (i, z) in zs.iter().enumerate() {
            if (z.norm() - 1.0).abs() < UNIT_CIRCLE_GAP {
                return Err(fail(format!(
                    "a zero at z = {z:.6} lies on the unit circle (|z| = {:.6})",
                    z.norm()
                )));
            }
            if z.im < -1e-9 * z.norm().max(1.0) {
                continue; // the conjugate of a pair already taken
            }
            let repeated = zs
                .iter()
                .enumerate()
                .any(|(j, w)| j != i && (w - z).norm() <= 1e-6 * z.norm().max(1.0));
            let dp = eval(&dprime, *z);
            if repeated || dp.norm() == 0.0 {
                return Err(fail(format!("its zeros repeat at z = {z:.6}")));
            }
            modes.push(Mode {
                c: eval(&rem, *z) / dp,
                zeta: *z,
                pair: z.im.abs() > 1e-9 * z.norm().max(1.0),
            });
        }
        Ok(StableInverse { poly, modes })
    }

    /// Samples before the motion for the backward modes to decay by `decay` (relative), and
    /// after it for the forward ones.
    pub fn lead_tail(&self, decay: f64) -> (usize, usize) {
        let n = |r: f64| (decay.ln() / r.ln()).ceil().max(0.0) as usize;
        let mut lead = self.poly.len().saturating_sub(1);
        let mut tail = 0;
        for m in &self.modes {
            let r = m.zeta.norm();
            if r > 1.0 {
                lead = lead.max(n(1.0 / r));
            } else if r > 0.0 {
                tail = tail.max(n(r));
            }
        }
        (lead, tail)
    }

    /// Applies the inverse to `y` (deviations from rest at the first sample; `y` is taken as
    /// held at its last value after the end).
    pub fn apply(&self, y: &[f64]) -> Vec<f64> {
        let n = y.len();
        if n == 0 {
            return Vec::new();
        }
        let last = y[n - 1];
        let deg = self.poly.len() - 1;
        let mut r: Vec<f64> = (0..n)
            .map(|k| {
                self.poly
                    .iter()
                    .enumerate()
                    .map(|(i, q)| q * y.get(k + deg - i).copied().unwrap_or(last))
                    .sum()
            })
            .collect();
        let zero = Complex::new(0.0, 0.0);
        for m in &self.modes {
            let k = if m.pair { 2.0 } else { 1.0 };
            let mut w = vec![zero; n];
            if m.zeta.norm() < 1.0 {
                // w_{k+1} = ζ w_k + c y_k from rest.
                for i in 0..n - 1 {
                    w[i + 1] = m.zeta * w[i] + m.c * y[i];
                }
            } else {
                // w_k = (w_{k+1} − c y_k)/ζ from the steady state of the held end value.
                let mut next = m.c * last / (Complex::new(1.0, 0.0) - m.zeta);
                for i in (0..n).rev() {
                    w[i] = (next - m.c * y[i]) / m.zeta;
                    next = w[i];
                }
            }
            for (r, w) in r.iter_mut().zip(&w) {
                *r += k * w.re;
            }
        }
        r
    }
}

/// Settings of [`compensate_run`]. Plain data; [`Default`] gives the documented defaults.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CompensateOptions {
    /// Most iterations of the learning loop on the model. Default 30.
    pub max_iterations: usize,
    /// The loop stops once the model follows the desired positions to this, axis units (mm or
    /// deg). Default 1e-6 (1 nm, 1 µdeg).
    pub tolerance: f64,
    /// The loop also stops after this many iterations without a smaller error (friction's
    /// sticking is discontinuous: the error stops shrinking at a floor). Default 3.
    pub patience: usize,
    /// Relative size to which the inverse's modes decay within the lead and the tail.
    /// Default 1e-12.
    pub decay: f64,
    /// Longest lead or tail, s. Default 2.
    pub max_lead_s: f64,
}

impl Default for CompensateOptions {
    fn default() -> Self {
        CompensateOptions {
            max_iterations: 30,
            tolerance: 1e-6,
            patience: 3,
            decay: 1e-12,
            max_lead_s: 2.0,
        }
    }
}

/// The result of [`compensate_positions`] for one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct CompensatedPositions {
    /// Compensated reference positions, axis units.
    pub reference: Vec<f64>,
    /// The model's positions on that reference (friction included), axis units.
    pub model: Vec<f64>,
    /// Largest |desired − model| after each model simulation, axis units: the exact linear
    /// inverse alone first, then one entry per learning iteration.
    pub history: Vec<f64>,
}

/// The reference positions that make `model` follow `desired` (absolute positions at `ts`,
/// starting and ending at rest), by the exact inverse and the learning loop (module
/// documentation). The iterate with the smallest error is returned.
pub fn compensate_positions(
    model: &DriveModel,
    inverse: &StableInverse,
    desired: &[f64],
    ts: f64,
    opts: &CompensateOptions,
) -> Result<CompensatedPositions, Error> {
    let n = desired.len();
    if n == 0 {
        return Err(Error::Usage("nothing to compensate: no samples".into()));
    }
    let x0 = desired[0];
    let yd: Vec<f64> = desired.iter().map(|x| x - x0).collect();
    // The paper's structure runs on its exact discretisation; a structure with a dead time,
    // filter or extra pole on the drive model's own exact scheme.
    let core = if model.is_core_only() {
        Some(
            model
                .core
                .discretize(ts)
                .map_err(|e| Error::Usage(format!("cannot simulate the model: {e}")))?,
        )
    } else {
        None
    };
    let mut r = inverse.apply(&yd);
    let mut y = vec![0.0; n];
    let mut best: Option<(f64, Vec<f64>, Vec<f64>)> = None;
    let mut history = Vec::new();
    let mut stale = 0;
    for it in 0..=opts.max_iterations {
        // The machine rests at the first sample: the reference starts there.
        r[0] = 0.0;
        let (vel, acc) = time_exact_rates(&r, ts);
        let reference = Reference {
            pos: &r,
            vel: &vel,
            acc: &acc,
        };
        match &core {
            Some(d) => d
                .simulate_into(reference, &SimOptions::default(), &mut y)
                .map_err(|e| Error::Internal(format!("model simulation: {e}")))?,
            None => {
                y = model
                    .simulate(reference, ts, &SimOptions::default())
                    .map_err(|e| Error::Internal(format!("model simulation: {e}")))?;
            }
        }
        let e: Vec<f64> = yd.iter().zip(&y).map(|(a, b)| a - b).collect();
        let err = max_abs(&e);
        history.push(err);
        if !err.is_finite() {
            return Err(Error::Internal(format!(
                "the learning loop diverged at iteration {it}"
            )));
        }
        if best.as_ref().is_none_or(|b| err < b.0) {
            best = Some((err, r.clone(), y.clone()));
            stale = 0;
        } else {
            stale += 1;
        }
        if err <= opts.tolerance || stale >= opts.patience || it == opts.max_iterations {
            break;
        }
        for (r, d) in r.iter_mut().zip(inverse.apply(&e)) {
            *r += d;
        }
    }
    let (_, r, y) = best.ok_or_else(|| Error::Internal("no iteration ran".into()))?;
    Ok(CompensatedPositions {
        reference: r.into_iter().map(|v| v + x0).collect(),
        model: y.into_iter().map(|v| v + x0).collect(),
        history,
    })
}

/// An axis reference and motion against the axis' limits (docs/compensation.md#limits).
///
/// A compensated set-point is not a motion: its acceleration has spikes wherever the desired
/// acceleration jumps (the inverse acts on the jerk there), which the closed loop filters out —
/// the axis performs the desired motion, not the set-point. What is judged is therefore the
/// set-point's **velocity** (what a control checks block by block) and the **acceleration of
/// the motion** the model predicts (what the motor must deliver); the set-point's own
/// acceleration is reported, not judged.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LimitMargin {
    /// The axis.
    pub axis: AxisName,
    /// The axis' velocity limit, units/s.
    pub velocity_limit: f64,
    /// The axis' acceleration limit, units/s².
    pub acceleration_limit: f64,
    /// Largest speed of a fine block of the set-point, $|r_k - r_{k-1}|/T_s$, units/s: what
    /// the interpolator checks block by block (docs/gcode.md). Judged.
    pub reference_velocity: f64,
    /// The set-point's sample (lead included) where that speed is reached (the end of the
    /// block).
    pub reference_velocity_sample: usize,
    /// Largest |acceleration| of the set-point (central differences), units/s². Reported only.
    pub reference_acceleration: f64,
    /// Largest |acceleration| of the motion the model predicts on the set-point (central
    /// differences of its positions), units/s². Judged.
    pub motion_acceleration: f64,
    /// Largest |acceleration| of the desired motion (the program's own references, central
    /// differences), units/s²: where it exceeds the limit (velocity jumps at polyline
    /// junctions), the motion may reach it too.
    pub desired_acceleration: f64,
    /// The acceleration the motion may reach, units/s²: the limit (or the desired motion's own
    /// peak where that is higher) plus $4\delta/T_s^2$, the resolution of a second difference of
    /// positions known to $\delta$ = the model's largest |motion − desired|.
    pub acceleration_allowed: f64,
}

impl LimitMargin {
    /// The margins of a set-point, the model's motion on it and the desired motion (positions
    /// at `ts`).
    pub fn of(
        axis: &vcnc_machine::Axis,
        reference: &[f64],
        motion: &[f64],
        desired: &[f64],
        ts: f64,
    ) -> LimitMargin {
        let (_, ra) = time_exact_rates(reference, ts);
        let (block_speed, at) =
            reference
                .windows(2)
                .enumerate()
                .fold((0.0f64, 0), |(m, at), (k, w)| {
                    let v = (w[1] - w[0]).abs() / ts;
                    if v > m { (v, k + 1) } else { (m, at) }
                });
        let (_, ma) = time_exact_rates(motion, ts);
        let (_, da) = time_exact_rates(desired, ts);
        let delta = motion
            .iter()
            .zip(desired)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let desired_acceleration = max_abs(&da);
        LimitMargin {
            acceleration_allowed: axis.max_acceleration.max(desired_acceleration)
                + 4.0 * delta / (ts * ts),
            axis: axis.name,
            velocity_limit: axis.max_velocity,
            acceleration_limit: axis.max_acceleration,
            reference_velocity: block_speed,
            reference_velocity_sample: at,
            reference_acceleration: max_abs(&ra),
            motion_acceleration: max_abs(&ma),
            desired_acceleration,
        }
    }

    /// Set-point velocity and motion acceleration within what is allowed.
    pub fn within(&self) -> bool {
        self.reference_velocity <= self.velocity_limit * (1.0 + 1e-9)
            && self.motion_acceleration <= self.acceleration_allowed
    }
}

/// The compensation of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisCompensation {
    /// Compensated set-point: positions, and velocity and acceleration by [`time_exact_rates`]
    /// (axis units, /s, /s²), lead and tail included.
    pub reference: AxisSignals,
    /// The model's positions on the set-point, axis units: the physical axis', advanced by the
    /// stated actual-value latency when one was given ([`compensate_run`]).
    pub model: Vec<f64>,
    /// The desired positions (the run's, with the lead and tail at rest), axis units.
    pub desired: Vec<f64>,
    /// Zeros of the sampled model ([`SampledModel::zeros`]).
    pub zeros: Vec<Complex<f64>>,
    /// [`CompensatedPositions::history`], axis units.
    pub history: Vec<f64>,
    /// The set-point and the motion against the axis' limits.
    pub margin: LimitMargin,
}

/// Compensated set-points of every axis of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Compensation {
    /// Sample period, s.
    pub ts: f64,
    /// Samples at rest added before the run's first sample (pre-actuation).
    pub lead: usize,
    /// Samples at rest added after the run's last sample (settling).
    pub tail: usize,
    /// Per machine axis, in machine order.
    pub axes: Vec<AxisCompensation>,
}

impl Compensation {
    /// Number of samples (lead + run + tail).
    pub fn len(&self) -> usize {
        self.axes.first().map_or(0, |a| a.reference.pos.len())
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Duration from the first to the last sample, s.
    pub fn duration_s(&self) -> f64 {
        self.len().saturating_sub(1) as f64 * self.ts
    }

    /// The margins of every axis, in machine order.
    pub fn margins(&self) -> Vec<LimitMargin> {
        self.axes.iter().map(|a| a.margin).collect()
    }

    /// Refuses ([`Error::Limit`]) a compensation of `run` (planned with the velocity
    /// `headroom`, 1 for none) whose set-point velocity or predicted motion acceleration exceeds
    /// an axis limit (the worst excess first), saying where and by how much the program's feed,
    /// or the headroom, would have to drop.
    pub fn check_limits(&self, run: &Run, headroom: f64) -> Result<(), Error> {
        let mut worst: Option<(f64, Error)> = None;
        for a in &self.axes {
            let m = &a.margin;
            let u = a.reference.unit;
            let vr = m.reference_velocity / m.velocity_limit;
            if vr > 1.0 + 1e-9 && worst.as_ref().is_none_or(|w| vr > w.0) {
                worst = Some((
                    vr,
                    Error::Limit {
                        axis: m.axis,
                        what: "compensated set-point's velocity",
                        value: m.reference_velocity,
                        limit: m.velocity_limit,
                        unit: format!("{u}/s"),
                        advice: format!(
                            "{}; lower the program's feeds there to at most {:.1} %, or, where it runs at the axis limits (rapids), plan it with a velocity headroom of at most {:.3} (a set-point leads the motion: a move at the velocity limit cannot be compensated)",
                            self.place(run, m.reference_velocity_sample),
                            100.0 / vr,
                            headroom / vr
                        ),
                    },
                ));
            }
            let ar = m.motion_acceleration / m.acceleration_allowed;
            if ar > 1.0 && worst.as_ref().is_none_or(|w| ar > w.0) {
                worst = Some((
                    ar,
                    Error::Limit {
                        axis: m.axis,
                        what: "acceleration of the motion the model predicts",
                        value: m.motion_acceleration,
                        limit: m.acceleration_limit,
                        unit: format!("{u}/s²"),
                        advice: format!(
                            "lower the machine's acceleration limits for this program to at most {:.1} % (accelerations scale with them)",
                            100.0 / ar
                        ),
                    },
                ));
            }
        }
        match worst {
            Some((_, e)) => Err(e),
            None => Ok(()),
        }
    }

    /// "at t = … s, line … (a rapid)" for set-point sample `k` (lead included) of `run`'s
    /// compensation.
    fn place(&self, run: &Run, k: usize) -> String {
        let t = (k as f64 - self.lead as f64) * self.ts;
        let j = k.saturating_sub(self.lead).min(run.len().saturating_sub(1));
        match run.loaded.trajectory.block_at(j) {
            Some(b) => format!(
                "at t = {t:.3} s, {}:{} (a {} move)",
                run.file,
                b.line,
                match b.class {
                    vcnc_gcode::MoveClass::Rapid => "rapid",
                    vcnc_gcode::MoveClass::Feed => "feed",
                    vcnc_gcode::MoveClass::Dwell => "dwell",
                }
            ),
            None => format!("at t = {t:.3} s"),
        }
    }

    /// The compensated set-points as a G-code program the control runs as they are
    /// (docs/compensation.md#the-fine-block-program): `G21 G90 G49 G64`, a `G0` to the first
    /// sample, then under `G93` one `G1` per sample period with $F = 60/T_s$ (the block lasts
    /// exactly one period; only the axes that move are written, every value in full precision),
    /// a `G4` dwell for each run of samples where no axis moves, `M2`. `header` lines become
    /// comments (parentheses are replaced).
    pub fn program(&self, header: &[String]) -> String {
        let n = self.len();
        let mut out = String::with_capacity(n * 64 + 256);
        out.push_str("%\n");
        for h in header {
            out.push('(');
            out.push_str(&h.replace(['(', ')'], "'"));
            out.push_str(")\n");
        }
        out.push_str("G21 G90 G17 G49 G64\n");
        if n == 0 {
            out.push_str("M2\n%\n");
            return out;
        }
        let at = |k: usize| -> Vec<f64> { self.axes.iter().map(|a| a.reference.pos[k]).collect() };
        let word = |a: &AxisCompensation, v: f64| format!(" {}{}", a.reference.name, fmt_exact(v));
        out.push_str("G0");
        for (a, v) in self.axes.iter().zip(at(0)) {
            out.push_str(&word(a, v));
        }
        out.push_str("\nG93\n");
        let f = fmt_exact(60.0 / self.ts);
        let mut prev = at(0);
        let mut rest = 0usize;
        for k in 1..n {
            let cur = at(k);
            if cur == prev {
                rest += 1;
                continue;
            }
            if rest > 0 {
                out.push_str(&format!("G4 P{}\n", fmt_exact(rest as f64 * self.ts)));
                rest = 0;
            }
            out.push_str("G1");
            for ((a, v), p) in self.axes.iter().zip(&cur).zip(&prev) {
                if v != p {
                    out.push_str(&word(a, *v));
                }
            }
            out.push_str(" F");
            out.push_str(&f);
            out.push('\n');
            prev = cur;
        }
        if rest > 0 {
            out.push_str(&format!("G4 P{}\n", fmt_exact(rest as f64 * self.ts)));
        }
        out.push_str("G94 G61\nM2\n%\n");
        out
    }
}

/// A G-code number that reads back as the same `f64` (shortest round-trip decimal, never an
/// exponent: Rust's `Display` for floats writes plain decimals), `-0` written as `0`.
fn fmt_exact(v: f64) -> String {
    if v == 0.0 {
        "0".to_string()
    } else {
        format!("{v}")
    }
}

/// `machine` with every axis velocity limit and the tool-tip path velocity limit times
/// `headroom` (in (0, 1]): a program prepared on it leaves the set-points room to lead the
/// motion where the original runs at a limit (rapids, feeds above the limits). Accelerations are
/// kept: the motion the compensation produces is the desired one.
pub fn with_velocity_headroom(machine: &Machine, headroom: f64) -> Result<Machine, Error> {
    if !(headroom > 0.0 && headroom <= 1.0) {
        return Err(Error::Usage(format!(
            "the velocity headroom must lie in (0, 1], got {headroom}"
        )));
    }
    let mut m = machine.clone();
    for a in &mut m.axes {
        a.max_velocity *= headroom;
    }
    m.tcp_max_vel *= headroom;
    Ok(m)
}

/// Replanning rounds [`compensate_within_limits`] may take when no headroom is given.
pub const MAX_REPLANS: usize = 3;

/// A compensation within the axes' limits and the velocity headroom it was planned with.
#[derive(Debug, Clone)]
pub struct Planned {
    /// The compensation.
    pub compensation: Compensation,
    /// The velocity headroom the program was planned with (1: none).
    pub headroom: f64,
    /// The headrooms planned again with, in order, when none was given (empty: none needed).
    pub replanned: Vec<f64>,
}

/// Compensates `original` (the program at `program` prepared on `machine`) with `models` and
/// refuses ([`Error::Limit`]) a set-point beyond an axis limit. With `headroom` the program is
/// planned with it; without, it is planned as it is, and a set-point that must lead a move at a
/// velocity limit (a rapid, usually) makes the headroom just small enough, up to
/// [`MAX_REPLANS`] times. The path followed is the original's either way. `actual_latency_s`
/// as [`compensate_run`] takes it.
#[allow(clippy::too_many_arguments)]
pub fn compensate_within_limits(
    machine: &Machine,
    program: &std::path::Path,
    original: &Run,
    models: &[DriveModel],
    actual_latency_s: &[f64],
    opts: &CompensateOptions,
    headroom: Option<f64>,
    lenient: bool,
) -> Result<Planned, Error> {
    let mut h = headroom.unwrap_or(1.0);
    let mut replanned = Vec::new();
    loop {
        let slower;
        let planned = if h < 1.0 {
            slower =
                crate::run::prepare_file(&with_velocity_headroom(machine, h)?, program, lenient)?;
            &slower
        } else {
            original
        };
        let compensation = compensate_run(machine, planned, models, actual_latency_s, opts)?;
        let Err(e) = compensation.check_limits(planned, h) else {
            return Ok(Planned {
                compensation,
                headroom: h,
                replanned,
            });
        };
        // The set-points' largest velocity over its limit (an excess of acceleration is not
        // helped by a headroom).
        let ratio = compensation
            .margins()
            .iter()
            .map(|m| m.reference_velocity / m.velocity_limit)
            .fold(0.0f64, f64::max);
        if headroom.is_some() || replanned.len() == MAX_REPLANS || ratio <= 1.0 {
            return Err(e);
        }
        h = (h / ratio * 0.99).min(1.0);
        replanned.push(h);
    }
}

/// `v` with `lead` copies of its first and `tail` copies of its last value around it.
fn padded(v: &[f64], lead: usize, tail: usize) -> Vec<f64> {
    let (first, last) = (v[0], v[v.len() - 1]);
    std::iter::repeat_n(first, lead)
        .chain(v.iter().copied())
        .chain(std::iter::repeat_n(last, tail))
        .collect()
}

/// Every axis reference of `run` compensated with its model (one per machine axis, in order):
/// lead and tail at rest, exact inverse, learning loop, limit margins. Axes run in parallel;
/// results come in machine order. The limits are not enforced here
/// ([`Compensation::check_limits`]).
///
/// **Actual-value latency.** A model predicts the logged actual position, which trails the
/// physical axis by the axis' stated latency $\tau$ (`actual_latency_s`, s, per machine axis;
/// empty: none; [`crate::latency`]). For the physical axis to follow the desired positions
/// $y_d(t)$ the model must follow $y_d(t - \tau)$: that is what is inverted, and the tail is
/// longer by $\lceil\tau/T_s\rceil$ samples so that it still ends at rest. The axes' `model`
/// positions are then the physical ones (the model's advanced by $\tau$).
pub fn compensate_run(
    machine: &Machine,
    run: &Run,
    models: &[DriveModel],
    actual_latency_s: &[f64],
    opts: &CompensateOptions,
) -> Result<Compensation, Error> {
    if models.len() != run.axes.len() || run.axes.len() != machine.axes.len() {
        return Err(Error::Usage(format!(
            "{} models for {} axes",
            models.len(),
            run.axes.len()
        )));
    }
    crate::latency::check(actual_latency_s, run.axes.len())?;
    let latency = |i: usize| actual_latency_s.get(i).copied().unwrap_or(0.0);
    if run.is_empty() {
        return Err(Error::Usage(format!(
            "{}: the program has no samples",
            run.file
        )));
    }
    let ts = run.ts;
    let inverses = models
        .iter()
        .zip(&run.axes)
        .map(|(m, s)| {
            let h = SampledModel::of_drive(m, ts).map_err(|e| axis_error(s.name, e))?;
            let inv = StableInverse::of(&h).map_err(|e| axis_error(s.name, e))?;
            Ok((h, inv))
        })
        .collect::<Result<Vec<_>, Error>>()?;
    let max_pad = (opts.max_lead_s / ts).ceil() as usize;
    let (mut lead, mut tail) = (0usize, 0usize);
    for ((_, inv), s) in inverses.iter().zip(&run.axes) {
        let (l, t) = inv.lead_tail(opts.decay);
        if l > max_pad || t > max_pad {
            return Err(Error::Usage(format!(
                "axis {}: the model's inverse needs {:.3} s of lead and {:.3} s of tail to settle, more than {} s (a zero of the sampled model lies close to the unit circle)",
                s.name,
                l as f64 * ts,
                t as f64 * ts,
                opts.max_lead_s
            )));
        }
        lead = lead.max(l);
        tail = tail.max(t);
    }
    let max_latency = (0..run.axes.len()).map(latency).fold(0.0f64, f64::max);
    tail += (max_latency / ts).ceil() as usize;
    let axes = inverses
        .par_iter()
        .zip(models.par_iter())
        .zip(run.axes.par_iter().zip(machine.axes.par_iter()))
        .enumerate()
        .map(|(i, (((h, inv), m), (s, axis)))| {
            let desired = padded(&s.pos, lead, tail);
            let tau = latency(i);
            let c = if tau == 0.0 {
                compensate_positions(m, inv, &desired, ts, opts)
            } else {
                let target = crate::latency::shifted(&desired, -tau, ts);
                compensate_positions(m, inv, &target, ts, opts).map(|c| CompensatedPositions {
                    model: crate::latency::shifted(&c.model, tau, ts),
                    ..c
                })
            }
            .map_err(|e| axis_error(s.name, e))?;
            let (vel, acc) = time_exact_rates(&c.reference, ts);
            Ok(AxisCompensation {
                margin: LimitMargin::of(axis, &c.reference, &c.model, &desired, ts),
                reference: AxisSignals {
                    name: s.name,
                    unit: s.unit,
                    pos: c.reference,
                    vel,
                    acc,
                },
                model: c.model,
                desired,
                zeros: h.zeros(),
                history: c.history,
            })
        })
        .collect::<Result<Vec<_>, Error>>()?;
    Ok(Compensation {
        ts,
        lead,
        tail,
        axes,
    })
}

fn axis_error(axis: AxisName, e: Error) -> Error {
    match e {
        Error::Usage(m) => Error::Usage(format!("axis {axis}: {m}")),
        other => other,
    }
}

/// How closely a program's run reproduces the set-points it was written from: the largest
/// |Δ| per axis of positions, velocities and accelerations (axis units, /s, /s²), the
/// program's last sample (its final rest) excluded from the rates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Reproduction {
    /// The axis.
    pub axis: AxisName,
    /// Largest |Δ position|, axis units.
    pub position: f64,
    /// Largest |Δ velocity|, units/s.
    pub velocity: f64,
    /// Largest |Δ acceleration|, units/s².
    pub acceleration: f64,
}

/// [`Reproduction`] of every axis of `comp` by `run` (the program re-read and interpolated);
/// an error when the sample counts differ.
pub fn reproduction(comp: &Compensation, run: &Run) -> Result<Vec<Reproduction>, Error> {
    if run.len() != comp.len() {
        return Err(Error::Internal(format!(
            "the compensated program runs {} samples, the set-points have {}",
            run.len(),
            comp.len()
        )));
    }
    let n = comp.len();
    let diff = |a: &[f64], b: &[f64], m: usize| {
        a[..m]
            .iter()
            .zip(&b[..m])
            .fold(0.0f64, |w, (x, y)| w.max((x - y).abs()))
    };
    Ok(comp
        .axes
        .iter()
        .zip(&run.axes)
        .map(|(c, r)| Reproduction {
            axis: c.reference.name,
            position: diff(&c.reference.pos, &r.pos, n),
            velocity: diff(&c.reference.vel, &r.vel, n - 1),
            acceleration: diff(&c.reference.acc, &r.acc, n - 1),
        })
        .collect())
}

/// Tool-tip and orientation contour statistics (µm, mrad) of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ContourStats {
    /// Largest tool-tip contour error, µm.
    pub contour_max_um: f64,
    /// RMS tool-tip contour error, µm.
    pub contour_rms_um: f64,
    /// Largest orientation contour error, mrad.
    pub orientation_max_mrad: f64,
    /// RMS orientation contour error, mrad.
    pub orientation_rms_mrad: f64,
}

/// Per sample of a contour report measured against `reference`'s path: whether its foot point
/// lies on a feed move of `reference`. Contour statistics cover what is cut (docs/contour.md);
/// a program without feed moves counts every sample.
pub fn feed_samples(reference: &Run, r: &vcnc_contour::ContourReport) -> Vec<bool> {
    let feed = reference.measured(crate::run::Measured::Feed);
    if !feed.iter().any(|f| *f) {
        return vec![true; r.foot.len()];
    }
    r.foot
        .iter()
        .map(|f| {
            let k = f.u.round().max(0.0) as usize;
            feed.get(k.min(feed.len() - 1)).copied().unwrap_or(false)
        })
        .collect()
}

impl ContourStats {
    /// Over the samples of `r` that `mask` selects.
    pub fn over(r: &vcnc_contour::ContourReport, mask: &[bool]) -> ContourStats {
        let pick = |v: &[f64]| -> Vec<f64> {
            v.iter()
                .zip(mask)
                .filter_map(|(x, m)| m.then_some(*x))
                .collect()
        };
        let (tip, or) = (pick(&r.tip_mm), pick(&r.orientation_rad));
        ContourStats {
            contour_max_um: max_abs(&tip) * 1e3,
            contour_rms_um: crate::stats::rms(&tip) * 1e3,
            orientation_max_mrad: max_abs(&or) * 1e3,
            orientation_rms_mrad: crate::stats::rms(&or) * 1e3,
        }
    }

    /// Over the samples of `r` whose foot lies on a feed move of `reference`
    /// ([`feed_samples`]).
    pub fn over_feed(reference: &Run, r: &vcnc_contour::ContourReport) -> ContourStats {
        ContourStats::over(r, &feed_samples(reference, r))
    }

    /// Of a contour report, every sample.
    pub fn of(r: &vcnc_contour::ContourReport) -> ContourStats {
        ContourStats {
            contour_max_um: r.tip_max_mm * 1e3,
            contour_rms_um: r.tip_rms_mm * 1e3,
            orientation_max_mrad: r.orientation_max_rad * 1e3,
            orientation_rms_mrad: r.orientation_rms_rad * 1e3,
        }
    }
}

/// A program run on the true machine and judged against another run's reference path.
#[derive(Debug, Clone)]
pub struct Judged {
    /// The true drives' traces on the program.
    pub traces: Vec<vcnc_drive::DriveTrace>,
    /// Contour and orientation errors of the true tool poses against the reference run's path;
    /// `None` on a machine without kinematics.
    pub contour: Option<vcnc_contour::ContourReport>,
    /// The program's duration, s.
    pub cycle_time_s: f64,
}

impl Judged {
    /// The contour errors, or the error a machine without kinematics gives.
    pub fn contour(&self, machine: &Machine) -> Result<&vcnc_contour::ContourReport, Error> {
        self.contour.as_ref().ok_or_else(|| {
            vcnc_machine::Error::NoKinematics {
                file: machine.source.clone(),
            }
            .into()
        })
    }
}

/// Runs `run` through the true drives and, on a machine with kinematics, measures its contour
/// errors against the tool path and tool axis of `reference` (the ORIGINAL program's poses,
/// whatever program `run` is).
pub fn on_true_machine(machine: &Machine, reference: &Run, run: &Run) -> Result<Judged, Error> {
    let traces = crate::simulate::simulate_true(machine, run)?;
    let contour = match machine.kinematics {
        Some(_) => {
            let pos: Vec<&[f64]> = traces.iter().map(|t| t.true_position.as_slice()).collect();
            Some(crate::predict::contour(machine, reference, &pos)?.1)
        }
        None => None,
    };
    Ok(Judged {
        traces,
        contour,
        cycle_time_s: run.duration_s(),
    })
}

/// Where each sample of a contour report lies along the reference run's tool-tip path: the arc
/// length of its foot point from the path's start, mm (for plotting runs of different
/// durations over the same path).
/// Empty on a machine without kinematics.
pub fn path_position_mm(
    machine: &Machine,
    reference: &Run,
    report: &vcnc_contour::ContourReport,
) -> Vec<f64> {
    let poses = reference.reference_poses(machine).unwrap_or_default();
    let mut s = Vec::with_capacity(poses.len());
    let mut acc = 0.0;
    for (i, p) in poses.iter().enumerate() {
        if i > 0 {
            acc += (p.p - poses[i - 1].p).norm();
        }
        s.push(acc);
    }
    report
        .foot
        .iter()
        .map(|f| {
            if s.is_empty() {
                return 0.0;
            }
            let j = (f.u.floor().max(0.0) as usize).min(s.len() - 1);
            let frac = f.u - j as f64;
            let next = s.get(j + 1).copied().unwrap_or(s[j]);
            s[j] + frac * (next - s[j])
        })
        .collect()
}

/// The models' contour errors on `run` against the tool path of `reference` (the prediction a
/// plan is made with): the physical axes, each model's positions advanced by its axis' stated
/// actual-value latency (`actual_latency_s`, s, per machine axis; empty: none;
/// [`crate::latency`]).
pub fn with_models(
    machine: &Machine,
    reference: &Run,
    run: &Run,
    models: &[DriveModel],
    actual_latency_s: &[f64],
) -> Result<vcnc_contour::ContourReport, Error> {
    let positions = crate::latency::physical_positions(
        crate::simulate::simulate_models(models, run)?,
        actual_latency_s,
        run.ts,
    )?;
    let pos: Vec<&[f64]> = positions.iter().map(Vec::as_slice).collect();
    Ok(crate::predict::contour(machine, reference, &pos)?.1)
}

/// One program's true drives on one axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AxisRunFigures {
    /// Largest |true position − desired position|, µm or mdeg (the desired positions are the
    /// original program's references).
    pub tracking_max: f64,
    /// Largest |acceleration| of the true motion (central differences of the true positions),
    /// units/s².
    pub motion_acceleration: f64,
    /// Largest |motor torque|, N·m.
    pub torque_peak_nm: f64,
}

impl AxisRunFigures {
    /// Of a true drive's trace against desired positions (same sample times).
    pub fn of(trace: &vcnc_drive::DriveTrace, desired: &[f64], unit: Unit) -> AxisRunFigures {
        let (_, acc) = time_exact_rates(&trace.true_position, trace.ts);
        AxisRunFigures {
            tracking_max: desired
                .iter()
                .zip(&trace.true_position)
                .fold(0.0f64, |m, (d, x)| m.max((d - x).abs()))
                * unit.micro_factor(),
            motion_acceleration: max_abs(&acc),
            torque_peak_nm: max_abs(&trace.motor_torque),
        }
    }
}

/// One axis of [`CompensateSummary`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisCompensateSummary {
    /// `mm` or `deg`.
    pub unit: Unit,
    /// The limits judged and reported ([`LimitMargin`]).
    pub margin: LimitMargin,
    /// Both judged quantities within their limits.
    pub within_limits: bool,
    /// Model simulations of the learning loop.
    pub iterations: usize,
    /// |desired − model| after the exact linear inverse alone, µm or mdeg.
    pub model_error_linear_inverse: f64,
    /// |desired − model| of the set-point written, µm or mdeg.
    pub model_error: f64,
    /// The program re-read and interpolated against the set-points.
    pub reproduction: Reproduction,
    /// The original program on the true drive.
    pub before: AxisRunFigures,
    /// The compensated program on the true drive.
    pub after: AxisRunFigures,
}

/// Before and after figures of one program on the true machine.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RunFigures {
    /// Contour statistics against the original program's path (absent on a machine without
    /// kinematics).
    #[serde(flatten)]
    pub contour: Option<ContourStats>,
    /// The program's duration, s.
    pub cycle_time_s: f64,
}

/// `summary.json` of `vcnc compensate`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompensateSummary {
    /// Machine name.
    pub machine: String,
    /// The original program.
    pub program: String,
    /// The model file.
    pub models: String,
    /// The compensated program written.
    pub compensated_program: String,
    /// Sample period, s.
    pub ts_s: f64,
    /// Pre-actuation before the original's first sample, s.
    pub lead_s: f64,
    /// Settling after the original's last sample, s.
    pub tail_s: f64,
    /// Options of the compensation.
    pub options: CompensateOptions,
    /// The velocity headroom the program was planned with ([`with_velocity_headroom`]; 1:
    /// none).
    pub velocity_headroom: f64,
    /// The original program on the true machine.
    pub before: RunFigures,
    /// The compensated program on the true machine.
    pub after: RunFigures,
    /// The models on the compensated program (what the compensation aims at; absent without
    /// kinematics).
    pub after_models: Option<ContourStats>,
    /// Per axis.
    pub axes: std::collections::BTreeMap<String, AxisCompensateSummary>,
    /// Every axis within its judged limits.
    pub within_limits: bool,
}

#[cfg(test)]
mod tests {
    use super::*;
    use vcnc_drive::{Reference, SimOptions};

    /// A smooth rest-to-rest move and back: x = L s(τ) − L s(τ − 1), s the quintic
    /// 10τ³ − 15τ⁴ + 6τ⁵ on [0, 1], τ = t / T; at rest before, between and after.
    fn there_and_back(len: f64, t_move: f64, ts: f64) -> Vec<f64> {
        let s = |tau: f64| {
            let t = tau.clamp(0.0, 1.0);
            10.0 * t.powi(3) - 15.0 * t.powi(4) + 6.0 * t.powi(5)
        };
        let n = (2.6 * t_move / ts) as usize;
        (0..n)
            .map(|k| {
                let tau = (k as f64 * ts - 0.05) / t_move;
                5.0 + len * (s(tau) - s(tau - 1.2))
            })
            .collect()
    }

    fn model(b0: f64, dc: f64) -> ClosedLoopModel {
        // The paper's Table 1 drive (docs/reference-numbers.md) with Vff = 0.5, Bff = 0.1.
        ClosedLoopModel {
            b0,
            dc,
            ..vcnc_drive::TABLE1_MODEL
        }
    }

    fn simulate(m: &ClosedLoopModel, pos: &[f64], ts: f64) -> Vec<f64> {
        let (vel, acc) = time_exact_rates(pos, ts);
        m.simulate(
            Reference {
                pos,
                vel: &vel,
                acc: &acc,
            },
            ts,
            &SimOptions::default(),
        )
        .unwrap()
    }

    fn max_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
    }

    #[test]
    fn the_sampled_model_is_the_model() {
        // Truth: the model's own simulation. Filtering a reference through the difference
        // equation A(z⁻¹) y = z B(z⁻¹) r must give the simulated positions.
        let ts = 1e-3;
        for m in [model(0.0, 0.0), model(-0.05, 0.0), model(0.02, 0.0)] {
            let h = SampledModel::of(&m, ts).unwrap();
            let r = there_and_back(30.0, 0.2, ts);
            let r0 = r[0];
            let dev: Vec<f64> = r.iter().map(|v| v - r0).collect();
            let want: Vec<f64> = simulate(&m, &r, ts).iter().map(|v| v - r0).collect();
            let mut y = vec![0.0; dev.len()];
            let at = |k: isize| dev[k.clamp(0, dev.len() as isize - 1) as usize];
            for k in 0..dev.len() {
                let mut v: f64 = (0..h.num.len())
                    .map(|j| h.num[j] * at(k as isize + 1 - j as isize))
                    .sum();
                for (i, a) in h.den.iter().enumerate().skip(1) {
                    if k >= i {
                        v -= a * y[k - i];
                    }
                }
                y[k] = v;
            }
            assert!(max_diff(&y, &want) < 1e-9, "{m:?}: {}", max_diff(&y, &want));
            // The static gain is 1 (numerator constant a3).
            let dc: f64 = h.num.iter().sum::<f64>() / h.den.iter().sum::<f64>();
            assert!((dc - 1.0).abs() < 1e-9, "{dc}");
        }
    }

    #[test]
    fn the_stable_inverse_makes_the_linear_model_follow_exactly() {
        // Truth: the model itself. Uncompensated, its following error on a 30 mm move in
        // 0.2 s is hundreds of µm; on the exact inverse it follows to rounding. A b0 < 0 puts a
        // zero outside the unit circle (anti-causal mode): the inverse stays bounded and
        // exact, with a lead in which it acts before the motion.
        let ts = 1e-3;
        for m in [model(0.0, 0.0), model(-0.05, 0.0), model(0.02, 0.0)] {
            let h = SampledModel::of(&m, ts).unwrap();
            let inv = StableInverse::of(&h).unwrap();
            let (lead, tail) = inv.lead_tail(1e-12);
            let desired = padded(&there_and_back(30.0, 0.2, ts), lead, tail);
            let before = max_diff(&simulate(&m, &desired, ts), &desired);
            let x0 = desired[0];
            let dev: Vec<f64> = desired.iter().map(|v| v - x0).collect();
            let r: Vec<f64> = inv.apply(&dev).iter().map(|v| v + x0).collect();
            let after = max_diff(&simulate(&m, &r, ts), &desired);
            assert!(before > 0.2, "{before}");
            assert!(after < 1e-9, "{m:?}: {before} → {after}");
            assert!(r.iter().all(|v| v.is_finite() && (v - 20.0).abs() < 20.0));
            if m.b0 < 0.0 {
                assert!(h.zeros().iter().any(|z| z.norm() > 1.0));
            }
        }
    }

    #[test]
    fn models_with_dead_time_filter_and_extra_pole_are_inverted_exactly() {
        // Truth: each structured model simulated by its own exact scheme
        // (DriveModel::simulate). A whole-sample and a fractional dead time, first- and
        // second-order reference filters and an extra pole: the sampled model's inverse makes
        // the linear model follow the move to rounding (the dead time by a lead).
        use vcnc_drive::ReferenceFilter;
        let ts = 1e-3;
        let core = model(0.0, 0.0);
        let cases = [
            DriveModel {
                delay_s: 2e-3,
                ..DriveModel::from(core)
            },
            DriveModel {
                delay_s: 1.4e-3,
                ..DriveModel::from(core)
            },
            DriveModel {
                reference_filter: Some(ReferenceFilter::FirstOrder { tau_s: 3e-3 }),
                ..DriveModel::from(core)
            },
            DriveModel {
                delay_s: 1e-3,
                reference_filter: Some(ReferenceFilter::SecondOrder {
                    wn_hz: 60.0,
                    zeta: 0.6,
                }),
                ..DriveModel::from(core)
            },
            DriveModel {
                extra_pole_hz: Some(150.0),
                ..DriveModel::from(core)
            },
        ];
        let sim = |m: &DriveModel, pos: &[f64]| {
            let (vel, acc) = time_exact_rates(pos, ts);
            m.simulate(
                Reference {
                    pos,
                    vel: &vel,
                    acc: &acc,
                },
                ts,
                &SimOptions::default(),
            )
            .unwrap()
        };
        for m in cases {
            let h = SampledModel::of_drive(&m, ts).unwrap();
            let inv = StableInverse::of(&h).unwrap();
            let (lead, tail) = inv.lead_tail(1e-12);
            let desired = padded(&there_and_back(30.0, 0.2, ts), lead + 5, tail);
            let before = max_diff(&sim(&m, &desired), &desired);
            let x0 = desired[0];
            let dev: Vec<f64> = desired.iter().map(|v| v - x0).collect();
            let r: Vec<f64> = inv.apply(&dev).iter().map(|v| v + x0).collect();
            let after = max_diff(&sim(&m, &r), &desired);
            assert!(before > 0.2, "{before}");
            assert!(after < 1e-8, "{m:?}: {before} → {after}");
        }
    }

    #[test]
    fn learning_on_the_model_handles_friction() {
        // Truth: the model with Coulomb friction and sticking (docs/drive-model.md). The move
        // reverses, so friction flips sign at rest. The exact linear inverse alone leaves the
        // friction error (about 2 µm here); the learning loop takes the model to tens of nm.
        let ts = 1e-3;
        let m = model(0.0, 47.7);
        let h = SampledModel::of(&m, ts).unwrap();
        let inv = StableInverse::of(&h).unwrap();
        let (lead, tail) = inv.lead_tail(1e-12);
        let desired = padded(&there_and_back(30.0, 0.2, ts), lead, tail);
        let c = compensate_positions(
            &DriveModel::from(m),
            &inv,
            &desired,
            ts,
            &CompensateOptions::default(),
        )
        .unwrap();
        let first = c.history[0];
        let last = max_diff(&simulate(&m, &c.reference, ts), &desired);
        assert!(first > 1e-3, "{:?}", c.history);
        assert!(last < 5e-5 && last < first / 50.0, "{:?}", c.history);
        assert_eq!(last, max_diff(&c.model, &desired));
    }

    #[test]
    fn a_zero_on_the_unit_circle_is_refused() {
        // z(z − 0.5)… with b(z) = z² − 1 (zeros ±1): no bounded inverse.
        let h = SampledModel {
            ts: 1e-3,
            den: vec![1.0, -0.5],
            num: vec![1.0, 0.0, -1.0],
        };
        let e = StableInverse::of(&h).unwrap_err();
        assert!(e.to_string().contains("unit circle"), "{e}");
    }

    #[test]
    fn polynomial_helpers_agree_with_hand_results() {
        // (s³ + 2s² + 3s + 4) / (s² + 1) = s + 2 + (2s + 2)/(s² + 1).
        let (q, r) = divide(&[1.0, 2.0, 3.0, 4.0], &[1.0, 0.0, 1.0]);
        assert_eq!(q, vec![1.0, 2.0]);
        assert_eq!(r, vec![2.0, 2.0]);
        let mut z = roots(&[1.0, -6.0, 11.0, -6.0]);
        z.sort_by(|a, b| a.re.total_cmp(&b.re));
        for (w, want) in z.iter().zip([1.0, 2.0, 3.0]) {
            assert!((w.re - want).abs() < 1e-9 && w.im.abs() < 1e-9);
        }
        assert_eq!(
            from_roots(&[Complex::new(2.0, 0.0), Complex::new(3.0, 0.0)]),
            vec![1.0, -5.0, 6.0]
        );
    }
}
