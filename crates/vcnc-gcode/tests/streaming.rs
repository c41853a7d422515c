//! Streaming (`vcnc_gcode::plan` + `StreamPlan::sample`) against the whole-program path
//! (`vcnc_gcode::load`): the truth is `load`'s trajectory, which the streamed samples, spans,
//! warnings and slowdown must equal bit for bit, on the repository's programs, on long generated
//! ones (look-ahead windows far shorter than the chains) and on random programs, with pieces of
//! source and of samples small enough to cut every block and chain.

use proptest::prelude::*;
use std::fmt::Write;
use vcnc_gcode::{
    AxisName, Error, InterpOptions, InterpolateOptions, Limits, MoveClass, PlannerRules, Profile,
    SampleChunk, StreamOptions, TcpProgramOptions, load, plan,
};

/// Everything a streamed run hands over, gathered.
#[derive(Default)]
struct Gathered {
    pos: Vec<Vec<f64>>,
    vel: Vec<Vec<f64>>,
    acc: Vec<Vec<f64>>,
    tcp: Vec<bool>,
    line: Vec<u32>,
    class: Vec<Option<MoveClass>>,
}

fn stream(
    src: &str,
    interp: &InterpOptions,
    limits: &Limits,
    opts: &InterpolateOptions,
    so: &StreamOptions,
) -> Result<(vcnc_gcode::StreamPlan, Gathered), Error> {
    let p = plan(src, interp, limits, opts, so)?;
    let mut g = Gathered {
        pos: vec![Vec::new(); p.axes.len()],
        vel: vec![Vec::new(); p.axes.len()],
        acc: vec![Vec::new(); p.axes.len()],
        ..Gathered::default()
    };
    let mut sink = |c: &SampleChunk| -> Result<(), Error> {
        assert_eq!(c.first, g.tcp.len(), "chunks arrive in order");
        for i in 0..c.pos.len() {
            g.pos[i].extend_from_slice(&c.pos[i]);
            g.vel[i].extend_from_slice(&c.vel[i]);
            g.acc[i].extend_from_slice(&c.acc[i]);
        }
        g.tcp.extend_from_slice(&c.tcp);
        g.line.extend_from_slice(&c.line);
        g.class.extend_from_slice(&c.class);
        Ok(())
    };
    p.sample(src, &mut sink)?;
    Ok((p, g))
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Streams `src` with tiny and default pieces and checks every output against `load`.
fn same(src: &str, interp: &InterpOptions, limits: &Limits, opts: &InterpolateOptions) {
    let whole = load(src, interp, limits, opts);
    for so in [
        StreamOptions {
            chunk_bytes: 1,
            chunk_samples: 7,
        },
        StreamOptions {
            chunk_bytes: 300,
            chunk_samples: 1000,
        },
        StreamOptions::default(),
    ] {
        let streamed = stream(src, interp, limits, opts, &so);
        let (whole, (p, g)) = match (&whole, streamed) {
            (Ok(w), Ok(s)) => (w, s),
            (Err(a), Err(b)) => {
                // Both refuse; the kind of error agrees, and a program's diagnostics are the
                // same, in the same order.
                assert_eq!(
                    std::mem::discriminant(a),
                    std::mem::discriminant(&b),
                    "{a} vs {b}"
                );
                if let (Error::Program { diagnostics: d1 }, Error::Program { diagnostics: d2 }) =
                    (a, &b)
                {
                    assert_eq!(d1, d2, "diagnostics ({so:?})");
                }
                continue;
            }
            (Ok(_), Err(e)) => panic!("stream refused what load accepts: {e}"),
            (Err(e), Ok(_)) => panic!("stream accepted what load refuses: {e}"),
        };
        let t = &whole.trajectory;
        assert_eq!(p.samples, t.len(), "sample count");
        assert_eq!(g.tcp.len(), t.len());
        assert_eq!(p.axes, t.axes.iter().map(|a| a.name).collect::<Vec<_>>());
        for (i, a) in t.axes.iter().enumerate() {
            assert_eq!(bits(&g.pos[i]), bits(&a.pos), "{} position", a.name);
            assert_eq!(bits(&g.vel[i]), bits(&a.vel), "{} velocity", a.name);
            assert_eq!(bits(&g.acc[i]), bits(&a.acc), "{} acceleration", a.name);
        }
        assert_eq!(g.tcp, t.tcp);
        let (lines, classes): (Vec<u32>, Vec<Option<MoveClass>>) = t
            .sample_spans()
            .map(|i| {
                i.and_then(|i| t.blocks.get(i))
                    .map_or((0, None), |b| (b.line, Some(b.class)))
            })
            .unzip();
        assert_eq!(g.line, lines, "per-sample lines");
        assert_eq!(g.class, classes, "per-sample classes");
        assert_eq!(p.warnings, whole.warnings, "warnings");
        assert_eq!(p.slowdown, t.slowdown, "slowdown");
        assert_eq!(p.cycle, t.cycle, "cycle time");
        assert_eq!(p.start, whole.toolpath.start);
        assert_eq!(p.axes_used, whole.toolpath.axes_used);
        assert_eq!(p.moves, whole.toolpath.moves.len());
    }
}

/// vcnc's rules (trapezoidal and jerk-limited) and LinuxCNC 2.9's.
fn option_sets() -> [InterpolateOptions; 3] {
    [
        InterpolateOptions::default(),
        InterpolateOptions {
            profile: Profile::JerkLimited,
            ..InterpolateOptions::default()
        },
        InterpolateOptions {
            planner: PlannerRules::LinuxCnc29,
            ..InterpolateOptions::default()
        },
    ]
}

fn nmv_like() -> Limits {
    let mut l = Limits::uniform(250.0, 2500.0);
    for i in 3..6 {
        l.axes[i].max_vel = 100.0;
        l.axes[i].max_acc = 1000.0;
    }
    l.tcp_max_vel = 250.0;
    l.tcp_max_acc = 2500.0;
    for a in &mut l.axes {
        a.max_jerk = 50.0 * a.max_acc;
    }
    l.tcp_max_jerk = 50.0 * l.tcp_max_acc;
    l
}

fn tcp_opts() -> InterpOptions {
    InterpOptions {
        tcp_on_mcodes: vec![428],
        tcp_off_mcodes: vec![429],
        ..InterpOptions::default()
    }
}

#[test]
fn the_spiral_and_the_identification_program_stream_bit_for_bit() {
    let spiral = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../gcode/spiral.ngc"
    ))
    .unwrap();
    for opts in option_sets() {
        same(&spiral, &tcp_opts(), &nmv_like(), &opts);
    }
    let ident = vcnc_gcode::identification(AxisName::X, &Default::default()).unwrap();
    same(
        &ident,
        &InterpOptions::default(),
        &nmv_like(),
        &InterpolateOptions::default(),
    );
}

#[test]
fn the_corpus_streams_bit_for_bit() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/corpus");
    let mut n = 0;
    for e in std::fs::read_dir(dir).unwrap() {
        let path = e.unwrap().path();
        let ext = path.extension().and_then(|x| x.to_str()).unwrap_or("");
        if !matches!(ext, "nc" | "gcode" | "ngc") {
            continue;
        }
        let src = std::fs::read_to_string(&path).unwrap();
        for lenient in [false, true] {
            let interp = InterpOptions {
                lenient,
                ..InterpOptions::default()
            };
            same(
                &src,
                &interp,
                &Limits::uniform(100.0, 1000.0),
                &InterpolateOptions::default(),
            );
        }
        n += 1;
    }
    assert!(n >= 4);
}

#[test]
fn cutter_compensation_streams_bit_for_bit() {
    // Compensated moves are held back until the next move is known: cut into pieces of 1 byte
    // and of 300 bytes, the held moves must come out as in the whole program, including
    // those still held at the end and the errors of the bad programs.
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/linuxcnc");
    let tools = std::fs::read_to_string(format!("{dir}/tools.tbl")).unwrap();
    let interp = InterpOptions {
        tools: vcnc_gcode::parse_tool_table(&tools, "tools.tbl").unwrap(),
        machine_units: vcnc_gcode::LengthUnit::Inch,
        ..InterpOptions::default()
    };
    let mut n = 0;
    for e in std::fs::read_dir(format!("{dir}/programs")).unwrap() {
        let path = e.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if !name.contains("comp") {
            continue;
        }
        let src = std::fs::read_to_string(&path).unwrap();
        same(
            &src,
            &interp,
            &Limits::uniform(100.0, 1000.0),
            &InterpolateOptions::default(),
        );
        n += 1;
    }
    assert!(n >= 10, "{n} programs");
}

/// A long 5-axis TCP program of short segments: a helix of `n` points with a tilting tool, so
/// that chains run over thousands of segments while the look-ahead holds a braking distance.
fn long_tcp(n: usize, feed: f64) -> String {
    let pts: Vec<([f64; 3], f64, f64)> = (0..n)
        .map(|k| {
            let u = k as f64 * 0.01;
            (
                [
                    30.0 * u.cos() + 0.3 * (7.0 * u).sin(),
                    30.0 * u.sin(),
                    -0.02 * k as f64 / 10.0,
                ],
                20.0 * (0.5 * u).sin(),
                (u.to_degrees()) % 360.0,
            )
        })
        .collect();
    vcnc_gcode::tcp_program(
        &pts,
        &TcpProgramOptions {
            feed_mm_per_min: feed,
            ..TcpProgramOptions::default()
        },
    )
    .unwrap()
    .replace("G43.4", "M428")
    .replace("G49", "M429")
}

#[test]
fn a_long_tcp_program_streams_bit_for_bit_with_a_short_look_ahead() {
    let src = long_tcp(6000, 3000.0);
    for opts in option_sets() {
        same(&src, &tcp_opts(), &nmv_like(), &opts);
    }
    let p = plan(
        src.as_str(),
        &tcp_opts(),
        &nmv_like(),
        &InterpolateOptions::default(),
        &StreamOptions::default(),
    )
    .unwrap();
    // The look-ahead holds a braking distance of segments, not the 6000-segment chain.
    assert!(p.lookahead_peak < 600, "look-ahead {}", p.lookahead_peak);
}

/// One `G64` chain of 20 000 segments, 0.01 to 2 mm long, turning by 0 to 170° at each
/// junction (a seeded generator): sharp corners, whose slow junctions the look-ahead must see
/// coming, fall anywhere relative to where the look-ahead is cut, so a junction made final too
/// early shows as a different sample.
#[test]
fn a_long_chain_with_sharp_corners_anywhere_streams_bit_for_bit() {
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut src = String::from("G21 G90 G64 P0.05\nG0 X0 Y0 Z0\nG1 F6000\n");
    let (mut x, mut y, mut heading) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..20_000 {
        // Mostly gentle turns, now and then a sharp one.
        let turn = if uniform() < 0.05 {
            (90.0 + 80.0 * uniform()).to_radians()
        } else {
            (10.0 * uniform()).to_radians()
        };
        heading += if uniform() < 0.5 { turn } else { -turn };
        let len = 0.01 + 1.99 * uniform() * uniform();
        x = (x + len * heading.cos()).clamp(-200.0, 200.0);
        y = (y + len * heading.sin()).clamp(-200.0, 200.0);
        let z = 2.0 * (k as f64 * 0.003).sin();
        let _ = writeln!(src, "X{x:.4} Y{y:.4} Z{z:.4}");
    }
    src.push_str("M2\n");
    for opts in option_sets() {
        same(
            &src,
            &InterpOptions::default(),
            &Limits::uniform_with_jerk(250.0, 2500.0, 100_000.0),
            &opts,
        );
    }
}

/// Fine blocks (G93 G64, 1/F = Ts): accepted as set-points, then a chain too fast for the limits
/// (run as exact stops, with a warning), then ordinary blocks.
#[test]
fn fine_block_chains_stream_bit_for_bit() {
    let mut src = String::from("G21 G90 G64\nG0 X0 Y0\nG93\n");
    for k in 1..400 {
        let x = 5.0 * (k as f64 * 0.02).sin();
        let _ = writeln!(src, "G1 X{x:.5} Y{:.5} F60000", k as f64 * 0.01);
    }
    // Too fast: 2 mm per 1 ms sample is 2000 mm/s.
    for k in 0..30 {
        let _ = writeln!(src, "G1 X{:.3} F60000", 10.0 + 2.0 * k as f64);
    }
    src.push_str("G94 G1 X0 Y0 F3000\nG4 P0.05\nG0 Z5\nM2\n");
    // Both kinds of chain are there: the first runs as set-points, the second is refused.
    let whole = load(
        &src,
        &InterpOptions::default(),
        &Limits::uniform(250.0, 2500.0),
        &InterpolateOptions::default(),
    )
    .unwrap();
    let refusals = whole
        .warnings
        .iter()
        .filter(|w| w.message.contains("are not run as set-points"))
        .count();
    assert_eq!(refusals, 1, "{:?}", whole.warnings);
    assert!(
        whole.trajectory.len() > 399,
        "the 399 set-points run one sample each"
    );
    same(
        &src,
        &InterpOptions::default(),
        &Limits::uniform(250.0, 2500.0),
        &InterpolateOptions::default(),
    );
}

/// `same`, and the program must be accepted (so that a test of a working program cannot pass
/// by both paths refusing it).
fn same_ok(src: &str, interp: &InterpOptions, limits: &Limits) {
    load(src, interp, limits, &InterpolateOptions::default()).expect("the whole path runs it");
    same(src, interp, limits, &InterpolateOptions::default());
}

/// `same`, for a program both paths must refuse with diagnostics naming `needle`.
fn same_err(src: &str, interp: &InterpOptions, needle: &str) {
    let limits = Limits::uniform(100.0, 1000.0);
    match load(src, interp, &limits, &InterpolateOptions::default()) {
        Err(Error::Program { diagnostics }) => assert!(
            diagnostics.iter().any(|d| d.message.contains(needle)),
            "{diagnostics:?}"
        ),
        other => panic!("expected a program error naming '{needle}': {other:?}"),
    }
    same(src, interp, &limits, &InterpolateOptions::default());
}

// O-word programs (LinuxCNC subroutines, conditions and loops). The truth is `load`, whose
// interpreter is checked against LinuxCNC's own in tests/linuxcnc.rs. With pieces of 1 byte
// (one line per piece, two pieces cached) every jump back and every call reads the file again
// from an indexed offset; with 300 bytes some jumps stay inside a piece.

#[test]
fn a_repeat_loop_streams_bit_for_bit() {
    let src = "G21 G90\no100 repeat [3]\nG1 X10 F600\nG1 X0\no100 endrepeat\nM2\n";
    same_ok(
        src,
        &InterpOptions::default(),
        &Limits::uniform(100.0, 1000.0),
    );
}

#[test]
fn subroutines_with_parameters_stream_bit_for_bit() {
    // A named subroutine defined after its first call, one calling another, a return with a
    // value, local and global named parameters, G64 chains through the calls.
    let src = "\
%
G21 G90 G64 P0.01
#<_side> = 4
o<square> call [0] [0] [#<_side>]
o200 sub
  #<k> = [#1 * 2]
  G1 X[#<k>] Y[#2] F1200
  o200 return [#<k> + 1]
o200 endsub
o<square> call [10] [5] [2.5]
o200 call [7] [3]
G1 X[#<_value>] Y0
o<square> sub
  ( #1 #2: corner, #3: side )
  G1 X#1 Y#2 F900
  G1 X[#1 + #3]
  G1 Y[#2 + #3]
  o200 call [#1 + 1] [#2 + #3]
  G1 X#1
  G1 Y#2
o<square> endsub
G0 Z5
%
";
    same_ok(
        src,
        &InterpOptions::default(),
        &Limits::uniform(100.0, 1000.0),
    );
}

#[test]
fn nested_loops_and_conditions_stream_bit_for_bit() {
    let src = "\
G21 G90 G64
#1 = 0
o10 while [#1 LT 6]
  #2 = 0
  o20 do
    o30 if [[#1 + #2] MOD 3 EQ 0]
      G1 X[#1 * 3] Y[#2 * 2] F1500
    o30 elseif [#2 EQ 1]
      G1 X[#1 * 3 + 1] Y[#2 * 2] F900
    o30 elseif [#2 EQ 2]
      o40 if [#1 GT 3]
        G0 Z[#1]
      o40 endif
    o30 else
      G1 X[#1 * 3] Y[#2 * 2 + 1] F600
    o30 endif
    #2 = [#2 + 1]
    o25 if [#2 GT 4]
      o20 break
    o25 endif
  o20 while [#2 LT 10]
  #1 = [#1 + 1]
  o50 if [#1 EQ 2]
    o10 continue
  o50 endif
  G4 P0.01
  o60 repeat [2]
    G1 Z-1 F300
    G1 Z0
  o60 endrepeat
o10 endwhile
G0 X0 Y0 Z10
M30
";
    same_ok(
        src,
        &InterpOptions::default(),
        &Limits::uniform(100.0, 1000.0),
    );
}

#[test]
fn a_long_loop_streams_bit_for_bit_in_pieces_of_moves() {
    // 12 000 moves from a loop of four lines: more than ChunkInterp's hand-over of 4096, so
    // the moves go on in several batches from inside one piece.
    let src = "\
G21 G90 G64 P0.02
G0 X0 Y0
#1 = 0
o1 while [#1 LT 3000]
  G1 X[10 * SIN[#1 * 0.7]] Y[10 * COS[#1 * 0.3]] F3000
  G1 Z[0.1 * [#1 MOD 7]]
  G1 X[#1 * 0.001] Y[-#1 * 0.002]
  G1 Z0
  #1 = [#1 + 1]
o1 endwhile
M2
";
    let whole = load(
        src,
        &InterpOptions::default(),
        &Limits::uniform(250.0, 2500.0),
        &InterpolateOptions::default(),
    )
    .unwrap();
    assert!(whole.toolpath.moves.len() > 2 * vcnc_gcode::interp::YIELD_MOVES);
    same_ok(
        src,
        &InterpOptions::default(),
        &Limits::uniform(250.0, 2500.0),
    );
}

/// A subroutine and a loop far apart: the main program calls a subroutine defined 1.2 MB before
/// the call and repeats a loop whose body is longer than the default 1 MiB piece, so every call,
/// return and repetition reads the file again from an indexed offset at every piece size. A
/// wrong offset, line number or block index shows as other moves, other lines or an error.
#[test]
fn jumps_farther_than_a_piece_read_the_file_again_bit_for_bit() {
    let mut src =
        String::from("G21 G90 G64\no7 sub\nG1 X#1 Y[#2 + 0.5] F2000\nG1 Z#3\no7 endsub\n");
    // 1.2 MB of blocks (a straight run along X and back) between the subroutine and its calls.
    for k in 0..36_000 {
        let _ = writeln!(
            src,
            "G1 X{:.3} F6000 ( filler {k:05} )",
            (k % 200) as f64 * 0.05
        );
    }
    src.push_str("#5 = 0\no8 repeat [3]\n");
    for k in 0..30_000 {
        let _ = writeln!(
            src,
            "G1 Y{:.3} F6000 ( body {k:05} padding )",
            (k % 100) as f64 * 0.02
        );
        if k % 10_000 == 0 {
            src.push_str("o7 call [#5] [#5 * 2] [-1]\n#5 = [#5 + 1]\n");
        }
    }
    src.push_str("o8 endrepeat\no7 call [1] [2] [3]\nM2\n");
    assert!(src.len() > 2 << 20, "{}", src.len());
    same_ok(
        &src,
        &InterpOptions::default(),
        &Limits::uniform(250.0, 2500.0),
    );
}

#[test]
fn block_delete_and_program_end_with_o_words_stream_bit_for_bit() {
    // Deleted lines hold O-word statements; the program ends inside a subroutine; code and
    // subroutine definitions follow the end.
    let src = "\
G21 G90
/o1 if [1]
o2 sub
  G1 X#1 F600
  o3 if [#1 GT 5]
    M2
  o3 endif
o2 endsub
/o1 endif
o2 call [3]
o2 call [8]
G1 X0
o4 sub
  G1 Y1
o4 endsub
G1 Y7
";
    for block_delete in [false, true] {
        let interp = InterpOptions {
            block_delete,
            ..InterpOptions::default()
        };
        let whole = load(
            src,
            &interp,
            &Limits::uniform(100.0, 1000.0),
            &InterpolateOptions::default(),
        );
        if block_delete {
            let w = whole.expect("runs with the switch on");
            assert!(
                w.warnings
                    .iter()
                    .any(|d| d.message.contains("after the program end on line 6") && d.line == 12),
                "{:?}",
                w.warnings
            );
        } else {
            // With the switch off, `/o1 if` opens around the sub definition: a flow error.
            assert!(whole.is_err());
        }
        same(
            src,
            &interp,
            &Limits::uniform(100.0, 1000.0),
            &InterpolateOptions::default(),
        );
    }
}

#[test]
fn o_word_programs_with_errors_give_the_whole_paths_diagnostics() {
    let d = InterpOptions::default();
    // Undefined subroutine, after moves.
    same_err("G21\nG1 X1 F100\no9 call [1]\nM2\n", &d, "not defined");
    // A loop never closed: only the flow error, though an unknown word comes first.
    same_err(
        "G21\nG1 X1 Q5 F100\no1 while [1]\nG1 X2\nM2\n",
        &d,
        "never closed",
    );
    // Flow errors found at the end of the file after moves were made.
    same_err(
        "G21\nG1 X1 F100\no1 if [1]\nG1 X2\no1 endif\nG1 X3\no2 endsub\nM2\n",
        &d,
        "without a o2 sub",
    );
    // Recursion beyond the call depth.
    same_err(
        "G21\no1 sub\nG1 X#1 F100\no1 call [#1 + 1]\no1 endsub\no1 call [0]\nM2\n",
        &d,
        "nested more than",
    );
    // A loop that does not end.
    let few = InterpOptions {
        max_loop_iterations: 500,
        ..InterpOptions::default()
    };
    same_err(
        "G21\n#1 = 0\no1 while [1]\nG1 X[#1 MOD 5] F3000\n#1 = [#1 + 1]\no1 endwhile\nM2\n",
        &few,
        "iterations in all",
    );
    // Errors in several places of a looping program: all of them, in order.
    same_err(
        "G21\no1 repeat [3]\nG1 X1 F100\no2 if [#1 EQ 0]\nG1 X2 Q1\no2 else\nG1 X3\no2 endif\n#1 = [#1 + 1]\no1 endrepeat\nG1 Y1 R2\nM2\n",
        &d,
        "",
    );
    // A parse error after the loop: the parser's diagnostics only.
    same_err(
        "G21\no1 repeat [2]\nG1 X1 F100\no1 endrepeat\nG1 X#\nM2\n",
        &d,
        "",
    );
    // A duplicate definition and a return outside a subroutine.
    same_err(
        "G21\no1 sub\nG1 X1\no1 endsub\no1 sub\nG1 X2\no1 endsub\no5 return\nM2\n",
        &d,
        "defined twice (first at line 2)",
    );
}

/// Bytes that are not UTF-8 before O-word statements: the parsed text (with U+FFFD) and the
/// file's bytes then have different offsets, and the jumps must seek by the file's.
#[test]
fn jumps_after_bytes_that_are_not_utf8_read_the_right_lines() {
    let mut bytes = b"G21 G90 (caf\xe9 \xff\xfe)\n".to_vec();
    bytes.extend_from_slice(b"o1 sub\n(\xe9\xe9)G1 X#1 F600\nG1 Y#1\no1 endsub\n");
    bytes.extend_from_slice(b"o2 repeat [3]\n(\xc3)o1 call [1]\no1 call [2]\no2 endrepeat\nM2\n");
    let dir = std::env::temp_dir().join(format!("vcnc-stream-utf8-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("prog.ngc");
    std::fs::write(&path, &bytes).unwrap();
    let text = String::from_utf8_lossy(&bytes).into_owned();
    let limits = Limits::uniform(100.0, 1000.0);
    let whole = load(
        &text,
        &InterpOptions::default(),
        &limits,
        &InterpolateOptions::default(),
    )
    .unwrap();
    for chunk_bytes in [1, 30, 1 << 20] {
        let so = StreamOptions {
            chunk_bytes,
            chunk_samples: 100,
        };
        let p = plan(
            path.as_path(),
            &InterpOptions::default(),
            &limits,
            &InterpolateOptions::default(),
            &so,
        )
        .unwrap();
        let mut pos = Vec::new();
        p.sample(
            path.as_path(),
            &mut |c: &SampleChunk| -> Result<(), Error> {
                pos.extend_from_slice(&c.pos[0]);
                Ok(())
            },
        )
        .unwrap();
        assert_eq!(
            bits(&pos),
            bits(&whole.trajectory.axes[0].pos),
            "{chunk_bytes}"
        );
        assert_eq!(p.warnings, whole.warnings);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn errors_are_reported_with_their_lines() {
    let src = "G21 G90\nG1 X10 F600\nG1 X1Q0\nG1 X#\nM2\n";
    let e = plan(
        src,
        &InterpOptions::default(),
        &Limits::uniform(100.0, 1000.0),
        &InterpolateOptions::default(),
        &StreamOptions {
            chunk_bytes: 4,
            chunk_samples: 16,
        },
    )
    .unwrap_err();
    let Error::Program { diagnostics } = e else {
        panic!("{e}")
    };
    let whole = load(
        src,
        &InterpOptions::default(),
        &Limits::uniform(100.0, 1000.0),
        &InterpolateOptions::default(),
    )
    .unwrap_err();
    let Error::Program { diagnostics: d2 } = whole else {
        panic!()
    };
    assert_eq!(diagnostics, d2);
}

#[derive(Debug, Clone)]
enum Op {
    Line {
        rapid: bool,
        d: [f64; 6],
        feed: f64,
    },
    Arc {
        ccw: bool,
        r: f64,
        sweep: f64,
        feed: f64,
    },
    Dwell(f64),
    /// 0: G61.1, 1: G61, 2: G64, 3: G64 P0.05, 4: G64 P0.02 Q0.01.
    PathMode(u8),
    InverseTime {
        d: [f64; 6],
        minutes: f64,
    },
    Fine(usize),
}

fn disp() -> impl Strategy<Value = [f64; 6]> {
    prop::array::uniform6((any::<bool>(), -1.0f64..1.0)).prop_map(|a| {
        let mut d = [0.0; 6];
        for (i, (on, v)) in a.iter().enumerate() {
            if *on {
                d[i] = v * if i < 3 { 20.0 } else { 45.0 };
            }
        }
        d
    })
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        6 => (any::<bool>(), disp(), 5.0f64..250.0).prop_map(|(rapid, d, feed)| Op::Line { rapid, d, feed }),
        2 => (any::<bool>(), 1.0f64..20.0, 0.1f64..6.0, 5.0f64..250.0)
            .prop_map(|(ccw, r, sweep, feed)| Op::Arc { ccw, r, sweep, feed }),
        1 => (0.0f64..0.05).prop_map(Op::Dwell),
        3 => (0u8..5).prop_map(Op::PathMode),
        1 => (disp(), 0.001f64..0.02).prop_map(|(d, minutes)| Op::InverseTime { d, minutes }),
        1 => (1usize..40).prop_map(Op::Fine),
    ]
}

fn render(ops: &[Op]) -> String {
    let names = ['X', 'Y', 'Z', 'A', 'B', 'C'];
    let mut pos = [0.0f64; 6];
    let mut out = String::from("G21 G90 G17 G94 G61.1\n");
    let words = |out: &mut String, new: &[f64; 6], pos: &[f64; 6]| {
        for i in 0..6 {
            if new[i] != pos[i] {
                let _ = write!(out, " {}{:.4}", names[i], new[i]);
            }
        }
    };
    for op in ops {
        match op {
            Op::Line { rapid, d, feed } => {
                let new: [f64; 6] = std::array::from_fn(|i| pos[i] + d[i]);
                out.push_str(if *rapid { "G0" } else { "G1" });
                words(&mut out, &new, &pos);
                if !rapid {
                    let _ = write!(out, " F{:.3}", feed * 60.0);
                }
                out.push('\n');
                pos = std::array::from_fn(|i| format!("{:.4}", new[i]).parse().unwrap_or(new[i]));
            }
            Op::Arc {
                ccw,
                r,
                sweep,
                feed,
            } => {
                // From the current point, centre at +r along X.
                let (cx, cy) = (pos[0] + r, pos[1]);
                let a = std::f64::consts::PI + if *ccw { *sweep } else { -*sweep };
                let (x, y) = (cx + r * a.cos(), cy + r * a.sin());
                let _ = writeln!(
                    out,
                    "{} X{x:.4} Y{y:.4} I{r:.4} J0 F{:.3}",
                    if *ccw { "G3" } else { "G2" },
                    feed * 60.0
                );
                pos[0] = format!("{x:.4}").parse().unwrap();
                pos[1] = format!("{y:.4}").parse().unwrap();
            }
            Op::Dwell(p) => {
                let _ = writeln!(out, "G4 P{p:.3}");
            }
            Op::PathMode(m) => {
                let code = ["G61.1", "G61", "G64", "G64 P0.05", "G64 P0.02 Q0.01"][*m as usize];
                let _ = writeln!(out, "{code}");
            }
            Op::InverseTime { d, minutes } => {
                let new: [f64; 6] = std::array::from_fn(|i| pos[i] + d[i]);
                out.push_str("G93 G1");
                words(&mut out, &new, &pos);
                let _ = writeln!(out, " F{:.4}\nG94", 1.0 / minutes);
                pos = std::array::from_fn(|i| format!("{:.4}", new[i]).parse().unwrap_or(new[i]));
            }
            Op::Fine(n) => {
                out.push_str("G64 G93\n");
                for k in 0..*n {
                    pos[0] += 0.05 + 0.01 * (k % 3) as f64;
                    pos[0] = format!("{:.4}", pos[0]).parse().unwrap();
                    let _ = writeln!(out, "G1 X{:.4} F60000", pos[0]);
                }
                out.push_str("G94\n");
            }
        }
    }
    out.push_str("M2\n");
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn random_programs_stream_bit_for_bit(ops in prop::collection::vec(op(), 1..40)) {
        let src = render(&ops);
        let limits = Limits::uniform_with_jerk(150.0, 1500.0, 60_000.0);
        for opts in option_sets() {
            same(&src, &InterpOptions::default(), &limits, &opts);
        }
    }
}
