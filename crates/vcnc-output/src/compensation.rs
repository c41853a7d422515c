//! The outputs of `vcnc compensate`: the set-point and contour tables, the before/after
//! figure, the terminal's tables (docs/compensation.md).

use std::path::Path;

use vcnc_pipeline::compensate::{self, CompensateSummary, Compensation, ContourStats, Judged};
use vcnc_pipeline::{ContourReport, Machine, Run};
use vcnc_report::{Axis, LineFigure, Panel, Series, line_figure};

use crate::Result;
use crate::figures::{self, Role};
use crate::report::RunReport;
use crate::table::{TableOptions, write_table};
use crate::text::table;

/// `references` (the set-points, the desired positions, the model's and the true drives'
/// positions) and `contour` (the compensated program's contour errors on the true machine).
pub fn write_tables(
    out: &Path,
    machine: &Machine,
    original: &Run,
    comp: &Compensation,
    after: &Judged,
    opts: &TableOptions,
) -> Result<()> {
    let n = comp.len();
    // Time from the original program's first sample (negative in the lead).
    let t: Vec<f64> = (0..n)
        .map(|k| (k as f64 - comp.lead as f64) * comp.ts)
        .collect();
    let mut header = vec!["t".to_string()];
    let mut cols: Vec<&[f64]> = vec![&t];
    for (a, tr) in comp.axes.iter().zip(&after.traces) {
        let name = a.reference.name;
        for (suffix, col) in [
            ("", &a.reference.pos),
            ("_vel", &a.reference.vel),
            ("_acc", &a.reference.acc),
            ("_desired", &a.desired),
            ("_model", &a.model),
            ("_true", &tr.true_position),
        ] {
            header.push(format!("{name}{suffix}"));
            cols.push(col);
        }
    }
    write_table(out, "references", header, &cols, opts)?;
    let Some(contour) = &after.contour else {
        return Ok(());
    };
    let tip: Vec<f64> = contour.tip_mm.iter().map(|e| e * 1e3).collect();
    let or: Vec<f64> = contour.orientation_rad.iter().map(|e| e * 1e3).collect();
    let s = compensate::path_position_mm(machine, original, contour);
    write_table(
        out,
        "contour",
        ["t", "path_mm", "contour_um", "orientation_mrad"]
            .map(String::from)
            .to_vec(),
        &[&t, &s, &tip, &or],
        opts,
    )?;
    Ok(())
}

/// `contour_before_after.svg`: tool-tip and orientation contour errors of the original and the
/// compensated program on the true machine, along the original path (log scale).
pub fn write_figure(
    report: &mut RunReport,
    machine: &Machine,
    original: &Run,
    before: &ContourReport,
    after: &ContourReport,
) -> Result<()> {
    let floor = |v: &[f64], k: f64| -> Vec<f64> { v.iter().map(|e| (e * k).max(1e-4)).collect() };
    let (sb, sa) = (
        compensate::path_position_mm(machine, original, before),
        compensate::path_position_mm(machine, original, after),
    );
    let (tb, ta) = (floor(&before.tip_mm, 1e3), floor(&after.tip_mm, 1e3));
    let (ob, oa) = (
        floor(&before.orientation_rad, 1e3),
        floor(&after.orientation_rad, 1e3),
    );
    let series = |b, a| {
        vec![
            Series::line("original program", Role::Reference, &sb, b),
            Series::line("compensated program", Role::TrueMachine, &sa, a),
        ]
    };
    let fig = line_figure(&LineFigure::new(
        "contour errors on the true machine, before and after compensation",
        Axis::linear("position along the programmed tool-tip path", "mm"),
        vec![
            Panel::new(Axis::log("tool-tip contour error", "µm"), series(&tb, &ta)),
            Panel::new(
                Axis::log("orientation contour error", "mrad"),
                series(&ob, &oa),
            ),
        ],
    ));
    report.figure(
        "contour_before_after.svg",
        fig,
        "Tool-tip and orientation contour errors of the true machine along the programmed \
         path: the original program and the compensated one, both against the original path.",
        figures::section::CONTOUR,
    )
}

/// The terminal tables of a compensation: the programs' contour errors and cycle times, then
/// per axis the tracking, the limits and the torque.
pub fn tables(s: &CompensateSummary, comp: &Compensation) -> String {
    let row = |name: &str, c: Option<ContourStats>, cycle: f64| {
        let f = |v: Option<f64>, d: usize| v.map_or("-".to_string(), |v| format!("{v:.d$}"));
        vec![
            name.to_string(),
            f(c.map(|c| c.contour_max_um), 3),
            f(c.map(|c| c.contour_rms_um), 3),
            f(c.map(|c| c.orientation_max_mrad), 4),
            format!("{cycle:.3}"),
        ]
    };
    let rows = vec![
        row(
            "original, true machine",
            s.before.contour,
            s.before.cycle_time_s,
        ),
        row(
            "compensated, true machine",
            s.after.contour,
            s.after.cycle_time_s,
        ),
        row("compensated, models", s.after_models, s.after.cycle_time_s),
    ];
    let mut out = table(
        &[
            "program",
            "contour max [um]",
            "RMS [um]",
            "orientation max [mrad]",
            "cycle [s]",
        ],
        &rows,
    );
    let rows: Vec<Vec<String>> = comp
        .axes
        .iter()
        .map(|a| {
            let m = &a.margin;
            let u = a.reference.unit;
            let ax = &s.axes[a.reference.name.as_str()];
            let l = u.micro_label();
            vec![
                a.reference.name.to_string(),
                format!(
                    "{:.2} -> {:.3} {l}",
                    ax.before.tracking_max, ax.after.tracking_max
                ),
                format!("{:.1} / {} {u}/s", m.reference_velocity, m.velocity_limit),
                format!(
                    "{:.0} / {} {u}/s2",
                    m.motion_acceleration, m.acceleration_limit
                ),
                format!("{:.0} {u}/s2", m.reference_acceleration),
                match (ax.before.torque_peak_nm, ax.after.torque_peak_nm) {
                    (Some(b), Some(a)) => format!("{b:.3} -> {a:.3}"),
                    _ => "- (model)".to_string(),
                },
                format!("{:.3} {l}", ax.reproduction.position * u.micro_factor()),
                (if m.within() { "ok" } else { "EXCEEDED" }).to_string(),
            ]
        })
        .collect();
    out.push_str(&table(
        &[
            "axis",
            "true tracking max",
            "set-point velocity / limit",
            "motion acceleration / limit",
            "set-point acceleration (not judged)",
            "torque peak [N m]",
            "program off set-point",
            "limits",
        ],
        &rows,
    ));
    let w = &s.written;
    out.push_str(&format!(
        "program: {} G1 blocks ({:.0} ms or longer; block cycle {:.0} ms), {} dwells; words at {} mm and {} deg, merged within {} mm and {} deg\n",
        w.blocks,
        w.shortest_block_s * 1e3,
        w.block_cycle_s * 1e3,
        w.dwells,
        w.resolution_mm,
        w.rotary_resolution_deg,
        w.chord_tolerance_mm,
        w.rotary_chord_tolerance_deg
    ));
    out
}
