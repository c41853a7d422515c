//! Helpers shared by the trace tests.

#![allow(dead_code)]

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
