//! [`Kinematics`]: the one value the rest of vcnc talks to, a closed enum of machine families,
//! and what works on it: the pose inverse over sequences ([`PoseSolver`]), the tool-centre-point
//! inverse over tracks, and the map from a machine's axes to the kinematics' ([`AxisMap`]).

use std::f64::consts::{FRAC_PI_2, PI};
use std::fmt;
use std::path::Path;

use nalgebra::Vector3;

use crate::chain::KinematicChain;
use crate::error::{Error, Result};
use crate::families::{HeadHead, HeadTable, TableTilting, Xyz, tilt_and_c};
use crate::types::{
    Axes, AxisLimits, AxisName, Branch, Carrier, JointMotion, PointMotion, Pose, RotaryAxis, Tilt,
    Track, Track3, Travel,
};
use crate::wrist::{Wrist, unit_orientation};

/// Degrees to radians, as the interpolated tracks of rotary axes are converted.
const DEG: f64 = PI / 180.0;

/// A machine family with its parameters: what [`Kinematics`] holds, without the numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Family {
    /// Three slides, the tool fixed along +Z.
    Xyz,
    /// A table tilted by A or B and turned by C.
    TableTilting(Tilt),
    /// A head turned by C and tilted by A or B.
    HeadHead(Tilt),
    /// A head tilted by A or B over a table turned by C.
    HeadTable(Tilt),
    /// Any other serial chain, from a URDF.
    Chain,
}

impl fmt::Display for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Family::Xyz => f.write_str("3-axis XYZ"),
            Family::TableTilting(t) => write!(f, "table-tilting {t}/C"),
            Family::HeadHead(t) => write!(f, "head-head C/{t}"),
            Family::HeadTable(t) => write!(f, "head-table {t}/C"),
            Family::Chain => f.write_str("serial chain"),
        }
    }
}

/// The kinematics of a machine: one of a closed set of families (docs/kinematics.md).
///
/// Conventions shared by every family:
/// - joint values are [`Axes`]: X, Y, Z in mm (the slides), A, B, C in rad (continuous);
///   [`Kinematics::axes`] says which slots a family uses;
/// - a pose is the tool tip and the unit tool axis (tip → spindle) in the workpiece frame,
///   which equals the machine frame when every axis is at zero;
/// - a positive rotary angle turns whatever it carries (the head or the table,
///   [`Kinematics::rotary_axes`]) right-handedly about the axis's + direction;
/// - the forward kinematics never clamps to travel; the inverse ones unwind C within its
///   travel and report what they cannot do as typed errors.
#[derive(Debug, Clone, PartialEq)]
pub enum Kinematics {
    /// 3-axis XYZ: tool tip = slides, tool along +Z.
    Xyz(Xyz),
    /// Table-tilting A/C or B/C (closed form).
    TableTilting(TableTilting),
    /// Head-head: C then A or B in the head (closed form).
    HeadHead(HeadHead),
    /// Head-table: A or B in the head, C in the table (closed form).
    HeadTable(HeadTable),
    /// Any other serial chain from a URDF: forward kinematics along the chain, the pose
    /// inverse by damped least squares.
    Chain(Box<KinematicChain>),
}

/// Which family to build and its offsets, as a machine file gives them (mm). A field that does
/// not apply to the family must be `None`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct KinematicsParams {
    /// The family. [`Family::Chain`] is built from a URDF instead
    /// ([`Kinematics::from_urdf_file`]).
    pub family: Option<Family>,
    /// Table-tilting and head-table: the C-axis centre $r$ in the machine frame, mm. Default 0.
    pub c_centre_mm: Option<[f64; 3]>,
    /// Table-tilting: the tilt-axis centre relative to the C-axis centre, $d$, mm. Default 0.
    pub tilt_offset_mm: Option<[f64; 3]>,
    /// Head-head and head-table: the pivot length $L$, mm (tilt axis above the tool tip at zero
    /// rotation, tool length included); sets the pivot to $(0, 0, L)$ and, on a head-head
    /// machine, the C-axis point too. Give this or `pivot_mm`.
    pub pivot_length_mm: Option<f64>,
    /// Head-head and head-table: a point of the tilt axis relative to the tool tip at zero
    /// rotation, $s_t$, mm.
    pub pivot_mm: Option<[f64; 3]>,
    /// Head-head: a point of the C axis relative to the tool tip at zero rotation, $s_c$, mm.
    /// Default: the pivot.
    pub c_axis_mm: Option<[f64; 3]>,
    /// Travels (mm, rad).
    pub limits: AxisLimits,
}

/// How a pose sequence is solved ([`Kinematics::inverse_sequence`], [`PoseSolver`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkOptions {
    /// The branch of the first sample, or `None` to choose automatically: branch +1 if it keeps
    /// every axis within travel over the whole sequence, else branch −1. Default `None`.
    pub branch: Option<Branch>,
    /// The joints "before" the first sample (mm, rad): C is unwound nearest to its C, a chain's
    /// solve starts from it. Default all zero.
    pub start: Axes,
    /// Check every sample against the travels, and unwind C within its travel. Default true.
    pub check_travel: bool,
    /// Never switch branch: a path through the singularity then turns C by half a turn in one
    /// sample (recorded in [`IkSolution::flips`]). Default false: the branch switches where
    /// that keeps the rotary axes continuous (docs/kinematics.md, "Branch rule").
    pub keep_branch: bool,
}

impl Default for IkOptions {
    fn default() -> Self {
        Self {
            branch: None,
            start: Axes::default(),
            check_travel: true,
            keep_branch: false,
        }
    }
}

/// The joints of a pose sequence and how they were obtained.
#[derive(Debug, Clone, PartialEq)]
pub struct IkSolution {
    /// One set of joints per pose (mm, rad; rotary axes continuous).
    pub axes: Vec<Axes>,
    /// The branch of the first sample.
    pub branch: Branch,
    /// Samples at the singularity ($|\sin t| <$ [`SINGULAR_SIN_A`](crate::SINGULAR_SIN_A))
    /// whose C was held at the previous value.
    pub singular_samples: usize,
    /// Samples where the branch switched (the tilt changed sign through the singularity).
    pub branch_switches: Vec<usize>,
    /// Samples whose C was moved a whole turn to stay within its travel (the table unwinds).
    pub unwinds: Vec<usize>,
    /// Samples where C turned by more than a quarter turn from the previous sample (only with
    /// [`IkOptions::keep_branch`] through the singularity, or a path that demands it).
    pub flips: Vec<usize>,
}

/// Rotary angles for a tool axis ([`Kinematics::inverse_orientation`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotarySolution {
    /// The joints with the rotary axes set (rad); the slides are the previous ones.
    pub joints: Axes,
    /// True at the singularity, where C was held.
    pub singular: bool,
    /// True if C was moved a whole turn to stay within its travel.
    pub unwound: bool,
}

impl Kinematics {
    /// The family, without its parameters.
    pub fn family(&self) -> Family {
        match self {
            Kinematics::Xyz(_) => Family::Xyz,
            Kinematics::TableTilting(m) => Family::TableTilting(m.tilt),
            Kinematics::HeadHead(m) => Family::HeadHead(m.tilt),
            Kinematics::HeadTable(m) => Family::HeadTable(m.tilt),
            Kinematics::Chain(_) => Family::Chain,
        }
    }

    /// The rotary axes, in the order A, B, C, and what each turns: none for 3-axis, two for the
    /// closed-form families (the tilt, then C), up to three for a chain.
    pub fn rotary_axes(&self) -> Vec<RotaryAxis> {
        let pair = |tilt: Tilt, t: Carrier, c: Carrier| {
            let [ta, ca] = tilt_and_c(tilt);
            vec![
                RotaryAxis { axis: ta, turns: t },
                RotaryAxis { axis: ca, turns: c },
            ]
        };
        match self {
            Kinematics::Xyz(_) => Vec::new(),
            Kinematics::TableTilting(m) => pair(m.tilt, Carrier::Table, Carrier::Table),
            Kinematics::HeadHead(m) => pair(m.tilt, Carrier::Head, Carrier::Head),
            Kinematics::HeadTable(m) => pair(m.tilt, Carrier::Head, Carrier::Table),
            Kinematics::Chain(c) => c.rotary_axes().to_vec(),
        }
    }

    /// The machine axes this kinematics uses: X, Y, Z, then the rotary axes in the order A, B, C.
    pub fn axes(&self) -> Vec<AxisName> {
        [AxisName::X, AxisName::Y, AxisName::Z]
            .into_iter()
            .chain(self.rotary_axes().into_iter().map(|r| r.axis))
            .collect()
    }

    /// The travels (mm, rad).
    pub fn limits(&self) -> AxisLimits {
        match self {
            Kinematics::Xyz(m) => m.limits,
            Kinematics::TableTilting(m) => m.limits,
            Kinematics::HeadHead(m) => m.limits,
            Kinematics::HeadTable(m) => m.limits,
            Kinematics::Chain(c) => c.limits(),
        }
    }

    /// The same kinematics with other travels (mm, rad), e.g. the machine file's.
    pub fn with_limits(self, limits: AxisLimits) -> Result<Self> {
        limits.validate()?;
        Ok(match self {
            Kinematics::Xyz(_) => Kinematics::Xyz(Xyz { limits }),
            Kinematics::TableTilting(m) => Kinematics::TableTilting(TableTilting { limits, ..m }),
            Kinematics::HeadHead(m) => Kinematics::HeadHead(HeadHead { limits, ..m }),
            Kinematics::HeadTable(m) => Kinematics::HeadTable(HeadTable { limits, ..m }),
            Kinematics::Chain(c) => Kinematics::Chain(Box::new(c.with_limits(limits)?)),
        })
    }

    /// Builds a closed-form family from its parameter table, checked: the offsets a family needs
    /// are given and finite, none is given that does not apply to it, the travels are ordered.
    pub fn from_params(p: &KinematicsParams) -> Result<Self> {
        let given = |name: &str, set: bool, applies: bool| -> Result<()> {
            if set && !applies {
                Err(Error::BadParameter {
                    name: name.into(),
                    value: "given".into(),
                    reason: "does not apply to this kinematic family",
                })
            } else {
                Ok(())
            }
        };
        let family = p.family.ok_or(Error::BadParameter {
            name: "family".into(),
            value: "none".into(),
            reason: "needs one of xyz, table-tilting, head-head, head-table (or a URDF)",
        })?;
        let is = |f: fn(Family) -> bool| f(family);
        let table = is(|f| matches!(f, Family::TableTilting(_)));
        let head_head = is(|f| matches!(f, Family::HeadHead(_)));
        let head_table = is(|f| matches!(f, Family::HeadTable(_)));
        given("c_centre_mm", p.c_centre_mm.is_some(), table || head_table)?;
        given("tilt_offset_mm", p.tilt_offset_mm.is_some(), table)?;
        given(
            "pivot_length_mm",
            p.pivot_length_mm.is_some(),
            head_head || head_table,
        )?;
        given("pivot_mm", p.pivot_mm.is_some(), head_head || head_table)?;
        given("c_axis_mm", p.c_axis_mm.is_some(), head_head)?;
        let v = |a: Option<[f64; 3]>| a.map_or(Vector3::zeros(), Vector3::from);
        let pivot = || -> Result<Vector3<f64>> {
            match (p.pivot_length_mm, p.pivot_mm) {
                (Some(l), None) => Ok(Vector3::new(0.0, 0.0, l)),
                (None, Some(s)) => Ok(Vector3::from(s)),
                (Some(_), Some(_)) => Err(Error::BadParameter {
                    name: "pivot_mm".into(),
                    value: "given with pivot_length_mm".into(),
                    reason: "give one of pivot_length_mm and pivot_mm",
                }),
                (None, None) => Err(Error::BadParameter {
                    name: "pivot_length_mm".into(),
                    value: "missing".into(),
                    reason: "a spindle head needs its pivot: pivot_length_mm or pivot_mm",
                }),
            }
        };
        Ok(match family {
            Family::Xyz => {
                p.limits.validate()?;
                Kinematics::Xyz(Xyz { limits: p.limits })
            }
            Family::TableTilting(tilt) => Kinematics::TableTilting(TableTilting::new(
                tilt,
                v(p.c_centre_mm),
                v(p.tilt_offset_mm),
                p.limits,
            )?),
            Family::HeadHead(tilt) => {
                let s_t = pivot()?;
                let s_c = p.c_axis_mm.map_or(s_t, Vector3::from);
                Kinematics::HeadHead(HeadHead::new(tilt, s_t, s_c, p.limits)?)
            }
            Family::HeadTable(tilt) => {
                Kinematics::HeadTable(HeadTable::new(tilt, pivot()?, v(p.c_centre_mm), p.limits)?)
            }
            Family::Chain => {
                return Err(Error::BadParameter {
                    name: "family".into(),
                    value: "chain".into(),
                    reason: "a serial chain is read from a URDF (Kinematics::from_urdf_file)",
                });
            }
        })
    }

    /// Reads a machine's URDF (any serial machine, docs/kinematics.md) and returns its
    /// closed-form family where the chain matches one, else the chain.
    pub fn from_urdf_file(path: impl AsRef<Path>) -> Result<Self> {
        Ok(KinematicChain::read_urdf_file(path)?.kinematics())
    }

    /// [`Kinematics::from_urdf_file`] from text; `source` names it in messages.
    pub fn from_urdf_str(urdf: &str, source: &str) -> Result<Self> {
        Ok(KinematicChain::read_urdf_str(urdf, source)?.kinematics())
    }

    /// The closed-form families' tool-axis map.
    fn wrist(&self) -> Option<Wrist> {
        match self {
            Kinematics::TableTilting(m) => Some(m.wrist()),
            Kinematics::HeadHead(m) => Some(m.wrist()),
            Kinematics::HeadTable(m) => Some(m.wrist()),
            Kinematics::Xyz(_) | Kinematics::Chain(_) => None,
        }
    }

    /// Forward kinematics: the tool pose in the workpiece frame (mm, unit tool axis) at joints
    /// `j` (mm, rad). Never clamps to travel (actual positions overshoot, and the contour error
    /// must see it); non-finite joints give a non-finite pose.
    pub fn forward(&self, j: &Axes) -> Pose {
        match self {
            Kinematics::Xyz(m) => m.forward(j),
            Kinematics::TableTilting(m) => m.forward(j),
            Kinematics::HeadHead(m) => m.forward(j),
            Kinematics::HeadTable(m) => m.forward(j),
            Kinematics::Chain(c) => c.forward(j),
        }
    }

    /// The rotary angles that point the tool along `o` (any positive length) on `branch`, the
    /// one nearest to `previous` (docs/kinematics.md, "Rotary axes and the tool axis"): C is
    /// unwound to the value nearest the previous C within its travel and held at the
    /// singularity. A chain solves by damped least squares from `previous` (its branch is the
    /// one continuous from there). A 3-axis machine accepts only +Z. `sample` tags errors.
    pub fn inverse_orientation(
        &self,
        o: &Vector3<f64>,
        branch: Branch,
        previous: &Axes,
        sample: Option<usize>,
    ) -> Result<RotarySolution> {
        self.orientation_with(o, branch, previous, true, sample)
    }

    fn orientation_with(
        &self,
        o: &Vector3<f64>,
        branch: Branch,
        previous: &Axes,
        check_travel: bool,
        sample: Option<usize>,
    ) -> Result<RotarySolution> {
        let c_travel = if check_travel {
            self.limits().c
        } else {
            Travel::UNBOUNDED
        };
        let closed = |wrist: Wrist| -> Result<RotarySolution> {
            let ang = wrist.angles(o, branch, previous.c, c_travel, sample)?;
            Ok(RotarySolution {
                joints: previous
                    .with(wrist.tilt.axis(), ang.a)
                    .with(AxisName::C, ang.c),
                singular: ang.singular,
                unwound: ang.unwound,
            })
        };
        match self {
            Kinematics::Xyz(_) => {
                let u = unit_orientation(o, sample)?;
                if (u - Vector3::z()).norm() > crate::chain::CHAIN_TOLERANCE {
                    return Err(Error::BadOrientation {
                        o: [o.x, o.y, o.z],
                        sample,
                        reason: "a 3-axis machine holds the tool along +Z",
                    });
                }
                Ok(RotarySolution {
                    joints: *previous,
                    singular: false,
                    unwound: false,
                })
            }
            Kinematics::Chain(c) => Ok(RotarySolution {
                joints: c.solve_orientation(o, previous, check_travel, sample)?,
                singular: false,
                unwound: false,
            }),
            Kinematics::TableTilting(m) => closed(m.wrist()),
            Kinematics::HeadHead(m) => closed(m.wrist()),
            Kinematics::HeadTable(m) => closed(m.wrist()),
        }
    }

    /// Tool-centre-point inverse: the slides X, Y, Z (mm) that put the tool tip at `p_w`
    /// (workpiece frame, mm) with the rotary axes of `rotary` (rad), as tool-centre-point G-code
    /// specifies them. Exact for every family (the tip is affine in the slides); fails only on
    /// a chain whose slides become dependent.
    pub fn inverse_tcp(&self, p_w: &Vector3<f64>, rotary: &Axes) -> Result<Vector3<f64>> {
        self.tcp_position(p_w, rotary, None)
    }

    fn tcp_position(
        &self,
        p_w: &Vector3<f64>,
        rotary: &Axes,
        sample: Option<usize>,
    ) -> Result<Vector3<f64>> {
        Ok(match self {
            Kinematics::Xyz(_) => *p_w,
            Kinematics::TableTilting(m) => m.tcp_position(p_w, rotary),
            Kinematics::HeadHead(m) => m.tcp_position(p_w, rotary),
            Kinematics::HeadTable(m) => m.tcp_position(p_w, rotary),
            Kinematics::Chain(c) => c.tcp_position(p_w, rotary, sample)?,
        })
    }

    /// [`Kinematics::inverse_tcp`] with the analytic first and second time derivatives (chain
    /// rule, docs/kinematics.md): the tip's motion (mm, mm/s, mm/s²) and the rotary axes' (rad,
    /// rad/s, rad/s²) give the joints' motion, slides computed and rotary axes copied.
    pub fn inverse_tcp_motion(
        &self,
        tip: &PointMotion,
        rotary: &JointMotion,
    ) -> Result<JointMotion> {
        let m = self.tcp_motion(tip, rotary, None)?;
        Ok(JointMotion {
            pos: rotary.pos.with_pm(&m.p),
            vel: rotary.vel.with_pm(&m.p_dot),
            acc: rotary.acc.with_pm(&m.p_ddot),
        })
    }

    fn tcp_motion(
        &self,
        tip: &PointMotion,
        rotary: &JointMotion,
        sample: Option<usize>,
    ) -> Result<PointMotion> {
        Ok(match self {
            Kinematics::Xyz(_) => *tip,
            Kinematics::TableTilting(m) => m.tcp_motion(tip, rotary),
            Kinematics::HeadHead(m) => m.tcp_motion(tip, rotary),
            Kinematics::HeadTable(m) => m.tcp_motion(tip, rotary),
            Kinematics::Chain(c) => c.tcp_motion(tip, rotary, sample)?,
        })
    }

    /// [`Kinematics::inverse_tcp_motion`] over a run or a piece of one. The X Y Z tracks hold the
    /// tool tip in the workpiece frame (mm, mm/s, mm/s²), `rotary` one track per axis of
    /// [`Kinematics::rotary_axes`], in that order, in **degrees** (deg/s, deg/s²), as a
    /// tool-centre-point program is interpolated. The result is the X Y Z slide references with
    /// their analytic derivatives. Samples where `tcp[k]` is false are slide coordinates
    /// already and are copied unchanged. Every track has `tcp.len()` samples.
    ///
    /// Each sample is computed on its own, so a run fed whole or in pieces gives the same bits.
    pub fn inverse_tcp_track(
        &self,
        tip: [Track<'_>; 3],
        rotary: &[Track<'_>],
        tcp: &[bool],
    ) -> Result<[Track3; 3]> {
        let names = self.rotary_axes();
        if rotary.len() != names.len() {
            return Err(Error::TrackCount {
                expected: names.len(),
                got: rotary.len(),
            });
        }
        let n = tcp.len();
        for t in tip.iter().chain(rotary) {
            for len in [t.pos.len(), t.vel.len(), t.acc.len()] {
                if len != n {
                    return Err(Error::TrackLength {
                        expected: n,
                        got: len,
                    });
                }
            }
        }
        let mut out: [Track3; 3] = std::array::from_fn(|i| Track3 {
            pos: tip[i].pos.to_vec(),
            vel: tip[i].vel.to_vec(),
            acc: tip[i].acc.to_vec(),
        });
        if matches!(self, Kinematics::Xyz(_)) {
            return Ok(out);
        }
        // Every slice cut to `n` once (their lengths are checked above), so that the loop
        // indexes without bounds checks; the arithmetic is `tcp_motion`'s alone.
        fn cut<'a>(t: &Track<'a>, n: usize) -> [&'a [f64]; 3] {
            [&t.pos[..n], &t.vel[..n], &t.acc[..n]]
        }
        let tip = tip.each_ref().map(|t| cut(t, n));
        let rotary: Vec<(AxisName, [&[f64]; 3])> = names
            .iter()
            .zip(rotary)
            .map(|(r, t)| (r.axis, cut(t, n)))
            .collect();
        for k in (0..n).filter(|k| tcp[*k]) {
            let v3 = |d: usize| Vector3::new(tip[0][d][k], tip[1][d][k], tip[2][d][k]);
            let mut rot = JointMotion::default();
            for (axis, [p, v, a]) in &rotary {
                rot.pos[*axis] = p[k] * DEG;
                rot.vel[*axis] = v[k] * DEG;
                rot.acc[*axis] = a[k] * DEG;
            }
            let tip_k = PointMotion {
                p: v3(0),
                p_dot: v3(1),
                p_ddot: v3(2),
            };
            let m = self.tcp_motion(&tip_k, &rot, Some(k))?;
            for (j, o) in out.iter_mut().enumerate() {
                o.pos[k] = m.p[j];
                o.vel[k] = m.p_dot[j];
                o.acc[k] = m.p_ddot[j];
            }
        }
        Ok(out)
    }

    /// Inverse kinematics of one pose on `branch`, nearest to `previous` (mm, rad): the rotary
    /// axes by [`Kinematics::inverse_orientation`], then the slides by the tool-centre-point
    /// inverse. Slots the family does not use are copied from `previous`. Travel is not
    /// checked, except that C is unwound within its travel.
    pub fn inverse(&self, pose: &Pose, branch: Branch, previous: &Axes) -> Result<Axes> {
        self.inverse_at(pose, branch, previous, true, None)
            .map(|(j, _)| j)
    }

    fn inverse_at(
        &self,
        pose: &Pose,
        branch: Branch,
        previous: &Axes,
        check_travel: bool,
        sample: Option<usize>,
    ) -> Result<(Axes, RotarySolution)> {
        if !pose.p.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinitePosition {
                p: [pose.p.x, pose.p.y, pose.p.z],
                sample,
            });
        }
        let rot = self.orientation_with(&pose.o, branch, previous, check_travel, sample)?;
        let pm = self.tcp_position(&pose.p, &rot.joints, sample)?;
        Ok((rot.joints.with_pm(&pm), rot))
    }

    /// `Ok` if every axis this kinematics uses is within its travel at `j`, else the first
    /// violation (X Y Z, then the rotary axes), tagged with `sample`.
    pub fn check_travel(&self, j: &Axes, sample: Option<usize>) -> Result<()> {
        self.limits().check_axes(j, &self.axes(), sample)
    }

    /// A solver for a pose sequence fed in pieces, starting on `branch` (see [`PoseSolver`]).
    pub fn pose_solver(&self, branch: Branch, opts: &IkOptions) -> PoseSolver<'_> {
        PoseSolver {
            kin: self,
            branch,
            start_branch: branch,
            previous: opts.start,
            check_travel: opts.check_travel,
            keep_branch: opts.keep_branch,
            next: 0,
            singular_samples: 0,
            branch_switches: Vec::new(),
            unwinds: Vec::new(),
            flips: Vec::new(),
        }
    }

    /// Inverse kinematics of a whole pose sequence (docs/kinematics.md, "Branch rule"): the
    /// first sample on the requested branch, or automatically on the first of +1, −1 that keeps
    /// every axis within travel over the whole sequence; then sample by sample with the rule of
    /// [`PoseSolver`]. When switching branch at the singularity leads out of travel, the same
    /// branch is tried again without switching. Errors carry the sample index and the numbers:
    /// "A = -131.200° is out of travel -120.000° ..= 30.000° at sample 812".
    pub fn inverse_sequence(&self, poses: &[Pose], opts: &IkOptions) -> Result<IkSolution> {
        if let Some(branch) = opts.branch {
            return self.solve_from(poses, branch, opts);
        }
        match self.solve_from(poses, Branch::Plus, opts) {
            Ok(sol) => Ok(sol),
            Err(plus @ Error::OutOfTravel { .. }) => {
                match self.solve_from(poses, Branch::Minus, opts) {
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

    fn solve_from(&self, poses: &[Pose], branch: Branch, opts: &IkOptions) -> Result<IkSolution> {
        let mut solver = self.pose_solver(branch, opts);
        match solver.solve_piece(poses) {
            Ok(axes) => Ok(solver.into_solution(axes)),
            Err(e @ Error::OutOfTravel { .. })
                if !opts.keep_branch && !solver.branch_switches.is_empty() =>
            {
                let keep = IkOptions {
                    keep_branch: true,
                    ..*opts
                };
                let mut solver = self.pose_solver(branch, &keep);
                match solver.solve_piece(poses) {
                    Ok(axes) => Ok(solver.into_solution(axes)),
                    Err(_) => Err(e),
                }
            }
            Err(e) => Err(e),
        }
    }
}

/// The pose inverse of a sequence fed in pieces (the pipeline streams samples): the state
/// between samples (the previous joints, the current branch) lives here, so a sequence solved
/// whole or piece by piece gives the same bits.
///
/// The branch rule (docs/kinematics.md): each sample is solved on the current branch with C
/// nearest to the previous C (within its travel); at the singularity C is held. When that
/// turns C by more than a quarter turn in one sample (the tool axis passed through or near the
/// C axis) and is not an unwinding move, the other branch is tried, and taken if it moves the
/// rotary axes less (measured as $|\Delta t| + |\Delta c|$): the tilt changes sign instead of
/// C turning half a turn, and C stays continuous. [`IkOptions::keep_branch`] turns this off.
/// A chain follows its damped least-squares solve from the previous sample.
#[derive(Debug, Clone)]
pub struct PoseSolver<'k> {
    kin: &'k Kinematics,
    branch: Branch,
    start_branch: Branch,
    previous: Axes,
    check_travel: bool,
    keep_branch: bool,
    next: usize,
    singular_samples: usize,
    branch_switches: Vec<usize>,
    unwinds: Vec<usize>,
    flips: Vec<usize>,
}

impl PoseSolver<'_> {
    /// The current branch.
    pub fn branch(&self) -> Branch {
        self.branch
    }

    /// The joints of the last sample solved (the start joints before the first).
    pub fn previous(&self) -> Axes {
        self.previous
    }

    /// Solves the next sample (errors carry its index in the whole sequence).
    pub fn solve(&mut self, pose: &Pose) -> Result<Axes> {
        let k = self.next;
        let prev = self.previous;
        let (mut joints, mut rot) =
            self.kin
                .inverse_at(pose, self.branch, &prev, self.check_travel, Some(k))?;
        let c_jump = (joints.c - prev.c).abs() > FRAC_PI_2;
        if let Some(wrist) = self.kin.wrist()
            && k > 0
            && c_jump
            && !self.keep_branch
            && !rot.singular
            && !rot.unwound
        {
            let tilt = wrist.tilt.axis();
            let step = |j: &Axes| (j[tilt] - prev[tilt]).abs() + (j.c - prev.c).abs();
            let other =
                self.kin
                    .inverse_at(pose, self.branch.other(), &prev, self.check_travel, Some(k));
            if let Ok((j2, r2)) = other
                && step(&j2) < step(&joints)
            {
                (joints, rot) = (j2, r2);
                self.branch = self.branch.other();
                self.branch_switches.push(k);
            }
        }
        if self.check_travel {
            self.kin.check_travel(&joints, Some(k))?;
        }
        self.singular_samples += usize::from(rot.singular);
        if rot.unwound {
            self.unwinds.push(k);
        }
        if k > 0 && (joints.c - prev.c).abs() > FRAC_PI_2 && !rot.unwound {
            self.flips.push(k);
        }
        self.previous = joints;
        self.next += 1;
        Ok(joints)
    }

    /// Solves the next piece of samples.
    pub fn solve_piece(&mut self, poses: &[Pose]) -> Result<Vec<Axes>> {
        poses.iter().map(|p| self.solve(p)).collect()
    }

    /// The whole-sequence record, with the joints collected by the caller.
    pub fn into_solution(self, axes: Vec<Axes>) -> IkSolution {
        IkSolution {
            axes,
            branch: self.start_branch,
            singular_samples: self.singular_samples,
            branch_switches: self.branch_switches,
            unwinds: self.unwinds,
            flips: self.flips,
        }
    }
}

/// Which machine axis (its index in the machine's axis list) plays each axis of a kinematics,
/// resolved once when a machine is loaded; turns per-machine-axis position series (mm, deg)
/// into joints (mm, rad).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AxisMap {
    index: [Option<usize>; 6],
}

impl AxisMap {
    /// The map for `kinematics` on a machine whose axes are `machine_axes`, in its order. Error:
    /// the machine lacks an axis the kinematics needs ("a head-table B/C machine needs axis B").
    pub fn new(kinematics: &Kinematics, machine_axes: &[AxisName]) -> Result<Self> {
        let mut index = [None; 6];
        for axis in kinematics.axes() {
            let i = machine_axes
                .iter()
                .position(|a| *a == axis)
                .ok_or_else(|| Error::MissingAxis {
                    axis,
                    family: kinematics.family().to_string(),
                })?;
            index[axis.index()] = Some(i);
        }
        Ok(Self { index })
    }

    /// The machine-axis index of `axis`, if the kinematics uses it.
    pub fn index(&self, axis: AxisName) -> Option<usize> {
        self.index.get(axis.index()).copied().flatten()
    }

    /// The joints (mm, rad) at sample `k` of per-machine-axis position series (mm, deg); slots
    /// the kinematics does not use are 0. The series are the machine's own (one per machine
    /// axis, each with at least `k + 1` samples): anything shorter is a bug of the caller, and
    /// panics.
    pub fn at<P: AsRef<[f64]>>(&self, positions: &[P], k: usize) -> Axes {
        Axes::from_fn(|axis| {
            self.index(axis).map_or(0.0, |i| {
                let v = positions[i].as_ref()[k];
                if axis.is_rotary() { v.to_radians() } else { v }
            })
        })
    }
}
