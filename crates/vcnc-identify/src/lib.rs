//! Identification of the 7-parameter closed-loop feed-drive model from an air-cutting run
//! (reference and measured axis position sampled at $T_s$), after Altintas and co-authors'
//! "Identification of 5-Axis Machine Tools Feed Drive Systems for Contouring Simulation"
//! (the paper, section 3), with the corrections and the extra stage of docs/identification.md.
//!
//! ```text
//! Trace (t, xr, x) ──► Regressors (one O(N) pass: prefilter, E, central differences, sign,
//!      │                 9×9 Gram matrix of [Φ1 Φ2 1 Y])
//!      │                     │
//!      │                     ├──► unconstrained_ls ........ baseline, may be unstable
//!      │                     └──► EquationErrorCost ──► Pso (paper §3.3) ──► paper_pso
//!      │                                                   │ distinct good particles
//!      └──────────────────────────────────────────────────► refine (output error, per
//!                                                           structure) ──► identified
//!                                                           │  validation error
//!                                                           └──► model (DriveModel) ──► score
//! ```
//!
//! 1. [`Trace`]: validated samples $(x_{r,k}, x_k)$ at a uniform period (optionally with the exact
//!    reference velocity and acceleration of a simulated machine). The initial measured position
//!    is subtracted from both signals (zero initial conditions, docs/identification.md).
//! 2. [`Regressors`]: the corrected time-domain model (paper eq. 7, docs/identification.md's eq. 18)
//!    $$ x = \alpha_3 E - \alpha_1 \dot x - \alpha_2 \ddot x + \beta_0 x_r + \beta_1 \dot x_r + \beta_2 \ddot x_r - \delta\,\mathrm{sgn}(\dot x), \qquad E = \int (x_r - x)\,dt, $$
//!    reduced in one O(N) pass to its Gram matrix, with a zero-phase prefilter, a sign deadband
//!    and column scaling.
//! 3. [`Pso`] minimises a [`CostFunction`]: here [`EquationErrorCost`], the paper's objective over
//!    $\sigma = [p, \omega_n, \zeta]$ with $\Theta_2$ from the least-squares subproblem. The bounds
//!    keep every pole in the left half plane (paper eq. 12). Seeded, bit-identical for any thread
//!    count, history kept.
//! 4. [`refine`]: output-error refinement, the step beyond the paper (docs/identification.md): the
//!    free-run simulation error of the model ([`free_run_model`], the same simulation the
//!    predictions use) minimised over all parameters, by variable projection and a bounded
//!    Levenberg–Marquardt in coefficients mapped onto the stable region (no seam where poles
//!    change roles), from several distinct swarm particles, with the model's own friction
//!    (sticking included) in a fixed-point second stage and a direct fit of the model's own
//!    free run in a third, and a sandwich covariance that
//!    accounts for the residual's autocorrelation.
//! 5. [`unconstrained_ls`]: the 7-parameter least-squares baseline, reported with its poles and
//!    a stability flag, whatever they are.
//! 6. [`fit_metrics`] and [`score`]: one-step and free-run prediction errors and fit % of any
//!    model ([`vcnc_drive::DriveModel`], the paper's structure or an extended one) on any trace
//!    (estimation or validation run, or a held-out part).
//! 7. Model structures beyond the paper ([`ModelStructure`]: the core without integral action,
//!    dead time, first- or second-order reference filter, extra pole), each identified by the same swarm and refinement and
//!    chosen by validation error ([`identify`] holds out the end of a single trace,
//!    [`identify_with_validation`] takes a second trace).
//!
//! [`identify`] runs 1–7 and returns an [`Identification`] with the refined model, the chosen
//! structure's model, the paper's result and the baseline side by side, the parameters that
//! ended on a bound ([`BoundHit`]) and their standard deviations ([`Uncertainty`]).
//!
//! A measured trace enters through [`Trace::from_log`] ([`Timing`]: a time column is always
//! checked).
//!
//! Drives without integral action (the EMPS benchmark) have their third pole at the origin: set
//! `bounds.p_hz = [0.0, ...]` ([`PoleBounds`]); the model found may then have $a_3 = 0$, which
//! [`vcnc_drive::ClosedLoopModel::is_marginally_stable`] accepts. The structure without integral
//! action ([`ModelStructure::NoIntegral`]) has $a_3 = 0$ exactly, with no bound on $p$ to end on.
//!
//! Variables are named as in the paper (`a1`, `wn`, `zeta`, `dc`, `alpha3`, ...). Positions are in
//! axis units (mm for linear axes, deg for rotary axes), times in seconds, pole frequencies in Hz
//! where a name ends in `_hz` and rad/s otherwise.

mod filter;
mod identify;
mod metrics;
mod options;
mod pso;
mod refine;
mod regress;
#[cfg(test)]
mod test_support;
mod trace;

pub use filter::Butterworth2;
pub use identify::{
    Degeneracy, Identification, LsBaseline, SCREEN_SAMPLES, StructureFit, UNDETERMINED_RELATIVE,
    ValidationSource, Verdict, identify, identify_with_validation, unconstrained_ls,
};
pub use metrics::{FitMetrics, fit_metrics, fit_metrics_with, free_run, free_run_model, score};
pub use options::{
    ExtendedBounds, IdentifyOptions, MAX_POLE_HZ, MAX_ZETA, ModelStructure, PoleBounds, Prefilter,
    PsoSettings, RefineOptions, StartCondition,
};
pub use pso::{CostFunction, DISTINCT, HistoryEntry, Pso, PsoResult};
pub use refine::{
    BoundHit, Determination, OutputErrorProblem, POORLY_DETERMINED, PROFILE_RELATIVE, ParameterStd,
    RefineResult, RefineSetup, RefineStage, SignSource, Start, Uncertainty, UncertaintyLevel,
    refine,
};
pub use regress::{EquationErrorCost, Regressors, Theta};
pub use trace::{MIN_MOTION, MIN_SAMPLES, REST_SPEED, TIME_JITTER, Timing, Trace};
pub use vcnc_drive::drive_model::ReferenceInput;

/// Errors of the identification crate. Every variant carries the values needed to act on it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// The time, reference and position columns differ in length.
    #[error("column lengths differ: t has {t} rows, xr {xr}, x {x}")]
    LengthMismatch {
        /// Rows of the time column (0 when the trace was given by its period).
        t: usize,
        /// Rows of the reference column.
        xr: usize,
        /// Rows of the position column.
        x: usize,
    },
    /// NaN or infinity in a column.
    #[error("column {column} is not finite at row {row}: {value}")]
    NonFinite {
        /// Which column (`t`, `xr`, `x`, `vr` or `ar`).
        column: &'static str,
        /// Row (0-based) of the first bad value.
        row: usize,
        /// The value found.
        value: f64,
    },
    /// Time does not increase strictly.
    #[error("time does not increase at row {row}: t = {t} s after {t_prev} s")]
    TimeNotIncreasing {
        /// Row (0-based) of the offending sample.
        row: usize,
        /// Previous time, s.
        t_prev: f64,
        /// Time at `row`, s.
        t: f64,
    },
    /// Time steps are not uniform.
    #[error(
        "time is not uniformly sampled at row {row}: step {dt} s, nominal period {ts} s \
         (relative tolerance {tolerance})"
    )]
    NonUniformTime {
        /// Row (0-based) at the end of the offending step.
        row: usize,
        /// The step found, s.
        dt: f64,
        /// Nominal (median) sample period, s.
        ts: f64,
        /// Relative tolerance allowed.
        tolerance: f64,
    },
    /// The period stated for a trace disagrees with its time column.
    #[error(
        "the stated sample period {given} s disagrees with the time column's {measured} s \
         (relative tolerance {tolerance})"
    )]
    PeriodMismatch {
        /// Period stated by the user, s.
        given: f64,
        /// Median step of the time column, s.
        measured: f64,
        /// Relative tolerance allowed.
        tolerance: f64,
    },
    /// Sample period not positive and finite.
    #[error("sample period must be positive and finite, got {ts} s")]
    BadSamplePeriod {
        /// The period, s.
        ts: f64,
    },
    /// Not enough samples to identify seven parameters through the prefilter.
    #[error("too few samples: {got}, at least {needed} are needed")]
    TooFewSamples {
        /// Samples given.
        got: usize,
        /// Samples needed.
        needed: usize,
    },
    /// The reference hardly moves.
    #[error("no motion: the reference spans {range} axis units, less than {threshold}")]
    NoMotion {
        /// Peak-to-peak reference range, axis units.
        range: f64,
        /// Smallest range accepted, axis units.
        threshold: f64,
    },
    /// A regressor column is zero: its parameter cannot be identified.
    #[error("regressor {column} is zero over the whole run: {hint}")]
    ZeroRegressor {
        /// The column (`E`, `xr`, `sgn(v)`, ...).
        column: &'static str,
        /// What to change.
        hint: &'static str,
    },
    /// The scaled regressors are too ill-conditioned to identify the model.
    #[error(
        "the regressors cannot identify the model: condition number {condition:.3e} of the \
         column-scaled regressor matrix exceeds {limit:.1e} (excite the axis with more varied moves)"
    )]
    IllConditioned {
        /// 2-norm condition number of the column-scaled regressor matrix.
        condition: f64,
        /// Largest condition number accepted.
        limit: f64,
    },
    /// An option is out of its valid range.
    #[error("option {name} = {value:?} is invalid: {expected}")]
    InvalidOption {
        /// Option name as in the machine file.
        name: &'static str,
        /// Value given.
        value: f64,
        /// What is expected.
        expected: &'static str,
    },
    /// Bounds with min above max (or otherwise invalid).
    #[error("bounds {name} = [{min:?}, {max:?}] are invalid: {expected}")]
    InvalidBounds {
        /// Which bounds.
        name: &'static str,
        /// Lower bound.
        min: f64,
        /// Upper bound.
        max: f64,
        /// What is expected.
        expected: &'static str,
    },
    /// PSO settings outside the convergence region of paper eq. 24.
    #[error(
        "PSO settings w = {w}, eta1 + eta2 = {eta} do not converge (paper eq. 24 needs \
         0 < w < 1 and 0 < eta1 + eta2 < 2 (1 + w) = {limit})"
    )]
    PsoDivergent {
        /// Inertia weight.
        w: f64,
        /// Sum of the learning gains.
        eta: f64,
        /// Upper limit $2(1+w)$ on the sum.
        limit: f64,
    },
    /// The output-error refinement found no usable model from any start.
    #[error("the output-error refinement of the {structure} structure failed from every start")]
    RefinementFailed {
        /// The structure being refined.
        structure: ModelStructure,
    },
    /// The drive model could not be simulated.
    #[error("model simulation failed: {0}")]
    Drive(#[from] vcnc_drive::Error),
}

impl Error {
    /// True when the data or the options are at fault (exit code 2: too few samples, no
    /// motion, an unidentifiable trace, a bad option or PSO settings outside the convergence
    /// region); false for a numerical failure of the identifier itself, such as a candidate
    /// model that cannot be simulated (exit code 1).
    pub fn is_bad_input(&self) -> bool {
        match self {
            Error::LengthMismatch { .. }
            | Error::NonFinite { .. }
            | Error::TimeNotIncreasing { .. }
            | Error::NonUniformTime { .. }
            | Error::BadSamplePeriod { .. }
            | Error::TooFewSamples { .. }
            | Error::NoMotion { .. }
            | Error::ZeroRegressor { .. }
            | Error::IllConditioned { .. }
            | Error::InvalidOption { .. }
            | Error::InvalidBounds { .. }
            | Error::PeriodMismatch { .. }
            | Error::PsoDivergent { .. } => true,
            Error::Drive(_) | Error::RefinementFailed { .. } => false,
        }
    }
}
