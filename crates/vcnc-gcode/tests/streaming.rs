//! Streaming (`vcnc_gcode::plan` + `StreamPlan::sample`) against the whole-program path
//! (`vcnc_gcode::load`): the truth is `load`'s trajectory, which the streamed samples, spans,
//! warnings and slowdown must equal bit for bit, on the repository's programs, on long generated
//! ones (look-ahead windows far shorter than the chains) and on random programs, with pieces of
//! source and of samples small enough to cut every block and chain.

use proptest::prelude::*;
use std::fmt::Write;
use vcnc_gcode::{
    AxisName, Error, InterpOptions, InterpolateOptions, Limits, MoveClass, SampleChunk,
    StreamOptions, TcpProgramOptions, load, plan,
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
                // Both refuse; the kind of error agrees.
                assert_eq!(
                    std::mem::discriminant(a),
                    std::mem::discriminant(&b),
                    "{a} vs {b}"
                );
                return;
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
        assert_eq!(p.start, whole.toolpath.start);
        assert_eq!(p.axes_used, whole.toolpath.axes_used);
        assert_eq!(p.moves, whole.toolpath.moves.len());
    }
}

fn nmv_like() -> Limits {
    let mut l = Limits::uniform(250.0, 2500.0);
    for i in 3..6 {
        l.axes[i].max_vel = 100.0;
        l.axes[i].max_acc = 1000.0;
    }
    l.tcp_max_vel = 250.0;
    l.tcp_max_acc = 2500.0;
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
    same(
        &spiral,
        &tcp_opts(),
        &nmv_like(),
        &InterpolateOptions::default(),
    );
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
    same(
        &src,
        &tcp_opts(),
        &nmv_like(),
        &InterpolateOptions::default(),
    );
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
    same(
        &src,
        &InterpOptions::default(),
        &Limits::uniform(250.0, 2500.0),
        &InterpolateOptions::default(),
    );
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

#[test]
fn a_repeat_loop_streams_bit_for_bit() {
    let src = "G21 G90\no100 repeat [3]\nG1 X10 F600\nG1 X0\no100 endrepeat\nM2\n";
    same(
        src,
        &InterpOptions::default(),
        &Limits::uniform(100.0, 1000.0),
        &InterpolateOptions::default(),
    );
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
    PathMode(bool),
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
        3 => any::<bool>().prop_map(Op::PathMode),
        1 => (disp(), 0.001f64..0.02).prop_map(|(d, minutes)| Op::InverseTime { d, minutes }),
        1 => (1usize..40).prop_map(Op::Fine),
    ]
}

fn render(ops: &[Op]) -> String {
    let names = ['X', 'Y', 'Z', 'A', 'B', 'C'];
    let mut pos = [0.0f64; 6];
    let mut out = String::from("G21 G90 G17 G94 G61\n");
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
            Op::PathMode(g64) => {
                let _ = writeln!(out, "{}", if *g64 { "G64" } else { "G61" });
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
        same(&src, &InterpOptions::default(), &Limits::uniform(150.0, 1500.0), &InterpolateOptions::default());
    }
}
