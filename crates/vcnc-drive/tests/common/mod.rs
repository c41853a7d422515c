//! Reference programs for the drive tests and benches: an identification-like sequence of random
//! rest-to-rest trapezoidal moves, sampled exactly (position, velocity, acceleration) at `ts`.

#![allow(dead_code)]

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Sampled reference: position (mm), velocity (mm/s), acceleration (mm/s²).
pub struct Program {
    pub pos: Vec<f64>,
    pub vel: Vec<f64>,
    pub acc: Vec<f64>,
}

impl Program {
    pub fn reference(&self) -> vcnc_drive::Reference<'_> {
        vcnc_drive::Reference {
            pos: &self.pos,
            vel: &self.vel,
            acc: &self.acc,
        }
    }

    pub fn len(&self) -> usize {
        self.pos.len()
    }
}

/// One rest-to-rest trapezoidal move starting at `t0` from `x0`: accelerate at `a` for `ta`,
/// cruise at `vp` for `tc`, decelerate for `ta`, then dwell until `t0 + ta + tc + ta + dwell`.
struct Move {
    t0: f64,
    x0: f64,
    dir: f64,
    a: f64,
    vp: f64,
    ta: f64,
    tc: f64,
    end: f64,
}

impl Move {
    /// (position, velocity, acceleration) at absolute time t in [t0, end].
    fn eval(&self, t: f64) -> (f64, f64, f64) {
        let tau = t - self.t0;
        let (ta, tc, a, vp) = (self.ta, self.tc, self.a, self.vp);
        let (s, v, acc) = if tau < ta {
            (0.5 * a * tau * tau, a * tau, a)
        } else if tau < ta + tc {
            (0.5 * a * ta * ta + vp * (tau - ta), vp, 0.0)
        } else if tau < 2.0 * ta + tc {
            let d = tau - ta - tc;
            (
                0.5 * a * ta * ta + vp * tc + vp * d - 0.5 * a * d * d,
                vp - a * d,
                -a,
            )
        } else {
            (a * ta * ta + vp * tc, 0.0, 0.0)
        };
        (self.x0 + self.dir * s, self.dir * v, self.dir * acc)
    }
}

/// Random rest-to-rest moves between targets uniform in ±`range` mm, peak speed up to `v_max`,
/// acceleration up to `a_max`, dwell 50–300 ms, for `duration` s, sampled at `ts`. Starts with
/// 0.1 s at rest at `x_start`.
pub fn identification_program(
    seed: u64,
    duration: f64,
    ts: f64,
    x_start: f64,
    range: f64,
    v_max: f64,
    a_max: f64,
) -> Program {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut moves = Vec::new();
    let mut t = 0.1;
    let mut x = x_start;
    while t < duration {
        let target = x_start + range * (2.0 * rng.random::<f64>() - 1.0);
        let vp_max = v_max * (0.1 + 0.9 * rng.random::<f64>());
        let a = a_max * (0.2 + 0.8 * rng.random::<f64>());
        let dwell = 0.05 + 0.25 * rng.random::<f64>();
        let d = (target - x).abs();
        let (vp, ta, tc) = if d * a < vp_max * vp_max {
            let vp = (d * a).sqrt();
            (vp, vp / a, 0.0)
        } else {
            (vp_max, vp_max / a, (d - vp_max * vp_max / a) / vp_max)
        };
        let end = t + 2.0 * ta + tc + dwell;
        moves.push(Move {
            t0: t,
            x0: x,
            dir: (target - x).signum(),
            a,
            vp,
            ta,
            tc,
            end,
        });
        x = target;
        t = end;
    }
    let n = (duration / ts).round() as usize + 1;
    let mut prog = Program {
        pos: Vec::with_capacity(n),
        vel: Vec::with_capacity(n),
        acc: Vec::with_capacity(n),
    };
    let mut m = 0;
    for k in 0..n {
        let t = k as f64 * ts;
        while m < moves.len() && t >= moves[m].end {
            m += 1;
        }
        let (p, v, a) = match moves.get(m) {
            Some(mv) if t >= mv.t0 => mv.eval(t),
            Some(mv) => (mv.x0, 0.0, 0.0),
            None => (x, 0.0, 0.0),
        };
        prog.pos.push(p);
        prog.vel.push(v);
        prog.acc.push(a);
    }
    prog
}

/// The identification-like program of the drive tests: 30 s, ±50 mm, 250 mm/s, 2500 mm/s².
pub fn standard_program() -> Program {
    identification_program(7, 30.0, 1e-3, 0.0, 50.0, 250.0, 2500.0)
}

/// The Table 1 drive with every effect at a value typical of a ball-screw axis of its class
/// (the same kinds of values as machines/nmv5000-realistic.toml's X axis): two-mass screw with a
/// 120 Hz first mode, Stribeck friction with pre-sliding, a 1.5 kHz current loop and torque
/// limit, linear scale with 50 nm noise, one cycle of dead time, a 2 kHz velocity filter, a 4 ms
/// moving-average nominal filter and a 2 ms interpolation delay.
pub fn realistic_table1() -> vcnc_drive::DriveParams {
    use vcnc_drive::{
        Compliance, CurrentLoop, CurrentLoopOrder, Feedback, FeedbackSource, Friction,
        FrictionLocation, ReferenceShaping, ShapingFilter,
    };
    let mut p = vcnc_drive::table1_drive();
    p.encoder.noise_std = 5e-5;
    p.encoder.seed = 3;
    p.compliance = Some(Compliance {
        j_motor: 0.005,
        stiffness: None,
        mode_hz: Some(120.0),
        damping: None,
        mode_zeta: Some(0.05),
        backlash: 0.0,
    });
    p.friction = Some(Friction::MaxwellSlip {
        presliding_displacement: 0.002,
        elements: 4,
        static_torque: Some(0.4),
        stribeck_velocity: Some(2.0),
        stribeck_exponent: 2.0,
        coulomb_torque_negative: Some(0.28),
        static_torque_negative: None,
        location: FrictionLocation::Load,
    });
    p.current_loop = Some(CurrentLoop {
        order: CurrentLoopOrder::FirstOrder,
        bandwidth_hz: Some(1500.0),
        zeta: None,
        torque_max: Some(20.0),
    });
    p.feedback = Some(Feedback {
        source: FeedbackSource::Load,
        dead_time_cycles: 1,
        velocity_filter_hz: Some(2000.0),
        motor_resolution: None,
        motor_noise_std: 0.0,
    });
    p.reference = Some(ReferenceShaping {
        filter: Some(ShapingFilter::MovingAverage { window_s: 0.004 }),
        interpolation_delay_s: 0.002,
    });
    p
}

/// The X axis of machines/nmv5000-realistic.toml, read from the file (its drive keys, as
/// [`machine_drives`] reads them): a two-mass screw (180 Hz first mode), Maxwell-slip Stribeck
/// friction, a 1.5 kHz current loop, a linear scale with 10 nm steps and 20 nm noise, two cycles
/// of dead time, a 1 kHz velocity filter, a 2 ms moving-average nominal filter and a 2 ms
/// interpolation delay.
pub fn realistic_nmv5000_x() -> vcnc_drive::DriveParams {
    machine_drives("nmv5000-realistic.toml")
        .into_iter()
        .find(|(a, _)| a == "X")
        .map(|(_, p)| p)
        .expect("the realistic NMV5000 has an X axis")
}

/// The drives of a machine file of the repository (`machines/<name>`), X, Y, Z, A, C as the
/// file holds them: each `[axes.*]` table's drive keys (plant, controller, encoder, servo rate
/// and the effect tables) read as [`vcnc_drive::DriveParams`]; the machine-level keys (unit,
/// travel, limits, identification range) are not the drive's and are left out.
pub fn machine_drives(name: &str) -> Vec<(String, vcnc_drive::DriveParams)> {
    let axes = machine_axes(name);
    assert_eq!(
        axes.iter().map(|(a, _)| a.as_str()).collect::<Vec<_>>(),
        ["X", "Y", "Z", "A", "C"],
        "{name}: the five NMV5000 axes"
    );
    axes
}

/// The drives of every axis a machine file of the repository holds (X, Y, Z, A, B, C, those
/// present), read as [`machine_drives`] reads them.
pub fn machine_axes(name: &str) -> Vec<(String, vcnc_drive::DriveParams)> {
    const DRIVE_KEYS: [&str; 9] = [
        "plant",
        "controller",
        "encoder",
        "servo_rate_hz",
        "compliance",
        "friction",
        "current_loop",
        "feedback",
        "reference",
    ];
    let path = format!("{}/../../machines/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).expect("machine file is readable");
    let file: toml::Table = text.parse().expect("machine file is TOML");
    let axes = file["axes"].as_table().expect("[axes]");
    ["X", "Y", "Z", "A", "B", "C"]
        .iter()
        .filter(|a| axes.contains_key(**a))
        .map(|a| {
            let mut t = axes[*a].as_table().expect("axis table").clone();
            t.retain(|k, _| DRIVE_KEYS.contains(&k));
            let p: vcnc_drive::DriveParams = t.try_into().expect("drive keys parse");
            (a.to_string(), p)
        })
        .collect()
}

use vcnc_drive::{
    Compliance, ControllerSpec, CurrentLoop, CurrentLoopOrder, DriveParams, DriveTrace, Feedback,
    FeedbackSource, Friction, FrictionLocation, PoleDesign, Reference, ReferenceShaping,
    ShapingFilter,
};

/// The Table 1 poles (docs/reference-numbers.md, from [`vcnc_drive::table1_drive`]'s gains) as a
/// design, for the PID and SMC drives that share them.
pub fn table1_design() -> PoleDesign {
    let poles = vcnc_drive::table1_drive()
        .closed_loop_model()
        .unwrap()
        .poles()
        .unwrap();
    PoleDesign {
        p_hz: poles.p_hz(),
        wn_hz: poles.wn_hz(),
        zeta: poles.zeta,
    }
}

/// `p` with a PID law designed for the Table 1 poles, $B_{ff} = 0.1$ and the given $J_{ff}$.
pub fn pid(p: DriveParams, jff: f64) -> DriveParams {
    DriveParams {
        controller: ControllerSpec::Pid {
            kp: None,
            ki: None,
            kd: None,
            design: Some(table1_design()),
            jff,
            bff: 0.1,
        },
        ..p
    }
}

/// `p` with an SMC law designed for the Table 1 poles, with exact estimates.
pub fn smc(p: DriveParams) -> DriveParams {
    DriveParams {
        controller: ControllerSpec::Smc {
            lambda: None,
            ks: None,
            rho: None,
            je_hat: None,
            be_hat: None,
            design: Some(table1_design()),
        },
        ..p
    }
}

/// [`realistic_table1`] and three variants for the other paths of the effects engine, in this
/// order: the realistic drive; PID (with `pid_jff`) with a second-order shaping filter and a
/// torque limit low enough to saturate; SMC with a first-order filter and semi-closed feedback;
/// a rigid P-PI with set-valued Stribeck friction and no dead time (one reading for both loops).
pub fn realistic_table1_variants(pid_jff: f64) -> [DriveParams; 4] {
    let base = realistic_table1();
    let mut v1 = pid(base.clone(), pid_jff);
    if let Some(s) = v1.reference.as_mut() {
        s.filter = Some(ShapingFilter::SecondOrder {
            time_constant_s: 0.002,
            zeta: 0.7,
        });
    }
    if let Some(c) = v1.current_loop.as_mut() {
        c.torque_max = Some(0.6);
    }
    let mut v2 = smc(base.clone());
    if let Some(s) = v2.reference.as_mut() {
        s.filter = Some(ShapingFilter::FirstOrder {
            time_constant_s: 0.003,
        });
    }
    if let Some(f) = v2.feedback.as_mut() {
        f.source = FeedbackSource::Motor;
    }
    let mut v3 = base.clone();
    v3.compliance = None;
    v3.feedback = None;
    v3.friction = Some(Friction::Stribeck {
        static_torque: 0.4,
        stribeck_velocity: 2.0,
        stribeck_exponent: 2.0,
        coulomb_torque_negative: None,
        static_torque_negative: None,
        location: FrictionLocation::Load,
    });
    [base, v1, v2, v3]
}

/// Variants of the realistic drives for the SIMD lanes, in this order: [`realistic_nmv5000_x`]
/// with backlash (a lane in the gap while the others are in contact), with another seed and
/// noise, with 7 Maxwell-slip elements and 5 cycles of dead time; [`realistic_table1`] with a
/// tight torque limit (saturation in some lanes) and a motor encoder of 10 nm steps.
pub fn realistic_lane_variants() -> [DriveParams; 4] {
    let x = realistic_nmv5000_x();
    let mut with_backlash = x.clone();
    with_backlash.compliance.as_mut().unwrap().backlash = 0.004;
    let mut other_noise = x.clone();
    other_noise.encoder.seed = 99;
    other_noise.encoder.noise_std = 1e-4;
    let mut slow = x;
    if let Some(Friction::MaxwellSlip { elements, .. }) = slow.friction.as_mut() {
        *elements = 7;
    }
    slow.feedback.as_mut().unwrap().dead_time_cycles = 5;
    slow.feedback.as_mut().unwrap().motor_noise_std = 3e-5;
    let mut limited = realistic_table1();
    limited.current_loop.as_mut().unwrap().torque_max = Some(1.5);
    limited.feedback.as_mut().unwrap().motor_resolution = Some(1e-5);
    [with_backlash, other_noise, slow, limited]
}

/// The trace of the drive `p` following `pos`, `vel`, `acc` (axis units, /s, /s²) at period
/// `ts`, s; a test failure when `p` is invalid or the run fails.
pub fn simulate(p: &DriveParams, pos: &[f64], vel: &[f64], acc: &[f64], ts: f64) -> DriveTrace {
    p.validate()
        .expect("a valid drive")
        .simulate(Reference { pos, vel, acc }, ts)
        .expect("the run succeeds")
}

/// The samples `p` of the reference `r`: a piece to feed a stream.
pub fn slice<'a>(r: Reference<'a>, p: &std::ops::Range<usize>) -> Reference<'a> {
    Reference {
        pos: &r.pos[p.clone()],
        vel: &r.vel[p.clone()],
        acc: &r.acc[p.clone()],
    }
}

/// A change made to a drive's parameters.
pub type Mutation = fn(&mut DriveParams);

/// Each case mutates the Table 1 drive so that its validation must fail with
/// `Error::BadParameter` naming the case's key.
pub fn assert_rejected_with_key(cases: &[(Mutation, &str)]) {
    for (mutate, key) in cases {
        let mut p = vcnc_drive::table1_drive();
        mutate(&mut p);
        match p.validate() {
            Err(vcnc_drive::Error::BadParameter { name, .. }) => assert_eq!(name, *key),
            other => panic!("{key}: expected BadParameter, got {other:?}"),
        }
    }
}

/// The largest absolute difference between two series of equal length.
pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// The Table 1 drive as a P-P cascade: $K_v$ and $K_p$ of Table 1, $K_i = 0$, no feed-forward,
/// an ideal encoder. A constant position error $\delta$ gives the constant torque
/// $K_p K_v \delta$.
pub fn p_p_cascade() -> DriveParams {
    DriveParams {
        controller: ControllerSpec::PPi {
            kv: Some(70.0),
            kp: Some(2.342478),
            ki: Some(0.0),
            design: None,
            vff: 0.0,
            bff: 0.0,
            jff: 0.0,
        },
        encoder: vcnc_drive::Encoder::ideal(),
        ..vcnc_drive::table1_drive()
    }
}

/// A random drive of a random structure: which effects it has and how its loop is built are
/// drawn from `structure`'s generator, its numbers from `numbers`'s.
pub fn random_drive(structure: &mut ChaCha8Rng, numbers: &mut ChaCha8Rng) -> DriveParams {
    let s = structure;
    let n = numbers;
    let mut p = vcnc_drive::table1_drive();
    let scale = |n: &mut ChaCha8Rng, v: f64| v * n.random_range(0.7..1.3);
    p.plant.j = scale(n, p.plant.j);
    p.plant.b = scale(n, p.plant.b);
    p.plant.coulomb_torque = scale(n, 0.3);
    p.encoder.seed = n.random_range(0..1000);
    p.encoder.noise_std = if s.random_bool(0.7) {
        scale(n, 5e-5)
    } else {
        0.0
    };
    p.encoder.resolution = if s.random_bool(0.8) { 1e-4 } else { 0.0 };
    if s.random_bool(0.3) {
        p.plant.u_max = Some(scale(n, 6.0));
    }
    let design = PoleDesign {
        p_hz: scale(n, 10.0),
        wn_hz: scale(n, 30.0),
        zeta: n.random_range(0.4..0.8),
    };
    p.controller = match s.random_range(0..3) {
        0 => ControllerSpec::PPi {
            kv: None,
            kp: None,
            ki: None,
            design: Some(design),
            vff: n.random_range(0.0..1.0),
            bff: n.random_range(0.0..1.0),
            jff: n.random_range(0.0..1.0),
        },
        1 => ControllerSpec::Pid {
            kp: None,
            ki: None,
            kd: None,
            design: Some(design),
            jff: n.random_range(0.0..1.0),
            bff: n.random_range(0.0..1.0),
        },
        _ => ControllerSpec::Smc {
            lambda: None,
            ks: None,
            rho: None,
            je_hat: None,
            be_hat: None,
            design: Some(design),
        },
    };
    let two_mass = s.random_bool(0.6);
    if two_mass {
        p.compliance = Some(Compliance {
            j_motor: p.plant.j * n.random_range(0.3..0.7),
            stiffness: None,
            mode_hz: Some(scale(n, 150.0)),
            damping: None,
            mode_zeta: Some(n.random_range(0.02..0.1)),
            // Backlash in some lanes only (a per-lane number).
            backlash: if n.random_bool(0.5) {
                scale(n, 3e-3)
            } else {
                0.0
            },
        });
    }
    let location = if two_mass && s.random_bool(0.3) {
        FrictionLocation::Motor
    } else {
        FrictionLocation::Load
    };
    p.friction = match s.random_range(0..4) {
        0 => None,
        1 => Some(Friction::Coulomb {
            coulomb_torque_negative: Some(scale(n, 0.25)),
            location,
        }),
        2 => Some(Friction::Stribeck {
            static_torque: scale(n, 0.45),
            stribeck_velocity: scale(n, 2.0),
            stribeck_exponent: n.random_range(0.5..3.0),
            coulomb_torque_negative: None,
            static_torque_negative: None,
            location,
        }),
        _ => Some(Friction::MaxwellSlip {
            presliding_displacement: scale(n, 2e-3),
            elements: n.random_range(1..7),
            static_torque: if n.random_bool(0.7) {
                Some(scale(n, 0.45))
            } else {
                None
            },
            stribeck_velocity: Some(scale(n, 2.0)),
            stribeck_exponent: if n.random_bool(0.5) {
                2.0
            } else {
                n.random_range(0.5..3.0)
            },
            coulomb_torque_negative: Some(scale(n, 0.25)),
            static_torque_negative: None,
            location,
        }),
    };
    if s.random_bool(0.6) {
        let order = if s.random_bool(0.5) {
            CurrentLoopOrder::FirstOrder
        } else {
            CurrentLoopOrder::SecondOrder
        };
        p.current_loop = Some(CurrentLoop {
            order,
            bandwidth_hz: Some(scale(n, 1500.0)),
            zeta: (order == CurrentLoopOrder::SecondOrder).then(|| n.random_range(0.5..1.0)),
            // Tight in some lanes: saturation.
            torque_max: n.random_bool(0.5).then(|| scale(n, 3.0)),
        });
    } else if s.random_bool(0.3) {
        p.current_loop = Some(CurrentLoop {
            order: CurrentLoopOrder::FirstOrder,
            bandwidth_hz: None,
            zeta: None,
            torque_max: Some(scale(n, 3.0)),
        });
    }
    if s.random_bool(0.7) {
        let source = if two_mass && s.random_bool(0.3) {
            FeedbackSource::Motor
        } else {
            FeedbackSource::Load
        };
        let delayed = s.random_bool(0.6);
        p.feedback = Some(Feedback {
            source,
            dead_time_cycles: if delayed { n.random_range(1..4) } else { 0 },
            velocity_filter_hz: n.random_bool(0.7).then(|| scale(n, 1500.0)),
            motor_resolution: (two_mass && source == FeedbackSource::Load)
                .then(|| if n.random_bool(0.7) { 1e-5 } else { 0.0 }),
            motor_noise_std: if two_mass && source == FeedbackSource::Load && n.random_bool(0.5) {
                scale(n, 2e-5)
            } else {
                0.0
            },
        });
    }
    // Reference shaping: a per-lane choice (the shaper runs per lane).
    if n.random_bool(0.7) {
        let filter = match n.random_range(0..4) {
            0 => None,
            1 => Some(ShapingFilter::FirstOrder {
                time_constant_s: scale(n, 2e-3),
            }),
            2 => Some(ShapingFilter::SecondOrder {
                time_constant_s: scale(n, 2e-3),
                zeta: n.random_range(0.4..1.2),
            }),
            _ => Some(ShapingFilter::MovingAverage {
                window_s: n.random_range(1..80) as f64 * 5e-5,
            }),
        };
        p.reference = Some(ReferenceShaping {
            filter,
            interpolation_delay_s: n.random_range(0..40) as f64 * 5e-5,
        });
    }
    p
}
