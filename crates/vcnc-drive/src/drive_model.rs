//! Model structures beyond the paper's seven parameters (docs/drive-model.md, "extended
//! models"): the closed-loop model of [`crate::model`] with an input dead time, a reference
//! filter and one extra real pole.
//!
//! $$ x = P(s)\Big[\frac{N(s)}{D(s)}\,F(s)\,e^{-sT_d}\,x_r \;-\; \frac{d_c\,s}{D(s)}\,\mathcal{L}\{\operatorname{sgn}\dot x_c\}\Big],
//!    \qquad N = b_0 s^3 + b_1 s^2 + b_2 s + a_3,\quad D = s^3 + a_1 s^2 + a_2 s + a_3, $$
//!
//! - $T_d$ (`delay_s`): a dead time of the reference, as the nominal position a commercial
//!   control logs runs ahead of what its loop receives (interpolation and filter delays);
//! - $F(s)$ (`reference_filter`): a nominal-position (jerk) filter of unit static gain, first
//!   order $1/(\tau s + 1)$ or second order $\omega_f^2/(s^2 + 2\zeta_f\omega_f s + \omega_f^2)$;
//! - $P(s) = p_e/(s + p_e)$ (`extra_pole_hz`): one extra real pole that the whole loop sees,
//!   the reference and the friction alike (a current-loop or velocity-filter lag, or a filtered
//!   position measurement). For the reference alone it spans the same transfer functions as a
//!   first-order reference filter (four poles, a cubic numerator, unit static gain); the two
//!   differ in the friction path, which the filter leaves to the core's poles.
//!
//! The friction acts on the core's velocity $\dot x_c$ (before $P$), with the same implicit
//! sticking rule as [`ClosedLoopModel::simulate`].
//!
//! # Simulation
//!
//! The realisation keeps physical states: the filter's ($y_f$, $\dot y_f$), the core's
//! $[q = \int (x_{r,f} - x_c)\,dt,\ x_c,\ v_c]$ and the lag's output. Without integral action
//! ($a_3 = 0$) $q$ is instead a constant position offset ($\dot q = 0$, $\dot v_c$ gets
//! $a_2 q$: a constant load such as asymmetric friction), zero in a run from rest and
//! estimated with the rest of the state for a trace that starts moving. It is discretised exactly
//! for inputs that are piecewise linear between their knots. Two input conventions:
//!
//! - [`DriveModel::simulate`]: reference position, velocity and acceleration samples, each held
//!   first-order (as [`ClosedLoopModel::simulate`]; a simulated machine's interpolator knows
//!   them exactly);
//! - [`DriveModel::simulate_positions`]: the first-order hold of the position samples alone,
//!   with its exact derivatives: a constant velocity over each sample and the velocity changes
//!   as impulses of acceleration at the samples. A measured trace holds positions only; this
//!   uses them without differencing, so no derivative estimate biases the model (central
//!   differences of a trapezoidal profile are wrong next to every change of acceleration, and
//!   a fit bends the poles to absorb that).
//!
//! Which of the two a model uses is its [`ReferenceInput`] (`DriveModel::input`), a property of
//! the drive it models, recorded in `model.toml` and honoured by every simulation: a control
//! whose feed-forward takes the interpolator's velocity and acceleration is modelled with
//! [`ReferenceInput::Smooth`] (the exact derivatives when known, else the central differences
//! of the positions), one whose feed-forward differentiates its setpoints with
//! [`ReferenceInput::Hold`] (docs/identification.md, "The model input").
//!
//! A sub-sample dead time $T_d = (m + \varphi)T_s$ shifts the knots of the first-order hold
//! to $t_k + \varphi T_s$: each sample period is integrated in two exact pieces, $\varphi T_s$
//! and $(1 - \varphi)T_s$, so the delayed input is represented exactly (no re-interpolation
//! between shifted samples, which would cut the corners of the reference by up to
//! $a T_s^2/8$). Before the first sample the reference is at rest at its first value.
//!
//! Variables are named as in the paper and docs/drive-model.md (`a1`, `dc`, `wn`, `zeta`).

use nalgebra::{Complex, DMatrix};
use serde::{Deserialize, Serialize};

use crate::Error;
use crate::model::{
    ClosedLoopModel, Reference, SimOptions, check_exp_norm, friction_level, friction_sign,
};

/// Largest dead time accepted, s.
pub const MAX_DELAY_S: f64 = 10.0;

/// Largest actual-value latency a model accepts, s: far above any control's (a few servo
/// cycles), small enough that a value in the wrong unit (ms written as s) is refused.
pub const MAX_ACTUAL_LATENCY_S: f64 = 0.1;

/// How a model's reference input is rebuilt from the nominal positions (module documentation;
/// docs/identification.md, "The model input"): what the drive's feed-forward sees.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReferenceInput {
    /// The interpolator's velocity and acceleration, each held first-order: the exact ones
    /// when the interpolator's are known (a simulated machine, a prediction), else the central
    /// differences of the positions ([`crate::model::central_differences`]), exact at every
    /// sample whose neighbours share its acceleration. A control whose feed-forward is fed by
    /// its interpolator. The default (what a model file without the key means, and what
    /// [`ClosedLoopModel::simulate`] does).
    #[default]
    Smooth,
    /// The first-order hold of the positions with its exact derivatives: a constant velocity
    /// over each sample, the velocity changes as impulses of acceleration. A control whose
    /// feed-forward differentiates its position setpoints.
    Hold,
}

impl ReferenceInput {
    /// Name as in `model.toml` (`smooth`, `hold`).
    pub fn name(&self) -> &'static str {
        match self {
            ReferenceInput::Smooth => "smooth",
            ReferenceInput::Hold => "hold",
        }
    }
}

impl std::fmt::Display for ReferenceInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A nominal-position filter of unit static gain, applied to the reference before the loop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ReferenceFilter {
    /// $F(s) = 1/(\tau s + 1)$.
    FirstOrder {
        /// Time constant $\tau$, s. Positive.
        tau_s: f64,
    },
    /// $F(s) = \omega_f^2/(s^2 + 2\zeta_f\omega_f s + \omega_f^2)$.
    SecondOrder {
        /// Natural frequency $\omega_f/2\pi$, Hz. Positive.
        wn_hz: f64,
        /// Damping ratio $\zeta_f$, dimensionless. Positive.
        zeta: f64,
    },
}

impl ReferenceFilter {
    /// Frequency response $F(j\omega)$ at `w` rad/s.
    pub fn frf(&self, w: f64) -> Complex<f64> {
        let s = Complex::new(0.0, w);
        match *self {
            ReferenceFilter::FirstOrder { tau_s } => Complex::new(1.0, 0.0) / (s * tau_s + 1.0),
            ReferenceFilter::SecondOrder { wn_hz, zeta } => {
                let wf = std::f64::consts::TAU * wn_hz;
                Complex::new(wf * wf, 0.0) / ((s + 2.0 * zeta * wf) * s + wf * wf)
            }
        }
    }

    /// Its poles, rad/s.
    pub fn roots(&self) -> Vec<Complex<f64>> {
        match *self {
            ReferenceFilter::FirstOrder { tau_s } => vec![Complex::new(-1.0 / tau_s, 0.0)],
            ReferenceFilter::SecondOrder { wn_hz, zeta } => {
                let wf = std::f64::consts::TAU * wn_hz;
                let d = zeta * zeta - 1.0;
                if d >= 0.0 {
                    let r = wf * d.sqrt();
                    vec![
                        Complex::new(-zeta * wf + r, 0.0),
                        Complex::new(-zeta * wf - r, 0.0),
                    ]
                } else {
                    let im = wf * (-d).sqrt();
                    vec![Complex::new(-zeta * wf, im), Complex::new(-zeta * wf, -im)]
                }
            }
        }
    }

    /// Number of states (1 or 2).
    pub fn order(&self) -> usize {
        match self {
            ReferenceFilter::FirstOrder { .. } => 1,
            ReferenceFilter::SecondOrder { .. } => 2,
        }
    }

    fn validate(&self) -> Result<(), Error> {
        let (name, v) = match *self {
            ReferenceFilter::FirstOrder { tau_s } => ("reference_filter.tau_s", tau_s),
            ReferenceFilter::SecondOrder { wn_hz, zeta } => {
                if !(zeta > 0.0 && zeta.is_finite()) {
                    return Err(Error::BadParameter {
                        name: "reference_filter.zeta",
                        value: zeta,
                        expected: "positive and finite",
                    });
                }
                ("reference_filter.wn_hz", wn_hz)
            }
        };
        if !(v > 0.0 && v.is_finite()) {
            return Err(Error::BadParameter {
                name,
                value: v,
                expected: "positive and finite",
            });
        }
        Ok(())
    }
}

/// A closed-loop model of any structure vcnc identifies: the paper's seven parameters
/// (`core`) with an optional dead time, reference filter and extra pole (see the module
/// documentation). Plain data; its serde form is flat (the seven coefficients beside
/// `delay_s`, `reference_filter`, `extra_pole_hz`), checked on reading.
///
/// ```
/// use vcnc_drive::{ClosedLoopModel, DriveModel, ReferenceFilter};
/// let core = ClosedLoopModel { a1: 238.4, a2: 48421.6, a3: 2487140.3, b0: 0.0, b1: 117.5, b2: 37259.0, dc: 47.7 };
/// let m = DriveModel { delay_s: 0.085, reference_filter: Some(ReferenceFilter::FirstOrder { tau_s: 0.004 }), ..DriveModel::from(core) };
/// assert_eq!(m.roots().len(), 4);
/// // The dead time adds phase, not gain.
/// let g = m.tracking_frf(10.0);
/// let g0 = m.core.tracking_frf(10.0) * m.reference_filter.unwrap().frf(10.0);
/// assert!((g.norm() - g0.norm()).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawDriveModel", into = "RawDriveModel")]
pub struct DriveModel {
    /// The paper's 7-parameter closed loop (docs/drive-model.md).
    pub core: ClosedLoopModel,
    /// Dead time $T_d$ of the reference, s (0: none). At most [`MAX_DELAY_S`].
    pub delay_s: f64,
    /// Nominal-position filter of the reference, if any.
    pub reference_filter: Option<ReferenceFilter>,
    /// Extra real pole $p_e/2\pi$ of the whole loop, Hz, if any.
    pub extra_pole_hz: Option<f64>,
    /// The control's actual-value latency, s (0: none): the time by which the logged actual
    /// position — what the model predicts — trails the physical axis. Stated from the control's
    /// configuration, never identified (docs/drive-model.md#actual-value-latency); a
    /// prediction of the physical axis advances the model's output by it. It does not enter
    /// the model's own dynamics ([`DriveModel::simulate`] gives the logged position).
    pub actual_latency_s: f64,
    /// How the reference input is rebuilt from the nominal positions (default
    /// [`ReferenceInput::Smooth`]).
    pub input: ReferenceInput,
}

impl From<ClosedLoopModel> for DriveModel {
    fn from(core: ClosedLoopModel) -> DriveModel {
        DriveModel {
            core,
            delay_s: 0.0,
            reference_filter: None,
            extra_pole_hz: None,
            actual_latency_s: 0.0,
            input: ReferenceInput::Smooth,
        }
    }
}

/// Flat serde form of [`DriveModel`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDriveModel {
    a1: f64,
    a2: f64,
    a3: f64,
    b0: f64,
    b1: f64,
    b2: f64,
    dc: f64,
    #[serde(default, skip_serializing_if = "is_zero")]
    delay_s: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    reference_filter: Option<ReferenceFilter>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    extra_pole_hz: Option<f64>,
    #[serde(default, skip_serializing_if = "is_zero")]
    actual_latency_s: f64,
    #[serde(default)]
    input: ReferenceInput,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl TryFrom<RawDriveModel> for DriveModel {
    type Error = Error;
    fn try_from(r: RawDriveModel) -> Result<DriveModel, Error> {
        let m = DriveModel {
            core: ClosedLoopModel {
                a1: r.a1,
                a2: r.a2,
                a3: r.a3,
                b0: r.b0,
                b1: r.b1,
                b2: r.b2,
                dc: r.dc,
            },
            delay_s: r.delay_s,
            reference_filter: r.reference_filter,
            extra_pole_hz: r.extra_pole_hz,
            actual_latency_s: r.actual_latency_s,
            input: r.input,
        };
        m.validate()?;
        Ok(m)
    }
}

impl From<DriveModel> for RawDriveModel {
    fn from(m: DriveModel) -> RawDriveModel {
        let c = m.core;
        RawDriveModel {
            a1: c.a1,
            a2: c.a2,
            a3: c.a3,
            b0: c.b0,
            b1: c.b1,
            b2: c.b2,
            dc: c.dc,
            delay_s: m.delay_s,
            reference_filter: m.reference_filter,
            extra_pole_hz: m.extra_pole_hz,
            actual_latency_s: m.actual_latency_s,
            input: m.input,
        }
    }
}

/// The reference a [`DriveModel`] is driven by.
#[derive(Debug, Clone, Copy)]
pub enum ModelInput<'a> {
    /// Position, velocity and acceleration samples, each held first-order.
    Derivatives(Reference<'a>),
    /// Position samples held first-order, with the exact derivatives of that hold.
    Positions(&'a [f64]),
}

impl ModelInput<'_> {
    fn check(&self) -> Result<usize, Error> {
        match self {
            ModelInput::Derivatives(r) => r.check(),
            ModelInput::Positions(p) => {
                if p.is_empty() {
                    return Err(Error::EmptySignal);
                }
                if let Some(index) = p.iter().position(|v| !v.is_finite()) {
                    return Err(Error::NonFinite {
                        signal: "position",
                        index,
                    });
                }
                Ok(p.len())
            }
        }
    }
}

/// A free run: the position and the friction level held over each sample.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelRun {
    /// Model position $\hat x_k$ at every sample, axis units.
    pub position: Vec<f64>,
    /// Friction level over $[t_k, t_{k+1}]$, in $[-1, 1]$ (a sign, or the fraction that holds
    /// the axis while it sticks); the last entry is 0.
    pub friction: Vec<f64>,
}

/// Continuous realisation: $\dot z = A z + B_u [r, \dot r, \ddot r]^T + b_f f$, position
/// $x = c_x z$, core velocity $v_c = c_v z$.
#[derive(Debug, Clone, PartialEq)]
pub struct Realisation {
    /// State matrix, n×n.
    pub a: DMatrix<f64>,
    /// Input matrix of $[r, \dot r, \ddot r]$, n×3.
    pub b: DMatrix<f64>,
    /// Friction input column, n×1.
    pub bf: DMatrix<f64>,
    /// Output row of the position.
    pub cx: Vec<f64>,
    /// Output row of the core velocity (the friction acts on it).
    pub cv: Vec<f64>,
}

/// Exact discretisation of one piece of length `h`: $z(h) = \Phi z_0 + \Gamma u_0 + R(u_1 - u_0) + \gamma_f f$.
#[derive(Debug, Clone)]
struct Piece {
    /// Row-major n×n.
    phi: Vec<f64>,
    /// Row-major n×3.
    gamma: Vec<f64>,
    /// Row-major n×3.
    ramp: Vec<f64>,
    gf: Vec<f64>,
}

impl DriveModel {
    /// Checks the parts: finite core coefficients, a dead time in $[0,$ [`MAX_DELAY_S`]$]$,
    /// positive finite filter parameters and extra pole.
    pub fn validate(&self) -> Result<(), Error> {
        if !self.core.is_finite() {
            return Err(Error::NonFiniteModel);
        }
        if !(self.delay_s >= 0.0 && self.delay_s <= MAX_DELAY_S) {
            return Err(Error::BadParameter {
                name: "delay_s",
                value: self.delay_s,
                expected: "a dead time between 0 and 10 s",
            });
        }
        if let Some(f) = &self.reference_filter {
            f.validate()?;
        }
        if let Some(pe) = self.extra_pole_hz
            && !(pe > 0.0 && pe.is_finite())
        {
            return Err(Error::BadParameter {
                name: "extra_pole_hz",
                value: pe,
                expected: "positive and finite",
            });
        }
        if !(0.0..=MAX_ACTUAL_LATENCY_S).contains(&self.actual_latency_s) {
            return Err(Error::BadParameter {
                name: "actual_latency_s",
                value: self.actual_latency_s,
                expected: "an actual-value latency between 0 and 0.1 s (a few servo cycles; a value in ms written as s is refused)",
            });
        }
        Ok(())
    }

    /// How long the control's shaping delays the reference before the loop, s, at low
    /// frequency: the dead time plus the filter's group delay at 0 Hz ($\tau$ of a first-order
    /// filter, $2\zeta_f/\omega_f$ of a second-order one). 0 for the core alone.
    pub fn reference_lag_s(&self) -> f64 {
        self.delay_s
            + match self.reference_filter {
                None => 0.0,
                Some(ReferenceFilter::FirstOrder { tau_s }) => tau_s,
                Some(ReferenceFilter::SecondOrder { wn_hz, zeta }) => {
                    2.0 * zeta / (std::f64::consts::TAU * wn_hz)
                }
            }
    }

    /// Whether the model is the paper's seven parameters as [`ClosedLoopModel::simulate`] runs
    /// them: no dead time, filter or extra pole, and the smooth input
    /// ([`ReferenceInput::Smooth`]; a model with the hold input is simulated by this type).
    pub fn is_core_only(&self) -> bool {
        self.delay_s == 0.0
            && self.reference_filter.is_none()
            && self.extra_pole_hz.is_none()
            && self.input == ReferenceInput::Smooth
    }

    /// Every pole, rad/s: the core's three, the filter's, the extra one.
    pub fn roots(&self) -> Vec<Complex<f64>> {
        let mut r = self.core.roots().to_vec();
        if let Some(f) = &self.reference_filter {
            r.extend(f.roots());
        }
        if let Some(pe) = self.extra_pole_hz {
            r.push(Complex::new(-std::f64::consts::TAU * pe, 0.0));
        }
        r
    }

    /// Decay rate $-\operatorname{Re} s$ (rad/s) of the slowest pole decaying faster than
    /// `floor` rad/s, if any: the time scale of the model's transients (a pole at or near
    /// $s = 0$, the near-integrator of a drive without integral action, is left out by
    /// `floor`).
    pub fn slowest_decay_rate(&self, floor: f64) -> Option<f64> {
        self.roots()
            .iter()
            .map(|r| -r.re)
            .filter(|r| *r > floor)
            .min_by(f64::total_cmp)
    }

    /// Every pole strictly in the left half plane.
    pub fn is_stable(&self) -> bool {
        self.validate().is_ok() && self.core.is_stable()
    }

    /// Stable, or the core marginally so (a drive without integral action, docs/drive-model.md).
    pub fn is_marginally_stable(&self) -> bool {
        self.validate().is_ok() && self.core.is_marginally_stable()
    }

    fn lag(&self, w: f64) -> Complex<f64> {
        match self.extra_pole_hz {
            Some(pe) => {
                let p = std::f64::consts::TAU * pe;
                Complex::new(p, 0.0) / Complex::new(p, w)
            }
            None => Complex::new(1.0, 0.0),
        }
    }

    /// Tracking frequency response $x/x_r = P\,F\,e^{-j\omega T_d}\,N/D$ at `w` rad/s.
    pub fn tracking_frf(&self, w: f64) -> Complex<f64> {
        let f = self
            .reference_filter
            .map_or(Complex::new(1.0, 0.0), |f| f.frf(w));
        let delay = Complex::from_polar(1.0, -w * self.delay_s);
        self.core.tracking_frf(w) * f * delay * self.lag(w)
    }

    /// Disturbance frequency response per unit friction acceleration, $-P\,s/D$ at `w` rad/s.
    pub fn disturbance_frf(&self, w: f64) -> Complex<f64> {
        self.core.disturbance_frf(w) * self.lag(w)
    }

    /// The continuous realisation (see the module documentation): states
    /// [filter (0–2), $q$, $x_c$, $v_c$, lag (0–1)].
    pub fn realisation(&self) -> Realisation {
        let nf = self.reference_filter.map_or(0, |f| f.order());
        let np = usize::from(self.extra_pole_hz.is_some());
        let n = nf + 3 + np;
        let (iq, ix, iv) = (nf, nf + 1, nf + 2);
        // The filtered reference and its two derivatives as rows over [z | r, rd, rdd].
        let mut rf = vec![0.0; n + 3];
        let mut rfd = vec![0.0; n + 3];
        let mut rfdd = vec![0.0; n + 3];
        let mut a = DMatrix::zeros(n, n);
        let mut b = DMatrix::zeros(n, 3);
        match self.reference_filter {
            None => {
                rf[n] = 1.0;
                rfd[n + 1] = 1.0;
                rfdd[n + 2] = 1.0;
            }
            Some(ReferenceFilter::FirstOrder { tau_s }) => {
                let k = 1.0 / tau_s;
                // y' = (r - y)/tau; rf = y, rf' = (r - y)/tau, rf'' = (r' - rf')/tau.
                a[(0, 0)] = -k;
                b[(0, 0)] = k;
                rf[0] = 1.0;
                rfd[0] = -k;
                rfd[n] = k;
                rfdd[0] = k * k;
                rfdd[n] = -k * k;
                rfdd[n + 1] = k;
            }
            Some(ReferenceFilter::SecondOrder { wn_hz, zeta }) => {
                let w = std::f64::consts::TAU * wn_hz;
                // y1' = y2, y2' = w^2 (r - y1) - 2 zeta w y2.
                a[(0, 1)] = 1.0;
                a[(1, 0)] = -w * w;
                a[(1, 1)] = -2.0 * zeta * w;
                b[(1, 0)] = w * w;
                rf[0] = 1.0;
                rfd[1] = 1.0;
                rfdd[0] = -w * w;
                rfdd[1] = -2.0 * zeta * w;
                rfdd[n] = w * w;
            }
        }
        let c = &self.core;
        if c.a3 != 0.0 {
            // q' = rf - x.
            for j in 0..n {
                a[(iq, j)] += rf[j];
            }
            for j in 0..3 {
                b[(iq, j)] += rf[n + j];
            }
            a[(iq, ix)] -= 1.0;
        } else {
            // Without integral action q is a constant position offset (q' = 0; a constant
            // load, such as asymmetric friction, moves the loop's rest by q): v' gets a2 q.
            a[(iv, iq)] += c.a2;
        }
        // x' = v.
        a[(ix, iv)] = 1.0;
        // v' = a3 q - a2 x - a1 v + b2 rf + b1 rf' + b0 rf'' - dc f.
        for j in 0..n {
            a[(iv, j)] += c.b2 * rf[j] + c.b1 * rfd[j] + c.b0 * rfdd[j];
        }
        for j in 0..3 {
            b[(iv, j)] += c.b2 * rf[n + j] + c.b1 * rfd[n + j] + c.b0 * rfdd[n + j];
        }
        a[(iv, iq)] += c.a3;
        a[(iv, ix)] -= c.a2;
        a[(iv, iv)] -= c.a1;
        let mut bf = DMatrix::zeros(n, 1);
        bf[(iv, 0)] = -c.dc;
        let mut cx = vec![0.0; n];
        let mut cv = vec![0.0; n];
        cv[iv] = 1.0;
        match self.extra_pole_hz {
            Some(pe) => {
                let p = std::f64::consts::TAU * pe;
                a[(n - 1, ix)] = p;
                a[(n - 1, n - 1)] = -p;
                cx[n - 1] = 1.0;
            }
            None => cx[ix] = 1.0,
        }
        Realisation { a, b, bf, cx, cv }
    }

    /// Free run from the samples `pos`, `vel`, `acc` (each held first-order) at period `ts`,
    /// starting at rest at `pos[0]`. Returns the position at every sample. See the module
    /// documentation; with no dead time, filter or extra pole this is
    /// [`ClosedLoopModel::simulate`] up to rounding. A model with the hold input
    /// ([`ReferenceInput::Hold`]) uses `pos` alone, as [`DriveModel::simulate_positions`].
    ///
    /// This is [`DriveModel::stream`] (of a model that is not core-only) fed the whole
    /// reference: a stream fed it in pieces gives the same positions bit for bit.
    pub fn simulate(
        &self,
        reference: Reference<'_>,
        ts: f64,
        opts: &SimOptions,
    ) -> Result<Vec<f64>, Error> {
        let input = match self.input {
            ReferenceInput::Smooth => ModelInput::Derivatives(reference),
            ReferenceInput::Hold => ModelInput::Positions(reference.pos),
        };
        Ok(self.simulate_run(input, ts, opts)?.position)
    }

    /// Free run from the position samples alone, starting at rest at `pos[0]`, with the model's
    /// input (module documentation): the first-order hold with its exact derivatives
    /// ([`ReferenceInput::Hold`]), or the positions with their central-difference velocity and
    /// acceleration, each held first-order ([`ReferenceInput::Smooth`]).
    pub fn simulate_positions(
        &self,
        pos: &[f64],
        ts: f64,
        opts: &SimOptions,
    ) -> Result<Vec<f64>, Error> {
        let input = self.input_of(pos, ts);
        Ok(self.simulate_run(input.as_input(), ts, opts)?.position)
    }

    /// The input of this model rebuilt from the positions `pos` alone: the positions
    /// ([`ReferenceInput::Hold`]), or the positions with their central-difference velocity and
    /// acceleration ([`ReferenceInput::Smooth`]), held by the returned [`PositionsInput`].
    pub fn input_of<'a>(&self, pos: &'a [f64], ts: f64) -> PositionsInput<'a> {
        match self.input {
            ReferenceInput::Hold => PositionsInput::Hold(pos),
            ReferenceInput::Smooth => {
                let (vel, acc) = crate::model::central_differences(pos, ts);
                PositionsInput::Smooth { pos, vel, acc }
            }
        }
    }

    /// Free run with the friction level of every sample (the identifier fits the friction the
    /// model itself would apply). `opts.integrator` is ignored: the scheme is exact. The input
    /// is taken as given (`input` states which convention), whatever `self.input` says. With
    /// [`ModelInput::Derivatives`] this is the stream of [`DriveModel::stream`] fed the whole
    /// reference at once.
    pub fn simulate_run(
        &self,
        input: ModelInput<'_>,
        ts: f64,
        opts: &SimOptions,
    ) -> Result<ModelRun, Error> {
        self.simulate_run_from(input, ts, opts, &[])
    }

    /// [`DriveModel::simulate_run`] from the state `z0` at the first sample instead of rest: the
    /// states of [`DriveModel::realisation`] in deviations from the first reference position
    /// (`[filter (0–2), q, x_c - x_{r,0}, v_c, lag (0–1)]`; empty: rest). Before the first
    /// sample the reference is at rest at its first value, as in a run from rest. A trace that
    /// starts in motion is predicted from the state the identifier estimates for it.
    pub fn simulate_run_from(
        &self,
        input: ModelInput<'_>,
        ts: f64,
        opts: &SimOptions,
        z0: &[f64],
    ) -> Result<ModelRun, Error> {
        self.validate()?;
        if !(ts > 0.0 && ts.is_finite()) {
            return Err(Error::BadSamplePeriod { ts });
        }
        let n = input.check()?;
        let stepper = Stepper::new(self, ts)?;
        if !(z0.is_empty() || z0.len() == stepper.ns) || z0.iter().any(|v| !v.is_finite()) {
            return Err(Error::BadParameter {
                name: "initial state",
                value: z0.len() as f64,
                expected: "one finite value per state of the realisation, or none",
            });
        }
        let mut out = ModelRun {
            position: Vec::with_capacity(n),
            friction: Vec::with_capacity(n),
        };
        match input {
            ModelInput::Derivatives(r) => {
                let mut stream = ExtendedStream::new(stepper, *opts);
                stream.set_state(z0);
                stream.feed(r, 0, &mut out.position, Some(&mut out.friction))?;
                out.friction.push(0.0);
            }
            ModelInput::Positions(p) => {
                let r0 = p[0];
                // Sample j as [r - r0, slope after sample j, 0] (the slope changes are
                // impulses), at rest before the first sample.
                let sample = |j: isize| -> [f64; 3] {
                    if j < 0 {
                        return [0.0; 3];
                    }
                    let j = (j as usize).min(n - 1);
                    let slope = if j + 1 < n {
                        (p[j + 1] - p[j]) / ts
                    } else {
                        0.0
                    };
                    [p[j] - r0, slope, 0.0]
                };
                let mut z = vec![0.0; stepper.ns];
                let mut next = vec![0.0; stepper.ns];
                out.position.push(r0);
                if z0.iter().any(|v| *v != 0.0) {
                    z.copy_from_slice(z0);
                    out.position[0] = r0 + dot(&stepper.cx, &z);
                }
                for k in 0..n - 1 {
                    let j = k as isize - stepper.m as isize;
                    let (f, x) = stepper.step(&mut z, &mut next, j, true, sample, opts);
                    out.friction.push(f);
                    out.position.push(x + r0);
                }
                out.friction.push(0.0);
                if out.position.iter().any(|v| !v.is_finite()) {
                    return Err(Error::NonFiniteModel);
                }
            }
        }
        Ok(out)
    }
}

/// A model's input rebuilt from positions alone ([`DriveModel::input_of`]).
#[derive(Debug, Clone, PartialEq)]
pub enum PositionsInput<'a> {
    /// The positions, held first-order with their exact derivatives.
    Hold(&'a [f64]),
    /// The positions with their central-difference velocity and acceleration (axis units/s,
    /// /s²), each held first-order.
    Smooth {
        /// Positions, axis units.
        pos: &'a [f64],
        /// Velocity, axis units/s.
        vel: Vec<f64>,
        /// Acceleration, axis units/s².
        acc: Vec<f64>,
    },
}

impl PositionsInput<'_> {
    /// As the input of [`DriveModel::simulate_run`].
    pub fn as_input(&self) -> ModelInput<'_> {
        match self {
            PositionsInput::Hold(p) => ModelInput::Positions(p),
            PositionsInput::Smooth { pos, vel, acc } => {
                ModelInput::Derivatives(Reference { pos, vel, acc })
            }
        }
    }
}

/// A [`DriveModel`] discretised at one sample period, and its step from one sample to the
/// next (module documentation, "Simulation").
#[derive(Debug, Clone)]
pub(crate) struct Stepper {
    /// Output rows of the position and of the core velocity.
    cx: Vec<f64>,
    cv: Vec<f64>,
    /// One piece per sample period, or two ($\varphi T_s$ and $(1 - \varphi)T_s$) with a
    /// sub-sample dead time.
    pieces: Vec<Piece>,
    /// Friction column over the whole step.
    gf_total: Vec<f64>,
    /// Core velocity drop over one step under full friction.
    l: f64,
    /// Input column of the reference acceleration (the impulses of positions).
    b_acc: Vec<f64>,
    /// States.
    ns: usize,
    /// Dead time $T_d = (m + \varphi)T_s$.
    m: usize,
    phi: f64,
}

impl Stepper {
    /// The discretisation of `model` (validated by the caller) at `ts` (checked).
    #[allow(clippy::needless_range_loop)] // small dense kernels: indices read best
    fn new(model: &DriveModel, ts: f64) -> Result<Stepper, Error> {
        let real = model.realisation();
        let mut d = model.delay_s / ts;
        // A dead time within rounding of whole samples is whole samples.
        if (d - d.round()).abs() < 1e-9 {
            d = d.round();
        }
        let m = d.floor();
        let mut phi = d - m;
        if phi < 1e-12 {
            phi = 0.0;
        }
        let m = m as usize;
        let pieces: Vec<Piece> = if phi == 0.0 {
            vec![piece(&real, ts)?]
        } else {
            vec![piece(&real, phi * ts)?, piece(&real, (1.0 - phi) * ts)?]
        };
        let ns = real.a.nrows();
        // Friction column over the whole step: through the second piece's transition.
        let mut gf_total = pieces[pieces.len() - 1].gf.clone();
        if pieces.len() == 2 {
            let (p1, p2) = (&pieces[0], &pieces[1]);
            for i in 0..ns {
                gf_total[i] += (0..ns).map(|j| p2.phi[i * ns + j] * p1.gf[j]).sum::<f64>();
            }
        }
        let l = -dot(&real.cv, &gf_total);
        let b_acc: Vec<f64> = (0..ns).map(|i| real.b[(i, 2)]).collect();
        Ok(Stepper {
            cx: real.cx,
            cv: real.cv,
            pieces,
            gf_total,
            l,
            b_acc,
            ns,
            m,
            phi,
        })
    }

    /// The step from $t_k$ to $t_{k+1}$ of state `z` (`next`: work space of the same length):
    /// `j` $= k - m$ is the input sample whose knot lies in the step, `sample(i)` input sample
    /// $i$ as $[x_r - x_{r,0}, \dot x_r, \ddot x_r]$ (zero before the first; `positions`: the
    /// slope after sample $i$ and 0, the slope changes being impulses of acceleration).
    /// Returns the friction level held over the step and the position $x_{k+1} - x_{r,0}$.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // small dense kernels: indices read best
    fn step(
        &self,
        z: &mut Vec<f64>,
        next: &mut Vec<f64>,
        j: isize,
        positions: bool,
        sample: impl Fn(isize) -> [f64; 3],
        opts: &SimOptions,
    ) -> (f64, f64) {
        let (ns, phi) = (self.ns, self.phi);
        // The input at time t_j - phi T within [t_{j-1}, t_j]: position interpolated; the
        // slope of positions is constant over the interval.
        let between = |j: isize| -> [f64; 3] {
            let (a, b) = (sample(j - 1), sample(j));
            if positions {
                [a[0] + (1.0 - phi) * (b[0] - a[0]), a[1], 0.0]
            } else {
                std::array::from_fn(|i| a[i] + (1.0 - phi) * (b[i] - a[i]))
            }
        };
        let slope_before = |j: isize| -> f64 { if j <= 0 { 0.0 } else { sample(j - 1)[1] } };
        let v_start = dot(&self.cv, z);
        if phi == 0.0 {
            let (u0, u1) = (sample(j), sample(j + 1));
            if positions {
                let dv = u0[1] - slope_before(j);
                for i in 0..ns {
                    z[i] += self.b_acc[i] * dv;
                }
            }
            let u1 = if positions { [u1[0], u0[1], 0.0] } else { u1 };
            advance(&self.pieces[0], ns, z, &u0, &u1, next);
        } else {
            // First piece: from t_k (between samples j-1 and j) to the knot of sample j.
            let u0 = between(j);
            let uk = sample(j);
            let uk_in = if positions { [uk[0], u0[1], 0.0] } else { uk };
            advance(&self.pieces[0], ns, z, &u0, &uk_in, next);
            std::mem::swap(z, next);
            if positions {
                let dv = uk[1] - slope_before(j);
                for i in 0..ns {
                    z[i] += self.b_acc[i] * dv;
                }
            }
            let u1 = between(j + 1);
            let u1 = if positions { [u1[0], uk[1], 0.0] } else { u1 };
            advance(&self.pieces[1], ns, z, &uk, &u1, next);
        }
        let v_free = dot(&self.cv, next);
        let f = if opts.sticking {
            friction_level(v_start, v_free, self.l).0
        } else {
            friction_sign(v_start, opts.friction_deadband)
        };
        for i in 0..ns {
            z[i] = next[i] + self.gf_total[i] * f;
        }
        (f, dot(&self.cx, z))
    }
}

/// $z(h)$ of piece `p` from state `z` under the input ramp from `u0` to `u1`, into `out`.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // small dense kernel: indices read best
fn advance(p: &Piece, ns: usize, z: &[f64], u0: &[f64; 3], u1: &[f64; 3], out: &mut [f64]) {
    for i in 0..ns {
        let row = &p.phi[i * ns..(i + 1) * ns];
        let mut s: f64 = row.iter().zip(z).map(|(a, b)| a * b).sum();
        for j in 0..3 {
            s += p.gamma[i * 3 + j] * u0[j] + p.ramp[i * 3 + j] * (u1[j] - u0[j]);
        }
        out[i] = s;
    }
}

/// A [`DriveModel`] driven by reference samples (position, velocity, acceleration) one piece
/// at a time ([`crate::ModelStream`]): the step of sample $k$ reads input samples up to
/// $k - m$, so it keeps the last $m + 3$ of them (and at most as many again before it
/// compacts), not the run.
#[derive(Debug, Clone)]
pub(crate) struct ExtendedStream {
    stepper: Stepper,
    opts: SimOptions,
    /// First reference position $x_{r,0}$, axis units.
    r0: f64,
    /// Input samples from number `base` on, as $[x_r - x_{r,0}, \dot x_r, \ddot x_r]$.
    hist: Vec<[f64; 3]>,
    base: usize,
    /// Samples fed.
    count: usize,
    z: Vec<f64>,
    next: Vec<f64>,
    /// The hold input ([`ReferenceInput::Hold`]): the positions alone drive the model, each
    /// input sample kept as $[x_r - x_{r,0}$, the slope after it (set when the next sample
    /// comes), $0]$.
    hold: bool,
    /// Sample period, s (for the slopes of the hold input).
    ts: f64,
    /// The last position fed, axis units (hold input).
    last_p: f64,
}

impl ExtendedStream {
    /// Before the first sample.
    pub(crate) fn new(stepper: Stepper, opts: SimOptions) -> ExtendedStream {
        let ns = stepper.ns;
        ExtendedStream {
            stepper,
            opts,
            r0: 0.0,
            hist: Vec::new(),
            base: 0,
            count: 0,
            z: vec![0.0; ns],
            next: vec![0.0; ns],
            hold: false,
            ts: 0.0,
            last_p: 0.0,
        }
    }

    /// The stream of `model` (validated by the caller) at `ts` (checked), with the model's
    /// input convention.
    pub(crate) fn of(model: &DriveModel, ts: f64, opts: SimOptions) -> Result<Self, Error> {
        let mut s = ExtendedStream::new(Stepper::new(model, ts)?, opts);
        s.hold = model.input == ReferenceInput::Hold;
        s.ts = ts;
        Ok(s)
    }

    /// Starts from state `z0` (checked by the caller; empty: rest) instead of rest.
    fn set_state(&mut self, z0: &[f64]) {
        if !z0.is_empty() {
            self.z.copy_from_slice(z0);
        }
    }

    /// Runs the next samples (checked by the caller; `first` samples came before) and appends
    /// the position at each to `position` and, if given, the friction level of each step that
    /// ends at one of them to `friction`. [`Error::NonFiniteModel`] if a position is not
    /// finite.
    pub(crate) fn feed(
        &mut self,
        piece: Reference<'_>,
        first: usize,
        position: &mut Vec<f64>,
        mut friction: Option<&mut Vec<f64>>,
    ) -> Result<(), Error> {
        debug_assert_eq!(first, self.count);
        let start = position.len();
        let keep = self.stepper.m + 3;
        for ((p, v), a) in piece.pos.iter().zip(piece.vel).zip(piece.acc) {
            if self.count == 0 {
                self.r0 = *p;
            }
            if self.hist.len() >= 2 * keep + 1024 {
                let drop = self.hist.len() - keep;
                self.hist.drain(..drop);
                self.base += drop;
            }
            if self.hold {
                if let Some(last) = self.hist.last_mut() {
                    last[1] = (p - self.last_p) / self.ts;
                }
                self.last_p = *p;
                self.hist.push([p - self.r0, 0.0, 0.0]);
            } else {
                self.hist.push([p - self.r0, *v, *a]);
            }
            self.count += 1;
            if self.count == 1 {
                position.push(if self.z.iter().any(|v| *v != 0.0) {
                    self.r0 + dot(&self.stepper.cx, &self.z)
                } else {
                    self.r0
                });
                continue;
            }
            // The step from sample k = count - 2 to the new one; its knot is input sample
            // k - m (inputs up to k + 1 - m are read, all fed).
            let k = self.count - 2;
            let j = k as isize - self.stepper.m as isize;
            let (hist, base) = (&self.hist, self.base);
            let sample = |i: isize| -> [f64; 3] {
                if i < 0 {
                    [0.0; 3]
                } else {
                    hist[i as usize - base]
                }
            };
            let (f, x) = self.stepper.step(
                &mut self.z,
                &mut self.next,
                j,
                self.hold,
                sample,
                &self.opts,
            );
            if let Some(fr) = friction.as_deref_mut() {
                fr.push(f);
            }
            position.push(x + self.r0);
        }
        if position[start..].iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFiniteModel);
        }
        Ok(())
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Exact discretisation of one piece of length `h` with first-order hold on $[r, \dot r, \ddot r]$
/// and zero-order hold on the friction: the exponential of the augmented matrix
/// $\begin{bmatrix} A & B_u & b_f & 0 \\ 0 & 0 & 0 & I \\ 0 & 0 & 0 & 0 \end{bmatrix} h$.
fn piece(r: &Realisation, h: f64) -> Result<Piece, Error> {
    let n = r.a.nrows();
    let size = n + 7;
    let mut m = DMatrix::<f64>::zeros(size, size);
    for i in 0..n {
        for j in 0..n {
            m[(i, j)] = r.a[(i, j)] * h;
        }
        for j in 0..3 {
            m[(i, n + j)] = r.b[(i, j)] * h;
        }
        m[(i, n + 3)] = r.bf[(i, 0)] * h;
    }
    for j in 0..3 {
        m[(n + j, n + 4 + j)] = h;
    }
    check_exp_norm(&m)?;
    let e = m.exp();
    if e.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFiniteModel);
    }
    let rows = |c0: usize, w: usize, scale: f64| -> Vec<f64> {
        (0..n)
            .flat_map(|i| (0..w).map(move |j| (i, j)))
            .map(|(i, j)| e[(i, c0 + j)] * scale)
            .collect()
    };
    Ok(Piece {
        phi: rows(0, n, 1.0),
        gamma: rows(n, 3, 1.0),
        ramp: rows(n + 4, 3, 1.0 / h),
        gf: (0..n).map(|i| e[(i, n + 3)]).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn table1() -> ClosedLoopModel {
        ClosedLoopModel {
            b0: 0.3,
            ..crate::TABLE1_MODEL
        }
    }

    /// Rest-to-rest smooth moves with reversals, sampled at `ts`: position, velocity,
    /// acceleration, and the exact position at any time.
    fn moves() -> impl Fn(f64) -> (f64, f64, f64) {
        let list = [
            (0.1, 0.25, 20.0),
            (0.5, 0.3, -35.0),
            (0.95, 0.12, 4.0),
            (1.2, 0.4, 30.0),
        ];
        move |t: f64| {
            let (mut p, mut v, mut a) = (0.0, 0.0, 0.0);
            for &(t0, dur, d) in &list {
                let s = ((t - t0) / dur).clamp(0.0, 1.0);
                p += d * (3.0 * s * s - 2.0 * s * s * s);
                if (0.0..1.0).contains(&s) && t > t0 {
                    v += d * (6.0 * s - 6.0 * s * s) / dur;
                    a += d * (6.0 - 12.0 * s) / (dur * dur);
                }
            }
            (p + 5.0, v, a)
        }
    }

    /// `m`'s positions following `p`, `v`, `a` at period `ts`, default options.
    fn run(m: &DriveModel, p: &[f64], v: &[f64], a: &[f64], ts: f64) -> Vec<f64> {
        crate::test_util::follow(|r, ts, o| m.simulate(r, ts, o), (p, v, a), ts)
    }

    fn sampled(ts: f64, n: usize, shift: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let f = moves();
        let (mut p, mut v, mut a) = (vec![], vec![], vec![]);
        for k in 0..n {
            let (x, y, z) = f(k as f64 * ts - shift);
            p.push(x);
            v.push(y);
            a.push(z);
        }
        (p, v, a)
    }

    #[test]
    fn core_only_matches_the_closed_loop_model() {
        // Truth: ClosedLoopModel::simulate, the same exact scheme in another realisation.
        let (p, v, a) = sampled(1e-3, 2000, 0.0);
        let r = Reference {
            pos: &p,
            vel: &v,
            acc: &a,
        };
        let o = SimOptions::default();
        let x0 = table1().simulate(r, 1e-3, &o).unwrap();
        let x1 = DriveModel::from(table1()).simulate(r, 1e-3, &o).unwrap();
        let d = crate::test_util::max_abs_diff(&x0, &x1);
        assert!(d < 1e-9, "{d}");
    }

    #[test]
    fn whole_sample_delay_equals_a_shifted_reference() {
        // Truth: the same model driven by the reference shifted by 7 samples (at rest before).
        let (p, v, a) = sampled(1e-3, 2000, 0.0);
        let shift = |s: &[f64], rest: f64| -> Vec<f64> {
            (0..s.len())
                .map(|k| if k < 7 { rest } else { s[k - 7] })
                .collect()
        };
        let (ps, vs, as_) = (shift(&p, p[0]), shift(&v, 0.0), shift(&a, 0.0));
        let m = DriveModel {
            delay_s: 7e-3,
            ..DriveModel::from(table1())
        };
        let x = run(&m, &p, &v, &a, 1e-3);
        let xs = run(&DriveModel::from(table1()), &ps, &vs, &as_, 1e-3);
        let d = crate::test_util::max_abs_diff(&x, &xs);
        assert!(d < 1e-9, "{d}");
    }

    #[test]
    fn sub_sample_delay_filter_and_pole_agree_with_a_fine_simulation() {
        // Truth: the same model at a 100 times finer step, driven by the delayed first-order
        // hold of the coarse samples evaluated exactly at the fine instants (with a fine step
        // the knots fall on the grid, so the fine run's only approximation is its friction
        // held per fine step). Friction off: the sticking rule acts per step by design.
        let ts = 1e-3;
        let (p, v, a) = sampled(ts, 1600, 0.0);
        let mut core = table1();
        core.dc = 0.0;
        for m in [
            DriveModel {
                delay_s: 0.0374,
                ..DriveModel::from(core)
            },
            DriveModel {
                delay_s: 0.0123,
                reference_filter: Some(ReferenceFilter::FirstOrder { tau_s: 0.006 }),
                extra_pole_hz: Some(80.0),
                ..DriveModel::from(core)
            },
            DriveModel {
                delay_s: 0.0551,
                reference_filter: Some(ReferenceFilter::SecondOrder {
                    wn_hz: 20.0,
                    zeta: 0.6,
                }),
                ..DriveModel::from(core)
            },
        ] {
            let fine = 100;
            let h = ts / fine as f64;
            let interp = |s: &[f64], t: f64| {
                let q = (t / ts).max(0.0);
                let i = q.floor() as usize;
                if i + 1 >= s.len() {
                    return s[s.len() - 1];
                }
                s[i] + (q - i as f64) * (s[i + 1] - s[i])
            };
            let nf = (p.len() - 1) * fine + 1;
            let t = |k: usize| k as f64 * h - m.delay_s;
            let pf: Vec<f64> = (0..nf).map(|k| interp(&p, t(k))).collect();
            let vf: Vec<f64> = (0..nf)
                .map(|k| if t(k) < 0.0 { 0.0 } else { interp(&v, t(k)) })
                .collect();
            let af: Vec<f64> = (0..nf)
                .map(|k| if t(k) < 0.0 { 0.0 } else { interp(&a, t(k)) })
                .collect();
            let undelayed = DriveModel { delay_s: 0.0, ..m };
            let xf = run(&undelayed, &pf, &vf, &af, h);
            let x = run(&m, &p, &v, &a, ts);
            let d = (0..p.len())
                .map(|k| (x[k] - xf[k * fine]).abs())
                .fold(0.0, f64::max);
            assert!(d < 1e-8, "{m:?}: {d} mm");
        }
    }

    #[test]
    fn positions_mode_tracks_a_ramp_like_the_final_value_theorem() {
        // Truth: e_ss = v (a2 - b2) / a3 on a ramp; positions alone carry the velocity.
        let mut m = table1();
        m.dc = 0.0;
        let v = 100.0;
        let p: Vec<f64> = (0..4000).map(|k| 2.0 + v * k as f64 * 1e-3).collect();
        let x = DriveModel::from(m)
            .simulate_positions(&p, 1e-3, &SimOptions::default())
            .unwrap();
        let e = p[3999] - x[3999];
        assert!((e - m.ramp_following_error(v)).abs() < 1e-9, "{e}");
    }

    #[test]
    fn positions_mode_sine_matches_the_frequency_response() {
        // Truth: the analytic FRF, delay and filter included; the first-order hold of a
        // sampled sine is exact up to O((w Ts)^2/8) of the amplitude.
        let mut core = table1();
        core.dc = 0.0;
        let m = DriveModel {
            delay_s: 0.0213,
            reference_filter: Some(ReferenceFilter::SecondOrder {
                wn_hz: 25.0,
                zeta: 0.8,
            }),
            extra_pole_hz: Some(60.0),
            ..DriveModel::from(core)
        };
        let (ts, w, n) = (1e-3, TAU * 5.0, 6000);
        let p: Vec<f64> = (0..n).map(|k| (w * k as f64 * ts).sin()).collect();
        let x = m
            .simulate_positions(&p, ts, &SimOptions::default())
            .unwrap();
        let g = m.tracking_frf(w);
        let err = (4000..n)
            .map(|k| (x[k] - g.norm() * (w * k as f64 * ts + g.arg()).sin()).abs())
            .fold(0.0, f64::max);
        assert!(err < 2e-4, "{err}");
    }

    #[test]
    fn the_input_convention_is_honoured_by_every_simulation() {
        // Truth: the two explicit inputs of simulate_run. A hold model driven through
        // `simulate` (velocity and acceleration given) or its stream (in pieces) uses the
        // positions alone, bit for bit as `simulate_run(Positions)`; a smooth model driven by
        // positions alone uses their central differences.
        let (p, v, a) = sampled(1.3e-3, 1500, 0.0);
        let o = SimOptions::default();
        let r = Reference {
            pos: &p,
            vel: &v,
            acc: &a,
        };
        for base in [
            DriveModel::from(table1()),
            DriveModel {
                delay_s: 0.0071,
                reference_filter: Some(ReferenceFilter::FirstOrder { tau_s: 0.004 }),
                ..DriveModel::from(table1())
            },
        ] {
            let hold = DriveModel {
                input: ReferenceInput::Hold,
                ..base
            };
            assert!(!hold.is_core_only());
            let want = hold
                .simulate_run(ModelInput::Positions(&p), 1.3e-3, &o)
                .unwrap()
                .position;
            assert_eq!(hold.simulate(r, 1.3e-3, &o).unwrap(), want);
            assert_eq!(hold.simulate_positions(&p, 1.3e-3, &o).unwrap(), want);
            let mut s = hold.stream(1.3e-3, &o).unwrap();
            let mut got = vec![];
            for (i, j) in [(0, 1), (1, 700), (700, 701), (701, 1500)] {
                let piece = Reference {
                    pos: &p[i..j],
                    vel: &v[i..j],
                    acc: &a[i..j],
                };
                s.feed(piece, &mut got).unwrap();
            }
            assert_eq!(got, want);
            // Smooth: positions alone are their central differences.
            let (cv, ca) = crate::model::central_differences(&p, 1.3e-3);
            let smooth = base;
            let want = run(&smooth, &p, &cv, &ca, 1.3e-3);
            assert_eq!(smooth.simulate_positions(&p, 1.3e-3, &o).unwrap(), want);
            // The two differ: by about half a sample of velocity through b1.
            let d = want
                .iter()
                .zip(hold.simulate_positions(&p, 1.3e-3, &o).unwrap())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(d > 1e-5, "{d}");
        }
    }

    #[test]
    fn a_run_from_a_state_adds_the_free_response() {
        // Truth: superposition for a linear model (no friction): the run from z0 is the run
        // from rest plus c_x exp(A t_k) z0, the matrix exponential by nalgebra.
        let mut core = table1();
        core.dc = 0.0;
        let ts = 1e-3;
        let (p, v, a) = sampled(ts, 800, 0.0);
        let o = SimOptions::default();
        for m in [
            DriveModel::from(core),
            DriveModel {
                reference_filter: Some(ReferenceFilter::SecondOrder {
                    wn_hz: 30.0,
                    zeta: 0.7,
                }),
                extra_pole_hz: Some(90.0),
                input: ReferenceInput::Hold,
                ..DriveModel::from(core)
            },
        ] {
            let real = m.realisation();
            let n = real.a.nrows();
            let z0: Vec<f64> = (0..n).map(|i| 0.01 * (i as f64 + 1.0)).collect();
            let input = ModelInput::Derivatives(Reference {
                pos: &p,
                vel: &v,
                acc: &a,
            });
            let rest = m.simulate_run(input, ts, &o).unwrap().position;
            let from = m.simulate_run_from(input, ts, &o, &z0).unwrap().position;
            let zv = nalgebra::DVector::from_vec(z0.clone());
            let d = (0..p.len())
                .map(|k| {
                    let e = (&real.a * (k as f64 * ts)).exp() * &zv;
                    let free: f64 = real.cx.iter().zip(e.iter()).map(|(c, z)| c * z).sum();
                    (from[k] - rest[k] - free).abs()
                })
                .fold(0.0, f64::max);
            assert!(d < 1e-10, "{d}");
            let hold = m
                .simulate_run_from(ModelInput::Positions(&p), ts, &o, &z0)
                .unwrap()
                .position;
            let hold_rest = m
                .simulate_run(ModelInput::Positions(&p), ts, &o)
                .unwrap()
                .position;
            let e = (&real.a * (0.5)).exp() * &zv;
            let free: f64 = real.cx.iter().zip(e.iter()).map(|(c, z)| c * z).sum();
            assert!((hold[500] - hold_rest[500] - free).abs() < 1e-10);
        }
        let bad = DriveModel::from(core).simulate_run_from(
            ModelInput::Positions(&p),
            ts,
            &o,
            &[1.0, 2.0],
        );
        assert!(matches!(bad, Err(Error::BadParameter { .. })), "{bad:?}");
    }

    #[test]
    fn without_integral_action_the_core_follows_its_second_order_closed_form() {
        // Truth: the Laplace transform by hand. With a3 = 0 and b2 = a2 the tracking path is
        // G = (b0 s^2 + b1 s + a2)/(s^2 + a1 s + a2); a ramp v t from rest (the hold of its
        // samples, whose velocity step at t = 0 is an impulse of acceleration) gives
        // x = v [t + (b1 - a1)/a2 + e^{-st} (A cos wd t + (B - A s)/wd sin wd t)],
        // s = a1/2, wd = sqrt(a2 - s^2), A = (a1 - b1)/a2, B = b0 - 1 - (b1 - a1) a1/a2.
        let (a1, a2, b1, b0) = (95.0, 16194.0, 20.0, 0.03);
        let core = ClosedLoopModel {
            a1,
            a2,
            a3: 0.0,
            b0,
            b1,
            b2: a2,
            dc: 0.0,
        };
        let m = DriveModel {
            input: ReferenceInput::Hold,
            ..DriveModel::from(core)
        };
        let (ts, v, n) = (1e-3, 10.0, 2000);
        let pos: Vec<f64> = (0..n).map(|k| 5.0 + v * k as f64 * ts).collect();
        let o = SimOptions::default();
        let x = m.simulate_positions(&pos, ts, &o).unwrap();
        let (sg, wd) = (0.5 * a1, (a2 - 0.25 * a1 * a1).sqrt());
        let (ca, cb) = ((a1 - b1) / a2, b0 - 1.0 - (b1 - a1) * a1 / a2);
        let exact = |t: f64| {
            v * (t
                + (b1 - a1) / a2
                + (-sg * t).exp() * (ca * (wd * t).cos() + (cb - ca * sg) / wd * (wd * t).sin()))
        };
        let d = (0..n)
            .map(|k| (x[k] - 5.0 - exact(k as f64 * ts)).abs())
            .fold(0.0, f64::max);
        assert!(d < 1e-9, "{d}");
        // Coulomb friction moving forward leaves the steady offset -dc/a2 (no integral to
        // remove it), on top of the ramp's following error v (a1 - b1)/a2.
        let dc = 50.0;
        let mf = DriveModel {
            core: ClosedLoopModel { dc, ..core },
            ..m
        };
        let xf = mf.simulate_positions(&pos, ts, &o).unwrap();
        let t = (n - 1) as f64 * ts;
        let lag = pos[n - 1] - xf[n - 1];
        let want = v * (a1 - b1) / a2 + dc / a2;
        assert!((lag - want).abs() < 1e-9, "{lag} vs {want}");
        assert!((t - 1.999).abs() < 1e-12);
        // The realisation's state q is a constant position offset (a constant load): from
        // q0 at rest, x'' + a1 x' + a2 x = a2 q0, x = q0 [1 - e^{-st}(cos wd t + s/wd sin wd t)].
        let real = m.realisation();
        assert_eq!(real.a.nrows(), 3);
        let q0 = 0.004;
        let still = vec![5.0; 400];
        let xq = m
            .simulate_run_from(ModelInput::Positions(&still), ts, &o, &[q0, 0.0, 0.0])
            .unwrap()
            .position;
        let d = (0..still.len())
            .map(|k| {
                let t = k as f64 * ts;
                let e = q0 * (1.0 - (-sg * t).exp() * ((wd * t).cos() + sg / wd * (wd * t).sin()));
                (xq[k] - 5.0 - e).abs()
            })
            .fold(0.0, f64::max);
        assert!(d < 1e-12, "{d}");
        assert!(m.is_marginally_stable() && !m.is_stable());
        let p = m.core.poles().unwrap();
        assert_eq!(p.p.to_bits(), 0.0f64.to_bits(), "p = +0, not -0");
        assert!((p.wn - a2.sqrt()).abs() < 1e-9 && (p.zeta - a1 / (2.0 * a2.sqrt())).abs() < 1e-12);
    }

    #[test]
    fn serde_form_is_flat_and_checked() {
        let m = DriveModel {
            delay_s: 0.08,
            reference_filter: Some(ReferenceFilter::SecondOrder {
                wn_hz: 12.0,
                zeta: 0.7,
            }),
            ..DriveModel::from(table1())
        };
        let s = serde_json::to_string(&m).unwrap();
        assert!(
            s.contains("\"a1\"") && s.contains("\"kind\":\"second-order\""),
            "{s}"
        );
        let back: DriveModel = serde_json::from_str(&s).unwrap();
        assert_eq!(back, m);
        let bad = s.replace("0.08", "-0.08");
        assert!(serde_json::from_str::<DriveModel>(&bad).is_err());
        let unknown = s.replace("\"a1\"", "\"a9\":1,\"a1\"");
        assert!(serde_json::from_str::<DriveModel>(&unknown).is_err());
        // The input is written, and a model without it is smooth (what a prediction always did).
        assert!(s.contains("\"input\":\"smooth\""), "{s}");
        let hold = DriveModel {
            input: ReferenceInput::Hold,
            ..m
        };
        let h = serde_json::to_string(&hold).unwrap();
        assert!(h.contains("\"input\":\"hold\""), "{h}");
        assert_eq!(serde_json::from_str::<DriveModel>(&h).unwrap(), hold);
        let legacy = s.replace(",\"input\":\"smooth\"", "");
        assert_ne!(legacy, s);
        assert_eq!(serde_json::from_str::<DriveModel>(&legacy).unwrap(), m);
    }
}
