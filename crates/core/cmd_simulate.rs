//! `vcnc interpolate` and `vcnc simulate`.

use std::path::Path;

use anyhow::Result;
use vcnc_output::figures::{ReferenceEnvelopes, TrackingEnvelopes, simulation_tracking};
use vcnc_output::files::{ensure_dir, write_json};
use vcnc_output::runs::{TRACE_TABLE_NOTE, report_table_file, run_report};
use vcnc_output::table::{ReferenceTable, TableOptions, TraceTable};
use vcnc_output::text::table as text_table;
use vcnc_pipeline::simulate::{self, simulate_summary_of};
use vcnc_pipeline::{MachineModels, SimulationRecord, Source, Unit, source};

use crate::{Ctx, bounded_outputs, print_warnings};

/// `vcnc interpolate MACHINE PROGRAM --out DIR`: `reference.csv`, `summary.json` and
/// `reference.svg`, the program streamed (docs/performance.md, "Streaming").
pub fn interpolate(
    machine_path: &Path,
    program: &Path,
    out: &Path,
    table: &TableOptions,
    ctx: &Ctx,
) -> Result<()> {
    let machine = ctx.machine(machine_path)?;
    let plan = source::plan_file(&machine, program, ctx.lenient)?;
    print_warnings(&plan.warnings);
    let source = Source::Streamed(&plan);
    ensure_dir(out)?;
    let mut reference = ReferenceTable::create(out, &machine, &source, table)?;
    let mut envelopes = ReferenceEnvelopes::new(machine.axes.len(), source.len());
    let outcome = vcnc_pipeline::interpolate::interpolate(
        &machine,
        source,
        &mut (&mut reference, &mut envelopes),
    )?;
    let table_path = reference.finish()?;
    print_warnings(&outcome.reference.warnings);
    let summary = &outcome.summary;
    write_json(&out.join("summary.json"), summary)?;
    let mut report = run_report(
        out,
        "interpolate",
        machine_path,
        &machine,
        &source,
        &summary.warnings,
        None,
        table,
        ctx.lenient,
    );
    envelopes.finish(
        &mut report,
        &machine,
        (source.file(), source.ts()),
        &outcome.reference.moved,
    )?;
    report_table_file(
        &mut report,
        &table_path,
        "per sample: t, the tool tip px py pz (TCP programs), and per axis position, velocity \
         and acceleration (docs/cli.md)",
    );
    report.finish()?;
    if !ctx.quiet {
        println!(
            "{}: {} samples, {:.3} s at Ts = {} s -> {} (streamed, look-ahead peak {} segments)",
            program.display(),
            source.len(),
            source.duration_s(),
            source.ts(),
            out.display(),
            plan.plan.lookahead_peak
        );
        println!("{}", crate::cycle_time_line(&source.cycle()));
    }
    Ok(())
}

/// `vcnc simulate MACHINE PROGRAM [--model MODEL] --out DIR`: `trace.csv`, `summary.json` and
/// `tracking.svg`. The program is always streamed; the figure is drawn from every sample, or
/// with `stream` (and for a program over [`crate::STREAM_ABOVE_BYTES`]) from min/max envelopes
/// in bounded memory. The table and the summary are the same either way.
#[allow(clippy::too_many_arguments)]
pub fn simulate(
    machine_path: &Path,
    program: &Path,
    model: Option<&Path>,
    out: &Path,
    table: &TableOptions,
    stream: bool,
    ctx: &Ctx,
) -> Result<()> {
    let machine = ctx.machine(machine_path)?;
    let bounded = bounded_outputs(program, stream);
    let plan = source::plan_file(&machine, program, ctx.lenient)?;
    print_warnings(&plan.warnings);
    let models = model
        .map(|p| MachineModels::load(p, &machine))
        .transpose()?;
    let source = Source::Streamed(&plan);
    ensure_dir(out)?;
    let mut trace = TraceTable::create(out, &machine, &source, models.is_some(), table)?;
    let mut envelopes =
        bounded.then(|| TrackingEnvelopes::new(&machine, source.len(), models.is_some()));
    let mut record = (!bounded).then(|| SimulationRecord::new(&machine));
    let outcome = simulate::simulate(
        &machine,
        source,
        models.as_ref(),
        &mut (&mut trace, (&mut envelopes, &mut record)),
    )?;
    let table_path = trace.finish()?;
    print_warnings(&outcome.reference.warnings);
    let summary = simulate_summary_of(
        &machine,
        (source.file(), source.len(), source.duration_s()),
        &outcome.tracking,
        models.as_ref(),
    );
    write_json(&out.join("summary.json"), &summary)?;
    let mut report = run_report(
        out,
        "simulate",
        machine_path,
        &machine,
        &source,
        &outcome.warnings,
        models.as_ref().map(MachineModels::source),
        table,
        ctx.lenient,
    );
    let program_ts = (source.file(), source.ts());
    if let Some(record) = record {
        let reference = record.reference.clone();
        let tracking = record.into_tracking(&machine, &outcome);
        let mut header = vec!["axis", "controller", "max", "RMS"];
        if models.is_some() {
            header.push("|model − true| max");
        }
        report.table(
            "tracking errors x_r − x",
            &header,
            tracking_rows(&tracking, Unit::micro_symbol),
            "the true drives' encoder readings against the reference; µm for linear axes, mdeg \
             for rotary axes",
        );
        simulation_tracking(
            &mut report,
            (program_ts.0, program_ts.1, &reference),
            &tracking,
        )?;
        report_table_file(&mut report, &table_path, TRACE_TABLE_NOTE);
        report.finish()?;
        if !ctx.quiet {
            let mut header = vec!["axis", "controller", "tracking max", "tracking RMS"];
            if models.is_some() {
                header.push("|model - true| max");
            }
            print!(
                "{}",
                text_table(&header, &tracking_rows(&tracking, Unit::micro_label))
            );
            println!("-> {}", out.display());
        }
        return Ok(());
    }
    if let Some(envelopes) = envelopes {
        envelopes.finish(&mut report, &machine, program_ts, &outcome.reference.moved)?;
    }
    report_table_file(&mut report, &table_path, TRACE_TABLE_NOTE);
    report.finish()?;
    if !ctx.quiet {
        println!(
            "{}: {} samples simulated streamed -> {}",
            program.display(),
            source.len(),
            out.display()
        );
    }
    Ok(())
}

/// Per axis: controller, tracking max and RMS, and the model's largest departure from the true
/// drive; errors labelled by `unit_label` (µm in reports, um on the terminal).
fn tracking_rows(
    tracking: &[vcnc_pipeline::AxisTracking],
    unit_label: fn(Unit) -> &'static str,
) -> Vec<Vec<String>> {
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
}
