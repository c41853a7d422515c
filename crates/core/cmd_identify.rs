//! `vcnc identify`: from a simulated machine (each axis: excitation program → true drive →
//! identification → validation) or from a measured trace.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use serde_json::{Value, json};
use vcnc_drive::ClosedLoopModel;
use vcnc_identify::{FitMetrics, Identification, IdentifyOptions, Trace};
use vcnc_machine::pipeline::{self, AxisIdentification};
use vcnc_machine::{AxisModel, ModelSet, Unit};

use crate::cli::{IdentifyArgs, TraceUnits};
use crate::output::{write_atomic, write_json};
use crate::plot::{LinePlot, Scale, Series, write_line_plot, write_panels};
use crate::report::{ensure_dir, fit_json, load_machine, model_json, rel_pct, scaled_diff, table};
use crate::{Ctx, bad_input, cmd_sim};

pub fn identify(args: &IdentifyArgs, ctx: &Ctx) -> Result<()> {
    match (&args.machine, &args.trace) {
        // clap's `requires = "trace"` on these does not fire next to the positional MACHINE
        // (which conflicts with --trace), so say it here rather than ignore them silently.
        (Some(_), None)
            if args.ts.is_some()
                || args.options.is_some()
                || args.units.is_some()
                || args.t_col.is_some()
                || args.xr_col.is_some()
                || args.x_col.is_some() =>
        {
            Err(bad_input(
                "--ts, --units, --t-col, --xr-col, --x-col and --options apply to --trace only; \
                 a machine file sets its identifier options in [identification.options]",
            ))
        }
        (Some(m), None) => identify_machine(m, args, ctx),
        (None, Some(t)) => identify_trace(t, args, ctx),
        _ => Err(bad_input("give either MACHINE.toml or --trace TRACE.csv")),
    }
}

fn identify_machine(path: &Path, args: &IdentifyArgs, ctx: &Ctx) -> Result<()> {
    let machine = load_machine(path)?;
    let axes: Vec<vcnc_gcode::AxisName> = if args.axes.is_empty() {
        machine.axis_names()
    } else {
        let mut v = Vec::new();
        for &c in &args.axes {
            if machine.axis(c).is_none() {
                return Err(bad_input(format!(
                    "--axis {c}: machine \"{}\" ({}) has no axis {c}; it has {}",
                    machine.name,
                    path.display(),
                    machine
                        .axis_names()
                        .iter()
                        .map(|a| a.as_str())
                        .collect::<String>()
                )));
            }
            if !v.contains(&c) {
                v.push(c);
            }
        }
        v
    };
    let results = pipeline::identify_axes(&machine, &axes, args.seed)?;
    ensure_dir(&args.out)?;
    write_identification(&args.out, &machine.name, &results)?;
    if !ctx.quiet {
        print!("{}", identification_table(&results));
        println!("-> {}", args.out.display());
    }
    Ok(())
}

/// Writes `summary.json`, `model.toml` and the plots of a machine identification.
pub fn write_identification(
    out: &Path,
    machine: &str,
    results: &[AxisIdentification],
) -> Result<()> {
    let mut axes = serde_json::Map::new();
    let mut models = BTreeMap::new();
    for r in results {
        axes.insert(r.axis.to_string(), axis_summary(r));
        models.insert(
            r.axis.to_string(),
            AxisModel::new(r.unit, &r.result.identified),
        );
        write_axis_plots(out, r)?;
    }
    let summary = json!({
        "machine": machine,
        "axes": Value::Object(axes),
    });
    write_json(&out.join("summary.json"), &summary)?;
    let set = ModelSet {
        machine: machine.to_string(),
        description: Some(
            "identified by vcnc: stability-constrained PSO (paper section 3) + output-error refinement (docs/identification.md)"
                .into(),
        ),
        axes: models,
    };
    write_atomic(&out.join("model.toml"), set.to_toml_string()?.as_bytes())?;
    Ok(())
}

fn axis_summary(r: &AxisIdentification) -> Value {
    let id = &r.result;
    let truth = model_json(&r.truth);
    let mut errors = serde_json::Map::new();
    if let (Some(t), Some(p)) = (r.truth.poles(), id.identified.poles()) {
        errors.insert(
            "identified".into(),
            pole_errors(&t, &p, r.truth.dc, id.identified.dc),
        );
    }
    if let (Some(t), Some(p)) = (r.truth.poles(), id.paper_pso.poles()) {
        errors.insert(
            "paper_pso".into(),
            pole_errors(&t, &p, r.truth.dc, id.paper_pso.dc),
        );
    }
    json!({
        "unit": r.unit.as_str(),
        "identified": model_json(&id.identified),
        "paper_pso": model_json(&id.paper_pso),
        "unconstrained_ls": model_json(&id.unconstrained_ls.model),
        "true": truth,
        "error_percent_vs_true": Value::Object(errors),
        // `fit`: the identified model on the validation run (a different seed of the
        // identification program), docs/cli.md keys.
        "fit": fit_json(&r.validation, r.unit),
        "fit_estimation": fit_json(&id.fit_estimation, r.unit),
        "fit_paper_pso": fit_json(&r.validation_paper, r.unit),
        "fit_paper_pso_estimation": fit_json(&id.fit_estimation_paper, r.unit),
        "pso": {"cost": id.pso_cost, "iterations": id.pso_history.len()},
        "regressor_condition": id.condition_number,
    })
}

fn pole_errors(t: &vcnc_drive::Poles, p: &vcnc_drive::Poles, dc_t: f64, dc_p: f64) -> Value {
    json!({
        "p": rel_pct(p.p, t.p),
        "wn": rel_pct(p.wn, t.wn),
        "zeta": rel_pct(p.zeta, t.zeta),
        "dc": if dc_t != 0.0 { Some(rel_pct(dc_p, dc_t)) } else { None },
    })
}

fn fmt_poles(m: &ClosedLoopModel) -> String {
    match m.poles() {
        Some(p) => format!("{:.3} / {:.4} / {:.3}", p.wn_hz(), p.zeta, p.p_hz()),
        None => "-".into(),
    }
}

/// Per axis: true vs identified poles, dc, and validation fit.
pub fn identification_table(results: &[AxisIdentification]) -> String {
    let mut rows = Vec::new();
    for r in results {
        let label = r.unit.micro_label();
        let k = r.unit.micro_factor();
        let ls = &r.result.unconstrained_ls;
        rows.push(vec![
            r.axis.to_string(),
            fmt_poles(&r.truth),
            fmt_poles(&r.result.identified),
            fmt_poles(&r.result.paper_pso),
            format!("{}", if ls.stable { "stable" } else { "UNSTABLE" }),
            format!("{:.1} / {:.1}", r.truth.dc, r.result.identified.dc),
            format!(
                "{:.2} / {:.2} {label}",
                r.validation.freerun_max * k,
                r.validation.tracking_peak * k
            ),
        ]);
    }
    table(
        &[
            "axis",
            "true wn/zeta/p [Hz]",
            "identified",
            "paper PSO",
            "LS baseline",
            "dc true/id",
            "validation err/peak",
        ],
        &rows,
    )
}

fn write_axis_plots(out: &Path, r: &AxisIdentification) -> Result<()> {
    let a = r.axis;
    cmd_sim::write_frf(
        out,
        &format!("frf_{a}"),
        a,
        &[
            ("true", &r.truth),
            ("identified", &r.result.identified),
            ("paper PSO", &r.result.paper_pso),
        ],
    )?;
    write_convergence(out, &a.to_string(), &r.result)?;
    let vtrace = r.validation_run.identification_trace()?;
    write_validation(
        out,
        &a.to_string(),
        r.unit,
        &vtrace,
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
    unit: Unit,
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

/// Reads a trace CSV: `#` comment lines skipped, a header row, numeric columns.
fn read_trace_csv(path: &Path, cols: [&str; 3]) -> Result<[Vec<f64>; 3]> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| bad_input(format!("{file}: cannot read: {e}")))?;
    let mut rdr = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(false)
        .from_reader(bytes.as_slice());
    let header = rdr
        .headers()
        .map_err(|e| bad_input(format!("{file}: cannot read the header row: {e}")))?
        .clone();
    let mut idx = [0usize; 3];
    for (i, name) in cols.iter().enumerate() {
        idx[i] = header.iter().position(|h| h == *name).ok_or_else(|| {
            bad_input(format!(
                "{file}: missing column '{name}' (the header has: {}); choose columns with --t-col, --xr-col, --x-col",
                header.iter().collect::<Vec<_>>().join(", ")
            ))
        })?;
    }
    let mut out: [Vec<f64>; 3] = Default::default();
    for (row, rec) in rdr.records().enumerate() {
        let rec = rec.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            bad_input(format!("{file}:{line}: {e}"))
        })?;
        let line = rec.position().map_or(row as u64 + 2, |p| p.line());
        for (i, &c) in idx.iter().enumerate() {
            let s = rec.get(c).unwrap_or("");
            let v: f64 = s.parse().map_err(|_| {
                bad_input(format!(
                    "{file}:{line}: column '{}': '{s}' is not a number",
                    cols[i]
                ))
            })?;
            if !v.is_finite() {
                return Err(bad_input(format!(
                    "{file}:{line}: column '{}' is {s}: not a finite number",
                    cols[i]
                )));
            }
            out[i].push(v);
        }
    }
    Ok(out)
}

fn identify_trace(path: &Path, args: &IdentifyArgs, ctx: &Ctx) -> Result<()> {
    let file = path.display().to_string();
    // The options first: a mistake in them is reported before the trace is read.
    let options_file = args
        .options
        .as_deref()
        .map(vcnc_machine::OptionsFile::load)
        .transpose()?;
    let cols = [
        args.t_col.as_deref().unwrap_or("t"),
        args.xr_col.as_deref().unwrap_or("xr"),
        args.x_col.as_deref().unwrap_or("x"),
    ];
    let [t, mut xr, mut x] = read_trace_csv(path, cols)?;
    let (unit, scale) = match args.units.unwrap_or(TraceUnits::Mm) {
        TraceUnits::M => (Unit::Mm, 1000.0),
        TraceUnits::Mm => (Unit::Mm, 1.0),
        TraceUnits::Deg => (Unit::Deg, 1.0),
    };
    for v in xr.iter_mut().chain(x.iter_mut()) {
        *v *= scale;
    }
    // The time column is always checked; a stated --ts must agree with it.
    let timing = match args.ts {
        Some(ts) => vcnc_identify::Timing::ColumnWithPeriod(&t, ts),
        None => vcnc_identify::Timing::Column(&t),
    };
    let trace = Trace::from_log(timing, xr, x).map_err(|e| bad_input(format!("{file}: {e}")))?;
    let (mut opts, sets_p_bounds) = match options_file {
        Some(f) => (f.options, f.sets_p_bounds),
        None => (IdentifyOptions::default(), false),
    };
    if let Some(s) = args.seed {
        opts.seed = s;
    }
    // Measured drives may lack integral action (a3 = 0): let the real pole approach 0, unless
    // the options file sets its own bounds.
    if !sets_p_bounds {
        opts.bounds.p_hz[0] = opts.bounds.p_hz[0].min(1e-4);
    }
    let id = vcnc_identify::identify(&trace, &opts)
        .map_err(|e| bad_input(format!("{file}: identification refused: {e}")))?;
    ensure_dir(&args.out)?;
    let name = args
        .axes
        .first()
        .copied()
        .unwrap_or(vcnc_gcode::AxisName::X)
        .to_string();
    let summary = json!({
        "trace": file,
        "samples": trace.len(),
        "ts_s": trace.ts,
        "units": unit.as_str(),
        "axes": {
            name.clone(): {
                "unit": unit.as_str(),
                "identified": model_json(&id.identified),
                "paper_pso": model_json(&id.paper_pso),
                "unconstrained_ls": model_json(&id.unconstrained_ls.model),
                // A measured trace has one run: `fit` is on it.
                "fit": fit_json(&id.fit_estimation, unit),
                "fit_paper_pso": fit_json(&id.fit_estimation_paper, unit),
                "pso": {"cost": id.pso_cost, "iterations": id.pso_history.len()},
                "regressor_condition": id.condition_number,
                "moving_start": id.moving_start,
            }
        },
        // What the identifier was told (defaults included), so the run can be repeated.
        "identify_options": opts,
    });
    write_json(&args.out.join("summary.json"), &summary)?;
    let mut axes = BTreeMap::new();
    axes.insert(name.clone(), AxisModel::new(unit, &id.identified));
    let set = ModelSet {
        machine: format!("trace {file}"),
        description: Some("identified by vcnc from a measured trace".into()),
        axes,
    };
    write_atomic(
        &args.out.join("model.toml"),
        set.to_toml_string()?.as_bytes(),
    )?;
    cmd_sim::write_frf(
        &args.out,
        &format!("frf_{name}"),
        name.chars().next().unwrap_or('X'),
        &[("identified", &id.identified), ("paper PSO", &id.paper_pso)],
    )?;
    write_convergence(&args.out, &name, &id)?;
    write_validation(
        &args.out,
        &name,
        unit,
        &trace,
        &id.fit_estimation,
        Some(&id.fit_estimation_paper),
    )
    .context("writing the fit plot")?;
    if !ctx.quiet {
        let k = unit.micro_factor();
        let l = unit.micro_label();
        let rows: Vec<Vec<String>> = [
            ("identified", &id.identified, Some(&id.fit_estimation)),
            ("paper PSO", &id.paper_pso, Some(&id.fit_estimation_paper)),
            ("unconstrained LS", &id.unconstrained_ls.model, None),
        ]
        .iter()
        .map(|(n, m, f)| {
            vec![
                n.to_string(),
                fmt_poles(m),
                format!("{:.1}", m.dc),
                if m.is_stable() {
                    "yes".into()
                } else if m.is_marginally_stable() {
                    "marginal".into()
                } else {
                    "NO".into()
                },
                f.map_or("-".into(), |f| format!("{:.2} {l}", f.freerun_rms * k)),
            ]
        })
        .collect();
        println!(
            "{file}: {} samples at {} s, tracking error {:.1} {l} RMS",
            trace.len(),
            trace.ts,
            trace.tracking_rms() * k
        );
        print!(
            "{}",
            table(
                &["model", "wn/zeta/p [Hz]", "dc", "stable", "free-run RMS"],
                &rows
            )
        );
        println!("-> {}", args.out.display());
    }
    Ok(())
}
