//! The crate's one error type.

use std::fmt;

/// Which input sequence an error refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Sequence {
    /// The reference (commanded) poses.
    Reference,
    /// The actual (measured or simulated) poses.
    Actual,
}

impl fmt::Display for Sequence {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Sequence::Reference => "reference",
            Sequence::Actual => "actual",
        })
    }
}

/// Every failure of this crate, carrying the offending values.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// The reference or the actual sequence has no pose.
    #[error("the {0} pose sequence is empty")]
    Empty(Sequence),

    /// A tip position or tool axis contains NaN or an infinity.
    #[error("{which} pose {sample}: {what} ({}, {}, {}) is not finite", v[0], v[1], v[2])]
    NonFinite {
        /// Which sequence.
        which: Sequence,
        /// Index of the pose in it.
        sample: usize,
        /// `"tip position (mm)"` or `"tool axis"`.
        what: &'static str,
        /// The offending vector.
        v: [f64; 3],
    },

    /// A tool axis has zero length, so no orientation error can be measured.
    #[error("{which} pose {sample}: tool axis ({}, {}, {}) has zero length", o[0], o[1], o[2])]
    ZeroOrientation {
        /// Which sequence.
        which: Sequence,
        /// Index of the pose in it.
        sample: usize,
        /// The offending vector (unitless).
        o: [f64; 3],
    },

    /// A [`SearchWindow`](crate::SearchWindow) setting is unusable.
    #[error("bad search window: {name} = {value:?}: {reason}")]
    BadWindow {
        /// Field name.
        name: &'static str,
        /// The offending value.
        value: f64,
        /// What is required.
        reason: &'static str,
    },

    /// A [`StreamLimits`](crate::StreamLimits) setting is unusable.
    #[error("bad stream limits: {name} = {value}: {reason}")]
    BadLimits {
        /// Field name.
        name: &'static str,
        /// The offending value.
        value: usize,
        /// What is required.
        reason: &'static str,
    },

    /// A streamed foot search reads a reference knot already dropped: the foot moved back, or
    /// the window grew back, farther than the knots kept behind the previous foot.
    #[error(
        "actual sample {sample}: the foot search reads reference knot {knot}, but the stream \
         keeps only {history} knots behind the previous foot (oldest held: {oldest}); raise \
         StreamLimits::history"
    )]
    HistoryExceeded {
        /// Index of the actual sample.
        sample: usize,
        /// The knot read (index among the path's knots, runs of identical poses merged).
        knot: usize,
        /// The oldest knot held.
        oldest: usize,
        /// [`StreamLimits::history`](crate::StreamLimits::history).
        history: usize,
    },

    /// More actual poses wait for reference than the stream may hold.
    #[error(
        "actual sample {sample}: {limit} actual samples already wait for more reference \
         (push reference ahead of the actual samples, or raise StreamLimits::queue)"
    )]
    QueueFull {
        /// Index of the actual sample refused.
        sample: usize,
        /// [`StreamLimits::queue`](crate::StreamLimits::queue).
        limit: usize,
    },

    /// More reference knots than the stream may hold.
    #[error(
        "reference sample {sample}: the stream already holds {limit} reference knots that \
         waiting actual samples may need (push and drain actual samples before more \
         reference, or raise StreamLimits::knots)"
    )]
    TooManyKnots {
        /// Index of the reference sample refused.
        sample: usize,
        /// [`StreamLimits::knots`](crate::StreamLimits::knots).
        limit: usize,
    },

    /// A [`ContourStream`](crate::ContourStream) method called out of order.
    #[error("contour stream: {0}")]
    StreamOrder(&'static str),

    /// A failure of the search itself (a bug), reported rather than panicking.
    #[error("contour search: internal error: {0}")]
    Internal(&'static str),
}

impl Error {
    /// False: the pose sequences are computed by vcnc (interpolation, simulation, kinematics),
    /// so a bad sequence is a failure of the run, not of the user's input (exit code 1).
    pub fn is_bad_input(&self) -> bool {
        false
    }
}

/// Shorthand for this crate's results.
pub type Result<T, E = Error> = std::result::Result<T, E>;
