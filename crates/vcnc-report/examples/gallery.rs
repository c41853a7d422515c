//! Every figure type of vcnc-report from synthetic data, plus `path.vtp`, `manifest.json`,
//! `summary.json` and `report.html`, into one folder:
//!
//! ```text
//! cargo run --release -p vcnc-report --example gallery -- /tmp/vcnc-gallery
//! ```
//!
//! The data are made up but shaped like vcnc's: a second-order closed loop (Bode, step-like
//! tracking errors), a spiral-like 3-D tool path with a contour-error spike at one block, a PSO
//! history and a two-key sweep. The browser test builds its report with this same code.

#![allow(dead_code)]

use std::f64::consts::{PI, TAU};
use std::path::{Path, PathBuf};

use vcnc_report::vtp::{VtpEncoding, VtpPath, write_vtp};
use vcnc_report::*;

/// Second-order closed loop H(s) = ωn² / (s² + 2ζωn s + ωn²) at f Hz: (|H| dB, ∠H deg).
fn second_order(wn_hz: f64, zeta: f64, f: f64) -> (f64, f64) {
    let (wn, w) = (TAU * wn_hz, TAU * f);
    let (re, im) = (wn * wn - w * w, 2.0 * zeta * wn * w);
    let mag = wn * wn / (re * re + im * im).sqrt();
    (20.0 * mag.log10(), -im.atan2(re).to_degrees())
}

/// Its disturbance response x/d = −1 / (s² + 2ζωn s + ωn²) (d an acceleration, mm/s²).
fn disturbance(wn_hz: f64, zeta: f64, f: f64) -> (f64, f64) {
    let (wn, w) = (TAU * wn_hz, TAU * f);
    let (re, im) = (wn * wn - w * w, 2.0 * zeta * wn * w);
    let mag = 1.0 / (re * re + im * im).sqrt();
    (20.0 * mag.log10(), -180.0 - im.atan2(re).to_degrees())
}

/// Tracking error of a drive following a smooth move: a damped oscillation after each start.
fn tracking(t: &[f64], wn_hz: f64, zeta: f64, amp: f64) -> Vec<f64> {
    let wd = TAU * wn_hz * (1.0 - zeta * zeta).sqrt();
    t.iter()
        .map(|&t| {
            let tt = t % 2.0;
            let s = (tt * 0.5 * PI).sin();
            amp * (0.6 * s + (-zeta * TAU * wn_hz * tt).exp() * (wd * tt).sin())
        })
        .collect()
}

/// Tracking magnitude and phase, disturbance magnitude and phase.
type Response = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

pub struct Gallery {
    pub dir: PathBuf,
    pub figures: Vec<(String, usize)>,
}

/// Builds every figure, the `.vtp`, the manifest, the summary and the report in `dir`.
pub fn build_gallery(dir: &Path) -> Result<Gallery, Error> {
    std::fs::create_dir_all(dir).map_err(|e| Error::Io {
        path: dir.to_path_buf(),
        source: e,
    })?;
    let mut manifest = Manifest::new(
        "vcnc gallery: every figure type from synthetic data",
        "cargo run --release -p vcnc-report --example gallery",
        env!("CARGO_PKG_VERSION"),
    );
    manifest.inputs = vec![
        Input {
            name: "machine".into(),
            value: "synthetic (second-order axes, ωn 55.5 / 73.5 / 73.6 Hz)".into(),
        },
        Input {
            name: "program".into(),
            value: "synthetic spiral, 10 000 samples at 1 kHz, 200 blocks".into(),
        },
        Input {
            name: "models".into(),
            value: "vcnc model (±0.5 %), paper's method (±1.5 %)".into(),
        },
        Input {
            name: "options".into(),
            value: "clip percentile 99.5 %, 5 worst blocks".into(),
        },
    ];
    manifest.warnings =
        vec!["spiral.ngc:57: feed F12000 exceeds the X axis limit; clamped to 10000 mm/min".into()];
    let add = |fig: Figure,
               file: &str,
               caption: &str,
               section: &str,
               m: &mut Manifest|
     -> Result<(), Error> {
        fig.save(&dir.join(file))?;
        m.figures.push(FigureEntry {
            file: file.into(),
            caption: caption.into(),
            section: section.into(),
        });
        Ok(())
    };

    // 1. Bode of the true loop, the vcnc model and the paper's method.
    let f: Vec<f64> = (0..400)
        .map(|k| 0.1 * 5000f64.powf(k as f64 / 399.0))
        .collect();
    let curves = [
        ("true machine", Role::TrueMachine, 55.54, 0.39),
        ("vcnc model", Role::Model, 55.78, 0.3878),
        ("paper's method", Role::Paper, 55.13, 0.405),
    ];
    let resp: Vec<Response> = curves
        .iter()
        .map(|&(_, _, wn, z)| {
            let (m, p): (Vec<f64>, Vec<f64>) = f.iter().map(|&f| second_order(wn, z, f)).unzip();
            let (dm, dp): (Vec<f64>, Vec<f64>) = f.iter().map(|&f| disturbance(wn, z, f)).unzip();
            (m, p, dm, dp)
        })
        .collect();
    // One group per response: tracking (magnitude, phase in resp.0, resp.1), disturbance (2, 3).
    let group = |name: &str, pick: fn(&Response) -> (&[f64], &[f64])| BodeGroup {
        name: name.into(),
        curves: curves
            .iter()
            .zip(&resp)
            .map(|(c, r)| {
                let (mag_db, phase_deg) = pick(r);
                BodeCurve {
                    label: c.0.into(),
                    role: c.1,
                    freq_hz: &f,
                    mag_db,
                    phase_deg,
                }
            })
            .collect(),
    };
    let track = group("tracking x/x_r", |r| (&r.0, &r.1));
    let dist = group("disturbance x/d (d: acceleration)", |r| (&r.2, &r.3));
    add(
        bode("axis X: closed-loop frequency responses", &[track, dist])?,
        "frf_X.svg",
        "Tracking and disturbance responses of the true loop, the vcnc model and the paper's method.",
        "Identification",
        &mut manifest,
    )?;

    // 2. PSO convergence.
    let it: Vec<f64> = (0..200).map(|k| k as f64).collect();
    let best: Vec<f64> = it.iter().map(|k| 1e-7 + 3.0 * (-k / 18.0).exp()).collect();
    let mean: Vec<f64> = it
        .iter()
        .map(|k| 2e-7 + 40.0 * (-k / 30.0).exp() * (1.0 + 0.3 * (k * 0.7).sin()))
        .collect();
    add(
        convergence(
            "axis X: PSO convergence",
            &Quantity::new("equation-error cost", "mm²"),
            &[
                Series::line("global best", Role::Other(0), &it, &best),
                Series::line("swarm mean", Role::Other(1), &it, &mean),
            ],
        )?,
        "pso_X.svg",
        "Cost of the best particle and the swarm mean per iteration.",
        "Identification",
        &mut manifest,
    )?;

    // 3. Validation: measurement against the models, with the residuals below.
    let tv: Vec<f64> = (0..35_000).map(|k| k as f64 * 1e-3).collect();
    let meas = tracking(&tv, 55.5, 0.39, 420.0);
    let model: Vec<f64> = meas
        .iter()
        .enumerate()
        .map(|(k, e)| e * 1.0004 + 0.05 * ((k as f64) * 0.37).sin())
        .collect();
    let paper: Vec<f64> = meas
        .iter()
        .enumerate()
        .map(|(k, e)| e * 1.0015 + 0.2 * ((k as f64) * 0.011).sin())
        .collect();
    add(
        comparison_figure(
            "axis X: validation run",
            "",
            Axis::linear("time t", "s"),
            &[Comparison {
                title: None,
                y: Axis::linear("tracking error x_r − x", "µm"),
                truth: Series::line("measurement", Role::Measurement, &tv, &meas),
                others: vec![
                    Series::line("vcnc model", Role::Model, &tv, &model),
                    Series::line("paper's method", Role::Paper, &tv, &paper),
                ],
                difference: Some(Quantity::new("model − measurement", "µm")),
            }],
            Vec::new(),
        )?,
        "validation_X.svg",
        "Validation run: tracking error measured and predicted, and the prediction error of each model.",
        "Identification",
        &mut manifest,
    )?;

    // 4. Tracking errors of a 3-axis program on a 5-axis machine (A and C left out).
    let t: Vec<f64> = (0..10_000).map(|k| k as f64 * 1e-3).collect();
    let moving: Vec<f64> = t.iter().map(|t| 30.0 * (t * 0.6).sin()).collect();
    let still = vec![-90.0; t.len()];
    let zero = vec![0.0; t.len()];
    let ex = tracking(&t, 55.5, 0.39, 250.0);
    let ey = tracking(&t, 73.5, 0.27, 110.0);
    let ez = tracking(&t, 73.6, 0.28, 30.0);
    let mx: Vec<f64> = ex.iter().map(|e| e * 1.001).collect();
    let my: Vec<f64> = ey.iter().map(|e| e * 0.999).collect();
    let mz: Vec<f64> = ez.iter().map(|e| e * 1.002).collect();
    let axis = |a, r, e, m| AxisErrors {
        axis: a,
        reference: r,
        truth: Series::line("true machine", Role::TrueMachine, &t, e),
        models: vec![Series::line("vcnc model", Role::Model, &t, m)],
    };
    use vcnc_axis::AxisName;
    add(
        tracking_errors(
            "tracking errors, true machine and vcnc model",
            &[
                axis(AxisName::X, &moving[..], &ex[..], &mx[..]),
                axis(AxisName::Y, &moving[..], &ey[..], &my[..]),
                axis(AxisName::Z, &moving[..], &ez[..], &mz[..]),
                axis(AxisName::A, &still[..], &zero[..], &zero[..]),
                axis(AxisName::C, &still[..], &zero[..], &zero[..]),
            ],
        )?,
        "tracking_errors.svg",
        "Tracking error per axis; the difference panels show model − truth.",
        "Prediction",
        &mut manifest,
    )?;

    // 5. A spiral-like 3-D path: contour error with a spike at one block, orientation error.
    let n = 10_000;
    let pts: Vec<[f64; 3]> = (0..n)
        .map(|k| {
            let s = k as f64 / n as f64;
            let a = s * 6.0 * PI;
            let r = 20.0 + 50.0 * s;
            [30.0 + r * a.cos(), 15.0 + r * a.sin(), 48.0 - 6.0 * s]
        })
        .collect();
    let lines: Vec<u32> = (0..n).map(|k| 20 + (k / 50) as u32).collect();
    let mut contour: Vec<f64> = (0..n)
        .map(|k| {
            let s = k as f64 / n as f64;
            420.0 * (1.0 - 0.7 * s) * (0.5 + 0.5 * (s * 6.0 * PI * 2.0).sin().abs())
        })
        .collect();
    for (k, c) in contour.iter_mut().enumerate().take(6_130).skip(6_100) {
        *c += 1500.0 * (1.0 - ((k as f64 - 6115.0) / 15.0).abs());
    }
    let contour_model: Vec<f64> = contour
        .iter()
        .enumerate()
        .map(|(k, c)| c * 0.999 + 0.1 * (k as f64 * 0.05).sin())
        .collect();
    let orient: Vec<f64> = (0..n)
        .map(|k| 3.9 * (k as f64 / n as f64 * 9.0).sin().abs())
        .collect();
    let orient_model: Vec<f64> = orient.iter().map(|o| o * 1.0001).collect();
    add(
        contour_path_views(
            "tool-tip path coloured by the true contour error",
            &ColouredPath {
                points_mm: &pts,
                values: &contour,
                value: Quantity::new("contour error", "µm"),
                block_line: Some(&lines),
            },
            &PathViewOptions::default(),
        )?,
        "toolpath_contour.svg",
        "The tool-tip path in the workpiece frame coloured by the contour error; the five worst blocks are ringed with their line numbers.",
        "Contour errors",
        &mut manifest,
    )?;
    let s = arc_length_mm(&pts);
    add(
        error_along_path(
            "contour and orientation errors along the path",
            &PathErrors {
                arc_length_mm: &s,
                contour_truth: Series::line("true machine", Role::TrueMachine, &s, &contour),
                contour_models: vec![Series::line("vcnc model", Role::Model, &s, &contour_model)],
                orientation_truth: Series::line("true machine", Role::TrueMachine, &s, &orient),
                orientation_models: vec![Series::line(
                    "vcnc model",
                    Role::Model,
                    &s,
                    &orient_model,
                )],
                block_line: Some(&lines),
                worst_blocks: 5,
                points_mm: Some(&pts),
            },
        )?,
        "contour_error.svg",
        "Contour error (top) and orientation error (bottom) against the arc length of the reference path, each with model − truth below it.",
        "Contour errors",
        &mut manifest,
    )?;

    // 6. Sweeps: two keys as a heat map, one key as a line.
    let mut kx = Vec::new();
    let mut ky = Vec::new();
    let mut kz = Vec::new();
    for i in 0..8 {
        for j in 0..6 {
            let kp = 20.0 + 10.0 * i as f64;
            let feed = 2000.0 + 2000.0 * j as f64;
            kx.push(kp);
            ky.push(feed);
            kz.push(feed / 40.0 * (1.0 + ((kp - 55.0) / 30.0).powi(2)));
        }
    }
    let SweepGrid {
        x_values: xs,
        y_values: ys,
        values: grid,
    } = grid_from_rows(&kx, &ky, &kz)?;
    add(
        sweep_heatmap(
            "sweep: max contour error over position gain and feed",
            &HeatMap {
                x_key: Quantity::new("position gain kp", "1/s"),
                x_values: &xs,
                y_key: Quantity::new("feed F", "mm/min"),
                y_values: &ys,
                result: Quantity::new("max contour error", "µm"),
                values: &grid,
            },
        )?,
        "sweep_kp_feed.svg",
        "Maximum contour error of each configuration of a two-key sweep.",
        "Sweep",
        &mut manifest,
    )?;
    let row: Vec<f64> = (0..xs.len()).map(|i| grid[2 * xs.len() + i]).collect();
    add(
        sweep_line(
            "sweep: max contour error over position gain (F 6000 mm/min)",
            &Quantity::new("position gain kp", "1/s"),
            &Quantity::new("max contour error", "µm"),
            &[Series::line("configurations", Role::Other(0), &xs, &row)],
        )?,
        "sweep_kp.svg",
        "A one-key sweep as a line through its configurations.",
        "Sweep",
        &mut manifest,
    )?;

    // 7. The 3-D export.
    let axis_vec: Vec<[f64; 3]> = (0..n)
        .map(|k| {
            let a = 0.2 * (k as f64 / n as f64 * TAU).sin();
            [a.sin(), 0.0, a.cos()]
        })
        .collect();
    write_vtp(
        &dir.join("path.vtp"),
        &VtpPath::contour(&pts, &contour, &orient, &axis_vec, Some(&lines)),
        VtpEncoding::Base64,
    )?;
    manifest.files.push(FileEntry {
        file: "path.vtp".into(),
        description: "tool-tip path with contour error (µm), orientation error (mrad), tool axis and block lines (ParaView)".into(),
    });

    // 8. Summary, manifest, report.
    let summary = serde_json::json!({
        "machine": "synthetic",
        "samples": n,
        "contour_um": {"true_max": 1920.0, "true_rms": 260.3, "discrepancy_max": 0.31},
        "identification": {
            "X": {"wn_hz": 55.78, "zeta": 0.3878, "error_percent": {"wn": 0.43, "zeta": -0.57}},
            "Y": {"wn_hz": 73.83, "zeta": 0.266, "error_percent": {"wn": 0.45, "zeta": -1.49}},
        }
    });
    write_atomic(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)
            .unwrap_or_default()
            .as_bytes(),
    )?;
    manifest.summary = Some("summary.json".into());
    manifest.tables.push(Table {
        title: "contour errors".into(),
        header: vec!["".into(), "tip (µm)".into(), "orientation (mrad)".into()],
        rows: vec![
            vec!["true max".into(), "1920".into(), "3.900".into()],
            vec!["|model − true| max".into(), "0.31".into(), "0.0004".into()],
        ],
        note: "synthetic numbers".into(),
    });
    manifest.write(dir)?;
    build_report(dir)?;
    let figures = manifest
        .figures
        .iter()
        .map(|f| {
            let size = std::fs::metadata(dir.join(&f.file)).map_or(0, |m| m.len() as usize);
            (f.file.clone(), size)
        })
        .collect();
    Ok(Gallery {
        dir: dir.to_path_buf(),
        figures,
    })
}

fn main() {
    let dir = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("vcnc-gallery"));
    let t0 = std::time::Instant::now();
    match build_gallery(&dir) {
        Ok(g) => {
            for (f, size) in &g.figures {
                println!("{:>9} B  {}", size, f);
            }
            println!(
                "{:.3} s; report: {}",
                t0.elapsed().as_secs_f64(),
                g.dir.join(REPORT_FILE).display()
            );
        }
        Err(e) => {
            eprintln!("gallery: {e}");
            std::process::exit(1);
        }
    }
}
