//! Helpers shared by the trace tests.

#![allow(dead_code)]

use proptest::prelude::*;
use vcnc_axis::AxisName;
use vcnc_trace::ReadOptions;

/// Read options for a five-axis table-tilting machine's log whose joints are X, Y, Z, A, C.
pub fn xyzac_options() -> ReadOptions {
    ReadOptions {
        joints: vec![
            AxisName::X,
            AxisName::Y,
            AxisName::Z,
            AxisName::A,
            AxisName::C,
        ],
        ..ReadOptions::default()
    }
}

/// 1 to 4 columns of `n` values each: large, tiny, zeros of both signs and whole numbers.
pub fn values(n: usize) -> impl Strategy<Value = Vec<Vec<f64>>> {
    let v = prop_oneof![
        -1e6f64..1e6,
        -1e-3f64..1e-3,
        Just(0.0),
        Just(-0.0),
        (-1000i32..1000).prop_map(f64::from),
    ];
    prop::collection::vec(prop::collection::vec(v, n..=n), 1..5)
}
