//! Reports (issue 16): every computing command leaves `manifest.json` and a self-contained
//! `report.html` in its folder, listing figures that exist; `vcnc report DIR` rebuilds the same
//! page from the folder alone and refuses a folder it cannot read (exit 2, naming the file);
//! the demo's report renders in headless Chromium (installed by the test script when missing);
//! the demo's `toolpath.vtp` reads back in an independent VTK reader (vtkio) and holds exactly
//! the tool path and errors of `contour.csv`.

use std::path::Path;

use crate::util::{json, ok, repo, tempdir, text, vcnc};

#[path = "../crates/vcnc-report/tests/support/chromium.rs"]
mod chromium;

/// Checks a command's folder: the manifest lists figures and files that exist, the report
/// inlines every figure, and `vcnc report DIR` rebuilds it byte for byte. Returns the figure
/// files, in report order.
fn check_folder(dir: &Path, want_figures: &[&str]) -> Vec<String> {
    let manifest = crate::util::json(&dir.join("manifest.json"));
    assert_eq!(manifest["manifest_version"], 1, "{}", dir.display());
    assert!(
        manifest["command"].as_str().unwrap().starts_with("vcnc "),
        "{}",
        manifest["command"]
    );
    assert_eq!(manifest["version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(manifest["summary"], "summary.json", "{}", dir.display());
    let figures: Vec<String> = manifest["figures"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["file"].as_str().unwrap().to_string())
        .collect();
    for want in want_figures {
        assert!(
            figures.iter().any(|f| f == want),
            "{}: {want} not among {figures:?}",
            dir.display()
        );
    }
    for f in manifest["figures"].as_array().unwrap() {
        let file = dir.join(f["file"].as_str().unwrap());
        let svg =
            std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        assert!(svg.contains("<svg") && svg.ends_with("</svg>\n") || svg.ends_with("</svg>"));
        assert!(
            f["caption"].as_str().unwrap().len() > 40,
            "{}: a caption that says what the figure shows",
            file.display()
        );
        // One style: units with a real µ, never "um" or "[um]" on an axis.
        assert!(
            !svg.contains("[um]") && !svg.contains("(um)"),
            "{}",
            file.display()
        );
    }
    for f in manifest["files"].as_array().unwrap() {
        let file = dir.join(f["file"].as_str().unwrap());
        assert!(file.is_file(), "listed file {} missing", file.display());
    }
    let report = dir.join("report.html");
    let html = std::fs::read_to_string(&report).unwrap();
    assert_eq!(
        html.matches("<figure id=").count(),
        figures.len(),
        "{}: every figure inlined",
        report.display()
    );
    assert!(!html.contains("<script"));
    // `vcnc report DIR` rebuilds the same page.
    std::fs::remove_file(&report).unwrap();
    ok(&vcnc(&["--quiet", "report", dir.to_str().unwrap()]));
    assert_eq!(std::fs::read_to_string(&report).unwrap(), html);
    figures
}

#[test]
fn every_computing_command_writes_a_report_that_vcnc_report_rebuilds() {
    let tmp = tempdir();
    let d = |name: &str| tmp.path().join(name);
    let s = |p: &Path| p.to_str().unwrap().to_string();

    ok(&vcnc(&[
        "-q",
        "interpolate",
        "machines/nmv5000.toml",
        "gcode/spiral.ngc",
        "--out",
        &s(&d("interpolate")),
    ]));
    check_folder(&d("interpolate"), &["reference.svg"]);

    ok(&vcnc(&[
        "-q",
        "identify",
        "machines/ballscrew-ppi.toml",
        "--out",
        &s(&d("identify")),
    ]));
    check_folder(
        &d("identify"),
        &["frf_X.svg", "pso_X.svg", "validation_X.svg"],
    );

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
        &s(&d("identify-trace")),
    ]));
    check_folder(
        &d("identify-trace"),
        &["frf_X.svg", "pso_X.svg", "validation_X.svg"],
    );
    // A measured trace has no true machine: its truth is the measurement.
    let v = std::fs::read_to_string(d("identify-trace").join("validation_X.svg")).unwrap();
    assert!(v.contains("measurement") && !v.contains("true machine"));

    let model = d("identify").join("model.toml");
    ok(&vcnc(&[
        "-q",
        "simulate",
        "machines/ballscrew-ppi.toml",
        "gcode/identification-X.ngc",
        "--model",
        &s(&model),
        "--out",
        &s(&d("simulate")),
    ]));
    check_folder(&d("simulate"), &["tracking.svg"]);

    ok(&vcnc(&[
        "-q",
        "frf",
        "machines/nmv5000.toml",
        "--out",
        &s(&d("frf")),
    ]));
    check_folder(
        &d("frf"),
        &[
            "frf_X.svg",
            "frf_Y.svg",
            "frf_Z.svg",
            "frf_A.svg",
            "frf_C.svg",
        ],
    );
    // The disturbance response has its phase (issue 16).
    let f = std::fs::read_to_string(d("frf").join("frf_X.svg")).unwrap();
    assert!(f.contains("disturbance x/d (d: acceleration): phase"));

    // A 3-axis program on the 5-axis machine: only X and Y get tracking panels.
    let prog = d("square.ngc");
    std::fs::write(
        &prog,
        "G0 X0 Y0 Z0 A0 C0\nG1 X40 F3000\nG1 Y30\nG1 X0\nG1 Y0\nM2\n",
    )
    .unwrap();
    ok(&vcnc(&[
        "-q",
        "predict",
        "machines/nmv5000.toml",
        &s(&prog),
        "--out",
        &s(&d("predict")),
    ]));
    check_folder(
        &d("predict"),
        &[
            "toolpath_contour.svg",
            "contour_error.svg",
            "tracking_errors.svg",
        ],
    );
    let t = std::fs::read_to_string(d("predict").join("tracking_errors.svg")).unwrap();
    assert!(t.contains("axis X") && t.contains("axis Y"));
    assert!(!t.contains("axis Z") && !t.contains("axis A") && !t.contains("axis C"));
    assert!(t.contains("not shown: Z, A, C"));
    // The worst blocks are marked by the program's line numbers (G1 blocks on lines 2 to 5).
    let path = std::fs::read_to_string(d("predict").join("toolpath_contour.svg")).unwrap();
    assert!(
        ["L2", "L3", "L4", "L5"].iter().any(|l| path.contains(l)),
        "no block line marked"
    );

    // Streamed (docs/performance.md#streamed-prediction): the same table and summary byte for
    // byte, the errors against time drawn from their envelopes.
    ok(&vcnc(&[
        "-q",
        "predict",
        "machines/nmv5000.toml",
        &s(&prog),
        "--stream",
        "--out",
        &s(&d("predict-stream")),
    ]));
    check_folder(&d("predict-stream"), &["contour_error.svg"]);
    let read = |dir: &str| std::fs::read(d(dir).join("contour.csv")).unwrap();
    assert!(
        read("predict") == read("predict-stream"),
        "contour.csv differs when streamed"
    );
    // The summary too, but for the bytes of the figures (streamed, there is one figure).
    let summary = |dir: &str| {
        let mut v = json(&d(dir).join("summary.json"));
        v.as_object_mut().unwrap().remove("output_bytes");
        v
    };
    assert_eq!(summary("predict"), summary("predict-stream"));

    for (dir, extra) in [("simulate", None), ("simulate-stream", Some("--stream"))] {
        let mut args = vec![
            "-q".to_string(),
            "simulate".into(),
            "machines/nmv5000-realistic.toml".into(),
            s(&prog),
            "--out".into(),
            s(&d(dir)),
        ];
        args.extend(extra.map(String::from));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        ok(&vcnc(&args));
    }
    check_folder(&d("simulate-stream"), &["tracking.svg"]);
    for f in ["trace.csv", "summary.json"] {
        let read = |dir: &str| std::fs::read(d(dir).join(f)).unwrap();
        assert!(
            read("simulate") == read("simulate-stream"),
            "{f} differs when streamed"
        );
    }

    let set1 = "axes.X.controller.vff=0.3,0.5,0.7";
    ok(&vcnc(&[
        "-q",
        "sweep",
        "machines/nmv5000.toml",
        "gcode/spiral.ngc",
        "--set",
        set1,
        "--out",
        &s(&d("sweep1")),
    ]));
    check_folder(&d("sweep1"), &["sweep_axes_X_controller_vff.svg"]);

    for i in 1..=2 {
        ok(&vcnc(&[
            "-q",
            "sweep",
            "machines/nmv5000.toml",
            "gcode/spiral.ngc",
            "--set",
            "axes.X.controller.vff=0.3,0.7",
            "--set",
            "axes.Y.controller.design.wn_hz=60,90",
            "--shard",
            &format!("{i}/2"),
            "--out",
            &s(&d(&format!("shard{i}"))),
        ]));
        check_folder(&d(&format!("shard{i}")), &["sweep_map.svg"]);
    }
    ok(&vcnc(&[
        "-q",
        "sweep-merge",
        &s(&d("shard1")),
        &s(&d("shard2")),
        "--out",
        &s(&d("merged")),
    ]));
    check_folder(&d("merged"), &["sweep_map.svg"]);
    assert!(!d("merged").join("sweep_axes_X_controller_vff.svg").exists());
}

#[test]
fn vcnc_report_refuses_a_folder_it_cannot_read() {
    let tmp = tempdir();
    let dir = tmp.path();
    let run = |d: &Path| vcnc(&["report", d.to_str().unwrap()]);
    // No manifest.
    let o = run(dir);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("manifest.json"), "{err}");
    // A malformed manifest: line and column.
    std::fs::write(
        dir.join("manifest.json"),
        "{\n  \"manifest_version\": 1,\n  oops\n}\n",
    )
    .unwrap();
    let o = run(dir);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("manifest.json:3:"), "{err}");
    // A manifest naming a figure the folder does not hold.
    std::fs::write(
        dir.join("manifest.json"),
        r#"{"manifest_version": 1, "title": "t", "command": "c", "version": "v",
            "figures": [{"file": "gone.svg", "caption": "c"}]}"#,
    )
    .unwrap();
    let o = run(dir);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("gone.svg"), "{err}");
    // A manifest naming a summary that is missing.
    std::fs::write(
        dir.join("manifest.json"),
        r#"{"manifest_version": 1, "title": "t", "command": "c", "version": "v",
            "summary": "summary.json"}"#,
    )
    .unwrap();
    let o = run(dir);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("summary.json"), "{err}");
    assert!(!dir.join("report.html").exists());
}

/// A numeric CSV column by name.
fn csv_column(text: &str, name: &str) -> Vec<f64> {
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let i = header
        .iter()
        .position(|h| *h == name)
        .unwrap_or_else(|| panic!("no column {name}"));
    lines
        .map(|l| l.split(',').nth(i).unwrap().parse().unwrap())
        .collect()
}

#[test]
fn demo_report_renders_in_chromium_and_its_vtp_reads_back() {
    let tmp = tempdir();
    let out = tmp.path().join("demo");
    ok(&vcnc(&["-q", "demo", "--out", out.to_str().unwrap()]));
    let figures = check_folder(
        &out,
        &[
            "toolpath_contour.svg",
            "contour_error.svg",
            "tracking_errors.svg",
            "identify/frf_X.svg",
            "identify/pso_C.svg",
            "identify/validation_A.svg",
        ],
    );
    check_folder(
        &out.join("identify"),
        &["frf_X.svg", "pso_X.svg", "validation_X.svg"],
    );
    // Contour views: the 99.5th-percentile scale stated, the worst blocks marked by line.
    let path = std::fs::read_to_string(out.join("toolpath_contour.svg")).unwrap();
    assert!(path.contains("99.5th percentile"), "scale clip not stated");
    assert!(path.contains(">L"), "no worst block marked");

    // The report in a real browser.
    let exe = chromium::ensure_chromium(&repo("crates/vcnc-report/tests/ensure-chromium.sh"));
    let work = tmp.path().join("chromium");
    std::fs::create_dir_all(&work).unwrap();
    // Screenshots of at most 6000 px: the page (about 15 000 px) is checked in several passes,
    // the later ones with the figures already checked hidden.
    let passes = chromium::check_report(&exe, &out.join("report.html"), &work, &figures, 6000);
    assert!(passes >= 2, "{passes} passes");

    // The .vtp, read back by vtkio, holds exactly the true tool path and errors of contour.csv
    // (whose numbers are written in their shortest exact form).
    use vtkio::model::{Attribute, DataSet, IOBuffer, Piece, VertexNumbers};
    let csv = std::fs::read_to_string(out.join("contour.csv")).unwrap();
    let n = csv_column(&csv, "t").len();
    let bytes = std::fs::read(out.join("toolpath.vtp")).unwrap();
    let vtk = vtkio::Vtk::parse_xml(std::io::BufReader::new(bytes.as_slice()))
        .expect("vtkio parses toolpath.vtp");
    let DataSet::PolyData { pieces, .. } = vtk.data else {
        panic!("not PolyData");
    };
    let Piece::Inline(p) = &pieces[0] else {
        panic!("piece not inline");
    };
    let f64s = |b: &IOBuffer| match b {
        IOBuffer::F64(v) => v.clone(),
        other => panic!("expected Float64, got {other:?}"),
    };
    let interleave = |prefix: &str| -> Vec<f64> {
        let c: Vec<Vec<f64>> = ["x", "y", "z"]
            .iter()
            .map(|a| csv_column(&csv, &format!("{prefix}{a}")))
            .collect();
        (0..n).flat_map(|k| [c[0][k], c[1][k], c[2][k]]).collect()
    };
    assert_eq!(
        f64s(&p.points),
        interleave("true_p"),
        "points: the true tool tip"
    );
    match p.lines.as_ref().expect("lines") {
        VertexNumbers::XML { offsets, .. } => assert_eq!(offsets, &vec![n as u64]),
        other => panic!("unexpected cell layout {other:?}"),
    }
    let array = |name: &str| {
        p.data
            .point
            .iter()
            .find_map(|a| match a {
                Attribute::DataArray(d) if d.name == name => Some(d.data.clone()),
                _ => None,
            })
            .unwrap_or_else(|| panic!("array {name} missing"))
    };
    assert_eq!(
        f64s(&array("contour_error_um")),
        csv_column(&csv, "true_contour_um")
    );
    assert_eq!(
        f64s(&array("orientation_error_mrad")),
        csv_column(&csv, "true_orientation_mrad")
    );
    assert_eq!(
        f64s(&array("vcnc_model_contour_error_um")),
        csv_column(&csv, "pred_contour_um")
    );
    assert_eq!(f64s(&array("tool_axis")), interleave("true_o"));
    // Block lines: lines of the spiral that hold a motion block, in program order.
    let spiral = std::fs::read_to_string(repo("gcode/spiral.ngc")).unwrap();
    let motion: Vec<u32> = spiral
        .lines()
        .enumerate()
        .filter(|(_, l)| l.starts_with("G1") || l.starts_with("G0"))
        .map(|(i, _)| i as u32 + 1)
        .collect();
    let lines = array("block_line").cast_into::<u32>().unwrap();
    assert_eq!(lines.len(), n);
    assert!(
        lines.windows(2).all(|w| w[0] <= w[1]),
        "block lines in program order"
    );
    for l in &lines {
        assert!(
            motion.contains(l),
            "line {l} of spiral.ngc is not a motion block"
        );
    }
}
