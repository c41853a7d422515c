//! `vcnc predict`: contour errors of a program with the true and the identified drives.

use std::path::Path;

use anyhow::Result;
use vcnc_drive::ClosedLoopModel;
use vcnc_machine::{Machine, ModelSet};
use vcnc_pipeline::identify;
use vcnc_pipeline::predict::{self, ContourSummary, PredictSummary};
use vcnc_pipeline::run;

use crate::Ctx;
use crate::figures::write_prediction_plots;
use crate::output::{ensure_dir, write_json};
use crate::sink::TableOptions;
use crate::table::{print_warnings, table as text_table};
use crate::writers::{contour_rows, write_contour_table};

/// `vcnc predict MACHINE PROGRAM [--model MODEL] --out DIR`.
pub fn predict(
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
    let (models, source): (Vec<ClosedLoopModel>, String) = match model {
        Some(p) => (
            ModelSet::load(p)?.for_machine(&machine, &p.display().to_string())?,
            p.display().to_string(),
        ),
        None => {
            let axes = identify::select_axes(&machine, &[])?;
            let ids = identify::identify_axes(&machine, &axes, None)?;
            (
                ids.iter().map(|r| r.result.identified).collect(),
                "identified on the fly".to_string(),
            )
        }
    };
    let p = predict::predict(&machine, &run, &models)?;
    ensure_dir(out)?;
    let summary = PredictSummary {
        contour: ContourSummary::of(&p),
        machine: machine.name.clone(),
        program: run.file.clone(),
        models: source,
        warnings: run.warnings.clone(),
    };
    write_contour_table(out, &run, &p, table)?;
    write_json(&out.join("summary.json"), &summary)?;
    write_prediction_plots(out, &run, &p, &p.tracking(&machine, &run), None)?;
    if !ctx.quiet {
        let rows: Vec<Vec<String>> = contour_rows(&p.figures())
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
