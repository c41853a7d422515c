//! `vcnc sweep` and `vcnc sweep-merge`: machine-configuration experiments (the engine is
//! `vcnc_pipeline::sweep`). Rows are written in configuration order, a chunk at a time, each
//! row whole and flushed, so an interrupted sweep keeps every row already written and the file
//! is the same for any thread count.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use vcnc_pipeline::run::read_program;
use vcnc_pipeline::sweep::{self, Sweep, SweepOutcome};
use vcnc_pipeline::{MachineDocument, MachineModels};

use crate::Ctx;
use crate::cli::SweepArgs;
use vcnc_output::figures::{self, program_name};
use vcnc_output::files::{ensure_dir, write_atomic, write_json};
use vcnc_output::report::RunReport;

pub fn sweep(args: &SweepArgs, ctx: &Ctx) -> Result<()> {
    let doc = MachineDocument::load(&args.machine)?;
    let program = read_program(&args.program)?;
    let program_file = args.program.display().to_string();
    let models = match &args.model {
        Some(p) => Some(MachineModels::load(p, &doc.check()?)?),
        None => None,
    };
    let plan = Sweep::new(
        &doc,
        &program,
        &program_file,
        &args.sets,
        args.shard.as_deref(),
        models,
        ctx.tool_table
            .as_deref()
            .map(vcnc_pipeline::run::load_tool_table)
            .transpose()?,
        ctx.lenient,
    )?;
    // Configurations that cannot be built are found before anything runs or is written.
    match plan.check_buildable() {
        Err(vcnc_pipeline::Error::InvalidConfigurations {
            count,
            total,
            first_index,
            first_set,
            first,
        }) if args.keep_going => {
            if !ctx.quiet {
                eprintln!(
                    "warning: {count} of {total} configurations cannot be built and are recorded as failed rows, e.g. #{first_index} {first_set}: {first}"
                );
            }
        }
        other => other?,
    }
    ensure_dir(&args.out)?;
    let csv_path = args.out.join("sweep.csv");
    let mut file =
        File::create(&csv_path).with_context(|| format!("cannot create {}", csv_path.display()))?;
    writeln!(file, "{}", plan.header().join(","))?;
    file.flush()?;
    let bar = if ctx.quiet {
        ProgressBar::hidden()
    } else {
        let b = ProgressBar::new(plan.indices().len() as u64);
        b.set_style(
            ProgressStyle::with_template(
                "{bar:40} {pos}/{len} configurations, {per_sec}, ETA {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    };
    let chunk = (4 * rayon::current_num_threads()).max(8);
    let started = std::time::Instant::now();
    let outcome = plan.run(chunk, &|| bar.inc(1), |rows| {
        let mut text = String::new();
        for r in rows {
            text.push_str(&plan.cells(r).join(","));
            text.push('\n');
        }
        // One write per chunk of whole rows, then flush: an interruption keeps whole rows.
        file.write_all(text.as_bytes())?;
        file.flush()
    })?;
    bar.finish_and_clear();
    let elapsed = started.elapsed().as_secs_f64();
    write_json(&args.out.join("summary.json"), &plan.summary(&outcome))?;
    let keys: Vec<String> = plan.keys().iter().map(|k| k.key.clone()).collect();
    let mut report = RunReport::new(
        &args.out,
        format!(
            "vcnc sweep: {} on {}",
            program_name(&program_file),
            plan.base().name
        ),
    );
    report.input(
        "machine",
        format!("{} ({})", plan.base().name, args.machine.display()),
    );
    report.input("program", program_file.as_str());
    for s in &args.sets {
        report.input("--set", s.as_str());
    }
    if let Some(m) = &args.model {
        report.input("models", m.display().to_string());
    }
    if let Some(s) = &args.shard {
        report.input("shard", s.as_str());
    }
    sweep_report(&mut report, &keys, &outcome)?;
    report.finish()?;
    if !ctx.quiet {
        println!(
            "{} configurations ({} ok, {} failed) in {:.2} s ({:.1}/s on {} threads) -> {}",
            outcome.ok + outcome.failed,
            outcome.ok,
            outcome.failed,
            elapsed,
            (outcome.ok + outcome.failed) as f64 / elapsed.max(1e-9),
            rayon::current_num_threads(),
            args.out.display()
        );
        if let Some(b) = &outcome.best {
            let set: Vec<String> = keys
                .iter()
                .zip(&b.values)
                .map(|(k, v)| format!("{k}={v}"))
                .collect();
            println!(
                "best: #{} {} with contour error {:.3} um",
                b.index,
                set.join(" "),
                b.contour_max_um
            );
        }
    }
    outcome.check_any_ok()?;
    Ok(())
}

/// `vcnc sweep-merge DIR... --out DIR`: joins shard tables (same header) in index order.
pub fn merge(dirs: &[PathBuf], out: &Path, ctx: &Ctx) -> Result<()> {
    let tables = dirs
        .iter()
        .map(|d| {
            let path = d.join("sweep.csv");
            std::fs::read_to_string(&path)
                .map(|text| (path.display().to_string(), text))
                .map_err(|e| {
                    vcnc_pipeline::Error::Io {
                        file: path.display().to_string(),
                        message: e.to_string(),
                    }
                    .into()
                })
        })
        .collect::<Result<Vec<_>>>()?;
    let merged = sweep::merge(&tables)?;
    ensure_dir(out)?;
    write_atomic(&out.join("sweep.csv"), merged.text.as_bytes())?;
    let dirs: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
    write_json(&out.join("summary.json"), &merged.summary(dirs.clone()))?;
    let mut report = RunReport::new(out, format!("vcnc sweep-merge: {} shards", dirs.len()));
    for d in &dirs {
        report.input("shard", d.as_str());
    }
    sweep_report(&mut report, &merged.keys, &merged.outcome)?;
    report.finish()?;
    if !ctx.quiet {
        println!(
            "merged {} rows from {} shards -> {}",
            merged.rows,
            tables.len(),
            out.display()
        );
    }
    Ok(())
}

/// What both sweep commands report: the failures, the best configuration, the figures and the
/// table.
fn sweep_report(report: &mut RunReport, keys: &[String], outcome: &SweepOutcome) -> Result<()> {
    if outcome.failed > 0 {
        report.warnings(&[format!(
            "{} of {} configurations failed (status column of sweep.csv); the first: {}",
            outcome.failed,
            outcome.ok + outcome.failed,
            outcome.first_error.as_deref().unwrap_or("-")
        )]);
    }
    if let Some(b) = &outcome.best {
        let mut rows: Vec<Vec<String>> = keys
            .iter()
            .zip(&b.values)
            .map(|(k, v)| vec![k.clone(), v.to_string()])
            .collect();
        rows.push(vec!["configuration index".into(), b.index.to_string()]);
        rows.push(vec![
            "max contour error, true machine (µm)".into(),
            format!("{:.3}", b.contour_max_um),
        ]);
        report.table(
            "best configuration",
            &["", "value"],
            rows,
            "the smallest largest tool-tip contour error of the true machine",
        );
    }
    figures::sweep(report, keys, outcome)?;
    report.file(
        "sweep.csv",
        "one row per configuration: index, the swept keys, tracking and contour errors, status \
         (docs/cli.md)",
    );
    Ok(())
}
