//! `vcnc identify`: from a simulated machine (each axis: excitation program → true drive →
//! identification → validation) or from a measured trace.

use std::path::Path;

use anyhow::Result;
use vcnc_identify::Trace;
use vcnc_machine::{Machine, OptionsFile, Unit};
use vcnc_pipeline::identify::{self, IdentifySummary};
use vcnc_pipeline::table::read_columns;

use crate::cli::{IdentifyArgs, TraceUnits};
use crate::output::ensure_dir;
use crate::table::table;
use crate::writers::{
    MACHINE_MODELS, fmt_poles, identification_table, identify_machine_report,
    identify_trace_report, write_identification,
};
use crate::{Ctx, bad_input};

pub fn identify(args: &IdentifyArgs, ctx: &Ctx) -> Result<()> {
    match (&args.machine, &args.trace) {
        // clap's `requires = "trace"` on these does not fire next to the positional MACHINE
        // (which conflicts with --trace), so say it here rather than ignore them silently.
        (Some(_), None)
            if args.ts.is_some()
                || args.options.is_some()
                || args.units.is_some()
                || args.t_col.is_some()
                || args.xr_col.is_some()
                || args.x_col.is_some() =>
        {
            Err(bad_input(
                "--ts, --units, --t-col, --xr-col, --x-col and --options apply to --trace only; \
                 a machine file sets its identifier options in [identification.options]",
            ))
        }
        (Some(m), None) => identify_machine(m, args, ctx),
        (None, Some(t)) => identify_trace(t, args, ctx),
        _ => Err(bad_input("give either MACHINE.toml or --trace TRACE.csv")),
    }
}

fn identify_machine(path: &Path, args: &IdentifyArgs, ctx: &Ctx) -> Result<()> {
    let machine = Machine::load(path)?;
    let axes = identify::select_axes(&machine, &args.axes)?;
    let results = identify::identify_axes(&machine, &axes, args.seed)?;
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
    let cols = [
        args.t_col.as_deref().unwrap_or("t"),
        args.xr_col.as_deref().unwrap_or("xr"),
        args.x_col.as_deref().unwrap_or("x"),
    ];
    let c = read_columns(
        path,
        &cols,
        "; choose columns with --t-col, --xr-col, --x-col",
    )?;
    let (unit, scale) = match args.units.unwrap_or(TraceUnits::Mm) {
        TraceUnits::M => (Unit::Mm, 1000.0),
        TraceUnits::Mm => (Unit::Mm, 1.0),
        TraceUnits::Deg => (Unit::Deg, 1.0),
    };
    let xr: Vec<f64> = c[1].iter().map(|v| v * scale).collect();
    let x: Vec<f64> = c[2].iter().map(|v| v * scale).collect();
    let trace = match args.ts {
        Some(ts) => Trace::new(ts, xr, x),
        None => Trace::from_columns(&c[0], &xr, &x),
    }
    .map_err(|e| bad_input(format!("{file}: {e}")))?;
    let axis = args.axes.first().copied().unwrap_or(vcnc_axis::AxisName::X);
    let id = identify::identify_trace(trace, &file, axis, unit, &options, args.seed)?;
    ensure_dir(&args.out)?;
    let mut report = identify_trace_report(&args.out, &file, &id, &cols, args.options.as_deref());
    write_identification(
        &mut report,
        &IdentifySummary::trace(&file, &id),
        &format!("trace {file}"),
        "identified by vcnc from a measured trace",
        std::slice::from_ref(&id),
    )?;
    if !ctx.quiet {
        let (k, l) = (unit.micro_factor(), unit.micro_label());
        let r = &id.result;
        let rows: Vec<Vec<String>> = [
            ("identified", &r.identified, Some(&r.fit_estimation)),
            ("paper PSO", &r.paper_pso, Some(&r.fit_estimation_paper)),
            ("unconstrained LS", &r.unconstrained_ls.model, None),
        ]
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
            "{file}: {} samples at {} s, tracking error {:.1} {l} RMS",
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
        println!("-> {}", args.out.display());
    }
    Ok(())
}
