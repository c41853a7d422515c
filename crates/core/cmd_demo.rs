//! `vcnc demo`: the main job on the embedded NMV5000 and spiral — identify the five drives,
//! predict the spiral with the true drives, the identified models and the paper's models.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use serde::Serialize;
use vcnc_drive::ClosedLoopModel;
use vcnc_machine::{Machine, embedded};
use vcnc_pipeline::identify::{self, AxisOverview, IdentifySummary};
use vcnc_pipeline::predict::{self, ContourSummary};
use vcnc_pipeline::run;

use crate::Ctx;
use crate::figures::write_prediction_plots;
use crate::output::{ensure_dir, write_json};
use crate::sink::TableOptions;
use crate::table::{print_warnings, table as text_table};
use crate::writers::{
    MACHINE_MODELS, contour_rows, identification_table, write_contour_table, write_identification,
};

/// `summary.json` of the demo.
#[derive(Serialize)]
struct DemoSummary {
    /// The refined models' prediction.
    #[serde(flatten)]
    contour: ContourSummary,
    machine: String,
    program: &'static str,
    models: &'static str,
    /// The paper-PSO models' prediction.
    paper_pso: ContourSummary,
    /// Per axis: pole errors of both model sets, %.
    identification: BTreeMap<String, AxisOverview>,
}

/// `vcnc demo [--out DIR]`.
pub fn demo(out: &Path, table: &TableOptions, ctx: &Ctx) -> Result<()> {
    let start = Instant::now();
    let machine = Machine::embedded_nmv5000()?;
    let spiral = "<embedded>/gcode/spiral.ngc";
    let axes = identify::select_axes(&machine, &[])?;
    let (ids, run) = rayon::join(
        || identify::identify_axes(&machine, &axes, None),
        || run::prepare(&machine, embedded::SPIRAL_NGC, spiral, false),
    );
    let (ids, run) = (ids?, run?);
    print_warnings(&run.warnings);
    let refined: Vec<ClosedLoopModel> = ids.iter().map(|r| r.result.identified).collect();
    let paper: Vec<ClosedLoopModel> = ids.iter().map(|r| r.result.paper_pso).collect();
    let [p, pp]: [predict::Prediction; 2] =
        predict::predict_many(&machine, &run, &[&refined, &paper])?
            .try_into()
            .map_err(|_| anyhow::anyhow!("predict_many returns one prediction per model set"))?;
    ensure_dir(out)?;
    let id_dir = out.join("identify");
    ensure_dir(&id_dir)?;
    write_identification(
        &id_dir,
        &IdentifySummary::machine(&machine.name, &ids),
        &machine.name,
        MACHINE_MODELS,
        &ids,
    )?;
    let summary = DemoSummary {
        contour: ContourSummary::of(&p),
        machine: machine.name.clone(),
        program: spiral,
        models: "identified (PSO + output-error refinement)",
        paper_pso: ContourSummary::of(&pp),
        identification: identify::overview(&ids),
    };
    write_json(&out.join("summary.json"), &summary)?;
    write_contour_table(out, &run, &p, table)?;
    write_prediction_plots(
        out,
        &run,
        &p,
        &p.tracking(&machine, &run),
        Some(("paper PSO", &pp)),
    )?;
    let elapsed = start.elapsed().as_secs_f64();
    if !ctx.quiet {
        println!(
            "vcnc demo: {} + spiral ({} samples, {:.2} s)\n",
            machine.name,
            run.len(),
            run.duration_s()
        );
        println!(
            "Identification (each axis: 70-move excitation through the true 20 kHz drive; poles as wn [Hz] / zeta / p [Hz]):"
        );
        print!("{}", identification_table(&ids));
        println!("\nSpiral contour errors, true drives vs identified models:");
        let (a, b) = (contour_rows(&p.figures()), contour_rows(&pp.figures()));
        let rows: Vec<Vec<String>> = a
            .iter()
            .zip(&b)
            .map(|((n, t1, o1), (_, t2, o2))| {
                vec![
                    n.clone(),
                    format!("{t1:.3}"),
                    format!("{o1:.4}"),
                    format!("{t2:.3}"),
                    format!("{o2:.4}"),
                ]
            })
            .collect();
        print!(
            "{}",
            text_table(
                &[
                    "",
                    "tip [um] refined",
                    "orient. [mrad] refined",
                    "tip [um] paper PSO",
                    "orient. [mrad] paper PSO"
                ],
                &rows
            )
        );
        println!(
            "\n{elapsed:.2} s; summaries and SVG plots in {}",
            out.display()
        );
    }
    Ok(())
}
