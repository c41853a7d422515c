//! The machine's kinematic chain read from URDF, and generic forward kinematics over it.
//!
//! docs/kinematics.md: two branches leave the base link; one carries the X, Y, Z prismatic joints to
//! the tool tip, the other the A revolute joint (about +X) and the C joint (about +Z) to the
//! workpiece. Every frame is composed from the URDF joint origins and joint motions with
//! [`Isometry3`]; the tool pose in the workpiece frame is
//! $$ T = T_{wp}^{-1}\, T_{tool}. $$
//! Lengths are read as mm and angles as rad (URDF's metres are only a convention here).

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::model::TableTiltingAc;
use crate::types::{Axes, AxisLimits, AxisName, Pose, Travel};

/// Geometric tolerance of the chain validation: axis directions (unitless) and the zero-position
/// frames (mm and rad) must match the table-tilting A/C form to this.
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

/// A validated table-tilting A/C chain (docs/kinematics.md).
///
/// Built only by [`KinematicChain::from_urdf_file`] or [`KinematicChain::from_urdf_str`], which
/// check that the URDF has exactly this structure: base → X, Y, Z prismatic joints along +X, +Y,
/// +Z → tool tip (at the machine origin with the machine's orientation when X = Y = Z = 0), and
/// base → A rotary about +X → C rotary about +Z → workpiece (equal to the machine frame when
/// A = C = 0), plus any number of fixed joints. Directions are checked in the machine frame at
/// the zero position, so intermediate fixed joints and `rpy` rotations are allowed.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicChain {
    name: String,
    source: String,
    base_link: String,
    tool_link: String,
    workpiece_link: String,
    tool: Vec<ChainJoint>,
    workpiece: Vec<ChainJoint>,
    r: Vector3<f64>,
    d: Vector3<f64>,
    limits: AxisLimits,
}

impl KinematicChain {
    /// Reads and validates a URDF file. Errors name the file.
    pub fn from_urdf_file(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| Error::Urdf {
            file: file.clone(),
            message: e.to_string(),
        })?;
        Self::from_urdf_str(&text, &file)
    }

    /// Parses and validates URDF text; `source` names it in error messages (a path, or e.g.
    /// `"<embedded nmv5000.urdf>"`).
    pub fn from_urdf_str(urdf: &str, source: &str) -> Result<Self> {
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

    /// Name of the workpiece link.
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

    /// The C-axis centre r (a point of the C axis at A = 0) in the machine frame, mm, taken from
    /// the C joint's frame origin.
    pub fn r(&self) -> Vector3<f64> {
        self.r
    }

    /// The A-axis centre relative to the C-axis centre, d, mm, taken from the A joint's frame
    /// origin minus [`KinematicChain::r`].
    pub fn d(&self) -> Vector3<f64> {
        self.d
    }

    /// Axis travels from the joints' `<limit>` elements (mm, rad; C unbounded when continuous).
    pub fn limits(&self) -> AxisLimits {
        self.limits
    }

    /// The closed-form model with r, d and limits from this chain.
    pub fn table_tilting_ac(&self) -> TableTiltingAc {
        TableTiltingAc {
            r: self.r,
            d: self.d,
            limits: self.limits,
        }
    }

    /// Tool-tip frame in the machine frame, $T_{tool}$, at the given axes. Composes joint
    /// origins and joint motions; never clamps to travel.
    pub fn tool_frame(&self, axes: &Axes) -> Isometry3<f64> {
        compose(&self.tool, axes)
    }

    /// Workpiece frame in the machine frame, $T_{wp}$, at the given axes. Never clamps.
    pub fn workpiece_frame(&self, axes: &Axes) -> Isometry3<f64> {
        compose(&self.workpiece, axes)
    }

    /// Generic forward kinematics: the tool pose in the workpiece frame,
    /// $T = T_{wp}^{-1} T_{tool}$; `p` is its translation (mm) and `o` its +Z axis.
    /// Equals [`TableTiltingAc::forward`] (tested to 1e-9 mm).
    pub fn forward(&self, axes: &Axes) -> Pose {
        let t = self.workpiece_frame(axes).inv_mul(&self.tool_frame(axes));
        Pose {
            p: t.translation.vector,
            o: t.rotation * Vector3::z(),
        }
    }
}

fn compose(joints: &[ChainJoint], axes: &Axes) -> Isometry3<f64> {
    let mut t = Isometry3::identity();
    for j in joints {
        let q = j.role.and_then(|axis| axes.get(axis)).unwrap_or(0.0);
        t = t * j.origin * j.motion(q);
    }
    t
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

/// The URDF's links as a tree.
struct Tree<'r> {
    /// Link name → index in the URDF.
    link_index: HashMap<&'r str, usize>,
    /// Joints whose parent is each link.
    child_joints: Vec<Vec<usize>>,
    /// Index of the base link.
    root: usize,
    /// Name of the base link.
    base_link: String,
}

struct Builder<'a> {
    source: &'a str,
    robot: &'a urdf_rs::Robot,
}

impl Builder<'_> {
    fn fail(&self, reason: String) -> Error {
        Error::NotTableTilting {
            file: self.source.to_string(),
            reason,
        }
    }

    /// Reads the URDF in stages: the link tree, its root-to-leaf paths, the joint kinds, the two
    /// branches (X Y Z to the tool tip, A C to the workpiece), then the geometry at zero.
    fn build(&self) -> Result<KinematicChain> {
        let tree = self.tree()?;
        let paths = self.paths(&tree)?;
        let kinds = self.joint_kinds()?;
        let (tool_path, wp_path) = self.branches(&paths, &kinds, &tree.base_link)?;
        let tool = self.convert(&tool_path, &kinds, &[AxisName::X, AxisName::Y, AxisName::Z])?;
        let workpiece = self.convert(&wp_path, &kinds, &[AxisName::A, AxisName::C])?;

        // Geometry at the zero position.
        self.check_axes(&tool)?;
        let wp_points = self.check_axes(&workpiece)?;
        let zero = Axes::default();
        let tool_tip = self.leaf_name(&tool_path, &tree.base_link);
        let wp_link = self.leaf_name(&wp_path, &tree.base_link);
        self.check_identity(
            &compose(&tool, &zero),
            &format!("the tool tip link '{tool_tip}'"),
            "X = Y = Z = 0",
            "make the tool tip coincide with the machine origin, tool along +Z, at zero",
        )?;
        self.check_identity(
            &compose(&workpiece, &zero),
            &format!("the workpiece link '{wp_link}'"),
            "A = C = 0",
            "the fixed workpiece joint's origin must be -r (the workpiece frame equals the \
             machine frame at A = C = 0)",
        )?;
        let (p_a, p_c) = match wp_points.as_slice() {
            [pa, pc] => (*pa, *pc),
            _ => return Err(self.fail("internal: the A C branch lost a joint".into())),
        };

        let mut limits = AxisLimits::default();
        for j in tool.iter().chain(workpiece.iter()) {
            if let Some(t) = j.role.and_then(|axis| limits.get_mut(axis)) {
                *t = j.travel;
            }
        }

        Ok(KinematicChain {
            name: self.robot.name.clone(),
            source: self.source.to_string(),
            base_link: tree.base_link,
            tool_link: tool_tip,
            workpiece_link: wp_link,
            tool,
            workpiece,
            r: p_c,
            d: p_a - p_c,
            limits,
        })
    }

    /// The name of the link that ends `path` (the base link for an empty path).
    fn leaf_name(&self, path: &[usize], base_link: &str) -> String {
        path.last()
            .and_then(|&ji| self.robot.joints.get(ji))
            .map_or(base_link.to_string(), |j| j.child.link.clone())
    }

    /// Links and joints as a tree: unique names, one parent joint per link, one base link.
    fn tree(&self) -> Result<Tree<'_>> {
        let robot = self.robot;
        // Links and their parent joints.
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
                let other_name = robot.joints.get(*other).map_or("?", |j| j.name.as_str());
                return Err(self.fail(format!(
                    "link '{}' is the child of two joints, '{}' and '{}'",
                    joint.child.link, other_name, joint.name
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

        Ok(Tree {
            link_index,
            child_joints,
            root,
            base_link,
        })
    }

    /// Every root-to-leaf path of joint indices (each link has one parent, so this walk
    /// terminates and visits every link reachable from the root exactly once).
    fn paths(&self, tree: &Tree<'_>) -> Result<Vec<Vec<usize>>> {
        let robot = self.robot;
        let (link_index, child_joints, root, base_link) = (
            &tree.link_index,
            &tree.child_joints,
            tree.root,
            &tree.base_link,
        );
        let mut paths: Vec<Vec<usize>> = Vec::new();
        let mut stack: Vec<(usize, Vec<usize>)> = vec![(root, Vec::new())];
        let mut visited = 0usize;
        while let Some((link, path)) = stack.pop() {
            visited += 1;
            let children = child_joints.get(link).map_or(&[][..], |v| v.as_slice());
            if children.is_empty() {
                paths.push(path);
                continue;
            }
            for &ji in children.iter().rev() {
                let mut p = path.clone();
                p.push(ji);
                let child = robot
                    .joints
                    .get(ji)
                    .and_then(|j| link_index.get(j.child.link.as_str()))
                    .copied();
                if let Some(c) = child {
                    stack.push((c, p));
                }
            }
        }
        if visited != robot.links.len() {
            return Err(self.fail(format!(
                "{} link(s) are not connected to the base link '{}' (a loop of joints?)",
                robot.links.len() - visited,
                base_link
            )));
        }

        Ok(paths)
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

    /// The X Y Z branch (three prismatic joints) and the A C branch (two rotary joints); any
    /// other moving joint is an error.
    fn branches(
        &self,
        paths: &[Vec<usize>],
        kinds: &[JointKind],
        base_link: &str,
    ) -> Result<(Vec<usize>, Vec<usize>)> {
        let robot = self.robot;
        let kind_of = |ji: usize| kinds.get(ji).copied().unwrap_or(JointKind::Fixed);
        let movable = |path: &[usize]| -> Vec<usize> {
            path.iter()
                .copied()
                .filter(|&ji| kind_of(ji).is_movable())
                .collect()
        };

        // Identify the two branches by their movable joints.
        let mut tool_paths = Vec::new();
        let mut wp_paths = Vec::new();
        for path in paths {
            let m = movable(path);
            let ks: Vec<JointKind> = m.iter().map(|&ji| kind_of(ji)).collect();
            if ks.len() == 3 && ks.iter().all(|k| *k == JointKind::Prismatic) {
                tool_paths.push(path.clone());
            } else if ks.len() == 2 && ks.iter().all(|k| k.is_rotary()) {
                wp_paths.push(path.clone());
            }
        }
        let leaf_name = |path: &[usize]| self.leaf_name(path, base_link);
        let tool_path = match tool_paths.as_slice() {
            [p] => p.clone(),
            [] => {
                return Err(self.fail(format!(
                    "no branch from the base link '{base_link}' has exactly three prismatic \
                     joints (X, Y, Z) and no rotary joint"
                )));
            }
            [p, q, ..] => {
                return Err(self.fail(format!(
                    "two leaf links, '{}' and '{}', both end an X Y Z branch; keep one tool tip",
                    leaf_name(p),
                    leaf_name(q)
                )));
            }
        };
        let wp_path = match wp_paths.as_slice() {
            [p] => p.clone(),
            [] => {
                return Err(self.fail(format!(
                    "no branch from the base link '{base_link}' has exactly two rotary joints \
                     (A then C) and no prismatic joint"
                )));
            }
            [p, q, ..] => {
                return Err(self.fail(format!(
                    "two leaf links, '{}' and '{}', both end an A C branch; keep one workpiece",
                    leaf_name(p),
                    leaf_name(q)
                )));
            }
        };
        for (ji, joint) in robot.joints.iter().enumerate() {
            if kind_of(ji).is_movable() && !tool_path.contains(&ji) && !wp_path.contains(&ji) {
                return Err(self.fail(format!(
                    "joint '{}' moves but is on neither the X Y Z branch nor the A C branch",
                    joint.name
                )));
            }
        }

        Ok((tool_path, wp_path))
    }

    /// Converts the URDF joints of one branch, assigning `roles` to its movable joints in order.
    fn convert(
        &self,
        path: &[usize],
        kinds: &[JointKind],
        roles: &[AxisName],
    ) -> Result<Vec<ChainJoint>> {
        let mut out = Vec::with_capacity(path.len());
        let mut roles = roles.iter();
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
                roles.next().copied()
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

    /// Checks every movable joint's axis, expressed in the machine frame at the zero position,
    /// against its role's direction; returns each movable joint's frame origin (a point on its
    /// axis) in the machine frame, mm.
    fn check_axes(&self, joints: &[ChainJoint]) -> Result<Vec<Vector3<f64>>> {
        let mut t = Isometry3::identity();
        let mut points = Vec::new();
        for j in joints {
            t *= j.origin;
            if let Some(role) = j.role {
                let dir = t.rotation * j.axis.into_inner();
                let (name, expected) = unit_name(role);
                if (dir - expected).norm() > CHAIN_TOLERANCE {
                    let shown = if t.rotation.angle() == 0.0 {
                        format!("joint '{}' axis is {}", j.name, fmt_vec(&dir))
                    } else {
                        format!(
                            "joint '{}' axis is {} in the machine frame",
                            j.name,
                            fmt_vec(&dir)
                        )
                    };
                    return Err(self.fail(format!("{shown}, expected {name} (axis {role})")));
                }
                points.push(t.translation.vector);
            }
        }
        Ok(points)
    }

    fn check_identity(&self, t: &Isometry3<f64>, what: &str, at: &str, hint: &str) -> Result<()> {
        let p = t.translation.vector;
        let angle = t.rotation.angle();
        if p.norm() > CHAIN_TOLERANCE || angle > CHAIN_TOLERANCE {
            return Err(self.fail(format!(
                "{what} is at {} mm, rotated by {angle} rad, at {at}; {hint}",
                fmt_vec(&p)
            )));
        }
        Ok(())
    }
}
