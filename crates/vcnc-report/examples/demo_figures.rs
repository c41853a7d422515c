//! The demo's figures redrawn with vcnc-report, from the files `vcnc demo` writes (the
//! before/after comparison of the house style):
//!
//! ```text
//! cargo run --release -- demo --out /tmp/demo-before
//! cargo run --release -p vcnc-report --example demo_figures -- /tmp/demo-before gcode/spiral.ngc /tmp/demo-after
//! ```
//!
//! Reads `contour.csv` (reference, true and predicted axis positions, tool poses and errors per
//! sample), `identify/frf_X.csv` and `summary.json`; writes `tracking_errors.svg`,
//! `contour_error.svg`, `toolpath_contour.svg`, `frf_X.svg`, `path.vtp`, `manifest.json` and
//! `report.html`. The CSV carries no block line numbers, so this example assigns each sample
//! the G1 block of the program whose cumulative path length it has reached (an approximation
//! good to a block; the commands pass the interpreter's own line numbers).

use std::path::{Path, PathBuf};

use vcnc_axis::AxisName;
use vcnc_report::vtp::{VtpEncoding, VtpPath, write_vtp};
use vcnc_report::*;

type Res<T> = Result<T, String>;

/// A numeric CSV: header names and columns.
struct Csv {
    header: Vec<String>,
    cols: Vec<Vec<f64>>,
}

impl Csv {
    fn read(path: &Path) -> Res<Csv> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut lines = text.lines().filter(|l| !l.starts_with('#'));
        let header: Vec<String> = lines
            .next()
            .ok_or(format!("{}: empty", path.display()))?
            .split(',')
            .map(|s| s.trim().to_string())
            .collect();
        let mut cols = vec![Vec::new(); header.len()];
        for (i, l) in lines.enumerate() {
            for (j, cell) in l.split(',').enumerate() {
                let v: f64 = cell
                    .trim()
                    .parse()
                    .map_err(|e| format!("{}:{}: column {}: {e}", path.display(), i + 2, j + 1))?;
                cols.get_mut(j)
                    .ok_or(format!("{}:{}: too many columns", path.display(), i + 2))?
                    .push(v);
            }
        }
        Ok(Csv { header, cols })
    }

    fn col(&self, name: &str) -> Res<&[f64]> {
        self.header
            .iter()
            .position(|h| h == name)
            .map(|i| self.cols[i].as_slice())
            .ok_or(format!("no column {name}"))
    }

    fn xyz(&self, prefix: &str) -> Res<Vec<[f64; 3]>> {
        let (x, y, z) = (
            self.col(&format!("{prefix}x"))?,
            self.col(&format!("{prefix}y"))?,
            self.col(&format!("{prefix}z"))?,
        );
        Ok((0..x.len()).map(|k| [x[k], y[k], z[k]]).collect())
    }
}

/// Line number of each G1 block and the path length at its end.
fn block_ends(program: &Path) -> Res<Vec<(u32, f64)>> {
    let text =
        std::fs::read_to_string(program).map_err(|e| format!("{}: {e}", program.display()))?;
    let mut last: Option<[f64; 3]> = None;
    let mut s = 0.0;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let mut p = last.unwrap_or([0.0; 3]);
        let mut has = false;
        for w in &words {
            let (k, v) = w.split_at(1);
            let idx = match k {
                "X" => 0,
                "Y" => 1,
                "Z" => 2,
                _ => continue,
            };
            if let Ok(v) = v.parse::<f64>() {
                p[idx] = v;
                has = true;
            }
        }
        if !has {
            continue;
        }
        if let Some(q) = last
            && words.first() == Some(&"G1")
        {
            s += ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
            out.push((i as u32 + 1, s));
        }
        last = Some(p);
    }
    Ok(out)
}

fn run(demo: &Path, program: &Path, out: &Path) -> Res<()> {
    let e = |e: Error| e.to_string();
    let c = Csv::read(&demo.join("contour.csv"))?;
    let t = c.col("t")?;
    // 1. Tracking errors of every axis (µm, mdeg), truth and model.
    let mut errs = Vec::new();
    for a in [
        AxisName::X,
        AxisName::Y,
        AxisName::Z,
        AxisName::A,
        AxisName::C,
    ] {
        let r = c.col(&format!("{a}_ref"))?;
        let tr = c.col(&format!("{a}_true"))?;
        let pr = c.col(&format!("{a}_pred"))?;
        let k = a.unit().micro_factor();
        let et: Vec<f64> = r.iter().zip(tr).map(|(r, x)| (r - x) * k).collect();
        let ep: Vec<f64> = r.iter().zip(pr).map(|(r, x)| (r - x) * k).collect();
        errs.push((a, r, et, ep));
    }
    let axes: Vec<AxisErrors> = errs
        .iter()
        .map(|(a, r, et, ep)| AxisErrors {
            axis: *a,
            reference: r,
            truth: Series::line("true machine", Role::TrueMachine, t, et),
            models: vec![Series::line("vcnc model", Role::Model, t, ep)],
        })
        .collect();
    let mut manifest = Manifest::new(
        "vcnc demo (redrawn): NMV5000 + spiral",
        format!("demo_figures {} {}", demo.display(), program.display()),
        env!("CARGO_PKG_VERSION"),
    );
    let mut add = |f: Figure, file: &str, caption: &str, section: &str| -> Res<()> {
        f.save(&out.join(file)).map_err(e)?;
        manifest.figures.push(FigureEntry {
            file: file.into(),
            caption: caption.into(),
            section: section.into(),
        });
        Ok(())
    };
    add(
        tracking_errors("spiral: tracking errors x_r − x per axis", &axes).map_err(e)?,
        "tracking_errors.svg",
        "Tracking error of each axis, true 20 kHz drive and identified model, and their difference.",
        "Prediction",
    )?;

    // 2. Errors along the path.
    let ref_p = c.xyz("ref_p")?;
    let s = arc_length_mm(&ref_p);
    let ends = block_ends(program)?;
    let lines: Vec<u32> = s
        .iter()
        .map(|v| {
            let j = ends
                .partition_point(|(_, e)| e < v)
                .min(ends.len().saturating_sub(1));
            ends.get(j).map_or(0, |b| b.0)
        })
        .collect();
    let (ct, cp) = (c.col("true_contour_um")?, c.col("pred_contour_um")?);
    let (ot, op) = (
        c.col("true_orientation_mrad")?,
        c.col("pred_orientation_mrad")?,
    );
    add(
        error_along_path(
            "spiral: contour and orientation errors along the path",
            &PathErrors {
                arc_length_mm: &s,
                contour_truth: Series::line("true machine", Role::TrueMachine, &s, ct),
                contour_models: vec![Series::line("vcnc model", Role::Model, &s, cp)],
                orientation_truth: Series::line("true machine", Role::TrueMachine, &s, ot),
                orientation_models: vec![Series::line("vcnc model", Role::Model, &s, op)],
                block_line: Some(&lines),
                worst_blocks: 5,
                points_mm: None,
            },
        )
        .map_err(e)?,
        "contour_error.svg",
        "Tool-tip contour error and orientation error against arc length, each with model − truth.",
        "Contour errors",
    )?;

    // 3. The path in 3-D coloured by the true contour error.
    let true_p = c.xyz("true_p")?;
    add(
        contour_path_views(
            "spiral: tool-tip path coloured by the true contour error",
            &ColouredPath {
                points_mm: &true_p,
                values: ct,
                value: Quantity::new("contour error", "µm"),
                block_line: Some(&lines),
            },
            &PathViewOptions::default(),
        )
        .map_err(e)?,
        "toolpath_contour.svg",
        "The tool-tip path (workpiece frame) coloured by the contour error of the true machine.",
        "Contour errors",
    )?;

    // 4. Bode of axis X: truth, vcnc model, paper's method.
    let f = Csv::read(&demo.join("identify/frf_X.csv"))?;
    let fz = f.col("f_hz")?;
    let mut groups = Vec::new();
    for (name, key) in [
        ("tracking x/x_r", "track"),
        ("disturbance x/d (d: acceleration)", "dist"),
    ] {
        let mut curves = Vec::new();
        for (label, role, p) in [
            ("true machine", Role::TrueMachine, "true"),
            ("vcnc model", Role::Model, "identified"),
            ("paper's method", Role::Paper, "paper_PSO"),
        ] {
            curves.push(BodeCurve {
                label: label.into(),
                role,
                freq_hz: fz,
                mag_db: f.col(&format!("{p}_{key}_mag_db"))?,
                phase_deg: f.col(&format!("{p}_{key}_phase_deg"))?,
            });
        }
        groups.push(BodeGroup {
            name: name.into(),
            curves,
        });
    }
    add(
        bode("axis X: closed-loop frequency responses", &groups).map_err(e)?,
        "frf_X.svg",
        "Tracking and disturbance responses of axis X.",
        "Identification",
    )?;

    // 5. The 3-D export, the summary and the report.
    let axis = c.xyz("true_o")?;
    write_vtp(
        &out.join("path.vtp"),
        &VtpPath::contour(&true_p, ct, ot, &axis, Some(&lines)),
        VtpEncoding::Base64,
    )
    .map_err(e)?;
    manifest.files.push(FileEntry {
        file: "path.vtp".into(),
        description: "tool-tip path with contour and orientation errors and tool axis (ParaView)"
            .into(),
    });
    if let Ok(text) = std::fs::read(demo.join("summary.json")) {
        write_atomic(&out.join("summary.json"), &text).map_err(e)?;
        manifest.summary = Some("summary.json".into());
    }
    manifest.inputs = vec![
        Input {
            name: "demo folder".into(),
            value: demo.display().to_string(),
        },
        Input {
            name: "program".into(),
            value: program.display().to_string(),
        },
    ];
    manifest.write(out).map_err(e)?;
    build_report(out).map_err(e)?;
    Ok(())
}

fn main() {
    let a: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    if a.len() != 3 {
        eprintln!("usage: demo_figures DEMO_DIR PROGRAM.ngc OUT_DIR");
        std::process::exit(2);
    }
    let t0 = std::time::Instant::now();
    if let Err(m) = run(&a[0], &a[1], &a[2]) {
        eprintln!("demo_figures: {m}");
        std::process::exit(1);
    }
    for entry in std::fs::read_dir(&a[2]).into_iter().flatten().flatten() {
        if let Ok(md) = entry.metadata() {
            println!("{:>9} B  {}", md.len(), entry.file_name().to_string_lossy());
        }
    }
    println!("{:.3} s", t0.elapsed().as_secs_f64());
}
