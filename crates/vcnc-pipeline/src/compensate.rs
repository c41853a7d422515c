//! Reference pre-compensation with an identified drive model (docs/compensation.md): the axis
//! reference that makes the model follow the programmed path.
//!
//! The closed-loop model (docs/drive-model.md) is
//! $$ D(s)\,x = N(s)\,x_r - d_c\, s\,\mathcal L\{\operatorname{sgn}\dot x\},\qquad
//!    D = s^3 + a_1 s^2 + a_2 s + a_3,\quad N = b_0 s^3 + b_1 s^2 + b_2 s + a_3 . $$
//! For the output to be the desired path $x_d$ the reference must be
//! $$ x_c = \frac{D(s)}{N(s)}\,x_d + d_c\,\frac{s}{N(s)}\,\operatorname{sgn}\dot x_d , $$
//! the model inverse plus its friction feed-forward. Offline, with the whole trajectory known,
//! the inverse is applied exactly and stably (stable inversion, Devasia, Chen and Paden, IEEE
//! TAC 41(7), 1996): $D/N$ is split into a polynomial part $Q(s)$, applied with the
//! interpolator's analytic derivatives of $x_d$ ($\dot x_d$, $\ddot x_d$; a relative degree
//! above 2 would need the jerk and is refused), and a strictly proper part $R/N$ in partial
//! fractions $\sum_i c_i/(s - z_i)$ over the zeros $z_i$ of $N$, each mode filtered exactly for
//! an input linear between samples (first-order hold, like the model's own simulation). Zeros
//! common to $D$ and $N$ (the root at $s = 0$ of a drive without integral action, $a_3 = 0$)
//! cancel first.
//!
//! A zero in the right half plane (an identified $b_0 < 0$ puts one near $b_1/|b_0|$) cannot be
//! inverted causally, and its exact bounded (anti-causal) inverse acts within $1/z$ of every
//! acceleration change — far faster than the 1 ms reference can carry when the zero lies beyond
//! the drive's bandwidth, which is where identified ones lie. Such a zero is mirrored into the
//! left half plane ($z \to -\bar z$) with $N(0)$ kept, so the inverse stays causal and its gain
//! exact. What remains, $\prod (z - s)/(\bar z + s)$, is an all-pass whose phase at
//! frequencies well below $|z|$ is a pure delay $\tau = \sum 2\operatorname{Re} z/|z|^2$;
//! since the whole path is known in advance, the compensated reference is advanced by $\tau$
//! (the preview of Tomizuka's zero-phase-error tracking controller, ZPETC, in continuous
//! time), leaving an error of order $(\omega/|z|)^3$.
//!
//! The compensated velocity and acceleration, which the drives' feed-forward and the model use,
//! are the same operator applied to $\dot x_d$ and $\ddot x_d$ where the relative degree allows,
//! else second-order central differences of the compensated position. Everything is computed on
//! deviations from the first sample (the model starts at rest there).

use vcnc_drive::ClosedLoopModel;
use vcnc_kinematics::nalgebra::{Complex, DMatrix};

use crate::Error;
use crate::run::AxisSignals;

/// A polynomial, highest power first.
type Poly = Vec<f64>;

/// The degree-trimmed polynomial (leading coefficients whose magnitude is below `tol` times the
/// largest removed).
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

/// Roots of a polynomial of degree ≥ 1 (companion-matrix eigenvalues).
fn roots(p: &[f64]) -> Vec<Complex<f64>> {
    let p = trim(p);
    let n = p.len() - 1;
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

/// A rational operator $Q(s) + \sum_i c_i/(s - z_i)$ applied to sampled signals.
#[derive(Debug, Clone)]
struct Operator {
    /// Polynomial part, highest power first (degree ≤ 2).
    q: Poly,
    /// Partial fractions: residue and pole. Conjugate pairs appear once with `pair = true`.
    modes: Vec<(Complex<f64>, Complex<f64>, bool)>,
}

impl Operator {
    /// `num(s) / den(s)`. Errors when `den` has repeated roots (the partial fractions need
    /// distinct ones) or the polynomial part needs derivatives above the second.
    fn new(num: &[f64], den: &[f64]) -> Result<Operator, String> {
        let (q, r) = divide(num, den);
        if q.len() > 3 {
            return Err(format!(
                "the inverse needs derivatives of order {} of the reference (at most 2 are known)",
                q.len() - 1
            ));
        }
        let den = trim(den);
        let dprime = derivative(&den);
        let zs = roots(&den);
        let mut modes = Vec::new();
        for (i, z) in zs.iter().enumerate() {
            if z.im < -1e-9 * z.norm().max(1.0) {
                continue; // the conjugate of a pair already taken
            }
            let dp = eval(&dprime, *z);
            let repeated = zs
                .iter()
                .enumerate()
                .any(|(j, w)| j != i && (w - z).norm() <= 1e-6 * z.norm().max(1.0));
            if dp.norm() == 0.0 || repeated {
                return Err(format!("the model's zeros repeat at {z} rad/s"));
            }
            let c = eval(&r, *z) / dp;
            let pair = z.im.abs() > 1e-9 * z.norm().max(1.0);
            modes.push((c, *z, pair));
        }
        Ok(Operator { q, modes })
    }

    /// Applies the operator to `u` (samples at `ts`, linear between them) with its first two
    /// derivatives `du`, `ddu` (used by the polynomial part only).
    fn apply(&self, u: &[f64], du: &[f64], ddu: &[f64], ts: f64) -> Vec<f64> {
        let n = u.len();
        let deg = self.q.len() - 1;
        let mut y: Vec<f64> = (0..n)
            .map(|k| {
                let d = [u[k], du[k], ddu[k]];
                self.q.iter().enumerate().map(|(i, c)| c * d[deg - i]).sum()
            })
            .collect();
        for &(c, z, pair) in &self.modes {
            let w = first_order(z, u, ts);
            let k = if pair { 2.0 } else { 1.0 };
            for (y, w) in y.iter_mut().zip(&w) {
                *y += k * (c * w).re;
            }
        }
        y
    }
}

/// The solution of $\dot w = z\,w + u$ from $w = 0$ (`z` in the left half plane) for `u` linear
/// between samples.
fn first_order(z: Complex<f64>, u: &[f64], ts: f64) -> Vec<Complex<f64>> {
    let n = u.len();
    let mut w = vec![Complex::new(0.0, 0.0); n];
    // Over one step of length T from w0, with u going linearly from u0 to u1:
    // w1 = e^{zT} w0 + g0 u0 + g1 (u1 - u0),
    // g0 = (e^{zT} - 1)/z, g1 = (e^{zT} - 1 - zT)/(z² T) (limits T and T/2 as z → 0).
    let zt = z * ts;
    let e = zt.exp();
    let (g0, g1) = if zt.norm() < 1e-6 {
        (
            Complex::new(ts, 0.0) * (1.0 + zt / 2.0),
            Complex::new(ts / 2.0, 0.0) * (1.0 + zt / 3.0),
        )
    } else {
        ((e - 1.0) / z, (e - 1.0 - zt) / (z * z * ts))
    };
    for k in 0..n.saturating_sub(1) {
        w[k + 1] = e * w[k] + g0 * u[k] + g1 * (u[k + 1] - u[k]);
    }
    w
}

/// `p` with its right-half-plane roots mirrored into the left half plane ($z \to -\bar z$),
/// same magnitude on the imaginary axis, same value at $s = 0$.
fn minimum_phase(p: &[f64]) -> Poly {
    let p = trim(p);
    let zs = roots(&p);
    if zs.iter().all(|z| z.re <= 0.0) {
        return p;
    }
    let mut out = vec![Complex::new(p[0], 0.0)];
    for z in zs {
        let z = if z.re > 0.0 { -z.conj() } else { z };
        // out ← out · (s − z)
        let mut next = vec![Complex::new(0.0, 0.0); out.len() + 1];
        for (i, c) in out.iter().enumerate() {
            next[i] += c;
            next[i + 1] -= c * z;
        }
        out = next;
    }
    let mut q: Poly = out.iter().map(|c| c.re).collect();
    // Keep the value at 0 (the DC gain of the inverse): mirroring a real root flips its sign.
    let (old0, new0) = (p[p.len() - 1], q[q.len() - 1]);
    if old0 != 0.0 && new0 != 0.0 && (old0 < 0.0) != (new0 < 0.0) {
        for c in &mut q {
            *c = -*c;
        }
    }
    q
}

/// `(u_{k+1} - u_{k-1}) / 2T` inside, one-sided at the ends.
fn central(u: &[f64], ts: f64) -> Vec<f64> {
    let n = u.len();
    (0..n)
        .map(|k| match (k, n) {
            (_, 0 | 1) => 0.0,
            (0, _) => (u[1] - u[0]) / ts,
            (k, n) if k == n - 1 => (u[k] - u[k - 1]) / ts,
            (k, _) => (u[k + 1] - u[k - 1]) / (2.0 * ts),
        })
        .collect()
}

/// The reference that makes `model` follow `desired` (see the module documentation): position,
/// velocity and acceleration at the same samples. `deadband` (axis units/s) is the speed below
/// which the friction feed-forward treats the desired motion as at rest.
pub fn compensate_axis(
    model: &ClosedLoopModel,
    desired: &AxisSignals,
    ts: f64,
    deadband: f64,
) -> Result<AxisSignals, Error> {
    let fail = |m: String| {
        Error::Usage(format!(
            "axis {}: cannot invert the model: {m}",
            desired.name
        ))
    };
    if !(model.is_finite() && model.is_marginally_stable()) {
        return Err(fail("the model is not stable".into()));
    }
    let mut d = vec![1.0, model.a1, model.a2, model.a3];
    let mut nn = vec![model.b0, model.b1, model.b2, model.a3];
    // A drive without integral action: D(0) = N(0) = 0, the root s = 0 cancels.
    if model.a3 == 0.0 {
        d.pop();
        nn.pop();
    }
    if trim(&nn).iter().all(|c| *c == 0.0) {
        return Err(fail("its numerator is zero".into()));
    }
    let advance = all_pass_delay(&nn);
    let nn = minimum_phase(&nn);
    let inverse = Operator::new(&d, &nn).map_err(fail)?;
    let n = desired.pos.len();
    let x0 = desired.pos.first().copied().unwrap_or(0.0);
    let dev: Vec<f64> = desired.pos.iter().map(|x| x - x0).collect();
    let zero = vec![0.0; n];
    let jerk = central(&desired.acc, ts);
    let mut pos = inverse.apply(&dev, &desired.vel, &desired.acc, ts);
    let mut vel = inverse.apply(&desired.vel, &desired.acc, &jerk, ts);
    // The acceleration: exact when the operator needs no more than the acceleration of
    // the desired path (relative degree 0), else from the compensated velocity.
    let mut acc = if inverse.q.len() == 1 {
        inverse.apply(&desired.acc, &zero, &zero, ts)
    } else {
        central(&vel, ts)
    };
    if model.dc != 0.0 {
        // Friction feed-forward dc·(s/N)·sgn(ẋ_d) and its derivatives (dc·s²/N, dc·s³/N).
        let f: Vec<f64> = desired
            .vel
            .iter()
            .map(|v| if v.abs() <= deadband { 0.0 } else { v.signum() })
            .collect();
        // s/N, or 1/(N/s) once the root at 0 has cancelled.
        let mut num = if model.a3 == 0.0 {
            vec![1.0]
        } else {
            vec![1.0, 0.0]
        };
        let mut parts = Vec::new();
        for _ in 0..3 {
            parts.push(Operator::new(&num, &nn).ok().filter(|o| o.q.len() == 1));
            num.push(0.0);
        }
        let fp = parts[0]
            .as_ref()
            .ok_or_else(|| fail("its friction feed-forward would be a step".into()))?
            .apply(&f, &zero, &zero, ts);
        let fv = match &parts[1] {
            Some(o) => o.apply(&f, &zero, &zero, ts),
            None => central(&fp, ts),
        };
        let fa = match &parts[2] {
            Some(o) => o.apply(&f, &zero, &zero, ts),
            None => central(&fv, ts),
        };
        for k in 0..n {
            pos[k] += model.dc * fp[k];
            vel[k] += model.dc * fv[k];
            acc[k] += model.dc * fa[k];
        }
    }
    for p in &mut pos {
        *p += x0;
    }
    if advance > 0.0 {
        let (p, v, a) = (
            shift(&pos, &vel, advance, ts),
            shift(&vel, &acc, advance, ts),
            shift(&acc, &central(&acc, ts), advance, ts),
        );
        (pos, vel, acc) = (p, v, a);
    }
    Ok(AxisSignals {
        name: desired.name,
        unit: desired.unit,
        pos,
        vel,
        acc,
    })
}

/// Velocity and acceleration of an axis reference against the axis' limits.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LimitMargin {
    /// The axis.
    pub axis: vcnc_axis::AxisName,
    /// Largest |velocity| of the reference, units/s.
    pub max_velocity: f64,
    /// The axis' velocity limit, units/s.
    pub velocity_limit: f64,
    /// Largest |acceleration| of the reference, units/s².
    pub max_acceleration: f64,
    /// The axis' acceleration limit, units/s².
    pub acceleration_limit: f64,
}

impl LimitMargin {
    /// Of a reference against a machine axis.
    pub fn of(axis: &vcnc_machine::Axis, s: &AxisSignals) -> LimitMargin {
        use crate::stats::max_abs;
        LimitMargin {
            axis: axis.name,
            max_velocity: max_abs(&s.vel),
            velocity_limit: axis.max_velocity,
            max_acceleration: max_abs(&s.acc),
            acceleration_limit: axis.max_acceleration,
        }
    }

    /// Both within their limits.
    pub fn within(&self) -> bool {
        self.max_velocity <= self.velocity_limit * (1.0 + 1e-9)
            && self.max_acceleration <= self.acceleration_limit * (1.0 + 1e-9)
    }
}

/// Every axis reference of `run` compensated with its model (one per machine axis, in order),
/// with the margins to the axes' limits. The models' friction deadband is the identifier's
/// default, 1.5 units/s.
pub fn compensate_run(
    machine: &vcnc_machine::Machine,
    run: &crate::Run,
    models: &[ClosedLoopModel],
) -> Result<(Vec<AxisSignals>, Vec<LimitMargin>), Error> {
    use rayon::prelude::*;
    if models.len() != run.axes.len() {
        return Err(Error::Usage(format!(
            "{} models for {} axes",
            models.len(),
            run.axes.len()
        )));
    }
    let axes = models
        .par_iter()
        .zip(run.axes.par_iter())
        .map(|(m, s)| compensate_axis(m, s, run.ts, 1.5))
        .collect::<Result<Vec<_>, _>>()?;
    let margins = machine
        .axes
        .iter()
        .zip(&axes)
        .map(|(a, s)| LimitMargin::of(a, s))
        .collect();
    Ok((axes, margins))
}

/// The low-frequency delay $\sum 2\operatorname{Re} z/|z|^2$, s, of the all-pass left by
/// mirroring the right-half-plane roots of `p`.
fn all_pass_delay(p: &[f64]) -> f64 {
    roots(p)
        .iter()
        .filter(|z| z.re > 0.0)
        .map(|z| 2.0 * z.re / z.norm_sqr())
        .sum()
}

/// `u(t + tau)` at the samples (cubic Hermite with the derivative `du`), the last value held
/// beyond the end.
fn shift(u: &[f64], du: &[f64], tau: f64, ts: f64) -> Vec<f64> {
    let n = u.len();
    let whole = (tau / ts).floor();
    let f = tau / ts - whole;
    let j = whole as usize;
    (0..n)
        .map(|k| {
            let i = k + j;
            if i + 1 >= n {
                return u[n - 1];
            }
            // Hermite basis on [t_i, t_{i+1}] at fraction f.
            let (f2, f3) = (f * f, f * f * f);
            let h00 = 2.0 * f3 - 3.0 * f2 + 1.0;
            let h10 = f3 - 2.0 * f2 + f;
            let h01 = -2.0 * f3 + 3.0 * f2;
            let h11 = f3 - f2;
            h00 * u[i] + h10 * ts * du[i] + h01 * u[i + 1] + h11 * ts * du[i + 1]
        })
        .collect()
}

#[cfg(test)]
mod spiral_experiment {
    use super::*;

    #[test]
    #[ignore]
    fn spiral() {
        let machine = vcnc_machine::Machine::embedded_nmv5000().unwrap();
        let run =
            crate::run::prepare(&machine, vcnc_machine::embedded::SPIRAL_NGC, "s", false).unwrap();
        let axes: Vec<_> = machine.axes.iter().collect();
        let ids = crate::identify::identify_axes(&machine, &axes, None).unwrap();
        let models: Vec<ClosedLoopModel> = ids.iter().map(|r| r.result.identified).collect();
        for (label, ms) in [
            ("identified", models.clone()),
            (
                "true",
                machine.axes.iter().map(|a| a.true_model()).collect(),
            ),
        ] {
            let (comp, _margins) = compensate_run(&machine, &run, &ms).unwrap();
            let mut crun = run.clone();
            crun.axes = comp;
            let traces = crate::simulate::simulate_true(&machine, &crun).unwrap();
            let pos: Vec<&[f64]> = traces.iter().map(|t| t.true_position.as_slice()).collect();
            let (_, c) = crate::predict::contour(&machine, &run, &pos).unwrap();
            eprintln!(
                "{label}: contour max {:.3} µm rms {:.3}, orientation max {:.5} mrad",
                c.tip_max_mm * 1e3,
                c.tip_rms_mm * 1e3,
                c.orientation_max_rad * 1e3
            );
            let n = c.tip_mm.len();
            for w in 0..20 {
                let (a, b) = (w * n / 20, (w + 1) * n / 20);
                let m = c.tip_mm[a..b].iter().cloned().fold(0.0, f64::max);
                let (k, _) = c.tip_mm[a..b]
                    .iter()
                    .enumerate()
                    .fold(
                        (0, 0.0),
                        |acc, (i, v)| if *v > acc.1 { (i, *v) } else { acc },
                    );
                eprint!(
                    "[{:.2}s {:.2}µm @{:.3}] ",
                    a as f64 * 1e-3,
                    m * 1e3,
                    (a + k) as f64 * 1e-3
                );
            }
            eprintln!();
            for (i, a) in crun.axes.iter().enumerate() {
                let x = ms[i]
                    .simulate(a.reference(), run.ts, &vcnc_drive::SimOptions::default())
                    .unwrap();
                let d = &run.axes[i].pos;
                let win = |lo: usize, hi: usize, v: &[f64]| {
                    (lo..hi.min(d.len()))
                        .map(|k| (v[k] - d[k]).abs())
                        .fold(0.0, f64::max)
                        * 1e3
                };
                let n = d.len();
                eprintln!(
                    "  {}: model-vs-desired start {:.3} mid {:.3} end {:.3}; drive-vs-desired start {:.3} mid {:.3} end {:.3}",
                    a.name,
                    win(0, 60, &x),
                    win(60, n - 60, &x),
                    win(n - 60, n, &x),
                    win(0, 60, &traces[i].true_position),
                    win(60, n - 60, &traces[i].true_position),
                    win(n - 60, n, &traces[i].true_position)
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vcnc_axis::{AxisName, Unit};
    use vcnc_drive::{Reference, SimOptions};

    /// A smooth rest-to-rest move: x = L (10 τ³ − 15 τ⁴ + 6 τ⁵), τ = t / T, then rest.
    fn quintic(len: f64, t_move: f64, ts: f64, n: usize) -> AxisSignals {
        let mut s = AxisSignals {
            name: AxisName::X,
            unit: Unit::Mm,
            pos: vec![0.0; n],
            vel: vec![0.0; n],
            acc: vec![0.0; n],
        };
        for k in 0..n {
            let tau = (k as f64 * ts / t_move).min(1.0);
            s.pos[k] = 5.0 + len * (10.0 * tau.powi(3) - 15.0 * tau.powi(4) + 6.0 * tau.powi(5));
            if tau < 1.0 {
                s.vel[k] =
                    len / t_move * (30.0 * tau.powi(2) - 60.0 * tau.powi(3) + 30.0 * tau.powi(4));
                s.acc[k] = len / (t_move * t_move)
                    * (60.0 * tau - 180.0 * tau.powi(2) + 120.0 * tau.powi(3));
            }
        }
        s
    }

    fn model(b0: f64, dc: f64) -> ClosedLoopModel {
        // The paper's Table 1 drive (docs/reference-numbers.md) with Vff = 0.5, Bff = 0.1.
        ClosedLoopModel {
            a1: 238.4335,
            a2: 48421.586,
            a3: 2487140.3,
            b0,
            b1: 117.5424,
            b2: 37258.98,
            dc,
        }
    }

    fn track_error(m: &ClosedLoopModel, r: &AxisSignals, desired: &AxisSignals, ts: f64) -> f64 {
        let x = m
            .simulate(
                Reference {
                    pos: &r.pos,
                    vel: &r.vel,
                    acc: &r.acc,
                },
                ts,
                &SimOptions::default(),
            )
            .unwrap();
        x.iter()
            .zip(&desired.pos)
            .fold(0.0f64, |e, (a, b)| e.max((a - b).abs()))
    }

    #[test]
    fn the_model_follows_the_compensated_reference() {
        // Truth: the model itself. Uncompensated, its following error on a 100 mm move in
        // 0.4 s is hundreds of µm; with the compensated reference it must follow the desired
        // path to a fraction of a µm (what is left is the 1 ms sampling of the reference).
        let ts = 1e-3;
        let desired = quintic(100.0, 0.4, ts, 800);
        // What is left comes from sampling the reference at 1 ms (the inverse and the model
        // both hold it linear between samples): it must shrink as T², here 4× when the
        // samples halve.
        for m in [model(0.0, 0.0), model(0.0, 47.7), model(0.3, 47.7)] {
            let before = track_error(&m, &desired, &desired, ts);
            let c = compensate_axis(&m, &desired, ts, 1.5).unwrap();
            let after = track_error(&m, &c, &desired, ts);
            assert!(before > 1.0, "{before}");
            assert!(after < 1e-3, "{m:?}: {before} → {after}");
            if m.dc == 0.0 {
                let fine = quintic(100.0, 0.4, ts / 2.0, 1600);
                let c2 = compensate_axis(&m, &fine, ts / 2.0, 1.5).unwrap();
                let after2 = track_error(&m, &c2, &fine, ts / 2.0);
                assert!(
                    after / after2 > 3.2,
                    "{m:?}: {after} at 1 ms, {after2} at 0.5 ms"
                );
            }
        }
    }

    #[test]
    fn a_non_minimum_phase_model_is_approximated_by_its_mirror() {
        // b0 < 0: N = b0 s³ + b1 s² + b2 s + a3 has a real zero at ≈ +b1/|b0| = 2350 rad/s
        // in the right half plane. Mirrored and advanced by 2/z, the inverse misses an all-pass
        // error of order (ω/z)³: at the move's ~10 Hz the error must drop by well over 100×
        // (mirroring alone leaves the 2/z = 0.85 ms delay: v·2/z ≈ 0.2 mm).
        let ts = 1e-3;
        let m = model(-0.05, 0.0);
        let zs = roots(&[m.b0, m.b1, m.b2, m.a3]);
        assert!(zs.iter().any(|z| z.re > 2000.0), "{zs:?}");
        let mirrored = minimum_phase(&[m.b0, m.b1, m.b2, m.a3]);
        assert!(roots(&mirrored).iter().all(|z| z.re < 0.0));
        assert!((mirrored[3] - m.a3).abs() < 1e-6 * m.a3, "{mirrored:?}");
        for w in [1.0, 100.0, 5000.0] {
            let (a, b) = (
                eval(&mirrored, Complex::new(0.0, w)).norm(),
                eval(&[m.b0, m.b1, m.b2, m.a3], Complex::new(0.0, w)).norm(),
            );
            assert!((a - b).abs() < 1e-9 * b, "{w}: {a} vs {b}");
        }
        // Rest before the move: the advanced reference starts moving 0.85 ms early.
        let mut desired = quintic(50.0, 0.3, ts, 700);
        for v in [&mut desired.pos, &mut desired.vel, &mut desired.acc] {
            let first = v[0];
            v.splice(0..0, std::iter::repeat_n(first, 20));
        }
        let before = track_error(&m, &desired, &desired, ts);
        let c = compensate_axis(&m, &desired, ts, 1.5).unwrap();
        let after = track_error(&m, &c, &desired, ts);
        assert!(after < before / 100.0, "{before} → {after}");
    }

    #[test]
    fn polynomial_helpers_agree_with_hand_results() {
        // (s³ + 2s² + 3s + 4) / (s² + 1) = s + 2 + (2s + 2)/(s² + 1).
        let (q, r) = divide(&[1.0, 2.0, 3.0, 4.0], &[1.0, 0.0, 1.0]);
        assert_eq!(q, vec![1.0, 2.0]);
        assert_eq!(r, vec![2.0, 2.0]);
        let mut z = roots(&[1.0, -6.0, 11.0, -6.0]);
        z.sort_by(|a, b| a.re.partial_cmp(&b.re).unwrap());
        for (w, want) in z.iter().zip([1.0, 2.0, 3.0]) {
            assert!((w.re - want).abs() < 1e-9 && w.im.abs() < 1e-9);
        }
    }
}
