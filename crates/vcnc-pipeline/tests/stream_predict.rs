//! The streamed prediction (`vcnc predict --stream`, docs/performance.md) against the
//! whole-run prediction, bit for bit.
//!
//! Truth: [`predict::predict_releasing_rates`] over the whole run — the true drives (in SIMD
//! lanes where they share a loop), the models, the latency shift and the windowed contour
//! search over the whole reference path — and [`predict::ContourSummary::of`] for the
//! statistics. Programs: the embedded spiral and a generated 5-axis TCP program with
//! inverse-time feeds ([`programs::long_tcp_program`]), streamed in pieces of 1 000 and 4 099
//! samples (the default 65 536 is longer than the spiral), on the ideal and on the realistic
//! NMV5000 (compliance, friction, backlash, current loop, noise, dead time, reference
//! shaping), with models of the true drives and with models that have a dead time, a
//! reference filter and a stated actual-value latency.

use std::path::{Path, PathBuf};

use vcnc_drive::{DriveModel, ReferenceFilter};
use vcnc_gcode::StreamOptions;
use vcnc_machine::{Machine, embedded};
use vcnc_pipeline::predict::{self, ContourSummary, Prediction};
use vcnc_pipeline::run::{self, Measured};
use vcnc_pipeline::stream::plan_file;
use vcnc_pipeline::stream_predict::{PredictPiece, StreamedPrediction, predict_streamed};
use vcnc_pipeline::{Run, programs};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Models of the true drives, or (`rich`) the same with a dead time of 0.4 samples, a
/// first-order reference filter and an extra pole where the model allows them.
fn models(machine: &Machine, rich: bool) -> Vec<DriveModel> {
    machine
        .axes
        .iter()
        .map(|a| {
            let mut m = DriveModel::from(a.true_model());
            if rich {
                m.delay_s = 0.4e-3;
                m.reference_filter = Some(ReferenceFilter::FirstOrder { tau_s: 0.7e-3 });
                m.extra_pole_hz = Some(400.0);
            }
            m
        })
        .collect()
}

/// The streamed prediction, its pieces concatenated.
fn streamed(
    machine: &Machine,
    path: &Path,
    models: &[DriveModel],
    latency: &[f64],
    which: Measured,
    chunk_samples: usize,
) -> (StreamedPrediction, PredictPiece) {
    let opts = StreamOptions {
        chunk_samples,
        ..StreamOptions::default()
    };
    let stream = plan_file(machine, path, false, &opts).expect("planned");
    let mut all = PredictPiece::default();
    let mut next = 0;
    let p = predict_streamed(machine, &stream, path, models, latency, which, &mut |p| {
        assert_eq!(p.first, next, "pieces in order, none missing");
        next += p.len();
        all.lines.extend(&p.lines);
        all.classes.extend(&p.classes);
        all.reference.resize_with(p.reference.len(), Vec::new);
        all.truth.resize_with(p.truth.len(), Vec::new);
        all.predicted.resize_with(p.predicted.len(), Vec::new);
        for i in 0..p.reference.len() {
            all.reference[i].extend(&p.reference[i]);
            all.truth[i].extend(&p.truth[i]);
            all.predicted[i].extend(&p.predicted[i]);
        }
        all.reference_poses.extend(&p.reference_poses);
        all.true_poses.extend(&p.true_poses);
        all.predicted_poses.extend(&p.predicted_poses);
        all.true_tip_mm.extend(&p.true_tip_mm);
        all.predicted_tip_mm.extend(&p.predicted_tip_mm);
        all.true_orientation_rad.extend(&p.true_orientation_rad);
        all.predicted_orientation_rad
            .extend(&p.predicted_orientation_rad);
        Ok(())
    })
    .expect("streamed prediction");
    (p, all)
}

fn assert_same(
    name: &str,
    machine: &Machine,
    run: &Run,
    whole: &Prediction,
    which: Measured,
    (s, p): &(StreamedPrediction, PredictPiece),
) {
    let n = run.len();
    assert_eq!(p.len(), n, "{name}: samples");
    assert_eq!(p.lines, run.lines, "{name}: lines");
    assert_eq!(p.classes, run.classes, "{name}: classes");
    for (i, a) in run.axes.iter().enumerate() {
        assert_eq!(
            bits(&p.reference[i]),
            bits(&a.pos),
            "{name}: {} reference",
            a.name
        );
        assert_eq!(
            bits(&p.truth[i]),
            bits(&whole.true_traces[i].true_position),
            "{name}: {} true drive",
            a.name
        );
        assert_eq!(
            bits(&p.predicted[i]),
            bits(&whole.predicted[i]),
            "{name}: {} model",
            a.name
        );
    }
    let (t, q) = (&whole.true_contour, &whole.predicted_contour);
    assert_eq!(bits(&p.true_tip_mm), bits(&t.tip_mm), "{name}: true tip");
    assert_eq!(
        bits(&p.predicted_tip_mm),
        bits(&q.tip_mm),
        "{name}: model tip"
    );
    assert_eq!(
        bits(&p.true_orientation_rad),
        bits(&t.orientation_rad),
        "{name}: true orientation"
    );
    assert_eq!(
        bits(&p.predicted_orientation_rad),
        bits(&q.orientation_rad),
        "{name}: model orientation"
    );
    let poses = |x: Vec<&[f64]>| predict::poses_at(machine, &x, 0..n).expect("poses");
    for (got, want) in [
        (&p.reference_poses, poses(run.reference_positions())),
        (&p.true_poses, poses(whole.true_positions())),
        (&p.predicted_poses, poses(whole.predicted_positions())),
    ] {
        assert!(
            got.iter()
                .zip(&want)
                .all(|(a, b)| a.p.iter().chain(&a.o).map(|x| x.to_bits()).eq(b
                    .p
                    .iter()
                    .chain(&b.o)
                    .map(|x| x.to_bits()))),
            "{name}: poses"
        );
    }
    let summary = ContourSummary::of(whole, run, which);
    assert_eq!(s.summary, summary, "{name}: summary");
    assert_eq!(
        s.figures,
        whole.figures(&run.measured(which)),
        "{name}: figures"
    );
    assert!(
        summary.contour_um["true_max"] > 1.0,
        "{name}: a run with contour errors"
    );
}

fn check(machine: &Machine, label: &str, rich: bool, latency: &[f64], chunks: &[usize]) {
    let dir = tempfile::tempdir().expect("temporary folder");
    let long = programs::long_tcp_program(600, 0.5, 0.05, 428).expect("generated program");
    for (name, src) in [("spiral.ngc", embedded::SPIRAL_NGC), ("long.ngc", &long)] {
        let path = dir.path().join(name);
        std::fs::write(&path, src).expect("program written");
        let models = models(machine, rich);
        let mut run = run::prepare_file(machine, &path, false).expect("prepared");
        let which = if name == "long.ngc" {
            Measured::All
        } else {
            Measured::Feed
        };
        let whole =
            predict::predict_releasing_rates(machine, &mut run, &models, latency).expect("whole");
        for &chunk in chunks {
            let s = streamed(machine, &path, &models, latency, which, chunk);
            assert_same(
                &format!("{label} {name}, pieces of {chunk}"),
                machine,
                &run,
                &whole,
                which,
                &s,
            );
        }
    }
}

#[test]
fn streamed_prediction_equals_the_whole_run_on_the_ideal_machine() {
    let machine = Machine::embedded_nmv5000().expect("embedded machine");
    check(&machine, "ideal", false, &[], &[1000, 4099]);
    // Models with a dead time and a reference filter, and a stated latency on three axes
    // (whole and fractional samples).
    check(
        &machine,
        "ideal, rich models",
        true,
        &[1e-4, 0.0, 2e-3, 0.0, 3.5e-4],
        &[4099],
    );
}

#[test]
fn streamed_prediction_equals_the_whole_run_on_the_realistic_machine() {
    let machine =
        Machine::load(&repo("machines/nmv5000-realistic.toml")).expect("realistic machine");
    check(
        &machine,
        "realistic",
        false,
        &[1e-4, 1e-4, 1e-4, 1e-4, 1e-4],
        &[1000, 65_536],
    );
}

#[test]
fn streamed_prediction_is_the_same_on_one_and_two_threads() {
    let machine = Machine::embedded_nmv5000().expect("embedded machine");
    let dir = tempfile::tempdir().expect("temporary folder");
    let path = dir.path().join("spiral.ngc");
    std::fs::write(&path, embedded::SPIRAL_NGC).expect("program written");
    let models = models(&machine, true);
    let latency = [1e-4; 5];
    let run_on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool")
            .install(|| streamed(&machine, &path, &models, &latency, Measured::Feed, 3000))
    };
    let (a, pa) = run_on(1);
    let (b, pb) = run_on(2);
    assert_eq!(a.summary, b.summary);
    assert_eq!(bits(&pa.true_tip_mm), bits(&pb.true_tip_mm));
    assert_eq!(bits(&pa.predicted_tip_mm), bits(&pb.predicted_tip_mm));
    assert_eq!(
        bits(&pa.predicted_orientation_rad),
        bits(&pb.predicted_orientation_rad)
    );
}

#[test]
fn streamed_simulation_equals_the_whole_run() {
    // Truth: simulate::simulate (true drives in SIMD lanes where they share a loop, every
    // channel) and simulate::tracking over the whole run.
    use vcnc_pipeline::simulate;
    use vcnc_pipeline::stream_simulate::simulate_streamed;
    let dir = tempfile::tempdir().expect("temporary folder");
    let path = dir.path().join("spiral.ngc");
    std::fs::write(&path, embedded::SPIRAL_NGC).expect("program written");
    for machine in [
        Machine::embedded_nmv5000().expect("embedded machine"),
        Machine::load(&repo("machines/nmv5000-realistic.toml")).expect("realistic machine"),
    ] {
        let models = models(&machine, true);
        let run = run::prepare_file(&machine, &path, false).expect("prepared");
        for with_models in [false, true] {
            let m = with_models.then_some(models.as_slice());
            let whole = simulate::simulate(&machine, &run, m).expect("whole");
            let tracking = simulate::tracking(&machine, &run, &whole);
            let opts = StreamOptions {
                chunk_samples: 777,
                ..StreamOptions::default()
            };
            let stream = plan_file(&machine, &path, false, &opts).expect("planned");
            let axes = machine.axes.len();
            let mut channels: Vec<[Vec<f64>; 6]> = (0..axes).map(|_| Default::default()).collect();
            let mut predicted: Vec<Vec<f64>> = vec![Vec::new(); axes];
            let s = simulate_streamed(&machine, &stream, &path, m, &mut |p| {
                for (i, t) in p.traces.iter().enumerate() {
                    for (c, v) in channels[i].iter_mut().zip(t.channels()) {
                        c.extend(v);
                    }
                    if let Some(x) = &p.predicted {
                        predicted[i].extend(&x[i]);
                    }
                }
                Ok(())
            })
            .expect("streamed");
            for (i, t) in whole.traces.iter().enumerate() {
                for ((c, v), name) in channels[i]
                    .iter()
                    .zip(t.channels())
                    .zip(vcnc_drive::DriveTrace::CHANNELS)
                {
                    assert_eq!(bits(c), bits(v), "{}: axis {i}, {name}", machine.name);
                }
                if let Some(p) = &whole.predicted {
                    assert_eq!(
                        bits(&predicted[i]),
                        bits(&p[i]),
                        "{}: model {i}",
                        machine.name
                    );
                }
                let f = &s.tracking[i];
                let w = &tracking[i];
                assert_eq!(f.tracking, (w.tracking_max, w.tracking_rms));
                assert_eq!(
                    f.model_vs_true,
                    w.model_vs_true_max.zip(w.model_vs_true_rms)
                );
            }
            assert_eq!(s.samples, run.len());
        }
    }
}
