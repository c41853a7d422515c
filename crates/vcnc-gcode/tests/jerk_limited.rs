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
        let (lo, hi) = (rounded(t_star * (1.0 - 1e-9)), rounded(t_star * (1.0 + 1e-9)));
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
