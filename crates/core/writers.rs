//! Output files and tables of the kinds of result several commands produce (identifications
//! and predictions), so that command files never import each other.

use std::path::{Path, PathBuf};

use anyhow::Result;
use vcnc_drive::ClosedLoopModel;
use vcnc_machine::Machine;
use vcnc_pipeline::identify::{IdentifySummary, axis_warnings, model_set};
use vcnc_pipeline::predict::poses_at;
use vcnc_pipeline::stream_predict::PredictPiece;
use vcnc_pipeline::{AxisIdentification, ContourFigures, Prediction, Run};

use crate::Ctx;
use crate::figures;
use crate::output::{write_atomic, write_json};
use crate::report::RunReport;
use crate::sink::{TableOptions, write_table_rows};
use crate::table::table;

/// How `model.toml` describes models identified on a simulated machine.
pub const MACHINE_MODELS: &str = "identified by vcnc: stability-constrained PSO (paper section 3) + output-error refinement (docs/identification.md)";

/// Writes the figures of identifications, `summary.json`, `model.toml` and the folder's
/// report (its manifest and `report.html`).
pub fn write_identification(
    report: &mut RunReport,
    summary: &IdentifySummary,
    model_machine: &str,
    model_description: &str,
    ids: &[AxisIdentification],
) -> Result<()> {
    let out = report.dir().to_path_buf();
    for r in ids {
        figures::identification(report, r)?;
    }
    write_json(&out.join("summary.json"), summary)?;
    let set = model_set(model_machine, model_description, ids);
    write_atomic(&out.join("model.toml"), set.to_toml_string()?.as_bytes())?;
    identification_report_table(report, ids);
    let (header, rows) = model_rows(ids);
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    report.table(
        "chosen model structure and parameter uncertainty",
        &header,
        rows,
        "structure chosen by the validation error among those tried; ± one standard deviation \
         from the refinement's Jacobian with the residual's autocorrelation (docs/identification.md)",
    );
    let warnings: Vec<String> = ids.iter().flat_map(axis_warnings).collect();
    report.warnings(&warnings);
    for r in ids {
        let a = r.axis;
        report.file(
            &format!("frf_{a}.csv"),
            &format!("axis {a}: Bode data (f_hz; per model tracking and disturbance magnitude, dB, and phase, deg)"),
        );
    }
    report.file(
        "model.toml",
        "the identified models, for --model (docs/machine-file.md)",
    );
    report.finish()
}

/// The report of `vcnc identify MACHINE`: its inputs.
pub fn identify_machine_report(
    out: &Path,
    machine: &str,
    machine_file: &Path,
    ids: &[AxisIdentification],
    seed: Option<u64>,
) -> RunReport {
    let mut report = RunReport::new(out, format!("vcnc identify: {machine}"));
    report.input("machine", format!("{machine} ({})", machine_file.display()));
    let axes: Vec<String> = ids.iter().map(|r| r.axis.to_string()).collect();
    report.input("axes", axes.join(" "));
    report.input(
        "seed",
        seed.map_or(
            "the machine file's [identification] seeds".to_string(),
            |s| s.to_string(),
        ),
    );
    report
}
/// The report of an identification from a measured trace (one or more axes).
pub fn identify_trace_report(
    out: &Path,
    file: &str,
    format: vcnc_trace::Format,
    ids: &[AxisIdentification],
    options_file: Option<&Path>,
) -> RunReport {
    let mut report = RunReport::new(
        out,
        format!(
            "vcnc identify: trace {}",
            crate::figures::program_name(file)
        ),
    );
    report.input("trace", format!("{file} ({format})"));
    for id in ids {
        let t = &id.validation_trace;
        let channels = match &id.source {
            vcnc_pipeline::IdentificationSource::Measured { provenance, .. } => format!(
                "nominal '{}', actual '{}'",
                provenance.nominal.name, provenance.actual.name
            ),
            vcnc_pipeline::IdentificationSource::Simulated { .. } => String::new(),
        };
        report.input(
            &format!("axis {}", id.axis),
            format!(
                "{} samples at Ts = {} s, {}; {channels}",
                t.len(),
                t.ts,
                id.unit.as_str()
            ),
        );
    }
    report.input(
        "identifier options",
        options_file.map_or(
            "defaults (summary.json: identify_options)".to_string(),
            |p| format!("{} (summary.json: identify_options)", p.display()),
        ),
    );
    report
}

/// The identification table in a report (simulated machines: poles against the true drives).
pub fn identification_report_table(report: &mut RunReport, ids: &[AxisIdentification]) {
    if !ids.iter().any(|r| r.truth().is_some()) {
        return;
    }
    let (_, rows) = identification_rows(ids, vcnc_axis::Unit::micro_symbol);
    report.table(
        "identified poles against the true drives",
        &[
            "axis",
            "true machine ωn (Hz) / ζ / p (Hz)",
            "vcnc model",
            "paper's method",
            "LS baseline",
            "dc true / vcnc model",
            "validation: free-run error max / tracking peak",
        ],
        rows,
        "dc: Coulomb friction acceleration, axis units/s²; validation on a second excitation run \
         not used to identify",
    );
}

/// Per axis: the chosen structure and each of its parameters with its standard deviation.
pub fn model_rows(ids: &[AxisIdentification]) -> (Vec<String>, Vec<Vec<String>>) {
    let header = ["axis", "structure", "parameter", "value", "± std", "± %"]
        .map(String::from)
        .to_vec();
    let mut rows = Vec::new();
    for r in ids {
        let id = &r.result;
        let Some(u) = &id.uncertainty else {
            rows.push(vec![
                r.axis.to_string(),
                id.structure.to_string(),
                "-".into(),
                "-".into(),
                "-".into(),
                "-".into(),
            ]);
            continue;
        };
        for (i, p) in u.parameters.iter().enumerate() {
            let rel = 100.0 * p.relative();
            rows.push(vec![
                if i == 0 {
                    r.axis.to_string()
                } else {
                    String::new()
                },
                if i == 0 {
                    id.structure.to_string()
                } else {
                    String::new()
                },
                p.name.to_string(),
                format!("{:.6}", p.value),
                if p.std.is_finite() {
                    format!("{:.3e}", p.std)
                } else {
                    "undetermined".into()
                },
                if rel.is_finite() {
                    format!("{rel:.2}")
                } else {
                    "-".into()
                },
            ]);
        }
    }
    (header, rows)
}

/// The chosen structures and their parameters with standard deviations, for the terminal.
pub fn model_table(ids: &[AxisIdentification]) -> String {
    let (header, rows) = model_rows(ids);
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    table(&header, &rows)
}

/// `wn [Hz] / zeta / p [Hz]` of a model, or `-`.
pub fn fmt_poles(m: &ClosedLoopModel) -> String {
    match m.poles() {
        Some(p) => format!("{:.3} / {:.4} / {:.3}", p.wn_hz(), p.zeta, p.p_hz()),
        None => "-".into(),
    }
}

/// Per axis of a simulated machine: true vs identified poles, dc, and validation fit; the
/// header and the rows, errors labelled by `unit_label` (`um` for the terminal, `µm` in
/// reports).
pub fn identification_rows(
    results: &[AxisIdentification],
    unit_label: fn(vcnc_axis::Unit) -> &'static str,
) -> (Vec<String>, Vec<Vec<String>>) {
    let mut rows = Vec::new();
    for r in results {
        let label = unit_label(r.unit);
        let k = r.unit.micro_factor();
        let ls = &r.result.unconstrained_ls;
        let truth = r.truth();
        rows.push(vec![
            r.axis.to_string(),
            truth.map_or("-".into(), fmt_poles),
            fmt_poles(&r.result.identified),
            fmt_poles(&r.result.paper_pso),
            (if ls.stable { "stable" } else { "UNSTABLE" }).to_string(),
            format!(
                "{} / {:.1}",
                truth.map_or("-".into(), |t| format!("{:.1}", t.dc)),
                r.result.identified.dc
            ),
            format!(
                "{:.2} / {:.2} {label}",
                r.validation.freerun_max * k,
                r.validation.tracking_peak * k
            ),
        ]);
    }
    let header = [
        "axis",
        "true wn/zeta/p [Hz]",
        "identified",
        "paper PSO",
        "LS baseline",
        "dc true/id",
        "validation err/peak",
    ]
    .map(String::from)
    .to_vec();
    (header, rows)
}

/// [`identification_rows`] as the terminal table.
pub fn identification_table(results: &[AxisIdentification]) -> String {
    let (header, rows) = identification_rows(results, vcnc_axis::Unit::micro_label);
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    table(&header, &rows)
}

/// The `contour` table (`contour.csv` or `.parquet`): per sample t; reference, true and
/// predicted axis positions; reference, true and predicted tool tip and orientation; contour and
/// orientation errors of both.
pub fn write_contour_table(
    out: &Path,
    machine: &Machine,
    run: &Run,
    p: &Prediction,
    opts: &TableOptions,
) -> Result<PathBuf> {
    let n = run.len();
    let names: Vec<String> = run.axes.iter().map(|a| a.name.to_string()).collect();
    let header = contour_header(&names);
    let axis_cols: Vec<[&[f64]; 3]> = run
        .axes
        .iter()
        .enumerate()
        .map(|(i, a)| {
            [
                a.pos.as_slice(),
                p.true_traces[i].true_position.as_slice(),
                p.predicted[i].as_slice(),
            ]
        })
        .collect();
    let errors = [
        &p.true_contour.tip_mm,
        &p.predicted_contour.tip_mm,
        &p.true_contour.orientation_rad,
        &p.predicted_contour.orientation_rad,
    ];
    // Computed a row group at a time: the poses' components and the errors in µm / mrad never
    // exist for the whole run at once.
    let (ref_pos, true_pos, pred_pos) = (
        run.reference_positions(),
        p.true_positions(),
        p.predicted_positions(),
    );
    let mut failed = None;
    let path = write_table_rows(out, "contour", header, n, opts, |rows, cols| {
        let mut c = cols.iter_mut();
        let mut next = || c.next().expect("one buffer per header column");
        let t = next();
        t.extend(rows.clone().map(|k| run.time(k)));
        // The source line of the block running at each sample, so a user finds it in the
        // program.
        next().extend(run.lines[rows.clone()].iter().map(|l| f64::from(*l)));
        for a in &axis_cols {
            for s in a {
                next().extend_from_slice(&s[rows.clone()]);
            }
        }
        // The reference and actual poses, by the forward kinematics of this chunk's positions.
        let [ref_poses, true_poses, pred_poses] = [&ref_pos, &true_pos, &pred_pos].map(|x| {
            poses_at(machine, x, rows.clone()).unwrap_or_else(|e| {
                failed.get_or_insert(e);
                Vec::new()
            })
        });
        for poses in [&ref_poses, &true_poses, &pred_poses] {
            for i in 0..6 {
                next().extend(
                    poses
                        .iter()
                        .map(|q| if i < 3 { q.p[i] } else { q.o[i - 3] }),
                );
            }
        }
        for e in errors {
            next().extend(e[rows.clone()].iter().map(|x| x * 1000.0));
        }
    });
    if let Some(e) = failed {
        return Err(e.into());
    }
    path
}

/// Columns of `contour.csv` (axes named `names`, in machine order): `t`, `line`, per axis its
/// reference, true and predicted positions, the reference, true and predicted poses, and the
/// four errors (µm, mrad).
pub fn contour_header(names: &[String]) -> Vec<String> {
    let mut header = vec!["t".to_string(), "line".to_string()];
    for a in names {
        header.push(format!("{a}_ref"));
        header.push(format!("{a}_true"));
        header.push(format!("{a}_pred"));
    }
    let pose = ["px", "py", "pz", "ox", "oy", "oz"];
    for prefix in ["ref", "true", "pred"] {
        for nm in pose {
            header.push(format!("{prefix}_{nm}"));
        }
    }
    header.extend(
        [
            "true_contour_um",
            "pred_contour_um",
            "true_orientation_mrad",
            "pred_orientation_mrad",
        ]
        .map(String::from),
    );
    header
}

/// The columns of [`contour_header`] for a piece of a streamed prediction (sample period
/// `ts`), into `cols` (one buffer per column, cleared first): the values
/// [`write_contour_table`] writes for those samples.
pub fn contour_columns(p: &PredictPiece, ts: f64, cols: &mut [Vec<f64>]) {
    cols.iter_mut().for_each(Vec::clear);
    let mut c = cols.iter_mut();
    let mut next = || c.next().expect("one buffer per header column");
    next().extend((p.first..p.first + p.len()).map(|k| k as f64 * ts));
    next().extend(p.lines.iter().map(|l| f64::from(*l)));
    for i in 0..p.reference.len() {
        for s in [&p.reference[i], &p.truth[i], &p.predicted[i]] {
            next().extend_from_slice(s);
        }
    }
    for poses in [&p.reference_poses, &p.true_poses, &p.predicted_poses] {
        for i in 0..6 {
            next().extend(
                poses
                    .iter()
                    .map(|q| if i < 3 { q.p[i] } else { q.o[i - 3] }),
            );
        }
    }
    for e in [
        &p.true_tip_mm,
        &p.predicted_tip_mm,
        &p.true_orientation_rad,
        &p.predicted_orientation_rad,
    ] {
        next().extend(e.iter().map(|x| x * 1000.0));
    }
}

/// How a report lists `predict`'s per-sample table.
pub const CONTOUR_TABLE_NOTE: &str = "per sample: reference, true and predicted axis positions, \
     tool poses, contour and orientation errors (docs/cli.md)";

/// How a report lists `simulate`'s per-sample table.
pub const TRACE_TABLE_NOTE: &str = "per sample: t and per axis the reference, the true drive's \
     encoder reading and, with --model, the model's position (docs/cli.md)";

/// The report of a streamed run of `command` (`interpolate`, `predict`, `simulate`) of the
/// program `stream` planned, with its `warnings`.
#[allow(clippy::too_many_arguments)]
pub fn streamed_report(
    out: &Path,
    command: &str,
    machine_path: &Path,
    machine: &Machine,
    stream: &vcnc_pipeline::stream::ReferenceStream,
    warnings: &[String],
    models: Option<&str>,
    table: &TableOptions,
    ctx: &Ctx,
) -> RunReport {
    let info = RunInfo {
        file: &stream.file,
        samples: stream.len(),
        duration_s: stream.duration_s(),
        ts: stream.plan.ts,
        warnings,
    };
    run_report_info(
        out,
        command,
        machine_path,
        machine,
        &info,
        models,
        table,
        ctx,
    )
}

/// The per-sample table as a report lists it.
pub fn report_table_file(report: &mut RunReport, path: &Path, description: &str) {
    if let Some(name) = path.file_name() {
        report.file(&name.to_string_lossy(), description);
    }
}

/// The contour-error statistics of models against the true machine, as a report table: the
/// true machine's max and RMS, each model's, and each model's |model − true machine|.
pub fn contour_report_table(report: &mut RunReport, models: &[(&str, &ContourFigures)]) {
    let cells = |f: &[vcnc_pipeline::predict::Figure; 2]| {
        vec![
            format!("{:.3}", f[0].tip_um),
            format!("{:.3}", f[1].tip_um),
            format!("{:.4}", f[0].orientation_mrad),
            format!("{:.4}", f[1].orientation_mrad),
        ]
    };
    let mut rows = Vec::new();
    if let Some((_, f)) = models.first() {
        let mut r = vec![crate::figures::TRUE_MACHINE.to_string()];
        r.extend(cells(&[f.true_max, f.true_rms]));
        rows.push(r);
    }
    for (label, f) in models {
        let mut r = vec![label.to_string()];
        r.extend(cells(&[f.predicted_max, f.predicted_rms]));
        rows.push(r);
    }
    for (label, f) in models {
        let mut r = vec![format!("|{label} − true machine|")];
        r.extend(cells(&[f.discrepancy_max, f.discrepancy_rms]));
        rows.push(r);
    }
    report.table(
        "contour errors",
        &[
            "",
            "tool tip max (µm)",
            "tool tip RMS (µm)",
            "orientation max (mrad)",
            "orientation RMS (mrad)",
        ],
        rows,
        "|model − true machine|: the difference of the two contour errors at each sample",
    );
}

/// The contour figures as table rows: label, tool tip (µm), orientation (mrad).
pub fn contour_rows(f: &ContourFigures) -> Vec<(String, f64, f64)> {
    f.rows()
        .iter()
        .map(|(label, _, v)| (label.to_string(), v.tip_um, v.orientation_mrad))
        .collect()
}

/// The report of a run of `command` on a machine and a program: its inputs (machine, program,
/// the model file when there is one, table options, --lenient) and warnings.
#[allow(clippy::too_many_arguments)]
pub fn run_report(
    out: &Path,
    command: &str,
    machine_path: &Path,
    machine: &Machine,
    run: &Run,
    models: Option<&str>,
    table: &TableOptions,
    ctx: &Ctx,
) -> RunReport {
    let info = RunInfo {
        file: &run.file,
        samples: run.len(),
        duration_s: run.duration_s(),
        ts: run.ts,
        warnings: &run.warnings,
    };
    run_report_info(
        out,
        command,
        machine_path,
        machine,
        &info,
        models,
        table,
        ctx,
    )
}

/// What a report says about a run: for runs that are streamed rather than held as a
/// [`Run`].
pub struct RunInfo<'a> {
    /// The program's path.
    pub file: &'a str,
    /// Number of samples.
    pub samples: usize,
    /// Duration, s.
    pub duration_s: f64,
    /// Sample period, s.
    pub ts: f64,
    /// Warnings of the run.
    pub warnings: &'a [String],
}

/// [`run_report`] from a [`RunInfo`].
#[allow(clippy::too_many_arguments)]
pub fn run_report_info(
    out: &Path,
    command: &str,
    machine_path: &Path,
    machine: &Machine,
    run: &RunInfo<'_>,
    models: Option<&str>,
    table: &TableOptions,
    ctx: &Ctx,
) -> RunReport {
    let mut report = RunReport::new(
        out,
        format!(
            "vcnc {command}: {} on {}",
            figures::program_name(run.file),
            machine.name
        ),
    );
    report.input(
        "machine",
        format!("{} ({})", machine.name, machine_path.display()),
    );
    report.input(
        "program",
        format!(
            "{} ({} samples, {:.3} s at Ts = {} s)",
            run.file, run.samples, run.duration_s, run.ts
        ),
    );
    if let Some(m) = models {
        report.input("models", m);
    }
    report.input("table options", table.describe());
    if ctx.lenient {
        report.input("option", "--lenient");
    }
    report.warnings(run.warnings);
    report
}
