//! Held-out machines (docs/kinematics.md, "Fitting offsets"): LinuxCNC's own functions computed
//! tool tips of one machine per module whose offsets the test does not know; vcnc fits them from
//! the 'fit' rows ([`Kinematics::fit_offsets`]), predicts the 'check' rows, and only then reads
//! the answers (tests/data/linuxcnc/heldout-answers.csv). A second test draws fresh machines
//! every run (seed printed) from transcriptions of the same functions.

use crate::common;

use common::{col, fresh_seed, ok, read_vectors};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{
    Axes, AxisLimits, HeadHead, HeadTable, Kinematics, OffsetFit, Pose, TableTilting, Tilt,
};

/// A family with zero offsets: the template the fit fills in.
fn template(module: &str) -> Kinematics {
    let l = AxisLimits::default();
    let z = Vector3::zeros();
    match module {
        "xyzac-trt" => Kinematics::TableTilting(ok(TableTilting::new(Tilt::A, z, z, l))),
        "xyzbc-trt" => Kinematics::TableTilting(ok(TableTilting::new(Tilt::B, z, z, l))),
        "5axiskins" => Kinematics::HeadHead(ok(HeadHead::new(Tilt::B, z, z, l))),
        _ => Kinematics::HeadTable(ok(HeadTable::new(Tilt::B, z, z, l))),
    }
}

/// The samples of a held-out file, mapped to vcnc's conventions (conventional directions off):
/// (set, joints, pose).
fn samples(module: &str) -> Vec<(f64, Axes, Pose)> {
    let (h, rows) = read_vectors(&format!("heldout-{module}.csv"));
    rows.iter()
        .map(|row| {
            let g = |n: &str| col(&h, row, n);
            let (t_name, t_sign, c_sign, tilt) = match module {
                "xyzac-trt" => ("ja", 1.0, 1.0, vcnc_kinematics::AxisName::A),
                "xyzbc-trt" => ("jb", 1.0, 1.0, vcnc_kinematics::AxisName::B),
                "5axiskins" => ("jb", -1.0, 1.0, vcnc_kinematics::AxisName::B),
                _ => ("jb", -1.0, -1.0, vcnc_kinematics::AxisName::B),
            };
            let j = Axes {
                x: g("jx"),
                y: g("jy"),
                z: g("jz"),
                c: c_sign * g("jc").to_radians(),
                ..Axes::default()
            }
            .with(tilt, t_sign * g(t_name).to_radians());
            let o = if module == "maxkins" {
                // maxkins gives the tool axis in the machine frame; the workpiece frame is the
                // machine frame turned by −c about Z.
                let (s, c) = (-j.c).sin_cos();
                let (mx, my) = (g("mx"), g("my"));
                Vector3::new(c * mx - s * my, s * mx + c * my, g("mz"))
            } else {
                Vector3::new(g("ox"), g("oy"), g("oz"))
            };
            (
                g("set"),
                j,
                Pose::new(Vector3::new(g("px"), g("py"), g("pz")), o),
            )
        })
        .collect()
}

fn fit_and_check(module: &str, kin_template: &Kinematics, data: &[(f64, Axes, Pose)]) -> OffsetFit {
    let fit_rows: Vec<(Axes, Pose)> = data
        .iter()
        .filter(|r| r.0 == 0.0)
        .map(|r| (r.1, r.2))
        .collect();
    let fit = ok(kin_template.fit_offsets(&fit_rows));
    assert!(
        fit.max_mm < 1e-9,
        "{module}: fit residual {} mm",
        fit.max_mm
    );
    assert!(
        fit.max_axis < 1e-9,
        "{module}: tool-axis residual {}",
        fit.max_axis
    );
    let mut worst = 0.0f64;
    for (_, j, pose) in data.iter().filter(|r| r.0 == 1.0) {
        let p = fit.kinematics.forward(j);
        worst = worst.max((p.p - pose.p).norm());
        assert!((p.o - pose.o).norm() < 1e-9, "{module}: tool axis");
    }
    assert!(
        worst < 1e-9,
        "{module}: held-out prediction error {worst} mm"
    );
    println!(
        "{module}: {} fit rows, rank {}, held-out prediction error {worst:.3e} mm",
        fit_rows.len(),
        fit.rank
    );
    fit
}

fn answers() -> Vec<(String, Vec<f64>)> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/linuxcnc/heldout-answers.csv"
    );
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    text.lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let mut it = l.split(',');
            let name = it.next().unwrap_or_default().to_string();
            (name, it.map(|x| x.parse().unwrap_or(f64::NAN)).collect())
        })
        .collect()
}

#[test]
fn offsets_fitted_from_linuxcnc_samples_predict_held_out_ones() {
    let mut fits = Vec::new();
    for module in ["xyzac-trt", "xyzbc-trt", "5axiskins", "maxkins"] {
        let data = samples(module);
        assert_eq!(data.len(), 48);
        fits.push((module, fit_and_check(module, &template(module), &data)));
    }
    // Only now: the parameters LinuxCNC was given. The identifiable ones must come back.
    let ans = answers();
    let close = |a: f64, b: f64, what: &str| {
        assert!((a - b).abs() < 1e-6, "{what}: fitted {a}, LinuxCNC {b}")
    };
    for (module, fit) in &fits {
        let p = &ans
            .iter()
            .find(|(n, _)| n == module)
            .unwrap_or_else(|| panic!("{module}"))
            .1;
        match &fit.kinematics {
            Kinematics::TableTilting(m) => {
                // LinuxCNC: r = rot point, d = (x-offset, y-offset, z-offset + tool-offset).
                // Determined: the C axis (r_x, r_y) and the tilt axis (r + d across it); the
                // canonical form has r_z = 0 and d along the tilt axis = 0.
                let (r, d) = ([p[0], p[1], p[2]], [p[3], p[4], p[5] + p[6]]);
                close(m.r.x, r[0], "r x");
                close(m.r.y, r[1], "r y");
                assert_eq!(m.r.z, 0.0);
                let along = if m.tilt == Tilt::A { 0 } else { 1 };
                for i in 0..3 {
                    if i == along {
                        assert_eq!(m.d[i], 0.0);
                    } else {
                        close(m.r[i] + m.d[i], r[i] + d[i], "tilt axis");
                    }
                }
                assert_eq!(fit.rank, 4);
            }
            Kinematics::HeadHead(m) => {
                // pivot (0, ·, L), C-axis point (0, 0, ·): y of the pivot and z of the C point
                // are pinned.
                close(m.pivot.x, 0.0, "pivot x");
                close(m.pivot.z, p[0], "pivot length");
                close(m.c_axis.x, 0.0, "C x");
                close(m.c_axis.y, 0.0, "C y");
                assert_eq!(fit.rank, 4);
            }
            Kinematics::HeadTable(m) => {
                close(m.pivot.x, 0.0, "pivot x");
                close(m.pivot.z, p[0], "pivot length");
                close(m.r.x, 0.0, "r x");
                close(m.r.y, 0.0, "r y");
                assert_eq!(fit.rank, 4);
            }
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn offsets_of_fresh_machines_are_recovered() {
    // Fresh machines every run: random offsets, random joints, tips from LinuxCNC's formulas
    // (transcribed in tests/linuxcnc.rs and here for xyzac-trt and maxkins' inverse).
    let seed = fresh_seed("offsets_of_fresh_machines_are_recovered");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..8 {
        let r = Vector3::new(
            rng.random_range(-200.0..200.0),
            rng.random_range(-200.0..200.0),
            rng.random_range(-200.0..200.0),
        );
        let (dy, dz) = (
            rng.random_range(-150.0..150.0),
            rng.random_range(-300.0..300.0),
        );
        let l = rng.random_range(50.0..400.0);
        // xyzac-trt forward (trtfuncs.c, conventional directions off).
        let trt = |j: [f64; 5]| {
            let (a, c) = (j[3].to_radians(), j[4].to_radians());
            let (sa, ca, sc, cc) = (a.sin(), a.cos(), c.sin(), c.cos());
            let (qx, qy, qz) = (j[0] - r.x, j[1] - dy - r.y, j[2] - dz - r.z);
            Vector3::new(
                cc * qx + sc * ca * qy + sc * sa * qz + sc * dy + r.x,
                -sc * qx + cc * ca * qy + cc * sa * qz + cc * dy + r.y,
                -sa * qy + ca * qz + dz + r.z,
            )
        };
        // maxkins inverse (conventional directions off): the joints for a tip, B and C.
        let maxinv = |p: Vector3<f64>, b: f64, c: f64| {
            let (zb, xb) = (l * b.to_radians().cos(), l * b.to_radians().sin());
            let th = p.y.atan2(p.x) - c.to_radians();
            let xyr = p.x.hypot(p.y);
            Vector3::new(xyr * th.cos() - xb, xyr * th.sin(), p.z + zb - l)
        };
        let mut ac = Vec::new();
        let mut ht = Vec::new();
        for _ in 0..40 {
            let j = [
                rng.random_range(-400.0..400.0),
                rng.random_range(-300.0..300.0),
                rng.random_range(-300.0..300.0),
                rng.random_range(-120.0..120.0),
                rng.random_range(-720.0..720.0),
            ];
            let q = Axes {
                x: j[0],
                y: j[1],
                z: j[2],
                a: j[3].to_radians(),
                c: j[4].to_radians(),
                ..Axes::default()
            };
            ac.push((q, Pose::new(trt(j), Vector3::z())));
            let p = Vector3::new(j[1], j[2], j[0] * 0.5);
            let m = maxinv(p, j[3], j[4]);
            let q = Axes {
                x: m.x,
                y: m.y,
                z: m.z,
                b: -j[3].to_radians(),
                c: -j[4].to_radians(),
                ..Axes::default()
            };
            ht.push((q, Pose::new(p, Vector3::z())));
        }
        let check = |kin: &Kinematics, rows: &[(Axes, Pose)]| {
            let fit = ok(kin.fit_offsets(&rows[..20]));
            for (q, pose) in &rows[20..] {
                let e = (fit.kinematics.forward(q).p - pose.p).norm();
                assert!(
                    e < 1e-9,
                    "seed {seed}: {} held-out error {e} mm",
                    kin.family()
                );
            }
            fit.kinematics
        };
        match check(&template("xyzac-trt"), &ac) {
            Kinematics::TableTilting(m) => {
                let (fitted, truth) = (m.r + m.d, r + Vector3::new(0.0, dy, dz));
                assert!((m.r.xy() - r.xy()).norm() < 1e-6, "seed {seed}: {m:?}");
                assert!(
                    (fitted.yz() - truth.yz()).norm() < 1e-6,
                    "seed {seed}: {m:?}"
                );
            }
            other => panic!("{other:?}"),
        }
        match check(&template("maxkins"), &ht) {
            Kinematics::HeadTable(m) => assert!((m.pivot.z - l).abs() < 1e-6, "seed {seed}: {m:?}"),
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn fitting_needs_samples_and_a_family_with_offsets() {
    let t = template("xyzac-trt");
    assert!(t.fit_offsets(&[]).is_err());
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/machines/nutating-head.urdf"
    );
    let chain = ok(Kinematics::from_urdf_file(path));
    let e = chain.fit_offsets(&[(Axes::default(), Pose::default()); 5]);
    assert!(e.is_err_and(|e| e.to_string().contains("URDF")));
}
