//! Pose sequences (docs/kinematics.md, "Branch rule", "Singularity", "Unwinding"): a tool axis
//! passing through the C axis keeps C continuous (the tilt changes sign instead of C turning
//! half a turn); C is unwound within a limited travel; a chain follows its previous sample and
//! says clearly where it cannot.

use crate::common;

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use common::{five_axis_families, ok};
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{
    Axes, AxisLimits, AxisName, Branch, Error, Family, IkOptions, Kinematics, KinematicsParams,
    Pose, Tilt, Travel,
};

fn max_step(sol: &[Axes], axis: AxisName) -> f64 {
    sol.windows(2)
        .map(|w| (w[1][axis] - w[0][axis]).abs())
        .fold(0.0, f64::max)
}

/// The tool axis of every family swept along a straight line through the pole: tilt from
/// +0.3 rad through 0 (sample 100 exactly) to −0.3 rad at a fixed azimuth.
fn through_the_pole(kin: &Kinematics) -> Vec<Pose> {
    let t = kin.rotary_axes()[0].axis;
    (0..=200)
        .map(|k| {
            let tilt = 0.3 - 0.003 * k as f64;
            let j = Axes {
                x: 10.0,
                y: -5.0,
                z: 20.0,
                c: 0.8,
                ..Axes::default()
            }
            .with(t, tilt);
            kin.forward(&j)
        })
        .collect()
}

#[test]
fn through_the_singularity_c_stays_continuous() {
    for kin in five_axis_families() {
        let t = kin.rotary_axes()[0].axis;
        let poses = through_the_pole(&kin);
        let opts = IkOptions {
            branch: Some(Branch::Plus),
            start: Axes {
                c: 0.8,
                ..Axes::default()
            },
            ..IkOptions::default()
        };
        let sol = ok(kin.inverse_sequence(&poses, &opts));
        // The tilt runs continuously through zero; C does not move at all.
        assert!(
            max_step(&sol.axes, t) < 0.0031,
            "{}: tilt step {}",
            kin.family(),
            max_step(&sol.axes, t)
        );
        assert!(
            max_step(&sol.axes, AxisName::C) < 1e-9,
            "{}: C step {}",
            kin.family(),
            max_step(&sol.axes, AxisName::C)
        );
        assert_eq!(sol.branch_switches, vec![101], "{}", kin.family());
        assert_eq!(sol.singular_samples, 1);
        assert!(sol.flips.is_empty());
        assert!((sol.axes[200][t] + 0.3).abs() < 1e-9);
        for (p, j) in poses.iter().zip(&sol.axes) {
            let back = kin.forward(j);
            assert!((back.p - p.p).norm() < 1e-9 && (back.o - p.o).norm() < 1e-12);
        }
        // Keeping the branch: C turns half a turn in one sample, recorded as a flip.
        let keep = IkOptions {
            keep_branch: true,
            ..opts
        };
        let sol = ok(kin.inverse_sequence(&poses, &keep));
        assert!(sol.branch_switches.is_empty());
        assert_eq!(sol.flips, vec![101], "{}", kin.family());
        assert!((max_step(&sol.axes, AxisName::C) - PI).abs() < 1e-9);
        assert!(sol.axes.iter().all(|j| j[t] >= 0.0));
    }
}

#[test]
fn touching_the_pole_holds_c_and_keeps_the_branch() {
    // Tilt 0.3 → 0 → 0.3 at one azimuth: no switch, C held at the pole.
    for kin in five_axis_families() {
        let t = kin.rotary_axes()[0].axis;
        let poses: Vec<Pose> = (0..=100)
            .map(|k| {
                let tilt = 0.3 * ((k as f64 - 50.0) / 50.0).abs();
                kin.forward(
                    &Axes {
                        c: -2.0,
                        ..Axes::default()
                    }
                    .with(t, tilt),
                )
            })
            .collect();
        let opts = IkOptions {
            branch: Some(Branch::Plus),
            start: Axes {
                c: -2.0,
                ..Axes::default()
            },
            ..IkOptions::default()
        };
        let sol = ok(kin.inverse_sequence(&poses, &opts));
        assert!(
            sol.branch_switches.is_empty() && sol.flips.is_empty(),
            "{}",
            kin.family()
        );
        assert_eq!(sol.singular_samples, 1);
        assert!(sol.axes.iter().all(|j| (j.c + 2.0).abs() < 1e-9));
    }
}

#[test]
fn a_switch_that_leaves_the_tilt_travel_falls_back_to_the_fixed_branch() {
    // An A/C table with A in -120 .. 10°: the path crosses the pole into +25°. Switching would
    // need A = +25° (out of travel); keeping branch −1 turns C half a turn at the pole instead.
    let limits = AxisLimits {
        a: ok(Travel::new((-120f64).to_radians(), 10f64.to_radians())),
        ..AxisLimits::default()
    };
    let kin = ok(Kinematics::from_params(&KinematicsParams {
        family: Some(Family::TableTilting(Tilt::A)),
        tilt_offset_mm: Some([0.0, 0.0, -100.0]),
        limits,
        ..KinematicsParams::default()
    }));
    let poses: Vec<Pose> = (0..=100)
        .map(|k| {
            let tilt = (-50.0 + 0.75 * k as f64).to_radians();
            kin.forward(&Axes {
                a: tilt,
                c: 1.0,
                ..Axes::default()
            })
        })
        .collect();
    let sol = ok(kin.inverse_sequence(
        &poses,
        &IkOptions {
            branch: Some(Branch::Minus),
            start: Axes {
                c: 1.0,
                ..Axes::default()
            },
            ..IkOptions::default()
        },
    ));
    assert!(sol.branch_switches.is_empty());
    assert_eq!(sol.flips, vec![67]);
    assert!(sol.axes.iter().all(|j| j.a <= 1e-12));
    for (p, j) in poses.iter().zip(&sol.axes) {
        assert!((kin.forward(j).p - p.p).norm() < 1e-9);
    }
}

#[test]
fn c_unwinds_within_its_travel() {
    // A head-head gantry with C limited to ±200° (a cable-wrapped head): the tool axis, tilted
    // 30°, circles twice. C runs continuously until it would pass +200°, then the solution a
    // turn back is taken (an unwinding move), never leaving the travel.
    let limits = AxisLimits {
        c: ok(Travel::new((-200f64).to_radians(), 200f64.to_radians())),
        ..AxisLimits::default()
    };
    let kin = ok(Kinematics::from_params(&KinematicsParams {
        family: Some(Family::HeadHead(Tilt::A)),
        pivot_length_mm: Some(250.0),
        limits,
        ..KinematicsParams::default()
    }));
    let n = 720;
    let poses: Vec<Pose> = (0..n)
        .map(|k| {
            let c = TAU * (k as f64 + 0.5) / 360.0;
            kin.forward(&Axes {
                x: 5.0,
                a: 30f64.to_radians(),
                c,
                ..Axes::default()
            })
        })
        .collect();
    let sol = ok(kin.inverse_sequence(
        &poses,
        &IkOptions {
            branch: Some(Branch::Plus),
            ..IkOptions::default()
        },
    ));
    let cs: Vec<f64> = sol.axes.iter().map(|j| j.c.to_degrees()).collect();
    assert!(cs.iter().all(|c| (-200.0..=200.0).contains(c)), "{cs:?}");
    // Two unwinds: at 200.5° (→ −159.5°) and again one turn later.
    assert_eq!(sol.unwinds, vec![200, 560]);
    assert!((cs[200] + 159.5).abs() < 1e-9, "{}", cs[200]);
    assert!(sol.flips.is_empty(), "an unwinding move is not a flip");
    for (p, j) in poses.iter().zip(&sol.axes) {
        let back = kin.forward(j);
        assert!((back.p - p.p).norm() < 1e-9 && (back.o - p.o).norm() < 1e-12);
    }
    // Without the travel check C simply keeps turning.
    let free = ok(kin.inverse_sequence(
        &poses,
        &IkOptions {
            branch: Some(Branch::Plus),
            check_travel: false,
            ..IkOptions::default()
        },
    ));
    assert!(free.unwinds.is_empty());
    assert!((free.axes[n - 1].c.to_degrees() - 719.5).abs() < 1e-9);
    // A single pose's C is unwound within the travel too.
    // (300.5° is nearest to 190° but beyond 200°: −59.5°.)
    let j = ok(kin.inverse(
        &poses[300],
        Branch::Plus,
        &Axes {
            c: 190f64.to_radians(),
            ..Axes::default()
        },
    ));
    assert!(
        (j.c.to_degrees() + 59.5).abs() < 1e-9,
        "{}",
        j.c.to_degrees()
    );
}

#[test]
fn c_with_no_turn_inside_its_travel_is_an_error() {
    let limits = AxisLimits {
        c: ok(Travel::new(-FRAC_PI_2, FRAC_PI_2)),
        ..AxisLimits::default()
    };
    let kin = ok(Kinematics::from_params(&KinematicsParams {
        family: Some(Family::HeadTable(Tilt::B)),
        pivot_length_mm: Some(150.0),
        limits,
        ..KinematicsParams::default()
    }));
    // Branch +1 needs C = 180°, outside ±90°; branch −1 needs C = 0.
    let pose = Pose::new(Vector3::zeros(), Vector3::new(-0.5, 0.0, 0.75f64.sqrt()));
    match kin.inverse(&pose, Branch::Plus, &Axes::default()) {
        Err(Error::OutOfTravel {
            axis: AxisName::C, ..
        }) => {}
        other => panic!("{other:?}"),
    }
    let j = ok(kin.inverse(&pose, Branch::Minus, &Axes::default()));
    assert!(j.c.abs() < 1e-12 && j.b < 0.0);
    // Automatic branch choice over a sequence finds branch −1.
    let sol = ok(kin.inverse_sequence(&[pose], &IkOptions::default()));
    assert_eq!(sol.branch, Branch::Minus);
}

// ---- a chain with no closed form ----------------------------------------------------------

fn nutating() -> Kinematics {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/machines/nutating-head.urdf"
    );
    ok(Kinematics::from_urdf_file(path))
}

#[test]
fn a_chain_follows_the_previous_sample() {
    // The 45° nutating head over a C table: no closed form, the chain's damped least squares
    // solve each sample from the previous one.
    let kin = nutating();
    assert_eq!(kin.family(), Family::Chain);
    let n = 400;
    // A tool axis tilting from 10° to 80° while circling.
    let poses: Vec<Pose> = (0..n)
        .map(|k| {
            let s = k as f64 / n as f64;
            let tilt = (10.0 + 70.0 * s).to_radians();
            let az = 3.0 * TAU * s;
            Pose::new(
                Vector3::new(40.0 * az.cos(), 30.0 * az.sin(), 10.0 * s),
                Vector3::new(tilt.sin() * az.cos(), tilt.sin() * az.sin(), tilt.cos()),
            )
        })
        .collect();
    // A seed near the first sample's solution: B = 2 asin(sin(10°)/sin(90°)·…) ≈ 20°.
    let start = Axes {
        b: 0.2,
        c: 0.0,
        ..Axes::default()
    };
    let sol = ok(kin.inverse_sequence(
        &poses,
        &IkOptions {
            branch: Some(Branch::Plus),
            start,
            ..IkOptions::default()
        },
    ));
    let mut worst = (0.0f64, 0.0f64);
    for (p, j) in poses.iter().zip(&sol.axes) {
        let back = kin.forward(j);
        worst = (
            worst.0.max((back.p - p.p).norm()),
            worst.1.max((back.o - p.o).norm()),
        );
    }
    assert!(worst.0 < 1e-9 && worst.1 < 1e-12, "{worst:?}");
    // Continuous: no rotary step beyond what the path asks for.
    assert!(max_step(&sol.axes, AxisName::B) < 0.1 && max_step(&sol.axes, AxisName::C) < 0.2);
}

#[test]
fn an_orientation_a_chain_cannot_reach_is_a_clear_error() {
    // A 45° head reaches tilts of 0 .. 90° from vertical; 120° is out of reach.
    let kin = nutating();
    let t = 120f64.to_radians();
    let pose = Pose::new(Vector3::zeros(), Vector3::new(t.sin(), 0.0, t.cos()));
    match kin.inverse(
        &pose,
        Branch::Plus,
        &Axes {
            b: 1.0,
            ..Axes::default()
        },
    ) {
        Err(e @ Error::NoConvergence { .. }) => {
            let text = e.to_string();
            assert!(
                text.contains("did not converge") && text.contains("cannot reach"),
                "{text}"
            );
        }
        other => panic!("{other:?}"),
    }
    // Sequences name the sample.
    let ok_pose = Pose::new(Vector3::zeros(), Vector3::z());
    match kin.inverse_sequence(
        &[ok_pose, pose],
        &IkOptions {
            branch: Some(Branch::Plus),
            ..IkOptions::default()
        },
    ) {
        Err(e) => assert!(e.to_string().contains("at sample 1"), "{e}"),
        Ok(s) => panic!("{s:?}"),
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]

    /// FK∘IK = id on the chain with no closed form, from a seed near the solution: the damped
    /// least squares land on the joints the pose came from.
    #[test]
    fn chain_fk_of_ik_is_identity(
        x in -200.0..200.0f64, y in -200.0..200.0f64, z in -150.0..150.0f64,
        b in 0.2..3.0f64, c in -10.0..10.0f64,
        db in -0.1..0.1f64, dc in -0.1..0.1f64,
    ) {
        let kin = nutating();
        let q = Axes { x, y, z, b, c, ..Axes::default() };
        let pose = kin.forward(&q);
        let j = ok(kin.inverse(&pose, Branch::Plus, &Axes { b: b + db, c: c + dc, ..Axes::default() }));
        let back = kin.forward(&j);
        proptest::prop_assert!((back.p - pose.p).norm() < 1e-9 && (back.o - pose.o).norm() < 1e-12);
        for axis in kin.axes() {
            proptest::prop_assert!((j[axis] - q[axis]).abs() < 1e-9, "{axis}: {} vs {}", j[axis], q[axis]);
        }
    }
}
