//! [`TableTiltingAc`]: the table-tilting A/C machine under the name and methods vcnc used before
//! it knew other families. Every method is the [`Kinematics::TableTilting`] family's with
//! tilt A (the same code, the same bits); new code uses [`Kinematics`].

use nalgebra::Vector3;

use crate::chain::KinematicChain;
use crate::error::Result;
use crate::families::TableTilting;
use crate::kinematics::{IkOptions, IkSolution, Kinematics};
use crate::types::{Axes, AxisLimits, Branch, Pose, Tilt, Track, Track3, Travel};
use crate::wrist::{RotaryAngles, Wrist};

/// The closed-form table-tilting A/C model (docs/kinematics.md; equals LinuxCNC's `xyzac-trt`
/// kinematics with `conventional-directions = 0`, x/y/z-rot-point = r, y/z-offset = d_y, d_z).
///
/// Forward:
/// $$ p_w = r + R_z(-c)\,\big(R_x(-a)(p_m - r - d) + d\big), \qquad
///    o_w = (\sin a \sin c,\ \sin a \cos c,\ \cos a). $$
/// Inverse (branch ±1):
/// $$ a = \pm\arccos o_z, \quad c = \operatorname{atan2}(\pm o_x, \pm o_y), \qquad
///    p_m = r + d + R_x(a)\big(R_z(c)(p_w - r) - d\big). $$
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableTiltingAc {
    /// C-axis centre (a point of the C axis at A = 0) in the machine frame, mm.
    /// vcnc's default (0, 0, 0), docs/kinematics.md; the NMV5000's real value is not public.
    pub r: Vector3<f64>,
    /// A-axis centre relative to the C-axis centre, mm; default (0, 0, −100) (the table surface
    /// 100 mm above the A axis; not a published figure). Its x component has no effect.
    pub d: Vector3<f64>,
    /// Axis travels (mm, rad) checked by [`TableTiltingAc::inverse_sequence`]; never applied by
    /// the forward kinematics.
    pub limits: AxisLimits,
}

impl Default for TableTiltingAc {
    /// docs/kinematics.md defaults: r = 0, d = (0, 0, −100) mm, unbounded travel.
    fn default() -> Self {
        Self {
            r: Vector3::zeros(),
            d: Vector3::new(0.0, 0.0, -100.0),
            limits: AxisLimits::default(),
        }
    }
}

const AC: Wrist = Wrist {
    tilt: Tilt::A,
    sigma_t: -1.0,
    sigma_c: -1.0,
};

impl TableTiltingAc {
    /// A checked model: r and d finite (mm), every travel `lower <= upper` (mm, rad).
    pub fn new(r: Vector3<f64>, d: Vector3<f64>, limits: AxisLimits) -> Result<Self> {
        TableTilting::new(Tilt::A, r, d, limits)?;
        Ok(Self { r, d, limits })
    }

    /// Reads a table-tilting A/C chain from a URDF file and returns its closed-form model
    /// (see [`KinematicChain::from_urdf_file`]).
    pub fn from_urdf_file(path: impl AsRef<std::path::Path>) -> Result<Self> {
        Ok(KinematicChain::from_urdf_file(path)?.table_tilting_ac())
    }

    /// The same model with other offsets (e.g. from the machine file), mm.
    pub fn with_offsets(self, r: Vector3<f64>, d: Vector3<f64>) -> Result<Self> {
        Self::new(r, d, self.limits)
    }

    /// The same model with other travels (mm, rad).
    pub fn with_limits(self, limits: AxisLimits) -> Result<Self> {
        Self::new(self.r, self.d, limits)
    }

    /// This model as the table-tilting family with tilt A.
    pub fn family(&self) -> TableTilting {
        TableTilting {
            tilt: Tilt::A,
            r: self.r,
            d: self.d,
            limits: self.limits,
        }
    }

    /// This model as a [`Kinematics`] value.
    pub fn kinematics(&self) -> Kinematics {
        Kinematics::TableTilting(self.family())
    }

    /// Tool axis in the workpiece frame for rotary angles `a`, `c` (rad):
    /// $o_w = (\sin a \sin c, \sin a \cos c, \cos a)$.
    pub fn orientation(a: f64, c: f64) -> Vector3<f64> {
        AC.orientation(a, c)
    }

    /// Forward kinematics (docs/kinematics.md). Never clamps to travel.
    pub fn forward(&self, axes: &Axes) -> Pose {
        self.family().forward(axes)
    }

    /// A and C from a tool axis `o` (any positive length) on `branch`, with C unwrapped to the
    /// solution nearest `c_prev` (rad) and held at `c_prev` at the A = 0 singularity. Zero or
    /// non-finite `o` is an error. `sample` tags errors.
    pub fn rotary_angles(
        o: &Vector3<f64>,
        branch: Branch,
        c_prev: f64,
        sample: Option<usize>,
    ) -> Result<RotaryAngles> {
        AC.angles(o, branch, c_prev, Travel::UNBOUNDED, sample)
    }

    /// TCP inverse: the machine position of the tool tip for a workpiece-frame tip `p_w` (mm)
    /// and rotary angles `a`, `c` (rad):
    /// $p_m = r + d + R_x(a)\big(R_z(c)(p_w - r) - d\big)$.
    pub fn inverse_tcp(&self, p_w: &Vector3<f64>, a: f64, c: f64) -> Vector3<f64> {
        self.family()
            .tcp_position(p_w, &Axes::new(0.0, 0.0, 0.0, a, c))
    }

    /// [`Kinematics::inverse_tcp_track`] of this model: X Y Z tracks of the tool tip in the
    /// workpiece frame, A and C in degrees. Tracks shorter than `tcp` are the caller's bug;
    /// the tip tracks are then returned unchanged.
    pub fn inverse_tcp_track(
        &self,
        tip: [Track<'_>; 3],
        a: Track<'_>,
        c: Track<'_>,
        tcp: &[bool],
    ) -> [Track3; 3] {
        self.kinematics()
            .inverse_tcp_track(tip, &[a, c], tcp)
            .unwrap_or_else(|_| {
                std::array::from_fn(|i| Track3 {
                    pos: tip[i].pos.to_vec(),
                    vel: tip[i].vel.to_vec(),
                    acc: tip[i].acc.to_vec(),
                })
            })
    }

    /// Inverse kinematics of one pose on `branch`, C nearest to `c_prev` (rad) and held at
    /// `c_prev` at the A = 0 singularity. Travel is not checked (C is unwound within it).
    pub fn inverse_near(&self, pose: &Pose, branch: Branch, c_prev: f64) -> Result<Axes> {
        self.kinematics()
            .inverse(pose, branch, &Axes::new(0.0, 0.0, 0.0, 0.0, c_prev))
    }

    /// Inverse kinematics of one pose on `branch` with C in $[-\pi, \pi]$ (0 at the A = 0
    /// singularity). Travel is not checked.
    pub fn inverse(&self, pose: &Pose, branch: Branch) -> Result<Axes> {
        self.inverse_near(pose, branch, 0.0)
    }

    /// [`Kinematics::inverse_sequence`] of this model.
    pub fn inverse_sequence(&self, poses: &[Pose], opts: &IkOptions) -> Result<IkSolution> {
        self.kinematics().inverse_sequence(poses, opts)
    }
}
