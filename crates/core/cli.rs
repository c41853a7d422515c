//! The command line (docs/cli.md: a contract that scripts and tests depend on).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};
use vcnc_pipeline::AxisName;
use vcnc_pipeline::traces::{GapPolicy, PairOptions, ReadOptions, TraceArgs};

/// vcnc — a virtual 5-axis CNC: identify the closed-loop dynamics of each feed drive from an
/// air-cutting run, then predict the contour errors a 5-axis toolpath will leave on the part.
#[derive(Debug, Parser)]
#[command(name = "vcnc", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// Downgrade unknown G-code words and codes to warnings (still printed).
    #[arg(long, global = true)]
    pub lenient: bool,
    /// Worker threads (default: all cores). Results are bit-identical for any count.
    #[arg(long, global = true, value_name = "N")]
    pub threads: Option<usize>,
    /// Print less: no tables, no progress bars.
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// LinuxCNC tool table (`.tbl`) for the programs' `G43 H` tool-length offsets (predict,
    /// simulate, interpolate, feed-plan, compensate, sweep).
    #[arg(long, global = true, value_name = "FILE")]
    pub tool_table: Option<PathBuf>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// The main job on the embedded default (NMV5000 + spiral): identify all five axes, predict
    /// the spiral's contour errors with the true and the identified drives, and compare.
    Demo {
        /// Output folder.
        #[arg(long, default_value = "vcnc-demo")]
        out: PathBuf,
        /// Run the demo on the realistic NMV5000 (machines/nmv5000-realistic.toml: compliance,
        /// friction, backlash, current loop, noise, delays, reference filter): identification
        /// accuracy, each structure's validation error, and the prediction discrepancy of the
        /// paper's method and of vcnc's chosen models.
        #[arg(long)]
        realistic: bool,
        /// With --realistic: also the effect budget, the same evaluation with one effect group
        /// at a time (eight identifications of the machine: about a minute).
        #[arg(long, requires = "realistic")]
        budget: bool,
        #[command(flatten)]
        table: TableArgs,
    },
    /// Identify each axis' closed-loop model: from a simulated machine (interpolate the
    /// identification program, run the true drive, identify, validate) or from a measured trace.
    Identify(IdentifyArgs),
    /// Score an identified model on a measured trace it was not fitted on: free-run and
    /// one-step errors, fit %, tracking error, residual plots (docs/identification.md).
    Validate(ValidateArgs),
    /// Run a program through the machine's true drives.
    Simulate {
        /// Machine file (TOML).
        machine: PathBuf,
        /// G-code program.
        program: PathBuf,
        /// Also simulate this identified model file and add `<AXIS>_model` columns.
        #[arg(long)]
        model: Option<PathBuf>,
        /// Output folder (trace.csv, summary.json, tracking.svg).
        #[arg(long, default_value = "vcnc-simulate")]
        out: PathBuf,
        /// Stream the run (bounded memory, `tracking.svg` from min/max envelopes; the same
        /// table and summary bit for bit). Programs over 8 MiB are always streamed
        /// (docs/performance.md).
        #[arg(long)]
        stream: bool,
        #[command(flatten)]
        table: TableArgs,
    },
    /// Predict tool-tip and orientation contour errors of a program with the true and the
    /// identified drives.
    Predict {
        /// Machine file (TOML).
        machine: PathBuf,
        /// G-code program.
        program: PathBuf,
        /// Identified model file (from `vcnc identify`); identified on the fly when absent.
        #[arg(long)]
        model: Option<PathBuf>,
        /// Output folder (contour.csv, summary.json, plots).
        #[arg(long, default_value = "vcnc-predict")]
        out: PathBuf,
        /// Count rapids (G0) and dwells in the contour statistics too; by default they cover
        /// the feed moves (G1 G2 G3, cycles' feed parts): what is cut.
        #[arg(long)]
        include_rapids: bool,
        /// Stream the run (bounded memory, figures from min/max envelopes; the same table and
        /// statistics bit for bit). Programs over 8 MiB are always streamed
        /// (docs/performance.md).
        #[arg(long)]
        stream: bool,
        /// Which outputs to write, comma-separated: `tables` (contour.csv/.parquet),
        /// `figures` (the SVGs), `vtp` (toolpath.vtp), `report` (manifest.json, report.html).
        /// Default: all. summary.json is always written.
        #[arg(long, value_enum, value_delimiter = ',', value_name = "LIST")]
        outputs: Option<Vec<OutputArg>>,
        #[command(flatten)]
        table: TableArgs,
    },
    /// Compensate a program with identified models: set-points that make the drives follow the
    /// programmed path, written as a fine-block program (G93 G64 blocks of whole sample
    /// periods, at the resolution and block cycle of the machine file's `[program_output]`) and
    /// judged on the true machine against the original path (docs/compensation.md).
    Compensate(CompensateArgs),
    /// Plan per-block feeds (never above the programmed ones) that keep the predicted contour
    /// error within a tolerance, and compare with the uniform feed scale that meets it
    /// (docs/compensation.md).
    FeedPlan {
        /// Machine file (TOML).
        machine: PathBuf,
        /// G-code program.
        program: PathBuf,
        /// Identified model file (from `vcnc identify`). Default on a machine made of
        /// identified models: its own.
        #[arg(long)]
        model: Option<PathBuf>,
        /// Tool-tip contour-error tolerance with its unit: `10um` (or `µm`), `0.01mm`.
        #[arg(long)]
        tolerance: String,
        /// Also keep the orientation contour error within this: `0.05mrad`, `0.003deg`.
        #[arg(long)]
        orientation_tolerance: Option<String>,
        /// Output folder (planned.ngc, uniform.ngc, blocks.csv, summary.json, plots).
        #[arg(long, default_value = "vcnc-feed-plan")]
        out: PathBuf,
    },
    /// Interpolate a program into the reference trajectory at the sample period.
    Interpolate {
        /// Machine file (TOML).
        machine: PathBuf,
        /// G-code program.
        program: PathBuf,
        /// Output folder (reference.csv, summary.json).
        #[arg(long, default_value = "vcnc-interpolate")]
        out: PathBuf,
        #[command(flatten)]
        table: TableArgs,
    },
    /// Forward or inverse kinematics of the machine on a CSV of axes or poses.
    Kinematics {
        /// Machine file (TOML) with a `[kinematics]` section.
        machine: PathBuf,
        /// `forward` (axes → poses) or `inverse` (poses → axes).
        direction: Direction,
        /// Input CSV: columns X Y Z A C (forward) or px py pz ox oy oz (inverse).
        #[arg(long)]
        input: PathBuf,
        /// Output CSV (default: standard output).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Inverse-kinematics branch (sign of A) [default: the machine file's
        /// `kinematics.branch`].
        #[arg(long, allow_hyphen_values = true)]
        branch: Option<i8>,
    },
    /// Tracking and disturbance frequency responses of each axis (CSV and SVG Bode plots).
    Frf {
        /// Machine file (TOML).
        machine: PathBuf,
        /// Also plot this identified model file beside the true drives.
        #[arg(long)]
        model: Option<PathBuf>,
        /// Output folder (`frf_<AXIS>.csv`/`.svg`, `summary.json`).
        #[arg(long, default_value = "vcnc-frf")]
        out: PathBuf,
    },
    /// Sweep machine-file keys over the cartesian product of their values.
    Sweep(SweepArgs),
    /// Join the outputs of sharded sweeps.
    SweepMerge {
        /// Shard output folders (each with its sweep.csv).
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Output folder of the joined table, summary and plots.
        #[arg(long)]
        out: PathBuf,
    },
    /// Read scope files (`vcnc trace info FILE`).
    Trace {
        #[command(subcommand)]
        what: TraceCommand,
    },
    /// Rebuild `report.html` of an output folder from its `manifest.json`, `summary.json` and
    /// figures (every computing command writes all three).
    Report {
        /// Output folder of a vcnc command.
        dir: PathBuf,
    },
    /// Generate G-code programs on standard output.
    Gen {
        #[command(subcommand)]
        what: GenCommand,
    },
}

/// How per-sample tables (`reference`, `trace`, `contour`) are written.
#[derive(Debug, Clone, Args)]
pub struct TableArgs {
    /// Table format: `csv`, `parquet`, or `auto` (CSV up to 200 000 rows, Parquet beyond).
    #[arg(long, value_enum, default_value_t = FormatArg::Auto)]
    pub format: FormatArg,
    /// Write every N-th sample only (summaries and statistics still use every sample). Default
    /// 1; for `predict`, every sample up to 50 000 and beyond that the smallest N that keeps
    /// the table, the path figures and toolpath.vtp to 50 000 samples (`--decimate 1`: all).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub decimate: Option<u64>,
    /// Columns to write, comma-separated names or `prefix*` patterns (e.g. `t,X_*,true_contour_um`).
    #[arg(long, value_name = "COLS")]
    pub columns: Option<String>,
}

/// One of `predict --outputs`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OutputArg {
    /// The per-sample table (contour.csv or contour.parquet).
    Tables,
    /// The SVG figures.
    Figures,
    /// toolpath.vtp.
    Vtp,
    /// manifest.json and report.html.
    Report,
}

/// `--format`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// CSV up to 200 000 rows, Parquet beyond.
    Auto,
    /// Comma-separated text, shortest round-trip numbers.
    Csv,
    /// Apache Parquet, one Float64 column per table column.
    Parquet,
}

impl TableArgs {
    /// The writer's options.
    pub fn options(&self) -> vcnc_output::table::TableOptions {
        use vcnc_output::table::Format;
        vcnc_output::table::TableOptions {
            format: match self.format {
                FormatArg::Auto => Format::Auto,
                FormatArg::Csv => Format::Csv,
                FormatArg::Parquet => Format::Parquet,
            },
            decimate: self
                .decimate
                .map_or(1, |n| usize::try_from(n).unwrap_or(usize::MAX)),
            columns: self
                .columns
                .as_deref()
                .map(vcnc_output::table::parse_columns),
        }
    }
}

#[derive(Debug, Args)]
pub struct CompensateArgs {
    /// Machine file (TOML).
    pub machine: PathBuf,
    /// G-code program.
    pub program: PathBuf,
    /// Identified model file (from `vcnc identify`). Default on a machine made of identified
    /// models: its own.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Most iterations of the learning loop on the models.
    #[arg(long, default_value_t = 30)]
    pub iterations: usize,
    /// Plan the program with every velocity limit times this (0 < H ≤ 1), so that the
    /// set-points can lead moves that run at a limit (rapids). Default: 1, lowered just enough
    /// (and reported) when a set-point would exceed a velocity limit.
    #[arg(long)]
    pub headroom: Option<f64>,
    /// Output folder (compensated.ngc, references.csv, contour.csv, summary.json, plots).
    #[arg(long, default_value = "vcnc-compensate")]
    pub out: PathBuf,
    #[command(flatten)]
    pub table: TableArgs,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Direction {
    Forward,
    Inverse,
}

#[derive(Debug, Args)]
pub struct IdentifyArgs {
    /// Machine file (simulated machine). Not with --trace.
    #[arg(required_unless_present = "trace", conflicts_with = "trace")]
    pub machine: Option<PathBuf>,
    /// Axes to identify (default: all).
    #[arg(long = "axis", value_name = "A")]
    pub axes: Vec<vcnc_pipeline::AxisName>,
    /// Seed of the identification program and the PSO (default: the machine file's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Measured trace: a scope file of any supported format (LinuxCNC halscope/halsampler,
    /// Heidenhain TNCscope, Siemens Sinumerik trace XML, Beckhoff TwinCAT Scope CSV, delimited
    /// text, Parquet tables such as `vcnc simulate` writes), detected from its content. Every axis with a nominal and an actual position is
    /// identified (or the ones named with --axis).
    #[arg(long)]
    pub trace: Option<PathBuf>,
    #[command(flatten)]
    pub read: TraceReadArgs,
    #[command(flatten)]
    pub columns: TraceColumnArgs,
    /// Identifier options for the trace: a TOML file with the keys of a machine file's
    /// `[identification.options]` table (deadband, bounds, prefilter, pso, refine, seed, ...).
    #[arg(long, value_name = "OPTIONS.toml", requires = "trace")]
    pub options: Option<PathBuf>,
    /// The control's actual-value latency, s: the time by which the logged actual position
    /// trails the physical axis (fieldbus and encoder-interface delays; stated from the
    /// control's configuration, not identifiable). Written to model.toml as `actual_latency_s`
    /// of every axis identified. Default: a machine file's position-loop dead time
    /// (`dead_time_cycles` / `servo_rate_hz`); 0 for a trace.
    #[arg(long, value_name = "S")]
    pub actual_latency_s: Option<f64>,
    /// Output folder (summary.json, model.toml, plots).
    #[arg(long, default_value = "vcnc-identify")]
    pub out: PathBuf,
}

/// `vcnc validate --model MODEL.toml --trace TRACE [--axis A] --out DIR`.
#[derive(Debug, Args)]
pub struct ValidateArgs {
    /// Identified model file (from `vcnc identify`).
    #[arg(long)]
    pub model: PathBuf,
    /// Measured trace, any supported format (as `identify --trace`).
    #[arg(long)]
    pub trace: PathBuf,
    /// Axes to score (default: every axis of the trace that has a model).
    #[arg(long = "axis", value_name = "A")]
    pub axes: Vec<AxisName>,
    #[command(flatten)]
    pub read: TraceReadArgs,
    #[command(flatten)]
    pub columns: TraceColumnArgs,
    /// Output folder (summary.json, residual plots, report.html).
    #[arg(long, default_value = "vcnc-validate")]
    pub out: PathBuf,
}

/// How a trace file is read (shared by `identify --trace` and `trace info`).
#[derive(Debug, Clone, Args)]
pub struct TraceReadArgs {
    /// Sample period in seconds, for files that carry none (halsampler output, delimited text
    /// without a time column). A file's own time column or period is always checked and wins;
    /// a different --ts is an error.
    #[arg(long)]
    pub ts: Option<f64>,
    /// Unit of positions where the file states none, or states one vcnc does not know: nm, um,
    /// mm, cm, m, inch (linear axes), deg, mdeg, rad (rotary axes). A file that states a known
    /// unit keeps it [default: mm, deg].
    #[arg(long, value_name = "UNIT")]
    pub units: Option<String>,
    /// Read as this format instead of detecting it: parquet, sinumerik, tncscope, halscope,
    /// halscope-pairs, twincat, halsampler, delimited.
    #[arg(long, value_name = "FORMAT")]
    pub trace_format: Option<String>,
    /// LinuxCNC joint-to-axis map, e.g. XYZAC for a table-tilting machine [default: XYZABC].
    #[arg(long, value_name = "AXES")]
    pub joints: Option<String>,
    /// The file's axis numbers as axes, e.g. 1=X,2=Y,3=Z: a Sinumerik trace names its channels
    /// by axis number (`[u1, 1]`), not by letter.
    #[arg(long, value_name = "N=A,...")]
    pub axis_map: Option<String>,
}

/// Which columns and stretch of a trace to pair (`identify --trace`, `validate`). No clap
/// defaults, so that `identify` can refuse them next to a machine file instead of ignoring them.
#[derive(Debug, Clone, Args)]
pub struct TraceColumnArgs {
    /// The time column (delimited text, halsampler): a name or a 0-based column number
    /// [default: t, time, zeit or timestamp].
    #[arg(long)]
    pub t_col: Option<String>,
    /// The nominal position channel of the (first) --axis, X by default, in any format: a name
    /// as `trace info` lists it (exactly, else ignoring case, else by description) or a 0-based
    /// column number.
    #[arg(long)]
    pub xr_col: Option<String>,
    /// The actual position channel of the same axis (as --xr-col).
    #[arg(long)]
    pub x_col: Option<String>,
    /// Lost samples in the trace (halsampler overruns, jumps in time): refuse to use a trace
    /// across them, or use the longest stretch without any.
    #[arg(long, value_enum)]
    pub gaps: Option<GapsArg>,
}

impl TraceColumnArgs {
    /// Whether any is given.
    pub fn any(&self) -> bool {
        self.t_col.is_some() || self.xr_col.is_some() || self.x_col.is_some() || self.gaps.is_some()
    }

    /// The checked read and pairing options of `read`, these columns and `axes`.
    pub fn pairing(
        &self,
        read: &TraceReadArgs,
        axes: &[AxisName],
    ) -> Result<(ReadOptions, PairOptions), vcnc_pipeline::Error> {
        let args = read.trace_args(Some(self), axes);
        Ok((args.read_options()?, args.pair_options()?))
    }
}

/// `--gaps`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GapsArg {
    /// Refuse to identify across lost samples.
    Refuse,
    /// Identify on the longest stretch without lost samples.
    Longest,
}

impl GapsArg {
    fn policy(self) -> GapPolicy {
        match self {
            GapsArg::Refuse => GapPolicy::Refuse,
            GapsArg::Longest => GapPolicy::LongestSegment,
        }
    }
}

#[derive(Debug, Subcommand)]
pub enum TraceCommand {
    /// The format found and every channel: axis, quantity, unit, period, samples, gaps.
    Info {
        /// The trace file.
        file: PathBuf,
        #[command(flatten)]
        read: TraceReadArgs,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Debug, Args)]
pub struct SweepArgs {
    /// Machine file (TOML) whose keys are swept.
    pub machine: PathBuf,
    /// G-code program run on every configuration.
    pub program: PathBuf,
    /// `KEY=V1,V2,...` or `KEY=start:stop:count`; KEY is a dotted machine-file path such as
    /// `axes.X.controller.kv`. Repeat for a cartesian product.
    #[arg(long = "set", value_name = "KEY=VALUES", required = true)]
    pub sets: Vec<String>,
    /// Identified model file: add the identified-model prediction beside each configuration.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Run shard i of n (1-based), a deterministic 1/n of the product.
    #[arg(long, value_name = "i/n")]
    pub shard: Option<String>,
    /// Output folder (sweep.csv streamed row by row, summary.json, plots).
    #[arg(long, default_value = "vcnc-sweep")]
    pub out: PathBuf,
    /// Run even when some configurations cannot be built (an unreachable controller design, a
    /// value out of range): they become failed rows. Without it such a sweep is refused before
    /// anything runs.
    #[arg(long)]
    pub keep_going: bool,
}

#[derive(Debug, Subcommand)]
pub enum GenCommand {
    /// The paper's identification excitation for one axis.
    Identification {
        /// Axis letter (X Y Z A B C).
        #[arg(long, default_value = "X")]
        axis: vcnc_pipeline::AxisName,
        /// Number of random moves.
        #[arg(long, default_value_t = 70)]
        moves: usize,
        /// Moves stay within ±RANGE (mm or deg).
        #[arg(long, default_value_t = 50.0)]
        range: f64,
        /// Highest feed in units per SECOND (mm/s or deg/s; the program's F words are written
        /// per minute, F = 60 × this).
        #[arg(long, default_value_t = 250.0)]
        max_feed: f64,
        /// Seed of the random moves (same seed, same program).
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// The 5-axis spiral of docs/contour.md in tool-centre-point mode.
    Spiral {
        /// Feed along the tool-tip path in mm per SECOND (the program's F word is per minute,
        /// F = 60 × this).
        #[arg(long, default_value_t = 75.0)]
        feed: f64,
        /// Segment length along the tip path, mm.
        #[arg(long, default_value_t = 0.5)]
        segment: f64,
        /// Write the spiral for this machine's kinematics (its rotary axes and branch, or a
        /// 3-axis contour) instead of the NMV5000's A/C program.
        #[arg(long)]
        machine: Option<std::path::PathBuf>,
    },
    /// A long 5-axis program for speed and memory measurements (docs/performance.md): TCP
    /// switched on by M428, inverse-time feeds (G93), short segments round a wavy band.
    Long {
        /// Number of G1 segments (20 000 at the defaults give about 1 M samples at 1 ms).
        #[arg(long, default_value_t = 20_000)]
        segments: usize,
        /// Tip travel per segment, mm.
        #[arg(long, default_value_t = 0.5)]
        segment: f64,
        /// Duration of each segment, s (its inverse-time F word).
        #[arg(long, default_value_t = 0.05)]
        segment_s: f64,
    },
}

impl TraceReadArgs {
    /// The options as typed, with the columns and axes of a command that pairs positions
    /// (checked by [`TraceArgs::read_options`] and [`TraceArgs::pair_options`]).
    pub fn trace_args(&self, columns: Option<&TraceColumnArgs>, axes: &[AxisName]) -> TraceArgs {
        TraceArgs {
            ts: self.ts,
            units: self.units.clone(),
            trace_format: self.trace_format.clone(),
            joints: self.joints.clone(),
            axis_map: self.axis_map.clone(),
            axes: axes.to_vec(),
            t_col: columns.and_then(|c| c.t_col.clone()),
            xr_col: columns.and_then(|c| c.xr_col.clone()),
            x_col: columns.and_then(|c| c.x_col.clone()),
            gaps: columns.and_then(|c| c.gaps).map(GapsArg::policy),
        }
    }
}
