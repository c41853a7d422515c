//! The SVG figures of each kind of result (drawn with `plot`), shared by the commands.

use std::path::Path;

use anyhow::Result;
use vcnc_drive::ClosedLoopModel;
use vcnc_identify::{FitMetrics, Identification, Trace};
use vcnc_pipeline::frf::{BodeData, standard_freqs};
use vcnc_pipeline::stats::scaled_diff;
use vcnc_pipeline::sweep::SweepOutcome;
use vcnc_pipeline::{AxisIdentification, AxisTracking, Prediction, Run};

use crate::output::write_csv;
use crate::plot::{
    LinePlot, Scale, Series, write_coloured_path, write_line_plot, write_panels, write_scatter,
};

/// Writes `<prefix>.csv` and `<prefix>.svg` for an axis: tracking and disturbance Bode data of
/// named models (true drive, identified, …).
pub fn write_frf(
    dir: &Path,
    prefix: &str,
    axis: impl std::fmt::Display,
    models: &[(&str, &ClosedLoopModel)],
) -> Result<()> {
    let freqs = standard_freqs();
    let data: Vec<BodeData> = models
        .iter()
        .map(|(_, m)| BodeData::of(m, &freqs))
        .collect();
    let mut header = vec!["f_hz".to_string()];
    let mut cols: Vec<&[f64]> = vec![&freqs];
    for ((name, _), d) in models.iter().zip(&data) {
        let tag = name.replace(' ', "_");
        for (suffix, col) in [
            ("track_mag_db", &d.track_mag),
            ("track_phase_deg", &d.track_phase),
            ("dist_mag_db", &d.dist_mag),
            ("dist_phase_deg", &d.dist_phase),
        ] {
            header.push(format!("{tag}_{suffix}"));
            cols.push(col);
        }
    }
    write_csv(&dir.join(format!("{prefix}.csv")), &header, &cols)?;
    let t1 = format!("axis {axis}: tracking x/x_r, magnitude");
    let t2 = format!("axis {axis}: tracking x/x_r, phase");
    let t3 = format!("axis {axis}: disturbance x/d, magnitude (d: acceleration)");
    let series = |pick: fn(&BodeData) -> &Vec<f64>| -> Vec<Series> {
        models
            .iter()
            .zip(&data)
            .map(|((name, _), d)| Series {
                name: name.to_string(),
                x: &freqs,
                y: pick(d),
            })
            .collect()
    };
    let panels = vec![
        LinePlot {
            title: &t1,
            x_label: "f [Hz]",
            y_label: "dB",
            x_scale: Scale::Log10,
            series: series(|d| &d.track_mag),
        },
        LinePlot {
            title: &t2,
            x_label: "f [Hz]",
            y_label: "deg",
            x_scale: Scale::Log10,
            series: series(|d| &d.track_phase),
        },
        LinePlot {
            title: &t3,
            x_label: "f [Hz]",
            y_label: "dB",
            x_scale: Scale::Log10,
            series: series(|d| &d.dist_mag),
        },
    ];
    write_panels(&dir.join(format!("{prefix}.svg")), &panels, 800, 300)
}

/// The plots of one identified axis: FRF (true when known, identified, paper PSO), PSO
/// convergence, validation.
pub fn write_identification_plots(out: &Path, r: &AxisIdentification) -> Result<()> {
    let a = r.axis;
    let mut models: Vec<(&str, &ClosedLoopModel)> = Vec::new();
    if let Some(t) = r.truth() {
        models.push(("true", t));
    }
    models.push(("identified", &r.result.identified));
    models.push(("paper PSO", &r.result.paper_pso));
    write_frf(out, &format!("frf_{a}"), a, &models)?;
    write_convergence(out, &a.to_string(), &r.result)?;
    write_validation(
        out,
        &a.to_string(),
        r.unit,
        &r.validation_trace,
        &r.validation,
        Some(&r.validation_paper),
    )
}

fn write_convergence(out: &Path, name: &str, id: &Identification) -> Result<()> {
    let it: Vec<f64> = id.pso_history.iter().map(|h| h.iteration as f64).collect();
    let best: Vec<f64> = id
        .pso_history
        .iter()
        .map(|h| h.best_cost.max(1e-300).log10())
        .collect();
    let mean: Vec<f64> = id
        .pso_history
        .iter()
        .map(|h| h.mean_cost.max(1e-300).log10())
        .collect();
    let title = format!("axis {name}: PSO convergence (equation-error cost)");
    write_line_plot(
        &out.join(format!("pso_{name}.svg")),
        &LinePlot {
            title: &title,
            x_label: "iteration",
            y_label: "log10 cost",
            x_scale: Scale::Linear,
            series: vec![
                Series {
                    name: "global best".into(),
                    x: &it,
                    y: &best,
                },
                Series {
                    name: "swarm mean".into(),
                    x: &it,
                    y: &mean,
                },
            ],
        },
    )
}

fn write_validation(
    out: &Path,
    name: &str,
    unit: vcnc_axis::Unit,
    trace: &Trace,
    fit: &FitMetrics,
    paper: Option<&FitMetrics>,
) -> Result<()> {
    let k = unit.micro_factor();
    let label = unit.micro_label();
    let t: Vec<f64> = (0..trace.len()).map(|i| i as f64 * trace.ts).collect();
    let measured = scaled_diff(&trace.xr, &trace.x, k);
    let predicted = scaled_diff(&trace.xr, &fit.predicted_x, k);
    let diff = scaled_diff(&fit.predicted_x, &trace.x, k);
    let paper_diff = paper.map(|f| scaled_diff(&f.predicted_x, &trace.x, k));
    let t1 = format!("axis {name}: validation run, tracking error x_r - x [{label}]");
    let t2 = format!("axis {name}: prediction error x_model - x [{label}]");
    // The paper's model first, so the refined one is drawn on top of it.
    let mut s2 = Vec::new();
    if let Some(p) = &paper_diff {
        s2.push(Series {
            name: "paper PSO".into(),
            x: &t,
            y: p,
        });
    }
    s2.push(Series {
        name: "identified (refined)".into(),
        x: &t,
        y: &diff,
    });
    write_panels(
        &out.join(format!("validation_{name}.svg")),
        &[
            LinePlot {
                title: &t1,
                x_label: "t [s]",
                y_label: label,
                x_scale: Scale::Linear,
                series: vec![
                    Series {
                        name: "measured / true drive".into(),
                        x: &t,
                        y: &measured,
                    },
                    Series {
                        name: "predicted (identified model)".into(),
                        x: &t,
                        y: &predicted,
                    },
                ],
            },
            LinePlot {
                title: &t2,
                x_label: "t [s]",
                y_label: label,
                x_scale: Scale::Linear,
                series: s2,
            },
        ],
        1000,
        340,
    )
}

/// Per-axis tracking-error panels of the true drives (and of models when simulated): `name`
/// in `out`; `model_label` names the model's series.
pub fn write_tracking(
    path: &Path,
    run: &Run,
    tracking: &[AxisTracking],
    model_label: &str,
    width: u32,
    height: u32,
) -> Result<()> {
    let t = run.times();
    let titles: Vec<String> = tracking
        .iter()
        .map(|a| {
            format!(
                "axis {}: tracking error x_r - x [{}]",
                a.axis,
                a.unit.micro_label()
            )
        })
        .collect();
    let panels: Vec<LinePlot> = tracking
        .iter()
        .zip(&titles)
        .map(|(a, title)| {
            let mut series = vec![Series {
                name: "true drive".into(),
                x: &t,
                y: &a.error,
            }];
            if let Some(m) = &a.model_error {
                series.push(Series {
                    name: model_label.to_string(),
                    x: &t,
                    y: m,
                });
            }
            LinePlot {
                title,
                x_label: "t [s]",
                y_label: a.unit.micro_label(),
                x_scale: Scale::Linear,
                series,
            }
        })
        .collect();
    write_panels(path, &panels, width, height)
}

/// Plots of a prediction: contour error over time, tool path coloured by contour error,
/// per-axis tracking errors. `extra` is a second prediction sharing `p`'s true drives
/// (`predict_many`), drawn beside it in the discrepancy panel.
pub fn write_prediction_plots(
    out: &Path,
    run: &Run,
    p: &Prediction,
    tracking: &[AxisTracking],
    extra: Option<(&str, &Prediction)>,
) -> Result<()> {
    let t = run.times();
    let um = |v: &[f64]| v.iter().map(|x| x * 1000.0).collect::<Vec<f64>>();
    let (tt, tp) = (um(&p.true_contour.tip_mm), um(&p.predicted_contour.tip_mm));
    let (ot, op) = (
        um(&p.true_contour.orientation_rad),
        um(&p.predicted_contour.orientation_rad),
    );
    let d_tip = um(&p.tip_discrepancy());
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
    let pair = |a: &'static str, b: &'static str, ya, yb| {
        vec![
            Series {
                name: a.into(),
                x: &t,
                y: ya,
            },
            Series {
                name: b.into(),
                x: &t,
                y: yb,
            },
        ]
    };
    write_panels(
        &out.join("contour_error.svg"),
        &[
            LinePlot {
                title: "tool-tip contour error",
                x_label: "t [s]",
                y_label: "um",
                x_scale: Scale::Linear,
                series: pair("true drives", "identified drives", &tt, &tp),
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
                series: pair("true drives", "identified drives", &ot, &op),
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
    write_tracking(
        &out.join("tracking_errors.svg"),
        run,
        tracking,
        "identified model",
        1000,
        260,
    )
}

/// One scatter per swept key: the configurations' contour error against the key's value.
pub fn write_sweep_plots(out: &Path, keys: &[String], outcome: &SweepOutcome) -> Result<()> {
    let ys: Vec<f64> = outcome.points.iter().map(|p| p.1).collect();
    for (i, k) in keys.iter().enumerate() {
        let xs: Vec<f64> = outcome.points.iter().map(|p| p.0[i]).collect();
        let title = format!("contour error against {k}");
        let name = format!("sweep_{}.svg", k.replace(['.', '/'], "_"));
        write_scatter(
            &out.join(name),
            &LinePlot {
                title: &title,
                x_label: k,
                y_label: "max contour error [um]",
                x_scale: Scale::Linear,
                series: vec![Series {
                    name: "configurations".into(),
                    x: &xs,
                    y: &ys,
                }],
            },
        )?;
    }
    Ok(())
}
