//! Compensation of the NMV5000 spiral (docs/compensation.md) with the true drives' analytic
//! models: the sampled models and their stable inverses, the whole `compensate_run` (inverse,
//! learning loop on five axes, margins), and the fine-block program text.
//!
//! `cargo bench -p vcnc-pipeline --bench compensate`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use vcnc_drive::{ClosedLoopModel, DriveModel};
use vcnc_machine::{Machine, MachineModels, embedded};
use vcnc_pipeline::compensate::{CompensateOptions, SampledModel, StableInverse, compensate_run};
use vcnc_pipeline::run;

fn compensate(c: &mut Criterion) {
    let Ok(machine) = Machine::embedded_nmv5000() else {
        return;
    };
    let Ok(spiral) = run::prepare(&machine, embedded::SPIRAL_NGC, "spiral.ngc", false) else {
        return;
    };
    let models: Vec<ClosedLoopModel> = machine.axes.iter().map(|a| a.true_model()).collect();
    let drive_models: Vec<DriveModel> = models.iter().map(|m| DriveModel::from(*m)).collect();
    let Ok(drive_models) = MachineModels::new(&machine, drive_models, "true drives") else {
        return;
    };
    let opts = CompensateOptions::default();
    let mut group = c.benchmark_group("compensate_spiral");
    group.sample_size(10);
    group.bench_function("sampled_models_and_inverses", |b| {
        b.iter(|| {
            models
                .iter()
                .map(|m| SampledModel::of(m, spiral.ts).and_then(|h| StableInverse::of(&h)))
                .collect::<Result<Vec<_>, _>>()
        })
    });
    group.bench_function("compensate_run", |b| {
        b.iter(|| compensate_run(&machine, black_box(&spiral), &drive_models, &opts))
    });
    if let Ok(comp) = compensate_run(&machine, &spiral, &drive_models, &opts) {
        group.bench_function("program_text", |b| {
            b.iter(|| comp.program(&[], &vcnc_gcode::write::BlockRules::EXACT))
        });
    }
    group.finish();
}

criterion_group!(benches, compensate);
criterion_main!(benches);
