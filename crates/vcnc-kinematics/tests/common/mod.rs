//! Helpers shared by the kinematics tests: families with given offsets, their URDF, fresh
//! random seeds, the LinuxCNC vector files.

#![allow(dead_code)]

use std::f64::consts::TAU;
use vcnc_kinematics::nalgebra::Vector3;

use vcnc_kinematics::{
    AxisLimits, Error, HeadHead, HeadTable, Kinematics, Pose, TableTilting, Tilt, Xyz,
};

/// docs/contour.md: 3 turns, radius 20 → 60 mm, tip on a dome of radius 100 mm centred at
/// (30, 20) in the workpiece frame, tool axis = dome normal.
pub fn spiral(n: usize) -> Vec<Pose> {
    (0..=n)
        .map(|i| {
            let theta = 3.0 * TAU * i as f64 / n as f64;
            let rho = 20.0 + 40.0 * theta / (3.0 * TAU);
            let h = (100.0f64 * 100.0 - rho * rho).sqrt();
            Pose::new(
                Vector3::new(
                    30.0 + rho * theta.cos(),
                    20.0 + rho * theta.sin(),
                    -50.0 + h,
                ),
                Vector3::new(rho * theta.cos(), rho * theta.sin(), h) / 100.0,
            )
        })
        .collect()
}

pub fn ok<T>(r: Result<T, Error>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

pub fn v(a: [f64; 3]) -> Vector3<f64> {
    Vector3::from(a)
}

/// A closed-form family from its kind, tilt and two offset vectors (mm): (r, d) of a table,
/// (pivot, C-axis point) of a head-head, (pivot, r) of a head-table.
pub fn family(kind: usize, tilt: Tilt, o1: [f64; 3], o2: [f64; 3]) -> Kinematics {
    let limits = AxisLimits::default();
    match kind {
        0 => Kinematics::TableTilting(ok(TableTilting::new(tilt, v(o1), v(o2), limits))),
        1 => Kinematics::HeadHead(ok(HeadHead::new(tilt, v(o1), v(o2), limits))),
        2 => Kinematics::HeadTable(ok(HeadTable::new(tilt, v(o1), v(o2), limits))),
        _ => Kinematics::Xyz(Xyz { limits }),
    }
}

/// Every five-axis closed form with fixed, unround offsets, for deterministic tests.
pub fn five_axis_families() -> Vec<Kinematics> {
    let mut out = Vec::new();
    for tilt in [Tilt::A, Tilt::B] {
        out.push(family(0, tilt, [3.0, -4.0, 11.0], [7.5, 12.0, -140.0]));
        out.push(family(1, tilt, [4.0, -6.0, 230.0], [-2.0, 3.0, 260.0]));
        out.push(family(2, tilt, [5.0, 2.5, 175.0], [-30.0, 45.0, 8.0]));
    }
    out
}

fn fmt3(p: Vector3<f64>) -> String {
    format!("{:?} {:?} {:?}", p.x, p.y, p.z)
}

fn axis_xyz(tilt: Tilt) -> &'static str {
    match tilt {
        Tilt::A => "1 0 0",
        Tilt::B => "0 1 0",
    }
}

/// A URDF of a closed-form family, written as a machine builder would (docs/kinematics.md):
/// slides on the tool side, rotary joints at their points, the tool tip and the workpiece
/// frame at the machine origin at zero.
pub fn urdf_of(kin: &Kinematics) -> String {
    let limit = r#"<limit lower="-1000" upper="1000" effort="0" velocity="1"/>"#;
    let slides = |last: &str| {
        format!(
            r#"<joint name="x" type="prismatic"><parent link="machine"/><child link="sx"/>
    <axis xyz="1 0 0"/>{limit}</joint>
  <joint name="y" type="prismatic"><parent link="sx"/><child link="sy"/>
    <axis xyz="0 1 0"/>{limit}</joint>
  <joint name="z" type="prismatic"><parent link="sy"/><child link="{last}"/>
    <axis xyz="0 0 1"/>{limit}</joint>"#
        )
    };
    let rot = |name: &str, axis: &str, parent: &str, child: &str, at: Vector3<f64>| {
        format!(
            r#"<joint name="{name}" type="continuous"><parent link="{parent}"/><child link="{child}"/>
    <origin xyz="{}"/><axis xyz="{axis}"/><limit effort="0" velocity="1"/></joint>"#,
            fmt3(at)
        )
    };
    let fixed = |name: &str, parent: &str, child: &str, at: Vector3<f64>| {
        format!(
            r#"<joint name="{name}" type="fixed"><parent link="{parent}"/><child link="{child}"/>
    <origin xyz="{}"/></joint>"#,
            fmt3(at)
        )
    };
    let links = "<link name=\"machine\"/><link name=\"sx\"/><link name=\"sy\"/><link name=\"ram\"/>\
        <link name=\"h1\"/><link name=\"h2\"/><link name=\"tool_tip\"/><link name=\"t1\"/>\
        <link name=\"t2\"/><link name=\"workpiece\"/>";
    let body = match kin {
        Kinematics::Xyz(_) => format!(
            "{}\n{}",
            slides("tool_tip"),
            fixed("w", "machine", "workpiece", Vector3::zeros())
        ),
        Kinematics::TableTilting(m) => format!(
            "{}\n{}\n{}\n{}",
            slides("tool_tip"),
            rot(
                &m.tilt.to_string(),
                axis_xyz(m.tilt),
                "machine",
                "t1",
                m.r + m.d
            ),
            rot("c", "0 0 1", "t1", "t2", -m.d),
            fixed("w", "t2", "workpiece", -m.r)
        ),
        Kinematics::HeadHead(m) => format!(
            "{}\n{}\n{}\n{}\n{}",
            slides("ram"),
            rot("c", "0 0 1", "ram", "h1", m.c_axis),
            rot(
                &m.tilt.to_string(),
                axis_xyz(m.tilt),
                "h1",
                "h2",
                m.pivot - m.c_axis
            ),
            fixed("tool", "h2", "tool_tip", -m.pivot),
            fixed("w", "machine", "workpiece", Vector3::zeros())
        ),
        Kinematics::HeadTable(m) => format!(
            "{}\n{}\n{}\n{}\n{}",
            slides("ram"),
            rot(&m.tilt.to_string(), axis_xyz(m.tilt), "ram", "h2", m.pivot),
            fixed("tool", "h2", "tool_tip", -m.pivot),
            rot("c", "0 0 1", "machine", "t2", m.r),
            fixed("w", "t2", "workpiece", -m.r)
        ),
        Kinematics::Chain(_) => panic!("a chain has its own URDF"),
    };
    // Unused links would be disconnected: keep only the links the joints name.
    let used: Vec<&str> = [
        "machine",
        "sx",
        "sy",
        "ram",
        "h1",
        "h2",
        "tool_tip",
        "t1",
        "t2",
        "workpiece",
    ]
    .into_iter()
    .filter(|l| *l == "machine" || body.contains(&format!("link=\"{l}\"")))
    .collect();
    let links: String = links
        .split("/>")
        .filter(|l| used.iter().any(|u| l.contains(&format!("\"{u}\""))))
        .map(|l| format!("{l}/>"))
        .collect();
    format!("<?xml version=\"1.0\"?>\n<robot name=\"test\">\n  {links}\n  {body}\n</robot>\n")
}

/// A fresh seed for this run, printed so a failure can be replayed with `VCNC_SEED=...`.
pub fn fresh_seed(test: &str) -> u64 {
    let seed = std::env::var("VCNC_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| {
            use std::time::{SystemTime, UNIX_EPOCH};
            SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos() as u64)
        });
    println!("{test}: seed {seed} (replay with VCNC_SEED={seed})");
    seed
}

/// A LinuxCNC vector file (tests/data/linuxcnc): its column names and rows; `#` lines skipped.
pub fn read_vectors(name: &str) -> (Vec<String>, Vec<Vec<f64>>) {
    let path = format!("{}/tests/data/linuxcnc/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<String> = lines
        .next()
        .unwrap_or_else(|| panic!("{path}: no header"))
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| {
            l.split(',')
                .map(|x| x.parse().unwrap_or_else(|e| panic!("{path}: {x}: {e}")))
                .collect()
        })
        .collect();
    (header, rows)
}

/// Column `name` of a row read by [`read_vectors`].
pub fn col(header: &[String], row: &[f64], name: &str) -> f64 {
    let i = header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name}"));
    row[i]
}
