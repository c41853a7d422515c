//! Regression tests for bugs found while fuzzing (issue 7; `fuzz/README.md` lists the findings).
//! Each test is named after its bug and fails on the code before the fix (by a panic, or by
//! trying to build a program of unbounded size).

use vcnc_gcode::{AxisName, Error, IdentificationOptions, identification};

/// The identification generator drew long strokes from `long_min ..= 2 R`; with a finite range
/// `R` above `f64::MAX / 2` the upper end overflowed to infinity and `rand`'s `random_range`
/// panicked ("range overflow"). A machine file with travel ±1.7e308 and
/// `identification_range = 1e308` reached it. Now the range must keep `2 R` finite.
#[test]
fn identification_range_whose_double_overflows_is_an_error_not_a_panic() {
    for range in [f64::MAX, 1e308, f64::MAX / 1.999] {
        let opts = IdentificationOptions {
            range,
            ..IdentificationOptions::default()
        };
        match identification(AxisName::X, &opts) {
            Err(Error::InvalidGenerator { name, value, .. }) => {
                assert_eq!(name, "range");
                assert_eq!(value, range);
            }
            other => panic!("range {range:e}: expected an InvalidGenerator error, got {other:?}"),
        }
    }
    // The largest range whose double is finite still generates (no overflow in the sampler).
    let opts = IdentificationOptions {
        range: f64::MAX / 2.0,
        moves: 10,
        ..IdentificationOptions::default()
    };
    let text = identification(AxisName::X, &opts).expect("f64::MAX / 2 is a valid range");
    assert_eq!(text.matches("\nG1 ").count(), 10);
}

/// The number of moves had no upper bound: `moves = 10^12` in a machine file made the generator
/// try to write ~40 TB of G-code (an unbounded allocation). Now at most
/// [`vcnc_gcode::generate::MAX_IDENTIFICATION_MOVES`] moves are accepted, and the error carries
/// the requested count.
#[test]
fn identification_move_count_is_bounded() {
    let max = vcnc_gcode::generate::MAX_IDENTIFICATION_MOVES;
    for moves in [max + 1, 1_000_000_000_000, usize::MAX] {
        let opts = IdentificationOptions {
            moves,
            ..IdentificationOptions::default()
        };
        match identification(AxisName::X, &opts) {
            Err(Error::InvalidGenerator { name, value, .. }) => {
                assert_eq!(name, "moves");
                assert_eq!(value, moves as f64);
            }
            other => panic!("{moves} moves: expected an InvalidGenerator error, got {other:?}"),
        }
    }
}
