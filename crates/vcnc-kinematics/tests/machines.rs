//! The sample machines of tests/data/machines (one per family, values typical of their class
//! and marked in each file as assumed or cited): each reads as its family, with its travels,
//! and round-trips a 5-axis path through the sequence inverse and the TCP inverse.

use crate::common;

use std::f64::consts::TAU;

use common::ok;
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{
    Axes, AxisName, Family, IkOptions, JointMotion, Kinematics, PointMotion, Pose, Tilt,
};

fn machine(name: &str) -> Kinematics {
    let path = format!(
        "{}/tests/data/machines/{name}.urdf",
        env!("CARGO_MANIFEST_DIR")
    );
    ok(Kinematics::from_urdf_file(path))
}

#[test]
fn each_sample_machine_reads_as_its_family() {
    let cases = [
        ("vmc-3axis", Family::Xyz),
        ("dmu-bc-trunnion", Family::TableTilting(Tilt::B)),
        ("gantry-head-head", Family::HeadHead(Tilt::A)),
        ("head-table", Family::HeadTable(Tilt::B)),
        ("nutating-head", Family::Chain),
        (
            "../../../../../machines/nmv5000",
            Family::TableTilting(Tilt::A),
        ),
    ];
    for (name, family) in cases {
        let kin = machine(name);
        assert_eq!(kin.family(), family, "{name}");
    }
    // Offsets and travels come from the files.
    match machine("dmu-bc-trunnion") {
        Kinematics::TableTilting(m) => {
            assert_eq!(
                (m.r, m.d),
                (Vector3::zeros(), Vector3::new(0.0, 0.0, -150.0))
            );
            assert!((m.limits.b.upper.to_degrees() - 110.0).abs() < 1e-9);
        }
        other => panic!("{other:?}"),
    }
    match machine("gantry-head-head") {
        Kinematics::HeadHead(m) => {
            assert_eq!(
                (m.pivot, m.c_axis),
                (Vector3::new(0.0, 0.0, 250.0), Vector3::new(0.0, 0.0, 250.0))
            );
            assert!((m.limits.c.upper.to_degrees() - 200.0).abs() < 1e-9);
        }
        other => panic!("{other:?}"),
    }
    match machine("head-table") {
        Kinematics::HeadTable(m) => assert_eq!(
            (m.pivot, m.r),
            (Vector3::new(0.0, 0.0, 180.0), Vector3::zeros())
        ),
        other => panic!("{other:?}"),
    }
    // The VMC's table moves in X and Y, yet the tool tip in the workpiece frame is (X, Y, Z).
    let vmc = machine("vmc-3axis");
    let p = vmc.forward(&Axes {
        x: 100.0,
        y: -50.0,
        z: -20.0,
        ..Axes::default()
    });
    assert_eq!(
        (p.p, p.o),
        (Vector3::new(100.0, -50.0, -20.0), Vector3::z())
    );
    assert!((vmc.limits().x.upper - 381.0).abs() < 1e-12);
}

#[test]
fn each_sample_machine_round_trips_a_five_axis_path() {
    for name in [
        "dmu-bc-trunnion",
        "gantry-head-head",
        "head-table",
        "nutating-head",
    ] {
        let kin = machine(name);
        let tilt = kin.rotary_axes()[0].axis;
        // A spiral-like path: the tip on a dome, the tool tilted 15° .. 35°, turning twice.
        let n = 600;
        let poses: Vec<Pose> = (0..n)
            .map(|k| {
                let s = k as f64 / n as f64;
                let th = 2.0 * TAU * s;
                let t = (15.0 + 20.0 * s).to_radians();
                Pose::new(
                    Vector3::new(30.0 * th.cos(), 20.0 * th.sin(), 10.0 + 5.0 * s),
                    Vector3::new(t.sin() * th.cos(), t.sin() * th.sin(), t.cos()),
                )
            })
            .collect();
        let start = if name == "nutating-head" {
            Axes {
                b: 0.5,
                ..Axes::default()
            }
        } else {
            Axes::default()
        };
        let sol = ok(kin.inverse_sequence(
            &poses,
            &IkOptions {
                start,
                ..IkOptions::default()
            },
        ));
        let mut worst = 0.0f64;
        for (p, j) in poses.iter().zip(&sol.axes) {
            let back = kin.forward(j);
            worst = worst.max((back.p - p.p).norm()).max((back.o - p.o).norm());
            ok(kin.check_travel(j, None));
            // The TCP inverse of the same tip and rotary axes gives the same slides.
            let rot = JointMotion {
                pos: *j,
                ..JointMotion::default()
            };
            let tip = PointMotion {
                p: p.p,
                ..PointMotion::default()
            };
            let m = ok(kin.inverse_tcp_motion(&tip, &rot));
            worst = worst.max((m.pos.pm() - j.pm()).norm());
        }
        assert!(worst < 1e-9, "{name}: {worst}");
        assert!(
            sol.flips.is_empty() && sol.branch_switches.is_empty(),
            "{name}: {sol:?}"
        );
        // Continuous, except where C unwinds within its travel (the gantry's C has ±200°).
        let steps = |axis: AxisName| {
            sol.axes
                .windows(2)
                .enumerate()
                .filter(|(k, _)| !sol.unwinds.contains(&(k + 1)))
                .map(|(_, w)| (w[1][axis] - w[0][axis]).abs())
                .fold(0.0, f64::max)
        };
        assert!(steps(tilt) < 0.05 && steps(AxisName::C) < 0.1, "{name}");
        assert_eq!(
            sol.unwinds.is_empty(),
            name != "gantry-head-head",
            "{name}: {:?}",
            sol.unwinds
        );
    }
}
