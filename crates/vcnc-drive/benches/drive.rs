//! Speed of the true drive and of the closed-loop model simulation.
//!
//! `cargo bench -p vcnc-drive --bench drive`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use vcnc_drive::{DriveTrace, SimOptions, table1_drive};

#[path = "../tests/common/mod.rs"]
mod common;

fn drive(c: &mut Criterion) {
    // 30 s identification-like program (30 001 samples at 1 ms).
    let prog = common::standard_program();
    let table1 = table1_drive().validate().expect("Table 1 drive is valid");
    let mut noisy = table1_drive();
    noisy.encoder.noise_std = 1e-4;
    let noisy = noisy.validate().expect("valid");
    let mut group = c.benchmark_group("drive");
    group.sample_size(30);
    let mut trace = DriveTrace::default();
    group.bench_function(
        "true drive P-PI, 30 s at 20 kHz (600 000 servo ticks)",
        |b| {
            b.iter(|| {
                table1
                    .simulate_into(black_box(prog.reference()), 1e-3, &mut trace)
                    .expect("simulates");
                black_box(&trace);
            })
        },
    );
    group.bench_function("true drive P-PI with encoder noise, 30 s at 20 kHz", |b| {
        b.iter(|| {
            noisy
                .simulate_into(black_box(prog.reference()), 1e-3, &mut trace)
                .expect("simulates");
            black_box(&trace);
        })
    });
    let realistic = common::realistic_table1()
        .validate()
        .expect("the realistic Table 1 drive is valid");
    group.bench_function(
        "realistic drive P-PI (two-mass, Maxwell-slip Stribeck friction, current loop, noise, dead time, filters), 30 s at 20 kHz",
        |b| {
            b.iter(|| {
                realistic
                    .simulate_into(black_box(prog.reference()), 1e-3, &mut trace)
                    .expect("simulates");
                black_box(&trace);
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
    group.finish();
}

criterion_group!(benches, drive);
criterion_main!(benches);
