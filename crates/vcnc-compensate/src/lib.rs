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

use nalgebra::{Complex, DMatrix};
use serde::Serialize;
use vcnc_drive::{ClosedLoopModel, DriveModel, Reference, SimOptions};
use vcnc_gcode::interpolate::time_exact_rates;

/// What can go wrong inverting a model or running the learning loop.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// The model is not stable: it cannot be inverted (the user's model file).
    #[error("cannot invert the model: the model {model:?} is not stable")]
    Unstable {
        /// The model.
        model: Box<DriveModel>,
    },
    /// The model cannot be simulated (its discretisation fails: the user's model file).
    #[error("cannot simulate the model: {0}")]
    Model(vcnc_drive::Error),
    /// The sampled model's numerator is a constant: nothing to invert.
    #[error("cannot invert the sampled model: its numerator is a constant")]
    ConstantNumerator,
    /// A zero of the sampled model lies on the unit circle: no bounded inverse.
    #[error("cannot invert the sampled model: a zero at z = {z:.6} lies on the unit circle (|z| = {:.6})", z.norm())]
    ZeroOnUnitCircle {
        /// The zero.
        z: Complex<f64>,
    },
    /// Zeros of the sampled model repeat: the partial fractions do not apply.
    #[error("cannot invert the sampled model: its zeros repeat at z = {z:.6}")]
    RepeatedZeros {
        /// The repeated zero.
        z: Complex<f64>,
    },
    /// Nothing to compensate.
    #[error("nothing to compensate: no samples")]
    NoSamples,
    /// The sampled model is not of the order its poles give (vcnc's own failure).
    #[error(
        "internal error: the sampled model of {model:?} is not of the expected order (residual {residual:e} of {scale:e})"
    )]
    Order {
        /// The model.
        model: Box<DriveModel>,
        /// Largest coefficient beyond the numerator's degree.
        residual: f64,
        /// Largest numerator coefficient.
        scale: f64,
    },
    /// The model's simulation failed inside the loop (vcnc's own failure).
    #[error("internal error: model simulation: {0}")]
    Simulation(vcnc_drive::Error),
    /// The learning loop's error grew without bound (vcnc's own failure).
    #[error("internal error: the learning loop diverged at iteration {iteration}")]
    Diverged {
        /// The iteration.
        iteration: usize,
    },
}

impl Error {
    /// True when the user's input (the model) is at fault: exit code 2; false for vcnc's own
    /// failure.
    pub fn is_bad_input(&self) -> bool {
        match self {
            Error::Unstable { .. }
            | Error::Model(_)
            | Error::ConstantNumerator
            | Error::ZeroOnUnitCircle { .. }
            | Error::RepeatedZeros { .. }
            | Error::NoSamples => true,
            Error::Order { .. } | Error::Simulation(_) | Error::Diverged { .. } => false,
        }
    }
}

/// Largest |x| of a slice (0 for an empty one).
fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

/// A polynomial, highest power first.
type Poly = Vec<f64>;

/// `p` without leading coefficients below `1e-14` of its largest one.
fn trim(p: &[f64]) -> Poly {
    trim_below(p, 1e-14)
}

/// `p` without leading coefficients below `fraction` of its largest one.
fn trim_below(p: &[f64], fraction: f64) -> Poly {
    let scale = p.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    let first = p
        .iter()
        .position(|c| c.abs() > fraction * scale)
        .unwrap_or(p.len().saturating_sub(1));
    p[first..].to_vec()
}

/// Leading coefficients of a sampled model's numerator below this fraction of its largest one
/// are dropped before it is inverted ([`StableInverse::of`]). Such a coefficient comes from a
/// dead time just under a whole number of samples (3.9963 ms at 1 ms: 1e-9 of the largest); it
/// puts a zero near infinity, whose factor $(1 - z/\zeta)$ is 1 to within this fraction on the
/// unit circle, yet dividing by it gave the inverse's polynomial part coefficients of order
/// 1e9 that cancel: the realistic NMV5000's compensated X set-point reached 7e12 mm/s.
pub const NEGLIGIBLE_LEAD: f64 = 1e-6;

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
        if !(model.is_finite() && drive.is_marginally_stable()) {
            return Err(Error::Unstable {
                model: Box::new(*drive),
            });
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
        .map_err(Error::Model)?;
        let g: Vec<f64> = y[k0 - 1..].to_vec();
        let conv = |j: usize| -> f64 { (0..=na.min(j)).map(|i| den[i] * g[j - i]).sum::<f64>() };
        let num: Vec<f64> = (0..=nb).map(conv).collect();
        // Beyond degree nb the product must vanish: the model is what the formula says.
        let scale = max_abs(&num).max(f64::MIN_POSITIVE);
        let residual = (nb + 1..g.len())
            .map(conv)
            .fold(0.0f64, |m, v| m.max(v.abs()));
        if residual.is_nan() || residual > 1e-7 * scale {
            return Err(Error::Order {
                model: Box::new(*drive),
                residual,
                scale,
            });
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
        // z a(z): the denominator coefficients read as a polynomial in z, times z.
        // H = z^{1+na-nb} b(z)/a(z), so H^{-1} = z^{nb-na-1} a(z)/b(z).
        let mut num: Poly = h.den.clone();
        num.extend(std::iter::repeat_n(
            0.0,
            (h.num.len() - h.den.len()).saturating_sub(1),
        ));
        let den = trim_below(&h.num, NEGLIGIBLE_LEAD);
        if den.len() < 2 {
            return Err(Error::ConstantNumerator);
        }
        let (poly, rem) = divide(&num, &den);
        let dprime = derivative(&den);
        let zs = roots(&den);
        let mut modes = Vec::new();
        for (i, z) in zs.iter().enumerate() {
            if (z.norm() - 1.0).abs() < UNIT_CIRCLE_GAP {
                return Err(Error::ZeroOnUnitCircle { z: *z });
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
                return Err(Error::RepeatedZeros { z: *z });
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

/// Settings of the compensation (`vcnc_pipeline::compensate::compensate_run` and [`compensate_positions`]). Plain data; [`Default`] gives the documented defaults.
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
        return Err(Error::NoSamples);
    }
    let x0 = desired[0];
    let yd: Vec<f64> = desired.iter().map(|x| x - x0).collect();
    // The paper's structure runs on its exact discretisation; a structure with a dead time,
    // filter or extra pole on the drive model's own exact scheme.
    let core = if model.is_core_only() {
        Some(model.core.discretize(ts).map_err(Error::Model)?)
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
                .map_err(Error::Simulation)?,
            None => {
                y = model
                    .simulate(reference, ts, &SimOptions::default())
                    .map_err(Error::Simulation)?;
            }
        }
        let e: Vec<f64> = yd.iter().zip(&y).map(|(a, b)| a - b).collect();
        let err = max_abs(&e);
        history.push(err);
        if !err.is_finite() {
            return Err(Error::Diverged { iteration: it });
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
    // The loop runs at least once (iteration 0) and keeps its first result.
    let Some((_, r, y)) = best else {
        return Err(Error::Diverged { iteration: 0 });
    };
    Ok(CompensatedPositions {
        reference: r.into_iter().map(|v| v + x0).collect(),
        model: y.into_iter().map(|v| v + x0).collect(),
        history,
    })
}

/// `v` (not empty) with `lead` copies of its first and `tail` copies of its last value around it.
pub fn padded(v: &[f64], lead: usize, tail: usize) -> Vec<f64> {
    let (first, last) = (v[0], v[v.len() - 1]);
    std::iter::repeat_n(first, lead)
        .chain(v.iter().copied())
        .chain(std::iter::repeat_n(last, tail))
        .collect()
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

    /// What `run` (a model's `simulate`) gives for `pos` with its time-exact rates at period
    /// `ts`, default options.
    fn with_rates(
        pos: &[f64],
        ts: f64,
        run: impl FnOnce(Reference<'_>, f64, &SimOptions) -> Result<Vec<f64>, vcnc_drive::Error>,
    ) -> Vec<f64> {
        let (vel, acc) = time_exact_rates(pos, ts);
        let r = Reference {
            pos,
            vel: &vel,
            acc: &acc,
        };
        run(r, ts, &SimOptions::default()).unwrap()
    }

    fn simulate(m: &ClosedLoopModel, pos: &[f64], ts: f64) -> Vec<f64> {
        with_rates(pos, ts, |r, ts, o| m.simulate(r, ts, o))
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
        // Each model with the largest error its inverse may leave, mm.
        let cases = [
            (
                DriveModel {
                    delay_s: 2e-3,
                    ..DriveModel::from(core)
                },
                1e-8,
            ),
            (
                DriveModel {
                    delay_s: 1.4e-3,
                    ..DriveModel::from(core)
                },
                1e-8,
            ),
            // Just under four samples (an identified 3.9963 ms, the realistic NMV5000's X):
            // the sampled numerator's first coefficient is about 1e-9 of its largest and is
            // dropped (NEGLIGIBLE_LEAD); the inverse is then exact but for that coefficient
            // (measured 6.8e-6 mm; before, 7.5e11 mm).
            (
                DriveModel {
                    delay_s: 3.9963e-3,
                    ..DriveModel::from(core)
                },
                1.5e-5,
            ),
            (
                DriveModel {
                    reference_filter: Some(ReferenceFilter::FirstOrder { tau_s: 3e-3 }),
                    ..DriveModel::from(core)
                },
                1e-8,
            ),
            (
                DriveModel {
                    delay_s: 1e-3,
                    reference_filter: Some(ReferenceFilter::SecondOrder {
                        wn_hz: 60.0,
                        zeta: 0.6,
                    }),
                    ..DriveModel::from(core)
                },
                1e-8,
            ),
            (
                DriveModel {
                    extra_pole_hz: Some(150.0),
                    ..DriveModel::from(core)
                },
                1e-8,
            ),
        ];
        let sim =
            |m: &DriveModel, pos: &[f64]| with_rates(pos, ts, |r, ts, o| m.simulate(r, ts, o));
        for (m, tol) in cases {
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
            assert!(after < tol, "{m:?}: {before} → {after}");
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
        // `c.model` is the model's response to `c.reference`, simulated in deviations from
        // the start (5 mm): the re-simulation from absolute positions differs by the rounding
        // of that shift (a few ulps of 5 mm, carried through the friction events).
        assert!((last - max_diff(&c.model, &desired)).abs() < 1e-12);
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
