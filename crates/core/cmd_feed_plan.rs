//! `vcnc feed-plan`: per-block feeds that keep the predicted contour error within a tolerance,
//! against the uniform feed scale that meets it, judged on the true machine
//! (docs/compensation.md#feed-planning).

use std::path::Path;

use anyhow::Result;
use vcnc_machine::{Machine, ModelSet};
use vcnc_pipeline::compensate::{self, ContourStats, Judged};
use vcnc_pipeline::feed_plan::{self, FeedPlan, FeedPlanOptions, FeedPlanSummary, PlanFigures};
use vcnc_pipeline::run::{self, Run};
use vcnc_report::{Axis, LineFigure, Panel, Role, Series, line_figure};

use crate::output::{ensure_dir, write_atomic, write_csv, write_json};
use crate::report::RunReport;
use crate::table::{print_warnings, table as text_table};
use crate::{Ctx, bad_input};

/// A tolerance with its unit (`10um`, `10µm`, `0.01mm`) in mm.
fn parse_length(s: &str) -> Result<f64> {
    let t = s.trim();
    let (num, scale) = if let Some(n) = t.strip_suffix("um").or_else(|| t.strip_suffix("µm")) {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix("mm") {
        (n, 1.0)
    } else {
        return Err(bad_input(format!(
            "--tolerance {s}: give the unit, e.g. 10um or 0.01mm"
        )));
    };
    match num.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v * scale),
        _ => Err(bad_input(format!(
            "--tolerance {s}: expected a positive number before the unit"
        ))),
    }
}

/// An angle tolerance with its unit (`0.05mrad`, `0.003deg`, `5e-5rad`) in rad.
fn parse_angle(s: &str) -> Result<f64> {
    let t = s.trim();
    let (num, scale) = if let Some(n) = t.strip_suffix("mrad") {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix("rad") {
        (n, 1.0)
    } else if let Some(n) = t.strip_suffix("deg") {
        (n, std::f64::consts::PI / 180.0)
    } else {
        return Err(bad_input(format!(
            "--orientation-tolerance {s}: give the unit, e.g. 0.05mrad or 0.003deg"
        )));
    };
    match num.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v * scale),
        _ => Err(bad_input(format!(
            "--orientation-tolerance {s}: expected a positive number before the unit"
        ))),
    }
}

/// `vcnc feed-plan MACHINE PROGRAM --model MODEL --tolerance 10um [--orientation-tolerance …]`.
pub fn feed_plan(
    machine_path: &Path,
    program: &Path,
    model: &Path,
    tolerance: &str,
    orientation: Option<&str>,
    out: &Path,
    ctx: &Ctx,
) -> Result<()> {
    let tolerance_mm = parse_length(tolerance)?;
    let orientation_tolerance_rad = orientation.map(parse_angle).transpose()?;
    let machine = Machine::load(machine_path)?;
    let src = run::read_program(program)?;
    let file = program.display().to_string();
    let model_file = model.display().to_string();
    let set = ModelSet::load(model)?;
    let models = set.for_machine(&machine, &model_file)?;
    let latency = set.actual_latency_for_machine(&machine);
    let opts = FeedPlanOptions {
        orientation_tolerance_rad,
        ..FeedPlanOptions::new(tolerance_mm)
    };
    let plan = feed_plan::plan_feeds(&machine, &src, &file, &models, &latency, &opts, ctx.lenient)?;
    print_warnings(&plan.original.warnings);
    ensure_dir(out)?;
    let planned_path = out.join("planned.ngc");
    let uniform_path = out.join("uniform.ngc");
    write_atomic(&planned_path, plan.plan.text.as_bytes())?;
    write_atomic(&uniform_path, plan.uniform.text.as_bytes())?;
    // Judged on the true machine against the ORIGINAL program's path.
    let original = compensate::on_true_machine(&machine, &plan.original, &plan.original)?;
    let planned = compensate::on_true_machine(&machine, &plan.original, &plan.plan.run)?;
    let uniform = compensate::on_true_machine(&machine, &plan.original, &plan.uniform.run)?;
    write_blocks(out, &plan)?;
    let mut report = RunReport::new(
        out,
        format!("vcnc feed-plan: {}", crate::figures::program_name(&file)),
    );
    report.input("machine", machine.name.as_str());
    report.input("program", file.as_str());
    report.input("models", model_file.as_str());
    report.input("tolerance", format!("{} µm", tolerance_mm * 1e3));
    report.file("planned.ngc", "the program with the planned per-line feeds");
    report.file(
        "uniform.ngc",
        "the program with the uniform feed scale that meets the tolerance",
    );
    write_figure(
        &mut report,
        &machine,
        &plan,
        [
            original.contour(&machine)?,
            planned.contour(&machine)?,
            uniform.contour(&machine)?,
        ],
        tolerance_mm * 1e3,
    )?;
    let figures = |p: &vcnc_contour::ContourReport, j: &Judged| -> Result<PlanFigures> {
        Ok(PlanFigures {
            cycle_time_s: j.cycle_time_s,
            predicted: ContourStats::over_feed(&plan.original, p),
            true_machine: ContourStats::over_feed(&plan.original, j.contour(&machine)?),
        })
    };
    let summary = FeedPlanSummary {
        machine: machine.name.clone(),
        program: file,
        models: model_file,
        planned_program: planned_path.display().to_string(),
        options: opts,
        lag_s: plan.lag_s,
        tolerance_um: tolerance_mm * 1e3,
        original: figures(&plan.original_predicted, &original)?,
        planned: figures(&plan.plan.predicted, &planned)?,
        uniform: figures(&plan.uniform.predicted, &uniform)?,
        uniform_factor: plan.uniform_factor,
        saving_vs_uniform: 1.0 - planned.cycle_time_s / uniform.cycle_time_s,
        lines: plan.lines.len(),
        lines_slowed: plan.lines.iter().filter(|l| l.factor < 1.0).count(),
        min_factor: plan.lines.iter().map(|l| l.factor).fold(1.0, f64::min),
        history: plan.history.clone(),
    };
    write_json(&out.join("summary.json"), &summary)?;
    report.finish()?;
    if !ctx.quiet {
        print_report(&summary);
        println!("-> {}", out.display());
    }
    Ok(())
}

/// `blocks.csv`: every line the plan slowed — line, programmed and planned F (the program's
/// units per minute), factor, predicted largest contour error charged to the line (µm).
fn write_blocks(out: &Path, plan: &FeedPlan) -> Result<()> {
    let slowed: Vec<_> = plan.lines.iter().filter(|l| l.factor < 1.0).collect();
    let col = |f: fn(&feed_plan::PlannedLine) -> f64| -> Vec<f64> {
        slowed.iter().map(|l| f(l)).collect()
    };
    let cols = [
        col(|l| f64::from(l.line)),
        col(|l| l.programmed_f),
        col(|l| l.planned_f),
        col(|l| l.factor),
        col(|l| l.predicted_max_um),
    ];
    let refs: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
    write_csv(
        &out.join("blocks.csv"),
        &[
            "line",
            "programmed_f",
            "planned_f",
            "factor",
            "predicted_max_um",
        ]
        .map(String::from),
        &refs,
    )
}

/// Tool-tip speed (mm/s) of a run's reference at each sample, and the arc length (mm) of its
/// reference tip path there.
fn speed_along(machine: &Machine, run: &Run) -> (Vec<f64>, Vec<f64>) {
    let poses = run.reference_poses(machine).unwrap_or_default();
    let mut s = Vec::with_capacity(poses.len());
    let mut v = Vec::with_capacity(poses.len());
    let mut acc = 0.0;
    for (k, p) in poses.iter().enumerate() {
        let step = poses.get(k + 1).map_or(0.0, |q| (q.p - p.p).norm());
        s.push(acc);
        v.push(step / run.ts);
        acc += step;
    }
    (s, v)
}

/// `feed_plan.svg`: contour errors on the true machine (log) and tool-tip speeds along the
/// original path, for the original, the per-line plan and the uniform scale.
fn write_figure(
    report: &mut RunReport,
    machine: &Machine,
    plan: &FeedPlan,
    judged: [&vcnc_contour::ContourReport; 3],
    tolerance_um: f64,
) -> Result<()> {
    let runs: [(&str, Role, &Run); 3] = [
        ("original program", Role::Reference, &plan.original),
        ("per-line feeds", Role::TrueMachine, &plan.plan.run),
        ("uniform feed scale", Role::Other(2), &plan.uniform.run),
    ];
    let pos: Vec<Vec<f64>> = judged
        .iter()
        .map(|j| compensate::path_position_mm(machine, &plan.original, j))
        .collect();
    let err: Vec<Vec<f64>> = judged
        .iter()
        .map(|j| j.tip_mm.iter().map(|e| (e * 1e3).max(1e-3)).collect())
        .collect();
    let speeds: Vec<(Vec<f64>, Vec<f64>)> =
        runs.iter().map(|r| speed_along(machine, r.2)).collect();
    let tol = vec![tolerance_um; 2];
    let ends = [0.0, pos[0].last().copied().unwrap_or(1.0)];
    let mut e_series: Vec<Series> = runs
        .iter()
        .zip(pos.iter().zip(&err))
        .map(|((label, role, _), (x, y))| Series::line(*label, *role, x, y))
        .collect();
    e_series.push(Series::line("tolerance", Role::Other(1), &ends, &tol));
    let v_series: Vec<Series> = runs
        .iter()
        .zip(&speeds)
        .map(|((label, role, _), (x, y))| Series::line(*label, *role, x, y))
        .collect();
    let fig = line_figure(&LineFigure::new(
        "feed planning: contour errors on the true machine and tool-tip speeds",
        Axis::linear("position along the programmed tool-tip path", "mm"),
        vec![
            Panel::new(Axis::log("tool-tip contour error", "µm"), e_series),
            Panel::new(Axis::log("tool-tip speed", "mm/s"), v_series),
        ],
    ));
    report.figure(
        "feed_plan.svg",
        fig,
        "Tool-tip contour errors of the true machine along the programmed path (the original, \
         the per-line feeds and the uniform feed scale, all against the original path) with the \
         tolerance; below, the tool-tip speed of each.",
        crate::figures::section::CONTOUR,
    )
}

fn print_report(s: &FeedPlanSummary) {
    let row = |name: &str, f: &PlanFigures| {
        vec![
            name.to_string(),
            format!("{:.3}", f.cycle_time_s),
            format!("{:.3}", f.predicted.contour_max_um),
            format!("{:.3}", f.true_machine.contour_max_um),
            format!("{:.4}", f.true_machine.orientation_max_mrad),
        ]
    };
    let rows = vec![
        row("original", &s.original),
        row("per-line feeds", &s.planned),
        row(&format!("uniform x{:.4}", s.uniform_factor), &s.uniform),
    ];
    print!(
        "{}",
        text_table(
            &[
                "program",
                "cycle [s]",
                "predicted max [um]",
                "true max [um]",
                "true orientation max [mrad]"
            ],
            &rows
        )
    );
    println!(
        "tolerance {:.3} um: per-line feeds {:.1} % shorter than the uniform scale; {} of {} lines slowed (smallest factor {:.4})",
        s.tolerance_um,
        100.0 * s.saving_vs_uniform,
        s.lines_slowed,
        s.lines,
        s.min_factor
    );
}
