//! Parse + interpret + interpolate benchmarks: the spiral (docs/contour.md) and an
//! identification program (defaults, axis X), both started at their first point as the
//! pipeline does; and the interpreter alone on RS274/NGC control flow: a 20 000-iteration
//! `while` loop with expressions (20 000 moves) and 400 peck-drilled holes (`G83` in a loop).
//!
//! Run: `CARGO_TARGET_DIR=/work/targets/vcnc-gcode cargo bench -p vcnc-gcode --bench interpolate`

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use vcnc_gcode::{
    AxisName, IdentificationOptions, InterpOptions, InterpolateOptions, Limits, SpiralOptions,
    StartPosition, TcpProgramOptions, identification, interpret, load, parse, spiral_points,
    tcp_program,
};

/// Tool axis → (A, C) in degrees for the bench only: branch −1 of docs/kinematics.md,
/// a = −acos(o_z), c = atan2(−o_x, −o_y), c unwrapped continuously.
fn spiral_program() -> String {
    let pts = spiral_points(&SpiralOptions::default()).expect("default spiral options are valid");
    let mut out = Vec::with_capacity(pts.len());
    let mut prev_c: Option<f64> = None;
    for q in &pts {
        let a = -q.o[2].clamp(-1.0, 1.0).acos();
        let mut c = (-q.o[0]).atan2(-q.o[1]);
        if let Some(pc) = prev_c {
            c += std::f64::consts::TAU * ((pc - c) / std::f64::consts::TAU).round();
        }
        prev_c = Some(c);
        out.push((q.p, a.to_degrees(), c.to_degrees()));
    }
    tcp_program(&out, &TcpProgramOptions::default()).expect("finite points")
}

fn bench(c: &mut Criterion) {
    let spiral = spiral_program();
    let mut limits = Limits::uniform(250.0, 2500.0);
    limits.tcp_max_vel = 75.0;
    limits.tcp_max_acc = 1500.0;
    for i in 3..6 {
        limits.axes[i].max_vel = 1000.0;
        limits.axes[i].max_acc = 1.0e5;
    }
    let opts = InterpolateOptions::default();
    let io = InterpOptions {
        start: StartPosition::FirstMove,
        ..InterpOptions::default()
    };
    c.bench_function("spiral: parse + interpret + interpolate (1 ms)", |b| {
        b.iter(|| load(black_box(&spiral), &io, &limits, &opts).map(|r| r.trajectory.len()))
    });
    let ident =
        identification(AxisName::X, &IdentificationOptions::default()).expect("defaults are valid");
    let limits = Limits::uniform(250.0, 2500.0);
    c.bench_function(
        "identification X: parse + interpret + interpolate (1 ms)",
        |b| b.iter(|| load(black_box(&ident), &io, &limits, &opts).map(|r| r.trajectory.len())),
    );
    let ngc = InterpOptions::default();
    let zigzag = "G21 G90 G94 F3000\n#<i> = 0\no1 while [#<i> LT 20000]\n\
                  G1 X[#<i> MOD 2 * 10] Y[#<i> * 0.01] Z[SIN[#<i>] * 0.5]\n#<i> = [#<i> + 1]\n\
                  o1 endwhile\nM2\n";
    c.bench_function("ngc: 20 000-iteration while loop, interpret", |b| {
        let (p, _) = parse(zigzag);
        b.iter(|| interpret(black_box(&p), &ngc).map(|(tp, _)| tp.moves.len()))
    });
    let holes = "G21 G90 G94 F300\nG0 Z10\n#<i> = 0\no1 repeat [400]\n\
                 G98 G83 X[#<i> MOD 20 * 5] Y[FIX[#<i> / 20] * 5] Z-12 R1 Q2.5\n\
                 #<i> = [#<i> + 1]\no1 endrepeat\nG80\nM2\n";
    c.bench_function("ngc: 400 G83 holes in a repeat loop, interpret", |b| {
        let (p, _) = parse(holes);
        b.iter(|| interpret(black_box(&p), &ngc).map(|(tp, _)| tp.moves.len()))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
