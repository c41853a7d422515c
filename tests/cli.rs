//! The command-line contract (docs/cli.md): commands, output files, their keys.

use crate::util::{json, num, ok, repo, tempdir, text, vcnc, vcnc_in};

#[test]
fn committed_programs_are_what_the_generators_write() {
    // gcode/ holds the generated programs used by the demo and the tests; they must not drift.
    let spiral = ok(&vcnc(&["gen", "spiral"]));
    assert_eq!(
        spiral,
        std::fs::read_to_string(repo("gcode/spiral.ngc")).unwrap()
    );
    let ident = ok(&vcnc(&[
        "gen",
        "identification",
        "--axis",
        "X",
        "--seed",
        "1",
    ]));
    assert_eq!(
        ident,
        std::fs::read_to_string(repo("gcode/identification-X.ngc")).unwrap()
    );
    // Same seed, same text; another seed, another program.
    assert_eq!(
        ident,
        ok(&vcnc(&[
            "gen",
            "identification",
            "--axis",
            "X",
            "--seed",
            "1"
        ]))
    );
    assert_ne!(
        ident,
        ok(&vcnc(&[
            "gen",
            "identification",
            "--axis",
            "X",
            "--seed",
            "2"
        ]))
    );
}

#[test]
fn interpolate_writes_reference_and_summary() {
    let dir = tempdir();
    let out = dir.path().join("interp");
    let o = vcnc(&[
        "interpolate",
        "machines/nmv5000.toml",
        "gcode/spiral.ngc",
        "--out",
        out.to_str().unwrap(),
    ]);
    ok(&o);
    let s = json(&out.join("summary.json"));
    // docs/contour.md: ≈ 755 mm at 75 mm/s with 1500 mm/s² ≈ 10.1 s of feed moves, after the
    // opening rapid from the machine's start position (home, every axis at 0).
    assert!((num(&s, "feed_duration_s") - 10.12).abs() < 0.02);
    assert!(num(&s, "duration_s") > num(&s, "feed_duration_s") + 0.05);
    assert_eq!(
        s["samples"].as_u64().unwrap() as usize,
        (num(&s, "duration_s") / 0.001).round() as usize + 1
    );
    // The spiral's 212 °/s, or the opening rapid's, within C's 300 °/s limit.
    let c = num(&s, "axes.C.max_vel");
    assert!((211.0..=300.0).contains(&c), "{c}");
    let csv = std::fs::read_to_string(out.join("reference.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert_eq!(
        header,
        "t,px,py,pz,X,X_vel,X_acc,Y,Y_vel,Y_acc,Z,Z_vel,Z_acc,A,A_vel,A_acc,C,C_vel,C_acc"
    );
    assert_eq!(
        csv.lines().count(),
        s["samples"].as_u64().unwrap() as usize + 1
    );
}

#[test]
fn cycle_time_is_the_exact_stop_trapezoids_plus_the_dwell() {
    // Truth by hand (one axis, exact stop: a move of length d at peak speed v with acceleration
    // a lasts d/v + v/a when it reaches v): the rapid 50 mm at the axis' 250 mm/s and
    // 2500 mm/s² takes 0.2 + 0.1 s, the dwell 0.5 s, the feed 50 mm at F600 (10 mm/s)
    // 5 + 0.004 s.
    let dir = tempdir();
    let prog = dir.path().join("ct.ngc");
    std::fs::write(&prog, "G21 G90 G61.1\nG0 X50\nG4 P0.5\nG1 X0 F600\nM2\n").unwrap();
    let out = dir.path().join("ct");
    let stdout = ok(&vcnc(&[
        "interpolate",
        "machines/ballscrew-ppi.toml",
        prog.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    let s = json(&out.join("summary.json"));
    for (key, want) in [
        ("cycle_time.rapid_s", 0.3),
        ("cycle_time.dwell_s", 0.5),
        ("cycle_time.feed_s", 5.004),
        ("cycle_time.total_s", 5.804),
    ] {
        assert!(
            (num(&s, key) - want).abs() < 1e-9,
            "{key}: {}",
            num(&s, key)
        );
    }
    assert!(
        stdout.contains("cycle time 5.804 s (feed 5.004 s, rapid 0.300 s, dwell 0.500 s)"),
        "{stdout}"
    );
}

#[test]
fn identification_program_interpolates_within_the_issue_bounds() {
    // Issue 2: the identification program for one axis takes 20–60 s at the defaults.
    let dir = tempdir();
    let out = dir.path().join("i");
    ok(&vcnc(&[
        "interpolate",
        "machines/ballscrew-ppi.toml",
        "gcode/identification-X.ngc",
        "--out",
        out.to_str().unwrap(),
    ]));
    let s = json(&out.join("summary.json"));
    let d = num(&s, "duration_s");
    assert!((20.0..=60.0).contains(&d), "{d} s");
    assert!(num(&s, "axes.X.max_vel") <= 250.0 + 1e-9);
    assert!(num(&s, "axes.X.max_acc") <= 2500.0 + 1e-9);
}

#[test]
fn simulate_and_frf_write_their_files() {
    let dir = tempdir();
    let out = dir.path().join("sim");
    let stdout = ok(&vcnc(&[
        "simulate",
        "machines/ballscrew-ppi.toml",
        "gcode/identification-X.ngc",
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(stdout.contains("p-pi"));
    let s = json(&out.join("summary.json"));
    // Truth: docs/reference-numbers.md, Table 1 poles. The true drive's model is `true_model`
    // (issue 11: it was written as `model`, the key of the identified model).
    assert!((num(&s, "axes.X.true_model.wn_hz") - 30.569).abs() < 1e-3);
    assert!((num(&s, "axes.X.true_model.zeta") - 0.44519).abs() < 1e-5);
    assert!(s["axes"]["X"].get("model").is_none());
    assert!(s.get("models").is_none());
    assert!(num(&s, "axes.X.tracking_max_um") > 100.0);
    let header = std::fs::read_to_string(out.join("trace.csv")).unwrap();
    assert!(header.starts_with("t,X_ref,X_act\n"));
    assert!(out.join("tracking.svg").exists());

    // With --model: the model file is recorded and its model written under `model`.
    let id = dir.path().join("id");
    ok(&vcnc(&[
        "identify",
        "machines/ballscrew-ppi.toml",
        "--quiet",
        "--out",
        id.to_str().unwrap(),
    ]));
    let model = id.join("model.toml");
    let out2 = dir.path().join("sim2");
    ok(&vcnc(&[
        "simulate",
        "machines/ballscrew-ppi.toml",
        "gcode/identification-X.ngc",
        "--model",
        model.to_str().unwrap(),
        "--out",
        out2.to_str().unwrap(),
    ]));
    let s2 = json(&out2.join("summary.json"));
    assert_eq!(s2["models"].as_str(), model.to_str());
    let identified = json(&id.join("summary.json"));
    assert_eq!(
        s2["axes"]["X"]["model"]["wn_hz"],
        identified["axes"]["X"]["identified"]["wn_hz"]
    );
    assert!((num(&s2, "axes.X.true_model.wn_hz") - 30.569).abs() < 1e-3);
    assert!(num(&s2, "axes.X.model_vs_true_max_um") < 5.0);

    let frf = dir.path().join("frf");
    ok(&vcnc(&[
        "frf",
        "machines/nmv5000.toml",
        "--out",
        frf.to_str().unwrap(),
    ]));
    for a in ["X", "Y", "Z", "A", "C"] {
        assert!(frf.join(format!("frf_{a}.csv")).exists());
        assert!(frf.join(format!("frf_{a}.svg")).exists());
    }
    let s = json(&frf.join("summary.json"));
    assert!((num(&s, "axes.X.true.wn_hz") - 55.54).abs() < 1e-6);
}

#[test]
fn kinematics_forward_and_inverse_round_trip() {
    let dir = tempdir();
    let axes = dir.path().join("axes.csv");
    std::fs::write(
        &axes,
        "X,Y,Z,A,C\n10,-20,50,-30,57.29577951308232\n0,0,0,-12,400\n",
    )
    .unwrap();
    let poses = dir.path().join("poses.csv");
    ok(&vcnc(&[
        "kinematics",
        "machines/nmv5000.toml",
        "forward",
        "--input",
        axes.to_str().unwrap(),
        "--out",
        poses.to_str().unwrap(),
    ]));
    let back = ok(&vcnc(&[
        "kinematics",
        "machines/nmv5000.toml",
        "inverse",
        "--input",
        poses.to_str().unwrap(),
        "--branch",
        "-1",
    ]));
    let rows: Vec<Vec<f64>> = back
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    // C comes back unwrapped continuously from the previous row: 400° is the same table angle
    // as 40°, which is the solution nearest to the first row's 57.3°.
    let want = [
        [10.0, -20.0, 50.0, -30.0, 57.29577951308232],
        [0.0, 0.0, 0.0, -12.0, 40.0],
    ];
    for (r, w) in rows.iter().zip(&want) {
        for (a, b) in r.iter().zip(w) {
            assert!((a - b).abs() < 1e-9, "{r:?} vs {w:?}");
        }
    }
    // Without --branch the machine file's `kinematics.branch` decides (issue 11: the command
    // used -1 whatever the file said). A machine on branch +1 gives A = +30° for the pose of
    // A = -30°, C = 57.3° (the same tool axis, C turned by 180°).
    let text = std::fs::read_to_string(repo("machines/nmv5000.toml"))
        .unwrap()
        .replace("branch = -1", "branch = 1")
        .replace(
            "urdf = \"nmv5000.urdf\"",
            &format!("urdf = {:?}", repo("machines/nmv5000.urdf")),
        );
    let plus = dir.path().join("plus.toml");
    std::fs::write(&plus, text).unwrap();
    for (machine, sign) in [
        ("machines/nmv5000.toml", -1.0),
        (plus.to_str().unwrap(), 1.0),
    ] {
        let out = ok(&vcnc(&[
            "kinematics",
            machine,
            "inverse",
            "--input",
            poses.to_str().unwrap(),
        ]));
        let a: f64 = out
            .lines()
            .nth(1)
            .unwrap()
            .split(',')
            .nth(3)
            .unwrap()
            .parse()
            .unwrap();
        assert!((a - sign * 30.0).abs() < 1e-9, "{machine}: A = {a}");
    }
}

#[test]
fn interrupted_write_keeps_the_previous_file() {
    // Issue 7: outputs go to a temporary file and are renamed; a failure before the rename
    // (injected with VCNC_FAIL_WRITE) leaves the old file intact and no temporary behind.
    let dir = tempdir();
    let out = dir.path().join("o");
    let args = [
        "interpolate",
        "machines/ballscrew-ppi.toml",
        "gcode/identification-X.ngc",
        "--out",
        out.to_str().unwrap(),
    ];
    ok(&vcnc(&args));
    let before = std::fs::read(out.join("summary.json")).unwrap();
    std::fs::write(out.join("summary.json"), b"{\"old\": true}\n").unwrap();
    let o = vcnc_in(&repo(""), &args, &[("VCNC_FAIL_WRITE", "summary.json")]);
    assert_eq!(o.status.code(), Some(1), "{:?}", text(&o));
    assert_eq!(
        std::fs::read(out.join("summary.json")).unwrap(),
        b"{\"old\": true}\n"
    );
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    // And a normal run replaces it with the complete new file.
    ok(&vcnc(&args));
    assert_eq!(std::fs::read(out.join("summary.json")).unwrap(), before);
}
