//! Synthetic test paths: the docs/contour.md spiral with a trapezoidal feed, plus lagged and
//! offset "actual" copies of it. Shared by the tests and the benchmark.
#![allow(dead_code)]

use std::f64::consts::TAU;

use vcnc_kinematics::Pose;
use vcnc_kinematics::nalgebra::Vector3;

/// Sample period, s (docs/gcode.md default).
pub const TS: f64 = 1e-3;

/// The docs/contour.md spiral: 3 turns, radius 20 → 60 mm, tip on a dome of radius 100 mm
/// centred at (30, 20) in the workpiece frame, tool axis = dome normal; parametrised by the
/// polar angle θ ∈ [0, 6π] and, through a table, by the tip arc length s.
pub struct Spiral {
    theta: Vec<f64>,
    s: Vec<f64>,
}

impl Spiral {
    pub fn new() -> Self {
        let n = 200_000;
        let mut theta = Vec::with_capacity(n + 1);
        let mut s = Vec::with_capacity(n + 1);
        let mut acc = 0.0;
        let mut prev = Self::tip(0.0);
        for i in 0..=n {
            let th = 3.0 * TAU * i as f64 / n as f64;
            let p = Self::tip(th);
            acc += (p - prev).norm();
            prev = p;
            theta.push(th);
            s.push(acc);
        }
        Self { theta, s }
    }

    /// Tip position at polar angle θ, mm.
    pub fn tip(theta: f64) -> Vector3<f64> {
        let rho = 20.0 + 40.0 * theta / (3.0 * TAU);
        let h = (100.0f64 * 100.0 - rho * rho).sqrt();
        Vector3::new(
            30.0 + rho * theta.cos(),
            20.0 + rho * theta.sin(),
            -50.0 + h,
        )
    }

    /// Pose at polar angle θ (tool axis = outward dome normal).
    pub fn pose(theta: f64) -> Pose {
        let p = Self::tip(theta);
        let o = (p - Vector3::new(30.0, 20.0, -50.0)) / 100.0;
        Pose::new(p, o)
    }

    /// Total tip arc length, mm.
    pub fn length(&self) -> f64 {
        self.s.last().copied().unwrap_or(0.0)
    }

    /// θ at arc length s (clamped to the path).
    pub fn theta_at(&self, s: f64) -> f64 {
        let s = s.clamp(0.0, self.length());
        let i = self
            .s
            .partition_point(|&v| v < s)
            .clamp(1, self.s.len() - 1);
        let (s0, s1) = (self.s[i - 1], self.s[i]);
        let f = if s1 > s0 { (s - s0) / (s1 - s0) } else { 0.0 };
        self.theta[i - 1] + f * (self.theta[i] - self.theta[i - 1])
    }

    pub fn pose_at(&self, s: f64) -> Pose {
        Self::pose(self.theta_at(s))
    }
}

/// Distance travelled at time t along a rest-to-rest trapezoidal move of length `l` (mm) with
/// feed `v` (mm/s) and acceleration `a` (mm/s²); triangular if too short. Returns (s, duration).
pub fn trapezoid(t: f64, l: f64, v: f64, a: f64) -> (f64, f64) {
    let v = v.min((l * a).sqrt());
    let ta = v / a;
    let tc = (l - v * ta) / v;
    let dur = 2.0 * ta + tc;
    let t = t.clamp(0.0, dur);
    let s = if t < ta {
        0.5 * a * t * t
    } else if t < ta + tc {
        0.5 * v * ta + v * (t - ta)
    } else {
        let td = dur - t;
        l - 0.5 * a * td * td
    };
    (s, dur)
}

/// Arc length as a function of time for the whole spiral at 75 mm/s, 1500 mm/s² (docs/contour.md), or,
/// with `stop = Some((s_stop, dwell))`, two moves with a dwell of `dwell` s at `s_stop`.
pub fn arc_length_at(t: f64, length: f64, stop: Option<(f64, f64)>) -> f64 {
    let (v, a) = (75.0, 1500.0);
    match stop {
        None => trapezoid(t, length, v, a).0,
        Some((s_stop, dwell)) => {
            let (_, d1) = trapezoid(0.0, s_stop, v, a);
            if t <= d1 + dwell {
                trapezoid(t, s_stop, v, a).0
            } else {
                s_stop + trapezoid(t - d1 - dwell, length - s_stop, v, a).0
            }
        }
    }
}

/// Duration of the motion of [`arc_length_at`], s.
pub fn duration(length: f64, stop: Option<(f64, f64)>) -> f64 {
    let (v, a) = (75.0, 1500.0);
    match stop {
        None => trapezoid(0.0, length, v, a).1,
        Some((s_stop, dwell)) => {
            trapezoid(0.0, s_stop, v, a).1 + dwell + trapezoid(0.0, length - s_stop, v, a).1
        }
    }
}

/// Reference poses sampled at `TS`, plus `extra` samples at rest at the end.
pub fn reference(spiral: &Spiral, stop: Option<(f64, f64)>, extra: usize) -> Vec<Pose> {
    let n = (duration(spiral.length(), stop) / TS).ceil() as usize + extra;
    (0..=n)
        .map(|k| spiral.pose_at(arc_length_at(k as f64 * TS, spiral.length(), stop)))
        .collect()
}

/// An "actual" copy: the reference delayed by `delay` s (negative: leading), with the tip
/// moved by a smooth µm-scale offset (`offset_um` amplitude, radial and normal) and the tool
/// axis tilted by a smooth `tilt_mrad`-scale angle.
pub fn actual(
    spiral: &Spiral,
    stop: Option<(f64, f64)>,
    n: usize,
    delay: f64,
    offset_um: f64,
    tilt_mrad: f64,
) -> Vec<Pose> {
    (0..n)
        .map(|k| {
            let t = k as f64 * TS;
            let th = spiral.theta_at(arc_length_at(t - delay, spiral.length(), stop));
            let base = Spiral::pose(th);
            let radial = Vector3::new(th.cos(), th.sin(), 0.0);
            let w = offset_um * 1e-3;
            let p = base.p + radial * (w * (7.0 * t).sin()) + base.o * (0.5 * w * (3.0 * t).cos());
            let tilt = tilt_mrad * 1e-3 * (5.0 * t).sin();
            let tangent = radial.cross(&Vector3::z());
            let o = (base.o + tangent * tilt).normalize();
            Pose::new(p, o)
        })
        .collect()
}

/// A first-order low-pass of the reference tip and axis (a stand-in for a lagging drive):
/// x[k] = x[k-1] + alpha (r[k] - x[k-1]).
pub fn low_pass(reference: &[Pose], alpha: f64) -> Vec<Pose> {
    let mut out = Vec::with_capacity(reference.len());
    let Some(first) = reference.first() else {
        return out;
    };
    let (mut p, mut o) = (first.p, first.o);
    for r in reference {
        p += (r.p - p) * alpha;
        o += (r.o - o) * alpha;
        out.push(Pose::new(p, o.normalize()));
    }
    out
}

/// A CAM raster as in LinuxCNC's 5-axis "boat" demo: six 60 mm passes in alternating
/// directions, each 3 mm over from the last and slanted towards the next one, sampled at
/// 75 mm/s (1 kHz), tool along +Z. Returns the samples (the last knot excluded) and the last
/// knot, mm.
pub fn raster_passes() -> (Vec<Pose>, Vector3<f64>) {
    let mut knots = Vec::new();
    for pass in 0..6 {
        let y0 = 3.0 * pass as f64;
        let (xa, xb) = if pass % 2 == 0 {
            (-30.0, 30.0)
        } else {
            (30.0, -30.0)
        };
        knots.push(Vector3::new(xa, y0, 0.0));
        knots.push(Vector3::new(xb, y0 + 2.9, -0.5));
    }
    let mut r = Vec::new();
    for w in knots.windows(2) {
        let n = ((w[1] - w[0]).norm() / 0.075).ceil() as usize;
        for k in 0..n {
            r.push(Pose::new(
                w[0] + (w[1] - w[0]) * (k as f64 / n as f64),
                Vector3::z(),
            ));
        }
    }
    (r, knots[knots.len() - 1])
}
