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

    /// The URDF parsed but is not the X Y Z / A→C table-tilting chain of docs/kinematics.md.
    #[error("{file}: not a table-tilting A/C chain: {reason}")]
    NotTableTilting {
        /// Path or source name of the URDF.
        file: String,
        /// What is wrong, with the joint or link name and the numbers, e.g.
        /// "joint 'a' axis is (0, 1, 0), expected +X".
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
    /// Every error of this crate is about its input (a URDF, a pose, a travel): exit code 2.
    pub fn is_bad_input(&self) -> bool {
        true
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
