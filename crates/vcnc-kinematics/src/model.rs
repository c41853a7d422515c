//! Closed-form kinematics of the table-tilting A/C machine (docs/kinematics.md).
//!
//! Variables are named as in docs/kinematics.md: `pm` is the machine position of the tool tip
//! (X, Y, Z), `p_w` and `o_w` the tool tip and tool axis in the workpiece frame, `r` the C-axis
//! centre, `d` the A-axis centre relative to the C-axis centre, `a` and `c` the rotary axes.
//! $R_x(\cdot)$, $R_z(\cdot)$ are right-handed rotations about +X and +Z.

use std::f64::consts::TAU;

use nalgebra::{Matrix3, Vector3};

use crate::chain::KinematicChain;
use crate::error::{Error, Result};
use crate::types::{Axes, AxisLimits, Branch, Pose, Travel};

/// Below this $|\sin a|$ the C angle is undefined (the tool axis is parallel to the C axis):
/// the inverse kinematics keeps the previous C. The C rate a path demands grows as
/// $1/|\sin a|$ near it (docs/kinematics.md).
pub const SINGULAR_SIN_A: f64 = 1e-9;

/// The closed-form table-tilting A/C model (docs/kinematics.md; equals LinuxCNC's `xyzac-trt`
/// kinematics with `conventional-directions = 0`, x/y/z-rot-point = r, y/z-offset = d_y, d_z).
///
/// Forward:
/// $$ p_w = r + R_z(-c)\,\big(R_x(-a)(p_m - r - d) + d\big), \qquad
///    o_w = (\sin a \sin c,\ \sin a \cos c,\ \cos a). $$
/// Inverse (branch ±1):
/// $$ a = \pm\arccos o_z, \quad c = \operatorname{atan2}(\pm o_x, \pm o_y), \qquad
///    p_m = r + d + R_x(a)\big(R_z(c)(p_w - r) - d\big). $$
///
/// The offsets are configuration: build the model from the URDF joint origins with
/// [`KinematicChain::table_tilting_ac`], and override them with [`TableTiltingAc::with_offsets`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableTiltingAc {
    /// C-axis centre (a point of the C axis at A = 0) in the machine frame, mm.
    /// vcnc's default (0, 0, 0), docs/kinematics.md; the NMV5000's real value is not public.
    pub r: Vector3<f64>,
    /// A-axis centre relative to the C-axis centre, mm; d = (0, L_y, L_z) in docs/kinematics.md, default
    /// (0, 0, −100) (the table surface 100 mm above the A axis; not a published figure).
    /// Its x component has no effect (any point of the A axis may be used).
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

/// Options of [`TableTiltingAc::inverse_sequence`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkOptions {
    /// The branch to use for every sample, or `None` to choose automatically: branch +1 if it
    /// keeps every axis within travel over the whole sequence, else branch −1. Default `None`.
    pub branch: Option<Branch>,
    /// The C angle "before" the first sample, rad: the first C is unwrapped to the solution
    /// nearest to it, and it is kept if the first pose is singular. Default 0.
    pub c_start: f64,
    /// Check every sample against [`TableTiltingAc::limits`]. Default true.
    pub check_travel: bool,
}

impl Default for IkOptions {
    fn default() -> Self {
        Self {
            branch: None,
            c_start: 0.0,
            check_travel: true,
        }
    }
}

/// The axes of a pose sequence and how they were obtained.
#[derive(Debug, Clone, PartialEq)]
pub struct IkSolution {
    /// One set of axes per pose (mm, rad; C unwrapped continuously).
    pub axes: Vec<Axes>,
    /// The branch used for every sample.
    pub branch: Branch,
    /// Number of samples at the A = 0 singularity ($|\sin a| <$ [`SINGULAR_SIN_A`]) whose C was
    /// held at the previous value.
    pub singular_samples: usize,
}

/// Rotary angles derived from a tool axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotaryAngles {
    /// A, rad.
    pub a: f64,
    /// C, rad, unwrapped to the solution nearest to the previous C.
    pub c: f64,
    /// True if $|\sin a| <$ [`SINGULAR_SIN_A`] and C was held at the previous value.
    pub singular: bool,
}

/// Tool-tip motion in the workpiece frame plus the rotary-axis motion, as a TCP-mode (RTCP)
/// interpolator produces it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TcpMotion {
    /// Tool-tip position $p_w$, mm.
    pub p_w: Vector3<f64>,
    /// Tool-tip velocity $\dot p_w$, mm/s.
    pub p_w_dot: Vector3<f64>,
    /// Tool-tip acceleration $\ddot p_w$, mm/s².
    pub p_w_ddot: Vector3<f64>,
    /// A, rad.
    pub a: f64,
    /// $\dot a$, rad/s.
    pub a_dot: f64,
    /// $\ddot a$, rad/s².
    pub a_ddot: f64,
    /// C, rad.
    pub c: f64,
    /// $\dot c$, rad/s.
    pub c_dot: f64,
    /// $\ddot c$, rad/s².
    pub c_ddot: f64,
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

/// Linear-axis motion $p_m = (X, Y, Z)$ and its analytic time derivatives.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MachineMotion {
    /// $p_m$, mm.
    pub pm: Vector3<f64>,
    /// $\dot p_m$, mm/s.
    pub pm_dot: Vector3<f64>,
    /// $\ddot p_m$, mm/s².
    pub pm_ddot: Vector3<f64>,
}

/// $R_x(a)$ and its first two derivatives with respect to $a$.
fn rx_family(a: f64) -> (Matrix3<f64>, Matrix3<f64>, Matrix3<f64>) {
    let (s, c) = a.sin_cos();
    #[rustfmt::skip]
    let r = Matrix3::new(
        1.0, 0.0, 0.0,
        0.0, c, -s,
        0.0, s, c,
    );
    #[rustfmt::skip]
    let r1 = Matrix3::new(
        0.0, 0.0, 0.0,
        0.0, -s, -c,
        0.0, c, -s,
    );
    #[rustfmt::skip]
    let r2 = Matrix3::new(
        0.0, 0.0, 0.0,
        0.0, -c, s,
        0.0, -s, -c,
    );
    (r, r1, r2)
}

/// $R_z(c)$ and its first two derivatives with respect to $c$.
fn rz_family(c: f64) -> (Matrix3<f64>, Matrix3<f64>, Matrix3<f64>) {
    let (s, co) = c.sin_cos();
    #[rustfmt::skip]
    let r = Matrix3::new(
        co, -s, 0.0,
        s, co, 0.0,
        0.0, 0.0, 1.0,
    );
    #[rustfmt::skip]
    let r1 = Matrix3::new(
        -s, -co, 0.0,
        co, -s, 0.0,
        0.0, 0.0, 0.0,
    );
    #[rustfmt::skip]
    let r2 = Matrix3::new(
        -co, s, 0.0,
        -s, -co, 0.0,
        0.0, 0.0, 0.0,
    );
    (r, r1, r2)
}

/// Rotation about +X by `a` applied to `v`.
fn rot_x(a: f64, v: &Vector3<f64>) -> Vector3<f64> {
    let (s, c) = a.sin_cos();
    Vector3::new(v.x, c * v.y - s * v.z, s * v.y + c * v.z)
}

/// Rotation about +Z by `c` applied to `v`.
fn rot_z(c: f64, v: &Vector3<f64>) -> Vector3<f64> {
    let (s, co) = c.sin_cos();
    Vector3::new(co * v.x - s * v.y, s * v.x + co * v.y, v.z)
}

/// `c_raw` shifted by a whole number of turns to lie nearest to `c_prev` (rad).
pub fn unwrap_near(c_raw: f64, c_prev: f64) -> f64 {
    c_raw + TAU * ((c_prev - c_raw) / TAU).round()
}

fn check_finite(name: &str, v: &Vector3<f64>, unit: &str) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::BadParameter {
            name: name.to_string(),
            value: format!("({}, {}, {}) {unit}", v.x, v.y, v.z),
            reason: "must be finite",
        })
    }
}

fn check_limits(limits: &AxisLimits) -> Result<()> {
    for (axis, t) in Axes::NAMES
        .into_iter()
        .zip([limits.x, limits.y, limits.z, limits.a, limits.c])
    {
        Travel::new(t.lower, t.upper).map_err(|_| Error::BadParameter {
            name: format!("travel of {axis}"),
            value: format!("{} ..= {}", t.lower, t.upper),
            reason: "needs lower <= upper, neither NaN",
        })?;
    }
    Ok(())
}

impl TableTiltingAc {
    /// A checked model: r and d finite (mm), every travel `lower <= upper` (mm, rad).
    pub fn new(r: Vector3<f64>, d: Vector3<f64>, limits: AxisLimits) -> Result<Self> {
        check_finite("r", &r, "mm")?;
        check_finite("d", &d, "mm")?;
        check_limits(&limits)?;
        Ok(Self { r, d, limits })
    }

    /// Reads the chain from a URDF file and returns its closed-form model
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

    /// Tool axis in the workpiece frame for rotary angles `a`, `c` (rad):
    /// $o_w = (\sin a \sin c, \sin a \cos c, \cos a)$.
    pub fn orientation(a: f64, c: f64) -> Vector3<f64> {
        let (sa, ca) = a.sin_cos();
        let (sc, cc) = c.sin_cos();
        Vector3::new(sa * sc, sa * cc, ca)
    }

    /// Forward kinematics (docs/kinematics.md):
    /// $p_w = r + R_z(-c)\,(R_x(-a)(p_m - r - d) + d)$, $o_w$ as in
    /// [`TableTiltingAc::orientation`]. Never clamps to travel (actual positions overshoot);
    /// non-finite axes give a non-finite pose.
    pub fn forward(&self, axes: &Axes) -> Pose {
        let q = axes.pm() - self.r - self.d;
        let p = self.r + rot_z(-axes.c, &(rot_x(-axes.a, &q) + self.d));
        Pose {
            p,
            o: Self::orientation(axes.a, axes.c),
        }
    }

    /// A and C from a tool axis `o` (any positive length; normalised here) on `branch`, with C
    /// unwrapped to the solution nearest `c_prev` (rad) and held at `c_prev` at the A = 0
    /// singularity. $o_z$ is clamped into $[-1, 1]$ after normalising, so the result is never
    /// NaN; zero or non-finite `o` is an error. `sample` tags errors.
    pub fn rotary_angles(
        o: &Vector3<f64>,
        branch: Branch,
        c_prev: f64,
        sample: Option<usize>,
    ) -> Result<RotaryAngles> {
        let bad = |reason| Error::BadOrientation {
            o: [o.x, o.y, o.z],
            sample,
            reason,
        };
        if !o.iter().all(|v| v.is_finite()) {
            return Err(bad("not finite"));
        }
        // Scale by the largest component first so that huge or tiny vectors normalise exactly.
        let m = o.amax();
        if m == 0.0 {
            return Err(bad("zero length: no tool direction"));
        }
        let u = o / m;
        let u = u / u.norm();
        if !c_prev.is_finite() {
            return Err(Error::BadParameter {
                name: "previous C".into(),
                value: format!("{c_prev} rad"),
                reason: "must be finite",
            });
        }
        let s = branch.sign();
        let a = s * u.z.clamp(-1.0, 1.0).acos();
        let sin_a = u.x.hypot(u.y);
        if sin_a < SINGULAR_SIN_A {
            return Ok(RotaryAngles {
                a,
                c: c_prev,
                singular: true,
            });
        }
        let c_raw = (s * u.x).atan2(s * u.y);
        Ok(RotaryAngles {
            a,
            c: unwrap_near(c_raw, c_prev),
            singular: false,
        })
    }

    /// TCP inverse: the machine position of the tool tip for a workpiece-frame tip `p_w` (mm)
    /// and given rotary angles `a`, `c` (rad), as TCP-mode G-code specifies them:
    /// $$ p_m = r + d + R_x(a)\big(R_z(c)(p_w - r) - d\big). $$
    pub fn inverse_tcp(&self, p_w: &Vector3<f64>, a: f64, c: f64) -> Vector3<f64> {
        self.r + self.d + rot_x(a, &(rot_z(c, &(p_w - self.r)) - self.d))
    }

    /// [`TableTiltingAc::inverse_tcp`] with its analytic first and second time derivatives
    /// (chain rule). With $q = p_w - r$, $u = R_z(c) q - d$:
    /// $$ \dot u = R_z'\dot c\, q + R_z \dot q, \quad
    ///    \ddot u = (R_z''\dot c^2 + R_z'\ddot c)\, q + 2 R_z'\dot c\,\dot q + R_z \ddot q, $$
    /// $$ \dot p_m = R_x'\dot a\, u + R_x \dot u, \quad
    ///    \ddot p_m = (R_x''\dot a^2 + R_x'\ddot a)\, u + 2 R_x'\dot a\,\dot u + R_x \ddot u, $$
    /// where primes are derivatives with respect to the angle.
    pub fn inverse_tcp_motion(&self, m: &TcpMotion) -> MachineMotion {
        let (rx, rx1, rx2) = rx_family(m.a);
        let (rz, rz1, rz2) = rz_family(m.c);
        let q = m.p_w - self.r;
        let u = rz * q - self.d;
        let u_dot = rz1 * q * m.c_dot + rz * m.p_w_dot;
        let u_ddot = (rz2 * (m.c_dot * m.c_dot) + rz1 * m.c_ddot) * q
            + rz1 * m.p_w_dot * (2.0 * m.c_dot)
            + rz * m.p_w_ddot;
        MachineMotion {
            pm: self.r + self.d + rx * u,
            pm_dot: rx1 * u * m.a_dot + rx * u_dot,
            pm_ddot: (rx2 * (m.a_dot * m.a_dot) + rx1 * m.a_ddot) * u
                + rx1 * u_dot * (2.0 * m.a_dot)
                + rx * u_ddot,
        }
    }

    /// [`inverse_tcp_motion`](Self::inverse_tcp_motion) over a whole run: the X Y Z tracks hold
    /// the tool tip in the workpiece frame (mm, mm/s, mm/s²) and the A C tracks the rotary axes
    /// in **degrees** (deg/s, deg/s²), as a tool-centre-point program is interpolated; the
    /// result is the X Y Z machine-axis references (position, velocity, acceleration) with the
    /// analytic derivatives of the chain rule. Samples where `tcp[k]` is false are machine-axis
    /// coordinates already and are copied unchanged. All tracks have `tcp.len()` samples.
    pub fn inverse_tcp_track(
        &self,
        tip: [Track<'_>; 3],
        a: Track<'_>,
        c: Track<'_>,
        tcp: &[bool],
    ) -> [Track3; 3] {
        const DEG: f64 = std::f64::consts::PI / 180.0;
        let mut out: [Track3; 3] = std::array::from_fn(|i| Track3 {
            pos: tip[i].pos.to_vec(),
            vel: tip[i].vel.to_vec(),
            acc: tip[i].acc.to_vec(),
        });
        for (k, _) in tcp.iter().enumerate().filter(|(_, on)| **on) {
            let v3 = |pick: usize| {
                let at = |t: &Track<'_>| [t.pos, t.vel, t.acc][pick][k];
                Vector3::new(at(&tip[0]), at(&tip[1]), at(&tip[2]))
            };
            let m = self.inverse_tcp_motion(&TcpMotion {
                p_w: v3(0),
                p_w_dot: v3(1),
                p_w_ddot: v3(2),
                a: a.pos[k] * DEG,
                a_dot: a.vel[k] * DEG,
                a_ddot: a.acc[k] * DEG,
                c: c.pos[k] * DEG,
                c_dot: c.vel[k] * DEG,
                c_ddot: c.acc[k] * DEG,
            });
            for (j, o) in out.iter_mut().enumerate() {
                o.pos[k] = m.pm[j];
                o.vel[k] = m.pm_dot[j];
                o.acc[k] = m.pm_ddot[j];
            }
        }
        out
    }

    /// Inverse kinematics of one pose on `branch`, C nearest to `c_prev` (rad) and held at
    /// `c_prev` at the A = 0 singularity. Travel is not checked.
    pub fn inverse_near(&self, pose: &Pose, branch: Branch, c_prev: f64) -> Result<Axes> {
        self.inverse_at(pose, branch, c_prev, None)
            .map(|(axes, _)| axes)
    }

    /// Inverse kinematics of one pose on `branch` with C in $[-\pi, \pi]$ (0 at the A = 0
    /// singularity). Travel is not checked.
    pub fn inverse(&self, pose: &Pose, branch: Branch) -> Result<Axes> {
        self.inverse_near(pose, branch, 0.0)
    }

    fn inverse_at(
        &self,
        pose: &Pose,
        branch: Branch,
        c_prev: f64,
        sample: Option<usize>,
    ) -> Result<(Axes, bool)> {
        if !pose.p.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinitePosition {
                p: [pose.p.x, pose.p.y, pose.p.z],
                sample,
            });
        }
        let rot = Self::rotary_angles(&pose.o, branch, c_prev, sample)?;
        let pm = self.inverse_tcp(&pose.p, rot.a, rot.c);
        Ok((Axes::new(pm.x, pm.y, pm.z, rot.a, rot.c), rot.singular))
    }

    fn solve_branch(&self, poses: &[Pose], branch: Branch, opts: &IkOptions) -> Result<IkSolution> {
        let mut axes = Vec::with_capacity(poses.len());
        let mut c_prev = opts.c_start;
        let mut singular_samples = 0;
        for (k, pose) in poses.iter().enumerate() {
            let (ax, singular) = self.inverse_at(pose, branch, c_prev, Some(k))?;
            if opts.check_travel {
                self.limits.check(&ax, Some(k))?;
            }
            singular_samples += usize::from(singular);
            c_prev = ax.c;
            axes.push(ax);
        }
        Ok(IkSolution {
            axes,
            branch,
            singular_samples,
        })
    }

    /// Inverse kinematics of a pose sequence (docs/kinematics.md): one branch for every sample
    /// (the requested one, or automatically the first of +1, −1 that keeps every axis within
    /// travel), C unwrapped continuously from sample to sample starting near
    /// [`IkOptions::c_start`], C held at the A = 0 singularity, and every sample checked against
    /// the travels. Errors carry the sample index and the numbers:
    /// "A = -131.200° is out of travel -120.000° ..= 30.000° at sample 812".
    pub fn inverse_sequence(&self, poses: &[Pose], opts: &IkOptions) -> Result<IkSolution> {
        if let Some(branch) = opts.branch {
            return self.solve_branch(poses, branch, opts);
        }
        match self.solve_branch(poses, Branch::Plus, opts) {
            Ok(sol) => Ok(sol),
            Err(plus @ Error::OutOfTravel { .. }) => {
                match self.solve_branch(poses, Branch::Minus, opts) {
                    Ok(sol) => Ok(sol),
                    Err(minus @ Error::OutOfTravel { .. }) => Err(Error::NoBranch {
                        plus: Box::new(plus),
                        minus: Box::new(minus),
                    }),
                    Err(other) => Err(other),
                }
            }
            Err(other) => Err(other),
        }
    }
}
