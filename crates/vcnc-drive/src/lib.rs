//! Feed drives for vcnc: the "true" machine (plant, controllers, encoder) whose dynamics vcnc
//! identifies, and the 7-parameter closed-loop model the identifier fits (docs/drive-model.md).
//!
//! - [`params`]: the parts of a drive as plain data ([`Plant`], [`ControllerSpec`] with gains or
//!   desired poles, [`Encoder`]); [`drive`]: a whole drive as the machine file holds it
//!   ([`DriveParams`]), checked into a [`Drive`] by [`DriveParams::validate`] (raw → checked,
//!   like ripgrep's `LowArgs` → `HiArgs`), with the stability of the sampled loop (the
//!   private module `stability`: matrices from the law's and the plant step's constants, not a
//!   run of the engine).
//! - [`design`]: P-PI, PID and sliding-mode gains from desired poles.
//! - [`engine`]: the drive in the time domain at the servo rate ([`Drive::simulate`] →
//!   [`DriveTrace`]): one engine for the ideal drive and the drives with effects, on one drive
//!   or four in SIMD lanes (private modules: `law`, the control laws; `plant`, the plant's exact
//!   step; `lane`, the number type of one drive or four).
//! - [`model`]: the closed-loop model ([`ClosedLoopModel`]) with poles, FRFs and simulation.
//! - [`effects`]: what real drives add to the rigid plant, each an optional table with physical
//!   units (docs/machine-file.md#drive-effects): two-mass compliance and backlash ([`Compliance`]),
//!   Stribeck and pre-sliding friction ([`Friction`]), current loop and torque limit
//!   ([`CurrentLoop`]), feedback sensor, dead time and velocity filter ([`Feedback`]), the
//!   control's reference filter and interpolation delay ([`ReferenceShaping`]). Absent tables
//!   leave the ideal drive bit for bit.
//! - [`frf`]: the true drive's frequency response measured by simulation ([`Drive::measure_frf`]).
//! - [`drive_model`]: model structures beyond the paper ([`DriveModel`]: dead time, reference
//!   filter, extra pole), with simulation from positions alone or with derivatives.
//! - [`presets`]: the paper's Table 1 drive and the NMV5000 axes designed from Table 3.
//! - [`stream`]: the true drives and the models fed the reference a piece at a time
//!   ([`Drive::stream`] → [`DriveStream`], [`DriveModel::stream`] → [`ModelStream`]): state
//!   kept between pieces, memory O(piece), results the whole run's bit for bit for any split
//!   (the whole-run simulations are these streams fed everything at once).
//! - [`batch`]: drives that share a loop structure in SIMD lanes, streamed ([`GroupStream`]) or
//!   whole ([`simulate_batch`]).
//!
//! ```
//! use vcnc_drive::{Reference, SimOptions, table1_drive};
//!
//! let drive = table1_drive().validate()?; // the paper's Table 1 P-PI drive, Tc = 0.3 N m
//! let model = drive.closed_loop_model(); // a1 = 238.4335, a2 = 48421.586, ...
//! let poles = model.poles().expect("finite");
//! assert!((poles.wn_hz() - 30.569).abs() < 1e-3);
//!
//! // A 100 mm/s ramp sampled at 1 ms, run through the true drive at 20 kHz.
//! let n = 2000;
//! let pos: Vec<f64> = (0..n).map(|k| 100.0 * k as f64 * 1e-3).collect();
//! let (vel, acc) = (vec![100.0; n], vec![0.0; n]);
//! let r = Reference { pos: &pos, vel: &vel, acc: &acc };
//! let trace = drive.simulate(r, 1e-3)?;
//! let x_model = model.simulate(r, 1e-3, &SimOptions::default())?;
//! // Steady following error (1 - Vff) V / (Kv rg) = 0.449 mm; the model agrees to a few µm
//! // (friction and the 0.1 µm encoder are on in the drive).
//! let e = pos[n - 1] - trace.position[n - 1];
//! assert!((e - 0.4488).abs() < 2e-3);
//! assert!((trace.position[n - 1] - x_model[n - 1]).abs() < 5e-3);
//! # Ok::<(), vcnc_drive::Error>(())
//! ```

pub mod batch;
pub mod design;
pub mod drive;
pub mod drive_model;
pub mod effects;
pub mod engine;
pub mod frf;
mod lane;
mod law;
pub mod model;
pub mod nominal;
pub mod params;
mod plant;
pub mod presets;
mod stability;
pub mod stream;
#[cfg(test)]
mod test_util;

pub use batch::{BATCH_LANES, GroupStream, batch_groups, simulate_batch, simulate_batch_into};
pub use design::{design_pid, design_ppi, design_smc};
pub use drive::{Drive, DriveParams};
pub use drive_model::{
    DriveModel, MAX_ACTUAL_LATENCY_S, MAX_DELAY_S, ModelInput, ModelRun, Realisation,
    ReferenceFilter,
};
pub use effects::{
    Compliance, CurrentLoop, CurrentLoopOrder, Effects, Feedback, FeedbackSource, Friction,
    FrictionLocation, ReferenceShaping, ShapingFilter,
};
pub use engine::{DriveTrace, simulate_drive};
pub use frf::{Frf, FrfKind, FrfOptions};
pub use model::{ClosedLoopModel, Discretized, Integrator, Poles, Reference, SimOptions};
pub use nominal::{MAX_FIR_TAPS, NominalFilter, NominalStream};
pub use params::{
    Controller, ControllerSpec, Encoder, PPiGains, PidGains, Plant, PoleDesign, SmcGains,
};
pub use presets::{NMV5000_TABLE3, TABLE1_MODEL, nmv5000_axis_design, table1_drive};
pub use stream::{Channels, DriveStream, ModelStream};
pub use vcnc_axis::AxisName;

/// Errors of the drive crate. Each variant carries the values needed to act on it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A signal had no samples.
    #[error("the reference signal is empty")]
    EmptySignal,
    /// Position, velocity and acceleration slices of different lengths.
    #[error("signal lengths differ: position {pos}, velocity {vel}, acceleration {acc} samples")]
    LengthMismatch {
        /// Position samples.
        pos: usize,
        /// Velocity samples.
        vel: usize,
        /// Acceleration samples.
        acc: usize,
    },
    /// NaN or infinity in an input signal.
    #[error("the reference {signal} is not finite at sample {index}")]
    NonFinite {
        /// Which signal.
        signal: &'static str,
        /// First bad sample.
        index: usize,
    },
    /// Sample period not positive and finite.
    #[error("sample period must be positive and finite, got {ts} s")]
    BadSamplePeriod {
        /// The period given, s.
        ts: f64,
    },
    /// Model coefficients not finite, or their discretisation overflowed.
    #[error("the closed-loop model has non-finite coefficients or cannot be discretised")]
    NonFiniteModel,
    /// A physical parameter, gain or setting outside its valid range. `name` is the key path
    /// below the axis (`plant.j`, `controller.kv`, `servo_rate_hz`, ...).
    #[error("{name} = {value:?} is invalid: it must be {expected}")]
    BadParameter {
        /// Key path of the parameter, e.g. `plant.j`.
        name: &'static str,
        /// The value given (in the parameter's own unit).
        value: f64,
        /// What a valid value is, e.g. "positive and finite".
        expected: &'static str,
    },
    /// A controller given neither complete gains nor a pole design.
    #[error(
        "controller kind = \"{kind}\" needs `{gain}` (or `design = {{ p_hz, wn_hz, zeta }}` instead of gains)"
    )]
    MissingGain {
        /// Controller kind (`p-pi`, `pid`, `smc`).
        kind: &'static str,
        /// The missing key.
        gain: &'static str,
    },
    /// A controller given both a gain and a pole design.
    #[error(
        "controller kind = \"{kind}\" has both `{gain}` and `design`: give gains or desired poles, not both"
    )]
    GainsAndDesign {
        /// Controller kind (`p-pi`, `pid`, `smc`).
        kind: &'static str,
        /// The gain that conflicts with the design.
        gain: &'static str,
    },
    /// The closed loop has a pole in the right half plane (or on the imaginary axis other than a
    /// single pole at the origin of a drive without integral action).
    #[error("{}", unstable_message(model, poles))]
    Unstable {
        /// Closed-loop model of the rejected gains.
        model: ClosedLoopModel,
        /// Its poles, when they can be written as $(p, \omega_n, \zeta)$.
        poles: Option<Poles>,
    },
    /// Desired poles not finite or not strictly stable.
    #[error(
        "desired poles p = {p_hz} Hz, wn = {wn_hz} Hz, zeta = {zeta} are not a stable design: each must be positive and finite"
    )]
    BadDesign {
        /// Real pole, Hz.
        p_hz: f64,
        /// Natural frequency, Hz.
        wn_hz: f64,
        /// Damping ratio.
        zeta: f64,
    },
    /// P-PI design from poles: the quadratic for $K_v r_g$ has no real root (docs/drive-model.md).
    #[error(
        "desired poles p = {p_hz} Hz, wn = {wn_hz} Hz, zeta = {zeta} cannot be reached by a P-PI cascade \
         on a plant with B/J = {b_over_j} 1/s: Kv*rg must solve P K^2 - a2 K + a3 = 0, whose discriminant \
         a2^2 - 4 P a3 = {discriminant} is negative (raise zeta or p relative to wn)"
    )]
    Unreachable {
        /// Real pole, Hz.
        p_hz: f64,
        /// Natural frequency, Hz.
        wn_hz: f64,
        /// Damping ratio.
        zeta: f64,
        /// Plant's mechanical pole $B/J$, 1/s.
        b_over_j: f64,
        /// $a_2^2 - 4 P a_3$, 1/s⁴.
        discriminant: f64,
    },
    /// The design needs a negative proportional or derivative gain: the desired $a_1$ is below
    /// the damping the plant already has.
    #[error(
        "these poles need {gain} = {value} < 0: the desired a1 = {a1} 1/s is below the plant's own \
         damping B/J = {b_over_j} 1/s (choose faster poles)"
    )]
    NegativeGain {
        /// Gain name (`kp`, `kd`).
        gain: &'static str,
        /// The gain the design would need.
        value: f64,
        /// Desired $a_1 = p + 2\zeta\omega_n$, 1/s.
        a1: f64,
        /// Plant $B/J$, 1/s.
        b_over_j: f64,
    },
    /// Servo rate not an integer multiple of the logging rate.
    #[error(
        "the servo rate {servo_rate_hz} Hz is not an integer multiple (>= 1) of the logging rate \
         1/ts = {:.3} Hz", 1.0 / ts
    )]
    ServoRate {
        /// Servo rate, Hz.
        servo_rate_hz: f64,
        /// Logging period, s.
        ts: f64,
    },
    /// A matrix exponential would be asked for an absurdly stiff system (nalgebra's scaling and
    /// squaring loops practically forever above a 1-norm of about 1e38).
    #[error(
        "the dynamics are too stiff to discretise: |A·T|₁ = {norm:e} exceeds {limit:e}; check the \
         magnitudes of the plant, gains and model coefficients"
    )]
    TooStiff {
        /// 1-norm of the matrix whose exponential was needed.
        norm: f64,
        /// The largest accepted.
        limit: f64,
    },
    /// The continuous closed loop is stable but the sampled one (controller at the servo rate)
    /// is not.
    #[error(
        "the closed loop is stable in continuous time but unstable when the controller runs at \
         {servo_rate_hz} Hz: sampled spectral radius {radius:.6} > 1; raise servo_rate_hz or \
         lower the gains"
    )]
    SampledUnstable {
        /// Servo rate, Hz.
        servo_rate_hz: f64,
        /// Largest |eigenvalue| of the sampled loop's transition matrix.
        radius: f64,
    },
    /// Two keys that are alternatives (e.g. `compliance.stiffness` and `compliance.mode_hz`) were
    /// both given, or neither.
    #[error("{}", alternatives_message(name, other, *both))]
    Alternatives {
        /// Key path of the first alternative (the one the error points at).
        name: &'static str,
        /// Key path of the other.
        other: &'static str,
        /// Both given (true) or neither (false).
        both: bool,
    },
    /// The ideal loop is stable but the loop with the drive's effects (compliance, current loop,
    /// dead time, velocity filter), linearised at rest, is not.
    #[error(
        "the closed loop with its compliance, current loop, dead time and velocity filter is \
         unstable at {servo_rate_hz} Hz: sampled spectral radius {radius:.6} > 1 (a mode at \
         {mode_hz:.1} Hz grows at {growth_per_s:.3} 1/s); lower the gains, stiffen or damp the transmission, shorten the dead \
         time or widen the filters"
    )]
    EffectsUnstable {
        /// Servo rate, Hz.
        servo_rate_hz: f64,
        /// Largest |eigenvalue| of the linearised sampled loop.
        radius: f64,
        /// Frequency of that eigenvalue as a continuous mode $|\Im \ln z| / (2\pi h)$, Hz.
        mode_hz: f64,
        /// Its growth rate $\Re \ln z / h$, 1/s.
        growth_per_s: f64,
    },
    /// A drive of a [`GroupStream`] failed: which one (its index in the group) and why.
    #[error("drive {drive} of the group: {source}")]
    Group {
        /// Index of the drive in the group.
        drive: usize,
        /// Its error.
        #[source]
        source: Box<Error>,
    },
    /// A piece fed to one drive of a [`GroupStream`] is not as long as the first drive's: the
    /// drives of a group share the clock.
    #[error(
        "the piece has {samples} samples, the group's first piece {expected}: every drive of a \
         group is fed the same number of samples at a time"
    )]
    PieceLength {
        /// Samples of this piece.
        samples: usize,
        /// Samples of the first drive's piece.
        expected: usize,
    },
    /// No preset for this axis name.
    #[error("no NMV5000 design for axis {axis}: expected one of X, Y, Z, A, C")]
    UnknownAxis {
        /// The axis asked for.
        axis: AxisName,
    },
}

impl Error {
    /// True when drive parameters are at fault (exit code 2: a bad value, unstable or
    /// unreachable gains); false for a failure to simulate signals the caller built (exit
    /// code 1).
    pub fn is_bad_input(&self) -> bool {
        match self {
            Error::BadParameter { .. }
            | Error::MissingGain { .. }
            | Error::GainsAndDesign { .. }
            | Error::Unstable { .. }
            | Error::BadDesign { .. }
            | Error::Unreachable { .. }
            | Error::NegativeGain { .. }
            | Error::ServoRate { .. }
            | Error::TooStiff { .. }
            | Error::SampledUnstable { .. }
            | Error::UnknownAxis { .. }
            | Error::Alternatives { .. }
            | Error::EffectsUnstable { .. } => true,
            Error::Group { source, .. } => source.is_bad_input(),
            Error::EmptySignal
            | Error::PieceLength { .. }
            | Error::LengthMismatch { .. }
            | Error::NonFinite { .. }
            | Error::BadSamplePeriod { .. }
            | Error::NonFiniteModel => false,
        }
    }
}

fn alternatives_message(name: &str, other: &str, both: bool) -> String {
    if both {
        format!("`{name}` and `{other}` are alternatives: give one of them, not both")
    } else {
        format!("give `{name}` or `{other}`")
    }
}

fn unstable_message(model: &ClosedLoopModel, poles: &Option<Poles>) -> String {
    use std::f64::consts::TAU;
    let roots = model.roots();
    let mut s = String::from("the closed loop is unstable: poles at s/2pi = ");
    for (i, r) in roots.iter().enumerate() {
        if i > 0 {
            s.push_str(", ");
        }
        if r.im == 0.0 {
            s.push_str(&format!("{:.4} Hz", r.re / TAU));
        } else {
            s.push_str(&format!("{:.4}{:+.4}i Hz", r.re / TAU, r.im / TAU));
        }
    }
    if let Some(p) = poles {
        s.push_str(&format!(
            " (p = {:.4} Hz, wn = {:.4} Hz, zeta = {:.4})",
            p.p_hz(),
            p.wn_hz(),
            p.zeta
        ));
    }
    s.push_str(&format!(
        "; a1 = {}, a2 = {}, a3 = {} (Routh-Hurwitz needs a1 > 0, a3 >= 0, a1 a2 > a3)",
        model.a1, model.a2, model.a3
    ));
    s
}
