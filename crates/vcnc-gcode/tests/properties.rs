//! Property tests over random programs and limits (docs/gcode.md, "Properties that must hold"):
//! no sample exceeds a limit, blocks end on their programmed points, exact-stop durations are
//! the rounded time-optimal ones, G20 programs equal their G21 twins, G91 equals G90; and no
//! input panics the parser, the interpreter or the interpolator.

use proptest::prelude::*;
use std::fmt::Write;
use vcnc_gcode::{
    AxisName, Feed, InterpOptions, InterpolateOptions, Limits, Move, MoveKind, ParseOptions,
    PlannerRules, Profile, Trajectory, interpolate, interpret, load, parse_bytes, parse_with,
};

#[derive(Debug, Clone)]
enum Op {
    /// Straight move by `d` (mm, deg); `feed` in units/s; `rapid` for G0.
    Line {
        rapid: bool,
        d: [f64; 6],
        feed: f64,
    },
    /// Arc of radius `r` starting at angle `phi0` on its circle, sweeping `sweep` rad, with a
    /// helical rise `dz`.
    Arc {
        ccw: bool,
        r: f64,
        phi0: f64,
        sweep: f64,
        dz: f64,
        feed: f64,
    },
    /// Inverse-time straight move lasting `minutes`.
    InverseTime {
        d: [f64; 6],
        minutes: f64,
    },
    Dwell(f64),
    /// 0: G61.1, 1: G61, 2: G64, 3: G64 P0.05, 4: G64 P0.02 Q0.01.
    PathMode(u8),
    Tcp(bool),
}

fn disp() -> impl Strategy<Value = [f64; 6]> {
    // Each axis moves with probability ½; X Y Z within ±40 mm, A B C within ±90°.
    prop::array::uniform6((any::<bool>(), -1.0f64..1.0)).prop_map(|a| {
        let mut d = [0.0; 6];
        for (i, (on, v)) in a.iter().enumerate() {
            if *on {
                d[i] = v * if i < 3 { 40.0 } else { 90.0 };
            }
        }
        d
    })
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        4 => (any::<bool>(), disp(), 5.0f64..250.0).prop_map(|(rapid, d, feed)| Op::Line { rapid, d, feed }),
        2 => (any::<bool>(), 1.0f64..40.0, -3.2f64..3.2, 0.1f64..6.0, -10.0f64..10.0, 5.0f64..250.0)
            .prop_map(|(ccw, r, phi0, sweep, dz, feed)| Op::Arc { ccw, r, phi0, sweep, dz, feed }),
        1 => (disp(), 0.005f64..0.05).prop_map(|(d, minutes)| Op::InverseTime { d, minutes }),
        1 => (0.0f64..0.3).prop_map(Op::Dwell),
        2 => (0u8..5).prop_map(Op::PathMode),
        1 => any::<bool>().prop_map(Op::Tcp),
    ]
}

fn limits() -> impl Strategy<Value = Limits> {
    (
        prop::array::uniform6((20.0f64..500.0, 200.0f64..20000.0, 5.0f64..200.0)),
        20.0f64..500.0,
        200.0f64..20000.0,
        5.0f64..200.0,
    )
        .prop_map(|(axes, tv, ta, tj)| {
            let mut l = Limits::uniform(1.0, 1.0);
            for (i, (v, a, j)) in axes.iter().enumerate() {
                l.axes[i].max_vel = *v;
                l.axes[i].max_acc = *a;
                // The jerk limit: 5 to 200 times the acceleration limit, per second.
                l.axes[i].max_jerk = a * j;
            }
            l.tcp_max_vel = tv;
            l.tcp_max_acc = ta;
            l.tcp_max_jerk = ta * tj;
            l
        })
}

/// The third differences of the sampled positions within the jerk limits (jerk-limited
/// profile), per axis and for the tool tip in TCP spans.
fn check_jerk(t: &Trajectory, limits: &Limits) -> Result<(), TestCaseError> {
    let ts3 = t.ts * t.ts * t.ts;
    let noise = 1e-11 / ts3;
    for k in 1..t.len().saturating_sub(2) {
        let d3 = |i: usize| {
            let p = &t.axes[i].pos;
            (p[k + 2] - 3.0 * p[k + 1] + 3.0 * p[k] - p[k - 1]) / ts3
        };
        let tcp = t.tcp[k - 1] || t.tcp[k] || t.tcp[k + 1] || t.tcp[k + 2];
        let all_tcp = t.tcp[k - 1] && t.tcp[k] && t.tcp[k + 1] && t.tcp[k + 2];
        for (i, a) in t.axes.iter().enumerate() {
            if tcp && i < 3 {
                continue;
            }
            let j = limits.axes[i].max_jerk;
            prop_assert!(
                d3(i).abs() <= j * (1.0 + 1e-6) + noise,
                "{} jerk {} > {j} at k {k}",
                a.name,
                d3(i)
            );
        }
        if all_tcp {
            let j = (0..3).map(|i| d3(i).powi(2)).sum::<f64>().sqrt();
            prop_assert!(
                j <= limits.tcp_max_jerk * (1.0 + 1e-6) + noise,
                "tip jerk {j} at k {k}"
            );
        }
    }
    Ok(())
}

#[derive(Clone, Copy, PartialEq)]
enum Style {
    Absolute,
    Incremental,
    Inch,
}

/// Write the ops as a program in the given style. The opening block positions the machine at
/// a fixed start.
fn render(ops: &[Op], style: Style) -> String {
    let names = ['X', 'Y', 'Z', 'A', 'B', 'C'];
    let k = if style == Style::Inch {
        1.0 / 25.4
    } else {
        1.0
    };
    let len = |v: f64| v * k;
    let mut pos = [5.0, -3.0, 2.0, 10.0, 0.0, -20.0];
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{} G90 G17 G94 G61.1",
        if style == Style::Inch { "G20" } else { "G21" }
    );
    let mut first = String::from("G0");
    for (i, p) in pos.iter().enumerate() {
        let v = if i < 3 { len(*p) } else { *p };
        let _ = write!(first, " {}{}", names[i], v);
    }
    let _ = writeln!(out, "{first}");
    if style == Style::Incremental {
        let _ = writeln!(out, "G91");
    }
    let axis_words = |out: &mut String, pos: &[f64; 6], new: &[f64; 6], only_moving: bool| {
        for i in 0..6 {
            if only_moving && new[i] == pos[i] {
                continue;
            }
            let v = match style {
                Style::Incremental => new[i] - pos[i],
                _ => new[i],
            };
            let v = if i < 3 { len(v) } else { v };
            let _ = write!(out, " {}{}", names[i], v);
        }
    };
    for op in ops {
        match op {
            Op::Line { rapid, d, feed } => {
                let new: [f64; 6] = std::array::from_fn(|i| pos[i] + d[i]);
                if new == pos {
                    continue;
                }
                let xyz = (0..3).any(|i| new[i] != pos[i]);
                out.push_str(if *rapid { "G0" } else { "G1" });
                axis_words(&mut out, &pos, &new, true);
                if !rapid {
                    // Pure rotary feeds are deg/min and never scaled.
                    let f = if xyz { len(feed * 60.0) } else { feed * 60.0 };
                    let _ = write!(out, " F{f}");
                }
                out.push('\n');
                pos = new;
            }
            Op::Arc {
                ccw,
                r,
                phi0,
                sweep,
                dz,
                feed,
            } => {
                let (cx, cy) = (pos[0] - r * phi0.cos(), pos[1] - r * phi0.sin());
                let end = if *ccw { phi0 + sweep } else { phi0 - sweep };
                let mut new = pos;
                new[0] = cx + r * end.cos();
                new[1] = cy + r * end.sin();
                new[2] = pos[2] + dz;
                out.push_str(if *ccw { "G3" } else { "G2" });
                axis_words(&mut out, &pos, &new, false);
                let _ = writeln!(
                    out,
                    " I{} J{} F{}",
                    len(cx - pos[0]),
                    len(cy - pos[1]),
                    len(feed * 60.0)
                );
                pos = new;
            }
            Op::InverseTime { d, minutes } => {
                let new: [f64; 6] = std::array::from_fn(|i| pos[i] + d[i]);
                if new == pos {
                    continue;
                }
                out.push_str("G93 G1");
                axis_words(&mut out, &pos, &new, true);
                let _ = writeln!(out, " F{}\nG94", 1.0 / minutes);
                pos = new;
            }
            Op::Dwell(p) => {
                let _ = writeln!(out, "G4 P{p}");
            }
            Op::PathMode(m) => {
                let code = ["G61.1", "G61", "G64", "G64 P0.05", "G64 P0.02 Q0.01"][*m as usize];
                let tol = |x: f64| format!("{}", len(x));
                let code = code
                    .replace("0.05", &tol(0.05))
                    .replace("0.02", &tol(0.02))
                    .replace("0.01", &tol(0.01));
                let _ = writeln!(out, "{code}");
            }
            Op::Tcp(on) => {
                let _ = writeln!(out, "{}", if *on { "G43.4" } else { "G49" });
            }
        }
    }
    out.push_str("M2\n");
    out
}

fn all_axes() -> InterpolateOptions {
    InterpolateOptions {
        axes: Some(AxisName::ALL.to_vec()),
        ..InterpolateOptions::default()
    }
}

/// The machine must be at rest after `m` when `next` follows (docs/gcode.md, "Path modes"): a
/// `G61.1` block, a stop, the end, a dwell next, a change between rapids and feeds, of TCP
/// mode or of the kind of path parameter. (`G61` and `G64` may stop at corners too.)
fn rests(m: &Move, next: Option<&Move>) -> bool {
    m.path.is_exact_stop()
        || m.stop_after
        || next.is_none_or(|n| {
            matches!(n.kind, MoveKind::Dwell { .. })
                || n.tcp != m.tcp
                || (n.kind == MoveKind::Rapid) != (m.kind == MoveKind::Rapid)
                || xyz_basis(n) != xyz_basis(m)
        })
}

fn xyz_basis(m: &Move) -> bool {
    matches!(m.kind, MoveKind::Arc(_)) || (0..3).any(|i| m.end[i] != m.start[i])
}

/// Independent oracle: the time-optimal rest-to-rest time of a straight move (module doc
/// equations, recomputed here from the limits).
fn t_star_line(m: &Move, limits: &Limits) -> f64 {
    let d: Vec<f64> = (0..6).map(|i| m.end[i] - m.start[i]).collect();
    let xyz = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let rot = (d[3] * d[3] + d[4] * d[4] + d[5] * d[5]).sqrt();
    let l = if xyz > 0.0 { xyz } else { rot };
    let mut v = match m.feed {
        Some(Feed::UnitsPerMin(f)) => f / 60.0,
        // LinuxCNC's inverse-time rule: the block's length in 1/F.
        Some(Feed::InverseTime(f)) => l * f / 60.0,
        None => f64::INFINITY,
    };
    let mut a = f64::INFINITY;
    for (i, &di) in d.iter().enumerate() {
        if di == 0.0 || (m.tcp && i < 3) {
            continue;
        }
        v = v.min(limits.axes[i].max_vel * l / di.abs());
        a = a.min(limits.axes[i].max_acc * l / di.abs());
    }
    if m.tcp && xyz > 0.0 {
        v = v.min(limits.tcp_max_vel * l / xyz);
        a = a.min(limits.tcp_max_acc * l / xyz);
    }
    if l >= v * v / a {
        l / v + v / a
    } else {
        2.0 * (l / a).sqrt()
    }
}

fn rounded(t: f64, ts: f64) -> f64 {
    (t / ts - 1e-9).ceil() * ts
}

fn check_limits(t: &Trajectory, limits: &Limits) -> Result<(), TestCaseError> {
    let tol = 1.0 + 1e-9;
    // The second differences of the sampled positions too: no corner is taken at speed.
    let ts2 = t.ts * t.ts;
    for k in 1..t.len().saturating_sub(1) {
        let d2 =
            |i: usize| (t.axes[i].pos[k + 1] - 2.0 * t.axes[i].pos[k] + t.axes[i].pos[k - 1]) / ts2;
        // Round-off of positions up to ~100 units over Ts².
        let noise = 1e-12 / ts2;
        for (i, a) in t.axes.iter().enumerate() {
            if t.tcp[k] && i < 3 {
                continue;
            }
            prop_assert!(
                d2(i).abs() <= limits.axes[i].max_acc * tol + noise,
                "{} second difference {} > {} at k {k}",
                a.name,
                d2(i),
                limits.axes[i].max_acc
            );
        }
        if t.tcp[k] && t.tcp[k - 1] && t.tcp[k + 1] {
            let a = (0..3).map(|i| d2(i).powi(2)).sum::<f64>().sqrt();
            prop_assert!(
                a <= limits.tcp_max_acc * tol + noise,
                "tip second difference {a} at k {k}"
            );
        }
    }
    for k in 0..t.len() {
        for (i, a) in t.axes.iter().enumerate() {
            if t.tcp[k] && i < 3 {
                continue;
            }
            let l = limits.axes[i];
            prop_assert!(
                a.vel[k].abs() <= l.max_vel * tol + 1e-9,
                "{} vel {} > {} at k {k}",
                a.name,
                a.vel[k],
                l.max_vel
            );
            prop_assert!(
                a.acc[k].abs() <= l.max_acc * tol + 1e-9,
                "{} acc {} > {} at k {k}",
                a.name,
                a.acc[k],
                l.max_acc
            );
        }
        if t.tcp[k] {
            let v = (0..3).map(|i| t.axes[i].vel[k].powi(2)).sum::<f64>().sqrt();
            let a = (0..3).map(|i| t.axes[i].acc[k].powi(2)).sum::<f64>().sqrt();
            prop_assert!(
                v <= limits.tcp_max_vel * tol + 1e-9,
                "tip speed {v} at k {k}"
            );
            prop_assert!(a <= limits.tcp_max_acc * tol + 1e-9, "tip acc {a} at k {k}");
        }
    }
    Ok(())
}

fn close(a: &Trajectory, b: &Trajectory) -> Result<(), TestCaseError> {
    prop_assert_eq!(a.len(), b.len());
    for (x, y) in a.axes.iter().zip(&b.axes) {
        for k in 0..a.len() {
            prop_assert!(
                (x.pos[k] - y.pos[k]).abs() <= 1e-9 * (1.0 + x.pos[k].abs()),
                "{} pos at {k}: {} vs {}",
                x.name,
                x.pos[k],
                y.pos[k]
            );
            prop_assert!(
                (x.vel[k] - y.vel[k]).abs() <= 1e-6 * (1.0 + x.vel[k].abs()),
                "{} vel at {k}",
                x.name
            );
            prop_assert!(
                (x.acc[k] - y.acc[k]).abs() <= 1e-6 * (1.0 + x.acc[k].abs()),
                "{} acc at {k}",
                x.name
            );
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn random_programs_respect_limits_points_and_durations(
        ops in prop::collection::vec(op(), 1..10),
        limits in limits(),
    ) {
        let src = render(&ops, Style::Absolute);
        let run = load(&src, &InterpOptions::default(), &limits, &all_axes())
            .map_err(|e| TestCaseError::fail(format!("{e}\n{src}")))?;
        let t = &run.trajectory;
        check_limits(t, &limits)?;
        let moves = &run.toolpath.moves;
        let ts = t.ts;
        for (j, b) in t.blocks.iter().enumerate() {
            let m = &moves[b.move_index];
            let next = t.blocks.get(j + 1).map(|n| &moves[n.move_index]);
            let prev = j.checked_sub(1).map(|p| &moves[t.blocks[p].move_index]);
            if rests(m, next) {
                // Ends exactly on a sample, at rest, on the programmed point.
                let kf = b.t_end_s / ts;
                let k = kf.round() as usize;
                prop_assert!((kf - k as f64).abs() < 1e-6);
                for (i, a) in t.axes.iter().enumerate() {
                    prop_assert!((a.pos[k] - m.end[i]).abs() < 1e-9, "line {} axis {}: {} vs {}", m.line, a.name, a.pos[k], m.end[i]);
                    prop_assert!(a.vel[k].abs() < 1e-9);
                }
            }
            let dur = b.t_end_s - b.t_start_s;
            let straight = matches!(m.kind, MoveKind::Linear | MoveKind::Rapid);
            // A block on its own: it rests at both ends.
            let alone = rests(m, next) && prev.is_none_or(|p| rests(p, Some(m)));
            if straight && alone {
                let expected = rounded(t_star_line(m, &limits), ts);
                prop_assert!((dur - expected).abs() < 1e-9, "line {}: {dur} vs {expected}", m.line);
            }
            if let MoveKind::Dwell { seconds } = m.kind {
                prop_assert!((dur - rounded(seconds, ts)).abs() < 1e-9);
            }
        }
        // The last sample rests on the last programmed point (the interpolator writes that
        // sample from the program), and the profile arrives there: coming to rest within the
        // acceleration limit, the last step is at most a·Ts²/2, so a trajectory that fell
        // short and jumped onto the point would fail here.
        let last = run.toolpath.points().last().copied().unwrap_or(run.toolpath.start);
        for (i, a) in t.axes.iter().enumerate() {
            prop_assert_eq!(a.pos.last().copied(), Some(last[i]));
            if let [.., before, end] = a.pos[..] {
                let acc = limits.axes[i].max_acc.max(limits.tcp_max_acc);
                let step = (end - before).abs();
                prop_assert!(
                    step <= 0.5 * acc * ts * ts * (1.0 + 1e-6) + 1e-12,
                    "axis {}: last step {step} jumps onto the end point", a.name
                );
            }
        }
    }

    #[test]
    fn every_profile_and_rule_set_keeps_the_samples_within_the_limits(
        ops in prop::collection::vec(op(), 1..10),
        limits in limits(),
    ) {
        // Jerk-limited (vcnc's and LinuxCNC's rules) and trapezoidal under LinuxCNC 2.9's
        // rules: velocities, accelerations and second differences within the limits, third
        // differences within the jerk limits under the jerk-limited profile.
        let src = render(&ops, Style::Absolute);
        for (profile, planner) in [
            (Profile::JerkLimited, PlannerRules::Vcnc),
            (Profile::Trapezoidal, PlannerRules::LinuxCnc29),
            (Profile::JerkLimited, PlannerRules::LinuxCnc29),
        ] {
            let opts = InterpolateOptions { profile, planner, ..all_axes() };
            let run = load(&src, &InterpOptions::default(), &limits, &opts)
                .map_err(|e| TestCaseError::fail(format!("{e}\n{src}")))?;
            let t = &run.trajectory;
            let which = |e: TestCaseError| TestCaseError::fail(format!("{profile:?} {planner:?}: {e}\n{src}"));
            check_limits(t, &limits).map_err(which)?;
            if profile == Profile::JerkLimited {
                check_jerk(t, &limits).map_err(which)?;
            }
            let last = run.toolpath.points().last().copied().unwrap_or(run.toolpath.start);
            for (i, a) in t.axes.iter().enumerate() {
                prop_assert_eq!(a.pos.last().copied(), Some(last[i]));
            }
        }
    }

    #[test]
    fn arcs_stay_on_their_circle(
        ops in prop::collection::vec(op(), 1..8),
        limits in limits(),
    ) {
        let src = render(&ops, Style::Absolute);
        let run = load(&src, &InterpOptions::default(), &limits, &all_axes())
            .map_err(|e| TestCaseError::fail(format!("{e}\n{src}")))?;
        let t = &run.trajectory;
        for b in &t.blocks {
            let m = &run.toolpath.moves[b.move_index];
            if let MoveKind::Arc(a) = m.kind {
                let k0 = (b.t_start_s / t.ts).ceil() as usize;
                let k1 = ((b.t_end_s / t.ts).floor() as usize).min(t.len() - 1);
                for k in k0..=k1 {
                    let r = (t.axes[0].pos[k] - a.centre[0]).hypot(t.axes[1].pos[k] - a.centre[1]);
                    prop_assert!((r - a.radius_start_mm).abs() < 1e-9, "r = {r} vs {}", a.radius_start_mm);
                }
            }
        }
    }

    #[test]
    fn inch_and_incremental_twins_are_equal(
        ops in prop::collection::vec(op(), 1..8),
        limits in limits(),
    ) {
        let opts = all_axes();
        let io = InterpOptions::default();
        let abs = load(&render(&ops, Style::Absolute), &io, &limits, &opts)
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        let inch = load(&render(&ops, Style::Inch), &io, &limits, &opts)
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        let inc = load(&render(&ops, Style::Incremental), &io, &limits, &opts)
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        close(&abs.trajectory, &inch.trajectory)?;
        close(&abs.trajectory, &inc.trajectory)?;
    }
}

const TOKENS: &[&str] = &[
    "G0",
    "G1",
    "G2",
    "G3",
    "G4",
    "G17",
    "G18",
    "G19",
    "G20",
    "G21",
    "G43.4",
    "G49",
    "G61",
    "G64",
    "G90",
    "G91",
    "G93",
    "G94",
    "G28",
    "G54",
    "M0",
    "M2",
    "M3",
    "M6",
    "M30",
    "M428",
    "X",
    "Y",
    "Z",
    "A",
    "B",
    "C",
    "I",
    "J",
    "K",
    "R",
    "P",
    "F",
    "S",
    "T",
    "H",
    "N",
    "Q",
    "E",
    "(",
    ")",
    ";",
    "%",
    "/",
    "*",
    "\"",
    "\n",
    "\n",
    " ",
    " ",
    "-",
    ".",
    "#",
    "é",
    "\r\n",
    "[",
    "]",
    "=",
    "#1",
    "#<a>",
    "#<_b>",
    "**",
    "MOD",
    "EQ",
    "AND",
    "SIN",
    "ATAN",
    "o1",
    "o<s>",
    "sub",
    "endsub",
    "call",
    "while",
    "endwhile",
    "do",
    "repeat",
    "endrepeat",
    "if",
    "else",
    "endif",
    "break",
    "continue",
    "return",
    "G81",
    "G83",
    "G80",
    "G98",
    "G92",
    "G53",
    "G10 L2 P1",
    "G43",
    "@",
    "^",
];

fn token_soup() -> impl Strategy<Value = String> {
    prop::collection::vec(
        prop_oneof![
            3 => prop::sample::select(TOKENS).prop_map(str::to_string),
            2 => (-1000.0f64..1000.0).prop_map(|v| format!("{v}")),
            1 => (0u32..20).prop_map(|v| v.to_string()),
            1 => prop::sample::select(&["1e308", "99999999999999999999999999", "0.000000001", "-0", "5."][..]).prop_map(str::to_string),
        ],
        0..60,
    )
    .prop_map(|v| v.concat())
}

/// Parse, interpret and interpolate with a small sample budget; only panics fail.
fn exercise(text: &str) {
    let budget = InterpolateOptions {
        max_samples: 200_000,
        ..InterpolateOptions::default()
    };
    let limits = Limits::uniform(100.0, 1000.0);
    for lenient in [false, true] {
        let (program, _) = parse_with(
            text,
            &ParseOptions {
                lenient,
                ..ParseOptions::default()
            },
        );
        let opts = InterpOptions {
            lenient,
            tcp_on_mcodes: vec![428],
            max_loop_iterations: 10_000,
            ..InterpOptions::default()
        };
        if let Ok((tp, _)) = interpret(&program, &opts) {
            let _ = interpolate(&tp, &limits, &budget);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        let (program, _) = parse_bytes(&bytes, &ParseOptions::default());
        let _ = interpret(&program, &InterpOptions { lenient: true, ..InterpOptions::default() });
        exercise(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn token_soups_never_panic(text in token_soup()) {
        exercise(&text);
    }
}

#[test]
fn junk_is_handled_in_linear_time_and_bounded_memory() {
    // 8 MB of junk without line breaks, then 8 MB of short junk lines: rejected with a bounded
    // diagnostic list. (Speed is benchmarked, not asserted; this only shows it completes and
    // reports.)
    let long = "X".repeat(8 << 20);
    let (p, d) = parse_with(&long, &ParseOptions::default());
    assert!(p.blocks.is_empty());
    assert_eq!(d.len(), 1);
    let lines = "@!\n".repeat((8 << 20) / 3);
    let (_, d) = parse_with(&lines, &ParseOptions::default());
    assert_eq!(d.len(), 1001);
    assert!(d[1000].message.contains("suppressed"));
}
