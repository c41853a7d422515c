//! `vcnc predict`: contour errors of a program with the true and the identified drives.

use std::path::Path;

use anyhow::Result;
use vcnc_drive::DriveModel;
use vcnc_machine::{Machine, ModelSet};
use vcnc_pipeline::identify;
use vcnc_pipeline::predict::{self, ContourSummary, PredictSummary};
use vcnc_pipeline::run;
use vcnc_report::Role;

use crate::Ctx;
use crate::figures::{self, ModelErrors, VCNC_MODEL};
use crate::output::{ensure_dir, write_json};
use crate::sink::TableOptions;
use crate::table::{print_warnings, table as text_table};
use crate::writers::{
    contour_report_table, contour_rows, report_table_file, run_report, write_contour_table,
};

/// Programs larger than this (bytes of G-code) are predicted streamed (docs/performance.md):
/// 8 MiB is about 200 000 blocks, a few million samples of short five-axis segments.
pub const STREAM_ABOVE_BYTES: u64 = 8 << 20;

/// Samples per piece of a streamed prediction or simulation: a piece's buffers (the reference,
/// the drives' and models' positions, three poses and the errors of each sample, the table's
/// columns) are about 1 kB a sample, so 16 384 keep them near 16 MB; longer pieces save
/// nothing measurable.
pub const STREAM_PIECE_SAMPLES: usize = 1 << 14;

/// `vcnc predict MACHINE PROGRAM [--model MODEL] --out DIR`: whole-run (every figure at full
/// resolution), or streamed with `stream` or for a program over [`STREAM_ABOVE_BYTES`] (memory
/// bounded whatever its length; the same table and statistics bit for bit).
#[allow(clippy::too_many_arguments)]
pub fn predict(
    machine_path: &Path,
    program: &Path,
    model: Option<&Path>,
    out: &Path,
    measured: run::Measured,
    table: &TableOptions,
    stream: bool,
    ctx: &Ctx,
) -> Result<()> {
    let machine = Machine::load(machine_path)?;
    let large = std::fs::metadata(program).is_ok_and(|m| m.len() > STREAM_ABOVE_BYTES);
    if stream || large {
        return predict_streamed(
            machine_path,
            &machine,
            program,
            model,
            out,
            measured,
            table,
            ctx,
        );
    }
    let mut run = run::prepare_file(&machine, program, ctx.lenient)?;
    let mask = run.measured(measured);
    print_warnings(&run.warnings);
    let (models, latency, source) = models_of(&machine, model)?;

    // The run's reference velocities and accelerations are not needed once simulated
    // (docs/performance.md).
    let p = predict::predict_releasing_rates(&machine, &mut run, &models, &latency)?;
    ensure_dir(out)?;
    let figures_of = p.figures(&mask);
    let summary = PredictSummary::new(
        &machine,
        &run.file,
        ContourSummary::of(&p, &run, measured),
        source,
        &latency,
        run.warnings.clone(),
    );
    let table_path = write_contour_table(out, &machine, &run, &p, table)?;
    write_json(&out.join("summary.json"), &summary)?;
    let mut report = run_report(
        out,
        "predict",
        machine_path,
        &machine,
        &run,
        Some(summary.models.as_str()),
        table,
        ctx,
    );
    contour_report_table(&mut report, &[(VCNC_MODEL, &figures_of)]);
    figures::prediction(
        &mut report,
        &machine,
        &run,
        &mask,
        vec![ModelErrors {
            label: VCNC_MODEL,
            role: Role::Model,
            prediction: p,
        }],
    )?;
    report_table_file(&mut report, &table_path, crate::writers::CONTOUR_TABLE_NOTE);
    report.finish()?;
    if !ctx.quiet {
        print_figures(&figures_of);
        println!("-> {}", out.display());
    }
    Ok(())
}

/// The models (from `model`, or identified on the fly), the actual-value latency stated for
/// each axis (the model file's, or the machine's configuration for models identified on the
/// fly; docs/drive-model.md), and where the models come from.
fn models_of(
    machine: &Machine,
    model: Option<&Path>,
) -> Result<(Vec<DriveModel>, Vec<f64>, String)> {
    Ok(match model {
        Some(p) => {
            let set = ModelSet::load(p)?;
            (
                set.for_machine(machine, &p.display().to_string())?,
                set.actual_latency_for_machine(machine),
                p.display().to_string(),
            )
        }
        None => {
            let axes = identify::select_axes(machine, &[])?;
            let ids = identify::identify_axes(machine, &axes, None)?;
            (
                ids.iter().map(|r| r.result.model).collect(),
                ids.iter().map(|r| r.actual_latency_s).collect(),
                "identified on the fly".to_string(),
            )
        }
    })
}

/// `vcnc predict` streamed (docs/performance.md, "Streamed prediction"): the table is written
/// a piece at a time, the statistics and the figure's envelopes accumulated on the way.
#[allow(clippy::too_many_arguments)]
fn predict_streamed(
    machine_path: &Path,
    machine: &Machine,
    program: &Path,
    model: Option<&Path>,
    out: &Path,
    measured: run::Measured,
    table: &TableOptions,
    ctx: &Ctx,
) -> Result<()> {
    use vcnc_pipeline::stream::Envelope;
    let stream = plan_streamed(machine, program, ctx)?;
    print_warnings(&stream.warnings);
    let (models, latency, source) = models_of(machine, model)?;
    ensure_dir(out)?;
    let n = stream.len();
    let ts = stream.plan.ts;
    let names: Vec<String> = machine.axes.iter().map(|a| a.name.to_string()).collect();
    let header = crate::writers::contour_header(&names);
    let width = header.len();
    let mut writer =
        crate::sink::TableWriter::create_sized(out, "contour", header, table, Some(n))?;
    // The figure's curves: min/max envelopes per time bucket (tool tip: true, model, |Δ|;
    // orientation: the same).
    let mut env: [Envelope; 6] = std::array::from_fn(|_| Envelope::new(n, 2000));
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); width];
    let mut scratch = Vec::new();
    let mut write_err: Option<anyhow::Error> = None;
    let result = vcnc_pipeline::stream_predict::predict_streamed(
        machine,
        &stream,
        program,
        &models,
        &latency,
        measured,
        &mut |p| {
            crate::writers::contour_columns(p, ts, &mut cols);
            let [tt, pt, dt, to, po, dor] = &mut env;
            for (e, a, b, k) in [
                (tt, &p.true_tip_mm, None, 1e3),
                (pt, &p.predicted_tip_mm, None, 1e3),
                (dt, &p.true_tip_mm, Some(&p.predicted_tip_mm), 1e3),
                (to, &p.true_orientation_rad, None, 1e3),
                (po, &p.predicted_orientation_rad, None, 1e3),
                (
                    dor,
                    &p.true_orientation_rad,
                    Some(&p.predicted_orientation_rad),
                    1e3,
                ),
            ] {
                scratch.clear();
                match b {
                    None => scratch.extend(a.iter().map(|x| x * k)),
                    Some(b) => scratch.extend(a.iter().zip(b).map(|(x, y)| (y - x).abs() * k)),
                }
                e.add(p.first, &scratch);
            }
            let refs: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
            crate::sink::write_streamed(&mut writer, &refs, &mut write_err)
        },
    );
    let p = crate::sink::streamed_result(result, write_err)?;
    let table_path = writer.finish()?;
    let mut warnings = stream.warnings.clone();
    warnings.extend(p.stats.warnings.iter().cloned());
    print_warnings(&p.stats.warnings);
    let summary = PredictSummary::new(
        machine,
        &stream.file,
        p.summary.clone(),
        source,
        &latency,
        warnings.clone(),
    );
    write_json(&out.join("summary.json"), &summary)?;
    let mut report = crate::writers::streamed_report(
        out,
        "predict",
        machine_path,
        machine,
        &stream,
        &warnings,
        Some(summary.models.as_str()),
        table,
        ctx,
    );
    contour_report_table(&mut report, &[(VCNC_MODEL, &p.figures)]);
    let [tt, pt, dt, to, po, dor] = env.map(|e| e.polyline(ts));
    figures::prediction_streamed(
        &mut report,
        &stream.file,
        &figures::StreamedErrors {
            true_tip: tt,
            predicted_tip: pt,
            discrepancy_tip: dt,
            true_orientation: to,
            predicted_orientation: po,
            discrepancy_orientation: dor,
        },
    )?;
    report_table_file(&mut report, &table_path, crate::writers::CONTOUR_TABLE_NOTE);
    report.finish()?;
    if !ctx.quiet {
        print_figures(&p.figures);
        println!("-> {} (streamed, {n} samples)", out.display());
    }
    Ok(())
}

/// The contour figures as a table on the terminal.
fn print_figures(f: &vcnc_pipeline::ContourFigures) {
    let rows: Vec<Vec<String>> = contour_rows(f)
        .into_iter()
        .map(|(n, a, b)| vec![n, format!("{a:.3}"), format!("{b:.4}")])
        .collect();
    print!(
        "{}",
        text_table(
            &["contour error", "tool tip [um]", "orientation [mrad]"],
            &rows
        )
    );
}

/// The first pass of a streamed `predict` or `simulate` over `program`, in pieces of
/// [`STREAM_PIECE_SAMPLES`].
pub fn plan_streamed(
    machine: &Machine,
    program: &Path,
    ctx: &Ctx,
) -> Result<vcnc_pipeline::stream::ReferenceStream> {
    Ok(vcnc_pipeline::stream::plan_file(
        machine,
        program,
        ctx.lenient,
        &vcnc_gcode::StreamOptions {
            chunk_samples: STREAM_PIECE_SAMPLES,
            ..vcnc_gcode::StreamOptions::default()
        },
    )?)
}
