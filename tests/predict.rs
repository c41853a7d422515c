//! `vcnc predict` says where and why (issue 28 items 4–6): the worst blocks in the terminal
//! and in summary.json with their G-code, feeds, axis and flags; outputs that `--decimate` and
//! `--outputs` size; `--tool-table`; a program without motion refused.

use std::path::Path;

use crate::util::{json, ok, tempdir, text, vcnc};

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// A diagonal out and back at 600 mm/min around one diagonal at 6000 mm/min (line 3): ten
/// times the speed gives the X/Y lag mismatch, and so the contour error, about ten times the
/// size, so line 3 is the worst block by construction. Y turns round at its start (a
/// reversal) and the path turns by 90° there (a sharp corner).
const DIAGONALS: &str =
    "G0 X0 Y0 Z0 A0 C0\nG1 X20 Y20 F600\nG1 X40 Y0 F6000\nG1 X20 Y-20 F600\nM2\n";

fn predict(dir: &Path, name: &str, extra: &[&str]) -> (std::process::Output, std::path::PathBuf) {
    let prog = dir.join("diagonals.ngc");
    std::fs::write(&prog, DIAGONALS).unwrap();
    let out = dir.join(name);
    let mut args = vec![
        "predict".to_string(),
        "machines/nmv5000.toml".into(),
        s(&prog),
        "--out".into(),
        s(&out),
    ];
    args.extend(extra.iter().map(|a| a.to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    (vcnc(&args), out)
}

#[test]
fn worst_blocks_say_where_and_why_in_the_terminal_and_the_summary() {
    let dir = tempdir();
    let (o, out) = predict(dir.path(), "p", &[]);
    let stdout = ok(&o);
    // The terminal table: the worst line first, with its G-code, move kind and flags.
    let table = stdout
        .split("worst blocks (true machine):\n")
        .nth(1)
        .expect("a worst-blocks table");
    let first = table.lines().nth(2).expect("a first row");
    assert!(first.starts_with("3 "), "{first}");
    for word in ["G1 X40 Y0 F6000", "cutting", "reversal", "sharp corner"] {
        assert!(first.contains(word), "{word} missing in {first}");
    }
    // The same table in report.html: a real table whose first row is that line, not a JSON
    // dump.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let section = html
        .split("worst blocks (true machine)")
        .nth(1)
        .expect("a worst-blocks table in report.html");
    let first_row = section
        .split("<tbody>")
        .nth(1)
        .and_then(|b| b.split("</tr>").next())
        .expect("a first row");
    for cell in [">3<", "G1 X40 Y0 F6000", "cutting", "sharp corner"] {
        assert!(first_row.contains(cell), "{cell} missing in {first_row}");
    }
    let summary = json(&out.join("summary.json"));
    let w = &summary["worst_blocks"][0];
    assert_eq!(w["line"], 3);
    assert_eq!(w["text"], "G1 X40 Y0 F6000");
    assert_eq!(w["kind"], "cutting");
    // The planner reaches the programmed 6000 mm/min on 28 mm (its peak tool-tip speed over
    // the block is 6242 mm/min, 4 % above F, where the block blends into the next one), and
    // the true machine follows it to within a few per cent.
    let planned = w["planned_feed_mm_min"].as_f64().unwrap();
    let achieved = w["achieved_feed_mm_min"].as_f64().unwrap();
    assert!((planned / 6000.0 - 1.0).abs() < 0.05, "{planned}");
    assert!(
        (achieved / planned - 1.0).abs() < 0.05,
        "{achieved} vs {planned}"
    );
    let axis = w["axis"].as_str().unwrap();
    assert!(axis == "X" || axis == "Y", "{axis}");
    assert!(w["axis_share_um"].as_f64().unwrap() > 0.0);
    assert_eq!(w["flags"]["axis_reversal"], true);
    assert_eq!(w["flags"]["rotary_unwinding"], false);
    // The slow blocks rank below, ten times smaller or less.
    let second = summary["worst_blocks"][1]["contour_max_um"]
        .as_f64()
        .unwrap();
    assert!(second < 0.5 * w["contour_max_um"].as_f64().unwrap());
    // The bytes written are reported, and match the files.
    let bytes = &summary["output_bytes"];
    let vtp = std::fs::metadata(out.join("toolpath.vtp")).unwrap().len();
    assert_eq!(bytes["toolpath.vtp"].as_u64().unwrap(), vtp);
    assert!(stdout.contains("written)"), "{stdout}");
}

#[test]
fn decimate_shrinks_every_per_sample_output_and_outputs_chooses_them() {
    let dir = tempdir();
    let (full, full_dir) = predict(dir.path(), "full", &["-q", "--decimate", "1"]);
    ok(&full);
    let (dec, dec_dir) = predict(dir.path(), "dec", &["-q", "--decimate", "10"]);
    ok(&dec);
    let size = |d: &Path, f: &str| std::fs::metadata(d.join(f)).unwrap().len() as f64;
    for f in ["contour.csv", "toolpath.vtp"] {
        let ratio = size(&dec_dir, f) / size(&full_dir, f);
        assert!(ratio < 0.2, "{f}: decimated {ratio} of the full size");
    }
    // The statistics are of every sample either way.
    let (a, b) = (
        json(&full_dir.join("summary.json")),
        json(&dec_dir.join("summary.json")),
    );
    assert_eq!(a["contour_um"], b["contour_um"]);
    assert_eq!(b["decimate"], 10);

    let (only_table, t_dir) = predict(dir.path(), "tables", &["-q", "--outputs", "tables"]);
    ok(&only_table);
    assert!(t_dir.join("contour.csv").is_file() && t_dir.join("summary.json").is_file());
    for f in [
        "toolpath.vtp",
        "report.html",
        "manifest.json",
        "contour_error.svg",
    ] {
        assert!(
            !t_dir.join(f).exists(),
            "{f} written without being asked for"
        );
    }
    let (vtp, v_dir) = predict(dir.path(), "vtp", &["-q", "--outputs", "vtp,report"]);
    ok(&vtp);
    assert!(v_dir.join("toolpath.vtp").is_file() && v_dir.join("report.html").is_file());
    for f in ["contour.csv", "contour_error.svg", "toolpath_contour.svg"] {
        assert!(
            !v_dir.join(f).exists(),
            "{f} written without being asked for"
        );
    }
    let (bad, _) = predict(dir.path(), "bad", &["--outputs", "tables,movies"]);
    assert_eq!(bad.status.code(), Some(2));
}

#[test]
fn tool_table_gives_g43_its_tool_length() {
    let dir = tempdir();
    let prog = dir.path().join("g43.ngc");
    std::fs::write(
        &prog,
        "G0 X0 Y0 Z0 A0 C0\nT1 M6\nG43 H1\nG0 Z10\nG1 X10 F1000\nM2\n",
    )
    .unwrap();
    let tbl = dir.path().join("tools.tbl");
    std::fs::write(&tbl, "T1 P1 Z5.0 D10 ;end mill\n").unwrap();
    let out = dir.path().join("i");
    // `vcnc <args…>`, with `--tool-table t` when given.
    let with_table = |mut a: Vec<String>, t: Option<&Path>| {
        if let Some(t) = t {
            a.extend(["--tool-table".into(), s(t)]);
        }
        a
    };
    let args = |t: Option<&Path>| {
        let a = [
            "interpolate",
            "machines/nmv5000.toml",
            &s(&prog),
            "--out",
            &s(&out),
        ];
        with_table(a.map(String::from).to_vec(), t)
    };
    let run = |a: Vec<String>| vcnc(&a.iter().map(String::as_str).collect::<Vec<_>>());
    // Without a table, G43 H1 is an error naming the tool.
    let o = run(args(None));
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).1.contains("tool 1"), "{}", text(&o).1);
    // With it, Z ends 5 mm higher than programmed (Z10 + tool length 5).
    ok(&run(args(Some(&tbl))));
    let csv = std::fs::read_to_string(out.join("reference.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let z = header.iter().position(|h| *h == "Z").unwrap();
    let last: Vec<&str> = csv.lines().last().unwrap().split(',').collect();
    let z_end: f64 = last[z].parse().unwrap();
    assert!((z_end - 15.0).abs() < 1e-9, "{z_end}");
    // A sweep reads the same table in every configuration; without it G43 H1 is refused.
    let sweep = |t: Option<&Path>| {
        let a = [
            "sweep",
            "machines/nmv5000.toml",
            &s(&prog),
            "--set",
            "axes.X.controller.vff=0.5,0.7",
            "--quiet",
            "--out",
            &s(&dir.path().join("sweep")),
        ];
        run(with_table(a.map(String::from).to_vec(), t))
    };
    let o = sweep(None);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).1.contains("tool 1"), "{}", text(&o).1);
    ok(&sweep(Some(&tbl)));
    let rows = std::fs::read_to_string(dir.path().join("sweep/sweep.csv")).unwrap();
    assert_eq!(rows.lines().count(), 3, "{rows}");
    assert!(rows.lines().skip(1).all(|r| r.ends_with(",ok")), "{rows}");
    // A wrong line of the table is bad input naming the file and line.
    std::fs::write(&tbl, "T1 P1 Z5.0\nT2 P2 Zfive\n").unwrap();
    let o = run(args(Some(&tbl)));
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).1.contains("tools.tbl:2"), "{}", text(&o).1);
    // A command that reads no program refuses it.
    let o = vcnc(&["frf", "machines/nmv5000.toml", "--tool-table", &s(&tbl)]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn a_program_without_motion_is_a_warning_and_refused_by_predict() {
    let dir = tempdir();
    for (name, body) in [("empty.ngc", ""), ("still.ngc", "G21 G90\nG4 P0.1\nM2\n")] {
        let prog = dir.path().join(name);
        std::fs::write(&prog, body).unwrap();
        let o = vcnc(&[
            "predict",
            "machines/nmv5000.toml",
            &s(&prog),
            "--out",
            &s(&dir.path().join("p")),
        ]);
        let err = text(&o).1;
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(name) && err.contains("moves no axis"), "{err}");
        let o = vcnc(&[
            "interpolate",
            "machines/nmv5000.toml",
            &s(&prog),
            "--out",
            &s(&dir.path().join("i")),
        ]);
        ok(&o);
        assert!(text(&o).1.contains("moves no axis"), "{name}");
    }
}
