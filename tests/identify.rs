//! Identification end to end (issue 4): simulated drives against the analytic truth of their
//! physical parameters (`DriveParams` → closed-loop model, docs/drive-model.md), and the real EMPS
//! trace against docs/reference-numbers.md's published figures.

use std::path::Path;

use serde_json::Value;

use crate::util::{json, num, ok, repo, tempdir, text, vcnc};

fn identify(machine: &Path, out: &Path, extra: &[&str]) -> Value {
    let mut args = vec![
        "identify",
        machine.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let stdout = ok(&vcnc(&args));
    eprintln!("{stdout}");
    json(&out.join("summary.json"))
}

/// |identified − true| / true for `key` of axis `axis`.
fn rel(s: &Value, axis: &str, key: &str) -> f64 {
    let a = num(s, &format!("axes.{axis}.identified.{key}"));
    let t = num(s, &format!("axes.{axis}.true.{key}"));
    (a - t).abs() / t.abs()
}

#[test]
fn table1_drive_with_0_1um_encoder() {
    // About twice the README's published errors (p 0.03 %, ωn 0.27 %, ζ 0.21 %, dc 0.28 %;
    // issue 4 asked for 1 %, 1 %, 3 %, 5 %; the paper: 2.4 %, 12 %, 6 %, dc 220× off).
    let dir = tempdir();
    let s = identify(&repo("machines/ballscrew-ppi.toml"), dir.path(), &[]);
    let (wn, p, z, dc) = (
        rel(&s, "X", "wn_hz"),
        rel(&s, "X", "p_hz"),
        rel(&s, "X", "zeta"),
        rel(&s, "X", "dc"),
    );
    eprintln!("0.1 µm: wn {wn:.4}, p {p:.4}, zeta {z:.4}, dc {dc:.4}");
    assert!(
        wn < 0.006 && p < 0.0006 && z < 0.005 && dc < 0.006,
        "wn {wn} p {p} zeta {z} dc {dc}"
    );
    assert_eq!(s["axes"]["X"]["identified"]["stable"], Value::Bool(true));
    // The model file is readable by --model and predicts the true drive on another program: the
    // identification excitation with seed 3 (the estimation run uses seed 1, the validation
    // run seed 2). Truth: the true drive simulated on the same program.
    let program = dir.path().join("other.ngc");
    let gcode = ok(&vcnc(&[
        "-q",
        "gen",
        "identification",
        "--axis",
        "X",
        "--seed",
        "3",
    ]));
    std::fs::write(&program, gcode).unwrap();
    let out = dir.path().join("sim");
    ok(&vcnc(&[
        "simulate",
        "machines/ballscrew-ppi.toml",
        program.to_str().unwrap(),
        "--model",
        dir.path().join("model.toml").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    let sim = json(&out.join("summary.json"));
    let err = num(&sim, "axes.X.model_vs_true_max_um");
    let peak = num(&sim, "axes.X.tracking_max_um");
    eprintln!("another program: model vs true max {err:.3} µm of {peak:.1} µm");
    assert!(
        err < MODEL_VS_TRUE_MAX_UM,
        "model vs true {err} µm of {peak} µm"
    );
}

/// About twice the measured |model − true drive| on the seed-3 program (0.26 µm of 1024 µm peak
/// tracking error, 2026-11-29).
const MODEL_VS_TRUE_MAX_UM: f64 = 0.5;

#[test]
fn the_actual_value_latency_is_stated_not_identified() {
    // docs/drive-model.md#actual-value-latency: `--actual-latency-s` writes the stated value
    // into model.toml; without it a machine's dead time (none on this drive) is written, i.e.
    // no key; the identified parameters do not depend on it.
    let dir = tempdir();
    let (plain, stated) = (dir.path().join("plain"), dir.path().join("stated"));
    let ppi = repo("machines/ballscrew-ppi.toml");
    identify(&ppi, &plain, &[]);
    identify(&ppi, &stated, &["--actual-latency-s", "0.00025"]);
    let read = |d: &Path| std::fs::read_to_string(d.join("model.toml")).expect("model.toml");
    let (a, b) = (read(&plain), read(&stated));
    assert!(!a.contains("actual_latency_s"), "{a}");
    assert!(b.contains("actual_latency_s = 0.00025"), "{b}");
    let without: Vec<&str> = b
        .lines()
        .filter(|l| !l.starts_with("actual_latency_s"))
        .collect();
    assert_eq!(without, a.lines().collect::<Vec<_>>());
}

#[test]
fn table1_drive_with_1um_encoder() {
    // About twice the README's published errors with a 1 µm encoder (p 0.04 %, ωn 0.27 %,
    // ζ 0.27 %, dc 0.39 %; issue 4 asked for 2 %, 2 %, 5 %, 10 %).
    let dir = tempdir();
    let src = std::fs::read_to_string(repo("machines/ballscrew-ppi.toml")).unwrap();
    let coarse = src.replace(
        "encoder = { resolution = 0.0001 }",
        "encoder = { resolution = 0.001 }",
    );
    assert_ne!(src, coarse, "the machine file changed: update this test");
    let path = dir.path().join("coarse.toml");
    std::fs::write(&path, coarse).unwrap();
    let s = identify(&path, &dir.path().join("out"), &[]);
    let (wn, p, z, dc) = (
        rel(&s, "X", "wn_hz"),
        rel(&s, "X", "p_hz"),
        rel(&s, "X", "zeta"),
        rel(&s, "X", "dc"),
    );
    eprintln!("1 µm: wn {wn:.4}, p {p:.4}, zeta {z:.4}, dc {dc:.4}");
    assert!(
        wn < 0.006 && p < 0.0008 && z < 0.006 && dc < 0.008,
        "wn {wn} p {p} zeta {z} dc {dc}"
    );
}

/// The validation run's free-run max error within `max_um`: about twice the README's figure
/// (PID 0.26 µm of 97.7 µm, SMC 0.27 µm of 51.5 µm; issue 4 asked for 2 % of the peak).
fn validation_within(s: &Value, max_um: f64) {
    let err = num(s, "axes.X.fit.freerun_max_um");
    let peak = num(s, "axes.X.fit.tracking_peak_um");
    eprintln!("validation: free-run max error {err:.3} µm of {peak:.3} µm peak tracking error");
    assert!(err <= max_um, "{err} µm of {peak} µm");
    assert_eq!(s["axes"]["X"]["identified"]["stable"], Value::Bool(true));
}

#[test]
fn pid_drive_identified_stable_and_predictive() {
    let dir = tempdir();
    let s = identify(&repo("machines/ballscrew-pid.toml"), dir.path(), &[]);
    validation_within(&s, 0.55);
}

/// Routh–Hurwitz on a model object of a summary: every pole strictly in the left half plane.
fn routh_hurwitz(m: &Value) -> bool {
    let (a1, a2, a3) = (num(m, "a1"), num(m, "a2"), num(m, "a3"));
    a1 > 0.0 && a3 > 0.0 && a1 * a2 > a3
}

#[test]
fn smc_drive_identified_stable_and_predictive() {
    // ballscrew-smc.toml: sliding mode with realistic (half) inertia estimate.
    let dir = tempdir();
    let s = identify(&repo("machines/ballscrew-smc.toml"), dir.path(), &[]);
    validation_within(&s, 0.55);
    // The unconstrained LS baseline is reported beside it with its poles and a stability flag
    // that agrees with Routh–Hurwitz on its own coefficients (shown, whatever it is).
    let ls = &s["axes"]["X"]["unconstrained_ls"];
    assert_eq!(ls["stable"], Value::Bool(routh_hurwitz(ls)), "{ls}");
}

#[test]
fn smc_with_exact_estimates_stays_stable() {
    // Exact estimates: every pole is cancelled by a zero (G_track = 1, docs/drive-model.md), the
    // tracking error is Coulomb friction only (≈ 6 µm peak) and the poles are seen only through
    // the friction response. The identified model must still be stable, and predict the
    // validation run within 0.6 µm: the analytic model of the true drive itself misses the 20 kHz
    // drive by 0.44 µm there (sampled control and friction events; measured with `vcnc simulate
    // --model` on the true coefficients).
    let dir = tempdir();
    let src = std::fs::read_to_string(repo("machines/ballscrew-smc.toml")).unwrap();
    let exact = src.replace(
        "je_hat = 0.00314169, be_hat = 0.0",
        "je_hat = 0.00628338, be_hat = 0.0263005",
    );
    assert_ne!(src, exact, "the machine file changed: update this test");
    let path = dir.path().join("smc-exact.toml");
    std::fs::write(&path, exact).unwrap();
    let s = identify(&path, &dir.path().join("out"), &[]);
    assert_eq!(s["axes"]["X"]["identified"]["stable"], Value::Bool(true));
    assert_eq!(s["axes"]["X"]["paper_pso"]["stable"], Value::Bool(true));
    let err = num(&s, "axes.X.fit.freerun_max_um");
    assert!(err <= 0.6, "{err} µm");
    let ls = &s["axes"]["X"]["unconstrained_ls"];
    assert_eq!(ls["stable"], Value::Bool(routh_hurwitz(ls)), "{ls}");
}

#[test]
fn emps_real_trace() {
    // docs/reference-numbers.md: the EMPS benchmark (Janot, Gautier, Brunot 2019), a real ball-screw drive:
    // raw tracking error 578 µm RMS; the benchmark's physical model gives 3.15 µm RMS free-run;
    // we need a stable model at ≤ 3 µm. Unconstrained LS gives an unstable pole.
    let dir = tempdir();
    // EMPS columns: t, reference qg and measured qm, in metres.
    let emps = |out: &std::path::Path, extra: &[&str]| {
        let mut args = vec![
            "identify",
            "--trace",
            "tests/data/emps/DATA_EMPS.csv",
            "--units",
            "m",
            "--t-col",
            "t",
            "--xr-col",
            "qg",
            "--x-col",
            "qm",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        ok(&vcnc(&args))
    };
    let stdout = emps(dir.path(), &[]);
    eprintln!("{stdout}");
    let s = json(&dir.path().join("summary.json"));
    // Every structure tried is a row of the printout and of summary.json, exactly one marked
    // chosen: the structure model.toml holds, and every other one says why it was not chosen.
    let tried = s["axes"]["X"]["structures"].as_array().expect("structures");
    assert!(tried.len() >= 2, "{tried:?}");
    let chosen: Vec<&Value> = tried
        .iter()
        .filter(|t| t["verdict"]["kind"] == "chosen")
        .collect();
    assert_eq!(chosen.len(), 1, "{tried:?}");
    assert_eq!(chosen[0]["structure"], s["axes"]["X"]["structure"]);
    assert!(tried.iter().all(|t| t["verdict"]["kind"].is_string()));
    let header = stdout
        .lines()
        .position(|l| l.contains("held-out RMS / max") && l.contains("verdict"))
        .expect("the table of structures tried");
    let rows: Vec<&str> = stdout.lines().skip(header + 2).take(tried.len()).collect();
    assert_eq!(
        rows.iter().filter(|l| l.contains("* ")).count(),
        1,
        "{rows:?}"
    );
    assert!(
        rows.iter().all(|l| l.contains("chosen")
            || l.contains("higher held-out error")
            || l.contains("below the best trusted")),
        "{rows:?}"
    );
    // Issue 29: a physical model with no parameter on a bound. The EMPS position loop has no
    // integral action (tests/data/emps/PROVENANCE.md: position P, velocity P, no integrator),
    // and the structure without it is chosen; its held-out error was 1.638 µm RMS when it came
    // (docs/reference-numbers.md).
    assert_eq!(s["axes"]["X"]["structure"], "no-integral");
    assert_eq!(s["axes"]["X"]["on_bounds"], Value::Array(vec![]));
    let held = chosen[0]["fit_validation"]["freerun_rms_um"]
        .as_f64()
        .expect("held-out error");
    assert!(held <= 2.0 * 1.638, "held-out free-run RMS {held} µm");
    let rms = num(&s, "axes.X.fit.freerun_rms_um");
    let tracking = num(&s, "axes.X.fit.tracking_rms_um");
    assert!(
        (tracking - 578.0).abs() < 5.0,
        "raw tracking error {tracking} µm RMS"
    );
    assert!(rms <= 3.0, "free-run RMS {rms} µm");
    // `identified` is the model written to model.toml: without integral action its pole at the
    // origin (the loop's constant offset) makes it marginally stable; the paper structure's
    // refined model beside it is stable.
    let identified = &s["axes"]["X"]["identified"];
    assert_eq!(identified["a3"], 0.0, "{identified}");
    assert_eq!(identified["marginally_stable"], true, "{identified}");
    assert_eq!(s["axes"]["X"]["paper_refined"]["stable"], true);
    // The printout's first row is that model, with its structure and its own error.
    let first = stdout
        .lines()
        .find(|l| l.starts_with("identified"))
        .expect("the identified row");
    assert!(
        first.starts_with("identified (no-integral)")
            && first.contains(&format!("{:.4}", num(identified, "zeta")))
            && first.contains(&format!("{rms:.2} um")),
        "{first}"
    );
    assert_eq!(
        s["axes"]["X"]["unconstrained_ls"]["stable"],
        Value::Bool(false)
    );
    // Without an options file the lower bound of p is relaxed for drives without integral
    // action, and the options used are recorded.
    assert_eq!(num(&s, "identify_options.bounds.p_hz.0"), 1e-4);
    assert_eq!(num(&s, "identify_options.deadband"), 1.5);

    // An options file (the keys of a machine file's [identification.options]) is applied: a
    // wider sign deadband and another seed still give a stable model within the 3 µm target;
    // bounds it does not set keep the relaxed p bound.
    let options = dir.path().join("opts.toml");
    std::fs::write(
        &options,
        "deadband = 3.0\nseed = 5\n[pso]\nparticles = 120\n",
    )
    .unwrap();
    let out2 = dir.path().join("with-options");
    emps(&out2, &["--options", options.to_str().unwrap()]);
    let s2 = json(&out2.join("summary.json"));
    assert_eq!(num(&s2, "identify_options.deadband"), 3.0);
    assert_eq!(num(&s2, "identify_options.seed"), 5.0);
    assert_eq!(num(&s2, "identify_options.pso.particles"), 120.0);
    assert_eq!(num(&s2, "identify_options.bounds.p_hz.0"), 1e-4);
    let identified = &s2["axes"]["X"]["identified"];
    assert!(
        identified["stable"] == true || identified["marginally_stable"] == true,
        "{identified}"
    );
    let rms2 = num(&s2, "axes.X.fit.freerun_rms_um");
    assert!(rms2 <= 3.0, "free-run RMS with the options file {rms2} µm");
}

#[test]
fn same_seed_same_bits_for_any_thread_count() {
    let dir = tempdir();
    let (a, b) = (dir.path().join("t1"), dir.path().join("t2"));
    for (out, threads) in [(&a, "1"), (&b, "2")] {
        let o = vcnc(&[
            "--threads",
            threads,
            "identify",
            "machines/nmv5000.toml",
            "--axis",
            "X",
            "--axis",
            "C",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{:?}", text(&o));
    }
    for f in ["summary.json", "model.toml"] {
        assert_eq!(
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
            "{f} differs"
        );
    }
    // docs/cli.md keys: model objects and fit, µm on linear axes, millidegrees on rotary.
    let s = json(&a.join("summary.json"));
    for (axis, unit) in [("X", "um"), ("C", "mdeg")] {
        for model in ["identified", "paper_pso", "unconstrained_ls", "true"] {
            for key in [
                "a1", "a2", "a3", "b0", "b1", "b2", "dc", "p_hz", "wn_hz", "zeta", "stable",
            ] {
                assert!(
                    !s["axes"][axis][model][key].is_null(),
                    "axes.{axis}.{model}.{key} missing"
                );
            }
        }
        for key in ["freerun_rms", "freerun_max", "onestep_rms"] {
            num(&s, &format!("axes.{axis}.fit.{key}_{unit}"));
        }
        num(&s, &format!("axes.{axis}.fit.fit_percent"));
    }
}

#[test]
fn emps_validate_on_the_part_not_identified_on() {
    // Truth: the measurement itself (EMPS benchmark, docs/reference-numbers.md): a model
    // identified on the first half of the recording predicts the second half, which it never
    // saw, from the nominal position alone. The second half starts in motion, so the model's
    // start transient is scored apart; after it the free-run error must stay at the benchmark
    // level (≤ 3 µm RMS, the 7-parameter model's in-sample figure is about 2.3 µm). And
    // `validate` on the half it was identified on reproduces identify's own fit exactly.
    let dir = tempdir();
    let src = std::fs::read_to_string(repo("tests/data/emps/DATA_EMPS.csv")).unwrap();
    let (comments, rest): (Vec<&str>, Vec<&str>) = src.lines().partition(|l| l.starts_with('#'));
    let (header, rows) = rest.split_first().unwrap();
    let half = rows.len() / 2;
    let write = |name: &str, part: &[&str]| {
        let p = dir.path().join(name);
        let mut text: Vec<&str> = comments.clone();
        text.push(header);
        text.extend_from_slice(part);
        std::fs::write(&p, text.join("\n") + "\n").unwrap();
        p
    };
    let first = write("first.csv", &rows[..half]);
    let second = write("second.csv", &rows[half..]);
    let cols = [
        "--units", "m", "--t-col", "t", "--xr-col", "qg", "--x-col", "qm",
    ];
    let id_out = dir.path().join("id");
    let mut args = vec!["identify", "--trace", first.to_str().unwrap()];
    args.extend_from_slice(&cols);
    args.extend_from_slice(&["--out", id_out.to_str().unwrap()]);
    ok(&vcnc(&args));
    let ids = json(&id_out.join("summary.json"));
    let model = id_out.join("model.toml");
    let validate = |trace: &std::path::Path, out: &str| {
        let out = dir.path().join(out);
        let mut args = vec![
            "validate",
            "--model",
            model.to_str().unwrap(),
            "--trace",
            trace.to_str().unwrap(),
        ];
        args.extend_from_slice(&cols);
        args.extend_from_slice(&["--out", out.to_str().unwrap()]);
        eprintln!("{}", ok(&vcnc(&args)));
        assert!(out.join("validation_X.svg").is_file());
        assert!(out.join("residual_X.csv").is_file());
        assert!(out.join("report.html").is_file());
        json(&out.join("summary.json"))
    };
    let same = validate(&first, "same");
    for key in [
        "freerun_rms_um",
        "freerun_max_um",
        "fit_percent",
        "tracking_rms_um",
    ] {
        let (a, b) = (
            num(&same, &format!("axes.X.fit.{key}")),
            num(&ids, &format!("axes.X.fit.{key}")),
        );
        assert!(
            (a - b).abs() <= 1e-9 * b.abs().max(1.0),
            "{key}: {a} vs {b}"
        );
    }
    let other = validate(&second, "other");
    let tracking = num(&other, "axes.X.fit.tracking_rms_um");
    assert!(
        (tracking - 578.0).abs() < 10.0,
        "tracking {tracking} µm RMS"
    );
    assert_eq!(other["axes"]["X"]["moving_start"], Value::Bool(true));
    let settled = num(&other, "axes.X.fit_settled.freerun_rms_um");
    let from = num(&other, "axes.X.settled_from_s");
    assert!(
        settled <= 3.0,
        "held-out free-run RMS {settled} µm after {from} s"
    );
    assert!(from > 0.0 && from < 1.0, "{from} s");
    assert!(num(&other, "axes.X.fit.onestep_rms_um") < 5.0);
    assert!(num(&other, "axes.X.fit.fit_percent") > 95.0);
}
