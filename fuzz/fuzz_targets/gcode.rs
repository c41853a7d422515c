//! Fuzz target `gcode`: arbitrary bytes → parser → interpreter → interpolator, strict and lenient.
//!
//! Checks (a panic, a timeout or an out-of-memory is a finding):
//! - no stage panics, on any bytes;
//! - the work is bounded: the interpolator gets a budget of [`MAX_SAMPLES`] samples and must
//!   refuse longer programs with `Error::TooManySamples` instead of computing them;
//! - every diagnostic and error formats (`Display`) without panicking;
//! - an accepted trajectory is well formed: every axis track has `len()` samples of finite
//!   position, velocity and acceleration, the TCP flags match, and the length is within budget.
//!
//! The strict run uses machine-like limits where B cannot move (velocity and acceleration 0, as
//! on a table-tilting A/C machine), so the "axis cannot move" path is reached; the lenient run
//! uses uniform limits and outputs all six axes. Infeasible `G93` blocks run at the limits.

#![no_main]

use libfuzzer_sys::fuzz_target;
use vcnc_gcode::{
    AxisLimits, AxisName, InterpOptions, InterpolateOptions, Limits, ParseOptions, Trajectory,
    interpolate, interpret, parse_bytes,
};

/// Sample budget: 50 s at 1 ms. Longer programs must be refused, not computed. (Sampling
/// dominates the run time under coverage instrumentation: 50 000 keeps ~3x more executions per
/// second than 200 000 and still reaches the refusal path easily.)
const MAX_SAMPLES: usize = 50_000;

fn machine_limits() -> Limits {
    let lin = AxisLimits {
        max_vel: 500.0,
        max_acc: 5000.0,
        max_jerk: f64::INFINITY,
    };
    Limits {
        axes: [
            lin,
            lin,
            lin,
            AxisLimits {
                max_vel: 250.0,
                max_acc: 2500.0,
                max_jerk: f64::INFINITY,
            },
            AxisLimits {
                max_vel: 0.0,
                max_acc: 0.0,
                max_jerk: f64::INFINITY,
            },
            AxisLimits {
                max_vel: 300.0,
                max_acc: 5000.0,
                max_jerk: f64::INFINITY,
            },
        ],
        tcp_max_vel: 250.0,
        tcp_max_acc: 1500.0,
        tcp_max_jerk: f64::INFINITY,
    }
}

fn check_trajectory(t: &Trajectory) {
    let n = t.len();
    assert!(
        n <= MAX_SAMPLES,
        "{n} samples exceed the budget {MAX_SAMPLES}"
    );
    assert_eq!(t.tcp.len(), n, "TCP flags vs samples");
    for a in &t.axes {
        assert_eq!(a.pos.len(), n, "axis {} positions", a.name);
        assert_eq!(a.vel.len(), n, "axis {} velocities", a.name);
        assert_eq!(a.acc.len(), n, "axis {} accelerations", a.name);
        for k in 0..n {
            assert!(
                a.pos[k].is_finite() && a.vel[k].is_finite() && a.acc[k].is_finite(),
                "axis {} sample {k} is not finite: pos {} vel {} acc {}",
                a.name,
                a.pos[k],
                a.vel[k],
                a.acc[k]
            );
        }
    }
    for w in &t.warnings {
        let _ = w.to_string();
    }
}

fn run(data: &[u8], lenient: bool) {
    let (program, diags) = parse_bytes(
        data,
        &ParseOptions {
            lenient,
            ..ParseOptions::default()
        },
    );
    for d in &diags {
        let _ = d.to_string();
    }
    let interp_opts = InterpOptions {
        lenient,
        tcp_on_mcodes: vec![428],
        tcp_off_mcodes: vec![429],
        // O-word loops: a bounded budget keeps every input fast (an endless loop is an error).
        max_loop_iterations: 100_000,
        ..InterpOptions::default()
    };
    let toolpath = match interpret(&program, &interp_opts) {
        Ok((tp, warnings)) => {
            for w in &warnings {
                let _ = w.to_string();
            }
            tp
        }
        Err(errors) => {
            for e in &errors {
                let _ = e.to_string();
            }
            return;
        }
    };
    let (limits, opts) = if lenient {
        (
            Limits::uniform(100.0, 1000.0),
            InterpolateOptions {
                max_samples: MAX_SAMPLES,
                axes: Some(AxisName::ALL.to_vec()),
                ..InterpolateOptions::default()
            },
        )
    } else {
        (
            machine_limits(),
            InterpolateOptions {
                max_samples: MAX_SAMPLES,
                ..InterpolateOptions::default()
            },
        )
    };
    match interpolate(&toolpath, &limits, &opts) {
        Ok(t) => check_trajectory(&t),
        Err(e) => {
            let _ = e.to_string();
        }
    }
}

fuzz_target!(|data: &[u8]| {
    run(data, false);
    run(data, true);
});
