//! Plain data types shared by the chain, the closed-form model and `vcnc-contour`.

use std::fmt;

pub use vcnc_axis::AxisName;

use nalgebra::Vector3;

use crate::error::{Error, Result};

/// A tool pose in the workpiece frame (docs/kinematics.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Tool-tip position in the workpiece frame, mm.
    pub p: Vector3<f64>,
    /// Tool axis (from the tip towards the spindle) in the workpiece frame, unitless; unit length
    /// when produced by this crate. The inverse kinematics normalises it and rejects zero or
    /// non-finite vectors.
    pub o: Vector3<f64>,
}

impl Pose {
    /// A pose from a tip position (mm) and a tool axis (unitless).
    pub fn new(p: Vector3<f64>, o: Vector3<f64>) -> Self {
        Self { p, o }
    }
}

impl Default for Pose {
    /// Tip at the workpiece origin, tool along +Z.
    fn default() -> Self {
        Self {
            p: Vector3::zeros(),
            o: Vector3::z(),
        }
    }
}

/// Positions of the five machine axes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Axes {
    /// X slide, mm (tool-tip position in the machine frame).
    pub x: f64,
    /// Y slide, mm.
    pub y: f64,
    /// Z slide, mm.
    pub z: f64,
    /// A tilt about +X, rad (positive tilts the table right-handedly about +X).
    pub a: f64,
    /// C rotation about +Z, rad, continuous (not wrapped); positive turns the table
    /// right-handedly about +Z.
    pub c: f64,
}

impl Axes {
    /// Axes from their values (mm, mm, mm, rad, rad).
    pub fn new(x: f64, y: f64, z: f64, a: f64, c: f64) -> Self {
        Self { x, y, z, a, c }
    }

    /// The five axes of a table-tilting A/C machine, in order.
    pub const NAMES: [AxisName; 5] = [
        AxisName::X,
        AxisName::Y,
        AxisName::Z,
        AxisName::A,
        AxisName::C,
    ];

    /// The value of one axis (mm or rad); `None` for B, which this machine does not have.
    pub fn get(&self, axis: AxisName) -> Option<f64> {
        match axis {
            AxisName::X => Some(self.x),
            AxisName::Y => Some(self.y),
            AxisName::Z => Some(self.z),
            AxisName::A => Some(self.a),
            AxisName::B => None,
            AxisName::C => Some(self.c),
        }
    }

    /// `[x, y, z, a, c]` (mm, mm, mm, rad, rad).
    pub fn to_array(&self) -> [f64; 5] {
        [self.x, self.y, self.z, self.a, self.c]
    }

    /// From `[x, y, z, a, c]` (mm, mm, mm, rad, rad).
    pub fn from_array(v: [f64; 5]) -> Self {
        let [x, y, z, a, c] = v;
        Self { x, y, z, a, c }
    }

    /// The linear axes as a vector `pm = (X, Y, Z)`, mm.
    pub fn pm(&self) -> Vector3<f64> {
        Vector3::new(self.x, self.y, self.z)
    }
}

/// Inverse-kinematics branch (docs/kinematics.md): the sign of A.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Branch {
    /// Branch +1: $a = \arccos o_z \in [0, \pi]$, $c = \operatorname{atan2}(o_x, o_y)$.
    #[default]
    Plus,
    /// Branch −1: $a = -\arccos o_z \in [-\pi, 0]$, $c = \operatorname{atan2}(-o_x, -o_y)$.
    Minus,
}

impl Branch {
    /// +1.0 or −1.0.
    pub fn sign(self) -> f64 {
        match self {
            Branch::Plus => 1.0,
            Branch::Minus => -1.0,
        }
    }

    /// The other branch.
    pub fn other(self) -> Branch {
        match self {
            Branch::Plus => Branch::Minus,
            Branch::Minus => Branch::Plus,
        }
    }
}

impl TryFrom<i32> for Branch {
    type Error = Error;

    /// `1` → [`Branch::Plus`], `-1` → [`Branch::Minus`] (the CLI's `--branch 1|-1`).
    fn try_from(v: i32) -> Result<Self> {
        match v {
            1 => Ok(Branch::Plus),
            -1 => Ok(Branch::Minus),
            _ => Err(Error::BadParameter {
                name: "branch".into(),
                value: v.to_string(),
                reason: "must be 1 or -1",
            }),
        }
    }
}

impl fmt::Display for Branch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Branch::Plus => "+1",
            Branch::Minus => "-1",
        })
    }
}

/// Travel of one axis: `lower ..= upper`, mm for linear axes, rad for rotary ones.
/// A continuous axis has infinite bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Travel {
    /// Lower limit, mm or rad (may be `-inf`).
    pub lower: f64,
    /// Upper limit, mm or rad (may be `+inf`).
    pub upper: f64,
}

impl Travel {
    /// No limits.
    pub const UNBOUNDED: Travel = Travel {
        lower: f64::NEG_INFINITY,
        upper: f64::INFINITY,
    };

    /// A checked travel: neither bound NaN, `lower <= upper`.
    pub fn new(lower: f64, upper: f64) -> Result<Self> {
        if lower.is_nan() || upper.is_nan() || lower > upper {
            return Err(Error::BadParameter {
                name: "travel".into(),
                value: format!("{lower} ..= {upper}"),
                reason: "needs lower <= upper, neither NaN",
            });
        }
        Ok(Self { lower, upper })
    }

    /// True if `v` lies within `lower ..= upper` (false for NaN).
    pub fn contains(&self, v: f64) -> bool {
        v >= self.lower && v <= self.upper
    }
}

impl Default for Travel {
    /// [`Travel::UNBOUNDED`].
    fn default() -> Self {
        Travel::UNBOUNDED
    }
}

/// Travel of every axis (mm for X, Y, Z; rad for A, C).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AxisLimits {
    /// X travel, mm.
    pub x: Travel,
    /// Y travel, mm.
    pub y: Travel,
    /// Z travel, mm.
    pub z: Travel,
    /// A travel, rad.
    pub a: Travel,
    /// C travel, rad (unbounded for a continuous C).
    pub c: Travel,
}

impl AxisLimits {
    /// The travel of one axis; `None` for B, which this machine does not have.
    pub fn get(&self, axis: AxisName) -> Option<Travel> {
        match axis {
            AxisName::X => Some(self.x),
            AxisName::Y => Some(self.y),
            AxisName::Z => Some(self.z),
            AxisName::A => Some(self.a),
            AxisName::B => None,
            AxisName::C => Some(self.c),
        }
    }

    /// Mutable access to the travel of one axis; `None` for B.
    pub fn get_mut(&mut self, axis: AxisName) -> Option<&mut Travel> {
        match axis {
            AxisName::X => Some(&mut self.x),
            AxisName::Y => Some(&mut self.y),
            AxisName::Z => Some(&mut self.z),
            AxisName::A => Some(&mut self.a),
            AxisName::B => None,
            AxisName::C => Some(&mut self.c),
        }
    }

    /// `Ok` if every axis of `axes` is within travel, else the first violation in the order
    /// X, Y, Z, A, C, tagged with `sample`.
    pub fn check(&self, axes: &Axes, sample: Option<usize>) -> Result<()> {
        for (axis, t) in Axes::NAMES
            .into_iter()
            .zip([self.x, self.y, self.z, self.a, self.c])
        {
            let v = axes.get(axis).unwrap_or(0.0);
            if !t.contains(v) {
                return Err(Error::OutOfTravel {
                    axis,
                    value: v,
                    lower: t.lower,
                    upper: t.upper,
                    sample,
                });
            }
        }
        Ok(())
    }
}
