//! The closed-form families: their parameters (plain data, every field with its unit) and their
//! forward kinematics and tool-centre-point inverse (docs/kinematics.md, one section each).
//!
//! Variables are named as in docs/kinematics.md: `pm` = $p_m$ the slides' position (X, Y, Z),
//! `p_w` the tool tip in the workpiece frame, `t` the tilt (A or B), `c` the C angle;
//! $R_t$ is the rotation about the tilt's axis and $R_z$ about +Z, right-handed.

use nalgebra::Vector3;

use crate::error::{Error, Result};
use crate::rotation::{Principal, RotFamily, rotate, still};
use crate::types::{Axes, AxisLimits, AxisName, JointMotion, PointMotion, Pose, Tilt};
use crate::wrist::Wrist;

fn principal(tilt: Tilt) -> Principal {
    match tilt {
        Tilt::A => Principal::X,
        Tilt::B => Principal::Y,
    }
}

pub(crate) fn check_finite(name: &str, v: &Vector3<f64>) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::BadParameter {
            name: name.to_string(),
            value: format!("({}, {}, {}) mm", v.x, v.y, v.z),
            reason: "must be finite",
        })
    }
}

/// A three-axis machine (docs/kinematics.md, "3-axis XYZ"): the tool tip is at the slides'
/// position $p_w = p_m = (X, Y, Z)$ and the tool points along +Z.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Xyz {
    /// Travels (mm); only X, Y, Z are used. Never applied by the forward kinematics.
    pub limits: AxisLimits,
}

impl Xyz {
    pub(crate) fn forward(&self, j: &Axes) -> Pose {
        Pose::new(j.pm(), Vector3::z())
    }
}

/// A table-tilting machine, A/C or B/C (docs/kinematics.md, "Table-tilting A/C and B/C"): the
/// spindle moves in X, Y, Z with a fixed orientation; the workpiece sits on a rotary table (C,
/// about its own vertical axis) carried by a tilting cradle or trunnion (A about X, or B about
/// Y). Positive angles turn the table right-handedly (LinuxCNC's `xyzac-trt` / `xyzbc-trt`
/// with `conventional-directions` off).
///
/// $$ p_w = r + R_z(-c)\big(R_t(-t)(p_m - r - d) + d\big), \qquad
///    p_m = r + d + R_t(t)\big(R_z(c)(p_w - r) - d\big). $$
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableTilting {
    /// The tilting axis: A (a cradle about X, e.g. NMV5000) or B (a trunnion about Y).
    pub tilt: Tilt,
    /// C-axis centre $r$: a point of the C axis at tilt 0, machine frame, mm. Any point of the
    /// axis will do: $r_z$ counts only through $r_z + d_z$.
    pub r: Vector3<f64>,
    /// Tilt-axis centre relative to the C-axis centre, $d$, mm: $r + d$ is a point of the tilt
    /// axis. Its component along the tilt axis has no effect.
    pub d: Vector3<f64>,
    /// Travels (mm, rad) of X Y Z, the tilt and C. Never applied by the forward kinematics.
    pub limits: AxisLimits,
}

impl TableTilting {
    /// A checked model: `r` and `d` finite (mm), every travel `lower <= upper`.
    pub fn new(tilt: Tilt, r: Vector3<f64>, d: Vector3<f64>, limits: AxisLimits) -> Result<Self> {
        check_finite("r (C-axis centre)", &r)?;
        check_finite("d (tilt-axis centre relative to the C-axis centre)", &d)?;
        limits.validate()?;
        Ok(Self { tilt, r, d, limits })
    }

    pub(crate) fn wrist(&self) -> Wrist {
        Wrist {
            tilt: self.tilt,
            sigma_t: -1.0,
            sigma_c: -1.0,
        }
    }

    pub(crate) fn forward(&self, j: &Axes) -> Pose {
        let t = j[self.tilt.axis()];
        let q = j.pm() - self.r - self.d;
        let p = self.r
            + rotate(
                Principal::Z,
                -j.c,
                &(rotate(principal(self.tilt), -t, &q) + self.d),
            );
        Pose {
            p,
            o: self.wrist().orientation(t, j.c),
        }
    }

    pub(crate) fn tcp_position(&self, p_w: &Vector3<f64>, j: &Axes) -> Vector3<f64> {
        let t = j[self.tilt.axis()];
        self.r
            + self.d
            + rotate(
                principal(self.tilt),
                t,
                &(rotate(Principal::Z, j.c, &(p_w - self.r)) - self.d),
            )
    }

    /// With $q = p_w - r$ and $u = R_z(c)q - d$: $p_m = r + d + R_t(t)\,u$, differentiated by
    /// [`RotFamily::motion`] twice.
    pub(crate) fn tcp_motion(&self, tip: &PointMotion, rot: &JointMotion) -> PointMotion {
        let axis = self.tilt.axis();
        let q = PointMotion {
            p: tip.p - self.r,
            ..*tip
        };
        let rz_q = RotFamily::new(Principal::Z, rot.pos.c).motion(rot.vel.c, rot.acc.c, &q);
        let u = PointMotion {
            p: rz_q.p - self.d,
            ..rz_q
        };
        let m = RotFamily::new(principal(self.tilt), rot.pos[axis]).motion(
            rot.vel[axis],
            rot.acc[axis],
            &u,
        );
        PointMotion {
            p: self.r + self.d + m.p,
            ..m
        }
    }
}

/// A head-head machine (docs/kinematics.md, "Head-head"): the slides carry a fork head whose C
/// axis (about Z, nearer the slides) carries the tilt (A or B) that turns the spindle; the
/// workpiece is fixed. At zero rotation the tool tip is at the slides' position $p_m$. Positive
/// angles turn the head right-handedly (LinuxCNC's `5axiskins` turns B the other way).
///
/// $$ p_w = p_m + s_c + R_z(c)\big(s_t - s_c - R_t(t)\,s_t\big), \qquad
///    o_w = R_z(c)\,R_t(t)\,\hat z. $$
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadHead {
    /// The tilting axis of the head: A or B.
    pub tilt: Tilt,
    /// $s_t$: a point of the tilt axis (the pivot) relative to the tool tip at zero rotation,
    /// mm; typically $(0, 0, L)$ with $L$ the pivot length, which includes the tool length.
    /// Its component along the tilt axis has no effect.
    pub pivot: Vector3<f64>,
    /// $s_c$: a point of the C axis relative to the tool tip at zero rotation, mm; equal to
    /// `pivot` when the two axes intersect. Its z component has no effect.
    pub c_axis: Vector3<f64>,
    /// Travels (mm, rad) of X Y Z, the tilt and C. Never applied by the forward kinematics.
    pub limits: AxisLimits,
}

impl HeadHead {
    /// A checked model: offsets finite (mm), every travel `lower <= upper`.
    pub fn new(
        tilt: Tilt,
        pivot: Vector3<f64>,
        c_axis: Vector3<f64>,
        limits: AxisLimits,
    ) -> Result<Self> {
        check_finite("pivot (tilt-axis point relative to the tool tip)", &pivot)?;
        check_finite("C-axis point relative to the tool tip", &c_axis)?;
        limits.validate()?;
        Ok(Self {
            tilt,
            pivot,
            c_axis,
            limits,
        })
    }

    /// A head whose tilt and C axes meet at the pivot, `pivot_length` (mm) above the tool tip
    /// at zero rotation (LinuxCNC `5axiskins`' `pivot-length`).
    pub fn with_pivot_length(tilt: Tilt, pivot_length: f64, limits: AxisLimits) -> Result<Self> {
        let pivot = Vector3::new(0.0, 0.0, pivot_length);
        Self::new(tilt, pivot, pivot, limits)
    }

    pub(crate) fn wrist(&self) -> Wrist {
        Wrist {
            tilt: self.tilt,
            sigma_t: 1.0,
            sigma_c: 1.0,
        }
    }

    /// $h = s_c + R_z(c)(s_t - s_c - R_t(t)s_t)$: the tool tip relative to $p_m$.
    fn tip_offset(&self, t: f64, c: f64) -> Vector3<f64> {
        let u = self.pivot - self.c_axis - rotate(principal(self.tilt), t, &self.pivot);
        self.c_axis + rotate(Principal::Z, c, &u)
    }

    pub(crate) fn forward(&self, j: &Axes) -> Pose {
        let t = j[self.tilt.axis()];
        Pose {
            p: j.pm() + self.tip_offset(t, j.c),
            o: self.wrist().orientation(t, j.c),
        }
    }

    pub(crate) fn tcp_position(&self, p_w: &Vector3<f64>, j: &Axes) -> Vector3<f64> {
        p_w - self.tip_offset(j[self.tilt.axis()], j.c)
    }

    /// $p_m = p_w - h$ with $h$ differentiated by [`RotFamily::motion`].
    pub(crate) fn tcp_motion(&self, tip: &PointMotion, rot: &JointMotion) -> PointMotion {
        let axis = self.tilt.axis();
        let rt = RotFamily::new(principal(self.tilt), rot.pos[axis]).motion(
            rot.vel[axis],
            rot.acc[axis],
            &still(self.pivot),
        );
        let u = PointMotion {
            p: self.pivot - self.c_axis - rt.p,
            p_dot: -rt.p_dot,
            p_ddot: -rt.p_ddot,
        };
        let h = RotFamily::new(Principal::Z, rot.pos.c).motion(rot.vel.c, rot.acc.c, &u);
        PointMotion {
            p: tip.p - self.c_axis - h.p,
            p_dot: tip.p_dot - h.p_dot,
            p_ddot: tip.p_ddot - h.p_ddot,
        }
    }
}

/// A head-table machine (docs/kinematics.md, "Head-table"): the slides carry a head that tilts
/// the spindle (A or B); the workpiece sits on a rotary table C. Positive angles turn the head
/// and the table right-handedly (LinuxCNC's `maxkins` turns both the other way).
///
/// $$ p_w = r + R_z(-c)\big(p_m + s_t - R_t(t)\,s_t - r\big), \qquad
///    o_w = R_z(-c)\,R_t(t)\,\hat z. $$
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadTable {
    /// The tilting axis of the head: A or B.
    pub tilt: Tilt,
    /// $s_t$: a point of the head's tilt axis (the pivot) relative to the tool tip at zero
    /// rotation, mm; typically $(0, 0, L)$ with $L$ the pivot length including the tool.
    /// Its component along the tilt axis has no effect.
    pub pivot: Vector3<f64>,
    /// $r$: the C-axis centre (a point of the table's axis), machine frame, mm. Its z component
    /// has no effect.
    pub r: Vector3<f64>,
    /// Travels (mm, rad) of X Y Z, the tilt and C. Never applied by the forward kinematics.
    pub limits: AxisLimits,
}

impl HeadTable {
    /// A checked model: offsets finite (mm), every travel `lower <= upper`.
    pub fn new(
        tilt: Tilt,
        pivot: Vector3<f64>,
        r: Vector3<f64>,
        limits: AxisLimits,
    ) -> Result<Self> {
        check_finite("pivot (tilt-axis point relative to the tool tip)", &pivot)?;
        check_finite("r (C-axis centre)", &r)?;
        limits.validate()?;
        Ok(Self {
            tilt,
            pivot,
            r,
            limits,
        })
    }

    pub(crate) fn wrist(&self) -> Wrist {
        Wrist {
            tilt: self.tilt,
            sigma_t: 1.0,
            sigma_c: -1.0,
        }
    }

    pub(crate) fn forward(&self, j: &Axes) -> Pose {
        let t = j[self.tilt.axis()];
        let m = j.pm() + self.pivot - rotate(principal(self.tilt), t, &self.pivot);
        Pose {
            p: self.r + rotate(Principal::Z, -j.c, &(m - self.r)),
            o: self.wrist().orientation(t, j.c),
        }
    }

    pub(crate) fn tcp_position(&self, p_w: &Vector3<f64>, j: &Axes) -> Vector3<f64> {
        let t = j[self.tilt.axis()];
        self.r + rotate(Principal::Z, j.c, &(p_w - self.r)) - self.pivot
            + rotate(principal(self.tilt), t, &self.pivot)
    }

    /// $p_m = r + R_z(c)(p_w - r) - s_t + R_t(t)s_t$, differentiated by [`RotFamily::motion`].
    pub(crate) fn tcp_motion(&self, tip: &PointMotion, rot: &JointMotion) -> PointMotion {
        let axis = self.tilt.axis();
        let q = PointMotion {
            p: tip.p - self.r,
            ..*tip
        };
        let rz_q = RotFamily::new(Principal::Z, rot.pos.c).motion(rot.vel.c, rot.acc.c, &q);
        let rt = RotFamily::new(principal(self.tilt), rot.pos[axis]).motion(
            rot.vel[axis],
            rot.acc[axis],
            &still(self.pivot),
        );
        PointMotion {
            p: self.r + rz_q.p - self.pivot + rt.p,
            p_dot: rz_q.p_dot + rt.p_dot,
            p_ddot: rz_q.p_ddot + rt.p_ddot,
        }
    }
}

/// The rotary axes of a closed-form five-axis family: the tilt, then C.
pub(crate) fn tilt_and_c(tilt: Tilt) -> [AxisName; 2] {
    [tilt.axis(), AxisName::C]
}
