//! The parts of one feed drive: plant, controller, encoder (docs/drive-model.md), as plain data
//! that the machine file (TOML) embeds directly, with the checks each part makes on its own
//! numbers. A whole drive is a [`crate::DriveParams`], checked into a [`crate::Drive`]
//! ([`crate::drive`]).
//!
//! Variables are named as in the paper and docs/drive-model.md (`j`, `b`, `ka`, `kt`, `rg`, `kv`,
//! `kp`, `ki`, `vff`, `bff`, `jff`, `lambda`, `ks`, `rho`).

use serde::{Deserialize, Serialize};

use crate::Error;
use crate::model::{ClosedLoopModel, Poles};

/// The mechanical plant and amplifier of one axis (docs/drive-model.md):
///
/// $$ J\,\ddot\theta + B\,\dot\theta = K_a K_t\, u - T_c \operatorname{sgn}(\dot\theta), \qquad x = r_g\,\theta. $$
///
/// $u$ is the controller output (V), $\theta$ the motor angle (rad), $x$ the axis position (mm for
/// a linear axis, deg for a rotary one).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plant {
    /// Inertia $J$ reflected to the motor, kg·m². Must be positive.
    pub j: f64,
    /// Viscous friction $B$ at the motor, N·m·s/rad. Must be non-negative.
    pub b: f64,
    /// Amplifier gain $K_a$, A/V. Must be positive.
    pub ka: f64,
    /// Motor torque constant $K_t$, N·m/A. Must be positive.
    pub kt: f64,
    /// Transmission $r_g$, axis units per motor radian: mm/rad = pitch/2π for a ball screw,
    /// deg/rad = 180/π for a direct-drive rotary axis. Must be positive.
    pub rg: f64,
    /// Coulomb friction torque $T_c$, N·m. Must be non-negative; 0 turns friction off.
    pub coulomb_torque: f64,
    /// Control saturation $|u| \le u_{max}$, V. `None` (default): no saturation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub u_max: Option<f64>,
}

impl Plant {
    /// Checks every field (finite; positive where a zero would be meaningless).
    pub fn validate(&self) -> Result<(), Error> {
        positive("plant.j", self.j)?;
        non_negative("plant.b", self.b)?;
        positive("plant.ka", self.ka)?;
        positive("plant.kt", self.kt)?;
        positive("plant.rg", self.rg)?;
        non_negative("plant.coulomb_torque", self.coulomb_torque)?;
        for (name, v) in [
            ("plant.j", self.j),
            ("plant.b", self.b),
            ("plant.ka", self.ka),
            ("plant.kt", self.kt),
            ("plant.rg", self.rg),
            ("plant.coulomb_torque", self.coulomb_torque),
        ] {
            sane(name, v)?;
        }
        if let Some(u) = self.u_max {
            positive("plant.u_max", u)?;
        }
        Ok(())
    }

    /// $K_a K_t$, N·m/V.
    pub fn ka_kt(&self) -> f64 {
        self.ka * self.kt
    }

    /// Mechanical pole $B/J$, 1/s.
    pub fn b_over_j(&self) -> f64 {
        self.b / self.j
    }

    /// Equivalent inertia in axis units (docs/drive-model.md, sliding mode):
    /// $J_e = J / (K_a K_t r_g)$, V·s²/axis unit.
    pub fn je(&self) -> f64 {
        self.j / (self.ka_kt() * self.rg)
    }

    /// Equivalent viscous friction in axis units: $B_e = B / (K_a K_t r_g)$, V·s/axis unit.
    pub fn be(&self) -> f64 {
        self.b / (self.ka_kt() * self.rg)
    }

    /// Coulomb friction as an axis acceleration, $d_c = T_c r_g / J$, axis units/s².
    pub fn dc(&self) -> f64 {
        self.coulomb_torque * self.rg / self.j
    }
}

/// Desired closed-loop poles $(s + p)(s^2 + 2\zeta\omega_n s + \omega_n^2)$, in Hz, from which the
/// controller gains are designed (docs/drive-model.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoleDesign {
    /// Real pole $p/2\pi$, Hz.
    pub p_hz: f64,
    /// Natural frequency $\omega_n/2\pi$ of the pole pair, Hz.
    pub wn_hz: f64,
    /// Damping ratio $\zeta$ of the pole pair, dimensionless.
    pub zeta: f64,
}

impl PoleDesign {
    /// The same poles in rad/s.
    pub fn poles(&self) -> Poles {
        Poles::from_hz(self.p_hz, self.wn_hz, self.zeta)
    }

    /// Finite and strictly stable ($p, \omega_n, \zeta > 0$).
    pub fn validate(&self) -> Result<(), Error> {
        let ok = [self.p_hz, self.wn_hz, self.zeta]
            .iter()
            .all(|v| v.is_finite() && *v > 0.0);
        if ok {
            Ok(())
        } else {
            Err(Error::BadDesign {
                p_hz: self.p_hz,
                wn_hz: self.wn_hz,
                zeta: self.zeta,
            })
        }
    }
}

/// P-PI cascade gains with feed-forward (docs/drive-model.md, paper Fig. 1b):
///
/// $$ \omega_c = K_v (x_r - x) + V_{ff}\,\dot x_r / r_g, \qquad
///    u = \Big(K_p + \frac{K_i}{s}\Big)(\omega_c - \dot\theta) + \frac{J_{ff} J \ddot x_r + B_{ff} B \dot x_r}{r_g K_a K_t}. $$
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PPiGains {
    /// Position-loop gain $K_v$, (rad/s) per axis unit. Must be positive.
    pub kv: f64,
    /// Velocity-loop proportional gain $K_p$, V/(rad/s).
    pub kp: f64,
    /// Velocity-loop integral gain $K_i$, V/rad.
    pub ki: f64,
    /// Velocity feed-forward $V_{ff}$, dimensionless (0 ..= 1 usually).
    pub vff: f64,
    /// Viscous-friction feed-forward $B_{ff}$, dimensionless.
    pub bff: f64,
    /// Inertia feed-forward $J_{ff}$, dimensionless.
    pub jff: f64,
}

/// PID on the position error with inertia and viscous feed-forward (docs/drive-model.md):
///
/// $$ u = K_p e + K_i \int e\,dt + K_d \dot e + \frac{J_{ff} J \ddot x_r + B_{ff} B \dot x_r}{r_g K_a K_t},
///    \qquad e = x_r - x. $$
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PidGains {
    /// Proportional gain $K_p$, V per axis unit (V/mm).
    pub kp: f64,
    /// Integral gain $K_i$, V/(axis unit·s).
    pub ki: f64,
    /// Derivative gain $K_d$, V·s per axis unit.
    pub kd: f64,
    /// Inertia feed-forward $J_{ff}$, dimensionless.
    pub jff: f64,
    /// Viscous-friction feed-forward $B_{ff}$, dimensionless.
    pub bff: f64,
}

/// Adaptive sliding-mode gains (Altintas, Erkorkmaz, Zhu 2000; docs/drive-model.md), in axis units:
///
/// $$ S = \lambda e + \dot e, \qquad u = \hat J_e(\ddot x_r + \lambda \dot e) + \hat B_e \dot x + \hat d + K_s S,
///    \qquad \hat d = \rho \int S\,dt. $$
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SmcGains {
    /// Sliding-surface slope $\lambda$, 1/s.
    pub lambda: f64,
    /// Feedback gain $K_s$, V·s per axis unit.
    pub ks: f64,
    /// Disturbance-adaptation gain $\rho$, V per (axis unit·s).
    pub rho: f64,
    /// Inertia estimate $\hat J_e$ (true value $J/(K_a K_t r_g)$), V·s² per axis unit.
    pub je_hat: f64,
    /// Viscous-friction estimate $\hat B_e$ (true value $B/(K_a K_t r_g)$), V·s per axis unit.
    pub be_hat: f64,
}

/// A checked controller: gains only (designs already resolved). Build it with
/// [`ControllerSpec::resolve`] or directly from gains.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Controller {
    /// P-PI cascade with velocity, viscous and inertia feed-forward.
    PPi(PPiGains),
    /// PID on position error with inertia and viscous feed-forward.
    Pid(PidGains),
    /// Adaptive sliding-mode control.
    Smc(SmcGains),
}

impl Controller {
    /// `"p-pi"`, `"pid"` or `"smc"`, as in the machine file.
    pub fn kind(&self) -> &'static str {
        match self {
            Controller::PPi(_) => "p-pi",
            Controller::Pid(_) => "pid",
            Controller::Smc(_) => "smc",
        }
    }

    /// The 7-parameter closed-loop model of this controller on `plant` (docs/drive-model.md; paper
    /// eq. 4 for P-PI, corrected: "KaKtKt" → $K_aK_tK_i$, "I_ff" → $J_{ff}$; the PID form is the
    /// paper's missing eq. 5). With $k = K_a K_t$:
    ///
    /// P-PI: $a_1 = (B + k K_p)/J$, $a_2 = k(K_p K_v r_g + K_i)/J$, $a_3 = k K_i K_v r_g/J$,
    /// $b_0 = J_{ff}$, $b_1 = (B_{ff} B + k K_p V_{ff})/J$, $b_2 = k(K_p K_v r_g + K_i V_{ff})/J$.
    ///
    /// PID: $a_1 = (B + k K_d r_g)/J$, $a_2 = k K_p r_g/J$, $a_3 = k K_i r_g/J$, $b_0 = J_{ff}$,
    /// $b_1 = (B_{ff} B + k K_d r_g)/J$, $b_2 = a_2$.
    ///
    /// SMC: $a_1 = (B_e - \hat B_e + \hat J_e\lambda + K_s)/J_e$, $a_2 = (K_s\lambda + \rho)/J_e$,
    /// $a_3 = \lambda\rho/J_e$, $b_0 = \hat J_e/J_e$, $b_1 = (\hat J_e\lambda + K_s)/J_e$, $b_2 = a_2$.
    ///
    /// All kinds: $d_c = T_c r_g / J$. Pure arithmetic: an unstable or non-finite result is
    /// returned as is (see [`DriveParams::validate`](crate::DriveParams::validate) for the checks).
    pub fn closed_loop_model(&self, plant: &Plant) -> ClosedLoopModel {
        let Plant { j, b, rg, .. } = *plant;
        let k = plant.ka_kt();
        let dc = plant.dc();
        match *self {
            Controller::PPi(PPiGains {
                kv,
                kp,
                ki,
                vff,
                bff,
                jff,
            }) => ClosedLoopModel {
                a1: (b + k * kp) / j,
                a2: k * (kp * kv * rg + ki) / j,
                a3: k * ki * kv * rg / j,
                b0: jff,
                b1: (bff * b + k * kp * vff) / j,
                b2: k * (kp * kv * rg + ki * vff) / j,
                dc,
            },
            Controller::Pid(PidGains {
                kp,
                ki,
                kd,
                jff,
                bff,
            }) => {
                let a2 = k * kp * rg / j;
                ClosedLoopModel {
                    a1: (b + k * kd * rg) / j,
                    a2,
                    a3: k * ki * rg / j,
                    b0: jff,
                    b1: (bff * b + k * kd * rg) / j,
                    b2: a2,
                    dc,
                }
            }
            Controller::Smc(SmcGains {
                lambda,
                ks,
                rho,
                je_hat,
                be_hat,
            }) => {
                let je = plant.je();
                let be = plant.be();
                let a2 = (ks * lambda + rho) / je;
                ClosedLoopModel {
                    a1: (be - be_hat + je_hat * lambda + ks) / je,
                    a2,
                    a3: lambda * rho / je,
                    b0: je_hat / je,
                    b1: (je_hat * lambda + ks) / je,
                    b2: a2,
                    dc,
                }
            }
        }
    }

    /// Every gain finite, and the P-PI position gain positive (with $K_v \le 0$ nothing closes
    /// the position loop, whatever the velocity loop does).
    pub fn validate_gains(&self) -> Result<(), Error> {
        let gains: &[(&'static str, f64)] = match self {
            Controller::PPi(g) => &[
                ("controller.kv", g.kv),
                ("controller.kp", g.kp),
                ("controller.ki", g.ki),
                ("controller.vff", g.vff),
                ("controller.bff", g.bff),
                ("controller.jff", g.jff),
            ],
            Controller::Pid(g) => &[
                ("controller.kp", g.kp),
                ("controller.ki", g.ki),
                ("controller.kd", g.kd),
                ("controller.jff", g.jff),
                ("controller.bff", g.bff),
            ],
            Controller::Smc(g) => &[
                ("controller.lambda", g.lambda),
                ("controller.ks", g.ks),
                ("controller.rho", g.rho),
                ("controller.je_hat", g.je_hat),
                ("controller.be_hat", g.be_hat),
            ],
        };
        for (name, v) in gains {
            finite(name, *v)?;
            sane(name, *v)?;
        }
        match self {
            Controller::PPi(g) => {
                positive("controller.kv", g.kv)?;
                finite("controller.kp", g.kp)?;
                finite("controller.ki", g.ki)?;
                finite("controller.vff", g.vff)?;
                finite("controller.bff", g.bff)?;
                finite("controller.jff", g.jff)
            }
            Controller::Pid(g) => {
                finite("controller.kp", g.kp)?;
                finite("controller.ki", g.ki)?;
                finite("controller.kd", g.kd)?;
                finite("controller.jff", g.jff)?;
                finite("controller.bff", g.bff)
            }
            Controller::Smc(g) => {
                finite("controller.lambda", g.lambda)?;
                finite("controller.ks", g.ks)?;
                finite("controller.rho", g.rho)?;
                finite("controller.je_hat", g.je_hat)?;
                finite("controller.be_hat", g.be_hat)
            }
        }
    }
}

/// The controller as written in the machine file: `kind` = `"p-pi"` | `"pid"` | `"smc"`, then
/// either every gain of that kind, or `design = { p_hz, wn_hz, zeta }` (desired poles; the gains
/// are then designed for the plant, docs/drive-model.md, see [`crate::design`]). Feed-forward gains
/// default to 0. [`ControllerSpec::resolve`] turns it into a [`Controller`].
///
/// ```toml
/// [axes.X.controller]
/// kind = "p-pi"
/// design = { p_hz = 19.30, wn_hz = 55.54, zeta = 0.39 }
/// vff = 0.5
/// bff = 0.1
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ControllerSpec {
    /// P-PI cascade ([`PPiGains`]). With `design`, $K_v r_g$ is the larger root (as Table 1).
    PPi {
        /// $K_v$, (rad/s) per axis unit.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        kv: Option<f64>,
        /// $K_p$, V/(rad/s).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        kp: Option<f64>,
        /// $K_i$, V/rad.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ki: Option<f64>,
        /// Desired poles instead of `kv`, `kp`, `ki`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        design: Option<PoleDesign>,
        /// $V_{ff}$, dimensionless, default 0.
        #[serde(default)]
        vff: f64,
        /// $B_{ff}$, dimensionless, default 0.
        #[serde(default)]
        bff: f64,
        /// $J_{ff}$, dimensionless, default 0.
        #[serde(default)]
        jff: f64,
    },
    /// PID on position error ([`PidGains`]). With `design`, the gains follow from $a_1, a_2, a_3$.
    Pid {
        /// $K_p$, V per axis unit.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        kp: Option<f64>,
        /// $K_i$, V/(axis unit·s).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ki: Option<f64>,
        /// $K_d$, V·s per axis unit.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        kd: Option<f64>,
        /// Desired poles instead of `kp`, `ki`, `kd`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        design: Option<PoleDesign>,
        /// $J_{ff}$, dimensionless, default 0.
        #[serde(default)]
        jff: f64,
        /// $B_{ff}$, dimensionless, default 0.
        #[serde(default)]
        bff: f64,
    },
    /// Adaptive sliding mode ([`SmcGains`]). With `design`: $\lambda = p$,
    /// $K_s = 2\zeta\omega_n J_e$, $\rho = \omega_n^2 J_e$ and exact estimates.
    Smc {
        /// $\lambda$, 1/s.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        lambda: Option<f64>,
        /// $K_s$, V·s per axis unit.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ks: Option<f64>,
        /// $\rho$, V/(axis unit·s).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        rho: Option<f64>,
        /// $\hat J_e$, V·s² per axis unit. Default: the exact $J/(K_a K_t r_g)$.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        je_hat: Option<f64>,
        /// $\hat B_e$, V·s per axis unit. Default: the exact $B/(K_a K_t r_g)$.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        be_hat: Option<f64>,
        /// Desired poles instead of `lambda`, `ks`, `rho` (needs exact estimates: leave
        /// `je_hat`, `be_hat` out).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        design: Option<PoleDesign>,
    },
}

impl ControllerSpec {
    /// `"p-pi"`, `"pid"` or `"smc"`.
    pub fn kind(&self) -> &'static str {
        match self {
            ControllerSpec::PPi { .. } => "p-pi",
            ControllerSpec::Pid { .. } => "pid",
            ControllerSpec::Smc { .. } => "smc",
        }
    }
}

impl From<Controller> for ControllerSpec {
    /// The gains form of a checked controller (for writing designed gains back out).
    fn from(c: Controller) -> Self {
        match c {
            Controller::PPi(g) => ControllerSpec::PPi {
                kv: Some(g.kv),
                kp: Some(g.kp),
                ki: Some(g.ki),
                design: None,
                vff: g.vff,
                bff: g.bff,
                jff: g.jff,
            },
            Controller::Pid(g) => ControllerSpec::Pid {
                kp: Some(g.kp),
                ki: Some(g.ki),
                kd: Some(g.kd),
                design: None,
                jff: g.jff,
                bff: g.bff,
            },
            Controller::Smc(g) => ControllerSpec::Smc {
                lambda: Some(g.lambda),
                ks: Some(g.ks),
                rho: Some(g.rho),
                je_hat: Some(g.je_hat),
                be_hat: Some(g.be_hat),
                design: None,
            },
        }
    }
}

/// Position encoder: quantisation and optional seeded Gaussian noise. The reading is
/// $\hat x = q\,\mathrm{round}((x + n)/q)$ with $n \sim \mathcal N(0, \sigma^2)$ (no rounding when
/// $q = 0$).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Encoder {
    /// Quantisation step $q$, axis units (default 1e-4: 0.1 µm or 0.0001°). 0 turns it off.
    pub resolution: f64,
    /// Standard deviation $\sigma$ of the additive reading noise, axis units (default 0: off).
    pub noise_std: f64,
    /// Seed of the noise generator (ChaCha8), default 0. Same seed → bit-identical traces.
    pub seed: u64,
}

impl Default for Encoder {
    fn default() -> Self {
        Encoder {
            resolution: 1e-4,
            noise_std: 0.0,
            seed: 0,
        }
    }
}

impl Encoder {
    /// An ideal encoder: no quantisation, no noise.
    pub fn ideal() -> Encoder {
        Encoder {
            resolution: 0.0,
            noise_std: 0.0,
            seed: 0,
        }
    }

    /// Resolution and noise non-negative and finite.
    pub fn validate(&self) -> Result<(), Error> {
        non_negative("encoder.resolution", self.resolution)?;
        non_negative("encoder.noise_std", self.noise_std)?;
        sane("encoder.resolution", self.resolution)?;
        sane("encoder.noise_std", self.noise_std)
    }
}

/// Default servo (controller) rate, Hz.
pub const DEFAULT_SERVO_RATE_HZ: f64 = 20_000.0;

/// Highest servo rate accepted, Hz (the simulation's cost grows with it).
pub const MAX_SERVO_RATE_HZ: f64 = 1.0e6;

/// Magnitudes outside this range are typos, not machines (and overflow the simulation: a
/// subnormal encoder step has an infinite reciprocal).
const SANE: std::ops::RangeInclusive<f64> = 1e-12..=1e12;

/// 0, or a magnitude in [`SANE`].
pub(crate) fn sane(name: &'static str, v: f64) -> Result<(), Error> {
    if v == 0.0 || SANE.contains(&v.abs()) {
        Ok(())
    } else {
        Err(Error::BadParameter {
            name,
            value: v,
            expected: "0 or of magnitude between 1e-12 and 1e12",
        })
    }
}

pub(crate) fn finite(name: &'static str, v: f64) -> Result<(), Error> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(Error::BadParameter {
            name,
            value: v,
            expected: "finite",
        })
    }
}

pub(crate) fn positive(name: &'static str, v: f64) -> Result<(), Error> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::BadParameter {
            name,
            value: v,
            expected: "positive and finite",
        })
    }
}

pub(crate) fn non_negative(name: &'static str, v: f64) -> Result<(), Error> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(Error::BadParameter {
            name,
            value: v,
            expected: "non-negative and finite",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::presets::table1_drive;
    use approx::assert_relative_eq;

    #[test]
    fn pid_has_b2_equal_a2_and_smc_with_exact_estimates_is_unity() {
        // Truth: docs/drive-model.md. PID: the derivative acts on e, so b2 = a2 (unlike P-PI, whose
        // Table 1 b2 = 37258.98 differs from a2 = 48421.586). SMC with exact estimates: every
        // coefficient of the numerator equals the denominator's, G_track = 1 at every frequency.
        let plant = table1_drive().plant;
        let pid = Controller::Pid(PidGains {
            kp: 30.0,
            ki: 900.0,
            kd: 1.3,
            jff: 0.2,
            bff: 0.1,
        })
        .closed_loop_model(&plant);
        assert_eq!(pid.b2, pid.a2);
        let smc = ControllerSpec::Smc {
            lambda: Some(60.0),
            ks: Some(0.03),
            rho: Some(3.5),
            je_hat: None,
            be_hat: None,
            design: None,
        }
        .resolve(&plant)
        .unwrap()
        .closed_loop_model(&plant);
        assert_relative_eq!(smc.b0, 1.0, max_relative = 1e-14);
        assert_relative_eq!(smc.b1, smc.a1, max_relative = 1e-14);
        assert_relative_eq!(smc.b2, smc.a2, max_relative = 1e-14);
        for f_hz in [0.01, 0.1, 1.0, 10.0, 30.0, 100.0, 1000.0] {
            let g = smc.tracking_frf(std::f64::consts::TAU * f_hz);
            assert!(
                (g - nalgebra::Complex::new(1.0, 0.0)).norm() < 1e-12,
                "{f_hz} Hz: {g}"
            );
        }
        // Mismatched estimates break the cancellation.
        let off = Controller::Smc(SmcGains {
            lambda: 60.0,
            ks: 0.03,
            rho: 3.5,
            je_hat: 0.8 * plant.je(),
            be_hat: 0.0,
        })
        .closed_loop_model(&plant);
        assert!((off.tracking_frf(std::f64::consts::TAU * 30.0) - 1.0).norm() > 1e-3);
    }
}
