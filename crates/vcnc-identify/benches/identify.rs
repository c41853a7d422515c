//! One axis' identification (docs/identification.md, issue 4): N ≈ 30 000 samples of the Table 1 drive
//! (20 kHz servo, 0.1 µm encoder), M = 200 particles, 100 iterations; split into the O(N)
//! regressor pass, the swarm, and the output-error refinement. Targets on the 2-core machine:
//! O(N) pass + PSO under 2 ms, everything under 100 ms.

use criterion::{Criterion, criterion_group, criterion_main};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;
use vcnc_drive::Poles;
use vcnc_identify::{
    IdentifyOptions, ModelStructure, Pso, ReferenceInput, RefineSetup, Regressors, Start, Trace,
    identify, refine,
};

#[path = "../tests/support/mod.rs"]
mod support;

fn trace() -> Trace {
    // 80 moves of the paper's program give about 30 000 samples at 1 ms.
    let r = support::identification_program(7, 80, 50.0, 250.0, 2500.0, 1e-3);
    support::drive_trace(&vcnc_drive::table1_drive(), &r)
}

fn bench(c: &mut Criterion) {
    let tr = trace();
    let opts = IdentifyOptions::default();
    eprintln!("bench trace: N = {} samples", tr.len());
    let mut g = c.benchmark_group("identify");
    g.sample_size(20);
    g.bench_function("regressors_O(N)", |b| {
        b.iter(|| {
            let regs = Regressors::build(black_box(&tr), &opts).expect("regressors");
            regs.equation_error_cost().expect("cost")
        })
    });
    let regs = Regressors::build(&tr, &opts).expect("regressors");
    let cost = regs.equation_error_cost().expect("cost");
    let pso = Pso::new(opts.bounds.lower().to_vec(), opts.bounds.upper().to_vec())
        .and_then(|p| p.with_settings(opts.pso))
        .expect("pso");
    g.bench_function("pso_M200_100it", |b| {
        b.iter(|| pso.run(black_box(&cost), &mut ChaCha8Rng::seed_from_u64(1)))
    });
    g.bench_function("regressors_plus_pso", |b| {
        b.iter(|| {
            let regs = Regressors::build(black_box(&tr), &opts).expect("regressors");
            let cost = regs.equation_error_cost().expect("cost");
            pso.run(&cost, &mut ChaCha8Rng::seed_from_u64(1))
        })
    });
    let best = pso.run(&cost, &mut ChaCha8Rng::seed_from_u64(1)).best;
    let start = Start::from_poles(&Poles::from_hz(best[0], best[1], best[2]));
    g.bench_function("refinement_one_start", |b| {
        b.iter(|| {
            refine(
                black_box(&tr),
                &regs,
                std::slice::from_ref(&start),
                RefineSetup::full(ModelStructure::Paper, ReferenceInput::Smooth, &opts),
            )
            .expect("refine")
        })
    });
    g.bench_function("identify_total", |b| {
        b.iter(|| identify(black_box(&tr), &opts).expect("identify"))
    });
    // The same trace without the exact reference derivatives (a measured trace's case), with
    // every extended structure chosen by a held-out part.
    let measured = Trace::new(tr.ts, tr.xr.clone(), tr.x.clone()).expect("trace");
    let all = IdentifyOptions {
        structures: ModelStructure::ALL.to_vec(),
        ..IdentifyOptions::default()
    };
    g.sample_size(10);
    g.bench_function("identify_measured_paper_only", |b| {
        b.iter(|| identify(black_box(&measured), &opts).expect("identify"))
    });
    // The same cut 50 samples after the reference first exceeds 100 mm/s (a moving start: the
    // fit estimates the initial state with free-response columns; until 2026-11-30 they
    // decayed into subnormal numbers, and a 570 k-sample moving start's evaluations took 11
    // times as long as at rest). 2-core VM, 2026-11-30: 137 ms against 106 ms at rest.
    let cut = (1..measured.len() - 1)
        .find(|&k| (measured.xr[k + 1] - measured.xr[k]).abs() > 100.0 * measured.ts)
        .expect("a move");
    let moving = Trace::new(
        measured.ts,
        measured.xr[cut + 50..].to_vec(),
        measured.x[cut + 50..].to_vec(),
    )
    .expect("trace");
    assert!(!moving.starts_at_rest(vcnc_identify::REST_SPEED));
    g.bench_function("identify_measured_paper_only_moving_start", |b| {
        b.iter(|| identify(black_box(&moving), &opts).expect("identify"))
    });
    g.bench_function("identify_measured_all_structures", |b| {
        b.iter(|| identify(black_box(&measured), &all).expect("identify"))
    });
    // The default search of `vcnc identify --trace`: every structure and both model inputs.
    let command = IdentifyOptions {
        inputs: vec![ReferenceInput::Smooth, ReferenceInput::Hold],
        ..all.clone()
    };
    g.bench_function("identify_measured_default_search", |b| {
        b.iter(|| identify(black_box(&measured), &command).expect("identify"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
