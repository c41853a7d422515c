//! Jerk-limited interpolation of single moves (docs/gcode.md, "Speed profiles"), as programs:
//! a `G61.1` block on its own lasts the time-optimal duration rounded up to whole samples, and
//! no sample exceeds the velocity, acceleration or jerk limit.
//!
//! Truth: Ruckig's time-optimal durations (`tests/data/ruckig/single_moves.csv`, made by
//! `scripts/ruckig/goldens.py`; 66 moves, 60 of them random, many too short to reach the feed or
//! the acceleration limit), and for fresh random moves drawn every run (the seed is printed) an
//! independent brute-force oracle: the shortest rest-to-rest time over a fine grid of peak
//! speeds.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use vcnc_gcode::{AxisName, InterpOptions, InterpolateOptions, Limits, Profile, Trajectory, load};

const TS: f64 = 0.001;

fn opts() -> InterpolateOptions {
    InterpolateOptions {
        profile: Profile::JerkLimited,
        ..InterpolateOptions::default()
    }
}

/// The goldens: (L, V, A, J, Ruckig's duration).
fn goldens() -> Vec<[f64; 5]> {
    let text = include_str!("data/ruckig/single_moves.csv");
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("length"))
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3], v[4]]
        })
        .collect()
}

/// A rapid of length `l` along `dir` (unit, X Y) on a machine whose X and Y limits are `v`, `a`,
/// `j` scaled so that the move's own caps along the path are exactly (v, a, j).
fn run(l: f64, v: f64, a: f64, j: f64, dir: [f64; 2]) -> Trajectory {
    let mut limits = Limits::uniform_with_jerk(1.0, 1.0, 1.0);
    let c = dir[0].abs().max(dir[1].abs());
    for i in 0..2 {
        limits.axes[i].max_vel = v * c;
        limits.axes[i].max_acc = a * c;
        limits.axes[i].max_jerk = j * c;
    }
    let src = format!(
        "G21 G90 G61.1\nG0 X{:.17} Y{:.17}\nM2\n",
        l * dir[0],
        l * dir[1]
    );
    load(&src, &InterpOptions::default(), &limits, &opts())
        .unwrap()
        .trajectory
}

/// Sampled velocity, acceleration and jerk of axis `i` against its limits: the analytic
/// velocity and acceleration, and the first, second and third differences of the positions.
/// Returns the largest ratio to the limit of each.
fn worst(t: &Trajectory, limits: [f64; 3], scale: f64) -> [f64; 3] {
    let mut w = [0.0f64; 3];
    for a in &t.axes {
        let p = &a.pos;
        for k in 0..p.len() {
            w[0] = w[0].max(a.vel[k].abs() / limits[0]);
            w[1] = w[1].max(a.acc[k].abs() / limits[1]);
            if k + 1 < p.len() {
                w[0] = w[0].max((p[k + 1] - p[k]).abs() / TS / limits[0]);
            }
            if k >= 1 && k + 1 < p.len() {
                w[1] = w[1].max((p[k + 1] - 2.0 * p[k] + p[k - 1]).abs() / (TS * TS) / limits[1]);
            }
            if k >= 1 && k + 2 < p.len() {
                let d3 = p[k + 2] - 3.0 * p[k + 1] + 3.0 * p[k] - p[k - 1];
                // Round-off of positions of size `scale`: a few ulps over Ts³.
                let noise = 8.0 * f64::EPSILON * scale / (TS * TS * TS);
                w[2] = w[2].max((d3.abs() / (TS * TS * TS) - noise).max(0.0) / limits[2]);
            }
        }
    }
    w
}

fn rounded(t: f64) -> f64 {
    (t / TS - 1e-9).ceil() * TS
}

#[test]
fn single_moves_take_ruckigs_optimum_rounded_up_within_the_limits() {
    let g = goldens();
    assert!(g.len() >= 50);
    let mut worst_all = [0.0f64; 3];
    for [l, v, a, j, t] in g {
        let tr = run(l, v, a, j, [1.0, 0.0]);
        let want = rounded(t);
        assert!(
            (tr.duration_s() - want).abs() < 1e-12,
            "{l} {v} {a} {j}: {} s, Ruckig {t} s rounded up {want} s",
            tr.duration_s()
        );
        let x = tr.axis(AxisName::X).unwrap();
        // On the programmed point (as the program's text writes it).
        assert!((x.pos.last().unwrap() - l).abs() <= 1e-15 * l.max(1.0));
        let w = worst(&tr, [v, a, j], l);
        for (all, w) in worst_all.iter_mut().zip(w) {
            *all = all.max(w);
        }
    }
    println!(
        "Ruckig goldens: largest velocity, acceleration, jerk over the limit: {:.6} {:.6} {:.6}",
        worst_all[0], worst_all[1], worst_all[2]
    );
    for w in worst_all {
        assert!(w <= 1.0 + 1e-9, "{worst_all:?}");
    }
}

/// Independent oracle: the shortest rest-to-rest time, as the minimum over peak speeds $v_p$
/// (a fine grid, refined around the best) of ramp up + cruise + ramp down, each ramp the
/// fastest jerk-limited change of speed with zero acceleration at its ends.
fn oracle(l: f64, v: f64, a: f64, j: f64) -> f64 {
    let ramp = |vp: f64| -> (f64, f64) {
        let t = if vp * j >= a * a {
            vp / a + a / j
        } else {
            2.0 * (vp / j).sqrt()
        };
        (t, vp * t / 2.0)
    };
    let total = |vp: f64| -> f64 {
        let (t, d) = ramp(vp);
        if 2.0 * d > l {
            f64::INFINITY
        } else {
            2.0 * t + (l - 2.0 * d) / vp
        }
    };
    let (mut lo, mut hi) = (0.0, v);
    let mut best = f64::INFINITY;
    for _ in 0..8 {
        let n = 2000;
        let mut arg = lo;
        for k in 1..=n {
            let vp = lo + (hi - lo) * k as f64 / n as f64;
            let t = total(vp);
            if t < best {
                best = t;
                arg = vp;
            }
        }
        let w = (hi - lo) / n as f64;
        (lo, hi) = ((arg - 2.0 * w).max(1e-300), (arg + 2.0 * w).min(v));
    }
    best
}

#[test]
fn fresh_random_moves_are_time_optimal_and_within_the_limits() {
    let seed: u64 = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(1, |d| d.as_nanos() as u64);
    println!("seed {seed}");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..60 {
        let l = 10f64.powf(rng.random_range(-4.0..2.7));
        let v = rng.random_range(5.0..500.0);
        let a = 10f64.powf(rng.random_range(2.0..4.5));
        let j = 10f64.powf(rng.random_range(3.0..6.5));
        let ang: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let dir = [ang.cos(), ang.sin()];
        let tr = run(l, v, a, j, dir);
        let t_star = oracle(l, v, a, j);
        // The oracle's grid is within 1e-9 of the optimum; the rounding then agrees unless the
        // optimum falls within that of a sample boundary.
        let (lo, hi) = (
            rounded(t_star * (1.0 - 1e-9)),
            rounded(t_star * (1.0 + 1e-9)),
        );
        let d = tr.duration_s();
        assert!(
            (d - lo).abs() < 1e-12 || (d - hi).abs() < 1e-12,
            "seed {seed}: L {l} V {v} A {a} J {j} dir {dir:?}: {d} s, oracle {t_star} s"
        );
        // Per axis the limits are (v, a, j) times the larger direction component.
        let c = dir[0].abs().max(dir[1].abs());
        let w = worst(&tr, [v * c, a * c, j * c], l);
        for x in w {
            assert!(
                x <= 1.0 + 1e-6,
                "seed {seed}: L {l} V {v} A {a} J {j}: {w:?}"
            );
        }
    }
}

/// The programs of `tests/data/linuxcnc-planner/programs` with their limits, each axis' jerk
/// limit 40 times its acceleration limit (a moving average of 50 ms).
fn planner_programs() -> Vec<(String, String, Limits)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/linuxcnc-planner/programs");
    let mut out = Vec::new();
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    names.sort();
    for p in names {
        let src = std::fs::read_to_string(&p).unwrap();
        let first = src.lines().next().unwrap();
        let inner = first.trim_start_matches("(limits ").trim_end_matches(')');
        let mut limits = Limits::uniform_with_jerk(0.0, 0.0, f64::INFINITY);
        for (i, w) in inner.split_whitespace().enumerate() {
            let (_, vals) = w.split_once('=').unwrap();
            let (v, a) = vals.split_once(',').unwrap();
            limits.axes[i].max_vel = v.parse().unwrap();
            limits.axes[i].max_acc = a.parse().unwrap();
            limits.axes[i].max_jerk = 40.0 * limits.axes[i].max_acc;
        }
        let name = p.file_stem().unwrap().to_string_lossy().to_string();
        out.push((name, src, limits));
    }
    out
}

/// Largest sampled velocity, acceleration and jerk of each axis over its limits (first,
/// second and third differences of the positions, and the analytic velocity and acceleration).
fn worst_per_axis(t: &Trajectory, limits: &Limits) -> [f64; 3] {
    let mut w = [0.0f64; 3];
    for track in &t.axes {
        let l = limits.axes[track.name.index()];
        let one = Trajectory {
            axes: vec![track.clone()],
            ..t.clone()
        };
        let r = worst(&one, [l.max_vel, l.max_acc, l.max_jerk], 1000.0);
        for (a, b) in w.iter_mut().zip(r) {
            *a = a.max(b);
        }
    }
    w
}

#[test]
fn chains_keep_every_sample_within_velocity_acceleration_and_jerk() {
    // Programs with G61 corners, G64 blends of lines and arcs, short segments, rapids, cycles
    // and inverse time: every sample's velocity, acceleration and jerk (differences of the
    // sampled positions) within the axis limits.
    for (name, src, limits) in planner_programs() {
        let opts = InterpolateOptions {
            axes: Some(vec![AxisName::X, AxisName::Y, AxisName::Z]),
            ..opts()
        };
        let t = load(&src, &InterpOptions::default(), &limits, &opts)
            .unwrap()
            .trajectory;
        let w = worst_per_axis(&t, &limits);
        println!(
            "{name}: {:.3} s; velocity, acceleration, jerk up to {:.4} {:.4} {:.4} of the limits",
            t.duration_s(),
            w[0],
            w[1],
            w[2]
        );
        for x in w {
            assert!(x <= 1.0 + 1e-6, "{name}: {w:?}");
        }
    }
}

#[test]
fn short_segments_do_not_stall_the_chain() {
    // 2000 segments of 0.05 mm on a circle of radius 500 mm at F6000 (100 mm/s), blended
    // under G64: a planner that brings the acceleration to zero at every junction would crawl
    // (each 0.05 mm segment alone allows a speed change of (2·0.05)^(2/3)·J^(1/3) ≈ 10 mm/s).
    // Truth: the same 100 mm as one straight move takes its time-optimal duration; the chain,
    // whose junctions and gentle curve take little, must come within 5 % of that plus the
    // moving average's length, and reach the feed.
    let (v, a, j) = (100.0, 1000.0, 50_000.0);
    let limits = Limits::uniform_with_jerk(300.0, a, j);
    let mut src = String::from("G21 G90 G64\nG0 X500 Y0\nG1 F6000\n");
    let n = 2000;
    let step = 0.05 / 500.0;
    for k in 1..=n {
        let ang = k as f64 * step;
        src.push_str(&format!(
            "X{:.6} Y{:.6}\n",
            500.0 * ang.cos(),
            500.0 * ang.sin()
        ));
    }
    src.push_str("M2\n");
    let t = load(&src, &InterpOptions::default(), &limits, &opts())
        .unwrap()
        .trajectory;
    let feed_span: Vec<usize> = (0..t.len())
        .filter(|&k| t.span_at(k).is_some_and(|b| b.line > 2))
        .collect();
    let dur = feed_span.len() as f64 * TS;
    let one_move = oracle(100.0, v, a, j);
    // The chain's trapezoid smoothed over T_f = 2a/j.
    let bound = (100.0 / v + v / a) * 1.05 + 2.0 * a / j;
    println!("chain {dur:.3} s, one straight move {one_move:.3} s, bound {bound:.3} s");
    assert!(dur <= bound, "{dur} > {bound}");
    let top = feed_span
        .iter()
        .map(|&k| t.axes[0].vel[k].hypot(t.axes[1].vel[k]))
        .fold(0.0, f64::max);
    assert!(top > 0.99 * v, "top speed {top}");
    let w = worst_per_axis(&t, &limits);
    assert!(w.iter().all(|x| *x <= 1.0 + 1e-6), "{w:?}");
}
