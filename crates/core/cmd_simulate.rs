//! `vcnc interpolate` and `vcnc simulate`.

use std::path::Path;

use anyhow::Result;
use vcnc_machine::{Machine, ModelSet};
use vcnc_pipeline::run::{self, InterpolateSummary};
use vcnc_pipeline::simulate;

use crate::Ctx;
use crate::figures::write_tracking;
use crate::output::{ensure_dir, write_json};
use crate::sink::{TableOptions, write_table};
use crate::table::{print_warnings, table as text_table};

/// `vcnc interpolate MACHINE PROGRAM --out DIR`: `reference.csv` and `summary.json`.
pub fn interpolate(
    machine: &Path,
    program: &Path,
    out: &Path,
    table: &TableOptions,
    ctx: &Ctx,
) -> Result<()> {
    let machine = Machine::load(machine)?;
    let run = run::prepare_file(&machine, program, ctx.lenient)?;
    print_warnings(&run.warnings);
    ensure_dir(out)?;
    let t = run.times();
    let mut header = vec!["t".to_string()];
    let mut cols: Vec<&[f64]> = vec![&t];
    let px: Vec<Vec<f64>>;
    if run.has_tcp() {
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
    write_table(out, "reference", header, &cols, table)?;
    write_json(
        &out.join("summary.json"),
        &InterpolateSummary::of(&machine, &run),
    )?;
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
    write_table(out, "trace", header, &cols, table)?;
    let tracking = simulate::tracking(&machine, &run, &sim);
    let summary = simulate::simulate_summary(
        &machine,
        &run,
        &tracking,
        models.as_ref().map(|(f, m)| (f.as_str(), m.as_slice())),
    );
    write_json(&out.join("summary.json"), &summary)?;
    write_tracking(
        &out.join("tracking.svg"),
        &run,
        &tracking,
        "model",
        900,
        300,
    )?;
    if !ctx.quiet {
        let rows: Vec<Vec<String>> = tracking
            .iter()
            .map(|a| {
                let l = a.unit.micro_label();
                let mut row = vec![
                    a.axis.to_string(),
                    a.controller.to_string(),
                    format!("{:.2} {l}", a.tracking_max),
                    format!("{:.2} {l}", a.tracking_rms),
                ];
                if let Some(m) = a.model_vs_true_max {
                    row.push(format!("{m:.3} {l}"));
                }
                row
            })
            .collect();
        let mut header = vec!["axis", "controller", "tracking max", "tracking RMS"];
        if sim.predicted.is_some() {
            header.push("|model - true| max");
        }
        print!("{}", text_table(&header, &rows));
        println!("-> {}", out.display());
    }
    Ok(())
}
