//! The crate's one error type.

use std::fmt;

use crate::types::AxisName;

/// Every failure of this crate. Variants carry the offending values so that a message can be
/// acted on without a debugger ("A = -131.200° is out of travel -120.000° ..= 30.000° at sample 812").
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// The URDF could not be read or parsed (file missing, malformed XML, missing attribute).
    #[error("{file}: cannot read the URDF: {message}")]
    Urdf {
        /// Path of the URDF file, or the source name given to
        /// [`KinematicChain::from_urdf_str`](crate::KinematicChain::from_urdf_str).
        file: String,
        /// What urdf-rs or the file system reported.
        message: String,
    },

    /// The URDF was read where a table-tilting A/C chain is required
    /// ([`KinematicChain::from_urdf_file`](crate::KinematicChain::from_urdf_file)) and is not one.
    #[error("{file}: not a table-tilting A/C chain: {reason}")]
    NotTableTilting {
        /// Path or source name of the URDF.
        file: String,
        /// What is wrong, with the joint or link name and the numbers, e.g.
        /// "joint 'a' axis is (0, 1, 0), expected +X".
        reason: String,
    },

    /// The URDF parsed but is not a machine vcnc can use (docs/kinematics.md, "Any serial
    /// chain from a URDF").
    #[error("{file}: cannot use the URDF as a machine: {reason}")]
    Chain {
        /// Path or source name of the URDF.
        file: String,
        /// What is wrong, with the joint or link name and the numbers.
        reason: String,
    },

    /// The chain matches no closed-form family ([`KinematicChain::closed_form`](crate::KinematicChain::closed_form)).
    #[error("{file}: the chain matches no closed-form family: {reason}")]
    NoClosedForm {
        /// Path or source name of the URDF.
        file: String,
        /// Why, with the joint name or the numbers.
        reason: String,
    },

    /// The damped least-squares inverse of a chain did not reach the tool axis asked for.
    #[error(
        "the inverse kinematics did not converge{}: tool-axis error {residual:.3e} after          {iterations} iterations (an orientation this machine cannot reach, or too far from the          previous sample)",
        AtSample(*sample)
    )]
    NoConvergence {
        /// The remaining tool-axis error (unit vector difference, about rad).
        residual: f64,
        /// Iterations made.
        iterations: usize,
        /// Index of the pose in the sequence, if it came from one.
        sample: Option<usize>,
    },

    /// A chain's slides move along dependent directions at the rotary angles asked for, so no
    /// slide position puts the tool tip where it is asked.
    #[error(
        "the slides X, Y, Z move along dependent directions (determinant {det:.3e}){}",
        AtSample(*sample)
    )]
    DependentSlides {
        /// Determinant of the slides' direction matrix (unitless).
        det: f64,
        /// Index of the sample, if it came from a sequence.
        sample: Option<usize>,
    },

    /// The machine lacks an axis its kinematics needs.
    #[error("a {family} machine needs axis {axis}")]
    MissingAxis {
        /// The missing axis.
        axis: AxisName,
        /// The family, e.g. "table-tilting B/C".
        family: String,
    },

    /// The number of rotary tracks given is not the kinematics' number of rotary axes
    /// (a caller's bug: a runtime failure, not bad input).
    #[error("{got} rotary tracks given, the kinematics has {expected} rotary axes")]
    TrackCount {
        /// Rotary axes of the kinematics.
        expected: usize,
        /// Tracks given.
        got: usize,
    },

    /// A track has another number of samples than the TCP flags (a caller's bug).
    #[error("a track has {got} samples, the TCP flags {expected}")]
    TrackLength {
        /// Samples of the TCP flags.
        expected: usize,
        /// Samples of the track.
        got: usize,
    },

    /// Offsets cannot be fitted: a chain (no offsets of its own), or too few samples.
    #[error("cannot fit the offsets of a {family} machine: {reason}")]
    Fit {
        /// The family.
        family: String,
        /// Why.
        reason: String,
    },

    /// A model parameter is not usable (non-finite offset, inverted travel).
    #[error("bad parameter {name} = {value}: {reason}")]
    BadParameter {
        /// Parameter name, e.g. `r.x` or `travel of A`.
        name: String,
        /// The offending value, formatted with its unit.
        value: String,
        /// What is required.
        reason: &'static str,
    },

    /// The tool orientation vector is zero, too short or not finite, so no A, C can be derived.
    #[error(
        "bad tool orientation ({}, {}, {}){}: {reason}",
        o[0], o[1], o[2], AtSample(*sample)
    )]
    BadOrientation {
        /// The orientation vector as given (unitless).
        o: [f64; 3],
        /// Index of the pose in the sequence, if it came from one.
        sample: Option<usize>,
        /// What is wrong with it.
        reason: &'static str,
    },

    /// A tool-tip position is not finite.
    #[error("tool tip position ({}, {}, {}) mm is not finite{}", p[0], p[1], p[2], AtSample(*sample))]
    NonFinitePosition {
        /// The position as given, mm.
        p: [f64; 3],
        /// Index of the pose in the sequence, if it came from one.
        sample: Option<usize>,
    },

    /// An axis position computed by the inverse kinematics leaves its travel.
    #[error(
        "{axis} = {} is out of travel {} ..= {}{}",
        Value(*axis, *value), Value(*axis, *lower), Value(*axis, *upper), AtSample(*sample)
    )]
    OutOfTravel {
        /// Which axis.
        axis: AxisName,
        /// The required position: mm for X, Y, Z; rad for A, C (shown in degrees).
        value: f64,
        /// Lower travel limit, same unit as `value`.
        lower: f64,
        /// Upper travel limit, same unit as `value`.
        upper: f64,
        /// Index of the pose in the sequence, if it came from one.
        sample: Option<usize>,
    },

    /// Neither inverse-kinematics branch keeps every axis within travel over the whole sequence.
    #[error(
        "no inverse-kinematics branch keeps every axis within travel: branch +1: {plus}; \
         branch -1: {minus}"
    )]
    NoBranch {
        /// Why branch +1 failed.
        plus: Box<Error>,
        /// Why branch −1 failed.
        minus: Box<Error>,
    },
}

impl Error {
    /// True for errors about the input (a URDF, a pose, a travel, a parameter): exit code 2.
    /// False for a caller's bug (tracks of the wrong count or length): a runtime failure.
    pub fn is_bad_input(&self) -> bool {
        !matches!(self, Error::TrackCount { .. } | Error::TrackLength { .. })
    }
}

/// Shorthand for this crate's results.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Formats " at sample N" or nothing.
struct AtSample(Option<usize>);

impl fmt::Display for AtSample {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(k) => write!(f, " at sample {k}"),
            None => Ok(()),
        }
    }
}

/// Formats an axis value in its display unit: mm for linear axes, degrees for rotary ones.
struct Value(AxisName, f64);

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Value(axis, v) = *self;
        if axis.is_rotary() {
            write!(f, "{:.3}°", v.to_degrees())
        } else {
            write!(f, "{v:.3} mm")
        }
    }
}
