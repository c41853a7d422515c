//! One feed drive, raw and checked, like ripgrep's `LowArgs` → `HiArgs`:
//!
//! - [`DriveParams`] is what a user writes (the parts of [`crate::params`] and the effect tables
//!   of [`crate::effects`]). Its controller is a [`ControllerSpec`]: gains, or desired poles
//!   (`design = { p_hz, wn_hz, zeta }`) to design the gains from, in which case the gains are
//!   optional. Nothing is checked yet.
//! - [`Drive`] is what [`DriveParams::validate`] returns: every number checked, the gains
//!   resolved into a [`Controller`], the closed loop known to be stable as sampled at the servo
//!   rate, with its effects too (the crate's `stability` module: an analysis of the plant and
//!   law data, not a run of the engine). Only a `Drive` can be simulated ([`crate::engine`]).

use nalgebra::{Complex, DMatrix, SMatrix};
use serde::{Deserialize, Serialize};

use crate::Error;
use crate::design::{design_pid, design_ppi, design_smc};
use crate::effects::{
    Compliance, CurrentLoop, EffectTables, Effects, Feedback, Friction, RawEffects,
    ReferenceShaping,
};
use crate::model::{ClosedLoopModel, Poles};
use crate::params::{
    Controller, ControllerSpec, DEFAULT_SERVO_RATE_HZ, Encoder, MAX_SERVO_RATE_HZ, PPiGains,
    PidGains, Plant, SmcGains, positive,
};
use crate::stability;

/// `Some(value)` of a required gain, or the error naming it.
fn need(kind: &'static str, gain: &'static str, v: Option<f64>) -> Result<f64, Error> {
    v.ok_or(Error::MissingGain { kind, gain })
}

/// Error when a gain is given together with a design.
fn forbid(kind: &'static str, gains: &[(&'static str, Option<f64>)]) -> Result<(), Error> {
    match gains.iter().find(|(_, v)| v.is_some()) {
        Some((gain, _)) => Err(Error::GainsAndDesign { kind, gain }),
        None => Ok(()),
    }
}

impl ControllerSpec {
    /// Gains of this spec on `plant` (which should be valid, see [`Plant::validate`]): the gains
    /// as given, or designed from `design` (docs/drive-model.md, [`crate::design`]). Errors when a gain
    /// is missing, when gains and a design are both given, or when the design is impossible.
    /// Does not check stability (see [`DriveParams::validate`]).
    pub fn resolve(&self, plant: &Plant) -> Result<Controller, Error> {
        let kind = self.kind();
        match *self {
            ControllerSpec::PPi {
                kv,
                kp,
                ki,
                design,
                vff,
                bff,
                jff,
            } => match design {
                Some(d) => {
                    forbid(kind, &[("kv", kv), ("kp", kp), ("ki", ki)])?;
                    d.validate()?;
                    Ok(Controller::PPi(design_ppi(
                        plant,
                        &d.poles(),
                        vff,
                        bff,
                        jff,
                    )?))
                }
                None => Ok(Controller::PPi(PPiGains {
                    kv: need(kind, "kv", kv)?,
                    kp: need(kind, "kp", kp)?,
                    ki: need(kind, "ki", ki)?,
                    vff,
                    bff,
                    jff,
                })),
            },
            ControllerSpec::Pid {
                kp,
                ki,
                kd,
                design,
                jff,
                bff,
            } => match design {
                Some(d) => {
                    forbid(kind, &[("kp", kp), ("ki", ki), ("kd", kd)])?;
                    d.validate()?;
                    Ok(Controller::Pid(design_pid(plant, &d.poles(), jff, bff)?))
                }
                None => Ok(Controller::Pid(PidGains {
                    kp: need(kind, "kp", kp)?,
                    ki: need(kind, "ki", ki)?,
                    kd: need(kind, "kd", kd)?,
                    jff,
                    bff,
                })),
            },
            ControllerSpec::Smc {
                lambda,
                ks,
                rho,
                je_hat,
                be_hat,
                design,
            } => match design {
                Some(d) => {
                    forbid(
                        kind,
                        &[
                            ("lambda", lambda),
                            ("ks", ks),
                            ("rho", rho),
                            ("je_hat", je_hat),
                            ("be_hat", be_hat),
                        ],
                    )?;
                    d.validate()?;
                    Ok(Controller::Smc(design_smc(plant, &d.poles())?))
                }
                None => Ok(Controller::Smc(SmcGains {
                    lambda: need(kind, "lambda", lambda)?,
                    ks: need(kind, "ks", ks)?,
                    rho: need(kind, "rho", rho)?,
                    je_hat: je_hat.unwrap_or_else(|| plant.je()),
                    be_hat: be_hat.unwrap_or_else(|| plant.be()),
                })),
            },
        }
    }
}

fn default_servo_rate_hz() -> f64 {
    DEFAULT_SERVO_RATE_HZ
}

/// Everything about one feed drive, as written in the machine file (unchecked). See the module
/// documentation for the raw → checked split.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveParams {
    /// Mechanics and amplifier.
    pub plant: Plant,
    /// Controller gains or desired poles.
    pub controller: ControllerSpec,
    /// Position encoder (default: 1e-4 axis units, no noise).
    #[serde(default)]
    pub encoder: Encoder,
    /// Rate at which the controller runs, Hz (default 20 000). Must be an integer multiple of
    /// the logging rate $1/T_s$ when simulating.
    #[serde(default = "default_servo_rate_hz")]
    pub servo_rate_hz: f64,
    /// Two-mass transmission and backlash (default: rigid). See [`Compliance`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compliance: Option<Compliance>,
    /// Stribeck, direction-dependent and pre-sliding friction (default: the plant's symmetric
    /// Coulomb friction). See [`Friction`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<Friction>,
    /// Current-loop dynamics and torque limit (default: ideal current loop, no limit). See
    /// [`CurrentLoop`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub current_loop: Option<CurrentLoop>,
    /// Feedback sensor, dead time and velocity filter (default: encoder on the load, no delay,
    /// no filter). See [`Feedback`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feedback: Option<Feedback>,
    /// The control's reference filter and interpolation delay (default: none). See
    /// [`ReferenceShaping`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<ReferenceShaping>,
}

impl DriveParams {
    /// Checks every number, resolves the controller (designing gains from poles if asked) and
    /// rejects unstable closed loops ([`Error::Unstable`] names the poles). A drive without
    /// integral action ($a_3 = 0$: a single pole at the origin cancelled by the numerator, with
    /// the other two stable) is accepted.
    ///
    /// The effect tables are checked against the plant, encoder and servo rate
    /// ([`Effects::check`]); a drive with effects must also be stable as linearised at rest with
    /// them ([`Error::EffectsUnstable`]).
    pub fn validate(&self) -> Result<Drive, Error> {
        self.plant.validate()?;
        self.encoder.validate()?;
        positive("servo_rate_hz", self.servo_rate_hz)?;
        let controller = self.controller.resolve(&self.plant)?;
        let drive = Drive::new(
            self.plant.clone(),
            controller,
            self.encoder.clone(),
            self.servo_rate_hz,
        )?;
        let effects = Effects::check(
            self.effect_tables(),
            &self.plant,
            &self.encoder,
            self.servo_rate_hz,
        )?;
        drive.with_effects(effects)
    }

    /// The five effect tables, borrowed.
    pub fn effect_tables(&self) -> EffectTables<'_> {
        EffectTables {
            compliance: self.compliance.as_ref(),
            friction: self.friction.as_ref(),
            current_loop: self.current_loop.as_ref(),
            feedback: self.feedback.as_ref(),
            reference: self.reference.as_ref(),
        }
    }

    /// The drive without any effect table (the rigid ideal drive of the same plant and gains).
    pub fn ideal(&self) -> DriveParams {
        DriveParams {
            compliance: None,
            friction: None,
            current_loop: None,
            feedback: None,
            reference: None,
            ..self.clone()
        }
    }

    /// The closed-loop model of these parameters (validates first: a design may be impossible,
    /// gains may be unstable). See [`Controller::closed_loop_model`].
    pub fn closed_loop_model(&self) -> Result<ClosedLoopModel, Error> {
        Ok(self.validate()?.closed_loop_model())
    }
}

/// A checked drive: valid plant and encoder, resolved and stable controller. Only
/// [`DriveParams::validate`] and [`Drive::new`] make one.
#[derive(Debug, Clone, PartialEq)]
pub struct Drive {
    plant: Plant,
    controller: Controller,
    encoder: Encoder,
    servo_rate_hz: f64,
    model: ClosedLoopModel,
    effects: Effects,
}

impl Drive {
    /// Checks the parts (see [`DriveParams::validate`]).
    pub fn new(
        plant: Plant,
        controller: Controller,
        encoder: Encoder,
        servo_rate_hz: f64,
    ) -> Result<Drive, Error> {
        plant.validate()?;
        encoder.validate()?;
        positive("servo_rate_hz", servo_rate_hz)?;
        controller.validate_gains()?;
        if servo_rate_hz > MAX_SERVO_RATE_HZ {
            return Err(Error::BadParameter {
                name: "servo_rate_hz",
                value: servo_rate_hz,
                expected: "at most 1 MHz",
            });
        }
        let model = controller.closed_loop_model(&plant);
        if !model.is_finite() {
            return Err(Error::NonFiniteModel);
        }
        if !model.is_marginally_stable() {
            return Err(Error::Unstable {
                model,
                poles: model.poles(),
            });
        }
        let drive = Drive {
            plant,
            controller,
            encoder,
            servo_rate_hz,
            model,
            effects: Effects::default(),
        };
        drive.check_sampled_stability()?;
        Ok(drive)
    }

    /// The same drive with checked `effects` (see [`Effects::check`], which must have been run
    /// against this drive's plant, encoder and servo rate). Rejects a loop that the effects
    /// destabilise ([`Error::EffectsUnstable`]: the spectral radius of
    /// [`Drive::effects_transition_matrix`] exceeds 1).
    pub fn with_effects(&self, effects: Effects) -> Result<Drive, Error> {
        let drive = Drive {
            effects,
            ..self.clone()
        };
        if !effects.is_ideal() {
            stability::check_effects(&self.plant, &self.controller, &effects, self.servo_rate_hz)?;
        }
        Ok(drive)
    }

    /// The drive's effects (`Effects::default()`: the ideal rigid drive).
    pub fn effects(&self) -> &Effects {
        &self.effects
    }

    /// Rejects a loop that is stable in continuous time but not as sampled at the servo rate
    /// (too much gain for the servo period): the spectral radius of
    /// [`Drive::sampled_transition_matrix`] must not exceed 1 (a drive without integral action
    /// keeps its pole at $z = 1$).
    fn check_sampled_stability(&self) -> Result<(), Error> {
        stability::check_sampled(&self.plant, &self.controller, self.servo_rate_hz)
    }

    /// Transition matrix $M$ of the sampled linear closed loop at the servo rate (friction,
    /// quantisation, noise and saturation off, zero reference) of the ideal drive (for a drive
    /// with effects, of its rigid ideal part: see [`Drive::effects_transition_matrix`]):
    /// $z_{k+1} = M z_k$ with $z = [x, \dot x, \text{integrator}, \hat x_{k-1}, \hat x_{k-2}]$.
    /// Made from the law's and the plant step's constants (not by running the engine).
    pub fn sampled_transition_matrix(&self) -> Result<SMatrix<f64, 5, 5>, Error> {
        stability::ideal_matrix(&self.plant, &self.controller, self.servo_rate_hz)
    }

    /// Effective continuous poles of the sampled closed loop: the three slowest eigenvalues $z$
    /// of [`Drive::sampled_transition_matrix`] (the other two are fast parasitic modes of the
    /// velocity estimator and the hold) mapped by $s = \ln(z)/h$. Returns the three poles (rad/s)
    /// and their $(p, \omega_n, \zeta)$ form. docs/drive-model.md: at 20 kHz they lie within 1 % of
    /// the continuous design; at 1 kHz they move by several percent.
    pub fn effective_poles(&self) -> Result<([Complex<f64>; 3], Poles), Error> {
        stability::effective_poles(&self.plant, &self.controller, self.servo_rate_hz)
    }

    /// Transition matrix $M$ of the loop with its effects at the servo rate, linearised at rest
    /// (friction off except viscous, backlash closed, ideal encoders, no limit, zero
    /// reference): $z_{k+1} = M z_k$ with $z$ = mechanical and current-loop states, integrator,
    /// previous position error, the two previous filtered velocity-path positions, and the
    /// readings pending in the dead-time line. For an ideal drive it is
    /// the matrix of the general loop, not of [`Drive::sampled_transition_matrix`] (same
    /// eigenvalues up to the state basis).
    pub fn effects_transition_matrix(&self) -> Result<DMatrix<f64>, Error> {
        stability::effects_matrix(
            &self.plant,
            &self.controller,
            &self.effects,
            self.servo_rate_hz,
        )
    }

    /// The plant.
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The resolved controller (designed gains included).
    pub fn controller(&self) -> &Controller {
        &self.controller
    }

    /// The encoder.
    pub fn encoder(&self) -> &Encoder {
        &self.encoder
    }

    /// Servo rate, Hz.
    pub fn servo_rate_hz(&self) -> f64 {
        self.servo_rate_hz
    }

    /// The continuous closed-loop model (docs/drive-model.md), see [`Controller::closed_loop_model`].
    pub fn closed_loop_model(&self) -> ClosedLoopModel {
        self.model
    }

    /// Back to plain parameters, with the controller as gains (designs resolved).
    pub fn params(&self) -> DriveParams {
        let RawEffects {
            compliance,
            friction,
            current_loop,
            feedback,
            reference,
        } = self
            .effects
            .tables(&self.plant, &self.encoder, self.servo_rate_hz);
        DriveParams {
            plant: self.plant.clone(),
            controller: self.controller.into(),
            encoder: self.encoder.clone(),
            servo_rate_hz: self.servo_rate_hz,
            compliance,
            friction,
            current_loop,
            feedback,
            reference,
        }
    }

    /// The same drive with another encoder (e.g. to switch quantisation off). The effects are
    /// kept as checked (a closed-loop two-mass drive's motor encoder keeps its resolution).
    pub fn with_encoder(&self, encoder: Encoder) -> Result<Drive, Error> {
        encoder.validate()?;
        Ok(Drive {
            encoder,
            ..self.clone()
        })
    }

    /// The same drive at another servo rate, Hz (effects re-checked: delays must stay whole
    /// servo periods).
    pub fn with_servo_rate_hz(&self, servo_rate_hz: f64) -> Result<Drive, Error> {
        positive("servo_rate_hz", servo_rate_hz)?;
        let mut p = self.params();
        p.servo_rate_hz = servo_rate_hz;
        p.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::PoleDesign;
    use crate::presets::table1_drive;

    #[test]
    fn gains_and_design_are_exclusive_and_gains_complete() {
        let d = PoleDesign {
            p_hz: 10.0,
            wn_hz: 30.0,
            zeta: 0.5,
        };
        let mut ppi_with_design = table1_drive().controller;
        if let ControllerSpec::PPi { design, .. } = &mut ppi_with_design {
            *design = Some(d);
        }
        let pid_without_ki = ControllerSpec::Pid {
            kp: Some(1.0),
            ki: None,
            kd: Some(0.1),
            design: None,
            jff: 0.0,
            bff: 0.0,
        };
        let smc_with_je_hat_and_design = ControllerSpec::Smc {
            lambda: None,
            ks: None,
            rho: None,
            je_hat: Some(0.1),
            be_hat: None,
            design: Some(d),
        };
        let cases = [
            (
                ppi_with_design,
                Error::GainsAndDesign {
                    kind: "p-pi",
                    gain: "kv",
                },
            ),
            (
                pid_without_ki,
                Error::MissingGain {
                    kind: "pid",
                    gain: "ki",
                },
            ),
            (
                smc_with_je_hat_and_design,
                Error::GainsAndDesign {
                    kind: "smc",
                    gain: "je_hat",
                },
            ),
        ];
        for (controller, want) in cases {
            let p = DriveParams {
                controller,
                ..table1_drive()
            };
            assert_eq!(p.validate().unwrap_err(), want);
        }
    }

    #[test]
    fn resolved_params_round_trip() {
        let d = crate::presets::nmv5000_axis_design(crate::AxisName::Y).unwrap();
        let drive = d.validate().unwrap();
        let again = drive.params().validate().unwrap();
        assert_eq!(drive, again);
        assert_eq!(drive.controller().kind(), "p-pi");
    }
}
