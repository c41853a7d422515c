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

/// `vcnc predict MACHINE PROGRAM [--model MODEL] --out DIR`.
pub fn predict(
    machine_path: &Path,
    program: &Path,
    model: Option<&Path>,
    out: &Path,
    measured: run::Measured,
    table: &TableOptions,
    ctx: &Ctx,
) -> Result<()> {
    let machine = Machine::load(machine_path)?;
    let mut run = run::prepare_file(&machine, program, ctx.lenient)?;
    let mask = run.measured(measured);
    print_warnings(&run.warnings);
    // The models, and the actual-value latency stated for each axis (the model file's, or the
    // machine's configuration for models identified on the fly; docs/drive-model.md).
    let (models, latency, source): (Vec<DriveModel>, Vec<f64>, String) = match model {
        Some(p) => {
            let set = ModelSet::load(p)?;
            (
                set.for_machine(&machine, &p.display().to_string())?,
                set.actual_latency_for_machine(&machine),
                p.display().to_string(),
            )
        }
        None => {
            let axes = identify::select_axes(&machine, &[])?;
            let ids = identify::identify_axes(&machine, &axes, None)?;
            (
                ids.iter().map(|r| r.result.model).collect(),
                ids.iter().map(|r| r.actual_latency_s).collect(),
                "identified on the fly".to_string(),
            )
        }
    };
    // The run's reference velocities and accelerations are not needed once simulated
    // (docs/performance.md).
    let p = predict::predict_releasing_rates(&machine, &mut run, &models, &latency)?;
    ensure_dir(out)?;
    let figures_of = p.figures(&mask);
    let summary = PredictSummary {
        contour: ContourSummary::of(&p, &run, measured),
        machine: machine.name.clone(),
        program: run.file.clone(),
        models: source,
        actual_latency_s: machine
            .axes
            .iter()
            .zip(&latency)
            .map(|(a, l)| (a.name.to_string(), *l))
            .collect(),
        warnings: run.warnings.clone(),
    };
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
    report_table_file(
        &mut report,
        &table_path,
        "per sample: reference, true and predicted axis positions, tool poses, contour and \
         orientation errors (docs/cli.md)",
    );
    report.finish()?;
    if !ctx.quiet {
        let rows: Vec<Vec<String>> = contour_rows(&figures_of)
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
        println!("-> {}", out.display());
    }
    Ok(())
}
