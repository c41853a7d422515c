//! Windowed vs brute-force foot-point search on a 10 000-sample docs/contour.md spiral
//! (actual = reference delayed 4 ms with a 5 µm offset and a 0.2 mrad tilt), and the windowed
//! search streamed (docs/contour.md#streamed-search) in pieces of 1000 samples.
//!
//! `cargo bench -p vcnc-contour --bench foot_search`

#[path = "../tests/common/mod.rs"]
mod common;

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use vcnc_contour::{
    ContourStream, Result, SearchWindow, StreamLimits, contour_errors, contour_errors_brute_force,
};
use vcnc_kinematics::Pose;

/// The stream fed a piece of reference, then the actual poses of the same samples, then
/// drained; the tip errors summed (so that nothing is optimised away).
fn streamed(reference: &[Pose], actual: &[Pose], piece: usize) -> Result<f64> {
    let mut s = ContourStream::new(&SearchWindow::default(), StreamLimits::default())?;
    let mut sum = 0.0;
    for (r, a) in reference.chunks(piece).zip(actual.chunks(piece)) {
        s.push_reference(r.iter().copied())?;
        for pose in a {
            s.push_actual(pose)?;
        }
        s.drain(|_, tip, _, _| sum += tip)?;
    }
    s.end_reference();
    s.finish(|_, tip, _, _| sum += tip)?;
    Ok(sum)
}

fn foot_search(c: &mut Criterion) {
    let spiral = common::Spiral::new();
    let mut reference = common::reference(&spiral, None, 0);
    reference.truncate(10_000);
    let actual = common::actual(&spiral, None, 10_000, 4e-3, 5.0, 0.2);
    if let (Ok(w), Ok(b)) = (
        contour_errors(&reference, &actual),
        contour_errors_brute_force(&reference, &actual),
    ) {
        eprintln!(
            "segment projections: windowed {} ({:.2} per sample), brute force {} (ratio {:.0}); \
             max tip error {:.3} µm (windowed) vs {:.3} µm (brute force)",
            w.segment_evaluations,
            w.segment_evaluations as f64 / actual.len() as f64,
            b.segment_evaluations,
            b.segment_evaluations as f64 / w.segment_evaluations as f64,
            w.tip_max_mm * 1e3,
            b.tip_max_mm * 1e3,
        );
    }
    let mut group = c.benchmark_group("contour_spiral_10k");
    group.sample_size(10);
    group.bench_function("windowed", |b| {
        b.iter(|| contour_errors(black_box(&reference), black_box(&actual)))
    });
    group.bench_function("streamed", |b| {
        b.iter(|| streamed(black_box(&reference), black_box(&actual), 1000))
    });
    group.bench_function("brute_force", |b| {
        b.iter(|| contour_errors_brute_force(black_box(&reference), black_box(&actual)))
    });
    group.finish();
}

criterion_group!(benches, foot_search);
criterion_main!(benches);
