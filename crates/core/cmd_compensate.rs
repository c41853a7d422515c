//! `vcnc compensate`: compensated set-points from identified models, written as a fine-block
//! program, and judged on the true machine against the original program's path
//! (docs/compensation.md).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use vcnc_machine::{Machine, ModelSet};
use vcnc_pipeline::compensate::{
    self, AxisCompensateSummary, AxisRunFigures, CompensateOptions, CompensateSummary,
    Compensation, ContourStats, Judged, RunFigures,
};
use vcnc_pipeline::run::{self, Run};
use vcnc_report::{Axis, LineFigure, Panel, Role, Series, line_figure};

use crate::Ctx;
use crate::cli::CompensateArgs;
use crate::output::{ensure_dir, write_atomic, write_json};
use crate::report::RunReport;
use crate::sink::{TableOptions, write_table};
use crate::table::{print_warnings, table as text_table};

/// `vcnc compensate MACHINE PROGRAM --model MODEL [--iterations N] [--headroom H] --out DIR`.
pub fn compensate(args: &CompensateArgs, ctx: &Ctx) -> Result<()> {
    let CompensateArgs {
        machine: machine_path,
        program,
        model,
        iterations,
        headroom,
        out,
        table,
    } = args;
    let (iterations, headroom, table) = (*iterations, *headroom, &table.options());
    let machine = Machine::load(machine_path)?;
    let original = run::prepare_file(&machine, program, ctx.lenient)?;
    print_warnings(&original.warnings);
    let model_file = model.display().to_string();
    let set = ModelSet::load(model)?;
    let models = set.for_machine(&machine, &model_file)?;
    let latency = set.actual_latency_for_machine(&machine);
    let opts = CompensateOptions {
        max_iterations: iterations,
        ..CompensateOptions::default()
    };
    let compensate::Planned {
        compensation: comp,
        headroom,
        replanned,
    } = compensate::compensate_within_limits(
        &machine,
        program,
        &original,
        &models,
        &latency,
        &opts,
        headroom,
        ctx.lenient,
    )?;
    if !ctx.quiet {
        for h in &replanned {
            eprintln!(
                "note: a set-point leads a move at a velocity limit; planned again with a velocity headroom of {h:.3} (give --headroom to fix it)"
            );
        }
    }
    ensure_dir(out)?;
    let program_path = out.join("compensated.ngc");
    let header = vec![
        format!(
            "vcnc compensate: {} on machine {}, models {}",
            original.file, machine.name, model_file
        ),
        format!(
            "{} set-points at {} s, one G93 block each; lead {} s, tail {} s; velocity headroom {headroom}; docs/compensation.md",
            comp.len(),
            comp.ts,
            comp.lead as f64 * comp.ts,
            comp.tail as f64 * comp.ts
        ),
    ];
    let text = comp.program(&header);
    write_atomic(&program_path, text.as_bytes())?;
    // The program as the control runs it: re-read and interpolated, it must reproduce the
    // set-points; the true drives are judged on it.
    let program_name = program_path.display().to_string();
    let rerun = run::prepare(&machine, &text, &program_name, false)
        .with_context(|| format!("re-reading {program_name}"))?;
    let repro = compensate::reproduction(&comp, &rerun)?;
    if let Some(r) = repro.iter().find(|r| r.position != 0.0) {
        anyhow::bail!(
            "internal error: {program_name} does not reproduce the set-points of axis {} (off by {:e})",
            r.axis,
            r.position
        );
    }
    let before = compensate::on_true_machine(&machine, &original, &original)?;
    let after = compensate::on_true_machine(&machine, &original, &rerun)?;
    let after_models = match machine.kinematics {
        Some(_) => Some(compensate::with_models(
            &machine, &original, &rerun, &models, &latency,
        )?),
        None => None,
    };
    write_tables(out, &machine, &original, &comp, &after, table)?;
    let mut report = RunReport::new(
        out,
        format!(
            "vcnc compensate: {}",
            crate::figures::program_name(&original.file)
        ),
    );
    report.input("machine", machine.name.as_str());
    report.input("program", original.file.as_str());
    report.input("models", model_file.as_str());
    report.input("velocity headroom", headroom.to_string());
    if let (Some(b), Some(a)) = (&before.contour, &after.contour) {
        write_figure(&mut report, &machine, &original, b, a)?;
    }
    report.file(
        "compensated.ngc",
        "the compensated program: one G93 G1 block per sample period (docs/compensation.md)",
    );
    let summary = summary(
        &machine,
        &original,
        &model_file,
        &program_name,
        &comp,
        (&opts, headroom),
        (&before, &after, after_models.as_ref()),
        &repro,
    );
    write_json(&out.join("summary.json"), &summary)?;
    report.finish()?;
    if !ctx.quiet {
        print_report(&summary, &comp);
        println!("-> {}", out.display());
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn summary(
    machine: &Machine,
    original: &Run,
    model_file: &str,
    program_name: &str,
    comp: &Compensation,
    (opts, headroom): (&CompensateOptions, f64),
    (before, after, after_models): (&Judged, &Judged, Option<&vcnc_contour::ContourReport>),
    repro: &[compensate::Reproduction],
) -> CompensateSummary {
    let axes: BTreeMap<String, AxisCompensateSummary> = comp
        .axes
        .iter()
        .zip(repro)
        .zip(before.traces.iter().zip(&after.traces))
        .zip(&original.axes)
        .map(|(((a, r), (tb, ta)), o)| {
            let unit = a.reference.unit;
            let k = unit.micro_factor();
            (
                a.reference.name.to_string(),
                AxisCompensateSummary {
                    unit,
                    margin: a.margin,
                    within_limits: a.margin.within(),
                    iterations: a.history.len(),
                    model_error_linear_inverse: a.history.first().copied().unwrap_or(0.0) * k,
                    model_error: a
                        .desired
                        .iter()
                        .zip(&a.model)
                        .fold(0.0f64, |m, (d, y)| m.max((d - y).abs()))
                        * k,
                    reproduction: *r,
                    before: AxisRunFigures::of(tb, &o.pos, unit),
                    after: AxisRunFigures::of(ta, &a.desired, unit),
                },
            )
        })
        .collect();
    let figures = |j: &Judged| RunFigures {
        contour: j
            .contour
            .as_ref()
            .map(|c| ContourStats::over_feed(original, c)),
        cycle_time_s: j.cycle_time_s,
    };
    CompensateSummary {
        machine: machine.name.clone(),
        program: original.file.clone(),
        models: model_file.to_string(),
        compensated_program: program_name.to_string(),
        ts_s: comp.ts,
        lead_s: comp.lead as f64 * comp.ts,
        tail_s: comp.tail as f64 * comp.ts,
        options: *opts,
        velocity_headroom: headroom,
        before: figures(before),
        after: figures(after),
        after_models: after_models.map(|c| ContourStats::over_feed(original, c)),
        within_limits: comp.axes.iter().all(|a| a.margin.within()),
        axes,
    }
}

/// `references` (the set-points, the desired positions, the model's and the true drives'
/// positions) and `contour` (the compensated program's contour errors on the true machine).
fn write_tables(
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
fn write_figure(
    report: &mut RunReport,
    machine: &Machine,
    original: &Run,
    before: &vcnc_contour::ContourReport,
    after: &vcnc_contour::ContourReport,
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
        crate::figures::section::CONTOUR,
    )
}

fn print_report(s: &CompensateSummary, comp: &Compensation) {
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
    print!(
        "{}",
        text_table(
            &[
                "program",
                "contour max [um]",
                "RMS [um]",
                "orientation max [mrad]",
                "cycle [s]"
            ],
            &rows
        )
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
                format!(
                    "{:.3} -> {:.3}",
                    ax.before.torque_peak_nm, ax.after.torque_peak_nm
                ),
                (if m.within() { "ok" } else { "EXCEEDED" }).to_string(),
            ]
        })
        .collect();
    print!(
        "{}",
        text_table(
            &[
                "axis",
                "true tracking max",
                "set-point velocity / limit",
                "motion acceleration / limit",
                "set-point acceleration (not judged)",
                "torque peak [N m]",
                "limits"
            ],
            &rows
        )
    );
}
