//! Cross-checks against LinuxCNC's kinematics modules (docs/kinematics.md, "Cross-checks against
//! LinuxCNC"): the vectors in tests/data/linuxcnc were computed by LinuxCNC's own C functions
//! (scripts/kinematics-vectors.py compiles them out of a LinuxCNC repository); the proptests
//! below draw fresh cases every run against transcriptions of the same functions.
//!
//! Conventions (LinuxCNC → vcnc), as docs/kinematics.md derives them:
//! - `xyzac-trt`, `xyzbc-trt`: r = x/y/z-rot-point; d = (x-offset, y-offset, z-offset +
//!   tool-offset) (A/C has no x-offset, B/C no y-offset); angles equal with
//!   `conventional-directions` off, negated with it on.
//! - `5axiskins`: head-head C/B with pivot = C-axis point = (0, 0, pivot-length); b = −B, c = C.
//! - `maxkins`: head-table B/C with pivot (0, 0, pivot-length), r = 0; c = −C; b = −B with
//!   `conventional-directions` off, b = B with it on.

use crate::common;

use common::{col, ok, read_vectors};
use proptest::prelude::*;
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{Axes, AxisLimits, HeadHead, HeadTable, Kinematics, TableTilting, Tilt};

/// Position tolerance: 1e-9 mm (LinuxCNC's and vcnc's rounding differ by ~1e-13 mm here).
const TOL_MM: f64 = 1e-9;

fn table(tilt: Tilt, h: &[String], row: &[f64]) -> Kinematics {
    let r = Vector3::new(
        col(h, row, "x_rot_point"),
        col(h, row, "y_rot_point"),
        col(h, row, "z_rot_point"),
    );
    let d = Vector3::new(
        col(h, row, "x_offset"),
        col(h, row, "y_offset"),
        col(h, row, "z_offset") + col(h, row, "tool_offset"),
    );
    Kinematics::TableTilting(ok(TableTilting::new(tilt, r, d, AxisLimits::default())))
}

fn five_axis(l: f64) -> Kinematics {
    let p = Vector3::new(0.0, 0.0, l);
    Kinematics::HeadHead(ok(HeadHead::new(Tilt::B, p, p, AxisLimits::default())))
}

fn max(l: f64) -> Kinematics {
    Kinematics::HeadTable(ok(HeadTable::new(
        Tilt::B,
        Vector3::new(0.0, 0.0, l),
        Vector3::zeros(),
        AxisLimits::default(),
    )))
}

fn v3(h: &[String], row: &[f64], names: [&str; 3]) -> Vector3<f64> {
    Vector3::new(
        col(h, row, names[0]),
        col(h, row, names[1]),
        col(h, row, names[2]),
    )
}

/// The sign LinuxCNC's table modules put on both angles: +1 with conventional directions off.
fn trt_sign(h: &[String], row: &[f64]) -> f64 {
    if col(h, row, "conventional") == 0.0 {
        1.0
    } else {
        -1.0
    }
}

#[test]
fn trt_vectors_equal_linuxcnc() {
    let mut worst = 0.0f64;
    for (name, tilt, jt, t) in [
        ("xyzac-trt", Tilt::A, "ja", "a"),
        ("xyzbc-trt", Tilt::B, "jb", "b"),
    ] {
        let (h, rows) = read_vectors(&format!("{name}-forward.csv"));
        assert_eq!(rows.len(), 64);
        for row in &rows {
            let kin = table(tilt, &h, row);
            let s = trt_sign(&h, row);
            let j = Axes {
                x: col(&h, row, "jx"),
                y: col(&h, row, "jy"),
                z: col(&h, row, "jz"),
                c: s * col(&h, row, "jc").to_radians(),
                ..Axes::default()
            }
            .with(tilt.axis(), s * col(&h, row, jt).to_radians());
            let pose = kin.forward(&j);
            let e = (pose.p - v3(&h, row, ["px", "py", "pz"])).norm();
            let eo = (pose.o - v3(&h, row, ["ox", "oy", "oz"])).norm();
            assert!(
                e < TOL_MM && eo < 1e-9,
                "{name} forward {row:?}: {e} mm, {eo}"
            );
            worst = worst.max(e);
        }
        let (h, rows) = read_vectors(&format!("{name}-inverse.csv"));
        let mut discrepant = 0;
        for row in &rows {
            let kin = table(tilt, &h, row);
            let s = trt_sign(&h, row);
            let rot = Axes {
                c: s * col(&h, row, "c").to_radians(),
                ..Axes::default()
            }
            .with(tilt.axis(), s * col(&h, row, t).to_radians());
            let ours = ok(kin.inverse_tcp(&v3(&h, row, ["px", "py", "pz"]), &rot));
            let theirs = v3(&h, row, ["jx", "jy", "jz"]);
            // LinuxCNC's xyzbc inverse leaves `conventional-directions` out of its offset terms
            // (trtfuncs.c, dpx and dpz): with the switch off and offsets present it is not the
            // inverse of its own forward. Its difference from the true inverse is exactly
            // (2 sin b d_z, 0, -2 sin b d_x) (docs/kinematics.md); the true inverse is ours.
            let expected = if tilt == Tilt::B && s > 0.0 {
                let (sb, dx) = (rot.b.sin(), col(&h, row, "x_offset"));
                let dz = col(&h, row, "z_offset") + col(&h, row, "tool_offset");
                let shift = Vector3::new(2.0 * sb * dz, 0.0, -2.0 * sb * dx);
                if shift.norm() > 1e-6 {
                    discrepant += 1;
                }
                ours + shift
            } else {
                ours
            };
            let e = (expected - theirs).norm();
            assert!(e < TOL_MM, "{name} inverse {row:?}: {e} mm");
            worst = worst.max(e);
        }
        if tilt == Tilt::B {
            assert!(
                discrepant > 10,
                "the xyzbc discrepancy must be exercised: {discrepant}"
            );
        }
    }
    println!("trt: largest difference from LinuxCNC {worst:.3e} mm");
}

#[test]
fn fiveaxiskins_vectors_equal_linuxcnc() {
    let (h, rows) = read_vectors("5axiskins-forward.csv");
    assert_eq!(rows.len(), 64);
    let mut worst = 0.0f64;
    for row in &rows {
        let kin = five_axis(col(&h, row, "pivot_length"));
        let j = Axes {
            x: col(&h, row, "jx"),
            y: col(&h, row, "jy"),
            z: col(&h, row, "jz"),
            b: -col(&h, row, "jb").to_radians(),
            c: col(&h, row, "jc").to_radians(),
            ..Axes::default()
        };
        let pose = kin.forward(&j);
        let e = (pose.p - v3(&h, row, ["px", "py", "pz"])).norm();
        let eo = (pose.o - v3(&h, row, ["ox", "oy", "oz"])).norm();
        assert!(
            e < TOL_MM && eo < 1e-9,
            "5axiskins forward {row:?}: {e} mm, {eo}"
        );
        worst = worst.max(e);
    }
    let (h, rows) = read_vectors("5axiskins-inverse.csv");
    for row in &rows {
        let kin = five_axis(col(&h, row, "pivot_length"));
        let rot = Axes {
            b: -col(&h, row, "b").to_radians(),
            c: col(&h, row, "c").to_radians(),
            ..Axes::default()
        };
        let ours = ok(kin.inverse_tcp(&v3(&h, row, ["px", "py", "pz"]), &rot));
        let e = (ours - v3(&h, row, ["jx", "jy", "jz"])).norm();
        assert!(e < TOL_MM, "5axiskins inverse {row:?}: {e} mm");
        worst = worst.max(e);
    }
    println!("5axiskins: largest difference from LinuxCNC {worst:.3e} mm");
}

/// maxkins' B sign: −1 (b = −B) with conventional directions off.
fn max_b_sign(h: &[String], row: &[f64]) -> f64 {
    if col(h, row, "conventional") == 0.0 {
        -1.0
    } else {
        1.0
    }
}

#[test]
fn maxkins_vectors_equal_linuxcnc() {
    let (h, rows) = read_vectors("maxkins-inverse.csv");
    assert_eq!(rows.len(), 64);
    let mut worst = 0.0f64;
    for row in &rows {
        let kin = max(col(&h, row, "pivot_length"));
        let rot = Axes {
            b: max_b_sign(&h, row) * col(&h, row, "b").to_radians(),
            c: -col(&h, row, "c").to_radians(),
            ..Axes::default()
        };
        let ours = ok(kin.inverse_tcp(&v3(&h, row, ["px", "py", "pz"]), &rot));
        let e = (ours - v3(&h, row, ["jx", "jy", "jz"])).norm();
        assert!(e < TOL_MM, "maxkins inverse {row:?}: {e} mm");
        // The tool axis in the machine frame: R_y(b) z.
        let m = v3(&h, row, ["mx", "my", "mz"]);
        assert!((m - Vector3::new(rot.b.sin(), 0.0, rot.b.cos())).norm() < 1e-9);
        // And our forward kinematics returns the tip LinuxCNC's inverse was given.
        let p = kin
            .forward(&rot.with_pm(&v3(&h, row, ["jx", "jy", "jz"])))
            .p;
        assert!((p - v3(&h, row, ["px", "py", "pz"])).norm() < TOL_MM);
        worst = worst.max(e);
    }
    // maxkins' forward rotates the slides' X Y by C but not the head's B offset, so it is not
    // the inverse of its own inverse when B and C are both nonzero; it differs from the true
    // forward (ours) by con·L·sin B·((cos C, sin C) − (1, 0)) (docs/kinematics.md). Rows 0-15
    // have B = 0 or C = 0, where the two agree exactly.
    let (h, rows) = read_vectors("maxkins-forward.csv");
    for (k, row) in rows.iter().enumerate() {
        let l = col(&h, row, "pivot_length");
        let kin = max(l);
        let (b_deg, c_deg) = (col(&h, row, "jb"), col(&h, row, "jc"));
        let j = Axes {
            x: col(&h, row, "jx"),
            y: col(&h, row, "jy"),
            z: col(&h, row, "jz"),
            b: max_b_sign(&h, row) * b_deg.to_radians(),
            c: -c_deg.to_radians(),
            ..Axes::default()
        };
        let ours = kin.forward(&j).p;
        let con = max_b_sign(&h, row);
        let (cb, cc) = (b_deg.to_radians(), c_deg.to_radians());
        let shift = Vector3::new(cc.cos() - 1.0, cc.sin(), 0.0) * (con * l * cb.sin());
        if k < 16 {
            assert!(b_deg == 0.0 || c_deg == 0.0);
            assert!(shift.norm() < 1e-9);
        }
        let e = (ours + shift - v3(&h, row, ["px", "py", "pz"])).norm();
        assert!(e < TOL_MM, "maxkins forward {row:?}: {e} mm");
    }
    println!("maxkins: largest difference from LinuxCNC {worst:.3e} mm");
}

// ---- fresh cases against transcriptions of the same functions -----------------------------

/// LinuxCNC `trtfuncs.c`, `xyzbcKinematicsForward`, transcribed (joints mm, deg; returns the tip).
fn lcnc_xyzbc_forward(rp: [f64; 3], dx: f64, dz: f64, conv: bool, j: [f64; 5]) -> [f64; 3] {
    let (b, c) = (j[3].to_radians(), j[4].to_radians());
    let con = if conv { 1.0 } else { -1.0 };
    let (sb, cb, sc, cc) = (b.sin(), b.cos(), c.sin(), c.cos());
    let (qx, qy, qz) = (j[0] - dx - rp[0], j[1] - rp[1], j[2] - dz - rp[2]);
    [
        cc * cb * qx - con * sc * qy + con * cc * sb * qz + cc * dx + rp[0],
        con * sc * cb * qx + cc * qy + sc * sb * qz + con * sc * dx + rp[1],
        -con * sb * qx + cb * qz + dz + rp[2],
    ]
}

/// LinuxCNC `5axiskins.c`, `fiveaxis_KinematicsForward` with W = 0, transcribed.
fn lcnc_5axis_forward(l: f64, j: [f64; 5]) -> [f64; 3] {
    let (t, p) = (j[4].to_radians(), (180.0 - j[3]).to_radians());
    [
        j[0] + l * p.sin() * t.cos(),
        j[1] + l * p.sin() * t.sin(),
        j[2] + l + l * p.cos(),
    ]
}

/// LinuxCNC `maxkins.c`, `kinematicsInverse` with U = V = W = 0, transcribed.
fn lcnc_max_inverse(l: f64, conv: bool, p: [f64; 3], b_deg: f64, c_deg: f64) -> [f64; 3] {
    let con = if conv { 1.0 } else { -1.0 };
    let (zb, xb) = (l * b_deg.to_radians().cos(), l * b_deg.to_radians().sin());
    let xyr = p[0].hypot(p[1]);
    let th = p[1].atan2(p[0]) - c_deg.to_radians();
    [xyr * th.cos() + con * xb, xyr * th.sin(), p[2] + zb - l]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn xyzbc_forward_equals_fresh_linuxcnc_cases(
        rp in (-200.0..200.0f64, -200.0..200.0f64, -200.0..200.0f64),
        dx in -150.0..150.0f64, dz in -300.0..300.0f64, conv in any::<bool>(),
        j in (-500.0..500.0f64, -400.0..400.0f64, -400.0..400.0f64, -120.0..120.0f64, -720.0..720.0f64),
    ) {
        let rp = [rp.0, rp.1, rp.2];
        let kin = Kinematics::TableTilting(ok(TableTilting::new(
            Tilt::B, Vector3::from(rp), Vector3::new(dx, 0.0, dz), AxisLimits::default())));
        let s = if conv { -1.0 } else { 1.0 };
        let q = Axes { x: j.0, y: j.1, z: j.2, b: s * j.3.to_radians(), c: s * j.4.to_radians(), ..Axes::default() };
        let theirs = Vector3::from(lcnc_xyzbc_forward(rp, dx, dz, conv, [j.0, j.1, j.2, j.3, j.4]));
        prop_assert!((kin.forward(&q).p - theirs).norm() < TOL_MM);
    }

    #[test]
    fn fiveaxis_forward_equals_fresh_linuxcnc_cases(
        l in 10.0..500.0f64,
        j in (-500.0..500.0f64, -400.0..400.0f64, -400.0..400.0f64, -120.0..120.0f64, -720.0..720.0f64),
    ) {
        let q = Axes { x: j.0, y: j.1, z: j.2, b: -j.3.to_radians(), c: j.4.to_radians(), ..Axes::default() };
        let theirs = Vector3::from(lcnc_5axis_forward(l, [j.0, j.1, j.2, j.3, j.4]));
        prop_assert!((five_axis(l).forward(&q).p - theirs).norm() < TOL_MM);
    }

    #[test]
    fn maxkins_inverse_equals_fresh_linuxcnc_cases(
        l in 10.0..500.0f64, conv in any::<bool>(),
        p in (-300.0..300.0f64, -300.0..300.0f64, -300.0..300.0f64),
        b in -120.0..120.0f64, c in -720.0..720.0f64,
    ) {
        let sb = if conv { 1.0 } else { -1.0 };
        let rot = Axes { b: sb * b.to_radians(), c: -c.to_radians(), ..Axes::default() };
        let ours = ok(max(l).inverse_tcp(&Vector3::new(p.0, p.1, p.2), &rot));
        let theirs = Vector3::from(lcnc_max_inverse(l, conv, [p.0, p.1, p.2], b, c));
        prop_assert!((ours - theirs).norm() < TOL_MM, "{ours:?} vs {theirs:?}");
    }
}
