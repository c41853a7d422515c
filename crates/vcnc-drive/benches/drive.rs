//! Speed of the true drive and of the closed-loop model simulation.
//!
//! `cargo bench -p vcnc-drive --bench drive`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use vcnc_drive::{
    AxisName, Drive, DriveModel, DriveTrace, Reference, ReferenceFilter, SimOptions,
    nmv5000_axis_design, simulate_batch_into, table1_drive,
};

#[path = "../tests/common/mod.rs"]
mod common;

fn drive(c: &mut Criterion) {
    // 30 s identification-like program (30 001 samples at 1 ms).
    let prog = common::standard_program();
    let table1 = table1_drive().validate().expect("Table 1 drive is valid");
    let mut noisy = table1_drive();
    noisy.encoder.noise_std = 1e-4;
    let noisy = noisy.validate().expect("valid");
    let ideal_x = nmv5000_axis_design(AxisName::X)
        .and_then(|p| p.validate())
        .expect("NMV5000 X is valid");
    let realistic_x = common::realistic_nmv5000_x()
        .validate()
        .expect("realistic NMV5000 X is valid");
    let mut group = c.benchmark_group("drive");
    group.sample_size(30);
    let mut trace = DriveTrace::default();
    let mut case = |name: &str, d: &vcnc_drive::Drive| {
        group.bench_function(name, |b| {
            b.iter(|| {
                d.simulate_into(black_box(prog.reference()), 1e-3, &mut trace)
                    .expect("simulates");
                black_box(&trace);
            })
        });
    };
    case(
        "true drive P-PI, 30 s at 20 kHz (600 000 servo ticks)",
        &table1,
    );
    case("true drive P-PI with encoder noise, 30 s at 20 kHz", &noisy);
    case(
        "NMV5000 X ideal (machines/nmv5000.toml), 30 s at 20 kHz",
        &ideal_x,
    );
    case(
        "NMV5000 X realistic (machines/nmv5000-realistic.toml: every effect), 30 s at 20 kHz",
        &realistic_x,
    );
    // A machine's five true drives: machines/nmv5000.toml (ideal) one after the other, as the
    // pipeline runs them, and machines/nmv5000-realistic.toml in lanes (four in one loop, the
    // fifth alone) and one after the other.
    let machine = |name: &str| -> Vec<Drive> {
        common::machine_drives(name)
            .into_iter()
            .map(|(a, p)| p.validate().unwrap_or_else(|e| panic!("{name} {a}: {e}")))
            .collect()
    };
    let ideal5 = machine("nmv5000.toml");
    let realistic5 = machine("nmv5000-realistic.toml");
    let five = |drives: &[Drive], trace: &mut DriveTrace| {
        for d in drives {
            d.simulate_into(black_box(prog.reference()), 1e-3, trace)
                .expect("simulates");
            black_box(&*trace);
        }
    };
    group.bench_function(
        "NMV5000 5 axes ideal (machines/nmv5000.toml), one after the other, 30 s at 20 kHz",
        |b| b.iter(|| five(&ideal5, &mut trace)),
    );
    group.bench_function(
        "NMV5000 5 axes realistic (machines/nmv5000-realistic.toml), one after the other, 30 s at 20 kHz",
        |b| b.iter(|| five(&realistic5, &mut trace)),
    );
    let jobs: Vec<(&Drive, Reference<'_>)> =
        realistic5.iter().map(|d| (d, prog.reference())).collect();
    // The traces are reused from iteration to iteration, as `simulate_into` reuses its one in
    // the cases above: every case times the simulation, none the allocation of its output.
    let mut traces = Vec::new();
    group.bench_function(
        "NMV5000 5 axes realistic, simulate_batch (4 in SIMD lanes + 1 alone), 30 s at 20 kHz",
        |b| {
            b.iter(|| {
                for r in simulate_batch_into(black_box(&jobs), 1e-3, &mut traces) {
                    r.expect("simulates");
                }
                black_box(&traces);
            })
        },
    );
    group.bench_function(
        "NMV5000 4 axes realistic (X, Y, Z, A), simulate_batch (one loop of 4 lanes), 30 s at 20 kHz",
        |b| {
            b.iter(|| {
                for r in simulate_batch_into(black_box(&jobs[..4]), 1e-3, &mut traces) {
                    r.expect("simulates");
                }
                black_box(&traces);
            })
        },
    );
    let model = table1.closed_loop_model();
    group.bench_function(
        "ClosedLoopModel::simulate, 30 000 samples (exact FOH)",
        |b| {
            b.iter(|| {
                black_box(
                    model
                        .simulate(black_box(prog.reference()), 1e-3, &SimOptions::default())
                        .expect("simulates"),
                )
            })
        },
    );
    // The extended model as `predict` runs it: a sub-sample dead time (two exact pieces per
    // sample), a first-order reference filter and an extra pole.
    let extended = DriveModel {
        delay_s: 1.5e-3,
        reference_filter: Some(ReferenceFilter::FirstOrder { tau_s: 2e-3 }),
        extra_pole_hz: Some(150.0),
        ..DriveModel::from(model)
    };
    group.bench_function(
        "DriveModel::simulate, 30 000 samples (1.5 ms dead time, filter, extra pole)",
        |b| {
            b.iter(|| {
                black_box(
                    extended
                        .simulate(black_box(prog.reference()), 1e-3, &SimOptions::default())
                        .expect("simulates"),
                )
            })
        },
    );
    group.finish();
}

criterion_group!(benches, drive);
criterion_main!(benches);
