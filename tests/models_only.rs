//! A machine made of identified models (issue 28 item 3): axes given by unit, travel and
//! limits alone take their dynamics from the machine file's `model` file.
//!
//! Truth: the same machine with its virtual drives, predicting with the same `model.toml`
//! (`--model`). Both runs put the same models through the same streams and the same
//! actual-value shift, so the models-only machine's "true" figures must equal the full
//! machine's predicted ones bit for bit, and its prediction must equal them too.

use std::path::Path;

use crate::util::{json, ok, repo, tempdir, text, vcnc};

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// The NMV5000's machine file with the plant, controller and encoder of `axes` removed and
/// `model` named at its top; the URDF path made absolute (the file is written elsewhere).
fn strip(axes: &[&str], model: &Path) -> String {
    let src = std::fs::read_to_string(repo("machines/nmv5000.toml")).unwrap();
    let mut out = String::new();
    let mut section = String::new();
    for line in src.lines() {
        if line.starts_with('[') {
            section = line.to_string();
        }
        let physical = ["plant =", "controller =", "encoder ="]
            .iter()
            .any(|k| line.starts_with(k));
        if physical && axes.iter().any(|a| section == format!("[axes.{a}]")) {
            continue;
        }
        if line.starts_with("urdf =") {
            out.push_str(&format!(
                "urdf = \"{}\"\n",
                s(&repo("machines/nmv5000.urdf"))
            ));
            continue;
        }
        out.push_str(line);
        out.push('\n');
        if line.starts_with("sample_period_s") {
            out.push_str(&format!("model = \"{}\"\n", s(model)));
        }
    }
    out
}

/// The NMV5000's identified models (`vcnc identify`, its own excitation programs).
fn identified_models(dir: &Path) -> std::path::PathBuf {
    let out = dir.join("id");
    ok(&vcnc(&[
        "-q",
        "identify",
        "machines/nmv5000.toml",
        "--out",
        &s(&out),
    ]));
    out.join("model.toml")
}

fn predict(machine: &Path, extra: &[&str], out: &Path) -> (String, String, serde_json::Value) {
    let spiral = repo("gcode/spiral.ngc");
    let mut args = vec![
        "predict".to_string(),
        s(machine),
        s(&spiral),
        "--out".into(),
        s(out),
        "--outputs".into(),
        "tables".into(),
    ];
    args.extend(extra.iter().map(|a| a.to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = vcnc(&args);
    ok(&o);
    let (stdout, stderr) = text(&o);
    (stdout, stderr, json(&out.join("summary.json")))
}

fn figure(summary: &serde_json::Value, group: &str, key: &str) -> f64 {
    summary[group][key]
        .as_f64()
        .unwrap_or_else(|| panic!("{group}.{key} in {summary}"))
}

#[test]
fn a_machine_of_identified_models_predicts_what_the_full_machine_predicts_with_them() {
    let dir = tempdir();
    let model = identified_models(dir.path());
    let (_, _, full) = predict(
        &repo("machines/nmv5000.toml"),
        &["--model", &s(&model)],
        &dir.path().join("full"),
    );
    let stripped = dir.path().join("models-only.toml");
    std::fs::write(&stripped, strip(&["X", "Y", "Z", "A", "C"], &model)).unwrap();
    let (stdout, stderr, only) = predict(&stripped, &[], &dir.path().join("only"));
    for group in ["contour_um", "orientation_mrad"] {
        for (k_only, k_full) in [
            ("true_max", "predicted_max"),
            ("true_rms", "predicted_rms"),
            ("predicted_max", "predicted_max"),
            ("predicted_rms", "predicted_rms"),
        ] {
            assert_eq!(
                figure(&only, group, k_only).to_bits(),
                figure(&full, group, k_full).to_bits(),
                "{group}: models-only {k_only} against the full machine's {k_full}"
            );
        }
        assert_eq!(figure(&only, group, "discrepancy_max"), 0.0);
    }
    // It says so: the note, the summary, and only the prediction's rows.
    assert!(stderr.contains("no true machine"), "{stderr}");
    assert!(
        only["truth"]
            .as_str()
            .unwrap()
            .starts_with("no true machine"),
        "{only}"
    );
    assert_eq!(full["truth"], "virtual drives");
    assert!(
        stdout.contains("predicted max") && !stdout.contains("true max"),
        "{stdout}"
    );
    assert!(
        stdout.contains("worst blocks (the machine's models)"),
        "{stdout}"
    );

    // The other commands that run models work on it, and say there is no true machine.
    let spiral = s(&repo("gcode/spiral.ngc"));
    let m = s(&stripped);
    for args in [
        vec!["simulate", &m, &spiral],
        vec!["compensate", &m, &spiral, "--iterations", "3"],
        vec!["feed-plan", &m, &spiral, "--tolerance", "200um"],
        vec!["frf", &m],
    ] {
        let out = s(&dir.path().join(args[0]));
        let mut a = args.clone();
        a.extend(["--out", &out]);
        let o = vcnc(&a);
        let (_, err) = text(&o);
        ok(&o);
        assert!(err.contains("no true machine"), "{}: {err}", args[0]);
    }

    // What needs a virtual drive is refused, naming the axis and what to do.
    let o = vcnc(&["identify", &m, "--out", &s(&dir.path().join("i"))]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("axis X has no plant and controller"), "{err}");
}

#[test]
fn a_mixed_machine_runs_drives_and_models_side_by_side_and_a_lag_mismatch_is_a_warning() {
    let dir = tempdir();
    let model = identified_models(dir.path());
    // A and C known by their models, X Y Z by their virtual drives.
    let mixed = dir.path().join("mixed.toml");
    std::fs::write(&mixed, strip(&["A", "C"], &model)).unwrap();
    let (_, stderr, summary) = predict(&mixed, &["--model", &s(&model)], &dir.path().join("m"));
    assert_eq!(
        summary["truth"],
        format!(
            "virtual drives on X Y Z, the identified models of {} on A C",
            s(&model)
        )
    );
    assert!(!stderr.contains("lag the reference"), "{stderr}");
    // The rotary axes' truth is their model: they add nothing to the discrepancy, which the
    // linear axes' drives against their models make.
    assert!(figure(&summary, "contour_um", "discrepancy_max") > 0.0);

    // One axis with a 98 ms dead time and the others none: warned (the contour error is then
    // that mismatch).
    let text_model = std::fs::read_to_string(&model).unwrap();
    let delayed = text_model.replacen("[axes.X]\n", "[axes.X]\ndelay_s = 0.098\n", 1);
    assert_ne!(delayed, text_model);
    let delayed_path = dir.path().join("delayed.toml");
    std::fs::write(&delayed_path, delayed).unwrap();
    let only = dir.path().join("only.toml");
    std::fs::write(&only, strip(&["X", "Y", "Z", "A", "C"], &delayed_path)).unwrap();
    let (_, stderr, summary) = predict(&only, &[], &dir.path().join("d"));
    assert!(
        stderr.contains("lag the reference by different times") && stderr.contains("X 98.0 ms"),
        "{stderr}"
    );
    assert!(
        summary["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("lag the reference")),
        "{summary}"
    );
}

#[test]
fn incomplete_axes_are_refused_with_the_key_and_what_to_do() {
    let dir = tempdir();
    let model = dir.path().join("absent-model.toml");
    let full = strip(&[], &model).replace(&format!("model = \"{}\"\n", s(&model)), "");
    let cases = [
        (
            // A plant without a controller.
            full.replacen(
                "controller = { kind = \"p-pi\", design = { p_hz = 19.30",
                "# controller = { kind = \"p-pi\", design = { p_hz = 19.30",
                1,
            ),
            "has a plant but no controller",
        ),
        (
            // No plant, no controller, no model file.
            strip(&["Y"], &model).replace(&format!("model = \"{}\"\n", s(&model)), ""),
            "model = \"model.toml\"",
        ),
        (
            // A model file that is not there.
            strip(&["Y"], &model),
            "absent-model.toml: cannot read",
        ),
        (
            // A model file no axis uses.
            strip(&[], &repo("machines/emps-model.toml")),
            "no axis would use it",
        ),
    ];
    for (i, (src, expected)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("bad{i}.toml"));
        std::fs::write(&path, src).unwrap();
        let o = vcnc(&[
            "predict",
            &s(&path),
            &s(&repo("gcode/spiral.ngc")),
            "--out",
            &s(&dir.path().join(format!("o{i}"))),
        ]);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "case {i}: {err}");
        assert!(err.contains(*expected), "case {i}: {err}");
        assert!(!dir.path().join(format!("o{i}")).exists(), "case {i}");
    }
    // An encoder on an axis without a drive acts on nothing.
    let src = strip(&["Y"], &model).replacen(
        "[axes.Y]\n",
        "[axes.Y]\nencoder = { resolution = 0.0001 }\n",
        1,
    );
    std::fs::write(
        dir.path().join("absent-model.toml"),
        "machine = \"m\"\n[axes]\n",
    )
    .unwrap();
    let path = dir.path().join("encoder.toml");
    std::fs::write(&path, src).unwrap();
    let o = vcnc(&[
        "interpolate",
        &s(&path),
        &s(&repo("gcode/spiral.ngc")),
        "--out",
        &s(&dir.path().join("e")),
    ]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("axes.Y.encoder"), "{err}");
}

/// The README's worked example: the sample model file is what `vcnc identify --trace` writes
/// for the EMPS recording (its X table on X, Y and Z), and the mixed sample machine predicts
/// the spiral with the slides from it and A C from their virtual drives.
#[test]
fn the_emps_sample_machine_is_the_recording_identified_and_predicts_the_spiral() {
    let dir = tempdir();
    let id = dir.path().join("emps");
    ok(&vcnc(&[
        "-q",
        "identify",
        "--trace",
        "tests/data/emps/DATA_EMPS.csv",
        "--units",
        "m",
        "--xr-col",
        "qg",
        "--x-col",
        "qm",
        "--out",
        &s(&id),
    ]));
    let parse =
        |p: &Path| -> toml::Table { toml::from_str(&std::fs::read_to_string(p).unwrap()).unwrap() };
    let identified = parse(&id.join("model.toml"));
    let sample = parse(&repo("machines/emps-model.toml"));
    for axis in ["X", "Y", "Z"] {
        assert_eq!(
            sample["axes"][axis], identified["axes"]["X"],
            "machines/emps-model.toml axis {axis}: run the README's identify command again"
        );
    }
    let (_, stderr, summary) = predict(
        &repo("machines/nmv5000-emps.toml"),
        &[],
        &dir.path().join("p"),
    );
    assert!(
        stderr.contains("virtual drives on A C, the identified models of"),
        "{stderr}"
    );
    assert!(
        summary["models"]
            .as_str()
            .unwrap()
            .starts_with("identified on the fly (A C), the machine's models"),
        "{summary}"
    );
    let tip = figure(&summary, "contour_um", "true_max");
    assert!(tip.is_finite() && tip > 0.0, "{summary}");
}
