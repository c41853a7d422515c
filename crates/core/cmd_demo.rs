//! `vcnc demo`: the main job on the embedded NMV5000 and spiral — identify the five drives,
//! predict the spiral with the true drives, the identified models and the paper's models.
//! `vcnc demo --realistic`: the same on the realistic NMV5000 (every drive effect on), with each
//! structure's validation error and, with `--budget`, the cost of each effect alone
//! (vcnc_pipeline::realistic).

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use serde::Serialize;
use vcnc_drive::DriveModel;
use vcnc_machine::{Machine, embedded};
use vcnc_pipeline::identify::{self, AxisOverview, IdentifySummary};
use vcnc_pipeline::predict::{self, ContourSummary};
use vcnc_pipeline::realistic::{
    self, BudgetRow, Discrepancy, RealisticAxis, TARGET_ORIENTATION_MRAD, TARGET_TIP_UM,
};
use vcnc_pipeline::run::{self, Measured, Run};
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

/// `summary.json` of `vcnc demo --realistic`.
#[derive(Serialize)]
struct RealisticSummary {
    /// vcnc's chosen models' prediction.
    #[serde(flatten)]
    contour: ContourSummary,
    machine: String,
    program: &'static str,
    models: &'static str,
    /// The paper's method's prediction.
    paper_pso: ContourSummary,
    /// vcnc's chosen models with the actual-value latency stated from the machine's control
    /// configuration.
    stated_latency: StatedLatency,
    /// Per axis: poles against the rigid truth, structures and their validation errors.
    identification: BTreeMap<String, RealisticAxis>,
    /// The target and whether vcnc's models meet it.
    target: Target,
    /// One effect group at a time (`--budget`).
    #[serde(skip_serializing_if = "Option::is_none")]
    effect_budget: Option<Vec<BudgetRow>>,
}

/// The prediction of vcnc's models with a stated actual-value latency.
#[derive(Serialize)]
struct StatedLatency {
    /// Where the latency comes from.
    source: &'static str,
    /// Per axis, s.
    actual_latency_s: BTreeMap<String, f64>,
    /// The contour figures.
    #[serde(flatten)]
    contour: ContourSummary,
}

/// Where the realistic demo's stated latency comes from.
const STATED_LATENCY_SOURCE: &str = "stated, not identified: the machine's control      configuration, feedback.dead_time_cycles / servo_rate_hz (the logged actual position is the      reading the position loop used); the models' positions advanced by it (docs/drive-model.md)";

#[derive(Serialize)]
struct Target {
    /// Largest tool-tip discrepancy allowed, µm.
    tip_max_um: f64,
    /// Largest orientation discrepancy allowed, mrad.
    orientation_max_mrad: f64,
    /// vcnc's discrepancy.
    model: Discrepancy,
    /// vcnc's discrepancy with the stated actual-value latency.
    model_stated_latency: Discrepancy,
    /// The paper's method's.
    paper_pso: Discrepancy,
    /// Whether vcnc's models meet both.
    reached: bool,
    /// Whether vcnc's models with the stated latency meet both.
    reached_with_stated_latency: bool,
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
    let machine_input = format!("{} (embedded machines/nmv5000.toml)", machine.name);
    let summary = DemoSummary {
        contour: ContourSummary::of(&p, &run, Measured::Feed),
        machine: machine.name.clone(),
        program: spiral,
        models: "identified (PSO + output-error refinement)",
        paper_pso: ContourSummary::of(&pp, &run, Measured::Feed),
        identification: identify::overview(&ids),
    };
    ensure_dir(out)?;
    write_json(&out.join("summary.json"), &summary)?;
    let mut report = demo_report(out, &machine, &machine_input, &run, &ids, [&p, &pp], table)?;
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
        print_contour_table(&p, &pp, &mask, "refined", "paper PSO");
        println!(
            "\n{elapsed:.2} s; report: {}",
            out.join(vcnc_report::REPORT_FILE).display()
        );
    }
    Ok(())
}

/// The demo's report (contour table, identification, prediction figures, files), unfinished:
/// the identification's own report is written into `out/identify`.
fn demo_report(
    out: &Path,
    machine: &Machine,
    machine_input: &str,
    run: &Run,
    ids: &[identify::AxisIdentification],
    [p, pp]: [&predict::Prediction; 2],
    table: &TableOptions,
) -> Result<RunReport> {
    let spiral = run.file.as_str();
    let mask = run.measured(Measured::Feed);
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
    let table_path = write_contour_table(out, machine, run, p, table)?;

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
    identification_report_table(&mut report, ids);
    figures::prediction(
        &mut report,
        machine,
        run,
        &mask,
        vec![
            ModelErrors {
                label: VCNC_MODEL,
                role: Role::Model,
                prediction: p.clone(),
            },
            ModelErrors {
                label: PAPER,
                role: Role::Paper,
                prediction: pp.clone(),
            },
        ],
    )?;
    report.include(&id_report, "identify");
    report_table_file(&mut report, &table_path, crate::writers::CONTOUR_TABLE_NOTE);
    report.file(
        "identify/report.html",
        "the identification's own report (its inputs, tables and figures)",
    );
    report.file("identify/model.toml", "the identified models, for --model");
    Ok(report)
}

/// Prints the contour table of two model sets side by side.
fn print_contour_table(
    p: &predict::Prediction,
    pp: &predict::Prediction,
    mask: &[bool],
    a_name: &str,
    b_name: &str,
) {
    let (a, b) = (
        contour_rows(&p.figures(mask)),
        contour_rows(&pp.figures(mask)),
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
    let h = [
        format!("tip [um] {a_name}"),
        format!("orient. [mrad] {a_name}"),
        format!("tip [um] {b_name}"),
        format!("orient. [mrad] {b_name}"),
    ];
    print!("{}", text_table(&["", &h[0], &h[1], &h[2], &h[3]], &rows));
}

/// `vcnc demo --realistic [--budget]`: the demo on machines/nmv5000-realistic.toml.
fn demo_realistic(out: &Path, budget: bool, table: &TableOptions, ctx: &Ctx) -> Result<()> {
    let start = Instant::now();
    let machine = Machine::embedded_nmv5000_realistic()?;
    let spiral = "<embedded>/gcode/spiral.ngc";
    let run = run::prepare(&machine, embedded::SPIRAL_NGC, spiral, false)?;
    print_warnings(&run.warnings);
    let e = realistic::evaluate(&machine, &run)?;
    let t_eval = start.elapsed().as_secs_f64();
    let rows = if budget {
        Some(realistic::effect_budget(&machine, &run)?)
    } else {
        None
    };
    let mask = run.measured(Measured::Feed);
    let (fm, fp) = (e.model.figures(&mask), e.paper.figures(&mask));
    let fs = e.model_stated.figures(&mask);
    let (model, stated) = (Discrepancy::of(&fm), Discrepancy::of(&fs));
    let summary = RealisticSummary {
        contour: ContourSummary::of(&e.model, &run, Measured::Feed),
        machine: machine.name.clone(),
        program: spiral,
        models: "identified, structure chosen by validation error (PSO + output-error refinement)",
        paper_pso: ContourSummary::of(&e.paper, &run, Measured::Feed),
        stated_latency: StatedLatency {
            source: STATED_LATENCY_SOURCE,
            actual_latency_s: e
                .ids
                .iter()
                .map(|r| (r.axis.to_string(), r.actual_latency_s))
                .collect(),
            contour: ContourSummary::of(&e.model_stated, &run, Measured::Feed),
        },
        identification: e
            .ids
            .iter()
            .filter_map(|r| Some((r.axis.to_string(), RealisticAxis::of(r)?)))
            .collect(),
        target: Target {
            tip_max_um: TARGET_TIP_UM,
            orientation_max_mrad: TARGET_ORIENTATION_MRAD,
            model,
            model_stated_latency: stated,
            paper_pso: Discrepancy::of(&fp),
            reached: model.meets_target(),
            reached_with_stated_latency: stated.meets_target(),
        },
        effect_budget: rows,
    };
    ensure_dir(out)?;
    write_json(&out.join("summary.json"), &summary)?;
    let machine_input = format!(
        "{} (embedded machines/nmv5000-realistic.toml)",
        machine.name
    );
    let mut report = demo_report(
        out,
        &machine,
        &machine_input,
        &run,
        &e.ids,
        [&e.model, &e.paper],
        table,
    )?;
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
            stated_row("paper's method", &[], &Discrepancy::of(&fp)),
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
            run.len(),
            run.duration_s()
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
        print_contour_table(&e.model, &e.paper, &mask, "vcnc", "paper");
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
            out.join(vcnc_report::REPORT_FILE).display()
        );
    }
    Ok(())
}

/// The note on the stated-latency figures.
const STATED_LATENCY_NOTE: &str = "the latency is stated from the machine's control \
     configuration (feedback.dead_time_cycles / servo_rate_hz), not identified: the models \
     predict the logged actual position, which trails the physical axis by it";

/// A row of the stated-latency table: label, latencies (ms), discrepancy.
fn stated_row(label: &str, latency_s: &[f64], d: &Discrepancy) -> Vec<String> {
    vec![
        label.to_string(),
        if latency_s.is_empty() {
            "-".to_string()
        } else {
            latency_s
                .iter()
                .map(|t| format!("{}", t * 1e3))
                .collect::<Vec<_>>()
                .join(" ")
        },
        format!("{:.3}", d.tip_max_um),
        format!("{:.3}", d.tip_rms_um),
        format!("{:.4}", d.orientation_max_mrad),
        format!("{:.4}", d.orientation_rms_mrad),
    ]
}

const BUDGET_HEADER: [&str; 10] = [
    "effect",
    "true max [um]",
    "vcnc max [um]",
    "vcnc RMS [um]",
    "vcnc max [mrad]",
    "vcnc+lat. max [um]",
    "vcnc+lat. max [mrad]",
    "paper max [um]",
    "paper max [mrad]",
    "structures X Y Z A C",
];

fn budget_rows(rows: &[BudgetRow]) -> Vec<Vec<String>> {
    rows.iter()
        .map(|r| {
            vec![
                r.effect.to_string(),
                format!("{:.3}", r.true_max_um),
                format!("{:.3}", r.model.tip_max_um),
                format!("{:.3}", r.model.tip_rms_um),
                format!("{:.4}", r.model.orientation_max_mrad),
                format!("{:.3}", r.model_stated_latency.tip_max_um),
                format!("{:.4}", r.model_stated_latency.orientation_max_mrad),
                format!("{:.3}", r.paper_pso.tip_max_um),
                format!("{:.4}", r.paper_pso.orientation_max_mrad),
                r.structures
                    .iter()
                    .map(|(_, s)| short_tag(*s))
                    .collect::<Vec<_>>()
                    .join(" "),
            ]
        })
        .collect()
}

/// A two-letter tag of a structure for the budget table ([`BUDGET_NOTE`]).
fn short_tag(s: vcnc_identify::ModelStructure) -> &'static str {
    use vcnc_identify::ModelStructure as M;
    match s {
        M::Paper => "P",
        M::Delay => "D",
        M::FirstOrderFilter => "F1",
        M::SecondOrderFilter => "F2",
        M::ExtraPole => "XP",
    }
}

/// The budget table's note.
const BUDGET_NOTE: &str = "ideal: the drives without any effect table and without encoder \
     noise; each other row adds one group of machines/nmv5000-realistic.toml \
     (docs/machine-file.md, Drive effects); |prediction − true| over the feed moves; vcnc+lat.: vcnc's \
     models with the actual-value latency stated from the configuration (dead_time_cycles / \
     servo_rate_hz; 0 without a dead time); structures chosen per axis: P paper, D delay, F1/F2 \
     first/second-order reference filter, XP extra pole";

/// A short tag of a structure for tables.
fn structure_tag(s: vcnc_identify::ModelStructure) -> String {
    serde_json::to_value(s)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_else(|| format!("{s:?}"))
}

/// Header and rows: axis, true poles, chosen structure and its core poles, the paper's
/// method's poles, then each structure's validation free-run error max (chosen starred) and
/// the paper's method's.
fn realistic_identification_rows(
    ids: &[identify::AxisIdentification],
) -> (Vec<String>, Vec<Vec<String>>) {
    let poles = |m: &vcnc_drive::ClosedLoopModel| {
        m.poles().map_or("-".to_string(), |p| {
            format!(
                "{:.2} / {:.3} / {:.2}",
                p.wn / std::f64::consts::TAU,
                p.zeta,
                p.p / std::f64::consts::TAU
            )
        })
    };
    let structures: Vec<vcnc_identify::ModelStructure> = ids
        .first()
        .map(|r| r.result.structures.iter().map(|s| s.structure).collect())
        .unwrap_or_default();
    let mut header: Vec<String> = ["axis", "true", "chosen", "vcnc core", "paper's method"]
        .map(String::from)
        .to_vec();
    header.extend(structures.iter().map(|s| structure_tag(*s)));
    header.push("paper's method val.".to_string());
    let rows = ids
        .iter()
        .map(|r| {
            let k = r.unit.micro_factor();
            let mut row = vec![
                r.axis.to_string(),
                r.truth().map_or("-".to_string(), poles),
                structure_tag(r.result.structure),
                poles(&r.result.model.core),
                poles(&r.result.paper_pso),
            ];
            for s in &structures {
                let cell = r
                    .result
                    .structures
                    .iter()
                    .find(|f| f.structure == *s)
                    .and_then(|f| f.validation.as_ref())
                    .map_or("-".to_string(), |v| {
                        let star = if *s == r.result.structure { "*" } else { "" };
                        format!("{:.2} / {:.1}{star}", v.freerun_rms * k, v.freerun_max * k)
                    });
                row.push(cell);
            }
            let v = &r.validation_paper;
            row.push(format!(
                "{:.2} / {:.1}",
                v.freerun_rms * k,
                v.freerun_max * k
            ));
            row
        })
        .collect();
    (header, rows)
}
