//! `vcnc compensate`: compensated set-points from identified models, written as a fine-block
//! program, and judged on the true machine against the original program's path
//! (docs/compensation.md).

use anyhow::Result;
use vcnc_output::compensation::{tables, write_figure, write_tables};
use vcnc_output::files::{ensure_dir, write_atomic, write_json};
use vcnc_output::report::RunReport;
use vcnc_pipeline::compensate::{self, CompensateOptions};
use vcnc_pipeline::identify;

use crate::cli::CompensateArgs;
use crate::{Ctx, print_warnings};

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
    let machine = ctx.machine(machine_path)?;
    let models = identify::given_models(&machine, model.as_deref(), "compensate")?;
    let opts = CompensateOptions {
        max_iterations: *iterations,
        ..CompensateOptions::default()
    };
    let program_path = out.join("compensated.ngc");
    let program_name = program_path.display().to_string();
    let c = compensate::compensate_program(
        &machine,
        program,
        &program_name,
        &models,
        &opts,
        *headroom,
        ctx.lenient,
    )?;
    print_warnings(&c.original.warnings);
    if !ctx.quiet {
        for h in &c.planned.replanned {
            eprintln!(
                "note: a set-point leads a move at a velocity limit; planned again with a velocity headroom of {h:.3} (give --headroom to fix it)"
            );
        }
    }
    ensure_dir(out)?;
    write_atomic(&program_path, c.text.as_bytes())?;
    let comp = &c.planned.compensation;
    write_tables(out, &machine, &c.original, comp, &c.after, &table.options())?;
    let mut report = RunReport::new(
        out,
        format!(
            "vcnc compensate: {}",
            vcnc_output::figures::program_name(&c.original.file)
        ),
    );
    report.input("machine", machine.name.as_str());
    report.input("program", c.original.file.as_str());
    report.input("models", models.source());
    report.input("velocity headroom", c.planned.headroom.to_string());
    if let (Some(b), Some(a)) = (&c.before.contour, &c.after.contour) {
        write_figure(&mut report, &machine, &c.original, b, a)?;
    }
    report.file(
        "compensated.ngc",
        "the compensated program: G93 G1 blocks of whole sample periods, written as the machine file's [program_output] states (docs/compensation.md)",
    );
    write_json(&out.join("summary.json"), &c.summary)?;
    report.finish()?;
    if !ctx.quiet {
        print!("{}", tables(&c.summary, comp));
        println!("-> {}", out.display());
    }
    Ok(())
}
