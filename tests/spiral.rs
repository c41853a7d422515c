//! The 5-axis spiral (docs/contour.md) on the NMV5000 with the true drives and with the
//! identified models: the regression test of the whole pipeline (issue 5).

use std::sync::OnceLock;

use vcnc_drive::AxisName;
use vcnc_machine::{Machine, embedded};
use vcnc_pipeline::predict::{self, PredictOptions};
use vcnc_pipeline::run::Measured;
use vcnc_pipeline::{
    AxisIdentification, PredictOutcome, PredictionRecord, Run, Source, identify, run,
};

struct Fixture {
    machine: Machine,
    run: Run,
    ids: Vec<AxisIdentification>,
    /// The true machine, then the refined models, then the paper's.
    record: PredictionRecord,
    outcome: PredictOutcome,
}

impl Fixture {
    /// |model set `set` − true machine| per sample: tool tip (mm) and orientation (rad).
    fn discrepancy(&self, set: usize) -> (Vec<f64>, Vec<f64>) {
        let (t, m) = (&self.record.truth, &self.record.models[set]);
        let d = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).abs()).collect();
        (
            d(&t.tip_mm, &m.tip_mm),
            d(&t.orientation_rad, &m.orientation_rad),
        )
    }
}

/// Identify the five axes and predict the spiral once for every test in this file.
fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let machine = Machine::embedded_nmv5000().expect("embedded machine");
        let run =
            run::prepare(&machine, embedded::SPIRAL_NGC, "spiral.ngc", false).expect("spiral");
        let axes: Vec<_> = machine.axes.iter().collect();
        let ids = identify::identify_axes(&machine, &axes, None).expect("identification");
        let refined = identify::machine_models(&machine, &ids, "identified")
            .expect("models")
            .with_latencies(ids.iter().map(|_| 0.0));
        let paper = identify::paper_models(&machine, &ids).expect("paper models");
        let mut record = PredictionRecord::default();
        let outcome = predict::predict(
            &machine,
            Source::Prepared(&run),
            &[&refined, &paper],
            &PredictOptions::default(),
            &mut record,
        )
        .expect("prediction");
        Fixture {
            machine,
            run,
            ids,
            record,
            outcome,
        }
    })
}

fn max(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(*x))
}

#[test]
fn spiral_matches_spec_geometry_and_duration() {
    // Truth: docs/contour.md (≈ 755 mm at 75 mm/s and 1500 mm/s² ≈ 10.1 s; axis spans X −36…36,
    // Y −25…58, Z 22…61 mm, A −36.9…−11.5°, peak rates 127, 110, 28 mm/s, 4.6 and 212 °/s).
    // The spiral's feed moves (the program opens with a rapid from the machine's start).
    let f = fixture();
    let feed = f.run.measured(Measured::Feed);
    let d = feed.iter().filter(|m| **m).count() as f64 * f.run.ts;
    assert!((d - 10.12).abs() < 0.02, "duration {d} s");
    let span = |c: AxisName| {
        let a = f.run.axes.iter().find(|a| a.name == c).unwrap();
        let on = |v: &[f64]| -> Vec<f64> {
            v.iter()
                .zip(&feed)
                .filter_map(|(x, m)| m.then_some(*x))
                .collect()
        };
        let (pos, vel) = (on(&a.pos), on(&a.vel));
        let lo = pos.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = pos.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let v = vel.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        (lo, hi, v)
    };
    let (xl, xh, xv) = span(AxisName::X);
    let (yl, yh, yv) = span(AxisName::Y);
    let (zl, zh, zv) = span(AxisName::Z);
    let (al, ah, av) = span(AxisName::A);
    let (_, _, cv) = span(AxisName::C);
    for (got, want, tol) in [
        (xl, -36.0, 0.5),
        (xh, 36.0, 0.5),
        (yl, -25.0, 0.5),
        (yh, 58.0, 0.6),
        (zl, 22.0, 0.5),
        (zh, 61.0, 0.5),
        (al, -36.9, 0.1),
        (ah, -11.5, 0.1),
        (xv, 127.0, 1.0),
        (yv, 110.0, 1.0),
        (zv, 28.0, 0.5),
        (av, 4.6, 0.1),
        (cv, 212.0, 1.0),
    ] {
        assert!(
            (got - want).abs() <= tol,
            "got {got}, docs/contour.md says {want}"
        );
    }
    let c = f.run.axes.iter().find(|a| a.name == AxisName::C).unwrap();
    // From the end of the opening rapid (the sample before the first feed sample).
    let first = feed.iter().position(|m| *m).unwrap();
    let turns = (c.pos[c.pos.len() - 1] - c.pos[first - 1]).abs() / 360.0;
    assert!((turns - 3.0).abs() < 1e-6, "C turns {turns}");
}

#[test]
fn true_contour_error_is_the_published_scale() {
    // docs/contour.md / issue 5: with Table 3 drives the true contour error peaks near 450 µm
    // and 3.9 mrad.
    // Over the feed moves (the contour statistics' default).
    let f = fixture();
    let figures = f.outcome.figures[0];
    let tip = figures.true_max.tip_um;
    let ori = figures.true_max.orientation_mrad;
    assert!((tip - 450.0).abs() < 10.0, "true contour max {tip} µm");
    assert!((ori - 3.9).abs() < 0.1, "true orientation max {ori} mrad");
}

#[test]
fn identified_drives_predict_the_contour_error_within_a_micrometre() {
    // About twice the README's published discrepancies (identified 0.13 µm / 0.0004 mrad, the
    // paper's equation-error PSO alone 0.47 µm / 0.0044 mrad; issue 5 asked for 1 µm and
    // 0.01 mrad); this fixture measures 0.130 µm / 0.00057 mrad and 0.470 µm / 0.00439 mrad.
    // Truth: the true machine on the same run.
    let f = fixture();
    let ((dt, dor), (pt, por)) = (f.discrepancy(0), f.discrepancy(1));
    let d_tip = max(&dt) * 1e3;
    let d_ori = max(&dor) * 1e3;
    eprintln!("refined: tip discrepancy {d_tip:.4} µm, orientation {d_ori:.5} mrad");
    let p_tip = max(&pt) * 1e3;
    let p_ori = max(&por) * 1e3;
    eprintln!("paper PSO: tip discrepancy {p_tip:.4} µm, orientation {p_ori:.5} mrad");
    assert!(d_tip <= 0.26, "tool-tip discrepancy {d_tip} µm");
    assert!(d_ori <= 0.001, "orientation discrepancy {d_ori} mrad");
    assert!(p_tip <= 0.95, "paper PSO tool-tip discrepancy {p_tip} µm");
    assert!(
        p_ori <= 0.009,
        "paper PSO orientation discrepancy {p_ori} mrad"
    );
    assert!(
        d_tip < p_tip && d_ori < p_ori,
        "the refinement gains nothing"
    );
}

#[test]
fn identified_nmv5000_poles_are_within_tolerance() {
    // Every NMV5000 axis within about twice the README's published errors (p ≤ 0.06 %, ωn ≤
    // 0.46 %, ζ ≤ 1.5 %, dc ≤ 4.1 %; issue 4 asked for 2 %, 2 %, 5 %) of the analytic model of
    // the true drive (truth: `DriveParams` → closed-loop model, docs/drive-model.md).
    let f = fixture();
    for r in &f.ids {
        let truth = r.truth().unwrap();
        let t = truth.poles().unwrap();
        let p = r.result.identified.poles().expect("identified poles");
        let e = |a: f64, b: f64| (a - b).abs() / b;
        eprintln!(
            "{}: p {:+.2} %, wn {:+.2} %, zeta {:+.2} %, dc {:+.2} %",
            r.axis,
            100.0 * (p.p - t.p) / t.p,
            100.0 * (p.wn - t.wn) / t.wn,
            100.0 * (p.zeta - t.zeta) / t.zeta,
            100.0 * (r.result.identified.dc - truth.dc) / truth.dc
        );
        assert!(r.result.identified.is_stable(), "{}", r.axis);
        assert!(e(p.wn, t.wn) < 0.01, "{} wn {} vs {}", r.axis, p.wn, t.wn);
        assert!(e(p.p, t.p) < 0.0012, "{} p {} vs {}", r.axis, p.p, t.p);
        let dc = r.result.identified.dc;
        assert!(
            e(dc, truth.dc) < 0.07,
            "{} dc {} vs {}",
            r.axis,
            dc,
            truth.dc
        );
        assert!(
            e(p.zeta, t.zeta) < 0.03,
            "{} zeta {} vs {}",
            r.axis,
            p.zeta,
            t.zeta
        );
    }
}

#[test]
fn windowed_contour_error_equals_brute_force_on_every_spiral_sample() {
    // Truth: the O(N·M) brute-force foot-point search (issue 5).
    let f = fixture();
    let reference = f.run.reference_poses(&f.machine).unwrap();
    let kin = f.machine.require_kinematics().unwrap();
    let pos = f.record.truth.positions();
    let true_poses: Vec<_> = (0..f.run.len()).map(|k| kin.pose_at(&pos, k)).collect();
    let brute = vcnc_contour::contour_errors_brute_force(&reference, &true_poses).unwrap();
    assert_eq!(brute.tip_mm.len(), f.record.truth.tip_mm.len());
    for (k, (a, b)) in brute.tip_mm.iter().zip(&f.record.truth.tip_mm).enumerate() {
        assert_eq!(a, b, "tip error differs at sample {k}");
    }
    for (k, (a, b)) in brute
        .orientation_rad
        .iter()
        .zip(&f.record.truth.orientation_rad)
        .enumerate()
    {
        assert_eq!(a, b, "orientation error differs at sample {k}");
    }
}

#[test]
fn reference_poses_round_trip_the_programmed_tool_tip() {
    // FK(IK(programmed tip pose)) = programmed pose within 1e-9 mm at every TCP sample.
    let f = fixture();
    // The programmed tip, as the interpolator returns it (a prepared run moves the tracks into
    // its axis references, which the inverse kinematics then turns into machine axes).
    let loaded = vcnc_gcode::load(
        embedded::SPIRAL_NGC,
        &f.machine.interp_options(false),
        &f.machine.limits(),
        &f.machine.interpolate_options(),
    )
    .unwrap();
    let traj = &loaded.trajectory;
    let poses = f.run.reference_poses(&f.machine).unwrap();
    let (x, y, z) = (
        traj.axis(AxisName::X).unwrap(),
        traj.axis(AxisName::Y).unwrap(),
        traj.axis(AxisName::Z).unwrap(),
    );
    for (k, pose) in poses.iter().enumerate().take(traj.len()) {
        let d = ((pose.p.x - x.pos[k]).powi(2)
            + (pose.p.y - y.pos[k]).powi(2)
            + (pose.p.z - z.pos[k]).powi(2))
        .sqrt();
        assert!(d < 1e-9, "sample {k}: {d} mm");
    }
    assert!(f.machine.kinematics.is_some());
}
