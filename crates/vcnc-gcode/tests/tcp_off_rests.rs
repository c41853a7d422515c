//! Switching TCP mode off (docs/gcode.md, "Path modes" and "Tool-centre-point mode"): the
//! machine rests at the switch, and the rest sample on the TCP move's end point is a TCP sample,
//! so every second difference of X Y Z outside TCP samples stays within the axis limits.
//!
//! The case proptest shrank `random_programs_respect_limits_points_and_durations` to
//! (`properties.proptest-regressions`, seed 364efe2c…): `G43.4`, a Z feed at the tool-tip
//! limits (acceleration 18270 mm/s², so the stop takes less than one sample), `G49`, a C feed.
//! And its mirror (seed c52b78fb…): an A feed in TCP mode, `G49`, a Y feed whose axis may
//! accelerate faster (19002 mm/s²) than the tool tip (200 mm/s²): the rest sample, a TCP
//! sample, must not carry the Y move's starting acceleration.
//! Truth: the axis and tool-tip limits and the rest at the switch, by definition.

use vcnc_gcode::{AxisName, InterpOptions, InterpolateOptions, Limits, Trajectory, load};

fn fast_tip() -> Limits {
    let mut l = Limits::uniform_with_jerk(20.0, 200.0, 1000.0);
    l.tcp_max_vel = 20.0;
    l.tcp_max_acc = 18269.672116538062;
    l.tcp_max_jerk = 91348.36058269031;
    l
}

fn run(src: &str, limits: &Limits) -> Trajectory {
    let opts = InterpolateOptions {
        axes: Some(AxisName::ALL.to_vec()),
        ..InterpolateOptions::default()
    };
    load(src, &InterpOptions::default(), limits, &opts)
        .unwrap()
        .trajectory
}

/// Every second difference of an axis at a non-TCP sample (X Y Z) or anywhere (A B C) within
/// the axis' acceleration limit; returns the number of samples checked for X Y Z.
fn check_axis_second_differences(t: &Trajectory, l: &Limits) -> usize {
    let ts2 = t.ts * t.ts;
    let mut checked = 0;
    for k in 1..t.len() - 1 {
        for (i, a) in t.axes.iter().enumerate() {
            if t.tcp[k] && i < 3 {
                continue;
            }
            checked += usize::from(i < 3);
            let d2 = (a.pos[k + 1] - 2.0 * a.pos[k] + a.pos[k - 1]) / ts2;
            assert!(
                d2.abs() <= l.axes[i].max_acc * (1.0 + 1e-9) + 1e-12 / ts2,
                "{} second difference {d2} > {} at k {k}",
                a.name,
                l.axes[i].max_acc
            );
        }
    }
    checked
}

const PROGRAM: &str = "G21 G90 G17 G94 G61.1\nG0 X5 Y-3 Z2 A10 B0 C-20\n\
    G43.4\nG1 Z13.095310012016323 F300\nG49\nG1 C-107.067994383995 F300\nM2\n";

#[test]
fn switching_tcp_off_keeps_axis_second_differences_within_the_limits() {
    let t = run(PROGRAM, &fast_tip());
    assert!(check_axis_second_differences(&t, &fast_tip()) > 0);
    // The TCP move stops within one sample (tip acceleration, 5 mm/s at 18270 mm/s²): the
    // rest sample on its end point is a TCP sample, the next one (the C move) is not.
    let b = &t.blocks[1];
    assert!(b.tcp);
    let k = (b.t_end_s / t.ts).round() as usize;
    assert_eq!(t.axes[2].pos[k], 13.095310012016323);
    assert!(t.tcp[k - 1] && t.tcp[k] && !t.tcp[k + 1]);
    // The switch on is tagged the same way: its rest sample opens the TCP move.
    let k0 = (b.t_start_s / t.ts).round() as usize;
    assert!(!t.tcp[k0 - 1] && t.tcp[k0]);
}

#[test]
fn a_dwell_after_the_switch_off_is_tagged_the_same_way() {
    let src = PROGRAM.replace("G49\n", "G49\nG4 P0.1\n");
    let t = run(&src, &fast_tip());
    check_axis_second_differences(&t, &fast_tip());
}

#[test]
fn the_rest_sample_at_the_switch_off_carries_no_axis_acceleration() {
    let mut l = Limits::uniform_with_jerk(20.0, 200.0, 1000.0);
    l.axes[1].max_acc = 19002.385334467326;
    l.axes[1].max_jerk = 95011.92667233663;
    let src = "G21 G90 G17 G94 G61.1\nG0 X5 Y-3 Z2 A10 B0 C-20\n\
        G43.4\nG1 A-58.1256547035395 F300\nG49\nG1 Y8.421573868666655 F300\nM2\n";
    let t = run(src, &l);
    check_axis_second_differences(&t, &l);
    for k in 0..t.len() {
        if t.tcp[k] {
            let a = (0..3).map(|i| t.axes[i].acc[k].powi(2)).sum::<f64>().sqrt();
            assert!(a <= l.tcp_max_acc * (1.0 + 1e-9), "tip acc {a} at k {k}");
        }
    }
    let b = &t.blocks[1];
    let k = (b.t_end_s / t.ts).round() as usize;
    assert!(t.tcp[k] && !t.tcp[k + 1]);
    assert!(t.axes.iter().all(|a| a.vel[k] == 0.0 && a.acc[k] == 0.0));
}
