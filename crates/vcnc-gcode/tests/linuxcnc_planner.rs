//! vcnc's planner with LinuxCNC 2.9's rules (`PlannerRules::LinuxCnc29`) against LinuxCNC 2.9's
//! own trajectory planner.
//!
//! Truth: the joint commands LinuxCNC 2.9 (Debian package `linuxcnc-uspace`
//! 2.9.0~pre1+git20230208.f1270d6ed7) sent every 1 ms on a simulated XYZ machine running each
//! program of `tests/data/linuxcnc-planner/programs` with the limits its first line states,
//! recorded by `scripts/linuxcnc-planner/record.py` (README there). For each program vcnc runs
//! on the same limits and this checks:
//! - the cycle time within 1 % of LinuxCNC's under `G61`, `G61.1` and `G64 P`, 2 % under plain
//!   `G64` (docs/gcode.md gives the table);
//! - the path: every recorded point within the program's blend tolerance of vcnc's sampled
//!   path and every vcnc sample within it of the recorded path (plus the chord of a sample step
//!   and LinuxCNC's joint interpolator's smoothing);
//! - no second difference of vcnc's sampled positions above an axis' acceleration limit by
//!   more than 1 %.

use std::path::PathBuf;

use vcnc_gcode::{
    AxisName, InterpOptions, InterpolateOptions, Limits, PlannerRules, StartPosition, load,
};

/// The programs and recordings: the committed ones, or those of the folder
/// `VCNC_LINUXCNC_PLANNER_DIR` names (made by `record.py --data`, e.g. from programs that are not
/// in the repository).
fn data() -> PathBuf {
    match std::env::var_os("VCNC_LINUXCNC_PLANNER_DIR") {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/linuxcnc-planner"),
    }
}

/// The limits of a program's first line, `(limits X=v,a Y=v,a Z=v,a)`.
fn limits_of(src: &str) -> [(f64, f64); 3] {
    let first = src.lines().next().unwrap();
    let inner = first.trim_start_matches("(limits ").trim_end_matches(')');
    let mut out = [(0.0, 0.0); 3];
    for (i, w) in inner.split_whitespace().enumerate() {
        let (_, vals) = w.split_once('=').unwrap();
        let (v, a) = vals.split_once(',').unwrap();
        out[i] = (v.parse().unwrap(), a.parse().unwrap());
    }
    out
}

/// A recording: the cycle time and the joint positions (mm) every 1 ms.
fn recording(name: &str) -> (f64, Vec<[f64; 3]>) {
    let text =
        std::fs::read_to_string(data().join("recordings").join(format!("{name}.txt"))).unwrap();
    let mut cycle = f64::NAN;
    let mut pts = Vec::new();
    for line in text.lines() {
        if let Some(rest) = line.strip_prefix('#') {
            if let Some((_, t)) = rest.split_once("cycle_time_s ") {
                cycle = t.trim().parse().unwrap();
            }
            continue;
        }
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        pts.push([v[0], v[1], v[2]]);
    }
    (cycle, pts)
}

/// Distance from `p` to the segment `a`–`b`.
fn seg_dist(p: &[f64; 3], a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let d: [f64; 3] = std::array::from_fn(|i| b[i] - a[i]);
    let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let t = if dd > 0.0 {
        (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1] + (p[2] - a[2]) * d[2]) / dd).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (0..3)
        .map(|i| (p[i] - a[i] - t * d[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The largest distance from a point of `from` to the polyline `to`, each point searched
/// within `window` samples of its place in proportion to the two lengths.
fn path_distance(from: &[[f64; 3]], to: &[[f64; 3]], window: usize) -> f64 {
    let mut worst: f64 = 0.0;
    let r = to.len() as f64 / from.len() as f64;
    for (k, p) in from.iter().enumerate() {
        let c = (k as f64 * r) as usize;
        let lo = c.saturating_sub(window);
        let hi = (c + window).min(to.len() - 1);
        let mut best = f64::INFINITY;
        for j in lo..hi {
            best = best.min(seg_dist(p, &to[j], &to[j + 1]));
        }
        worst = worst.max(best);
    }
    worst
}

struct Row {
    name: String,
    mode: &'static str,
    limits: [(f64, f64); 3],
    vcnc_rules_s: f64,
    vcnc_s: f64,
    linuxcnc_s: f64,
    path_mm: f64,
    tol_mm: f64,
    acc_ratio: f64,
}

fn compare(name: &str) -> Row {
    let src = std::fs::read_to_string(data().join("programs").join(format!("{name}.ngc"))).unwrap();
    let lim = limits_of(&src);
    let mut limits = Limits::uniform(0.0, 0.0);
    for (i, (v, a)) in lim.iter().enumerate() {
        limits.axes[i].max_vel = *v;
        limits.axes[i].max_acc = *a;
    }
    limits.tcp_max_vel = 1e5;
    limits.tcp_max_acc = 1e6;
    let opts = InterpolateOptions {
        planner: PlannerRules::LinuxCnc29,
        axes: Some(vec![AxisName::X, AxisName::Y, AxisName::Z]),
        ..InterpolateOptions::default()
    };
    let interp = InterpOptions {
        start: StartPosition::Machine([0.0; 6]),
        ..InterpOptions::default()
    };
    let run = load(&src, &interp, &limits, &opts).unwrap();
    let t = &run.trajectory;
    // vcnc's own rules on the same limits, for the table (not checked).
    let own = InterpolateOptions {
        planner: PlannerRules::Vcnc,
        ..opts.clone()
    };
    let vcnc_rules_s = load(&src, &interp, &limits, &own)
        .unwrap()
        .trajectory
        .duration_s();
    let (cycle, rec) = recording(name);
    let ours: Vec<[f64; 3]> = (0..t.len())
        .map(|k| std::array::from_fn(|i| t.axes[i].pos[k]))
        .collect();
    // The blend tolerance the program states (its largest G64 P), and the mode its checks use.
    let upper = src.to_uppercase().replace(' ', "");
    let (mode, tol) = if upper.contains("G64P") {
        let p = upper
            .split("G64P")
            .skip(1)
            .filter_map(|r| {
                let end = r
                    .find(|c: char| !(c.is_ascii_digit() || c == '.'))
                    .unwrap_or(r.len());
                r[..end].parse::<f64>().ok()
            })
            .fold(0.0, f64::max);
        // In the program's units.
        let scale = if upper.contains("G20") { 25.4 } else { 1.0 };
        ("G64 P", p * scale)
    } else if upper.contains("G64") {
        // Plain G64: a quarter of a block's length (LinuxCNC 2.9's rule), at most.
        ("G64", f64::INFINITY)
    } else if upper.contains("G61.1") {
        ("G61.1", 0.0)
    } else {
        ("G61", 0.0)
    };
    let window = 400 + (cycle - t.duration_s()).abs().mul_add(1000.0, 0.0) as usize;
    let path = path_distance(&rec, &ours, window).max(path_distance(&ours, &rec, window));
    let mut acc_ratio: f64 = 0.0;
    for (i, (_, a)) in lim.iter().enumerate() {
        let p = &t.axes[i].pos;
        for k in 1..p.len() - 1 {
            let d2 = (p[k + 1] - 2.0 * p[k] + p[k - 1]) / (t.ts * t.ts);
            acc_ratio = acc_ratio.max(d2.abs() / a);
        }
    }
    Row {
        name: name.to_string(),
        mode,
        limits: lim,
        vcnc_rules_s,
        vcnc_s: t.duration_s(),
        linuxcnc_s: cycle,
        path_mm: path,
        tol_mm: tol,
        acc_ratio,
    }
}

#[test]
fn cycle_times_paths_and_accelerations_agree_with_linuxcnc() {
    let mut names: Vec<String> = std::fs::read_dir(data().join("programs"))
        .unwrap()
        .filter_map(|e| {
            let p = e.ok()?.path();
            (p.extension()? == "ngc").then(|| p.file_stem()?.to_str().map(String::from))?
        })
        .collect();
    names.sort();
    assert!(names.len() >= 8 || std::env::var_os("VCNC_LINUXCNC_PLANNER_DIR").is_some());
    println!(
        "| program | mode | limits X, Y, Z (mm/s, mm/s²) | vcnc s | LinuxCNC s | difference | path mm | max |Δ²x|/a | vcnc's own rules s |"
    );
    let mut failures = Vec::new();
    for name in &names {
        let r = compare(name);
        let diff = r.vcnc_s / r.linuxcnc_s - 1.0;
        let lim = r
            .limits
            .iter()
            .map(|(v, a)| format!("{v}/{a}"))
            .collect::<Vec<_>>()
            .join(", ");
        println!(
            "| {} | {} | {lim} | {:.3} | {:.3} | {:+.2} % | {:.4} | {:.4} | {:.3} |",
            r.name,
            r.mode,
            r.vcnc_s,
            r.linuxcnc_s,
            100.0 * diff,
            r.path_mm,
            r.acc_ratio,
            r.vcnc_rules_s
        );
        let bound = if r.mode == "G64" { 0.02 } else { 0.01 };
        if diff.abs() > bound {
            failures.push(format!("{}: cycle time {:+.2} %", r.name, 100.0 * diff));
        }
        // The chord of a 1 ms step and LinuxCNC's cubic joint interpolation add a few µm.
        if r.path_mm > r.tol_mm + 0.005 {
            failures.push(format!(
                "{}: path {:.4} mm > {}",
                r.name, r.path_mm, r.tol_mm
            ));
        }
        if r.acc_ratio > 1.01 {
            failures.push(format!(
                "{}: acceleration {:.4} of the limit",
                r.name, r.acc_ratio
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
