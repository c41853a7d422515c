//! `vcnc identify`: from a simulated machine (each axis: excitation program → true drive →
//! identification → validation) or from a measured trace.

use std::path::Path;

use anyhow::Result;
use vcnc_pipeline::identify::{self, IdentifySummary};
use vcnc_pipeline::traces;
use vcnc_pipeline::{MAX_ACTUAL_LATENCY_S, Machine, OptionsFile};

use crate::cli::IdentifyArgs;
use crate::print_warnings;
use crate::{Ctx, bad_input};
use vcnc_output::files::ensure_dir;
use vcnc_output::identification::{
    MACHINE_MODELS, fmt_poles, identification_table, identify_machine_report,
    identify_trace_report, model_table, structure_table, write_identification,
};
use vcnc_output::text::table;

pub fn identify(args: &IdentifyArgs, ctx: &Ctx) -> Result<()> {
    match (&args.machine, &args.trace) {
        // clap's `requires = "trace"` on these does not fire next to the positional MACHINE
        // (which conflicts with --trace), so say it here rather than ignore them silently.
        (Some(_), None)
            if args.read.ts.is_some()
                || args.options.is_some()
                || args.read.units.is_some()
                || args.read.trace_format.is_some()
                || args.read.joints.is_some()
                || args.columns.any() =>
        {
            Err(bad_input(
                "--ts, --units, --trace-format, --joints, --gaps, --t-col, --xr-col, --x-col and \
                 --options apply to --trace only; a machine file sets its identifier options in \
                 [identification.options]",
            ))
        }
        _ if args
            .actual_latency_s
            .is_some_and(|t| !(0.0..=MAX_ACTUAL_LATENCY_S).contains(&t)) =>
        {
            Err(bad_input(format!(
                "--actual-latency-s {}: must be finite, ≥ 0 and ≤ {MAX_ACTUAL_LATENCY_S} s",
                args.actual_latency_s.unwrap_or_default(),
            )))
        }
        (Some(m), None) => identify_machine(m, args, ctx),
        (None, Some(t)) => identify_trace(t, args, ctx),
        _ => Err(bad_input("give either MACHINE.toml or --trace TRACE.csv")),
    }
}

/// The actual-value latency given with `--actual-latency-s`, stated for every axis identified.
fn state_latency(ids: &mut [identify::AxisIdentification], args: &IdentifyArgs) {
    if let Some(t) = args.actual_latency_s {
        for r in ids {
            r.result.model.actual_latency_s = t;
        }
    }
}

fn identify_machine(path: &Path, args: &IdentifyArgs, ctx: &Ctx) -> Result<()> {
    let machine = Machine::load(path)?;
    let axes = identify::select_axes(&machine, &args.axes)?;
    let mut results = identify::identify_axes(&machine, &axes, args.seed)?;
    state_latency(&mut results, args);
    for r in &results {
        print_warnings(&identify::axis_warnings(r));
    }
    ensure_dir(&args.out)?;
    let mut report = identify_machine_report(&args.out, &machine.name, path, &results, args.seed);
    write_identification(
        &mut report,
        &IdentifySummary::machine(&machine.name, &results),
        &machine.name,
        MACHINE_MODELS,
        &results,
    )?;
    if !ctx.quiet {
        print!("{}", identification_table(&results));
        print!("{}", structure_table(&results));
        print!("{}", model_table(&results));
        println!("-> {}", args.out.display());
    }
    Ok(())
}

fn identify_trace(path: &Path, args: &IdentifyArgs, ctx: &Ctx) -> Result<()> {
    let file = path.display().to_string();
    // The options first: a mistake in them is reported before the trace is read.
    let options = match &args.options {
        Some(p) => OptionsFile::load(p)?,
        None => OptionsFile::default(),
    };
    let (read, pair) = args.columns.pairing(&args.read, &args.axes)?;
    let measured = traces::read_trace(path, &read, &pair)?;
    for s in &measured.paired.skipped {
        eprintln!(
            "{file}: warning: axis {} not identified: {}",
            s.axis, s.reason
        );
    }
    let mut ids = traces::identify_measured(&measured, &options, args.seed)?;
    state_latency(&mut ids, args);
    for r in &ids {
        print_warnings(&identify::axis_warnings(r));
    }
    ensure_dir(&args.out)?;
    let mut report = identify_trace_report(
        &args.out,
        &file,
        measured.paired.format,
        &ids,
        args.options.as_deref(),
    );
    write_identification(
        &mut report,
        &IdentifySummary::trace(&file, measured.paired.format, &ids),
        &format!("trace {file}"),
        "identified by vcnc from a measured trace",
        &ids,
    )?;
    if !ctx.quiet {
        println!("{file}: {}", measured.paired.format);
        for id in &ids {
            let (k, l) = (id.unit.micro_factor(), id.unit.micro_label());
            let r = &id.result;
            // "identified" is the model written to model.toml, with its fit on the whole trace;
            // the paper structure's refined fit beside it when another structure was chosen.
            let chosen = format!("identified ({})", r.structure);
            let mut models = vec![(chosen.as_str(), &r.model.core, Some(&id.validation))];
            if r.model != r.identified_model {
                models.push(("paper, refined", &r.identified, Some(&r.fit_estimation)));
            }
            models.push(("paper PSO", &r.paper_pso, Some(&r.fit_estimation_paper)));
            models.push(("unconstrained LS", &r.unconstrained_ls.model, None));
            let rows: Vec<Vec<String>> = models
                .iter()
                .map(|(n, m, f)| {
                    vec![
                        n.to_string(),
                        fmt_poles(m),
                        format!("{:.1}", m.dc),
                        if m.is_stable() {
                            "yes".into()
                        } else if m.is_marginally_stable() {
                            "marginal".into()
                        } else {
                            "NO".into()
                        },
                        f.map_or("-".into(), |f| format!("{:.2} {l}", f.freerun_rms * k)),
                    ]
                })
                .collect();
            let t = &id.validation_trace;
            println!(
                "axis {}: {} samples at {} s, tracking error {:.1} {l} RMS",
                id.axis,
                t.len(),
                t.ts,
                t.tracking_rms() * k
            );
            print!(
                "{}",
                table(
                    &["model", "wn/zeta/p [Hz]", "dc", "stable", "free-run RMS"],
                    &rows
                )
            );
        }
        print!("{}", structure_table(&ids));
        print!("{}", model_table(&ids));
        for id in &ids {
            if let Some(section) = identify::control_section(id) {
                println!(
                    "axis {}: its dead time and reference filter can be the control's filters instead (docs/machine-file.md#control); with this section in the machine file and the model changed as the comment says, it predicts the same:\n{}",
                    id.axis,
                    section.trim_end()
                );
            }
        }
        println!("-> {}", args.out.display());
    }
    Ok(())
}
