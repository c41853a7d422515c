//! Unit tests of the interpreter. Where a test states "rs274", its truth is the output of
//! LinuxCNC 2.9's stand-alone interpreter on the same lines (the program corpus and goldens
//! of `tests/linuxcnc.rs` hold the full comparisons).

use super::*;
use crate::syntax::parse;
use std::f64::consts::{FRAC_PI_2, PI};

fn run(src: &str) -> Result<(Toolpath, Vec<Diagnostic>), Vec<Diagnostic>> {
    run_with(src, &InterpOptions::default())
}

fn run_with(
    src: &str,
    opts: &InterpOptions,
) -> Result<(Toolpath, Vec<Diagnostic>), Vec<Diagnostic>> {
    let (p, d) = parse(src);
    assert!(d.is_empty(), "{d:?}");
    interpret(&p, opts)
}

fn ok(src: &str) -> Toolpath {
    match run(src) {
        Ok((tp, _)) => tp,
        Err(e) => panic!("{src}: {e:?}"),
    }
}

/// (line, col) of every error.
fn errors(src: &str) -> Vec<(u32, u32)> {
    match run(src) {
        Ok(_) => Vec::new(),
        Err(d) => d
            .iter()
            .filter(|d| d.is_error())
            .map(|d| (d.line, d.col))
            .collect(),
    }
}

/// The first error: line, column, kind, message.
fn first_error(src: &str) -> (u32, u32, DiagnosticKind, String) {
    let d = run(src).expect_err(src);
    let e = d.iter().find(|d| d.is_error()).expect("an error");
    (e.line, e.col, e.kind, e.message.clone())
}

fn arc(m: &Move) -> ArcMove {
    match m.kind {
        MoveKind::Arc(a) => a,
        k => panic!("not an arc: {k:?}"),
    }
}

/// End points of the motions (dwells excluded).
fn ends(tp: &Toolpath) -> Vec<[f64; 6]> {
    tp.points()[1..].to_vec()
}

fn xyz(x: f64, y: f64, z: f64) -> [f64; 6] {
    [x, y, z, 0.0, 0.0, 0.0]
}

fn close(a: [f64; 6], b: [f64; 6]) -> bool {
    a.iter().zip(b).all(|(p, q)| (p - q).abs() < 1e-9)
}

#[test]
fn the_machine_starts_at_the_start_position() {
    // Default: every axis at 0 (homed); the first block moves from there.
    let tp = ok("G4 P1\nG0 X10 Y5\nG1 X20 F600");
    assert_eq!(tp.start, [0.0; 6]);
    assert_eq!(tp.moves.len(), 3);
    assert_eq!(tp.moves[0].kind, MoveKind::Dwell { seconds: 1.0 });
    assert_eq!(tp.moves[1].start, [0.0; 6]);
    assert_eq!(tp.moves[1].end, xyz(10.0, 5.0, 0.0));
    assert_eq!(tp.moves[2].feed, Some(Feed::UnitsPerMin(600.0)));
    let opts = InterpOptions {
        start: StartPosition::Machine([1.0; 6]),
        ..InterpOptions::default()
    };
    let (tp, _) = run_with("G0 X10 Y5", &opts).unwrap();
    assert_eq!(tp.start, [1.0; 6]);
    assert_eq!(tp.moves[0].start, [1.0; 6]);
    assert_eq!(tp.moves[0].end, [10.0, 5.0, 1.0, 1.0, 1.0, 1.0]);
    // A first move to where the machine already is costs nothing.
    assert!(ok("G0 X0").moves.is_empty());
}

#[test]
fn legacy_start_at_the_first_move() {
    let opts = InterpOptions {
        start: StartPosition::FirstMove,
        ..InterpOptions::default()
    };
    let (tp, _) = run_with("G4 P1\nG0 X10 Y5\nG1 X20 F600", &opts).unwrap();
    assert_eq!(tp.start, xyz(10.0, 5.0, 0.0));
    assert_eq!(tp.moves.len(), 2);
    // The dwell before the first motion holds at the start.
    assert_eq!(tp.moves[0].start, tp.start);
    assert_eq!(tp.moves[1].end, xyz(20.0, 5.0, 0.0));
    let (tp, w) = run_with("G2 X0 Y0 I1 F10", &opts).unwrap();
    assert_eq!(tp.start, [0.0; 6]);
    assert!(w[0].message.contains("first motion is an arc"));
}

#[test]
fn incremental_equals_absolute() {
    let a = ok("G0 X1 Y2\nG90 G1 X4 Y6 A30 F100\nX0");
    let b = ok("G0 X1 Y2\nG91 G1 X3 Y4 A30 F100\nX-4");
    assert_eq!(a, b);
}

#[test]
fn inch_converts_lengths_and_linear_feeds_only() {
    // 1 in = 25.4 mm exactly; rotary words and pure rotary feeds are not scaled.
    let tp = ok("G20 G0 X1 A0\nG1 X2 F10\nG1 A90 F3600");
    assert_eq!(tp.moves[0].end[0], 25.4);
    assert_eq!(tp.moves[1].end[0], 50.8);
    assert_eq!(tp.moves[1].feed, Some(Feed::UnitsPerMin(254.0)));
    assert_eq!(tp.moves[2].end[3], 90.0);
    assert_eq!(tp.moves[2].feed, Some(Feed::UnitsPerMin(3600.0)));
}

#[test]
fn feed_is_read_before_the_units_change_as_in_linuxcnc() {
    // rs274: `G20 G1 X1 F10` sets the feed (10, in mm/min: still G21) before switching to
    // inches; `G21 G1 X2 F10` sets 10 in/min before switching back.
    let tp = ok("G20 G1 X1 F10\nG21 G1 X2 F10");
    assert_eq!(tp.moves[0].feed, Some(Feed::UnitsPerMin(10.0)));
    assert_eq!(tp.moves[1].feed, Some(Feed::UnitsPerMin(254.0)));
}

#[test]
fn modal_conflicts_and_repeats_are_errors_with_columns() {
    assert_eq!(errors("G0 G1 X1 F1"), vec![(1, 4)]);
    assert_eq!(errors("G90 G91"), vec![(1, 5)]);
    assert_eq!(errors("G0 X1\nG1 X1 X2 F1"), vec![(2, 7)]);
    assert_eq!(errors("M3 M5"), vec![(1, 4)]);
    assert_eq!(errors("M8 M9"), vec![(1, 4)]);
    assert!(errors("M7 M8").is_empty());
    assert_eq!(errors("G17 G18"), vec![(1, 5)]);
    assert_eq!(errors("G54 G55"), vec![(1, 5)]);
}

#[test]
fn words_without_a_user_are_errors() {
    assert_eq!(errors("G0 X0\nG1 X1 I2 F100"), vec![(2, 7)]);
    assert_eq!(errors("G1 P2 F100"), vec![(1, 4)]);
    assert_eq!(errors("H1"), vec![(1, 1)]);
    assert_eq!(errors("X1"), vec![(1, 1)]);
    assert_eq!(errors("G4"), vec![(1, 1)]);
    assert_eq!(errors("G0 L2 X1"), vec![(1, 4)]);
    assert!(errors("G43.4 H1 G64 P0.01 Q0.01").is_empty());
    assert_eq!(errors("G80 X1"), vec![(1, 5)]);
    assert_eq!(errors("G53 G2 X1 I1 F10"), vec![(1, 1)]);
}

#[test]
fn feeds_must_be_set() {
    // No feed ever set.
    assert_eq!(errors("G0 X0\nG1 X1"), vec![(2, 1)]);
    // G93: F on every feed block.
    assert_eq!(errors("G0 X0\nG93 G1 X1 F2\nG1 X3"), vec![(3, 1)]);
    // Leaving G93 leaves no feed.
    assert_eq!(errors("G0 X0\nG93 G1 X1 F2\nG94 G1 X3"), vec![(3, 5)]);
    let tp = ok("G0 X0\nG93 G1 X1 F2\nG0 X0\nG1 X3 F4");
    assert_eq!(tp.moves[0].feed, Some(Feed::InverseTime(2.0)));
    assert_eq!(tp.moves[1].feed, None);
    assert_eq!(tp.moves[2].feed, Some(Feed::InverseTime(4.0)));
}

#[test]
fn lenient_only_downgrades_what_cannot_change_the_path() {
    let src = "G0 X0\nG1 X1 F100 E5 M101\nM2";
    assert_eq!(errors(src), vec![(2, 12), (2, 15)]);
    let opts = InterpOptions {
        lenient: true,
        ..InterpOptions::default()
    };
    let (tp, warnings) = run_with(src, &opts).unwrap();
    assert_eq!(tp.moves.len(), 1);
    assert_eq!(warnings.len(), 2);
    assert!(warnings.iter().all(|w| w.severity == Severity::Warning));
    // Unknown G- and M-codes, unsupported axes and compensation errors stay errors.
    for src in ["G5.1 X1", "M587", "G0 U1", "G19 G41.1 D1", "M70"] {
        let (p, _) = parse(src);
        let e = interpret(&p, &opts).expect_err(src);
        assert!(e.iter().any(Diagnostic::is_error), "{src}");
    }
}

#[test]
fn centre_format_arcs() {
    // Quarter circle clockwise about the origin: from angle 0 to −90°.
    let tp = ok("G0 X10 Y0\nG2 X0 Y-10 I-10 J0 F100");
    let a = arc(&tp.moves[1]);
    assert_eq!(a.centre, [0.0, 0.0]);
    assert!((a.sweep_rad + FRAC_PI_2).abs() < 1e-12);
    assert_eq!(a.radius_start_mm, 10.0);
    // Full circle, and two turns with P2.
    let tp = ok("G0 X10 Y0\nG3 X10 Y0 I-10 F100\nG3 X10 Y0 I-10 P2");
    assert!((arc(&tp.moves[1]).sweep_rad - 2.0 * PI).abs() < 1e-12);
    assert!((arc(&tp.moves[2]).sweep_rad - 4.0 * PI).abs() < 1e-12);
    // G18: first axis Z, second X; K and I offsets.
    let tp = ok("G18 G0 X0 Z10\nG3 X10 Z0 K-10 F100");
    let a = arc(&tp.moves[1]);
    assert_eq!(a.plane, Plane::ZX);
    assert_eq!(a.centre, [0.0, 0.0]);
    assert!((a.sweep_rad - FRAC_PI_2).abs() < 1e-12);
    // Offsets off the plane are errors.
    assert_eq!(errors("G0 X10 Y0\nG2 X0 Y-10 I-10 K1 F100"), vec![(2, 17)]);
}

#[test]
fn full_circles_without_an_end_point() {
    // rs274: `G2 I-5` from (5,0) is ARC_FEED(5, 0, 0, 0, -1); a bare `I1` with G3 modal is a
    // full circle about (6, 0); `G2` alone is "R i j k words all missing for arc".
    let tp = ok("G0 X5\nG2 I-5 F100\nG3 J2 P2\nI1");
    let a = arc(&tp.moves[1]);
    assert_eq!(a.centre, [0.0, 0.0]);
    assert!((a.sweep_rad + 2.0 * PI).abs() < 1e-12);
    let b = arc(&tp.moves[2]);
    assert_eq!(b.centre, [5.0, 2.0]);
    assert!((b.sweep_rad - 4.0 * PI).abs() < 1e-12);
    let c = arc(&tp.moves[3]);
    assert_eq!(c.centre, [6.0, 0.0]);
    assert!((c.sweep_rad - 2.0 * PI).abs() < 1e-12);
    assert_eq!(errors("G0 X1\nG2 F10"), vec![(2, 1)]);
    // G90.1: I J are the centre itself.
    let tp = ok("G0 X5\nG90.1 G3 X-5 I0 J0 F100");
    assert_eq!(arc(&tp.moves[1]).centre, [0.0, 0.0]);
}

#[test]
fn radius_format_arcs() {
    // G3 from (1,0) to (0,1): R1 → centre (0,0), 90°; R−1 → centre (1,1), 270°.
    let tp = ok("G0 X1 Y0\nG3 X0 Y1 R1 F100\nG0 X1 Y0\nG3 X0 Y1 R-1");
    let a = arc(&tp.moves[1]);
    assert!(a.centre[0].abs() < 1e-12 && a.centre[1].abs() < 1e-12);
    assert!((a.sweep_rad - FRAC_PI_2).abs() < 1e-12);
    let b = arc(&tp.moves[3]);
    assert!((b.centre[0] - 1.0).abs() < 1e-12 && (b.centre[1] - 1.0).abs() < 1e-12);
    assert!((b.sweep_rad - 1.5 * PI).abs() < 1e-12);
    // G2 with R > 0 puts the centre on the right: (1,0) → (0,1) centre (1,1), −90°.
    let tp = ok("G0 X1 Y0\nG2 X0 Y1 R1 F100");
    let c = arc(&tp.moves[1]);
    assert!((c.centre[0] - 1.0).abs() < 1e-12 && (c.centre[1] - 1.0).abs() < 1e-12);
    assert!((c.sweep_rad + FRAC_PI_2).abs() < 1e-12);
}

#[test]
fn arcs_that_do_not_fit_are_errors() {
    // End radius 10.5 vs start radius 10: 5 %, far over 0.002 mm and 0.1 %.
    assert_eq!(errors("G0 X10 Y0\nG2 X0 Y-10.5 I-10 J0 F100"), vec![(2, 1)]);
    // Within 0.002 mm: accepted (runs as a spiral).
    let tp = ok("G0 X10 Y0\nG2 X0 Y-10.001 I-10 J0 F100");
    assert!((arc(&tp.moves[1]).radius_end_mm - 10.001).abs() < 1e-12);
    // R shorter than half the chord (5 mm).
    assert_eq!(errors("G0 X0 Y0\nG2 X10 Y0 R4 F100"), vec![(2, 11)]);
    // A 1.27 µm shortfall is tolerated (LinuxCNC RADIUS_TOLERANCE_MM): a half circle.
    let tp = ok("G0 X0 Y0\nG2 X10 Y0 R4.999 F100");
    assert_eq!(errors("G0 X0 Y0\nG2 X10 Y0 R4.99 F100"), vec![(2, 11)]);
    assert!(
        tp.moves
            .iter()
            .any(|m| matches!(m.kind, MoveKind::Arc(a) if (a.sweep_rad + PI).abs() < 1e-12))
    );
    // R and I together; no offsets at all.
    assert_eq!(errors("G0 X0 Y0\nG2 X10 Y0 R5 I5 F100"), vec![(2, 11)]);
    assert_eq!(errors("G0 X0 Y0\nG2 X10 Y0 F100"), vec![(2, 1)]);
}

#[test]
fn tcp_mode_by_g43_4_or_mapped_m_codes() {
    let tp = ok("G0 X1\nG43.4 H1\nG1 X2 F100\nG49\nG1 X3");
    assert!(tp.moves[1].tcp && !tp.moves[2].tcp);
    let opts = InterpOptions {
        tcp_on_mcodes: vec![428],
        tcp_off_mcodes: vec![429],
        ..InterpOptions::default()
    };
    let (tp, _) = run_with("G0 X1\nM428\nG1 X2 F100\nM429\nG1 X3", &opts).unwrap();
    assert!(tp.moves[1].tcp && !tp.moves[2].tcp);
    assert_eq!(errors("M428"), vec![(1, 1)]);
}

#[test]
fn path_mode_stops_and_program_end() {
    let tp = ok("%\nG0 X1\nG64 P0.05 G1 X2 F100\nM6 T2\nG1 X3\nM0\nG61 G1 X4\nM30\nG1 X9\n%");
    assert_eq!(tp.moves.len(), 4);
    // vcnc's start-up mode is exact stop (G61.1).
    assert_eq!(tp.moves[0].path, PathMode::ExactStop);
    assert!(tp.moves[1].stop_after);
    // G64 P without Q merges within P (LinuxCNC's convert_control_mode).
    assert_eq!(
        tp.moves[1].path,
        PathMode::Blend {
            tolerance_mm: Some(0.05),
            merge_mm: Some(0.05)
        }
    );
    assert!(tp.moves[2].stop_after);
    assert_eq!(tp.moves[3].path, PathMode::ExactPath);
    let tp =
        ok("G0 X1\nG64 G1 X2 F100\nG64 P0.1 Q0.02 X3\nG64 P0 Q0.5 X4\nG61.1 X5\nG20 G64 P0.01 X6");
    let modes: Vec<PathMode> = tp.moves.iter().map(|m| m.path).collect();
    let blend = |p: Option<f64>, q: Option<f64>| PathMode::Blend {
        tolerance_mm: p,
        merge_mm: q,
    };
    assert_eq!(modes[1], blend(None, None));
    assert_eq!(modes[2], blend(Some(0.1), Some(0.02)));
    assert_eq!(modes[3], blend(None, Some(0.5)));
    assert_eq!(modes[4], PathMode::ExactStop);
    assert_eq!(modes[5], blend(Some(0.254), Some(0.254)));
    assert_eq!(errors("G64 P-1 G0 X1"), vec![(1, 5)]);
    assert_eq!(PathMode::parse("g61.1"), Some(PathMode::ExactStop));
    assert_eq!(PathMode::parse(" G61 "), Some(PathMode::ExactPath));
    assert_eq!(
        PathMode::parse("G64 P0.02"),
        Some(blend(Some(0.02), Some(0.02)))
    );
    assert_eq!(PathMode::parse("G64 P0 Q0.1"), Some(blend(None, Some(0.1))));
    assert_eq!(PathMode::parse("G64"), Some(blend(None, None)));
    for bad in [
        "",
        "G62",
        "G64 P",
        "G64 P-1",
        "G64 X1",
        "G61 P1",
        "G64 P1 P2",
    ] {
        assert_eq!(PathMode::parse(bad), None, "{bad}");
    }
    let (_, warnings) = run("G0 X0\nM2\nG1 X9").unwrap();
    assert_eq!(warnings.len(), 1);
    assert_eq!(warnings[0].line, 3);
}

#[test]
fn block_delete_switch() {
    let src = "G0 X1\n/G0 X5\nG0 X2";
    assert_eq!(ok(src).moves.len(), 3);
    let opts = InterpOptions {
        block_delete: true,
        ..InterpOptions::default()
    };
    assert_eq!(run_with(src, &opts).unwrap().0.moves.len(), 2);
}

#[test]
fn dwell_and_units() {
    let tp = ok("G0 X1\nG4 P0.5\nG20 G1 X1 F10");
    assert_eq!(tp.moves[1].kind, MoveKind::Dwell { seconds: 0.5 });
    assert_eq!(tp.moves[2].end[0], 25.4);
}

#[test]
fn parameters_expressions_and_end_of_line_assignment() {
    // rs274: `#16=5 #17=#16` leaves #17 at its old value 0; precedence and MOD as LinuxCNC.
    let tp = ok(
        "#16=5 #17=#16\nG0 X#16 Y[#17 + 0]\n#1 = [2 ** 3 ** 2]\n#2 = [-7 MOD 3]\n\
         #<v> = ATAN[1]/[-1]\nG0 X#1 Y#2 Z#<v>\nG0 X[1 + 2 * 3 - 4 / 2] Y[ROUND[-2.5]] Z[FIX[-2.5]]",
    );
    let e = ends(&tp);
    assert_eq!(e[0], xyz(5.0, 0.0, 0.0));
    assert_eq!(e[1], xyz(64.0, 2.0, 135.0));
    assert_eq!(e[2], xyz(5.0, -3.0, -3.0));
}

#[test]
fn named_parameters_and_exists() {
    let tp = ok("#<_g> = 2\n#<l> = 3\nG0 X[#<_g> + #<l>] Y[EXISTS[#<l>]] Z[EXISTS[#<nope>]]");
    assert_eq!(ends(&tp)[0], xyz(5.0, 1.0, 0.0));
    let (l, c, k, m) = first_error("G0 X#<nope>");
    assert_eq!((l, c, k), (1, 5, DiagnosticKind::UndefinedParameter));
    assert!(m.contains("#<nope>"), "{m}");
    // System parameters are read-only.
    assert_eq!(first_error("#<_x> = 1").2, DiagnosticKind::Block);
}

#[test]
fn arithmetic_errors_name_the_operator() {
    let (l, c, k, m) = first_error("#1 = 0\nG0 X[2 / #1]");
    assert_eq!((l, c, k), (2, 8, DiagnosticKind::Arithmetic));
    assert!(m.contains("division by zero"), "{m}");
    assert_eq!(first_error("G0 X[SQRT[-1]]").2, DiagnosticKind::Arithmetic);
    assert_eq!(first_error("G0 X[ACOS[2]]").2, DiagnosticKind::Arithmetic);
    assert_eq!(
        first_error("G0 X#[3000 * 3]").2,
        DiagnosticKind::ParameterNumber
    );
}

#[test]
fn subroutines_with_arguments_local_scope_and_return_values() {
    // rs274: inside the call #1 #2 are the arguments and #<x> is local; after it #1 and #<x>
    // are the caller's again and #<_value> holds the return value.
    let src = "#1=11 #<x>=3\no<s> sub\n#<x>=9\nG0 X#1 Y#<x> Z#2\n#1=4\no<s> return [#1*2]\n\
               o<s> endsub\no<s> call [7] [8]\nG0 X#1 Y#<x> Z#<_value>\nM2";
    let tp = ok(src);
    assert_eq!(ends(&tp), vec![xyz(7.0, 9.0, 8.0), xyz(11.0, 3.0, 8.0)]);
    // The caller's locals are not visible in the sub.
    assert_eq!(
        first_error("#<a>=1\no1 sub\nG0 X#<a>\no1 endsub\no1 call").2,
        DiagnosticKind::UndefinedParameter
    );
    // Recursion stops at the call depth.
    let (_, _, k, _) = first_error("o1 sub\no1 call\no1 endsub\no1 call");
    assert_eq!(k, DiagnosticKind::CallDepth);
    // A call to a sub the file does not define.
    let (l, c, k, _) = first_error("G0 X1\no<nope> call [1]");
    assert_eq!((l, c, k), (2, 1, DiagnosticKind::UndefinedSubroutine));
}

#[test]
fn loops_and_conditions() {
    // rs274: do … while runs X1 X2 X3; repeat [2] runs twice.
    let tp = ok(
        "#1=0\no1 do\n#1=[#1+1]\nG0 X#1\no1 while [#1 LT 3]\no2 repeat [2]\nG0 Y#1\n#1=[#1+1]\no2 endrepeat",
    );
    let e = ends(&tp);
    assert_eq!(
        e,
        vec![
            xyz(1.0, 0.0, 0.0),
            xyz(2.0, 0.0, 0.0),
            xyz(3.0, 0.0, 0.0),
            xyz(3.0, 3.0, 0.0),
            xyz(3.0, 4.0, 0.0)
        ]
    );
    // rs274: continue at 2, break at 4 → X1 X3 then Y4.
    let tp = ok(
        "#1=0\no1 while [#1 LT 10]\n#1=[#1+1]\no2 if [#1 EQ 2]\no1 continue\no2 elseif [#1 EQ 4]\n\
         o1 break\no2 else\nG0 X#1\no2 endif\no1 endwhile\nG0 Y#1",
    );
    assert_eq!(
        ends(&tp),
        vec![xyz(1.0, 0.0, 0.0), xyz(3.0, 0.0, 0.0), xyz(3.0, 4.0, 0.0)]
    );
    // A break out of an inner while nested in a repeat.
    let tp = ok(
        "#1=0\no1 repeat [3]\no2 while [1]\n#1=[#1+1]\no3 if [#1 MOD 2 EQ 0]\no2 break\no3 endif\no2 endwhile\no1 endrepeat\nG0 X#1",
    );
    assert_eq!(ends(&tp), vec![xyz(6.0, 0.0, 0.0)]);
    // rs274: "no matching while/do label" for break/continue in a repeat; continue in a do
    // loop leaves the loop in LinuxCNC 2.9, so vcnc refuses it.
    assert_eq!(
        first_error("o1 repeat [2]\no1 break\no1 endrepeat").2,
        DiagnosticKind::ControlFlow
    );
    assert_eq!(
        first_error("o1 do\no1 continue\no1 while [0]").2,
        DiagnosticKind::ControlFlow
    );
}

#[test]
fn endless_loops_stop_at_the_budget() {
    let opts = InterpOptions {
        max_loop_iterations: 1000,
        ..InterpOptions::default()
    };
    let (p, _) = parse("#1=0\no7 while [1]\n#1=[#1+1]\no7 endwhile");
    let d = interpret(&p, &opts).expect_err("endless");
    let e = d.iter().find(|d| d.is_error()).unwrap();
    assert_eq!((e.line, e.col, e.kind), (2, 4, DiagnosticKind::LoopBudget));
    assert!(e.message.contains("line 2"), "{}", e.message);
}

#[test]
fn control_flow_errors_name_the_statement() {
    let (l, c, k, _) = first_error("G0 X1\no100 endsub");
    assert_eq!((l, c, k), (2, 6, DiagnosticKind::ControlFlow));
    assert_eq!(
        first_error("o1 if [1]\nG0 X1").2,
        DiagnosticKind::ControlFlow
    );
    assert_eq!(
        first_error("o1 if [1]\no2 endif").2,
        DiagnosticKind::ControlFlow
    );
    assert_eq!(
        first_error("o1 while [1]\no2 break\no1 endwhile").2,
        DiagnosticKind::ControlFlow
    );
    assert_eq!(
        first_error("o1 sub\no1 endsub\no1 sub\no1 endsub").2,
        DiagnosticKind::ControlFlow
    );
    // A bare program number is ignored, as by LinuxCNC.
    assert_eq!(ends(&ok("O1234\nG0 X1")), vec![xyz(1.0, 0.0, 0.0)]);
}

#[test]
fn work_offsets_g92_g52_and_g53() {
    // rs274: G10 L2 P1 X10 Y20 Z5 then G54 G0 X1 Y2 Z3 → machine (11, 22, 8); G92 X0 Y0 there
    // gives offsets (1, 2); G53 G0 X0 Y0 Z0 goes to machine 0.
    let tp = ok(
        "G10 L2 P1 X10 Y20 Z5\nG54 G0 X1 Y2 Z3\nG92 X0 Y0\nG0 X1 Y1\nG53 G0 X0 Y0 Z0\nG92.1\nG0 X0 Y0 Z0",
    );
    let e = ends(&tp);
    assert!(close(e[0], xyz(11.0, 22.0, 8.0)), "{e:?}");
    assert!(close(e[1], xyz(12.0, 23.0, 8.0)), "{e:?}");
    assert!(close(e[2], xyz(0.0, 0.0, 0.0)), "{e:?}");
    assert!(close(e[3], xyz(10.0, 20.0, 5.0)), "{e:?}");
    // rs274: G10 L20 P1 X5 at machine X1 (prog X0 with G92 offset 1) → G54 X offset −5.
    let tp = ok("G0 X1 Y1\nG92 X0 Y0\nG10 L20 P1 X5\nG0 X0\nG53 G0 X0\nG0 X0");
    let e = ends(&tp);
    assert!(close(e[1], xyz(-4.0, 1.0, 0.0)), "{e:?}");
    assert!(close(e[3], xyz(-4.0, 1.0, 0.0)), "{e:?}");
    // rs274: G52 X5 after G92 X1 Y2 Z3 at 0 → offsets (5, −2, −3).
    let tp = ok("G92 X1 Y2 Z3\nG52 X5\nG0 X0 Y0 Z0");
    assert!(close(ends(&tp)[0], xyz(5.0, -2.0, -3.0)));
}

#[test]
fn parameter_file_offsets_in_machine_units() {
    let mut params = ParameterTable::default();
    params.set(5220, 2.0);
    params.set(5241, 1.0);
    params.set(5242, 2.0);
    let opts = InterpOptions {
        parameters: params,
        machine_units: LengthUnit::Inch,
        ..InterpOptions::default()
    };
    // G55 active at start, offsets in inches: X0 Y0 is machine (25.4, 50.8).
    let (tp, _) = run_with("G0 X0 Y0\nG54 G0 X0 Y0", &opts).unwrap();
    assert_eq!(tp.moves[0].end, xyz(25.4, 50.8, 0.0));
    assert_eq!(tp.moves.len(), 2);
    assert_eq!(tp.moves[1].end, [0.0; 6]);
}

#[test]
fn tool_length_offsets() {
    let mut tools = ToolTable::default();
    tools.tools.insert(
        1,
        crate::tables::Tool {
            offset: [0.0, 0.0, 12.7, 0.0, 0.0, 0.0],
            ..Default::default()
        },
    );
    tools.tools.insert(
        3,
        crate::tables::Tool {
            offset: [2.54, 0.0, -6.35, 0.0, 0.0, 0.0],
            ..Default::default()
        },
    );
    let opts = InterpOptions {
        tools,
        ..InterpOptions::default()
    };
    // rs274: T3 M6 G43 → (2.54, 0, −6.35); G43 H1 → Z 12.7; G43.1 Z1; G43.2 H3 adds; G49.
    let src = "T3 M6\nG43\nG0 X2 Z0\nG43 H1\nG0 X3 Z0\nG43.1 Z1\nG0 X4 Z0\nG43.2 H3\nG0 X5 Z0\nG49\nG0 X6 Z0";
    let (tp, _) = run_with(src, &opts).unwrap();
    let e = ends(&tp);
    assert!(close(e[0], xyz(4.54, 0.0, -6.35)), "{e:?}");
    assert!(close(e[1], xyz(3.0, 0.0, 12.7)), "{e:?}");
    assert!(close(e[2], xyz(4.0, 0.0, 1.0)), "{e:?}");
    assert!(close(e[3], xyz(7.54, 0.0, -5.35)), "{e:?}");
    assert!(close(e[4], xyz(6.0, 0.0, 0.0)), "{e:?}");
    let (p, _) = parse("G43 H9");
    let d = interpret(&p, &opts).unwrap_err();
    assert!(d[0].message.contains("tool 9"), "{d:?}");
}

#[test]
fn g28_goes_through_the_point_to_the_stored_position() {
    // rs274: G28 Z1 rapids to Z1 then Z to the G28 position, X Y stay.
    let tp = ok("G0 X1 Y2 Z3\nG28.1\nG0 X5 Y5 Z5\nG28 Z1\nG28");
    let e = ends(&tp);
    assert_eq!(e[1], xyz(5.0, 5.0, 5.0));
    assert_eq!(e[2], xyz(5.0, 5.0, 1.0));
    assert_eq!(e[3], xyz(5.0, 5.0, 3.0));
    assert_eq!(e[4], xyz(1.0, 2.0, 3.0));
}

#[test]
fn polar_coordinates() {
    let tp = ok("G0 @10 ^90\nG91 G0 ^90\nG0 @5");
    let e = ends(&tp);
    assert!(close(e[0], xyz(0.0, 10.0, 0.0)), "{e:?}");
    assert!(close(e[1], xyz(-10.0, 0.0, 0.0)), "{e:?}");
    assert!(close(e[2], xyz(-15.0, 0.0, 0.0)), "{e:?}");
    assert_eq!(errors("G0 X1 @2 ^90"), vec![(1, 7)]);
}

#[test]
fn canned_cycles_expand_as_in_linuxcnc() {
    // rs274 (LinuxCNC 2.9): the G81 positions at Z10, drills to −2 and retracts to R2 (G99 at
    // start); X3 repeats it; G98 G83 pecks 1.1 with R1, rapids out to R between pecks and back
    // to 0.254 mm above the last depth, and retracts to the initial level (Z2 after the G80).
    let tp = ok("G0 X0 Y0 Z10\nF100\nG81 X1 Y1 Z-2 R2\nX3\nG80\nG98 G83 X0 Y0 Z-3 R1 Q1.1");
    let got: Vec<(bool, [f64; 6])> = tp
        .moves
        .iter()
        .map(|m| (m.kind == MoveKind::Rapid, m.end))
        .collect();
    let want = [
        (true, xyz(0.0, 0.0, 10.0)),
        (true, xyz(1.0, 1.0, 10.0)),
        (true, xyz(1.0, 1.0, 2.0)),
        (false, xyz(1.0, 1.0, -2.0)),
        (true, xyz(1.0, 1.0, 2.0)),
        (true, xyz(3.0, 1.0, 2.0)),
        (false, xyz(3.0, 1.0, -2.0)),
        (true, xyz(3.0, 1.0, 2.0)),
        (true, xyz(0.0, 0.0, 2.0)),
        (true, xyz(0.0, 0.0, 1.0)),
        (false, xyz(0.0, 0.0, -0.1)),
        (true, xyz(0.0, 0.0, 1.0)),
        (true, xyz(0.0, 0.0, 0.154)),
        (false, xyz(0.0, 0.0, -1.2)),
        (true, xyz(0.0, 0.0, 1.0)),
        (true, xyz(0.0, 0.0, -0.946)),
        (false, xyz(0.0, 0.0, -2.3)),
        (true, xyz(0.0, 0.0, 1.0)),
        (true, xyz(0.0, 0.0, -2.046)),
        (false, xyz(0.0, 0.0, -3.0)),
        (true, xyz(0.0, 0.0, 2.0)),
    ];
    assert_eq!(got.len(), want.len(), "{got:?}");
    for (g, w) in got.iter().zip(want) {
        assert_eq!(g.0, w.0, "{got:?}");
        assert!(close(g.1, w.1), "{g:?} vs {w:?}");
    }
    assert!(tp.moves[1..].iter().all(|m| m.line >= 3));
    // Errors: no R, R below Z, G93.
    assert_eq!(first_error("F10\nG81 X1 Z-1").2, DiagnosticKind::Block);
    assert_eq!(first_error("F10\nG81 X1 Z-1 R-2").2, DiagnosticKind::Block);
    assert_eq!(first_error("G93 G81 X1 Z-1 R1 F1").2, DiagnosticKind::Block);
}

#[test]
fn cutter_compensation_errors_name_the_line() {
    // Lines 1–3 turn compensation on and make the entry move.
    let on = "G0 X-9 Y-9\nG41.1 D2\nG1 X0 Y0 F100\n";
    let cases = [
        (format!("{on}G41.1 D2"), 4, "when it is on"),
        ("G19 G41.1 D2".to_string(), 1, "not G19"),
        ("G18 G41.1 D2 L10".to_string(), 1, "from 0 to 9"),
        ("G18 G41.1 D2 L2.5".to_string(), 1, "from 0 to 9"),
        (
            "G10 L2 P1 R30\nG18 G41.1 D2".to_string(),
            2,
            "rotated coordinate system",
        ),
        (
            "G18 G0 X0 Z0\nG41.1 D2 L2\nG2 X5 Z5 R5 F100".to_string(),
            3,
            "orientation 2 is not supported",
        ),
        ("G41.1\nG1 X1".to_string(), 1, "no D word"),
        ("G41.1 D2 L3".to_string(), 1, "not G18"),
        ("G41 D3".to_string(), 1, "not in the tool table"),
        ("G41 D1.5".to_string(), 1, "tool number"),
        (format!("{on}G18"), 4, "cannot change planes"),
        (format!("{on}G81 X1 Y1 Z-1 R1"), 4, "canned cycles"),
        (format!("{on}G28"), 4, "G28 or G30"),
        (format!("{on}G53 G0 X0"), 4, "G53"),
        (format!("{on}G92 X0"), 4, "axis offsets"),
        (format!("{on}G55"), 4, "coordinate systems"),
        (format!("{on}G49"), 4, "tool length offset"),
        (format!("{on}T1 M6"), 4, "change tools"),
        (format!("{on}G40\nG2 X5 Y0 R5"), 5, "must be straight"),
        (
            "G0 X0\nG41.1 D20\nG2 X5 Y0 R5 F100".to_string(),
            3,
            "entry arc",
        ),
        ("G0 X0\nG41.1 D10\nG1 X4 F100".to_string(), 3, "not longer"),
        (format!("{on}G1 X10\nG3 X10 Y1.8 R0.9"), 5, "not less than"),
        // A concave corner deeper than the line before it: the line would reverse.
        (
            "G0 X-9 Y-9\nG42.1 D10\nG1 X0 Y0 F100\nG1 Y30\nG1 X2\nG1 Y0".to_string(),
            6,
            "gouging",
        ),
    ];
    for (src, line, words) in cases {
        let (l, _, k, m) = first_error(&src);
        assert_eq!(
            (l, k),
            (line, DiagnosticKind::CutterCompensation),
            "{src}: {m}"
        );
        assert!(m.contains(words), "{src}: {m}");
    }
    assert!(errors("G40 G0 X1").is_empty());
    // Radius 0 (no tool): compensation is on, the path is the programmed one.
    let tp = ok("G0 X-9 Y-9\nG41\nG1 X0 Y0 F100\nG1 X10\nG40\nM2");
    assert_eq!(ends(&tp)[2], xyz(10.0, 0.0, 0.0));
}

#[test]
fn cutter_compensation_offsets_the_path() {
    // Left of a square run clockwise (the tool outside): a corner arc at each corner.
    let tp = ok("G0 X-10 Y-10\nG41.1 D4\nG1 X0 Y0 F100\nG1 Y10\nG1 X10\nG40\nG1 X20 Y20\nM2");
    let e = ends(&tp);
    // The entry line (direction (1,1)) and Y10 make a concave corner for the tool on the left:
    // the entry ends where its offset line meets x = −2, at y = 2(√2 − 1).
    assert!(
        close(e[1], xyz(-2.0, 2.0 * (2f64.sqrt() - 1.0), 0.0)),
        "{e:?}"
    );
    assert!(close(e[2], xyz(-2.0, 10.0, 0.0)), "{e:?}");
    let a = arc(&tp.moves[3]);
    assert_eq!(a.centre, [0.0, 10.0]);
    assert!((a.sweep_rad + FRAC_PI_2).abs() < 1e-12, "{a:?}");
    assert!(close(e[3], xyz(0.0, 12.0, 0.0)), "{e:?}");
    // The line after G40 is held back until then; the exit move starts where it ends.
    assert!(close(e[4], xyz(10.0, 12.0, 0.0)), "{e:?}");
    assert!(close(e[5], xyz(20.0, 20.0, 0.0)), "{e:?}");
    // A negative diameter compensates on the other side.
    let a = ok("G0 X-10 Y-10\nG41.1 D-4\nG1 X0 Y0 F100\nG1 Y10\nM2");
    let b = ok("G0 X-10 Y-10\nG42.1 D4\nG1 X0 Y0 F100\nG1 Y10\nM2");
    assert_eq!(ends(&a), ends(&b));
}

/// Distance from `x` to the segment `a`–`b`.
fn segment_distance(x: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let t = (((x[0] - a[0]) * d[0] + (x[1] - a[1]) * d[1]) / (d[0] * d[0] + d[1] * d[1]))
        .clamp(0.0, 1.0);
    (x[0] - a[0] - t * d[0]).hypot(x[1] - a[1] - t * d[1])
}

#[test]
fn compensated_paths_keep_the_tool_radius_from_the_programmed_path() {
    // In the XY plane, and in the XZ plane with the same polylines programmed on (Z, X), its
    // first and second axes (left of travel and the corner arcs' turning are defined in that
    // order, as rs274 shows: tests/linuxcnc.rs).
    tool_keeps_its_radius("G17", ['X', 'Y'], [0, 1]);
    tool_keeps_its_radius("G18", ['Z', 'X'], [2, 0]);
}

/// Random polylines compensated in `plane`, programmed with `letters` (first and second axis)
/// and read back from the moves' coordinates `axes`.
fn tool_keeps_its_radius(plane: &str, letters: [char; 2], axes: [usize; 2]) {
    let [u, v] = letters;
    // Random polylines (segments 10–30 mm, turns up to ±150°), tool radius 0.5–8 mm, either
    // side. Truth from geometry, not from LinuxCNC: every compensated line lies at exactly r
    // from its programmed line on the compensation side; every corner arc is centred on the
    // programmed corner with radius r and turns away from the tool's side; no point of a
    // compensated move comes nearer than r to its own programmed segment or its neighbours.
    // Corners within LinuxCNC's 0.05 rad get no corner arc: the next line starts where the
    // previous one ended, at r·cos(turn) from its own line, so starts and distances get a
    // slack of r·(1 − cos 0.05).
    let mut seed = 0x9E37_79B9_7F4A_7C15_u64;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut passed, mut refused) = (0, 0);
    for _ in 0..400 {
        let r = ((0.5 + 7.5 * rnd()) * 1e4).round() / 1e4;
        let s = if rnd() < 0.5 { 1.0 } else { -1.0 };
        let slack = r * (1.0 - 0.05f64.cos()) + 1e-9;
        let mut pts = vec![[0.0f64, 0.0f64]];
        let mut heading = rnd() * 2.0 * PI;
        for _ in 0..6 {
            let len = 10.0 + 20.0 * rnd();
            let p = *pts.last().unwrap();
            let q = [p[0] + len * heading.cos(), p[1] + len * heading.sin()];
            pts.push(q.map(|v| (v * 1e4).round() / 1e4));
            heading += (rnd() - 0.5) * 2.0 * 150f64.to_radians();
        }
        // Enter along the first segment's direction, from 20 mm before it.
        let d0 = [pts[1][0] - pts[0][0], pts[1][1] - pts[0][1]];
        let l0 = d0[0].hypot(d0[1]);
        let start = [-20.0 * d0[0] / l0, -20.0 * d0[1] / l0].map(|v| (v * 1e4).round() / 1e4);
        let code = if s > 0.0 { "G41.1" } else { "G42.1" };
        let mut src = format!(
            "{plane} G0 {u}{:.4} {v}{:.4}\n{code} D{:.4}\nG1 {u}0 {v}0 F100\n",
            start[0],
            start[1],
            2.0 * r
        );
        for p in &pts[1..] {
            src += &format!("G1 {u}{:.4} {v}{:.4}\n", p[0], p[1]);
        }
        src += "G40\nM2\n";
        let tp = match run(&src) {
            Ok((tp, _)) => tp,
            Err(d) => {
                // Only the tool not fitting a concave corner may stop it.
                assert!(
                    d.iter()
                        .any(|d| d.kind == DiagnosticKind::CutterCompensation
                            && d.message.contains("gouging")),
                    "{src}: {d:?}"
                );
                refused += 1;
                continue;
            }
        };
        // Segment k (from pts[k-1] to pts[k]) is programmed on line k + 3.
        for m in &tp.moves {
            let k = m.line as usize - 3;
            if k == 0 || k >= pts.len() {
                continue; // the entry move
            }
            let (a, b) = (pts[k - 1], pts[k]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let len = d[0].hypot(d[1]);
            let side = |x: [f64; 2]| (d[0] * (x[1] - a[1]) - d[1] * (x[0] - a[0])) / len;
            let start = axes.map(|i| m.start[i]);
            let end = axes.map(|i| m.end[i]);
            let samples: Vec<[f64; 2]> = match m.kind {
                MoveKind::Linear => {
                    for (x, tol) in [(start, slack), (end, 1e-9)] {
                        let off = side(x);
                        assert!(
                            (off - s * r).abs() < tol,
                            "{src}: {m:?} at {off}, not {}",
                            s * r
                        );
                    }
                    (0..=20)
                        .map(|i| {
                            let t = f64::from(i) / 20.0;
                            [0, 1].map(|j| start[j] + t * (end[j] - start[j]))
                        })
                        .collect()
                }
                MoveKind::Arc(arc) => {
                    assert!(
                        (arc.centre[0] - a[0]).abs() < 1e-9 && (arc.centre[1] - a[1]).abs() < 1e-9,
                        "{src}: corner arc {m:?} not about the corner {a:?}"
                    );
                    assert!((arc.radius_start_mm - r).abs() < 1e-9, "{src}: {m:?}");
                    assert!((arc.radius_end_mm - r).abs() < 1e-9, "{src}: {m:?}");
                    assert!(
                        arc.sweep_rad * s < 0.0,
                        "{src}: corner arc turns towards the tool"
                    );
                    let t0 = (start[1] - a[1]).atan2(start[0] - a[0]);
                    (0..=20)
                        .map(|i| {
                            let t = t0 + arc.sweep_rad * f64::from(i) / 20.0;
                            [a[0] + r * t.cos(), a[1] + r * t.sin()]
                        })
                        .collect()
                }
                _ => panic!("{src}: unexpected {m:?}"),
            };
            for j in k.saturating_sub(1).max(1)..=(k + 1).min(pts.len() - 1) {
                for x in &samples {
                    let dist = segment_distance(*x, pts[j - 1], pts[j]);
                    assert!(
                        dist > r - slack,
                        "{src}: {m:?} comes {dist} from segment {j}"
                    );
                }
            }
        }
        passed += 1;
    }
    assert!(
        passed > 200 && refused > 10,
        "{passed} passed, {refused} refused"
    );
}

#[test]
fn abort_comment_stops_the_program() {
    let (l, _, k, m) = first_error("G0 X1\n(ABORT, bad setup)\nG0 X2");
    assert_eq!((l, k), (2, DiagnosticKind::Abort));
    assert!(m.contains("bad setup"));
}
