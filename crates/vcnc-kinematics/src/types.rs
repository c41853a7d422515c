//! Plain data types shared by every family, the URDF chain and `vcnc-contour`.

use std::fmt;
use std::ops::{Index, IndexMut};

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

/// Joint values of a machine: one slot per [`AxisName`], mm for X Y Z and rad for A B C.
///
/// A family uses the slots of its axes ([`Kinematics::axes`](crate::Kinematics::axes)); the
/// others are ignored by the forward kinematics and copied through by the inverse ones.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Axes {
    /// X slide, mm (the tool tip in the machine frame when every rotary axis is at zero).
    pub x: f64,
    /// Y slide, mm.
    pub y: f64,
    /// Z slide, mm.
    pub z: f64,
    /// A, rad: rotation about +X, continuous (not wrapped).
    pub a: f64,
    /// B, rad: rotation about +Y, continuous.
    pub b: f64,
    /// C, rad: rotation about +Z, continuous.
    pub c: f64,
}

impl Axes {
    /// The axes of a table-tilting A/C machine (mm, mm, mm, rad, rad); B is 0.
    pub fn new(x: f64, y: f64, z: f64, a: f64, c: f64) -> Self {
        Self {
            x,
            y,
            z,
            a,
            b: 0.0,
            c,
        }
    }

    /// Every slot from a function of its axis (mm or rad).
    pub fn from_fn(mut f: impl FnMut(AxisName) -> f64) -> Self {
        Self {
            x: f(AxisName::X),
            y: f(AxisName::Y),
            z: f(AxisName::Z),
            a: f(AxisName::A),
            b: f(AxisName::B),
            c: f(AxisName::C),
        }
    }

    /// The value of one axis (mm or rad). `Some` for every axis (the `Option` is kept for the
    /// callers written when B had no slot).
    pub fn get(&self, axis: AxisName) -> Option<f64> {
        Some(self[axis])
    }

    /// The same axes with `axis` set to `value` (mm or rad).
    pub fn with(mut self, axis: AxisName, value: f64) -> Self {
        self[axis] = value;
        self
    }

    /// The six values in the order X Y Z A B C (mm, rad).
    pub fn values(&self) -> [f64; 6] {
        [self.x, self.y, self.z, self.a, self.b, self.c]
    }

    /// The linear axes as a vector `pm = (X, Y, Z)`, mm.
    pub fn pm(&self) -> Vector3<f64> {
        Vector3::new(self.x, self.y, self.z)
    }

    /// The same axes with X, Y, Z replaced by `pm`, mm.
    pub fn with_pm(self, pm: &Vector3<f64>) -> Self {
        Self {
            x: pm.x,
            y: pm.y,
            z: pm.z,
            ..self
        }
    }
}

/// `Index<AxisName>` and `IndexMut<AxisName>` for a struct with one field per axis, `x` to `c`:
/// the one place that maps an axis name to its field.
macro_rules! index_by_axis_name {
    ($t:ty, $out:ty) => {
        impl Index<AxisName> for $t {
            type Output = $out;

            fn index(&self, axis: AxisName) -> &$out {
                match axis {
                    AxisName::X => &self.x,
                    AxisName::Y => &self.y,
                    AxisName::Z => &self.z,
                    AxisName::A => &self.a,
                    AxisName::B => &self.b,
                    AxisName::C => &self.c,
                }
            }
        }

        impl IndexMut<AxisName> for $t {
            fn index_mut(&mut self, axis: AxisName) -> &mut $out {
                match axis {
                    AxisName::X => &mut self.x,
                    AxisName::Y => &mut self.y,
                    AxisName::Z => &mut self.z,
                    AxisName::A => &mut self.a,
                    AxisName::B => &mut self.b,
                    AxisName::C => &mut self.c,
                }
            }
        }
    };
}

index_by_axis_name!(Axes, f64);

/// What a rotary axis turns: the spindle head (the tool) or the table (the workpiece).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Carrier {
    /// The axis turns the spindle head: positive angles turn the tool right-handedly.
    Head,
    /// The axis turns the table: positive angles turn the workpiece right-handedly.
    Table,
}

impl fmt::Display for Carrier {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Carrier::Head => "head",
            Carrier::Table => "table",
        })
    }
}

/// A rotary axis of a machine and what it turns (its role in the kinematics).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RotaryAxis {
    /// A, B or C.
    pub axis: AxisName,
    /// The head or the table.
    pub turns: Carrier,
}

/// The tilting rotary axis of a five-axis family: A (about +X) or B (about +Y). The other
/// rotary axis of every closed-form family is C (about +Z).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Tilt {
    /// A, about +X.
    A,
    /// B, about +Y.
    B,
}

impl Tilt {
    /// [`AxisName::A`] or [`AxisName::B`].
    pub fn axis(self) -> AxisName {
        match self {
            Tilt::A => AxisName::A,
            Tilt::B => AxisName::B,
        }
    }

    /// The tilt of a rotary axis name; `None` for C and the linear axes.
    pub fn of(axis: AxisName) -> Option<Tilt> {
        match axis {
            AxisName::A => Some(Tilt::A),
            AxisName::B => Some(Tilt::B),
            _ => None,
        }
    }
}

impl fmt::Display for Tilt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.axis().as_str())
    }
}

/// Inverse-kinematics branch (docs/kinematics.md): the sign of the tilting axis (A or B).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Branch {
    /// Branch +1: the tilt is $\arccos o_z \in [0, \pi]$.
    #[default]
    Plus,
    /// Branch −1: the tilt is $-\arccos o_z \in [-\pi, 0]$.
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

/// Travel of every axis (mm for X, Y, Z; rad for A, B, C); unbounded by default.
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
    /// B travel, rad.
    pub b: Travel,
    /// C travel, rad (unbounded for a continuous C).
    pub c: Travel,
}

impl AxisLimits {
    /// The travel of one axis. `Some` for every axis (the `Option` is kept for the callers
    /// written when B had no slot).
    pub fn get(&self, axis: AxisName) -> Option<Travel> {
        Some(self[axis])
    }

    /// Mutable access to the travel of one axis; `Some` for every axis.
    pub fn get_mut(&mut self, axis: AxisName) -> Option<&mut Travel> {
        Some(&mut self[axis])
    }

    /// `Ok` if every axis of a table-tilting A/C machine (X, Y, Z, A, C) is within travel, else
    /// the first violation in that order, tagged with `sample`.
    pub fn check(&self, axes: &Axes, sample: Option<usize>) -> Result<()> {
        self.check_axes(
            axes,
            &[
                AxisName::X,
                AxisName::Y,
                AxisName::Z,
                AxisName::A,
                AxisName::C,
            ],
            sample,
        )
    }

    /// `Ok` if each axis of `names` is within travel, else the first violation in the order of
    /// `names`, tagged with `sample`.
    pub fn check_axes(&self, axes: &Axes, names: &[AxisName], sample: Option<usize>) -> Result<()> {
        for &axis in names {
            let (t, v) = (self[axis], axes[axis]);
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

    /// `Ok` if every travel is `lower <= upper` with neither bound NaN.
    pub(crate) fn validate(&self) -> Result<()> {
        for axis in AxisName::ALL {
            let t = self[axis];
            Travel::new(t.lower, t.upper).map_err(|_| Error::BadParameter {
                name: format!("travel of {axis}"),
                value: format!("{} ..= {}", t.lower, t.upper),
                reason: "needs lower <= upper, neither NaN",
            })?;
        }
        Ok(())
    }
}

index_by_axis_name!(AxisLimits, Travel);

/// A point's position, velocity and acceleration (mm, mm/s, mm/s²): the tool tip in the
/// workpiece frame as a tool-centre-point interpolator produces it, or the slides' motion.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PointMotion {
    /// Position, mm.
    pub p: Vector3<f64>,
    /// Velocity, mm/s.
    pub p_dot: Vector3<f64>,
    /// Acceleration, mm/s².
    pub p_ddot: Vector3<f64>,
}

/// Joint positions with their first two time derivatives (mm, rad; per s; per s²).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointMotion {
    /// Positions, mm and rad.
    pub pos: Axes,
    /// Velocities, mm/s and rad/s.
    pub vel: Axes,
    /// Accelerations, mm/s² and rad/s².
    pub acc: Axes,
}

/// One axis over a run, borrowed: position, velocity and acceleration per sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Track<'a> {
    /// Position per sample (mm or deg).
    pub pos: &'a [f64],
    /// Velocity per sample (units/s).
    pub vel: &'a [f64],
    /// Acceleration per sample (units/s²).
    pub acc: &'a [f64],
}

/// One axis over a run, owned: position, velocity and acceleration per sample.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Track3 {
    /// Position per sample (mm).
    pub pos: Vec<f64>,
    /// Velocity per sample (mm/s).
    pub vel: Vec<f64>,
    /// Acceleration per sample (mm/s²).
    pub acc: Vec<f64>,
}
