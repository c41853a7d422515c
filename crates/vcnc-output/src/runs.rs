//! What several commands' reports share: the report of a run on a machine and a program (its
//! inputs and warnings), the per-sample table's entry, and the contour-error tables.

use std::path::Path;

use vcnc_pipeline::predict::WorstBlock;
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

/// The worst blocks of a prediction, where (line, G-code, cut to `text_chars` characters) and
/// why (cutting or link move, planned and achieved feed, the axis whose following error moves
/// the tip farthest and by how much, flags): the header and the rows, errors labelled
/// `micro` (`um` in the terminal, `µm` in reports).
pub fn worst_rows(
    blocks: &[WorstBlock],
    micro: &str,
    text_chars: usize,
) -> (Vec<String>, Vec<Vec<String>>) {
    let rows = blocks
        .iter()
        .map(|b| {
            let c = b.cause.as_ref();
            let text = c.map_or(String::new(), |c| {
                let mut t: String = c.text.chars().take(text_chars).collect();
                if c.text.chars().count() > text_chars {
                    t.push('~');
                }
                t
            });
            vec![
                b.line.to_string(),
                format!("{:.3}", b.contour_max_um),
                c.map_or(String::new(), |c| c.kind.to_string()),
                c.map_or(String::new(), |c| format!("{:.0}", c.planned_feed_mm_min)),
                c.map_or(String::new(), |c| format!("{:.0}", c.achieved_feed_mm_min)),
                c.map_or(String::new(), |c| {
                    format!("{} {:.1}", c.axis, c.axis_share_um)
                }),
                c.map_or(String::new(), |c| c.flags.words().join(", ")),
                text,
            ]
        })
        .collect();
    let header = vec![
        "line".to_string(),
        format!("tip [{micro}]"),
        "move".to_string(),
        "planned [mm/min]".to_string(),
        "achieved [mm/min]".to_string(),
        format!("axis [{micro}]"),
        "flags".to_string(),
        "G-code".to_string(),
    ];
    (header, rows)
}

/// The worst blocks' table in a report ([`worst_rows`]); nothing when there are none.
pub fn worst_report_table(report: &mut RunReport, blocks: &[WorstBlock]) {
    if blocks.is_empty() {
        return;
    }
    let (header, rows) = worst_rows(blocks, "µm", 60);
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    report.table(
        "worst blocks (true machine)",
        &header,
        rows,
        "the program lines where the true machine's tool-tip contour error peaks; move: cutting, \
         link or dwell; planned / achieved: the reference's and the true machine's peak tool-tip \
         speed over the block; axis: the axis whose following error alone moves the tip farthest \
         across the path at the worst sample, and by how much; flags: at an axis limit, axis \
         reversal, sharp corner, rotary unwinding (docs/contour.md, \"Why a block is bad\")",
    );
}
