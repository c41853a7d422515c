//! The plant over one servo period $h$ with the command held (zero-order hold), exactly: the
//! rigid plant of the ideal drive in closed form ([`RigidStep`]), and the linear part of a drive
//! with effects as $\Phi = e^{Ah}$, $\Gamma = \int_0^h e^{As}ds\,B$ ([`Lin`]). Plain data, made
//! once per drive: the engine steps with it, the stability analysis builds its matrices from it.
//!
//! # Rigid plant (the ideal drive)
//!
//! In axis units, $\ddot x = -\beta \dot x + c\,u - d_c \operatorname{sgn}\dot x$ with
//! $\beta = B/J$, $c = K_aK_t r_g/J$, $d_c = T_c r_g/J$. Over one period with $u$ and the friction
//! force $f$ held, the exact solution is
//!
//! $$ v_{k+1} = e^{-\beta h} v_k + \varphi_1 (c u_k - f), \qquad
//!    x_{k+1} = x_k + \varphi_1 v_k + \varphi_2 (c u_k - f), $$
//!
//! $\varphi_1 = \int_0^h e^{-\beta s}ds$, $\varphi_2 = \int_0^h\!\int_0^s e^{-\beta r}dr\,ds$. The
//! friction is set-valued and chosen implicitly, as in Kikuuwe et al. (2005) and
//! docs/drive-model.md (whose implicit-Euler form this generalises: with
//! $e^{-\beta h} \approx 1/(1 + \beta h)$ it is the same step): with
//! $v^* = e^{-\beta h} v_k + \varphi_1 c\,u_k$ and $L = \varphi_1 d_c$, the axis sticks
//! ($v_{k+1} = 0$, $f$ whatever keeps it there) if $|v^*| \le L$, else
//! $v_{k+1} = v^* - L\operatorname{sgn}(v^*)$. An axis at rest with $|K_aK_t u| \le T_c$
//! therefore stays exactly at rest.
//!
//! # Linear part of a drive with effects
//!
//! The state $z$ is `[x_m, v_m, x_L, v_L, current...]` (two-mass) or `[x, v, current...]`
//! (rigid), in axis units; the inputs are the command $u$, the friction torque $f$ on the friction
//! body and the backlash offset $o$ (docs/machine-file.md#drive-effects):
//! $z^+ = \Phi z + \Gamma_u u + \Gamma_f f + \Gamma_o o$, with a second $(\Phi, \Gamma)$ without
//! the spring for the backlash gap.

use nalgebra::{SMatrix, SVector};

use crate::Error;
use crate::effects::{CurrentLoopOrder, Effects};
use crate::lane::Lane;
use crate::model::check_exp_norm;
use crate::params::Plant;

/// Exact zero-order-hold step of the rigid plant with implicit Coulomb friction (module docs).
#[derive(Debug, Clone, Copy)]
pub(crate) struct RigidStep {
    /// $e^{-\beta h}$.
    pub(crate) decay: f64,
    pub(crate) phi1: f64,
    pub(crate) phi2: f64,
    /// Acceleration per volt $c = K_aK_t r_g / J$, axis units/s² per V.
    pub(crate) c: f64,
    /// Friction velocity bound $L = \varphi_1 d_c$.
    pub(crate) stick: f64,
    /// Friction acceleration $d_c$.
    pub(crate) dc: f64,
    /// Position gain on $v_k$ when the step ends stuck: $\varphi_1 - \varphi_2 e^{-\beta h}/\varphi_1$.
    pub(crate) stuck_dx: f64,
}

impl RigidStep {
    pub(crate) fn new(plant: &Plant, h: f64) -> Result<RigidStep, Error> {
        let beta = plant.b_over_j();
        // exp of [[0, 1, 0], [0, -beta, 1], [0, 0, 0]] h gives phi1 (row 0 col 1 = int e^{-beta s}),
        // phi2 (row 0 col 2) and the decay (row 1 col 1) without cancellation for small beta h.
        #[rustfmt::skip]
        let m = SMatrix::<f64, 3, 3>::new(
            0.0, h, 0.0,
            0.0, -beta * h, h,
            0.0, 0.0, 0.0,
        );
        check_exp_norm(&m)?;
        let e = m.exp();
        let (decay, phi1, phi2) = (e[(1, 1)], e[(0, 1)], e[(0, 2)]);
        let c = plant.ka_kt() * plant.rg / plant.j;
        let dc = plant.dc();
        let step = RigidStep {
            decay,
            phi1,
            phi2,
            c,
            stick: phi1 * dc,
            dc,
            stuck_dx: phi1 - phi2 * decay / phi1,
        };
        let all = [decay, phi1, phi2, c, dc, step.stuck_dx];
        if all.iter().all(|v| v.is_finite()) && phi1 > 0.0 {
            Ok(step)
        } else {
            Err(Error::NonFiniteModel)
        }
    }

    /// Ends a step from the friction-free predictions $v^*$ and $x^*$ (with $f = 0$):
    /// sticks if $|v^*| \le L$, else applies $f = d_c \operatorname{sgn} v^*$.
    #[inline(always)]
    pub(crate) fn finish(&self, x: &mut f64, v: &mut f64, v_star: f64, x_star: f64) {
        if v_star.abs() <= self.stick {
            // Stuck at the end of the step: the friction force is whatever makes v = 0.
            *x += self.stuck_dx * *v;
            *v = 0.0;
        } else {
            let f = self.dc.copysign(v_star);
            *x = x_star - self.phi2 * f;
            *v = v_star - self.phi1 * f;
        }
    }
}

/// Layout of the state vector $z$ of a drive with effects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Layout {
    /// Two-mass: `[x_m, v_m, x_L, v_L, ...]`; rigid: `[x, v, ...]`.
    pub(crate) two_mass: bool,
    /// Index of the first current-loop state (== number of mechanical states).
    pub(crate) i_cur: usize,
    /// Current-loop states (0, 1 or 2).
    pub(crate) n_cur: usize,
}

impl Layout {
    /// The layout of a drive with `effects`.
    pub(crate) fn of(effects: &Effects) -> Layout {
        let two_mass = effects.compliance.is_some();
        Layout {
            two_mass,
            i_cur: if two_mass { 4 } else { 2 },
            n_cur: match effects.current {
                None => 0,
                Some(c) => match c.order {
                    CurrentLoopOrder::FirstOrder => 1,
                    CurrentLoopOrder::SecondOrder => 2,
                },
            },
        }
    }
    /// Motor position and velocity; load position and velocity (the motor's when rigid).
    pub(crate) fn xm(&self) -> usize {
        0
    }
    pub(crate) fn vm(&self) -> usize {
        1
    }
    pub(crate) fn xl(&self) -> usize {
        if self.two_mass { 2 } else { 0 }
    }
    pub(crate) fn vl(&self) -> usize {
        if self.two_mass { 3 } else { 1 }
    }
    /// States.
    pub(crate) fn n(&self) -> usize {
        self.i_cur + self.n_cur
    }
}

/// Exact ZOH step of the linear part: $z^+ = \Phi z + \Gamma_u u + \Gamma_f f + \Gamma_o o$, per
/// lane of `T`.
#[derive(Clone, Copy)]
pub(crate) struct Lin<T, const N: usize> {
    pub(crate) phi: [[T; N]; N],
    pub(crate) g_u: [T; N],
    pub(crate) g_f: [T; N],
    pub(crate) g_o: [T; N],
    /// $-\Gamma_f$ at the friction body's velocity: the velocity one N·m of friction removes
    /// over a step, axis units/s per N·m (> 0).
    pub(crate) g: T,
    /// Stuck step folded: $z = (P + c P_v) + (\Gamma_u + c\,\Gamma_{u,v}) u$ with
    /// $c = \Gamma_f / g$.
    pub(crate) stick_k: [T; N],
    pub(crate) stick_gu: [T; N],
    /// $g\,[T_s^+, T_s^-]$: the largest end velocity the static friction can stop.
    pub(crate) stick_lim: [T; 2],
}

impl<const N: usize> Lin<f64, N> {
    /// The linear part of a drive with `effects` on `plant` at servo period `h` (`spring`:
    /// in contact; else in the backlash gap), with the friction on the load (else the motor).
    pub(crate) fn new(
        plant: &Plant,
        effects: &Effects,
        h: f64,
        friction_on_load: bool,
        spring: bool,
    ) -> Result<Lin<f64, N>, Error> {
        let lay = Layout::of(effects);
        let (a, b) = continuous(plant, effects, lay, friction_on_load, spring);
        let vf = if friction_on_load { lay.vl() } else { lay.vm() };
        discretise(&a, &b, h, vf, lay.i_cur)
    }

    /// $\Phi$ and $\Gamma_u$ as matrices.
    pub(crate) fn matrices(&self) -> (SMatrix<f64, N, N>, SVector<f64, N>) {
        (
            SMatrix::from_fn(|i, j| self.phi[i][j]),
            SVector::from_fn(|i, _| self.g_u[i]),
        )
    }
}

impl<T: Lane, const N: usize> Lin<T, N> {
    /// Lane `l` steps with `lins[l]` (the last one in the lanes beyond).
    pub(crate) fn gather(lins: &[&Lin<f64, N>]) -> Lin<T, N> {
        let pick = |l: usize| lins[l.min(lins.len() - 1)];
        let v = |f: &dyn Fn(&Lin<f64, N>) -> f64| T::from_fn(|l| f(pick(l)));
        Lin {
            phi: std::array::from_fn(|i| std::array::from_fn(|j| v(&|x| x.phi[i][j]))),
            g_u: std::array::from_fn(|i| v(&|x| x.g_u[i])),
            g_f: std::array::from_fn(|i| v(&|x| x.g_f[i])),
            g_o: std::array::from_fn(|i| v(&|x| x.g_o[i])),
            g: v(&|x| x.g),
            stick_k: std::array::from_fn(|i| v(&|x| x.stick_k[i])),
            stick_gu: std::array::from_fn(|i| v(&|x| x.stick_gu[i])),
            stick_lim: std::array::from_fn(|i| v(&|x| x.stick_lim[i])),
        }
    }

    /// `b`'s coefficients in the lanes of `m`, else `a`'s.
    #[inline(always)]
    pub(crate) fn select(m: T::Mask, b: &Lin<T, N>, a: &Lin<T, N>) -> Lin<T, N> {
        let mut out = *a;
        for i in 0..N {
            for j in 0..N {
                out.phi[i][j] = T::select(m, b.phi[i][j], a.phi[i][j]);
            }
            out.g_u[i] = T::select(m, b.g_u[i], a.g_u[i]);
            out.g_f[i] = T::select(m, b.g_f[i], a.g_f[i]);
            out.g_o[i] = T::select(m, b.g_o[i], a.g_o[i]);
            out.stick_k[i] = T::select(m, b.stick_k[i], a.stick_k[i]);
            out.stick_gu[i] = T::select(m, b.stick_gu[i], a.stick_gu[i]);
        }
        for i in 0..2 {
            out.stick_lim[i] = T::select(m, b.stick_lim[i], a.stick_lim[i]);
        }
        out
    }
}

/// Continuous $A$ (n×n, padded to 6) and $B$ = [u, f, o] columns of the linear part.
fn continuous(
    plant: &Plant,
    e: &Effects,
    lay: Layout,
    friction_on_load: bool,
    spring: bool,
) -> (SMatrix<f64, 6, 6>, SMatrix<f64, 6, 3>) {
    let mut a = SMatrix::<f64, 6, 6>::zeros();
    let mut b = SMatrix::<f64, 6, 3>::zeros();
    let rg = plant.rg;
    let kakt = plant.ka_kt();
    // Where the torque command enters: the motor velocity, or the current loop.
    let (jm, jl) = match e.compliance {
        Some(c) => (c.j_motor, c.j_load),
        None => (plant.j, plant.j),
    };
    let (xm, vm, xl, vl) = (lay.xm(), lay.vm(), lay.xl(), lay.vl());
    a[(xm, vm)] = 1.0;
    if lay.two_mass {
        a[(xl, vl)] = 1.0;
    }
    // Torque input (axis acceleration per volt of u at the motor).
    let torque_gain = rg * kakt / jm;
    match e.current {
        None => b[(vm, 0)] = torque_gain,
        Some(c) => {
            let i = lay.i_cur;
            a[(vm, i)] = torque_gain;
            match c.order {
                CurrentLoopOrder::FirstOrder => {
                    a[(i, i)] = -c.w;
                    b[(i, 0)] = c.w;
                }
                CurrentLoopOrder::SecondOrder => {
                    a[(i, i + 1)] = 1.0;
                    a[(i + 1, i)] = -c.w * c.w;
                    a[(i + 1, i + 1)] = -2.0 * c.zeta * c.w;
                    b[(i + 1, 0)] = c.w * c.w;
                }
            }
        }
    }
    // Friction and viscous friction on the friction body.
    let (vf, jf) = if friction_on_load { (vl, jl) } else { (vm, jm) };
    a[(vf, vf)] -= plant.b / jf;
    b[(vf, 1)] = -rg / jf;
    if let (Some(c), true) = (e.compliance, spring) {
        let (k, d) = (c.stiffness, c.damping);
        a[(vm, xm)] -= k / jm;
        a[(vm, xl)] += k / jm;
        a[(vm, vm)] -= d / jm;
        a[(vm, vl)] += d / jm;
        a[(vl, xm)] += k / jl;
        a[(vl, xl)] -= k / jl;
        a[(vl, vm)] += d / jl;
        a[(vl, vl)] -= d / jl;
        // Spring force k (x_m - x_L - o): the offset o enters with the opposite sign.
        b[(vm, 2)] = k / jm;
        b[(vl, 2)] = -k / jl;
    }
    (a, b)
}

#[allow(clippy::needless_range_loop)] // copying matrix blocks: indices read best
/// $\Phi = e^{Ah}$ and $\Gamma = \int_0^h e^{As}ds\,B$ from one exponential of the augmented
/// matrix $\begin{bmatrix}A & B\\ 0 & 0\end{bmatrix}h$.
///
/// The current loop's states (from `i_cur` on) do not depend on the mechanics: that block of
/// $\Phi$ is zero in exact arithmetic and is set so (the tick skips it).
fn discretise<const N: usize>(
    a: &SMatrix<f64, 6, 6>,
    b: &SMatrix<f64, 6, 3>,
    h: f64,
    vf: usize,
    i_cur: usize,
) -> Result<Lin<f64, N>, Error> {
    let mut m = SMatrix::<f64, 9, 9>::zeros();
    m.fixed_view_mut::<6, 6>(0, 0).copy_from(&(a * h));
    m.fixed_view_mut::<6, 3>(0, 6).copy_from(&(b * h));
    check_exp_norm(&m)?;
    let e = m.exp();
    let mut lin = Lin {
        phi: [[0.0; N]; N],
        g_u: [0.0; N],
        g_f: [0.0; N],
        g_o: [0.0; N],
        g: 0.0,
        stick_k: [0.0; N],
        stick_gu: [0.0; N],
        stick_lim: [0.0; 2],
    };
    for i in 0..N {
        for j in 0..N {
            lin.phi[i][j] = if i >= i_cur && j < i_cur {
                0.0
            } else {
                e[(i, j)]
            };
        }
        lin.g_u[i] = e[(i, 6)];
        lin.g_f[i] = e[(i, 7)];
        lin.g_o[i] = e[(i, 8)];
    }
    lin.g = -lin.g_f[vf];
    let inv_g = 1.0 / lin.g;
    for i in 0..N {
        lin.stick_k[i] = lin.g_f[i] * inv_g;
        lin.stick_gu[i] = lin.g_u[i] + lin.stick_k[i] * lin.g_u[vf];
    }
    let finite = e.iter().all(|v| v.is_finite());
    if finite && lin.g > 0.0 {
        Ok(lin)
    } else {
        Err(Error::NonFiniteModel)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::{CurrentDynamics, bandwidth_factor};
    use crate::presets::table1_drive;
    use approx::assert_relative_eq;
    use nalgebra::Complex;
    use std::f64::consts::TAU;

    /// The Table 1 plant with Coulomb torque `tc`, N·m.
    fn plant(tc: f64) -> Plant {
        Plant {
            coulomb_torque: tc,
            ..crate::presets::TABLE1_PLANT
        }
    }

    #[test]
    fn plant_step_is_the_exact_solution_under_constant_input() {
        // Truth: closed-form solution of x'' = -beta x' + a with constant a:
        // v(t) = v0 e^{-beta t} + (a/beta)(1 - e^{-beta t}),
        // x(t) = x0 + (v0 - a/beta)(1 - e^{-beta t})/beta + (a/beta) t.
        let p = plant(0.0);
        let h = 5e-5;
        let step = RigidStep::new(&p, h).unwrap();
        let beta = p.b / p.j;
        let (x0, v0, u) = (3.0, -20.0, 7.0);
        let a = step.c * u;
        let (mut x, mut v) = (x0, v0);
        let n = 20_000; // 1 s
        for _ in 0..n {
            let v_star = step.decay * v + step.phi1 * a;
            let x_star = x + step.phi1 * v + step.phi2 * a;
            step.finish(&mut x, &mut v, v_star, x_star);
        }
        let t = n as f64 * h;
        let e = (-beta * t).exp();
        let v_exact = v0 * e + a / beta * (1.0 - e);
        let x_exact = x0 + (v0 - a / beta) * (1.0 - e) / beta + a / beta * t;
        assert_relative_eq!(v, v_exact, max_relative = 1e-10);
        assert_relative_eq!(x, x_exact, max_relative = 1e-10);
    }

    #[test]
    fn friction_step_sticks_below_breakaway_and_slides_above() {
        // Truth: Coulomb's law. At rest, a drive torque below Tc leaves the axis exactly at rest;
        // above it, the axis accelerates at (Ka Kt u - Tc) rg / J.
        let p = plant(0.3);
        let h = 5e-5;
        let step = RigidStep::new(&p, h).unwrap();
        for u in [0.0, 0.1, -0.29999, 0.3] {
            let (mut x, mut v) = (1.25, 0.0);
            for _ in 0..1000 {
                let a = step.c * u;
                let x_star = x + step.phi2 * a;
                step.finish(&mut x, &mut v, step.phi1 * a, x_star);
            }
            assert_eq!((x, v), (1.25, 0.0), "u = {u}");
        }
        let u = 0.5;
        let (mut x, mut v) = (0.0, 0.0);
        let a = step.c * u;
        let v_star = step.decay * v + step.phi1 * a;
        let x_star = x + step.phi1 * v + step.phi2 * a;
        step.finish(&mut x, &mut v, v_star, x_star);
        let expected_acc = (u - 0.3) * p.rg / p.j;
        assert_relative_eq!(v / h, expected_acc, max_relative = 1e-3);
        assert!(x > 0.0);
    }

    /// The current-loop block of the discretised linear part, driven by a unit step of the
    /// command from rest: its output at every tick.
    #[allow(clippy::needless_range_loop)] // 4×4 matrix-vector product
    fn current_step(order: CurrentLoopOrder, bw_hz: f64, zeta: f64, h: f64, n: usize) -> Vec<f64> {
        let plant = table1_drive().plant;
        let w = match order {
            CurrentLoopOrder::FirstOrder => TAU * bw_hz,
            CurrentLoopOrder::SecondOrder => TAU * bw_hz / bandwidth_factor(zeta),
        };
        let e = Effects {
            current: Some(CurrentDynamics { order, w, zeta }),
            ..Effects::default()
        };
        let lin = Lin::<f64, 4>::new(&plant, &e, h, true, true).unwrap();
        let mut z = [0.0; 4];
        let mut out = vec![0.0];
        for _ in 0..n {
            let mut next = [0.0; 4];
            for i in 0..4 {
                next[i] = lin.g_u[i];
                for j in 0..4 {
                    next[i] += lin.phi[i][j] * z[j];
                }
            }
            z = next;
            out.push(z[2]);
        }
        out
    }

    #[test]
    fn current_loop_step_response_has_its_time_constant() {
        // Truth: the step response of 1/(1 + s/wc), 1 - exp(-t/tau), tau = 1/(2 pi f_bw); and of
        // wn²/(s² + 2 zeta wn s + wn²), 1 - exp(-zeta wn t)(cos wd t + zeta/sqrt(1-zeta²) sin wd t),
        // whose -3 dB frequency is f_bw (checked on the continuous transfer function). A step
        // held over each tick is exactly what the zero-order-hold discretisation assumes, so the
        // ticks must agree to rounding.
        let h = 5e-5;
        let bw = 1500.0;
        let tau = 1.0 / (TAU * bw);
        let y = current_step(CurrentLoopOrder::FirstOrder, bw, 1.0, h, 200);
        for (k, yk) in y.iter().enumerate() {
            let t = k as f64 * h;
            assert!(
                (yk - (1.0 - (-t / tau).exp())).abs() < 1e-12,
                "tick {k}: {yk}"
            );
        }
        // The time constant read off the response, -t / ln(1 - y(t)), at 1, 2 and 4 tau.
        for k in [2, 4, 8] {
            let t = k as f64 * h;
            let tau_hat = -t / (1.0 - y[k]).ln();
            assert!((tau_hat / tau - 1.0).abs() < 1e-9, "tau {tau_hat} vs {tau}");
        }
        for zeta in [0.5, std::f64::consts::FRAC_1_SQRT_2, 0.9] {
            let wn = TAU * bw / bandwidth_factor(zeta);
            let g = |w: f64| {
                let s = Complex::new(0.0, w);
                (wn * wn / (s * s + 2.0 * zeta * wn * s + wn * wn)).norm()
            };
            assert!((g(TAU * bw) - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
            let y = current_step(CurrentLoopOrder::SecondOrder, bw, zeta, h, 400);
            let wd = wn * (1.0 - zeta * zeta).sqrt();
            for (k, yk) in y.iter().enumerate() {
                let t = k as f64 * h;
                let exact = 1.0
                    - (-zeta * wn * t).exp()
                        * ((wd * t).cos() + zeta / (1.0 - zeta * zeta).sqrt() * (wd * t).sin());
                assert!(
                    (yk - exact).abs() < 1e-11,
                    "zeta {zeta}, tick {k}: {yk} vs {exact}"
                );
            }
        }
    }
}
