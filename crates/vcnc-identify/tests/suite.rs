//! Randomised accuracy suite (issue 18): independent random drives, identified from CSV files
//! that hold only `t, xr, x`, as a user's scope recording would.
//!
//! Truth: the analytic closed-loop model of each drive's physical parameters
//! (`DriveParams::closed_loop_model`, docs/drive-model.md). The traces come from the true drive
//! simulator of `vcnc-drive` (plant with Coulomb friction and sticking, P-PI or PID controller
//! with random feed-forward, quantised encoder) run at a servo rate of at least 200 kHz, so that
//! the continuous model is the truth: each drive's true position is checked against a fine
//! simulation of the analytic model (within 0.2 µm) before the drive counts.
//!
//! Two conventions of the simulated controls, stated because they decide that claim and the
//! model's input:
//! - the loop's encoder is ideal and the logged position is quantised (0.05–1 µm): an encoder
//!   of 0.4 µm in a 200 kHz loop differentiated for velocity feedback made the drive depart
//!   from the continuous model by 0.3 µm (limit cycling of the quantised velocity);
//! - the control interpolates its logged setpoints linearly at the servo rate and derives its
//!   feed-forward from them (velocity = slope, acceleration = slope changes), which is what
//!   a model can know from a log of positions. A control that feeds forward the exact
//!   derivatives of a trapezoidal profile instead differs from it by a sawtooth within each
//!   sample: on one drive (Ts = 1.72 ms, 5000 mm/s²) that biased ζ by −5 % through the fit.
//!
//! Per drive (the issue's acceptance):
//! - the identified model is stable;
//! - ωn and p within 2 %, ζ within 5 % — or, where the reported relative standard deviation of
//!   that parameter exceeds 1 % (a weakly determined pole), an error within three reported
//!   standard deviations;
//! - the free-run RMS error on a second, unseen program of the same drive is at most 1.2 × the
//!   true model's;
//! - and at least 90 % of the drives meet the fixed tolerances outright.
//!
//! Drives whose control shapes the reference before the loop (a dead time of 20–90 ms, or a
//! first- or second-order nominal-position filter; the shaping is done here, at the fine
//! rate, before the reference enters the drive simulator) are identified with the extended model
//! structures; the table shows the 7-parameter model's validation error beside the extended one,
//! which must come within 1.2 × the true extended model's.
//!
//! Run it (prints the table):
//!
//! ```text
//! cargo test --release -p vcnc-identify --test suite -- --nocapture
//! ```
//!
//! By default (and in CI) that is the 64 fixed drives and two shaped ones, about two minutes
//! on two cores; `VCNC_SUITE=full` adds six shaped drives, `VCNC_SUITE_IDS=3,56` runs only
//! those drives, and `--ignored` the fresh drives (below).
//! The per-drive step is [`identify_csv`]: CSV path in, identification out, the library route
//! of `vcnc identify --trace FILE.csv`; swapping it for the binary changes nothing else.

mod support;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use support::RefSignal;
use vcnc_drive::{
    Channels, ClosedLoopModel, ControllerSpec, DriveModel, DriveParams, DriveTrace, Encoder, Plant,
    Poles, Reference, SimOptions,
};
use vcnc_identify::{Identification, ReferenceInput, Trace, identify};

/// Drives of the fixed suite.
const FULL_DRIVES: usize = 64;

/// Fresh drives per run.
const FRESH_DRIVES: usize = 32;

/// Smallest servo rate of the simulated drives, Hz.
const MIN_SERVO_HZ: f64 = 200_000.0;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    PPi,
    Pid,
}

/// How the control shapes the reference before the loop.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Shaping {
    None,
    /// Dead time, s.
    Delay(f64),
    /// First-order filter, time constant s.
    Filter1(f64),
    /// Second-order filter, natural frequency Hz and damping.
    Filter2(f64, f64),
}

#[derive(Debug, Clone)]
struct SuiteDrive {
    id: usize,
    kind: Kind,
    params: DriveParams,
    ts: f64,
    moving: bool,
    vmax: f64,
    amax: f64,
    shaping: Shaping,
    /// Resolution of the logged position, axis units.
    resolution: f64,
}

fn log_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    (lo.ln() + (hi.ln() - lo.ln()) * rng.random::<f64>()).exp()
}

fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

/// A random drive: plant, controller kind and gains from random poles (both roots of the P-PI
/// design), random feed-forward, encoder, sample period, start condition.
fn random_drive(id: usize, shaping: Shaping) -> SuiteDrive {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5u64 << 32 | id as u64);
    loop {
        let j = log_uniform(&mut rng, 0.002, 0.05);
        let b_over_j = log_uniform(&mut rng, 0.5, 20.0);
        let kt = log_uniform(&mut rng, 0.3, 3.0);
        let pitch = uniform(&mut rng, 5.0, 20.0);
        let rg = pitch / std::f64::consts::TAU;
        let dc = log_uniform(&mut rng, 20.0, 250.0);
        let plant = Plant {
            j,
            b: b_over_j * j,
            ka: 1.0,
            kt,
            rg,
            coulomb_torque: dc * j / rg,
            u_max: None,
        };
        let kind = if rng.random::<f64>() < 0.6 {
            Kind::PPi
        } else {
            Kind::Pid
        };
        let poles = Poles::from_hz(
            log_uniform(&mut rng, 3.0, 40.0),
            log_uniform(&mut rng, 15.0, 90.0),
            uniform(&mut rng, 0.3, 1.4),
        );
        let (vff, bff, jff) = (
            rng.random::<f64>(),
            rng.random::<f64>(),
            0.5 * rng.random::<f64>(),
        );
        let larger_root = rng.random::<f64>() < 0.5;
        let (a1, a2, a3) = poles.denominator();
        let k = plant.ka_kt();
        let controller = match kind {
            Kind::PPi => {
                // P = Ka Kt Kp / J = a1 - B/J; Kv rg solves P K^2 - a2 K + a3 = 0
                // (docs/drive-model.md), either root.
                let pp = a1 - b_over_j;
                let disc = a2 * a2 - 4.0 * pp * a3;
                if pp <= 0.0 || disc < 0.0 {
                    continue;
                }
                let kk = if larger_root {
                    (a2 + disc.sqrt()) / (2.0 * pp)
                } else {
                    2.0 * a3 / (a2 + disc.sqrt())
                };
                ControllerSpec::PPi {
                    kv: Some(kk / rg),
                    kp: Some(pp * j / k),
                    ki: Some(a3 * j / (kk * k)),
                    design: None,
                    vff,
                    bff,
                    jff,
                }
            }
            Kind::Pid => {
                let kr = k * rg / j;
                let kd = (a1 - b_over_j) / kr;
                if kd <= 0.0 {
                    continue;
                }
                ControllerSpec::Pid {
                    kp: Some(a2 / kr),
                    ki: Some(a3 / kr),
                    kd: Some(kd),
                    design: None,
                    jff,
                    bff,
                }
            }
        };
        let ts = (uniform(&mut rng, 0.5, 2.0) * 1e3).round() * 1e-6;
        let resolution = log_uniform(&mut rng, 0.05e-3, 1e-3);
        let moving = rng.random::<f64>() < 0.35;
        let vmax = uniform(&mut rng, 100.0, 300.0);
        let amax = uniform(&mut rng, 1000.0, 5000.0);
        let params = DriveParams {
            plant,
            controller,
            encoder: Encoder::ideal(),
            servo_rate_hz: 1.0,
            compliance: None,
            friction: None,
            current_loop: None,
            feedback: None,
            reference: None,
        };
        let sd = SuiteDrive {
            id,
            kind,
            params,
            ts,
            moving,
            vmax,
            amax,
            shaping,
            resolution,
        };
        if sd.params_at(ts).validate().is_ok() {
            return sd;
        }
    }
}

impl SuiteDrive {
    /// The drive's parameters with the servo rate set for logging period `ts_log`: the smallest
    /// whole multiple of the logging rate at or above [`MIN_SERVO_HZ`].
    fn params_at(&self, ts_log: f64) -> DriveParams {
        let ticks = (MIN_SERVO_HZ * ts_log).ceil();
        DriveParams {
            servo_rate_hz: ticks / ts_log,
            ..self.params.clone()
        }
    }

    fn truth(&self) -> ClosedLoopModel {
        self.params_at(self.ts)
            .closed_loop_model()
            .expect("valid drive")
    }

    fn kind_name(&self) -> &'static str {
        match self.kind {
            Kind::PPi => "p-pi",
            Kind::Pid => "pid",
        }
    }
}

/// One simulated run: what the CSV holds (t, xr, x at Ts) and the drive's true position.
struct Run {
    t: Vec<f64>,
    xr: Vec<f64>,
    x: Vec<f64>,
    /// Largest gap between the drive's true position and the analytic model driven by the same
    /// reference, over every servo tick of the whole run before any cut, axis units (see
    /// [`run_drive`]).
    gap: f64,
}

/// Linear interpolation of a sampled signal at fractional index `s` (held at the ends).
fn interp(v: &[f64], s: f64) -> f64 {
    if s <= 0.0 {
        return v[0];
    }
    let i = s.floor() as usize;
    if i + 1 >= v.len() {
        return v[v.len() - 1];
    }
    let f = s - i as f64;
    v[i] + f * (v[i + 1] - v[i])
}

/// The reference the loop receives, made a piece at a time at the servo tick `h = r.ts / m`
/// (the drive then has nothing to interpolate): the control interpolates its logged setpoints
/// linearly (first-order hold) and derives its feed-forward from them (the hold's slope as
/// velocity, its slope changes as acceleration pulses of the same area), then shapes the result
/// (dead time; reference filter integrated with RK4 at the tick, independent of the library's
/// discretisation). Only the setpoints `r.pos` are used.
///
/// Each tick's sample is what the hold gives *around* it: the velocity is the hold's slope
/// averaged over the tick's own interval (a slope change at a knot becomes a ramp centred on the
/// knot) and each acceleration pulse is split between the two ticks around its knot, so that its
/// centre is the knot. Until 2026-11-29 the reference was made at a 50 µs step with the knot's
/// sample already holding the new slope; the drive interpolated it linearly, so the velocity
/// feed-forward led the hold by 25 µs: on fresh drives with strong feed-forward that biased the
/// fitted ωn by up to +1.4 %, and the identified model predicted the unseen program better than
/// this "truth" (validation ratios 0.2–0.9; issue 30). Made whole at the tick, the reference of
/// a long trace took 1.5 GB; made in pieces it takes O(piece).
struct LoopReference<'a> {
    r: &'a RefSignal,
    /// Ticks per logged sample.
    m: usize,
    /// The tick, s.
    h: f64,
    delay: f64,
    shaping: Shaping,
    /// Ticks in the whole reference.
    n: usize,
    /// The next tick to make.
    next: usize,
    /// The reference filter's state (position, velocity), from the first tick on.
    filter: Option<(f64, f64)>,
}

impl<'a> LoopReference<'a> {
    fn new(r: &'a RefSignal, m: usize, shaping: Shaping) -> Self {
        LoopReference {
            r,
            m,
            h: r.ts / m as f64,
            delay: match shaping {
                Shaping::Delay(d) => d,
                _ => 0.0,
            },
            shaping,
            n: (r.pos.len() - 1) * m + 1,
            next: 0,
            filter: None,
        }
    }

    /// The hold's slope over logged interval `j` (0 outside the log).
    fn slope(&self, j: isize) -> f64 {
        let p = &self.r.pos;
        if j < 0 || j as usize + 1 >= p.len() {
            0.0
        } else {
            (p[j as usize + 1] - p[j as usize]) / self.r.ts
        }
    }

    /// The unshaped (but delayed) position and velocity at tick `k`.
    fn hold_at(&self, k: usize) -> (f64, f64) {
        let s = k as f64 / self.m as f64 - self.delay / self.r.ts;
        let half = 0.5 / self.m as f64;
        let (a, b) = (s - half, s + half);
        let c = b.floor();
        let vel = if a.floor() == c {
            self.slope(c as isize)
        } else {
            (self.slope(c as isize - 1) * (c - a) + self.slope(c as isize) * (b - c)) / (b - a)
        };
        (interp(&self.r.pos, s), vel)
    }

    /// Makes the next ticks, at most `len`, into `pos`, `vel`, `acc` (cleared first); false
    /// when the reference is done.
    fn piece(
        &mut self,
        len: usize,
        pos: &mut Vec<f64>,
        vel: &mut Vec<f64>,
        acc: &mut Vec<f64>,
    ) -> bool {
        let (k0, k1) = (self.next, (self.next + len).min(self.n));
        self.next = k1;
        pos.clear();
        vel.clear();
        acc.clear();
        if k0 == k1 {
            return false;
        }
        for k in k0..k1 {
            let (p, v) = self.hold_at(k);
            pos.push(p);
            vel.push(v);
            acc.push(0.0);
        }
        // The acceleration pulses of the knots whose two ticks fall in this piece, in the order
        // of the knots (the knots at x = (j Ts + delay)/h ticks, each pulse split between
        // ticks floor(x) and floor(x) + 1).
        let (ts, h) = (self.r.ts, self.h);
        let j_lo = (((k0 as f64 - 1.0) * h - self.delay) / ts).floor() as isize - 1;
        let j_hi = ((k1 as f64 * h - self.delay) / ts).ceil() as isize + 1;
        for j in j_lo.max(0)..j_hi.min(self.r.pos.len() as isize) {
            let x = (j as f64 * ts + self.delay) / h;
            let (t0, w1) = (x.floor(), x - x.floor());
            let area = (self.slope(j) - self.slope(j - 1)) / h;
            for (t, w) in [(t0, 1.0 - w1), (t0 + 1.0, w1)] {
                if w > 0.0 && t >= k0 as f64 && t < k1 as f64 {
                    acc[t as usize - k0] += w * area;
                }
            }
        }
        match self.shaping {
            Shaping::None | Shaping::Delay(_) => {}
            Shaping::Filter1(tau) => {
                // y' = (u - y)/tau with u piecewise linear: RK4 is exact to O(h^5) per step.
                let (mut y, _) = *self.filter.get_or_insert((pos[0], 0.0));
                for i in 0..pos.len() {
                    let (u0, u1) = (pos[i], self.next_position(k0 + i, pos));
                    let (py, pv) = (y, (u0 - y) / tau);
                    let pa = (vel[i] - pv) / tau;
                    let u = |s: f64| u0 + s * (u1 - u0);
                    let f = |s: f64, y: f64| (u(s) - y) / tau;
                    let k1_ = f(0.0, y);
                    let k2 = f(0.5, y + 0.5 * h * k1_);
                    let k3 = f(0.5, y + 0.5 * h * k2);
                    let k4 = f(1.0, y + h * k3);
                    y += h / 6.0 * (k1_ + 2.0 * k2 + 2.0 * k3 + k4);
                    (pos[i], vel[i], acc[i]) = (py, pv, pa);
                }
                self.filter = Some((y, 0.0));
            }
            Shaping::Filter2(f_hz, zeta) => {
                let w = std::f64::consts::TAU * f_hz;
                let (mut y, mut v) = *self.filter.get_or_insert((pos[0], 0.0));
                for i in 0..pos.len() {
                    let (u0, u1) = (pos[i], self.next_position(k0 + i, pos));
                    let (py, pv) = (y, v);
                    let pa = w * w * (u0 - y) - 2.0 * zeta * w * v;
                    let u = |s: f64| u0 + s * (u1 - u0);
                    let f = |s: f64, y: f64, v: f64| (v, w * w * (u(s) - y) - 2.0 * zeta * w * v);
                    let (a1, b1) = f(0.0, y, v);
                    let (a2, b2) = f(0.5, y + 0.5 * h * a1, v + 0.5 * h * b1);
                    let (a3, b3) = f(0.5, y + 0.5 * h * a2, v + 0.5 * h * b2);
                    let (a4, b4) = f(1.0, y + h * a3, v + h * b3);
                    y += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
                    v += h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4);
                    (pos[i], vel[i], acc[i]) = (py, pv, pa);
                }
                self.filter = Some((y, v));
            }
        }
        true
    }

    /// The unshaped position at the tick after `k` (the filters' step needs it), from the
    /// piece `pos` (which starts at tick `self.next - pos.len()`) while that holds it
    /// unshaped; the last tick's is its own (the filter is not stepped past the end).
    fn next_position(&self, k: usize, pos: &[f64]) -> f64 {
        let k0 = self.next - pos.len();
        if k + 1 < self.next {
            pos[k + 1 - k0]
        } else if k + 1 < self.n {
            self.hold_at(k + 1).0
        } else {
            pos[k - k0]
        }
    }
}

/// Runs the drive through program `r` (sampled at the drive's Ts), logging at Ts: the loop's
/// reference is made at every servo tick ([`LoopReference`], in pieces) and fed to the true
/// drive and to the analytic model side by side; the log keeps the drive's true position at
/// the logged samples, quantised, and the largest gap between the two over every tick.
fn run_drive(d: &SuiteDrive, r: &RefSignal, cut: bool) -> Run {
    let m = (d.ts * MIN_SERVO_HZ).ceil().max(1.0) as usize;
    let mut lr = LoopReference::new(r, m, d.shaping);
    // One servo tick per fine sample: the servo rate is m / Ts ([`SuiteDrive::params_at`]).
    let drive = d.params_at(d.ts).validate().expect("valid drive");
    let mut drive_run = drive
        .stream(lr.h, Channels::TruePosition)
        .expect("drive streams");
    // Sticking friction at the tick, the drive's own: both start at rest at the first sample.
    let mut model_run = d
        .truth()
        .stream(lr.h, &SimOptions::default())
        .expect("model streams");
    let q = d.resolution;
    let mut x = Vec::with_capacity(r.pos.len());
    let mut gap = 0.0_f64;
    let (mut pos, mut vel, mut acc) = (vec![], vec![], vec![]);
    let (mut trace, mut xm) = (DriveTrace::default(), vec![]);
    while lr.piece(512 * m, &mut pos, &mut vel, &mut acc) {
        let piece = Reference {
            pos: &pos,
            vel: &vel,
            acc: &acc,
        };
        // The piece's first tick.
        let k0 = lr.next - pos.len();
        trace.true_position.clear();
        xm.clear();
        drive_run.feed(piece, &mut trace).expect("drive simulates");
        model_run.feed(piece, &mut xm).expect("model simulates");
        for (i, (a, b)) in trace.true_position.iter().zip(&xm).enumerate() {
            gap = gap.max((a - b).abs());
            if (k0 + i).is_multiple_of(m) {
                x.push(q * (a / q).round());
            }
        }
    }
    drive_run.finish().expect("drive simulates");
    let n = r.pos.len();
    assert_eq!(x.len(), n);
    let mut run = Run {
        t: (0..n).map(|k| k as f64 * r.ts).collect(),
        xr: r.pos.clone(),
        x,
        gap,
    };
    if cut && d.moving {
        // A cut-out of a longer log: start 1.5 s in, within a move if there is one nearby.
        let k0 = (1.5 / r.ts) as usize;
        let k0 = (k0..n)
            .find(|&k| r.vel[k].abs() > 20.0)
            .unwrap_or(k0)
            .min(n / 4);
        run.t.drain(..k0);
        run.xr.drain(..k0);
        run.x.drain(..k0);
    }
    run
}

fn write_csv(path: &Path, run: &Run) {
    let mut s = String::with_capacity(run.t.len() * 48);
    s.push_str("t,xr,x\n");
    for k in 0..run.t.len() {
        let _ = writeln!(s, "{},{},{}", run.t[k], run.xr[k], run.x[k]);
    }
    std::fs::write(path, s).expect("write csv");
}

/// Reads a `t, xr, x` CSV into a checked trace (the command's route: columns by header name,
/// time column checked).
fn read_csv(path: &Path) -> Result<Trace, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .ok_or("empty file")?
        .split(',')
        .map(str::trim)
        .collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or(format!("no column {name}"))
    };
    let idx = [col("t")?, col("xr")?, col("x")?];
    let mut cols: [Vec<f64>; 3] = Default::default();
    for (row, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        for (c, &i) in idx.iter().enumerate() {
            let v: f64 = f.get(i).and_then(|s| s.trim().parse().ok()).ok_or(format!(
                "{}:{}: bad number",
                path.display(),
                row + 2
            ))?;
            cols[c].push(v);
        }
    }
    let [t, xr, x] = cols;
    Trace::from_columns(&t, &xr, &x).map_err(|e| format!("{}: {e}", path.display()))
}

/// The per-drive step: CSV file in, identification out.
fn identify_csv(path: &Path) -> Result<Identification, String> {
    let trace = read_csv(path)?;
    identify(&trace, &support::command_options()).map_err(|e| format!("{}: {e}", path.display()))
}

struct Row {
    /// The drive's line of the table.
    line: String,
    /// Whether the estimation trace starts moving.
    moving: bool,
    score: support::Score,
}

fn run_one(d: &SuiteDrive, dir: &Path) -> Row {
    let truth = d.truth();
    let tp = truth.poles().expect("poles");
    let prog = |seed: u64| support::identification_program(seed, 70, 50.0, d.vmax, d.amax, d.ts);
    // The estimation trace of a "moving" drive is a cut-out of a longer log; the validation
    // program starts at rest, so that the comparison with the true model is one of dynamics,
    // not of a guessed initial state.
    let est_run = run_drive(d, &prog(1000 + d.id as u64), true);
    let val_run = run_drive(d, &prog(5000 + d.id as u64), false);
    let gap = est_run.gap.max(val_run.gap);
    let est_path = dir.join(format!("drive{:03}_est.csv", d.id));
    let val_path = dir.join(format!("drive{:03}_val.csv", d.id));
    write_csv(&est_path, &est_run);
    write_csv(&val_path, &val_run);
    let id = identify_csv(&est_path).expect("identifies");
    let val = read_csv(&val_path).expect("validation trace");
    // The model the command writes to model.toml: the chosen candidate's.
    let m = id.model.core;
    if std::env::var("VCNC_SUITE_DEBUG").is_ok() {
        eprintln!("DEBUG {} {:?}", d.id, id.uncertainty);
        for f in &id.structures {
            eprintln!(
                "DEBUG   {} {} whole {} val {:?} {:?} {:?}",
                f.structure,
                f.input,
                f.whole,
                f.validation.as_ref().map(|v| v.freerun_rms),
                f.verdict,
                f.degenerate
            );
            for st in &f.refinement.stages {
                eprintln!(
                    "DEBUG      stage {:?} cost {:e} fr {:e} poles {:?}",
                    st.sign,
                    st.cost,
                    st.freerun_rms,
                    st.model.core.poles().map(|p| (p.p_hz(), p.wn_hz(), p.zeta))
                );
            }
        }
    }
    let errs = support::pole_errors(&m, &truth);
    let rv = support::freerun_rms(&id.model, &val);
    // The suite's controls differentiate their setpoints (module documentation): the true
    // model's input is the hold of the logged reference.
    let true_model = DriveModel {
        input: ReferenceInput::Hold,
        ..DriveModel::from(truth)
    };
    let rt = support::freerun_rms(&true_model, &val);
    let ratio = rv / rt;
    let tol = [0.02, 0.02, 0.05];
    let fixed_ok = (0..3).all(|i| errs[i].abs() <= tol[i]);
    // Reported relative standard deviations of p, wn, zeta (issue 18 item 5).
    let rel_std: [f64; 3] = match &id.uncertainty {
        Some(u) => ["p_hz", "wn_hz", "zeta"].map(|n| u.get(n).map_or(f64::NAN, |q| q.relative())),
        None => [f64::NAN; 3],
    };
    // A weakly determined pole (relative deviation above 1 %) may miss the fixed tolerance
    // if it stays within three reported deviations.
    let sigma_ok = (0..3).all(|i| {
        errs[i].abs() <= tol[i] || (rel_std[i] > 0.01 && errs[i].abs() <= 3.0 * rel_std[i])
    });
    // The continuous model must be the truth within 0.2 µm for the drive to count.
    assert!(gap <= 2e-4, "drive {}: truth gap {} µm", d.id, 1e3 * gap);
    let ok = m.is_stable() && sigma_ok && ratio <= 1.2;
    let line = format!(
        "{:10} {:4} {} | {:7.3} {:7.3} {:5.2} | {:6.3} {}",
        d.id,
        d.kind_name(),
        support::fit_columns(d.ts, d.resolution, d.moving, &tp, &id, &errs, &rel_std),
        1e3 * rv,
        1e3 * rt,
        ratio,
        1e3 * gap,
        if ok { "ok" } else { "FAIL" }
    );
    Row {
        line,
        moving: d.moving,
        score: support::Score::new(fixed_ok, ok, errs, &rel_std, ratio),
    }
}

/// The table's last lines: passes, worst and median |error| per parameter, the coverage of
/// ±1σ and ±3σ, the validation ratio; then the suite's acceptance (every drive passes, at
/// least 90 % within the fixed tolerances).
fn judge(rows: &[Row]) {
    let n = rows.len();
    let fixed = rows.iter().filter(|r| r.score.fixed_ok).count();
    let moving = rows.iter().filter(|r| r.moving).count();
    let scores: Vec<&support::Score> = rows.iter().map(|r| &r.score).collect();
    let note = format!(" ({moving} moving starts)");
    println!("{}", support::summary_line(&scores, &note));
    let failed: Vec<&str> = rows
        .iter()
        .filter(|r| !r.score.ok)
        .map(|r| r.line.as_str())
        .collect();
    assert!(failed.is_empty(), "failed drives:\n{}", failed.join("\n"));
    assert!(
        10 * fixed >= 9 * n,
        "{fixed}/{n} within the fixed tolerances"
    );
}

const HEADER: &str = "id         kind Ts_ms q_um start | true p_Hz wn_Hz zeta | ident p_Hz wn_Hz zeta | err% p wn zeta | std% p wn zeta | structure           input  | val_rms_um ident true ratio | truth_gap_um";

/// The drives `ids`, two at a time (each drive's simulation runs on one core), rows printed in
/// the order of `ids`.
fn run_all(ids: &[usize], dir: &Path) -> Vec<Row> {
    use rayon::prelude::*;
    let rows: Vec<Row> = ids
        .par_iter()
        .map(|&i| run_one(&random_drive(i, Shaping::None), dir))
        .collect();
    for r in &rows {
        println!("{}", r.line);
    }
    rows
}

fn suite_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("vcnc-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

#[test]
fn randomised_drives_are_identified_from_csv() {
    // The 64 fixed drives (the development set of issues 18 and 30); VCNC_SUITE_IDS=3,17 runs
    // only those drives (to look at one).
    let dir = suite_dir("suite");
    let ids: Vec<usize> = match std::env::var("VCNC_SUITE_IDS") {
        Ok(v) => v.split(',').filter_map(|s| s.trim().parse().ok()).collect(),
        Err(_) => (0..FULL_DRIVES).collect(),
    };
    println!("{HEADER}");
    let rows = run_all(&ids, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    judge(&rows);
}

/// Fresh drives of the same generator, whose ids are drawn anew for every run and printed
/// (rerun one with `VCNC_SUITE_IDS=...` on the fixed test): no fixed set is both developed on
/// and accepted on. `VCNC_SUITE_FRESH=N` sets how many (default 32).
///
/// History: at its merge about one fresh drive in 32 failed the per-drive criteria (ids
/// 1140374506: wn −2.08 % with σ 0.91 %, beyond the fixed tolerance). On 2026-11-29, with
/// the input decided on the whole trace and the nested test of the structure without integral
/// action, 254 of 256 fresh drives passed (runs of 64, 128 and 64; the failures, ids 816151506
/// and 4294495396, are near ζ = 1 with ωn +4.9 % and +10.4 % at 3.05 and 4 reported σ) and 239
/// of 256 were within the fixed tolerances. With stage C (the direct free-run fit,
/// docs/identification.md) runs of 64 gave 63/64 (failure 2367117528, below), a failed run
/// whose row was not kept, and 64/64 (58/64 within the fixed tolerances). 2367117528 (P-PI, a
/// trace that starts moving, ζ = 0.59) passed without stage C (validation 0.94×) and failed
/// with it (1.54×, poles the same): stage C fitted the extra-pole structure's free run from an
/// *estimated* initial state, 0.38 µm on the estimation trace against 0.032 µm for its
/// projected fit, and bent the linear parameters to that estimate's error. Its paper fit now
/// starts from the chosen structure's core and is chosen (0.94×, the fixed test below).
///
/// On 2026-11-30, with the friction reversal within a step (docs/drive-model.md, "Friction"),
/// 239 of 240 fresh drives passed (runs of 48, 64 and 128; 235 within the fixed tolerances).
/// The failure, 2059745961 (PID, ζ 1.31, Ts 1.88 ms, a rest start), has ωn −2.06 % at a
/// reported σ of 0.90 %: past the fixed tolerance, and its σ below the 1 % that lets three of
/// them count. At one drive in 240, 32 drives would still fail about one CI run in eight, so
/// the test stays out of CI. Run it with
/// `cargo test --release -p vcnc-identify --test suite fresh -- --ignored --nocapture`; a
/// failure prints its ids above the table (rerun them with `VCNC_SUITE_IDS`).
#[test]
#[ignore = "about one fresh drive in 240 fails the per-drive criteria (issue 30 open); run with --ignored"]
fn fresh_randomised_drives_are_identified_from_csv() {
    let count: usize = std::env::var("VCNC_SUITE_FRESH")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(FRESH_DRIVES);
    // Ids above the fixed set, drawn from the operating system's entropy.
    let ids: Vec<usize> = (0..count)
        .map(|_| FULL_DRIVES + (support::fresh_seed() as u32 as usize))
        .collect();
    println!(
        "fresh drive ids (rerun: VCNC_SUITE_IDS={}):",
        ids.iter()
            .map(|i| i.to_string())
            .collect::<Vec<_>>()
            .join(",")
    );
    let dir = suite_dir("fresh");
    println!("{HEADER}");
    let rows = run_all(&ids, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    judge(&rows);
}

/// A fixed regression case (docs/identification.md, "Choosing a structure"): fresh drive
/// 2954566393, an overdamped P-PI (ζ = 1.2, p = 7.06 Hz) whose trace starts at rest. The
/// structure without integral action came within the 5 % margin of the paper's held-out error
/// and was chosen as the simpler (p = 0, ωn −45 %), although the paper's fit determined p to
/// within 0.01 %: the data reject p = 0, so the restricted structure is not simpler.
#[test]
fn a_determined_integral_action_is_not_traded_for_parsimony() {
    let dir = suite_dir("nested");
    let rows = run_all(&[2_954_566_393], &dir);
    let _ = std::fs::remove_dir_all(&dir);
    assert!(rows.iter().all(|r| r.score.ok), "drive 2954566393 fails");
}

/// A fixed regression case (docs/identification.md, "Choosing a structure"): fresh drive
/// 2367117528, a P-PI (ζ = 0.59, p = 3.03 Hz, Ts = 1.85 ms) whose trace starts moving. The
/// paper's swarm and its compared fit ended in another valley (p 1.25 Hz, ωn 19.6 Hz, ζ 3.3);
/// the extra-pole structure found the drive's poles on the compared stretch and was chosen, and
/// its whole-trace fit (a free run from an estimated initial state) predicted the validation
/// program at 1.54× the true model's error. The paper's structure also starts from the chosen
/// structure's core on the whole trace now, reaches the drive's poles there, fits the whole
/// trace better than the extra-pole structure and is chosen (validation 0.94×).
#[test]
fn a_paper_fit_in_another_valley_starts_from_the_chosen_structures_core() {
    let dir = suite_dir("valley");
    let rows = run_all(&[2_367_117_528], &dir);
    let _ = std::fs::remove_dir_all(&dir);
    assert!(rows.iter().all(|r| r.score.ok), "drive 2367117528 fails");
}

/// Drives whose control delays (20–90 ms) or filters (first or second order) the reference
/// before the loop: the 7-parameter model's validation error beside the extended structure's,
/// which must come within 1.2 × the true extended model's (the analytic core with the true
/// shaping, [`vcnc_drive::DriveModel`]). Each identification tries every structure and
/// chooses by a held-out part of the estimation trace.
#[test]
fn shaped_references_are_identified_with_the_extended_structures() {
    use vcnc_drive::ReferenceFilter;
    let full = std::env::var("VCNC_SUITE").is_ok_and(|v| v == "full");
    let mut cases = vec![
        (100, Shaping::Delay(0.085)),
        (101, Shaping::Filter2(12.0, 0.8)),
    ];
    if full {
        cases.extend([
            (102, Shaping::Delay(0.021)),
            (103, Shaping::Delay(0.047)),
            (104, Shaping::Filter1(0.008)),
            (105, Shaping::Filter1(0.03)),
            (106, Shaping::Filter2(25.0, 1.0)),
            (107, Shaping::Delay(0.0633)),
        ]);
    }
    let dir = suite_dir("shaped");
    println!("id  shaping        | chosen               | val_rms_um 7-par  extended  true  ratio");
    let mut failed = vec![];
    for (id, shaping) in cases {
        let mut d = random_drive(id, shaping);
        d.moving = false;
        let prog =
            |seed: u64| support::identification_program(seed, 70, 50.0, d.vmax, d.amax, d.ts);
        let est = run_drive(&d, &prog(1000 + id as u64), false);
        let val = run_drive(&d, &prog(5000 + id as u64), false);
        let (pe, pv) = (
            dir.join(format!("shaped{id}_est.csv")),
            dir.join(format!("shaped{id}_val.csv")),
        );
        write_csv(&pe, &est);
        write_csv(&pv, &val);
        let opts = support::command_options();
        let tr = read_csv(&pe).expect("trace");
        let id_ = identify(&tr, &opts).expect("identifies");
        let vt = read_csv(&pv).expect("trace");
        let true_model = DriveModel {
            delay_s: match shaping {
                Shaping::Delay(t) => t,
                _ => 0.0,
            },
            reference_filter: match shaping {
                Shaping::Filter1(tau_s) => Some(ReferenceFilter::FirstOrder { tau_s }),
                Shaping::Filter2(wn_hz, zeta) => Some(ReferenceFilter::SecondOrder { wn_hz, zeta }),
                _ => None,
            },
            input: ReferenceInput::Hold,
            ..DriveModel::from(d.truth())
        };
        let rms = |m: &DriveModel| {
            let xh = vcnc_identify::free_run_model(m, &vt).expect("free run");
            let s: f64 = xh.iter().zip(&vt.x).map(|(a, b)| (a - b) * (a - b)).sum();
            (s / vt.len() as f64).sqrt()
        };
        let (r7, rx, rt) = (
            rms(&id_.identified_model),
            rms(&id_.model),
            rms(&true_model),
        );
        let ok = rx <= 1.2 * rt && id_.model.is_stable();
        let shaping_name = format!("{shaping:?}");
        let line = format!(
            "{id} {:14} | {:20} | {:9.3} {:9.3} {:7.3} {:5.2} {} Td {:.4} filter {:?} pole {:?}",
            shaping_name,
            id_.structure.name(),
            1e3 * r7,
            1e3 * rx,
            1e3 * rt,
            rx / rt,
            if ok { "ok" } else { "FAIL" },
            id_.model.delay_s,
            id_.model.reference_filter,
            id_.model.extra_pole_hz
        );
        println!("{line}");
        if !ok {
            failed.push(line);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(failed.is_empty(), "failed:\n{}", failed.join("\n"));
}
