//! Kinematics of a table-tilting A/C 5-axis machine (NMV5000 type), for vcnc.
//!
//! The machine's chain is read from URDF with urdf-rs ([`KinematicChain`]): two branches leave
//! the base, X Y Z prismatic joints to the tool tip and A (about +X) → C (about +Z) to the
//! workpiece. [`KinematicChain::forward`] composes joint origins and motions generically; the
//! closed-form model [`TableTiltingAc`] takes its offsets r (C-axis centre) and d (A-axis centre
//! relative to r) from the URDF joint origins and provides forward kinematics, inverse
//! kinematics on both branches, sequence inverse kinematics (A = 0 singularity held, C unwrapped,
//! travel checked) and the TCP inverse with analytic derivatives. See docs/kinematics.md.
//!
//! **Units: lengths in mm, angles in rad, time in s**, everywhere in this crate (the URDF
//! stores mm and rad; its metres are only a convention). Callers convert degrees at the edge.
//!
//! ```
//! use vcnc_kinematics::{Axes, Branch, KinematicChain};
//!
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../machines/nmv5000.urdf");
//! let chain = KinematicChain::from_urdf_file(path)?;
//! let model = chain.table_tilting_ac();
//! assert_eq!(model.d.z, -100.0); // vcnc's default (docs/kinematics.md): table surface 100 mm above the A axis
//!
//! let axes = Axes::new(10.0, -20.0, 50.0, (-30f64).to_radians(), 1.0);
//! let pose = model.forward(&axes);
//! assert!((chain.forward(&axes).p - pose.p).norm() < 1e-9);
//!
//! let back = model.inverse_near(&pose, Branch::Minus, 1.0)?;
//! assert!((back.x - axes.x).abs() < 1e-9 && (back.c - axes.c).abs() < 1e-12);
//! # Ok::<(), vcnc_kinematics::Error>(())
//! ```

mod chain;
mod error;
mod model;
mod types;

pub use chain::{CHAIN_TOLERANCE, ChainJoint, JointKind, KinematicChain};
pub use error::{Error, Result};
pub use model::{
    IkOptions, IkSolution, MachineMotion, RotaryAngles, SINGULAR_SIN_A, TableTiltingAc, TcpMotion,
    Track, Track3, unwrap_near,
};
pub use types::{Axes, AxisLimits, AxisName, Branch, Pose, Travel};

/// The nalgebra version this crate's types use (so callers need not depend on it directly).
pub use nalgebra;
