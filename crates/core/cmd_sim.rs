//! `vcnc interpolate`, `vcnc simulate`, `vcnc frf`.

use std::path::Path;

use anyhow::Result;
use serde_json::{Value, json};
use vcnc_drive::ClosedLoopModel;
use vcnc_machine::{Machine, pipeline};

use crate::Ctx;
use crate::output::{write_csv, write_json};
use crate::plot::{LinePlot, Scale, Series, write_panels};
use crate::report::{
    ensure_dir, load_machine, load_models, max_abs, model_json, prepare_run, rms, scaled_diff,
    table,
};

/// `vcnc interpolate MACHINE PROGRAM --out DIR`: `reference.csv` and `summary.json`.
pub fn interpolate(machine: &Path, program: &Path, out: &Path, ctx: &Ctx) -> Result<()> {
    let (machine, run) = prepare_run(machine, program, ctx.lenient)?;
    ensure_dir(out)?;
    let traj = &run.loaded.trajectory;
    let n = run.len();
    let t: Vec<f64> = (0..n).map(|k| run.time(k)).collect();
    let mut header = vec!["t".to_string()];
    let mut cols: Vec<&[f64]> = vec![&t];
    let tcp = traj.tcp.iter().any(|v| *v);
    let px: Vec<Vec<f64>>;
    if tcp {
        // Tool tip in the workpiece frame (the reference poses), then every machine axis.
        let poses = run.poses.as_deref().unwrap_or(&[]);
        px = (0..3)
            .map(|i| poses.iter().map(|p| p.p[i]).collect())
            .collect();
        for (i, name) in ["px", "py", "pz"].iter().enumerate() {
            header.push(name.to_string());
            cols.push(&px[i]);
        }
    }
    for a in &run.axes {
        header.push(a.name.to_string());
        header.push(format!("{}_vel", a.name));
        header.push(format!("{}_acc", a.name));
        cols.push(&a.pos);
        cols.push(&a.vel);
        cols.push(&a.acc);
    }
    write_csv(&out.join("reference.csv"), &header, &cols)?;
    let mut axes = serde_json::Map::new();
    for a in &run.axes {
        axes.insert(
            a.name.to_string(),
            json!({"unit": a.unit.as_str(), "max_vel": max_abs(&a.vel), "max_acc": max_abs(&a.acc)}),
        );
    }
    let summary = json!({
        "machine": machine.name,
        "program": program.display().to_string(),
        "duration_s": traj.duration_s(),
        "samples": n,
        "ts_s": run.ts,
        "tcp": tcp,
        "axes": axes,
        "warnings": run.warnings,
    });
    write_json(&out.join("summary.json"), &summary)?;
    if !ctx.quiet {
        println!(
            "{}: {} samples, {:.3} s at Ts = {} s -> {}",
            program.display(),
            n,
            traj.duration_s(),
            run.ts,
            out.display()
        );
    }
    Ok(())
}

/// `vcnc simulate MACHINE PROGRAM [--model MODEL] --out DIR`: `trace.csv` and `summary.json`.
pub fn simulate(
    machine_path: &Path,
    program: &Path,
    model: Option<&Path>,
    out: &Path,
    ctx: &Ctx,
) -> Result<()> {
    let (machine, run) = prepare_run(machine_path, program, ctx.lenient)?;
    let models = load_models(model, &machine)?;
    let traces = pipeline::simulate_true(&machine, &run)?;
    let predicted = match &models {
        Some(m) => Some(pipeline::simulate_models(m, &run)?),
        None => None,
    };
    ensure_dir(out)?;
    let n = run.len();
    let t: Vec<f64> = (0..n).map(|k| run.time(k)).collect();
    let mut header = vec!["t".to_string()];
    let mut cols: Vec<&[f64]> = vec![&t];
    for (i, (a, tr)) in run.axes.iter().zip(&traces).enumerate() {
        header.push(format!("{}_ref", a.name));
        header.push(format!("{}_act", a.name));
        cols.push(&a.pos);
        cols.push(&tr.position);
        if let Some(p) = &predicted {
            header.push(format!("{}_model", a.name));
            cols.push(&p[i]);
        }
    }
    write_csv(&out.join("trace.csv"), &header, &cols)?;
    let mut axes = serde_json::Map::new();
    let mut rows = Vec::new();
    let mut panels_data = Vec::new();
    for (i, (axis, (a, tr))) in machine
        .axes
        .iter()
        .zip(run.axes.iter().zip(&traces))
        .enumerate()
    {
        let (label, k) = (a.unit.micro_label(), a.unit.micro_factor());
        let e = scaled_diff(&a.pos, &tr.position, k);
        let mut obj = json!({
            "unit": a.unit.as_str(),
            format!("tracking_max_{label}"): max_abs(&e),
            format!("tracking_rms_{label}"): rms(&e),
            "model": model_json(&axis.true_model()),
            "controller": axis.drive.controller().kind(),
        });
        let mut row = vec![
            a.name.to_string(),
            axis.drive.controller().kind().to_string(),
            format!("{:.2} {label}", max_abs(&e)),
            format!("{:.2} {label}", rms(&e)),
        ];
        let mut em = None;
        if let Some(p) = &predicted {
            let d = scaled_diff(&p[i], &tr.position, k);
            obj[format!("model_vs_true_max_{label}")] = json!(max_abs(&d));
            obj[format!("model_vs_true_rms_{label}")] = json!(rms(&d));
            row.push(format!("{:.3} {label}", max_abs(&d)));
            em = Some(scaled_diff(&a.pos, &p[i], k));
        }
        axes.insert(a.name.to_string(), obj);
        rows.push(row);
        panels_data.push((a.name, label, e, em));
    }
    let summary = json!({
        "machine": machine.name,
        "program": program.display().to_string(),
        "samples": n,
        "duration_s": run.loaded.trajectory.duration_s(),
        "axes": axes,
    });
    write_json(&out.join("summary.json"), &summary)?;
    let titles: Vec<String> = panels_data
        .iter()
        .map(|(n, l, _, _)| format!("axis {n}: tracking error x_r - x [{l}]"))
        .collect();
    let panels: Vec<LinePlot> = panels_data
        .iter()
        .zip(&titles)
        .map(|((_, l, e, em), title)| {
            let mut series = vec![Series {
                name: "true drive".into(),
                x: &t,
                y: e,
            }];
            if let Some(em) = em {
                series.push(Series {
                    name: "model".into(),
                    x: &t,
                    y: em,
                });
            }
            LinePlot {
                title,
                x_label: "t [s]",
                y_label: l,
                x_scale: Scale::Linear,
                series,
            }
        })
        .collect();
    write_panels(&out.join("tracking.svg"), &panels, 900, 300)?;
    if !ctx.quiet {
        let mut header = vec!["axis", "controller", "tracking max", "tracking RMS"];
        if predicted.is_some() {
            header.push("|model - true| max");
        }
        print!("{}", table(&header, &rows));
        println!("-> {}", out.display());
    }
    Ok(())
}

/// Log-spaced frequencies from `f0` to `f1` Hz.
pub fn log_freqs(f0: f64, f1: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| f0 * (f1 / f0).powf(i as f64 / (n - 1) as f64))
        .collect()
}

/// Magnitude (dB) and phase (deg, unwrapped) of a frequency response.
pub fn bode(
    freqs: &[f64],
    h: impl Fn(f64) -> vcnc_kinematics::nalgebra::Complex<f64>,
) -> (Vec<f64>, Vec<f64>) {
    let mut mag = Vec::with_capacity(freqs.len());
    let mut phase = Vec::with_capacity(freqs.len());
    let mut prev: Option<f64> = None;
    for f in freqs {
        let z = h(std::f64::consts::TAU * f);
        mag.push(20.0 * z.norm().log10());
        let mut p = z.arg().to_degrees();
        if let Some(q) = prev {
            while p - q > 180.0 {
                p -= 360.0;
            }
            while p - q < -180.0 {
                p += 360.0;
            }
        }
        prev = Some(p);
        phase.push(p);
    }
    (mag, phase)
}

/// Bode data of one model: tracking (mag, phase), disturbance (mag, phase).
pub struct BodeData {
    pub track_mag: Vec<f64>,
    pub track_phase: Vec<f64>,
    pub dist_mag: Vec<f64>,
    pub dist_phase: Vec<f64>,
}

pub fn bode_data(m: &ClosedLoopModel, freqs: &[f64]) -> BodeData {
    let (track_mag, track_phase) = bode(freqs, |w| m.tracking_frf(w));
    let (dist_mag, dist_phase) = bode(freqs, |w| m.disturbance_frf(w));
    BodeData {
        track_mag,
        track_phase,
        dist_mag,
        dist_phase,
    }
}

/// Writes `<prefix>.csv` and `<prefix>.svg` for an axis: the true drive and, optionally, other
/// named models (identified ...).
pub fn write_frf(
    dir: &Path,
    prefix: &str,
    axis: impl std::fmt::Display,
    models: &[(&str, &ClosedLoopModel)],
) -> Result<()> {
    let freqs = log_freqs(0.1, 500.0, 400);
    let data: Vec<BodeData> = models.iter().map(|(_, m)| bode_data(m, &freqs)).collect();
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

/// `vcnc frf MACHINE [--model MODEL] --out DIR`.
pub fn frf(machine_path: &Path, model: Option<&Path>, out: &Path, ctx: &Ctx) -> Result<()> {
    let machine: Machine = load_machine(machine_path)?;
    let models = load_models(model, &machine)?;
    ensure_dir(out)?;
    let mut summary = serde_json::Map::new();
    let mut rows = Vec::new();
    for (i, a) in machine.axes.iter().enumerate() {
        let truth = a.true_model();
        let mut list: Vec<(&str, &ClosedLoopModel)> = vec![("true", &truth)];
        if let Some(m) = &models {
            list.push(("model", &m[i]));
        }
        write_frf(out, &format!("frf_{}", a.name), a.name, &list)?;
        let bw = bandwidth_hz(&truth);
        let mut obj = json!({"true": model_json(&truth), "bandwidth_3db_hz": bw});
        if let Some(m) = &models {
            obj["model"] = model_json(&m[i]);
        }
        summary.insert(a.name.to_string(), obj);
        let p = truth.poles();
        rows.push(vec![
            a.name.to_string(),
            p.map_or("-".into(), |p| format!("{:.3}", p.wn_hz())),
            p.map_or("-".into(), |p| format!("{:.4}", p.zeta)),
            p.map_or("-".into(), |p| format!("{:.3}", p.p_hz())),
            bw.map_or("-".into(), |b| format!("{b:.2}")),
        ]);
    }
    write_json(
        &out.join("summary.json"),
        &json!({"machine": machine.name, "axes": Value::Object(summary)}),
    )?;
    if !ctx.quiet {
        print!(
            "{}",
            table(&["axis", "wn [Hz]", "zeta", "p [Hz]", "-3 dB [Hz]"], &rows)
        );
        println!("-> {}", out.display());
    }
    Ok(())
}

/// First frequency where |G_track| falls 3 dB below its DC value (1), by bisection on a log grid.
pub fn bandwidth_hz(m: &ClosedLoopModel) -> Option<f64> {
    let target = 10f64.powf(-3.0 / 20.0);
    let freqs = log_freqs(0.01, 5000.0, 2000);
    let idx = freqs
        .iter()
        .position(|f| m.tracking_frf(std::f64::consts::TAU * f).norm() < target)?;
    if idx == 0 {
        return Some(freqs[0]);
    }
    let (mut lo, mut hi) = (freqs[idx - 1], freqs[idx]);
    for _ in 0..60 {
        let mid = (lo * hi).sqrt();
        if m.tracking_frf(std::f64::consts::TAU * mid).norm() < target {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(0.5 * (lo + hi))
}
