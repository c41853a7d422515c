//! The generators checked through this crate's own parser, interpreter and interpolator.

use vcnc_gcode::{
    AxisName, Feed, IdentificationOptions, InterpOptions, InterpolateOptions, Limits, Loaded,
    MoveKind, SpiralOptions, TcpProgramOptions, TipPose, identification, load, spiral_points,
    tcp_program,
};

/// `text` loaded with the default options under the paper's identification limits (250 mm/s,
/// 2500 mm/s² on every axis).
fn load_at_paper_limits(text: &str) -> Loaded {
    let limits = Limits::uniform(250.0, 2500.0);
    load(
        text,
        &InterpOptions::default(),
        &limits,
        &InterpolateOptions::default(),
    )
    .unwrap()
}

/// Direction reversals between consecutive moves of axis `i`.
fn reversals(points: &[[f64; 6]], i: usize) -> usize {
    let steps: Vec<f64> = points
        .windows(2)
        .map(|w| w[1][i] - w[0][i])
        .filter(|d| *d != 0.0)
        .collect();
    steps.windows(2).filter(|w| w[0] * w[1] < 0.0).count()
}

#[test]
fn identification_takes_20_to_60_s_and_reverses_30_times() {
    // Acceptance figures from issue 2 ("Done means"): 20–60 s at the defaults with
    // 250 mm/s and 2500 mm/s² (the paper's identification settings), ≥ 30 reversals.
    for seed in 1..=8u64 {
        let opts = IdentificationOptions {
            seed,
            ..IdentificationOptions::default()
        };
        let text = identification(AxisName::X, &opts).unwrap();
        let run = load_at_paper_limits(&text);
        let t = run.trajectory.duration_s();
        let pts = run.toolpath.points();
        let rev = reversals(&pts, 0);
        println!("seed {seed}: {t:.2} s, {rev} reversals");
        assert!((20.0..=60.0).contains(&t), "seed {seed}: {t} s");
        assert!(rev >= 30, "seed {seed}: {rev} reversals");
        assert_eq!(run.toolpath.moves.len(), 70);
        assert_eq!(run.toolpath.start, [0.0; 6]);
        assert!(pts.iter().all(|p| p[0].abs() <= 50.0));
        assert!(run.toolpath.moves.iter().all(|m| m.path.is_exact_stop()));
        // Feeds up to 250 mm/s (F15000), read from the program's F words (the interpolator
        // would cap any faster feed at the 250 mm/s limit, so the trajectory alone cannot
        // show it), and the trajectory within the limit.
        let feeds: Vec<f64> = run
            .toolpath
            .moves
            .iter()
            .filter_map(|m| match m.feed {
                Some(Feed::UnitsPerMin(f)) => Some(f),
                _ => None,
            })
            .collect();
        assert_eq!(feeds.len(), 70, "every move has a per-minute feed");
        assert!(feeds.iter().all(|&f| f > 0.0 && f <= 15000.0), "{feeds:?}");
        let x = run.trajectory.axis(AxisName::X).unwrap();
        let vmax = x.vel.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(vmax <= 250.0 * (1.0 + 1e-12), "{vmax}");
        // Short and long strokes are both present.
        let strokes: Vec<f64> = pts.windows(2).map(|w| (w[1][0] - w[0][0]).abs()).collect();
        assert!(strokes.iter().any(|&s| s <= 5.0));
        assert!(strokes.iter().any(|&s| s >= 40.0));
    }
}

#[test]
fn identification_is_deterministic_and_seeded() {
    let a = identification(AxisName::Y, &IdentificationOptions::default()).unwrap();
    let b = identification(AxisName::Y, &IdentificationOptions::default()).unwrap();
    assert_eq!(a, b);
    let c = identification(
        AxisName::Y,
        &IdentificationOptions {
            seed: 2,
            ..IdentificationOptions::default()
        },
    )
    .unwrap();
    assert_ne!(a, c);
}

#[test]
fn identification_for_a_rotary_axis_is_in_degrees() {
    let text = identification(AxisName::C, &IdentificationOptions::default()).unwrap();
    let x = identification(AxisName::X, &IdentificationOptions::default()).unwrap();
    // Same numbers, only the letter differs (F is then deg/min).
    assert_eq!(text.replace('C', "X").replace("deg", "mm"), x);
    let run = load_at_paper_limits(&text);
    assert_eq!(run.toolpath.axis_names(), vec![AxisName::C]);
    let t = run.trajectory.duration_s();
    assert!((20.0..=60.0).contains(&t), "{t}");
}

#[test]
fn identification_rejects_bad_options() {
    let bad = IdentificationOptions {
        min_feed: 300.0,
        ..IdentificationOptions::default()
    };
    assert!(identification(AxisName::X, &bad).is_err());
}

/// Branch −1 orientation → (A, C) in degrees (docs/kinematics.md), C unwrapped.
fn angles(points: &[TipPose]) -> Vec<([f64; 3], f64, f64)> {
    let mut prev: Option<f64> = None;
    points
        .iter()
        .map(|q| {
            let a = -q.o[2].acos();
            let mut c = (-q.o[0]).atan2(-q.o[1]);
            if let Some(p) = prev {
                c += std::f64::consts::TAU * ((p - c) / std::f64::consts::TAU).round();
            }
            prev = Some(c);
            (q.p, a.to_degrees(), c.to_degrees())
        })
        .collect()
}

#[test]
fn spiral_geometry_matches_spec_section_6() {
    let pts = spiral_points(&SpiralOptions::default()).unwrap();
    // Every point on the dome of radius 100 centred at (30, 20, −50), o its unit normal.
    for q in &pts {
        let r = [q.p[0] - 30.0, q.p[1] - 20.0, q.p[2] + 50.0];
        let n = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        assert!((n - 100.0).abs() < 1e-9);
        for (o, r) in q.o.iter().zip(r) {
            assert!((o - r / 100.0).abs() < 1e-12);
        }
    }
    let tilt = |q: &TipPose| q.o[2].acos().to_degrees();
    // docs/contour.md: tilt 11.5° → 36.9° (acos(√(1 − 0.2²)) = 11.537°, acos(0.8) = 36.870°).
    assert!((tilt(&pts[0]) - 11.537).abs() < 1e-3);
    assert!((tilt(pts.last().unwrap()) - 36.870).abs() < 1e-3);
    // Segment lengths ≈ 0.5 mm (chords of equal arc-length steps).
    let len: f64 = pts
        .windows(2)
        .map(|w| {
            let d: Vec<f64> = (0..3).map(|i| w[1].p[i] - w[0].p[i]).collect();
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
        })
        .sum();
    let segs = pts.len() - 1;
    println!("spiral: {segs} segments, polyline length {len:.3} mm");
    // docs/contour.md: ≈ 755 mm.
    assert!((len - 755.0).abs() < 5.0, "{len}");
    assert!((len / segs as f64 - 0.5).abs() < 0.01);
}

#[test]
fn spiral_program_runs_as_one_trapezoid_in_about_10_1_s_without_dips() {
    let pts = spiral_points(&SpiralOptions::default()).unwrap();
    let text = tcp_program(&angles(&pts), &TcpProgramOptions::default()).unwrap();
    let mut limits = Limits::uniform(250.0, 2500.0);
    limits.tcp_max_vel = 75.0;
    limits.tcp_max_acc = 1500.0;
    for i in 3..6 {
        // Rotary limits out of the way: this test is about the tip path.
        limits.axes[i].max_vel = 1000.0;
        limits.axes[i].max_acc = 1.0e6;
    }
    // The machine starts where the program's opening rapid goes, so that rapid costs nothing
    // and the path is the spiral alone.
    let (program, _) = vcnc_gcode::parse(&text);
    let (first, _) = vcnc_gcode::interpret(&program, &InterpOptions::default()).unwrap();
    assert_eq!(first.moves[0].kind, MoveKind::Rapid);
    let opts = InterpOptions {
        start: vcnc_gcode::StartPosition::Machine(first.moves[0].end),
        ..InterpOptions::default()
    };
    let run = load(&text, &opts, &limits, &InterpolateOptions::default()).unwrap();
    let tp = &run.toolpath;
    assert!(tp.moves.iter().all(|m| m.tcp && !m.path.is_exact_stop()));
    assert!(tp.moves.iter().all(|m| matches!(m.kind, MoveKind::Linear)));
    let l: f64 = tp
        .moves
        .iter()
        .map(|m| {
            let d: Vec<f64> = (0..3).map(|i| m.end[i] - m.start[i]).collect();
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
        })
        .sum();
    // One trapezoid over the whole path: T = L/V + V/A, rounded up to the 1 ms sample; the
    // corner blends of plain G64 (arcs within a quarter of a segment, tangent to both) take a
    // little of the tip's acceleration sideways where the ramps run over them, a few ms.
    let t_star = l / 75.0 + 75.0 / 1500.0;
    let t = run.trajectory.duration_s();
    println!("spiral: L = {l:.3} mm, T = {t:.4} s (one trapezoid: {t_star:.4} s)");
    assert!((l - 755.0).abs() < 5.0);
    assert!(t >= t_star - 1e-9 && t < t_star + 0.005, "{t} vs {t_star}");
    assert!((t - 10.1).abs() < 0.1);
    // Tip speed: 75 mm/s cruise from 0.05 s to T − 0.05 s, no dips.
    let v = |k: usize| {
        let s: f64 = [AxisName::X, AxisName::Y, AxisName::Z]
            .iter()
            .map(|&a| run.trajectory.axis(a).unwrap().vel[k].powi(2))
            .sum();
        s.sqrt()
    };
    let n = run.trajectory.len();
    for k in 60..n - 60 {
        assert!((v(k) - 75.0).abs() < 0.01, "k = {k}: {}", v(k));
    }
    assert!(run.trajectory.tcp.iter().all(|&b| b));
}
