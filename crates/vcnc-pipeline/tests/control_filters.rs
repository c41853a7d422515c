//! The control's nominal-position filters (`[control]`, docs/machine-file.md#control) against
//! the same physics inside the drives' models.
//!
//! Truth: a model with a dead time $T_d$ and a reference filter $F(s)$ is, by its definition
//! (docs/drive-model.md, "extended models"), the core loop driven by the reference delayed by
//! $T_d$ and filtered by $F$. So the embedded NMV5000's spiral predicted by the core models on
//! a machine whose `[control]` section holds that delay and filter must give the positions of
//! the extended models on the machine without the section. The two are stepped differently —
//! the section filters the samples (exactly for a reference linear between samples) and hands
//! the core a first-order hold of the filtered samples, the extended model integrates the
//! filter between samples too — so they agree to the discretisation of the filter's output
//! between samples, not bit for bit. That difference is second order in the sample period: on
//! the spiral at 1 ms it is at most 0.25 µm and 0.42 mdeg (contour errors are hundreds of µm),
//! at 0.5 ms a quarter of it, at 0.25 ms a sixteenth (measured, ratio 4.0 per halving). The
//! test asserts both: at most 1 µm (1 mdeg) at 1 ms, and at most a third of it at 0.5 ms.
//! A whole-period delay alone is the same shift in both places and agrees to rounding.
//!
//! The filters are a fixed case (an iTNC 530's 98 ms, the delay `vcnc identify --trace` found
//! on a real one, with a 5 ms first-order filter) and fresh ones drawn from a seed printed in
//! the log (set `VCNC_CONTROL_SEED` to repeat one).

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use vcnc_drive::{DriveModel, ReferenceFilter, ShapingFilter};
use vcnc_machine::{Machine, MachineModels, embedded};
use vcnc_pipeline::{run, simulate};

/// The embedded NMV5000 with a `[control]` section (TOML text), and its core models (the
/// drives' analytic closed loops).
fn machine(control: &str, ts: f64) -> (Machine, MachineModels) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machines");
    let toml = embedded::NMV5000_TOML.replace(
        "sample_period_s = 0.001",
        &format!("sample_period_s = {ts}"),
    );
    let src = format!("{toml}\n{control}");
    let m = Machine::from_toml_str(&src, "nmv5000-control.toml", &dir).expect("machine");
    let core = m
        .axes
        .iter()
        .map(|a| DriveModel::from(a.true_model()))
        .collect();
    let models = MachineModels::new(&m, core, "core").expect("models");
    (m, models)
}

/// Largest |Δ position| per axis between the core models behind `[control]` and the extended
/// models without it, at sample period `ts`.
fn compare(delay_s: f64, filter: Option<ShapingFilter>, ts: f64) -> Vec<f64> {
    let section = match filter {
        None => format!("[control]\ndelay_s = {delay_s}\n"),
        Some(ShapingFilter::FirstOrder { time_constant_s }) => format!(
            "[control]\ndelay_s = {delay_s}\nfilters = [{{ kind = \"first-order\", time_constant_s = {time_constant_s} }}]\n"
        ),
        Some(ShapingFilter::SecondOrder {
            time_constant_s,
            zeta,
        }) => format!(
            "[control]\ndelay_s = {delay_s}\nfilters = [{{ kind = \"second-order\", time_constant_s = {time_constant_s}, zeta = {zeta} }}]\n"
        ),
        Some(f) => panic!("not a model structure: {f:?}"),
    };
    let (with, core) = machine(&section, ts);
    let (without, _) = machine("", ts);
    let extended: Vec<DriveModel> = core
        .models()
        .iter()
        .map(|m| DriveModel {
            delay_s,
            reference_filter: filter.map(|f| match f {
                ShapingFilter::FirstOrder { time_constant_s } => ReferenceFilter::FirstOrder {
                    tau_s: time_constant_s,
                },
                ShapingFilter::SecondOrder {
                    time_constant_s,
                    zeta,
                } => ReferenceFilter::SecondOrder {
                    wn_hz: 1.0 / (std::f64::consts::TAU * time_constant_s),
                    zeta,
                },
                _ => unreachable!(),
            }),
            ..*m
        })
        .collect();
    let extended = MachineModels::new(&without, extended, "extended").expect("models");
    let r = run::prepare(&with, embedded::SPIRAL_NGC, "spiral.ngc", false).expect("spiral");
    let a = simulate::model_positions(&with, &core, &r, false).expect("behind [control]");
    let b = simulate::model_positions(&without, &extended, &r, false).expect("extended");
    a.iter()
        .zip(&b)
        .map(|(x, y)| {
            assert_eq!(x.len(), y.len());
            x.iter()
                .zip(y)
                .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()))
        })
        .collect()
}

fn check(delay_s: f64, filter: Option<ShapingFilter>) {
    let d1 = compare(delay_s, filter, 1e-3);
    let d2 = compare(delay_s, filter, 5e-4);
    let um = |d: &[f64]| d.iter().map(|v| v * 1e3).collect::<Vec<_>>();
    eprintln!(
        "delay {delay_s} s, {filter:?}: largest difference {:?} um/mdeg at 1 ms, {:?} at 0.5 ms",
        um(&d1),
        um(&d2)
    );
    for ((axis, a), b) in ["X", "Y", "Z", "A", "C"].iter().zip(&d1).zip(&d2) {
        if filter.is_none() {
            assert!(*a <= 1e-9 && *b <= 1e-9, "axis {axis}: {a}, {b}");
        } else {
            assert!(*a <= 1e-3, "axis {axis}: {a} at 1 ms");
            assert!(
                *b <= a / 3.0 + 1e-9,
                "axis {axis}: {b} at 0.5 ms against {a} at 1 ms"
            );
        }
    }
}

#[test]
fn a_delay_and_filter_in_control_predict_what_they_predict_inside_the_models() {
    check(
        0.098,
        Some(ShapingFilter::FirstOrder {
            time_constant_s: 0.005,
        }),
    );
    check(0.004, None);
    check(
        0.0,
        Some(ShapingFilter::SecondOrder {
            time_constant_s: 0.003,
            zeta: 0.7,
        }),
    );
}

#[test]
fn fresh_delays_and_filters_predict_alike_in_both_places() {
    let seed = std::env::var("VCNC_CONTROL_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| {
            // A fresh seed from the standard library's per-process random hasher keys.
            use std::hash::{BuildHasher, Hasher};
            std::collections::hash_map::RandomState::new()
                .build_hasher()
                .finish()
        });
    eprintln!("fresh control filters: seed {seed} (VCNC_CONTROL_SEED={seed} repeats it)");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..2 {
        let delay = rng.random_range(0..=100) as f64 * 1e-3;
        let t = rng.random_range(0.001..0.02);
        let filter = if rng.random_bool(0.5) {
            ShapingFilter::FirstOrder { time_constant_s: t }
        } else {
            ShapingFilter::SecondOrder {
                time_constant_s: t,
                zeta: rng.random_range(0.5..1.5),
            }
        };
        check(delay, Some(filter));
    }
}

#[test]
fn a_compensation_folds_a_delay_and_one_filter_into_the_models_and_refuses_the_rest() {
    // Truth: the definition of the fold (docs/machine-file.md#control): the control's delay
    // adds to each model's dead time and its one first- or second-order filter becomes the
    // model's reference filter; what a model cannot hold is refused as bad input.
    use vcnc_pipeline::compensate::with_control_filters;
    let (m, core) = machine(
        "[control]\ndelay_s = 0.012\nfilters = [{ kind = \"second-order\", time_constant_s = 0.004, zeta = 0.8 }]\n",
        1e-3,
    );
    let folded = with_control_filters(&m, &core).expect("foldable");
    for (f, c) in folded.models().iter().zip(core.models()) {
        assert_eq!(f.core, c.core);
        assert_eq!(f.delay_s, 0.012);
        let Some(ReferenceFilter::SecondOrder { wn_hz, zeta }) = f.reference_filter else {
            panic!("{:?}", f.reference_filter);
        };
        assert!((wn_hz - 1.0 / (std::f64::consts::TAU * 0.004)).abs() < 1e-9);
        assert_eq!(zeta, 0.8);
    }
    for section in [
        "[control]\nfilters = [{ kind = \"moving-average\", window_s = 0.004 }]\n",
        "[control]\nfilters = [{ kind = \"triangular\", window_s = 0.004 }]\n",
        "[control]\n[control.sinumerik]\nax_jerk_mode = 2\nax_jerk_time = 0.008\n",
        "[control]\nfilters = [{ kind = \"fir\", taps = [0.25, 0.5, 0.25] }]\n",
        "[control]\nfilters = [{ kind = \"band-stop\", frequency_hz = 40.0, zeta_numerator = 0.05, zeta_denominator = 0.7 }]\n",
    ] {
        let (m, core) = machine(section, 1e-3);
        let e = with_control_filters(&m, &core).unwrap_err();
        assert!(e.is_bad_input(), "{e}");
        assert!(e.to_string().contains("[control]"), "{e}");
        if section.contains("band-stop") {
            assert!(e.to_string().contains("BandStop"), "{e}");
        }
    }
}

/// The amplitude of the transmission's deflection (motor minus load position) at 180 Hz over
/// a 20 mm move of X and a dwell, µm: the embedded NMV5000 with a compliant X transmission
/// (nmv5000-realistic's: a 180 Hz mode with 3 % damping) and `control` appended. The run
/// starts and ends at rest, deflection 0, so the record's Fourier coefficient at 180 Hz is
/// the mode's excitation without an edge.
fn vibration_at_the_mode_um(control: &str) -> f64 {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machines");
    let compliant = embedded::NMV5000_TOML.replace(
        "encoder = { resolution = 0.0001 }\n\n[axes.Y]",
        "encoder = { resolution = 0.0001 }\ncompliance = { j_motor = 0.007, mode_hz = 180.0, mode_zeta = 0.03 }\n\n[axes.Y]",
    );
    assert_ne!(compliant, embedded::NMV5000_TOML, "the X axis block moved");
    let src = format!("{compliant}\n{control}");
    let m = Machine::from_toml_str(&src, "compliant.toml", &dir).expect("machine");
    let program = "G90 G21\nG1 X20 F9000\nG4 P0.3\nM30\n";
    let r = run::prepare(&m, program, "move.ngc", false).expect("program");
    let t = &simulate::true_traces(&m, &r).expect("true drives")[0];
    let w = std::f64::consts::TAU * 180.0 * r.ts;
    let (mut re, mut im) = (0.0, 0.0);
    for (k, (motor, load)) in t.motor_position.iter().zip(&t.true_position).enumerate() {
        let d = motor - load;
        re += d * (w * k as f64).cos();
        im += d * (w * k as f64).sin();
    }
    re.hypot(im) * 2.0 / t.true_position.len() as f64 * 1e3
}

#[test]
fn a_band_stop_at_a_drive_resonance_excites_it_less() {
    // Truth: a band-stop removes the setpoint's content at its blocking frequency, so a
    // lightly damped mode there is excited less by the move's acceleration steps. Measured:
    // the deflection's 180 Hz amplitude falls from 0.022 to 0.0056 µm behind an ideal notch at
    // the mode (ζd 0.7); asserted: by half at least. (After the stop the drive's own settling,
    // friction and encoder steps keep the mode ringing at ~0.003 µm with or without the
    // filter: the difference is in what the move excites.)
    let without = vibration_at_the_mode_um("");
    let with = vibration_at_the_mode_um(
        "[control]\nfilters = [{ kind = \"band-stop\", frequency_hz = 180.0, zeta_numerator = 0.0, zeta_denominator = 0.7 }]\n",
    );
    eprintln!(
        "X's deflection at 180 Hz: {without:.5} µm without, {with:.5} µm behind the band-stop"
    );
    assert!(with < 0.5 * without, "{with} µm against {without} µm");
}

#[test]
fn control_sections_are_checked_naming_the_key() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machines");
    for (section, says) in [
        ("[control]\ndelay_s = 0.0015\n", "delay_s"),
        (
            "[control]\nfilters = [{ kind = \"triangular\", window_s = 0.003 }]\n",
            "window_s",
        ),
        (
            "[control]\nfilters = [{ kind = \"first-order\", time_constant_s = 0 }]\n",
            "time_constant_s",
        ),
        (
            "[control]\n[control.sinumerik]\nax_jerk_mode = 5\nax_jerk_time = 0.004\n",
            "AX_JERK_MODE 5",
        ),
        ("[control]\nfilter = 3\n", "filter"),
        (
            "[control]\nfilters = [{ kind = \"fir\", taps = [0.5, 0.4] }]\n",
            "sum",
        ),
        (
            "[control]\nfilters = [{ kind = \"band-stop\", frequency_hz = 40.0, zeta_denominator = 0.7 }]\n",
            "zeta_numerator",
        ),
        (
            "[control]\nfilters = [{ kind = \"band-stop\", frequency_hz = 260.0, zeta_numerator = 0.1, zeta_denominator = 0.7 }]\n",
            "frequency_hz",
        ),
        (
            "[control]\n[control.sinumerik]\nax_jerk_mode = 3\nax_jerk_time = 0.0\n",
            "band-stop",
        ),
    ] {
        let src = format!("{}\n{section}", embedded::NMV5000_TOML);
        let e = Machine::from_toml_str(&src, "m.toml", &dir)
            .unwrap_err()
            .to_string();
        assert!(e.contains(says) && e.contains("m.toml"), "{section}: {e}");
    }
    // A Sinumerik double moving average is two moving averages; an empty section is none.
    let src = format!(
        "{}\n[control]\n[control.sinumerik]\nax_jerk_mode = 4\nax_jerk_time = 0.004\nax_jerk_time_add = 0.002\n",
        embedded::NMV5000_TOML
    );
    let m = Machine::from_toml_str(&src, "m.toml", &dir).unwrap();
    assert_eq!(
        m.control.expect("filters").filters(),
        [
            ShapingFilter::MovingAverage { window_s: 0.004 },
            ShapingFilter::MovingAverage { window_s: 0.002 }
        ]
    );
    let src = format!("{}\n[control]\n", embedded::NMV5000_TOML);
    assert!(
        Machine::from_toml_str(&src, "m.toml", &dir)
            .unwrap()
            .control
            .is_none()
    );
}
