//! `vcnc interpolate` and `vcnc simulate`.

use std::path::Path;

use anyhow::Result;
use vcnc_machine::{Machine, ModelSet};
use vcnc_pipeline::run::{self, InterpolateSummary};
use vcnc_pipeline::simulate;

use crate::Ctx;
use crate::figures;
use crate::output::{ensure_dir, write_json};
use crate::sink::{TableOptions, write_table, write_table_rows};
use crate::table::{print_warnings, table as text_table};
use crate::writers::{report_table_file, run_report};

/// `vcnc interpolate MACHINE PROGRAM --out DIR`: `reference.csv` and `summary.json`.
pub fn interpolate(
    machine_path: &Path,
    program: &Path,
    out: &Path,
    table: &TableOptions,
    ctx: &Ctx,
) -> Result<()> {
    let machine = Machine::load(machine_path)?;
    let run = run::prepare_file(&machine, program, ctx.lenient)?;
    print_warnings(&run.warnings);
    ensure_dir(out)?;
    let tcp = run.has_tcp();
    let mut header = vec!["t".to_string()];
    if tcp {
        // Tool tip in the workpiece frame (the reference poses), then every machine axis.
        header.extend(["px", "py", "pz"].map(String::from));
    }
    for a in &run.axes {
        header.push(a.name.to_string());
        header.push(format!("{}_vel", a.name));
        header.push(format!("{}_acc", a.name));
    }
    // Computed a row group at a time (docs/performance.md).
    let table_path = write_table_rows(out, "reference", header, run.len(), table, |rows, cols| {
        let mut c = cols.iter_mut();
        let mut next = || c.next().expect("one buffer per header column");
        next().extend(rows.clone().map(|k| run.time(k)));
        if tcp {
            let p = run
                .reference_poses_at(&machine, rows.clone())
                .unwrap_or_default();
            for i in 0..3 {
                next().extend(p.iter().map(|q| q.p[i]));
            }
        }
        for a in &run.axes {
            for s in [&a.pos, &a.vel, &a.acc] {
                next().extend_from_slice(&s[rows.clone()]);
            }
        }
    })?;
    write_json(
        &out.join("summary.json"),
        &InterpolateSummary::of(&machine, &run),
    )?;
    let mut report = run_report(
        out,
        "interpolate",
        machine_path,
        &machine,
        &run,
        None,
        table,
        ctx,
    );
    figures::reference(&mut report, &run)?;
    report_table_file(
        &mut report,
        &table_path,
        "per sample: t, the tool tip px py pz (TCP programs), and per axis position, velocity \
         and acceleration (docs/cli.md)",
    );
    report.finish()?;
    if !ctx.quiet {
        println!(
            "{}: {} samples, {:.3} s at Ts = {} s -> {}",
            program.display(),
            run.len(),
            run.duration_s(),
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
    table: &TableOptions,
    ctx: &Ctx,
) -> Result<()> {
    let machine = Machine::load(machine_path)?;
    let run = run::prepare_file(&machine, program, ctx.lenient)?;
    print_warnings(&run.warnings);
    let models = match model {
        Some(p) => Some((
            p.display().to_string(),
            ModelSet::load(p)?.for_machine(&machine, &p.display().to_string())?,
        )),
        None => None,
    };
    let sim = simulate::simulate(&machine, &run, models.as_ref().map(|m| m.1.as_slice()))?;
    ensure_dir(out)?;
    let t = run.times();
    let mut header = vec!["t".to_string()];
    let mut cols: Vec<&[f64]> = vec![&t];
    for (i, (a, tr)) in run.axes.iter().zip(&sim.traces).enumerate() {
        header.push(format!("{}_ref", a.name));
        header.push(format!("{}_act", a.name));
        cols.push(&a.pos);
        cols.push(&tr.position);
        if let Some(p) = &sim.predicted {
            header.push(format!("{}_model", a.name));
            cols.push(&p[i]);
        }
    }
    let table_path = write_table(out, "trace", header, &cols, table)?;
    let tracking = simulate::tracking(&machine, &run, &sim);
    let summary = simulate::simulate_summary(
        &machine,
        &run,
        &tracking,
        models.as_ref().map(|(f, m)| (f.as_str(), m.as_slice())),
    );
    write_json(&out.join("summary.json"), &summary)?;
    let mut report = run_report(
        out,
        "simulate",
        machine_path,
        &machine,
        &run,
        models.as_ref().map(|(f, _)| f.as_str()),
        table,
        ctx,
    );
    let mut header = vec!["axis", "controller", "max", "RMS"];
    if sim.predicted.is_some() {
        header.push("|model − true| max");
    }
    // Per axis: controller, tracking max and RMS, and the model's largest departure from the
    // true drive; errors labelled by `unit_label` (µm in reports, um on the terminal).
    let tracking_rows = |unit_label: fn(vcnc_axis::Unit) -> &'static str| -> Vec<Vec<String>> {
        tracking
            .iter()
            .map(|a| {
                let u = unit_label(a.unit);
                let mut row = vec![
                    a.axis.to_string(),
                    a.controller.to_string(),
                    format!("{:.2} {u}", a.tracking_max),
                    format!("{:.2} {u}", a.tracking_rms),
                ];
                if let Some(m) = a.model_vs_true_max {
                    row.push(format!("{m:.3} {u}"));
                }
                row
            })
            .collect()
    };
    report.table(
        "tracking errors x_r − x",
        &header,
        tracking_rows(vcnc_axis::Unit::micro_symbol),
        "the true drives' encoder readings against the reference; µm for linear axes, mdeg for \
         rotary axes",
    );
    figures::simulation_tracking(&mut report, &run, &tracking)?;
    report_table_file(
        &mut report,
        &table_path,
        "per sample: t and per axis the reference, the true drive's encoder reading and, with \
         --model, the model's position (docs/cli.md)",
    );
    report.finish()?;
    if !ctx.quiet {
        let rows = tracking_rows(vcnc_axis::Unit::micro_label);
        let mut header = vec!["axis", "controller", "tracking max", "tracking RMS"];
        if sim.predicted.is_some() {
            header.push("|model - true| max");
        }
        print!("{}", text_table(&header, &rows));
        println!("-> {}", out.display());
    }
    Ok(())
}
