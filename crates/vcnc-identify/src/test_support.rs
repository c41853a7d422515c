//! Helpers of the unit tests: a reference of smooth rest-to-rest moves and the positions a
//! model follows it with.

use vcnc_drive::{ClosedLoopModel, Reference, SimOptions};

/// Period of [`smooth_moves`], s.
pub const TS: f64 = 1e-3;

/// Smooth moves `(start s, duration s, distance)` with reversals, for [`smooth_moves`].
pub const MOVES: [(f64, f64, f64); 6] = [
    (0.1, 0.25, 20.0),
    (0.5, 0.3, -35.0),
    (0.95, 0.12, 4.0),
    (1.2, 0.4, 30.0),
    (1.8, 0.2, -25.0),
    (2.2, 0.5, 12.0),
];

/// `n` samples at [`TS`] of the sum of `moves`, each a cubic blend $3s^2 - 2s^3$ over its
/// duration (rest to rest): position, velocity, acceleration.
pub fn smooth_moves(n: usize, moves: &[(f64, f64, f64)]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (mut p, mut v, mut a) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for k in 0..n {
        let t = k as f64 * TS;
        for &(t0, dur, d) in moves {
            let s = ((t - t0) / dur).clamp(0.0, 1.0);
            p[k] += d * (3.0 * s * s - 2.0 * s * s * s);
            if (0.0..1.0).contains(&s) && t > t0 {
                v[k] += d * (6.0 * s - 6.0 * s * s) / dur;
                a[k] += d * (6.0 - 12.0 * s) / (dur * dur);
            }
        }
    }
    (p, v, a)
}

/// The positions of `m` following the reference `p`, `v`, `a` at [`TS`], default options.
pub fn follow(m: &ClosedLoopModel, p: &[f64], v: &[f64], a: &[f64]) -> Vec<f64> {
    m.simulate(
        Reference {
            pos: p,
            vel: v,
            acc: a,
        },
        TS,
        &SimOptions::default(),
    )
    .unwrap()
}
