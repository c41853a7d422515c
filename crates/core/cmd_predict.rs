//! `vcnc predict`: contour errors of a program with the true and the identified drives.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Result;
use vcnc_output::figures::{
    self, ContourEnvelopes, ModelLabel, PredictionDrawing, Role, TOOLPATH_VTP, VCNC_MODEL,
};
use vcnc_output::files::{ensure_dir, write_json};
use vcnc_output::runs::{
    CONTOUR_TABLE_NOTE, contour_report_table, contour_rows, report_table_file, run_report,
    worst_report_table, worst_rows,
};
use vcnc_output::table::ContourTable;
use vcnc_output::text::table as text_table;
use vcnc_pipeline::predict::{self, PredictOptions, PredictSummary, WorstBlock};
use vcnc_pipeline::{Measured, PredictionRecord, Source, identify, source};

use crate::cli::{OutputArg, TableArgs};
use crate::{Ctx, bounded_outputs, print_warnings};

/// Samples a long program's table, path figures and `toolpath.vtp` keep by default: every
/// sample up to this many, beyond it every N-th with the smallest N that stays within it
/// (about 36 MB of CSV, 7 MB of VTP and 10 MB of memory for the kept samples).
pub const DEFAULT_OUTPUT_SAMPLES: usize = 50_000;

/// The files of `vcnc predict`.
pub struct PredictInputs<'a> {
    /// Machine file.
    pub machine: &'a Path,
    /// G-code program.
    pub program: &'a Path,
    /// Identified models (identified on the fly when absent).
    pub model: Option<&'a Path>,
    /// Output folder.
    pub out: &'a Path,
}

/// `--outputs`: which files a prediction writes (summary.json always).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Outputs {
    /// The per-sample table.
    pub tables: bool,
    /// The SVG figures.
    pub figures: bool,
    /// toolpath.vtp.
    pub vtp: bool,
    /// manifest.json and report.html.
    pub report: bool,
}

impl Outputs {
    /// All outputs when `list` is absent, else those it names.
    pub fn from_args(list: &Option<Vec<OutputArg>>) -> Outputs {
        let on = |o: OutputArg| list.as_ref().is_none_or(|l| l.contains(&o));
        Outputs {
            tables: on(OutputArg::Tables),
            figures: on(OutputArg::Figures),
            vtp: on(OutputArg::Vtp),
            report: on(OutputArg::Report),
        }
    }
}

/// `vcnc predict MACHINE PROGRAM [--model MODEL] --out DIR`. The program is always streamed.
/// `contour_error.svg` is drawn from every sample (or, with `stream`, for a program over
/// [`crate::STREAM_ABOVE_BYTES`] and where the record keeps every N-th sample, from min/max
/// envelopes in bounded memory); the table, the path figures and `toolpath.vtp` keep every
/// N-th sample (`--decimate`, by default the N that keeps [`DEFAULT_OUTPUT_SAMPLES`]). The
/// statistics and the worst blocks are of every sample either way.
pub fn predict(
    inputs: &PredictInputs<'_>,
    measured: Measured,
    table_args: &TableArgs,
    outputs: &Outputs,
    stream: bool,
    ctx: &Ctx,
) -> Result<()> {
    let &PredictInputs {
        machine: machine_path,
        program,
        model,
        out,
    } = inputs;
    let machine = ctx.machine(machine_path)?;
    let plan = source::plan_file(&machine, program, ctx.lenient)?;
    print_warnings(&plan.warnings);
    let source = Source::Streamed(&plan);
    if !source.has_motion() {
        // Refused before identifying models: there is no contour to measure.
        return Err(vcnc_pipeline::Error::NoMotion {
            file: source.file().to_string(),
            samples: source.len(),
        }
        .into());
    }
    let models = identify::models_for(&machine, model)?;
    crate::release_freed_memory();
    print_warnings(&predict::model_warnings(&machine, &[&models]));
    let every = match table_args.decimate {
        Some(n) => usize::try_from(n).unwrap_or(usize::MAX),
        None => source.len().div_ceil(DEFAULT_OUTPUT_SAMPLES).max(1),
    };
    let mut table = table_args.options();
    table.decimate = every;
    let bounded = bounded_outputs(program, stream);
    // The record keeps every `every`-th sample for the path figures and the VTP (none with
    // --stream or a huge program, whose figure is the envelope alone); the envelopes draw
    // contour_error.svg from every sample wherever the record does not hold every sample.
    let wants_record = outputs.figures || outputs.vtp;
    let keep_record = wants_record && !bounded;
    let along_path_from_record = keep_record && every == 1;
    ensure_dir(out)?;
    let mut contour = outputs
        .tables
        .then(|| ContourTable::create(out, &machine, &source, &table))
        .transpose()?;
    let mut envelopes = (outputs.figures && !along_path_from_record)
        .then(|| ContourEnvelopes::new(source.len(), measured));
    let mut record = keep_record.then(|| PredictionRecord::of_run(source.len(), every));
    let opts = PredictOptions {
        measured,
        tracking: false,
    };
    let outcome = predict::predict(
        &machine,
        source,
        &[&models],
        &opts,
        &mut (&mut contour, (&mut envelopes, &mut record)),
    )?;
    let table_path = contour.map(|c| c.finish()).transpose()?;
    print_warnings(&outcome.reference.warnings);
    let mut report = run_report(
        out,
        "predict",
        machine_path,
        &machine,
        &source,
        &outcome.warnings,
        Some(models.source()),
        &table,
        ctx.lenient,
    );
    contour_report_table(&mut report, &[(VCNC_MODEL, &outcome.figures[0])]);
    worst_report_table(&mut report, &outcome.summaries[0].worst_blocks);
    let program_ts = (source.file(), source.ts());
    if let Some(record) = record {
        let mask = record.measured(measured);
        let labels = [ModelLabel {
            label: VCNC_MODEL,
            role: Role::Model,
        }];
        let draw = PredictionDrawing {
            figures: outputs.figures,
            along_path: along_path_from_record,
            vtp: outputs.vtp,
        };
        figures::prediction(
            &mut report,
            &machine,
            program_ts,
            record,
            &mask,
            &labels,
            &draw,
        )?;
    }
    if let Some(envelopes) = envelopes {
        envelopes.finish(&mut report, program_ts)?;
    }
    if let Some(path) = &table_path {
        report_table_file(&mut report, path, CONTOUR_TABLE_NOTE);
    }
    // The bytes of the per-sample outputs, written by now.
    let mut written: Vec<String> = table_path
        .iter()
        .filter_map(|p| p.file_name())
        .map(|n| n.to_string_lossy().into_owned())
        .collect();
    written.extend(report.manifest.figures.iter().map(|f| f.file.clone()));
    if outputs.vtp && out.join(TOOLPATH_VTP).is_file() && keep_record {
        written.push(TOOLPATH_VTP.to_string());
    }
    let mut bytes: BTreeMap<String, u64> = written
        .into_iter()
        .map(|f| {
            let n = std::fs::metadata(out.join(&f)).map_or(0, |m| m.len());
            (f, n)
        })
        .collect();
    let mut summary = PredictSummary::new(
        &machine,
        &source,
        outcome.summaries[0].clone(),
        &models,
        outcome.warnings.clone(),
    );
    summary.decimate = every;
    summary.output_bytes = bytes.clone();
    let summary_path = out.join("summary.json");
    write_json(&summary_path, &summary)?;
    bytes.insert("summary.json".into(), file_len(&summary_path));
    if outputs.report {
        report.finish()?;
        for f in ["manifest.json", vcnc_output::report::REPORT_FILE] {
            bytes.insert(f.into(), file_len(&out.join(f)));
        }
    }
    if !ctx.quiet {
        // Without a true machine, a prediction with the machine's own models is the result:
        // only its rows say something (the "true" rows would repeat them).
        let own = machine
            .own_models()
            .is_some_and(|own| own.models() == models.models());
        let rows: Vec<Vec<String>> = contour_rows(&outcome.figures[0])
            .into_iter()
            .filter(|(n, _, _)| !own || n.starts_with("predicted"))
            .map(|(n, a, b)| vec![n, format!("{a:.3}"), format!("{b:.4}")])
            .collect();
        println!("{}", crate::cycle_time_line(&source.cycle()));
        print!(
            "{}",
            text_table(
                &["contour error", "tool tip [um]", "orientation [mrad]"],
                &rows
            )
        );
        print!(
            "{}",
            worst_table(
                &outcome.summaries[0].worst_blocks,
                match (machine.has_true_machine(), machine.own_models().is_some()) {
                    (true, _) => "true machine",
                    (false, true) => "the machine's models",
                    (false, false) => "the machine: virtual drives and identified models",
                }
            )
        );
        let total: u64 = bytes.values().sum();
        let decimated = if every > 1 {
            format!(", 1 sample in {every} kept in the table/path outputs")
        } else {
            String::new()
        };
        if bounded {
            println!(
                "-> {} (streamed, {} samples{decimated}; {} written)",
                out.display(),
                source.len(),
                human_bytes(total)
            );
        } else {
            println!(
                "-> {} ({} samples{decimated}; {} written)",
                out.display(),
                source.len(),
                human_bytes(total)
            );
        }
    }
    Ok(())
}

fn file_len(p: &Path) -> u64 {
    std::fs::metadata(p).map_or(0, |m| m.len())
}

/// `1.2 MB`-style (powers of 1000).
fn human_bytes(n: u64) -> String {
    let n = n as f64;
    if n >= 1e6 {
        format!("{:.1} MB", n / 1e6)
    } else if n >= 1e3 {
        format!("{:.1} kB", n / 1e3)
    } else {
        format!("{n} B")
    }
}

/// The worst blocks as the terminal shows them: where (line, G-code) and why (kind, feeds,
/// the axis contributing most, flags).
/// `by` names what ranked them (the true machine, or a machine's models).
pub fn worst_table(blocks: &[WorstBlock], by: &str) -> String {
    if blocks.is_empty() {
        return String::new();
    }
    let (header, rows) = worst_rows(blocks, "um", 40);
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    format!("worst blocks ({by}):\n{}", text_table(&header, &rows))
}
