//! A machine's kinematic chain read from URDF: any serial machine with slides X, Y, Z and up to
//! three rotary axes, its forward kinematics, the tool-centre-point inverse and the pose inverse
//! by damped least squares (docs/kinematics.md, "Any serial chain from a URDF").
//!
//! The tool pose in the workpiece frame is $T = T_{wp}^{-1}\,T_{tool}$, with $T_{tool}$ the
//! composition of the joint origins and motions from the base link to the tool tip and $T_{wp}$
//! from the base link to the workpiece. The chain is kept as one list of steps from the
//! workpiece to the tool tip: fixed transforms and joint motions, a workpiece-side joint
//! entering with its sign reversed ($T_{wp}^{-1}$ undoes its motion). Lengths are read as mm and
//! angles as rad (URDF's metres are only a convention here).

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::families::{HeadHead, HeadTable, TableTilting, Xyz};
use crate::kinematics::Kinematics;
use crate::model::TableTiltingAc;
use crate::types::{
    Axes, AxisLimits, AxisName, Carrier, JointMotion, PointMotion, Pose, RotaryAxis, Tilt, Travel,
};
use crate::wrist::{unit_orientation, unwrap_within};

/// Geometric tolerance of the chain validation: axis directions (unitless) and the zero-position
/// frames (mm and rad) must match a closed form to this.
pub const CHAIN_TOLERANCE: f64 = 1e-9;

/// The joint kinds this crate accepts (a closed set; URDF's floating, planar and spherical
/// joints are rejected).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum JointKind {
    /// Translation along the joint axis by the joint value, mm.
    Prismatic,
    /// Rotation about the joint axis by the joint value, rad, within travel limits.
    Revolute,
    /// Rotation about the joint axis, rad, without travel limits.
    Continuous,
    /// No motion.
    Fixed,
}

impl JointKind {
    fn is_movable(self) -> bool {
        !matches!(self, JointKind::Fixed)
    }

    fn is_rotary(self) -> bool {
        matches!(self, JointKind::Revolute | JointKind::Continuous)
    }
}

/// One joint of the chain, in the units of this crate.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainJoint {
    /// Joint name from the URDF.
    pub name: String,
    /// Joint kind.
    pub kind: JointKind,
    /// Pose of the joint frame in the parent link frame (translation mm, rotation from the
    /// URDF `rpy`, rad).
    pub origin: Isometry3<f64>,
    /// Joint axis in the joint frame, unit length (unitless).
    pub axis: Unit<Vector3<f64>>,
    /// Travel from `<limit lower upper>`: mm for prismatic, rad for revolute; unbounded for
    /// continuous and fixed joints.
    pub travel: Travel,
    /// `<limit velocity>`: mm/s for prismatic, rad/s for rotary joints; 0 for fixed joints
    /// without a `<limit>`. Informational: the machine file holds the drive limits.
    pub velocity: f64,
    /// The machine axis this joint moves (`None` for fixed joints).
    pub role: Option<AxisName>,
}

impl ChainJoint {
    /// The joint's own motion for joint value `q` (mm or rad): a translation along, or a
    /// rotation about, [`ChainJoint::axis`]. Forward kinematics never clamps `q` to the travel.
    pub fn motion(&self, q: f64) -> Isometry3<f64> {
        match self.kind {
            JointKind::Prismatic => Isometry3::from_parts(
                Translation3::from(self.axis.into_inner() * q),
                UnitQuaternion::identity(),
            ),
            JointKind::Revolute | JointKind::Continuous => Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&self.axis, q),
            ),
            JointKind::Fixed => Isometry3::identity(),
        }
    }
}

/// One step of the chain from the workpiece frame to the tool tip.
#[derive(Debug, Clone, PartialEq)]
enum Step {
    /// A fixed transform (joint origins, inverted on the workpiece side).
    Fixed(Isometry3<f64>),
    /// A joint's motion.
    Joint(JointStep),
}

/// A joint's motion by `sign` times its value: +1 on the tool side, −1 on the workpiece side.
#[derive(Debug, Clone, PartialEq)]
struct JointStep {
    prismatic: bool,
    axis: Unit<Vector3<f64>>,
    role: AxisName,
    sign: f64,
}

/// The tool tip and its motion, and the chain's Jacobian columns, at one set of joints: the
/// outcome of [`KinematicChain::propagate`], all in the workpiece frame.
struct ChainState {
    /// Tool tip, mm.
    p: Vector3<f64>,
    /// Tool axis, unit.
    o: Vector3<f64>,
    /// Tool-tip velocity for the joint velocities given, mm/s.
    v: Vector3<f64>,
    /// Tool-tip acceleration for the joint velocities and accelerations given, mm/s².
    a: Vector3<f64>,
    /// Columns X, Y, Z: the tip's motion per mm of each slide (unitless).
    slides: Matrix3<f64>,
    /// Per rotary joint: its role and its signed axis $\sigma z$ (unit) in the workpiece frame.
    rotary: Vec<(AxisName, Vector3<f64>)>,
}

/// A machine's kinematic chain read from URDF (docs/kinematics.md).
///
/// [`KinematicChain::read_urdf_file`] accepts any serial machine: a tool-tip link named
/// `tool_tip`, a workpiece link named `workpiece` (or the base link), the three slides X, Y, Z
/// and up to three rotary axes, on either side. Each moving joint drives one machine axis:
/// the one its name spells (`x` … `c`, either case) or, for other names, the one along whose
/// direction it moves (a prismatic joint along ±X drives X, a rotary joint about ±Y drives B).
/// [`KinematicChain::kinematics`] turns it into its closed-form family where its forward
/// kinematics equals one, else keeps the chain itself.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicChain {
    name: String,
    source: String,
    base_link: String,
    tool_link: String,
    workpiece_link: String,
    tool: Vec<ChainJoint>,
    workpiece: Vec<ChainJoint>,
    steps: Vec<Step>,
    rotary: Vec<RotaryAxis>,
    limits: AxisLimits,
}

impl KinematicChain {
    /// Reads and validates any serial machine's URDF file. Errors name the file.
    pub fn read_urdf_file(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| Error::Urdf {
            file: file.clone(),
            message: e.to_string(),
        })?;
        Self::read_urdf_str(&text, &file)
    }

    /// Parses and validates any serial machine's URDF text; `source` names it in messages.
    pub fn read_urdf_str(urdf: &str, source: &str) -> Result<Self> {
        let robot = urdf_rs::read_from_string(urdf).map_err(|e| Error::Urdf {
            file: source.to_string(),
            message: e.to_string(),
        })?;
        Builder {
            source,
            robot: &robot,
        }
        .build()
    }

    /// Reads a URDF file that must describe a table-tilting A/C machine (the form vcnc accepted
    /// before it knew other families; [`KinematicChain::read_urdf_file`] takes any machine).
    pub fn from_urdf_file(path: impl AsRef<Path>) -> Result<Self> {
        Self::read_urdf_file(path)?.require_table_tilting_ac()
    }

    /// [`KinematicChain::from_urdf_file`] from text; `source` names it in messages.
    pub fn from_urdf_str(urdf: &str, source: &str) -> Result<Self> {
        Self::read_urdf_str(urdf, source)?.require_table_tilting_ac()
    }

    fn require_table_tilting_ac(self) -> Result<Self> {
        let not = |reason: String| Error::NotTableTilting {
            file: self.source.clone(),
            reason,
        };
        match self.match_closed_form() {
            Ok(Kinematics::TableTilting(TableTilting { tilt: Tilt::A, .. })) => Ok(self),
            Ok(other) => Err(not(format!("it is a {} machine", other.family()))),
            Err(reason) => Err(not(reason)),
        }
    }

    /// The URDF robot name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The file path or source name the chain was read from.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// Name of the base link (the machine frame).
    pub fn base_link(&self) -> &str {
        &self.base_link
    }

    /// Name of the tool-tip link.
    pub fn tool_link(&self) -> &str {
        &self.tool_link
    }

    /// Name of the workpiece link (the base link when the URDF has no `workpiece` link).
    pub fn workpiece_link(&self) -> &str {
        &self.workpiece_link
    }

    /// Joints from the base to the tool tip, in chain order (fixed joints included).
    pub fn tool_joints(&self) -> &[ChainJoint] {
        &self.tool
    }

    /// Joints from the base to the workpiece, in chain order (fixed joints included).
    pub fn workpiece_joints(&self) -> &[ChainJoint] {
        &self.workpiece
    }

    /// The rotary axes, in the order A, B, C, with what each turns.
    pub fn rotary_axes(&self) -> &[RotaryAxis] {
        &self.rotary
    }

    /// Axis travels from the joints' `<limit>` elements (mm, rad; unbounded when continuous).
    pub fn limits(&self) -> AxisLimits {
        self.limits
    }

    /// The same chain with other travels (mm, rad), e.g. the machine file's.
    pub fn with_limits(mut self, limits: AxisLimits) -> Result<Self> {
        limits.validate()?;
        self.limits = limits;
        Ok(self)
    }

    /// The frame origin of the joint driving `axis` (a point of its axis) in the machine frame
    /// at the zero position, mm; `None` if no joint drives it.
    pub fn joint_point(&self, axis: AxisName) -> Option<Vector3<f64>> {
        [&self.tool, &self.workpiece]
            .into_iter()
            .find_map(|joints| {
                let mut t = Isometry3::identity();
                joints.iter().find_map(|j| {
                    t *= j.origin;
                    (j.role == Some(axis)).then_some(t.translation.vector)
                })
            })
    }

    /// The C-axis centre r of an A/C table (the C joint's frame origin at zero), mm.
    pub fn r(&self) -> Vector3<f64> {
        self.joint_point(AxisName::C).unwrap_or_default()
    }

    /// The A-axis centre relative to the C-axis centre of an A/C table, mm.
    pub fn d(&self) -> Vector3<f64> {
        self.joint_point(AxisName::A).unwrap_or_default() - self.r()
    }

    /// The closed form of a table-tilting A/C chain, with r, d and limits from the chain.
    /// Meaningful for a chain read by [`KinematicChain::from_urdf_file`], which checks that
    /// form; [`KinematicChain::kinematics`] serves any chain.
    pub fn table_tilting_ac(&self) -> TableTiltingAc {
        TableTiltingAc {
            r: self.r(),
            d: self.d(),
            limits: self.limits,
        }
    }

    /// Tool-tip frame in the machine frame, $T_{tool}$, at the given axes. Never clamps.
    pub fn tool_frame(&self, axes: &Axes) -> Isometry3<f64> {
        compose(&self.tool, axes)
    }

    /// Workpiece frame in the machine frame, $T_{wp}$, at the given axes. Never clamps.
    pub fn workpiece_frame(&self, axes: &Axes) -> Isometry3<f64> {
        compose(&self.workpiece, axes)
    }

    /// Forward kinematics: the tool pose in the workpiece frame, $T = T_{wp}^{-1} T_{tool}$;
    /// `p` is its translation (mm) and `o` its +Z axis. Never clamps to travel.
    pub fn forward(&self, axes: &Axes) -> Pose {
        let mut t = Isometry3::identity();
        for step in &self.steps {
            match step {
                Step::Fixed(f) => t *= f,
                Step::Joint(j) => {
                    let q = j.sign * axes[j.role];
                    if j.prismatic {
                        t *= Translation3::from(j.axis.into_inner() * q);
                    } else {
                        t *= UnitQuaternion::from_axis_angle(&j.axis, q);
                    }
                }
            }
        }
        Pose {
            p: t.translation.vector,
            o: t.rotation * Vector3::z(),
        }
    }

    /// The kinematics of this chain: its closed-form family when its forward kinematics equals
    /// one (docs/kinematics.md, "From URDF to a family"), else the chain itself.
    pub fn kinematics(&self) -> Kinematics {
        self.match_closed_form()
            .unwrap_or_else(|_| Kinematics::Chain(Box::new(self.clone())))
    }

    /// The closed-form family this chain matches, or why it matches none.
    pub fn closed_form(&self) -> Result<Kinematics> {
        self.match_closed_form()
            .map_err(|reason| Error::NoClosedForm {
                file: self.source.clone(),
                reason,
            })
    }

    /// Joint values, velocities and accelerations → the tool tip's position, velocity and
    /// acceleration in the workpiece frame and the Jacobian columns, by propagating the motion
    /// of every frame along the steps (docs/kinematics.md, "Derivatives along a chain"). Each
    /// frame carries its origin $o$, rotation $R$, angular velocity $\omega$ and acceleration
    /// $\alpha$, origin velocity $v$ and acceleration $a$.
    fn propagate(&self, q: &Axes, qd: &Axes, qdd: &Axes) -> ChainState {
        let mut rot = Matrix3::identity();
        let (mut o, mut v, mut a) = (Vector3::zeros(), Vector3::zeros(), Vector3::zeros());
        let (mut w, mut alpha) = (Vector3::<f64>::zeros(), Vector3::<f64>::zeros());
        let mut slides = Matrix3::zeros();
        let mut rotary = Vec::with_capacity(3);
        // A lever arm `off` carried by the frame: its end moves with the frame's rotation.
        let carry = |off: Vector3<f64>, w: &Vector3<f64>, alpha: &Vector3<f64>| {
            (w.cross(&off), alpha.cross(&off) + w.cross(&w.cross(&off)))
        };
        for step in &self.steps {
            match step {
                Step::Fixed(f) => {
                    let off = rot * f.translation.vector;
                    let (dv, da) = carry(off, &w, &alpha);
                    o += off;
                    v += dv;
                    a += da;
                    rot *= f.rotation.to_rotation_matrix().into_inner();
                }
                Step::Joint(j) => {
                    let z = rot * j.axis.into_inner() * j.sign;
                    let (qv, qdv, qddv) = (q[j.role], qd[j.role], qdd[j.role]);
                    if j.prismatic {
                        let off = z * qv;
                        let (dv, da) = carry(off, &w, &alpha);
                        o += off;
                        v += dv + z * qdv;
                        a += da + w.cross(&z) * (2.0 * qdv) + z * qddv;
                        let col = j.role.index().min(2);
                        slides.set_column(col, &z);
                    } else {
                        alpha += z * qddv + w.cross(&z) * qdv;
                        w += z * qdv;
                        rot *= Rotation3::from_axis_angle(&j.axis, j.sign * qv).into_inner();
                        rotary.push((j.role, z));
                    }
                }
            }
        }
        ChainState {
            p: o,
            o: rot * Vector3::z(),
            v,
            a,
            slides,
            rotary,
        }
    }

    /// The slides' values solving `slides · x = rhs`, or the error of a chain whose slides move
    /// along dependent directions at these rotary angles.
    fn solve_slides(
        slides: &Matrix3<f64>,
        rhs: &Vector3<f64>,
        sample: Option<usize>,
    ) -> Result<Vector3<f64>> {
        let scale = slides.column(0).norm() * slides.column(1).norm() * slides.column(2).norm();
        let det = slides.determinant();
        let solved = (det.abs() > 1e-12 * scale)
            .then(|| slides.lu().solve(rhs))
            .flatten();
        solved.ok_or(Error::DependentSlides { det, sample })
    }

    /// The slides that put the tool tip at `p_w` (workpiece frame, mm) with the rotary axes of
    /// `rot` (rad): the tip is affine in the slides when the rotary angles are fixed,
    /// $p_w = b + S\,x$, so $x = S^{-1}(p_w - b)$, exactly and without iteration.
    pub(crate) fn tcp_position(
        &self,
        p_w: &Vector3<f64>,
        rot: &Axes,
        sample: Option<usize>,
    ) -> Result<Vector3<f64>> {
        let zero = Axes::default();
        let at0 = self.propagate(&rot.with_pm(&Vector3::zeros()), &zero, &zero);
        Self::solve_slides(&at0.slides, &(p_w - at0.p), sample)
    }

    /// [`Self::tcp_position`] with the slides' velocity and acceleration: the tip's velocity is
    /// linear in the slides' velocities and its acceleration linear in their accelerations, so
    /// each follows from one propagation with the slides' rate set to zero.
    pub(crate) fn tcp_motion(
        &self,
        tip: &PointMotion,
        rot: &JointMotion,
        sample: Option<usize>,
    ) -> Result<PointMotion> {
        let zero = Axes::default();
        let pm = self.tcp_position(&tip.p, &rot.pos, sample)?;
        let q = rot.pos.with_pm(&pm);
        let at_v = self.propagate(&q, &rot.vel.with_pm(&Vector3::zeros()), &zero);
        let pm_dot = Self::solve_slides(&at_v.slides, &(tip.p_dot - at_v.v), sample)?;
        let qd = rot.vel.with_pm(&pm_dot);
        let at_a = self.propagate(&q, &qd, &rot.acc.with_pm(&Vector3::zeros()));
        let pm_ddot = Self::solve_slides(&at_a.slides, &(tip.p_ddot - at_a.a), sample)?;
        Ok(PointMotion {
            p: pm,
            p_dot: pm_dot,
            p_ddot: pm_ddot,
        })
    }

    /// The rotary angles that turn the tool axis to `o` (normalised here), by damped least
    /// squares (Levenberg–Marquardt) on the tool-axis error seeded from `seed`'s rotary angles
    /// (docs/kinematics.md, "Pose inverse of a chain"):
    /// $$ \Delta\theta = (J^T J + \lambda^2 I)^{-1} J^T (o - o(\theta)), \qquad
    ///    J_i = \sigma_i z_i \times o(\theta), $$
    /// with $\lambda$ divided by 10 after a step that lowers the error and multiplied by 10
    /// otherwise. Each rotary angle is then moved by whole turns to the value nearest the seed
    /// within its travel. Fails with [`Error::NoConvergence`] when the error stays above
    /// [`IK_TOLERANCE`] (an orientation this chain cannot reach, or one too far from the seed).
    pub(crate) fn solve_orientation(
        &self,
        o: &Vector3<f64>,
        seed: &Axes,
        check_travel: bool,
        sample: Option<usize>,
    ) -> Result<Axes> {
        let target = unit_orientation(o, sample)?;
        let zero = Axes::default();
        let error_at = |q: &Axes| {
            let s = self.propagate(q, &zero, &zero);
            (target - s.o, s)
        };
        let mut q = *seed;
        let (mut e, mut state) = error_at(&q);
        let mut lambda = 1e-3;
        let mut iterations = 0;
        while e.norm() > IK_TOLERANCE && iterations < IK_MAX_ITERATIONS && lambda < 1e8 {
            iterations += 1;
            // Normal equations padded to 3×3 (a chain has at most three rotary joints).
            let cols: Vec<Vector3<f64>> = state
                .rotary
                .iter()
                .map(|(_, z)| z.cross(&state.o))
                .collect();
            let mut jtj = Matrix3::identity();
            let mut jte = Vector3::zeros();
            for (i, ci) in cols.iter().enumerate() {
                for (k, ck) in cols.iter().enumerate() {
                    jtj[(i, k)] = ci.dot(ck) + if i == k { lambda * lambda } else { 0.0 };
                }
                jte[i] = ci.dot(&e);
            }
            let Some(step) = jtj.cholesky().map(|c| c.solve(&jte)) else {
                lambda *= 10.0;
                continue;
            };
            let mut trial = q;
            for ((role, _), dq) in state.rotary.iter().zip(step.iter()) {
                trial[*role] += dq;
            }
            let (e_trial, s_trial) = error_at(&trial);
            if e_trial.norm() < e.norm() {
                (q, e, state) = (trial, e_trial, s_trial);
                lambda = (lambda / 10.0).max(1e-12);
            } else {
                lambda *= 10.0;
            }
        }
        if e.norm() > IK_TOLERANCE {
            return Err(Error::NoConvergence {
                residual: e.norm(),
                iterations,
                sample,
            });
        }
        for r in &self.rotary {
            let travel = if check_travel {
                self.limits[r.axis]
            } else {
                Travel::UNBOUNDED
            };
            let (v, _) =
                unwrap_within(q[r.axis], seed[r.axis], travel).ok_or(Error::OutOfTravel {
                    axis: r.axis,
                    value: q[r.axis],
                    lower: travel.lower,
                    upper: travel.upper,
                    sample,
                })?;
            q[r.axis] = v;
        }
        Ok(q)
    }

    /// Matches the chain against the closed-form families (docs/kinematics.md, "From URDF to a
    /// family"): the rotary axes pick the candidate, the zero position and the axis directions
    /// must be the family's, its offsets are the joints' points at zero, and the forward
    /// kinematics must agree at probe positions.
    fn match_closed_form(&self) -> std::result::Result<Kinematics, String> {
        let kin = self.closed_form_candidate()?;
        // Probe positions spread over the travels and beyond, rotary angles of every quadrant.
        let probes = [
            (120.0, -80.0, 45.0, 0.3, -0.7, 2.2),
            (-310.0, 205.0, -150.0, -1.1, 2.6, -4.0),
            (0.0, 0.0, 0.0, 2.0, -1.9, 0.0),
            (55.0, 400.0, 90.0, -2.9, 0.2, 7.5),
        ];
        let mut worst = (0.0f64, 0.0f64);
        for (x, y, z, a, b, c) in probes {
            let q = Axes { x, y, z, a, b, c };
            let (g, f) = (self.forward(&q), kin.forward(&q));
            worst = (
                worst.0.max((g.p - f.p).norm()),
                worst.1.max((g.o - f.o).norm()),
            );
        }
        if worst.0 > CHAIN_TOLERANCE || worst.1 > CHAIN_TOLERANCE {
            return Err(format!(
                "its forward kinematics differs from the {} closed form by up to {:.3e} mm and \
                 {:.3e} in the tool axis",
                kin.family(),
                worst.0,
                worst.1
            ));
        }
        Ok(kin)
    }

    /// The closed form this chain's structure suggests, with offsets from the joints' points at
    /// zero, after the structural checks (zero position, directions, order of the joints).
    fn closed_form_candidate(&self) -> std::result::Result<Kinematics, String> {
        let tilt_of = |r: &RotaryAxis| Tilt::of(r.axis);
        let (tilt, tilt_on, c_on) = match self.rotary.as_slice() {
            [] => (None, None, None),
            [t, c] if c.axis == AxisName::C && tilt_of(t).is_some() => {
                (tilt_of(t), Some(t.turns), Some(c.turns))
            }
            other => {
                let names: Vec<String> = other
                    .iter()
                    .map(|r| format!("{} ({})", r.axis, r.turns))
                    .collect();
                return Err(format!(
                    "its rotary axes {} match no closed-form family",
                    if names.is_empty() {
                        "(none)".into()
                    } else {
                        names.join(", ")
                    }
                ));
            }
        };
        self.check_zero_position()?;
        self.check_directions()?;
        let point = |axis| self.joint_point(axis).unwrap_or_default();
        let order = |joints: &[ChainJoint], first: AxisName, then: AxisName| {
            let pos = |a| joints.iter().position(|j| j.role == Some(a));
            pos(first) < pos(then)
        };
        let limits = self.limits;
        let kin = match (tilt, tilt_on, c_on) {
            (None, ..) => Kinematics::Xyz(Xyz { limits }),
            (Some(t), Some(Carrier::Table), Some(Carrier::Table)) => {
                if !order(&self.workpiece, t.axis(), AxisName::C) {
                    return Err(format!(
                        "the table's C axis carries {t}; the tilt must carry C"
                    ));
                }
                let r = point(AxisName::C);
                Kinematics::TableTilting(TableTilting {
                    tilt: t,
                    r,
                    d: point(t.axis()) - r,
                    limits,
                })
            }
            (Some(t), Some(Carrier::Head), Some(Carrier::Head)) => {
                if !order(&self.tool, AxisName::C, t.axis()) {
                    return Err(format!(
                        "the head's {t} axis carries C; C must carry the tilt"
                    ));
                }
                Kinematics::HeadHead(HeadHead {
                    tilt: t,
                    pivot: point(t.axis()),
                    c_axis: point(AxisName::C),
                    limits,
                })
            }
            (Some(t), Some(Carrier::Head), Some(Carrier::Table)) => {
                Kinematics::HeadTable(HeadTable {
                    tilt: t,
                    pivot: point(t.axis()),
                    r: point(AxisName::C),
                    limits,
                })
            }
            (Some(t), ..) => {
                return Err(format!(
                    "a tilting table {t} under a C head matches no closed-form family"
                ));
            }
        };
        Ok(kin)
    }

    /// At zero the tool tip and the workpiece frame coincide with the machine frame.
    fn check_zero_position(&self) -> std::result::Result<(), String> {
        let zero = Axes::default();
        check_identity(
            &compose(&self.tool, &zero),
            &format!("the tool tip link '{}'", self.tool_link),
            "make the tool tip coincide with the machine origin, tool along +Z, at zero",
        )?;
        check_identity(
            &compose(&self.workpiece, &zero),
            &format!("the workpiece link '{}'", self.workpiece_link),
            "the workpiece frame must equal the machine frame at zero (a fixed workpiece joint \
             at -r on a table)",
        )
    }

    /// Every moving joint points along its axis in the machine frame at zero: rotary joints
    /// and tool-side slides along +, workpiece-side slides along − (a table moving −X moves the
    /// tool +X relative to the workpiece).
    fn check_directions(&self) -> std::result::Result<(), String> {
        for (joints, side) in [(&self.tool, 1.0), (&self.workpiece, -1.0)] {
            let mut t = Isometry3::identity();
            for j in joints.iter() {
                t *= j.origin;
                let Some(role) = j.role else { continue };
                let dir = t.rotation * j.axis.into_inner();
                let (plus, unit) = unit_name(role);
                let slide_sign = if role.is_rotary() { 1.0 } else { side };
                let expected = unit * slide_sign;
                let name = if slide_sign > 0.0 {
                    plus.to_string()
                } else {
                    plus.replace('+', "-")
                };
                if (dir - expected).norm() > CHAIN_TOLERANCE {
                    let frame = if t.rotation.angle() == 0.0 {
                        ""
                    } else {
                        " in the machine frame"
                    };
                    return Err(format!(
                        "joint '{}' axis is {}{frame}, expected {name} (axis {role})",
                        j.name,
                        fmt_vec(&dir)
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Tolerance of the chain's pose inverse on the tool axis (unit vector): about 1e-13 rad.
pub const IK_TOLERANCE: f64 = 1e-13;

/// Iteration limit of the chain's pose inverse.
pub const IK_MAX_ITERATIONS: usize = 200;

fn compose(joints: &[ChainJoint], axes: &Axes) -> Isometry3<f64> {
    let mut t = Isometry3::identity();
    for j in joints {
        let q = j.role.map_or(0.0, |axis| axes[axis]);
        t = t * j.origin * j.motion(q);
    }
    t
}

fn check_identity(t: &Isometry3<f64>, what: &str, hint: &str) -> std::result::Result<(), String> {
    let p = t.translation.vector;
    let angle = t.rotation.angle();
    if p.norm() > CHAIN_TOLERANCE || angle > CHAIN_TOLERANCE {
        return Err(format!(
            "{what} is at {} mm, rotated by {angle} rad, at zero; {hint}",
            fmt_vec(&p)
        ));
    }
    Ok(())
}

fn fmt_vec(v: &Vector3<f64>) -> String {
    format!("({}, {}, {})", v.x, v.y, v.z)
}

fn unit_name(axis: AxisName) -> (&'static str, Vector3<f64>) {
    match axis {
        AxisName::X | AxisName::A => ("+X", Vector3::x()),
        AxisName::Y | AxisName::B => ("+Y", Vector3::y()),
        AxisName::Z | AxisName::C => ("+Z", Vector3::z()),
    }
}

/// The machine axis a direction lies along (±X, ±Y, ±Z), if any: the linear one for a slide,
/// the rotary one for a rotary joint.
fn principal_role(dir: &Vector3<f64>, rotary: bool) -> Option<AxisName> {
    let axes = if rotary {
        [AxisName::A, AxisName::B, AxisName::C]
    } else {
        [AxisName::X, AxisName::Y, AxisName::Z]
    };
    axes.into_iter().find(|&a| {
        let (_, e) = unit_name(a);
        (dir - e).norm() <= CHAIN_TOLERANCE || (dir + e).norm() <= CHAIN_TOLERANCE
    })
}

/// The URDF's links as a tree.
struct Tree<'r> {
    /// Link name → index in the URDF.
    link_index: HashMap<&'r str, usize>,
    /// The joint whose child is each link.
    parent_joint: Vec<Option<usize>>,
    /// Name of the base link.
    base_link: String,
}

struct Builder<'a> {
    source: &'a str,
    robot: &'a urdf_rs::Robot,
}

/// The link the tool tip must be named.
pub const TOOL_LINK: &str = "tool_tip";
/// The link the workpiece frame is named (optional: the base link otherwise).
pub const WORKPIECE_LINK: &str = "workpiece";

impl Builder<'_> {
    fn fail(&self, reason: String) -> Error {
        Error::Chain {
            file: self.source.to_string(),
            reason,
        }
    }

    /// Reads the URDF in stages: the link tree, the paths to the tool tip and the workpiece,
    /// the joints with their roles, then the steps from the workpiece to the tool tip.
    fn build(&self) -> Result<KinematicChain> {
        let kinds = self.joint_kinds()?;
        let tree = self.tree()?;
        let tool_path = self.path_to(&tree, TOOL_LINK)?.ok_or_else(|| {
            self.fail(format!(
                "no link named '{TOOL_LINK}': vcnc finds the tool tip and the workpiece by their \
                 link names '{TOOL_LINK}' and '{WORKPIECE_LINK}' (docs/kinematics.md)"
            ))
        })?;
        let wp_path = self.path_to(&tree, WORKPIECE_LINK)?.unwrap_or_default();
        let workpiece_link = if wp_path.is_empty() && !tree.link_index.contains_key(WORKPIECE_LINK)
        {
            tree.base_link.clone()
        } else {
            WORKPIECE_LINK.to_string()
        };
        // Joints on both paths move tool and workpiece together: only fixed ones may be shared.
        let shared = tool_path
            .iter()
            .zip(&wp_path)
            .take_while(|(a, b)| a == b)
            .count();
        for &ji in &tool_path[..shared] {
            if kinds.get(ji).is_some_and(|k| k.is_movable()) {
                return Err(self.fail(format!(
                    "joint '{}' moves both the tool tip and the workpiece",
                    self.joint_name(ji)
                )));
            }
        }
        for (ji, joint) in self.robot.joints.iter().enumerate() {
            if kinds.get(ji).is_some_and(|k| k.is_movable())
                && !tool_path.contains(&ji)
                && !wp_path.contains(&ji)
            {
                return Err(self.fail(format!(
                    "joint '{}' moves but is on neither the tool branch nor the workpiece branch",
                    joint.name
                )));
            }
        }
        let tool = self.convert(&tool_path, &kinds)?;
        let workpiece = self.convert(&wp_path, &kinds)?;
        self.check_roles(&tool, &workpiece)?;

        let mut limits = AxisLimits::default();
        let mut rotary = Vec::new();
        for (joints, turns) in [(&tool, Carrier::Head), (&workpiece, Carrier::Table)] {
            for j in joints.iter() {
                if let Some(axis) = j.role {
                    limits[axis] = j.travel;
                    if axis.is_rotary() {
                        rotary.push(RotaryAxis { axis, turns });
                    }
                }
            }
        }
        rotary.sort_by_key(|r| r.axis);

        // Steps: T_wp^-1 (the workpiece path backwards, past the shared part) then T_tool.
        let mut steps = Vec::new();
        for j in workpiece[shared..].iter().rev() {
            push_joint(&mut steps, j, -1.0);
            push_fixed(&mut steps, j.origin.inverse());
        }
        for j in &tool[shared..] {
            push_fixed(&mut steps, j.origin);
            push_joint(&mut steps, j, 1.0);
        }

        let chain = KinematicChain {
            name: self.robot.name.clone(),
            source: self.source.to_string(),
            base_link: tree.base_link.clone(),
            tool_link: TOOL_LINK.to_string(),
            workpiece_link,
            tool,
            workpiece,
            steps,
            rotary,
            limits,
        };
        // The slides must span space at zero (the TCP inverse solves for them).
        let zero = Axes::default();
        let s = chain.propagate(&zero, &zero, &zero);
        if KinematicChain::solve_slides(&s.slides, &Vector3::zeros(), None).is_err() {
            return Err(self.fail(format!(
                "the slides X, Y, Z move along dependent directions {}, {}, {} at zero",
                fmt_vec(&s.slides.column(0).into()),
                fmt_vec(&s.slides.column(1).into()),
                fmt_vec(&s.slides.column(2).into())
            )));
        }
        Ok(chain)
    }

    fn joint_name(&self, ji: usize) -> &str {
        self.robot.joints.get(ji).map_or("?", |j| j.name.as_str())
    }

    /// Links and joints as a tree: unique names, one parent joint per link, one base link.
    fn tree(&self) -> Result<Tree<'_>> {
        let robot = self.robot;
        let mut link_index: HashMap<&str, usize> = HashMap::new();
        for (i, link) in robot.links.iter().enumerate() {
            if link_index.insert(link.name.as_str(), i).is_some() {
                return Err(self.fail(format!("link '{}' is defined twice", link.name)));
            }
        }
        let mut joint_names: HashMap<&str, usize> = HashMap::new();
        for (i, joint) in robot.joints.iter().enumerate() {
            if joint_names.insert(joint.name.as_str(), i).is_some() {
                return Err(self.fail(format!("joint '{}' is defined twice", joint.name)));
            }
        }
        let mut parent_joint: Vec<Option<usize>> = vec![None; robot.links.len()];
        let mut child_joints: Vec<Vec<usize>> = vec![Vec::new(); robot.links.len()];
        for (ji, joint) in robot.joints.iter().enumerate() {
            let Some(&p) = link_index.get(joint.parent.link.as_str()) else {
                return Err(self.fail(format!(
                    "joint '{}' names parent link '{}', which is not defined",
                    joint.name, joint.parent.link
                )));
            };
            let Some(&c) = link_index.get(joint.child.link.as_str()) else {
                return Err(self.fail(format!(
                    "joint '{}' names child link '{}', which is not defined",
                    joint.name, joint.child.link
                )));
            };
            if let Some(Some(other)) = parent_joint.get(c) {
                return Err(self.fail(format!(
                    "link '{}' is the child of two joints, '{}' and '{}'",
                    joint.child.link,
                    self.joint_name(*other),
                    joint.name
                )));
            }
            if let Some(slot) = parent_joint.get_mut(c) {
                *slot = Some(ji);
            }
            if let Some(children) = child_joints.get_mut(p) {
                children.push(ji);
            }
        }
        let roots: Vec<usize> = (0..robot.links.len())
            .filter(|&i| parent_joint.get(i).is_some_and(|p| p.is_none()))
            .collect();
        let root = match roots.as_slice() {
            [r] => *r,
            [] => {
                return Err(self.fail(
                    "no base link: every link has a parent joint (the joints form a loop)".into(),
                ));
            }
            many => {
                let names: Vec<String> = many
                    .iter()
                    .filter_map(|&i| robot.links.get(i).map(|l| format!("'{}'", l.name)))
                    .collect();
                return Err(self.fail(format!(
                    "links {} have no parent joint; expected one base link",
                    names.join(", ")
                )));
            }
        };
        let base_link = robot
            .links
            .get(root)
            .map_or(String::new(), |l| l.name.clone());
        // Every link must hang from the base (a loop of joints would leave some unreachable).
        let mut stack = vec![root];
        let mut reached = 0usize;
        while let Some(link) = stack.pop() {
            reached += 1;
            for &ji in child_joints.get(link).map_or(&[][..], |v| v.as_slice()) {
                if let Some(&c) = robot
                    .joints
                    .get(ji)
                    .and_then(|j| link_index.get(j.child.link.as_str()))
                {
                    stack.push(c);
                }
            }
        }
        if reached != robot.links.len() {
            return Err(self.fail(format!(
                "{} link(s) are not connected to the base link '{}' (a loop of joints?)",
                robot.links.len() - reached,
                base_link
            )));
        }
        Ok(Tree {
            link_index,
            parent_joint,
            base_link,
        })
    }

    /// The joints from the base link to the link named `name`, in order; `None` if there is no
    /// such link.
    fn path_to(&self, tree: &Tree<'_>, name: &str) -> Result<Option<Vec<usize>>> {
        let Some(&leaf) = tree.link_index.get(name) else {
            return Ok(None);
        };
        let mut link = leaf;
        let mut path = Vec::new();
        while let Some(Some(ji)) = tree.parent_joint.get(link) {
            path.push(*ji);
            let parent = self.robot.joints.get(*ji).map(|j| j.parent.link.as_str());
            match parent.and_then(|p| tree.link_index.get(p)) {
                Some(&p) => link = p,
                None => return Err(self.fail("internal: a joint lost its parent link".into())),
            }
            if path.len() > self.robot.joints.len() {
                return Err(self.fail("internal: the joints form a loop".into()));
            }
        }
        path.reverse();
        Ok(Some(path))
    }

    /// The kind of every joint, in URDF order; mimic and planar/floating joints are refused.
    fn joint_kinds(&self) -> Result<Vec<JointKind>> {
        let robot = self.robot;
        let mut kinds = Vec::with_capacity(robot.joints.len());
        for joint in &robot.joints {
            if joint.mimic.is_some() {
                return Err(self.fail(format!(
                    "joint '{}' is a mimic joint; mimic joints are not supported",
                    joint.name
                )));
            }
            let kind = match joint.joint_type {
                urdf_rs::JointType::Prismatic => JointKind::Prismatic,
                urdf_rs::JointType::Revolute => JointKind::Revolute,
                urdf_rs::JointType::Continuous => JointKind::Continuous,
                urdf_rs::JointType::Fixed => JointKind::Fixed,
                ref other => {
                    return Err(self.fail(format!(
                        "joint '{}' is {:?}; only prismatic, revolute, continuous and fixed \
                         joints are supported",
                        joint.name, other
                    )));
                }
            };
            kinds.push(kind);
        }
        Ok(kinds)
    }

    /// Converts the URDF joints of one path, giving each moving joint its machine axis: the one
    /// its name spells, else the one along whose direction (in the machine frame at zero) it
    /// moves.
    fn convert(&self, path: &[usize], kinds: &[JointKind]) -> Result<Vec<ChainJoint>> {
        let mut out = Vec::with_capacity(path.len());
        let mut frame = Isometry3::identity();
        for &ji in path {
            let (Some(joint), Some(&kind)) = (self.robot.joints.get(ji), kinds.get(ji)) else {
                return Err(self.fail("internal: joint index out of range".into()));
            };
            let xyz = Vector3::from(joint.origin.xyz.0);
            let rpy = joint.origin.rpy.0;
            if !xyz.iter().chain(rpy.iter()).all(|v| v.is_finite()) {
                return Err(self.fail(format!(
                    "joint '{}' origin xyz = {} rpy = {} is not finite",
                    joint.name,
                    fmt_vec(&xyz),
                    fmt_vec(&Vector3::from(rpy))
                )));
            }
            let origin = Isometry3::from_parts(
                Translation3::from(xyz),
                UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
            );
            frame *= origin;
            let raw_axis = Vector3::from(joint.axis.xyz.0);
            let norm = raw_axis.norm();
            let axis = if kind == JointKind::Fixed {
                Unit::new_unchecked(Vector3::x())
            } else if norm.is_finite() && norm > CHAIN_TOLERANCE {
                Unit::new_normalize(raw_axis)
            } else {
                return Err(self.fail(format!(
                    "joint '{}' axis is {}; it needs a finite nonzero direction",
                    joint.name,
                    fmt_vec(&raw_axis)
                )));
            };
            let travel = match kind {
                JointKind::Prismatic | JointKind::Revolute => {
                    let (lo, hi) = (joint.limit.lower, joint.limit.upper);
                    if lo.is_nan() || hi.is_nan() || lo > hi {
                        return Err(self.fail(format!(
                            "joint '{}' travel {lo} ..= {hi} needs lower <= upper",
                            joint.name
                        )));
                    }
                    if lo == hi {
                        return Err(self.fail(format!(
                            "joint '{}' has no travel (lower = upper = {lo}); give \
                             <limit lower=\"..\" upper=\"..\" velocity=\"..\"/>",
                            joint.name
                        )));
                    }
                    Travel {
                        lower: lo,
                        upper: hi,
                    }
                }
                JointKind::Continuous | JointKind::Fixed => Travel::UNBOUNDED,
            };
            let role = if kind.is_movable() {
                Some(self.role(joint, kind, &(frame.rotation * axis.into_inner()))?)
            } else {
                None
            };
            out.push(ChainJoint {
                name: joint.name.clone(),
                kind,
                origin,
                axis,
                travel,
                velocity: joint.limit.velocity,
                role,
            });
        }
        Ok(out)
    }

    /// The machine axis a moving joint drives (its name, else its direction `dir` at zero).
    fn role(
        &self,
        joint: &urdf_rs::Joint,
        kind: JointKind,
        dir: &Vector3<f64>,
    ) -> Result<AxisName> {
        let rotary = kind.is_rotary();
        let mut letters = joint.name.chars();
        let named = match (letters.next(), letters.next()) {
            (Some(c), None) => AxisName::from_letter(c),
            _ => None,
        };
        match named {
            Some(axis) if axis.is_rotary() != rotary => Err(self.fail(format!(
                "joint '{}' is {} but its name makes it the {} axis {axis}",
                joint.name,
                if rotary { "rotary" } else { "prismatic" },
                if axis.is_rotary() { "rotary" } else { "linear" },
            ))),
            Some(axis) => Ok(axis),
            None => principal_role(dir, rotary).ok_or_else(|| {
                self.fail(format!(
                    "joint '{}' axis is {} in the machine frame, not along X, Y or Z: name the \
                     joint after the machine axis it drives (x, y, z, a, b or c)",
                    joint.name,
                    fmt_vec(dir)
                ))
            }),
        }
    }

    /// Each machine axis is driven by one joint; X, Y and Z are there.
    fn check_roles(&self, tool: &[ChainJoint], workpiece: &[ChainJoint]) -> Result<()> {
        let mut by_axis: HashMap<AxisName, &str> = HashMap::new();
        for j in tool.iter().chain(workpiece) {
            if let Some(axis) = j.role
                && let Some(other) = by_axis.insert(axis, &j.name)
            {
                return Err(self.fail(format!(
                    "joints '{other}' and '{}' both drive axis {axis}",
                    j.name
                )));
            }
        }
        for axis in [AxisName::X, AxisName::Y, AxisName::Z] {
            if !by_axis.contains_key(&axis) {
                return Err(self.fail(format!(
                    "no joint drives axis {axis}: vcnc needs the three slides X, Y and Z"
                )));
            }
        }
        Ok(())
    }
}

fn push_fixed(steps: &mut Vec<Step>, f: Isometry3<f64>) {
    if let Some(Step::Fixed(last)) = steps.last_mut() {
        *last *= f;
    } else {
        steps.push(Step::Fixed(f));
    }
}

fn push_joint(steps: &mut Vec<Step>, j: &ChainJoint, sign: f64) {
    if let Some(role) = j.role {
        steps.push(Step::Joint(JointStep {
            prismatic: j.kind == JointKind::Prismatic,
            axis: j.axis,
            role,
            sign,
        }));
    }
}
