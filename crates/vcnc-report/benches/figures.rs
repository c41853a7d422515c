//! Figure building speed: a long time series, a coloured 3-D path (10⁴ and 10⁶ samples), the
//! tracking-error figure of a demo-sized run, and the `.vtp` export.
//!
//! `cargo bench -p vcnc-report --bench figures`

use std::f64::consts::PI;

use criterion::{Criterion, criterion_group, criterion_main};
use vcnc_axis::AxisName;
use vcnc_report::vtp::{VtpEncoding, VtpPath, vtp_string};
use vcnc_report::*;

fn spiral(n: usize) -> (Vec<[f64; 3]>, Vec<f64>, Vec<u32>) {
    let pts = (0..n)
        .map(|k| {
            let s = k as f64 / n as f64;
            let a = s * 6.0 * PI;
            let r = 20.0 + 50.0 * s;
            [30.0 + r * a.cos(), 15.0 + r * a.sin(), 48.0 - 6.0 * s]
        })
        .collect();
    let v = (0..n)
        .map(|k| 400.0 * (k as f64 / n as f64 * 37.0).sin().abs())
        .collect();
    let l = (0..n).map(|k| 10 + (k * 1500 / n) as u32).collect();
    (pts, v, l)
}

fn bench(c: &mut Criterion) {
    let n = 1_000_000;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-4).collect();
    let e: Vec<f64> = t.iter().map(|t| 20.0 * (t * 3.0).sin()).collect();
    let m: Vec<f64> = e.iter().map(|v| v * 1.001).collect();
    c.bench_function("comparison_figure 1e6 samples, truth + model", |b| {
        b.iter(|| {
            comparison_figure(
                "long",
                "",
                Axis::linear("time t", "s"),
                &[Comparison {
                    title: None,
                    y: Axis::linear("tracking error", "µm"),
                    truth: Series::line("true machine", Role::TrueMachine, &t, &e),
                    others: vec![Series::line("vcnc model", Role::Model, &t, &m)],
                    difference: None,
                }],
                Vec::new(),
            )
            .unwrap()
        })
    });
    let t4: Vec<f64> = (0..10_123).map(|k| k as f64 * 1e-3).collect();
    let r4: Vec<f64> = t4.iter().map(|t| t * 3.0).collect();
    let e4: Vec<f64> = t4.iter().map(|t| 200.0 * (t * 2.0).sin()).collect();
    c.bench_function("tracking_errors 5 axes x 10123 samples", |b| {
        b.iter(|| {
            let axes: Vec<AxisErrors> = [
                AxisName::X,
                AxisName::Y,
                AxisName::Z,
                AxisName::A,
                AxisName::C,
            ]
            .iter()
            .map(|&a| AxisErrors {
                axis: a,
                reference: &r4,
                truth: Series::line("true machine", Role::TrueMachine, &t4, &e4),
                models: vec![Series::line("vcnc model", Role::Model, &t4, &e4)],
            })
            .collect();
            tracking_errors("tracking", &axes).unwrap()
        })
    });
    for n in [10_000usize, 1_000_000] {
        let (pts, v, l) = spiral(n);
        let mut g = c.benchmark_group("contour_path_views");
        if n > 100_000 {
            g.sample_size(10);
        }
        g.bench_function(format!("{n} samples"), |b| {
            b.iter(|| {
                contour_path_views(
                    "path",
                    &ColouredPath {
                        points_mm: &pts,
                        values: &v,
                        value: Quantity::new("contour error", "µm"),
                        block_line: Some(&l),
                    },
                    &PathViewOptions::default(),
                )
                .unwrap()
            })
        });
        g.finish();
    }
    let (pts, v, l) = spiral(10_000);
    let axis = vec![[0.0, 0.0, 1.0]; pts.len()];
    c.bench_function("vtp base64 10000 points", |b| {
        b.iter(|| {
            vtp_string(
                &VtpPath::contour(&pts, &v, &v, &axis, Some(&l)),
                VtpEncoding::Base64,
            )
            .unwrap()
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
