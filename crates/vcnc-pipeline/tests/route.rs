//! The one route of a run (`source` → drives and models → contour searches → sink) against an
//! independent whole-run computation, bit for bit, whatever the source and its pieces.
//!
//! Truth: the whole-array functions of the stage crates, called directly on the prepared
//! program's references — [`vcnc_drive::Drive::simulate`] (every channel) for the true drives,
//! [`vcnc_drive::DriveModel::stream`] fed the whole reference and [`latency::shifted`] for the
//! models, the machine's
//! forward kinematics sample by sample, [`vcnc_contour::contour_errors`] (the windowed search
//! over the whole reference path, not the streamed one) for the contour errors, max and RMS
//! over the masked arrays and [`predict::worst_blocks`] for the statistics. The route runs the
//! same stages as streams fed a piece at a time; the pieces here cut blocks, chains and the
//! latency look-ahead anywhere (source read 500 bytes at a time, 999 and 4 099 samples a
//! piece), from the program streamed and from the program prepared whole.
//!
//! Programs: the embedded spiral, a generated 5-axis TCP program with inverse-time feeds
//! ([`programs::long_tcp_program`]) and an O-word program; machines: the ideal NMV5000 with
//! the true drives' models and with models that have a dead time, a reference filter, an extra
//! pole and a stated latency, and the realistic NMV5000 (compliance, friction, backlash,
//! current loop, noise, dead time, reference shaping).

use crate::common;

use std::path::{Path, PathBuf};

use vcnc_drive::SimOptions;
use vcnc_machine::{Machine, MachineModels, embedded};
use vcnc_pipeline::predict::{self, PredictOptions};
use vcnc_pipeline::run::{self, Run};
use vcnc_pipeline::simulate::{self, SimulatePiece};
use vcnc_pipeline::sink::FnSink;
use vcnc_pipeline::source::{self, Program};
use vcnc_pipeline::stats::{max_abs, rms};
use vcnc_pipeline::{
    Measured, PredictionRecord, ReferenceStream, Source, StreamOptions, latency, programs,
};

use common::{OWORD, models};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn programs() -> Vec<(&'static str, String)> {
    vec![
        ("spiral.ngc", embedded::SPIRAL_NGC.to_string()),
        (
            "long.ngc",
            programs::long_tcp_program(600, 0.5, 0.05, 428).expect("generated program"),
        ),
        ("oword.ngc", OWORD.to_string()),
    ]
}

/// The program streamed from its file in pieces of `opts`.
fn planned(machine: &Machine, path: &Path, opts: &StreamOptions) -> ReferenceStream {
    source::plan_pieces(machine, Program::File(path.to_path_buf()), false, opts).expect("planned")
}

/// The piece sizes every case runs with (source bytes, samples).
fn piece_options() -> [StreamOptions; 2] {
    [
        StreamOptions {
            chunk_bytes: 500,
            chunk_samples: 999,
        },
        StreamOptions {
            chunk_samples: 4099,
            ..StreamOptions::default()
        },
    ]
}

/// The whole-run oracle of a prediction (module documentation): per actual sequence (true
/// machine, then each model set) the positions per axis and the tool-tip and orientation
/// errors.
struct Oracle {
    positions: Vec<Vec<Vec<f64>>>,
    tip_mm: Vec<Vec<f64>>,
    orientation_rad: Vec<Vec<f64>>,
}

fn oracle(machine: &Machine, run: &Run, sets: &[&MachineModels]) -> Oracle {
    let ts = run.ts;
    let truth: Vec<Vec<f64>> = machine
        .axes
        .iter()
        .zip(&run.axes)
        .map(|(a, s)| {
            a.drive()
                .expect("a virtual drive")
                .simulate(s.reference(), ts)
                .expect("true drive")
                .true_position
        })
        .collect();
    let mut positions = vec![truth];
    for set in sets {
        positions.push(
            set.models()
                .iter()
                .zip(&run.axes)
                .map(|(m, s)| {
                    // The model's stream fed the whole reference at once: the route cuts it
                    // into pieces. (`DriveModel::simulate` of a model with no dead time, filter
                    // or extra pole is the core's own recursion, equal only up to rounding.)
                    let mut stream = m.stream(ts, &SimOptions::default()).expect("model");
                    let mut x = Vec::new();
                    stream.feed(s.reference(), &mut x).expect("model");
                    stream.finish().expect("model");
                    latency::shifted(&x, m.actual_latency_s, ts)
                })
                .collect(),
        );
    }
    let kin = machine.require_kinematics().expect("kinematics");
    let poses = |pos: &[Vec<f64>]| {
        let cols: Vec<&[f64]> = pos.iter().map(Vec::as_slice).collect();
        (0..run.len())
            .map(|k| kin.pose_at(&cols, k))
            .collect::<Vec<_>>()
    };
    let reference: Vec<Vec<f64>> = run.axes.iter().map(|a| a.pos.clone()).collect();
    let reference = poses(&reference);
    let mut tip_mm = Vec::new();
    let mut orientation_rad = Vec::new();
    for p in &positions {
        let r = vcnc_contour::contour_errors(&reference, &poses(p)).expect("contour");
        tip_mm.push(r.tip_mm);
        orientation_rad.push(r.orientation_rad);
    }
    Oracle {
        positions,
        tip_mm,
        orientation_rad,
    }
}

/// The prediction's pieces kept, checked to come in order with none missing.
fn predicted(
    machine: &Machine,
    source: Source<'_>,
    sets: &[&MachineModels],
    which: Measured,
) -> (vcnc_pipeline::PredictOutcome, PredictionRecord) {
    let mut record = PredictionRecord::default();
    let mut next = 0;
    let mut poses_ok = true;
    let kin = machine.require_kinematics().expect("kinematics");
    let mut check = FnSink(|p: &vcnc_pipeline::PredictPiece| {
        assert_eq!(p.first, next, "pieces in order, none missing");
        next += p.len();
        // The pieces' poses are the forward kinematics of their positions.
        let pos: Vec<&[f64]> = p.truth.positions.iter().map(Vec::as_slice).collect();
        poses_ok &= (0..p.len()).all(|k| kin.pose_at(&pos, k) == p.truth.poses[k]);
        Ok(())
    });
    let opts = PredictOptions {
        measured: which,
        tracking: false,
    };
    let outcome = predict::predict(machine, source, sets, &opts, &mut (&mut record, &mut check))
        .expect("prediction");
    assert!(poses_ok, "poses");
    (outcome, record)
}

fn masked(v: &[f64], mask: &[bool]) -> Vec<f64> {
    v.iter()
        .zip(mask)
        .filter_map(|(x, m)| m.then_some(*x))
        .collect()
}

fn check_prediction(machine: &Machine, label: &str, sets: &[&MachineModels]) {
    let dir = tempfile::tempdir().expect("temporary folder");
    for (name, src) in programs() {
        let path = dir.path().join(name);
        std::fs::write(&path, &src).expect("program written");
        let run = run::prepare_file(machine, &path, false).expect("prepared");
        let which = if name == "long.ngc" {
            Measured::All
        } else {
            Measured::Feed
        };
        let o = oracle(machine, &run, sets);
        let mask = run.measured(which);
        let plans: Vec<ReferenceStream> = piece_options()
            .iter()
            .map(|opts| planned(machine, &path, opts))
            .collect();
        let sources = plans
            .iter()
            .map(Source::Streamed)
            .chain([Source::Prepared(&run)]);
        for (c, source) in sources.enumerate() {
            let case = format!("{label} {name}, source {c}");
            let (outcome, r) = predicted(machine, source, sets, which);
            assert_eq!(r.len(), run.len(), "{case}: samples");
            assert_eq!(r.lines, run.lines, "{case}: lines");
            assert_eq!(r.classes, run.classes, "{case}: classes");
            let actual = std::iter::once(&r.truth).chain(&r.models);
            for (j, a) in actual.enumerate() {
                for (i, axis) in machine.axes.iter().enumerate() {
                    assert_eq!(
                        bits(&a.positions[i]),
                        bits(&o.positions[j][i]),
                        "{case}: sequence {j}, axis {}",
                        axis.name
                    );
                }
                assert_eq!(bits(&a.tip_mm), bits(&o.tip_mm[j]), "{case}: tip {j}");
                assert_eq!(
                    bits(&a.orientation_rad),
                    bits(&o.orientation_rad[j]),
                    "{case}: orientation {j}"
                );
            }
            for (s, (summary, f)) in outcome.summaries.iter().zip(&outcome.figures).enumerate() {
                let (t, m) = (&o.tip_mm[0], &o.tip_mm[s + 1]);
                let d: Vec<f64> = t.iter().zip(m).map(|(a, b)| (a - b).abs()).collect();
                assert_eq!(
                    f.true_max.tip_um,
                    max_abs(&masked(t, &mask)) * 1e3,
                    "{case}"
                );
                assert_eq!(f.true_rms.tip_um, rms(&masked(t, &mask)) * 1e3, "{case}");
                assert_eq!(
                    f.predicted_max.tip_um,
                    max_abs(&masked(m, &mask)) * 1e3,
                    "{case}"
                );
                assert_eq!(
                    f.discrepancy_rms.tip_um,
                    rms(&masked(&d, &mask)) * 1e3,
                    "{case}"
                );
                assert_eq!(
                    summary.measured_samples,
                    mask.iter().filter(|m| **m).count(),
                    "{case}"
                );
                let ranked: Vec<_> = summary
                    .worst_blocks
                    .iter()
                    .map(|b| predict::WorstBlock {
                        cause: None,
                        ..b.clone()
                    })
                    .collect();
                assert!(summary.worst_blocks.iter().all(|b| b.cause.is_some()));
                assert_eq!(
                    ranked,
                    predict::worst_blocks(&run.lines, t, &o.orientation_rad[0], &mask, 10),
                    "{case}: worst blocks"
                );
            }
            assert!(
                outcome.truth.0.tip_um > 1.0 || name == "oword.ngc",
                "{case}: a run with contour errors"
            );
        }
    }
}

#[test]
fn prediction_equals_an_independent_whole_run_on_the_ideal_machine() {
    let machine = Machine::embedded_nmv5000().expect("embedded machine");
    let (plain, rich) = (models(&machine, false), models(&machine, true));
    check_prediction(&machine, "ideal", &[&plain, &rich]);
}

#[test]
fn prediction_equals_an_independent_whole_run_on_the_realistic_machine() {
    let machine =
        Machine::load(&repo("machines/nmv5000-realistic.toml")).expect("realistic machine");
    check_prediction(&machine, "realistic", &[&models(&machine, true)]);
}

#[test]
fn simulation_equals_an_independent_whole_run() {
    // Truth: Drive::simulate (every channel) and DriveModel::simulate over the whole run; the
    // tracking figures as max and RMS of the whole arrays.
    let dir = tempfile::tempdir().expect("temporary folder");
    let path = dir.path().join("spiral.ngc");
    std::fs::write(&path, embedded::SPIRAL_NGC).expect("program written");
    for machine in [
        Machine::embedded_nmv5000().expect("embedded machine"),
        Machine::load(&repo("machines/nmv5000-realistic.toml")).expect("realistic machine"),
    ] {
        let models = models(&machine, true);
        let run = run::prepare_file(&machine, &path, false).expect("prepared");
        let plan = planned(
            &machine,
            &path,
            &StreamOptions {
                chunk_samples: 777,
                ..StreamOptions::default()
            },
        );
        for (with_models, source) in [
            (false, Source::Streamed(&plan)),
            (true, Source::Streamed(&plan)),
            (true, Source::Prepared(&run)),
        ] {
            let m = with_models.then_some(&models);
            let axes = machine.axes.len();
            let mut channels: Vec<[Vec<f64>; 6]> = (0..axes).map(|_| Default::default()).collect();
            let mut predicted: Vec<Vec<f64>> = vec![Vec::new(); axes];
            let mut keep = FnSink(|p: &SimulatePiece| {
                for (i, t) in p.traces.iter().enumerate() {
                    for (c, v) in channels[i].iter_mut().zip(t.channels()) {
                        c.extend(v);
                    }
                    if let Some(x) = &p.predicted {
                        predicted[i].extend(&x[i]);
                    }
                }
                Ok(())
            });
            let s = simulate::simulate(&machine, source, m, &mut keep).expect("simulated");
            for (i, (axis, a)) in machine.axes.iter().zip(&run.axes).enumerate() {
                let whole = axis
                    .drive()
                    .expect("a virtual drive")
                    .simulate(a.reference(), run.ts)
                    .expect("drive");
                for ((c, v), name) in channels[i]
                    .iter()
                    .zip(whole.channels())
                    .zip(vcnc_drive::DriveTrace::CHANNELS)
                {
                    assert_eq!(bits(c), bits(v), "{}: axis {i}, {name}", machine.name);
                }
                assert_eq!(s.saturated_ticks[i], whole.saturated_ticks);
                let k = a.unit.micro_factor();
                let e: Vec<f64> = a
                    .pos
                    .iter()
                    .zip(&whole.position)
                    .map(|(r, x)| (r - x) * k)
                    .collect();
                assert_eq!(s.tracking[i].tracking, (max_abs(&e), rms(&e)));
                if with_models {
                    let x = models
                        .get(i)
                        .simulate(a.reference(), run.ts, &SimOptions::default())
                        .expect("model");
                    assert_eq!(bits(&predicted[i]), bits(&x), "{}: model {i}", machine.name);
                    let d: Vec<f64> = x
                        .iter()
                        .zip(&whole.position)
                        .map(|(m, x)| (m - x) * k)
                        .collect();
                    assert_eq!(s.tracking[i].model_vs_true, Some((max_abs(&d), rms(&d))));
                }
            }
        }
    }
}

#[test]
fn runs_are_bit_identical_on_one_and_two_threads() {
    let machine = Machine::embedded_nmv5000().expect("embedded machine");
    let models = models(&machine, true);
    let long = programs::long_tcp_program(3_000, 0.5, 0.05, 428).expect("generated program");
    for src in [embedded::SPIRAL_NGC, long.as_str()] {
        let run = run::prepare(&machine, src, "p.ngc", false).expect("prepared");
        let on = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("thread pool")
                .install(|| predicted(&machine, Source::Prepared(&run), &[&models], Measured::Feed))
        };
        let ((a, ra), (b, rb)) = (on(1), on(2));
        assert_eq!(a.summaries, b.summaries);
        for (x, y) in
            std::iter::once((&ra.truth, &rb.truth)).chain(ra.models.iter().zip(&rb.models))
        {
            assert_eq!(bits(&x.tip_mm), bits(&y.tip_mm));
            assert_eq!(bits(&x.orientation_rad), bits(&y.orientation_rad));
        }
    }
}

/// The streamed reference (what `vcnc interpolate` writes) against the whole-program path
/// (`run::prepare`): every machine axis' position, velocity and acceleration after the inverse
/// kinematics, the tool tips, and the summary's rates, bit for bit; with pieces of source and
/// of samples that cut blocks and chains anywhere. The rotary references are the
/// interpolator's own samples ([`vcnc_gcode::load`]), moved, not recomputed.
#[test]
fn the_streamed_reference_equals_the_whole_program_path_bit_for_bit() {
    let machine = Machine::embedded_nmv5000().expect("embedded machine");
    let dir = tempfile::tempdir().expect("temporary folder");
    for (name, src) in programs() {
        let path = dir.path().join(name);
        std::fs::write(&path, &src).expect("program written");
        let whole = run::prepare(&machine, &src, &path.display().to_string(), false)
            .expect("prepared whole");
        let loaded = vcnc_gcode::load(
            &src,
            &machine.interp_options(false),
            &machine.limits(),
            &machine.interpolate_options(),
        )
        .expect("loaded");
        for a in whole.axes.iter().filter(|a| a.name.is_rotary()) {
            let t = loaded.trajectory.axis(a.name).expect("track");
            assert_eq!(bits(&a.pos), bits(&t.pos), "{name}: axis {}", a.name);
            assert_eq!(bits(&a.acc), bits(&t.acc), "{name}: axis {}", a.name);
        }
        for opts in piece_options() {
            let s = planned(&machine, &path, &opts);
            assert_eq!(s.len(), whole.len(), "{name}: samples");
            let n_axes = machine.axes.len();
            let mut got: Vec<[Vec<f64>; 3]> = vec![Default::default(); n_axes];
            let mut tips: [Vec<f64>; 3] = Default::default();
            let mut keep = FnSink(|c: &vcnc_pipeline::ReferenceChunk| {
                for (i, g) in got.iter_mut().enumerate() {
                    g[0].extend_from_slice(&c.pos[i]);
                    g[1].extend_from_slice(&c.vel[i]);
                    g[2].extend_from_slice(&c.acc[i]);
                }
                let t = vcnc_pipeline::interpolate::tool_tips(&machine, c)?;
                for (tip, part) in tips.iter_mut().zip(t) {
                    tip.extend(part);
                }
                Ok(())
            });
            let outcome =
                vcnc_pipeline::interpolate::interpolate(&machine, Source::Streamed(&s), &mut keep)
                    .expect("streamed");
            for (a, g) in whole.axes.iter().zip(&got) {
                assert_eq!(bits(&g[0]), bits(&a.pos), "{name}: {} position", a.name);
                assert_eq!(bits(&g[1]), bits(&a.vel), "{name}: {} velocity", a.name);
                assert_eq!(bits(&g[2]), bits(&a.acc), "{name}: {} acceleration", a.name);
            }
            let poses = whole.reference_poses(&machine).expect("poses");
            for (j, tip) in tips.iter().enumerate() {
                let want: Vec<f64> = poses.iter().map(|q| q.p[j]).collect();
                assert_eq!(bits(tip), bits(&want), "{name}: tip {j}");
            }
            assert_eq!(s.plan.any_tcp, whole.has_tcp(), "{name}: TCP");
            for a in &whole.axes {
                let r = &outcome.summary.axes[a.name.as_str()];
                assert_eq!(r.max_vel, max_abs(&a.vel), "{name}: {}", a.name);
                assert_eq!(r.max_acc, max_abs(&a.acc), "{name}: {}", a.name);
            }
            assert_eq!(outcome.summary.samples, whole.len());
            assert_eq!(outcome.summary.warnings, whole.warnings, "{name}: warnings");
        }
    }
}

/// A program that leaves an axis' travel is refused while streaming, naming the line, as the
/// whole-program path refuses it.
#[test]
fn a_streamed_program_beyond_travel_is_refused_with_its_line() {
    let machine = Machine::embedded_nmv5000().expect("embedded machine");
    let dir = tempfile::tempdir().expect("temporary folder");
    let path = dir.path().join("far.ngc");
    let src = "G21 G90 G64\nG1 X10 F3000\nG1 X400\nG1 X0\nM2\n";
    std::fs::write(&path, src).expect("program written");
    let whole = run::prepare(&machine, src, &path.display().to_string(), false).unwrap_err();
    let s = planned(&machine, &path, &StreamOptions::default());
    let e = vcnc_pipeline::interpolate::interpolate(
        &machine,
        Source::Streamed(&s),
        &mut vcnc_pipeline::sink::Discard,
    )
    .unwrap_err();
    assert_eq!(e.to_string(), whole.to_string());
    assert!(e.to_string().contains(":3:"), "{e}");
}
