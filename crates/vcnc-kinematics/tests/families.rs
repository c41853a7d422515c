//! Every family through the one `Kinematics` API (docs/kinematics.md): round trips FK∘IK and
//! IK∘FK on both branches, the tool-centre-point inverse and its derivatives against finite
//! differences, each closed form against the generic URDF chain of the same machine, the same
//! bits whole or in pieces, parameter tables and axis maps.

use crate::common;

use std::f64::consts::PI;

use common::{family, five_axis_families, ok, urdf_of};
use proptest::prelude::*;
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{
    Axes, AxisMap, AxisName, Branch, Carrier, Error, Family, IkOptions, JointMotion,
    KinematicChain, Kinematics, KinematicsParams, PointMotion, Pose, Tilt, Track,
};

fn offset() -> impl Strategy<Value = [f64; 3]> {
    (-200.0..200.0f64, -200.0..200.0f64, -300.0..300.0f64).prop_map(|(a, b, c)| [a, b, c])
}

/// Any five-axis closed form with random offsets.
fn five_axis() -> impl Strategy<Value = Kinematics> {
    (
        0..3usize,
        prop_oneof![Just(Tilt::A), Just(Tilt::B)],
        offset(),
        offset(),
    )
        .prop_map(|(kind, tilt, o1, o2)| family(kind, tilt, o1, o2))
}

fn branch() -> impl Strategy<Value = Branch> {
    prop_oneof![Just(Branch::Plus), Just(Branch::Minus)]
}

/// A unit tool axis with tilt in [0.01, π − 0.01] rad (away from the singularities).
fn unit_axis() -> impl Strategy<Value = Vector3<f64>> {
    (0.01..(PI - 0.01), -PI..PI).prop_map(|(tilt, az)| {
        Vector3::new(tilt.sin() * az.cos(), tilt.sin() * az.sin(), tilt.cos())
    })
}

fn tilt_axis(kin: &Kinematics) -> AxisName {
    kin.rotary_axes()[0].axis
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// FK(IK(pose)) = pose within 1e-9 mm and 1e-9 (unit vector), both branches, every family;
    /// the tilt's sign is the branch and C is the turn nearest the previous C.
    #[test]
    fn fk_of_ik_is_identity(
        kin in five_axis(),
        p in (-300.0..300.0f64, -300.0..300.0f64, -300.0..300.0f64),
        o in unit_axis(),
        b in branch(),
        c_prev in -30.0..30.0f64,
    ) {
        let pose = Pose::new(Vector3::new(p.0, p.1, p.2), o);
        let prev = Axes { c: c_prev, ..Axes::default() };
        let j = ok(kin.inverse(&pose, b, &prev));
        prop_assert!(b.sign() * j[tilt_axis(&kin)] >= 0.0);
        prop_assert!((j.c - c_prev).abs() <= PI + 1e-12);
        let back = kin.forward(&j);
        prop_assert!((back.p - pose.p).norm() < 1e-9, "{}: p {:?} vs {:?}", kin.family(), back.p, pose.p);
        prop_assert!((back.o - pose.o).norm() < 1e-9, "{}: o {:?} vs {:?}", kin.family(), back.o, pose.o);
    }

    /// IK(FK(joints)) = joints within 1e-9 mm / 1e-9 rad on the branch of the tilt's sign, every
    /// family.
    #[test]
    fn ik_of_fk_is_identity(
        kin in five_axis(),
        pm in (-300.0..300.0f64, -300.0..300.0f64, -300.0..300.0f64),
        tilt in 0.01..(PI - 0.01),
        b in branch(),
        c in -40.0..40.0f64,
        dc in -3.0..3.0f64,
    ) {
        let t = tilt_axis(&kin);
        let j = Axes { x: pm.0, y: pm.1, z: pm.2, c, ..Axes::default() }.with(t, b.sign() * tilt);
        let back = ok(kin.inverse(&kin.forward(&j), b, &Axes { c: c + dc, ..Axes::default() }));
        for axis in kin.axes() {
            prop_assert!((back[axis] - j[axis]).abs() < 1e-9, "{}: {axis}: {} vs {}", kin.family(), back[axis], j[axis]);
        }
    }

    /// The TCP inverse puts the tool tip where it is asked: FK(rotary, TCP(p_w, rotary)) = p_w.
    #[test]
    fn tcp_inverse_reaches_the_tip(
        kin in five_axis(),
        p in (-300.0..300.0f64, -300.0..300.0f64, -300.0..300.0f64),
        r in (-3.5..3.5f64, -20.0..20.0f64),
    ) {
        let rot = Axes { c: r.1, ..Axes::default() }.with(tilt_axis(&kin), r.0);
        let p_w = Vector3::new(p.0, p.1, p.2);
        let pm = ok(kin.inverse_tcp(&p_w, &rot));
        prop_assert!((kin.forward(&rot.with_pm(&pm)).p - p_w).norm() < 1e-9);
    }
}

// ---- the URDF chain against the closed forms --------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// A family written as URDF reads back as that family with its offsets, and the generic
    /// chain of the same file (forward along the steps, the TCP inverse by propagating the
    /// frames' motion, the pose inverse by damped least squares) equals the closed form.
    #[test]
    fn urdf_chains_equal_their_closed_forms(
        kin in five_axis(),
        j in (-300.0..300.0f64, -300.0..300.0f64, -300.0..300.0f64, -3.0..3.0f64, -8.0..8.0f64),
        d in (-2.0..2.0f64, -2.0..2.0f64, -300.0..300.0f64, -300.0..300.0f64, -300.0..300.0f64),
        dd in (-20.0..20.0f64, -20.0..20.0f64),
    ) {
        let text = urdf_of(&kin);
        let read = ok(Kinematics::from_urdf_str(&text, "family.urdf"));
        prop_assert_eq!(read.family(), kin.family(), "{}", text);
        let chain = Kinematics::Chain(Box::new(ok(KinematicChain::read_urdf_str(&text, "family.urdf"))));
        let t = tilt_axis(&kin);
        let q = Axes { x: j.0, y: j.1, z: j.2, c: j.4, ..Axes::default() }.with(t, j.3);
        for other in [&read, &chain] {
            let (f, g) = (kin.forward(&q), other.forward(&q));
            prop_assert!((f.p - g.p).norm() < 1e-9 && (f.o - g.o).norm() < 1e-12, "{f:?} {g:?}");
        }
        // TCP motion: tip moving, rotary axes moving.
        let tip = PointMotion {
            p: Vector3::new(j.0, j.1, j.2) * 0.5,
            p_dot: Vector3::new(d.2, d.3, d.4),
            p_ddot: Vector3::new(d.4, d.2, d.3) * 10.0,
        };
        let rot = JointMotion {
            pos: q,
            vel: Axes { c: d.1, ..Axes::default() }.with(t, d.0),
            acc: Axes { c: dd.1, ..Axes::default() }.with(t, dd.0),
        };
        let (a, b) = (ok(kin.inverse_tcp_motion(&tip, &rot)), ok(chain.inverse_tcp_motion(&tip, &rot)));
        prop_assert!((a.pos.pm() - b.pos.pm()).norm() < 1e-9);
        prop_assert!((a.vel.pm() - b.vel.pm()).norm() < 1e-8, "{:?} {:?}", a.vel, b.vel);
        prop_assert!((a.acc.pm() - b.acc.pm()).norm() < 1e-6, "{:?} {:?}", a.acc, b.acc);
        // The pose inverse by damped least squares from a nearby seed lands on the same joints.
        if j.3.abs() > 0.05 && (PI - j.3.abs()) > 0.05 {
            let pose = kin.forward(&q);
            let seed = q.with(t, q[t] + 0.03).with(AxisName::C, q.c - 0.04);
            let back = ok(chain.inverse(&pose, Branch::Plus, &seed));
            for axis in kin.axes() {
                prop_assert!((back[axis] - q[axis]).abs() < 1e-9, "{axis}: {} vs {}", back[axis], q[axis]);
            }
        }
    }
}

// ---- TCP derivatives ----------------------------------------------------------------------

/// A smooth TCP trajectory with analytic derivatives (mm, rad, s): the tip and the rotary axes
/// `t` (the tilt) and C.
fn tcp_at(t_axis: AxisName, t: f64) -> (PointMotion, JointMotion) {
    let (w1, w2, w3, wa, wc) = (1.3, 0.7, 2.1, 1.1, 1.7);
    let tip = PointMotion {
        p: Vector3::new(
            10.0 + 40.0 * (w1 * t).sin(),
            -5.0 + 25.0 * (w2 * t).cos(),
            30.0 + 8.0 * (w3 * t).sin(),
        ),
        p_dot: Vector3::new(
            40.0 * w1 * (w1 * t).cos(),
            -25.0 * w2 * (w2 * t).sin(),
            8.0 * w3 * (w3 * t).cos(),
        ),
        p_ddot: Vector3::new(
            -40.0 * w1 * w1 * (w1 * t).sin(),
            -25.0 * w2 * w2 * (w2 * t).cos(),
            -8.0 * w3 * w3 * (w3 * t).sin(),
        ),
    };
    let pos = Axes {
        c: 0.5 + 2.0 * t + 0.4 * (wc * t).sin(),
        ..Axes::default()
    }
    .with(t_axis, -0.4 + 0.3 * (wa * t).sin());
    let vel = Axes {
        c: 2.0 + 0.4 * wc * (wc * t).cos(),
        ..Axes::default()
    }
    .with(t_axis, 0.3 * wa * (wa * t).cos());
    let acc = Axes {
        c: -0.4 * wc * wc * (wc * t).sin(),
        ..Axes::default()
    }
    .with(t_axis, -0.3 * wa * wa * (wa * t).sin());
    (tip, JointMotion { pos, vel, acc })
}

#[test]
fn tcp_derivatives_match_finite_differences() {
    // Truth: 5-point central differences of the position function `inverse_tcp` (step 1 ms;
    // truncation error < 1e-9, rounding < 1e-6 mm/s² for these amplitudes and frequencies),
    // for every closed form and for the generic chain of each.
    let mut cases: Vec<Kinematics> = five_axis_families();
    let chains: Vec<Kinematics> = cases
        .iter()
        .map(|k| {
            Kinematics::Chain(Box::new(ok(KinematicChain::read_urdf_str(
                &urdf_of(k),
                "t.urdf",
            ))))
        })
        .collect();
    cases.extend(chains);
    for kin in &cases {
        let ta = tilt_axis(kin);
        let pos = |t: f64| {
            let (tip, rot) = tcp_at(ta, t);
            ok(kin.inverse_tcp(&tip.p, &rot.pos))
        };
        let h = 1e-3;
        let (mut max_v, mut max_acc, mut max_ev, mut max_ea) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for i in 0..=100 {
            let t = i as f64 * 0.05;
            let (tip, rot) = tcp_at(ta, t);
            let mm = ok(kin.inverse_tcp_motion(&tip, &rot));
            let (f2, f1, f0, g1, g2) = (
                pos(t + 2.0 * h),
                pos(t + h),
                pos(t),
                pos(t - h),
                pos(t - 2.0 * h),
            );
            let v_fd = (-f2 + f1 * 8.0 - g1 * 8.0 + g2) / (12.0 * h);
            let a_fd = (-f2 + f1 * 16.0 - f0 * 30.0 + g1 * 16.0 - g2) / (12.0 * h * h);
            assert!(
                (mm.pos.pm() - f0).norm() < 1e-9,
                "{}: position",
                kin.family()
            );
            max_v = max_v.max(mm.vel.pm().norm());
            max_acc = max_acc.max(mm.acc.pm().norm());
            max_ev = max_ev.max((mm.vel.pm() - v_fd).norm());
            max_ea = max_ea.max((mm.acc.pm() - a_fd).norm());
        }
        // The trajectory is not trivial: hundreds of mm/s and mm/s².
        assert!(max_v > 100.0 && max_acc > 100.0, "{max_v} {max_acc}");
        assert!(
            max_ev < 1e-7,
            "{}: velocity error {max_ev} mm/s",
            kin.family()
        );
        assert!(
            max_ea < 1e-5,
            "{}: acceleration error {max_ea} mm/s²",
            kin.family()
        );
    }
}

// ---- whole or in pieces -------------------------------------------------------------------

#[test]
fn tcp_track_gives_the_same_bits_whole_or_in_pieces() {
    let n = 1000;
    let mut cases = five_axis_families();
    cases.push(Kinematics::Chain(Box::new(ok(
        KinematicChain::read_urdf_str(&urdf_of(&cases[3]), "t.urdf"),
    ))));
    for kin in &cases {
        let cols: Vec<Vec<f64>> = (0..15)
            .map(|i| {
                (0..n)
                    .map(|k| ((k * 7 + i * 13) as f64 * 0.37).sin() * 100.0)
                    .collect()
            })
            .collect();
        let tcp: Vec<bool> = (0..n).map(|k| k % 11 != 5).collect();
        let track = |i: usize, r: std::ops::Range<usize>| Track {
            pos: &cols[3 * i][r.clone()],
            vel: &cols[3 * i + 1][r.clone()],
            acc: &cols[3 * i + 2][r],
        };
        let whole = ok(kin.inverse_tcp_track(
            [track(0, 0..n), track(1, 0..n), track(2, 0..n)],
            &[track(3, 0..n), track(4, 0..n)],
            &tcp,
        ));
        let mut pieces: [Vec<f64>; 9] = Default::default();
        for r in [0..137, 137..600, 600..601, 601..n] {
            let part = ok(kin.inverse_tcp_track(
                [
                    track(0, r.clone()),
                    track(1, r.clone()),
                    track(2, r.clone()),
                ],
                &[track(3, r.clone()), track(4, r.clone())],
                &tcp[r],
            ));
            for (i, t) in part.iter().enumerate() {
                pieces[3 * i].extend(&t.pos);
                pieces[3 * i + 1].extend(&t.vel);
                pieces[3 * i + 2].extend(&t.acc);
            }
        }
        for (i, t) in whole.iter().enumerate() {
            for (a, b) in [
                (&t.pos, &pieces[3 * i]),
                (&t.vel, &pieces[3 * i + 1]),
                (&t.acc, &pieces[3 * i + 2]),
            ] {
                assert!(
                    a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{}",
                    kin.family()
                );
            }
        }
        // Samples outside TCP mode are copied.
        assert_eq!(whole[0].pos[5], cols[0][5]);
    }
}

#[test]
fn pose_solver_gives_the_same_bits_whole_or_in_pieces() {
    for kin in five_axis_families() {
        let poses: Vec<Pose> = (0..500)
            .map(|k| {
                let s = k as f64 * 0.01;
                let j = Axes {
                    x: 30.0 * s.sin(),
                    y: 20.0 * s.cos(),
                    z: 5.0 * s,
                    c: 3.0 * s,
                    ..Axes::default()
                }
                .with(tilt_axis(&kin), 0.3 + 0.2 * (2.0 * s).sin());
                kin.forward(&j)
            })
            .collect();
        let opts = IkOptions {
            branch: Some(Branch::Plus),
            ..IkOptions::default()
        };
        let whole = ok(kin.inverse_sequence(&poses, &opts));
        let mut solver = kin.pose_solver(Branch::Plus, &opts);
        let mut pieces = Vec::new();
        for r in [0..1, 1..250, 250..500] {
            pieces.extend(ok(solver.solve_piece(&poses[r])));
        }
        assert_eq!(whole.axes.len(), pieces.len());
        for (a, b) in whole.axes.iter().zip(&pieces) {
            assert!(
                a.values()
                    .iter()
                    .zip(b.values())
                    .all(|(x, y)| x.to_bits() == y.to_bits())
            );
        }
        // And the poses come back.
        for (p, j) in poses.iter().zip(&whole.axes) {
            assert!((kin.forward(j).p - p.p).norm() < 1e-9);
        }
    }
}

// ---- 3-axis, roles, parameter tables ---------------------------------------------------------

#[test]
fn three_axis_machine_keeps_the_tool_along_z() {
    let kin = ok(Kinematics::from_params(&KinematicsParams {
        family: Some(Family::Xyz),
        ..KinematicsParams::default()
    }));
    assert_eq!(kin.axes(), vec![AxisName::X, AxisName::Y, AxisName::Z]);
    assert!(kin.rotary_axes().is_empty());
    let j = Axes {
        x: 1.0,
        y: -2.0,
        z: 3.5,
        ..Axes::default()
    };
    let pose = kin.forward(&j);
    assert_eq!(
        (pose.p, pose.o),
        (Vector3::new(1.0, -2.0, 3.5), Vector3::z())
    );
    assert_eq!(ok(kin.inverse(&pose, Branch::Plus, &Axes::default())), j);
    let tilted = Pose::new(pose.p, Vector3::new(0.1, 0.0, 1.0));
    match kin.inverse(&tilted, Branch::Plus, &Axes::default()) {
        Err(e @ Error::BadOrientation { .. }) => assert!(e.to_string().contains("along +Z"), "{e}"),
        other => panic!("{other:?}"),
    }
    // The TCP track is the tip itself.
    let x = [1.0, 2.0];
    let t = Track {
        pos: &x,
        vel: &x,
        acc: &x,
    };
    let out = ok(kin.inverse_tcp_track([t, t, t], &[], &[true, true]));
    assert_eq!(out[0].pos, x.to_vec());
}

#[test]
fn roles_and_axis_maps() {
    let cases = [
        (
            family(0, Tilt::B, [0.0; 3], [0.0; 3]),
            "table-tilting B/C",
            [Carrier::Table, Carrier::Table],
        ),
        (
            family(1, Tilt::A, [0.0, 0.0, 1.0], [0.0; 3]),
            "head-head C/A",
            [Carrier::Head, Carrier::Head],
        ),
        (
            family(2, Tilt::B, [0.0, 0.0, 1.0], [0.0; 3]),
            "head-table B/C",
            [Carrier::Head, Carrier::Table],
        ),
    ];
    for (kin, name, turns) in cases {
        assert_eq!(kin.family().to_string(), name);
        let r = kin.rotary_axes();
        assert_eq!([r[0].turns, r[1].turns], turns);
        assert_eq!(r[1].axis, AxisName::C);
        // A machine listing its axes in its own order.
        let machine = [
            AxisName::C,
            AxisName::Z,
            r[0].axis,
            AxisName::X,
            AxisName::Y,
        ];
        let map = ok(AxisMap::new(&kin, &machine));
        let series: Vec<Vec<f64>> = vec![vec![90.0], vec![3.0], vec![-45.0], vec![1.0], vec![2.0]];
        let j = map.at(&series, 0);
        assert_eq!((j.x, j.y, j.z), (1.0, 2.0, 3.0));
        assert!((j.c - PI / 2.0).abs() < 1e-15 && (j[r[0].axis] + PI / 4.0).abs() < 1e-15);
        // A machine without the tilt.
        let e = AxisMap::new(&kin, &[AxisName::X, AxisName::Y, AxisName::Z, AxisName::C]);
        match e {
            Err(e) => assert_eq!(
                e.to_string(),
                format!("a {name} machine needs axis {}", r[0].axis)
            ),
            Ok(_) => panic!("expected an error"),
        }
    }
}

#[test]
fn parameter_tables_are_checked() {
    let base = KinematicsParams {
        family: Some(Family::HeadTable(Tilt::B)),
        ..KinematicsParams::default()
    };
    // A head needs its pivot.
    let e = Kinematics::from_params(&base);
    assert!(
        matches!(&e, Err(Error::BadParameter { name, .. }) if name == "pivot_length_mm"),
        "{e:?}"
    );
    // The pivot length sets the pivot straight above the tip.
    let kin = ok(Kinematics::from_params(&KinematicsParams {
        pivot_length_mm: Some(180.0),
        ..base.clone()
    }));
    match kin {
        Kinematics::HeadTable(m) => assert_eq!(m.pivot, Vector3::new(0.0, 0.0, 180.0)),
        other => panic!("{other:?}"),
    }
    // A key of another family is refused, by name.
    let e = Kinematics::from_params(&KinematicsParams {
        pivot_length_mm: Some(180.0),
        tilt_offset_mm: Some([0.0, 0.0, -100.0]),
        ..base.clone()
    });
    assert!(
        matches!(&e, Err(Error::BadParameter { name, .. }) if name == "tilt_offset_mm"),
        "{e:?}"
    );
    // Both pivot forms at once.
    let e = Kinematics::from_params(&KinematicsParams {
        pivot_length_mm: Some(180.0),
        pivot_mm: Some([0.0, 0.0, 180.0]),
        ..base.clone()
    });
    assert!(e.is_err());
    // Non-finite offsets.
    let e = Kinematics::from_params(&KinematicsParams {
        family: Some(Family::TableTilting(Tilt::A)),
        c_centre_mm: Some([f64::NAN, 0.0, 0.0]),
        ..KinematicsParams::default()
    });
    assert!(matches!(e, Err(Error::BadParameter { .. })), "{e:?}");
    // No family.
    assert!(Kinematics::from_params(&KinematicsParams::default()).is_err());
    // A head-head from its pivot length has C and the tilt meeting at the pivot.
    let kin = ok(Kinematics::from_params(&KinematicsParams {
        family: Some(Family::HeadHead(Tilt::B)),
        pivot_length_mm: Some(250.0),
        ..KinematicsParams::default()
    }));
    match kin {
        Kinematics::HeadHead(m) => assert_eq!(
            (m.pivot, m.c_axis),
            (Vector3::new(0.0, 0.0, 250.0), Vector3::new(0.0, 0.0, 250.0))
        ),
        other => panic!("{other:?}"),
    }
}

#[test]
fn positive_angles_turn_the_head_or_the_table_right_handedly() {
    // Truth: the conventions of docs/kinematics.md, by hand. A head tilted +90° about Y points
    // the tool along +X; a table tilted +90° about Y turns the workpiece so that the tool
    // (fixed along machine +Z) points along -X in the workpiece frame.
    let q = std::f64::consts::FRAC_PI_2;
    let head = family(1, Tilt::B, [0.0, 0.0, 100.0], [0.0, 0.0, 100.0]);
    let o = head
        .forward(&Axes {
            b: q,
            ..Axes::default()
        })
        .o;
    assert!((o - Vector3::x()).norm() < 1e-15, "{o:?}");
    // ... and the tip swings from below the pivot to the -X side of it: (−100, 0, 100).
    let p = head
        .forward(&Axes {
            b: q,
            ..Axes::default()
        })
        .p;
    assert!(
        (p - Vector3::new(-100.0, 0.0, 100.0)).norm() < 1e-12,
        "{p:?}"
    );
    let table = family(0, Tilt::B, [0.0; 3], [0.0; 3]);
    let o = table
        .forward(&Axes {
            b: q,
            ..Axes::default()
        })
        .o;
    assert!((o + Vector3::x()).norm() < 1e-15, "{o:?}");
    // C +90° on a head turns the tool's +X tilt to +Y; on a table, to −Y in the workpiece frame.
    let ht = family(2, Tilt::B, [0.0, 0.0, 100.0], [0.0; 3]);
    let o = ht
        .forward(&Axes {
            b: q,
            c: q,
            ..Axes::default()
        })
        .o;
    assert!((o + Vector3::y()).norm() < 1e-15, "{o:?}");
    let hh_o = head
        .forward(&Axes {
            b: q,
            c: q,
            ..Axes::default()
        })
        .o;
    assert!((hh_o - Vector3::y()).norm() < 1e-15, "{hh_o:?}");
}

// ---- round-trip figures ---------------------------------------------------------------------

#[test]
fn round_trip_figures() {
    // Fresh random machines, poses and joints every run (seed printed): the worst FK∘IK and
    // IK∘FK errors per family, printed for docs/kinematics.md and held to 1e-9.
    use rand::{RngExt, SeedableRng};
    let seed = common::fresh_seed("round_trip_figures");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    for kind in 0..3 {
        for tilt in [Tilt::A, Tilt::B] {
            let (mut fk_ik, mut ik_fk) = (0.0f64, 0.0f64);
            let mut name = String::new();
            for _ in 0..20 {
                let mut o3 = || [0; 3].map(|_| rng.random_range(-300.0..300.0));
                let (o1, o2) = (o3(), o3());
                let kin = family(kind, tilt, o1, o2);
                name = kin.family().to_string();
                let t = tilt_axis(&kin);
                for _ in 0..500 {
                    let b = if rng.random_bool(0.5) {
                        Branch::Plus
                    } else {
                        Branch::Minus
                    };
                    let tl = rng.random_range(0.01..(PI - 0.01));
                    let az = rng.random_range(-PI..PI);
                    let p = Vector3::new(
                        rng.random_range(-500.0..500.0),
                        rng.random_range(-500.0..500.0),
                        rng.random_range(-500.0..500.0),
                    );
                    let pose = Pose::new(
                        p,
                        Vector3::new(tl.sin() * az.cos(), tl.sin() * az.sin(), tl.cos()),
                    );
                    let c_prev = rng.random_range(-30.0..30.0);
                    let j = ok(kin.inverse(
                        &pose,
                        b,
                        &Axes {
                            c: c_prev,
                            ..Axes::default()
                        },
                    ));
                    let back = kin.forward(&j);
                    fk_ik = fk_ik.max((back.p - pose.p).norm());
                    let q = Axes {
                        x: p.x,
                        y: p.y,
                        z: p.z,
                        c: c_prev,
                        ..Axes::default()
                    }
                    .with(t, b.sign() * tl);
                    let again = ok(kin.inverse(
                        &kin.forward(&q),
                        b,
                        &Axes {
                            c: c_prev + 0.5,
                            ..Axes::default()
                        },
                    ));
                    let e = kin
                        .axes()
                        .iter()
                        .map(|a| (again[*a] - q[*a]).abs())
                        .fold(0.0, f64::max);
                    ik_fk = ik_fk.max(e);
                }
            }
            println!(
                "{name}: FK∘IK worst {fk_ik:.2e} mm, IK∘FK worst {ik_fk:.2e} (mm or rad), 10000 cases"
            );
            assert!(fk_ik < 1e-9 && ik_fk < 1e-9, "seed {seed}: {name}");
        }
    }
}
