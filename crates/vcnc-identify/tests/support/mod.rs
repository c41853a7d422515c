//! Shared helpers of the integration tests: the paper's identification excitation (section 4:
//! random rest-to-rest trapezoidal moves) and traces of the true drive simulator of
//! `vcnc-drive` (plant with Coulomb friction and sticking, controller at the 20 kHz servo rate,
//! quantised encoder).
#![allow(dead_code)]

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use vcnc_drive::drive_model::ReferenceInput;
use vcnc_drive::{ClosedLoopModel, DriveModel, DriveParams, Poles, Reference};
use vcnc_identify::{Identification, IdentifyOptions, ModelStructure, Trace};

/// A sampled reference: position, velocity, acceleration (axis units, /s, /s²).
pub struct RefSignal {
    pub ts: f64,
    pub pos: Vec<f64>,
    pub vel: Vec<f64>,
    pub acc: Vec<f64>,
}

impl RefSignal {
    pub fn as_ref(&self) -> Reference<'_> {
        Reference {
            pos: &self.pos,
            vel: &self.vel,
            acc: &self.acc,
        }
    }
}

/// One rest-to-rest trapezoidal move (unbounded jerk).
struct Move {
    t0: f64,
    x0: f64,
    dir: f64,
    vp: f64,
    a: f64,
    ta: f64,
    tc: f64,
}

impl Move {
    fn end(&self) -> f64 {
        self.t0 + 2.0 * self.ta + self.tc
    }
    /// (position, velocity, acceleration) at time t within or after the move.
    fn eval(&self, t: f64) -> (f64, f64, f64) {
        let (a, vp, ta, tc) = (self.a, self.vp, self.ta, self.tc);
        let tau = (t - self.t0).max(0.0);
        let d_acc = 0.5 * a * ta * ta;
        let (s, v, acc) = if tau < ta {
            (0.5 * a * tau * tau, a * tau, a)
        } else if tau < ta + tc {
            (d_acc + vp * (tau - ta), vp, 0.0)
        } else if tau < 2.0 * ta + tc {
            let u = tau - ta - tc;
            (d_acc + vp * tc + vp * u - 0.5 * a * u * u, vp - a * u, -a)
        } else {
            (2.0 * d_acc + vp * tc, 0.0, 0.0)
        };
        (self.x0 + self.dir * s, self.dir * v, self.dir * acc)
    }
}

/// The paper's identification excitation (section 4, Fig. 5): `moves` random rest-to-rest
/// trapezoidal moves within ±`range`, feeds up to `vmax`, acceleration `amax`, short and long
/// strokes mixed, frequent reversals, a short random dwell between moves; sampled at `ts`.
pub fn identification_program(
    seed: u64,
    moves: usize,
    range: f64,
    vmax: f64,
    amax: f64,
    ts: f64,
) -> RefSignal {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut list = Vec::with_capacity(moves);
    let mut t = 0.2;
    let mut x = 0.0;
    let mut dir = 1.0;
    for _ in 0..moves {
        let short = rng.random::<f64>() < 0.35;
        let dist = if short {
            0.3 + 4.7 * rng.random::<f64>()
        } else {
            5.0 + 75.0 * rng.random::<f64>()
        };
        if rng.random::<f64>() < 0.6 {
            dir = -dir;
        }
        if (x + dir * dist).abs() > range {
            dir = -dir;
        }
        let target = (x + dir * dist).clamp(-range, range);
        let d = (target - x).abs();
        if d < 1e-6 {
            continue;
        }
        let feed = 10.0 + (vmax - 10.0) * rng.random::<f64>();
        let vp = feed.min((d * amax).sqrt());
        let ta = vp / amax;
        let tc = (d - vp * vp / amax) / vp;
        let m = Move {
            t0: t,
            x0: x,
            dir: (target - x).signum(),
            vp,
            a: amax,
            ta,
            tc: tc.max(0.0),
        };
        t = m.end() + 0.01 + 0.09 * rng.random::<f64>();
        x = target;
        list.push(m);
    }
    let t_end = t + 0.3;
    let n = (t_end / ts).ceil() as usize + 1;
    let (mut pos, mut vel, mut acc) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut i = 0;
    for k in 0..n {
        let tk = k as f64 * ts;
        while i + 1 < list.len() && tk >= list[i + 1].t0 {
            i += 1;
        }
        let (p, v, a) = match list.get(i) {
            Some(m) if tk >= m.t0 => m.eval(tk),
            _ => (0.0, 0.0, 0.0),
        };
        pos[k] = p;
        vel[k] = v;
        acc[k] = a;
    }
    RefSignal { ts, pos, vel, acc }
}

/// The paper's program: 70 moves, ±50 mm, 250 mm/s, 2500 mm/s², 1 ms.
pub fn paper_program(seed: u64) -> RefSignal {
    identification_program(seed, 70, 50.0, 250.0, 2500.0, 1e-3)
}

/// The identification program of docs/gcode.md as `vcnc-gcode` generates it (paper section 4:
/// 70 random moves within ±50, feeds up to 250/s), interpolated at 1 ms with acceleration
/// `amax` (2500 mm/s² in the paper): G-code text → parse → interpret → trapezoidal profiles.
pub fn gcode_program(axis: vcnc_gcode::AxisName, seed: u64, amax: f64) -> RefSignal {
    let opts = vcnc_gcode::IdentificationOptions {
        seed,
        ..Default::default()
    };
    let text = vcnc_gcode::identification(axis, &opts).expect("program");
    let (program, diags) = vcnc_gcode::parse(&text);
    assert!(
        diags
            .iter()
            .all(|d| d.severity != vcnc_gcode::Severity::Error),
        "{diags:?}"
    );
    let (tp, _) =
        vcnc_gcode::interpret(&program, &vcnc_gcode::InterpOptions::default()).expect("interprets");
    let limits = vcnc_gcode::Limits::uniform(opts.max_feed, amax);
    let traj = vcnc_gcode::interpolate(&tp, &limits, &vcnc_gcode::InterpolateOptions::default())
        .expect("interpolates");
    let track = traj.axis(axis).expect("axis track");
    RefSignal {
        ts: traj.ts,
        pos: track.pos.clone(),
        vel: track.vel.clone(),
        acc: track.acc.clone(),
    }
}

/// Simulates the true drive and returns the identification trace (encoder reading).
pub fn drive_trace(params: &DriveParams, r: &RefSignal) -> Trace {
    let out = vcnc_drive::simulate_drive(params, r.as_ref(), r.ts).expect("drive simulates");
    Trace::new(r.ts, r.pos.clone(), out.position)
        .and_then(|t| t.with_reference_derivatives(r.vel.clone(), r.acc.clone()))
        .expect("valid trace")
}

/// Relative error (signed) of `est` against `truth`.
pub fn rel(est: f64, truth: f64) -> f64 {
    (est - truth) / truth
}

/// Prints one comparison line (for the report) and returns the (p, wn, zeta, dc) relative errors.
pub fn compare(name: &str, m: &ClosedLoopModel, truth: &ClosedLoopModel) -> [f64; 4] {
    let (pe, pt) = (m.poles().expect("poles"), truth.poles().expect("poles"));
    let e = [
        rel(pe.p, pt.p),
        rel(pe.wn, pt.wn),
        rel(pe.zeta, pt.zeta),
        rel(m.dc, truth.dc),
    ];
    println!(
        "{name:>22}: p {:8.4} Hz ({:+6.2} %)  wn {:8.4} Hz ({:+6.2} %)  zeta {:6.4} ({:+6.2} %)  dc {:9.3} ({:+6.2} %)",
        pe.p_hz(),
        100.0 * e[0],
        pe.wn_hz(),
        100.0 * e[1],
        pe.zeta,
        100.0 * e[2],
        m.dc,
        100.0 * e[3]
    );
    e
}

/// A seed drawn anew for every call from the operating system's entropy (the standard
/// library's randomly keyed hasher), for test cases that must not be a fixed set.
pub fn fresh_seed() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    std::collections::hash_map::RandomState::new()
        .build_hasher()
        .finish()
}

/// The identification options of `vcnc identify --trace` without an options file
/// (vcnc-pipeline's `identifier_options`): every model structure and both model inputs, chosen
/// on a held-out part, and the real pole allowed towards 0 (a measured drive may lack integral
/// action).
pub fn command_options() -> IdentifyOptions {
    let mut opts = IdentifyOptions {
        structures: ModelStructure::ALL.to_vec(),
        inputs: vec![ReferenceInput::Smooth, ReferenceInput::Hold],
        ..IdentifyOptions::default()
    };
    opts.bounds.p_hz[0] = opts.bounds.p_hz[0].min(1e-4);
    opts
}

/// Relative errors of the identified model's (p, ωn, ζ) as it reports them (the canonical
/// split of `ClosedLoopModel::poles`, which its standard deviations refer to) against the
/// truth written in the split nearest to them: with three real poles any of them may be p,
/// a convention rather than a property of the drive, so the truth is split the same way.
pub fn pole_errors(m: &ClosedLoopModel, truth: &ClosedLoopModel) -> [f64; 3] {
    let splits = |m: &ClosedLoopModel| -> Vec<Poles> {
        let mut out: Vec<Poles> = m.poles().into_iter().collect();
        let roots = m.roots();
        if roots.iter().all(|r| r.im == 0.0) {
            for i in 0..3 {
                let o: Vec<f64> = (0..3).filter(|&k| k != i).map(|k| roots[k].re).collect();
                if o[0] * o[1] > 0.0 {
                    let wn = (o[0] * o[1]).sqrt();
                    out.push(Poles {
                        p: -roots[i].re,
                        wn,
                        zeta: -(o[0] + o[1]) / (2.0 * wn),
                    });
                }
            }
        }
        out
    };
    let Some(p) = m.poles() else {
        return [f64::INFINITY; 3];
    };
    let worst = |e: &[f64; 3]| e.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let mut best = [f64::INFINITY; 3];
    for pt in splits(truth) {
        let e = [
            (p.p - pt.p) / pt.p,
            (p.wn - pt.wn) / pt.wn,
            (p.zeta - pt.zeta) / pt.zeta,
        ];
        if worst(&e) < worst(&best) {
            best = e;
        }
    }
    best
}

/// Free-run RMS error of `model` on a trace (from rest), axis units.
pub fn freerun_rms(model: &DriveModel, tr: &Trace) -> f64 {
    let xh = vcnc_identify::free_run_model(model, tr).expect("free run");
    let s: f64 = xh.iter().zip(&tr.x).map(|(a, b)| (a - b) * (a - b)).sum();
    (s / tr.len() as f64).sqrt()
}

/// The middle columns of a drive's row in a suite's table: sample period (ms), encoder step
/// (µm), whether the trace starts moving; the true (p, ωn, ζ) in Hz, Hz and 1, the identified
/// ones (NaN when the model has none), the relative errors `errs` and the reported relative
/// deviations `rel_std`, both in %; the chosen structure and input.
pub fn fit_columns(
    ts: f64,
    resolution: f64,
    moving: bool,
    tp: &Poles,
    id: &Identification,
    errs: &[f64; 3],
    rel_std: &[f64; 3],
) -> String {
    let ip = id.model.core.poles();
    format!(
        "{:4.2} {:5.3} {:4} | {:6.2} {:6.2} {:5.3} | {:6.2} {:6.2} {:5.3} | {:+6.2} {:+6.2} {:+6.2} | {:5.2} {:5.2} {:5.2} | {:19} {:6}",
        1e3 * ts,
        1e3 * resolution,
        if moving { "mov" } else { "rest" },
        tp.p_hz(),
        tp.wn_hz(),
        tp.zeta,
        ip.map_or(f64::NAN, |p| p.p_hz()),
        ip.map_or(f64::NAN, |p| p.wn_hz()),
        ip.map_or(f64::NAN, |p| p.zeta),
        100.0 * errs[0],
        100.0 * errs[1],
        100.0 * errs[2],
        100.0 * rel_std[0],
        100.0 * rel_std[1],
        100.0 * rel_std[2],
        id.structure.name(),
        id.input.name(),
    )
}

/// A drive's verdict in a suite.
pub struct Score {
    /// Every pole within the fixed tolerances.
    pub fixed_ok: bool,
    /// The drive passes.
    pub ok: bool,
    /// Relative errors of p, ωn, ζ.
    pub errs: [f64; 3],
    /// |error| / reported relative deviation of p, ωn, ζ.
    pub z: [f64; 3],
    /// Validation ratio: the identified model's free-run RMS over the true model's.
    pub ratio: f64,
}

impl Score {
    pub fn new(fixed_ok: bool, ok: bool, errs: [f64; 3], rel_std: &[f64; 3], ratio: f64) -> Score {
        Score {
            fixed_ok,
            ok,
            errs,
            z: std::array::from_fn(|i| errs[i].abs() / rel_std[i]),
            ratio,
        }
    }
}

/// The statistics line of a suite: how many drives pass and how many are within the fixed
/// tolerances (then `note`); per parameter (p, ωn, ζ) the worst and median |relative error|
/// and how many are within ±1σ and ±3σ of their reported deviation; the worst and median
/// validation ratio.
pub fn summary_line(rows: &[&Score], note: &str) -> String {
    let n = rows.len();
    let fixed = rows.iter().filter(|r| r.fixed_ok).count();
    let ok = rows.iter().filter(|r| r.ok).count();
    let stat = |f: &dyn Fn(&Score) -> f64| {
        let mut v: Vec<f64> = rows.iter().map(|r| f(r)).collect();
        v.sort_by(f64::total_cmp);
        (v[n - 1], v[n / 2])
    };
    let mut line = format!("{ok}/{n} pass, {fixed}/{n} within fixed tolerances{note};");
    for (i, name) in ["p", "wn", "zeta"].iter().enumerate() {
        let (w, m) = stat(&|r| r.errs[i].abs());
        let c1 = rows.iter().filter(|r| r.z[i] <= 1.0).count();
        let c3 = rows.iter().filter(|r| r.z[i] <= 3.0).count();
        line += &format!(
            " {name} |err| worst/median {:.2}/{:.2} %, within ±1σ {c1}/{n}, ±3σ {c3}/{n};",
            100.0 * w,
            100.0 * m
        );
    }
    let (wr, mr) = stat(&|r| r.ratio);
    line += &format!(" validation ratio worst/median {wr:.3}/{mr:.3}");
    line
}
