//! The outputs of `vcnc feed-plan`: the slowed blocks, the figure along the path, the
//! terminal's table (docs/compensation.md#feed-planning).

use std::path::Path;

use vcnc_pipeline::feed_plan::{
    self, FeedPlan, FeedPlanSummary, JudgedPlan, PathSeries, PlanFigures,
};
use vcnc_report::{Axis, LineFigure, Panel, Series, line_figure};

use crate::Result;
use crate::figures::{self, Role};
use crate::files::write_csv;
use crate::report::RunReport;
use crate::text::table;

/// `blocks.csv`: every line the plan slowed — line, whether its F is an inverse time (1: `G93`,
/// 1/min; 0: the program's units per minute), programmed and planned F, factor, predicted
/// largest contour error charged to the line (µm).
pub fn write_blocks(out: &Path, plan: &FeedPlan) -> Result<()> {
    let slowed: Vec<_> = plan.lines.iter().filter(|l| l.factor < 1.0).collect();
    let col = |f: fn(&feed_plan::PlannedLine) -> f64| -> Vec<f64> {
        slowed.iter().map(|l| f(l)).collect()
    };
    let cols = [
        col(|l| f64::from(l.line)),
        col(|l| f64::from(u8::from(l.inverse_time))),
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
            "inverse_time",
            "programmed_f",
            "planned_f",
            "factor",
            "predicted_max_um",
        ]
        .map(String::from),
        &refs,
    )
}

/// `feed_plan.svg`: contour errors on the true machine (log) and tool-tip speeds along the
/// original path, for the original, the per-line plan and the uniform scale (each series at
/// most [`feed_plan::FIGURE_POINTS`] points: a long run's largest error of each run of
/// consecutive samples).
pub fn write_figure(report: &mut RunReport, judged: &JudgedPlan, tolerance_um: f64) -> Result<()> {
    let runs: [(&str, Role, &PathSeries); 3] = [
        ("original program", Role::Reference, &judged.original.series),
        ("per-line feeds", Role::TrueMachine, &judged.planned.series),
        ("uniform feed scale", Role::Other(2), &judged.uniform.series),
    ];
    let err: Vec<Vec<f64>> = runs
        .iter()
        .map(|r| r.2.tip_mm.iter().map(|e| (e * 1e3).max(1e-3)).collect())
        .collect();
    let tol = vec![tolerance_um; 2];
    let end = |s: &PathSeries| s.reference_mm.last().copied().unwrap_or(1.0);
    let ends = [0.0, end(&judged.original.series)];
    let mut e_series: Vec<Series> = runs
        .iter()
        .zip(&err)
        .map(|((label, role, s), y)| Series::line(*label, *role, &s.position_mm, y))
        .collect();
    e_series.push(Series::line("tolerance", Role::Other(1), &ends, &tol));
    let v_series: Vec<Series> = runs
        .iter()
        .map(|(label, role, s)| Series::line(*label, *role, &s.reference_mm, &s.speed_mm_s))
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
        figures::section::CONTOUR,
    )
}

/// The terminal table of a feed plan and its one-line verdict.
pub fn tables(s: &FeedPlanSummary) -> String {
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
    let mut out = table(
        &[
            "program",
            "cycle [s]",
            "predicted max [um]",
            "true max [um]",
            "true orientation max [mrad]",
        ],
        &rows,
    );
    out.push_str(&format!(
        "tolerance {:.3} um: per-line feeds {:.1} % shorter than the uniform scale; {} of {} lines slowed (smallest factor {:.4})",
        s.tolerance_um,
        100.0 * s.saving_vs_uniform,
        s.lines_slowed,
        s.lines,
        s.min_factor
    ));
    out.push('\n');
    out
}
