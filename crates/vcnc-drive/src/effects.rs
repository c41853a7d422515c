//! The dynamics real feed drives have beyond the rigid plant: mechanical compliance and backlash,
//! Stribeck and pre-sliding friction, the current loop and torque limit, feedback delay, filters
//! and noise, and the control's reference shaping (docs/machine-file.md#drive-effects).
//!
//! Each effect is an optional machine-file table of the axis; an absent table is today's ideal
//! behaviour, bit for bit (the simulator then runs the unmodified rigid-plant loop). Two levels,
//! as for the rest of [`crate::params`]:
//!
//! - raw, as written: [`Compliance`], [`Friction`], [`CurrentLoop`], [`Feedback`],
//!   [`ReferenceShaping`] (every key documented with its unit, default and range);
//! - checked: [`Effects`], built by [`Effects::check`] against the plant, encoder and servo rate
//!   (alternatives resolved, e.g. `mode_hz` into a stiffness; defaults that depend on the plant
//!   filled in; delays turned into whole servo ticks).
//!
//! Symbols follow docs/machine-file.md#drive-effects: $J_m, J_L$ motor- and load-side inertia, $k, c$ transmission
//! stiffness and damping, $b$ backlash, $T_c, T_s, v_s, \delta$ Coulomb and static friction,
//! Stribeck velocity and exponent.

use std::f64::consts::TAU;

use serde::{Deserialize, Serialize};

use crate::Error;
use crate::lane::{LANES, Lane};
use crate::params::{Encoder, Plant};

/// Two-mass transmission between motor and load (docs/machine-file.md#compliance), in the plant's motor-side units:
///
/// $$ J_m\ddot\theta_m = T_m - T_k - B_m\dot\theta_m,\qquad J_L\ddot\theta_L = T_k - B_L\dot\theta_L - T_f, $$
/// $$ T_k = k\,\mathrm{dz}_b(\theta_m - \theta_L) + c\,(\dot\theta_m - \dot\theta_L)\ [\text{in contact}], $$
///
/// with the dead zone $\mathrm{dz}_b$ of the backlash. `plant.j` stays the total inertia
/// $J_m + J_L$ (what the controller design and feed-forward use); viscous friction `plant.b`
/// and the friction table act on the body named by the friction's `location` (default: load).
///
/// ```toml
/// [axes.X.compliance]
/// j_motor = 0.006      # kg m², the rest of plant.j is the load
/// mode_hz = 120.0      # or stiffness = ... (N m/rad)
/// mode_zeta = 0.05     # or damping = ... (N m s/rad)
/// backlash = 0.0       # axis units
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Compliance {
    /// Motor-side inertia $J_m$ (rotor, coupling, screw share), kg·m², reflected to the motor
    /// like `plant.j`. Required; $0 < J_m <$ `plant.j`; the load is $J_L$ = `plant.j` $- J_m$.
    pub j_motor: f64,
    /// Transmission stiffness $k$ at the motor, N·m/rad (an axial screw stiffness $k_{ax}$ in N/m
    /// gives $k = k_{ax} r_g^2$ with $r_g$ in m/rad). Give this or `mode_hz`. Positive.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
    /// Instead of `stiffness`: the first mode (resonance of the free two-mass system),
    /// $f_r = \frac{1}{2\pi}\sqrt{k (J_m + J_L)/(J_m J_L)}$, Hz. Positive, at most half the servo
    /// rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mode_hz: Option<f64>,
    /// Transmission damping $c$, N·m·s/rad. Give this or `mode_zeta`. Non-negative.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<f64>,
    /// Instead of `damping`: the first mode's damping ratio
    /// $\zeta_r = c / (2\omega_r J_m J_L/(J_m + J_L))$, dimensionless, in [0, 1].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mode_zeta: Option<f64>,
    /// Backlash (lost motion), the total width $2b$ of the transmission's dead zone, axis units
    /// (mm or deg). Default 0; non-negative.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub backlash: f64,
}

/// Where friction (and the plant's viscous friction $B$) acts in a two-mass drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FrictionLocation {
    /// On the load (guideways, nut): the default.
    #[default]
    Load,
    /// On the motor side (bearings, seals).
    Motor,
}

/// Friction beyond the plant's symmetric Coulomb torque (docs/machine-file.md#friction). The positive-direction
/// Coulomb level is always `plant.coulomb_torque` $T_c$; viscous friction is `plant.b`. Sliding
/// friction (torque opposing the velocity $v$, in axis units/s) follows the Stribeck law
///
/// $$ F(v) = \operatorname{sgn}(v)\Big[T_c^\pm + (T_s^\pm - T_c^\pm)\,e^{-|v/v_s|^{\delta}}\Big], $$
///
/// $\pm$ by the direction of motion; at rest the friction holds any torque up to $T_s^\pm$
/// (true sticking).
///
/// ```toml
/// [axes.X.friction]
/// model = "stribeck"           # or "coulomb", "maxwell-slip"
/// static_torque = 0.40          # N m
/// stribeck_velocity = 2.0       # mm/s (axis units/s)
/// coulomb_torque_negative = 0.28
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Friction {
    /// Set-valued Coulomb friction with direction-dependent levels (static = Coulomb).
    Coulomb {
        /// Coulomb level in the negative direction $T_c^-$, N·m. Default $T_c$; non-negative.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        coulomb_torque_negative: Option<f64>,
        /// Body the friction acts on (two-mass drives). Default `"load"`.
        #[serde(default, skip_serializing_if = "is_default")]
        location: FrictionLocation,
    },
    /// Set-valued static friction $T_s$ and the Stribeck curve in sliding.
    Stribeck {
        /// Static (breakaway) level $T_s^+$, N·m. Required; at least $T_c$.
        static_torque: f64,
        /// Stribeck velocity $v_s$, axis units/s. Required; positive.
        stribeck_velocity: f64,
        /// Stribeck exponent $\delta$, dimensionless. Default 2 (Gaussian); in [0.5, 4].
        #[serde(default = "default_exponent", skip_serializing_if = "is_two")]
        stribeck_exponent: f64,
        /// $T_c^-$, N·m. Default $T_c$; non-negative.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        coulomb_torque_negative: Option<f64>,
        /// $T_s^-$, N·m. Default: $T_c^-\, T_s^+/T_c$ (same ratio as the positive side, or
        /// $T_s^+$ when $T_c = 0$); at least $T_c^-$.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        static_torque_negative: Option<f64>,
        /// Body the friction acts on (two-mass drives). Default `"load"`.
        #[serde(default, skip_serializing_if = "is_default")]
        location: FrictionLocation,
    },
    /// Pre-sliding friction as a Maxwell-slip model: `elements` elasto-plastic elements in
    /// parallel (spring in series with a slider), whose slip levels follow the Stribeck law, so
    /// the steady sliding friction is exactly $F(v)$ and small motions are elastic with
    /// hysteresis (docs/machine-file.md#friction).
    MaxwellSlip {
        /// Pre-sliding displacement $x_{ps}$, axis units: the virgin curve reaches $T_c$ after
        /// this much motion (typically 1–5 µm on guideways). Required; positive.
        presliding_displacement: f64,
        /// Number of elements $N$. Default 4; 1 to 16.
        #[serde(default = "default_elements", skip_serializing_if = "is_four")]
        elements: usize,
        /// $T_s^+$, N·m. Default $T_c$ (no Stribeck dip); at least $T_c$.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        static_torque: Option<f64>,
        /// $v_s$, axis units/s. Required when a static level above Coulomb is given; positive.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        stribeck_velocity: Option<f64>,
        /// $\delta$. Default 2; in [0.5, 4].
        #[serde(default = "default_exponent", skip_serializing_if = "is_two")]
        stribeck_exponent: f64,
        /// $T_c^-$, N·m. Default $T_c$.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        coulomb_torque_negative: Option<f64>,
        /// $T_s^-$, N·m. Default as for `stribeck`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        static_torque_negative: Option<f64>,
        /// Body the friction acts on (two-mass drives). Default `"load"`.
        #[serde(default, skip_serializing_if = "is_default")]
        location: FrictionLocation,
    },
}

/// Order of the current (torque) loop's closed-loop response.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CurrentLoopOrder {
    /// $T/T^* = 1/(1 + s/\omega_c)$, $\omega_c = 2\pi f_{bw}$. The default.
    #[default]
    FirstOrder,
    /// $T/T^* = \omega_n^2/(s^2 + 2\zeta\omega_n s + \omega_n^2)$, $\omega_n$ such that the
    /// −3 dB bandwidth is $f_{bw}$.
    SecondOrder,
}

/// The amplifier's current loop and torque limit (docs/machine-file.md#current_loop). The controller output $u$
/// commands the torque $T^* = K_aK_t u$; the motor receives $T$, the current loop's response to
/// $T^*$, after the limit $|T^*| \le T_{max}$.
///
/// ```toml
/// [axes.X.current_loop]
/// order = "first-order"   # or "second-order" (then zeta, default 0.7071)
/// bandwidth_hz = 1500.0
/// torque_max = 12.0        # N m
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CurrentLoop {
    /// Response order. Default `"first-order"`.
    #[serde(default, skip_serializing_if = "is_default")]
    pub order: CurrentLoopOrder,
    /// −3 dB bandwidth $f_{bw}$, Hz. Default: none (the current follows instantly). Positive,
    /// at most half the servo rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bandwidth_hz: Option<f64>,
    /// Damping ratio of a second-order loop, dimensionless. Default $1/\sqrt2$; in (0, 2]. Only
    /// with `order = "second-order"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zeta: Option<f64>,
    /// Peak motor torque $T_{max}$, N·m: the torque command is limited to $\pm T_{max}$ (with
    /// the same conditional-integration anti-windup as `plant.u_max`). Default: none. Positive.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torque_max: Option<f64>,
}

/// Which sensor closes the position loop in a two-mass drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FeedbackSource {
    /// A linear scale (or table encoder) on the load: closed loop. The default. The velocity
    /// loop still uses the motor encoder.
    #[default]
    Load,
    /// The motor encoder: semi-closed loop (position and velocity from the motor).
    Motor,
}

/// Feedback path of the loop (docs/machine-file.md#feedback): sensor, position-loop dead time, velocity filter.
/// The position encoder (`encoder`: quantisation, noise, seed) reads the `source`; in a
/// closed-loop two-mass drive the velocity comes from a second, motor encoder.
///
/// ```toml
/// [axes.X.feedback]
/// source = "load"            # or "motor"
/// dead_time_cycles = 1       # servo cycles
/// velocity_filter_hz = 1500.0
/// ```
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Feedback {
    /// Position sensor. Default `"load"` (for a rigid drive load and motor are the same).
    #[serde(default, skip_serializing_if = "is_default")]
    pub source: FeedbackSource,
    /// Position-loop dead time, whole servo cycles: the position loop at tick $k$ uses the
    /// reading of tick $k - n$ (fieldbus, sampling). Default 0; at most
    /// [`MAX_DEAD_TIME_CYCLES`].
    #[serde(default, skip_serializing_if = "is_zero_u32")]
    pub dead_time_cycles: u32,
    /// Cut-off of the first-order low-pass on the velocity feedback, Hz. Default: none.
    /// Positive, below half the servo rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_filter_hz: Option<f64>,
    /// Quantisation of the motor encoder that measures velocity in a closed-loop two-mass drive,
    /// axis units. Default: `encoder.resolution`. Non-negative. Only with `[compliance]` and
    /// `source = "load"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motor_resolution: Option<f64>,
    /// Noise standard deviation of that motor encoder, axis units. Default 0. Non-negative.
    /// Only with `[compliance]` and `source = "load"`.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub motor_noise_std: f64,
}

/// The control's nominal-position filter.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ShapingFilter {
    /// $1/(1 + T s)$.
    FirstOrder {
        /// Time constant $T$, s. Positive, at most 1.
        time_constant_s: f64,
    },
    /// $1/(T^2 s^2 + 2\zeta T s + 1)$.
    SecondOrder {
        /// Time constant $T = 1/\omega_n$, s. Positive, at most 1.
        time_constant_s: f64,
        /// Damping ratio $\zeta$. Default 1 (critically damped: no overshoot); in (0, 2].
        #[serde(default = "default_one")]
        zeta: f64,
    },
    /// Moving average over a window $T_w$ (a CNC's "jerk filter"): $(1 - e^{-T_w s})/(T_w s)$.
    MovingAverage {
        /// Window $T_w$, s: a whole number (≥ 1) of servo periods, at most 1 s.
        window_s: f64,
    },
    /// Band-stop, second order over second order with unit static gain:
    /// $\frac{\omega_d^2}{\omega_z^2}\,\frac{s^2 + 2\zeta_z\omega_z s + \omega_z^2}{s^2 + 2\zeta_d\omega_d s + \omega_d^2}$,
    /// $\omega_z = 2\pi f_z$, $\omega_d = 2\pi f_d$. With $f_d = f_z$ its gain at the blocking
    /// frequency is $\zeta_z/\zeta_d$; a lower (higher) $f_d$ lowers (raises) the gain above the
    /// band to $(f_d/f_z)^2$.
    BandStop {
        /// Blocking (numerator) frequency $f_z$, Hz: at least 0.1, at most a quarter of the rate
        /// the filter runs at.
        frequency_hz: f64,
        /// Numerator damping $\zeta_z$ (notch depth: 0 blocks $f_z$ entirely); in
        /// $[0, \zeta_d]$.
        zeta_numerator: f64,
        /// Denominator damping $\zeta_d$ (width); in (0, 2].
        zeta_denominator: f64,
        /// Denominator frequency $f_d$, Hz. Default $f_z$; the same range.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        denominator_frequency_hz: Option<f64>,
    },
}

/// Reference shaping between the logged nominal position and the position loop (docs/machine-file.md#reference).
/// The trace's reference (what a control's scope records as nominal position) is the unshaped
/// one; the loop sees it delayed by `interpolation_delay_s` and filtered by `filter` (position,
/// velocity and acceleration feed-forward alike).
///
/// ```toml
/// [axes.X.reference]
/// filter = { kind = "moving-average", window_s = 0.004 }
/// interpolation_delay_s = 0.002
/// ```
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceShaping {
    /// Nominal-position filter. Default: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub filter: Option<ShapingFilter>,
    /// Delay between the logged nominal position and the loop, s: a whole number of servo
    /// periods. Default 0; at most 1 s.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub interpolation_delay_s: f64,
}

/// Largest position-loop dead time, servo cycles.
pub const MAX_DEAD_TIME_CYCLES: u32 = 100;
/// Largest number of Maxwell-slip elements.
pub const MAX_ELEMENTS: usize = 16;

fn default_exponent() -> f64 {
    2.0
}
fn default_elements() -> usize {
    4
}
fn default_one() -> f64 {
    1.0
}
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}
fn is_zero_u32(v: &u32) -> bool {
    *v == 0
}
fn is_two(v: &f64) -> bool {
    *v == 2.0
}
fn is_four(v: &usize) -> bool {
    *v == 4
}
fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

// ---------------------------------------------------------------------------------------------
// Checked forms.

/// A checked two-mass transmission, in the plant's motor-side units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoMass {
    /// $J_m$, kg·m².
    pub j_motor: f64,
    /// $J_L$, kg·m².
    pub j_load: f64,
    /// $k$, N·m/rad.
    pub stiffness: f64,
    /// $c$, N·m·s/rad.
    pub damping: f64,
    /// Total backlash $2b$, axis units.
    pub backlash: f64,
}

impl TwoMass {
    /// Resonance of the free two-mass system, $\omega_r = \sqrt{k(J_m + J_L)/(J_m J_L)}$, Hz:
    /// the peak of the motor-side admittance (docs/machine-file.md#compliance).
    pub fn resonance_hz(&self) -> f64 {
        (self.stiffness * (self.j_motor + self.j_load) / (self.j_motor * self.j_load)).sqrt() / TAU
    }

    /// Anti-resonance, $\omega_a = \sqrt{k/J_L}$, Hz: the load swinging against a locked motor,
    /// the dip of the motor-side admittance.
    pub fn antiresonance_hz(&self) -> f64 {
        (self.stiffness / self.j_load).sqrt() / TAU
    }

    /// Damping ratio of the resonance, $c/(2\omega_r J_m J_L/(J_m + J_L))$.
    pub fn zeta(&self) -> f64 {
        let jr = self.j_motor * self.j_load / (self.j_motor + self.j_load);
        self.damping / (2.0 * TAU * self.resonance_hz() * jr)
    }
}

/// How the friction is modelled (checked).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrictionKind {
    /// Set-valued Coulomb/static friction with the Stribeck law in sliding.
    SetValued,
    /// Maxwell-slip pre-sliding elements.
    MaxwellSlip {
        /// $N$.
        elements: usize,
        /// $x_{ps}$, axis units.
        presliding_displacement: f64,
    },
}

/// Checked friction: levels per direction (index 0 positive, 1 negative), N·m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrictionLaw {
    /// Model.
    pub kind: FrictionKind,
    /// $[T_c^+, T_c^-]$, N·m.
    pub coulomb: [f64; 2],
    /// $[T_s^+, T_s^-]$, N·m.
    pub static_: [f64; 2],
    /// $v_s$, axis units/s (1 when unused: $T_s = T_c$).
    pub stribeck_velocity: f64,
    /// $\delta$.
    pub exponent: f64,
    /// Body the friction acts on.
    pub location: FrictionLocation,
}

impl FrictionLaw {
    /// Sliding friction magnitude $T_c + (T_s - T_c)e^{-|v/v_s|^\delta}$ for motion in direction
    /// `dir` (0 positive, 1 negative) at speed `speed` ≥ 0, N·m: $T_s$ at rest; $T_c$ where
    /// $T_s = T_c$ or for $|v/v_s|^\delta > 40$; else the law (the engine's evaluation of it, for
    /// one drive).
    #[inline]
    pub fn level(&self, dir: usize, speed: f64) -> f64 {
        Stribeck::<f64>::of(|_| self, false).level(dir == 0, speed)
    }

    /// Whether any level depends on the speed.
    pub fn has_stribeck(&self) -> bool {
        self.static_ != self.coulomb
    }

    /// A speed above which [`FrictionLaw::level`] is the Coulomb level for certain:
    /// $v_s\,40^{1/\delta}$ with a relative margin of $10^{-9}$, far above the rounding of the
    /// power, so that beyond it the level takes its $|v/v_s|^\delta > 40$ branch (the same number
    /// as evaluating the law, with no division, power or exponential).
    pub(crate) fn flat_speed(&self) -> f64 {
        self.stribeck_velocity * 40f64.powf(1.0 / self.exponent) * (1.0 + 1e-9)
    }
}

/// The Stribeck levels of one [`FrictionLaw`] per lane ([`crate::lane`]): the law evaluated once
/// for every lane, each lane by the scalar law's operations.
#[derive(Clone, Copy)]
pub(crate) struct Stribeck<T: Lane> {
    /// $[T_c^+, T_c^-]$, $[T_s^+, T_s^-]$, N·m.
    pub(crate) coulomb: [T; 2],
    pub(crate) static_: [T; 2],
    /// $v_s$, axis units/s.
    vs: T,
    /// Exponent 2; exponent neither 1 nor 2 (libm's power, per lane), and whether any lane has
    /// such an exponent.
    exp2: T::Mask,
    exp_other: T::Mask,
    any_other: bool,
    exponent: [f64; LANES],
    /// Some level depends on the speed.
    stribeck: T::Mask,
    /// Speed beyond which the level is $T_c$ ([`FrictionLaw::flat_speed`], or $+\infty$).
    v_flat: T,
}

impl<T: Lane> Stribeck<T> {
    /// Lane `l`'s law is `law(l)`; `flat`: skip the law beyond [`FrictionLaw::flat_speed`].
    pub(crate) fn of<'a>(law: impl Fn(usize) -> &'a FrictionLaw, flat: bool) -> Stribeck<T> {
        let f = |g: &dyn Fn(&FrictionLaw) -> f64| T::from_fn(|l| g(law(l)));
        let m = |g: &dyn Fn(&FrictionLaw) -> bool| T::mask_from_fn(|l| g(law(l)));
        let other = |f: &FrictionLaw| f.exponent != 2.0 && f.exponent != 1.0;
        Stribeck {
            coulomb: [f(&|f| f.coulomb[0]), f(&|f| f.coulomb[1])],
            static_: [f(&|f| f.static_[0]), f(&|f| f.static_[1])],
            vs: f(&|f| f.stribeck_velocity),
            exp2: m(&|f| f.exponent == 2.0),
            exp_other: m(&other),
            any_other: (0..T::WIDTH).any(|l| other(law(l))),
            exponent: std::array::from_fn(|l| law(l.min(T::WIDTH - 1)).exponent),
            stribeck: m(&|f| f.has_stribeck()),
            v_flat: f(&|f| if flat { f.flat_speed() } else { f64::INFINITY }),
        }
    }

    /// Lane `l` is `lanes(l)`'s (for `l` below the lane width).
    pub(crate) fn gather(lanes: &dyn Fn(usize) -> Stribeck<f64>) -> Stribeck<T> {
        let f = |g: &dyn Fn(&Stribeck<f64>) -> f64| T::from_fn(|l| g(&lanes(l)));
        let m = |g: &dyn Fn(&Stribeck<f64>) -> bool| T::mask_from_fn(|l| g(&lanes(l)));
        Stribeck {
            coulomb: [f(&|s| s.coulomb[0]), f(&|s| s.coulomb[1])],
            static_: [f(&|s| s.static_[0]), f(&|s| s.static_[1])],
            vs: f(&|s| s.vs),
            exp2: m(&|s| s.exp2),
            exp_other: m(&|s| s.exp_other),
            any_other: (0..T::WIDTH).any(|l| lanes(l).any_other),
            exponent: std::array::from_fn(|l| lanes(l.min(T::WIDTH - 1)).exponent[0]),
            stribeck: m(&|s| s.stribeck),
            v_flat: f(&|s| s.v_flat),
        }
    }

    /// Whether some lane's level depends on the speed.
    #[inline(always)]
    pub(crate) fn any_stribeck(&self) -> bool {
        T::any(self.stribeck)
    }

    /// The sliding level for motion in the positive direction (lanes of `pos`) or the negative
    /// one at `speed` ≥ 0, N·m:
    ///
    /// $$ T(v) = T_c + (T_s - T_c)\,e^{-p},\qquad p = |v/v_s|^\delta, $$
    ///
    /// $T_s$ at rest; $T_c$ where $T_s = T_c$, beyond the flat speed, or for $p > 40$
    /// ($e^{-40}(T_s - T_c)$ is below the rounding of $T_c$); for $p < 10^{-4}$ the series to
    /// $p^3$, exact to rounding (next term $p^4/24 < 5 \cdot 10^{-18}$); else [`exp_neg`].
    #[inline(always)]
    pub(crate) fn level(&self, pos: T::Mask, speed: T) -> T {
        let tc = T::select(pos, self.coulomb[0], self.coulomb[1]);
        let flat = speed.gt(self.v_flat);
        if T::all(flat) {
            return tc;
        }
        let ts = T::select(pos, self.static_[0], self.static_[1]);
        let zero = T::splat(0.0);
        let at_rest = speed.eq(zero);
        let trivial = ts.eq(tc) | at_rest;
        let mut lev = T::select(trivial & !flat, T::select(at_rest, ts, tc), tc);
        let general = !flat & !trivial;
        if !T::any(general) {
            return lev;
        }
        let r = speed / self.vs;
        let mut p = T::select(self.exp2, r * r, r);
        if self.any_other {
            let other = general & self.exp_other;
            p = T::from_fn(|l| {
                if T::test(other, l) {
                    r.at(l).powf(self.exponent[l])
                } else {
                    p.at(l)
                }
            });
        }
        let (big, small) = (p.gt(T::splat(40.0)), p.lt(T::splat(1e-4)));
        let short = general & small;
        if T::any(short) {
            let one = T::splat(1.0);
            let series =
                tc + (ts - tc) * (one - p * (one - p * (T::splat(0.5) - p / T::splat(6.0))));
            lev = T::select(short, series, lev);
        }
        let mid = general & !(big | small);
        if T::any(mid) {
            lev = T::select(mid, tc + (ts - tc) * exp_neg(p), lev);
        }
        lev
    }
}

/// $e^{-p}$ for $0 \le p \le 700$, within 2 units in the last place, by the same IEEE operations
/// on every platform and in every lane (no libm): the friction level's exponential.
///
/// Cody–Waite reduction $-p = n \ln 2 + r$, $n = \mathrm{round}(-p/\ln 2)$, $|r| \lesssim
/// \ln 2 / 2$ ($\ln 2$ split in a high part with $n \ln 2_{hi}$ exact and a low part), then
/// $e^{-p} = 2^n \sum_{i=0}^{13} r^i/i!$ (the Taylor remainder $r^{14}/14! < 5\cdot10^{-18}$),
/// the sum in Estrin's order (short dependency chains), the scaling by $2^n$ exact.
#[inline(always)]
pub(crate) fn exp_neg<T: Lane>(p: T) -> T {
    use exp_neg_consts::{C, INV_LN2, LN2_HI, LN2_LO, ROUND};
    let x = -p;
    let t = x * T::splat(INV_LN2) + T::splat(ROUND);
    let n = t - T::splat(ROUND);
    let r = (x - n * T::splat(LN2_HI)) - n * T::splat(LN2_LO);
    let c = |i: usize| T::splat(C[i]);
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let q0 = c(0) + c(1) * r;
    let q1 = c(2) + c(3) * r;
    let q2 = c(4) + c(5) * r;
    let q3 = c(6) + c(7) * r;
    let q4 = c(8) + c(9) * r;
    let q5 = c(10) + c(11) * r;
    let q6 = c(12) + c(13) * r;
    let s0 = q0 + q1 * r2;
    let s1 = q2 + q3 * r2;
    let s2 = q4 + q5 * r2;
    let u0 = s0 + s1 * r4;
    let u1 = s2 + q6 * r4;
    let poly = u0 + u1 * r8;
    // n from the rounding constant's low bits: t = ROUND + n exactly.
    poly * T::pow2_of_rounded(t)
}

/// Constants of [`exp_neg`].
pub(crate) mod exp_neg_consts {
    /// $1/\ln 2$.
    pub(crate) const INV_LN2: f64 = std::f64::consts::LOG2_E;
    /// $1.5 \cdot 2^{52}$: adding it rounds to an integer (ties to even) in the low bits.
    pub(crate) const ROUND: f64 = 6_755_399_441_055_744.0;
    /// $\ln 2$ in two parts; the high part's low 21 bits are zero (fdlibm's split).
    pub(crate) const LN2_HI: f64 = 0.693_147_180_369_123_8;
    pub(crate) const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    /// $1/i!$, $i = 0 \dots 13$.
    pub(crate) const C: [f64; 14] = [
        1.0,
        1.0,
        1.0 / 2.0,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5_040.0,
        1.0 / 40_320.0,
        1.0 / 362_880.0,
        1.0 / 3_628_800.0,
        1.0 / 39_916_800.0,
        1.0 / 479_001_600.0,
        1.0 / 6_227_020_800.0,
    ];
}

/// Checked current loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurrentDynamics {
    /// Order.
    pub order: CurrentLoopOrder,
    /// $\omega_c$ (first order) or $\omega_n$ (second order), rad/s.
    pub w: f64,
    /// $\zeta$ (second order; 1 for first order, unused).
    pub zeta: f64,
}

/// Checked feedback path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedbackPath {
    /// Position sensor.
    pub source: FeedbackSource,
    /// Position-loop dead time, servo cycles.
    pub dead_time_cycles: u32,
    /// Velocity low-pass cut-off, Hz.
    pub velocity_filter_hz: Option<f64>,
    /// Motor encoder quantisation (closed-loop two-mass drives), axis units.
    pub motor_resolution: f64,
    /// Motor encoder noise, axis units.
    pub motor_noise_std: f64,
}

/// Checked reference shaping: delay and window in whole servo ticks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shaping {
    /// The filter as given (checked).
    pub filter: Option<ShapingFilter>,
    /// Interpolation delay, servo ticks.
    pub delay_ticks: usize,
}

/// Every effect of a checked drive. `Effects::default()` is the ideal drive.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Effects {
    /// Two-mass transmission (and backlash).
    pub compliance: Option<TwoMass>,
    /// Friction beyond symmetric Coulomb.
    pub friction: Option<FrictionLaw>,
    /// Current-loop dynamics.
    pub current: Option<CurrentDynamics>,
    /// Peak motor torque, N·m.
    pub torque_max: Option<f64>,
    /// Feedback path (`None`: encoder on the load, no delay, no filter).
    pub feedback: Option<FeedbackPath>,
    /// Reference shaping (`None`: none).
    pub shaping: Option<Shaping>,
}

/// The five raw effect tables, owned (see [`Effects::tables`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RawEffects {
    /// `compliance`.
    pub compliance: Option<Compliance>,
    /// `friction`.
    pub friction: Option<Friction>,
    /// `current_loop`.
    pub current_loop: Option<CurrentLoop>,
    /// `feedback`.
    pub feedback: Option<Feedback>,
    /// `reference`.
    pub reference: Option<ReferenceShaping>,
}

/// The raw effect tables of one axis, as [`crate::DriveParams`] holds them.
#[derive(Debug, Clone, Copy)]
pub struct EffectTables<'a> {
    /// `compliance`.
    pub compliance: Option<&'a Compliance>,
    /// `friction`.
    pub friction: Option<&'a Friction>,
    /// `current_loop`.
    pub current_loop: Option<&'a CurrentLoop>,
    /// `feedback`.
    pub feedback: Option<&'a Feedback>,
    /// `reference`.
    pub reference: Option<&'a ReferenceShaping>,
}

impl Effects {
    /// No effect: the rigid ideal drive.
    pub fn is_ideal(&self) -> bool {
        *self == Effects::default()
    }

    /// Checks the raw tables against the (valid) plant, encoder and servo rate. Errors name the
    /// key (`compliance.mode_hz`, ...) and the value. Tables that change nothing (e.g. an empty
    /// `[feedback]`) check into `None`, so the drive stays ideal.
    pub fn check(
        t: EffectTables<'_>,
        plant: &Plant,
        encoder: &Encoder,
        servo_rate_hz: f64,
    ) -> Result<Effects, Error> {
        let nyquist = 0.5 * servo_rate_hz;
        let compliance = t
            .compliance
            .map(|c| check_compliance(c, plant, nyquist))
            .transpose()?;
        let friction = t.friction.map(|f| check_friction(f, plant)).transpose()?;
        let (current, torque_max) = match t.current_loop {
            Some(c) => check_current(c, nyquist)?,
            None => (None, None),
        };
        let feedback = t
            .feedback
            .map(|f| check_feedback(f, compliance.is_some(), encoder, nyquist))
            .transpose()?
            .flatten();
        let shaping = t
            .reference
            .map(|r| check_shaping(r, servo_rate_hz))
            .transpose()?
            .flatten();
        let effects = Effects {
            compliance,
            friction,
            current,
            torque_max,
            feedback,
            shaping,
        };
        if let Some(f) = &effects.friction {
            check_presliding_rate(f, plant, effects.compliance.as_ref(), servo_rate_hz)?;
        }
        Ok(effects)
    }

    /// Back to raw tables (for writing a checked drive out): stiffness and damping rather than
    /// mode frequency and damping ratio; delays in seconds at `servo_rate_hz`.
    pub fn tables(&self, plant: &Plant, encoder: &Encoder, servo_rate_hz: f64) -> RawEffects {
        let compliance = self.compliance.map(|c| Compliance {
            j_motor: c.j_motor,
            stiffness: Some(c.stiffness),
            mode_hz: None,
            damping: Some(c.damping),
            mode_zeta: None,
            backlash: c.backlash,
        });
        let friction = self.friction.map(|f| {
            let neg = |v: f64, default: f64| (v != default).then_some(v);
            let tc = plant.coulomb_torque;
            match f.kind {
                FrictionKind::SetValued if !f.has_stribeck() => Friction::Coulomb {
                    coulomb_torque_negative: neg(f.coulomb[1], tc),
                    location: f.location,
                },
                FrictionKind::SetValued => Friction::Stribeck {
                    static_torque: f.static_[0],
                    stribeck_velocity: f.stribeck_velocity,
                    stribeck_exponent: f.exponent,
                    coulomb_torque_negative: Some(f.coulomb[1]),
                    static_torque_negative: Some(f.static_[1]),
                    location: f.location,
                },
                FrictionKind::MaxwellSlip {
                    elements,
                    presliding_displacement,
                } => Friction::MaxwellSlip {
                    presliding_displacement,
                    elements,
                    static_torque: Some(f.static_[0]),
                    stribeck_velocity: f.has_stribeck().then_some(f.stribeck_velocity),
                    stribeck_exponent: f.exponent,
                    coulomb_torque_negative: Some(f.coulomb[1]),
                    static_torque_negative: Some(f.static_[1]),
                    location: f.location,
                },
            }
        });
        let current_loop = (self.current.is_some() || self.torque_max.is_some()).then(|| {
            let c = self.current;
            CurrentLoop {
                order: c.map(|c| c.order).unwrap_or_default(),
                bandwidth_hz: c.map(|c| match c.order {
                    CurrentLoopOrder::FirstOrder => c.w / TAU,
                    CurrentLoopOrder::SecondOrder => c.w * bandwidth_factor(c.zeta) / TAU,
                }),
                zeta: c
                    .filter(|c| c.order == CurrentLoopOrder::SecondOrder)
                    .map(|c| c.zeta),
                torque_max: self.torque_max,
            }
        });
        let feedback = self.feedback.map(|f| Feedback {
            source: f.source,
            dead_time_cycles: f.dead_time_cycles,
            velocity_filter_hz: f.velocity_filter_hz,
            motor_resolution: (f.motor_resolution != encoder.resolution)
                .then_some(f.motor_resolution),
            motor_noise_std: f.motor_noise_std,
        });
        let reference = self.shaping.map(|s| ReferenceShaping {
            filter: s.filter,
            interpolation_delay_s: s.delay_ticks as f64 / servo_rate_hz,
        });
        RawEffects {
            compliance,
            friction,
            current_loop,
            feedback,
            reference,
        }
    }
}

/// $\omega_{bw}/\omega_n$ of $\omega_n^2/(s^2 + 2\zeta\omega_n s + \omega_n^2)$:
/// $\sqrt{1 - 2\zeta^2 + \sqrt{4\zeta^4 - 4\zeta^2 + 2}}$ (1 at $\zeta = 1/\sqrt2$).
pub fn bandwidth_factor(zeta: f64) -> f64 {
    let z2 = zeta * zeta;
    (1.0 - 2.0 * z2 + (4.0 * z2 * z2 - 4.0 * z2 + 2.0).sqrt()).sqrt()
}

fn bad(name: &'static str, value: f64, expected: &'static str) -> Error {
    Error::BadParameter {
        name,
        value,
        expected,
    }
}

fn positive(name: &'static str, v: f64) -> Result<f64, Error> {
    if v.is_finite() && v > 0.0 && (1e-12..=1e12).contains(&v) {
        Ok(v)
    } else {
        Err(bad(name, v, "positive, finite and between 1e-12 and 1e12"))
    }
}

fn non_negative(name: &'static str, v: f64) -> Result<f64, Error> {
    if v.is_finite() && v >= 0.0 && (v == 0.0 || (1e-12..=1e12).contains(&v)) {
        Ok(v)
    } else {
        Err(bad(
            name,
            v,
            "non-negative, finite and 0 or between 1e-12 and 1e12",
        ))
    }
}

fn one_of(
    name: &'static str,
    other: &'static str,
    a: Option<f64>,
    b: Option<f64>,
) -> Result<(), Error> {
    match (a, b) {
        (Some(_), Some(_)) => Err(Error::Alternatives {
            name,
            other,
            both: true,
        }),
        (None, None) => Err(Error::Alternatives {
            name,
            other,
            both: false,
        }),
        _ => Ok(()),
    }
}

fn check_compliance(c: &Compliance, plant: &Plant, nyquist: f64) -> Result<TwoMass, Error> {
    let jm = positive("compliance.j_motor", c.j_motor)?;
    if jm >= plant.j {
        return Err(bad(
            "compliance.j_motor",
            jm,
            "below plant.j (plant.j is the total inertia; the load gets plant.j - j_motor)",
        ));
    }
    let jl = plant.j - jm;
    let jr = jm * jl / (jm + jl);
    one_of(
        "compliance.stiffness",
        "compliance.mode_hz",
        c.stiffness,
        c.mode_hz,
    )?;
    one_of(
        "compliance.damping",
        "compliance.mode_zeta",
        c.damping,
        c.mode_zeta,
    )?;
    let stiffness = match (c.stiffness, c.mode_hz) {
        (Some(k), _) => positive("compliance.stiffness", k)?,
        (_, Some(f)) => {
            let f = positive("compliance.mode_hz", f)?;
            let w = TAU * f;
            w * w * jr
        }
        _ => unreachable!("one_of checked"),
    };
    let wr = (stiffness / jr).sqrt();
    if wr / TAU > nyquist {
        let (name, value) = match c.mode_hz {
            Some(f) => ("compliance.mode_hz", f),
            None => ("compliance.stiffness", stiffness),
        };
        return Err(bad(
            name,
            value,
            "such that the first mode lies below half the servo rate",
        ));
    }
    let damping = match (c.damping, c.mode_zeta) {
        (Some(d), _) => non_negative("compliance.damping", d)?,
        (_, Some(z)) => {
            if !(z.is_finite() && (0.0..=1.0).contains(&z)) {
                return Err(bad("compliance.mode_zeta", z, "in [0, 1]"));
            }
            2.0 * z * wr * jr
        }
        _ => unreachable!("one_of checked"),
    };
    let backlash = non_negative("compliance.backlash", c.backlash)?;
    Ok(TwoMass {
        j_motor: jm,
        j_load: jl,
        stiffness,
        damping,
        backlash,
    })
}

fn check_exponent(d: f64) -> Result<f64, Error> {
    if d.is_finite() && (0.5..=4.0).contains(&d) {
        Ok(d)
    } else {
        Err(bad("friction.stribeck_exponent", d, "in [0.5, 4]"))
    }
}

/// Negative-direction levels: `tc_neg` default $T_c$, `ts_neg` default $T_c^- T_s^+/T_c$.
fn negative_levels(
    plant: &Plant,
    ts_pos: f64,
    tc_neg: Option<f64>,
    ts_neg: Option<f64>,
) -> Result<[f64; 2], Error> {
    let tc = plant.coulomb_torque;
    let tcn = match tc_neg {
        Some(v) => non_negative("friction.coulomb_torque_negative", v)?,
        None => tc,
    };
    let tsn = match ts_neg {
        Some(v) => non_negative("friction.static_torque_negative", v)?,
        None if tc > 0.0 => tcn * ts_pos / tc,
        None => ts_pos.max(tcn),
    };
    if tsn < tcn {
        return Err(bad(
            "friction.static_torque_negative",
            tsn,
            "at least coulomb_torque_negative (the static level is the larger one)",
        ));
    }
    Ok([tcn, tsn])
}

fn check_friction(f: &Friction, plant: &Plant) -> Result<FrictionLaw, Error> {
    let tc = plant.coulomb_torque;
    let static_pos = |ts: Option<f64>| -> Result<f64, Error> {
        match ts {
            Some(v) => {
                let v = non_negative("friction.static_torque", v)?;
                if v < tc {
                    Err(bad(
                        "friction.static_torque",
                        v,
                        "at least plant.coulomb_torque (the static level is the larger one)",
                    ))
                } else {
                    Ok(v)
                }
            }
            None => Ok(tc),
        }
    };
    match *f {
        Friction::Coulomb {
            coulomb_torque_negative,
            location,
        } => {
            let [tcn, _] = negative_levels(plant, tc, coulomb_torque_negative, None)?;
            Ok(FrictionLaw {
                kind: FrictionKind::SetValued,
                coulomb: [tc, tcn],
                static_: [tc, tcn],
                stribeck_velocity: 1.0,
                exponent: 2.0,
                location,
            })
        }
        Friction::Stribeck {
            static_torque,
            stribeck_velocity,
            stribeck_exponent,
            coulomb_torque_negative,
            static_torque_negative,
            location,
        } => {
            let tsp = static_pos(Some(static_torque))?;
            let vs = positive("friction.stribeck_velocity", stribeck_velocity)?;
            let d = check_exponent(stribeck_exponent)?;
            let [tcn, tsn] =
                negative_levels(plant, tsp, coulomb_torque_negative, static_torque_negative)?;
            Ok(FrictionLaw {
                kind: FrictionKind::SetValued,
                coulomb: [tc, tcn],
                static_: [tsp, tsn],
                stribeck_velocity: vs,
                exponent: d,
                location,
            })
        }
        Friction::MaxwellSlip {
            presliding_displacement,
            elements,
            static_torque,
            stribeck_velocity,
            stribeck_exponent,
            coulomb_torque_negative,
            static_torque_negative,
            location,
        } => {
            let xps = positive("friction.presliding_displacement", presliding_displacement)?;
            if !(1..=MAX_ELEMENTS).contains(&elements) {
                return Err(bad("friction.elements", elements as f64, "from 1 to 16"));
            }
            let tsp = static_pos(static_torque)?;
            let d = check_exponent(stribeck_exponent)?;
            let [tcn, tsn] =
                negative_levels(plant, tsp, coulomb_torque_negative, static_torque_negative)?;
            let vs = match stribeck_velocity {
                Some(v) => positive("friction.stribeck_velocity", v)?,
                None if tsp != tc || tsn != tcn => {
                    return Err(Error::Alternatives {
                        name: "friction.stribeck_velocity",
                        other: "friction.static_torque",
                        both: false,
                    });
                }
                None => 1.0,
            };
            if tc.max(tcn) <= 0.0 {
                return Err(bad(
                    "plant.coulomb_torque",
                    tc,
                    "positive with model = \"maxwell-slip\" (the elements' stiffness is T_c / x_ps)",
                ));
            }
            Ok(FrictionLaw {
                kind: FrictionKind::MaxwellSlip {
                    elements,
                    presliding_displacement: xps,
                },
                coulomb: [tc, tcn],
                static_: [tsp, tsn],
                stribeck_velocity: vs,
                exponent: d,
                location,
            })
        }
    }
}

/// The Maxwell-slip elements are coupled explicitly (Heun) to the exact step; their stiffest
/// frequency $\sqrt{r_g K_0/J_\text{body}}$ must stay well below the servo rate.
fn check_presliding_rate(
    f: &FrictionLaw,
    plant: &Plant,
    tm: Option<&TwoMass>,
    servo_rate_hz: f64,
) -> Result<(), Error> {
    let FrictionKind::MaxwellSlip {
        elements,
        presliding_displacement,
    } = f.kind
    else {
        return Ok(());
    };
    let j_body = match (tm, f.location) {
        (None, _) => plant.j,
        (Some(t), FrictionLocation::Load) => t.j_load,
        (Some(t), FrictionLocation::Motor) => t.j_motor,
    };
    let k0 = maxwell_slip_stiffness(
        f.coulomb[0].max(f.coulomb[1]),
        elements,
        presliding_displacement,
    )
    .iter()
    .sum::<f64>();
    let w = (plant.rg * k0 / j_body).sqrt();
    if w / servo_rate_hz > MAX_PRESLIDING_WH {
        return Err(bad(
            "friction.presliding_displacement",
            presliding_displacement,
            "large enough that the pre-sliding stiffness resonates below servo_rate_hz/(2 pi)/10 \
             (raise it or the servo rate)",
        ));
    }
    Ok(())
}

/// Largest $\omega_{ps} h$ of the pre-sliding elements.
const MAX_PRESLIDING_WH: f64 = 0.1;

/// Element stiffnesses $k_i = T_c/(N\,x_i)$, $x_i = i\,x_{ps}/N$ (N·m per axis unit): element
/// $i$ slips after $x_i$, so the virgin curve is the concave piecewise-linear
/// $F(x) = \sum_i \min(k_i x, T_c/N)$, reaching $T_c$ at $x_{ps}$ (docs/machine-file.md#friction).
pub fn maxwell_slip_stiffness(tc: f64, elements: usize, xps: f64) -> [f64; MAX_ELEMENTS] {
    let mut k = [0.0; MAX_ELEMENTS];
    let n = elements as f64;
    for (i, ki) in k.iter_mut().enumerate().take(elements) {
        let xi = (i + 1) as f64 * xps / n;
        *ki = tc / (n * xi);
    }
    k
}

fn check_current(
    c: &CurrentLoop,
    nyquist: f64,
) -> Result<(Option<CurrentDynamics>, Option<f64>), Error> {
    let torque_max = c
        .torque_max
        .map(|t| positive("current_loop.torque_max", t))
        .transpose()?;
    if c.zeta.is_some() && c.order == CurrentLoopOrder::FirstOrder {
        return Err(bad(
            "current_loop.zeta",
            c.zeta.unwrap_or(f64::NAN),
            "absent with order = \"first-order\"",
        ));
    }
    let Some(bw) = c.bandwidth_hz else {
        if let Some(z) = c.zeta {
            return Err(bad(
                "current_loop.zeta",
                z,
                "given only together with bandwidth_hz",
            ));
        }
        return Ok((None, torque_max));
    };
    let bw = positive("current_loop.bandwidth_hz", bw)?;
    if bw > nyquist {
        return Err(bad(
            "current_loop.bandwidth_hz",
            bw,
            "at most half the servo rate",
        ));
    }
    let dynamics = match c.order {
        CurrentLoopOrder::FirstOrder => CurrentDynamics {
            order: c.order,
            w: TAU * bw,
            zeta: 1.0,
        },
        CurrentLoopOrder::SecondOrder => {
            let z = c.zeta.unwrap_or(std::f64::consts::FRAC_1_SQRT_2);
            if !(z.is_finite() && z > 0.0 && z <= 2.0) {
                return Err(bad("current_loop.zeta", z, "in (0, 2]"));
            }
            CurrentDynamics {
                order: c.order,
                w: TAU * bw / bandwidth_factor(z),
                zeta: z,
            }
        }
    };
    Ok((Some(dynamics), torque_max))
}

fn check_feedback(
    f: &Feedback,
    two_mass: bool,
    encoder: &Encoder,
    nyquist: f64,
) -> Result<Option<FeedbackPath>, Error> {
    if f.dead_time_cycles > MAX_DEAD_TIME_CYCLES {
        return Err(bad(
            "feedback.dead_time_cycles",
            f.dead_time_cycles as f64,
            "at most 100 servo cycles",
        ));
    }
    if let Some(fc) = f.velocity_filter_hz {
        let fc = positive("feedback.velocity_filter_hz", fc)?;
        if fc >= nyquist {
            return Err(bad(
                "feedback.velocity_filter_hz",
                fc,
                "below half the servo rate",
            ));
        }
    }
    let second_encoder = two_mass && f.source == FeedbackSource::Load;
    if let Some(q) = f.motor_resolution {
        non_negative("feedback.motor_resolution", q)?;
        if !second_encoder {
            return Err(bad(
                "feedback.motor_resolution",
                q,
                "absent unless [compliance] is given and source = \"load\" (only then is there a \
                 second, motor encoder)",
            ));
        }
    }
    non_negative("feedback.motor_noise_std", f.motor_noise_std)?;
    if f.motor_noise_std != 0.0 && !second_encoder {
        return Err(bad(
            "feedback.motor_noise_std",
            f.motor_noise_std,
            "0 unless [compliance] is given and source = \"load\" (only then is there a second, \
             motor encoder)",
        ));
    }
    let path = FeedbackPath {
        source: f.source,
        dead_time_cycles: f.dead_time_cycles,
        velocity_filter_hz: f.velocity_filter_hz,
        motor_resolution: f.motor_resolution.unwrap_or(encoder.resolution),
        motor_noise_std: f.motor_noise_std,
    };
    let neutral = f.source == FeedbackSource::Load
        && f.dead_time_cycles == 0
        && f.velocity_filter_hz.is_none()
        && f.motor_resolution.is_none()
        && f.motor_noise_std == 0.0;
    // A load sensor on a rigid drive is the ideal encoder; a semi-closed loop on a rigid drive
    // reads the same position.
    let rigid_neutral = !two_mass && f.dead_time_cycles == 0 && f.velocity_filter_hz.is_none();
    Ok((!(neutral || rigid_neutral)).then_some(path))
}

/// Whole servo ticks in `seconds` (to 1e-6 of a tick), or the error naming `name`.
fn whole_ticks(
    name: &'static str,
    seconds: f64,
    servo_rate_hz: f64,
    min: usize,
) -> Result<usize, Error> {
    let expected = if min == 0 {
        "a whole number (>= 0) of servo periods 1/servo_rate_hz, at most 1 s"
    } else {
        "a whole number (>= 1) of servo periods 1/servo_rate_hz, at most 1 s"
    };
    if !(seconds.is_finite() && (0.0..=1.0).contains(&seconds)) {
        return Err(bad(name, seconds, expected));
    }
    let ticks = seconds * servo_rate_hz;
    let n = ticks.round();
    if (ticks - n).abs() > 1e-6 || (n as usize) < min {
        return Err(bad(name, seconds, expected));
    }
    Ok(n as usize)
}

pub(crate) fn check_shaping(
    r: &ReferenceShaping,
    servo_rate_hz: f64,
) -> Result<Option<Shaping>, Error> {
    let delay_ticks = whole_ticks(
        "reference.interpolation_delay_s",
        r.interpolation_delay_s,
        servo_rate_hz,
        0,
    )?;
    let time_constant = |name: &'static str, t: f64| -> Result<(), Error> {
        if t.is_finite() && t > 0.0 && t <= 1.0 {
            Ok(())
        } else {
            Err(bad(name, t, "positive and at most 1 s"))
        }
    };
    match r.filter {
        Some(ShapingFilter::FirstOrder { time_constant_s }) => {
            time_constant("reference.filter.time_constant_s", time_constant_s)?
        }
        Some(ShapingFilter::SecondOrder {
            time_constant_s,
            zeta,
        }) => {
            time_constant("reference.filter.time_constant_s", time_constant_s)?;
            if !(zeta.is_finite() && zeta > 0.0 && zeta <= 2.0) {
                return Err(bad("reference.filter.zeta", zeta, "in (0, 2]"));
            }
        }
        Some(ShapingFilter::MovingAverage { window_s }) => {
            whole_ticks("reference.filter.window_s", window_s, servo_rate_hz, 1)?;
        }
        Some(ShapingFilter::BandStop {
            frequency_hz,
            zeta_numerator,
            zeta_denominator,
            denominator_frequency_hz,
        }) => {
            // A quarter of the rate: half the Nyquist frequency, so that the band to stop lies
            // well inside what the samples can carry.
            let frequency = |name: &'static str, f: f64| -> Result<(), Error> {
                if f.is_finite() && f >= 0.1 && f <= servo_rate_hz / 4.0 {
                    Ok(())
                } else {
                    Err(bad(
                        name,
                        f,
                        "at least 0.1 Hz and at most a quarter of the servo rate",
                    ))
                }
            };
            frequency("reference.filter.frequency_hz", frequency_hz)?;
            if let Some(f) = denominator_frequency_hz {
                frequency("reference.filter.denominator_frequency_hz", f)?;
            }
            if !(zeta_denominator.is_finite() && zeta_denominator > 0.0 && zeta_denominator <= 2.0)
            {
                return Err(bad(
                    "reference.filter.zeta_denominator",
                    zeta_denominator,
                    "in (0, 2]",
                ));
            }
            if !(zeta_numerator.is_finite()
                && zeta_numerator >= 0.0
                && zeta_numerator <= zeta_denominator)
            {
                return Err(bad(
                    "reference.filter.zeta_numerator",
                    zeta_numerator,
                    "in [0, zeta_denominator] (a larger one raises the band instead of stopping it)",
                ));
            }
        }
        None => {}
    }
    if r.filter.is_none() && delay_ticks == 0 {
        return Ok(None);
    }
    Ok(Some(Shaping {
        filter: r.filter,
        delay_ticks,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_neg_is_the_exponential_within_two_ulp() {
        // Truth: the platform's libm `exp` (correct to within one unit in the last place), on
        // a log-spaced sweep of p from 1e-6 to 700 and on every multiple of ln 2 / 2 there (the
        // reduction's edges), and the exact values e^0 = 1 and e^{-n ln 2} = 2^{-n}.
        let ulps = |p: f64| {
            let (a, b) = (exp_neg::<f64>(p), (-p).exp());
            (a.to_bits() as i64 - b.to_bits() as i64).abs()
        };
        let mut worst = (0, 0.0);
        let sweep = (0..200_000).map(|i| 1e-6 * (7e8f64).powf(i as f64 / 200_000.0));
        let edges = (1..2020).map(|i| i as f64 * std::f64::consts::LN_2 / 2.0);
        for p in sweep.chain(edges).filter(|p| *p <= 700.0) {
            let u = ulps(p);
            if u > worst.0 {
                worst = (u, p);
            }
        }
        assert!(worst.0 <= 2, "{} ulp at p = {}", worst.0, worst.1);
        assert_eq!(exp_neg::<f64>(0.0), 1.0);
        for n in [1, 2, 10, 57] {
            // p = n ln 2 rounded is not exactly n ln 2: compare within an ulp of 2^-n.
            let v = exp_neg::<f64>(n as f64 * std::f64::consts::LN_2);
            let exact = (0.5f64).powi(n);
            assert!(
                (v - exact).abs() <= 2.0 * f64::EPSILON * exact,
                "n = {n}: {v}"
            );
        }
    }
}
