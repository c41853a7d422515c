//! `vcnc predict` and `vcnc demo`: contour errors of a program with the true and the identified
//! drives.

use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use serde_json::{Value, json};
use vcnc_drive::ClosedLoopModel;
use vcnc_machine::pipeline::{self, AxisIdentification, Prediction, Run};
use vcnc_machine::{Machine, embedded};

use crate::Ctx;
use crate::cmd_identify::{identification_table, write_identification};
use crate::output::{write_csv, write_json};
use crate::plot::{LinePlot, Scale, Series, write_coloured_path, write_panels};
use crate::report::{
    ensure_dir, load_models, max_abs, prepare_run, print_warnings, rms, scaled_diff, table,
};

/// The twelve contour figures of a prediction, one row per statistic: table label, docs/cli.md
/// key, tool tip (µm), orientation (mrad).
fn contour_figures(p: &Prediction) -> [(&'static str, &'static str, f64, f64); 6] {
    let (t, q) = (&p.true_contour, &p.predicted_contour);
    let (d_tip, d_or) = (p.tip_discrepancy(), p.orientation_discrepancy());
    [
        ("true max", "true_max", t.tip_max_mm, t.orientation_max_rad),
        ("true RMS", "true_rms", t.tip_rms_mm, t.orientation_rms_rad),
        (
            "predicted max",
            "predicted_max",
            q.tip_max_mm,
            q.orientation_max_rad,
        ),
        (
            "predicted RMS",
            "predicted_rms",
            q.tip_rms_mm,
            q.orientation_rms_rad,
        ),
        (
            "|pred - true| max",
            "discrepancy_max",
            max_abs(&d_tip),
            max_abs(&d_or),
        ),
        (
            "|pred - true| RMS",
            "discrepancy_rms",
            rms(&d_tip),
            rms(&d_or),
        ),
    ]
    .map(|(label, key, tip_mm, or_rad)| (label, key, tip_mm * 1e3, or_rad * 1e3))
}

/// Contour summary (docs/cli.md keys) of a prediction.
pub fn contour_summary(p: &Prediction) -> Value {
    let figures = contour_figures(p);
    let section = |pick: fn(&(&str, &str, f64, f64)) -> f64| {
        figures
            .iter()
            .map(|f| (f.1.to_string(), json!(pick(f))))
            .collect::<serde_json::Map<_, _>>()
    };
    json!({
        "contour_um": section(|f| f.2),
        "orientation_mrad": section(|f| f.3),
        "samples": p.true_contour.tip_mm.len(),
    })
}

/// `contour.csv`: per sample t; reference, true and predicted axis positions; reference, true
/// and predicted tool tip and orientation; contour and orientation errors of both.
pub fn write_contour_csv(path: &Path, run: &Run, p: &Prediction) -> Result<()> {
    let n = run.len();
    let t: Vec<f64> = (0..n).map(|k| run.time(k)).collect();
    let reference = run.poses.as_deref().unwrap_or(&[]);
    let pose_cols = |poses: &[vcnc_kinematics::Pose]| -> Vec<Vec<f64>> {
        let mut cols: Vec<Vec<f64>> = (0..6).map(|_| Vec::with_capacity(n)).collect();
        for q in poses {
            for i in 0..3 {
                cols[i].push(q.p[i]);
                cols[3 + i].push(q.o[i]);
            }
        }
        cols
    };
    let rc = pose_cols(reference);
    let tc = pose_cols(&p.true_poses);
    let pc = pose_cols(&p.predicted_poses);
    let to_um = |v: &[f64]| v.iter().map(|x| x * 1000.0).collect::<Vec<f64>>();
    let tip_t = to_um(&p.true_contour.tip_mm);
    let tip_p = to_um(&p.predicted_contour.tip_mm);
    let or_t = to_um(&p.true_contour.orientation_rad);
    let or_p = to_um(&p.predicted_contour.orientation_rad);
    let mut header = vec!["t".to_string()];
    let mut cols: Vec<&[f64]> = vec![&t];
    for (i, a) in run.axes.iter().enumerate() {
        header.push(format!("{}_ref", a.name));
        cols.push(&a.pos);
        header.push(format!("{}_true", a.name));
        cols.push(&p.true_traces[i].true_position);
        header.push(format!("{}_pred", a.name));
        cols.push(&p.predicted[i]);
    }
    let names = ["px", "py", "pz", "ox", "oy", "oz"];
    for (prefix, c) in [("ref", &rc), ("true", &tc), ("pred", &pc)] {
        for (i, nm) in names.iter().enumerate() {
            header.push(format!("{prefix}_{nm}"));
            cols.push(&c[i]);
        }
    }
    header.extend(
        [
            "true_contour_um",
            "pred_contour_um",
            "true_orientation_mrad",
            "pred_orientation_mrad",
        ]
        .iter()
        .map(|s| s.to_string()),
    );
    cols.extend([
        tip_t.as_slice(),
        tip_p.as_slice(),
        or_t.as_slice(),
        or_p.as_slice(),
    ]);
    write_csv(path, &header, &cols)
}

/// Plots of a prediction: contour error over time, tool path coloured by contour error,
/// per-axis tracking errors.
pub fn write_prediction_plots(
    out: &Path,
    run: &Run,
    p: &Prediction,
    extra: Option<(&str, &Prediction)>,
) -> Result<()> {
    let n = run.len();
    let t: Vec<f64> = (0..n).map(|k| run.time(k)).collect();
    let um = |v: &[f64]| v.iter().map(|x| x * 1000.0).collect::<Vec<f64>>();
    let (tt, tp) = (um(&p.true_contour.tip_mm), um(&p.predicted_contour.tip_mm));
    let (ot, op) = (
        um(&p.true_contour.orientation_rad),
        um(&p.predicted_contour.orientation_rad),
    );
    let d_tip = um(&p.tip_discrepancy());
    // `e` shares `p`'s true drives (`pipeline::predict_many`).
    let d_extra = extra.map(|(_, e)| um(&e.tip_discrepancy()));
    // The comparison model first, so the refined one is drawn on top of it.
    let mut disc = Vec::new();
    if let (Some((name, _)), Some(d)) = (extra, &d_extra) {
        disc.push(Series {
            name: name.to_string(),
            x: &t,
            y: d,
        });
    }
    disc.push(Series {
        name: "identified (refined)".into(),
        x: &t,
        y: &d_tip,
    });
    write_panels(
        &out.join("contour_error.svg"),
        &[
            LinePlot {
                title: "tool-tip contour error",
                x_label: "t [s]",
                y_label: "um",
                x_scale: Scale::Linear,
                series: vec![
                    Series {
                        name: "true drives".into(),
                        x: &t,
                        y: &tt,
                    },
                    Series {
                        name: "identified drives".into(),
                        x: &t,
                        y: &tp,
                    },
                ],
            },
            LinePlot {
                title: "|predicted - true| tool-tip contour error",
                x_label: "t [s]",
                y_label: "um",
                x_scale: Scale::Linear,
                series: disc,
            },
            LinePlot {
                title: "orientation contour error",
                x_label: "t [s]",
                y_label: "mrad",
                x_scale: Scale::Linear,
                series: vec![
                    Series {
                        name: "true drives".into(),
                        x: &t,
                        y: &ot,
                    },
                    Series {
                        name: "identified drives".into(),
                        x: &t,
                        y: &op,
                    },
                ],
            },
        ],
        1000,
        320,
    )?;
    if let Some(poses) = &run.poses {
        let xy: Vec<(f64, f64)> = poses.iter().map(|q| (q.p.x, q.p.y)).collect();
        write_coloured_path(
            &out.join("toolpath_contour.svg"),
            "tool path (workpiece frame), coloured by the true contour error",
            ("x [mm]", "y [mm]"),
            &xy,
            &tt,
            "contour error [um]",
        )?;
    }
    let errs: Vec<(String, Vec<f64>, Vec<f64>)> = run
        .axes
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let k = a.unit.micro_factor();
            (
                format!(
                    "axis {}: tracking error x_r - x [{}]",
                    a.name,
                    a.unit.micro_label()
                ),
                scaled_diff(&a.pos, &p.true_traces[i].true_position, k),
                scaled_diff(&a.pos, &p.predicted[i], k),
            )
        })
        .collect();
    let panels: Vec<LinePlot> = errs
        .iter()
        .zip(&run.axes)
        .map(|((title, e, m), a)| LinePlot {
            title,
            x_label: "t [s]",
            y_label: a.unit.micro_label(),
            x_scale: Scale::Linear,
            series: vec![
                Series {
                    name: "true drive".into(),
                    x: &t,
                    y: e,
                },
                Series {
                    name: "identified model".into(),
                    x: &t,
                    y: m,
                },
            ],
        })
        .collect();
    write_panels(&out.join("tracking_errors.svg"), &panels, 1000, 260)
}

fn prediction_rows(p: &Prediction) -> Vec<(String, f64, f64)> {
    contour_figures(p)
        .iter()
        .map(|(label, _, tip, or)| (label.to_string(), *tip, *or))
        .collect()
}

/// `vcnc predict MACHINE PROGRAM [--model MODEL] --out DIR`.
pub fn predict(
    machine_path: &Path,
    program: &Path,
    model: Option<&Path>,
    out: &Path,
    ctx: &Ctx,
) -> Result<()> {
    let (machine, run) = prepare_run(machine_path, program, ctx.lenient)?;
    let file = program.display().to_string();
    let (models, source) = match (load_models(model, &machine)?, model) {
        (Some(m), Some(p)) => (m, p.display().to_string()),
        _ => {
            let ids = pipeline::identify_axes(&machine, &machine.axis_names(), None)?;
            (
                ids.iter().map(|r| r.result.identified).collect(),
                "identified on the fly".to_string(),
            )
        }
    };
    let p = pipeline::predict(&machine, &run, &models)?;
    ensure_dir(out)?;
    let mut summary = contour_summary(&p);
    summary["machine"] = json!(machine.name);
    summary["program"] = json!(file);
    summary["models"] = json!(source);
    summary["warnings"] = json!(run.warnings);
    write_contour_csv(&out.join("contour.csv"), &run, &p)?;
    write_json(&out.join("summary.json"), &summary)?;
    write_prediction_plots(out, &run, &p, None)?;
    if !ctx.quiet {
        let rows: Vec<Vec<String>> = prediction_rows(&p)
            .into_iter()
            .map(|(n, a, b)| vec![n, format!("{a:.3}"), format!("{b:.4}")])
            .collect();
        print!(
            "{}",
            table(
                &["contour error", "tool tip [um]", "orientation [mrad]"],
                &rows
            )
        );
        println!("-> {}", out.display());
    }
    Ok(())
}

/// `vcnc demo [--out DIR]`: the main job on the embedded NMV5000 and spiral.
pub fn demo(out: &Path, ctx: &Ctx) -> Result<()> {
    let start = Instant::now();
    let machine = Machine::embedded_nmv5000()?;
    let spiral = "<embedded>/gcode/spiral.ngc";
    let (ids, run) = rayon::join(
        || pipeline::identify_axes(&machine, &machine.axis_names(), None),
        || pipeline::prepare(&machine, embedded::SPIRAL_NGC, spiral, false),
    );
    let (ids, run) = (ids?, run?);
    print_warnings(&run.warnings);
    let refined: Vec<ClosedLoopModel> = ids.iter().map(|r| r.result.identified).collect();
    let paper: Vec<ClosedLoopModel> = ids.iter().map(|r| r.result.paper_pso).collect();
    let [p, pp]: [pipeline::Prediction; 2] =
        pipeline::predict_many(&machine, &run, &[&refined, &paper])?
            .try_into()
            .map_err(|_| anyhow::anyhow!("predict_many returns one prediction per model set"))?;
    ensure_dir(out)?;
    let id_dir = out.join("identify");
    ensure_dir(&id_dir)?;
    write_identification(&id_dir, &machine.name, &ids)?;
    let mut summary = contour_summary(&p);
    summary["machine"] = json!(machine.name);
    summary["program"] = json!(spiral);
    summary["models"] = json!("identified (PSO + output-error refinement)");
    summary["paper_pso"] = contour_summary(&pp);
    summary["identification"] = axes_overview(&ids);
    write_json(&out.join("summary.json"), &summary)?;
    write_contour_csv(&out.join("contour.csv"), &run, &p)?;
    write_prediction_plots(out, &run, &p, Some(("paper PSO", &pp)))?;
    let elapsed = start.elapsed().as_secs_f64();
    if !ctx.quiet {
        println!(
            "vcnc demo: {} + spiral ({} samples, {:.2} s)\n",
            machine.name,
            run.len(),
            run.loaded.trajectory.duration_s()
        );
        println!(
            "Identification (each axis: 70-move excitation through the true 20 kHz drive; poles as wn [Hz] / zeta / p [Hz]):"
        );
        print!("{}", identification_table(&ids));
        println!("\nSpiral contour errors, true drives vs identified models:");
        let (a, b) = (prediction_rows(&p), prediction_rows(&pp));
        let rows: Vec<Vec<String>> = a
            .iter()
            .zip(&b)
            .map(|((n, t1, o1), (_, t2, o2))| {
                vec![
                    n.clone(),
                    format!("{t1:.3}"),
                    format!("{o1:.4}"),
                    format!("{t2:.3}"),
                    format!("{o2:.4}"),
                ]
            })
            .collect();
        print!(
            "{}",
            table(
                &[
                    "",
                    "tip [um] refined",
                    "orient. [mrad] refined",
                    "tip [um] paper PSO",
                    "orient. [mrad] paper PSO"
                ],
                &rows
            )
        );
        println!(
            "\n{elapsed:.2} s; summaries and SVG plots in {}",
            out.display()
        );
    }
    Ok(())
}

/// Compact per-axis identification overview for the demo summary.
fn axes_overview(ids: &[AxisIdentification]) -> Value {
    let mut m = serde_json::Map::new();
    for r in ids {
        let pct = |a: Option<vcnc_drive::Poles>| match (r.truth.poles(), a) {
            (Some(t), Some(p)) => json!({
                "p": crate::report::rel_pct(p.p, t.p),
                "wn": crate::report::rel_pct(p.wn, t.wn),
                "zeta": crate::report::rel_pct(p.zeta, t.zeta),
            }),
            _ => Value::Null,
        };
        m.insert(
            r.axis.to_string(),
            json!({
                "identified_error_percent": pct(r.result.identified.poles()),
                "paper_pso_error_percent": pct(r.result.paper_pso.poles()),
            }),
        );
    }
    Value::Object(m)
}
