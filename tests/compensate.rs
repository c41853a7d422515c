//! Compensation and feed planning (issue 17, docs/compensation.md) on the NMV5000 spiral. Every
//! "after" figure is the TRUE drives on the written program — through the binary, the program
//! re-read by the interpolator — against the ORIGINAL program's tool path and tool axis, never
//! the models' promise.
//!
//! Truths: the spiral's uncompensated errors on the true drives (docs/contour.md: 450.57 µm,
//! 3.893 mrad); the targets (≤ 5 µm, ≤ 0.05 mrad); the axis limits of the machine file;
//! the tolerance asked of the feed plan; and, on the realistic machine, the identified models'
//! own prediction accuracy (what `vcnc predict` measures), which no model-based compensation can
//! beat.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use vcnc_machine::Machine;
use vcnc_pipeline::{compensate, run};

use crate::util::{json, num, ok, repo, tempdir, text, vcnc};

/// `model.toml` of the machine file `machine`, identified once by `vcnc identify`.
fn models(machine: &'static str) -> PathBuf {
    static IDEAL: OnceLock<tempfile::TempDir> = OnceLock::new();
    static REALISTIC: OnceLock<tempfile::TempDir> = OnceLock::new();
    static BALL_SCREW: OnceLock<tempfile::TempDir> = OnceLock::new();
    let cell = if machine.contains("realistic") {
        &REALISTIC
    } else if machine.contains("ballscrew") {
        &BALL_SCREW
    } else {
        &IDEAL
    };
    let dir = cell.get_or_init(|| {
        let d = tempdir();
        ok(&vcnc(&[
            "identify",
            repo(machine).to_str().unwrap(),
            "--out",
            d.path().to_str().unwrap(),
            "-q",
        ]));
        d
    });
    dir.path().join("model.toml")
}

/// `vcnc compensate` of the spiral on `machine`; returns its output folder and summary.
fn compensate(machine: &'static str, out: &Path) -> serde_json::Value {
    let stdout = ok(&vcnc(&[
        "compensate",
        repo(machine).to_str().unwrap(),
        repo("gcode/spiral.ngc").to_str().unwrap(),
        "--model",
        models(machine).to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    eprintln!("{machine}:\n{stdout}");
    json(&out.join("summary.json"))
}

/// Columns of a CSV file by name.
fn columns(path: &Path, names: &[String]) -> Vec<Vec<f64>> {
    let mut r = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let header = r.headers().unwrap().clone();
    let idx: Vec<usize> = names
        .iter()
        .map(|n| {
            header
                .iter()
                .position(|h| h == n)
                .unwrap_or_else(|| panic!("{}: no column {n}", path.display()))
        })
        .collect();
    let mut cols = vec![Vec::new(); names.len()];
    for rec in r.records() {
        let rec = rec.unwrap();
        for (c, i) in cols.iter_mut().zip(&idx) {
            c.push(rec[*i].parse::<f64>().unwrap());
        }
    }
    cols
}

#[test]
fn compensation_takes_the_spiral_from_450_um_to_under_5_um_on_the_true_drives() {
    let out = tempdir();
    let s = compensate("machines/nmv5000.toml", out.path());
    let before = num(&s, "before.contour_max_um");
    let after = num(&s, "after.contour_max_um");
    let after_or = num(&s, "after.orientation_max_mrad");
    eprintln!(
        "contour {before:.3} -> {after:.3} um (RMS {:.4}), orientation {:.4} -> {after_or:.5} mrad",
        num(&s, "after.contour_rms_um"),
        num(&s, "before.orientation_max_mrad")
    );
    assert!((before - 450.57).abs() < 1.0, "{before}");
    assert!((num(&s, "before.orientation_max_mrad") - 3.893).abs() < 0.01);
    assert!(after <= 5.0, "after compensation {after} um");
    assert!(after_or <= 0.05, "after compensation {after_or} mrad");
    // No axis limit exceeded: the set-point's velocity and the motion's acceleration.
    assert_eq!(s["within_limits"], true);
    for (axis, a) in s["axes"].as_object().unwrap() {
        let m = &a["margin"];
        let (v, vl) = (num(m, "reference_velocity"), num(m, "velocity_limit"));
        let (ma, al) = (num(m, "motion_acceleration"), num(m, "acceleration_limit"));
        eprintln!(
            "{axis}: set-point velocity {v:.1}/{vl}, motion acceleration {ma:.0}/{al}, set-point acceleration {:.0}",
            num(m, "reference_acceleration")
        );
        assert!(v <= vl && ma <= al, "{axis}: {m}");
        // And the true drive's own motion on the written program.
        let ta = num(&a["after"], "motion_acceleration");
        assert!(ta <= al, "{axis}: the true drive accelerates at {ta}");
        // The re-read program runs through the set-points within the machine file's
        // [program_output] (default: words at 0.1 µm / 0.0001°, blocks merged within the same):
        // the larger of the chord tolerance and half the resolution, blocks of one period being
        // allowed.
        let off = num(&a["reproduction"], "position");
        assert!(off <= 1e-4 * (1.0 + 1e-9), "{axis}: {off}");
    }

    // Independently of `compensate`'s own judging: `vcnc simulate` runs the written program on
    // the true drives; their encoder readings, through the forward kinematics, are measured
    // against the ORIGINAL spiral's path.
    let sim = out.path().join("simulate");
    ok(&vcnc(&[
        "simulate",
        repo("machines/nmv5000.toml").to_str().unwrap(),
        out.path().join("compensated.ngc").to_str().unwrap(),
        "--out",
        sim.to_str().unwrap(),
        "-q",
    ]));
    let machine = Machine::load(&repo("machines/nmv5000.toml")).unwrap();
    let original = run::prepare_file(&machine, &repo("gcode/spiral.ngc"), false).unwrap();
    let names: Vec<String> = machine
        .axes
        .iter()
        .map(|a| format!("{}_act", a.name))
        .collect();
    let act = columns(&sim.join("trace.csv"), &names);
    let refs: Vec<String> = machine
        .axes
        .iter()
        .map(|a| format!("{}_ref", a.name))
        .collect();
    let set_points: Vec<String> = machine.axes.iter().map(|a| a.name.to_string()).collect();
    for (r, c) in columns(&sim.join("trace.csv"), &refs)
        .iter()
        .zip(&columns(&out.path().join("references.csv"), &set_points))
    {
        assert_eq!(r.len(), c.len());
        let off = r
            .iter()
            .zip(c)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(
            off <= 1e-4 * (1.0 + 1e-9),
            "simulate runs the set-points compensate computed, as written: {off}"
        );
    }
    let pos: Vec<&[f64]> = act.iter().map(Vec::as_slice).collect();
    let c = compensate::contour_against(&machine, &original, &pos).unwrap();
    eprintln!(
        "vcnc simulate on compensated.ngc: {:.3} um, {:.5} mrad (encoder readings)",
        c.tip_max_mm * 1e3,
        c.orientation_max_rad * 1e3
    );
    // The encoder's 0.1 µm quantisation adds at most a few tenths of a µm to the true positions'.
    assert!(c.tip_max_mm * 1e3 <= 5.0 && c.orientation_max_rad * 1e3 <= 0.05);
}

/// The spiral in inverse time: `G93`, every G1 block's F = 4500 mm/min over its tool-tip
/// length (the spiral is a tool-centre-point program), so that each block lasts what it lasts
/// at F4500 under `G94`.
fn spiral_in_inverse_time() -> String {
    let src = std::fs::read_to_string(repo("gcode/spiral.ngc")).unwrap();
    let mut prev: Option<[f64; 3]> = None;
    let mut out = String::new();
    for line in src.lines() {
        let line = line.replace("G94", "G93");
        let words: Vec<&str> = line.split_whitespace().collect();
        let coord = |l: char| {
            words
                .iter()
                .find_map(|w| w.strip_prefix(l))
                .and_then(|v| v.parse::<f64>().ok())
        };
        let p = match (coord('X'), coord('Y'), coord('Z')) {
            (Some(x), Some(y), Some(z)) => Some([x, y, z]),
            _ => None,
        };
        match (words.first(), p, prev) {
            (Some(&"G1"), Some(p), Some(q)) => {
                let d =
                    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
                let kept: Vec<&str> = words
                    .iter()
                    .copied()
                    .filter(|w| !w.starts_with('F'))
                    .collect();
                out.push_str(&format!("{} F{:.4}\n", kept.join(" "), 4500.0 / d));
            }
            _ => {
                out.push_str(&line);
                out.push('\n');
            }
        }
        if p.is_some() {
            prev = p;
        }
    }
    out
}

#[test]
fn feed_planning_plans_an_inverse_time_program_as_its_feed_per_minute_twin() {
    // Truth: the same spiral under G94 F4500, whose blocks last as long: the plan of the G93
    // program (its F words scaled, 1/min) must give the same cycle times and the same errors.
    let dir = tempdir();
    let g93 = dir.path().join("spiral-g93.ngc");
    std::fs::write(&g93, spiral_in_inverse_time()).unwrap();
    let plan = |program: &Path, out: &Path| {
        ok(&vcnc(&[
            "feed-plan",
            repo("machines/nmv5000.toml").to_str().unwrap(),
            program.to_str().unwrap(),
            "--model",
            models("machines/nmv5000.toml").to_str().unwrap(),
            "--tolerance",
            "200um",
            "--out",
            out.to_str().unwrap(),
            "-q",
        ]));
        json(&out.join("summary.json"))
    };
    let a = plan(&g93, &dir.path().join("g93"));
    let b = plan(&repo("gcode/spiral.ngc"), &dir.path().join("g94"));
    for key in [
        "original.cycle_time_s",
        "planned.cycle_time_s",
        "uniform.cycle_time_s",
        "planned.predicted.contour_max_um",
    ] {
        let (x, y) = (num(&a, key), num(&b, key));
        eprintln!("{key}: G93 {x:.4}, G94 {y:.4}");
        assert!((x - y).abs() <= 2e-3 * y, "{key}: G93 {x} against G94 {y}");
    }
    assert!(num(&a, "planned.predicted.contour_max_um") <= 200.0);
    // Every block still in inverse time, never faster than programmed.
    let programmed = spiral_in_inverse_time();
    let planned = std::fs::read_to_string(dir.path().join("g93/planned.ngc")).unwrap();
    let f = |text: &str| -> Vec<f64> {
        text.lines()
            .filter(|l| l.starts_with("G1"))
            .filter_map(|l| l.split_whitespace().find_map(|w| w.strip_prefix('F')))
            .map(|v| v.parse().unwrap())
            .collect()
    };
    let (fp, fq) = (f(&programmed), f(&planned));
    assert_eq!(fp.len(), fq.len());
    assert!(fp.iter().zip(&fq).all(|(p, q)| *q > 0.0 && q <= p));
    assert!(planned.contains("G93"));
    let blocks = columns(
        &dir.path().join("g93/blocks.csv"),
        &["inverse_time".to_string()],
    );
    assert!(!blocks[0].is_empty() && blocks[0].iter().all(|&v| v == 1.0));
}

#[test]
fn a_control_with_a_4_ms_block_cycle_gets_blocks_of_4_ms_at_its_resolution() {
    // Truths: the machine file's [program_output] (block cycle 4 ms = 4 periods, words at
    // 0.001 mm / 0.001°), read from the written text itself: every G1 block's 1/F (G93) is a
    // whole number of periods, at least 4; every axis word has at most 3 decimals; and the
    // blocks' end points, placed at their samples by summing the blocks' periods, are the
    // set-points of references.csv rounded to the resolution (within half of it).
    let dir = tempdir();
    let mut text = std::fs::read_to_string(repo("machines/nmv5000.toml")).unwrap();
    text.push_str(
        "\n[program_output]\nblock_cycle_s = 0.004\nresolution = 0.001\nrotary_resolution = 0.001\nchord_tolerance = 0.002\nrotary_chord_tolerance = 0.002\n",
    );
    let machine = dir.path().join("nmv5000-4ms.toml");
    std::fs::write(&machine, text).unwrap();
    std::fs::copy(
        repo("machines/nmv5000.urdf"),
        dir.path().join("nmv5000.urdf"),
    )
    .unwrap();
    let out = dir.path().join("out");
    let stdout = ok(&vcnc(&[
        "compensate",
        machine.to_str().unwrap(),
        repo("gcode/spiral.ngc").to_str().unwrap(),
        "--model",
        models("machines/nmv5000.toml").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    eprintln!("{stdout}");
    let s = json(&out.join("summary.json"));
    assert!((num(&s, "written.shortest_block_s") - 0.004).abs() < 1e-12);
    let after = num(&s, "after.contour_max_um");
    // Blocks of 4 periods and words at 1 µm cannot carry all of the compensation's content:
    // measured 4.31 µm (0.17 µm with one full-precision block per period, docs/compensation.md),
    // still a hundredth of the 450 µm uncompensated. Tolerance 2× the figure.
    assert!(after <= 9.0, "{after} um");

    let names = ["X", "Y", "Z", "A", "C"].map(String::from);
    let set = columns(&out.join("references.csv"), &names);
    let program = std::fs::read_to_string(out.join("compensated.ngc")).unwrap();
    let mut k = 0usize;
    let mut g93 = false;
    let mut blocks = 0;
    for line in program.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        if words.first() == Some(&"G93") {
            g93 = true;
            continue;
        }
        if !g93 {
            continue;
        }
        let value = |l: char| {
            words
                .iter()
                .find_map(|w| w.strip_prefix(l))
                .map(|v| v.parse::<f64>().unwrap())
        };
        match words.first() {
            Some(&"G4") => k += (value('P').unwrap() / 0.001).round() as usize,
            Some(&"G1") => {
                let periods = 60.0 / (value('F').unwrap() * 0.001);
                let m = periods.round();
                assert!((periods - m).abs() <= 1e-7 * m, "{line}");
                assert!(m >= 4.0, "{line}: a block of {m} periods");
                k += m as usize;
                blocks += 1;
                for (i, n) in names.iter().enumerate() {
                    let c = n.chars().next().unwrap();
                    if let Some(v) = value(c) {
                        let w = words.iter().find(|w| w.starts_with(c)).unwrap();
                        assert!(w.split('.').nth(1).map_or(0, str::len) <= 3, "{w}");
                        let off = (v - set[i][k]).abs();
                        assert!(
                            off <= 0.0005 + 1e-12,
                            "{line}: {n} {v} against {}",
                            set[i][k]
                        );
                    }
                }
            }
            _ => {}
        }
    }
    assert_eq!(k + 1, set[0].len(), "the blocks last the set-points' time");
    assert_eq!(blocks as f64, num(&s, "written.blocks"));
}

#[test]
fn feed_planning_meets_10_um_on_the_true_machine_faster_than_a_uniform_feed() {
    let out = tempdir();
    let stdout = ok(&vcnc(&[
        "feed-plan",
        repo("machines/nmv5000.toml").to_str().unwrap(),
        repo("gcode/spiral.ngc").to_str().unwrap(),
        "--model",
        models("machines/nmv5000.toml").to_str().unwrap(),
        "--tolerance",
        "10um",
        "--out",
        out.path().to_str().unwrap(),
    ]));
    eprintln!("{stdout}");
    let s = json(&out.path().join("summary.json"));
    let (tp, tu) = (
        num(&s, "planned.cycle_time_s"),
        num(&s, "uniform.cycle_time_s"),
    );
    eprintln!(
        "cycle time: per-line {tp:.2} s, uniform (x{:.5}) {tu:.2} s, ratio {:.3}; true max {:.3} / {:.3} um",
        num(&s, "uniform_factor"),
        tp / tu,
        num(&s, "planned.true_machine.contour_max_um"),
        num(&s, "uniform.true_machine.contour_max_um")
    );
    // The models' prediction meets the tolerance by construction; the true machine within a
    // 3 % slack (the identified models predict this machine's spiral to ~0.15 µm).
    for plan in ["planned", "uniform"] {
        assert!(num(&s, &format!("{plan}.predicted.contour_max_um")) <= 10.0);
        let t = num(&s, &format!("{plan}.true_machine.contour_max_um"));
        assert!(t <= 10.3, "{plan}: {t} um on the true machine");
    }
    // The goal: at least 30 % shorter than the uniform feed meeting the same tolerance.
    assert!(tp <= 0.7 * tu, "{tp} s against {tu} s");
    // Feeds never above the programmed F (F4500 throughout the spiral).
    let planned = std::fs::read_to_string(out.path().join("planned.ngc")).unwrap();
    let f: Vec<f64> = planned
        .split_whitespace()
        .filter_map(|w| w.strip_prefix('F'))
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(f.len(), 1511);
    assert!(f.iter().all(|&v| v > 0.0 && v <= 4500.0));
    let blocks = columns(
        &out.path().join("blocks.csv"),
        &["factor".to_string(), "planned_f".to_string()],
    );
    assert!(!blocks[0].is_empty() && blocks[0].iter().all(|&k| k < 1.0));
}

#[test]
fn on_the_realistic_machine_compensation_removes_most_of_the_error() {
    // The identified models cannot represent the realistic drives' compliance, Stribeck and
    // pre-sliding friction, backlash and position-loop dead time; what they predict of the
    // uncompensated spiral is off by |predicted − true| (vcnc predict, measured 1.86 µm max).
    // Compensation here falls short of that accuracy: its inverted
    // set-points carry more high-frequency content (set-point accelerations above 100 m/s²)
    // than the identification program, which excites exactly the dynamics the models lack
    // (measured 450.6 -> 5.34 µm max, 202.4 -> 0.45 µm RMS, 3.89 -> 0.032 mrad). Asserted: the
    // reductions at half their measured size, so a regression of the inverse shows.
    let out = tempdir();
    let s = compensate("machines/nmv5000-realistic.toml", out.path());
    let pred = out.path().join("predict");
    ok(&vcnc(&[
        "predict",
        repo("machines/nmv5000-realistic.toml").to_str().unwrap(),
        repo("gcode/spiral.ngc").to_str().unwrap(),
        "--model",
        models("machines/nmv5000-realistic.toml").to_str().unwrap(),
        "--out",
        pred.to_str().unwrap(),
        "-q",
    ]));
    let p = json(&pred.join("summary.json"));
    let (before, after, after_rms) = (
        num(&s, "before.contour_max_um"),
        num(&s, "after.contour_max_um"),
        num(&s, "after.contour_rms_um"),
    );
    let (d_max, d_rms) = (
        num(&p, "contour_um.discrepancy_max"),
        num(&p, "contour_um.discrepancy_rms"),
    );
    eprintln!(
        "realistic: {before:.2} -> {after:.3} um max, RMS {after_rms:.3} um, orientation {:.4} -> {:.4} mrad; models' prediction error {d_max:.2} um max, {d_rms:.3} um RMS",
        num(&s, "before.orientation_max_mrad"),
        num(&s, "after.orientation_max_mrad")
    );
    let (o_before, o_after) = (
        num(&s, "before.orientation_max_mrad"),
        num(&s, "after.orientation_max_mrad"),
    );
    assert!(after < before / 40.0, "{before} -> {after}");
    assert!(
        after_rms < num(&s, "before.contour_rms_um") / 200.0,
        "RMS -> {after_rms}"
    );
    assert!(o_after < o_before / 60.0, "{o_before} -> {o_after} mrad");
    assert_eq!(s["within_limits"], true);
}

#[test]
fn a_compensation_beyond_an_axis_limit_is_refused_naming_the_axis() {
    // At 100 mm/s the spiral's C axis runs at its 300 deg/s limit; the compensated set-point
    // leads it and would exceed it. With the headroom stated (none: 1) vcnc does not plan the
    // program again with less: refused (exit 2), nothing written.
    let out = tempdir();
    let program = out.path().join("spiral100.ngc");
    let src = ok(&vcnc(&["gen", "spiral", "--feed", "100"]));
    std::fs::write(&program, src).unwrap();
    let o = vcnc(&[
        "compensate",
        repo("machines/nmv5000.toml").to_str().unwrap(),
        program.to_str().unwrap(),
        "--model",
        models("machines/nmv5000.toml").to_str().unwrap(),
        "--headroom",
        "1",
        "--out",
        out.path().join("c").to_str().unwrap(),
    ]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("axis C") && err.contains("velocity") && err.contains("300 deg/s"),
        "{err}"
    );
    assert!(!out.path().join("c").join("compensated.ngc").exists());
}

#[test]
fn feed_plan_tolerances_need_their_unit() {
    for (flag, value, word) in [
        ("--tolerance", "10", "unit"),
        ("--tolerance", "0um", "positive"),
        ("--orientation-tolerance", "0.05", "unit"),
    ] {
        let mut args = vec![
            "feed-plan",
            "machines/nmv5000.toml",
            "gcode/spiral.ngc",
            "--model",
            "none.toml",
        ];
        if flag != "--tolerance" {
            args.extend(["--tolerance", "10um"]);
        }
        args.extend([flag, value]);
        let o = vcnc(&args);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(flag) && err.contains(word), "{err}");
    }
}

#[test]
fn without_kinematics_compensation_is_judged_by_tracking_and_rapids_need_headroom() {
    // The X identification program on the single-axis Table 1 ball screw: rapids and feeds at
    // the 250 mm/s limit. The set-point must lead the motion, so it is refused as planned and
    // accepted with a velocity headroom; the true drive's tracking error (against the program's
    // own references: no kinematics, no contour) must then fall from its uncompensated
    // millimetre to under a micrometre.
    let (machine, program) = ("machines/ballscrew-ppi.toml", "gcode/identification-X.ngc");
    let out = tempdir();
    let args = |headroom: &'static str, dir: &Path| -> Vec<String> {
        [
            "compensate",
            repo(machine).to_str().unwrap(),
            repo(program).to_str().unwrap(),
            "--model",
            models(machine).to_str().unwrap(),
            "--headroom",
            headroom,
            "--out",
            dir.to_str().unwrap(),
        ]
        .map(String::from)
        .to_vec()
    };
    let refused = vcnc(
        &args("1", &out.path().join("a"))
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    let (_, err) = text(&refused);
    assert_eq!(refused.status.code(), Some(2), "{err}");
    assert!(err.contains("axis X") && err.contains("headroom"), "{err}");
    let dir = out.path().join("b");
    ok(&vcnc(
        &args("0.89", &dir)
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    ));
    let s = json(&dir.join("summary.json"));
    let (before, after) = (
        num(&s, "axes.X.before.tracking_max"),
        num(&s, "axes.X.after.tracking_max"),
    );
    eprintln!("ball screw: tracking {before:.2} -> {after:.4} um");
    assert!(before > 500.0 && after < 1.0, "{before} -> {after}");
    assert!(s["before"].get("contour_max_um").is_none());
    assert_eq!(s["within_limits"], true);
}

#[test]
fn a_set_point_ten_times_the_velocity_limit_is_refused_not_replanned() {
    // A model far slower than the drive (ωn 1 Hz, ζ 0.7, no zeros, for the Table 1 ball screw
    // of about 18 Hz): its exact inverse leads every acceleration step of the trapezoids with
    // a set-point velocity of roughly a_max / (ωn² T_s), hundreds of times the 250 mm/s limit.
    // Replanning would slow the rapids to a crawl and hide the bad model: below a headroom of
    // 0.1 the command refuses, naming the axis, and leaves no output directory.
    let out = tempdir();
    let (wn, zeta) = (std::f64::consts::TAU, 0.7);
    let model = out.path().join("slow.toml");
    std::fs::write(
        &model,
        format!(
            "machine = \"slow\"\n\n[axes.X]\nunit = \"mm\"\na1 = {}\na2 = {}\na3 = 0.0\nb0 = 0.0\nb1 = 0.0\nb2 = {}\ndc = 0.0\ninput = \"hold\"\n",
            2.0 * zeta * wn,
            wn * wn,
            wn * wn
        ),
    )
    .unwrap();
    let dir = out.path().join("c");
    let o = vcnc(&[
        "compensate",
        repo("machines/ballscrew-ppi.toml").to_str().unwrap(),
        repo("gcode/identification-X.ngc").to_str().unwrap(),
        "--model",
        model.to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
    ]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("axis X") && err.contains("does not replan below a headroom of 0.1"),
        "{err}"
    );
    assert!(!dir.exists(), "{err}");
}
