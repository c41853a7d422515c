//! Kinematics of machine tools for vcnc: one value, [`Kinematics`], a closed enum of machine
//! families, each with forward kinematics, the pose inverse (both branches, the singularity,
//! C unwound within its travel) and the tool-centre-point inverse with analytic derivatives.
//!
//! | family | rotary axes | closed form | LinuxCNC module it is cross-checked against |
//! |---|---|---|---|
//! | [`Kinematics::Xyz`] | none (tool along +Z) | $p_w = p_m$ | — (the identity, as `trivkins`) |
//! | [`Kinematics::TableTilting`] | A or B and C, in the table | yes | `xyzac-trt-kins`, `xyzbc-trt-kins` |
//! | [`Kinematics::HeadHead`] | C then A or B, in the head | yes | `5axiskins` |
//! | [`Kinematics::HeadTable`] | A or B in the head, C in the table | yes | `maxkins` |
//! | [`Kinematics::Chain`] | up to three, anywhere (URDF) | forward only; inverse by damped least squares | — |
//!
//! Where it is built from: a parameter table ([`Kinematics::from_params`]) or a URDF
//! ([`Kinematics::from_urdf_file`], which maps a chain onto its closed form where the chain
//! matches one). What the rest of vcnc calls:
//!
//! - [`Kinematics::axes`], [`Kinematics::rotary_axes`]: which machine axes, in which role;
//!   [`AxisMap`] turns a machine's per-axis positions (mm, deg) into joints ([`Axes`], mm, rad);
//! - [`Kinematics::forward`]: joints → [`Pose`] (tool tip, unit tool axis, workpiece frame);
//! - [`Kinematics::inverse`]: pose, [`Branch`], previous joints → joints, or a typed [`Error`];
//!   [`Kinematics::inverse_sequence`] and [`PoseSolver`] for whole sequences or pieces of one;
//! - [`Kinematics::inverse_tcp_track`]: tool-centre-point tracks (tip + rotary axes) → slide
//!   references with analytic velocity and acceleration, the same bits whole or in pieces;
//! - [`Kinematics::fit_offsets`]: a family's offsets identified from measured poses.
//!
//! The equations, conventions and the cross-checks are in docs/kinematics.md.
//!
//! **Units: lengths in mm, angles in rad, time in s**, everywhere in this crate (a URDF stores
//! mm and rad; its metres are only a convention). The tool-centre-point tracks take rotary
//! axes in degrees, as programs are interpolated; callers convert elsewhere at the edge.
//!
//! ```
//! use vcnc_kinematics::nalgebra::Vector3;
//! use vcnc_kinematics::{Axes, Branch, Family, Kinematics, KinematicsParams, Tilt};
//!
//! // The shipped NMV5000 URDF is a table-tilting A/C machine.
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../machines/nmv5000.urdf");
//! let nmv = Kinematics::from_urdf_file(path)?;
//! assert_eq!(nmv.family(), Family::TableTilting(Tilt::A));
//!
//! // A head-head gantry from its parameter table: C then B in the head, pivot 250 mm.
//! let gantry = Kinematics::from_params(&KinematicsParams {
//!     family: Some(Family::HeadHead(Tilt::B)),
//!     pivot_length_mm: Some(250.0),
//!     ..KinematicsParams::default()
//! })?;
//! let joints = Axes { x: 10.0, y: -20.0, z: 50.0, b: 0.4, c: 1.0, ..Axes::default() };
//! let pose = gantry.forward(&joints);
//! let back = gantry.inverse(&pose, Branch::Plus, &Axes { c: 1.1, ..Axes::default() })?;
//! assert!((back.x - joints.x).abs() < 1e-9 && (back.c - joints.c).abs() < 1e-12);
//! # Ok::<(), vcnc_kinematics::Error>(())
//! ```

mod chain;
mod error;
mod families;
mod fit;
mod kinematics;
mod model;
mod rotation;
mod types;
mod wrist;

pub use chain::{
    CHAIN_TOLERANCE, ChainJoint, IK_MAX_ITERATIONS, IK_TOLERANCE, JointKind, KinematicChain,
    TOOL_LINK, WORKPIECE_LINK,
};
pub use error::{Error, Result};
pub use families::{HeadHead, HeadTable, TableTilting, Xyz};
pub use fit::OffsetFit;
pub use kinematics::{
    AxisMap, Family, IkOptions, IkSolution, Kinematics, KinematicsParams, PoseSolver,
    RotarySolution,
};
pub use model::TableTiltingAc;
pub use types::{
    Axes, AxisLimits, AxisName, Branch, Carrier, JointMotion, PointMotion, Pose, RotaryAxis, Tilt,
    Track, Track3, Travel,
};
pub use wrist::{RotaryAngles, SINGULAR_SIN_A, unwrap_near, unwrap_within};

/// The nalgebra version this crate's types use (so callers need not depend on it directly).
pub use nalgebra;
