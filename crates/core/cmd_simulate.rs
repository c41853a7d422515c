//! `vcnc interpolate` and `vcnc simulate`.

use std::path::Path;

use anyhow::Result;
use vcnc_machine::{Machine, ModelSet};
use vcnc_pipeline::run;
use vcnc_pipeline::simulate;

use crate::Ctx;
use crate::figures;
use crate::output::{ensure_dir, write_json};
use crate::sink::{TableOptions, write_table};
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
    let stream = vcnc_pipeline::stream::plan_file(
        &machine,
        program,
        ctx.lenient,
        &vcnc_gcode::StreamOptions::default(),
    )?;
    interpolate_streamed(machine_path, &machine, program, &stream, out, table, ctx)
}

/// The end of `interpolate`'s report: the reference table's entry, then the page.
fn finish_reference_report(mut report: crate::report::RunReport, table_path: &Path) -> Result<()> {
    report_table_file(
        &mut report,
        table_path,
        "per sample: t, the tool tip px py pz (TCP programs), and per axis position, velocity \
         and acceleration (docs/cli.md)",
    );
    report.finish()?;
    Ok(())
}

/// Columns of `reference.csv`: `t`, the tool tip for TCP programs, then per axis position,
/// velocity and acceleration.
fn reference_header(tcp: bool, axes: &[vcnc_gcode::AxisName]) -> Vec<String> {
    let mut header = vec!["t".to_string()];
    if tcp {
        header.extend(["px", "py", "pz"].map(String::from));
    }
    for a in axes {
        header.push(a.to_string());
        header.push(format!("{a}_vel"));
        header.push(format!("{a}_acc"));
    }
    header
}

/// `vcnc interpolate` streamed (docs/performance.md, "Streaming"): the program is read twice a
/// piece at a time and every piece of samples is written and dropped; the outputs are those of
/// the whole-program path.
fn interpolate_streamed(
    machine_path: &Path,
    machine: &Machine,
    program: &Path,
    stream: &vcnc_pipeline::stream::ReferenceStream,
    out: &Path,
    table: &TableOptions,
    ctx: &Ctx,
) -> Result<()> {
    use vcnc_pipeline::stream::Envelope;
    print_warnings(&stream.warnings);
    ensure_dir(out)?;
    let tcp = stream.plan.any_tcp;
    let names: Vec<vcnc_gcode::AxisName> = machine.axes.iter().map(|a| a.name).collect();
    let header = reference_header(tcp, &names);
    let n = stream.len();
    let ts = stream.plan.ts;
    let mut writer =
        crate::sink::TableWriter::create_sized(out, "reference", header, table, Some(n))?;
    // The figure from a min/max envelope per pixel column: a spike is never lost.
    let mut env: Vec<Envelope> = names.iter().map(|_| Envelope::new(n, 2000)).collect();
    let mut t = Vec::new();
    let mut write_err: Option<anyhow::Error> = None;
    let stats = stream.run(machine, program, &mut |c| {
        t.clear();
        t.extend((c.first..c.first + c.len()).map(|k| k as f64 * ts));
        let mut cols: Vec<&[f64]> = vec![&t];
        if let Some(tip) = &c.tip {
            cols.extend(tip.iter().map(Vec::as_slice));
        }
        for (i, e) in env.iter_mut().enumerate() {
            cols.push(&c.pos[i]);
            cols.push(&c.vel[i]);
            cols.push(&c.acc[i]);
            e.add(c.first, &c.vel[i]);
        }
        crate::sink::write_streamed(&mut writer, &cols, &mut write_err)
    });
    let stats = crate::sink::streamed_result(stats, write_err)?;
    let table_path = writer.finish()?;
    print_warnings(&stats.warnings);
    let summary = stream.summary(machine, &stats);
    write_json(&out.join("summary.json"), &summary)?;
    let mut report = crate::writers::streamed_report(
        out,
        "interpolate",
        machine_path,
        machine,
        stream,
        &summary.warnings,
        None,
        table,
        ctx,
    );
    let lines: Vec<(Vec<f64>, Vec<f64>)> = env.iter().map(|e| e.polyline(ts)).collect();
    let axes: Vec<figures::ReferenceAxis<'_>> = machine
        .axes
        .iter()
        .zip(&lines)
        .zip(&stats.moved)
        .map(|((a, (t, v)), moved)| figures::ReferenceAxis {
            name: a.name,
            unit: a.unit,
            moved: *moved,
            t,
            vel: v,
        })
        .collect();
    figures::reference_axes(&mut report, &stream.file, &axes)?;
    finish_reference_report(report, &table_path)?;
    if !ctx.quiet {
        println!(
            "{}: {} samples, {:.3} s at Ts = {} s -> {} (streamed, look-ahead peak {} segments)",
            program.display(),
            n,
            stream.duration_s(),
            ts,
            out.display(),
            stream.plan.lookahead_peak
        );
    }
    Ok(())
}

/// `vcnc simulate MACHINE PROGRAM [--model MODEL] --out DIR`: `trace.csv` and `summary.json`;
/// streamed with `stream` or for a program over
/// [`crate::cmd_predict::STREAM_ABOVE_BYTES`] (docs/performance.md).
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
    let machine = Machine::load(machine_path)?;
    let large =
        std::fs::metadata(program).is_ok_and(|m| m.len() > crate::cmd_predict::STREAM_ABOVE_BYTES);
    if stream || large {
        return simulate_streamed(machine_path, &machine, program, model, out, table, ctx);
    }
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
    let names: Vec<String> = run.axes.iter().map(|a| a.name.to_string()).collect();
    let header = trace_header(&names, sim.predicted.is_some());
    let mut cols: Vec<&[f64]> = vec![&t];
    for (i, (a, tr)) in run.axes.iter().zip(&sim.traces).enumerate() {
        cols.push(&a.pos);
        cols.push(&tr.position);
        if let Some(p) = &sim.predicted {
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
    report_table_file(&mut report, &table_path, crate::writers::TRACE_TABLE_NOTE);
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

/// The columns of `trace.csv`: `t`, then per axis `<A>_ref`, `<A>_act` and, with models,
/// `<A>_model`.
fn trace_header(names: &[String], models: bool) -> Vec<String> {
    let mut header = vec!["t".to_string()];
    for a in names {
        header.push(format!("{a}_ref"));
        header.push(format!("{a}_act"));
        if models {
            header.push(format!("{a}_model"));
        }
    }
    header
}

/// `vcnc simulate` streamed (docs/performance.md, "Streamed prediction"): `trace.csv` written a
/// piece at a time, the summary's tracking figures accumulated on the way (bit for bit the
/// whole run's), and `tracking.svg` drawn from min/max envelopes.
#[allow(clippy::too_many_arguments)]
fn simulate_streamed(
    machine_path: &Path,
    machine: &Machine,
    program: &Path,
    model: Option<&Path>,
    out: &Path,
    table: &TableOptions,
    ctx: &Ctx,
) -> Result<()> {
    use vcnc_pipeline::stream::Envelope;
    let stream = crate::cmd_predict::plan_streamed(machine, program, ctx)?;
    print_warnings(&stream.warnings);
    let models = match model {
        Some(p) => Some((
            p.display().to_string(),
            ModelSet::load(p)?.for_machine(machine, &p.display().to_string())?,
        )),
        None => None,
    };
    ensure_dir(out)?;
    let n = stream.len();
    let ts = stream.plan.ts;
    let names: Vec<String> = machine.axes.iter().map(|a| a.name.to_string()).collect();
    let header = trace_header(&names, models.is_some());
    let mut writer = crate::sink::TableWriter::create_sized(out, "trace", header, table, Some(n))?;
    let axes = machine.axes.len();
    let mut env_true: Vec<Envelope> = (0..axes).map(|_| Envelope::new(n, 2000)).collect();
    let mut env_model: Vec<Envelope> = (0..axes).map(|_| Envelope::new(n, 2000)).collect();
    let mut t = Vec::new();
    let mut scratch = Vec::new();
    let mut write_err: Option<anyhow::Error> = None;
    let result = vcnc_pipeline::stream_simulate::simulate_streamed(
        machine,
        &stream,
        program,
        models.as_ref().map(|m| m.1.as_slice()),
        &mut |p| {
            t.clear();
            t.extend((p.first..p.first + p.len()).map(|k| k as f64 * ts));
            let mut cols: Vec<&[f64]> = vec![&t];
            for (i, a) in machine.axes.iter().enumerate() {
                cols.push(&p.reference[i]);
                cols.push(&p.traces[i].position);
                let k = a.unit.micro_factor();
                scratch.clear();
                scratch.extend(
                    p.reference[i]
                        .iter()
                        .zip(&p.traces[i].position)
                        .map(|(r, x)| (r - x) * k),
                );
                env_true[i].add(p.first, &scratch);
                if let Some(pred) = &p.predicted {
                    cols.push(&pred[i]);
                    scratch.clear();
                    scratch.extend(
                        p.reference[i]
                            .iter()
                            .zip(&pred[i])
                            .map(|(r, x)| (r - x) * k),
                    );
                    env_model[i].add(p.first, &scratch);
                }
            }
            crate::sink::write_streamed(&mut writer, &cols, &mut write_err)
        },
    );
    let sim = crate::sink::streamed_result(result, write_err)?;
    let table_path = writer.finish()?;
    print_warnings(&sim.stats.warnings);
    let summary = simulate::simulate_summary_of(
        machine,
        (&stream.file, n, stream.duration_s()),
        &sim.tracking,
        models.as_ref().map(|(f, m)| (f.as_str(), m.as_slice())),
    );
    write_json(&out.join("summary.json"), &summary)?;
    let mut warnings = stream.warnings.clone();
    warnings.extend(sim.stats.warnings.iter().cloned());
    let mut report = crate::writers::streamed_report(
        out,
        "simulate",
        machine_path,
        machine,
        &stream,
        &warnings,
        models.as_ref().map(|(f, _)| f.as_str()),
        table,
        ctx,
    );
    let true_lines: Vec<(Vec<f64>, Vec<f64>)> = env_true.iter().map(|e| e.polyline(ts)).collect();
    let model_lines: Vec<(Vec<f64>, Vec<f64>)> = env_model.iter().map(|e| e.polyline(ts)).collect();
    let figure_axes: Vec<figures::StreamedAxis<'_>> = machine
        .axes
        .iter()
        .enumerate()
        .map(|(i, a)| figures::StreamedAxis {
            name: a.name,
            unit: a.unit,
            moved: sim.stats.moved[i],
            truth: (&true_lines[i].0, &true_lines[i].1),
            model: models
                .is_some()
                .then(|| (model_lines[i].0.as_slice(), model_lines[i].1.as_slice())),
        })
        .collect();
    figures::simulation_tracking_streamed(&mut report, &stream.file, &figure_axes)?;
    report_table_file(&mut report, &table_path, crate::writers::TRACE_TABLE_NOTE);
    report.finish()?;
    if !ctx.quiet {
        println!(
            "{}: {n} samples simulated streamed -> {}",
            program.display(),
            out.display()
        );
    }
    Ok(())
}
