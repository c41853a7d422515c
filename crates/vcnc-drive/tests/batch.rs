//! The batch simulation (several drives with effects in SIMD lanes, `vcnc_drive::batch`) against
//! its truth, the single-drive simulator: every channel of every trace bit for bit, for the
//! realistic axes and for randomised combinations of effects and control laws.
//!
//! `VCNC_BATCH_CASES=n` runs n random structures instead of the CI's bounded number.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use vcnc_drive::{
    Drive, DriveTrace, Friction, Reference, ReferenceShaping, ShapingFilter, batch_groups,
    simulate_batch, simulate_batch_into,
};

use crate::common;

/// Every channel of `a` and `b` as bits (so that −0.0 ≠ 0.0 and NaN = NaN), and the
/// saturation count.
fn assert_bit_identical(a: &DriveTrace, b: &DriveTrace, what: &str) {
    for ((ca, cb), name) in a
        .channels()
        .iter()
        .zip(b.channels())
        .zip(DriveTrace::CHANNELS)
    {
        assert_eq!(ca.len(), cb.len(), "{what}: {name} length");
        if let Some(k) = ca
            .iter()
            .zip(cb)
            .position(|(x, y)| x.to_bits() != y.to_bits())
        {
            panic!(
                "{what}: {name} differs first at sample {k}: batch {:e} vs single {:e}",
                ca[k], cb[k]
            );
        }
    }
    assert_eq!(
        a.saturated_ticks, b.saturated_ticks,
        "{what}: saturated ticks"
    );
    assert_eq!(a.ts.to_bits(), b.ts.to_bits(), "{what}: ts");
}

/// Runs `jobs` through the batch and each drive alone; compares; returns the groups. The batch
/// runs twice: `simulate_batch`, and `simulate_batch_into` into traces that already hold other
/// runs (the jobs in reverse order, one trace too many), whose buffers must not leak into the
/// new traces.
fn check_batch(jobs: &[(&Drive, Reference<'_>)], ts: f64, what: &str) -> Vec<Vec<usize>> {
    let single: Vec<_> = jobs.iter().map(|(d, r)| d.simulate(*r, ts)).collect();
    let compare =
        |i: usize, b: Result<&DriveTrace, &vcnc_drive::Error>, how: &str| match (b, &single[i]) {
            (Ok(b), Ok(s)) => assert_bit_identical(b, s, &format!("{what}, {how}, drive {i}")),
            (Err(b), Err(s)) => assert_eq!(b, s, "{what}, {how}, drive {i}"),
            (b, s) => panic!("{what}, {how}, drive {i}: batch {b:?} vs single {s:?}"),
        };
    let batch = simulate_batch(jobs, ts);
    assert_eq!(batch.len(), jobs.len());
    for (i, b) in batch.iter().enumerate() {
        compare(i, b.as_ref(), "simulate_batch");
    }
    let rev: Vec<(&Drive, Reference<'_>)> = jobs.iter().rev().copied().collect();
    let mut traces = vec![DriveTrace::default(); jobs.len() + 1];
    let _ = simulate_batch_into(&rev, ts, &mut traces);
    traces.push(DriveTrace::default());
    let into = simulate_batch_into(jobs, ts, &mut traces);
    assert_eq!((into.len(), traces.len()), (jobs.len(), jobs.len()));
    for (i, (r, t)) in into.iter().zip(&traces).enumerate() {
        compare(
            i,
            r.as_ref().map(|()| t),
            "simulate_batch_into, reused traces",
        );
    }
    batch_groups(jobs, ts)
}

#[test]
fn every_realistic_nmv5000_axis_in_lanes_is_bit_identical_to_it_alone() {
    // Truth: `Drive::simulate` of each axis alone. The five drives of
    // machines/nmv5000-realistic.toml (two-mass, Maxwell-slip, current loop, two encoders, dead
    // time, velocity filter, reference filter and delay; A and C with backlash, so lanes in the
    // backlash gap beside lanes without), each on its own program.
    let axes = common::machine_drives("nmv5000-realistic.toml");
    let drives: Vec<Drive> = axes
        .iter()
        .map(|(a, p)| p.validate().unwrap_or_else(|e| panic!("axis {a}: {e}")))
        .collect();
    let progs: Vec<common::Program> = (0..drives.len() as u64)
        .map(|i| common::identification_program(10 + i, 4.0, 1e-3, 0.0, 20.0, 250.0, 2500.0))
        .collect();
    let jobs: Vec<(&Drive, Reference<'_>)> = drives
        .iter()
        .zip(&progs)
        .map(|(d, p)| (d, p.reference()))
        .collect();
    let groups = check_batch(&jobs, 1e-3, "nmv5000-realistic");
    // All five share the structure: four lanes, and the fifth alone.
    assert_eq!(groups, vec![vec![0, 1, 2, 3], vec![4]]);
    // In the other order the backlash axes A and C share the batch with X and Y.
    let rev: Vec<(&Drive, Reference<'_>)> = jobs.iter().rev().copied().collect();
    assert_eq!(
        check_batch(&rev, 1e-3, "nmv5000-realistic, C to X"),
        vec![vec![0, 1, 2, 3], vec![4]]
    );
}

#[test]
fn negative_zero_samples_in_lanes_are_bit_identical_to_each_alone() {
    // Truth: `Drive::simulate` of each axis alone, whose servo loop takes each sample itself at
    // its first tick, as the lanes do. A reference at rest at −0.0 for a while, then moving (an
    // input class the programs above never give). On these drives the sign of a zero reference
    // is absorbed before any output (`p0 + 0·dp`, the lanes' former first tick, passes too).
    let axes = common::machine_drives("nmv5000-realistic.toml");
    let drives: Vec<Drive> = axes
        .iter()
        .map(|(a, p)| p.validate().unwrap_or_else(|e| panic!("axis {a}: {e}")))
        .collect();
    let n = 600;
    let pos: Vec<f64> = (0..n)
        .map(|k| {
            if k < 200 {
                -0.0
            } else {
                1e-3 * ((k - 200) as f64).powi(2) / 2.0
            }
        })
        .collect();
    let vel: Vec<f64> = (0..n)
        .map(|k| if k < 200 { -0.0 } else { (k - 200) as f64 })
        .collect();
    let acc: Vec<f64> = (0..n).map(|k| if k < 200 { -0.0 } else { 1e3 }).collect();
    let r = Reference {
        pos: &pos,
        vel: &vel,
        acc: &acc,
    };
    let jobs: Vec<(&Drive, Reference<'_>)> = drives.iter().map(|d| (d, r)).collect();
    check_batch(&jobs, 1e-3, "nmv5000-realistic from −0.0");
}

#[test]
fn lanes_shaped_alike_and_unlike_are_bit_identical_to_each_alone() {
    // Truth: `Drive::simulate` of each drive alone. The five realistic NMV5000 axes with one
    // reference shaping for all (the lanes then shape on lanes: none, a delay alone, a moving
    // average alone, both), then with the shaping differing per lane (each lane shapes alone):
    // a window or delay of another length, a first-order filter; then band-stops of different
    // frequencies and dampings on every lane (the lanes shape on lanes, each with its own
    // coefficients). With Stribeck exponents 1, 2 and 1.5 side by side (the level's
    // exponential on lanes, a general power per lane).
    let axes = common::machine_drives("nmv5000-realistic.toml");
    let prog = common::identification_program(21, 3.0, 1e-3, 0.0, 20.0, 250.0, 2500.0);
    let shaping = |window_s: Option<f64>, delay_s: f64| ReferenceShaping {
        filter: window_s.map(|window_s| ShapingFilter::MovingAverage { window_s }),
        interpolation_delay_s: delay_s,
    };
    let alike = [
        shaping(None, 0.0),
        shaping(None, 1.5e-3),
        shaping(Some(3.5e-4), 0.0),
        shaping(Some(3e-3), 1e-3),
    ];
    let mut unlike = vec![shaping(Some(2e-3), 2e-3); 5];
    unlike[1] = shaping(Some(1e-3), 2e-3);
    unlike[2] = shaping(Some(2e-3), 5e-4);
    unlike[3] = ReferenceShaping {
        filter: Some(ShapingFilter::FirstOrder {
            time_constant_s: 1e-3,
        }),
        interpolation_delay_s: 2e-3,
    };
    let band_stop = |f: f64, zeta_numerator: f64, fd: Option<f64>| ReferenceShaping {
        filter: Some(ShapingFilter::BandStop {
            frequency_hz: f,
            zeta_numerator,
            zeta_denominator: 0.7,
            denominator_frequency_hz: fd,
        }),
        interpolation_delay_s: 1e-3,
    };
    let band_stops = vec![
        band_stop(180.0, 0.0, None),
        band_stop(280.0, 0.1, Some(250.0)),
        band_stop(90.0, 0.05, None),
        band_stop(400.0, 0.0, Some(500.0)),
        band_stop(60.0, 0.2, None),
    ];
    let cases = alike
        .iter()
        .map(|s| vec![s.clone(); 5])
        .chain([unlike, band_stops]);
    for (c, per_axis) in cases.enumerate() {
        let drives: Vec<Drive> = axes
            .iter()
            .zip(&per_axis)
            .enumerate()
            .map(|(i, ((a, p), s))| {
                let mut p = p.clone();
                p.reference = Some(s.clone());
                if let Some(Friction::MaxwellSlip {
                    stribeck_exponent, ..
                }) = p.friction.as_mut()
                {
                    *stribeck_exponent = [1.0, 2.0, 1.5, 2.0, 1.0][i];
                }
                p.validate().unwrap_or_else(|e| panic!("axis {a}: {e}"))
            })
            .collect();
        let jobs: Vec<(&Drive, Reference<'_>)> =
            drives.iter().map(|d| (d, prog.reference())).collect();
        let groups = check_batch(&jobs, 1e-3, &format!("shaping case {c}"));
        assert_eq!(groups, vec![vec![0, 1, 2, 3], vec![4]], "shaping case {c}");
    }
}

#[test]
fn realistic_variants_in_lanes_are_bit_identical_to_each_alone() {
    // Truth: `Drive::simulate` of each drive alone. The realistic NMV5000 X drive and the
    // realistic Table 1 drive (every effect), with their variants: backlash (a lane in the gap
    // while the others are in contact), a different seed and noise, a different dead time and
    // number of Maxwell-slip elements, and a tight torque limit (saturation in some lanes).
    let prog = common::identification_program(3, 6.0, 1e-3, 0.0, 20.0, 250.0, 2500.0);
    let x = common::realistic_nmv5000_x();
    let t1 = common::realistic_table1();
    let [with_backlash, other_noise, slow, limited] = common::realistic_lane_variants();
    let drives: Vec<Drive> = [x, with_backlash, other_noise, slow, t1, limited]
        .into_iter()
        .map(|p| p.validate().expect("valid"))
        .collect();
    let jobs: Vec<(&Drive, Reference<'_>)> = drives.iter().map(|d| (d, prog.reference())).collect();
    let groups = check_batch(&jobs, 1e-3, "realistic");
    // The four X variants share a structure; the Table 1 drives (dead time 1, motor encoder
    // noise off) share theirs.
    assert_eq!(groups, vec![vec![0, 1, 2, 3], vec![4, 5]]);
    let limited_trace = drives[5].simulate(prog.reference(), 1e-3).unwrap();
    assert!(limited_trace.saturated_ticks > 0, "the limit is reached");
}

#[test]
fn random_effect_combinations_in_lanes_are_bit_identical_to_each_alone() {
    // Truth: `Drive::simulate` of each drive alone. Per case, a random structure (law, rigid or
    // two-mass, friction model and body, current loop order, feedback path) with one to five
    // drives of it (random numbers: gains, masses, levels, backlash or none, limits, noise,
    // dead time, Maxwell-slip elements, reference shaping), plus a drive of another random
    // structure in the same call (a group of its own, or a lane of another group).
    let cases: usize = std::env::var("VCNC_BATCH_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(24);
    let prog = common::identification_program(5, 2.0, 1e-3, 0.0, 10.0, 200.0, 2500.0);
    let mut numbers = ChaCha8Rng::seed_from_u64(2);
    let (mut batched, mut lanes_total) = (0, 0);
    for case in 0..cases as u64 {
        let mut drives = Vec::new();
        let count = 1 + (case as usize % 5);
        for _ in 0..count {
            let mut s = ChaCha8Rng::seed_from_u64(1000 + case);
            if let Ok(d) = common::random_drive(&mut s, &mut numbers).validate() {
                drives.push(d);
            }
        }
        let mut s = ChaCha8Rng::seed_from_u64(5000 + case);
        if let Ok(d) = common::random_drive(&mut s, &mut numbers).validate() {
            drives.push(d);
        }
        let jobs: Vec<(&Drive, Reference<'_>)> =
            drives.iter().map(|d| (d, prog.reference())).collect();
        let groups = check_batch(&jobs, 1e-3, &format!("case {case}"));
        for g in groups.iter().filter(|g| g.len() > 1) {
            batched += 1;
            lanes_total += g.len();
        }
    }
    // The test means something only if many drives really ran in lanes.
    assert!(
        batched >= cases / 3 && lanes_total >= cases,
        "{batched} batches, {lanes_total} lanes"
    );
}
