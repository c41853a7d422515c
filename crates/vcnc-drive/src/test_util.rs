//! Helpers of the unit tests.

use crate::Error;
use crate::model::{Reference, SimOptions};

/// The largest absolute difference between two series of equal length.
pub(crate) fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// What `simulate` (a model's) gives for the reference `(p, v, a)` at period `ts`, default
/// options; a test failure on an error.
pub(crate) fn follow(
    simulate: impl FnOnce(Reference<'_>, f64, &SimOptions) -> Result<Vec<f64>, Error>,
    (p, v, a): (&[f64], &[f64], &[f64]),
    ts: f64,
) -> Vec<f64> {
    let r = Reference {
        pos: p,
        vel: v,
        acc: a,
    };
    simulate(r, ts, &SimOptions::default()).unwrap()
}
