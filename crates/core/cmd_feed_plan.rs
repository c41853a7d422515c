//! `vcnc feed-plan`: per-block feeds that keep the predicted contour error within a tolerance,
//! against the uniform feed scale that meets it, judged on the true machine
//! (docs/compensation.md#feed-planning).

use std::path::Path;

use anyhow::Result;
use vcnc_output::feed_plan::{tables, write_blocks, write_figure};
use vcnc_output::files::{ensure_dir, write_atomic, write_json};
use vcnc_output::report::RunReport;
use vcnc_pipeline::feed_plan::{self, FeedPlanOptions};
use vcnc_pipeline::identify;

use crate::{Ctx, bad_input, print_warnings};

/// A tolerance with its unit (`10um`, `10µm`, `0.01mm`) in mm.
fn parse_length(s: &str) -> Result<f64> {
    let t = s.trim();
    let (num, scale) = if let Some(n) = t.strip_suffix("um").or_else(|| t.strip_suffix("µm")) {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix("mm") {
        (n, 1.0)
    } else {
        return Err(bad_input(format!(
            "--tolerance {s}: give the unit, e.g. 10um or 0.01mm"
        )));
    };
    match num.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v * scale),
        _ => Err(bad_input(format!(
            "--tolerance {s}: expected a positive number before the unit"
        ))),
    }
}

/// An angle tolerance with its unit (`0.05mrad`, `0.003deg`, `5e-5rad`) in rad.
fn parse_angle(s: &str) -> Result<f64> {
    let t = s.trim();
    let (num, scale) = if let Some(n) = t.strip_suffix("mrad") {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix("rad") {
        (n, 1.0)
    } else if let Some(n) = t.strip_suffix("deg") {
        (n, std::f64::consts::PI / 180.0)
    } else {
        return Err(bad_input(format!(
            "--orientation-tolerance {s}: give the unit, e.g. 0.05mrad or 0.003deg"
        )));
    };
    match num.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v * scale),
        _ => Err(bad_input(format!(
            "--orientation-tolerance {s}: expected a positive number before the unit"
        ))),
    }
}

/// `vcnc feed-plan MACHINE PROGRAM --model MODEL --tolerance 10um [--orientation-tolerance …]`.
pub fn feed_plan(
    machine_path: &Path,
    program: &Path,
    model: Option<&Path>,
    tolerance: &str,
    orientation: Option<&str>,
    out: &Path,
    ctx: &Ctx,
) -> Result<()> {
    let tolerance_mm = parse_length(tolerance)?;
    let orientation_tolerance_rad = orientation.map(parse_angle).transpose()?;
    let machine = ctx.machine(machine_path)?;
    let models = identify::given_models(&machine, model, "feed-plan")?;
    let opts = FeedPlanOptions {
        orientation_tolerance_rad,
        ..FeedPlanOptions::new(tolerance_mm)
    };
    let planned_path = out.join("planned.ngc");
    let j = feed_plan::plan_and_judge(
        &machine,
        program,
        &models,
        &opts,
        &planned_path.display().to_string(),
        ctx.lenient,
    )?;
    let plan = &j.plan;
    print_warnings(&plan.original.warnings);
    ensure_dir(out)?;
    write_atomic(&planned_path, plan.plan.text.as_bytes())?;
    write_atomic(&out.join("uniform.ngc"), plan.uniform.text.as_bytes())?;
    write_blocks(out, plan)?;
    let file = &j.summary.program;
    let mut report = RunReport::new(
        out,
        format!(
            "vcnc feed-plan: {}",
            vcnc_output::figures::program_name(file)
        ),
    );
    report.input("machine", machine.name.as_str());
    report.input("program", file.as_str());
    report.input("models", models.source());
    report.input("tolerance", format!("{} µm", tolerance_mm * 1e3));
    report.file("planned.ngc", "the program with the planned per-line feeds");
    report.file(
        "uniform.ngc",
        "the program with the uniform feed scale that meets the tolerance",
    );
    write_figure(&mut report, &j, tolerance_mm * 1e3)?;
    write_json(&out.join("summary.json"), &j.summary)?;
    report.finish()?;
    if !ctx.quiet {
        print!("{}", tables(&j.summary));
        println!("-> {}", out.display());
    }
    Ok(())
}
