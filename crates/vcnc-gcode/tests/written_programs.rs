//! Programs vcnc writes for a control (`write::fine_blocks`), read back by vcnc's own
//! interpreter and interpolator.
//!
//! Truth: the writer's own statement of what it wrote, checked from outside — the program is
//! parsed again and every `G1` block must last a whole number of sample periods no fewer than
//! the rules' minimum (its $1/F$), every coordinate word must have no more decimals than the
//! resolution, and the interpolated run must pass every sample within the deviation the writer
//! reports, which in turn is within the larger of the chord tolerance and half the resolution
//! when a block may be one period long. The sample series are random (smooth paths, rests,
//! and noise no tolerance can follow), and so are the rules.

use proptest::prelude::*;
use vcnc_gcode::write::{BlockRules, fine_blocks};
use vcnc_gcode::{
    AxisName, FINE_BLOCK_MAX_SAMPLES, InterpOptions, InterpolateOptions, Limits, load, parse,
};

const TS: f64 = 0.001;

/// Decimals a word of resolution `res` may have (any number for 0).
fn decimals(res: f64) -> usize {
    if res == 0.0 {
        usize::MAX
    } else {
        (-res.log10() - 1e-9).ceil() as usize
    }
}

/// Samples of one axis from 0: a smooth path, rests and (with `noise`) a jitter no line
/// follows.
fn series(n: usize, amp: f64, freq: f64, rest_at: usize, rest_len: usize, noise: f64) -> Vec<f64> {
    let mut v = Vec::with_capacity(n);
    let mut held = 0;
    for k in 0..n {
        let t = k as f64 * TS;
        let x = if k >= rest_at && held < rest_len {
            held += 1;
            *v.last().unwrap_or(&0.0)
        } else {
            amp * (1.0 - (freq * t).cos()) + noise * ((k * 7919 % 13) as f64 / 13.0 - 0.5)
        };
        v.push(if k == 0 { 0.0 } else { x });
    }
    // At rest at the end, as a compensated run is.
    let last = *v.last().unwrap_or(&0.0);
    v.extend(std::iter::repeat_n(last, 5));
    v
}

fn check(x: &[f64], c: &[f64], rules: &BlockRules) {
    let axes = [(AxisName::X, x), (AxisName::C, c)];
    let written = fine_blocks(&axes, TS, &["test".to_string()], rules);
    let n = x.len();

    // The words and the block lengths, read from the text.
    let (program, diags) = parse(&written.text);
    assert!(diags.is_empty(), "{diags:?}");
    let mut periods = 0u64;
    for b in &program.blocks {
        let g1 = b.words.iter().any(|w| w.letter == 'G' && w.value == 1.0);
        let g4 = b.words.iter().any(|w| w.letter == 'G' && w.value == 4.0);
        for w in &b.words {
            let text = &written.text[w.span.start..w.span.end];
            let res = match w.letter {
                'X' => rules.resolution,
                'C' => rules.rotary_resolution,
                _ => continue,
            };
            let d = text.split('.').nth(1).map_or(0, str::len);
            assert!(d <= decimals(res), "{text} at resolution {res}");
        }
        if g1 {
            let f = b.words.iter().find(|w| w.letter == 'F').expect("F").value;
            let m = (60.0 / (f * TS)).round();
            assert!(((60.0 / (f * TS)) - m).abs() <= 1e-7 * m, "F{f}");
            // No block is shorter than the block cycle, unless the whole run is.
            assert!(
                m as u64 >= rules.min_samples.min(n as u64 - 1),
                "F{f}: {m} periods"
            );
            assert!(m as u64 <= FINE_BLOCK_MAX_SAMPLES);
            periods += m as u64;
        } else if g4 {
            let p = b.words.iter().find(|w| w.letter == 'P').expect("P").value;
            periods += (p / TS).round() as u64;
        }
    }
    assert_eq!(periods as usize, n - 1, "the blocks last the samples' time");
    if written.blocks == 0 {
        assert_eq!(written.shortest_block, 0);
    } else {
        assert!(written.shortest_block >= rules.min_samples.min(n as u64 - 1));
    }

    // The run passes every sample within the deviation reported.
    let limits = Limits::uniform(1e6, 1e12);
    let run = load(
        &written.text,
        &InterpOptions::default(),
        &limits,
        &InterpolateOptions::default(),
    )
    .expect("the program runs");
    let t = run.trajectory;
    assert_eq!(t.len(), n);
    for (i, (name, v)) in axes.iter().enumerate() {
        let pos = &t.axis(*name).unwrap().pos;
        let off = pos
            .iter()
            .zip(v.iter())
            .fold(0.0f64, |m, (p, s)| m.max((p - s).abs()));
        let dev = written.deviation[i];
        assert!(off <= dev * (1.0 + 1e-9) + 1e-12, "{name}: {off} > {dev}");
        if rules.min_samples == 1 {
            let (tol, res) = if name.is_rotary() {
                (rules.rotary_tolerance, rules.rotary_resolution)
            } else {
                (rules.tolerance, rules.resolution)
            };
            assert!(
                dev <= tol.max(res / 2.0) * (1.0 + 1e-9) + 1e-12,
                "{name}: {dev} with tolerance {tol}, resolution {res}"
            );
        }
    }
}

#[test]
fn exact_rules_reproduce_the_samples_bit_for_bit() {
    let x = series(400, 3.0, 9.0, 120, 30, 0.0);
    let c = series(400, 40.0, 5.0, 300, 3, 1e-3);
    let rules = BlockRules::EXACT;
    check(&x, &c, &rules);
    let written = fine_blocks(&[(AxisName::X, &x), (AxisName::C, &c)], TS, &[], &rules);
    assert_eq!(written.deviation, vec![0.0, 0.0]);
}

#[test]
fn merged_blocks_are_fewer_on_a_smooth_path() {
    // A slow smooth path: lines of up to 32 periods stay within 1 µm of it.
    let x = series(2000, 1.0, 2.0, 0, 0, 0.0);
    let c = series(2000, 5.0, 2.0, 0, 0, 0.0);
    let rules = BlockRules {
        min_samples: 4,
        resolution: 1e-4,
        rotary_resolution: 1e-4,
        tolerance: 1e-3,
        rotary_tolerance: 1e-3,
    };
    check(&x, &c, &rules);
    let written = fine_blocks(&[(AxisName::X, &x), (AxisName::C, &c)], TS, &[], &rules);
    assert!(written.blocks < 2000 / 16, "{} blocks", written.blocks);
    assert!(written.deviation.iter().all(|d| *d <= 1e-3));
}

#[test]
fn motion_shorter_than_a_block_cycle_after_a_rest_takes_time_from_the_dwell() {
    // 100 samples of motion, 50 at rest, 3 of motion, 3 at rest: with blocks of at least
    // 8 periods the last 8 periods (2 taken from the rest) are one block.
    let mut x = series(100, 2.0, 20.0, 0, 0, 0.0);
    x.truncate(100);
    let at = x[99];
    x.extend(std::iter::repeat_n(at, 50));
    x.extend([at + 0.01, at + 0.02, at + 0.03]);
    x.extend(std::iter::repeat_n(at + 0.03, 3));
    let c = vec![0.0; x.len()];
    let rules = BlockRules {
        min_samples: 8,
        ..BlockRules::EXACT
    };
    check(&x, &c, &rules);
    let written = fine_blocks(&[(AxisName::X, &x), (AxisName::C, &c)], TS, &[], &rules);
    assert_eq!(written.shortest_block, 8);
    assert_eq!(written.dwells, 1, "the rest, shortened");
    let last = written.text.lines().rfind(|l| l.starts_with("G1")).unwrap();
    assert!(
        last.ends_with(" F7500"),
        "{last}: the motion and 2 periods of the rest"
    );
    // A run shorter than a block cycle is one block of its length.
    let x = [0.0, 0.001, 0.002];
    let c = [0.0; 3];
    let written = fine_blocks(&[(AxisName::X, &x), (AxisName::C, &c)], TS, &[], &rules);
    assert_eq!((written.blocks, written.shortest_block), (1, 2));
    check(&x, &c, &rules);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn written_programs_run_through_their_samples(
        n in 2usize..600,
        amp in 0.0f64..20.0,
        freq in 0.5f64..60.0,
        rest_at in 0usize..600,
        rest_len in 0usize..80,
        noise in prop_oneof![Just(0.0), 0.0f64..0.05],
        min_samples in 1u64..=8,
        resolution in prop_oneof![Just(0.0), Just(1e-4), Just(1e-3)],
        tolerance in prop_oneof![Just(0.0), Just(1e-4), Just(1e-3), Just(1e-2)],
    ) {
        let x = series(n, amp, freq, rest_at, rest_len, noise);
        let c = series(n, 3.0 * amp, 0.7 * freq, rest_at / 2, rest_len, 0.0);
        let rules = BlockRules {
            min_samples,
            resolution,
            rotary_resolution: resolution,
            tolerance,
            rotary_tolerance: tolerance,
        };
        check(&x, &c, &rules);
    }
}

#[test]
fn samples_that_return_to_where_a_block_starts_are_a_dwell() {
    // A case proptest found: C's last samples (at 0.001°) dip and come back to where the
    // last block ended, too few for two blocks of 3 periods. A line from a point to itself is
    // no move, so the interpreter would drop it and the run would lose those periods; they are
    // a dwell.
    let (n, amp, freq) = (468, 14.997777920923589, 19.26144181421281);
    let x = series(n, amp, freq, 422, 58, 0.02972679876679603);
    let c = series(n, 3.0 * amp, 0.7 * freq, 211, 58, 0.0);
    let rules = BlockRules {
        min_samples: 3,
        resolution: 0.001,
        rotary_resolution: 0.001,
        tolerance: 0.0,
        rotary_tolerance: 0.0,
    };
    check(&x, &c, &rules);
    let written = fine_blocks(&[(AxisName::X, &x), (AxisName::C, &c)], TS, &[], &rules);
    assert!(
        written.text.ends_with("G4 P0.007\nG94 G61\nM2\n%\n"),
        "{}",
        written.text
    );
}
