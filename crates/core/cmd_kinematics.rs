//! `vcnc kinematics MACHINE forward|inverse --input CSV [--out CSV] [--branch 1|-1]`.
//! Forward: columns X Y Z (mm) A C (deg) → px py pz (mm) ox oy oz (workpiece frame).
//! Inverse: px py pz ox oy oz → X Y Z A C, C unwrapped continuously from row to row.

use std::path::Path;

use anyhow::Result;
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{Axes, Branch, IkOptions, Pose};

use crate::bad_input;
use crate::cli::Direction;
use crate::output::{format_num, write_atomic};
use crate::report::load_machine;

/// Rows of the named columns (in the order of `names`).
fn read_rows(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| bad_input(format!("{file}: cannot read: {e}")))?;
    let mut rdr = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_reader(bytes.as_slice());
    let header = rdr
        .headers()
        .map_err(|e| bad_input(format!("{file}: {e}")))?
        .clone();
    let idx: Vec<usize> = names
        .iter()
        .map(|n| {
            header
                .iter()
                .position(|h| h.eq_ignore_ascii_case(n))
                .ok_or_else(|| {
                    bad_input(format!(
                        "{file}: missing column '{n}' (need {}; the header has {})",
                        names.join(" "),
                        header.iter().collect::<Vec<_>>().join(" ")
                    ))
                })
        })
        .collect::<Result<_>>()?;
    let mut rows = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(|e| {
            bad_input(format!(
                "{file}:{}: {e}",
                e.position().map_or(0, |p| p.line())
            ))
        })?;
        let line = rec.position().map_or(0, |p| p.line());
        let mut row = Vec::with_capacity(idx.len());
        for (j, &i) in idx.iter().enumerate() {
            let s = rec.get(i).unwrap_or("");
            let v: f64 = s
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| {
                    bad_input(format!(
                        "{file}:{line}: column {}: '{s}' is not a finite number",
                        names[j]
                    ))
                })?;
            row.push(v);
        }
        rows.push(row);
    }
    Ok(rows)
}

pub fn kinematics(
    machine_path: &Path,
    direction: Direction,
    input: &Path,
    out: Option<&Path>,
    branch: i8,
) -> Result<()> {
    let machine = load_machine(machine_path)?;
    let kin = machine.kinematics_model()?;
    let branch = match branch {
        1 => Branch::Plus,
        -1 => Branch::Minus,
        b => return Err(bad_input(format!("--branch {b}: expected 1 or -1"))),
    };
    let mut text = String::new();
    match direction {
        Direction::Forward => {
            let rows = read_rows(input, &["X", "Y", "Z", "A", "C"])?;
            text.push_str("px,py,pz,ox,oy,oz\n");
            for r in &rows {
                let axes = Axes::new(r[0], r[1], r[2], r[3].to_radians(), r[4].to_radians());
                let p = kin.forward(&axes);
                let row = [p.p.x, p.p.y, p.p.z, p.o.x, p.o.y, p.o.z]
                    .map(format_num)
                    .join(",");
                text.push_str(&row);
                text.push('\n');
            }
        }
        Direction::Inverse => {
            let rows = read_rows(input, &["px", "py", "pz", "ox", "oy", "oz"])?;
            let poses: Vec<Pose> = rows
                .iter()
                .map(|r| {
                    Pose::new(
                        Vector3::new(r[0], r[1], r[2]),
                        Vector3::new(r[3], r[4], r[5]),
                    )
                })
                .collect();
            let opts = IkOptions {
                branch: Some(branch),
                ..IkOptions::default()
            };
            let sol = kin
                .inverse_sequence(&poses, &opts)
                .map_err(|e| bad_input(format!("{}: {e}", input.display())))?;
            text.push_str("X,Y,Z,A,C\n");
            for a in &sol.axes {
                let row = [a.x, a.y, a.z, a.a.to_degrees(), a.c.to_degrees()]
                    .map(format_num)
                    .join(",");
                text.push_str(&row);
                text.push('\n');
            }
        }
    }
    match out {
        Some(p) => write_atomic(p, text.as_bytes())?,
        None => print!("{text}"),
    }
    Ok(())
}
