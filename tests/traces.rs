//! Scope files end to end (issue 12, docs/traces.md): realistic recordings of the simulated
//! NMV5000, written in every format vcnc reads, identified through `vcnc identify --trace`.
//!
//! Where the truth comes from: every axis of `machines/nmv5000.toml` is a P-PI drive designed
//! to the closed-loop poles of the paper's Table 3 ("Actual" columns, docs/reference-numbers.md),
//! so its true model has exactly those poles ([`TRUTH`], checked against the machine's analytic
//! `true_model()`). The recordings are the machine's own identification excitations (one program
//! per axis, generated with its seed) run through the true drives — a nonlinear simulation with
//! Coulomb friction and a 0.1 µm (0.1 mdeg) encoder — at the machine's 1 ms servo period (one
//! test at 500 µs), as the control's scope would have saved them. Two ignored tests pin known
//! limits of identification from traces (docs/traces.md, "Known limits").

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;

use serde_json::Value;
use vcnc_axis::AxisName;
use vcnc_machine::{AxisModel, Machine, ModelSet};
use vcnc_trace::write;

use crate::util::{json, num, ok, repo, tempdir, text, vcnc};

/// The true closed-loop poles of the NMV5000's drives: (axis, ωn Hz, ζ, p Hz), the paper's
/// Table 3 "Actual" poles as designed into `machines/nmv5000.toml`.
const TRUTH: [(AxisName, f64, f64, f64); 5] = [
    (AxisName::X, 55.54, 0.39, 19.30),
    (AxisName::Y, 73.50, 0.27, 22.12),
    (AxisName::Z, 73.60, 0.28, 22.20),
    (AxisName::A, 31.90, 0.47, 9.29),
    (AxisName::C, 27.30, 0.57, 8.45),
];

/// One axis of the recording: nominal (reference) and actual (encoder) position, mm or deg,
/// at [`Recording::ts`].
struct AxisRec {
    axis: AxisName,
    nominal: Vec<f64>,
    actual: Vec<f64>,
}

/// All five axes moving at once, each through its own identification program, recorded on one
/// time base.
struct Recording {
    /// Sample period, s.
    ts: f64,
    axes: Vec<AxisRec>,
}

impl Recording {
    fn axis(&self, a: AxisName) -> &AxisRec {
        self.axes.iter().find(|r| r.axis == a).unwrap()
    }
}

/// The recording at the machine's 1 ms servo period (made once per test run).
fn recording() -> &'static Recording {
    static REC: OnceLock<Recording> = OnceLock::new();
    REC.get_or_init(|| record(None))
}

/// The same programs recorded at 500 µs, for a scope that samples the actual position faster
/// than the set points come.
fn recording_500us() -> &'static Recording {
    static REC: OnceLock<Recording> = OnceLock::new();
    REC.get_or_init(|| record(Some(0.5e-3)))
}

/// Runs every axis' identification program (seed 1 + axis number) through its true drive, at the
/// machine's period or at `ts` (s).
fn record(ts: Option<f64>) -> Recording {
    let mut machine = Machine::embedded_nmv5000().expect("the embedded NMV5000 loads");
    if let Some(ts) = ts {
        machine.ts = ts;
    }
    let runs: Vec<_> = TRUTH
        .iter()
        .enumerate()
        .map(|(i, &(a, wn, zeta, p))| {
            let axis = machine.axis(a).unwrap();
            // Every axis' true poles are the table's.
            let poles = axis.true_model().poles().unwrap();
            for (got, want) in [(poles.wn_hz(), wn), (poles.zeta, zeta), (poles.p_hz(), p)] {
                assert!(
                    (got / want - 1.0).abs() < 1e-9,
                    "axis {a}: true model {got}, table {want}"
                );
            }
            let run = vcnc_pipeline::identify::excitation_run(&machine, axis, 1 + i as u64)
                .expect("the excitation runs");
            (axis, run)
        })
        .collect();
    // The axes' programs have different lengths: each axis, after its last move, stands still
    // at its end position while the others finish (the true drive is run again over the held
    // reference, so the record stays physical).
    let n = runs
        .iter()
        .map(|(_, r)| r.reference.pos.len())
        .max()
        .unwrap()
        + 200;
    let axes = runs
        .iter()
        .map(|(axis, run)| {
            let r = &run.reference;
            let last = *r.pos.last().unwrap();
            assert!(r.vel.last().unwrap().abs() < 1e-9, "a program ends at rest");
            let hold = |v: &[f64], with: f64| {
                let mut v = v.to_vec();
                v.resize(n, with);
                v
            };
            let (pos, vel, acc) = (hold(&r.pos, last), hold(&r.vel, 0.0), hold(&r.acc, 0.0));
            let reference = vcnc_drive::Reference {
                pos: &pos,
                vel: &vel,
                acc: &acc,
            };
            let trace = axis
                .drive()
                .expect("a virtual drive")
                .simulate(reference, machine.ts)
                .expect("the true drive runs");
            AxisRec {
                axis: axis.name,
                nominal: pos,
                actual: trace.position,
            }
        })
        .collect();
    Recording {
        ts: machine.ts,
        axes,
    }
}

/// Runs `vcnc identify --trace FILE ARGS --out OUT` and returns summary.json.
fn identify(file: &Path, out: &Path, args: &[&str]) -> Value {
    let mut a = vec![
        "identify",
        "--trace",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    a.extend_from_slice(args);
    let stdout = ok(&vcnc(&a));
    eprintln!("{stdout}");
    json(&out.join("summary.json"))
}

/// Runs `vcnc trace info FILE ARGS`: checks that the text names the format and every channel,
/// and returns the `--json` description.
fn trace_info(file: &Path, args: &[&str], format: &str, channels: &[&str]) -> Value {
    let mut a = vec!["trace", "info", file.to_str().unwrap()];
    a.extend_from_slice(args);
    let table = ok(&vcnc(&a));
    assert!(
        table.contains(&format!("format: {format}")),
        "trace info does not name the format '{format}':\n{table}"
    );
    for c in channels {
        assert!(
            table.contains(c),
            "trace info does not list '{c}':\n{table}"
        );
    }
    a.push("--json");
    serde_json::from_str(&ok(&vcnc(&a))).unwrap()
}

/// The channel `name` of a `trace info --json` description.
fn channel<'v>(info: &'v Value, name: &str) -> &'v Value {
    info["channels"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == name)
        .unwrap_or_else(|| panic!("no channel '{name}' in {info}"))
}

/// Checks a channel of a `trace info --json` description: axis, quantity, unit, period, count.
fn check_channel(info: &Value, name: &str, want: (&str, &str, &str, f64, usize)) {
    let c = channel(info, name);
    let (axis, quantity, unit, period_s, count) = want;
    assert_eq!(c["axis"], axis, "{name}: {c}");
    assert_eq!(c["quantity"], quantity, "{name}: {c}");
    assert_eq!(c["unit"], unit, "{name}: {c}");
    assert!(
        (num(c, "period_s") / period_s - 1.0).abs() < 1e-9,
        "{name}: {c}"
    );
    assert_eq!(c["count"], count, "{name}: {c}");
}

/// Checks the identified poles of `axes` in `summary` against [`TRUTH`]: ωn and p within 2 %,
/// ζ within 5 % (the tolerance issue 4 sets for a drive seen through a 1 µm encoder: a trace
/// gives the identifier no reference velocity and acceleration, which the machine route has),
/// and the model stable.
fn poles_match_truth(label: &str, summary: &Value, axes: &[AxisName]) {
    let found: Vec<&String> = summary["axes"].as_object().unwrap().keys().collect();
    // summary.json lists the axes by name.
    let mut want: Vec<String> = axes.iter().map(ToString::to_string).collect();
    want.sort();
    assert_eq!(
        found,
        want.iter().collect::<Vec<_>>(),
        "{label}: axes identified"
    );
    for a in axes {
        let (_, wn, zeta, p) = TRUTH.iter().find(|t| t.0 == *a).unwrap();
        let id = |k: &str| num(summary, &format!("axes.{a}.identified.{k}"));
        let e = (
            id("wn_hz") / wn - 1.0,
            id("zeta") / zeta - 1.0,
            id("p_hz") / p - 1.0,
        );
        eprintln!(
            "{label} axis {a}: wn {:.3} Hz ({:+.2} %), zeta {:.4} ({:+.2} %), p {:.3} Hz ({:+.2} %)",
            id("wn_hz"),
            100.0 * e.0,
            id("zeta"),
            100.0 * e.1,
            id("p_hz"),
            100.0 * e.2
        );
        assert!(
            e.0.abs() < 0.02 && e.1.abs() < 0.05 && e.2.abs() < 0.02,
            "{label} axis {a}: wn {:+.3} %, zeta {:+.3} %, p {:+.3} % (tolerance 2, 5, 2 %)",
            100.0 * e.0,
            100.0 * e.1,
            100.0 * e.2
        );
        assert_eq!(
            summary["axes"][a.to_string()]["identified"]["stable"],
            Value::Bool(true)
        );
    }
}

fn create(path: &Path) -> std::io::BufWriter<std::fs::File> {
    std::io::BufWriter::new(std::fs::File::create(path).unwrap())
}

/// The axes of the NMV5000, X Y Z A C.
fn xyzac() -> Vec<AxisName> {
    TRUTH.iter().map(|t| t.0).collect()
}

/// `contour_um.discrepancy_max` of `vcnc predict machines/nmv5000.toml gcode/spiral.ngc --model
/// MODEL`: the largest difference between the tool-tip contour error the model predicts and the
/// one the true (nonlinear) drives make, µm.
fn spiral_discrepancy_um(model: &Path, out: &Path) -> f64 {
    let stdout = ok(&vcnc(&[
        "predict",
        "machines/nmv5000.toml",
        "gcode/spiral.ngc",
        "--model",
        model.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    eprintln!("{stdout}");
    num(
        &json(&out.join("summary.json")),
        "contour_um.discrepancy_max",
    )
}

#[test]
fn multi_axis_halscope_log_gives_one_model_that_predict_uses() {
    // LinuxCNC 2.9 halscope log of a table-tilting XYZAC machine: joints 0..4 are X Y Z A C, each
    // with its servo loop's commanded and feedback position.
    let rec = recording();
    let dir = tempdir();
    let path = dir.path().join("xyzac.log");
    let names: Vec<String> = (0..5)
        .flat_map(|j| {
            [
                format!("joint.{j}.motor-pos-cmd"),
                format!("joint.{j}.motor-pos-fb"),
            ]
        })
        .collect();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let columns: Vec<&[f64]> = rec
        .axes
        .iter()
        .flat_map(|a| [a.nominal.as_slice(), a.actual.as_slice()])
        .collect();
    write::halscope_table(&mut create(&path), 1_000_000, &names, &columns).unwrap();
    let n = rec.axes[0].nominal.len();

    let info = trace_info(
        &path,
        &["--joints", "XYZAC"],
        "LinuxCNC halscope log (table, 2.9+)",
        &names,
    );
    check_channel(
        &info,
        "joint.3.motor-pos-cmd",
        ("A", "NominalPosition", "", 1e-3, n),
    );
    check_channel(
        &info,
        "joint.4.motor-pos-fb",
        ("C", "ActualPosition", "", 1e-3, n),
    );

    let s = identify(&path, &dir.path().join("id"), &["--joints", "XYZAC"]);
    poles_match_truth("halscope 2.9", &s, &xyzac());
    // The file states no unit: mm and deg were assumed, and the summary says so.
    let prov = &s["axes"]["C"]["trace"];
    assert_eq!(prov["actual"]["unit_source"], "Assumed", "{prov}");
    assert_eq!(s["axes"]["C"]["unit"], "deg");

    // predict uses the one model file for every axis. Its bound: the exact true models (the
    // analytic linear models of the true drives, Table 3 poles) predict the spiral's contour
    // error only up to what friction and the encoder add (a floor of about 0.18 µm, measured
    // here); models identified from the log must do as well, within one encoder increment
    // (0.1 µm). For scale: a model with ωn and p 0.5 % and ζ 1 % off leaves about 1.2 µm, one at
    // the 2 %/5 % pole tolerance 2.6–9 µm, of a 450 µm contour error.
    let truth = ModelSet {
        machine: "NMV5000 true drives".to_string(),
        description: Some("analytic closed-loop models of the true drives".to_string()),
        axes: {
            let machine = Machine::embedded_nmv5000().unwrap();
            machine
                .axes
                .iter()
                .map(|a| {
                    (
                        a.name.to_string(),
                        AxisModel::new(a.unit, &a.true_model().into()),
                    )
                })
                .collect::<BTreeMap<_, _>>()
        },
    };
    let truth_path = dir.path().join("truth.toml");
    std::fs::write(&truth_path, truth.to_toml_string().unwrap()).unwrap();
    let floor = spiral_discrepancy_um(&truth_path, &dir.path().join("pred-truth"));
    let d = spiral_discrepancy_um(&dir.path().join("id/model.toml"), &dir.path().join("pred"));
    eprintln!(
        "spiral contour discrepancy: halscope models {d:.3} µm, exact true models {floor:.3} µm"
    );
    assert!(floor < 0.5, "the true models' floor moved: {floor} µm");
    assert!(
        d <= floor + 0.1,
        "models from the log: {d} µm; exact true models: {floor} µm"
    );
}

#[test]
fn multi_axis_tncscope_file_in_um_and_two_cycle_times() {
    // A TNCscope export of X Y Z C recorded at 500 µs: the set points ("s soll") come at the
    // 1 ms interpolator cycle, C's actual position ("s ist") at the 500 µs position-controller
    // cycle (pairing takes it at C's set-point times), X's nominal velocity in mm/min beside
    // (listed, not used), Y in µm.
    let rec = recording_500us();
    let dir = tempdir();
    let path = dir.path().join("xyzc.DTA");
    let every2 = |v: &[f64], k: f64| v.iter().step_by(2).map(|p| p * k).collect::<Vec<_>>();
    let (x, y, z, c) = (
        rec.axis(AxisName::X),
        rec.axis(AxisName::Y),
        rec.axis(AxisName::Z),
        rec.axis(AxisName::C),
    );
    let (x_nom, x_act) = (every2(&x.nominal, 1.0), every2(&x.actual, 1.0));
    let (y_nom, y_act) = (every2(&y.nominal, 1e3), every2(&y.actual, 1e3));
    let (z_nom, z_act) = (every2(&z.nominal, 1.0), every2(&z.actual, 1.0));
    let c_nom = every2(&c.nominal, 1.0);
    // mm/min, by central differences over the 1 ms samples (one-sided at the ends).
    let n = x_nom.len();
    let x_vel: Vec<f64> = (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            (x_nom[b] - x_nom[a]) / ((b - a) as f64 * 1e-3) * 60.0
        })
        .collect();
    let curve = |name, channel_type, axis_type, dimension, cycle_us, samples| write::TncCurve {
        name,
        channel_type,
        axis_type,
        dimension,
        cycle_us,
        samples,
    };
    let curves = [
        curve("X s soll", "s soll", "X", "mm", 1000, &x_nom[..]),
        curve("X s ist", "s ist", "X", "mm", 1000, &x_act[..]),
        curve("X v soll", "v soll", "X", "mm/min", 1000, &x_vel[..]),
        curve("Y s soll", "s soll", "Y", "µm", 1000, &y_nom[..]),
        curve("Y s ist", "s ist", "Y", "µm", 1000, &y_act[..]),
        curve("Z s soll", "s soll", "Z", "mm", 1000, &z_nom[..]),
        curve("Z s ist", "s ist", "Z", "mm", 1000, &z_act[..]),
        curve("C s soll", "s soll", "C", "deg", 1000, &c_nom[..]),
        curve("C s ist", "s ist", "C", "deg", 500, &c.actual[..]),
    ];
    write::tncscope(&mut create(&path), "TNC 640", &curves).unwrap();

    let names: Vec<&str> = curves.iter().map(|c| c.name).collect();
    let info = trace_info(&path, &[], "Heidenhain TNCscope text export", &names);
    check_channel(&info, "Y s ist", ("Y", "ActualPosition", "µm", 1e-3, n));
    check_channel(
        &info,
        "X v soll",
        ("X", "NominalVelocity", "mm/min", 1e-3, n),
    );
    check_channel(&info, "C s soll", ("C", "NominalPosition", "deg", 1e-3, n));
    let n_fine = c.actual.len();
    check_channel(
        &info,
        "C s ist",
        ("C", "ActualPosition", "deg", 0.5e-3, n_fine),
    );

    let s = identify(&path, &dir.path().join("id"), &[]);
    let axes = [AxisName::X, AxisName::Y, AxisName::Z, AxisName::C];
    poles_match_truth("TNCscope", &s, &axes);
    let y_prov = &s["axes"]["Y"]["trace"];
    assert_eq!(y_prov["nominal"]["unit"], "µm", "{y_prov}");
    assert_eq!(y_prov["nominal"]["unit_source"], "File", "{y_prov}");
    assert_eq!(y_prov["nominal"]["factor"], 1e-3, "{y_prov}");
    let c_trace = &s["axes"]["C"]["trace"];
    assert_eq!(c_trace["resampled"], true, "{c_trace}");
    assert!((num(c_trace, "ts_s") - 1e-3).abs() < 1e-12, "{c_trace}");
    assert_eq!(c_trace["samples"], n, "{c_trace}");
    let model = std::fs::read_to_string(dir.path().join("id/model.toml")).unwrap();
    for a in axes {
        assert!(model.contains(&format!("[axes.{a}]")), "{model}");
    }
}

/// Runs `vcnc identify --trace FILE ARGS` expecting bad input: exit 2; returns stderr.
fn identify_refused(file: &Path, out: &Path, args: &[&str]) -> String {
    let mut a = vec![
        "identify",
        "--trace",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    a.extend_from_slice(args);
    let o = vcnc(&a);
    let (stdout, stderr) = text(&o);
    assert_eq!(
        o.status.code(),
        Some(2),
        "expected exit 2 (bad input):\nstdout:\n{stdout}\nstderr:\n{stderr}"
    );
    stderr
}

/// Rounds to `%f`'s six decimals (halsampler's output format).
fn six_decimals(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| (x * 1e6).round() / 1e6).collect()
}

#[test]
fn halscope_log_of_before_2_9_identifies_y() {
    // LinuxCNC ≤ 2.7 names joints `axis.N`; the log is `name value` pairs, one sample per line.
    let y = recording().axis(AxisName::Y);
    let dir = tempdir();
    let path = dir.path().join("y-pairs.log");
    let ferror: Vec<f64> = y
        .nominal
        .iter()
        .zip(&y.actual)
        .map(|(r, x)| r - x)
        .collect();
    let names = [
        "axis.1.motor-pos-cmd",
        "axis.1.motor-pos-fb",
        "axis.1.f-error",
    ];
    write::halscope_pairs(
        &mut create(&path),
        1_000_000,
        &names,
        &[&y.nominal, &y.actual, &ferror],
    )
    .unwrap();
    let info = trace_info(
        &path,
        &[],
        "LinuxCNC halscope log (name-value pairs, before 2.9)",
        &names,
    );
    let n = y.nominal.len();
    check_channel(
        &info,
        "axis.1.motor-pos-cmd",
        ("Y", "NominalPosition", "", 1e-3, n),
    );
    check_channel(&info, "axis.1.f-error", ("Y", "Other", "", 1e-3, n));
    let s = identify(&path, &dir.path().join("id"), &[]);
    poles_match_truth("halscope pairs", &s, &[AxisName::Y]);
}

#[test]
fn halsampler_output_identifies_z_with_its_period_given() {
    // halsampler -t: sample numbers, `%f` values, the sampled nets named in a first comment line;
    // the file states no period, so --ts gives the sampler thread's.
    let z = recording().axis(AxisName::Z);
    let dir = tempdir();
    let path = dir.path().join("z.txt");
    let (nom, act) = (six_decimals(&z.nominal), six_decimals(&z.actual));
    {
        use std::io::Write;
        let mut w = create(&path);
        writeln!(w, "# joint.2.motor-pos-cmd joint.2.motor-pos-fb").unwrap();
        write::halsampler(&mut w, true, &[&nom, &act], &[]).unwrap();
    }
    let names = ["joint.2.motor-pos-cmd", "joint.2.motor-pos-fb"];
    let info = trace_info(
        &path,
        &["--ts", "0.001"],
        "LinuxCNC halsampler output",
        &names,
    );
    check_channel(
        &info,
        names[1],
        ("Z", "ActualPosition", "", 1e-3, nom.len()),
    );
    // Without a period there is nothing to identify on: bad input.
    let err = identify_refused(&path, &dir.path().join("no-ts"), &[]);
    assert!(
        err.contains(&format!(
            "{}: channel 'joint.2.motor-pos-cmd' has no sample period",
            path.display()
        )),
        "{err}"
    );
    let s = identify(&path, &dir.path().join("id"), &["--ts", "0.001"]);
    poles_match_truth("halsampler", &s, &[AxisName::Z]);
}

/// A halsampler `-t` log of Z whose FIFO overflowed at `fraction` of Z's motion, 37 samples
/// lost (the sample numbers jump): refused by default (exit 2, naming the file and the overrun's
/// line), identified with `--gaps longest` on the longer stretch, checked against the truth.
/// Returns the summary and the number of samples before the gap.
fn overrun_case(fraction: f64) -> (Value, usize) {
    let z = recording().axis(AxisName::Z);
    let dir = tempdir();
    let path = dir.path().join("z-overrun.txt");
    let end = *z.nominal.last().unwrap();
    let moving = z.nominal.iter().rposition(|&v| v != end).unwrap();
    let (at, lost) = ((moving as f64 * fraction) as usize, 37);
    assert!(
        z.nominal[at] != z.nominal[at + 1],
        "the gap falls into a move"
    );
    let kept = |v: &[f64]| {
        let v = six_decimals(v);
        [&v[..at], &v[at + lost..]].concat()
    };
    let (nom, act) = (kept(&z.nominal), kept(&z.actual));
    {
        use std::io::Write;
        let mut w = create(&path);
        writeln!(w, "# joint.2.motor-pos-cmd joint.2.motor-pos-fb").unwrap();
        write::halsampler(&mut w, true, &[&nom, &act], &[(at, lost)]).unwrap();
    }
    // Line 1 is the names, sample k is on line k + 2; the `overrun` line comes before sample
    // `at`.
    let overrun_line = at + 2;
    let info = trace_info(&path, &["--ts", "0.001"], "LinuxCNC halsampler output", &[]);
    let ch = channel(&info, "joint.2.motor-pos-cmd");
    assert_eq!(
        (ch["gaps"].clone(), ch["lost"].clone()),
        (1.into(), lost.into()),
        "{ch}"
    );

    let err = identify_refused(&path, &dir.path().join("refused"), &["--ts", "0.001"]);
    let file = path.display().to_string();
    assert!(
        err.contains(&format!("{file}:{overrun_line}:")) && err.contains("37 samples lost"),
        "the message names the file, the overrun's line and the loss: {err}"
    );
    let s = identify(
        &path,
        &dir.path().join("longest"),
        &["--ts", "0.001", "--gaps", "longest"],
    );
    let t = &s["axes"]["Z"]["trace"];
    let (first, second) = (at, nom.len() - at);
    assert_eq!(t["samples"], first.max(second), "{t}");
    assert_eq!(t["segment"]["index"], usize::from(second > first), "{t}");
    assert_eq!(t["segment"]["of"], 2, "{t}");
    poles_match_truth(
        &format!(
            "halsampler, overrun at {:.0} % of the motion",
            100.0 * fraction
        ),
        &s,
        &[AxisName::Z],
    );
    (s, at)
}

#[test]
fn halsampler_overrun_is_refused_or_skipped_with_gaps_longest() {
    // Overrun late in the run: the stretch before it is the longer one and starts at rest.
    let (s, _) = overrun_case(0.85);
    assert_eq!(s["axes"]["Z"]["moving_start"], false);
}

#[test]
fn longest_stretch_that_starts_moving_is_identified() {
    // Overrun early in the run: the stretch after it is the longer one and starts in the middle
    // of a move. A regression test: the refinement's free run starts at rest, so it used to fit
    // the start transient (ζ +123 %, p +53 %); moving starts now leave their first 0.5 s out of
    // the fit (docs/identification.md).
    let (s, _) = overrun_case(0.40);
    assert_eq!(s["axes"]["Z"]["moving_start"], true);
}

#[test]
fn trace_sampled_at_3_ms_identifies_as_well_as_the_machine_route() {
    // The machine route identifies the NMV5000 at a 3 ms period within 0.4 % (X) and 1.6 % (C)
    // with the interpolator's exact reference velocity and acceleration; the same records as a
    // 3 ms halscope log (a trace carries no derivatives) gave X ζ +15 % and C ζ at its bound 1.0
    // while the model was driven by central differences; it is now driven by the first-order
    // hold of the logged positions. A control's scope often samples at 2-3 ms.
    let rec = record(Some(3e-3));
    let dir = tempdir();
    let path = dir.path().join("xyzac-3ms.log");
    let names: Vec<String> = (0..5)
        .flat_map(|j| {
            [
                format!("joint.{j}.motor-pos-cmd"),
                format!("joint.{j}.motor-pos-fb"),
            ]
        })
        .collect();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let columns: Vec<&[f64]> = rec
        .axes
        .iter()
        .flat_map(|a| [a.nominal.as_slice(), a.actual.as_slice()])
        .collect();
    write::halscope_table(&mut create(&path), 3_000_000, &names, &columns).unwrap();
    let s = identify(&path, &dir.path().join("id"), &["--joints", "XYZAC"]);
    poles_match_truth("halscope at 3 ms", &s, &xyzac());
}

#[test]
fn sinumerik_servo_trace_identifies_x() {
    // Sinumerik Operate servo trace of machine axis X1: set point, actual value of measuring
    // system 1 and following error, recorded at the 1 ms position-control cycle; records leave
    // out the values that did not change.
    let rec = recording();
    let x = rec.axis(AxisName::X);
    let dir = tempdir();
    let path = dir.path().join("x1.xml");
    let times: Vec<f64> = (0..x.nominal.len()).map(|k| k as f64 * rec.ts).collect();
    let ferror: Vec<f64> = x
        .nominal
        .iter()
        .zip(&x.actual)
        .map(|(r, a)| r - a)
        .collect();
    let signal = |id, name, description, samples| write::SinumerikSignal {
        id,
        name,
        description,
        unit: Some("mm"),
        samples,
    };
    let signals = [
        signal(
            1,
            "/Nck/ServoTrace/PositionSetpoint[X1]",
            "Position setpoint X1",
            &x.nominal[..],
        ),
        signal(
            2,
            "/Nck/ServoTrace/PositionActualValue1[X1]",
            "Position actual value measuring system 1 X1",
            &x.actual[..],
        ),
        signal(
            3,
            "/Nck/ServoTrace/FollowingError[X1]",
            "Following error X1",
            &ferror[..],
        ),
    ];
    write::sinumerik(&mut create(&path), &times, &signals).unwrap();
    let names: Vec<&str> = signals.iter().map(|s| s.description).collect();
    let info = trace_info(
        &path,
        &[],
        "Siemens Sinumerik Operate servo trace (XML)",
        &names,
    );
    let n = x.nominal.len();
    check_channel(&info, names[0], ("X", "NominalPosition", "mm", 1e-3, n));
    check_channel(&info, names[1], ("X", "ActualPosition", "mm", 1e-3, n));
    check_channel(&info, names[2], ("X", "Other", "mm", 1e-3, n));
    let s = identify(&path, &dir.path().join("id"), &[]);
    poles_match_truth("Sinumerik", &s, &[AxisName::X]);
}

#[test]
fn twincat_scope_export_with_decimal_comma_identifies_a() {
    // TwinCAT 3 Scope View export of NC axis A (`;` and decimal comma, a German Windows):
    // set and actual position and actual velocity, each with its own time column.
    let rec = recording();
    let a = rec.axis(AxisName::A);
    let dir = tempdir();
    let path = dir.path().join("axis-a.csv");
    let n = a.nominal.len();
    let vel: Vec<f64> = (0..n)
        .map(|k| {
            let (i, j) = (k.saturating_sub(1), (k + 1).min(n - 1));
            (a.actual[j] - a.actual[i]) / ((j - i) as f64 * rec.ts)
        })
        .collect();
    let channel = |name, symbol, unit, samples| write::TwinCatChannel {
        name,
        symbol,
        unit,
        sample_ms: 1.0,
        samples,
    };
    let channels = [
        channel(
            "SetPos_A",
            "MAIN.AxisA.NcToPlc.SetPos",
            "° (Degree)",
            &a.nominal[..],
        ),
        channel(
            "ActPos_A",
            "MAIN.AxisA.NcToPlc.ActPos",
            "° (Degree)",
            &a.actual[..],
        ),
        channel(
            "ActVelo_A",
            "MAIN.AxisA.NcToPlc.ActVelo",
            "°/s (Degree per second)",
            &vel[..],
        ),
    ];
    write::twincat(&mut create(&path), "axis_a", b';', true, &channels).unwrap();
    assert!(
        std::fs::read_to_string(&path).unwrap().contains("0,5"),
        "the file has decimal commas"
    );
    let names: Vec<&str> = channels.iter().map(|c| c.name).collect();
    let info = trace_info(&path, &[], "Beckhoff TwinCAT Scope CSV export", &names);
    check_channel(&info, "SetPos_A", ("A", "NominalPosition", "deg", 1e-3, n));
    check_channel(&info, "ActPos_A", ("A", "ActualPosition", "deg", 1e-3, n));
    check_channel(
        &info,
        "ActVelo_A",
        ("A", "ActualVelocity", "deg/s", 1e-3, n),
    );
    let s = identify(&path, &dir.path().join("id"), &[]);
    poles_match_truth("TwinCAT", &s, &[AxisName::A]);
}

#[test]
fn semicolon_text_with_decimal_comma_in_mdeg_identifies_c() {
    // A spreadsheet export: `;`, decimal comma, time in ms, C positions in mdeg (German names).
    let rec = recording();
    let c = rec.axis(AxisName::C);
    let dir = tempdir();
    let path = dir.path().join("c.csv");
    let t_ms: Vec<f64> = (0..c.nominal.len()).map(|k| k as f64).collect();
    let mdeg = |v: &[f64]| v.iter().map(|x| x * 1e3).collect::<Vec<_>>();
    let (nom, act) = (mdeg(&c.nominal), mdeg(&c.actual));
    let header = ["Zeit [ms]", "C Soll [mdeg]", "C Ist [mdeg]"];
    write::delimited(
        &mut create(&path),
        b';',
        true,
        Some(&header),
        &[&t_ms, &nom, &act],
    )
    .unwrap();
    let info = trace_info(&path, &[], "delimited text", &["C Soll", "C Ist"]);
    check_channel(
        &info,
        "C Soll",
        ("C", "NominalPosition", "mdeg", 1e-3, nom.len()),
    );
    check_channel(
        &info,
        "C Ist",
        ("C", "ActualPosition", "mdeg", 1e-3, nom.len()),
    );
    let s = identify(&path, &dir.path().join("id"), &[]);
    poles_match_truth("delimited ;", &s, &[AxisName::C]);
    assert_eq!(s["axes"]["C"]["trace"]["actual"]["factor"], 1e-3);
}

#[test]
fn real_twincat_exports_are_listed() {
    // The two TwinCAT 3 Scope exports of pytcs (BSD; crates/vcnc-trace/tests/data/twincat):
    // PLC test variables, no axis positions.
    let dir = repo("crates/vcnc-trace/tests/data/twincat");
    for (file, channels, first_period) in [
        ("tc3_scope_3_4_3145_3_noOS.csv", 19, 1e-3),
        ("tc3_scope_3_4_3145_3-DecimalMark_comma.csv", 21, 0.2e-3),
    ] {
        let path = dir.join(file);
        let info = trace_info(
            &path,
            &[],
            "Beckhoff TwinCAT Scope CSV export",
            &["var_BIT", "var_REAL64", "func_units_scaled", "dV (Voltage)"],
        );
        let list = info["channels"].as_array().unwrap();
        assert_eq!(list.len(), channels, "{file}");
        assert!(
            (num(&list[0], "period_s") / first_period - 1.0).abs() < 1e-9,
            "{file}"
        );
        let real64 = channel(&info, "var_REAL64");
        assert_eq!(real64["count"], 1000, "{file}");
        // Nothing in them is an axis position: identify says so (bad input, exit 2).
        let err = identify_refused(&path, &tempdir().path().join("id"), &[]);
        assert!(err.contains("no axis has both"), "{err}");
    }
}

/// vcnc reads the Parquet tables it writes: `simulate --format parquet` (what it writes by
/// default beyond 200 000 rows) identifies through `identify --trace` to the same model as the
/// CSV of the same run, bit for bit (truth: the delimited reader, tested above on every axis).
#[test]
fn simulate_parquet_identifies_as_its_csv() {
    let dir = tempdir();
    let d = dir.path();
    let program = d.join("id.ngc");
    let source = ok(&vcnc(&[
        "gen",
        "identification",
        "--moves",
        "40",
        "--seed",
        "3",
    ]));
    std::fs::write(&program, source).unwrap();
    let mut models = Vec::new();
    for format in ["csv", "parquet"] {
        let sim = d.join(format!("sim-{format}"));
        ok(&vcnc(&[
            "-q",
            "simulate",
            repo("machines/ballscrew-ppi.toml").to_str().unwrap(),
            program.to_str().unwrap(),
            "--out",
            sim.to_str().unwrap(),
            "--format",
            format,
        ]));
        let trace = sim.join(format!("trace.{format}"));
        let out = d.join(format!("id-{format}"));
        let summary = identify(&trace, &out, &[]);
        assert_eq!(
            summary["format"],
            if format == "csv" {
                "Delimited"
            } else {
                "Parquet"
            }
        );
        let model = std::fs::read_to_string(out.join("model.toml")).unwrap();
        // The first line names the trace file.
        models.push(model.lines().skip(1).collect::<Vec<_>>().join("\n"));
    }
    assert_eq!(models[0], models[1]);
}

/// Column `name` of a CSV file.
fn csv_column(path: &Path, name: &str) -> Vec<f64> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let i = r
        .headers()
        .unwrap()
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("{}: no column {name}", path.display()));
    r.records()
        .map(|rec| rec.unwrap()[i].parse().unwrap())
        .collect()
}

#[test]
fn an_identified_dead_time_moves_into_the_control_section_and_predicts_the_same() {
    // Truth: the ball-screw drive behind a control that delays its nominal position by 8 ms
    // ([control], the section this test reads back). `vcnc identify --trace` finds the dead
    // time inside the model and suggests the section; the machine with the suggested section
    // and the model changed as its comment says must predict, on another program, what the
    // identified model predicts on the machine without it — the same physics in two places
    // (a whole-period delay is the same shift in both: agreement to rounding).
    let dir = tempdir();
    let d = dir.path();
    let base = std::fs::read_to_string(repo("machines/ballscrew-ppi.toml")).unwrap();
    let machine = |name: &str, section: &str| {
        let p = d.join(name);
        std::fs::write(&p, format!("{base}\n{section}")).unwrap();
        p
    };
    let program_of = |seed: &str, file: &str| {
        let p = d.join(file);
        let src = ok(&vcnc(&[
            "gen",
            "identification",
            "--moves",
            "40",
            "--seed",
            seed,
        ]));
        std::fs::write(&p, src).unwrap();
        p
    };
    let delayed = machine("delayed.toml", "[control]\ndelay_s = 0.008\n");
    let program = program_of("11", "id.ngc");
    let sim = d.join("sim");
    ok(&vcnc(&[
        "-q",
        "simulate",
        delayed.to_str().unwrap(),
        program.to_str().unwrap(),
        "--out",
        sim.to_str().unwrap(),
    ]));
    let id = d.join("id");
    let s = identify(&sim.join("trace.csv"), &id, &[]);
    let section = s["axes"]["X"]["control_section"]
        .as_str()
        .expect("a suggested [control] section")
        .to_string();
    // Truth: the control's 8 ms, to within one sample period. A dead time trades, to first
    // order, with the model's feed-forward numerator: on this trace (1 ms samples, 0.1 µm
    // encoder steps, quantisation 0.029 µm RMS) the dead-time structure reaches the noise floor
    // at 7.43 ms with the smooth input (0.030 µm) and 8.33 ms with the hold (0.032 µm), while
    // the true drive with the true 8 ms gives 0.035 µm: the data do not decide the delay
    // within the period, though the reported deviation (0.015 ms) says they do (issue 30,
    // calibrated uncertainty). Which input is chosen there is a near-tie of the two paper
    // fits (0.1 %). The section must hold the identified delay's whole periods.
    let delay = s["axes"]["X"]["identified"]["delay_s"]
        .as_f64()
        .expect("the identified dead time");
    assert!((delay - 0.008).abs() < 0.001, "{delay} s");
    let whole = format!(
        "[control]\ndelay_s = {}\n",
        ((delay / 0.001 + 1e-9).floor() * 0.001 * 1e9).round() / 1e9
    );
    assert!(section.contains(&whole), "{section} against {whole}");
    // The model as the comment says: the delay's fraction of a period stays in it.
    let rest: f64 = section
        .lines()
        .next()
        .and_then(|l| l.split("delay_s = ").nth(1))
        .and_then(|v| v.parse().ok())
        .expect("the comment names the delay left in the model");
    let model = std::fs::read_to_string(id.join("model.toml")).unwrap();
    assert!(
        model.contains("delay_s = "),
        "the delay structure is chosen:\n{model}"
    );
    let core: String = model
        .lines()
        .map(|l| {
            if l.starts_with("delay_s = ") {
                format!("delay_s = {rest}")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(d.join("core.toml"), core).unwrap();
    let moved = machine("moved.toml", &section);

    let validation = program_of("12", "val.ngc");
    let predicted = |m: &Path, model: &Path, out: &str| {
        let out = d.join(out);
        ok(&vcnc(&[
            "-q",
            "simulate",
            m.to_str().unwrap(),
            validation.to_str().unwrap(),
            "--model",
            model.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]));
        csv_column(&out.join("trace.csv"), "X_model")
    };
    let a = predicted(
        &repo("machines/ballscrew-ppi.toml"),
        &id.join("model.toml"),
        "inside",
    );
    let b = predicted(&moved, &d.join("core.toml"), "in-front");
    assert_eq!(a.len(), b.len());
    let off = a
        .iter()
        .zip(&b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    eprintln!("model inside against [control] in front: {:.3e} mm", off);
    // The suggestion rounds the delay's fraction to 7 digits (1e-10 s × 250 mm/s).
    assert!(off < 1e-6, "{off} mm");
}
