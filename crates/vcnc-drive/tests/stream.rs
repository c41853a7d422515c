//! Streamed simulation: true drives and models fed the reference a piece at a time.
//!
//! Truth: the whole-run simulations ([`Drive::simulate`], [`Drive::simulate_true_position`],
//! [`ClosedLoopModel::simulate`], [`DriveModel::simulate`]), bit for bit (`to_bits`), for
//! pieces of 1, 7 and 1000 samples and for seeded random splits with empty pieces among
//! them. The cases cover each controller kind, quantisation, encoder noise and saturation of
//! the ideal loop; the realistic NMV5000 axes as machines/nmv5000-realistic.toml holds them
//! (two-mass screws, backlash on A and C, Maxwell-slip friction, dead time, velocity filter,
//! moving-average shaping and interpolation delay, noisy scale and motor encoder) and variants
//! that reach the other paths of the effects engine; the models as `predict` runs them
//! (core alone, or with a sub-sample dead time, reference filter and extra pole).

use crate::common;

use std::ops::Range;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use vcnc_drive::{
    Channels, ClosedLoopModel, Drive, DriveModel, DriveTrace, Error, Integrator, Reference,
    ReferenceFilter, SimOptions, table1_drive,
};

const TS: f64 = 1e-3;

/// How a run of `n` samples is cut into pieces.
#[derive(Debug, Clone, Copy)]
enum Split {
    /// Pieces of this many samples (the last shorter).
    Every(usize),
    /// Random lengths 0–2999 from this seed (the first at least 1; empty pieces included).
    Random(u64),
}

const SPLITS: [Split; 5] = [
    Split::Every(1),
    Split::Every(7),
    Split::Every(1000),
    Split::Random(1),
    Split::Random(2),
];

fn pieces(n: usize, split: Split) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    let mut rng = ChaCha8Rng::seed_from_u64(match split {
        Split::Random(seed) => seed,
        Split::Every(_) => 0,
    });
    while start < n {
        let len = match split {
            Split::Every(m) => m,
            Split::Random(_) if start == 0 => rng.random_range(1..3000),
            Split::Random(_) => rng.random_range(0..3000),
        };
        let end = (start + len).min(n);
        out.push(start..end);
        start = end;
    }
    out
}

/// The drive streamed through `r` in the pieces of `split`: the trace (channels asked for),
/// with the saturated ticks from `finish`.
fn stream_drive(d: &Drive, r: Reference<'_>, channels: Channels, split: Split) -> DriveTrace {
    let mut s = d.stream(TS, channels).expect("stream");
    let mut t = DriveTrace::default();
    for p in pieces(r.pos.len(), split) {
        s.feed(common::slice(r, &p), &mut t).expect("feeds");
    }
    assert_eq!(s.samples(), r.pos.len());
    t.saturated_ticks = s.finish().expect("finishes");
    t
}

fn stream_model(m: &DriveModel, r: Reference<'_>, opts: &SimOptions, split: Split) -> Vec<f64> {
    let mut s = m.stream(TS, opts).expect("stream");
    let mut x = Vec::new();
    for p in pieces(r.pos.len(), split) {
        s.feed(common::slice(r, &p), &mut x).expect("feeds");
    }
    s.finish().expect("finishes");
    x
}

fn assert_bits(got: &[f64], want: &[f64], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    if let Some(k) = (0..got.len()).find(|k| got[*k].to_bits() != want[*k].to_bits()) {
        panic!("{what}: sample {k} is {} instead of {}", got[k], want[k]);
    }
}

fn assert_trace_bits(got: &DriveTrace, want: &DriveTrace, what: &str) {
    assert_eq!(got.ts.to_bits(), want.ts.to_bits(), "{what}: ts");
    assert_eq!(
        got.saturated_ticks, want.saturated_ticks,
        "{what}: saturated ticks"
    );
    for ((g, w), name) in got
        .channels()
        .into_iter()
        .zip(want.channels())
        .zip(DriveTrace::CHANNELS)
    {
        assert_bits(g, w, &format!("{what}, {name}"));
    }
}

/// Every split, both channel sets, against the whole run. Returns the whole run's saturated
/// ticks.
fn check_drive(name: &str, d: &Drive, r: Reference<'_>) -> u64 {
    let whole = d.simulate(r, TS).expect("simulates");
    let (x_true, sat) = d.simulate_true_position(r, TS).expect("simulates");
    assert_bits(
        &x_true,
        &whole.true_position,
        &format!("{name}: true position alone"),
    );
    assert_eq!(sat, whole.saturated_ticks);
    for split in SPLITS {
        let what = format!("{name}, {split:?}");
        assert_trace_bits(&stream_drive(d, r, Channels::All, split), &whole, &what);
        let t = stream_drive(d, r, Channels::TruePosition, split);
        assert_bits(
            &t.true_position,
            &whole.true_position,
            &format!("{what}, true position"),
        );
        assert!(
            t.position.is_empty() && t.control.is_empty(),
            "{what}: other channels"
        );
        assert_eq!(
            t.saturated_ticks, whole.saturated_ticks,
            "{what}: saturated ticks"
        );
    }
    whole.saturated_ticks
}

#[test]
fn ideal_drives_streamed_in_pieces_are_the_whole_run_bit_for_bit() {
    let prog = common::standard_program();
    let r = prog.reference();
    let mut saturated = 0;
    for (kind, p) in [
        ("P-PI", table1_drive()),
        ("PID", common::pid(table1_drive(), 0.0)),
        ("SMC", common::smc(table1_drive())),
    ] {
        assert!(p.encoder.resolution > 0.0, "quantised encoder");
        let mut noisy = p.clone();
        noisy.encoder.noise_std = 1e-4;
        let mut limited = noisy.clone();
        limited.plant.u_max = Some(0.5);
        for (what, p) in [("", p), (" noisy", noisy), (" noisy, saturating", limited)] {
            let d = p.validate().expect("valid");
            assert!(d.effects().is_ideal());
            saturated += check_drive(&format!("{kind}{what}"), &d, r);
        }
    }
    assert!(saturated > 0, "some case must saturate");
}

#[test]
fn realistic_drives_streamed_in_pieces_are_the_whole_run_bit_for_bit() {
    let prog = common::standard_program();
    let r = prog.reference();
    let axes = common::machine_drives("nmv5000-realistic.toml");
    // The fixture holds what the streams must carry across pieces.
    let a = &axes.iter().find(|(a, _)| a == "A").expect("A axis").1;
    assert!(
        a.compliance.as_ref().is_some_and(|c| c.backlash > 0.0),
        "A has backlash"
    );
    assert!(a.feedback.as_ref().is_some_and(|f| f.dead_time_cycles > 0));
    assert!(a.reference.as_ref().is_some_and(|s| s.filter.is_some()));
    assert!(a.encoder.noise_std > 0.0);
    for (axis, p) in &axes {
        let d = p.validate().expect("valid");
        check_drive(&format!("NMV5000 realistic {axis}"), &d, r);
    }
    // Variants for the other paths of the effects engine (see the helper).
    let [base, v1, v2, v3] = common::realistic_table1_variants(0.0);
    let mut saturated = 0;
    for (name, p) in [
        ("realistic Table 1", base),
        ("PID, second-order shaping, torque limit", v1),
        ("SMC, first-order shaping, semi-closed", v2),
        ("rigid, Stribeck, no dead time", v3),
    ] {
        let d = p.validate().expect("valid");
        assert!(!d.effects().is_ideal());
        saturated += check_drive(name, &d, r);
    }
    assert!(saturated > 0, "some case must saturate");
}

/// What `predict` runs per axis: the core alone when the model is the seven parameters.
fn whole_model(m: &DriveModel, r: Reference<'_>, opts: &SimOptions) -> Vec<f64> {
    if m.is_core_only() {
        m.core.simulate(r, TS, opts).expect("simulates")
    } else {
        m.simulate(r, TS, opts).expect("simulates")
    }
}

fn models() -> Vec<(&'static str, DriveModel)> {
    let core: ClosedLoopModel = table1_drive().closed_loop_model().expect("model");
    vec![
        ("core", DriveModel::from(core)),
        (
            "1.5-sample dead time, first-order filter, extra pole",
            DriveModel {
                delay_s: 1.5e-3,
                reference_filter: Some(ReferenceFilter::FirstOrder { tau_s: 0.002 }),
                extra_pole_hz: Some(150.0),
                ..DriveModel::from(core)
            },
        ),
        (
            "0.37-sample dead time, second-order filter",
            DriveModel {
                delay_s: 0.37e-3,
                reference_filter: Some(ReferenceFilter::SecondOrder {
                    wn_hz: 40.0,
                    zeta: 0.7,
                }),
                ..DriveModel::from(core)
            },
        ),
        (
            "12-sample dead time",
            DriveModel {
                delay_s: 12e-3,
                ..DriveModel::from(core)
            },
        ),
    ]
}

#[test]
fn models_streamed_in_pieces_are_the_whole_run_bit_for_bit() {
    let prog = common::standard_program();
    let r = prog.reference();
    let options = [
        SimOptions::default(),
        SimOptions {
            sticking: false,
            ..SimOptions::default()
        },
        SimOptions {
            integrator: Integrator::Rk4 { substeps: 3 },
            ..SimOptions::default()
        },
    ];
    for (name, m) in models() {
        for opts in &options {
            let whole = whole_model(&m, r, opts);
            for split in SPLITS {
                let x = stream_model(&m, r, opts, split);
                assert_bits(&x, &whole, &format!("{name}, {opts:?}, {split:?}"));
            }
        }
    }
}

#[test]
fn a_stream_restarted_at_a_piece_border_is_caught() {
    // Guard on the references above: they are long and varied enough that a stream losing its
    // state between pieces could not match the whole run. Here every piece goes to a fresh
    // stream (the loop restarts at rest on the piece's first sample).
    let prog = common::standard_program();
    let r = prog.reference();
    let drive = common::realistic_nmv5000_x().validate().expect("valid");
    let whole = drive.simulate(r, TS).expect("simulates");
    let mut restarted = Vec::new();
    for p in pieces(r.pos.len(), Split::Every(1000)) {
        let mut s = drive.stream(TS, Channels::TruePosition).expect("stream");
        let mut t = DriveTrace::default();
        s.feed(common::slice(r, &p), &mut t).expect("feeds");
        restarted.extend(t.true_position);
    }
    let differ = restarted
        .iter()
        .zip(&whole.true_position)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    assert!(differ > 1000, "only {differ} samples differ");
    let (_, m) = &models()[1];
    let whole = whole_model(m, r, &SimOptions::default());
    let mut restarted = Vec::new();
    for p in pieces(r.pos.len(), Split::Every(1000)) {
        let mut s = m.stream(TS, &SimOptions::default()).expect("stream");
        s.feed(common::slice(r, &p), &mut restarted).expect("feeds");
    }
    assert!(restarted.iter().zip(&whole).any(|(a, b)| a != b));
}

#[test]
fn bad_pieces_give_the_whole_runs_errors() {
    let prog = common::standard_program();
    let n = prog.len();
    let drives = [
        table1_drive().validate().expect("valid"),
        common::realistic_nmv5000_x().validate().expect("valid"),
    ];
    let (_, model) = &models()[1];
    let opts = SimOptions::default();
    // A NaN or infinity in each signal, in the third piece of 1000: the whole run's error
    // (the index in the whole run), from the piece that holds it; the stream is spent.
    for (signal, at) in [
        ("position", 2345),
        ("velocity", 2999),
        ("acceleration", 2000),
    ] {
        let mut p = common::standard_program();
        match signal {
            "position" => p.pos[at] = f64::NAN,
            "velocity" => p.vel[at] = f64::INFINITY,
            _ => p.acc[at] = f64::NEG_INFINITY,
        }
        let r = p.reference();
        let want = Error::NonFinite { signal, index: at };
        for d in &drives {
            assert_eq!(d.simulate(r, TS), Err(want.clone()));
            let mut s = d.stream(TS, Channels::All).expect("stream");
            let mut t = DriveTrace::default();
            for (i, piece) in pieces(n, Split::Every(1000)).iter().enumerate() {
                let got = s.feed(common::slice(r, piece), &mut t);
                if i < 2 {
                    assert_eq!(got, Ok(()));
                } else {
                    assert_eq!(got, Err(want.clone()), "piece {i}");
                }
            }
            assert_eq!(t.len(), 2000, "nothing logged from the bad piece on");
            assert_eq!(s.finish(), Err(want.clone()));
        }
        assert_eq!(model.simulate(r, TS, &opts), Err(want.clone()));
        let mut s = model.stream(TS, &opts).expect("stream");
        let mut x = Vec::new();
        s.feed(common::slice(r, &(0..2000)), &mut x).expect("feeds");
        assert_eq!(
            s.feed(common::slice(r, &(2000..n)), &mut x),
            Err(want.clone())
        );
        assert_eq!(x.len(), 2000);
        assert_eq!(s.finish(), Err(want));
    }
    // Empty: the whole run and a first empty piece alike; finish with nothing fed too.
    let empty = Reference {
        pos: &[],
        vel: &[],
        acc: &[],
    };
    let r = prog.reference();
    for d in &drives {
        assert_eq!(d.simulate(empty, TS), Err(Error::EmptySignal));
        let mut s = d.stream(TS, Channels::All).expect("stream");
        assert_eq!(
            s.feed(empty, &mut DriveTrace::default()),
            Err(Error::EmptySignal)
        );
        assert_eq!(s.finish(), Err(Error::EmptySignal));
        let s = d.stream(TS, Channels::All).expect("stream");
        assert_eq!(s.finish(), Err(Error::EmptySignal));
        // An empty piece after the first is nothing to do.
        let mut s = d.stream(TS, Channels::All).expect("stream");
        let mut t = DriveTrace::default();
        s.feed(common::slice(r, &(0..10)), &mut t).expect("feeds");
        s.feed(empty, &mut t).expect("an empty later piece");
        assert_eq!(t.len(), 10);
        assert!(s.finish().is_ok());
        // Lengths that differ within a piece: the piece's lengths.
        let mut s = d.stream(TS, Channels::All).expect("stream");
        let bad = Reference {
            pos: &r.pos[..5],
            vel: &r.vel[..4],
            acc: &r.acc[..5],
        };
        assert_eq!(
            s.feed(bad, &mut t),
            Err(Error::LengthMismatch {
                pos: 5,
                vel: 4,
                acc: 5
            })
        );
    }
    for (_, m) in models() {
        assert_eq!(m.simulate(empty, TS, &opts), Err(Error::EmptySignal));
        let mut s = m.stream(TS, &opts).expect("stream");
        assert_eq!(s.feed(empty, &mut Vec::new()), Err(Error::EmptySignal));
        assert_eq!(s.finish(), Err(Error::EmptySignal));
        assert_eq!(
            m.stream(TS, &opts).expect("stream").finish(),
            Err(Error::EmptySignal)
        );
    }
    // The sample period is refused when the stream is made, as the whole run refuses it.
    assert!(matches!(
        drives[0].stream(0.0, Channels::All),
        Err(Error::BadSamplePeriod { .. })
    ));
    assert!(matches!(
        drives[1].stream(1.234e-4, Channels::All),
        Err(Error::ServoRate { .. })
    ));
    assert!(matches!(
        model.stream(-1.0, &opts),
        Err(Error::BadSamplePeriod { .. })
    ));
}
