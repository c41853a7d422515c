//! The discrete control laws of the servo loop (docs/drive-model.md): P-PI, PID and sliding
//! mode, each written once, on one drive or on lanes of drives ([`crate::lane`]).
//!
//! Integrals of the position error use the trapezoidal rule (Tustin), exact to $O(h^2)$;
//! integrals of quantities that are derivatives of measured or commanded positions use the
//! positions themselves (the P-PI's $\int(\omega_c - \dot\theta)dt$ contains
//! $\int \dot\theta\,dt = \theta - \theta_0$ exactly, as an incremental PI fed with encoder
//! differences computes it). The velocity is the second-order backward difference (BDF2) of the
//! velocity path's position $x_f$, $\hat v_k = (3x_{f,k} - 4x_{f,k-1} + x_{f,k-2})/(2h)$, exact
//! for motion of constant acceleration.
//!
//! A law reads two positions: $\hat x_p$, the position loop's reading (after the dead time), and
//! $x_f$, the velocity path's (the motor encoder's reading, low-pass filtered); in the ideal
//! drive both are the encoder reading $\hat x$. It is affine in them:
//!
//! $$ e = x_r - \hat x_p,\quad u = \text{direct}(e, \hat v) + K_I\,(I + \Delta I(e, e_1, x_f - x_{f1})), $$
//!
//! and is evaluated as its terms at $\hat x_p = x_f = 0$ ([`LawOn::terms0`]) plus slopes
//! ([`Law::slopes`]) times the readings, so that the servo tick can compute everything that
//! does not depend on this tick's readings first and let the readings enter $u$ through one
//! multiply-add each (an algebraic rearrangement, checked against the plain law in the tests).
//!
//! Variables are named as in docs/drive-model.md and the paper (`kv`, `kp`, `ki`, `lambda`,
//! `ks`, `rho`, `je_hat`, `be_hat`); `xr`, `vr`, `ar` are the reference at the tick, `h` the
//! servo period.

use crate::lane::Lane;
use crate::params::{Controller, PPiGains, PidGains, Plant, SmcGains};

/// One reference sample as the servo loop sees it at a tick: position, velocity and
/// acceleration (axis units, /s, /s²), per lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RefSample<T> {
    pub(crate) xr: T,
    pub(crate) vr: T,
    pub(crate) ar: T,
}

impl<T: Lane> RefSample<T> {
    /// Standing at `r`'s position, velocity and acceleration zero: what a run's reference
    /// shaping holds before its first reference. A shaper that held the first reference itself
    /// handed on, for the length of a delay, that reference's velocity and acceleration (a
    /// trapezoid starts with its full acceleration): a spurious feed-forward, 8 ms of it behind
    /// an 8 ms `[control]` delay, which the same model with the delay inside did not see.
    #[inline(always)]
    pub(crate) fn rest(r: RefSample<T>) -> RefSample<T> {
        RefSample {
            xr: r.xr,
            vr: T::splat(0.0),
            ar: T::splat(0.0),
        }
    }

    /// Lane `l` is `f(l)`.
    #[inline(always)]
    pub(crate) fn from_fn(f: impl Fn(usize) -> RefSample<f64>) -> RefSample<T> {
        let s: [RefSample<f64>; crate::lane::LANES] =
            std::array::from_fn(|l| f(l.min(T::WIDTH - 1)));
        RefSample {
            xr: T::from_fn(|l| s[l].xr),
            vr: T::from_fn(|l| s[l].vr),
            ar: T::from_fn(|l| s[l].ar),
        }
    }

    /// Every channel zero.
    pub(crate) fn zero() -> RefSample<T> {
        let z = T::splat(0.0);
        RefSample {
            xr: z,
            vr: z,
            ar: z,
        }
    }
}

/// The derivatives of a law's direct part and integrator increment in the position reading
/// $\hat x_p$ and the velocity path's position $x_f$.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Slopes {
    /// $\partial\,\text{direct}/\partial\hat x_p$.
    pub(crate) dp: f64,
    /// $\partial\,\text{direct}/\partial x_f$.
    pub(crate) df: f64,
    /// $\partial\Delta I/\partial\hat x_p$.
    pub(crate) ip: f64,
    /// $\partial\Delta I/\partial x_f$.
    pub(crate) i_f: f64,
}

/// A control law's terms on lanes of `T`.
pub(crate) trait LawOn<T: Lane>: Copy + Send + Sync + 'static {
    /// `(direct, ΔI)` with $\hat x_p = x_f = 0$, from the tick's reference `r`, the previous
    /// tick's reference position `xr1` and error `e1`, and the velocity path's previous two
    /// positions `xf1`, `xf2`.
    fn terms0(&self, r: &RefSample<T>, xr1: T, e1: T, xf1: T, xf2: T) -> (T, T);
}

/// A control law of one drive (its constants at the servo period), and the same law on lanes.
pub(crate) trait Law: LawOn<f64> {
    /// The law on lanes of `U`.
    type On<U: Lane>: LawOn<U>;
    /// The law of `controller` on `plant` at servo period `h`, if the controller is of this kind.
    fn of(controller: &Controller, plant: &Plant, h: f64) -> Option<Self>;
    /// Lane `l` runs `laws[l]` (the last one in the lanes beyond).
    fn gather<U: Lane>(laws: &[&Self]) -> Self::On<U>;
    /// The law on one lane is the law itself.
    fn as_scalar(on: &Self::On<f64>) -> &Self;
    /// The slopes in the two readings.
    fn slopes(&self) -> Slopes;
    /// `(gd, gi)`: the slopes of the direct part and of the increment in the one reading of the
    /// ideal drive ($\hat x_p = x_f = \hat x$). The same derivatives as [`Law::slopes`] summed,
    /// each folded as the ideal drive's loop has always folded it: the rounding differs from
    /// `dp + df` in the last bit, and the ideal drive's traces are kept bit for bit.
    fn one_reading_slopes(&self) -> (f64, f64);
    /// $K_I$: the gain of the integrator state in $u$.
    fn k_int(&self) -> f64;
}

/// Acceleration and velocity feed-forward gains $(J_{ff}J/(r_gK_aK_t), B_{ff}B/(r_gK_aK_t))$,
/// V per axis unit/s² and per axis unit/s.
fn feed_forward(plant: &Plant, jff: f64, bff: f64) -> (f64, f64) {
    let (j, b, rg, k) = (plant.j, plant.b, plant.rg, plant.ka_kt());
    (jff * j / (rg * k), bff * b / (rg * k))
}

/// A law's constants on lanes: each field of lane `l` from `laws[l]`.
macro_rules! gather {
    ($name:ident, $laws:expr, [$($f:ident),*]) => {{
        let laws = $laws;
        let pick = |l: usize| laws[l.min(laws.len() - 1)];
        $name { $($f: U::from_fn(|l| pick(l).$f),)* }
    }};
}

/// P-PI with constants folded (see [`PPiGains`]):
/// direct $= K_p(K_v e + V_{ff}v_r/r_g - \hat v/r_g) + $ feed-forward,
/// $\Delta I = K_v h(e + e_1)/2 + V_{ff}(x_r - x_{r1})/r_g - (x_f - x_{f1})/r_g$: the increment
/// of $I = \int(\omega_c - \dot\theta)dt$.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PPi<T> {
    kp: T,
    ki: T,
    kv: T,
    vff_over_rg: T,
    inv_rg: T,
    half_h_kv: T,
    inv_2h: T,
    ff_a: T,
    ff_v: T,
}

impl<T: Lane> LawOn<T> for PPi<T> {
    #[inline(always)]
    fn terms0(&self, r: &RefSample<T>, xr1: T, e1: T, xf1: T, xf2: T) -> (T, T) {
        // v_hat with the current position set to 0.
        let v0 = (xf2 - T::splat(4.0) * xf1) * self.inv_2h;
        // omega_c - theta_dot, rad/s.
        let w_err0 = self.kv * r.xr + self.vff_over_rg * r.vr - self.inv_rg * v0;
        let direct0 = self.kp * w_err0 + self.ff_a * r.ar + self.ff_v * r.vr;
        // Kv int(e) by the trapezoid rule, the velocity terms exactly from position increments.
        let d_int0 =
            self.half_h_kv * (r.xr + e1) + self.vff_over_rg * (r.xr - xr1) + self.inv_rg * xf1;
        (direct0, d_int0)
    }
}

impl PPi<f64> {
    /// The law with gains `g` on `plant` at servo period `h`.
    pub(crate) fn new(g: PPiGains, plant: &Plant, h: f64) -> PPi<f64> {
        let rg = plant.rg;
        let (ff_a, ff_v) = feed_forward(plant, g.jff, g.bff);
        PPi {
            kp: g.kp,
            ki: g.ki,
            kv: g.kv,
            vff_over_rg: g.vff / rg,
            inv_rg: 1.0 / rg,
            half_h_kv: 0.5 * h * g.kv,
            inv_2h: 0.5 / h,
            ff_a,
            ff_v,
        }
    }
}

impl Law for PPi<f64> {
    type On<U: Lane> = PPi<U>;
    fn as_scalar(on: &PPi<f64>) -> &Self {
        on
    }
    fn of(controller: &Controller, plant: &Plant, h: f64) -> Option<Self> {
        match *controller {
            Controller::PPi(g) => Some(PPi::new(g, plant, h)),
            _ => None,
        }
    }
    fn gather<U: Lane>(laws: &[&Self]) -> PPi<U> {
        gather!(
            PPi,
            laws,
            [
                kp,
                ki,
                kv,
                vff_over_rg,
                inv_rg,
                half_h_kv,
                inv_2h,
                ff_a,
                ff_v
            ]
        )
    }
    fn slopes(&self) -> Slopes {
        Slopes {
            dp: -self.kp * self.kv,
            df: -self.kp * self.inv_rg * 3.0 * self.inv_2h,
            ip: -self.half_h_kv,
            i_f: -self.inv_rg,
        }
    }
    fn one_reading_slopes(&self) -> (f64, f64) {
        (
            -self.kp * (self.kv + self.inv_rg * 3.0 * self.inv_2h),
            -(self.half_h_kv + self.inv_rg),
        )
    }
    fn k_int(&self) -> f64 {
        self.ki
    }
}

/// PID with constants folded (see [`PidGains`]): direct $= K_p e + K_d(v_r - \hat v) + $
/// feed-forward, $\Delta I = h(e + e_1)/2$.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Pid<T> {
    kp: T,
    ki: T,
    kd: T,
    half_h: T,
    inv_2h: T,
    ff_a: T,
    ff_v: T,
}

impl<T: Lane> LawOn<T> for Pid<T> {
    #[inline(always)]
    fn terms0(&self, r: &RefSample<T>, _xr1: T, e1: T, xf1: T, xf2: T) -> (T, T) {
        let v0 = (xf2 - T::splat(4.0) * xf1) * self.inv_2h;
        let direct0 = self.kp * r.xr + self.kd * (r.vr - v0) + self.ff_a * r.ar + self.ff_v * r.vr;
        (direct0, self.half_h * (r.xr + e1))
    }
}

impl Pid<f64> {
    /// The law with gains `g` on `plant` at servo period `h`.
    pub(crate) fn new(g: PidGains, plant: &Plant, h: f64) -> Pid<f64> {
        let PidGains {
            kp,
            ki,
            kd,
            jff,
            bff,
        } = g;
        let (ff_a, ff_v) = feed_forward(plant, jff, bff);
        Pid {
            kp,
            ki,
            kd,
            half_h: 0.5 * h,
            inv_2h: 0.5 / h,
            ff_a,
            ff_v,
        }
    }
}

impl Law for Pid<f64> {
    type On<U: Lane> = Pid<U>;
    fn as_scalar(on: &Pid<f64>) -> &Self {
        on
    }
    fn of(controller: &Controller, plant: &Plant, h: f64) -> Option<Self> {
        match *controller {
            Controller::Pid(g) => Some(Pid::new(g, plant, h)),
            _ => None,
        }
    }
    fn gather<U: Lane>(laws: &[&Self]) -> Pid<U> {
        gather!(Pid, laws, [kp, ki, kd, half_h, inv_2h, ff_a, ff_v])
    }
    fn slopes(&self) -> Slopes {
        Slopes {
            dp: -self.kp,
            df: -self.kd * 3.0 * self.inv_2h,
            ip: -self.half_h,
            i_f: 0.0,
        }
    }
    fn one_reading_slopes(&self) -> (f64, f64) {
        (-(self.kp + self.kd * 3.0 * self.inv_2h), -self.half_h)
    }
    fn k_int(&self) -> f64 {
        self.ki
    }
}

/// Sliding mode with constants folded (see [`SmcGains`]):
/// direct $= \hat J_e(a_r + \lambda\dot e) + \hat B_e\hat v + K_s(\lambda e + \dot e)$ with
/// $\dot e = v_r - \hat v$, $\Delta I = \lambda h(e + e_1)/2 + (e - e_1)$: the increment of
/// $\int S\,dt = \lambda\int e\,dt + e - e_0$, weighted by $\rho$.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Smc<T> {
    lambda: T,
    ks: T,
    rho: T,
    je_hat: T,
    be_hat: T,
    half_h_lambda: T,
    inv_2h: T,
}

impl<T: Lane> LawOn<T> for Smc<T> {
    #[inline(always)]
    fn terms0(&self, r: &RefSample<T>, _xr1: T, e1: T, xf1: T, xf2: T) -> (T, T) {
        let v0 = (xf2 - T::splat(4.0) * xf1) * self.inv_2h;
        let e_dot0 = r.vr - v0;
        let surface0 = self.lambda * r.xr + e_dot0;
        let direct0 =
            self.je_hat * (r.ar + self.lambda * e_dot0) + self.be_hat * v0 + self.ks * surface0;
        (direct0, self.half_h_lambda * (r.xr + e1) + (r.xr - e1))
    }
}

impl Smc<f64> {
    /// The law with gains `g` at servo period `h`.
    pub(crate) fn new(g: SmcGains, h: f64) -> Smc<f64> {
        let SmcGains {
            lambda,
            ks,
            rho,
            je_hat,
            be_hat,
        } = g;
        Smc {
            lambda,
            ks,
            rho,
            je_hat,
            be_hat,
            half_h_lambda: 0.5 * h * lambda,
            inv_2h: 0.5 / h,
        }
    }
}

impl Law for Smc<f64> {
    type On<U: Lane> = Smc<U>;
    fn as_scalar(on: &Smc<f64>) -> &Self {
        on
    }
    fn of(controller: &Controller, _plant: &Plant, h: f64) -> Option<Self> {
        match *controller {
            Controller::Smc(g) => Some(Smc::new(g, h)),
            _ => None,
        }
    }
    fn gather<U: Lane>(laws: &[&Self]) -> Smc<U> {
        gather!(
            Smc,
            laws,
            [lambda, ks, rho, je_hat, be_hat, half_h_lambda, inv_2h]
        )
    }
    fn slopes(&self) -> Slopes {
        // d v_hat / d xf = 3/(2h); d e / d xp = -1; d e_dot / d xf = -3/(2h).
        let dv = 3.0 * self.inv_2h;
        Slopes {
            dp: -self.ks * self.lambda,
            df: dv * (self.be_hat - self.je_hat * self.lambda - self.ks),
            ip: -(self.half_h_lambda + 1.0),
            i_f: 0.0,
        }
    }
    fn one_reading_slopes(&self) -> (f64, f64) {
        let dv = 3.0 * self.inv_2h;
        (
            -self.je_hat * self.lambda * dv + self.be_hat * dv - self.ks * (self.lambda + dv),
            -(self.half_h_lambda + 1.0),
        )
    }
    fn k_int(&self) -> f64 {
        self.rho
    }
}

/// Runs `job` on the law of `controller` on `plant` at servo period `h` (monomorphised on its
/// kind).
pub(crate) fn with_law<J: LawJob>(
    controller: &Controller,
    plant: &Plant,
    h: f64,
    job: J,
) -> J::Out {
    match *controller {
        Controller::PPi(g) => job.run(PPi::new(g, plant, h)),
        Controller::Pid(g) => job.run(Pid::new(g, plant, h)),
        Controller::Smc(g) => job.run(Smc::new(g, h)),
    }
}

/// Something to do with a law of any kind ([`with_law`]).
pub(crate) trait LawJob {
    type Out;
    fn run<L: Law>(self, law: L) -> Self::Out;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lane::F4;
    use approx::assert_relative_eq;

    fn laws(h: f64) -> (PPi<f64>, Pid<f64>, Smc<f64>) {
        let inv_2h = 0.5 / h;
        (
            PPi {
                kp: 2.3,
                ki: 223.0,
                kv: 70.0,
                vff_over_rg: 0.5 / 1.59,
                inv_rg: 1.0 / 1.59,
                half_h_kv: 0.5 * h * 70.0,
                inv_2h,
                ff_a: 0.01,
                ff_v: 0.002,
            },
            Pid {
                kp: 30.0,
                ki: 800.0,
                kd: 0.5,
                half_h: 0.5 * h,
                inv_2h,
                ff_a: 0.0,
                ff_v: 0.01,
            },
            Smc {
                lambda: 67.0,
                ks: 0.01,
                rho: 3.0,
                je_hat: 0.006,
                be_hat: 0.02,
                half_h_lambda: 0.5 * h * 67.0,
                inv_2h,
            },
        )
    }

    #[test]
    fn law_slopes_match_the_terms() {
        // Truth: the laws as docs/drive-model.md writes them, with the BDF2 velocity, and their
        // finite differences in each reading: `slopes` (and, for one reading, the folded
        // `one_reading_slopes`) must be the derivatives of what the tick computes, or the
        // rearranged tick would differ from the plain law.
        let (xr1, xf1, xf2, xp1) = (1.25, 1.2, 1.1, 1.21);
        let e1 = xr1 - xp1;
        let r = RefSample {
            xr: 1.3,
            vr: 50.0,
            ar: 400.0,
        };
        let h = 5e-5;
        let (ppi, pid, smc) = laws(h);
        fn check<L: Law>(
            law: &L,
            r: RefSample<f64>,
            (xr1, e1, xf1, xf2): (f64, f64, f64, f64),
            direct: impl Fn(f64, f64) -> (f64, f64),
        ) {
            let s = law.slopes();
            let (d0, i0) = law.terms0(&r, xr1, e1, xf1, xf2);
            let (d_ref0, i_ref0) = direct(0.0, 0.0);
            assert_relative_eq!(d0, d_ref0, max_relative = 1e-12, epsilon = 1e-9);
            assert_relative_eq!(i0, i_ref0, max_relative = 1e-12, epsilon = 1e-12);
            let (dp, ip) = direct(1.0, 0.0);
            let (df, i_f) = direct(0.0, 1.0);
            assert_relative_eq!(s.dp, dp - d_ref0, max_relative = 1e-9, epsilon = 1e-12);
            assert_relative_eq!(s.ip, ip - i_ref0, max_relative = 1e-9, epsilon = 1e-12);
            assert_relative_eq!(s.df, df - d_ref0, max_relative = 1e-9, epsilon = 1e-12);
            assert_relative_eq!(s.i_f, i_f - i_ref0, max_relative = 1e-9, epsilon = 1e-12);
            let (gd, gi) = law.one_reading_slopes();
            let (d1, i1) = direct(1.0, 1.0);
            assert_relative_eq!(gd, d1 - d_ref0, max_relative = 1e-9);
            assert_relative_eq!(gi, i1 - i_ref0, max_relative = 1e-9);
        }
        let vhat = |xf: f64| (3.0 * xf - 4.0 * xf1 + xf2) * (0.5 / h);
        let state = (xr1, e1, xf1, xf2);
        check(&ppi, r, state, |xp, xf| {
            let e = r.xr - xp;
            let w = 70.0 * e + 0.5 / 1.59 * r.vr - vhat(xf) / 1.59;
            let d = 2.3 * w + 0.01 * r.ar + 0.002 * r.vr;
            let di = 70.0 * h * (e + e1) / 2.0 + 0.5 * (r.xr - xr1) / 1.59 - (xf - xf1) / 1.59;
            (d, di)
        });
        check(&pid, r, state, |xp, xf| {
            let e = r.xr - xp;
            (
                30.0 * e + 0.5 * (r.vr - vhat(xf)) + 0.01 * r.vr,
                h * (e + e1) / 2.0,
            )
        });
        check(&smc, r, state, |xp, xf| {
            let e = r.xr - xp;
            let ed = r.vr - vhat(xf);
            let sv = 67.0 * e + ed;
            let d = 0.006 * (r.ar + 67.0 * ed) + 0.02 * vhat(xf) + 0.01 * sv;
            (d, 67.0 * h * (e + e1) / 2.0 + (e - e1))
        });
    }

    #[test]
    fn laws_on_lanes_are_each_lanes_law_bit_for_bit() {
        if !crate::lane::available() {
            eprintln!("skipped: no AVX2 on this processor, so no lanes");
            return;
        }
        // Truth: the scalar law of each lane's drive, on states that differ per lane.
        let (a, b, c) = (laws(5e-5), laws(1e-4), laws(2.5e-4));
        let state = |l: usize| (1.25 + l as f64, 0.01 * l as f64, 1.2 - l as f64, 1.1);
        let r = |l: usize| RefSample {
            xr: 1.3 * l as f64,
            vr: 50.0 - l as f64,
            ar: 400.0,
        };
        fn check<L: Law>(
            laws: [&L; 3],
            state: impl Fn(usize) -> (f64, f64, f64, f64),
            r: impl Fn(usize) -> RefSample<f64>,
        ) {
            let lanes: L::On<F4> = L::gather(&laws);
            let s = |i: usize| F4::from_fn(|l| [state(l).0, state(l).1, state(l).2, state(l).3][i]);
            let rf = RefSample::<F4>::from_fn(&r);
            let (d, i) = lanes.terms0(&rf, s(0), s(1), s(2), s(3));
            for l in 0..4 {
                let (xr1, e1, xf1, xf2) = state(l);
                let (ds, is) = laws[l.min(2)].terms0(&r(l), xr1, e1, xf1, xf2);
                assert_eq!(
                    (d.at(l).to_bits(), i.at(l).to_bits()),
                    (ds.to_bits(), is.to_bits())
                );
            }
        }
        check([&a.0, &b.0, &c.0], state, r);
        check([&a.1, &b.1, &c.1], state, r);
        check([&a.2, &b.2, &c.2], state, r);
    }
}
