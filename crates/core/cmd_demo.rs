//! `vcnc demo`: the main job on the embedded NMV5000 and spiral — identify the five drives,
//! predict the spiral with the true drives, the identified models and the paper's models.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use serde::Serialize;
use vcnc_drive::DriveModel;
use vcnc_machine::{Machine, embedded};
use vcnc_pipeline::identify::{self, AxisOverview, IdentifySummary};
use vcnc_pipeline::predict::{self, ContourSummary};
use vcnc_pipeline::run::{self, Measured};
use vcnc_report::Role;

use crate::Ctx;
use crate::figures::{self, ModelErrors, PAPER, VCNC_MODEL};
use crate::output::{ensure_dir, write_json};
use crate::report::RunReport;
use crate::sink::TableOptions;
use crate::table::{print_warnings, table as text_table};
use crate::writers::{
    MACHINE_MODELS, contour_report_table, contour_rows, identification_report_table,
    identification_table, report_table_file, write_contour_table, write_identification,
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
    let refined: Vec<DriveModel> = ids.iter().map(|r| r.result.model).collect();
    let paper: Vec<DriveModel> = ids.iter().map(|r| r.result.paper_pso.into()).collect();
    let mask = run.measured(Measured::Feed);
    let [p, pp]: [predict::Prediction; 2] =
        predict::predict_many(&machine, &run, &[&refined, &paper])?
            .try_into()
            .map_err(|_| anyhow::anyhow!("predict_many returns one prediction per model set"))?;
    ensure_dir(out)?;
    let id_dir = out.join("identify");
    ensure_dir(&id_dir)?;
    let machine_input = format!("{} (embedded machines/nmv5000.toml)", machine.name);
    let mut id_report = RunReport::new(
        &id_dir,
        format!("vcnc demo, identification: {}, five axes", machine.name),
    );
    id_report.input("machine", machine_input.as_str());
    id_report.input(
        "runs",
        "per axis: the 70-move excitation program through the true 20 kHz drive (estimation), a \
         second program (validation)",
    );
    write_identification(
        &mut id_report,
        &IdentifySummary::machine(&machine.name, &ids),
        &machine.name,
        MACHINE_MODELS,
        &ids,
    )?;
    let summary = DemoSummary {
        contour: ContourSummary::of(&p, &run, Measured::Feed),
        machine: machine.name.clone(),
        program: spiral,
        models: "identified (PSO + output-error refinement)",
        paper_pso: ContourSummary::of(&pp, &run, Measured::Feed),
        identification: identify::overview(&ids),
    };
    write_json(&out.join("summary.json"), &summary)?;
    let table_path = write_contour_table(out, &machine, &run, &p, table)?;

    let mut report = RunReport::new(out, format!("vcnc demo: {} + spiral", machine.name));
    report.input("machine", machine_input);
    report.input(
        "program",
        format!(
            "{spiral} ({} samples, {:.2} s at Ts = {} s)",
            run.len(),
            run.duration_s(),
            run.ts
        ),
    );
    report.input(
        "models",
        format!(
            "{VCNC_MODEL}: identified from each axis' excitation run (PSO + output-error \
             refinement); {PAPER}: the paper's equation-error PSO alone"
        ),
    );
    report.input("table options", table.describe());
    report.warnings(&run.warnings);
    contour_report_table(
        &mut report,
        &[(VCNC_MODEL, &p.figures(&mask)), (PAPER, &pp.figures(&mask))],
    );
    identification_report_table(&mut report, &ids);
    let (tp, tpp) = (p.tracking(&machine, &run), pp.tracking(&machine, &run));
    figures::prediction(
        &mut report,
        &machine,
        &run,
        &[
            ModelErrors {
                label: VCNC_MODEL,
                role: Role::Model,
                prediction: &p,
                tracking: &tp,
            },
            ModelErrors {
                label: PAPER,
                role: Role::Paper,
                prediction: &pp,
                tracking: &tpp,
            },
        ],
    )?;
    report.include(&id_report, "identify");
    report_table_file(
        &mut report,
        &table_path,
        "per sample: reference, true and predicted axis positions, tool poses, contour and \
         orientation errors (docs/cli.md)",
    );
    report.file(
        "identify/report.html",
        "the identification's own report (its inputs, tables and figures)",
    );
    report.file("identify/model.toml", "the identified models, for --model");
    report.finish()?;
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
        let (a, b) = (
            contour_rows(&p.figures(&mask)),
            contour_rows(&pp.figures(&mask)),
        );
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
            "\n{elapsed:.2} s; report: {}",
            out.join(vcnc_report::REPORT_FILE).display()
        );
    }
    Ok(())
}
