//! `vcnc predict`: contour errors of a program with the true and the identified drives.

use std::path::Path;

use anyhow::Result;
use vcnc_output::figures::{self, ContourEnvelopes, ModelLabel, Role, VCNC_MODEL};
use vcnc_output::files::{ensure_dir, write_json};
use vcnc_output::runs::{
    CONTOUR_TABLE_NOTE, contour_report_table, contour_rows, report_table_file, run_report,
};
use vcnc_output::table::{ContourTable, TableOptions};
use vcnc_output::text::table as text_table;
use vcnc_pipeline::predict::{self, PredictOptions, PredictSummary};
use vcnc_pipeline::{Machine, Measured, PredictionRecord, Source, identify, source};

use crate::{Ctx, bounded_outputs, print_warnings};

/// `vcnc predict MACHINE PROGRAM [--model MODEL] --out DIR`. The program is always streamed;
/// the figures are drawn from every sample, or with `stream` (and for a program over
/// [`crate::STREAM_ABOVE_BYTES`]) from min/max envelopes in bounded memory. The table and the
/// statistics are the same either way.
#[allow(clippy::too_many_arguments)]
pub fn predict(
    machine_path: &Path,
    program: &Path,
    model: Option<&Path>,
    out: &Path,
    measured: Measured,
    table: &TableOptions,
    stream: bool,
    ctx: &Ctx,
) -> Result<()> {
    let machine = Machine::load(machine_path)?;
    let bounded = bounded_outputs(program, stream);
    let plan = source::plan_file(&machine, program, ctx.lenient)?;
    print_warnings(&plan.warnings);
    let models = identify::models_for(&machine, model)?;
    let source = Source::Streamed(&plan);
    ensure_dir(out)?;
    let mut contour = ContourTable::create(out, &machine, &source, table)?;
    let mut envelopes = bounded.then(|| ContourEnvelopes::new(source.len()));
    let mut record = (!bounded).then(PredictionRecord::default);
    let opts = PredictOptions {
        measured,
        tracking: false,
    };
    let outcome = predict::predict(
        &machine,
        source,
        &[&models],
        &opts,
        &mut (&mut contour, (&mut envelopes, &mut record)),
    )?;
    let table_path = contour.finish()?;
    print_warnings(&outcome.reference.warnings);
    let summary = PredictSummary::new(
        &machine,
        source.file(),
        outcome.summaries[0].clone(),
        &models,
        outcome.warnings.clone(),
    );
    write_json(&out.join("summary.json"), &summary)?;
    let mut report = run_report(
        out,
        "predict",
        machine_path,
        &machine,
        &source,
        &outcome.warnings,
        Some(models.source()),
        table,
        ctx.lenient,
    );
    contour_report_table(&mut report, &[(VCNC_MODEL, &outcome.figures[0])]);
    let program_ts = (source.file(), source.ts());
    if let Some(record) = record {
        let mask = record.measured(measured);
        let labels = [ModelLabel {
            label: VCNC_MODEL,
            role: Role::Model,
        }];
        figures::prediction(&mut report, &machine, program_ts, record, &mask, &labels)?;
    }
    if let Some(envelopes) = envelopes {
        envelopes.finish(&mut report, program_ts)?;
    }
    report_table_file(&mut report, &table_path, CONTOUR_TABLE_NOTE);
    report.finish()?;
    if !ctx.quiet {
        let rows: Vec<Vec<String>> = contour_rows(&outcome.figures[0])
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
        if bounded {
            println!("-> {} (streamed, {} samples)", out.display(), source.len());
        } else {
            println!("-> {}", out.display());
        }
    }
    Ok(())
}
