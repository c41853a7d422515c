//! Golden fingerprints of the drive engine: what every route through it gives, bit for bit,
//! recorded from the engine as it was before it was rewritten as one engine generic over its
//! lane type (the three loops of commit 13c6b18: the ideal drive, the drive with effects, and the
//! drives with effects in SIMD lanes).
//!
//! Truth: `tests/data/engine-golden.txt`, written by this test run against vcnc-drive at commit
//! 13c6b18 (`VCNC_GOLDEN=write cargo test --release -p vcnc-drive --test integration golden`; the file's
//! header says which fingerprints were recorded later, and why). Each line is a
//! case and the FNV-1a hash of the bits of everything it produced: every channel of a trace
//! (with its length, the saturated ticks and `ts`), the true position alone, a measured
//! frequency response, a transition matrix, poles, the groups of a batch, an error. Each route
//! is held to the same number: [`Drive::simulate`], [`Drive::simulate_true_position`],
//! [`Drive::stream`] fed in odd pieces (both channel sets), [`simulate_batch`] and
//! [`simulate_batch_into`] (drives of one structure in lanes beside drives alone), and the
//! resumable batched stream [`GroupStream`] fed in odd pieces.
//!
//! The cases: the presets, each controller kind (ideal, noisy, saturating; 1, 4 and 20 servo
//! ticks per sample), every axis of the machine files, the realistic drives and variants that
//! reach every path of the effects engine (backlash, set-valued and Maxwell-slip friction on
//! either body, current loops of both orders, torque limits, each feedback path with and
//! without dead time, velocity filter, every reference filter and delay, a second noisy
//! encoder), drives of random structure, references starting at −0.0 and far from the origin.

use crate::common;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::ops::Range;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use vcnc_drive::{
    Channels, Drive, DriveParams, DriveTrace, FrfKind, FrfOptions, Friction, FrictionLocation,
    GroupStream, NMV5000_TABLE3, Reference, batch_groups, nmv5000_axis_design, simulate_batch,
    simulate_batch_into, table1_drive,
};

const TS: f64 = 1e-3;
const GOLDEN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/engine-golden.txt");

/// FNV-1a, 64 bits.
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn u64(&mut self, v: u64) {
        for b in v.to_le_bytes() {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn f64s(&mut self, v: &[f64]) {
        self.u64(v.len() as u64);
        for x in v {
            self.u64(x.to_bits());
        }
    }
    fn text(&mut self, s: &str) {
        self.u64(s.len() as u64);
        for b in s.bytes() {
            self.u64(b as u64);
        }
    }
}

/// Every channel of a trace, the saturated ticks and the period.
fn trace_hash(t: &DriveTrace) -> u64 {
    let mut h = Fnv::new();
    for c in t.channels() {
        h.f64s(c);
    }
    h.u64(t.saturated_ticks);
    h.u64(t.ts.to_bits());
    h.0
}

/// The true position alone and the saturated ticks.
fn true_position_hash(x: &[f64], saturated: u64) -> u64 {
    let mut h = Fnv::new();
    h.f64s(x);
    h.u64(saturated);
    h.0
}

/// A value's `Debug` text (every `f64` in it printed exactly: shortest round trip).
fn debug_hash(v: &impl std::fmt::Debug) -> u64 {
    let mut h = Fnv::new();
    h.text(&format!("{v:?}"));
    h.0
}

/// The recorded or recording fingerprints.
struct Book {
    write: bool,
    want: BTreeMap<String, String>,
    got: BTreeMap<String, String>,
    errors: Vec<String>,
}

impl Book {
    fn open() -> Book {
        let write = std::env::var("VCNC_GOLDEN").is_ok_and(|v| v == "write");
        let want = if write {
            BTreeMap::new()
        } else {
            let text = std::fs::read_to_string(GOLDEN).expect("tests/data/engine-golden.txt");
            text.lines()
                .filter(|l| !l.starts_with('#') && !l.is_empty())
                .map(|l| {
                    let (k, v) = l.rsplit_once(' ').expect("`case hash` lines");
                    (k.to_string(), v.to_string())
                })
                .collect()
        };
        Book {
            write,
            want,
            got: BTreeMap::new(),
            errors: Vec::new(),
        }
    }

    /// Records `value` for `key` (a route that must give the same as another records the same
    /// key again: it must be the same value).
    fn check(&mut self, key: &str, value: u64) {
        let v = format!("{value:016x}");
        if let Some(prev) = self.got.get(key) {
            if *prev != v {
                self.errors
                    .push(format!("{key}: {v} differs from another route's {prev}"));
            }
            return;
        }
        if !self.write {
            match self.want.get(key) {
                Some(w) if *w == v => {}
                Some(w) => self.errors.push(format!("{key}: {v}, recorded {w}")),
                None => self.errors.push(format!("{key}: not recorded")),
            }
        }
        self.got.insert(key.to_string(), v);
    }

    fn finish(self) {
        assert!(
            self.errors.is_empty(),
            "{} fingerprints differ:\n{}",
            self.errors.len(),
            self.errors
                .iter()
                .take(40)
                .cloned()
                .collect::<Vec<_>>()
                .join("\n")
        );
        if self.write {
            let mut text = String::from(
                "# Fingerprints of the drive engine at commit 13c6b18 (tests/golden.rs), except\n\
                 # effects-matrix/*: the linearised loop of a drive with effects is derived from the\n\
                 # law and plant data since (src/stability.rs), not taken from the engine's tick;\n\
                 # its entries differ from 13c6b18's by at most 2.5e-16 of the matrix's largest\n\
                 # (88 of 4219 entries), the spectral radius by at most 1.9e-9, no validation changes.\n",
            );
            for (k, v) in &self.got {
                writeln!(text, "{k} {v}").expect("string");
            }
            std::fs::write(GOLDEN, text).expect("golden file written");
            return;
        }
        let unchecked: Vec<&String> = self
            .want
            .keys()
            .filter(|k| !self.got.contains_key(*k))
            .collect();
        assert!(
            unchecked.is_empty(),
            "{} recorded fingerprints not produced: {:?}",
            unchecked.len(),
            unchecked.iter().take(20).collect::<Vec<_>>()
        );
        eprintln!("{} fingerprints as recorded", self.got.len());
    }
}

// ---------------------------------------------------------------------------------------------
// References and splits.

/// Pieces of a run of `n` samples: every `m` samples, or random lengths below `max` (seeded,
/// empty pieces among them).
fn pieces(n: usize, every: Option<usize>, seed: u64, max: usize) -> Vec<Range<usize>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    let mut start = 0;
    while start < n {
        let len = match every {
            Some(m) => m,
            None if start == 0 => rng.random_range(1..max),
            None => rng.random_range(0..max),
        };
        let end = (start + len).min(n);
        out.push(start..end);
        start = end;
    }
    out
}

/// The splits every drive is streamed in.
const SPLITS: [(Option<usize>, u64); 3] = [(Some(7), 0), (None, 1), (Some(1), 0)];

/// At rest at −0.0 for 200 samples, then accelerating.
fn negative_zero_program() -> common::Program {
    let n = 600;
    let at_rest = |k: usize| k < 200;
    common::Program {
        pos: (0..n)
            .map(|k| {
                if at_rest(k) {
                    -0.0
                } else {
                    1e-3 * ((k - 200) as f64).powi(2) / 2.0
                }
            })
            .collect(),
        vel: (0..n)
            .map(|k| if at_rest(k) { -0.0 } else { (k - 200) as f64 })
            .collect(),
        acc: (0..n)
            .map(|k| if at_rest(k) { -0.0 } else { 1e3 })
            .collect(),
    }
}

// ---------------------------------------------------------------------------------------------
// Drives.

/// Drives without effects.
fn ideal_cases() -> Vec<(String, DriveParams)> {
    let mut out = Vec::new();
    for (kind, p) in [
        ("ppi", table1_drive()),
        ("pid", common::pid(table1_drive(), 0.2)),
        ("smc", common::smc(table1_drive())),
    ] {
        let mut noisy = p.clone();
        noisy.encoder.noise_std = 2e-4;
        noisy.encoder.seed = 5;
        let mut limited = noisy.clone();
        limited.plant.u_max = Some(0.5);
        let mut unquantised = p.clone();
        unquantised.encoder.resolution = 0.0;
        unquantised.plant.coulomb_torque = 0.0;
        let mut slow = noisy.clone();
        slow.servo_rate_hz = 4000.0;
        let mut slowest = p.clone();
        slowest.servo_rate_hz = 1000.0;
        out.extend([
            (kind.to_string(), p),
            (format!("{kind}-noise"), noisy),
            (format!("{kind}-noise-umax"), limited),
            (format!("{kind}-unquantised"), unquantised),
            (format!("{kind}-4kHz"), slow),
            (format!("{kind}-1kHz"), slowest),
        ]);
    }
    for (a, _) in NMV5000_TABLE3 {
        out.push((format!("preset-{a}"), nmv5000_axis_design(a).unwrap()));
    }
    for file in [
        "nmv5000.toml",
        "ballscrew-ppi.toml",
        "ballscrew-pid.toml",
        "ballscrew-smc.toml",
    ] {
        for (a, p) in common::machine_axes(file) {
            out.push((format!("{file}-{a}"), p));
        }
    }
    out
}

/// Drives with effects.
fn effects_cases() -> Vec<(String, DriveParams)> {
    let mut out: Vec<(String, DriveParams)> = common::machine_axes("nmv5000-realistic.toml")
        .into_iter()
        .map(|(a, p)| (format!("realistic-{a}"), p))
        .collect();
    let [base, v1, v2, v3] = common::realistic_table1_variants(0.2);
    let mut v4 = base.clone();
    v4.friction = Some(Friction::Stribeck {
        static_torque: 0.45,
        stribeck_velocity: 1.5,
        stribeck_exponent: 1.3,
        coulomb_torque_negative: Some(0.25),
        static_torque_negative: None,
        location: FrictionLocation::Motor,
    });
    if let Some(c) = v4.compliance.as_mut() {
        c.backlash = 0.003;
    }
    let mut v5 = base.clone();
    if let Some(f) = v5.feedback.as_mut() {
        f.dead_time_cycles = 0;
        f.motor_resolution = Some(1e-5);
        f.motor_noise_std = 2e-5;
    }
    let mut v6 = base.clone();
    v6.servo_rate_hz = 4000.0;
    if let Some(s) = v6.reference.as_mut() {
        s.interpolation_delay_s = 0.0;
    }
    let [with_backlash, other_noise, slow, limited] = common::realistic_lane_variants();
    let mut unquantised = v3.clone();
    unquantised.encoder.resolution = 0.0;
    unquantised.encoder.noise_std = 0.0;
    let mut friction_only = table1_drive();
    friction_only.friction = Some(Friction::Coulomb {
        coulomb_torque_negative: Some(0.2),
        location: FrictionLocation::Load,
    });
    out.extend([
        ("realistic-table1".to_string(), base),
        ("pid-2nd-order-shaping-torque-limit".to_string(), v1),
        ("smc-1st-order-shaping-semi-closed".to_string(), v2),
        ("rigid-stribeck-no-dead-time".to_string(), v3),
        ("rigid-stribeck-unquantised".to_string(), unquantised),
        ("motor-stribeck-backlash".to_string(), v4),
        ("second-encoder-undelayed".to_string(), v5),
        ("4kHz-no-delay".to_string(), v6),
        ("x-backlash".to_string(), with_backlash),
        ("x-other-noise".to_string(), other_noise),
        ("x-7-elements-dead-5".to_string(), slow),
        ("table1-torque-limited".to_string(), limited),
        ("table1-asymmetric-coulomb".to_string(), friction_only),
    ]);
    let mut numbers = ChaCha8Rng::seed_from_u64(77);
    for case in 0..24u64 {
        let mut s = ChaCha8Rng::seed_from_u64(3000 + case);
        out.push((
            format!("random-{case}"),
            common::random_drive(&mut s, &mut numbers),
        ));
    }
    out
}

// ---------------------------------------------------------------------------------------------
// The routes.

/// The whole run, the true position alone, and the streams in odd pieces.
fn single_routes(book: &mut Book, key: &str, d: &Drive, r: Reference<'_>) {
    let whole = d.simulate(r, TS);
    let (sim_key, tp_key) = (format!("sim/{key}"), format!("tp/{key}"));
    let whole = match whole {
        Ok(t) => t,
        Err(e) => {
            book.check(&sim_key, debug_hash(&e));
            return;
        }
    };
    book.check(&sim_key, trace_hash(&whole));
    let (tp, sat) = d.simulate_true_position(r, TS).expect("as simulate");
    book.check(&tp_key, true_position_hash(&tp, sat));
    for (i, (every, seed)) in SPLITS.into_iter().enumerate() {
        // Long runs in pieces of one sample: only their first 400 samples.
        let n = if every == Some(1) {
            r.pos.len().min(400)
        } else {
            r.pos.len()
        };
        let r = common::slice(r, &(0..n));
        let (sk, tk) = if n == whole.len() {
            (sim_key.clone(), tp_key.clone())
        } else {
            let part = d.simulate(r, TS).expect("a prefix simulates");
            let (k1, k2) = (format!("sim400/{key}"), format!("tp400/{key}"));
            book.check(&k1, trace_hash(&part));
            book.check(
                &k2,
                true_position_hash(&part.true_position, part.saturated_ticks),
            );
            (k1, k2)
        };
        for channels in [Channels::All, Channels::TruePosition] {
            let mut s = d.stream(TS, channels).expect("stream");
            let mut t = DriveTrace::default();
            for p in pieces(n, every, seed + i as u64, 997) {
                s.feed(common::slice(r, &p), &mut t).expect("feeds");
            }
            t.saturated_ticks = s.finish().expect("finishes");
            match channels {
                Channels::All => book.check(&sk, trace_hash(&t)),
                Channels::TruePosition => {
                    book.check(&tk, true_position_hash(&t.true_position, t.saturated_ticks))
                }
            }
        }
    }
}

/// Frequency responses, transition matrices and poles.
fn analysis_routes(book: &mut Book, key: &str, d: &Drive, frf: bool) {
    book.check(
        &format!("sampled-matrix/{key}"),
        debug_hash(&d.sampled_transition_matrix()),
    );
    book.check(
        &format!("effective-poles/{key}"),
        debug_hash(&d.effective_poles()),
    );
    book.check(
        &format!("effects-matrix/{key}"),
        debug_hash(&d.effects_transition_matrix()),
    );
    if frf {
        for kind in [
            FrfKind::Tracking,
            FrfKind::LoadTracking,
            FrfKind::Mechanical,
        ] {
            let o = FrfOptions {
                kind,
                f_min_hz: 4.0,
                f_max_hz: 400.0,
                lines: 25,
                settle_periods: 1,
                periods: 2,
                ..FrfOptions::default()
            };
            book.check(
                &format!("frf-{kind:?}/{key}"),
                debug_hash(&d.measure_frf(&o)),
            );
        }
    }
}

/// The whole-run batches of `jobs` (keys of each job's whole run), both entries, and the
/// batched stream of each group in odd pieces.
fn batch_routes(book: &mut Book, name: &str, jobs: &[(&Drive, Reference<'_>)], keys: &[String]) {
    let groups = batch_groups(jobs, TS);
    book.check(&format!("groups/{name}"), debug_hash(&groups));
    let check = |book: &mut Book, i: usize, r: Result<&DriveTrace, &vcnc_drive::Error>| {
        let key = format!("sim/{}", keys[i]);
        match r {
            Ok(t) => book.check(&key, trace_hash(t)),
            Err(e) => book.check(&key, debug_hash(e)),
        }
    };
    for (i, r) in simulate_batch(jobs, TS).iter().enumerate() {
        check(book, i, r.as_ref());
    }
    let mut traces = vec![DriveTrace::default(); 2];
    for (i, r) in simulate_batch_into(jobs, TS, &mut traces)
        .iter()
        .enumerate()
    {
        check(book, i, r.as_ref().map(|()| &traces[i]));
    }
    for (gi, group) in groups.iter().enumerate() {
        let drives: Vec<&Drive> = group.iter().map(|i| jobs[*i].0).collect();
        let n = jobs[group[0]].1.pos.len();
        if group.iter().any(|i| jobs[*i].1.pos.len() != n) {
            continue;
        }
        for channels in [Channels::All, Channels::TruePosition] {
            let Ok(mut s) = GroupStream::new(&drives, TS, channels) else {
                continue;
            };
            let mut out = vec![DriveTrace::default(); group.len()];
            let mut failed = false;
            for p in pieces(n, None, 40 + gi as u64, 1500) {
                let refs: Vec<Reference<'_>> = group
                    .iter()
                    .map(|i| common::slice(jobs[*i].1, &p))
                    .collect();
                if s.feed(&refs, &mut out).is_err() {
                    failed = true;
                    break;
                }
            }
            if failed {
                continue;
            }
            for ((t, sat), i) in out.iter_mut().zip(s.finish()).zip(group) {
                t.saturated_ticks = sat.expect("finishes");
                match channels {
                    Channels::All => book.check(&format!("sim/{}", keys[*i]), trace_hash(t)),
                    Channels::TruePosition => book.check(
                        &format!("tp/{}", keys[*i]),
                        true_position_hash(&t.true_position, t.saturated_ticks),
                    ),
                }
            }
        }
    }
}

#[test]
fn every_route_through_the_engine_gives_the_recorded_bits() {
    let mut book = Book::open();
    let programs = [
        (
            "id7",
            common::identification_program(7, 3.0, TS, 0.0, 20.0, 250.0, 2500.0),
        ),
        (
            "id11-offset",
            common::identification_program(11, 1.5, TS, 120.0, 30.0, 400.0, 5000.0),
        ),
        ("negzero", negative_zero_program()),
    ];
    let mut drives: Vec<(String, Drive)> = Vec::new();
    for (name, p) in ideal_cases().into_iter().chain(effects_cases()) {
        match p.validate() {
            Ok(d) => drives.push((name, d)),
            Err(e) => book.check(&format!("validate/{name}"), debug_hash(&e)),
        }
    }
    assert!(drives.len() > 60, "{} drives", drives.len());
    for (name, d) in &drives {
        let frf = !name.starts_with("random") && !name.contains("kHz");
        analysis_routes(&mut book, name, d, frf);
        for (pn, prog) in &programs {
            single_routes(&mut book, &format!("{name}/{pn}"), d, prog.reference());
        }
    }
    // Batches: the realistic machine in both orders, every drive with effects on one
    // reference (groups of each structure), and ideal and realistic drives side by side.
    let by_name = |n: &str| &drives.iter().find(|(k, _)| k == n).expect(n).1;
    let axes = ["X", "Y", "Z", "A", "C"].map(|a| format!("realistic-{a}"));
    for (pn, prog) in &programs {
        let mut names: Vec<String> = axes.to_vec();
        for order in ["forward", "reverse"] {
            let jobs: Vec<(&Drive, Reference<'_>)> = names
                .iter()
                .map(|n| (by_name(n), prog.reference()))
                .collect();
            let keys: Vec<String> = names.iter().map(|n| format!("{n}/{pn}")).collect();
            batch_routes(&mut book, &format!("machine-{order}/{pn}"), &jobs, &keys);
            names.reverse();
        }
    }
    let (pn, prog) = &programs[0];
    let effects: Vec<&(String, Drive)> = drives
        .iter()
        .filter(|(_, d)| !d.effects().is_ideal())
        .collect();
    let jobs: Vec<(&Drive, Reference<'_>)> =
        effects.iter().map(|(_, d)| (d, prog.reference())).collect();
    let keys: Vec<String> = effects.iter().map(|(n, _)| format!("{n}/{pn}")).collect();
    batch_routes(&mut book, "every-effects-drive", &jobs, &keys);
    let mixed: Vec<&(String, Drive)> = drives.iter().step_by(3).collect();
    let jobs: Vec<(&Drive, Reference<'_>)> =
        mixed.iter().map(|(_, d)| (d, prog.reference())).collect();
    let keys: Vec<String> = mixed.iter().map(|(n, _)| format!("{n}/{pn}")).collect();
    batch_routes(&mut book, "mixed", &jobs, &keys);
    // Same structure, several numbers: groups of random drives of one structure each.
    let mut numbers = ChaCha8Rng::seed_from_u64(2);
    for case in 0..12u64 {
        let mut group: Vec<(String, Drive)> = Vec::new();
        for i in 0..(1 + case as usize % 6) {
            let mut s = ChaCha8Rng::seed_from_u64(1000 + case);
            if let Ok(d) = common::random_drive(&mut s, &mut numbers).validate() {
                group.push((format!("structure-{case}-{i}"), d));
            }
        }
        for (name, d) in &group {
            single_routes(&mut book, &format!("{name}/{pn}"), d, prog.reference());
        }
        let jobs: Vec<(&Drive, Reference<'_>)> =
            group.iter().map(|(_, d)| (d, prog.reference())).collect();
        let keys: Vec<String> = group.iter().map(|(n, _)| format!("{n}/{pn}")).collect();
        batch_routes(&mut book, &format!("structure-{case}"), &jobs, &keys);
    }
    book.finish();
}
