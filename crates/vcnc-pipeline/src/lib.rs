//! The runs of vcnc: every computation a command makes, with typed results.
//!
//! Every run that drives axes takes one route (ripgrep's searcher and sink): its reference
//! comes from a [`Source`] — the program streamed from its text ([`source::plan`]) or prepared
//! whole ([`run::prepare`]) — a piece at a time, goes through the run's stages (true drives,
//! models, kinematics, contour searches), and each finished piece goes to a [`Sink`]. The run
//! computes its statistics itself; what is kept of the pieces (a table, a figure's envelope,
//! every sample, nothing) is the sink's choice, so outputs do not depend on it.
//!
//! ```text
//!   machine file ──vcnc-machine──▶ Machine, MachineModels      program text
//!                                     │                             │
//!                                     └──── source::plan / run::prepare
//!                                                   │
//!                                                Source ──▶ ReferenceChunk (pieces)
//!                      ┌────────────────────────────┼──────────────────────────┐
//!                      ▼                            ▼                          ▼
//!        interpolate::interpolate        simulate::simulate          predict::predict
//!        (the reference)                 (true drives, models)       (true drives + model
//!                                                                     sets → poses → contour
//!                                                                     errors)
//!                      └──────────────▶ Sink (tables, envelopes, records) ◀────┘
//!
//!   identify::identify_axis (simulated machine: excitation runs → identify → validate)
//!   identify::identify_trace (measured trace → identify)
//!        └──▶ AxisIdentification ──▶ model.toml (MachineModels), IdentifySummary
//! ```
//!
//! | module | does | main types |
//! |---|---|---|
//! | [`source`] | where a run's reference comes from, in pieces | [`Source`], [`ReferenceChunk`], [`ReferenceStream`] |
//! | [`sink`] | where a run's pieces go | [`Sink`], [`sink::Discard`] |
//! | [`run`] | a program prepared whole: axis references | [`Run`], [`AxisSignals`] |
//! | [`interpolate`] | the reference itself | [`interpolate::InterpolateSummary`] |
//! | [`simulate`] | true drives and models; tracking figures | [`SimulatePiece`], [`SimulationRecord`], [`AxisTracking`] |
//! | [`predict`] | contour and orientation errors, true machine vs model sets | [`PredictPiece`], [`PredictionRecord`], [`ContourFigures`] |
//! | [`identify`] | identification of machine axes and traces (one route) | [`AxisIdentification`] |
//! | [`traces`] | scope files of every format → paired axes → identification | [`traces::MeasuredTrace`] |
//! | [`frf`] | Bode data and bandwidth of models | [`BodeData`] |
//! | [`kinematics`] | forward/inverse kinematics of tables | — |
//! | [`latency`] | the stated actual-value latency: a model's logged position → the physical axis | [`latency::Shifter`] |
//! | [`sweep`] | configuration sweeps, shards, merge | [`Sweep`], [`SweepRow`] |
//! | [`compensate`] | compensated programs (the math is `vcnc-compensate`'s), judging on the true machine | [`compensate::CompensatedProgram`] |
//! | [`feed_plan`] | per-block feeds within a contour tolerance, the uniform baseline | [`feed_plan::JudgedPlan`] |
//! | [`realistic`] | a realistic machine: identification accuracy, prediction discrepancy of both methods, the effect budget | [`realistic::Evaluation`], [`realistic::BudgetRow`] |
//! | [`demo`] | the summaries of `vcnc demo` | [`demo::DemoSummary`] |
//! | [`summary`] | the objects of `summary.json` | [`ModelSummary`], [`FitSummary`] |
//!
//! Every function is deterministic: axes, model sets and configurations run in parallel (rayon)
//! but results are collected in a fixed order, every stream runs its samples in order, and
//! every random number comes from a seeded generator. Errors keep their kind
//! ([`Error::is_bad_input`]).

pub mod compensate;
pub mod demo;
mod drives;
mod error;
pub mod feed_plan;
pub mod frf;
pub mod identify;
pub mod interpolate;
pub mod kinematics;
pub mod latency;
pub mod predict;
pub mod programs;
pub mod realistic;
pub mod run;
pub mod simulate;
pub mod sink;
pub mod source;
pub mod stats;
pub mod summary;
pub mod sweep;
pub mod table;
pub mod traces;
pub mod validate;

pub use error::Error;

// The stage types the outputs and the command line need, so that they reach the stages through
// the pipeline alone.
pub use frf::BodeData;
pub use identify::{AxisIdentification, ExcitationRun, IdentificationSource};
pub use predict::{
    ContourFigures, ContourSummary, PredictOutcome, PredictPiece, PredictSummary, PredictionRecord,
};
pub use run::{AxisSignals, Measured, Run};
pub use simulate::{AxisTracking, SimulateOutcome, SimulatePiece, SimulationRecord};
pub use sink::Sink;
pub use source::{PIECE_SAMPLES, Program, ReferenceChunk, ReferenceStats, ReferenceStream, Source};
pub use summary::{FitSummary, ModelSummary};
pub use sweep::{Sweep, SweepRow};
pub use vcnc_axis::{AxisName, Unit};
pub use vcnc_contour::ContourReport;
pub use vcnc_drive::{
    ClosedLoopModel, DriveModel, DriveTrace, Frf, MAX_ACTUAL_LATENCY_S, ReferenceFilter,
};
pub use vcnc_gcode::{CycleTime, StreamOptions};
pub use vcnc_identify::{Degeneracy, FitMetrics, ModelStructure, Verdict};
pub use vcnc_machine::{
    Dynamics, Error as MachineError, Machine, MachineDocument, MachineModels, ModelSet,
    OptionsFile, embedded,
};
pub use vcnc_trace::Format as TraceFormat;

/// Shortest text that reads back as the same float, `0` for zero (so CSV values reload
/// bit-identically).
pub fn format_num(v: f64) -> String {
    if v == 0.0 {
        "0".to_string()
    } else {
        format!("{v}")
    }
}
