//! The servo loop of a drive with effects (docs/machine-file.md#drive-effects): two-mass mechanics
//! with backlash, Stribeck and Maxwell-slip friction, current loop and torque limit, feedback
//! dead time, velocity filter, noisy motor and load encoders, and the reference filter and
//! interpolation delay. A drive without effects never comes here: [`crate::Drive::simulate`]
//! runs the rigid loop of [`crate::sim`] unchanged.
//!
//! # One servo tick (period $h$)
//!
//! 1. Reference: the fine-interpolated nominal sample (as in [`crate::sim`]) goes through the
//!    interpolation delay (whole ticks) and the nominal-position filter (exact for a reference
//!    that is linear between ticks, docs/machine-file.md#reference), for the ticks from one
//!    logged sample to the next ahead of them (the samples are run as they arrive: module docs
//!    of [`crate::sim`], "Timing"); so is the readings' noise. Both are independent of how the
//!    ticks are grouped, so a reference fed in pieces ([`crate::DriveStream`]) gives the
//!    whole run's trace bit for bit.
//! 2. Readings: the position sensor (load scale or motor encoder) is read with quantisation and
//!    seeded noise, and the position loop takes the reading of $n$ ticks ago (dead time). The
//!    velocity path reads the motor encoder (the same reading in a rigid or semi-closed drive),
//!    low-pass filtered $x_f \leftarrow a x_f + (1 - a)\hat x_m$, $a = e^{-2\pi f_c h}$; the
//!    velocity is the BDF2 difference of $x_f$, the PI's $\int\dot\theta$ its increments.
//! 3. Control: the law of [`crate::sim`] written with separate position and velocity readings;
//!    limit $|u| \le \min(u_{max}, T_{max}/K_aK_t)$ with conditional integration.
//! 4. Plant: the linear part (masses, spring and damper, viscous friction, current loop) is
//!    stepped exactly, $z^* = \Phi z + \Gamma_u u + \Gamma_o o$ ($o = \pm b$ the backlash
//!    offset in contact; a second $\Phi, \Gamma$ without spring while in the gap). Friction is a
//!    torque $f$ held over the step: $z = z^* + \Gamma_f f$, chosen implicitly for the set-valued
//!    part (stick: $f$ such that the friction body's velocity ends at 0, if that needs at most
//!    the static level; otherwise the Stribeck level at the step's initial speed) or, for
//!    Maxwell-slip, as the Heun average of the elements' force before and after the step.

use nalgebra::{Complex, DMatrix, SMatrix};

use crate::Error;
use crate::effects::{
    CurrentLoopOrder, Effects, FeedbackSource, FrictionKind, FrictionLaw, FrictionLocation,
    MAX_ELEMENTS, ShapingFilter, maxwell_slip_stiffness,
};
use crate::model::{Reference, check_exp_norm};
use crate::noise::Normals;
use crate::params::{Controller, Drive, PPiGains, PidGains, Plant, SmcGains};
use crate::sim::{
    AllChannels, DriveTrace, Logged, RefSample, SampleLog, TruePositionOnly, quantise_to,
};
use crate::stream::Channels;

#[cfg(target_arch = "x86_64")]
mod lanes;
/// Drives per batch ([`lanes`]): four `f64` fill a 256-bit AVX register.
pub(crate) const LANES: usize = 4;

// ---------------------------------------------------------------------------------------------
// Control laws with separate position and velocity readings.

/// A control law of [`crate::sim`] written with the position reading $\hat x_p$ (after the dead
/// time) and the filtered velocity-path position $x_f$ apart:
///
/// $$ e = x_r - \hat x_p,\quad \hat v = \frac{3x_f - 4x_{f1} + x_{f2}}{2h},\quad
///    u = \text{direct}(e, \hat v) + K_I\,(I + \Delta I(e, e_1, x_f - x_{f1})). $$
///
/// It is affine in $(\hat x_p, x_f)$; like [`crate::sim`]'s laws it is evaluated as the terms at
/// $\hat x_p = x_f = 0$ plus slopes, so that the readings enter $u$ through one multiply-add
/// each (an algebraic rearrangement, checked against the plain law in the tests).
pub(crate) trait RLaw: Copy + Send + 'static {
    /// `(direct, ΔI)` with $\hat x_p = x_f = 0$.
    fn terms0(&self, r: RefSample, xr1: f64, e1: f64, xf1: f64, xf2: f64) -> (f64, f64);
    /// $[\partial\,\text{direct}/\partial\hat x_p, \partial\,\text{direct}/\partial x_f,
    /// \partial\Delta I/\partial\hat x_p, \partial\Delta I/\partial x_f]$.
    fn slopes(&self) -> [f64; 4];
    /// $K_I$.
    fn k_int(&self) -> f64;
    /// The law of `drive` at servo period `h`, if its controller is of this kind.
    fn of(drive: &Drive, h: f64) -> Option<Self>;
    /// The law on lanes ([`lanes`]).
    #[cfg(target_arch = "x86_64")]
    type Lanes: lanes::LaneLaw;
    /// One law per lane.
    #[cfg(target_arch = "x86_64")]
    fn lanes(laws: &[Self; LANES]) -> Self::Lanes;
}

/// P-PI: direct $= K_p(K_v e + V_{ff}v_r/r_g - \hat v/r_g) + $ feed-forward,
/// $\Delta I = K_v h(e + e_1)/2 + V_{ff}(x_r - x_{r1})/r_g - (x_f - x_{f1})/r_g$.
#[derive(Clone, Copy)]
pub(crate) struct PPiR {
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

impl RLaw for PPiR {
    #[cfg(target_arch = "x86_64")]
    type Lanes = lanes::PPiL;
    #[cfg(target_arch = "x86_64")]
    fn lanes(laws: &[Self; LANES]) -> Self::Lanes {
        lanes::PPiL::of(laws)
    }
    #[inline(always)]
    fn terms0(&self, r: RefSample, xr1: f64, e1: f64, xf1: f64, xf2: f64) -> (f64, f64) {
        let v0 = (xf2 - 4.0 * xf1) * self.inv_2h;
        let w_err0 = self.kv * r.xr + self.vff_over_rg * r.vr - self.inv_rg * v0;
        let direct0 = self.kp * w_err0 + self.ff_a * r.ar + self.ff_v * r.vr;
        let d_int0 =
            self.half_h_kv * (r.xr + e1) + self.vff_over_rg * (r.xr - xr1) + self.inv_rg * xf1;
        (direct0, d_int0)
    }
    fn slopes(&self) -> [f64; 4] {
        [
            -self.kp * self.kv,
            -self.kp * self.inv_rg * 3.0 * self.inv_2h,
            -self.half_h_kv,
            -self.inv_rg,
        ]
    }
    fn k_int(&self) -> f64 {
        self.ki
    }
    fn of(drive: &Drive, h: f64) -> Option<Self> {
        match *drive.controller() {
            Controller::PPi(g) => Some(PPiR::new(drive, g, h)),
            _ => None,
        }
    }
}

/// PID: direct $= K_p e + K_d(v_r - \hat v) + $ feed-forward, $\Delta I = h(e + e_1)/2$.
#[derive(Clone, Copy)]
pub(crate) struct PidR {
    kp: f64,
    ki: f64,
    kd: f64,
    half_h: f64,
    inv_2h: f64,
    ff_a: f64,
    ff_v: f64,
}

impl RLaw for PidR {
    #[cfg(target_arch = "x86_64")]
    type Lanes = lanes::PidL;
    #[cfg(target_arch = "x86_64")]
    fn lanes(laws: &[Self; LANES]) -> Self::Lanes {
        lanes::PidL::of(laws)
    }
    #[inline(always)]
    fn terms0(&self, r: RefSample, _xr1: f64, e1: f64, xf1: f64, xf2: f64) -> (f64, f64) {
        let v0 = (xf2 - 4.0 * xf1) * self.inv_2h;
        let direct0 = self.kp * r.xr + self.kd * (r.vr - v0) + self.ff_a * r.ar + self.ff_v * r.vr;
        (direct0, self.half_h * (r.xr + e1))
    }
    fn slopes(&self) -> [f64; 4] {
        [-self.kp, -self.kd * 3.0 * self.inv_2h, -self.half_h, 0.0]
    }
    fn k_int(&self) -> f64 {
        self.ki
    }
    fn of(drive: &Drive, h: f64) -> Option<Self> {
        match *drive.controller() {
            Controller::Pid(g) => Some(PidR::new(drive, g, h)),
            _ => None,
        }
    }
}

/// Sliding mode: direct $= \hat J_e(a_r + \lambda\dot e) + \hat B_e\hat v + K_s(\lambda e + \dot e)$
/// with $\dot e = v_r - \hat v$, $\Delta I = \lambda h(e + e_1)/2 + (e - e_1)$.
#[derive(Clone, Copy)]
pub(crate) struct SmcR {
    lambda: f64,
    ks: f64,
    rho: f64,
    je_hat: f64,
    be_hat: f64,
    half_h_lambda: f64,
    inv_2h: f64,
}

impl RLaw for SmcR {
    #[cfg(target_arch = "x86_64")]
    type Lanes = lanes::SmcL;
    #[cfg(target_arch = "x86_64")]
    fn lanes(laws: &[Self; LANES]) -> Self::Lanes {
        lanes::SmcL::of(laws)
    }
    #[inline(always)]
    fn terms0(&self, r: RefSample, _xr1: f64, e1: f64, xf1: f64, xf2: f64) -> (f64, f64) {
        let v0 = (xf2 - 4.0 * xf1) * self.inv_2h;
        let e_dot0 = r.vr - v0;
        let surface0 = self.lambda * r.xr + e_dot0;
        let direct0 =
            self.je_hat * (r.ar + self.lambda * e_dot0) + self.be_hat * v0 + self.ks * surface0;
        (direct0, self.half_h_lambda * (r.xr + e1) + (r.xr - e1))
    }
    fn slopes(&self) -> [f64; 4] {
        let dv = 3.0 * self.inv_2h;
        [
            -self.ks * self.lambda,
            dv * (self.be_hat - self.je_hat * self.lambda - self.ks),
            -(self.half_h_lambda + 1.0),
            0.0,
        ]
    }
    fn k_int(&self) -> f64 {
        self.rho
    }
    fn of(drive: &Drive, h: f64) -> Option<Self> {
        match *drive.controller() {
            Controller::Smc(g) => Some(SmcR::new(g, h)),
            _ => None,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Linear part of the plant.

/// Exact ZOH step of the linear part: $z^+ = \Phi z + \Gamma_u u + \Gamma_f f + \Gamma_o o$.
#[derive(Clone, Copy)]
struct Lin<const N: usize> {
    phi: [[f64; N]; N],
    g_u: [f64; N],
    g_f: [f64; N],
    g_o: [f64; N],
    /// $-\Gamma_f$ at the friction body's velocity: the velocity one N·m of friction removes
    /// over a step, axis units/s per N·m (> 0).
    g: f64,
    inv_g: f64,
    /// Stuck step folded: $z = (P + c P_v) + (\Gamma_u + c\,\Gamma_{u,v}) u$ with
    /// $c = \Gamma_f / g$.
    stick_k: [f64; N],
    stick_gu: [f64; N],
    /// $g\,[T_s^+, T_s^-]$: the largest end velocity the static friction can stop.
    stick_lim: [f64; 2],
}

/// Layout of the state vector $z$.
#[derive(Clone, Copy, Debug)]
struct Layout {
    /// Two-mass: `[x_m, v_m, x_L, v_L, ...]`; rigid: `[x, v, ...]`.
    two_mass: bool,
    /// Index of the first current-loop state (== number of mechanical states).
    i_cur: usize,
    /// Current-loop states (0, 1 or 2).
    n_cur: usize,
}

impl Layout {
    fn xm(&self) -> usize {
        0
    }
    fn vm(&self) -> usize {
        1
    }
    fn xl(&self) -> usize {
        if self.two_mass { 2 } else { 0 }
    }
    fn vl(&self) -> usize {
        if self.two_mass { 3 } else { 1 }
    }
    fn n(&self) -> usize {
        self.i_cur + self.n_cur
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
) -> Result<Lin<N>, Error> {
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
        inv_g: 0.0,
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
    lin.inv_g = 1.0 / lin.g;
    for i in 0..N {
        lin.stick_k[i] = lin.g_f[i] * lin.inv_g;
        lin.stick_gu[i] = lin.g_u[i] + lin.stick_k[i] * lin.g_u[vf];
    }
    let finite = e.iter().all(|v| v.is_finite());
    if finite && lin.g > 0.0 {
        Ok(lin)
    } else {
        Err(Error::NonFiniteModel)
    }
}

// ---------------------------------------------------------------------------------------------
// Friction.

/// Friction of the engine: the table's law, or the plant's symmetric Coulomb friction. One per
/// engine, never in a collection: the Maxwell-slip variant's arrays stay inline.
#[derive(Clone, Copy)]
#[allow(clippy::large_enum_variant)]
enum Fric {
    None,
    SetValued(FrictionLaw),
    Maxwell {
        law: FrictionLaw,
        n: usize,
        /// Element stiffness $k_i$, N·m per axis unit.
        k: [f64; MAX_ELEMENTS],
        /// $w_i = 1/(N k_i)$: element $i$ slips at deflection ±level · $w_i$; their extremes.
        w: [f64; MAX_ELEMENTS],
        w_max: f64,
        w_min: f64,
        /// Speed above which the Stribeck term is below the rounding, axis units/s: the level
        /// is then the Coulomb level without evaluating the law (see `flat_speed`).
        v_flat: f64,
    },
}

/// A speed above which [`FrictionLaw::level`] returns the Coulomb level through its
/// $|v/v_s|^\delta > 40$ branch: $v_s\,40^{1/\delta}$ with a relative margin of $10^{-9}$ far
/// above the rounding of the power, so that a speed beyond it takes that branch for certain (the
/// same number as evaluating the law, with no division, power or exponential).
fn flat_speed(law: &FrictionLaw) -> f64 {
    law.stribeck_velocity * 40f64.powf(1.0 / law.exponent) * (1.0 + 1e-9)
}

// ---------------------------------------------------------------------------------------------
// Encoders and delay lines.

/// A position reading with quantisation and seeded Gaussian noise ([`crate::noise`]: ChaCha8,
/// ziggurat normals).
#[derive(Clone)]
pub(crate) struct Reader {
    q: f64,
    inv_q: f64,
    std: f64,
    normals: Normals,
}

impl Reader {
    fn new(q: f64, std: f64, seed: u64, stream: u64) -> Reader {
        Reader {
            q,
            inv_q: if q > 0.0 { 1.0 / q } else { 0.0 },
            std,
            normals: Normals::new(seed, stream),
        }
    }

    /// Quantisation only (the reading of a position at rest before the first tick).
    pub(crate) fn quantise(&self, x: f64) -> f64 {
        quantise_to(x, self.q, self.inv_q)
    }

    /// This reading's noise: $\sigma\,n$ with $n$ the stream's next normal number, or 0 (no
    /// draw) without noise.
    #[inline(always)]
    pub(crate) fn noise(&mut self) -> f64 {
        if self.std > 0.0 {
            self.std * self.normals.sample()
        } else {
            0.0
        }
    }

    /// Whether the readings are noisy (then [`Reader::noise`] draws).
    #[inline(always)]
    fn noisy(&self) -> bool {
        self.std > 0.0
    }

    /// [`Reader::noise`] of a noisy reader ([`Reader::noisy`]).
    #[inline(always)]
    fn draw(&mut self) -> f64 {
        self.std * self.normals.sample()
    }

    /// The reading of position `x` with this reading's `noise` (from [`Reader::noise`]).
    #[inline(always)]
    fn read(&self, x: f64, noise: f64) -> f64 {
        quantise_to(x + noise, self.q, self.inv_q)
    }
}

/// Ring of the last readings for the position-loop dead time (at most 100 cycles).
#[derive(Clone, Copy)]
struct DelayLine {
    buf: [f64; 128],
    pos: usize,
    d: usize,
}

impl DelayLine {
    fn new(d: usize, x0: f64) -> DelayLine {
        DelayLine {
            buf: [x0; 128],
            pos: 0,
            d,
        }
    }

    /// Stores `x` and returns the value stored `d` pushes ago (`x` itself when `d` = 0).
    #[inline(always)]
    fn push(&mut self, x: f64) -> f64 {
        self.buf[self.pos] = x;
        let out = self.buf[(self.pos + 128 - self.d) & 127];
        self.pos = (self.pos + 1) & 127;
        out
    }

    /// The `d` stored values that a future read will return, oldest first.
    fn pending(&self) -> impl Iterator<Item = f64> + '_ {
        (0..self.d).map(move |i| self.buf[(self.pos + 128 - self.d + i) & 127])
    }

    fn set_pending(&mut self, values: &[f64]) {
        for (i, v) in values.iter().enumerate() {
            self.buf[(self.pos + 128 - self.d + i) & 127] = *v;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Reference shaping.

/// Interpolation delay and nominal-position filter applied to position, velocity and
/// acceleration alike (docs/machine-file.md#reference).
///
/// The delay and the moving average read past inputs at fixed lags, so both work on one linear
/// buffer: from `start` on, the last `keep` nominal samples (the delay plus the window), oldest
/// first, followed by the block being shaped; after a block, `start` moves on by the block's
/// length, and the `keep` samples go back to the front when the buffer's end is reached (once
/// per 16 blocks or more). No ring index per tick and value.
pub(crate) struct Shaper {
    ext: Vec<RefSample>,
    start: usize,
    keep: usize,
    filter: ShapeFilter,
}

enum ShapeFilter {
    None,
    /// $s^+ = \Phi s + \Gamma_0 u_k + \Gamma_1 u_{k+1}$ per channel (2 states, output $s_0$).
    Lin {
        phi: [[f64; 2]; 2],
        g0: [f64; 2],
        g1: [f64; 2],
        s: [[f64; 2]; 3],
        u_prev: [f64; 3],
    },
    /// Trapezoidal moving average over `m` ticks: running sum of the last m + 1 inputs.
    Avg {
        m: usize,
        sum: [f64; 3],
        inv_m: f64,
    },
}

impl Shaper {
    /// At rest on `r0` (the loop's first reference).
    pub(crate) fn new(
        shaping: Option<crate::effects::Shaping>,
        h: f64,
        r0: RefSample,
    ) -> Result<Shaper, Error> {
        let (filter, delay_ticks) = match shaping {
            None => (None, 0),
            Some(s) => (s.filter, s.delay_ticks),
        };
        let u0 = [r0.xr, r0.vr, r0.ar];
        let filter = match filter {
            None => ShapeFilter::None,
            Some(ShapingFilter::MovingAverage { window_s }) => {
                let m = (window_s / h).round().max(1.0) as usize;
                ShapeFilter::Avg {
                    m,
                    sum: [
                        u0[0] * (m + 1) as f64,
                        u0[1] * (m + 1) as f64,
                        u0[2] * (m + 1) as f64,
                    ],
                    inv_m: 1.0 / m as f64,
                }
            }
            Some(ShapingFilter::FirstOrder { time_constant_s }) => {
                let a = [[-1.0 / time_constant_s, 0.0], [0.0, -1.0]];
                let b = [1.0 / time_constant_s, 0.0];
                foh_filter(a, b, h, u0)?
            }
            Some(ShapingFilter::SecondOrder {
                time_constant_s,
                zeta,
            }) => {
                let w = 1.0 / time_constant_s;
                let a = [[0.0, 1.0], [-w * w, -2.0 * zeta * w]];
                let b = [0.0, w * w];
                foh_filter(a, b, h, u0)?
            }
        };
        let window = match filter {
            ShapeFilter::Avg { m, .. } => m + 1,
            _ => 0,
        };
        let keep = delay_ticks + window;
        Ok(Shaper {
            ext: vec![r0; keep],
            start: 0,
            keep,
            filter,
        })
    }

    /// The loop's reference for one tick, from the nominal one (a block of one tick).
    #[cfg(test)]
    pub(crate) fn shape(&mut self, r: RefSample) -> RefSample {
        let mut one = [r];
        self.shape_block(&mut one);
        one[0]
    }

    /// The loop's references for consecutive ticks, in place: `buf` holds the nominal ones and
    /// receives the shaped ones; the result does not depend on how the ticks are split into
    /// blocks.
    #[allow(clippy::needless_range_loop)] // three channels side by side
    pub(crate) fn shape_block(&mut self, buf: &mut [RefSample]) {
        let (b, keep) = (buf.len(), self.keep);
        if keep > 0 {
            if self.start + keep + b > self.ext.len() {
                self.ext.copy_within(self.start..self.start + keep, 0);
                self.start = 0;
                let len = keep + 16 * b;
                if self.ext.len() < len {
                    self.ext.resize(len, buf[0]);
                }
            }
            // ext = [u_{k0-keep} .. u_{k0-1}, u_{k0} .. u_{k0+b-1}].
            let s0 = self.start;
            self.ext[s0 + keep..s0 + keep + b].copy_from_slice(buf);
        }
        let ext: &[RefSample] = if keep > 0 {
            &self.ext[self.start..self.start + keep + b]
        } else {
            &[]
        };
        match &mut self.filter {
            ShapeFilter::Avg { m, sum, inv_m } => {
                // With the delay d = keep - m - 1, the averaged input of tick k is u_{k-d}, at
                // index m + 1 + j for tick k0 + j; the input leaving the running sum,
                // u_{k-d-m-1}, at index j; the window's oldest, u_{k-d-m}, at j + 1.
                let (m, inv_m) = (*m, *inv_m);
                let mut acc = *sum;
                let rows = buf
                    .iter_mut()
                    .zip(&ext[m + 1..m + 1 + b])
                    .zip(ext[..b].iter().zip(&ext[1..b + 1]));
                for ((out, new), (leaving, oldest)) in rows {
                    let u = [new.xr, new.vr, new.ar];
                    let l = [leaving.xr, leaving.vr, leaving.ar];
                    let o = [oldest.xr, oldest.vr, oldest.ar];
                    let mut y = [0.0; 3];
                    for c in 0..3 {
                        acc[c] += u[c] - l[c];
                        y[c] = (acc[c] - 0.5 * (u[c] + o[c])) * inv_m;
                    }
                    *out = RefSample {
                        xr: y[0],
                        vr: y[1],
                        ar: y[2],
                    };
                }
                *sum = acc;
            }
            ShapeFilter::None | ShapeFilter::Lin { .. } => {
                if keep > 0 {
                    // The delayed input of tick k0 + j, u_{k0+j-keep}, is at index j.
                    buf.copy_from_slice(&ext[..b]);
                }
                if let ShapeFilter::Lin {
                    phi,
                    g0,
                    g1,
                    s,
                    u_prev,
                } = &mut self.filter
                {
                    for r in buf.iter_mut() {
                        let u = [r.xr, r.vr, r.ar];
                        let mut y = [0.0; 3];
                        for c in 0..3 {
                            let (s0, s1) = (s[c][0], s[c][1]);
                            let n0 =
                                phi[0][0] * s0 + phi[0][1] * s1 + g0[0] * u_prev[c] + g1[0] * u[c];
                            let n1 =
                                phi[1][0] * s0 + phi[1][1] * s1 + g0[1] * u_prev[c] + g1[1] * u[c];
                            s[c] = [n0, n1];
                            y[c] = n0;
                        }
                        *u_prev = u;
                        *r = RefSample {
                            xr: y[0],
                            vr: y[1],
                            ar: y[2],
                        };
                    }
                }
            }
        }
        if keep > 0 {
            self.start += b;
        }
    }
}

#[allow(clippy::needless_range_loop)] // 2×2 blocks: indices read best
/// FOH discretisation of $\dot s = A s + B u$ (docs/machine-file.md#reference): with $u$ linear between ticks,
/// $s^+ = \Phi s + \Gamma_a u_k + \Gamma_l (u_{k+1} - u_k)$ where the exponential of
/// $\begin{bmatrix}A & B & 0\\0 & 0 & 1\\0 & 0 & 0\end{bmatrix}h$ holds $\Phi$,
/// $\Gamma_a = \int_0^h e^{A\sigma}d\sigma B$ and $h\Gamma_l = \int_0^h e^{A\sigma}(h - \sigma)d\sigma B$.
fn foh_filter(a: [[f64; 2]; 2], b: [f64; 2], h: f64, u0: [f64; 3]) -> Result<ShapeFilter, Error> {
    let mut m = SMatrix::<f64, 4, 4>::zeros();
    for i in 0..2 {
        for j in 0..2 {
            m[(i, j)] = a[i][j] * h;
        }
        m[(i, 2)] = b[i] * h;
    }
    m[(2, 3)] = 1.0;
    check_exp_norm(&m)?;
    let e = m.exp();
    let mut phi = [[0.0; 2]; 2];
    let (mut g0, mut g1) = ([0.0; 2], [0.0; 2]);
    for i in 0..2 {
        for j in 0..2 {
            phi[i][j] = e[(i, j)];
        }
        let ga = e[(i, 2)];
        let gl = e[(i, 3)];
        g1[i] = gl;
        g0[i] = ga - gl;
    }
    if !e.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFiniteModel);
    }
    // At rest on u0: s = [u0, 0] (the filters have unit DC gain).
    let s = [[u0[0], 0.0], [u0[1], 0.0], [u0[2], 0.0]];
    Ok(ShapeFilter::Lin {
        phi,
        g0,
        g1,
        s,
        u_prev: u0,
    })
}

// ---------------------------------------------------------------------------------------------
// The engine.

/// Loop state of the engine. The arrays that are indexed at run time live behind boxes (made
/// once per simulation), so that the scalars and $z$ can stay in registers.
#[derive(Clone)]
pub(crate) struct RState<const N: usize> {
    z: [f64; N],
    integ: f64,
    e1: f64,
    xr1: f64,
    /// Filtered velocity-path position at the previous two ticks.
    xf1: f64,
    xf2: f64,
    delay: Box<DelayLine>,
    /// Maxwell-slip element deflections, axis units.
    ms: Box<[f64; MAX_ELEMENTS]>,
    /// Their force $\sum k_i d_i$, N·m, and tangent stiffness (elements between their slip
    /// bounds), N·m per axis unit.
    ms_force: f64,
    ms_stiffness: f64,
    /// All elements slipping at +level (1), at −level (−1), or not (0); the level, N·m. While
    /// all slip, `ms` is stale: the deflections are ±level · $w_i$.
    ms_sat: i8,
    ms_level: f64,
}

/// What one tick produced (for logging and frequency responses).
#[derive(Clone, Copy, Debug)]
pub(crate) struct TickOut {
    /// Control (after the limit), V.
    pub u: f64,
    /// Limited this tick.
    pub saturated: bool,
    /// Reading the position loop used (after the dead time), axis units.
    pub xp: f64,
    /// Command applied to the plant (with the injection), V.
    pub u_in: f64,
}

/// Constants of the loop of a drive with effects.
///
/// `N` states; `TM`: two-mass layout `[x_m, v_m, x_L, v_L, current...]`, else rigid
/// `[x, v, current...]`. Both are compile-time so that the state lives in registers.
#[derive(Clone)]
pub(crate) struct Engine<L, const N: usize, const TM: bool> {
    law: L,
    /// Current-loop states (0, 1, 2).
    n_cur: usize,
    /// In contact (or no backlash).
    lin: Lin<N>,
    /// In the backlash gap (no spring).
    gap: Lin<N>,
    half_backlash: f64,
    fric: Fric,
    /// Friction acts on the motor of a two-mass drive (else on the load).
    fric_motor: bool,
    u_lim: f64,
    k_int: f64,
    /// Law slopes (see [`RLaw::slopes`]).
    s_dp: f64,
    s_df: f64,
    s_ip: f64,
    s_if: f64,
    /// Slopes of $u$ (unsaturated): in $\hat x_p$, and in the raw velocity reading $\hat x_v$
    /// through the filter, $(s_{df} + K_I s_{if})(1 - a)$; their sum when both readings are one.
    gu_p: f64,
    /// Slopes of $u$ in the two readings of the tick that enter it undelayed.
    ga: f64,
    gb: f64,
    /// Velocity filter: $x_f = a\,x_{f1} + b\,\hat x_v$ ($a = 0$, $b = 1$ without a filter).
    vf_a: f64,
    vf_b: f64,
    /// The position and velocity readings are the same undelayed number.
    one_reading: bool,
    load_source: bool,
    second_encoder: bool,
    dead_time: usize,
    ka_kt: f64,
    /// Tangent stiffness of the Maxwell-slip elements at rest (all sticking), N·m per axis unit.
    ms_rest_stiffness: f64,
}

impl<L: RLaw, const N: usize, const TM: bool> Engine<L, N, TM> {
    /// Index of the load position and velocity in $z$ (the motor's are 0 and 1).
    const XL: usize = if TM { 2 } else { 0 };
    const VL: usize = if TM { 3 } else { 1 };
    /// Index of the current loop's output.
    const ICUR: usize = if TM { 4 } else { 2 };

    /// The state at rest at position `x0` with readings `xm0`.
    pub(crate) fn rest(&self, x0: f64, xm0: f64) -> RState<N> {
        let mut z = [0.0; N];
        z[0] = x0;
        z[Self::XL] = x0;
        RState {
            z,
            integ: 0.0,
            e1: x0 - xm0,
            xr1: x0,
            xf1: xm0,
            xf2: xm0,
            delay: Box::new(DelayLine::new(self.dead_time, xm0)),
            ms: Box::new([0.0; MAX_ELEMENTS]),
            ms_force: 0.0,
            ms_stiffness: self.ms_rest_stiffness,
            ms_sat: 0,
            ms_level: 0.0,
        }
    }

    /// The noise of this tick's position and motor-encoder readings (`tick`'s `noise`), drawn
    /// from their streams in the order the ticks read them.
    #[inline(always)]
    pub(crate) fn draw_noise(
        &self,
        pos_reader: &mut Reader,
        motor_reader: &mut Reader,
    ) -> (f64, f64) {
        let np = pos_reader.noise();
        let nm = if self.second_encoder {
            motor_reader.noise()
        } else {
            0.0
        };
        (np, nm)
    }

    /// One servo tick with loop reference `r` (already shaped), extra command `inject` (V,
    /// added after the limit: a torque excitation), the readers and the noise of their readings
    /// ([`Engine::draw_noise`]).
    #[inline(always)]
    pub(crate) fn tick(
        &self,
        st: &mut RState<N>,
        r: RefSample,
        inject: f64,
        pos_reader: &Reader,
        motor_reader: &Reader,
        noise: (f64, f64),
    ) -> TickOut {
        // Everything that does not depend on this tick's readings first.
        let (d0, i0) = self.law.terms0(r, st.xr1, st.e1, st.xf1, st.xf2);
        let af = self.vf_a * st.xf1;
        let direct_a = d0 + self.s_df * af;
        let integ_a = st.integ + i0 + self.s_if * af;
        let u_a = direct_a + self.k_int * integ_a;
        // Readings.
        let x_sensor = if self.load_source {
            st.z[Self::XL]
        } else {
            st.z[0]
        };
        let reading = pos_reader.read(x_sensor, noise.0);
        // u = ub + ga xa + gb xb with xa, xb the readings of this tick (0 when unused) and ub
        // the rest: the plant folds ga, gb into its coefficients (see `plant_step`).
        let (xp, xv, ub, xa, xb) = if self.one_reading {
            (reading, reading, u_a, reading, 0.0)
        } else if self.second_encoder {
            let xv = motor_reader.read(st.z[0], noise.1);
            if self.dead_time == 0 {
                (reading, xv, u_a, reading, xv)
            } else {
                let xp = st.delay.push(reading);
                (xp, xv, u_a + self.gu_p * xp, 0.0, xv)
            }
        } else {
            let xp = st.delay.push(reading);
            (xp, reading, u_a + self.gu_p * xp, 0.0, reading)
        };
        // The part of u that this tick's readings make, computed once and fed to the plant.
        let w = self.ga * xa + self.gb * xb;
        let u = ub + w;
        let xf = af + self.vf_b * xv;
        let d_int = i0 + self.s_ip * xp + self.s_if * xf;
        let saturated = u.abs() > self.u_lim;
        let (u, ub, w) = if !saturated {
            st.integ += d_int;
            (u, ub, w)
        } else {
            // Conditional integration: hold the integrator if its increment pushes u further
            // into the limit.
            let direct = d0 + self.s_dp * xp + self.s_df * xf;
            let mut u = u;
            if self.k_int * d_int * u > 0.0 {
                u = direct + self.k_int * st.integ;
            } else {
                st.integ += d_int;
            }
            let u = u.clamp(-self.u_lim, self.u_lim);
            (u, u, 0.0)
        };
        st.e1 = r.xr - xp;
        st.xr1 = r.xr;
        st.xf2 = st.xf1;
        st.xf1 = xf;
        let u_in = u + inject;
        let ub = ub + inject;
        if TM && !self.fric_motor {
            self.plant_step::<2, 3>(st, ub, w);
        } else {
            self.plant_step::<0, 1>(st, ub, w);
        }
        TickOut {
            u,
            saturated,
            xp,
            u_in,
        }
    }

    /// Load position, axis units.
    pub(crate) fn load_position(&self, st: &RState<N>) -> f64 {
        st.z[Self::XL]
    }

    /// Load velocity, axis units/s.
    pub(crate) fn load_velocity(&self, st: &RState<N>) -> f64 {
        st.z[Self::VL]
    }

    /// Motor velocity, axis units/s.
    pub(crate) fn motor_velocity(&self, st: &RState<N>) -> f64 {
        st.z[1]
    }

    /// The mechanical and current-loop state $z$.
    pub(crate) fn state(&self, st: &RState<N>) -> [f64; N] {
        st.z
    }

    /// Motor torque at the start of a tick whose command is `u_in`, N·m: $K_aK_t u$, or the
    /// current loop's output (read before the tick).
    #[inline(always)]
    pub(crate) fn torque(&self, z: &[f64; N], u_in: f64) -> f64 {
        if self.n_cur == 0 {
            self.ka_kt * u_in
        } else {
            self.ka_kt * z[Self::ICUR.min(N - 1)]
        }
    }

    /// The plant over one tick under the held command $u = u_b + w$, $w$ the part of $u$ that
    /// the tick's readings make (module docs, step 4). Written so that every new state is
    /// (terms known before the readings) + (coefficient) × $w$: the free response
    /// $P = \Phi z + \Gamma_o o + \Gamma_u u_b$ and the friction's own terms are computed while
    /// the encoder is read, as in [`crate::sim`] (an algebraic rearrangement, not an
    /// approximation).
    ///
    /// `IX`, `IV`: index of the friction body's position and velocity in $z$.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // small dense kernel on z, p and Γ: indices read best
    fn plant_step<const IX: usize, const IV: usize>(&self, st: &mut RState<N>, ub: f64, w: f64) {
        let (lin, o) = if self.half_backlash > 0.0 {
            let d = st.z[0] - st.z[2];
            if d >= self.half_backlash {
                (&self.lin, self.half_backlash)
            } else if d <= -self.half_backlash {
                (&self.lin, -self.half_backlash)
            } else {
                (&self.gap, 0.0)
            }
        } else {
            (&self.lin, 0.0)
        };
        let z = st.z;
        // Φ z with the positions entering only through the transmission's deflection
        // d = x_m - x_L (two-mass) or not at all (rigid): A (e_0 + e_L) = 0, so
        // Φ (e_0 + e_L) = e_0 + e_L exactly and Φ z = Φ_0 d + (e_0 + e_L) x_L + Σ_{j ≠ 0, L} Φ_j z_j.
        // Fewer products, and the large absolute position only passes through one addition.
        let d = if TM { z[0] - z[Self::XL] } else { 0.0 };
        let mut p = [0.0; N];
        // The current loop's states do not depend on the mechanics: their rows skip them.
        for i in 0..N {
            let mut acc = lin.g_u[i] * ub;
            if self.half_backlash > 0.0 {
                acc += lin.g_o[i] * o;
            }
            let mech_row = i < Self::ICUR;
            if TM && mech_row {
                acc += lin.phi[i][0] * d;
            }
            for j in 1..N {
                if !(TM && j == Self::XL) && (mech_row || j >= Self::ICUR) {
                    acc += lin.phi[i][j] * z[j];
                }
            }
            if i == 0 || i == Self::XL {
                acc += z[Self::XL];
            }
            p[i] = acc;
        }
        match &self.fric {
            Fric::None => {
                for i in 0..N {
                    st.z[i] = p[i] + lin.g_u[i] * w;
                }
            }
            Fric::SetValued(law) => {
                // The sliding level either way, from the speed the step starts with (the
                // static level when the step reverses the motion): known before the readings.
                let v0 = z[IV];
                let (f_pos, f_neg) = if law.static_ == law.coulomb {
                    (law.coulomb[0], -law.coulomb[1])
                } else {
                    (law.level(0, v0.max(0.0)), -law.level(1, (-v0).max(0.0)))
                };
                let v_star = p[IV] + lin.g_u[IV] * w;
                if v_star <= lin.stick_lim[0] && v_star >= -lin.stick_lim[1] {
                    // Stuck at the end of the step (|v*| within g T_s): the friction is
                    // whatever stops the body, f = v*/g, so z = z* + Γ_f v*/g.
                    for i in 0..N {
                        st.z[i] = (p[i] + lin.stick_k[i] * p[IV]) + lin.stick_gu[i] * w;
                    }
                    st.z[IV] = 0.0;
                } else {
                    let f = if v_star > 0.0 { f_pos } else { f_neg };
                    for i in 0..N {
                        st.z[i] = (p[i] + lin.g_f[i] * f) + lin.g_u[i] * w;
                    }
                }
            }
            Fric::Maxwell {
                law,
                n,
                k,
                w: wk,
                w_max,
                w_min,
                v_flat,
            } => {
                let (n, w_max, w_min) = (*n, *w_max, *w_min);
                let x0 = z[IX];
                // Trapezoidal rule on the elements' force: the end force is predicted with
                // their tangent stiffness K (elements between their slip bounds) from the
                // position x* the step reaches under the initial force f0:
                // f = f0 + K/2 (x* + Γ_f,x f0 - x0), linear in w through x*.
                let (f0, half_k) = (st.ms_force, 0.5 * st.ms_stiffness);
                if half_k == 0.0 {
                    for i in 0..N {
                        st.z[i] = (p[i] + lin.g_f[i] * f0) + lin.g_u[i] * w;
                    }
                } else {
                    let f_p = (1.0 + half_k * lin.g_f[IX]) * f0 + half_k * (p[IX] - x0);
                    let f_w = half_k * lin.g_u[IX];
                    for i in 0..N {
                        let c = lin.g_f[i];
                        st.z[i] = (p[i] + c * f_p) + (lin.g_u[i] + c * f_w) * w;
                    }
                }
                // Slip levels: T(v) in the direction of motion, T_s against it (element i slips
                // at ±level · w_i, w_i = 1/(N k_i)).
                let v0 = z[IV];
                let level = |dir: usize, speed: f64| {
                    if speed > *v_flat {
                        law.coulomb[dir]
                    } else {
                        law.level(dir, speed)
                    }
                };
                let (hi, lo) = if v0 >= 0.0 {
                    (level(0, v0), law.static_[1])
                } else {
                    (law.static_[0], level(1, -v0))
                };
                let dx = st.z[IX] - x0;
                // Fast path of steady sliding: every element slipping the same way stays so
                // (d_i + dx beyond the new bound for every i); their deflections are then
                // level · w_i, kept implicit.
                let stays = |new: f64, dx: f64| {
                    let dl = new - st.ms_level;
                    dx >= dl * if dl >= 0.0 { w_max } else { w_min }
                };
                if st.ms_sat > 0 && stays(hi, dx) {
                    st.ms_level = hi;
                    st.ms_force = hi;
                    st.ms_stiffness = 0.0;
                } else if st.ms_sat < 0 && stays(lo, -dx) {
                    st.ms_level = lo;
                    st.ms_force = -lo;
                    st.ms_stiffness = 0.0;
                } else {
                    if st.ms_sat != 0 {
                        let d = st.ms_sat as f64 * st.ms_level;
                        for i in 0..n {
                            st.ms[i] = d * wk[i];
                        }
                    }
                    let (mut force, mut stiffness) = (0.0, 0.0);
                    let (mut at_hi, mut at_lo) = (0, 0);
                    for i in 0..n {
                        let (lo_i, hi_i) = (-lo * wk[i], hi * wk[i]);
                        let d = (st.ms[i] + dx).clamp(lo_i, hi_i);
                        st.ms[i] = d;
                        force += k[i] * d;
                        let (above, below) = (d > lo_i, d < hi_i);
                        if above && below {
                            stiffness += k[i];
                        }
                        at_hi += !below as usize;
                        at_lo += !above as usize;
                    }
                    let (sat, level) = if at_hi == n {
                        (1, hi)
                    } else if at_lo == n {
                        (-1, lo)
                    } else {
                        (0, 0.0)
                    };
                    st.ms_sat = sat;
                    st.ms_level = level;
                    st.ms_force = force;
                    st.ms_stiffness = stiffness;
                }
            }
        }
    }

    /// Runs `refs.len()` consecutive ticks (`refs` the nominal references, shaped here when the
    /// drive shapes them) and logs the last one: the ticks from the previous logged sample up
    /// to and including the first tick of the next sample. Returns the saturated ticks.
    ///
    /// `noise` holds the noise of this block's readings, drawn before; the noise of the next
    /// block's `noise.next_len` readings is drawn during this block's ticks, one tick's draws
    /// per tick (the generator's work fills the gaps of the tick's dependency chain instead of
    /// running apart), the rest after them, and becomes `noise`'s current block. Each reader's
    /// stream is drawn in tick order, as the ticks read it.
    #[allow(clippy::too_many_arguments)] // the loop's parts, kept apart for the registers
    #[inline(always)]
    fn run_block(
        &self,
        st: &mut RState<N>,
        shaper: &mut Shaper,
        shaped: bool,
        readers: &mut (Reader, Reader),
        refs: &mut [RefSample],
        noise: &mut BlockNoise,
        log: &mut impl SampleLog,
    ) -> u64 {
        let ticks = refs.len();
        if shaped {
            shaper.shape_block(refs);
        }
        let (pr, mr) = (&mut readers.0, &mut readers.1);
        let n_next = noise.next_len;
        // Only noisy readers draw; a quiet one's buffer stays 0 (its noise).
        let (draw_p, draw_m) = (pr.noisy(), self.second_encoder && mr.noisy());
        let (cur_p, cur_m) = (&noise.cur.0[..ticks], &noise.cur.1[..ticks]);
        let (next_p, next_m) = (&mut noise.next.0[..n_next], &mut noise.next.1[..n_next]);
        let mut saturated_ticks = 0u64;
        let last = ticks - 1;
        // Ticks with a draw for the next block each, then the rest (the block's last tick is
        // logged apart).
        let paired = last.min(n_next);
        let drawn = next_p[..paired].iter_mut().zip(&mut next_m[..paired]);
        let ticked = refs[..paired]
            .iter()
            .zip(&cur_p[..paired])
            .zip(&cur_m[..paired]);
        for (((r, np), nm), (dp, dm)) in ticked.zip(drawn) {
            let out = self.tick(st, *r, 0.0, pr, mr, (*np, *nm));
            saturated_ticks += out.saturated as u64;
            if draw_p {
                *dp = pr.draw();
            }
            if draw_m {
                *dm = mr.draw();
            }
        }
        let ticked = refs[paired..last]
            .iter()
            .zip(&cur_p[paired..last])
            .zip(&cur_m[paired..last]);
        for ((r, np), nm) in ticked {
            let out = self.tick(st, *r, 0.0, pr, mr, (*np, *nm));
            saturated_ticks += out.saturated as u64;
        }
        let (xl, vl, xm) = (st.z[Self::XL], st.z[Self::VL], st.z[0]);
        let z_before = st.z;
        let out = self.tick(st, refs[last], 0.0, pr, mr, (cur_p[last], cur_m[last]));
        saturated_ticks += out.saturated as u64;
        log.log(Logged {
            position: out.xp,
            true_position: xl,
            velocity: vl,
            control: out.u,
            motor_position: xm,
            motor_torque: self.torque(&z_before, out.u_in),
        });
        for (dp, dm) in next_p[paired..].iter_mut().zip(&mut next_m[paired..]) {
            if draw_p {
                *dp = pr.draw();
            }
            if draw_m {
                *dm = mr.draw();
            }
        }
        std::mem::swap(&mut noise.cur, &mut noise.next);
        saturated_ticks
    }

    /// Linearised state as a vector: $z$, integrator, $e_1$, $x_{f1}$, $x_{f2}$, the pending
    /// dead-time readings.
    fn pack(&self, st: &RState<N>) -> Vec<f64> {
        let mut v: Vec<f64> = st.z.to_vec();
        v.extend([st.integ, st.e1, st.xf1, st.xf2]);
        v.extend(st.delay.pending());
        v
    }

    fn unpack(&self, v: &[f64]) -> RState<N> {
        let mut st = self.rest(0.0, 0.0);
        st.z.copy_from_slice(&v[..N]);
        st.integ = v[N];
        st.e1 = v[N + 1];
        st.xf1 = v[N + 2];
        st.xf2 = v[N + 3];
        st.delay.set_pending(&v[N + 4..]);
        st
    }

    /// Transition matrix of the linearised loop (the engine must be built linear: no friction,
    /// no backlash, ideal readers), from the tick itself on unit states.
    fn transition_matrix(&self) -> DMatrix<f64> {
        let dim = N + 4 + self.dead_time;
        let mut m = DMatrix::<f64>::zeros(dim, dim);
        let zero = RefSample {
            xr: 0.0,
            vr: 0.0,
            ar: 0.0,
        };
        let pr = Reader::new(0.0, 0.0, 0, 0);
        let mr = Reader::new(0.0, 0.0, 0, 1);
        for col in 0..dim {
            let mut unit = vec![0.0; dim];
            unit[col] = 1.0;
            let mut st = self.unpack(&unit);
            self.tick(&mut st, zero, 0.0, &pr, &mr, (0.0, 0.0));
            for (row, x) in self.pack(&st).iter().enumerate() {
                m[(row, col)] = *x;
            }
        }
        m
    }
}

/// Which engine variant to build.
#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Build {
    /// The drive as it is.
    Full,
    /// Linearised at rest: no friction (viscous kept), backlash closed, no saturation.
    Linear,
}

/// A job run on the monomorphised engine.
pub(crate) trait Job {
    type Out;
    fn run<L: RLaw, const N: usize, const TM: bool>(self, engine: &Engine<L, N, TM>) -> Self::Out;
}

/// Builds the engine of `drive` at servo period `h` and runs `job` on it.
pub(crate) fn with_engine<J: Job>(
    drive: &Drive,
    h: f64,
    build: Build,
    job: J,
) -> Result<J::Out, Error> {
    match *drive.controller() {
        Controller::PPi(g) => dispatch_n(drive, h, build, PPiR::new(drive, g, h), job),
        Controller::Pid(g) => dispatch_n(drive, h, build, PidR::new(drive, g, h), job),
        Controller::Smc(g) => dispatch_n(drive, h, build, SmcR::new(g, h), job),
    }
}

/// Acceleration and velocity feed-forward gains $(J_{ff}J/(r_gK_aK_t), B_{ff}B/(r_gK_aK_t))$.
fn feed_forward(drive: &Drive, jff: f64, bff: f64) -> (f64, f64) {
    let plant = drive.plant();
    let (j, b, rg, k) = (plant.j, plant.b, plant.rg, plant.ka_kt());
    (jff * j / (rg * k), bff * b / (rg * k))
}

impl PPiR {
    /// The law with gains `g` at servo period `h`.
    fn new(drive: &Drive, g: PPiGains, h: f64) -> PPiR {
        let PPiGains {
            kv,
            kp,
            ki,
            vff,
            bff,
            jff,
        } = g;
        let rg = drive.plant().rg;
        let (ff_a, ff_v) = feed_forward(drive, jff, bff);
        PPiR {
            kp,
            ki,
            kv,
            vff_over_rg: vff / rg,
            inv_rg: 1.0 / rg,
            half_h_kv: 0.5 * h * kv,
            inv_2h: 0.5 / h,
            ff_a,
            ff_v,
        }
    }
}

impl PidR {
    /// The law with gains `g` at servo period `h`.
    fn new(drive: &Drive, g: PidGains, h: f64) -> PidR {
        let PidGains {
            kp,
            ki,
            kd,
            jff,
            bff,
        } = g;
        let (ff_a, ff_v) = feed_forward(drive, jff, bff);
        PidR {
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

impl SmcR {
    /// The law with gains `g` at servo period `h`.
    fn new(g: SmcGains, h: f64) -> SmcR {
        let SmcGains {
            lambda,
            ks,
            rho,
            je_hat,
            be_hat,
        } = g;
        SmcR {
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

fn layout(e: &Effects) -> Layout {
    let two_mass = e.compliance.is_some();
    let i_cur = if two_mass { 4 } else { 2 };
    let n_cur = match e.current {
        None => 0,
        Some(c) => match c.order {
            CurrentLoopOrder::FirstOrder => 1,
            CurrentLoopOrder::SecondOrder => 2,
        },
    };
    Layout {
        two_mass,
        i_cur,
        n_cur,
    }
}

fn dispatch_n<L: RLaw, J: Job>(
    drive: &Drive,
    h: f64,
    build: Build,
    law: L,
    job: J,
) -> Result<J::Out, Error> {
    let lay = layout(drive.effects());
    Ok(match (lay.two_mass, lay.n()) {
        (false, 2) => job.run(&engine::<L, 2, false>(drive, h, build, law, lay)?),
        (false, 3) => job.run(&engine::<L, 3, false>(drive, h, build, law, lay)?),
        (false, _) => job.run(&engine::<L, 4, false>(drive, h, build, law, lay)?),
        (true, 4) => job.run(&engine::<L, 4, true>(drive, h, build, law, lay)?),
        (true, 5) => job.run(&engine::<L, 5, true>(drive, h, build, law, lay)?),
        (true, _) => job.run(&engine::<L, 6, true>(drive, h, build, law, lay)?),
    })
}

fn engine<L: RLaw, const N: usize, const TM: bool>(
    drive: &Drive,
    h: f64,
    build: Build,
    law: L,
    lay: Layout,
) -> Result<Engine<L, N, TM>, Error> {
    let plant = drive.plant();
    let e = drive.effects();
    let linear = build == Build::Linear;
    // Friction: the table's law, else the plant's symmetric Coulomb friction.
    let law_f = e.friction.or_else(|| {
        (plant.coulomb_torque > 0.0).then_some(FrictionLaw {
            kind: FrictionKind::SetValued,
            coulomb: [plant.coulomb_torque; 2],
            static_: [plant.coulomb_torque; 2],
            stribeck_velocity: 1.0,
            exponent: 2.0,
            location: FrictionLocation::Load,
        })
    });
    let on_load = law_f.is_none_or(|f| f.location == FrictionLocation::Load);
    let i_fv = if on_load { lay.vl() } else { lay.vm() };
    let fric = match (law_f, linear) {
        (_, true) | (None, _) => Fric::None,
        (Some(f), false) => match f.kind {
            FrictionKind::SetValued => Fric::SetValued(f),
            FrictionKind::MaxwellSlip {
                elements,
                presliding_displacement,
            } => {
                let k = maxwell_slip_stiffness(
                    f.coulomb[0].max(f.coulomb[1]),
                    elements,
                    presliding_displacement,
                );
                let mut w = [0.0; MAX_ELEMENTS];
                for (wi, k) in w.iter_mut().zip(&k).take(elements) {
                    *wi = 1.0 / (elements as f64 * k);
                }
                let w_max = w[..elements].iter().fold(0.0, |m: f64, v| m.max(*v));
                let w_min = w[..elements]
                    .iter()
                    .fold(f64::INFINITY, |m: f64, v| m.min(*v));
                Fric::Maxwell {
                    law: f,
                    n: elements,
                    k,
                    w,
                    w_max,
                    w_min,
                    v_flat: flat_speed(&f),
                }
            }
        },
    };
    let (a, b) = continuous(plant, e, lay, on_load, true);
    let mut lin = discretise::<N>(&a, &b, h, i_fv, lay.i_cur)?;
    let (a_gap, b_gap) = continuous(plant, e, lay, on_load, false);
    let mut gap = discretise::<N>(&a_gap, &b_gap, h, i_fv, lay.i_cur)?;
    let half_backlash = match (e.compliance, linear) {
        (Some(c), false) => 0.5 * c.backlash,
        _ => 0.0,
    };
    let u_lim = if linear {
        f64::INFINITY
    } else {
        let from_torque = e.torque_max.map_or(f64::INFINITY, |t| t / plant.ka_kt());
        plant.u_max.unwrap_or(f64::INFINITY).min(from_torque)
    };
    let fb = e.feedback;
    let vf_a = fb
        .and_then(|f| f.velocity_filter_hz)
        .map_or(0.0, |fc| (-std::f64::consts::TAU * fc * h).exp());
    let load_source = fb.is_none_or(|f| f.source == FeedbackSource::Load);
    let second_encoder = lay.two_mass && load_source;
    let dead_time = fb.map_or(0, |f| f.dead_time_cycles as usize);
    let [s_dp, s_df, s_ip, s_if] = law.slopes();
    let k_int = law.k_int();
    let vf_b = 1.0 - vf_a;
    let gu_p = s_dp + k_int * s_ip;
    let gu_v = (s_df + k_int * s_if) * vf_b;
    let one_reading = dead_time == 0 && !second_encoder;
    // Which readings enter u undelayed (see `Engine::tick`).
    let (ga, gb) = if one_reading {
        (gu_p + gu_v, 0.0)
    } else if second_encoder && dead_time == 0 {
        (gu_p, gu_v)
    } else {
        (0.0, gu_v)
    };
    if let Fric::SetValued(f) = &fric {
        for l in [&mut lin, &mut gap] {
            l.stick_lim = [l.g * f.static_[0], l.g * f.static_[1]];
        }
    }
    Ok(Engine {
        law,
        n_cur: lay.n_cur,
        lin,
        gap,
        half_backlash,
        fric,
        fric_motor: lay.two_mass && !on_load,
        u_lim,
        k_int,
        s_dp,
        s_df,
        s_ip,
        s_if,
        gu_p,
        ga,
        gb,
        vf_a,
        vf_b,
        one_reading,
        load_source,
        second_encoder,
        dead_time,
        ka_kt: plant.ka_kt(),
        ms_rest_stiffness: match &fric {
            Fric::Maxwell { k, .. } => k.iter().sum(),
            _ => 0.0,
        },
    })
}

/// Position and motor-encoder readers of `drive` (ideal ones when `ideal`).
pub(crate) fn readers(drive: &Drive, ideal: bool) -> (Reader, Reader) {
    let enc = drive.encoder();
    if ideal {
        return (Reader::new(0.0, 0.0, 0, 0), Reader::new(0.0, 0.0, 0, 1));
    }
    let (mq, mstd) = match drive.effects().feedback {
        Some(f) => (f.motor_resolution, f.motor_noise_std),
        None => (enc.resolution, 0.0),
    };
    (
        Reader::new(enc.resolution, enc.noise_std, enc.seed, 0),
        Reader::new(mq, mstd, enc.seed, 1),
    )
}

/// A drive with effects as a stream ([`crate::DriveStream`]), over the monomorphised engine.
pub(crate) trait EffectsFeed: Send {
    /// Runs the next samples (checked by the caller; empty only after the first) and logs the
    /// channels asked for into `out`.
    fn feed(
        &mut self,
        piece: Reference<'_>,
        channels: Channels,
        out: &mut DriveTrace,
    ) -> Result<(), Error>;
    /// Servo ticks saturated so far.
    fn saturated_ticks(&self) -> u64;
}

/// The loop of a drive with effects between pieces of the reference: the engine (constants),
/// the readers (their noise streams), and, after the first sample, the loop state, the
/// reference shaper and the last sample.
struct EffectsStream<L, const N: usize, const TM: bool> {
    engine: Engine<L, N, TM>,
    h: f64,
    n_sub: usize,
    shaping: Option<crate::effects::Shaping>,
    readers: (Reader, Reader),
    run: Option<Running<N>>,
    saturated_ticks: u64,
    /// Work buffer of one block of ticks: references.
    refs: Vec<RefSample>,
    /// The readings' noise of the next block, drawn ahead (after the first sample).
    noise: BlockNoise,
}

/// Position and motor-reading noise of a block of ticks (`cur`, drawn) and of the next one
/// (`next`, `next_len` readings, being drawn): see [`Engine::run_block`].
struct BlockNoise {
    cur: (Vec<f64>, Vec<f64>),
    next: (Vec<f64>, Vec<f64>),
    next_len: usize,
}

/// The state a stream carries from one sample to the next.
struct Running<const N: usize> {
    st: RState<N>,
    shaper: Shaper,
    /// The last sample fed (unshaped).
    prev: RefSample,
}

impl<L: RLaw, const N: usize, const TM: bool> EffectsStream<L, N, TM> {
    /// Runs the next samples, as [`crate::sim`]'s loop does (module docs of [`crate::sim`],
    /// "Timing"): each new sample $k$ is one block of ticks, the ticks $1 \ldots n_{sub} - 1$
    /// of sample $k - 1$ (interpolating towards sample $k$) and tick 0 of sample $k$, logged;
    /// the first sample is the block of its tick 0 alone, from rest.
    fn feed_to(&mut self, piece: Reference<'_>, log: &mut impl SampleLog) -> Result<(), Error> {
        let (pos, vel, acc) = (piece.pos, piece.vel, piece.acc);
        let n = pos.len();
        let sample = |k: usize| RefSample {
            xr: pos[k],
            vr: vel[k],
            ar: acc[k],
        };
        let e = &self.engine;
        let shaped = self.shaping.is_some();
        let mut saturated_ticks = 0u64;
        let mut k0 = 0;
        let mut running = match self.run.take() {
            Some(r) => r,
            None => {
                if n == 0 {
                    return Ok(());
                }
                let r0 = sample(0);
                let xm0 = self.readers.0.quantise(r0.xr);
                let mut running = Running {
                    st: e.rest(r0.xr, xm0),
                    shaper: Shaper::new(self.shaping, self.h, r0)?,
                    prev: r0,
                };
                self.refs[0] = r0;
                // The first block's one reading; the next blocks' are drawn ahead.
                self.noise.cur.0[0] = self.readers.0.noise();
                if e.second_encoder {
                    self.noise.cur.1[0] = self.readers.1.noise();
                }
                saturated_ticks += e.run_block(
                    &mut running.st,
                    &mut running.shaper,
                    shaped,
                    &mut self.readers,
                    &mut self.refs[..1],
                    &mut self.noise,
                    log,
                );
                k0 = 1;
                running
            }
        };
        let n_sub = self.n_sub;
        let inv_sub = 1.0 / n_sub as f64;
        for k in k0..n {
            let r = sample(k);
            let p = running.prev;
            let (dp, dv, da) = (r.xr - p.xr, r.vr - p.vr, r.ar - p.ar);
            for (j, rj) in self.refs[..n_sub - 1].iter_mut().enumerate() {
                let w = (j + 1) as f64 * inv_sub;
                *rj = RefSample {
                    xr: p.xr + w * dp,
                    vr: p.vr + w * dv,
                    ar: p.ar + w * da,
                };
            }
            self.refs[n_sub - 1] = r;
            saturated_ticks += e.run_block(
                &mut running.st,
                &mut running.shaper,
                shaped,
                &mut self.readers,
                &mut self.refs,
                &mut self.noise,
                log,
            );
            running.prev = r;
        }
        self.run = Some(running);
        self.saturated_ticks += saturated_ticks;
        Ok(())
    }
}

impl<L: RLaw, const N: usize, const TM: bool> EffectsFeed for EffectsStream<L, N, TM> {
    fn feed(
        &mut self,
        piece: Reference<'_>,
        channels: Channels,
        out: &mut DriveTrace,
    ) -> Result<(), Error> {
        match channels {
            Channels::All => self.feed_to(piece, &mut AllChannels(out)),
            Channels::TruePosition => {
                self.feed_to(piece, &mut TruePositionOnly(&mut out.true_position))
            }
        }
    }

    fn saturated_ticks(&self) -> u64 {
        self.saturated_ticks
    }
}

/// The stream of a drive with effects at `n_sub` ticks of `h` a sample, before its first
/// sample.
pub(crate) fn effects_stream(
    drive: &Drive,
    n_sub: usize,
    h: f64,
) -> Result<Box<dyn EffectsFeed>, Error> {
    struct Make {
        n_sub: usize,
        h: f64,
        shaping: Option<crate::effects::Shaping>,
        readers: (Reader, Reader),
    }
    impl Job for Make {
        type Out = Box<dyn EffectsFeed>;
        fn run<L: RLaw, const N: usize, const TM: bool>(self, e: &Engine<L, N, TM>) -> Self::Out {
            let r0 = RefSample {
                xr: 0.0,
                vr: 0.0,
                ar: 0.0,
            };
            Box::new(EffectsStream {
                engine: e.clone(),
                h: self.h,
                n_sub: self.n_sub,
                shaping: self.shaping,
                readers: self.readers,
                run: None,
                saturated_ticks: 0,
                refs: vec![r0; self.n_sub],
                noise: BlockNoise {
                    cur: (vec![0.0; self.n_sub], vec![0.0; self.n_sub]),
                    next: (vec![0.0; self.n_sub], vec![0.0; self.n_sub]),
                    next_len: self.n_sub,
                },
            })
        }
    }
    with_engine(
        drive,
        h,
        Build::Full,
        Make {
            n_sub,
            h,
            shaping: drive.effects().shaping,
            readers: readers(drive, false),
        },
    )
}

/// What the drives of one batch ([`lanes`]) must share: the loop's structure. The numbers
/// (gains, masses, levels, limits, delays, noise) may differ.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Structure {
    law: &'static str,
    n: usize,
    two_mass: bool,
    n_cur: usize,
    /// 0 none, 1 set-valued, 2 Maxwell-slip.
    fric: u8,
    fric_motor: bool,
    one_reading: bool,
    load_source: bool,
    second_encoder: bool,
    delayed: bool,
}

impl<L: RLaw, const N: usize, const TM: bool> Engine<L, N, TM> {
    fn structure(&self) -> Structure {
        Structure {
            law: std::any::type_name::<L>(),
            n: N,
            two_mass: TM,
            n_cur: self.n_cur,
            fric: match self.fric {
                Fric::None => 0,
                Fric::SetValued(_) => 1,
                Fric::Maxwell { .. } => 2,
            },
            fric_motor: self.fric_motor,
            one_reading: self.one_reading,
            load_source: self.load_source,
            second_encoder: self.second_encoder,
            delayed: self.dead_time > 0,
        }
    }
}

/// The loop structure of a drive with effects at servo period `h`.
pub(crate) fn structure(drive: &Drive, h: f64) -> Result<Structure, Error> {
    struct S;
    impl Job for S {
        type Out = Structure;
        fn run<L: RLaw, const N: usize, const TM: bool>(self, e: &Engine<L, N, TM>) -> Structure {
            e.structure()
        }
    }
    with_engine(drive, h, Build::Full, S)
}

/// Simulates drives with effects (at most [`LANES`], references of the same length,
/// `n_sub` ticks of `h` per sample) in one loop, one drive per lane, into `traces` (one per
/// drive, prepared as [`Drive::simulate_into`] prepares it). `Ok(false)`, with nothing
/// simulated, when the drives do not share a [`Structure`] or the processor has no lanes
/// (not x86-64 with AVX2).
#[cfg(not(target_arch = "x86_64"))]
pub(crate) fn simulate_lanes(
    _drives: &[&Drive],
    _references: &[Reference<'_>],
    _n_sub: usize,
    _h: f64,
    _traces: &mut [&mut DriveTrace],
) -> Result<bool, Error> {
    Ok(false)
}

/// See the other target's `simulate_lanes`: drives with effects in one loop.
#[cfg(target_arch = "x86_64")]
pub(crate) fn simulate_lanes(
    drives: &[&Drive],
    references: &[Reference<'_>],
    n_sub: usize,
    h: f64,
    traces: &mut [&mut DriveTrace],
) -> Result<bool, Error> {
    struct J<'a, 'r, 't> {
        drives: &'a [&'a Drive],
        references: &'a [Reference<'r>],
        n_sub: usize,
        h: f64,
        traces: &'a mut [&'t mut DriveTrace],
    }
    impl Job for J<'_, '_, '_> {
        type Out = Result<bool, Error>;
        fn run<L: RLaw, const N: usize, const TM: bool>(self, e0: &Engine<L, N, TM>) -> Self::Out {
            let (drives, h) = (self.drives, self.h);
            let lay0 = layout(drives[0].effects());
            let mut others = Vec::with_capacity(drives.len() - 1);
            for d in &drives[1..] {
                let lay = layout(d.effects());
                let Some(law) = L::of(d, h) else {
                    return Ok(false);
                };
                if (lay.two_mass, lay.n_cur) != (lay0.two_mass, lay0.n_cur) {
                    return Ok(false);
                }
                let e = engine::<L, N, TM>(d, h, Build::Full, law, lay)?;
                if e.structure() != e0.structure() {
                    return Ok(false);
                }
                others.push(e);
            }
            let engines: Vec<&Engine<L, N, TM>> = std::iter::once(e0).chain(&others).collect();
            let pick = |l: usize| l.min(drives.len() - 1);
            let mut inputs: [lanes::LaneInput<'_>; LANES] = std::array::from_fn(|l| {
                let d = drives[pick(l)];
                lanes::LaneInput {
                    reference: self.references[pick(l)],
                    shaping: d.effects().shaping,
                    readers: readers(d, false),
                }
            });
            let lane_engines = std::array::from_fn(|l| engines[pick(l)]);
            let laws = std::array::from_fn(|l| engines[pick(l)].law);
            let lane_readers = std::array::from_fn(|l| &inputs[l].readers);
            let ef = lanes::EngineF::of(lane_engines, L::lanes(&laws), lane_readers);
            // The drives' own traces; lanes beyond the drives (repeating the last one) log
            // into spare traces that are dropped.
            let mut spare: Vec<DriveTrace> = (self.traces.len()..LANES)
                .map(|_| {
                    let t = &self.traces[self.traces.len() - 1];
                    DriveTrace::with_capacity(t.ts, t.position.capacity())
                })
                .collect();
            let lane_traces: Vec<&mut DriveTrace> = self
                .traces
                .iter_mut()
                .map(|t| &mut **t)
                .chain(spare.iter_mut())
                .collect();
            let Ok(mut lane_traces) = <[&mut DriveTrace; LANES]>::try_from(lane_traces) else {
                unreachable!("at most LANES drives, checked before the loop is built")
            };
            lanes::run_batch(&ef, &mut inputs, self.n_sub, h, &mut lane_traces)?;
            Ok(true)
        }
    }
    if drives.is_empty()
        || drives.len() > LANES
        || references.len() != drives.len()
        || !lanes::available()
    {
        return Ok(false);
    }
    with_engine(
        drives[0],
        h,
        Build::Full,
        J {
            drives,
            references,
            n_sub,
            h,
            traces,
        },
    )?
}

impl Drive {
    /// Transition matrix $M$ of the loop with its effects at the servo rate, linearised at rest
    /// (friction off except viscous, backlash closed, ideal encoders, no limit, zero
    /// reference): $z_{k+1} = M z_k$ with $z$ = mechanical and current-loop states, integrator,
    /// previous position error, the two previous filtered velocity-path positions, and the
    /// readings pending in the dead-time line. Built column by column from the simulator's own
    /// tick. For an ideal drive it is the matrix of the effects engine, not of
    /// [`Drive::sampled_transition_matrix`] (same eigenvalues up to the state basis).
    pub fn effects_transition_matrix(&self) -> Result<DMatrix<f64>, Error> {
        struct T;
        impl Job for T {
            type Out = DMatrix<f64>;
            fn run<L: RLaw, const N: usize, const TM: bool>(
                self,
                e: &Engine<L, N, TM>,
            ) -> Self::Out {
                e.transition_matrix()
            }
        }
        with_engine(self, 1.0 / self.servo_rate_hz(), Build::Linear, T)
    }
}

/// Rejects a drive whose effects destabilise the loop linearised at rest.
pub(crate) fn check_effects_stability(drive: &Drive) -> Result<(), Error> {
    let m = drive.effects_transition_matrix()?;
    if !m.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFiniteModel);
    }
    let h = 1.0 / drive.servo_rate_hz();
    let eig: Vec<Complex<f64>> = m
        .try_schur(1e-15, 10_000)
        .ok_or(Error::NonFiniteModel)?
        .complex_eigenvalues()
        .iter()
        .copied()
        .collect();
    let worst = eig
        .iter()
        .copied()
        .max_by(|a, b| a.norm().total_cmp(&b.norm()))
        .unwrap_or(Complex::new(0.0, 0.0));
    let radius = worst.norm();
    if radius > 1.0 + 1e-9 {
        let s = worst.ln() / h;
        return Err(Error::EffectsUnstable {
            servo_rate_hz: drive.servo_rate_hz(),
            radius,
            mode_hz: s.im.abs() / std::f64::consts::TAU,
            growth_per_s: s.re,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::{CurrentDynamics, Shaping, bandwidth_factor};
    use crate::presets::table1_drive;

    /// The current-loop block of the discretised linear part, driven by a unit step of the
    /// command from rest: its output at every tick.
    #[allow(clippy::needless_range_loop)] // 4×4 matrix-vector product
    fn current_step(order: CurrentLoopOrder, bw_hz: f64, zeta: f64, h: f64, n: usize) -> Vec<f64> {
        let plant = table1_drive().plant;
        let w = match order {
            CurrentLoopOrder::FirstOrder => TAU_LOCAL * bw_hz,
            CurrentLoopOrder::SecondOrder => TAU_LOCAL * bw_hz / bandwidth_factor(zeta),
        };
        let e = Effects {
            current: Some(CurrentDynamics { order, w, zeta }),
            ..Effects::default()
        };
        let lay = layout(&e);
        let (a, b) = continuous(&plant, &e, lay, true, true);
        let lin = discretise::<4>(&a, &b, h, lay.vl(), lay.i_cur).unwrap();
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

    const TAU_LOCAL: f64 = std::f64::consts::TAU;

    #[test]
    fn current_loop_step_response_has_its_time_constant() {
        // Truth: the step response of 1/(1 + s/wc), 1 - exp(-t/tau), tau = 1/(2 pi f_bw); and of
        // wn²/(s² + 2 zeta wn s + wn²), 1 - exp(-zeta wn t)(cos wd t + zeta/sqrt(1-zeta²) sin wd t),
        // whose -3 dB frequency is f_bw (checked on the continuous transfer function). A step
        // held over each tick is exactly what the zero-order-hold discretisation assumes, so the
        // ticks must agree to rounding.
        let h = 5e-5;
        let bw = 1500.0;
        let tau = 1.0 / (TAU_LOCAL * bw);
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
            let wn = TAU_LOCAL * bw / bandwidth_factor(zeta);
            let g = |w: f64| {
                let s = Complex::new(0.0, w);
                (wn * wn / (s * s + 2.0 * zeta * wn * s + wn * wn)).norm()
            };
            assert!((g(TAU_LOCAL * bw) - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
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

    /// The shaper's position output for a nominal position that ramps from 0 to 1 over one
    /// tick (a step, as the fine interpolation sees it) starting at tick 5.
    fn shaped_step(filter: ShapingFilter, h: f64, n: usize) -> Vec<f64> {
        let r = |x: f64| RefSample {
            xr: x,
            vr: 0.0,
            ar: 0.0,
        };
        let mut s = Shaper::new(
            Some(Shaping {
                filter: Some(filter),
                delay_ticks: 0,
            }),
            h,
            r(0.0),
        )
        .unwrap();
        (0..n)
            .map(|k| s.shape(r(if k >= 6 { 1.0 } else { 0.0 })).xr)
            .collect()
    }

    #[test]
    fn reference_filters_follow_their_analytic_step_responses() {
        // Truth: the continuous filters' responses to the input the servo loop sees, a ramp
        // from 0 to 1 over one tick h starting at t0 = 5h (the fine interpolation is linear
        // between ticks), in closed form: with S the filter's ramp response (integral of its
        // step response), y(t) = (S(t - t0) - S(t - t0 - h)) / h.
        let h = 5e-5;
        let t0 = 5.0 * h;
        let check = |filter, s_ramp: &dyn Fn(f64) -> f64, what: &str| {
            let y = shaped_step(filter, h, 2000);
            for (k, yk) in y.iter().enumerate() {
                let t = k as f64 * h - t0;
                let s = |t: f64| if t <= 0.0 { 0.0 } else { s_ramp(t) };
                let exact = (s(t) - s(t - h)) / h;
                // 1e-10 of the step: the closed forms themselves lose ~1e-12 to cancellation.
                assert!(
                    (yk - exact).abs() < 1e-10,
                    "{what}, tick {k}: {yk} vs {exact}"
                );
            }
        };
        let tf = 2e-3;
        check(
            ShapingFilter::FirstOrder {
                time_constant_s: tf,
            },
            &|t| t - tf * (1.0 - (-t / tf).exp()),
            "first order",
        );
        // Critically damped second order: step 1 - e^{-t/T}(1 + t/T), ramp
        // t - 2T + e^{-t/T}(2T + t).
        check(
            ShapingFilter::SecondOrder {
                time_constant_s: tf,
                zeta: 1.0,
            },
            &|t| t - 2.0 * tf + (-t / tf).exp() * (2.0 * tf + t),
            "second order, zeta 1",
        );
        // Underdamped: ramp response t - 2 zeta/wn + e^{-zeta wn t}(2 zeta/wn cos wd t
        // + (2 zeta² - 1)/wd sin wd t).
        let (zeta, wn) = (0.4, 1.0 / tf);
        let wd = wn * (1.0f64 - zeta * zeta).sqrt();
        check(
            ShapingFilter::SecondOrder {
                time_constant_s: tf,
                zeta,
            },
            &|t| {
                t - 2.0 * zeta / wn
                    + (-zeta * wn * t).exp()
                        * (2.0 * zeta / wn * (wd * t).cos()
                            + (2.0 * zeta * zeta - 1.0) / wd * (wd * t).sin())
            },
            "second order, zeta 0.4",
        );
        // Moving average over Tw: y(t) = (U(t) - U(t - Tw)) / Tw with U the input's integral;
        // for the unit ramp-step, S(t) = (Sr(t) - Sr(t - Tw)) / Tw with Sr(t) = t²/2.
        let tw = 80.0 * h;
        let sr = |t: f64| if t <= 0.0 { 0.0 } else { 0.5 * t * t };
        check(
            ShapingFilter::MovingAverage { window_s: tw },
            &|t| (sr(t) - sr(t - tw)) / tw,
            "moving average",
        );
    }
}
