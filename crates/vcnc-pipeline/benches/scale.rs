//! Long programs (issue 15, docs/performance.md): a generated 5-axis tool-centre-point program
//! of 1 000 000 samples at 1 ms (20 000 short segments, TCP on by `M428`, inverse-time feeds
//! `G93`; [`programs::long_tcp_program`]) prepared (parse, interpret, interpolate, inverse
//! kinematics, travel checks) and predicted (true drives and models, forward kinematics, the
//! reference path, both contour errors); and the G-code parser alone on about 100 MB of the
//! same kind of text.
//!
//! The same program is also predicted streamed (`predict_streamed`, as `vcnc predict` runs it
//! without its table, docs/performance.md).
//!
//! `cargo bench -p vcnc-pipeline --bench scale`

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use vcnc_drive::DriveModel;
use vcnc_machine::{Machine, MachineModels};
use vcnc_pipeline::predict::{self, PredictOptions};
use vcnc_pipeline::sink::Discard;
use vcnc_pipeline::source::{self, Program};
use vcnc_pipeline::{Source, programs, run};

fn long_program(c: &mut Criterion) {
    let Ok(machine) = Machine::embedded_nmv5000() else {
        return;
    };
    let Ok(src) = programs::long_tcp_program(20_000, 0.5, 0.05, 428) else {
        return;
    };
    let models: Vec<DriveModel> = machine
        .axes
        .iter()
        .map(|a| DriveModel::from(a.true_model()))
        .collect();
    let Ok(models) = MachineModels::new(&machine, models, "true drives") else {
        return;
    };
    let opts = PredictOptions::default();
    let mut group = c.benchmark_group("long_tcp_1M_samples");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(30));
    group.bench_function("prepare", |b| {
        b.iter(|| run::prepare(&machine, black_box(&src), "long.ngc", false))
    });
    let Ok(prepared) = run::prepare(&machine, &src, "long.ngc", false) else {
        return;
    };
    // The prediction of a prepared program (true drives and models, forward kinematics, both
    // contour searches, the statistics), its pieces kept by no sink.
    group.bench_function("predict", |b| {
        b.iter(|| {
            predict::predict(
                &machine,
                Source::Prepared(black_box(&prepared)),
                &[&models],
                &opts,
                &mut Discard,
            )
        })
    });
    group.bench_function("prepare_and_predict", |b| {
        b.iter(|| {
            run::prepare(&machine, black_box(&src), "long.ngc", false).and_then(|r| {
                predict::predict(
                    &machine,
                    Source::Prepared(&r),
                    &[&models],
                    &opts,
                    &mut Discard,
                )
            })
        })
    });
    // The streamed reference (`vcnc interpolate`): both passes over the file, every piece of
    // samples through the inverse kinematics and the travel check, then dropped.
    if let Ok(dir) = tempfile::tempdir() {
        let path = dir.path().join("long.ngc");
        if std::fs::write(&path, &src).is_ok() {
            let program = || Program::File(path.clone());
            group.bench_function("interpolate_streamed", |b| {
                b.iter(|| {
                    if let Ok(s) = source::plan(&machine, program(), false) {
                        let _ = vcnc_pipeline::interpolate::interpolate(
                            &machine,
                            Source::Streamed(&s),
                            &mut Discard,
                        );
                    }
                })
            });
            // The streamed prediction (`vcnc predict` without the table writer): the
            // reference, the true drives and models, both contour searches, the statistics,
            // a piece of 16 384 samples at a time.
            group.bench_function("predict_streamed", |b| {
                b.iter(|| {
                    if let Ok(s) = source::plan(&machine, program(), false) {
                        let _ = predict::predict(
                            &machine,
                            Source::Streamed(&s),
                            &[&models],
                            &opts,
                            &mut Discard,
                        );
                    }
                })
            });
        }
    }
    group.finish();
}

fn parser(c: &mut Criterion) {
    // About 57 bytes a line: 1 750 000 segments make about 100 MB.
    let Ok(src) = programs::long_tcp_program(1_750_000, 0.5, 0.05, 428) else {
        return;
    };
    let mut group = c.benchmark_group("parse_100MB");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    group.throughput(Throughput::Bytes(src.len() as u64));
    group.bench_function("parse", |b| b.iter(|| vcnc_gcode::parse(black_box(&src))));
    group.finish();
}

criterion_group!(benches, long_program, parser);
criterion_main!(benches);
