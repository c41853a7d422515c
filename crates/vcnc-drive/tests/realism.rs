//! Acceptance tests of the drive's effects (issue 14, "Done means"). Each test states where its
//! truth comes from. Run with `--nocapture` to see the measured figures.

use crate::common;

use vcnc_drive::{
    AxisName, ControllerSpec, DriveParams, DriveTrace, Encoder, Friction, FrictionLocation,
    PoleDesign, nmv5000_axis_design, table1_drive,
};

const TS: f64 = 1e-3;

#[test]
fn neutral_effects_reproduce_the_ideal_drive() {
    // Truth: the ideal simulator (its own tests pin it to the analytic closed loop). A friction
    // table that restates the plant's symmetric Coulomb friction sends the drive through the
    // effects engine with the same physics.
    let prog = common::standard_program();
    for enc in [Encoder::ideal(), Encoder::default()] {
        let ideal = DriveParams {
            encoder: enc.clone(),
            ..table1_drive()
        };
        let neutral = DriveParams {
            friction: Some(Friction::Coulomb {
                coulomb_torque_negative: None,
                location: FrictionLocation::Load,
            }),
            ..ideal.clone()
        };
        let a = common::simulate(&ideal, &prog.pos, &prog.vel, &prog.acc, TS);
        let b = common::simulate(&neutral, &prog.pos, &prog.vel, &prog.acc, TS);
        let d = common::max_abs_diff(&a.true_position, &b.true_position);
        eprintln!(
            "neutral effects vs ideal (encoder step {} mm): max |dx| = {d:e} mm",
            enc.resolution
        );
        // Without quantisation the two differ by rounding only; with it, a rounding difference
        // can flip an encoder count, so they agree to within one count.
        let tol = if enc.resolution == 0.0 {
            1e-9
        } else {
            enc.resolution
        };
        assert!(d < tol, "{d}");
    }
}

/// FNV-1a over the bits of every logged value of the fields the simulator had before the effects
/// (position, true position, velocity, control) and the saturated-tick count.
fn fingerprint(t: &DriveTrace) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for v in [&t.position, &t.true_position, &t.velocity, &t.control] {
        for x in v.iter() {
            for b in x.to_bits().to_le_bytes() {
                h ^= b as u64;
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
    }
    h ^ t.saturated_ticks
}

#[test]
fn drives_without_effects_are_bit_identical_to_the_simulator_before_them() {
    // Truth: the unmodified simulator. The fingerprints below were printed by the same code run
    // against vcnc-drive at commit cab1ef9 (before any effect existed), on two identification
    // programs (one far from the origin) and seven drives: P-PI with and without encoder noise
    // and with a control limit, two NMV5000 axes (mm and deg), PID and sliding mode.
    let golden: [(&str, u64); 14] = [
        ("id7/table1", 0x2b696a0fe75a9b94),
        ("id7/table1-noise", 0x6c0b8fb913dde6b5),
        ("id7/table1-umax", 0x0ce934c8945d18ec),
        ("id7/nmv5000-X", 0xcc9aa1e3ee38018c),
        ("id7/nmv5000-A", 0x8aff07bca1c996f0),
        ("id7/pid", 0x551f6da30fd548df),
        ("id7/smc", 0x2cef5d65d469d3af),
        ("id11-offset/table1", 0x55ad1578b0f62064),
        ("id11-offset/table1-noise", 0xc0952d0aee8d5689),
        ("id11-offset/table1-umax", 0x9ea5c9d39aef088a),
        ("id11-offset/nmv5000-X", 0x0475687867a3edfd),
        ("id11-offset/nmv5000-A", 0x56d2f0517cd922f8),
        ("id11-offset/pid", 0x131f1185c972bda0),
        ("id11-offset/smc", 0x4d9eac8dbb5ac62f),
    ];
    let progs = [
        (
            "id7",
            common::identification_program(7, 6.0, TS, 0.0, 50.0, 250.0, 2500.0),
        ),
        (
            "id11-offset",
            common::identification_program(11, 6.0, TS, 120.0, 30.0, 400.0, 5000.0),
        ),
    ];
    let pole = {
        let p = table1_drive().closed_loop_model().unwrap().poles().unwrap();
        PoleDesign {
            p_hz: p.p_hz(),
            wn_hz: p.wn_hz(),
            zeta: p.zeta,
        }
    };
    let mut noisy = table1_drive();
    noisy.encoder.noise_std = 2e-4;
    noisy.encoder.seed = 5;
    let mut limited = table1_drive();
    limited.plant.u_max = Some(3.0);
    let mut pid = table1_drive();
    pid.controller = ControllerSpec::Pid {
        kp: None,
        ki: None,
        kd: None,
        design: Some(pole),
        jff: 0.0,
        bff: 0.1,
    };
    let mut smc = table1_drive();
    smc.controller = ControllerSpec::Smc {
        lambda: None,
        ks: None,
        rho: None,
        je_hat: None,
        be_hat: None,
        design: Some(pole),
    };
    let drives = [
        ("table1", table1_drive()),
        ("table1-noise", noisy),
        ("table1-umax", limited),
        ("nmv5000-X", nmv5000_axis_design(AxisName::X).unwrap()),
        ("nmv5000-A", nmv5000_axis_design(AxisName::A).unwrap()),
        ("pid", pid),
        ("smc", smc),
    ];
    let mut k = 0;
    for (pn, prog) in &progs {
        for (dn, d) in &drives {
            let drive = d.validate().unwrap();
            assert!(drive.effects().is_ideal());
            let t = drive.simulate(prog.reference(), TS).unwrap();
            let (name, want) = golden[k];
            assert_eq!(name, format!("{pn}/{dn}"));
            assert_eq!(
                fingerprint(&t),
                want,
                "{name}: trace differs from the unmodified simulator"
            );
            // The new fields: the rigid drive's motor is its load, its torque Ka Kt u.
            assert_eq!(t.motor_position, t.true_position);
            let kakt = d.plant.ka * d.plant.kt;
            assert!(
                t.control
                    .iter()
                    .zip(&t.motor_torque)
                    .all(|(u, tq)| *tq == kakt * u)
            );
            k += 1;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Helpers.

use std::f64::consts::TAU;
use vcnc_drive::{
    Compliance, CurrentLoop, CurrentLoopOrder, Error, Feedback, FeedbackSource, FrfKind,
    FrfOptions, ReferenceShaping, ShapingFilter,
};

/// Samples at TS of a piecewise-constant-velocity path: `(duration s, velocity units/s)`
/// segments joined by `accel` ramps, starting at rest at `x0`.
fn velocity_profile(x0: f64, segments: &[(f64, f64)], accel: f64) -> common::Program {
    let mut prog = common::Program {
        pos: vec![x0],
        vel: vec![0.0],
        acc: vec![0.0],
    };
    let (mut x, mut v) = (x0, 0.0);
    let sub = 100;
    let dt = TS / sub as f64;
    for &(duration, target) in segments {
        let n = (duration / TS).round() as usize;
        for _ in 0..n {
            let mut a_avg = 0.0;
            for _ in 0..sub {
                let dv = target - v;
                let a = dv.signum() * accel.min(dv.abs() / dt);
                x += v * dt + 0.5 * a * dt * dt;
                v += a * dt;
                a_avg = a;
            }
            prog.pos.push(x);
            prog.vel.push(v);
            prog.acc.push(if (target - v).abs() > 1e-12 {
                a_avg
            } else {
                0.0
            });
        }
    }
    prog
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

fn std_dev(v: &[f64]) -> f64 {
    let m = mean(v);
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}

/// A two-mass version of the Table 1 drive: J_m = 0.004, J_L = 0.006 kg m², stiffness k and
/// damping c, given backlash and feedback source, ideal encoder.
fn two_mass_table1(k: f64, c: f64, backlash: f64, source: FeedbackSource) -> DriveParams {
    DriveParams {
        encoder: Encoder::ideal(),
        compliance: Some(Compliance {
            j_motor: 0.004,
            stiffness: Some(k),
            mode_hz: None,
            damping: Some(c),
            mode_zeta: None,
            backlash,
        }),
        feedback: Some(Feedback {
            source,
            ..Feedback::default()
        }),
        ..table1_drive()
    }
}

// ---------------------------------------------------------------------------------------------
// 1. Compliance.

/// Frequency of the extremum of |G| near index `i`, by a parabola through log|G| at i - 1, i,
/// i + 1 (uniform line spacing).
fn refine_extremum(f: &[f64], m: &[f64], i: usize) -> f64 {
    let (a, b, c) = (m[i - 1].ln(), m[i].ln(), m[i + 1].ln());
    f[i] + 0.5 * (f[i + 1] - f[i]) * (a - c) / (a - 2.0 * b + c)
}

#[test]
fn mechanical_frf_has_the_two_mass_resonance_and_antiresonance() {
    // Truth: the two-mass formulas. Motor torque -> motor speed of J_m, J_L coupled by k:
    // anti-resonance sqrt(k/J_L), resonance sqrt(k (J_m + J_L)/(J_m J_L)). Measured with the
    // loop closed (Table 1 gains, linear scale on the load) by the multisine FRF on a 25 mm/s
    // bias, so the load's Coulomb friction stays a constant torque.
    let (jm, jl, k, c): (f64, f64, f64, f64) = (0.004, 0.006, 2132.0, 0.136);
    let wa = (k / jl).sqrt() / TAU;
    let wr = (k * (jm + jl) / (jm * jl)).sqrt() / TAU;
    let drive = two_mass_table1(k, c, 0.0, FeedbackSource::Load)
        .validate()
        .unwrap();
    let frf = drive
        .measure_frf(&FrfOptions {
            kind: FrfKind::Mechanical,
            f_min_hz: 40.0,
            f_max_hz: 300.0,
            resolution_hz: Some(0.5),
            lines: 0,
            amplitude: Some(0.3),
            bias_velocity: 25.0,
            settle_periods: 2,
            periods: 2,
        })
        .unwrap();
    assert!(frf.velocity_range.0 > 0.0, "{:?}", frf.velocity_range);
    let f = &frf.freq_hz;
    let band = |lo: f64, hi: f64| (0..f.len()).filter(move |&i| f[i] > lo && f[i] < hi);
    let i_max = band(wa * 1.2, 300.0)
        .max_by(|&a, &b| frf.magnitude[a].total_cmp(&frf.magnitude[b]))
        .unwrap();
    let i_min = band(41.0, wr * 0.8)
        .min_by(|&a, &b| frf.magnitude[a].total_cmp(&frf.magnitude[b]))
        .unwrap();
    let f_res = refine_extremum(&frf.freq_hz, &frf.magnitude, i_max);
    let f_anti = refine_extremum(&frf.freq_hz, &frf.magnitude, i_min);
    eprintln!(
        "resonance {f_res:.2} Hz (formula {wr:.2} Hz), anti-resonance {f_anti:.2} Hz (formula {wa:.2} Hz)"
    );
    assert!((f_res / wr - 1.0).abs() < 0.01);
    assert!((f_anti / wa - 1.0).abs() < 0.01);
    // The checked drive reports the same formulas.
    let tm = drive.effects().compliance.unwrap();
    assert!((tm.resonance_hz() / wr - 1.0).abs() < 1e-12);
    assert!((tm.antiresonance_hz() / wa - 1.0).abs() < 1e-12);
}

#[test]
fn mode_frequency_and_damping_ratio_are_the_stiffness_form() {
    // Truth: f_r = sqrt(k (J_m + J_L)/(J_m J_L))/2pi and zeta = c/(2 w_r J_m J_L/(J_m + J_L)).
    let p = DriveParams {
        compliance: Some(Compliance {
            j_motor: 0.004,
            stiffness: None,
            mode_hz: Some(150.0),
            damping: None,
            mode_zeta: Some(0.03),
            backlash: 0.0,
        }),
        ..table1_drive()
    };
    let tm = p.validate().unwrap().effects().compliance.unwrap();
    let jr = 0.004 * 0.006 / 0.01;
    let w = TAU * 150.0;
    assert!((tm.stiffness / (w * w * jr) - 1.0).abs() < 1e-12);
    assert!((tm.damping / (2.0 * 0.03 * w * jr) - 1.0).abs() < 1e-12);
    assert!((tm.resonance_hz() - 150.0).abs() < 1e-9);
    assert!((tm.zeta() - 0.03).abs() < 1e-12);
}

// ---------------------------------------------------------------------------------------------
// 3. Backlash.

#[test]
fn lost_motion_at_reversal_is_the_backlash_plus_the_elastic_windup() {
    // Truth: statics of the transmission. In steady motion at v the load's friction
    // T_c + B v/rg is carried by the spring on one flank of the backlash, so the motor leads the
    // load by b/2 + rg (T_c + B v/rg)/k; reversing moves to the other flank. The lost motion (the
    // change of motor minus load position between the two directions, what a reversal test
    // measures on a semi-closed-loop axis) is b + 2 rg (T_c + B v/rg)/k. With the load's
    // friction at 0 and only its viscous friction it is b + 2 B v/k.
    let (k, c, b) = (2132.0, 0.136, 0.02);
    let v = 10.0;
    for tc in [0.3, 0.0] {
        let mut p = two_mass_table1(k, c, b, FeedbackSource::Motor);
        p.plant.coulomb_torque = tc;
        let drive = p.validate().unwrap();
        let prog = velocity_profile(
            5.0,
            &[(0.2, 0.0), (2.0, v), (0.5, 0.0), (2.0, -v), (0.3, 0.0)],
            200.0,
        );
        let t = drive.simulate(prog.reference(), TS).unwrap();
        let lead: Vec<f64> = t
            .motor_position
            .iter()
            .zip(&t.true_position)
            .map(|(m, l)| m - l)
            .collect();
        let pos = mean(&lead[1700..2100]);
        let neg = mean(&lead[4200..4600]);
        let rg = p.plant.rg;
        let windup = rg * (tc + p.plant.b * v / rg) / k;
        let expect = b + 2.0 * windup;
        eprintln!(
            "Tc = {tc}: lost motion {:.4} um (backlash {:.1} um + elastic windup 2 x {:.4} um = {:.4} um)",
            (pos - neg) * 1e3,
            b * 1e3,
            windup * 1e3,
            expect * 1e3
        );
        assert!(
            (pos - neg - expect).abs() < 2e-5,
            "{} vs {expect}",
            pos - neg
        );
        assert!((pos - (0.5 * b + windup)).abs() < 2e-5);
    }
}

// ---------------------------------------------------------------------------------------------
// 2. Friction.

fn stribeck() -> Friction {
    Friction::Stribeck {
        static_torque: 0.45,
        stribeck_velocity: 2.0,
        stribeck_exponent: 2.0,
        coulomb_torque_negative: Some(0.25),
        static_torque_negative: Some(0.40),
        location: FrictionLocation::Load,
    }
}

/// The Stribeck law of `stribeck()` with plant.coulomb_torque = 0.3: torque opposing v.
fn stribeck_law(v: f64) -> f64 {
    let (tc, ts) = if v > 0.0 { (0.3, 0.45) } else { (0.25, 0.40) };
    v.signum() * (tc + (ts - tc) * (-(v / 2.0).powi(2)).exp())
}

#[test]
fn steady_friction_follows_the_stribeck_law() {
    // Truth: the Stribeck law T(v) = T_c + (T_s - T_c) exp(-(v/v_s)^2), per direction. At a
    // steady velocity the motor torque carries friction and viscous friction only:
    // K_a K_t u = T(v) + B v/rg. Both the set-valued and the Maxwell-slip model (whose elements
    // all slip in steady motion) must give it.
    let presliding = Friction::MaxwellSlip {
        presliding_displacement: 0.002,
        elements: 4,
        static_torque: Some(0.45),
        stribeck_velocity: Some(2.0),
        stribeck_exponent: 2.0,
        coulomb_torque_negative: Some(0.25),
        static_torque_negative: Some(0.40),
        location: FrictionLocation::Load,
    };
    for friction in [stribeck(), presliding] {
        let p = DriveParams {
            encoder: Encoder::ideal(),
            friction: Some(friction.clone()),
            ..table1_drive()
        };
        let drive = p.validate().unwrap();
        for v in [0.5, 1.0, 2.0, 3.0, 5.0, 40.0, -0.7, -2.0, -6.0] {
            let prog = velocity_profile(0.0, &[(0.05, 0.0), (1.5, v)], 1000.0);
            let t = drive.simulate(prog.reference(), TS).unwrap();
            let window = t.len() - 500..t.len();
            let torque = mean(&t.motor_torque[window.clone()]);
            let speed = mean(&t.velocity[window]);
            let expect = stribeck_law(v) + p.plant.b * v / p.plant.rg;
            eprintln!(
                "{}: v = {v:5.1} mm/s (measured {speed:.6}): torque {torque:.6} N m, law + viscous {expect:.6}",
                match friction {
                    Friction::Stribeck { .. } => "set-valued",
                    _ => "Maxwell-slip",
                }
            );
            assert!((speed / v - 1.0).abs() < 1e-6);
            assert!((torque - expect).abs() < 1e-6 * 0.3, "{torque} vs {expect}");
        }
    }
}

#[test]
fn axis_sticks_below_the_static_level_even_above_coulomb() {
    // Truth: static friction with true sticking. A P-P cascade (Ki = 0) holding a constant
    // position error delta applies the torque Kp Kv delta: 1.2 Tc (above Coulomb, below the
    // static 1.5 Tc) leaves the axis exactly at rest; 1.1 Ts breaks it away.
    let base = DriveParams {
        friction: Some(stribeck()),
        ..common::p_p_cascade()
    };
    let x0 = 12.5;
    for (torque, moves) in [(1.2 * 0.3, false), (1.1 * 0.45, true)] {
        let delta = torque / (2.342478 * 70.0);
        let n = 1000;
        let mut pos = vec![x0 + delta; n];
        pos[0] = x0;
        let z = vec![0.0; n];
        let t = common::simulate(&base, &pos, &z, &z, TS);
        let still = t.true_position.iter().all(|&x| x == x0);
        assert_eq!(still, !moves, "torque {torque} N m");
    }
}

#[test]
fn presliding_after_a_reversal_follows_masings_rule() {
    // Truth: Masing's rule of Maxwell-slip friction. After a reversal from steady sliding at
    // +T_c, the friction as a function of the displacement d back from the reversal point is
    // T_c - 2 F_v(d/2), F_v the virgin curve sum_i min(k_i x, T_c/N) of elements that slip at
    // x_i = i x_ps / N (k_i = T_c/(N x_i)). Quasi-static (0.02 mm/s): the motor torque is the
    // friction plus B v/rg.
    let (tc, xps, n_el) = (0.3, 0.004, 4usize);
    let p = DriveParams {
        encoder: Encoder::ideal(),
        friction: Some(Friction::MaxwellSlip {
            presliding_displacement: xps,
            elements: n_el,
            static_torque: None,
            stribeck_velocity: None,
            stribeck_exponent: 2.0,
            coulomb_torque_negative: None,
            static_torque_negative: None,
            location: FrictionLocation::Load,
        }),
        ..table1_drive()
    };
    let v = 0.02;
    let prog = velocity_profile(1.0, &[(0.05, 0.0), (1.5, v), (1.5, -v)], 0.2);
    let t = common::simulate(&p, &prog.pos, &prog.vel, &prog.acc, TS);
    let virgin = |x: f64| {
        (1..=n_el)
            .map(|i| {
                let xi = i as f64 * xps / n_el as f64;
                (tc / (n_el as f64 * xi) * x).min(tc / n_el as f64)
            })
            .sum::<f64>()
    };
    let k_rev = (0..t.len())
        .max_by(|&a, &b| t.true_position[a].total_cmp(&t.true_position[b]))
        .unwrap();
    let x_rev = t.true_position[k_rev];
    let mut checked = 0;
    for k in k_rev..t.len() {
        let d = x_rev - t.true_position[k];
        if d > 1.5 * xps {
            break;
        }
        // Friction = motor torque - viscous - inertial (acceleration by central differences).
        let acc = (t.velocity[k + 1] - t.velocity[k - 1]) / (2.0 * TS);
        let friction = t.motor_torque[k]
            - p.plant.b * t.velocity[k] / p.plant.rg
            - p.plant.j * acc / p.plant.rg;
        let expect = tc - 2.0 * virgin(0.5 * d);
        assert!(
            (friction - expect).abs() < 0.01 * tc,
            "d = {d:e} mm: friction {friction} vs Masing {expect}"
        );
        checked += 1;
    }
    eprintln!("Masing's rule held on {checked} samples after the reversal");
    assert!(checked > 100);
}

// ---------------------------------------------------------------------------------------------
// 4. Current loop and torque limit.

#[test]
fn torque_limit_is_respected_and_the_axis_still_settles() {
    // Truth: the limit itself, |T| <= T_max for the command and for the first-order current
    // loop's output (a first-order lag of a bounded input starting inside the bound stays
    // inside it); after the program the axis settles on the target.
    let t_max = 2.0;
    let p = DriveParams {
        current_loop: Some(CurrentLoop {
            order: CurrentLoopOrder::FirstOrder,
            bandwidth_hz: Some(1000.0),
            zeta: None,
            torque_max: Some(t_max),
        }),
        ..table1_drive()
    };
    let mut prog = common::identification_program(3, 6.0, TS, 0.0, 50.0, 250.0, 2500.0);
    // One more second at rest on the last target.
    let last = *prog.pos.last().unwrap();
    for _ in 0..1000 {
        prog.pos.push(last);
        prog.vel.push(0.0);
        prog.acc.push(0.0);
    }
    let t = common::simulate(&p, &prog.pos, &prog.vel, &prog.acc, TS);
    let peak_cmd = t.control.iter().fold(0.0f64, |m, u| m.max(u.abs()));
    let peak_torque = t.motor_torque.iter().fold(0.0f64, |m, u| m.max(u.abs()));
    let n = t.len();
    eprintln!(
        "limited ticks {}, peak command {peak_cmd} N m, peak torque {peak_torque} N m",
        t.saturated_ticks
    );
    assert!(t.saturated_ticks > 100);
    assert!(peak_cmd <= t_max * (1.0 + 1e-12));
    assert!(peak_torque <= t_max * (1.0 + 1e-12));
    let settled = (t.true_position[n - 1] - prog.pos[n - 1]).abs();
    eprintln!("final position error {settled:e} mm");
    assert!(settled < 1e-3);
}

// ---------------------------------------------------------------------------------------------
// 5. Encoder noise, dead time, velocity filter.

#[test]
fn standstill_encoder_noise_has_its_standard_deviation() {
    // Truth: the reading is q round((x + n)/q), n ~ N(0, sigma²): at standstill the reading
    // minus the true position has standard deviation sigma (q = 0), or sqrt(sigma² + q²/12)
    // (Sheppard's correction, q well below sigma). 20 000 samples: the sample standard deviation
    // is within 3 % (6 of its standard errors). Both the ideal loop and the effects engine.
    let sigma = 5e-4;
    for q in [0.0, 1e-4] {
        for engine in [false, true] {
            let p = DriveParams {
                encoder: Encoder {
                    resolution: q,
                    noise_std: sigma,
                    seed: 9,
                },
                friction: engine.then_some(Friction::Coulomb {
                    coulomb_torque_negative: None,
                    location: FrictionLocation::Load,
                }),
                ..table1_drive()
            };
            let n = 20_000;
            let pos = vec![3.0; n];
            let z = vec![0.0; n];
            let t = common::simulate(&p, &pos, &z, &z, TS);
            let err: Vec<f64> = t
                .position
                .iter()
                .zip(&t.true_position)
                .map(|(r, x)| r - x)
                .collect();
            let s = std_dev(&err);
            let expect = (sigma * sigma + q * q / 12.0).sqrt();
            eprintln!(
                "q = {q}, engine {engine}: reading noise {:.4} um, expected {:.4} um; true position jitter {:.4} um",
                s * 1e3,
                expect * 1e3,
                std_dev(&t.true_position) * 1e3
            );
            assert!((s / expect - 1.0).abs() < 0.03);
            assert!(mean(&err).abs() < 6.0 * expect / (n as f64).sqrt());
        }
    }
}

#[test]
fn same_seed_same_trace_and_another_seed_another() {
    let prog = common::identification_program(5, 2.0, TS, 0.0, 20.0, 100.0, 2500.0);
    let run = |seed: u64| {
        let mut p = common::realistic_table1();
        p.encoder.seed = seed;
        common::simulate(&p, &prog.pos, &prog.vel, &prog.acc, TS)
    };
    let (a, b, c) = (run(1), run(1), run(2));
    assert_eq!(a, b);
    assert_ne!(a.position, c.position);
}

#[test]
fn interpolation_delay_of_whole_samples_shifts_the_response_exactly() {
    // Truth: a pure delay. The loop sees the nominal position n servo ticks late and starts at
    // rest on its first value, so with a noise-free encoder every logged signal is the
    // undelayed drive's, n ticks later, bit for bit (checked for 20 and 40 ticks, one and two
    // logged samples).
    let prog = common::identification_program(4, 3.0, TS, 0.0, 30.0, 200.0, 2500.0);
    let base = DriveParams {
        encoder: Encoder::ideal(),
        friction: Some(Friction::Coulomb {
            coulomb_torque_negative: None,
            location: FrictionLocation::Load,
        }),
        ..table1_drive()
    };
    let t0 = common::simulate(&base, &prog.pos, &prog.vel, &prog.acc, TS);
    for samples in [1usize, 2] {
        let p = DriveParams {
            reference: Some(ReferenceShaping {
                filter: None,
                interpolation_delay_s: samples as f64 * TS,
            }),
            ..base.clone()
        };
        let t = common::simulate(&p, &prog.pos, &prog.vel, &prog.acc, TS);
        let n = t.len();
        assert_eq!(t.true_position[samples..], t0.true_position[..n - samples]);
        assert_eq!(t.position[samples..], t0.position[..n - samples]);
        assert_eq!(t.control[samples..], t0.control[..n - samples]);
        assert!(t.true_position[..samples].iter().all(|x| *x == prog.pos[0]));
    }
}

#[test]
fn dead_time_and_velocity_filter_match_a_plainly_written_loop() {
    // Truth: a brute-force oracle. The P-PI law of docs/drive-model.md with the position loop
    // reading the encoder 3 ticks late and the velocity estimated from a low-pass filtered
    // reading, written plainly below (no rearrangement, a queue for the delay), on the exact
    // step of the rigid plant x'' = -beta x' + c u (closed form). The engine must agree to
    // rounding.
    let d = 3usize;
    let fc = 800.0;
    let mut p = table1_drive();
    p.plant.coulomb_torque = 0.0;
    p.encoder = Encoder::ideal();
    p.feedback = Some(Feedback {
        dead_time_cycles: d as u32,
        velocity_filter_hz: Some(fc),
        ..Feedback::default()
    });
    let prog = common::identification_program(8, 2.0, TS, 10.0, 20.0, 150.0, 2500.0);
    let t = common::simulate(&p, &prog.pos, &prog.vel, &prog.acc, TS);

    let (kv, kp, ki, vff, bff) = (70.0, 2.342478, 223.252126, 0.5, 0.1);
    let (j, b, rg) = (p.plant.j, p.plant.b, p.plant.rg);
    let n_sub = 20;
    let h = TS / n_sub as f64;
    let beta = b / j;
    let c = rg / j;
    let decay = (-beta * h).exp();
    let phi1 = (1.0 - decay) / beta;
    let phi2 = (h - phi1) / beta;
    let a = (-TAU * fc * h).exp();
    let x0 = prog.pos[0];
    let (mut x, mut v) = (x0, 0.0);
    let mut queue: std::collections::VecDeque<f64> = std::iter::repeat_n(x0, d).collect();
    let (mut xf1, mut xf2, mut integ, mut e1, mut xr1) = (x0, x0, 0.0, 0.0, x0);
    let mut oracle = Vec::new();
    let n = prog.len();
    for k in 0..n {
        let ticks = if k + 1 == n { 1 } else { n_sub };
        for jt in 0..ticks {
            let w = jt as f64 / n_sub as f64;
            let nxt = (k + 1).min(n - 1);
            let xr = prog.pos[k] + w * (prog.pos[nxt] - prog.pos[k]);
            let vr = prog.vel[k] + w * (prog.vel[nxt] - prog.vel[k]);
            if jt == 0 {
                oracle.push(x);
            }
            let reading = x;
            queue.push_back(reading);
            let xp = queue.pop_front().unwrap();
            let xf = a * xf1 + (1.0 - a) * reading;
            let v_hat = (3.0 * xf - 4.0 * xf1 + xf2) / (2.0 * h);
            let e = xr - xp;
            let omega_c = kv * e + vff * vr / rg;
            let d_int = kv * h * (e + e1) / 2.0 + vff * (xr - xr1) / rg - (xf - xf1) / rg;
            integ += d_int;
            let u = kp * (omega_c - v_hat / rg) + ki * integ + bff * b * vr / rg;
            let x_next = x + phi1 * v + phi2 * c * u;
            v = decay * v + phi1 * c * u;
            x = x_next;
            e1 = e;
            xr1 = xr;
            xf2 = xf1;
            xf1 = xf;
        }
    }
    let worst = common::max_abs_diff(&t.true_position, &oracle);
    let peak_error = common::max_abs_diff(&t.true_position, &prog.pos);
    eprintln!(
        "dead time {d} ticks + {fc} Hz velocity filter: engine vs oracle {worst:e} mm (tracking error up to {peak_error:.3} mm)"
    );
    assert!(worst < 1e-9);
}

// ---------------------------------------------------------------------------------------------
// 6. Reference shaping through the drive; 8. tracking FRF.

#[test]
fn tracking_frf_of_the_ideal_drive_is_the_closed_loop_model() {
    // Truth: the analytic closed-loop model (docs/drive-model.md), whose coefficients the paper's
    // Table 1 fixes; at 20 kHz the sampled loop is within 1 % of it. With an interpolation
    // delay T_d the measured response is the model times exp(-j w T_d) (a pure delay: the phase
    // drops by 360 f T_d degrees, the magnitude is unchanged).
    let base = DriveParams {
        encoder: Encoder::ideal(),
        ..table1_drive()
    };
    let model = base.closed_loop_model().unwrap();
    let opts = FrfOptions {
        f_min_hz: 1.0,
        f_max_hz: 100.0,
        lines: 40,
        ..FrfOptions::default()
    };
    for delay in [0.0, 0.002] {
        let p = DriveParams {
            reference: (delay > 0.0).then_some(ReferenceShaping {
                filter: None,
                interpolation_delay_s: delay,
            }),
            ..base.clone()
        };
        let frf = p.validate().unwrap().measure_frf(&opts).unwrap();
        let (mut worst_mag, mut worst_phase) = (0.0f64, 0.0f64);
        for (i, f) in frf.freq_hz.iter().enumerate() {
            let g = model.tracking_frf(TAU * f);
            let mag = frf.magnitude[i] / g.norm() - 1.0;
            let mut dphase = frf.phase_deg[i] - g.arg().to_degrees() + 360.0 * f * delay;
            dphase -= 360.0 * (dphase / 360.0).round();
            worst_mag = worst_mag.max(mag.abs());
            worst_phase = worst_phase.max(dphase.abs());
        }
        eprintln!(
            "delay {delay} s: measured vs model up to {:.3} % magnitude, {:.3} deg phase over {} lines",
            worst_mag * 100.0,
            worst_phase,
            frf.freq_hz.len()
        );
        assert!(frf.velocity_range.0 > 0.0);
        assert!(worst_mag < 0.01);
        assert!(worst_phase < 1.0);
    }
}

#[test]
fn the_loop_sees_the_shaped_reference_but_the_trace_logs_the_nominal() {
    // Truth: a unit-DC-gain filter delays a ramp by its time constant: at a steady feed V the
    // position lags the nominal by the loop's own following error (1 - Vff) V/(Kv rg) plus
    // T V (first order) or the window's half Tw V/2 (moving average), plus the interpolation
    // delay Td V.
    let v = 100.0;
    let prog = velocity_profile(0.0, &[(0.05, 0.0), (1.0, v)], 2500.0);
    let base = DriveParams {
        encoder: Encoder::ideal(),
        ..table1_drive()
    };
    let follow = (1.0 - 0.5) * v / (70.0 * 1.5915);
    for (filter, lag) in [
        (
            ShapingFilter::FirstOrder {
                time_constant_s: 0.003,
            },
            0.003,
        ),
        (ShapingFilter::MovingAverage { window_s: 0.004 }, 0.002),
        (
            ShapingFilter::SecondOrder {
                time_constant_s: 0.002,
                zeta: 1.0,
            },
            0.004,
        ),
    ] {
        let td = 0.002;
        let p = DriveParams {
            reference: Some(ReferenceShaping {
                filter: Some(filter),
                interpolation_delay_s: td,
            }),
            ..base.clone()
        };
        let t = common::simulate(&p, &prog.pos, &prog.vel, &prog.acc, TS);
        let n = t.len();
        let e = prog.pos[n - 1] - t.true_position[n - 1];
        let expect = follow + (lag + td) * v;
        eprintln!("{filter:?}: lag {e:.5} mm, expected {expect:.5} mm");
        assert!((e - expect).abs() < 1e-5, "{e} vs {expect}");
    }
}

// ---------------------------------------------------------------------------------------------
// Checks of the configuration.

#[test]
fn effects_engine_linearisation_has_the_ideal_loops_eigenvalues() {
    // Truth: the ideal simulator's sampled transition matrix (itself tested against the
    // continuous design). A friction table does not change the linear loop, so the effects
    // engine's linearisation must have the same eigenvalues (plus one at 0: the engine also
    // carries the previous position error, a combination of the other states).
    let p = DriveParams {
        friction: Some(stribeck()),
        ..table1_drive()
    };
    let drive = p.validate().unwrap();
    let ideal = drive.sampled_transition_matrix().unwrap();
    let mut want: Vec<_> = ideal.complex_eigenvalues().iter().copied().collect();
    let m = drive.effects_transition_matrix().unwrap();
    let mut got: Vec<_> = m.complex_eigenvalues().iter().copied().collect();
    let key = |z: &nalgebra::Complex<f64>| (z.norm(), z.im);
    want.sort_by(|a, b| key(a).partial_cmp(&key(b)).unwrap());
    got.sort_by(|a, b| key(a).partial_cmp(&key(b)).unwrap());
    assert_eq!(got.len(), want.len() + 1);
    assert!(got[0].norm() < 1e-9);
    for (g, w) in got[1..].iter().zip(&want) {
        assert!((g - w).norm() < 1e-9, "{g} vs {w}");
    }
}

#[test]
fn loops_destabilised_by_their_effects_are_rejected() {
    // Truth: physics of non-collocated control. With the position measured on a load that
    // hangs on a soft, barely damped transmission (12 Hz first mode) the Table 1 gains cannot
    // hold the loop; with the same transmission and the motor encoder (collocated) they can.
    let soft = |source| DriveParams {
        compliance: Some(Compliance {
            j_motor: 0.004,
            stiffness: None,
            mode_hz: Some(12.0),
            damping: None,
            mode_zeta: Some(0.005),
            backlash: 0.0,
        }),
        feedback: Some(Feedback {
            source,
            ..Feedback::default()
        }),
        ..table1_drive()
    };
    match soft(FeedbackSource::Load).validate() {
        Err(e @ Error::EffectsUnstable { .. }) => eprintln!("{e}"),
        other => panic!("expected EffectsUnstable, got {other:?}"),
    }
    soft(FeedbackSource::Motor).validate().unwrap();
}

#[test]
fn bad_effect_parameters_are_rejected_with_their_key_and_value() {
    let with_compliance = |p: &mut DriveParams| {
        p.compliance = Some(Compliance {
            j_motor: 0.004,
            stiffness: Some(2000.0),
            mode_hz: None,
            damping: Some(0.1),
            mode_zeta: None,
            backlash: 0.0,
        })
    };
    let cases: Vec<(common::Mutation, &str)> = vec![
        (
            |p| {
                p.compliance = Some(Compliance {
                    j_motor: 0.02,
                    stiffness: Some(2000.0),
                    mode_hz: None,
                    damping: Some(0.1),
                    mode_zeta: None,
                    backlash: 0.0,
                })
            },
            "compliance.j_motor",
        ),
        (
            |p| {
                p.compliance = Some(Compliance {
                    j_motor: 0.004,
                    stiffness: None,
                    mode_hz: Some(15_000.0),
                    damping: Some(0.1),
                    mode_zeta: None,
                    backlash: 0.0,
                })
            },
            "compliance.mode_hz",
        ),
        (
            |p| {
                p.compliance = Some(Compliance {
                    j_motor: 0.004,
                    stiffness: Some(2000.0),
                    mode_hz: None,
                    damping: None,
                    mode_zeta: Some(1.5),
                    backlash: 0.0,
                })
            },
            "compliance.mode_zeta",
        ),
        (
            |p| {
                p.compliance = Some(Compliance {
                    j_motor: 0.004,
                    stiffness: Some(2000.0),
                    mode_hz: None,
                    damping: Some(0.1),
                    mode_zeta: None,
                    backlash: -0.01,
                })
            },
            "compliance.backlash",
        ),
        (
            |p| {
                p.friction = Some(Friction::Stribeck {
                    static_torque: 0.2,
                    stribeck_velocity: 1.0,
                    stribeck_exponent: 2.0,
                    coulomb_torque_negative: None,
                    static_torque_negative: None,
                    location: FrictionLocation::Load,
                })
            },
            "friction.static_torque",
        ),
        (
            |p| {
                p.friction = Some(Friction::Stribeck {
                    static_torque: 0.4,
                    stribeck_velocity: f64::NAN,
                    stribeck_exponent: 2.0,
                    coulomb_torque_negative: None,
                    static_torque_negative: None,
                    location: FrictionLocation::Load,
                })
            },
            "friction.stribeck_velocity",
        ),
        (
            |p| {
                p.friction = Some(Friction::MaxwellSlip {
                    presliding_displacement: 0.002,
                    elements: 0,
                    static_torque: None,
                    stribeck_velocity: None,
                    stribeck_exponent: 2.0,
                    coulomb_torque_negative: None,
                    static_torque_negative: None,
                    location: FrictionLocation::Load,
                })
            },
            "friction.elements",
        ),
        (
            |p| {
                p.friction = Some(Friction::MaxwellSlip {
                    presliding_displacement: 1e-9,
                    elements: 4,
                    static_torque: None,
                    stribeck_velocity: None,
                    stribeck_exponent: 2.0,
                    coulomb_torque_negative: None,
                    static_torque_negative: None,
                    location: FrictionLocation::Load,
                })
            },
            "friction.presliding_displacement",
        ),
        (
            |p| {
                p.current_loop = Some(CurrentLoop {
                    order: CurrentLoopOrder::FirstOrder,
                    bandwidth_hz: Some(20_000.0),
                    zeta: None,
                    torque_max: None,
                })
            },
            "current_loop.bandwidth_hz",
        ),
        (
            |p| {
                p.current_loop = Some(CurrentLoop {
                    order: CurrentLoopOrder::FirstOrder,
                    bandwidth_hz: Some(1000.0),
                    zeta: Some(0.7),
                    torque_max: None,
                })
            },
            "current_loop.zeta",
        ),
        (
            |p| {
                p.current_loop = Some(CurrentLoop {
                    order: CurrentLoopOrder::FirstOrder,
                    bandwidth_hz: None,
                    zeta: None,
                    torque_max: Some(-1.0),
                })
            },
            "current_loop.torque_max",
        ),
        (
            |p| {
                p.feedback = Some(Feedback {
                    dead_time_cycles: 500,
                    ..Feedback::default()
                })
            },
            "feedback.dead_time_cycles",
        ),
        (
            |p| {
                p.feedback = Some(Feedback {
                    velocity_filter_hz: Some(12_000.0),
                    ..Feedback::default()
                })
            },
            "feedback.velocity_filter_hz",
        ),
        (
            |p| {
                p.feedback = Some(Feedback {
                    motor_noise_std: 1e-4,
                    ..Feedback::default()
                })
            },
            "feedback.motor_noise_std",
        ),
        (
            |p| {
                p.reference = Some(ReferenceShaping {
                    filter: None,
                    interpolation_delay_s: 1.234e-5,
                })
            },
            "reference.interpolation_delay_s",
        ),
        (
            |p| {
                p.reference = Some(ReferenceShaping {
                    filter: Some(ShapingFilter::MovingAverage { window_s: 0.0 }),
                    interpolation_delay_s: 0.0,
                })
            },
            "reference.filter.window_s",
        ),
        (
            |p| {
                p.reference = Some(ReferenceShaping {
                    filter: Some(ShapingFilter::FirstOrder {
                        time_constant_s: -0.001,
                    }),
                    interpolation_delay_s: 0.0,
                })
            },
            "reference.filter.time_constant_s",
        ),
    ];
    common::assert_rejected_with_key(&cases);
    // Alternatives: both or neither.
    let mut p = table1_drive();
    with_compliance(&mut p);
    if let Some(c) = &mut p.compliance {
        c.mode_hz = Some(100.0);
    }
    assert!(matches!(
        p.validate(),
        Err(Error::Alternatives {
            name: "compliance.stiffness",
            both: true,
            ..
        })
    ));
    if let Some(c) = &mut p.compliance {
        c.mode_hz = None;
        c.damping = None;
    }
    let e = p.validate().unwrap_err();
    assert!(matches!(
        e,
        Error::Alternatives {
            name: "compliance.damping",
            both: false,
            ..
        }
    ));
    assert!(e.to_string().contains("compliance.mode_zeta"), "{e}");
    let msg = {
        let mut p = table1_drive();
        p.feedback = Some(Feedback {
            dead_time_cycles: 500,
            ..Feedback::default()
        });
        p.validate().unwrap_err().to_string()
    };
    assert!(msg.contains("feedback.dead_time_cycles = 500"), "{msg}");
}

#[test]
fn checked_effects_round_trip_through_parameters() {
    let d = common::realistic_table1().validate().unwrap();
    assert!(!d.effects().is_ideal());
    let again = d.params().validate().unwrap();
    assert_eq!(d, again);
    // Another servo rate keeps the effects (the delays are re-checked in ticks).
    let slow = d.with_servo_rate_hz(10_000.0).unwrap();
    assert_eq!(slow.effects().compliance, d.effects().compliance);
    assert_eq!(slow.effects().shaping.unwrap().delay_ticks, 20);
    let r = d.with_servo_rate_hz(4_100.0);
    assert!(matches!(
        r,
        Err(Error::BadParameter {
            name: "reference.interpolation_delay_s" | "reference.filter.window_s",
            ..
        })
    ));
}

#[test]
fn load_tracking_of_a_rigid_drive_is_its_tracking_and_bad_frf_options_are_named() {
    // Truth: on a rigid drive with an ideal encoder and no dead time the measured position is
    // the load position, so the two responses are one.
    let drive = DriveParams {
        encoder: Encoder::ideal(),
        ..table1_drive()
    }
    .validate()
    .unwrap();
    let opts = FrfOptions {
        f_min_hz: 2.0,
        f_max_hz: 200.0,
        lines: 20,
        ..FrfOptions::default()
    };
    let a = drive.measure_frf(&opts).unwrap();
    let b = drive
        .measure_frf(&FrfOptions {
            kind: FrfKind::LoadTracking,
            ..opts.clone()
        })
        .unwrap();
    assert_eq!(a.freq_hz, b.freq_hz);
    for (x, y) in a.response.iter().zip(&b.response) {
        assert!((x - y).norm() < 1e-9, "{x} vs {y}");
    }
    for (bad, key) in [
        (
            FrfOptions {
                resolution_hz: Some(0.3),
                ..opts.clone()
            },
            "frf.resolution_hz",
        ),
        (
            FrfOptions {
                f_max_hz: 15_000.0,
                ..opts.clone()
            },
            "frf.f_max_hz",
        ),
        (
            FrfOptions {
                bias_velocity: 0.0,
                ..opts.clone()
            },
            "frf.bias_velocity",
        ),
        (
            FrfOptions {
                periods: 0,
                ..opts.clone()
            },
            "frf.periods",
        ),
    ] {
        match drive.measure_frf(&bad) {
            Err(Error::BadParameter { name, .. }) => assert_eq!(name, key),
            other => panic!("{key}: {other:?}"),
        }
    }
}
