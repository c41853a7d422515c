//! Acceptance tests of the drive's effects (issue 14, "Done means"). Each test states where its
//! truth comes from. Run with `--nocapture` to see the measured figures.

mod common;

use vcnc_drive::{DriveParams, Encoder, Friction, FrictionLocation, table1_drive};

const TS: f64 = 1e-3;

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

#[test]
fn neutral_effects_reproduce_the_ideal_drive() {
    // Truth: the ideal simulator (its own tests pin it to the analytic closed loop). A friction
    // table that restates the plant's symmetric Coulomb friction sends the drive through the
    // effects engine with the same physics.
    let prog = common::standard_program();
    for enc in [Encoder::ideal(), Encoder::default()] {
        let ideal = DriveParams { encoder: enc.clone(), ..table1_drive() };
        let neutral = DriveParams {
            friction: Some(Friction::Coulomb { coulomb_torque_negative: None, location: FrictionLocation::Load }),
            ..ideal.clone()
        };
        let a = ideal.validate().unwrap().simulate(prog.reference(), TS).unwrap();
        let b = neutral.validate().unwrap().simulate(prog.reference(), TS).unwrap();
        let d = max_abs_diff(&a.true_position, &b.true_position);
        eprintln!(
            "neutral effects vs ideal (encoder step {} mm): max |dx| = {d:e} mm",
            enc.resolution
        );
        // Without quantisation the two differ by rounding only; with it, a rounding difference
        // can flip an encoder count, so they agree to within one count.
        let tol = if enc.resolution == 0.0 { 1e-9 } else { enc.resolution };
        assert!(d < tol, "{d}");
    }
}
