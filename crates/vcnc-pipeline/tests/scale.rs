//! Long runs in bounded memory (docs/performance.md): what a prediction keeps is bit-identical
//! to what the whole-run path computes, and to itself for any thread count.
//!
//! Truth: the full-trace path — every drive channel simulated and kept
//! ([`simulate::simulate_true`]), every pose of the actual paths and the contour errors with
//! their foot points ([`predict::contour`], [`predict::model_contour`]) and the trajectory as
//! the interpolator returns it ([`vcnc_gcode::load`]) — on the embedded
//! spiral and on a generated 5-axis TCP program with inverse-time feeds
//! ([`programs::long_tcp_program`], 150 000 samples).

use vcnc_drive::DriveModel;
use vcnc_machine::{Machine, embedded};
use vcnc_pipeline::predict::{self, Prediction};
use vcnc_pipeline::{programs, run, simulate};

fn machine() -> Machine {
    Machine::embedded_nmv5000().expect("embedded machine")
}

fn models(machine: &Machine) -> Vec<DriveModel> {
    machine
        .axes
        .iter()
        .map(|a| DriveModel::from(a.true_model()))
        .collect()
}

fn programs() -> Vec<(&'static str, String)> {
    vec![
        ("spiral.ngc", embedded::SPIRAL_NGC.to_string()),
        (
            "long.ngc",
            programs::long_tcp_program(3_000, 0.5, 0.05, 428).expect("generated program"),
        ),
    ]
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool")
        .install(f)
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Everything a prediction's outputs are made of, as bits.
fn fingerprint(p: &Prediction) -> Vec<Vec<u64>> {
    let mut f = Vec::new();
    for t in &p.true_traces {
        f.push(bits(&t.true_position));
    }
    for x in &p.predicted {
        f.push(bits(x));
    }
    for c in [&p.true_contour, &p.predicted_contour] {
        f.push(bits(&c.tip_mm));
        f.push(bits(&c.orientation_rad));
        f.push(bits(&[
            c.tip_max_mm,
            c.tip_rms_mm,
            c.orientation_max_rad,
            c.orientation_rms_rad,
        ]));
    }
    f
}

#[test]
fn prediction_equals_the_full_trace_path_bit_for_bit() {
    let machine = machine();
    let models = models(&machine);
    for (name, src) in programs() {
        let run = run::prepare(&machine, &src, name, false).expect("prepared");
        // The references are the interpolator's own samples, moved, not recomputed (A and C
        // are not touched by the TCP inverse kinematics).
        let loaded = vcnc_gcode::load(
            &src,
            &machine.interp_options(false),
            &machine.limits(),
            &machine.interpolate_options(),
        )
        .expect("loaded");
        for a in run.axes.iter().filter(|a| a.name.is_rotary()) {
            let t = loaded.trajectory.axis(a.name).expect("track");
            assert_eq!(bits(&a.pos), bits(&t.pos), "{name}: axis {}", a.name);
            assert_eq!(bits(&a.acc), bits(&t.acc), "{name}: axis {}", a.name);
        }
        let p = predict::predict(&machine, &run, &models).expect("prediction");
        let full = simulate::simulate_true(&machine, &run).expect("full traces");
        for (kept, all) in p.true_traces.iter().zip(&full) {
            assert_eq!(
                bits(&kept.true_position),
                bits(&all.true_position),
                "{name}"
            );
            assert_eq!(kept.saturated_ticks, all.saturated_ticks, "{name}");
        }
        let pos: Vec<&[f64]> = full.iter().map(|t| t.true_position.as_slice()).collect();
        let (poses, report) = predict::contour(&machine, &run, &pos).expect("contour");
        assert_eq!(
            report.foot.len(),
            run.len(),
            "{name}: the full path keeps its feet"
        );
        assert!(
            p.true_contour.foot.is_empty(),
            "{name}: a prediction does not"
        );
        assert_eq!(bits(&report.tip_mm), bits(&p.true_contour.tip_mm), "{name}");
        assert_eq!(
            bits(&report.orientation_rad),
            bits(&p.true_contour.orientation_rad),
            "{name}"
        );
        let n = run.len();
        assert_eq!(
            poses,
            predict::poses_at(&machine, &p.true_positions(), 0..n).expect("poses"),
            "{name}"
        );
        // The poses a table computes a chunk at a time are the whole run's.
        let mut chunked = Vec::new();
        for start in (0..n).step_by(65_536) {
            let rows = start..(start + 65_536).min(n);
            chunked.extend(predict::poses_at(&machine, &pos, rows).expect("chunk"));
        }
        assert_eq!(poses, chunked, "{name}");
        // The command's path: the reference rates dropped as each axis is simulated, the
        // tracking errors computed in the predicted positions' memory.
        let mut lean_run = run.clone();
        let lean = predict::predict_releasing_rates(&machine, &mut lean_run, &models, &[])
            .expect("lean prediction");
        assert_eq!(fingerprint(&lean), fingerprint(&p), "{name}");
        assert!(
            lean_run
                .axes
                .iter()
                .all(|a| a.vel.is_empty() && a.acc.is_empty() && a.pos.len() == n),
            "{name}: rates released, positions kept"
        );
        let tracking = p.tracking(&machine, &run);
        let in_place = lean.into_tracking(&machine, &lean_run);
        assert_eq!(tracking.len(), in_place.len(), "{name}");
        for (a, b) in tracking.iter().zip(&in_place) {
            assert_eq!(bits(&a.error), bits(&b.error), "{name}: axis {}", a.axis);
            let m = |t: &vcnc_pipeline::AxisTracking| bits(t.model_error.as_deref().unwrap_or(&[]));
            assert_eq!(m(a), m(b), "{name}: axis {}", a.axis);
            assert_eq!(
                bits(&[a.tracking_max, a.tracking_rms]),
                bits(&[b.tracking_max, b.tracking_rms]),
                "{name}: axis {}",
                a.axis
            );
            assert_eq!(
                a.model_vs_true_max.map(f64::to_bits),
                b.model_vs_true_max.map(f64::to_bits)
            );
            assert_eq!(
                a.model_vs_true_rms.map(f64::to_bits),
                b.model_vs_true_rms.map(f64::to_bits)
            );
        }
        // The reference poses computed a chunk at a time are the whole run's.
        let whole = run.reference_poses(&machine).expect("reference poses");
        assert_eq!(whole.len(), n, "{name}");
        assert_eq!(
            whole[n / 3..n / 2],
            run.reference_poses_at(&machine, n / 3..n / 2)
                .expect("chunk")[..],
            "{name}"
        );
        let m = predict::model_contour(&machine, &run, &models, &[]).expect("models");
        assert_eq!(m.positions, p.predicted, "{name}");
        assert_eq!(m.contour.foot.len(), n, "{name}");
        assert_eq!(
            bits(&m.contour.tip_mm),
            bits(&p.predicted_contour.tip_mm),
            "{name}"
        );
    }
}

#[test]
fn prediction_is_bit_identical_on_one_and_two_threads() {
    let machine = machine();
    let models = models(&machine);
    for (name, src) in programs() {
        let run = run::prepare(&machine, &src, name, false).expect("prepared");
        let one = in_pool(1, || {
            predict::predict(&machine, &run, &models).expect("1 thread")
        });
        let two = in_pool(2, || {
            predict::predict(&machine, &run, &models).expect("2 threads")
        });
        assert_eq!(fingerprint(&one), fingerprint(&two), "{name}");
        let lean = |threads| {
            in_pool(threads, || {
                let mut run = run.clone();
                predict::predict_releasing_rates(&machine, &mut run, &models, &[]).expect("lean")
            })
        };
        assert_eq!(fingerprint(&lean(1)), fingerprint(&one), "{name}");
        assert_eq!(fingerprint(&lean(2)), fingerprint(&one), "{name}");
    }
}

/// The streamed reference (`stream::plan_file` + `ReferenceStream::run`, what `vcnc interpolate`
/// writes) against the whole-program path (`run::prepare`): every machine axis' position,
/// velocity and acceleration after the inverse kinematics, the tool tips, and the summary, bit
/// for bit; with pieces of source and of samples that cut blocks and chains anywhere.
#[test]
fn the_streamed_reference_equals_the_whole_program_path_bit_for_bit() {
    use vcnc_pipeline::run::InterpolateSummary;
    use vcnc_pipeline::stream;
    let machine = machine();
    let dir = tempfile::tempdir().expect("temporary folder");
    // With O-word control flow: a subroutine called from nested loops, a condition.
    let oword = "\
G21 G90 G64 P0.01
G0 X0 Y0 Z0
o<pocket> sub
  G1 X[#1] Y[#2] F2400
  G1 X[#1 + #3] C[#4]
  G1 Y[#2 + #3]
  o1 if [#4 GT 40]
    G1 Z-2 F600
  o1 else
    G1 Z-1 F600
  o1 endif
  G1 X[#1] Y[#2]
o<pocket> endsub
#10 = 0
o2 while [#10 LT 12]
  o3 repeat [2]
    o<pocket> call [#10 * 3] [#10 * 2] [5] [#10 * 8]
  o3 endrepeat
  #10 = [#10 + 1]
o2 endwhile
G0 Z10
M2
"
    .to_string();
    for (name, src) in programs().into_iter().chain([("oword.ngc", oword)]) {
        let path = dir.path().join(name);
        std::fs::write(&path, &src).expect("program written");
        let whole = run::prepare(&machine, &src, &path.display().to_string(), false)
            .expect("prepared whole");
        for so in [
            vcnc_gcode::StreamOptions {
                chunk_bytes: 500,
                chunk_samples: 999,
            },
            vcnc_gcode::StreamOptions::default(),
        ] {
            let s = stream::plan_file(&machine, &path, false, &so).expect("planned");
            assert_eq!(s.len(), whole.len(), "{name}: samples");
            let n_axes = machine.axes.len();
            let mut got: Vec<[Vec<f64>; 3]> = vec![Default::default(); n_axes];
            let mut tips: [Vec<f64>; 3] = Default::default();
            let stats = s
                .run(&machine, &path, &mut |c| {
                    for (i, g) in got.iter_mut().enumerate() {
                        g[0].extend_from_slice(&c.pos[i]);
                        g[1].extend_from_slice(&c.vel[i]);
                        g[2].extend_from_slice(&c.acc[i]);
                    }
                    if let Some(t) = &c.tip {
                        for (tip, part) in tips.iter_mut().zip(t) {
                            tip.extend_from_slice(part);
                        }
                    }
                    Ok(())
                })
                .expect("streamed");
            for (a, g) in whole.axes.iter().zip(&got) {
                assert_eq!(bits(&g[0]), bits(&a.pos), "{name}: {} position", a.name);
                assert_eq!(bits(&g[1]), bits(&a.vel), "{name}: {} velocity", a.name);
                assert_eq!(bits(&g[2]), bits(&a.acc), "{name}: {} acceleration", a.name);
            }
            // Tool tips are streamed for TCP programs only.
            assert_eq!(s.plan.any_tcp, whole.has_tcp(), "{name}: TCP");
            let poses = whole.reference_poses(&machine).expect("poses");
            for (j, tip) in tips.iter().enumerate() {
                let want: Vec<f64> = match s.plan.any_tcp {
                    true => poses.iter().map(|q| q.p[j]).collect(),
                    false => Vec::new(),
                };
                assert_eq!(bits(tip), bits(&want), "{name}: tip {j}");
            }
            assert_eq!(
                s.summary(&machine, &stats),
                InterpolateSummary::of(&machine, &whole),
                "{name}: summary"
            );
        }
    }
}

/// A program that leaves an axis' travel is refused while streaming, naming the line, as the
/// whole-program path refuses it.
#[test]
fn a_streamed_program_beyond_travel_is_refused_with_its_line() {
    use vcnc_pipeline::stream;
    let machine = machine();
    let dir = tempfile::tempdir().expect("temporary folder");
    let path = dir.path().join("far.ngc");
    let src = "G21 G90 G64\nG1 X10 F3000\nG1 X400\nG1 X0\nM2\n";
    std::fs::write(&path, src).expect("program written");
    let whole = run::prepare(&machine, src, &path.display().to_string(), false).unwrap_err();
    let s = stream::plan_file(&machine, &path, false, &Default::default()).expect("planned");
    let e = s.run(&machine, &path, &mut |_| Ok(())).unwrap_err();
    assert_eq!(e.to_string(), whole.to_string());
    assert!(e.to_string().contains(":3:"), "{e}");
}
