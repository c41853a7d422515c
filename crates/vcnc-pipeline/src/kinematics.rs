//! `vcnc kinematics`: forward and inverse kinematics of a machine over tables of axes or poses.

use std::path::Path;

use vcnc_kinematics::Pose;
use vcnc_kinematics::nalgebra::Vector3;

pub use vcnc_kinematics::Branch;
use vcnc_machine::Machine;

use crate::Error;
use crate::table::read_columns;

/// Columns of a forward-kinematics input (and an inverse output) on `machine`: the axes its
/// kinematics reads, X Y Z (mm) then its rotary axes (deg), e.g. `X Y Z A C` or `X Y Z B C`.
pub fn axes_columns(machine: &Machine) -> Result<Vec<&'static str>, Error> {
    Ok(machine
        .require_kinematics()?
        .axis_names()
        .into_iter()
        .map(|a| a.as_str())
        .collect())
}
/// Columns of an inverse-kinematics input (and a forward output): tool tip px py pz (mm) and
/// tool axis ox oy oz in the workpiece frame.
pub const POSE_COLUMNS: [&str; 6] = ["px", "py", "pz", "ox", "oy", "oz"];

/// Forward kinematics of every row of the CSV at `input` (columns [`axes_columns`]): rows of
/// `px py pz ox oy oz`.
pub fn forward_file(machine: &Machine, input: &Path) -> Result<Vec<[f64; 6]>, Error> {
    let kin = machine.require_kinematics()?;
    let c = read_columns(input, &axes_columns(machine)?, "")?;
    Ok((0..c[0].len())
        .map(|k| {
            let row: Vec<f64> = c.iter().map(|col| col[k]).collect();
            let p = kin.pose_of(&row);
            [p.p.x, p.p.y, p.p.z, p.o.x, p.o.y, p.o.z]
        })
        .collect())
}

/// Inverse kinematics of every row of the CSV at `input` (columns [`POSE_COLUMNS`]) on
/// `branch` (the machine file's when `None`), C unwrapped continuously from row to row: rows of
/// [`axes_columns`] (mm, deg).
pub fn inverse_file(
    machine: &Machine,
    input: &Path,
    branch: Option<Branch>,
) -> Result<Vec<Vec<f64>>, Error> {
    let kin = machine.require_kinematics()?;
    let c = read_columns(input, &POSE_COLUMNS, "")?;
    let poses: Vec<Pose> = (0..c[0].len())
        .map(|k| {
            Pose::new(
                Vector3::new(c[0][k], c[1][k], c[2][k]),
                Vector3::new(c[3][k], c[4][k], c[5][k]),
            )
        })
        .collect();
    kin.inverse_poses(&poses, branch)
        .map_err(|source| Error::Kinematics {
            context: input.display().to_string(),
            source,
        })
}
