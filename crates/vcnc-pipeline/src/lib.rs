//! The runs of vcnc: every computation a command makes, with typed results.
//!
//! ```text
//!   machine file ──vcnc-machine──▶ Machine          program text
//!                                     │                  │
//!                                     └──── run::prepare ┘   parse → interpret → interpolate
//!                                              │              → TCP inverse kinematics
//!                                              ▼              → travel check → reference poses
//!                                             Run (axis references, reference poses)
//!                      ┌───────────────────────┼──────────────────────────┐
//!                      ▼                       ▼                          ▼
//!          simulate::simulate        predict::predict(_many)      sweep::Sweep (per
//!          (true drives, models)     (true drives + models →      configuration: true
//!                                     poses → contour errors)     drives → contour errors)
//!
//!   identify::identify_axis (simulated machine: excitation runs → identify → validate)
//!   identify::identify_trace (measured trace → identify)
//!        └──▶ AxisIdentification ──▶ model.toml (vcnc-machine::ModelSet), IdentifySummary
//! ```
//!
//! | module | does | main types |
//! |---|---|---|
//! | [`run`] | program → axis references | [`Run`], [`AxisSignals`] |
//! | [`simulate`] | references → true drives, models; tracking figures | [`Simulation`], [`AxisTracking`] |
//! | [`predict`] | contour and orientation errors, true vs models | [`Prediction`], [`ContourFigures`] |
//! | [`identify`] | identification of machine axes and traces (one route) | [`AxisIdentification`] |
//! | [`traces`] | scope files of every format → paired axes → identification | [`traces::MeasuredTrace`] |
//! | [`frf`] | Bode data and bandwidth of models | [`BodeData`] |
//! | [`kinematics`] | forward/inverse kinematics of tables | — |
//! | [`latency`] | the stated actual-value latency: a model's logged position → the physical axis | — |
//! | [`sweep`] | configuration sweeps, shards, merge | [`Sweep`], [`SweepRow`] |
//! | [`compensate`] | compensated set-points from identified models, the fine-block program, judging on the true machine | [`compensate::Compensation`] |
//! | [`feed_plan`] | per-block feeds within a contour tolerance, the uniform baseline | [`feed_plan::FeedPlan`] |
//! | [`realistic`] | a realistic machine: identification accuracy, prediction discrepancy of both methods, the effect budget | [`realistic::Evaluation`], [`realistic::BudgetRow`] |
//! | [`summary`] | the objects of `summary.json` | [`ModelSummary`], [`FitSummary`] |
//!
//! Every function is deterministic: axes and configurations run in parallel (rayon) but
//! results are collected in a fixed order, and every random number comes from a seeded
//! generator. Errors keep their kind ([`Error::is_bad_input`]).

pub mod compensate;
mod error;
pub mod feed_plan;
pub mod frf;
pub mod identify;
pub mod kinematics;
pub mod latency;
pub mod predict;
pub mod programs;
pub mod realistic;
pub mod run;
pub mod simulate;
pub mod stats;
pub mod stream;
pub mod stream_predict;
pub mod stream_simulate;
pub mod summary;
pub mod sweep;
pub mod table;
pub mod traces;
pub mod validate;

pub use error::Error;
pub use frf::BodeData;
pub use identify::{AxisIdentification, ExcitationRun, IdentificationSource};
pub use predict::{ContourFigures, ContourSummary, PredictSummary, Prediction};
pub use run::{AxisSignals, Run};
pub use simulate::{AxisTracking, Simulation};
pub use summary::{FitSummary, ModelSummary};
pub use sweep::{Sweep, SweepRow};

/// Shortest text that reads back as the same float, `0` for zero (so CSV values reload
/// bit-identically).
pub fn format_num(v: f64) -> String {
    if v == 0.0 {
        "0".to_string()
    } else {
        format!("{v}")
    }
}
