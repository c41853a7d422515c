//! Acceptance figures of issue 4 against independent truth: the analytic closed-loop model of
//! the drive parameters (`DriveParams::closed_loop_model`, docs/drive-model.md), identified from
//! traces of the true drive simulator of `vcnc-drive` (plant with Coulomb friction and sticking,
//! controller at the 20 kHz servo rate, quantised encoder) driven by the paper's identification
//! program (section 4: 70 random moves within ±50 mm, feeds up to 250 mm/s, 2500 mm/s², 1 ms) as
//! `vcnc-gcode` generates and interpolates it; validation runs use another seed.
//! Run with `--nocapture` to see the comparison table (paper PSO alone vs refined).

mod support;

use support::*;
use vcnc_drive::{AxisName, ClosedLoopModel, ControllerSpec, DriveParams, PoleDesign};
use vcnc_identify::*;

struct Case {
    truth: ClosedLoopModel,
    id: Identification,
    /// Fit of the identified model on a validation run (another seed of the program).
    val: FitMetrics,
    val_truth: FitMetrics,
}

fn run_case(name: &str, params: &DriveParams, axis: AxisName, seed: u64) -> Case {
    let truth = params.closed_loop_model().expect("valid drive");
    let est = drive_trace(params, &gcode_program(axis, seed, 2500.0));
    let val = drive_trace(params, &gcode_program(axis, seed + 1000, 2500.0));
    let opts = IdentifyOptions::default();
    let id = identify(&est, &opts).expect("identifies");
    println!(
        "== {name} (N = {}, peak tracking error {:.1} µm)",
        est.len(),
        1e3 * est.tracking_peak()
    );
    compare("paper PSO", &id.paper_pso, &truth);
    compare("identified (refined)", &id.identified, &truth);
    let ls = &id.unconstrained_ls;
    println!(
        "{:>22}: stable {} poles {:?}",
        "unconstrained LS",
        ls.stable,
        ls.poles.map(|p| (p.p_hz(), p.wn_hz(), p.zeta))
    );
    let val_fit = fit_metrics(&id.identified, &val, &opts).expect("fit");
    let val_truth = fit_metrics(&truth, &val, &opts).expect("fit");
    println!(
        "{:>22}: free-run RMS {:.3} µm, max {:.3} µm ({:.2} % of peak {:.1} µm), fit {:.3} %; true model max {:.3} µm",
        "validation",
        1e3 * val_fit.freerun_rms,
        1e3 * val_fit.freerun_max,
        100.0 * val_fit.freerun_max / val_fit.tracking_peak,
        1e3 * val_fit.tracking_peak,
        val_fit.fit_percent,
        1e3 * val_truth.freerun_max
    );
    Case {
        truth,
        id,
        val: val_fit,
        val_truth,
    }
}

/// Relative errors (p, ωn, ζ, dc) of a model.
fn errors(m: &ClosedLoopModel, truth: &ClosedLoopModel) -> [f64; 4] {
    let (pe, pt) = (m.poles().expect("poles"), truth.poles().expect("poles"));
    [
        rel(pe.p, pt.p).abs(),
        rel(pe.wn, pt.wn).abs(),
        rel(pe.zeta, pt.zeta).abs(),
        rel(m.dc, truth.dc).abs(),
    ]
}

fn assert_within(name: &str, m: &ClosedLoopModel, truth: &ClosedLoopModel, tol: [f64; 4]) {
    let e = errors(m, truth);
    let names = ["p", "wn", "zeta", "dc"];
    for i in 0..4 {
        assert!(
            e[i] <= tol[i],
            "{name}: {} off by {:.2} % (allowed {:.1} %)",
            names[i],
            100.0 * e[i],
            100.0 * tol[i]
        );
    }
}

/// [`run_case`] on axis X, its identified poles and $d_c$ within `tol` of the truth
/// ([`assert_within`]).
fn case_within(name: &str, params: &DriveParams, seed: u64, tol: [f64; 4]) -> Case {
    let c = run_case(name, params, AxisName::X, seed);
    assert_within(name, &c.id.identified, &c.truth, tol);
    c
}

#[test]
fn table1_drive_fine_encoder_poles_within_1_percent() {
    // Issue 4: 0.1 µm encoder → ωn, p within 1 %, ζ within 3 %, dc within 5 %.
    let params = vcnc_drive::table1_drive();
    assert_eq!(params.encoder.resolution, 1e-4);
    let c = case_within("Table 1, 0.1 µm", &params, 7, [0.01, 0.01, 0.03, 0.05]);
    assert!(c.id.identified.is_stable() && c.id.paper_pso.is_stable());
    // Against the published values (docs/reference-numbers.md) as well (the truth itself).
    let pt = c.truth.poles().expect("poles");
    assert!((pt.wn_hz() - 30.569).abs() < 1e-3 && (pt.p_hz() - 10.7296).abs() < 1e-3);
    // The validation run is predicted within 1 % of its peak tracking error (paper: 5 %).
    assert!(c.val.freerun_max <= 0.01 * c.val.tracking_peak);
}

#[test]
fn table1_drive_coarse_encoder_poles_within_2_percent() {
    // Issue 4: 1 µm encoder → ωn, p within 2 %, ζ within 5 %, dc within 10 %.
    let mut params = vcnc_drive::table1_drive();
    params.encoder.resolution = 1e-3;
    // Program seed 7, and a second seed to make sure the first is not a lucky draw.
    for seed in [7, 3] {
        case_within("Table 1, 1 µm", &params, seed, [0.02, 0.02, 0.05, 0.10]);
    }
}

#[test]
fn nmv5000_axes_poles_within_2_percent() {
    // Issue 4: every NMV5000 axis (the paper's Table 3 poles, docs/reference-numbers.md, P-PI designed with the larger Kv rg
    // root, B/J = 4.19) → ωn and p within 2 %, ζ within 5 %.
    for (axis, seed) in [
        (AxisName::X, 11),
        (AxisName::Y, 12),
        (AxisName::Z, 13),
        (AxisName::A, 14),
        (AxisName::C, 15),
    ] {
        let params = vcnc_drive::nmv5000_axis_design(axis).expect("design");
        let c = run_case(&format!("NMV5000 {axis}"), &params, axis, seed);
        let e = errors(&c.id.identified, &c.truth);
        assert!(
            e[0] <= 0.02 && e[1] <= 0.02 && e[2] <= 0.05,
            "axis {axis}: {e:?}"
        );
        assert!(c.id.identified.is_stable());
        assert!(
            c.val.freerun_max <= 0.01 * c.val.tracking_peak,
            "axis {axis}: {:?}",
            c.val
        );
    }
}

fn table1_poles() -> PoleDesign {
    PoleDesign {
        p_hz: 10.7296,
        wn_hz: 30.569,
        zeta: 0.44519,
    }
}

#[test]
fn pid_drive_predicted_within_2_percent_of_peak() {
    // Issue 4: PID on the Table 1 plant with the Table 1 poles → stable, validation free run
    // within 2 % of its peak tracking error.
    let mut params = vcnc_drive::table1_drive();
    params.controller = ControllerSpec::Pid {
        kp: None,
        ki: None,
        kd: None,
        design: Some(table1_poles()),
        jff: 0.0,
        bff: 0.1,
    };
    let c = run_case("PID", &params, AxisName::X, 5);
    assert!(c.id.identified.is_stable());
    assert!(
        c.val.freerun_max <= 0.02 * c.val.tracking_peak,
        "{:?}",
        c.val
    );
}

#[test]
fn sliding_mode_drives_are_stable_and_predicted_as_well_as_the_true_model() {
    // Sliding mode (docs/drive-model.md) on the Table 1 plant with the Table 1 poles. Issue 4 asks
    // for a free-run prediction within 2 % of the validation run's peak tracking error. For
    // SMC that is out of reach of the model class itself: the tracking error is mostly friction
    // (with exact estimates every pole is cancelled by a zero, G_track = 1, peak about 6 µm),
    // and even the true model's free run misses the 20 kHz plant's sticking by 0.6–1.5 µm at
    // single reversals. So the test asks: stable, and a prediction error no worse than the true
    // model's own (plus 0.1 µm), or within 2 % of the peak, whichever is larger.
    let check = |name: &str, params: &DriveParams| {
        let c = run_case(name, params, AxisName::X, 5);
        assert!(
            c.id.identified.is_stable() && c.id.paper_pso.is_stable(),
            "{name}"
        );
        let allowed = (0.02 * c.val.tracking_peak).max(c.val_truth.freerun_max + 1e-4);
        assert!(
            c.val.freerun_max <= allowed,
            "{name}: {:?} vs truth {:?}",
            c.val,
            c.val_truth
        );
        // The RMS error is a small fraction of the peak either way.
        assert!(
            c.val.freerun_rms <= 0.02 * c.val.tracking_peak,
            "{name}: {:?}",
            c.val
        );
    };
    // Exact estimates: the machine file's ballscrew-smc.toml drive.
    let mut exact = vcnc_drive::table1_drive();
    exact.controller = ControllerSpec::Smc {
        lambda: None,
        ks: None,
        rho: None,
        je_hat: None,
        be_hat: None,
        design: Some(table1_poles()),
    };
    check("SMC, exact estimates", &exact);
    // Detuned estimates (Ĵe = Je/2, no viscous compensation): about 50 µm of tracking error,
    // the order of the paper's SMC experiment (40 µm).
    let je = vcnc_drive::table1_drive().plant.je();
    let poles = vcnc_drive::Poles::from_hz(10.7296, 30.569, 0.44519);
    let mut detuned = vcnc_drive::table1_drive();
    detuned.controller = ControllerSpec::Smc {
        lambda: Some(poles.p),
        ks: Some(2.0 * poles.zeta * poles.wn * je),
        rho: Some(poles.wn * poles.wn * je),
        je_hat: Some(0.5 * je),
        be_hat: Some(0.0),
        design: None,
    };
    check("SMC, detuned estimates", &detuned);
}

/// The EMPS benchmark's estimation data (Janot, Gautier, Brunot, "Data Set and Reference Models
/// of EMPS", Nonlinear System Identification Benchmarks 2019), converted from metres to mm.
fn emps() -> Trace {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tests/data/emps/DATA_EMPS.csv"
    );
    let text = std::fs::read_to_string(path).expect("EMPS data");
    let (mut t, mut xr, mut x) = (vec![], vec![], vec![]);
    for line in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
        let c: Vec<f64> = line
            .split(',')
            .map(|v| v.trim().parse().expect("number"))
            .collect();
        t.push(c[0]);
        xr.push(c[1] * 1e3);
        x.push(c[2] * 1e3);
    }
    Trace::from_columns(&t, &xr, &x).expect("valid trace")
}

/// The EMPS benchmark's physical model mapped onto the 7 parameters
/// (docs/reference-numbers.md): a drive without integral action.
const EMPS_PHYSICAL: ClosedLoopModel = ClosedLoopModel {
    a1: 92.11,
    a2: 14412.2,
    a3: 0.0,
    b0: 0.0,
    b1: 0.0,
    b2: 14412.2,
    dc: 214.4,
};

#[test]
fn emps_real_drive_free_run_within_3_um() {
    // Real ball-screw drive without integral action (a3 = 0), not starting at rest. Truth:
    // the measured position. The benchmark's physical model, mapped onto the 7 parameters
    // (docs/reference-numbers.md), gives 3.15 µm RMS by the same simulation: a cross-check of
    // the simulation convention (the state at the moving start estimated, with the constant
    // position offset that a model without integral action carries as its third state; 3.99 µm
    // before that state existed).
    let tr = emps();
    assert!(!tr.starts_at_rest(1.5));
    assert!(
        (tr.tracking_rms() - 0.578).abs() < 0.001,
        "raw tracking error {}",
        tr.tracking_rms()
    );
    let opts = IdentifyOptions {
        bounds: PoleBounds {
            p_hz: [0.0, 500.0],
            ..Default::default()
        },
        ..Default::default()
    };
    let physical = EMPS_PHYSICAL;
    let fp = fit_metrics(&physical, &tr, &opts).expect("fit");
    assert!(
        (fp.freerun_rms - 3.15e-3).abs() < 0.1e-3,
        "physical model {} µm",
        1e3 * fp.freerun_rms
    );
    let id = identify(&tr, &opts).expect("identifies");
    let f = &id.fit_estimation;
    println!(
        "EMPS: identified {:?}\n  poles {:?}; free-run RMS {:.3} µm, max {:.3} µm, fit {:.2} %; paper PSO {:.3} µm; physical model {:.3} µm",
        id.identified,
        id.identified_poles,
        1e3 * f.freerun_rms,
        1e3 * f.freerun_max,
        f.fit_percent,
        1e3 * id.fit_estimation_paper.freerun_rms,
        1e3 * fp.freerun_rms
    );
    println!(
        "  unconstrained LS: stable {} poles {:?}",
        id.unconstrained_ls.stable, id.unconstrained_ls.poles
    );
    println!(
        "  condition numbers {:e} / phi2 {:e}",
        id.condition_number, id.condition_phi2
    );
    assert!(id.moving_start);
    assert!(id.identified.is_marginally_stable());
    assert!(
        id.identified_poles.p >= 0.0
            && id.identified_poles.wn > 0.0
            && id.identified_poles.zeta > 0.0
    );
    assert!(
        f.freerun_rms <= 3e-3,
        "free-run RMS {} µm",
        1e3 * f.freerun_rms
    );
    // The unconstrained baseline is unstable on these data (docs/reference-numbers.md): shown, not hidden.
    assert!(!id.unconstrained_ls.stable);
}

#[test]
fn same_seed_gives_identical_bits_on_one_and_two_threads() {
    let params = vcnc_drive::table1_drive();
    let tr = drive_trace(
        &params,
        &identification_program(21, 25, 50.0, 250.0, 2500.0, 1e-3),
    );
    let opts = IdentifyOptions {
        seed: 99,
        ..Default::default()
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| identify(&tr, &opts).expect("identifies"))
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a, b);
    // Debug prints every f64 with a round-trip representation: equal strings, equal bits.
    assert_eq!(format!("{a:?}"), format!("{b:?}"));
}

#[test]
fn data_that_cannot_identify_the_model_is_rejected_with_its_condition_number() {
    // A pure sine excites one frequency: x_r and its second difference are collinear, so the
    // seven parameters cannot be separated.
    let n = 3000;
    let ts = 1e-3;
    let w = std::f64::consts::TAU * 2.0;
    let xr: Vec<f64> = (0..n).map(|k| 10.0 * (w * k as f64 * ts).sin()).collect();
    let x: Vec<f64> = (0..n)
        .map(|k| 9.0 * (w * k as f64 * ts - 0.1).sin())
        .collect();
    let tr = Trace::new(ts, xr, x).expect("valid trace");
    match identify(&tr, &IdentifyOptions::default()) {
        Err(Error::IllConditioned { condition, limit }) => assert!(condition > limit),
        Ok(id) => panic!(
            "expected IllConditioned, got condition {:e}",
            id.condition_number
        ),
        Err(e) => panic!("expected IllConditioned, got {e}"),
    }
}

#[test]
fn invalid_options_are_rejected_before_any_work() {
    let tr = drive_trace(
        &vcnc_drive::table1_drive(),
        &identification_program(1, 5, 20.0, 100.0, 2500.0, 1e-3),
    );
    let mut opts = IdentifyOptions::default();
    opts.pso.w = 1.2;
    assert!(matches!(
        identify(&tr, &opts),
        Err(Error::PsoDivergent { .. })
    ));
    // A negative pole, and an upper bound far beyond any servo loop, which would overflow the
    // discretisation (fuzz finding 1 in fuzz/README.md): refused up front.
    let negative = PoleBounds {
        p_hz: [-1.0, 500.0],
        ..Default::default()
    };
    let huge = PoleBounds {
        wn_hz: [1.0, 1e300],
        ..Default::default()
    };
    for (bounds, key) in [(negative, "bounds.p_hz"), (huge, "bounds.wn_hz")] {
        let opts = IdentifyOptions {
            bounds,
            ..Default::default()
        };
        assert!(
            matches!(
                identify(&tr, &opts),
                Err(Error::InvalidBounds { name, .. }) if name == key
            ),
            "{key}"
        );
    }
    let opts = IdentifyOptions {
        prefilter: Prefilter {
            enabled: true,
            cutoff_hz: Some(800.0),
        },
        ..Default::default()
    };
    assert!(matches!(
        identify(&tr, &opts),
        Err(Error::InvalidOption {
            name: "prefilter.cutoff_hz",
            ..
        })
    ));
}

#[test]
fn emps_held_out_part_is_predicted_better_than_the_published_physical_model() {
    // Out of sample on real data: identify on the first 70 % of the EMPS trace, run the model
    // free through the whole trace and score the last 30 % only (`score` with a range). Truth:
    // the measured position; reference: the benchmark's published physical model mapped onto
    // the seven parameters (docs/reference-numbers.md), scored the same way.
    let tr = emps();
    let n = tr.len();
    let split = n * 7 / 10;
    let head = Trace::new(tr.ts, tr.xr[..split].to_vec(), tr.x[..split].to_vec()).expect("head");
    let opts = IdentifyOptions {
        bounds: PoleBounds {
            p_hz: [0.0, 500.0],
            ..Default::default()
        },
        ..Default::default()
    };
    let id = identify(&head, &opts).expect("identifies");
    let physical = vcnc_drive::DriveModel::from(EMPS_PHYSICAL);
    let held = score(&id.model, &tr, Some(split..n), &opts).expect("score");
    let held_phys = score(&physical, &tr, Some(split..n), &opts).expect("score");
    println!(
        "EMPS held-out 30 %: identified {:.3} µm RMS (max {:.3}), physical model {:.3} µm; uncertainty {:?}",
        1e3 * held.freerun_rms,
        1e3 * held.freerun_max,
        1e3 * held_phys.freerun_rms,
        id.uncertainty
    );
    assert!(held.freerun_rms < held_phys.freerun_rms);
}

#[test]
fn a_drive_without_integral_action_gets_the_structure_without_it() {
    // Truth: the analytic closed loop of the Table 1 plant under a P-P cascade (the Table 1
    // gains with K_i = 0: a3 = 0, b2 = a2, docs/drive-model.md), simulated by the true drive
    // (20 kHz controller, Coulomb friction with sticking, encoder). With every structure tried
    // as `vcnc identify --trace` does, the structure without integral action is chosen, with
    // no parameter on a bound, and recovers ωn and ζ; on the Table 1 P-PI drive (which has
    // integral action) it is not chosen.
    let mut pp = vcnc_drive::table1_drive();
    match &mut pp.controller {
        ControllerSpec::PPi { ki, .. } => *ki = Some(0.0),
        other => panic!("Table 1 is a P-PI drive: {other:?}"),
    }
    let truth = pp.closed_loop_model().expect("valid drive");
    assert_eq!(truth.a3, 0.0);
    let opts = command_options();
    let est = drive_trace(&pp, &gcode_program(AxisName::X, 7, 2500.0));
    let id = identify(&est, &opts).expect("identifies");
    let (pe, pt) = (
        id.model.core.poles().expect("poles"),
        truth.poles().expect("poles"),
    );
    let (e_wn, e_zeta) = (rel(pe.wn, pt.wn), rel(pe.zeta, pt.zeta));
    println!(
        "P-P drive: chosen {} ({}), wn {:.4} Hz ({:+.3} %), zeta {:.4} ({:+.3} %), truth {:.4} Hz / {:.4}",
        id.structure,
        id.input,
        pe.wn_hz(),
        100.0 * e_wn,
        pe.zeta,
        100.0 * e_zeta,
        pt.wn_hz(),
        pt.zeta
    );
    for s in &id.structures {
        println!(
            "  {:>20} {:>6}: held-out {:?} µm, {:?}",
            s.structure.name(),
            s.input.name(),
            s.validation.as_ref().map(|v| 1e3 * v.freerun_rms),
            s.verdict
        );
    }
    assert_eq!(id.structure, ModelStructure::NoIntegral);
    assert_eq!(id.model.core.a3, 0.0);
    assert_eq!(id.model.core.b2, id.model.core.a2);
    assert!(id.on_bounds.is_empty(), "{:?}", id.on_bounds);
    assert!(
        e_wn.abs() < WN_TOL && e_zeta.abs() < ZETA_TOL,
        "{e_wn} {e_zeta}"
    );

    let ppi = vcnc_drive::table1_drive();
    let est = drive_trace(&ppi, &gcode_program(AxisName::X, 7, 2500.0));
    let id = identify(&est, &opts).expect("identifies");
    println!("P-PI drive: chosen {} ({})", id.structure, id.input);
    assert_ne!(id.structure, ModelStructure::NoIntegral);
}

/// Tolerances of the P-P drive's ωn and ζ: about twice the errors measured when the structure
/// came (ωn +0.31 %, most of it the 20 kHz sampling's pole shift against the continuous truth,
/// docs/drive-model.md; ζ −0.01 %, floored at 0.5 %; see the test's printout).
const WN_TOL: f64 = 0.006;
const ZETA_TOL: f64 = 0.005;
