//! Property (issue 4, docs/identification.md): a model identified from a random stable P-PI
//! drive predicts that drive on a program it was not identified on about as well as the
//! drive's own analytic model does. The drives are random plants with P-PI gains designed from
//! random poles (docs/drive-model.md) and random feed-forward, simulated by the true drive
//! simulator; proptest draws them afresh every run (a failure prints its case, and
//! `property.proptest-regressions` replays the saved ones first). Stability and in-bound poles
//! are not asserted: the search's bounds make them true by construction.
//!
//! Truth: the analytic closed-loop model of each drive's parameters
//! (`DriveParams::closed_loop_model`), run free on the second program with the same input.
//! The identified model's free-run RMS error there must be at most [`VALIDATION_RATIO`] times
//! the analytic model's (the analytic model is not exact: the true drive samples its loop at
//! 20 kHz and quantises its encoder, so the identified model may also come out below it).
//!
//! 200 drives, as the issue asks: about 15 s in release mode (the README's test command).

mod support;

use proptest::prelude::*;
use vcnc_drive::DriveModel;
use vcnc_drive::{ControllerSpec, DriveParams, Encoder, Plant, PoleDesign};
use vcnc_identify::{IdentifyOptions, identify};

/// Largest identified/analytic ratio of the free-run RMS error on the second program. Measured
/// over 603 fresh drives (2026-11-29): median 0.979, 99th percentile 1.0003, worst 1.106.
const VALIDATION_RATIO: f64 = 1.2;

#[derive(Debug, Clone)]
struct RandomDrive {
    j: f64,
    b_over_j: f64,
    rg: f64,
    tc: f64,
    poles: (f64, f64, f64),
    ff: (f64, f64, f64),
    resolution: f64,
    seed: u64,
}

fn drive() -> impl Strategy<Value = RandomDrive> {
    (
        (0.002f64..0.05, 0.5f64..20.0, 0.5f64..3.0, 0.0f64..0.5),
        (2.0f64..40.0, 8.0f64..80.0, 0.2f64..1.2),
        (0.0f64..1.0, 0.0f64..1.0, 0.0f64..1.0),
        prop_oneof![Just(1e-4), Just(1e-3)],
        any::<u64>(),
    )
        .prop_map(
            |((j, b_over_j, rg, tc), poles, ff, resolution, seed)| RandomDrive {
                j,
                b_over_j,
                rg,
                tc,
                poles,
                ff,
                resolution,
                seed,
            },
        )
}

fn params(d: &RandomDrive) -> DriveParams {
    DriveParams {
        plant: Plant {
            j: d.j,
            b: d.b_over_j * d.j,
            ka: 1.0,
            kt: 1.0,
            rg: d.rg,
            coulomb_torque: d.tc,
            u_max: None,
        },
        controller: ControllerSpec::PPi {
            kv: None,
            kp: None,
            ki: None,
            design: Some(PoleDesign {
                p_hz: d.poles.0,
                wn_hz: d.poles.1,
                zeta: d.poles.2,
            }),
            vff: d.ff.0,
            bff: d.ff.1,
            jff: d.ff.2,
        },
        encoder: Encoder {
            resolution: d.resolution,
            noise_std: 0.0,
            seed: 0,
        },
        servo_rate_hz: 20_000.0,
        compliance: None,
        friction: None,
        current_loop: None,
        feedback: None,
        reference: None,
    }
}

fn check(d: &RandomDrive) -> Result<(), TestCaseError> {
    let p = params(d);
    // Poles that a P-PI cannot place on this plant (docs/drive-model.md) are not a drive.
    prop_assume!(p.validate().is_ok());
    let r = support::identification_program(d.seed, 30, 50.0, 250.0, 2500.0, 1e-3);
    let tr = support::drive_trace(&p, &r);
    let opts = IdentifyOptions {
        seed: d.seed,
        ..Default::default()
    };
    let id = identify(&tr, &opts).map_err(|e| TestCaseError::fail(format!("{e}")))?;
    // Accuracy on another program (module documentation).
    let r2 = support::identification_program(d.seed ^ 0x5eed, 30, 50.0, 250.0, 2500.0, 1e-3);
    let val = support::drive_trace(&p, &r2);
    let truth = DriveModel {
        input: id.identified_model.input,
        ..DriveModel::from(p.closed_loop_model().expect("analytic model"))
    };
    let (rv, rt) = (
        support::freerun_rms(&id.identified_model, &val),
        support::freerun_rms(&truth, &val),
    );
    prop_assert!(
        rv <= VALIDATION_RATIO * rt,
        "identified {:.4} µm against the analytic model's {:.4} µm on another program",
        1e3 * rv,
        1e3 * rt
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    #[test]
    fn identified_models_of_200_random_ppi_drives_predict_another_program(d in drive()) {
        check(&d)?;
    }
}

/// Fixed regression case (CI of 2026-11-29, shrunk by proptest): ζ = 0.2 lies on the search's
/// lower bound and strong Coulomb friction makes the drive stick. The friction stages' fit
/// leaves the bound by a hair; it used to end the stages there, keeping the measured-sign fit
/// at 1.92× the analytic model's error on the second program (0.1085 against 0.0565 µm). The
/// stages now go on in bounded pole coordinates: 0.0484 µm.
#[test]
fn a_sticking_drive_with_its_damping_on_the_bound_keeps_its_friction_stages() {
    let d = RandomDrive {
        j: 0.002,
        b_over_j: 0.5,
        rg: 0.5,
        tc: 0.450_677_264_927_714_65,
        poles: (2.0, 74.468_015_780_037_09, 0.2),
        ff: (0.0, 0.0, 0.0),
        resolution: 1e-4,
        seed: 0,
    };
    check(&d).unwrap();
}
