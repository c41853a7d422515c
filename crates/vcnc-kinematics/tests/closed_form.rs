//! The closed-form table-tilting A/C model (docs/kinematics.md): round trips, LinuxCNC's published
//! `xyzac-trt` kinematics (transcribed, fresh random cases every run), sequence inverse kinematics.
//! The derivatives of the TCP inverse are checked for every family in tests/families.rs.

use crate::common;

use std::f64::consts::{PI, TAU};

use common::{ok, spiral};

use proptest::prelude::*;
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{
    Axes, AxisLimits, AxisName, Branch, Error, IkOptions, Pose, SINGULAR_SIN_A, TableTiltingAc,
    Travel,
};

fn model(r: [f64; 3], d: [f64; 3]) -> TableTiltingAc {
    match TableTiltingAc::new(Vector3::from(r), Vector3::from(d), AxisLimits::default()) {
        Ok(m) => m,
        Err(e) => panic!("{e}"),
    }
}

/// The shipped NMV5000 model (vcnc's defaults, docs/kinematics.md: r = 0, d = (0, 0, −100) mm; A −120 ..= 30°).
fn nmv5000() -> TableTiltingAc {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../machines/nmv5000.urdf");
    match TableTiltingAc::from_urdf_file(path) {
        Ok(m) => m,
        Err(e) => panic!("{e}"),
    }
}

fn offsets() -> impl Strategy<Value = ([f64; 3], [f64; 3])> {
    (
        (-100.0..100.0f64, -100.0..100.0f64, -100.0..100.0f64),
        (-50.0..50.0f64, -100.0..100.0f64, -300.0..100.0f64),
    )
        .prop_map(|(r, d)| ([r.0, r.1, r.2], [d.0, d.1, d.2]))
}

/// A unit tool axis with tilt in [0.01, π − 0.01] rad (away from the A = 0 and A = π
/// singularities) and any azimuth.
fn unit_axis() -> impl Strategy<Value = Vector3<f64>> {
    (0.01..(PI - 0.01), -PI..PI).prop_map(|(tilt, az)| {
        Vector3::new(tilt.sin() * az.cos(), tilt.sin() * az.sin(), tilt.cos())
    })
}

fn branch() -> impl Strategy<Value = Branch> {
    prop_oneof![Just(Branch::Plus), Just(Branch::Minus)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// FK(IK(pose)) = pose within 1e-9 mm and 1e-9 (unit vector), both branches.
    #[test]
    fn fk_of_ik_is_identity(
        (r, d) in offsets(),
        p in (-300.0..300.0f64, -300.0..300.0f64, -300.0..300.0f64),
        o in unit_axis(),
        b in branch(),
        c_prev in -30.0..30.0f64,
    ) {
        let m = model(r, d);
        let pose = Pose::new(Vector3::new(p.0, p.1, p.2), o);
        let axes = ok(m.inverse_near(&pose, b, c_prev));
        prop_assert!(b.sign() * axes.a >= 0.0);
        prop_assert!((axes.c - c_prev).abs() <= PI + 1e-12);
        let back = m.forward(&axes);
        prop_assert!((back.p - pose.p).norm() < 1e-9, "p {:?} vs {:?}", back.p, pose.p);
        prop_assert!((back.o - pose.o).norm() < 1e-9, "o {:?} vs {:?}", back.o, pose.o);
    }

    /// IK(FK(axes)) = axes within 1e-9 mm / 1e-9 rad, both branches (A's sign picks the branch;
    /// C is recovered by unwrapping near a previous value less than half a turn away).
    #[test]
    fn ik_of_fk_is_identity(
        (r, d) in offsets(),
        pm in (-300.0..300.0f64, -300.0..300.0f64, -300.0..300.0f64),
        tilt in 0.01..(PI - 0.01),
        b in branch(),
        c in -40.0..40.0f64,
        dc in -3.0..3.0f64,
    ) {
        let m = model(r, d);
        let axes = Axes::new(pm.0, pm.1, pm.2, b.sign() * tilt, c);
        let back = ok(m.inverse_near(&m.forward(&axes), b, c + dc));
        for axis in [AxisName::X, AxisName::Y, AxisName::Z, AxisName::A, AxisName::C] {
            let (v, w) = (axes.get(axis).unwrap(), back.get(axis).unwrap());
            prop_assert!((v - w).abs() < 1e-9, "{axis}: {v} vs {w}");
        }
    }

    /// The result is never NaN: any finite position and orientation vector gives finite axes
    /// or a typed error (zero or non-finite vectors), never a NaN.
    #[test]
    fn inverse_never_produces_nan(
        p in (-1e6..1e6f64, -1e6..1e6f64, -1e6..1e6f64),
        o in (prop_oneof![Just(0.0), -1e-300..1e-300f64, -2.0..2.0f64, -1e300..1e300f64],
              prop_oneof![Just(0.0), -1e-300..1e-300f64, -2.0..2.0f64, -1e300..1e300f64],
              prop_oneof![Just(0.0), Just(1.0), Just(-1.0), -2.0..2.0f64, -1e300..1e300f64]),
        b in branch(),
    ) {
        let m = nmv5000();
        let pose = Pose::new(Vector3::new(p.0, p.1, p.2), Vector3::new(o.0, o.1, o.2));
        match m.inverse(&pose, b) {
            Ok(axes) => prop_assert!(axes.values().iter().all(|v| v.is_finite()), "{axes:?}"),
            Err(e) => {
                prop_assert!(o == (0.0, 0.0, 0.0), "unexpected error {e}");
                prop_assert!(matches!(e, Error::BadOrientation { .. }), "{}", e);
            }
        }
    }
}

#[test]
fn orientation_clamping_and_bad_vectors() {
    let m = nmv5000();
    // o_z slightly above 1 after normalisation by rounding: clamped, A = 0, C held.
    for o in [
        Vector3::new(1e-17, 0.0, 1.0),
        Vector3::new(0.0, 0.0, 1.0 + 1e-16),
        Vector3::new(-1e-300, 1e-300, -1e-300),
    ] {
        let axes = ok(m.inverse_near(&Pose::new(Vector3::zeros(), o), Branch::Minus, 0.7));
        assert!(
            axes.values().iter().all(|v| v.is_finite()),
            "{o:?} -> {axes:?}"
        );
    }
    for (o, reason) in [
        (Vector3::new(0.0, 0.0, 0.0), "zero length"),
        (Vector3::new(f64::NAN, 0.0, 1.0), "not finite"),
        (Vector3::new(0.0, f64::INFINITY, 1.0), "not finite"),
    ] {
        match m.inverse(&Pose::new(Vector3::zeros(), o), Branch::Plus) {
            Err(e @ Error::BadOrientation { .. }) => {
                assert!(e.to_string().contains(reason), "{e}")
            }
            other => panic!("expected BadOrientation for {o:?}, got {other:?}"),
        }
    }
    let e = m.inverse(
        &Pose::new(Vector3::new(f64::NAN, 0.0, 0.0), Vector3::z()),
        Branch::Plus,
    );
    assert!(matches!(e, Err(Error::NonFinitePosition { .. })), "{e:?}");
}

// ---- LinuxCNC xyzac-trt ------------------------------------------------------------------

/// Parameters of LinuxCNC's `xyzac-trt-kins` (`trt_params_t`): lengths in mm.
struct TrtParams {
    x_rot_point: f64,
    y_rot_point: f64,
    z_rot_point: f64,
    y_offset: f64,
    z_offset: f64,
    tool_offset: f64,
    conventional_directions: bool,
}

/// Transcription of LinuxCNC `src/emc/kinematics/trtfuncs.c`, function `xyzac_forward_math`
/// (LinuxCNC/linuxcnc master, the version with the `conventional_directions` switch;
/// with the switch off it is term by term the `xyzacKinematicsForward` of earlier versions,
/// e.g. commit 55084aaa). Joints X, Y, Z in mm and A, C in degrees (LinuxCNC's units);
/// returns the tool tip in the workpiece frame, mm. `con = +1` if conventional directions,
/// `-1` otherwise.
fn linuxcnc_xyzac_forward(p: &TrtParams, j: [f64; 5]) -> [f64; 3] {
    let (jx, jy, jz) = (j[0], j[1], j[2]);
    let a_rad = j[3].to_radians();
    let c_rad = j[4].to_radians();
    let dy = p.y_offset;
    let dz = p.z_offset + p.tool_offset;
    let con = if p.conventional_directions { 1.0 } else { -1.0 };
    let (sa, ca, sc, cc) = (a_rad.sin(), a_rad.cos(), c_rad.sin(), c_rad.cos());
    let x = cc * (jx - p.x_rot_point) - con * sc * ca * (jy - dy - p.y_rot_point)
        + sc * sa * (jz - dz - p.z_rot_point)
        - con * sc * dy
        + p.x_rot_point;
    let y = con * sc * (jx - p.x_rot_point) + cc * ca * (jy - dy - p.y_rot_point)
        - con * cc * sa * (jz - dz - p.z_rot_point)
        + cc * dy
        + p.y_rot_point;
    let z =
        con * sa * (jy - dy - p.y_rot_point) + ca * (jz - dz - p.z_rot_point) + dz + p.z_rot_point;
    [x, y, z]
}

/// Transcription of LinuxCNC `src/emc/kinematics/trtfuncs.c`, function `xyzac_inverse_math`
/// (same version): the machine position X, Y, Z (mm) for a workpiece-frame tip (mm) and given
/// A, C (degrees).
fn linuxcnc_xyzac_inverse(p: &TrtParams, pos: [f64; 3], a_deg: f64, c_deg: f64) -> [f64; 3] {
    let a_rad = a_deg.to_radians();
    let c_rad = c_deg.to_radians();
    let dy = p.y_offset;
    let dz = p.z_offset + p.tool_offset;
    let con = if p.conventional_directions { 1.0 } else { -1.0 };
    let (sa, ca, sc, cc) = (a_rad.sin(), a_rad.cos(), c_rad.sin(), c_rad.cos());
    let (tx, ty, tz) = (
        pos[0] - p.x_rot_point,
        pos[1] - p.y_rot_point,
        pos[2] - p.z_rot_point,
    );
    let x = cc * tx + con * sc * ty + p.x_rot_point;
    let y = -con * sc * ca * tx + cc * ca * ty + con * sa * tz - ca * dy - con * sa * dz
        + dy
        + p.y_rot_point;
    let z =
        sc * sa * tx - con * cc * sa * ty + ca * tz + con * sa * dy - ca * dz + dz + p.z_rot_point;
    [x, y, z]
}

/// Mapping (docs/kinematics.md): x/y/z-rot-point = r (the C-axis centre), y-offset = d_y,
/// z-offset = d_z (the A-axis centre relative to r; xyzac has no x-offset, so d_x = 0),
/// tool-offset = 0 (vcnc's pose is the tool tip), and `conventional-directions` off: in
/// LinuxCNC's default ("unconventional") convention a positive A or C turns the *table*
/// right-handedly, which is vcnc's convention (docs/kinematics.md). With conventional directions on, LinuxCNC's
/// formulas are vcnc's with A and C negated (checked below).
fn trt_params(r: [f64; 3], d: [f64; 3], conventional: bool) -> TrtParams {
    TrtParams {
        x_rot_point: r[0],
        y_rot_point: r[1],
        z_rot_point: r[2],
        y_offset: d[1],
        z_offset: d[2],
        tool_offset: 0.0,
        conventional_directions: conventional,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// FK equals LinuxCNC's xyzac-trt forward kinematics (conventional-directions off) within
    /// 1e-9 mm. Truth: the published LinuxCNC source, transcribed above.
    #[test]
    fn forward_equals_linuxcnc_xyzac_trt(
        (r, d) in offsets(),
        j in (-400.0..400.0f64, -400.0..400.0f64, -400.0..400.0f64, -200.0..200.0f64, -1000.0..1000.0f64),
    ) {
        let d = [0.0, d[1], d[2]];
        let m = model(r, d);
        let axes = Axes::new(j.0, j.1, j.2, j.3.to_radians(), j.4.to_radians());
        let ours = m.forward(&axes).p;
        let lcnc = linuxcnc_xyzac_forward(&trt_params(r, d, false), [j.0, j.1, j.2, j.3, j.4]);
        prop_assert!((ours - Vector3::from(lcnc)).norm() < 1e-9, "{ours:?} vs {lcnc:?}");

        // With conventional directions on, LinuxCNC equals ours at (−A, −C).
        let neg = Axes::new(j.0, j.1, j.2, -j.3.to_radians(), -j.4.to_radians());
        let conv = linuxcnc_xyzac_forward(&trt_params(r, d, true), [j.0, j.1, j.2, j.3, j.4]);
        prop_assert!((m.forward(&neg).p - Vector3::from(conv)).norm() < 1e-9);
    }

    /// The TCP inverse equals LinuxCNC's xyzac-trt inverse kinematics within 1e-9 mm.
    #[test]
    fn tcp_inverse_equals_linuxcnc_xyzac_trt(
        (r, d) in offsets(),
        p in (-300.0..300.0f64, -300.0..300.0f64, -300.0..300.0f64),
        a_deg in -200.0..200.0f64,
        c_deg in -1000.0..1000.0f64,
    ) {
        let d = [0.0, d[1], d[2]];
        let m = model(r, d);
        let ours = m.inverse_tcp(&Vector3::new(p.0, p.1, p.2), a_deg.to_radians(), c_deg.to_radians());
        let lcnc = linuxcnc_xyzac_inverse(&trt_params(r, d, false), [p.0, p.1, p.2], a_deg, c_deg);
        prop_assert!((ours - Vector3::from(lcnc)).norm() < 1e-9, "{ours:?} vs {lcnc:?}");
    }
}

// ---- sequences ----------------------------------------------------------------------------

#[test]
fn singularity_keeps_previous_c() {
    // A pose with the tool along +Z (A = 0) in the middle of a sequence keeps the C of the
    // sample before it; C then continues from there. Truth: docs/kinematics.md.
    let m = nmv5000();
    let tilt = (-20f64).to_radians();
    let poses: Vec<Pose> = [Some(1.0), Some(1.2), None, Some(1.3)]
        .iter()
        .map(|c| {
            let o = c.map_or(Vector3::z(), |c| TableTiltingAc::orientation(tilt, c));
            Pose::new(Vector3::new(5.0, 6.0, 7.0), o)
        })
        .collect();
    let opts = IkOptions {
        branch: Some(Branch::Minus),
        start: Axes::new(0.0, 0.0, 0.0, 0.0, 1.0),
        ..IkOptions::default()
    };
    let sol = ok(m.inverse_sequence(&poses, &opts));
    assert_eq!(sol.branch, Branch::Minus);
    assert_eq!(sol.singular_samples, 1);
    let cs: Vec<f64> = sol.axes.iter().map(|a| a.c).collect();
    assert!((cs[0] - 1.0).abs() < 1e-12, "{cs:?}");
    assert!((cs[1] - 1.2).abs() < 1e-12, "{cs:?}");
    assert_eq!(cs[2], cs[1]);
    assert_eq!(sol.axes[2].a, 0.0);
    assert!((cs[3] - 1.3).abs() < 1e-12, "{cs:?}");
    // A singular first sample keeps the start's C.
    let opts = IkOptions {
        start: Axes::new(0.0, 0.0, 0.0, 0.0, 2.5),
        ..opts
    };
    let sol = ok(m.inverse_sequence(&poses[2..], &opts));
    assert_eq!(sol.axes[0].c, 2.5);
    // Just above the tolerance C is computed, not held.
    let eps = 10.0 * SINGULAR_SIN_A;
    let o = Vector3::new(-eps * 0.6, -eps * 0.8, 1.0);
    let axes = ok(m.inverse_near(&Pose::new(Vector3::zeros(), o), Branch::Minus, 2.5));
    assert!((axes.c - 0.6f64.atan2(0.8)).abs() < 1e-6, "{axes:?}");
}

#[test]
fn auto_branch_picks_plus_when_it_fits() {
    // The tool axis does not carry the branch: o(a, c) = o(−a, c + π). A tilt of 17.2° fits
    // the A travel −120 ..= 30° on both branches; Auto takes +1.
    let m = nmv5000();
    let poses = [Pose::new(
        Vector3::zeros(),
        TableTiltingAc::orientation(-0.3, 0.0),
    )];
    let sol = ok(m.inverse_sequence(&poses, &IkOptions::default()));
    assert_eq!(sol.branch, Branch::Plus);
    assert!((sol.axes[0].a - 0.3).abs() < 1e-12);
    assert!((sol.axes[0].c.abs() - PI).abs() < 1e-12);
}

#[test]
fn unreachable_pose_reports_axis_value_travel_and_sample() {
    // Tilt 131.2°: branch +1 needs A = +131.2° > 30°, branch −1 needs A = −131.2° < −120°.
    let m = nmv5000();
    let mut poses = vec![Pose::new(Vector3::zeros(), TableTiltingAc::orientation(-0.3, 0.0)); 813];
    poses[812] = Pose::new(
        Vector3::zeros(),
        TableTiltingAc::orientation((-131.2f64).to_radians(), 0.4),
    );
    let e = match m.inverse_sequence(&poses, &IkOptions::default()) {
        Ok(_) => panic!("expected an error"),
        Err(e) => e,
    };
    let text = e.to_string();
    assert!(
        text.contains(
            "branch -1: A = -131.200° is out of travel -120.000° ..= 30.000° at sample 812"
        ),
        "{text}"
    );
    // Samples 0..812 (tilt 17.2°) fit either branch; branch +1 fails at 812 with A = +131.2°.
    assert!(
        text.contains(
            "branch +1: A = 131.200° is out of travel -120.000° ..= 30.000° at sample 812"
        ),
        "{text}"
    );
    // A fixed branch reports only its own failure.
    let opts = IkOptions {
        branch: Some(Branch::Minus),
        ..IkOptions::default()
    };
    match m.inverse_sequence(&poses, &opts) {
        Err(Error::OutOfTravel {
            axis: AxisName::A,
            value,
            lower,
            upper,
            sample: Some(812),
        }) => {
            assert!((value.to_degrees() + 131.2).abs() < 1e-9);
            assert!((lower.to_degrees() + 120.0).abs() < 1e-9);
            assert!((upper.to_degrees() - 30.0).abs() < 1e-9);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn linear_travel_violation_is_reported() {
    let m = nmv5000();
    let poses = [
        Pose::new(Vector3::new(0.0, 0.0, 0.0), Vector3::z()),
        Pose::new(Vector3::new(400.0, 0.0, 0.0), Vector3::z()),
    ];
    let e = m.inverse_sequence(&poses, &IkOptions::default());
    // A = 0 on both branches, so both fail on X; the message carries mm.
    let text = match e {
        Err(e) => e.to_string(),
        Ok(_) => panic!("expected an error"),
    };
    assert!(
        text.contains("X = 400.000 mm is out of travel -365.000 mm ..= 365.000 mm at sample 1"),
        "{text}"
    );
    // Without the travel check it solves.
    let opts = IkOptions {
        check_travel: false,
        ..IkOptions::default()
    };
    assert!(m.inverse_sequence(&poses, &opts).is_ok());
}

#[test]
fn bad_parameters_are_rejected() {
    let bad = TableTiltingAc::new(
        Vector3::new(f64::NAN, 0.0, 0.0),
        Vector3::zeros(),
        AxisLimits::default(),
    );
    assert!(matches!(bad, Err(Error::BadParameter { .. })));
    let limits = AxisLimits {
        a: Travel {
            lower: 1.0,
            upper: -1.0,
        },
        ..AxisLimits::default()
    };
    let bad = TableTiltingAc::default().with_limits(limits);
    assert!(matches!(bad, Err(Error::BadParameter { .. })), "{bad:?}");
    assert!(Branch::try_from(0).is_err());
    assert_eq!(ok(Branch::try_from(-1)), Branch::Minus);
}

// ---- the spiral (docs/contour.md) ------------------------------------------------------------

#[test]
fn spiral_axis_spans_match_spec() {
    // Truth: docs/contour.md (spans with the default offsets, branch −1): X −36…36 mm,
    // Y −25…58 mm, Z 22…61 mm, A −36.9…−11.5°, C three turns. Compared to the printed digits.
    let m = nmv5000();
    let poses = spiral(20_000);
    let sol = ok(m.inverse_sequence(&poses, &IkOptions::default()));
    // Branch +1 would need A up to +36.9° > 30°: Auto must fall back to −1.
    assert_eq!(sol.branch, Branch::Minus);
    assert_eq!(sol.singular_samples, 0);
    let span = |f: &dyn Fn(&Axes) -> f64| {
        sol.axes
            .iter()
            .map(f)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            })
    };
    let (x0, x1) = span(&|a| a.x);
    let (y0, y1) = span(&|a| a.y);
    let (z0, z1) = span(&|a| a.z);
    let (a0, a1) = span(&|a| a.a.to_degrees());
    let (c0, c1) = span(&|a| a.c);
    let near = |v: f64, spec: f64, tol: f64| (v - spec).abs() <= tol;
    assert!(
        near(x0, -36.0, 0.5) && near(x1, 36.0, 0.5),
        "X {x0} .. {x1}"
    );
    assert!(
        near(y0, -25.0, 0.5) && near(y1, 58.0, 0.5),
        "Y {y0} .. {y1}"
    );
    assert!(near(z0, 22.0, 0.5) && near(z1, 61.0, 0.5), "Z {z0} .. {z1}");
    assert!(
        near(a0, -36.9, 0.05) && near(a1, -11.5, 0.05),
        "A {a0} .. {a1}"
    );
    assert!(near((c1 - c0) / TAU, 3.0, 1e-9), "C {c0} .. {c1}");
    // C is continuous: no step larger than the spiral's own angular step.
    let max_step = sol
        .axes
        .windows(2)
        .map(|w| (w[1].c - w[0].c).abs())
        .fold(0.0, f64::max);
    assert!(max_step < 1.01 * 3.0 * TAU / 20_000.0, "{max_step}");
    // And every sample round-trips.
    for (pose, axes) in poses.iter().zip(&sol.axes) {
        let back = m.forward(axes);
        assert!((back.p - pose.p).norm() < 1e-9 && (back.o - pose.o).norm() < 1e-12);
    }
}
