//! The 7-parameter closed-loop feed-drive model (paper eq. 3, corrected in docs/drive-model.md).
//!
//! $$ (s^3 + a_1 s^2 + a_2 s + a_3)\,x = (b_0 s^3 + b_1 s^2 + b_2 s + a_3)\,x_r - d_c\, s\, \mathcal{L}\{\operatorname{sgn} \dot x\} $$
//!
//! The numerator constant is always $a_3$: the integral action acts on $x_r - x$, so the model has
//! no steady-state position error at rest. The paper prints the model with a $1/s$ term on both
//! sides; multiplying through by $s$ gives the form above.
//!
//! Variables are named as in the paper (`a1`, `wn`, `zeta`, `dc`, ...).
//!
//! Time simulation ([`ClosedLoopModel::simulate`]) uses the state $[q = \int (x_r - x)\,dt,\ x,\ v]$,
//!
//! $$ \dot v = a_3 q - a_2 x - a_1 v + b_2 x_r + b_1 \dot x_r + b_0 \ddot x_r - d_c \operatorname{sgn}(v), $$
//!
//! discretised exactly for inputs that are linear between samples (first-order hold) with the
//! friction sign held over each sample. Zero-order hold on $x_r$ would add half a sample of lag
//! (about 124 µm at 250 mm/s, docs/drive-model.md).

use nalgebra::{Complex, Dim, Matrix, RawStorage, SMatrix, SVector};
use serde::{Deserialize, Serialize};

use crate::Error;

/// Closed-loop model of one feed drive: three poles, three zeros and the Coulomb friction
/// amplitude (paper eq. 3, docs/drive-model.md). Units are those of the axis: mm (linear axes) or
/// deg (rotary axes), and seconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClosedLoopModel {
    /// Denominator coefficient of $s^2$, 1/s.
    pub a1: f64,
    /// Denominator coefficient of $s$, 1/s².
    pub a2: f64,
    /// Denominator constant, 1/s³ (also the numerator constant: integral action).
    pub a3: f64,
    /// Numerator coefficient of $s^3$ (inertia feed-forward, $J_{ff}$ for P-PI), dimensionless.
    pub b0: f64,
    /// Numerator coefficient of $s^2$, 1/s.
    pub b1: f64,
    /// Numerator coefficient of $s$, 1/s².
    pub b2: f64,
    /// Coulomb friction as an acceleration, $d_c = T_c r_g / J$, axis units/s².
    pub dc: f64,
}

/// Pole locations of the model: $s^3 + a_1 s^2 + a_2 s + a_3 = (s + p)(s^2 + 2\zeta\omega_n s + \omega_n^2)$
/// (paper eq. 11).
///
/// When all three poles are real the split is not unique; [`ClosedLoopModel::poles`] takes as `p`
/// the root whose sign differs from the other two, or, when all three share a sign, the one of
/// smallest magnitude (the slow integrator pole of a P-PI drive), and `zeta >= 1` for the pair.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Poles {
    /// Real pole magnitude, rad/s (the pole is at $s = -p$; negative `p` means unstable).
    pub p: f64,
    /// Natural frequency of the pole pair, rad/s.
    pub wn: f64,
    /// Damping ratio of the pole pair, dimensionless.
    pub zeta: f64,
}

impl Poles {
    /// Real pole in Hz.
    pub fn p_hz(&self) -> f64 {
        self.p / std::f64::consts::TAU
    }

    /// Natural frequency in Hz.
    pub fn wn_hz(&self) -> f64 {
        self.wn / std::f64::consts::TAU
    }

    /// Poles given in Hz (`p_hz`, `wn_hz`) and damping ratio.
    pub fn from_hz(p_hz: f64, wn_hz: f64, zeta: f64) -> Poles {
        Poles {
            p: p_hz * std::f64::consts::TAU,
            wn: wn_hz * std::f64::consts::TAU,
            zeta,
        }
    }

    /// Denominator coefficients $(a_1, a_2, a_3)$ of these poles:
    /// $a_1 = p + 2\zeta\omega_n$, $a_2 = \omega_n^2 + 2\zeta\omega_n p$, $a_3 = p\,\omega_n^2$.
    pub fn denominator(&self) -> (f64, f64, f64) {
        let Poles { p, wn, zeta } = *self;
        (
            p + 2.0 * zeta * wn,
            wn * wn + 2.0 * zeta * wn * p,
            p * wn * wn,
        )
    }

    /// The three poles as complex numbers, rad/s.
    pub fn roots(&self) -> [Complex<f64>; 3] {
        let Poles { p, wn, zeta } = *self;
        let re = -zeta * wn;
        let disc = zeta * zeta - 1.0;
        let pair = if disc >= 0.0 {
            let r = wn * disc.sqrt();
            [Complex::new(re + r, 0.0), Complex::new(re - r, 0.0)]
        } else {
            let im = wn * (-disc).sqrt();
            [Complex::new(re, im), Complex::new(re, -im)]
        };
        [Complex::new(-p, 0.0), pair[0], pair[1]]
    }

    /// Every pole strictly in the left half plane.
    pub fn is_stable(&self) -> bool {
        self.p > 0.0 && self.wn > 0.0 && self.zeta > 0.0
    }
}

/// How [`ClosedLoopModel::simulate`] integrates the model between samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Integrator {
    /// Exact discretisation with first-order hold on $x_r, \dot x_r, \ddot x_r$ (default).
    #[default]
    ExactFoh,
    /// Classical fourth-order Runge–Kutta, inputs linearly interpolated, `substeps` per sample.
    /// Friction is always explicit here (sign of the step-start velocity with the deadband):
    /// a cross-check of the exact scheme, not a model of sticking.
    Rk4 {
        /// RK4 steps per sample period.
        substeps: u32,
    },
}

/// Options of a model simulation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimOptions {
    /// Explicit friction only (`sticking = false`): below this speed (axis units/s) the friction
    /// sign is taken as 0. Default 0.1 (mm/s or deg/s): the simulated velocity is noise-free, so
    /// a small band only keeps the explicit model from chattering at rest.
    pub friction_deadband: f64,
    /// Integration scheme.
    pub integrator: Integrator,
    /// Coulomb friction with true sticking (default `true`, exact discretisation only): the
    /// friction over each step is chosen implicitly from the end-of-step velocity, as in the
    /// Kikuuwe et al. (2005) step of the true drive (docs/drive-model.md). An axis whose driving
    /// acceleration stays below $d_c$ stays exactly at rest, and breakaway after a reversal or
    /// from rest is reproduced. With `false`, the sign of the start-of-step velocity (with
    /// [`SimOptions::friction_deadband`]) is held over the step.
    pub sticking: bool,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            friction_deadband: 0.1,
            integrator: Integrator::ExactFoh,
            sticking: true,
        }
    }
}

/// Reference signal sampled at the period `ts`: position, velocity, acceleration, all of the same
/// length (axis units, units/s, units/s²).
#[derive(Debug, Clone, Copy)]
pub struct Reference<'a> {
    /// Reference position $x_r$.
    pub pos: &'a [f64],
    /// Reference velocity $\dot x_r$.
    pub vel: &'a [f64],
    /// Reference acceleration $\ddot x_r$.
    pub acc: &'a [f64],
}

impl<'a> Reference<'a> {
    /// Checks that the three slices have the same, non-zero length and finite values.
    pub fn check(&self) -> Result<usize, Error> {
        self.check_piece(0)
    }

    /// Checks the next piece of a reference fed in pieces ([`crate::DriveStream`],
    /// [`crate::ModelStream`]) whose first `first` samples came before: the three slices of
    /// the same length and finite values, a bad value named by its index in the whole
    /// reference (`first` + its index in the piece). The first piece must not be empty
    /// ([`Error::EmptySignal`], as [`Reference::check`]); a later empty piece is accepted.
    /// Returns the piece's length.
    pub(crate) fn check_piece(&self, first: usize) -> Result<usize, Error> {
        let n = self.pos.len();
        if n == 0 && first == 0 {
            return Err(Error::EmptySignal);
        }
        if self.vel.len() != n || self.acc.len() != n {
            return Err(Error::LengthMismatch {
                pos: n,
                vel: self.vel.len(),
                acc: self.acc.len(),
            });
        }
        for (name, s) in [
            ("position", self.pos),
            ("velocity", self.vel),
            ("acceleration", self.acc),
        ] {
            // A branch-free pass first (the compiler vectorises it); the index only on failure.
            let finite = s
                .chunks(16)
                .all(|c| c.iter().fold(true, |ok, v| ok & v.is_finite()));
            if !finite && let Some(k) = s.iter().position(|v| !v.is_finite()) {
                return Err(Error::NonFinite {
                    signal: name,
                    index: first + k,
                });
            }
        }
        Ok(n)
    }
}

/// Central-difference velocity and acceleration of a sampled position (one-sided at the ends),
/// for traces that carry positions only (measured data). Returns `(vel, acc)`.
///
/// $$ \dot x_k \approx \frac{x_{k+1} - x_{k-1}}{2T_s}, \qquad \ddot x_k \approx \frac{x_{k+1} - 2x_k + x_{k-1}}{T_s^2} $$
pub fn central_differences(x: &[f64], ts: f64) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let mut vel = vec![0.0; n];
    let mut acc = vec![0.0; n];
    if n < 3 {
        return (vel, acc);
    }
    for k in 1..n - 1 {
        vel[k] = (x[k + 1] - x[k - 1]) / (2.0 * ts);
        acc[k] = (x[k + 1] - 2.0 * x[k] + x[k - 1]) / (ts * ts);
    }
    vel[0] = (x[1] - x[0]) / ts;
    vel[n - 1] = (x[n - 1] - x[n - 2]) / ts;
    acc[0] = acc[1];
    acc[n - 1] = acc[n - 2];
    (vel, acc)
}

/// A model discretised for one sample period: the per-step update
/// $z_{k+1} = \Phi z_k + G_0 u_k + G_1 u_{k+1} + g_f f_k$ with $z = [q, x, v]$,
/// $u = [x_r, \dot x_r, \ddot x_r]$ and $f = \operatorname{sgn}(v_k)$.
///
/// Building it costs one 10×10 matrix exponential; stepping is a few dozen flops, so repeated
/// simulations of one model (identification refinement) should build it once.
#[derive(Debug, Clone, PartialEq)]
pub struct Discretized {
    phi: SMatrix<f64, 3, 3>,
    g0: SMatrix<f64, 3, 3>,
    g1: SMatrix<f64, 3, 3>,
    gf: SVector<f64, 3>,
    /// Sample period, s.
    pub ts: f64,
}

impl ClosedLoopModel {
    /// Model with the given poles and numerator/friction terms.
    pub fn from_poles(poles: &Poles, b0: f64, b1: f64, b2: f64, dc: f64) -> ClosedLoopModel {
        let (a1, a2, a3) = poles.denominator();
        ClosedLoopModel {
            a1,
            a2,
            a3,
            b0,
            b1,
            b2,
            dc,
        }
    }

    /// All seven parameters finite.
    pub fn is_finite(&self) -> bool {
        [
            self.a1, self.a2, self.a3, self.b0, self.b1, self.b2, self.dc,
        ]
        .iter()
        .all(|v| v.is_finite())
    }

    /// Routh–Hurwitz for a monic cubic: $a_1 > 0$, $a_3 > 0$, $a_1 a_2 > a_3$ — every pole strictly
    /// in the left half plane. (A model with $a_3 = 0$, such as a drive without integral action,
    /// has a pole at the origin and is reported as not strictly stable; see
    /// [`ClosedLoopModel::is_marginally_stable`].)
    pub fn is_stable(&self) -> bool {
        self.is_finite() && self.a1 > 0.0 && self.a3 > 0.0 && self.a1 * self.a2 > self.a3
    }

    /// Stable, or a single pole at the origin with the other two stable ($a_3 = 0$,
    /// $a_1, a_2 > 0$): a drive without integral action (EMPS benchmark).
    pub fn is_marginally_stable(&self) -> bool {
        self.is_stable() || (self.is_finite() && self.a3 == 0.0 && self.a1 > 0.0 && self.a2 > 0.0)
    }

    /// The three roots of $s^3 + a_1 s^2 + a_2 s + a_3$, rad/s: one real root found by a
    /// safeguarded Newton iteration, then the deflated quadratic.
    pub fn roots(&self) -> [Complex<f64>; 3] {
        let (r, c1, c0) = self.split_real_root();
        let disc = c1 * c1 - 4.0 * c0;
        let pair = if disc >= 0.0 {
            let sq = disc.sqrt();
            // Numerically stable quadratic roots.
            let qv = -0.5 * (c1 + c1.signum() * sq);
            if qv == 0.0 {
                [Complex::new(0.0, 0.0), Complex::new(0.0, 0.0)]
            } else {
                [Complex::new(qv, 0.0), Complex::new(c0 / qv, 0.0)]
            }
        } else {
            let im = 0.5 * (-disc).sqrt();
            [Complex::new(-0.5 * c1, im), Complex::new(-0.5 * c1, -im)]
        };
        [Complex::new(r, 0.0), pair[0], pair[1]]
    }

    /// A real root `r` and the deflated quadratic $s^2 + c_1 s + c_0$.
    fn split_real_root(&self) -> (f64, f64, f64) {
        let (a1, a2, a3) = (self.a1, self.a2, self.a3);
        let f = |s: f64| ((s + a1) * s + a2) * s + a3;
        // Cauchy bound on the root magnitudes brackets a real root.
        let bound = 1.0 + a1.abs().max(a2.abs()).max(a3.abs());
        let (mut lo, mut hi) = (-bound, bound);
        // f(-bound) < 0 < f(bound) for a monic cubic.
        let mut s = if a3 == 0.0 {
            0.0
        } else {
            -a3 / a2.abs().max(1e-300)
        };
        if !(s > lo && s < hi) {
            s = 0.0;
        }
        for _ in 0..200 {
            let fs = f(s);
            if fs == 0.0 {
                break;
            }
            if fs < 0.0 {
                lo = s;
            } else {
                hi = s;
            }
            let df = (3.0 * s + 2.0 * a1) * s + a2;
            let mut next = s - fs / df;
            if !(next > lo && next < hi && next.is_finite()) {
                next = 0.5 * (lo + hi);
            }
            if (next - s).abs() <= 1e-15 * (1.0 + s.abs()) {
                s = next;
                break;
            }
            s = next;
        }
        let c1 = a1 + s;
        let c0 = a2 + s * c1;
        (s, c1, c0)
    }

    /// The model with characteristic polynomial $s^3 + a_1 s^2 + a_2 s + a_3$ and nothing else
    /// (zero numerator and friction): the carrier of [`ClosedLoopModel::poles`] for a
    /// denominator alone.
    pub fn characteristic(a1: f64, a2: f64, a3: f64) -> ClosedLoopModel {
        ClosedLoopModel {
            a1,
            a2,
            a3,
            b0: 0.0,
            b1: 0.0,
            b2: 0.0,
            dc: 0.0,
        }
    }

    /// Pole locations $(p, \omega_n, \zeta)$ (paper eq. 11), or `None` when the roots cannot be
    /// written in that form (non-finite coefficients).
    pub fn poles(&self) -> Option<Poles> {
        if !self.is_finite() {
            return None;
        }
        let roots = self.roots();
        let real: Vec<f64> = roots.iter().filter(|z| z.im == 0.0).map(|z| z.re).collect();
        if real.len() == 1 {
            let c = roots[1];
            let wn = c.norm();
            if wn == 0.0 {
                return None;
            }
            // 0.0 - r: a root at the origin is p = +0, not -0.
            return Some(Poles {
                p: 0.0 - real[0],
                wn,
                zeta: -c.re / wn,
            });
        }
        // Three real roots: pick `p` as the root whose sign differs from the other two, else the
        // one of smallest magnitude; the other two form the pair (zeta >= 1 when both stable).
        let mut r = [roots[0].re, roots[1].re, roots[2].re];
        r.sort_by(|x, y| x.abs().total_cmp(&y.abs()));
        let neg = r.iter().filter(|v| **v < 0.0).count();
        let idx = match neg {
            1 => r.iter().position(|v| *v < 0.0).unwrap_or(0),
            2 => r.iter().position(|v| *v >= 0.0).unwrap_or(0),
            _ => 0,
        };
        let p_root = r[idx];
        let others: Vec<f64> = (0..3).filter(|&i| i != idx).map(|i| r[i]).collect();
        let prod = others[0] * others[1];
        let sum = others[0] + others[1];
        if prod <= 0.0 {
            return None;
        }
        let wn = prod.sqrt();
        Some(Poles {
            p: 0.0 - p_root,
            wn,
            zeta: -sum / (2.0 * wn),
        })
    }

    /// Tracking frequency response $G_{track}(j\omega) = x / x_r$ at `w` rad/s.
    pub fn tracking_frf(&self, w: f64) -> Complex<f64> {
        let s = Complex::new(0.0, w);
        let num = ((s * self.b0 + self.b1) * s + self.b2) * s + self.a3;
        num / self.denominator_at(s)
    }

    /// Disturbance frequency response per unit friction acceleration,
    /// $G_{dist}(j\omega) = x / d = -s / (s^3 + a_1 s^2 + a_2 s + a_3)$, where $d$ is an
    /// acceleration disturbance in axis units/s² (the friction enters as $d = d_c\,\mathrm{sgn}\,\dot x$).
    pub fn disturbance_frf(&self, w: f64) -> Complex<f64> {
        let s = Complex::new(0.0, w);
        -s / self.denominator_at(s)
    }

    fn denominator_at(&self, s: Complex<f64>) -> Complex<f64> {
        ((s + self.a1) * s + self.a2) * s + self.a3
    }

    /// Steady following error $x_r - x$ at constant reference velocity `v` (units/s):
    /// $e_{ss} = v (a_2 - b_2) / a_3$ (final-value theorem on a ramp). Infinite when $a_3 = 0$
    /// and $a_2 \ne b_2$.
    pub fn ramp_following_error(&self, v: f64) -> f64 {
        v * (self.a2 - self.b2) / self.a3
    }

    /// Continuous state-space matrices: $\dot z = A z + B [x_r, \dot x_r, \ddot x_r, f]^T$ with
    /// $z = [q, x, v]$ and $f = \operatorname{sgn} v$.
    pub fn state_space(&self) -> (SMatrix<f64, 3, 3>, SMatrix<f64, 3, 4>) {
        #[rustfmt::skip]
        let a = SMatrix::<f64, 3, 3>::new(
            0.0, -1.0, 0.0,
            0.0, 0.0, 1.0,
            self.a3, -self.a2, -self.a1,
        );
        #[rustfmt::skip]
        let b = SMatrix::<f64, 3, 4>::new(
            1.0, 0.0, 0.0, 0.0,
            0.0, 0.0, 0.0, 0.0,
            self.b2, self.b1, self.b0, -self.dc,
        );
        (a, b)
    }

    /// Exact discretisation at period `ts` (s) with first-order hold on the reference signals and
    /// zero-order hold on the friction sign.
    ///
    /// With $u(\tau) = u_k + \tfrac{\tau}{T}(u_{k+1} - u_k)$ on one step, the augmented system
    /// $\tfrac{d}{d\tau}[z; u; \Delta] = [[A, B, 0]; [0, 0, I]; [0, 0, 0]]\,[z; u; \Delta]$ with
    /// $\Delta = (u_{k+1} - u_k)/T$ is exact; its matrix exponential gives
    /// $\Phi = e^{AT}$, $\Gamma_0 = \int_0^T e^{A\tau}d\tau\,B$ and the first-order-hold block.
    pub fn discretize(&self, ts: f64) -> Result<Discretized, Error> {
        if !(ts > 0.0 && ts.is_finite()) {
            return Err(Error::BadSamplePeriod { ts });
        }
        if !self.is_finite() {
            return Err(Error::NonFiniteModel);
        }
        let (a, b) = self.state_space();
        // Augmented 10×10: z (3), u (4: xr, vr, ar, f), delta (3: for xr, vr, ar).
        let mut m = SMatrix::<f64, 10, 10>::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&(a * ts));
        m.fixed_view_mut::<3, 4>(0, 3).copy_from(&(b * ts));
        for i in 0..3 {
            m[(3 + i, 7 + i)] = ts;
        }
        check_exp_norm(&m)?;
        let e = m.exp();
        let phi = e.fixed_view::<3, 3>(0, 0).into_owned();
        let gamma0 = e.fixed_view::<3, 4>(0, 3).into_owned();
        // Coefficient of delta (per unit of (u_{k+1}-u_k)/T) times 1/T gives the block acting on
        // (u_{k+1} - u_k).
        let gamma1 = e.fixed_view::<3, 3>(0, 7).into_owned() / ts;
        let g_lin0 = gamma0.fixed_view::<3, 3>(0, 0).into_owned();
        let gf = gamma0.fixed_view::<3, 1>(0, 3).into_owned();
        if !(phi.iter().all(|v| v.is_finite()) && gamma0.iter().all(|v| v.is_finite())) {
            return Err(Error::NonFiniteModel);
        }
        Ok(Discretized {
            phi,
            g0: g_lin0 - gamma1,
            g1: gamma1,
            gf,
            ts,
        })
    }

    /// Free-run simulation of the model from a sampled reference, starting at rest at
    /// `reference.pos[0]`. Returns the position at every sample.
    ///
    /// The model has zero initial conditions, so it simulates deviations from the rest position
    /// ($x - x_0$, $x_r - x_0$) and adds $x_0$ back (docs/drive-model.md): with absolute coordinates and
    /// $q = 0$ the model would see a step of $(b_2 - a_2) x_0$.
    ///
    /// The same positions bit for bit come from [`ClosedLoopModel::stream`] fed the reference in
    /// pieces (both run the same step).
    pub fn simulate(
        &self,
        reference: Reference<'_>,
        ts: f64,
        opts: &SimOptions,
    ) -> Result<Vec<f64>, Error> {
        let n = reference.check()?;
        let mut out = vec![0.0; n];
        match opts.integrator {
            Integrator::ExactFoh => {
                let d = self.discretize(ts)?;
                d.simulate_into(reference, opts, &mut out)?;
            }
            Integrator::Rk4 { substeps } => {
                if !(ts > 0.0 && ts.is_finite()) {
                    return Err(Error::BadSamplePeriod { ts });
                }
                self.simulate_rk4_into(
                    reference,
                    ts,
                    substeps.max(1),
                    opts.friction_deadband,
                    &mut out,
                );
            }
        }
        Ok(out)
    }

    fn simulate_rk4_into(
        &self,
        r: Reference<'_>,
        ts: f64,
        substeps: u32,
        deadband: f64,
        out: &mut [f64],
    ) {
        let mut s = Rk4Stream::new(self, ts, substeps, deadband);
        for (k, o) in out.iter_mut().enumerate() {
            *o = s.sample(r.pos[k], r.vel[k], r.acc[k]);
        }
    }
}

/// The RK4 integration of [`ClosedLoopModel::simulate`] one sample at a time.
#[derive(Debug, Clone)]
pub(crate) struct Rk4Stream {
    a: SMatrix<f64, 3, 3>,
    b: SMatrix<f64, 3, 4>,
    ts: f64,
    substeps: u32,
    deadband: f64,
    /// The rest position $x_0$ and the last sample fed, once one has been.
    x0: f64,
    prev: Option<[f64; 3]>,
    z: SVector<f64, 3>,
}

impl Rk4Stream {
    /// Before the first sample; `substeps` ≥ 1.
    pub(crate) fn new(m: &ClosedLoopModel, ts: f64, substeps: u32, deadband: f64) -> Rk4Stream {
        let (a, b) = m.state_space();
        Rk4Stream {
            a,
            b,
            ts,
            substeps,
            deadband,
            x0: 0.0,
            prev: None,
            z: SVector::<f64, 3>::zeros(),
        }
    }

    /// The model position at the next sample (position `p`, velocity `v`, acceleration `acc`):
    /// the first sample is the rest position; each later one integrates the step from the
    /// previous sample.
    pub(crate) fn sample(&mut self, p: f64, v: f64, acc: f64) -> f64 {
        let Some(prev) = self.prev.replace([p, v, acc]) else {
            self.x0 = p;
            return p;
        };
        let (x0, ts, a, b) = (self.x0, self.ts, &self.a, &self.b);
        let f = friction_sign(self.z[2], self.deadband);
        let u0 = [prev[0] - x0, prev[1], prev[2]];
        let u1 = [p - x0, v, acc];
        let input = |tau: f64| {
            let w = tau / ts;
            SVector::<f64, 4>::new(
                u0[0] + w * (u1[0] - u0[0]),
                u0[1] + w * (u1[1] - u0[1]),
                u0[2] + w * (u1[2] - u0[2]),
                f,
            )
        };
        let deriv = |z: &SVector<f64, 3>, tau: f64| a * z + b * input(tau);
        let h = ts / self.substeps as f64;
        let mut z = self.z;
        for j in 0..self.substeps {
            let t0 = j as f64 * h;
            let k1 = deriv(&z, t0);
            let k2 = deriv(&(z + k1 * (h / 2.0)), t0 + h / 2.0);
            let k3 = deriv(&(z + k2 * (h / 2.0)), t0 + h / 2.0);
            let k4 = deriv(&(z + k3 * h), t0 + h);
            z += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        }
        self.z = z;
        z[1] + x0
    }
}

/// Largest 1-norm of a matrix whose exponential vcnc computes. Physical models at their sample
/// periods stay far below (the NMV5000's $a_3 T_s$ is 3e4); nalgebra 0.35's `Matrix::exp` spends
/// about $\log_2$ of the norm in squarings and saturates to ~2^64 of them above ~1e38.
pub const MAX_EXP_NORM: f64 = 1e15;

/// Refuses ([`Error::TooStiff`]) a matrix whose exponential must not be computed: $\|M\|_1$
/// not finite or above [`MAX_EXP_NORM`]. Call it before every `Matrix::exp`.
pub fn check_exp_norm<R: Dim, C: Dim, S: RawStorage<f64, R, C>>(
    m: &Matrix<f64, R, C, S>,
) -> Result<(), Error> {
    let norm = m
        .column_iter()
        .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    if !(norm.is_finite() && norm <= MAX_EXP_NORM) {
        return Err(Error::TooStiff {
            norm,
            limit: MAX_EXP_NORM,
        });
    }
    Ok(())
}

/// The Coulomb friction level held over one step, in $[-1, 1]$, and whether the axis ends the
/// step stuck at rest (docs/drive-model.md, "Coulomb friction with sticking"): given the
/// velocity `v_start` at the start of the step, the friction-free end-of-step velocity `v_free`
/// and the velocity drop `l` that full friction causes over the step. The level is exact for a
/// driving acceleration constant over the step. From rest it is Kikuuwe et al.'s (2005): the
/// axis sticks ($v_{free}/l$, the level that holds it) when $|v_{free}| \le l$, else slides
/// against full friction. Moving (in the start's direction: $w_0 = |v_{start}| > 0$, $u =
/// v_{free} \operatorname{sgn} v_{start}$, level $g$), it keeps sliding ($g = 1$) when $u > l$;
/// it stops within the step and sticks ($g = u/l$) when $w_0 - l \le u \le l$ (the drive's
/// acceleration within the friction's reach); else it reverses through zero at the fraction
/// $w_0/(w_0 - u + l)$ of the step, where the friction changes sign, and the held level is the
/// mean, $g = (w_0 + u - l)/(w_0 - u + l)$. Kikuuwe's implicit step takes the new direction's
/// full friction over the whole step of a reversal (and holds the axis where the drive
/// overcomes the friction within the step): the friction reversed half a step early on
/// average, which biased fitted poles by up to 1 % on drives with strong friction (issue 30).
/// Level 0, not stuck, when there is no friction ($l \le 0$).
#[inline]
pub fn friction_level(v_start: f64, v_free: f64, l: f64) -> (f64, bool) {
    if l <= 0.0 {
        return (0.0, false);
    }
    if v_start == 0.0 {
        return if v_free.abs() <= l {
            (v_free / l, true)
        } else {
            (v_free.signum(), false)
        };
    }
    let s0 = v_start.signum();
    let (w0, u) = (v_start.abs(), s0 * v_free);
    if u > l {
        (s0, false)
    } else if u >= w0 - l {
        (v_free / l, true)
    } else {
        (s0 * (w0 + u - l) / (w0 - u + l), false)
    }
}

/// $\operatorname{sgn}(v)$ with a deadband: 0 when $|v| \le$ `deadband`.
#[inline]
pub fn friction_sign(v: f64, deadband: f64) -> f64 {
    if v > deadband {
        1.0
    } else if v < -deadband {
        -1.0
    } else {
        0.0
    }
}

impl Discretized {
    /// Simulates into `out` (same length as the reference), without allocating. See
    /// [`ClosedLoopModel::simulate`]; `opts.integrator` is ignored (this is the exact scheme).
    ///
    /// Friction with sticking (`opts.sticking`): with the friction-free update
    /// $z^* = \Phi z_k + G_0 u_k + G_1 u_{k+1}$ and the friction column $g_f$ (whose velocity
    /// entry is $-L$, $L \approx d_c T_s$), the friction level $f \in [-1, 1]$ held over the step
    /// is [`friction_level`] of the start velocity, $v^*$ and $L$ (from rest: $f = v^*/L$ if
    /// $|v^*| \le L$, the axis sticking, else $f = \operatorname{sgn} v^*$; a reversal within the
    /// step holds the mean of the friction's two signs); $z_{k+1} = z^* + g_f f$, the velocity
    /// exactly 0 when the axis sticks.
    pub fn simulate_into(
        &self,
        r: Reference<'_>,
        opts: &SimOptions,
        out: &mut [f64],
    ) -> Result<(), Error> {
        let n = r.check()?;
        if out.len() != n {
            return Err(Error::LengthMismatch {
                pos: n,
                vel: out.len(),
                acc: out.len(),
            });
        }
        let mut st = self.start(r.pos[0], r.vel[0], r.acc[0]);
        out[0] = st.x0;
        for k in 0..n - 1 {
            out[k + 1] = self.step(&mut st, r.pos[k + 1], r.vel[k + 1], r.acc[k + 1], opts);
        }
        Ok(())
    }

    /// The state at rest at the first sample (position `p0`, velocity `v0`, acceleration
    /// `a0`), whose model position is `p0`.
    pub(crate) fn start(&self, p0: f64, v0: f64, a0: f64) -> FohState {
        FohState {
            x0: p0,
            q: 0.0,
            x: 0.0,
            v: 0.0,
            u0: [0.0, v0, a0],
        }
    }

    /// One step to the next sample (position `p1`, velocity `v1`, acceleration `a1`): the
    /// model position there (see [`Discretized::simulate_into`]).
    #[inline(always)]
    pub(crate) fn step(
        &self,
        st: &mut FohState,
        p1: f64,
        v1: f64,
        a1: f64,
        opts: &SimOptions,
    ) -> f64 {
        let (phi, g0, g1, gf) = (&self.phi, &self.g0, &self.g1, &self.gf);
        // Velocity drop over one step caused by full friction (f = 1).
        let l = -gf[2];
        let (q, x, v, u0) = (st.q, st.x, st.v, st.u0);
        let u1 = [p1 - st.x0, v1, a1];
        let mut next = [0.0; 3];
        for (i, nx) in next.iter_mut().enumerate() {
            *nx = phi[(i, 0)] * q
                + phi[(i, 1)] * x
                + phi[(i, 2)] * v
                + g0[(i, 0)] * u0[0]
                + g0[(i, 1)] * u0[1]
                + g0[(i, 2)] * u0[2]
                + g1[(i, 0)] * u1[0]
                + g1[(i, 1)] * u1[1]
                + g1[(i, 2)] * u1[2];
        }
        let (f, stuck) = if opts.sticking {
            friction_level(v, next[2], l)
        } else {
            (friction_sign(v, opts.friction_deadband), false)
        };
        st.q = next[0] + gf[0] * f;
        st.x = next[1] + gf[1] * f;
        st.v = if stuck { 0.0 } else { next[2] + gf[2] * f };
        st.u0 = u1;
        st.x + st.x0
    }
}

/// The state of [`Discretized`]'s simulation between samples: deviations from the rest
/// position $x_0$ (axis units), $q$, $x - x_0$, $v$, and the last input $[x_r - x_0, \dot x_r,
/// \ddot x_r]$.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FohState {
    x0: f64,
    q: f64,
    x: f64,
    v: f64,
    u0: [f64; 3],
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use std::f64::consts::TAU;

    #[test]
    fn the_friction_level_is_exact_for_a_constant_driving_acceleration() {
        // Truth: a mass driven at a constant acceleration `a` against Coulomb friction `dc`,
        // solved by hand over one step `h` from velocity `v0`: it slides on, stops and sticks
        // (|a| <= dc), or reverses at t* = |v0|/(dc - a') and slides on at a' + dc. The level
        // held over the step must give that end velocity, v* - L f with v* = v0 + a h and
        // L = dc h, in every case; Kikuuwe's sgn(v*) does not on a reversal.
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(30);
        let mut reversals = 0;
        for _ in 0..20_000 {
            let v0: f64 = match rng.random_range(0..4) {
                0 => 0.0,
                _ => rng.random_range(-10.0..10.0),
            };
            let a: f64 = rng.random_range(-40.0..40.0);
            let dc: f64 = rng.random_range(0.1..10.0);
            let h: f64 = rng.random_range(0.001..2.0);
            let s0 = if v0 == 0.0 { a.signum() } else { v0.signum() };
            let (w0, ap) = (v0.abs(), s0 * a);
            let exact = s0
                * if w0 + (ap - dc) * h > 0.0 {
                    w0 + (ap - dc) * h
                } else if ap.abs() <= dc {
                    0.0
                } else {
                    reversals += usize::from(w0 > 0.0);
                    (ap + dc) * (h - w0 / (dc - ap))
                };
            let (v_free, l) = (v0 + a * h, dc * h);
            let (f, stuck) = friction_level(v0, v_free, l);
            let v1 = if stuck { 0.0 } else { v_free - l * f };
            assert!(f.abs() <= 1.0);
            assert!(
                (v1 - exact).abs() <= 1e-12 * (1.0 + v0.abs() + a.abs() * h),
                "v0 {v0} a {a} dc {dc} h {h}: {v1} against {exact}"
            );
            if stuck {
                assert_eq!(exact, 0.0, "v0 {v0} a {a} dc {dc} h {h}");
            }
        }
        assert!(reversals > 1000, "{reversals}");
    }

    /// Table 1 drive, coefficients as docs/reference-numbers.md prints them.
    fn table1() -> ClosedLoopModel {
        ClosedLoopModel {
            dc: 0.0,
            ..crate::TABLE1_MODEL
        }
    }

    /// `m`'s positions following `p`, `v`, `a` at period `ts`, default options.
    fn run(m: &ClosedLoopModel, p: &[f64], v: &[f64], a: &[f64], ts: f64) -> Vec<f64> {
        crate::test_util::follow(|r, ts, o| m.simulate(r, ts, o), (p, v, a), ts)
    }

    #[test]
    fn table1_poles_match_published_exact_values() {
        // Truth: docs/reference-numbers.md, exact poles of the Table 1 drive.
        let p = table1().poles().unwrap();
        assert_relative_eq!(p.wn_hz(), 30.569, max_relative = 5e-5);
        assert_relative_eq!(p.zeta, 0.44519, max_relative = 5e-5);
        assert_relative_eq!(p.p_hz(), 10.7296, max_relative = 5e-5);
        assert!(table1().is_stable());
    }

    #[test]
    fn poles_round_trip_through_coefficients() {
        for &(p, wn, z) in &[
            (10.0, 30.0, 0.45),
            (22.12, 73.5, 0.27),
            (5.0, 40.0, 1.7),
            (0.0, 20.0, 0.8),
        ] {
            let poles = Poles::from_hz(p, wn, z);
            let m = ClosedLoopModel::from_poles(&poles, 0.0, 0.0, 0.0, 0.0);
            let back = m.poles().unwrap();
            assert_relative_eq!(back.p, poles.p, epsilon = 1e-9, max_relative = 1e-9);
            assert_relative_eq!(back.wn, poles.wn, max_relative = 1e-9);
            assert_relative_eq!(back.zeta, poles.zeta, max_relative = 1e-9);
        }
    }

    #[test]
    fn roots_satisfy_the_cubic() {
        let m = ClosedLoopModel {
            a1: 3.0,
            a2: -10.0,
            a3: -24.0,
            ..table1()
        }; // (s-3)(s+2)(s+4)
        for r in m.roots() {
            let v = ((r + m.a1) * r + m.a2) * r + m.a3;
            assert!(v.norm() < 1e-9, "{r} -> {v}");
        }
        assert!(!m.is_stable());
        let poles = m.poles().unwrap();
        assert_relative_eq!(poles.p, -3.0, max_relative = 1e-12);
    }

    #[test]
    fn sine_steady_state_matches_frequency_response() {
        // Truth: the analytic frequency response; the simulation is run long enough for the
        // transient (slowest pole 10.7 Hz) to die out.
        let m = table1();
        let ts = 1e-3;
        let f = 7.0;
        let w = TAU * f;
        let n = 6000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * ts).collect();
        let pos: Vec<f64> = t.iter().map(|t| (w * t).sin()).collect();
        let vel: Vec<f64> = t.iter().map(|t| w * (w * t).cos()).collect();
        let acc: Vec<f64> = t.iter().map(|t| -w * w * (w * t).sin()).collect();
        let r = Reference {
            pos: &pos,
            vel: &vel,
            acc: &acc,
        };
        let x = m.simulate(r, ts, &SimOptions::default()).unwrap();
        let g = m.tracking_frf(w);
        // The simulation starts at rest at pos[0] = 0 with zero state, whereas sin starts with
        // velocity w: compare after 4 s.
        let mut max_err: f64 = 0.0;
        for k in 4000..n {
            let expect = g.norm() * (w * t[k] + g.arg()).sin();
            max_err = max_err.max((x[k] - expect).abs());
        }
        // FOH on a sampled sine is exact up to the interpolation error of the inputs between
        // samples, O((w Ts)^2 / 8) ≈ 2e-4 of the amplitude.
        assert!(max_err < 3e-4, "max error {max_err}");
    }

    #[test]
    fn exact_foh_agrees_with_fine_rk4() {
        let mut m = table1();
        m.dc = 47.7;
        m.b0 = 0.3;
        let ts = 1e-3;
        let n = 3000;
        // Trapezoid-ish smooth reference: sum of ramps, positions from a cubic blend.
        let mut pos = vec![0.0; n];
        let mut vel = vec![0.0; n];
        let mut acc = vec![0.0; n];
        for k in 0..n {
            let t = k as f64 * ts;
            let s = (t / 1.5).min(1.0);
            pos[k] = 10.0 + 50.0 * (3.0 * s * s - 2.0 * s * s * s);
            vel[k] = if t < 1.5 {
                50.0 * (6.0 * s - 6.0 * s * s) / 1.5
            } else {
                0.0
            };
            acc[k] = if t < 1.5 {
                50.0 * (6.0 - 12.0 * s) / 2.25
            } else {
                0.0
            };
        }
        let r = Reference {
            pos: &pos,
            vel: &vel,
            acc: &acc,
        };
        // RK4 holds the explicit friction sign per sample; compare like with like.
        let explicit = SimOptions {
            sticking: false,
            ..Default::default()
        };
        let exact = m.simulate(r, ts, &explicit).unwrap();
        let rk = m
            .simulate(
                r,
                ts,
                &SimOptions {
                    integrator: Integrator::Rk4 { substeps: 20 },
                    ..explicit
                },
            )
            .unwrap();
        let max = crate::test_util::max_abs_diff(&exact, &rk);
        assert!(max < 1e-7, "exact vs RK4 differ by {max} mm");
        assert_relative_eq!(exact[0], 10.0);
    }

    #[test]
    fn ramp_following_error_matches_final_value_theorem() {
        // Truth: final-value theorem, e_ss = v (a2 - b2) / a3.
        let m = table1();
        let ts = 1e-3;
        let v = 100.0;
        let n = 4000;
        let pos: Vec<f64> = (0..n).map(|k| 5.0 + v * k as f64 * ts).collect();
        let vel = vec![v; n];
        let acc = vec![0.0; n];
        let x = run(&m, &pos, &vel, &acc, ts);
        let e = pos[n - 1] - x[n - 1];
        assert_relative_eq!(e, m.ramp_following_error(v), max_relative = 1e-6);
    }

    #[test]
    fn rest_away_from_origin_stays_at_rest() {
        let m = table1();
        let n = 100;
        let pos = vec![123.4; n];
        let z = vec![0.0; n];
        let x = run(&m, &pos, &z, &z, 1e-3);
        assert!(x.iter().all(|v| *v == 123.4));
    }

    #[test]
    fn bad_inputs_are_errors() {
        let m = table1();
        let z = vec![0.0; 2];
        let run = |p: &[f64]| {
            let r = Reference {
                pos: p,
                vel: &z,
                acc: &z,
            };
            m.simulate(r, 1e-3, &SimOptions::default())
        };
        assert!(matches!(
            run(&[0.0, f64::NAN]),
            Err(Error::NonFinite { .. })
        ));
        // Three positions against two velocities and accelerations.
        assert!(run(&[0.0; 3]).is_err());
        assert!(m.discretize(0.0).is_err());
    }
}
