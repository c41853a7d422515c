//! A feed plan's evaluation streamed (`feed_plan::evaluate`: the program a piece at a time,
//! reduced on the fly) against the whole-run computation it replaced: the program prepared
//! whole, the models' contour errors against the original path as whole series
//! (`compensate::with_models`, `compensate::feed_samples`), the per-line charge as the maximum
//! over each sample's lag window written out on the whole series, and the statistics over the
//! masked series (`ContourStats::over`). Bit for bit, whatever the pieces.
//!
//! Programs: the spiral against its own path and, slowed to a third, against the spiral's
//! path (a plan's evaluation: another program's run, measured against the original); the
//! O-word program shared with `route.rs` (`tests/common`) with models that have a dead time,
//! a reference filter, an extra pole and stated latencies (the source lines must follow the
//! samples through the latency shift).

use crate::common;

use std::collections::BTreeMap;

use vcnc_machine::{Machine, MachineModels, embedded};
use vcnc_pipeline::compensate::{self, ContourStats};
use vcnc_pipeline::feed_plan::{self, FeedPlanOptions, OriginalPath};
use vcnc_pipeline::run::{self, Run};
use vcnc_pipeline::source::{self, Program};
use vcnc_pipeline::{Source, StreamOptions};

use common::{OWORD, models};

/// The whole-run figures: per line its charge, the largest excess, the largest tool-tip
/// error, the feed samples' statistics, the cycle time.
fn whole(
    machine: &Machine,
    original: &Run,
    run: &Run,
    models: &MachineModels,
    opts: &FeedPlanOptions,
    lag: usize,
) -> (BTreeMap<u32, f64>, f64, f64, ContourStats, f64) {
    let report = compensate::with_models(machine, original, run, models).expect("prediction");
    let feed = compensate::feed_samples(original, &report);
    let e: Vec<f64> = (0..report.tip_mm.len())
        .map(|k| {
            if !feed[k] {
                return 0.0;
            }
            let tip = report.tip_mm[k].abs() / opts.tolerance_mm;
            match opts.orientation_tolerance_rad {
                Some(o) => tip.max(report.orientation_rad[k].abs() / o),
                None => tip,
            }
        })
        .collect();
    let n = e.len();
    let mut charged = BTreeMap::new();
    for k in 0..n {
        if run.lines[k] == 0 {
            continue;
        }
        let m = e[k..(k + lag + 1).min(n)]
            .iter()
            .fold(0.0f64, |a, b| a.max(*b));
        let v = charged.entry(run.lines[k]).or_insert(0.0f64);
        *v = v.max(m);
    }
    (
        charged,
        e.iter().fold(0.0f64, |a, b| a.max(*b)),
        report.tip_max_mm,
        ContourStats::over(&report, &feed),
        run.duration_s(),
    )
}

fn stats_bits(s: &ContourStats) -> [u64; 4] {
    [
        s.contour_max_um.to_bits(),
        s.contour_rms_um.to_bits(),
        s.orientation_max_mrad.to_bits(),
        s.orientation_rms_mrad.to_bits(),
    ]
}

#[test]
fn a_streamed_evaluation_is_the_whole_runs_bit_for_bit() {
    let machine = Machine::embedded_nmv5000().expect("machine");
    let spiral = embedded::SPIRAL_NGC.to_string();
    assert!(spiral.contains(" F4500"));
    let slow = spiral.replace(" F4500", " F1500");
    let cases = [
        (spiral.clone(), spiral.clone(), false),
        (spiral.clone(), slow, false),
        (OWORD.to_string(), OWORD.to_string(), true),
    ];
    for (original_text, text, rich) in cases {
        let models = models(&machine, rich);
        let original = run::prepare(&machine, &original_text, "original.ngc", false).unwrap();
        let run = run::prepare(&machine, &text, "p.ngc", false).unwrap();
        let path = OriginalPath::new(&machine, &original).unwrap();
        let lag = (feed_plan::lag_window(models.models()) / original.ts).round() as usize;
        assert!(lag > 10, "{lag}");
        for opts in [
            FeedPlanOptions::new(0.01),
            FeedPlanOptions {
                orientation_tolerance_rad: Some(1e-4),
                ..FeedPlanOptions::new(0.01)
            },
        ] {
            let (charged, excess, tip_max, stats, cycle) =
                whole(&machine, &original, &run, &models, &opts, lag);
            assert!(charged.len() > 3 && excess > 0.0);
            for pieces in [
                StreamOptions::default(),
                StreamOptions {
                    chunk_bytes: 300,
                    chunk_samples: 777,
                },
            ] {
                let stream = source::plan_pieces(
                    &machine,
                    Program::Text {
                        text: text.clone(),
                        name: "p.ngc".to_string(),
                    },
                    false,
                    &pieces,
                )
                .unwrap();
                let ev = feed_plan::evaluate(
                    &machine,
                    &path,
                    Source::Streamed(&stream),
                    &models,
                    &opts,
                    lag,
                )
                .unwrap();
                assert_eq!(ev.samples, run.len());
                assert_eq!(ev.cycle_time_s.to_bits(), cycle.to_bits());
                assert_eq!(ev.excess.to_bits(), excess.to_bits());
                assert_eq!(ev.tip_max_mm.to_bits(), tip_max.to_bits());
                assert_eq!(stats_bits(&ev.feed), stats_bits(&stats));
                let bits = |m: &BTreeMap<u32, f64>| -> Vec<(u32, u64)> {
                    m.iter().map(|(l, v)| (*l, v.to_bits())).collect()
                };
                assert_eq!(bits(&ev.charged), bits(&charged));
            }
        }
    }
}

/// A tolerance no feed meets is refused with the error of the samples held to it: the feed
/// moves' largest tool-tip error, whose ratio to the tolerance is the reported excess (the
/// refusal once gave the largest error of every sample, rapids included: 1117 µm beside an
/// excess of 5.66 at 20 µm on a generated TCP program). The program: a short generated 5-axis
/// TCP program of 10 ms inverse-time blocks, far beyond its axes' acceleration limits, whose
/// predicted error does not fall with the feed; the smallest factor 0.1 keeps the test short.
#[test]
fn an_unreachable_tolerance_reports_the_feed_moves_error() {
    let machine = Machine::embedded_nmv5000().expect("machine");
    let src = vcnc_pipeline::programs::long_tcp_program(60, 0.5, 0.01, 428).expect("program");
    let opts = FeedPlanOptions {
        min_factor: 0.1,
        ..FeedPlanOptions::new(0.02)
    };
    let err = feed_plan::plan_feeds(
        &machine,
        &src,
        "long.ngc",
        &models(&machine, false),
        &opts,
        false,
    )
    .expect_err("no feed factor meets 20 µm on this program");
    let vcnc_pipeline::Error::ToleranceUnreachable { tip_um, excess, .. } = err else {
        panic!("unexpected error: {err}");
    };
    println!("{err}");
    assert!(excess > 1.0);
    // Without an orientation tolerance the excess is the tip error over the tolerance.
    assert!(
        (tip_um / 20.0 - excess).abs() <= 1e-9 * excess,
        "reported {tip_um} µm at an excess of {excess} over 20 µm"
    );
}
