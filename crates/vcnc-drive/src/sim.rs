//! Time-domain simulation of the "true" drive: the plant with Coulomb friction and true sticking,
//! the encoder, and the controller running at the servo rate (docs/drive-model.md).
//!
//! # Timing
//!
//! The reference arrives as samples at the logging period $T_s$ (1 ms: the CNC interpolator
//! cycle). Between samples the servo loop sees the position, velocity and acceleration samples
//! each interpolated linearly ("fine interpolation", as a CNC's servo interpolates between
//! interpolator cycles). [`crate::ClosedLoopModel::simulate`] applies the same first-order hold
//! to the same samples, so a perfect model reproduces the drive up to the servo-rate
//! discretisation, which vanishes in proportion to the servo period $h$.
//!
//! At every servo tick $t_k$ the controller reads the encoder $\hat x_k$, computes $u_k$, and
//! holds it over $[t_k, t_k + h)$ (zero-order hold: the unavoidable half-period lag of a digital
//! controller, which makes the difference to the continuous loop first order in $h$). The drive
//! starts at rest at the first reference sample with every controller state zero; the trace
//! records each logging instant's encoder reading, true position and velocity, and $u$.
//!
//! The sample $k$ is logged at its first tick $t_k$; its other $n_{sub} - 1$ ticks interpolate
//! towards sample $k + 1$, and the last sample runs its first tick only. So the loop runs
//! sample by sample as the samples arrive: on sample $k$, the remaining ticks of sample $k - 1$,
//! then the first tick of sample $k$, logged. This is how [`crate::DriveStream`] runs a reference
//! fed in pieces, and [`Drive::simulate`] is that stream fed the whole reference.
//!
//! # Plant step (exact linear part, implicit friction)
//!
//! In axis units, $\ddot x = -\beta \dot x + c\,u - d_c \operatorname{sgn}\dot x$ with
//! $\beta = B/J$, $c = K_aK_t r_g/J$, $d_c = T_c r_g/J$. Over one period with $u$ and the friction
//! force $f$ held, the exact solution is
//!
//! $$ v_{k+1} = e^{-\beta h} v_k + \varphi_1 (c u_k - f), \qquad
//!    x_{k+1} = x_k + \varphi_1 v_k + \varphi_2 (c u_k - f), $$
//!
//! $\varphi_1 = \int_0^h e^{-\beta s}ds$, $\varphi_2 = \int_0^h\!\int_0^s e^{-\beta r}dr\,ds$. The
//! friction is set-valued and chosen implicitly, as in Kikuuwe et al. (2005) and docs/drive-model.md
//! (whose implicit-Euler form this generalises: with $e^{-\beta h} \approx 1/(1 + \beta h)$ it is
//! the same step): with $v^* = e^{-\beta h} v_k + \varphi_1 c\,u_k$ and $L = \varphi_1 d_c$,
//! the axis sticks ($v_{k+1} = 0$, $f$ whatever keeps it there) if $|v^*| \le L$, else
//! $v_{k+1} = v^* - L\operatorname{sgn}(v^*)$. An axis at rest with $|K_aK_t u| \le T_c$
//! therefore stays exactly at rest.
//!
//! # Controllers
//!
//! Integrals of the position error use the trapezoidal rule (Tustin), exact to $O(h^2)$;
//! integrals of quantities that are derivatives of measured or commanded positions use the
//! positions themselves (the P-PI's $\int(\omega_c - \dot\theta)dt$ contains
//! $\int \dot\theta\,dt = \theta - \theta_0$ exactly, as an incremental PI fed with encoder
//! differences computes it). The velocity is the second-order backward difference of the
//! encoder, $\hat v_k = (3\hat x_k - 4\hat x_{k-1} + \hat x_{k-2})/(2h)$, exact for motion of
//! constant acceleration, so the velocity feedback adds no lag to first order. With a saturation
//! limit, the integrator holds while $u$ is saturated and its increment would drive $u$ further
//! into the limit (conditional-integration anti-windup).
//!
//! Variables are named as in docs/drive-model.md and the paper (`kv`, `kp`, `ki`, `lambda`, `ks`,
//! `rho`, `je_hat`, `be_hat`, `dc`); `xm` is the encoder reading $\hat x$, `xr`, `vr`, `ar` the
//! interpolated reference, `h` the servo period.

use nalgebra::{Complex, SMatrix};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::Error;
use crate::model::{ClosedLoopModel, Poles, Reference};
use crate::params::{Controller, Drive, DriveParams, Encoder, PPiGains, PidGains, Plant, SmcGains};
use crate::stream::Channels;

/// What a drive simulation logs at every sample of the reference (period `ts`). Memory is
/// O(samples), independent of the servo rate.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DriveTrace {
    /// Logging period $T_s$, s.
    pub ts: f64,
    /// Encoder reading $\hat x$ (quantised, with noise if configured), axis units. This is what
    /// a real drive's trace contains and what identification should use.
    pub position: Vec<f64>,
    /// True axis position $x$, axis units.
    pub true_position: Vec<f64>,
    /// True axis velocity $\dot x$, axis units/s.
    pub velocity: Vec<f64>,
    /// Control signal $u$ computed at the sample instant (after saturation), V.
    pub control: Vec<f64>,
    /// Servo ticks at which $u$ was saturated (0 without a limit).
    pub saturated_ticks: u64,
    /// True motor-side position $r_g\theta_m$, axis units: equal to `true_position` for a rigid
    /// drive, different with a compliant transmission or backlash (docs/machine-file.md#drive-effects).
    pub motor_position: Vec<f64>,
    /// Motor torque at the sample instant, N·m: $K_aK_t u$, or the current loop's output when
    /// the drive has one.
    pub motor_torque: Vec<f64>,
}

impl DriveTrace {
    /// The names of the per-sample channels, in the order of [`DriveTrace::channels`].
    pub const CHANNELS: [&'static str; 6] = [
        "position",
        "true_position",
        "velocity",
        "control",
        "motor_position",
        "motor_torque",
    ];

    /// The per-sample channels, in the order of [`DriveTrace::CHANNELS`].
    pub fn channels(&self) -> [&[f64]; 6] {
        [
            &self.position,
            &self.true_position,
            &self.velocity,
            &self.control,
            &self.motor_position,
            &self.motor_torque,
        ]
    }

    /// Empties every channel, keeping each one's memory for `n` samples at least (a trace
    /// reused from run to run or from piece to piece of a stream).
    pub fn clear_channels(&mut self, n: usize) {
        for v in [
            &mut self.position,
            &mut self.true_position,
            &mut self.velocity,
            &mut self.control,
            &mut self.motor_position,
            &mut self.motor_torque,
        ] {
            v.clear();
            v.reserve(n);
        }
    }

    /// An empty trace of period `ts` with room for `n` samples in every channel.
    pub(crate) fn with_capacity(ts: f64, n: usize) -> Self {
        DriveTrace {
            ts,
            position: Vec::with_capacity(n),
            true_position: Vec::with_capacity(n),
            velocity: Vec::with_capacity(n),
            control: Vec::with_capacity(n),
            saturated_ticks: 0,
            motor_position: Vec::with_capacity(n),
            motor_torque: Vec::with_capacity(n),
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.position.len()
    }

    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }
}

/// Validates `params` and simulates the drive through `reference` (samples at period `ts`, s).
/// See [`Drive::simulate`].
pub fn simulate_drive(
    params: &DriveParams,
    reference: Reference<'_>,
    ts: f64,
) -> Result<DriveTrace, Error> {
    params.validate()?.simulate(reference, ts)
}

/// One reference sample seen by the servo loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RefSample {
    pub(crate) xr: f64,
    pub(crate) vr: f64,
    pub(crate) ar: f64,
}

/// $q\,\mathrm{round}(x/q)$ (ties to even), or $x$ when $q = 0$ (`inv_q` = $1/q$).
#[inline(always)]
pub(crate) fn quantise_to(x: f64, q: f64, inv_q: f64) -> f64 {
    // 1.5 * 2^52: adding and subtracting it rounds to an integer (ties to even) for
    // |y| < 2^51, without a libm call.
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    if q > 0.0 {
        let y = x * inv_q;
        let n = if y.abs() < 2_251_799_813_685_248.0 {
            (y + MAGIC) - MAGIC
        } else {
            y.round()
        };
        n * q
    } else {
        x
    }
}

/// Controller history and integrator, common to every law.
#[derive(Debug, Clone, Copy, PartialEq)]
struct CtrlState {
    /// Integrator state (meaning depends on the law).
    integ: f64,
    /// Encoder readings at the previous two ticks.
    xm1: f64,
    xm2: f64,
    /// Reference position at the previous tick.
    xr1: f64,
}

/// One discrete control law, written as an affine function of the current encoder reading
/// $\hat x_k$ so that the servo loop can keep the work that does not depend on it off the
/// loop-carried dependency chain: the direct part of $u$ is `direct0 + gd * xm`, the integrator
/// increment `d_int0 + gi * xm`, and $u$ = direct part + `k_int` × integrator. Monomorphised so
/// the inner loop has no dispatch.
trait Law {
    /// `(direct0, d_int0)`: the terms with $\hat x_k$ set to 0.
    fn terms0(&self, s: &CtrlState, r: RefSample) -> (f64, f64);
    /// `(gd, gi, k_int)`: slopes in $\hat x_k$ and the integral gain.
    fn slopes(&self) -> (f64, f64, f64);
}

/// P-PI with constants folded (see [`PPiGains`]):
/// $u = K_p(\omega_c - \hat v/r_g) + K_i I + \text{ff}$ with
/// $I = \int(\omega_c - \dot\theta)dt = K_v\int e\,dt + V_{ff}(x_r - x_{r0})/r_g - (\hat x - \hat x_0)/r_g$.
struct PPiLaw {
    kp: f64,
    ki: f64,
    kv: f64,
    vff_over_rg: f64,
    inv_rg: f64,
    half_h_kv: f64,
    inv_2h: f64,
    ff_a: f64,
    ff_v: f64,
}

impl Law for PPiLaw {
    #[inline(always)]
    fn terms0(&self, s: &CtrlState, r: RefSample) -> (f64, f64) {
        let e1 = s.xr1 - s.xm1;
        // v_hat with the current reading set to 0.
        let v_hat0 = (s.xm2 - 4.0 * s.xm1) * self.inv_2h;
        // omega_c - theta_dot, rad/s.
        let w_err0 = self.kv * r.xr + self.vff_over_rg * r.vr - self.inv_rg * v_hat0;
        let direct0 = self.kp * w_err0 + self.ff_a * r.ar + self.ff_v * r.vr;
        // Increment of the integral: Kv int(e) by the trapezoid rule, the velocity terms exactly
        // from position increments.
        let d_int0 =
            self.half_h_kv * (r.xr + e1) + self.vff_over_rg * (r.xr - s.xr1) + self.inv_rg * s.xm1;
        (direct0, d_int0)
    }

    fn slopes(&self) -> (f64, f64, f64) {
        (
            -self.kp * (self.kv + self.inv_rg * 3.0 * self.inv_2h),
            -(self.half_h_kv + self.inv_rg),
            self.ki,
        )
    }
}

/// PID with constants folded (see [`PidGains`]).
struct PidLaw {
    kp: f64,
    ki: f64,
    kd: f64,
    half_h: f64,
    inv_2h: f64,
    ff_a: f64,
    ff_v: f64,
}

impl Law for PidLaw {
    #[inline(always)]
    fn terms0(&self, s: &CtrlState, r: RefSample) -> (f64, f64) {
        let e1 = s.xr1 - s.xm1;
        let v_hat0 = (s.xm2 - 4.0 * s.xm1) * self.inv_2h;
        let direct0 =
            self.kp * r.xr + self.kd * (r.vr - v_hat0) + self.ff_a * r.ar + self.ff_v * r.vr;
        (direct0, self.half_h * (r.xr + e1))
    }

    fn slopes(&self) -> (f64, f64, f64) {
        (
            -(self.kp + self.kd * 3.0 * self.inv_2h),
            -self.half_h,
            self.ki,
        )
    }
}

/// Sliding mode with constants folded (see [`SmcGains`]):
/// $u = \hat J_e(\ddot x_r + \lambda\dot e) + \hat B_e\hat v + K_s S + \rho\int S\,dt$,
/// $\int S\,dt = \lambda\int e\,dt + e - e_0$.
struct SmcLaw {
    lambda: f64,
    ks: f64,
    rho: f64,
    je_hat: f64,
    be_hat: f64,
    half_h_lambda: f64,
    inv_2h: f64,
}

impl Law for SmcLaw {
    #[inline(always)]
    fn terms0(&self, s: &CtrlState, r: RefSample) -> (f64, f64) {
        let e1 = s.xr1 - s.xm1;
        let v_hat0 = (s.xm2 - 4.0 * s.xm1) * self.inv_2h;
        let e_dot0 = r.vr - v_hat0;
        let surface0 = self.lambda * r.xr + e_dot0;
        let direct0 =
            self.je_hat * (r.ar + self.lambda * e_dot0) + self.be_hat * v_hat0 + self.ks * surface0;
        (direct0, self.half_h_lambda * (r.xr + e1) + (r.xr - e1))
    }

    fn slopes(&self) -> (f64, f64, f64) {
        // d v_hat / d xm = 3/(2h); d e / d xm = -1; d e_dot / d xm = -3/(2h).
        let dv = 3.0 * self.inv_2h;
        (
            -self.je_hat * self.lambda * dv + self.be_hat * dv - self.ks * (self.lambda + dv),
            -(self.half_h_lambda + 1.0),
            self.rho,
        )
    }
}

/// Exact zero-order-hold step of the linear plant with implicit Coulomb friction (module docs).
#[derive(Debug, Clone, Copy)]
struct PlantStep {
    /// $e^{-\beta h}$.
    decay: f64,
    phi1: f64,
    phi2: f64,
    /// Acceleration per volt $c = K_aK_t r_g / J$, axis units/s² per V.
    c: f64,
    /// Friction velocity bound $L = \varphi_1 d_c$.
    stick: f64,
    /// Friction acceleration $d_c$.
    dc: f64,
    /// Position gain on $v_k$ when the step ends stuck: $\varphi_1 - \varphi_2 e^{-\beta h}/\varphi_1$.
    stuck_dx: f64,
}

impl PlantStep {
    fn new(plant: &Plant, h: f64) -> Result<PlantStep, Error> {
        let beta = plant.b_over_j();
        // exp of [[0, 1, 0], [0, -beta, 1], [0, 0, 0]] h gives phi1 (row 0 col 1 = int e^{-beta s}),
        // phi2 (row 0 col 2) and the decay (row 1 col 1) without cancellation for small beta h.
        #[rustfmt::skip]
        let m = SMatrix::<f64, 3, 3>::new(
            0.0, h, 0.0,
            0.0, -beta * h, h,
            0.0, 0.0, 0.0,
        );
        crate::model::check_exp_norm(&m)?;
        let e = m.exp();
        let (decay, phi1, phi2) = (e[(1, 1)], e[(0, 1)], e[(0, 2)]);
        let c = plant.ka_kt() * plant.rg / plant.j;
        let dc = plant.dc();
        let step = PlantStep {
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
    fn finish(&self, x: &mut f64, v: &mut f64, v_star: f64, x_star: f64) {
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

/// Encoder reading with quantisation and Box–Muller Gaussian noise from a seeded ChaCha8.
struct EncoderReader {
    q: f64,
    inv_q: f64,
    std: f64,
    rng: ChaCha8Rng,
    spare: Option<f64>,
}

impl EncoderReader {
    fn new(enc: &Encoder) -> EncoderReader {
        EncoderReader {
            q: enc.resolution,
            inv_q: if enc.resolution > 0.0 {
                1.0 / enc.resolution
            } else {
                0.0
            },
            std: enc.noise_std,
            rng: ChaCha8Rng::seed_from_u64(enc.seed),
            spare: None,
        }
    }

    /// $q\,\mathrm{round}(x/q)$ (ties to even), or $x$ when $q = 0$.
    #[inline(always)]
    fn quantise(&self, x: f64) -> f64 {
        quantise_to(x, self.q, self.inv_q)
    }

    #[inline(never)]
    fn gaussian(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        // u1 in (0, 1] so the log is finite.
        let u1 = 1.0 - self.rng.random::<f64>();
        let u2 = self.rng.random::<f64>();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
        self.spare = Some(r * s);
        r * c
    }

    #[inline(always)]
    fn read(&mut self, x: f64) -> f64 {
        let y = if self.std > 0.0 {
            x + self.std * self.gaussian()
        } else {
            x
        };
        self.quantise(y)
    }
}

/// One logged sample: every channel of a [`DriveTrace`] at a sample's first servo tick (the
/// states before the tick, the control and torque computed at it).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Logged {
    /// Position reading the loop used, axis units.
    pub(crate) position: f64,
    /// True (load) position, axis units.
    pub(crate) true_position: f64,
    /// True (load) velocity, axis units/s.
    pub(crate) velocity: f64,
    /// Control after the limit, V.
    pub(crate) control: f64,
    /// Motor-side position, axis units.
    pub(crate) motor_position: f64,
    /// Motor torque, N·m.
    pub(crate) motor_torque: f64,
}

/// Where a servo loop writes its logged samples: the channels a stream keeps
/// ([`crate::Channels`]). Monomorphised, so a channel left out costs nothing.
pub(crate) trait SampleLog {
    /// Appends one sample.
    fn log(&mut self, s: Logged);
}

/// Every channel of a [`DriveTrace`].
pub(crate) struct AllChannels<'a>(pub(crate) &'a mut DriveTrace);

impl SampleLog for AllChannels<'_> {
    #[inline(always)]
    fn log(&mut self, s: Logged) {
        let t = &mut *self.0;
        t.position.push(s.position);
        t.true_position.push(s.true_position);
        t.velocity.push(s.velocity);
        t.control.push(s.control);
        t.motor_position.push(s.motor_position);
        t.motor_torque.push(s.motor_torque);
    }
}

/// The true position alone (what a prediction keeps: 8 bytes a sample instead of 48).
pub(crate) struct TruePositionOnly<'a>(pub(crate) &'a mut Vec<f64>);

impl SampleLog for TruePositionOnly<'_> {
    #[inline(always)]
    fn log(&mut self, s: Logged) {
        self.0.push(s.true_position);
    }
}

/// The servo loop state: plant and controller.
#[derive(Debug, Clone, Copy, PartialEq)]
struct LoopState {
    x: f64,
    v: f64,
    ctrl: CtrlState,
}

/// Constants of one servo loop.
struct Servo<L> {
    law: L,
    plant: PlantStep,
    u_max: f64,
    /// $K_aK_t$, N·m/V (for logging the torque).
    ka_kt: f64,
    /// Slopes of the law in the reading: direct part, integrator increment, and of $u$.
    gd: f64,
    gi: f64,
    k_int: f64,
    gu: f64,
    /// Plant coefficients folded with the law: $\varphi_1 c$, $\varphi_2 c$, and their
    /// products with `gu`.
    phi1_c: f64,
    phi2_c: f64,
    phi1_c_gu: f64,
    phi2_c_gu: f64,
}

impl<L: Law> Servo<L> {
    fn new(law: L, plant: PlantStep, u_max: f64, ka_kt: f64) -> Servo<L> {
        let (gd, gi, k_int) = law.slopes();
        let gu = gd + k_int * gi;
        let (phi1_c, phi2_c) = (plant.phi1 * plant.c, plant.phi2 * plant.c);
        Servo {
            law,
            plant,
            u_max,
            ka_kt,
            gd,
            gi,
            k_int,
            gu,
            phi1_c,
            phi2_c,
            phi1_c_gu: phi1_c * gu,
            phi2_c_gu: phi2_c * gu,
        }
    }

    /// One servo tick from the encoder reading `xm`: control $u_k$ (saturated) and plant step
    /// over the period. Returns `(u, saturated)`.
    ///
    /// Everything that does not depend on `xm` is computed first; on the unsaturated path `xm`
    /// enters the new position and velocity through one multiply-add each, so the loop-carried
    /// chain is short (this is an algebraic rearrangement of $u = $ direct + $K$·integrator and
    /// of the plant step, not an approximation).
    #[inline(always)]
    fn tick(&self, st: &mut LoopState, xm: f64, r: RefSample) -> (f64, bool) {
        let (direct0, d_int0) = self.law.terms0(&st.ctrl, r);
        let integ0 = st.ctrl.integ + d_int0;
        let u0 = direct0 + self.k_int * integ0;
        let u = u0 + self.gu * xm;
        let p = &self.plant;
        let (x, v) = (st.x, st.v);
        let saturated = u.abs() > self.u_max;
        let u_applied = if !saturated {
            st.ctrl.integ = integ0 + self.gi * xm;
            let v_star = (p.decay * v + self.phi1_c * u0) + self.phi1_c_gu * xm;
            let x_star = (x + p.phi1 * v + self.phi2_c * u0) + self.phi2_c_gu * xm;
            p.finish(&mut st.x, &mut st.v, v_star, x_star);
            u
        } else {
            // Conditional integration: hold the integrator if its increment pushes u further
            // into the limit.
            let d_int = d_int0 + self.gi * xm;
            let mut u = u;
            if self.k_int * d_int * u > 0.0 {
                u = direct0 + self.gd * xm + self.k_int * st.ctrl.integ;
            } else {
                st.ctrl.integ += d_int;
            }
            let u = u.clamp(-self.u_max, self.u_max);
            let a_u = p.c * u;
            let v_star = p.decay * v + p.phi1 * a_u;
            let x_star = x + p.phi1 * v + p.phi2 * a_u;
            p.finish(&mut st.x, &mut st.v, v_star, x_star);
            u
        };
        st.ctrl.xm2 = st.ctrl.xm1;
        st.ctrl.xm1 = xm;
        st.ctrl.xr1 = r.xr;
        (u_applied, saturated)
    }

    /// Tick 0 of a sample (reference `r`, the sample itself): reads the encoder, ticks, and
    /// logs the sample.
    #[inline(always)]
    fn log_tick(
        &self,
        st: &mut LoopState,
        r: RefSample,
        enc: &mut EncoderReader,
        saturated_ticks: &mut u64,
        log: &mut impl SampleLog,
    ) {
        let xm = enc.read(st.x);
        let (x, v) = (st.x, st.v);
        let (u, sat) = self.tick(st, xm, r);
        *saturated_ticks += sat as u64;
        log.log(Logged {
            position: xm,
            true_position: x,
            velocity: v,
            control: u,
            motor_position: x,
            motor_torque: self.ka_kt * u,
        });
    }

    /// Runs the loop through the next samples of the reference (`piece`, not empty unless
    /// `run` is already set), `n_sub` ticks a sample (module docs, "Timing"). `run` holds the
    /// loop state and the last sample fed (`None` before the first sample: the loop then
    /// starts at rest on it). Each new sample $k$ first completes sample $k - 1$: its ticks
    /// $1 \ldots n_{sub} - 1$, which interpolate towards sample $k$; then tick 0 of sample $k$
    /// is run and logged. The last sample of a run thus runs its first tick only.
    fn feed(
        &self,
        piece: Reference<'_>,
        n_sub: usize,
        enc: &mut EncoderReader,
        run: &mut Option<(LoopState, RefSample)>,
        saturated_ticks: &mut u64,
        log: &mut impl SampleLog,
    ) {
        let (pos, vel, acc) = (piece.pos, piece.vel, piece.acc);
        let n = pos.len();
        let sample = |k: usize| RefSample {
            xr: pos[k],
            vr: vel[k],
            ar: acc[k],
        };
        let mut sat = 0u64;
        let mut k0 = 0;
        let (mut st, mut prev) = match *run {
            Some(running) => running,
            None => {
                if n == 0 {
                    return;
                }
                // At rest at the first sample with every controller state zero.
                let r = sample(0);
                let xm0 = enc.quantise(r.xr);
                let mut st = LoopState {
                    x: r.xr,
                    v: 0.0,
                    ctrl: CtrlState {
                        integ: 0.0,
                        xm1: xm0,
                        xm2: xm0,
                        xr1: r.xr,
                    },
                };
                self.log_tick(&mut st, r, enc, &mut sat, log);
                k0 = 1;
                (st, r)
            }
        };
        let inv_sub = 1.0 / n_sub as f64;
        for k in k0..n {
            let r = sample(k);
            let (dp, dv, da) = (r.xr - prev.xr, r.vr - prev.vr, r.ar - prev.ar);
            for j in 1..n_sub {
                let w = j as f64 * inv_sub;
                let rj = RefSample {
                    xr: prev.xr + w * dp,
                    vr: prev.vr + w * dv,
                    ar: prev.ar + w * da,
                };
                let xm = enc.read(st.x);
                let (_, s) = self.tick(&mut st, xm, rj);
                sat += s as u64;
            }
            self.log_tick(&mut st, r, enc, &mut sat, log);
            prev = r;
        }
        *run = Some((st, prev));
        *saturated_ticks += sat;
    }

    /// One tick of the linear loop (ideal encoder, zero reference): for building the sampled
    /// closed loop's transition matrix.
    fn linear_tick(&self, st: &mut LoopState) {
        let r = RefSample {
            xr: 0.0,
            vr: 0.0,
            ar: 0.0,
        };
        let xm = st.x;
        self.tick(st, xm, r);
    }
}

/// The servo loop of `drive` at servo period `h` (with `plant_override` instead of its plant,
/// if given), monomorphised on the controller kind.
fn servo(drive: &Drive, h: f64, plant_override: Option<&Plant>) -> Result<IdealServo, Error> {
    let plant = plant_override.unwrap_or(drive.plant());
    let plant_step = PlantStep::new(plant, h)?;
    let u_max = plant.u_max.unwrap_or(f64::INFINITY);
    let inv_2h = 0.5 / h;
    let (j, b, rg, k) = (plant.j, plant.b, plant.rg, plant.ka_kt());
    Ok(match *drive.controller() {
        Controller::PPi(PPiGains {
            kv,
            kp,
            ki,
            vff,
            bff,
            jff,
        }) => IdealServo::PPi(Servo::new(
            PPiLaw {
                kp,
                ki,
                kv,
                vff_over_rg: vff / rg,
                inv_rg: 1.0 / rg,
                half_h_kv: 0.5 * h * kv,
                ff_a: jff * j / (rg * k),
                ff_v: bff * b / (rg * k),
                inv_2h,
            },
            plant_step,
            u_max,
            k,
        )),
        Controller::Pid(PidGains {
            kp,
            ki,
            kd,
            jff,
            bff,
        }) => IdealServo::Pid(Servo::new(
            PidLaw {
                kp,
                ki,
                kd,
                half_h: 0.5 * h,
                ff_a: jff * j / (rg * k),
                ff_v: bff * b / (rg * k),
                inv_2h,
            },
            plant_step,
            u_max,
            k,
        )),
        Controller::Smc(SmcGains {
            lambda,
            ks,
            rho,
            je_hat,
            be_hat,
        }) => IdealServo::Smc(Servo::new(
            SmcLaw {
                lambda,
                ks,
                rho,
                je_hat,
                be_hat,
                half_h_lambda: 0.5 * h * lambda,
                inv_2h,
            },
            plant_step,
            u_max,
            k,
        )),
    })
}

/// The ideal servo loop of one controller kind.
enum IdealServo {
    PPi(Servo<PPiLaw>),
    Pid(Servo<PidLaw>),
    Smc(Servo<SmcLaw>),
}

/// The ideal drive's loop as a stream ([`crate::DriveStream`]): the servo loop, the encoder
/// (its seeded noise stream) and, after the first sample, the loop state and the last sample.
pub(crate) struct IdealStream {
    servo: IdealServo,
    n_sub: usize,
    enc: EncoderReader,
    run: Option<(LoopState, RefSample)>,
    saturated_ticks: u64,
}

impl IdealStream {
    /// The loop of the ideal `drive` at `n_sub` ticks of `h` a sample, before its first sample.
    pub(crate) fn new(drive: &Drive, h: f64, n_sub: usize) -> Result<IdealStream, Error> {
        Ok(IdealStream {
            servo: servo(drive, h, None)?,
            n_sub,
            enc: EncoderReader::new(drive.encoder()),
            run: None,
            saturated_ticks: 0,
        })
    }

    /// Runs the next samples (checked by the caller; empty only after the first) and logs
    /// the channels asked for into `out`.
    pub(crate) fn feed(&mut self, piece: Reference<'_>, channels: Channels, out: &mut DriveTrace) {
        match channels {
            Channels::All => self.feed_to(piece, &mut AllChannels(out)),
            Channels::TruePosition => {
                self.feed_to(piece, &mut TruePositionOnly(&mut out.true_position))
            }
        }
    }

    fn feed_to(&mut self, piece: Reference<'_>, log: &mut impl SampleLog) {
        let IdealStream {
            servo,
            n_sub,
            enc,
            run,
            saturated_ticks,
        } = self;
        let n_sub = *n_sub;
        match servo {
            IdealServo::PPi(s) => s.feed(piece, n_sub, enc, run, saturated_ticks, log),
            IdealServo::Pid(s) => s.feed(piece, n_sub, enc, run, saturated_ticks, log),
            IdealServo::Smc(s) => s.feed(piece, n_sub, enc, run, saturated_ticks, log),
        }
    }

    /// Servo ticks saturated so far.
    pub(crate) fn saturated_ticks(&self) -> u64 {
        self.saturated_ticks
    }
}

/// Servo ticks per logging period: `servo_rate_hz * ts` rounded, which must match to 1e-9.
fn ticks_per_sample(servo_rate_hz: f64, ts: f64) -> Result<usize, Error> {
    if !(ts > 0.0 && ts.is_finite()) {
        return Err(Error::BadSamplePeriod { ts });
    }
    let ratio = servo_rate_hz * ts;
    let n = ratio.round();
    if !(n >= 1.0 && (ratio - n).abs() <= 1e-9 * n && n < 1e9) {
        return Err(Error::ServoRate { servo_rate_hz, ts });
    }
    Ok(n as usize)
}

impl Drive {
    /// Servo ticks per logged sample of period `ts`: the servo rate must be a whole multiple
    /// (≥ 1) of the logging rate. The machine-file loader checks this with the same rule the
    /// simulation uses.
    pub fn ticks_per_sample(&self, ts: f64) -> Result<usize, Error> {
        ticks_per_sample(self.servo_rate_hz(), ts)
    }

    /// Simulates the drive through `reference` (samples at period `ts`, s), with the controller
    /// at the servo rate, which must be an integer multiple of $1/T_s$. The drive starts at rest
    /// at `reference.pos[0]` with every controller state zero. See the module documentation for
    /// the interpolation, the plant step and the controller discretisation. This is
    /// [`Drive::stream`] fed the whole reference at once: a stream fed the same samples in
    /// pieces gives the same trace bit for bit.
    ///
    /// Errors: the reference's ([`Reference::check`]: empty, lengths, non-finite),
    /// [`Error::BadSamplePeriod`], [`Error::ServoRate`]. Cost: about 10 ns per servo tick
    /// (30 s at 20 kHz ≈ 10 ms; see `benches/drive.rs`), memory O(samples).
    pub fn simulate(&self, reference: Reference<'_>, ts: f64) -> Result<DriveTrace, Error> {
        let mut trace = DriveTrace::default();
        self.simulate_into(reference, ts, &mut trace)?;
        Ok(trace)
    }

    /// [`Drive::simulate`]'s true position alone, and its saturated servo ticks: the same
    /// values bit for bit, without the other channels (a long run's prediction needs only
    /// this, at 8 bytes a sample instead of 48; docs/performance.md).
    pub fn simulate_true_position(
        &self,
        reference: Reference<'_>,
        ts: f64,
    ) -> Result<(Vec<f64>, u64), Error> {
        let n = reference.check()?;
        let mut stream = self.stream(ts, Channels::TruePosition)?;
        let mut out = DriveTrace {
            true_position: Vec::with_capacity(n),
            ..DriveTrace::default()
        };
        stream.feed(reference, &mut out)?;
        let saturated_ticks = stream.finish()?;
        Ok((out.true_position, saturated_ticks))
    }

    /// As [`Drive::simulate`], reusing `trace`'s buffers (cleared first).
    pub fn simulate_into(
        &self,
        reference: Reference<'_>,
        ts: f64,
        trace: &mut DriveTrace,
    ) -> Result<(), Error> {
        let n = reference.check()?;
        let mut stream = self.stream(ts, Channels::All)?;
        trace.clear_channels(n);
        trace.saturated_ticks = 0;
        stream.feed(reference, trace)?;
        trace.saturated_ticks = stream.finish()?;
        Ok(())
    }

    /// Transition matrix $M$ of the sampled linear closed loop at the servo rate (friction,
    /// quantisation, noise and saturation off, zero reference) of the ideal drive (for a drive
    /// with effects, of its rigid ideal part: see [`Drive::effects_transition_matrix`]): $z_{k+1} = M z_k$ with
    /// $z = [x, \dot x, \text{integrator}, \hat x_{k-1}, \hat x_{k-2}]$. Built column by column by
    /// running the simulator's own servo tick on unit states, so it is the matrix of the code,
    /// not of a separate derivation.
    pub fn sampled_transition_matrix(&self) -> Result<SMatrix<f64, 5, 5>, Error> {
        let h = 1.0 / self.servo_rate_hz();
        let linear_plant = Plant {
            coulomb_torque: 0.0,
            u_max: None,
            ..self.plant().clone()
        };
        let to_vec = |s: &LoopState| [s.x, s.v, s.ctrl.integ, s.ctrl.xm1, s.ctrl.xm2];
        let servo = servo(self, h, Some(&linear_plant))?;
        let mut m = SMatrix::<f64, 5, 5>::zeros();
        for col in 0..5 {
            let mut z = [0.0; 5];
            z[col] = 1.0;
            let mut st = LoopState {
                x: z[0],
                v: z[1],
                ctrl: CtrlState {
                    integ: z[2],
                    xm1: z[3],
                    xm2: z[4],
                    xr1: 0.0,
                },
            };
            match &servo {
                IdealServo::PPi(s) => s.linear_tick(&mut st),
                IdealServo::Pid(s) => s.linear_tick(&mut st),
                IdealServo::Smc(s) => s.linear_tick(&mut st),
            }
            for (row, v) in to_vec(&st).iter().enumerate() {
                m[(row, col)] = *v;
            }
        }
        Ok(m)
    }

    /// Effective continuous poles of the sampled closed loop: the three slowest eigenvalues $z$
    /// of [`Drive::sampled_transition_matrix`] (the other two are fast parasitic modes of the
    /// velocity estimator and the hold) mapped by $s = \ln(z)/h$. Returns the three poles (rad/s)
    /// and their $(p, \omega_n, \zeta)$ form. docs/drive-model.md: at 20 kHz they lie within 1 % of the
    /// continuous design; at 1 kHz they move by several percent.
    pub fn effective_poles(&self) -> Result<([Complex<f64>; 3], Poles), Error> {
        let m = self.sampled_transition_matrix()?;
        if !m.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFiniteModel);
        }
        let h = 1.0 / self.servo_rate_hz();
        let schur = m.try_schur(1e-15, 10_000).ok_or(Error::NonFiniteModel)?;
        let mut z: Vec<Complex<f64>> = schur.complex_eigenvalues().iter().copied().collect();
        z.sort_by(|a, b| b.norm().total_cmp(&a.norm()));
        let mut s = [Complex::new(0.0, 0.0); 3];
        for (si, zi) in s.iter_mut().zip(&z) {
            *si = zi.ln() / h;
        }
        // Real cubic through the three roots (conjugate pairs make the imaginary parts vanish).
        let a1 = -(s[0] + s[1] + s[2]).re;
        let a2 = (s[0] * s[1] + s[0] * s[2] + s[1] * s[2]).re;
        let a3 = -(s[0] * s[1] * s[2]).re;
        let cubic = ClosedLoopModel::characteristic(a1, a2, a3);
        let poles = cubic.poles().ok_or(Error::NonFiniteModel)?;
        Ok((s, poles))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn plant(tc: f64) -> Plant {
        Plant {
            j: 0.01,
            b: 0.0418572,
            ka: 1.0,
            kt: 1.0,
            rg: 1.5915,
            coulomb_torque: tc,
            u_max: None,
        }
    }

    #[test]
    fn plant_step_is_the_exact_solution_under_constant_input() {
        // Truth: closed-form solution of x'' = -beta x' + a with constant a:
        // v(t) = v0 e^{-beta t} + (a/beta)(1 - e^{-beta t}),
        // x(t) = x0 + (v0 - a/beta)(1 - e^{-beta t})/beta + (a/beta) t.
        let p = plant(0.0);
        let h = 5e-5;
        let step = PlantStep::new(&p, h).unwrap();
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
        let step = PlantStep::new(&p, h).unwrap();
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

    #[test]
    fn quantiser_rounds_to_the_grid() {
        let enc = EncoderReader::new(&Encoder {
            resolution: 1e-4,
            noise_std: 0.0,
            seed: 0,
        });
        assert_eq!(enc.quantise(0.00014), 1e-4);
        assert_eq!(enc.quantise(-0.00016), -2e-4);
        assert_relative_eq!(enc.quantise(123.456_789), 123.4568, max_relative = 1e-15);
        // Beyond the magic-number range it falls back to round().
        assert_eq!(enc.quantise(1e12), 1e12);
        let ideal = EncoderReader::new(&Encoder::ideal());
        assert_eq!(ideal.quantise(0.123_456_789), 0.123_456_789);
    }

    #[test]
    fn servo_rate_must_be_a_multiple_of_the_logging_rate() {
        assert_eq!(ticks_per_sample(20_000.0, 1e-3).unwrap(), 20);
        assert_eq!(ticks_per_sample(1_000.0, 1e-3).unwrap(), 1);
        assert!(matches!(
            ticks_per_sample(15_500.0, 1e-3 / 3.0),
            Err(Error::ServoRate { .. })
        ));
        assert!(matches!(
            ticks_per_sample(500.0, 1e-3),
            Err(Error::ServoRate { .. })
        ));
        assert!(matches!(
            ticks_per_sample(20_000.0, 0.0),
            Err(Error::BadSamplePeriod { .. })
        ));
    }

    #[test]
    fn law_slopes_match_the_terms() {
        // Truth: finite differences of the law in the reading; `slopes` must be the derivative
        // of what the tick computes, or the rearranged tick would differ from the plain law.
        let s = CtrlState {
            integ: 0.3,
            xm1: 1.2,
            xm2: 1.1,
            xr1: 1.25,
        };
        let r = RefSample {
            xr: 1.3,
            vr: 50.0,
            ar: 400.0,
        };
        let h = 5e-5;
        let inv_2h = 0.5 / h;
        let ppi = PPiLaw {
            kp: 2.3,
            ki: 223.0,
            kv: 70.0,
            vff_over_rg: 0.5 / 1.59,
            inv_rg: 1.0 / 1.59,
            half_h_kv: 0.5 * h * 70.0,
            inv_2h,
            ff_a: 0.01,
            ff_v: 0.002,
        };
        let pid = PidLaw {
            kp: 30.0,
            ki: 800.0,
            kd: 0.5,
            half_h: 0.5 * h,
            inv_2h,
            ff_a: 0.0,
            ff_v: 0.01,
        };
        let smc = SmcLaw {
            lambda: 67.0,
            ks: 0.01,
            rho: 3.0,
            je_hat: 0.006,
            be_hat: 0.02,
            half_h_lambda: 0.5 * h * 67.0,
            inv_2h,
        };
        fn check<L: Law>(law: &L, s: &CtrlState, r: RefSample, direct: impl Fn(f64) -> (f64, f64)) {
            let (gd, gi, _) = law.slopes();
            let (d0, i0) = law.terms0(s, r);
            let (d_ref0, i_ref0) = direct(0.0);
            assert_relative_eq!(d0, d_ref0, max_relative = 1e-12, epsilon = 1e-9);
            assert_relative_eq!(i0, i_ref0, max_relative = 1e-12, epsilon = 1e-12);
            let (d1, i1) = direct(1.0);
            assert_relative_eq!(gd, d1 - d_ref0, max_relative = 1e-9);
            assert_relative_eq!(gi, i1 - i_ref0, max_relative = 1e-9);
        }
        // The laws as docs/drive-model.md writes them, with the BDF2 velocity.
        let vhat = |xm: f64| (3.0 * xm - 4.0 * s.xm1 + s.xm2) * inv_2h;
        check(&ppi, &s, r, |xm| {
            let e = r.xr - xm;
            let e1 = s.xr1 - s.xm1;
            let w = 70.0 * e + 0.5 / 1.59 * r.vr - vhat(xm) / 1.59;
            let d = 2.3 * w + 0.01 * r.ar + 0.002 * r.vr;
            let di = 70.0 * h * (e + e1) / 2.0 + 0.5 * (r.xr - s.xr1) / 1.59 - (xm - s.xm1) / 1.59;
            (d, di)
        });
        check(&pid, &s, r, |xm| {
            let e = r.xr - xm;
            let e1 = s.xr1 - s.xm1;
            (
                30.0 * e + 0.5 * (r.vr - vhat(xm)) + 0.01 * r.vr,
                h * (e + e1) / 2.0,
            )
        });
        check(&smc, &s, r, |xm| {
            let e = r.xr - xm;
            let e1 = s.xr1 - s.xm1;
            let ed = r.vr - vhat(xm);
            let sv = 67.0 * e + ed;
            let d = 0.006 * (r.ar + 67.0 * ed) + 0.02 * vhat(xm) + 0.01 * sv;
            (d, 67.0 * h * (e + e1) / 2.0 + (e - e1))
        });
    }
}
