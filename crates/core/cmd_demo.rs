//! `vcnc demo`: the main job on the embedded NMV5000 and spiral — identify the five drives,
//! predict the spiral with the true drives, the identified models and the paper's models.
//! `vcnc demo --realistic`: the same on the realistic NMV5000 (every drive effect on), with each
//! structure's validation error and, with `--budget`, the cost of each effect alone
//! (vcnc_pipeline::realistic).

use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use vcnc_output::demo::{
    BUDGET_HEADER, BUDGET_NOTE, STATED_LATENCY_NOTE, budget_rows, contour_table_pair,
    realistic_identification_rows, stated_row,
};
use vcnc_output::figures::{self, ModelLabel, PAPER, Role, VCNC_MODEL};
use vcnc_output::files::{ensure_dir, write_json};
use vcnc_output::identification::{
    MACHINE_MODELS, identification_report_table, identification_table, write_identification,
};
use vcnc_output::report::RunReport;
use vcnc_output::runs::{CONTOUR_TABLE_NOTE, contour_report_table, report_table_file};
use vcnc_output::table::{ContourTable, TableOptions};
use vcnc_output::text::table as text_table;
use vcnc_pipeline::demo::{DemoPrediction, DemoSummary, RealisticSummary};
use vcnc_pipeline::identify::{self, IdentifySummary};
use vcnc_pipeline::predict::{self, PredictOptions};
use vcnc_pipeline::realistic::{self, Discrepancy, TARGET_ORIENTATION_MRAD, TARGET_TIP_UM, set};
use vcnc_pipeline::{
    AxisIdentification, Machine, Measured, PredictOutcome, PredictionRecord, Program,
    ReferenceStream, Source, embedded, source,
};

use crate::{Ctx, print_warnings};

/// The embedded spiral's name in messages and summaries.
const SPIRAL: &str = "<embedded>/gcode/spiral.ngc";

/// The embedded spiral planned on `machine`.
fn spiral(machine: &Machine) -> Result<ReferenceStream> {
    let program = Program::Text {
        text: embedded::SPIRAL_NGC.to_string(),
        name: SPIRAL.to_string(),
    };
    Ok(source::plan(machine, program, false)?)
}

/// `vcnc demo [--realistic [--budget]] [--out DIR]`.
pub fn demo(
    out: &Path,
    realistic: bool,
    budget: bool,
    table: &TableOptions,
    ctx: &Ctx,
) -> Result<()> {
    if realistic {
        return demo_realistic(out, budget, table, ctx);
    }
    let start = Instant::now();
    let machine = Machine::embedded_nmv5000()?;
    let axes = identify::select_axes(&machine, &[])?;
    let (ids, plan) = rayon::join(
        || identify::identify_axes(&machine, &axes, None),
        || spiral(&machine),
    );
    let (ids, plan) = (ids?, plan?);
    print_warnings(&plan.warnings);
    let source = Source::Streamed(&plan);
    // Both model sets predict the axes' logged positions (no actual-value latency).
    let refined = identify::machine_models(&machine, &ids, "identified")?
        .with_latencies(ids.iter().map(|_| 0.0));
    let paper = identify::paper_models(&machine, &ids)?;
    ensure_dir(out)?;
    let mut contour = ContourTable::create(out, &machine, &source, table)?;
    let mut record = PredictionRecord::default();
    let outcome = predict::predict(
        &machine,
        source,
        &[&refined, &paper],
        &PredictOptions::default(),
        &mut (&mut contour, &mut record),
    )?;
    let table_path = contour.finish()?;
    let summary = DemoSummary {
        prediction: DemoPrediction {
            contour: outcome.summaries[0].clone(),
            machine: machine.name.clone(),
            program: SPIRAL,
            models: "identified (PSO + output-error refinement)",
            paper_pso: outcome.summaries[1].clone(),
        },
        identification: identify::overview(&ids),
    };
    write_json(&out.join("summary.json"), &summary)?;
    let machine_input = format!("{} (embedded machines/nmv5000.toml)", machine.name);
    let prediction = Prediction {
        source: &source,
        outcome: &outcome,
        record,
        labels: [VCNC_MODEL, PAPER],
    };
    let mut report = demo_report(out, &machine, &machine_input, prediction, &ids, table)?;
    report_table_file(&mut report, &table_path, CONTOUR_TABLE_NOTE);
    demo_files(&mut report);
    report.finish()?;
    let elapsed = start.elapsed().as_secs_f64();
    if !ctx.quiet {
        println!(
            "vcnc demo: {} + spiral ({} samples, {:.2} s)\n",
            machine.name,
            source.len(),
            source.duration_s()
        );
        println!(
            "Identification (each axis: 70-move excitation through the true 20 kHz drive; poles as wn [Hz] / zeta / p [Hz]):"
        );
        print!("{}", identification_table(&ids));
        println!("\nSpiral contour errors, true drives vs identified models:");
        print!(
            "{}",
            contour_table_pair(
                &outcome.figures[0],
                &outcome.figures[1],
                "refined",
                "paper PSO"
            )
        );
        println!(
            "\n{elapsed:.2} s; report: {}",
            out.join(vcnc_output::report::REPORT_FILE).display()
        );
    }
    Ok(())
}

/// A demo's prediction of the spiral with two model sets (vcnc's, the paper's), every sample
/// kept for the figures.
struct Prediction<'a> {
    source: &'a Source<'a>,
    outcome: &'a PredictOutcome,
    record: PredictionRecord,
    /// The two sets' legend labels.
    labels: [&'static str; 2],
}

/// The files a demo's report lists after its figures.
fn demo_files(report: &mut RunReport) {
    report.file(
        "identify/report.html",
        "the identification's own report (its inputs, tables and figures)",
    );
    report.file("identify/model.toml", "the identified models, for --model");
}

/// The demo's report (inputs, contour table, identification, prediction figures), unfinished:
/// the identification's own report is written into `out/identify`.
fn demo_report(
    out: &Path,
    machine: &Machine,
    machine_input: &str,
    p: Prediction<'_>,
    ids: &[AxisIdentification],
    table: &TableOptions,
) -> Result<RunReport> {
    let id_dir = out.join("identify");
    ensure_dir(&id_dir)?;
    let mut id_report = RunReport::new(
        &id_dir,
        format!("vcnc demo, identification: {}, five axes", machine.name),
    );
    id_report.input("machine", machine_input);
    id_report.input(
        "runs",
        "per axis: the 70-move excitation program through the true 20 kHz drive (estimation), a \
         second program (validation)",
    );
    write_identification(
        &mut id_report,
        &IdentifySummary::machine(&machine.name, ids),
        &machine.name,
        MACHINE_MODELS,
        ids,
    )?;
    let source = p.source;
    let mut report = RunReport::new(out, format!("vcnc demo: {} + spiral", machine.name));
    report.input("machine", machine_input);
    report.input(
        "program",
        format!(
            "{} ({} samples, {:.2} s at Ts = {} s)",
            source.file(),
            source.len(),
            source.duration_s(),
            source.ts()
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
    report.warnings(&p.outcome.warnings);
    let [a, b] = p.labels;
    let f = &p.outcome.figures;
    contour_report_table(&mut report, &[(VCNC_MODEL, &f[0]), (PAPER, &f[1])]);
    identification_report_table(&mut report, ids);
    let mask = p.record.measured(Measured::Feed);
    let labels = [
        ModelLabel {
            label: a,
            role: Role::Model,
        },
        ModelLabel {
            label: b,
            role: Role::Paper,
        },
    ];
    figures::prediction(
        &mut report,
        machine,
        (source.file(), source.ts()),
        p.record,
        &mask,
        &labels,
        &figures::PredictionDrawing::default(),
    )?;
    report.include(&id_report, "identify");
    Ok(report)
}

/// `vcnc demo --realistic [--budget]`: the demo on machines/nmv5000-realistic.toml.
fn demo_realistic(out: &Path, budget: bool, table: &TableOptions, ctx: &Ctx) -> Result<()> {
    let start = Instant::now();
    let machine = Machine::embedded_nmv5000_realistic()?;
    let plan = spiral(&machine)?;
    print_warnings(&plan.warnings);
    let source = Source::Streamed(&plan);
    ensure_dir(out)?;
    let mut contour = ContourTable::create(out, &machine, &source, table)?;
    let mut record = PredictionRecord::default();
    let e = realistic::evaluate(&machine, source, &mut (&mut contour, &mut record))?;
    let table_path = contour.finish()?;
    let t_eval = start.elapsed().as_secs_f64();
    let rows = if budget {
        Some(realistic::effect_budget(&machine, source)?)
    } else {
        None
    };
    let summary = RealisticSummary::new(&machine.name, SPIRAL, &e, rows);
    let f = &e.outcome.figures;
    let (model, stated) = (summary.target.model, summary.target.model_stated_latency);
    write_json(&out.join("summary.json"), &summary)?;
    let machine_input = format!(
        "{} (embedded machines/nmv5000-realistic.toml)",
        machine.name
    );
    // The figures show vcnc's models (no latency) and the paper's method.
    record.models.remove(set::MODEL_STATED);
    let figures = [f[set::MODEL], f[set::PAPER]];
    let shown = PredictOutcome {
        figures: figures.to_vec(),
        ..e.outcome.clone()
    };
    let prediction = Prediction {
        source: &source,
        outcome: &shown,
        record,
        labels: [VCNC_MODEL, PAPER],
    };
    let mut report = demo_report(out, &machine, &machine_input, prediction, &e.ids, table)?;
    report_table_file(&mut report, &table_path, CONTOUR_TABLE_NOTE);
    demo_files(&mut report);
    let (h, id_rows) = realistic_identification_rows(&e.ids);
    report.table(
        "realistic drives: identified core poles and each structure's validation error",
        &h.iter().map(String::as_str).collect::<Vec<_>>(),
        id_rows.clone(),
        "true: the rigid 7-parameter model of the drive's plant and gains (the drive itself is \
         not of that structure); validation: free-run error RMS / max on a second excitation \
         run, µm or mdeg; * the structure chosen (smallest RMS, simpler structures preferred \
         within the identifier's selection margin)",
    );
    report.table(
        "vcnc's models with the stated actual-value latency",
        &[
            "models",
            "latency per axis [ms]",
            "|pred − true| max [µm]",
            "RMS [µm]",
            "max [mrad]",
            "RMS [mrad]",
        ],
        vec![
            stated_row("vcnc, no latency", &[], &model),
            stated_row("vcnc, stated latency", &e.actual_latency_s, &stated),
            stated_row("paper's method", &[], &Discrepancy::of(&f[set::PAPER])),
        ],
        STATED_LATENCY_NOTE,
    );
    if let Some(b) = &summary.effect_budget {
        report.table(
            "effect budget: the spiral's |prediction − true machine| with one effect group at a \
             time",
            &BUDGET_HEADER,
            budget_rows(b),
            BUDGET_NOTE,
        );
    }
    report.finish()?;
    let elapsed = start.elapsed().as_secs_f64();
    if !ctx.quiet {
        println!(
            "vcnc demo --realistic: {} + spiral ({} samples, {:.2} s)\n",
            machine.name,
            source.len(),
            source.duration_s()
        );
        println!(
            "Identification (poles as wn [Hz] / zeta / p [Hz]; validation: free-run error RMS / \
             max, um or mdeg, * chosen):"
        );
        print!(
            "{}",
            text_table(&h.iter().map(String::as_str).collect::<Vec<_>>(), &id_rows)
        );
        println!("\nSpiral contour errors (feed moves), true drives vs models:");
        print!(
            "{}",
            contour_table_pair(&f[set::MODEL], &f[set::PAPER], "vcnc", "paper")
        );
        println!(
            "\nTarget |pred - true| max <= {TARGET_TIP_UM} um and {TARGET_ORIENTATION_MRAD} mrad: \
             {} (vcnc {:.3} um / {:.4} mrad, paper's method {:.3} um / {:.4} mrad)",
            if summary.target.reached {
                "reached"
            } else {
                "NOT reached"
            },
            model.tip_max_um,
            model.orientation_max_mrad,
            summary.target.paper_pso.tip_max_um,
            summary.target.paper_pso.orientation_max_mrad,
        );
        println!(
            "With the actual-value latency stated from the control's configuration \
             (dead_time_cycles / servo_rate_hz, per axis {} ms; stated, not identified): vcnc \
             {:.3} um / {:.4} mrad: {}",
            e.ids
                .iter()
                .zip(&e.actual_latency_s)
                .map(|(r, t)| format!("{} {}", r.axis, t * 1e3))
                .collect::<Vec<_>>()
                .join(", "),
            stated.tip_max_um,
            stated.orientation_max_mrad,
            if summary.target.reached_with_stated_latency {
                "reached"
            } else {
                "NOT reached"
            },
        );
        if let Some(b) = &summary.effect_budget {
            println!("\nEffect budget (one effect group at a time on the ideal drives):");
            print!("{}", text_table(&BUDGET_HEADER, &budget_rows(b)));
            println!("({BUDGET_NOTE})");
        }
        println!(
            "\n{elapsed:.2} s (evaluation {t_eval:.2} s); report: {}",
            out.join(vcnc_output::report::REPORT_FILE).display()
        );
    }
    Ok(())
}
