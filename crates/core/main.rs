//! `vcnc`: the command-line front end (docs/cli.md). Library crates do the work: the runs are
//! `vcnc-pipeline`'s, the files they leave `vcnc-output`'s. This binary parses arguments,
//! chooses each run's sinks (tables, figures, report, summary), prints tables and progress.
//! Command files (`cmd_*`) do not import each other.
//!
//! Exit codes: 0 ok, 1 runtime failure, 2 bad input (every message names the file, and the line
//! and column where there is one).

mod cli;
mod cmd_compensate;
mod cmd_demo;
mod cmd_feed_plan;
mod cmd_frf;
mod cmd_gen;
mod cmd_identify;
mod cmd_kinematics;
mod cmd_predict;
mod cmd_report;
mod cmd_simulate;
mod cmd_sweep;
mod cmd_trace;
mod cmd_validate;

use std::process::ExitCode;

use clap::Parser;

use crate::cli::{Cli, Command};

/// An error caused by the user's input (a file, an option, data): exit code 2.
#[derive(Debug)]
pub struct BadInput(pub String);

impl std::fmt::Display for BadInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BadInput {}

/// Shorthand: a bad-input error with this message.
pub fn bad_input(msg: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(BadInput(msg.into()))
}

/// Prints warnings to stderr.
pub fn print_warnings(warnings: &[String]) {
    for w in warnings {
        eprintln!("{w}");
    }
}

/// Programs larger than this (bytes of G-code) get bounded-memory outputs (docs/performance.md):
/// 8 MiB is about 200 000 blocks, a few million samples of short five-axis segments.
pub const STREAM_ABOVE_BYTES: u64 = 8 << 20;

/// Whether a run of `program` keeps its figures in bounded memory (min/max envelopes) rather
/// than every sample: on request (`--stream`) or for a program over [`STREAM_ABOVE_BYTES`].
/// The run itself is the same either way, and so are its tables and statistics.
pub fn bounded_outputs(program: &std::path::Path, stream: bool) -> bool {
    stream || std::fs::metadata(program).is_ok_and(|m| m.len() > STREAM_ABOVE_BYTES)
}

/// Global settings every command sees.
pub struct Ctx {
    pub lenient: bool,
    pub quiet: bool,
    /// `--tool-table`: the LinuxCNC tool table the programs' `G43 H` read.
    pub tool_table: Option<std::path::PathBuf>,
}

impl Ctx {
    /// The machine file at `path`, with the tools of `--tool-table` when given. On a machine
    /// (partly) made of identified models, a note says what plays the true machine.
    pub fn machine(&self, path: &std::path::Path) -> anyhow::Result<vcnc_pipeline::Machine> {
        let mut machine = vcnc_pipeline::Machine::load(path)?;
        if !self.quiet && !machine.has_true_machine() {
            eprintln!(
                "note: {} (the results are what these models predict)",
                machine.truth_description()
            );
        }
        if let Some(t) = &self.tool_table {
            machine.tools = vcnc_pipeline::run::load_tool_table(t)?;
        }
        Ok(machine)
    }
}

/// Allocations of at least this many bytes are mapped from the system and returned to it when
/// freed: a long run's per-sample vectors (megabytes each) then never stay behind in the heap.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MMAP_THRESHOLD_BYTES: libc::c_int = 1 << 20;

/// Fixes glibc's large-allocation threshold at [`MMAP_THRESHOLD_BYTES`]. By default glibc
/// raises the threshold to the size of each mapped block freed (up to 32 MiB), after which a
/// long run's freed vectors of a few megabytes are kept in the heap, fragmented: measured on a
/// 1 M-sample prediction, 337 MB peak resident against 285 MB allocated; with the threshold
/// fixed, 301 MB (docs/performance.md).
fn fix_mmap_threshold() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets an allocator parameter; it is called before any thread starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES);
    }
}

/// The planner's cycle time as the commands print it: `cycle time 10.586 s (feed 10.125 s,
/// rapid 0.461 s, dwell 0.000 s)`.
pub fn cycle_time_line(c: &vcnc_pipeline::CycleTime) -> String {
    format!(
        "cycle time {:.3} s (feed {:.3} s, rapid {:.3} s, dwell {:.3} s)",
        c.total_s, c.feed_s, c.rapid_s, c.dwell_s
    )
}

/// Hands the heap's free memory back to the system: called between a run's stages when the
/// first (an identification on the worker threads) has freed what the next (a long
/// prediction) will not reuse. glibc keeps memory freed by a worker thread in that thread's
/// arena, where the main thread's allocations cannot reuse it: measured on the impeller's
/// prediction with models identified on the fly, 99 MB peak resident without this call and
/// 75–77 MB with it, against 67 MB with the models given (docs/performance.md).
pub fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free heap pages to the system; it is thread-safe.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// A closed standard output (`vcnc predict … | head`) ends the process quietly, as it ends
/// other command-line tools, instead of a panic in `println!`: Rust ignores SIGPIPE by
/// default, so the write fails and `println!` panics.
fn default_sigpipe() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: restores the signal's default action; called before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    fix_mmap_threshold();
    default_sigpipe();
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            // clap prints help/version to stdout (exit 0) and usage errors to stderr (exit 2).
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    if let Some(n) = cli.threads {
        if n == 0 {
            eprintln!("vcnc: --threads must be at least 1");
            return ExitCode::from(2);
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            eprintln!("vcnc: cannot start {n} threads: {e}");
            return ExitCode::from(1);
        }
    }
    let ctx = Ctx {
        lenient: cli.lenient,
        quiet: cli.quiet,
        tool_table: cli.tool_table,
    };
    let reads_tools = matches!(
        cli.command,
        Command::Predict { .. }
            | Command::Simulate { .. }
            | Command::Interpolate { .. }
            | Command::FeedPlan { .. }
            | Command::Compensate(_)
            | Command::Sweep(_)
    );
    if ctx.tool_table.is_some() && !reads_tools {
        eprintln!(
            "vcnc: --tool-table is for the commands that read a program on a machine: predict, \
             simulate, interpolate, feed-plan, compensate, sweep"
        );
        return ExitCode::from(2);
    }
    match run(cli.command, &ctx) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let code = exit_code(&e);
            eprintln!("vcnc: {}", render(&e));
            ExitCode::from(code)
        }
    }
}

fn run(command: Command, ctx: &Ctx) -> anyhow::Result<()> {
    match command {
        Command::Demo {
            out,
            realistic,
            budget,
            table,
        } => cmd_demo::demo(&out, realistic, budget, &table.options(), ctx),
        Command::Identify(args) => cmd_identify::identify(&args, ctx),
        Command::Validate(args) => cmd_validate::validate(&args, ctx),
        Command::Simulate {
            machine,
            program,
            model,
            out,
            stream,
            table,
        } => cmd_simulate::simulate(
            &machine,
            &program,
            model.as_deref(),
            &out,
            &table.options(),
            stream,
            ctx,
        ),
        Command::Predict {
            machine,
            program,
            model,
            out,
            include_rapids,
            stream,
            outputs,
            table,
        } => cmd_predict::predict(
            &cmd_predict::PredictInputs {
                machine: &machine,
                program: &program,
                model: model.as_deref(),
                out: &out,
            },
            if include_rapids {
                vcnc_pipeline::Measured::All
            } else {
                vcnc_pipeline::Measured::Feed
            },
            &table,
            &cmd_predict::Outputs::from_args(&outputs),
            stream,
            ctx,
        ),
        Command::Compensate(args) => cmd_compensate::compensate(&args, ctx),
        Command::FeedPlan {
            machine,
            program,
            model,
            tolerance,
            orientation_tolerance,
            out,
        } => cmd_feed_plan::feed_plan(
            &machine,
            &program,
            model.as_deref(),
            &tolerance,
            orientation_tolerance.as_deref(),
            &out,
            ctx,
        ),
        Command::Interpolate {
            machine,
            program,
            out,
            table,
        } => cmd_simulate::interpolate(&machine, &program, &out, &table.options(), ctx),
        Command::Kinematics {
            machine,
            direction,
            input,
            out,
            branch,
        } => cmd_kinematics::kinematics(&machine, direction, &input, out.as_deref(), branch),
        Command::Frf {
            machine,
            model,
            out,
        } => cmd_frf::frf(&machine, model.as_deref(), &out, ctx),
        Command::Sweep(args) => cmd_sweep::sweep(&args, ctx),
        Command::SweepMerge { dirs, out } => cmd_sweep::merge(&dirs, &out, ctx),
        Command::Trace { what } => cmd_trace::trace(&what, ctx),
        Command::Report { dir } => cmd_report::report(&dir, ctx),
        Command::Gen { what } => cmd_gen::generate(&what),
    }
}

/// The exit code of an error, decided by its kind: 2 when the user's input is at fault, else 1.
fn exit_code(e: &anyhow::Error) -> u8 {
    for cause in e.chain() {
        let bad = if cause.downcast_ref::<BadInput>().is_some()
            || cause.downcast_ref::<clap::Error>().is_some()
        {
            Some(true)
        } else if let Some(p) = cause.downcast_ref::<vcnc_pipeline::Error>() {
            Some(p.is_bad_input())
        } else if let Some(o) = cause.downcast_ref::<vcnc_output::Error>() {
            Some(o.is_bad_input())
        } else {
            cause
                .downcast_ref::<vcnc_pipeline::MachineError>()
                .map(vcnc_pipeline::MachineError::is_bad_input)
        };
        if let Some(bad) = bad {
            return if bad { 2 } else { 1 };
        }
    }
    1
}

/// The error and its causes, one per line after the first.
fn render(e: &anyhow::Error) -> String {
    let mut s = e.to_string();
    for cause in e.chain().skip(1) {
        s.push_str("\n  caused by: ");
        s.push_str(&cause.to_string());
    }
    s
}
