//! What several commands' reports share: the report of a run on a machine and a program (its
//! inputs and warnings), the per-sample table's entry, and the contour-error tables.

use std::path::Path;

use vcnc_pipeline::{ContourFigures, Machine, Source};

use crate::figures;
use crate::report::RunReport;
use crate::table::TableOptions;

/// How a report lists `predict`'s per-sample table.
pub const CONTOUR_TABLE_NOTE: &str = "per sample: reference, true and predicted axis positions, \
     tool poses, contour and orientation errors (docs/cli.md)";

/// How a report lists `simulate`'s per-sample table.
pub const TRACE_TABLE_NOTE: &str = "per sample: t and per axis the reference, the true drive's \
     encoder reading and, with --model, the model's position (docs/cli.md)";

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
        let mut r = vec![figures::TRUE_MACHINE.to_string()];
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

/// The report of a run of `command` on a machine and the program of `source`: its inputs
/// (machine, program, the models when there are some, table options, --lenient) and the run's
/// `warnings`.
#[allow(clippy::too_many_arguments)]
pub fn run_report(
    out: &Path,
    command: &str,
    machine_path: &Path,
    machine: &Machine,
    source: &Source<'_>,
    warnings: &[String],
    models: Option<&str>,
    table: &TableOptions,
    lenient: bool,
) -> RunReport {
    let file = source.file();
    let mut report = RunReport::new(
        out,
        format!(
            "vcnc {command}: {} on {}",
            figures::program_name(file),
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
            file,
            source.len(),
            source.duration_s(),
            source.ts()
        ),
    );
    if let Some(m) = models {
        report.input("models", m);
    }
    report.input("table options", table.describe());
    if lenient {
        report.input("option", "--lenient");
    }
    report.warnings(warnings);
    report
}
