//! `vcnc kinematics MACHINE forward|inverse --input CSV [--out CSV] [--branch 1|-1]`.
//! Forward: columns X Y Z (mm) and the machine's rotary axes, e.g. A C or B C (deg) → px py pz
//! (mm) ox oy oz (workpiece frame). Inverse: px py pz ox oy oz → those axes, C unwrapped continuously from row to row, on the
//! machine file's branch unless `--branch` is given.

use std::path::Path;

use anyhow::Result;
use vcnc_pipeline::Machine;
use vcnc_pipeline::kinematics::{Branch, POSE_COLUMNS, axes_columns, forward_file, inverse_file};

use crate::bad_input;
use crate::cli::Direction;
use vcnc_output::files::{format_num, write_atomic};

pub fn kinematics(
    machine_path: &Path,
    direction: Direction,
    input: &Path,
    out: Option<&Path>,
    branch: Option<i8>,
) -> Result<()> {
    let machine = Machine::load(machine_path)?;
    let branch = branch
        .map(|b| {
            Branch::try_from(i32::from(b))
                .map_err(|_| bad_input(format!("--branch {b}: expected 1 or -1")))
        })
        .transpose()?;
    let (header, rows): (Vec<&str>, Vec<Vec<f64>>) = match direction {
        Direction::Forward => (
            POSE_COLUMNS.to_vec(),
            forward_file(&machine, input)?
                .into_iter()
                .map(Vec::from)
                .collect(),
        ),
        Direction::Inverse => (
            axes_columns(&machine)?,
            inverse_file(&machine, input, branch)?,
        ),
    };
    let mut text = header.join(",");
    text.push('\n');
    for r in &rows {
        text.push_str(
            &r.iter()
                .map(|v| format_num(*v))
                .collect::<Vec<_>>()
                .join(","),
        );
        text.push('\n');
    }
    match out {
        Some(p) => write_atomic(p, text.as_bytes())?,
        None => print!("{text}"),
    }
    Ok(())
}
