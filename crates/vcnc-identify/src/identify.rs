//! The identification pipeline: regressors → PSO (paper) → output-error refinement from the
//! swarm's distinct good particles, for the paper's structure and any extended one, the
//! structure chosen by validation error; the unconstrained least-squares baseline beside it
//! (docs/identification.md).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use vcnc_drive::drive_model::ReferenceInput;
use vcnc_drive::{ClosedLoopModel, DriveModel, Poles, ReferenceFilter, SimOptions};

use crate::Error;
use crate::metrics::{FitMetrics, fit_metrics_with, score};
use crate::options::{IdentifyOptions, ModelStructure};
use crate::pso::{HistoryEntry, Pso, PsoResult};
use crate::refine::{
    BoundHit, RefineResult, RefineSetup, Start, Uncertainty, UncertaintyLevel, refine,
};
use crate::regress::{Regressors, Theta};
use crate::trace::Trace;

/// The unconstrained 7-parameter least-squares fit of paper eq. 7 (the baseline of
/// docs/identification.md): no stability constraint, so it may be unstable (sliding-mode drives, EMPS).
#[derive(Debug, Clone, PartialEq)]
pub struct LsBaseline {
    /// The fitted model (non-finite coefficients if $\alpha_2 = 0$).
    pub model: ClosedLoopModel,
    /// Its poles, when they can be written as $(p, \omega_n, \zeta)$.
    pub poles: Option<Poles>,
    /// Every pole strictly in the left half plane.
    pub stable: bool,
    /// Equation-error cost $\tfrac12\|Y - \Phi\Theta\|^2$, axis units².
    pub cost: f64,
}

/// Where the validation figures of the candidates come from.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum ValidationSource {
    /// One candidate only: nothing to choose, no validation.
    None,
    /// A separate validation trace ([`identify_with_validation`]).
    Trace,
    /// A held-out part of the single trace (0-based samples of the whole trace): the
    /// candidates were fitted on the stretch `stretch_first..stretch_first + stretch_samples`
    /// less the held-out samples `first..first + samples`, and scored on those.
    HeldOut {
        /// First held-out sample.
        first: usize,
        /// Number of held-out samples.
        samples: usize,
        /// First sample of the stretch the candidates were compared on.
        stretch_first: usize,
        /// Samples of that stretch (the whole trace, or [`SCREEN_SAMPLES`] of it).
        stretch_samples: usize,
    },
}

/// One candidate model as identified: a structure with a model input.
#[derive(Debug, Clone, PartialEq)]
pub struct StructureFit {
    /// The structure.
    pub structure: ModelStructure,
    /// The model input ([`ReferenceInput`]).
    pub input: ReferenceInput,
    /// Its refined model.
    pub model: DriveModel,
    /// Poles of the model's core.
    pub poles: Poles,
    /// The refinement's details: costs, stages, parameters on bounds, uncertainty.
    pub refinement: RefineResult,
    /// Fit on the trace it was refined on (`whole`: the estimation trace; else the fitted part
    /// of the compared stretch).
    pub estimation: FitMetrics,
    /// Whether it was refined on the whole estimation trace with every stage (the chosen
    /// candidate and the paper's structure with the chosen input, on a single trace with
    /// either input), or only compared (a quicker fit on the fitted part of the stretch,
    /// docs/identification.md, "Choosing a structure").
    pub whole: bool,
    /// Validation error that chose: on the held-out samples (from the fit on the rest of the
    /// stretch) or on the separate validation trace. `None` when nothing was chosen.
    pub validation: Option<FitMetrics>,
    /// Why the candidate's parameters are not trusted (on a bound, not determined by the
    /// data), from its compared fit; empty when they are.
    pub degenerate: Vec<Degeneracy>,
    /// The choice's verdict on this candidate; `None` when nothing was chosen.
    pub verdict: Option<Verdict>,
}

/// Why a candidate's parameters are not trusted ([`StructureFit::degenerate`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Degeneracy {
    /// A parameter ended on a bound of its search region.
    OnBound(BoundHit),
    /// A pole or the structure's own parameter has no deviation (NaN) or one larger than
    /// [`UNDETERMINED_RELATIVE`] times its value.
    Undetermined {
        /// Parameter name (`p_hz`, `wn_hz`, `zeta`, `dc`, `delay_s`, ...).
        parameter: &'static str,
        /// Its value.
        value: f64,
        /// Its relative standard deviation (NaN: none).
        relative_std: f64,
    },
}

impl std::fmt::Display for Degeneracy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Degeneracy::OnBound(h) => {
                write!(f, "{} = {} on its {} bound", h.parameter, h.value, h.bound)
            }
            Degeneracy::Undetermined {
                parameter,
                value,
                relative_std,
            } if relative_std.is_nan() => {
                write!(f, "{parameter} = {value} not determined by the data")
            }
            Degeneracy::Undetermined {
                parameter,
                value,
                relative_std,
            } => write!(
                f,
                "{parameter} = {value} not determined by the data (± {:.0} %)",
                100.0 * relative_std
            ),
        }
    }
}

/// Relative standard deviation above which a pole or a structure's own parameter counts as not
/// determined for the choice (100 %: the data do not fix even its order of magnitude).
pub const UNDETERMINED_RELATIVE: f64 = 1.0;

/// The choice's verdict on one candidate ([`StructureFit::verdict`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Verdict {
    /// Chosen: what the model file holds.
    Chosen,
    /// Its validation error is higher than the chosen candidate's.
    HigherError {
        /// Its validation free-run RMS, axis units.
        rms: f64,
        /// The chosen candidate's, axis units.
        chosen_rms: f64,
    },
    /// Within `selection_margin` of the lowest validation error, but with more parameters
    /// than the chosen candidate (or the same number and a higher error).
    Simpler {
        /// Its validation free-run RMS, axis units.
        rms: f64,
        /// The chosen candidate's, axis units.
        chosen_rms: f64,
        /// The margin, relative.
        margin: f64,
    },
    /// Trusted on the compared stretch, but refined on the whole trace a parameter ends on a
    /// bound or undetermined ([`StructureFit::degenerate`] says which), as did the paper's
    /// structure with the same input, while the paper's structure with the other input is
    /// trusted there: that one is chosen instead.
    DegenerateOnWholeTrace,
    /// Its model input is not the drive's: refined on the whole trace, the paper's structure
    /// with the other input has the lower free-run error (a single trace; the compared stretch
    /// chose this input, the whole trace did not).
    OtherInput {
        /// Whole-trace free-run RMS of the paper's structure with this input, axis units.
        rms: f64,
        /// The same with the other input, axis units.
        other_rms: f64,
    },
    /// It contains the paper's structure (the paper's is its limit with no dead time, filter or
    /// extra pole), yet refined on the whole trace its free-run error is higher than the
    /// paper's with the same input: its fit did not reach its optimum there, so its compared
    /// validation cannot be trusted either, and the paper's structure is chosen instead.
    WorseThanContained {
        /// Its whole-trace free-run RMS, axis units.
        rms: f64,
        /// The paper's structure's, same input, axis units.
        paper_rms: f64,
    },
    /// Its parameters are not trusted ([`StructureFit::degenerate`]) and its validation error
    /// is not below the best trusted candidate's by `degenerate_margin`.
    Degenerate {
        /// Its validation free-run RMS, axis units.
        rms: f64,
        /// The best trusted candidate's, axis units.
        trusted_rms: f64,
        /// The margin, relative.
        margin: f64,
    },
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Verdict::Chosen => f.write_str("chosen"),
            Verdict::HigherError { rms, chosen_rms } => write!(
                f,
                "validation error {:.4e} above the chosen {:.4e}",
                rms, chosen_rms
            ),
            Verdict::Simpler {
                rms,
                chosen_rms,
                margin,
            } => write!(
                f,
                "validation error {:.4e} within {:.0} % of the chosen {:.4e}, which has fewer parameters",
                rms,
                100.0 * margin,
                chosen_rms
            ),
            Verdict::DegenerateOnWholeTrace => f.write_str(
                "refined on the whole trace, its parameters are on a bound or not determined; the paper's structure with the other model input is trusted there",
            ),
            Verdict::OtherInput { rms, other_rms } => write!(
                f,
                "the other model input fits the whole trace better: the paper's structure with it {:.4e}, with this one {:.4e}",
                other_rms, rms
            ),
            Verdict::WorseThanContained { rms, paper_rms } => write!(
                f,
                "refined on the whole trace, its free-run error {:.4e} is above the {:.4e} of the paper's structure it contains",
                rms, paper_rms
            ),
            Verdict::Degenerate {
                rms,
                trusted_rms,
                margin,
            } => write!(
                f,
                "parameters on a bound or not determined, and its validation error {:.4e} is not {:.0} % below the best trusted candidate's {:.4e}",
                rms,
                100.0 * margin,
                trusted_rms
            ),
        }
    }
}

/// Longest stretch of a single trace on which the candidates are compared, samples
/// (docs/identification.md, "Choosing a structure"): a longer trace is compared on the
/// stretch of this length with the longest reference path, and only the chosen candidate (and
/// the paper's structure) is refined on the whole.
pub const SCREEN_SAMPLES: usize = 15_000;

/// Everything [`identify`] found: the chosen model, the paper's PSO result and the baseline side
/// by side, the swarm history and the fit on the estimation run.
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// The paper's 7-parameter model (with the chosen model input), refined by output error
    /// (or the PSO result when the refinement is off). Always inside the pole bounds, hence
    /// stable.
    pub identified: ClosedLoopModel,
    /// Poles of `identified`.
    pub identified_poles: Poles,
    /// The paper structure's model with its input: `identified` as the model file would hold it.
    pub identified_model: DriveModel,
    /// The model of the candidate chosen by validation error (the paper's when only it was
    /// asked for): what a model file should hold.
    pub model: DriveModel,
    /// The chosen structure.
    pub structure: ModelStructure,
    /// The chosen model input (`model.input`).
    pub input: ReferenceInput,
    /// Every candidate identified, the paper's structure with the chosen input first.
    pub structures: Vec<StructureFit>,
    /// Where the validation figures come from.
    pub validation: ValidationSource,
    /// Standard deviations of the chosen model's parameters, widened by the sensitivity to the
    /// model input (docs/identification.md, "Parameter uncertainty").
    pub uncertainty: Option<Uncertainty>,
    /// Parameters of the chosen model that ended on a bound.
    pub on_bounds: Vec<BoundHit>,
    /// The paper's method alone: equation-error PSO over the poles, $\Theta_2$ by least squares.
    pub paper_pso: ClosedLoopModel,
    /// Poles of `paper_pso` (the swarm's global best).
    pub paper_pso_poles: Poles,
    /// Unconstrained least squares of all seven parameters.
    pub unconstrained_ls: LsBaseline,
    /// Global best per swarm iteration (p Hz, ωn Hz, ζ), for the convergence plot.
    pub pso_history: Vec<HistoryEntry>,
    /// Equation-error cost of `paper_pso` (paper eq. 16), axis units².
    pub pso_cost: f64,
    /// The paper structure's refinement details, when it ran.
    pub refinement: Option<RefineResult>,
    /// Condition number of the column-scaled regressors.
    pub condition_number: f64,
    /// Condition number of the column-scaled $\Phi_2$.
    pub condition_phi2: f64,
    /// Whether the trace was treated as starting in motion.
    pub moving_start: bool,
    /// Fit of `identified_model` on the estimation run.
    pub fit_estimation: FitMetrics,
    /// Fit of `paper_pso` on the estimation run.
    pub fit_estimation_paper: FitMetrics,
}

impl Identification {
    /// The chosen candidate's entry in [`structures`](Identification::structures), refined on
    /// the whole estimation trace: its `estimation` fit is the fit of
    /// [`model`](Identification::model), what the model file holds.
    pub fn chosen(&self) -> &StructureFit {
        whole_fit(&self.structures, self.structure, self.input)
            .or_else(|| whole_fit(&self.structures, ModelStructure::Paper, self.input))
            .unwrap_or(&self.structures[0])
    }
}

/// The fit of `structure` with `input` refined on the whole estimation trace, if any.
fn whole_fit(
    fits: &[StructureFit],
    structure: ModelStructure,
    input: ReferenceInput,
) -> Option<&StructureFit> {
    fits.iter()
        .find(|f| f.structure == structure && f.input == input && f.whole)
}

/// Unconstrained least squares of the seven parameters on prepared regressors.
pub fn unconstrained_ls(regs: &Regressors) -> Result<LsBaseline, Error> {
    let (theta, _intercept, cost) = regs.least_squares()?;
    let model = theta.to_model();
    Ok(LsBaseline {
        poles: model.poles(),
        stable: model.is_stable(),
        model,
        cost,
    })
}

/// The swarm stage of one trace: regressors, baseline, PSO.
struct Swarm {
    regs: Regressors,
    condition_number: f64,
    condition_phi2: f64,
    baseline: LsBaseline,
    result: PsoResult,
    paper_pso: ClosedLoopModel,
    paper_pso_poles: Poles,
}

fn swarm(trace: &Trace, opts: &IdentifyOptions) -> Result<Swarm, Error> {
    let regs = Regressors::build(trace, opts)?;
    let condition_number = regs.check_identifiable(opts.max_condition)?;
    let condition_phi2 = regs.condition_phi2();
    let baseline = unconstrained_ls(&regs)?;
    let cost = regs.equation_error_cost()?;
    let pso = Pso::new(opts.bounds.lower().to_vec(), opts.bounds.upper().to_vec())?
        .with_settings(opts.pso)?;
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let result = pso.run(&cost, &mut rng);
    let [p_hz, wn_hz, zeta] = match result.best[..] {
        [a, b, c] => [a, b, c],
        _ => opts.bounds.lower(),
    };
    let paper_pso_poles = Poles::from_hz(p_hz, wn_hz, zeta);
    let (theta, _) = cost.theta_hz(p_hz, wn_hz, zeta);
    let paper_pso = from_poles_and_theta(&paper_pso_poles, &theta);
    Ok(Swarm {
        regs,
        condition_number,
        condition_phi2,
        baseline,
        result,
        paper_pso,
        paper_pso_poles,
    })
}

/// The swarm's distinct good particles as refinement starts: best first, at most `k`, each
/// within a factor 20 of the best cost and distinct in its denominator coefficients (two pole
/// triples that are the same cubic are one start).
fn distinct_starts(candidates: &[(Vec<f64>, f64)], k: usize, extra: &[f64]) -> Vec<Start> {
    let best = candidates.first().map_or(f64::INFINITY, |c| c.1);
    let mut out: Vec<Start> = Vec::new();
    for (pos, c) in candidates {
        if out.len() >= k
            || c.partial_cmp(&(20.0 * best.max(1e-300))) != Some(std::cmp::Ordering::Less)
        {
            break;
        }
        let [p, wn, z] = match pos[..] {
            [a, b, c] => [a, b, c],
            _ => continue,
        };
        let st = Start {
            core: Poles::from_hz(p, wn, z).denominator(),
            extra: extra.to_vec(),
        };
        if !out.iter().any(|o| same_cubic(o, &st)) {
            out.push(st);
        }
    }
    out
}

/// Two starts whose denominators are the same cubic (every coefficient within 5 %).
fn same_cubic(o: &Start, st: &Start) -> bool {
    let (a, b) = (o.core, st.core);
    [(a.0, b.0), (a.1, b.1), (a.2, b.2)]
        .iter()
        .all(|(x, y)| (x - y).abs() <= 0.05 * x.abs().max(y.abs()))
}

/// One candidate of the choice: a structure with a model input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Candidate {
    structure: ModelStructure,
    input: ReferenceInput,
}

/// The candidates asked for: every structure (the paper's first) with every input, each once.
/// No input asked for means the trace's own: smooth when it carries the interpolator's exact
/// derivatives, else hold.
fn candidates(trace: &Trace, opts: &IdentifyOptions) -> Vec<Candidate> {
    let mut structures = vec![ModelStructure::Paper];
    for s in &opts.structures {
        if !structures.contains(s) {
            structures.push(*s);
        }
    }
    let mut inputs: Vec<ReferenceInput> = vec![];
    for i in &opts.inputs {
        if !inputs.contains(i) {
            inputs.push(*i);
        }
    }
    if inputs.is_empty() {
        inputs.push(if trace.reference_derivatives.is_some() {
            ReferenceInput::Smooth
        } else {
            ReferenceInput::Hold
        });
    }
    structures
        .iter()
        .flat_map(|&structure| {
            inputs
                .iter()
                .map(move |&input| Candidate { structure, input })
        })
        .collect()
}

/// Identifies the closed-loop model of one axis from `trace` (docs/identification.md).
///
/// Steps: validate the options; build the prefiltered regressors and their Gram matrix (one
/// O(N) pass); reject data that cannot identify the model (condition number above
/// `opts.max_condition`); unconstrained LS baseline; paper PSO over the poles with the
/// least-squares subproblem, seeded with `opts.seed`; output-error refinement from the swarm's
/// distinct good particles (when `opts.refine.enabled`); fit metrics on the trace.
///
/// With several candidates (`opts.structures` beyond the paper's, or several `opts.inputs`)
/// the one with the lowest validation error is chosen, on a stretch of the trace (the whole
/// trace, or the [`SCREEN_SAMPLES`] with the longest reference path): the last
/// `opts.holdout_fraction` of the stretch is held out, every candidate is fitted on the rest
/// (a quicker fit: at most two friction stages, the linearised uncertainty), runs free
/// through the stretch and is scored on the held-out samples only; then the chosen candidate
/// and the paper's structure with either input are refined on the whole trace, from their
/// compared fits, and the input whose paper fit has the lower whole-trace error is the model's
/// (the choice runs again among its candidates when the stretch chose the other). A candidate
/// whose parameters are on a bound or not determined is chosen only if it beats the best
/// trusted one by `opts.degenerate_margin` ([`Verdict`]). Held out at the end, and contiguous: a free run needs the initial state, known only at the start, and the
/// residuals of neighbouring samples are strongly correlated, so scattered held-out samples
/// would be predicted from their fitted neighbours' errors rather than from the model. When
/// the end of a stretch that starts at rest hardly moves (less than a tenth of its reference
/// path), its start is held out instead.
pub fn identify(trace: &Trace, opts: &IdentifyOptions) -> Result<Identification, Error> {
    opts.validate()?;
    let cands = candidates(trace, opts);
    let main = swarm(trace, opts)?;
    if cands.len() == 1 || !opts.refine.enabled {
        let fit = sole_fit(trace, &main, cands[0], opts)?;
        return assemble(trace, main, vec![fit], ValidationSource::None, None, opts);
    }
    // The stretch the candidates are compared on, and its held-out part.
    let (w0, w1) = screen_window(trace);
    let stretch = sub_trace(trace, w0..w1)?;
    let m = stretch.len();
    let split = m - ((m as f64 * opts.holdout_fraction) as usize).max(1);
    let path = |a: usize, b: usize| -> f64 {
        stretch.xr[a..b]
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .sum()
    };
    let moving = !stretch.starts_at_rest(crate::trace::REST_SPEED);
    let hold_end = moving || path(split, m) >= 0.1 * path(0, m);
    let (fit_range, hold) = if hold_end {
        (0..split, split..m)
    } else {
        let k = m - split;
        (k..m, 0..k)
    };
    let part = sub_trace(&stretch, fit_range)?;
    let psw = &swarm(&part, opts)?;
    // Validation: each model (fitted on the part) runs free through the stretch; the held-out
    // samples score it.
    let validate = |m: &DriveModel| score(m, &stretch, Some(hold.clone()), opts);
    let (screened, validations) = compare(&part, psw, &cands, opts, &validate)?;
    let source = ValidationSource::HeldOut {
        first: w0 + hold.start,
        samples: hold.len(),
        stretch_first: w0,
        stretch_samples: m,
    };
    finish(trace, main, screened, validations, source, opts)
}

/// [`identify`] with a separate validation trace of the same axis (a simulated machine's
/// validation program, or a second recording): every candidate is fitted on `trace` (the
/// quicker fit of the comparison) and scored by its free run on `validation`; the choice is
/// [`identify`]'s; the chosen candidate and the paper's structure with the chosen input are
/// then refined with every stage.
pub fn identify_with_validation(
    trace: &Trace,
    validation: &Trace,
    opts: &IdentifyOptions,
) -> Result<Identification, Error> {
    opts.validate()?;
    let cands = candidates(trace, opts);
    let main = swarm(trace, opts)?;
    if cands.len() == 1 || !opts.refine.enabled {
        let c = cands[0];
        let mut fit = sole_fit(trace, &main, c, opts)?;
        fit.validation = Some(score(&fit.model, validation, None, opts)?);
        return assemble(
            trace,
            main,
            vec![fit],
            ValidationSource::Trace,
            Some(c),
            opts,
        );
    }
    let validate = |m: &DriveModel| score(m, validation, None, opts);
    let (screened, validations) = compare(trace, &main, &cands, opts, &validate)?;
    finish(
        trace,
        main,
        screened,
        validations,
        ValidationSource::Trace,
        opts,
    )
}

/// The whole-trace fit of the one candidate when there is nothing to compare (one candidate,
/// or refinement off), from the swarm's distinct starts.
fn sole_fit(
    trace: &Trace,
    main: &Swarm,
    c: Candidate,
    opts: &IdentifyOptions,
) -> Result<StructureFit, Error> {
    let starts = distinct_starts(&main.result.candidates, opts.refine.starts, &[]);
    fit_one(trace, main, c, &starts, opts, Stage::Whole)
}

/// The choice among the compared candidates, then the whole-trace refinement of the chosen one
/// and of the paper's structure with the chosen input, from their compared fits (and, for the
/// paper's structure, the swarm's distinct starts when its compared fit is not trusted); every
/// candidate reported. On a single trace (`source` held out) the paper's structure with the
/// other model input is refined on the whole trace too, in parallel, and the model input is the
/// one whose paper fit has the lower whole-trace error (docs/identification.md, "Choosing a
/// structure"): when that is the other input, the choice runs again among the candidates with
/// it, and those with the input it replaces get [`Verdict::OtherInput`].
fn finish(
    trace: &Trace,
    main: Swarm,
    mut screened: Vec<StructureFit>,
    validations: Vec<FitMetrics>,
    source: ValidationSource,
    opts: &IdentifyOptions,
) -> Result<Identification, Error> {
    let all: Vec<usize> = (0..screened.len()).collect();
    let (chosen, mut verdicts) = choose(&screened, &validations, &all, opts);
    for (f, v) in screened.iter_mut().zip(&validations) {
        f.validation = Some(v.clone());
    }
    let screened = screened;
    let mut c = candidate_of(&screened[chosen]);
    let paper_with = |input: ReferenceInput| Candidate {
        structure: ModelStructure::Paper,
        input,
    };
    let other_input = |input: ReferenceInput| {
        screened
            .iter()
            .find(|f| f.structure == ModelStructure::Paper && f.input != input)
            .map(|f| f.input)
    };
    // The chosen structure's core when it contains the paper's: where the paper's structure
    // also starts on the whole trace (below).
    let chosen_core = Some(&screened[chosen])
        .filter(|f| f.structure != ModelStructure::Paper && f.structure.contains_paper())
        .map(|f| start_of(&f.model, ModelStructure::Paper));
    let refit = |cand: Candidate| -> Result<StructureFit, Error> {
        let prev = screened.iter().find(|f| candidate_of(f) == cand);
        // From the compared fit (near the whole trace's optimum); for the paper's structure
        // also from the swarm's distinct starts when that fit is missing or not trusted (a
        // parameter on a bound is a poor place to start), and from the core of the chosen
        // structure when that contains the paper's and its poles differ: on a stretch the
        // richer structure can find the drive's poles where the paper's swarm and its compared
        // fit end in another valley (docs/identification.md, "Choosing a structure").
        let mut starts: Vec<Start> = prev
            .map(|f| start_of(&f.model, cand.structure))
            .into_iter()
            .collect();
        if cand.structure == ModelStructure::Paper && prev.is_none_or(|f| !f.degenerate.is_empty())
        {
            starts.extend(distinct_starts(
                &main.result.candidates,
                opts.refine.starts,
                &[],
            ));
        }
        if cand.structure == ModelStructure::Paper
            && let Some(core) = &chosen_core
            && !starts.iter().any(|s| same_cubic(s, core))
        {
            starts.push(core.clone());
        }
        let mut fit = fit_one(trace, &main, cand, &starts, opts, Stage::Whole)?;
        if let Some(p) = prev {
            fit.validation = p.validation.clone();
            fit.degenerate = p.degenerate.clone();
        }
        Ok(fit)
    };
    let held_out = matches!(source, ValidationSource::HeldOut { .. });
    let mut jobs = vec![c];
    for j in std::iter::once(paper_with(c.input))
        .chain(other_input(c.input).filter(|_| held_out).map(paper_with))
    {
        if !jobs.contains(&j) {
            jobs.push(j);
        }
    }
    let mut whole: Vec<StructureFit> = jobs
        .par_iter()
        .map(|&j| refit(j))
        .collect::<Result<_, _>>()?;
    let at = |whole: &[StructureFit], cand: Candidate| {
        whole.iter().position(|f| candidate_of(f) == cand)
    };
    // The model input on the whole trace: the paper's structure with either input.
    if held_out && let Some(other) = other_input(c.input) {
        let (mine, theirs) = (
            &whole[at(&whole, paper_with(c.input)).expect("refined")],
            &whole[at(&whole, paper_with(other)).expect("refined")],
        );
        let (rms, other_rms) = (mine.estimation.freerun_rms, theirs.estimation.freerun_rms);
        // Decisively lower: below this input's by the margin the choice among structures
        // uses, so that a tie between the two paper fits (a trace where the paper's structure
        // is not the drive's, its error dominated by what it lacks) leaves the compared
        // stretch's input.
        if degeneracy(&theirs.refinement).is_empty()
            && other_rms < (1.0 - opts.selection_margin) * rms
        {
            let pool: Vec<usize> = (0..screened.len())
                .filter(|&i| screened[i].input == other)
                .collect();
            let (k, pool_verdicts) = choose(&screened, &validations, &pool, opts);
            for (i, f) in screened.iter().enumerate() {
                if f.input != other {
                    verdicts[i] = Verdict::OtherInput { rms, other_rms };
                }
            }
            for (&i, v) in pool.iter().zip(pool_verdicts) {
                verdicts[i] = v;
            }
            c = candidate_of(&screened[k]);
            if at(&whole, c).is_none() {
                whole.push(refit(c)?);
            }
        }
    }
    for f in &mut whole {
        f.verdict = screened
            .iter()
            .position(|g| candidate_of(g) == candidate_of(f))
            .map(|i| verdicts[i].clone());
    }
    // A structure that contains the paper's and fits the whole trace worse than it did not
    // converge there (docs/identification.md, "Choosing a structure"): the paper's is chosen.
    let paper = paper_with(c.input);
    if c.structure.contains_paper() {
        let (ci, pi) = (
            at(&whole, c).expect("refined"),
            at(&whole, paper).expect("refined"),
        );
        let (rms, paper_rms) = (
            whole[ci].estimation.freerun_rms,
            whole[pi].estimation.freerun_rms,
        );
        if rms > paper_rms {
            whole[ci].verdict = Some(Verdict::WorseThanContained { rms, paper_rms });
            whole[pi].verdict = Some(Verdict::Chosen);
            c = paper;
        }
    }
    // The whole trace's own verdict (docs/identification.md, "Choosing a structure"): when the
    // chosen candidate and the paper's structure with its input both end on a bound or leave a
    // parameter undetermined once refined on the whole trace, the paper's structure with the
    // other input is refined there too (if it is not yet), and chosen when it is trusted.
    let degenerate_whole = |whole: &[StructureFit], cand: Candidate| {
        at(whole, cand).is_some_and(|i| !degeneracy(&whole[i].refinement).is_empty())
    };
    if degenerate_whole(&whole, c)
        && degenerate_whole(&whole, paper_with(c.input))
        && let Some(other) = other_input(c.input)
    {
        let alt = paper_with(other);
        if at(&whole, alt).is_none() {
            whole.push(refit(alt)?);
        }
        let i = at(&whole, alt).expect("refined");
        if degeneracy(&whole[i].refinement).is_empty() {
            for f in whole.iter_mut().filter(|f| f.input == c.input) {
                f.degenerate = degeneracy(&f.refinement);
                f.verdict = Some(Verdict::DegenerateOnWholeTrace);
            }
            whole[i].verdict = Some(Verdict::Chosen);
            c = alt;
        }
    }
    // The sensitivity to the model input: the paper's structure compared with either input.
    let compared = |cand: Candidate| screened.iter().find(|f| candidate_of(f) == cand);
    let twin = other_input(c.input).and_then(|i| compared(paper_with(i)));
    let me = compared(paper_with(c.input));
    let ci = at(&whole, c).expect("refined");
    if let (Some(me), Some(twin), Some(u)) = (me, twin, whole[ci].refinement.uncertainty.as_mut()) {
        widen_by_input(u, me, twin);
    }
    // The whole-trace fits: the paper's structure with the chosen input first, then the chosen
    // candidate, the rest in the order refined; then the compared-only candidates.
    whole.sort_by_key(|f| {
        let k = candidate_of(f);
        (k != paper_with(c.input), k != c)
    });
    let mut fits = whole;
    for (mut f, v) in screened.into_iter().zip(verdicts) {
        if !fits.iter().any(|g| candidate_of(g) == candidate_of(&f)) {
            f.verdict = Some(v);
            fits.push(f);
        }
    }
    assemble(trace, main, fits, source, Some(c), opts)
}

fn candidate_of(f: &StructureFit) -> Candidate {
    Candidate {
        structure: f.structure,
        input: f.input,
    }
}

/// Widens the chosen model's deviations `u` by its sensitivity to the model input (docs/
/// identification.md, "Parameter uncertainty"): the compared fits of the paper's structure with
/// the chosen input (`me`) and the other (`twin`) differ by $\Delta_i$ in each parameter; with the
/// two inputs weighed by their validation likelihoods — $w$ the other's posterior weight from
/// the ratio of the held-out mean squares over the independent samples the residual's
/// correlation window leaves, $\ln(w / (1 - w)) = -\tfrac{N_{eff}}{2}\ln(\mathrm{MS}_{twin} /
/// \mathrm{MS}_{me})$ — the mixture adds the variance $w(1 - w)\Delta_i^2$.
fn widen_by_input(u: &mut Uncertainty, me: &StructureFit, twin: &StructureFit) {
    let (Some(vm), Some(vt)) = (&me.validation, &twin.validation) else {
        return;
    };
    let (ms_me, ms_twin) = (vm.freerun_rms.powi(2), vt.freerun_rms.powi(2));
    if !(ms_me > 0.0 && ms_twin.is_finite()) {
        return;
    }
    let n_eff = vm.samples as f64 / u.window_samples.max(1) as f64;
    let log_odds = -0.5 * n_eff * (ms_twin / ms_me).ln();
    let w = 1.0 / (1.0 + (-log_odds).exp());
    let weight = (w * (1.0 - w)).sqrt();
    let (Some(a), Some(b)) = (
        me.refinement.uncertainty.as_ref(),
        twin.refinement.uncertainty.as_ref(),
    ) else {
        return;
    };
    for p in &mut u.parameters {
        if let (Some(x), Some(y)) = (a.get(p.name), b.get(p.name)) {
            let d = weight * (x.value - y.value);
            if d.is_finite() && p.std.is_finite() {
                p.std = p.std.hypot(d);
                p.input_std = d.abs();
            }
        }
    }
}

/// The stretch of `trace` on which candidates are compared: all of it, or the
/// [`SCREEN_SAMPLES`] (at half-window steps) with the longest reference path.
fn screen_window(trace: &Trace) -> (usize, usize) {
    let n = trace.len();
    if n <= SCREEN_SAMPLES {
        return (0, n);
    }
    let mut cum = Vec::with_capacity(n);
    let mut acc = 0.0;
    cum.push(0.0);
    for w in trace.xr.windows(2) {
        acc += (w[1] - w[0]).abs();
        cum.push(acc);
    }
    let step = SCREEN_SAMPLES / 2;
    let mut best = (0usize, f64::NEG_INFINITY);
    let mut a = 0;
    loop {
        let b = (a + SCREEN_SAMPLES).min(n);
        let p = cum[b - 1] - cum[a];
        if p > best.1 {
            best = (a, p);
        }
        if b == n {
            break;
        }
        a = (a + step).min(n - SCREEN_SAMPLES);
    }
    (best.0, best.0 + SCREEN_SAMPLES)
}

/// Samples `r` of `trace` as a trace of their own (with the exact derivatives, if any).
fn sub_trace(trace: &Trace, r: std::ops::Range<usize>) -> Result<Trace, Error> {
    if r.start == 0 && r.end == trace.len() {
        return Ok(trace.clone());
    }
    let t = Trace::new(
        trace.ts,
        trace.xr[r.clone()].to_vec(),
        trace.x[r.clone()].to_vec(),
    )?;
    match &trace.reference_derivatives {
        Some((v, a)) => t.with_reference_derivatives(v[r.clone()].to_vec(), a[r].to_vec()),
        None => Ok(t),
    }
}

/// Scores a compared model on the validation samples.
type Validate<'a> = dyn Fn(&DriveModel) -> Result<FitMetrics, Error> + Sync + 'a;

/// The compared fits of `cands` on `trace` and their validation scores (docs/identification.md,
/// "Choosing a structure"): first the paper's structure with every input (in parallel), whose
/// validation chooses the model input ([`choose`]); then every other structure with that input
/// (in parallel). Starts: the swarm's distinct good particles (paper's structure), those of
/// the swarm without the integral mode ([`no_integral_starts`]), a grid of the extra parameter
/// screened by the equation-error swarm (extended); found while the paper's structure is
/// fitted, at most [`COMPARE_STARTS`] each. Candidates of another input
/// than the chosen one with a structure other than the paper's are not fitted.
fn compare(
    trace: &Trace,
    sw: &Swarm,
    cands: &[Candidate],
    opts: &IdentifyOptions,
    validate: &Validate<'_>,
) -> Result<(Vec<StructureFit>, Vec<FitMetrics>), Error> {
    let k = opts.refine.starts.min(COMPARE_STARTS);
    let mut structures: Vec<ModelStructure> = vec![];
    for c in cands {
        if c.structure != ModelStructure::Paper && !structures.contains(&c.structure) {
            structures.push(c.structure);
        }
    }
    let fit_scored =
        |c: Candidate, starts: &[Start]| -> Result<(StructureFit, FitMetrics), Error> {
            let f = fit_one(trace, sw, c, starts, opts, Stage::Compare)?;
            let v = validate(&f.model)?;
            Ok((f, v))
        };
    let papers: Vec<Candidate> = cands
        .iter()
        .copied()
        .filter(|c| c.structure == ModelStructure::Paper)
        .collect();
    let paper_starts = distinct_starts(&sw.result.candidates, k, &[]);
    let (paper_fits, extended_starts_found) = rayon::join(
        || {
            papers
                .par_iter()
                .map(|&c| fit_scored(c, &paper_starts))
                .collect::<Result<Vec<_>, Error>>()
        },
        || {
            structures
                .par_iter()
                .map(|&s| {
                    if s == ModelStructure::NoIntegral {
                        return no_integral_starts(&sw.regs, k, opts);
                    }
                    let mut st = extended_starts(trace, s, opts)?;
                    st.truncate(COMPARE_EXTENDED_STARTS.min(k));
                    Ok(st)
                })
                .collect::<Result<Vec<_>, Error>>()
        },
    );
    let (mut fits, mut vals): (Vec<StructureFit>, Vec<FitMetrics>) =
        paper_fits?.into_iter().unzip();
    let starts = extended_starts_found?;
    let all: Vec<usize> = (0..fits.len()).collect();
    let (best, _) = choose(&fits, &vals, &all, opts);
    let input = fits[best].input;
    let rest: Vec<(StructureFit, FitMetrics)> = structures
        .par_iter()
        .zip(starts.par_iter())
        .filter(|(s, _)| {
            cands.contains(&Candidate {
                structure: **s,
                input,
            })
        })
        .map(|(&s, st)| {
            fit_scored(
                Candidate {
                    structure: s,
                    input,
                },
                st,
            )
        })
        .collect::<Result<_, _>>()?;
    for (f, v) in rest {
        fits.push(f);
        vals.push(v);
    }
    Ok((fits, vals))
}

/// The choice by validation free-run RMS ([`choose_among`]) among the candidates `pool`
/// (indices into `fits` and their validations `val`): the index of the chosen one in `fits`,
/// and the verdict on each of `pool`.
fn choose(
    fits: &[StructureFit],
    val: &[FitMetrics],
    pool: &[usize],
    opts: &IdentifyOptions,
) -> (usize, Vec<Verdict>) {
    let entries: Vec<Entry> = pool
        .iter()
        .map(|&i| entry(&fits[i], val[i].freerun_rms, fits))
        .collect();
    let (k, verdicts) = choose_among(&entries, opts.selection_margin, opts.degenerate_margin);
    (pool[k], verdicts)
}

/// A compared candidate `f` with its validation error `rms` as the choice sees it, among the
/// compared `fits`. The structure without integral action is the paper's with $p = 0$: when
/// the paper's structure with the same input determines $p$ away from zero (more than
/// [`NESTED_REJECTION_SIGMAS`] standard deviations), the data reject that restriction, and the
/// restricted structure counts the paper's parameters (it is not simpler in any way the data
/// allow; it can still win by a lower error).
fn entry(f: &StructureFit, rms: f64, fits: &[StructureFit]) -> Entry {
    let integral_determined = || {
        fits.iter()
            .find(|g| g.structure == ModelStructure::Paper && g.input == f.input)
            .and_then(|g| g.refinement.uncertainty.as_ref()?.get("p_hz"))
            .is_some_and(|q| q.value.abs() > NESTED_REJECTION_SIGMAS * q.std)
    };
    let parameters = if f.structure == ModelStructure::NoIntegral && integral_determined() {
        ModelStructure::Paper.parameters()
    } else {
        f.structure.parameters()
    };
    Entry {
        parameters,
        trusted: f.degenerate.is_empty(),
        rms: if rms.is_finite() { rms } else { f64::INFINITY },
    }
}

/// Standard deviations from zero beyond which a fitted $p$ rejects the structure without
/// integral action ([`entry`]): the usual three-sigma test of a nested restriction.
const NESTED_REJECTION_SIGMAS: f64 = 3.0;

/// A compared candidate as the choice sees it.
#[derive(Debug, Clone, Copy)]
struct Entry {
    /// Its number of parameters ([`ModelStructure::parameters`]).
    parameters: usize,
    /// No parameter on a bound or undetermined ([`StructureFit::degenerate`] empty).
    trusted: bool,
    /// Validation free-run RMS (infinite when the free run failed).
    rms: f64,
}

/// The choice among `entries` (docs/identification.md, "Choosing a structure"): among the
/// trusted candidates the lowest error wins, unless one with fewer parameters comes within
/// `selection_margin` (relative) of it — then the one with the fewest parameters among those
/// within the margin (ties to the lower error). A candidate that is not trusted wins only when
/// its error is below the best trusted candidate's by `degenerate_margin` (relative): the best
/// trusted error, not the trusted choice's, so that adding a trusted candidate never turns the
/// choice to an untrusted one. When none is trusted, the first rule runs over all.
fn choose_among(
    entries: &[Entry],
    selection_margin: f64,
    degenerate_margin: f64,
) -> (usize, Vec<Verdict>) {
    let rms = |i: usize| entries[i].rms;
    let trusted: Vec<usize> = (0..entries.len()).filter(|&i| entries[i].trusted).collect();
    let lowest = |pool: &[usize]| pool.iter().map(|&i| rms(i)).fold(f64::INFINITY, f64::min);
    // Within the margin of the pool's lowest error: the fewest parameters, then the lower
    // error, then the earlier candidate.
    let parsimonious = |pool: &[usize]| -> Option<usize> {
        let bar = lowest(pool) * (1.0 + selection_margin);
        pool.iter()
            .copied()
            .filter(|&i| rms(i) <= bar)
            .min_by(|&a, &b| {
                let (ea, eb) = (&entries[a], &entries[b]);
                ea.parameters
                    .cmp(&eb.parameters)
                    .then(ea.rms.total_cmp(&eb.rms))
            })
    };
    let all: Vec<usize> = (0..entries.len()).collect();
    let best_trusted = lowest(&trusted);
    let chosen = match parsimonious(&trusted) {
        Some(t) => {
            let untrusted_best = (0..entries.len())
                .filter(|&i| !entries[i].trusted)
                .min_by(|&a, &b| rms(a).total_cmp(&rms(b)));
            match untrusted_best {
                Some(d) if rms(d) < (1.0 - degenerate_margin) * best_trusted => d,
                _ => t,
            }
        }
        None => parsimonious(&all).unwrap_or(0),
    };
    let best = lowest(&all);
    let verdicts = (0..entries.len())
        .map(|i| {
            let (r, c) = (rms(i), rms(chosen));
            if i == chosen {
                Verdict::Chosen
            } else if !entries[i].trusted && !trusted.is_empty() && r < c {
                Verdict::Degenerate {
                    rms: r,
                    trusted_rms: best_trusted,
                    margin: degenerate_margin,
                }
            } else if r <= c || r <= best * (1.0 + selection_margin) {
                Verdict::Simpler {
                    rms: r,
                    chosen_rms: c,
                    margin: selection_margin,
                }
            } else {
                Verdict::HigherError {
                    rms: r,
                    chosen_rms: c,
                }
            }
        })
        .collect();
    (chosen, verdicts)
}

/// Why a compared fit's parameters are not trusted: its bound hits, and its poles and own
/// parameters whose deviation is undefined or above [`UNDETERMINED_RELATIVE`] (the friction
/// $d_c$ only when undefined: it is often poorly determined by runs with few reversals and is
/// not what a structure is chosen for).
fn degeneracy(r: &RefineResult) -> Vec<Degeneracy> {
    let mut out: Vec<Degeneracy> = r
        .on_bounds
        .iter()
        .cloned()
        .map(Degeneracy::OnBound)
        .collect();
    if let Some(u) = &r.uncertainty {
        for p in &u.parameters {
            let rel = p.relative();
            let bad = if p.name == "dc" {
                rel.is_nan()
            } else {
                rel.is_nan() || rel > UNDETERMINED_RELATIVE
            };
            if bad {
                out.push(Degeneracy::Undetermined {
                    parameter: p.name,
                    value: p.value,
                    relative_std: rel,
                });
            }
        }
    }
    out
}

/// How thoroughly a candidate is fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    /// Compared: at most two friction stages, the linearised uncertainty.
    Compare,
    /// Refined on the whole trace: every stage, the full uncertainty.
    Whole,
}

/// A start from a model of structure `s`.
fn start_of(m: &DriveModel, s: ModelStructure) -> Start {
    let extra = match (s, m.reference_filter) {
        (ModelStructure::Delay, _) => vec![m.delay_s],
        (ModelStructure::FirstOrderFilter, Some(ReferenceFilter::FirstOrder { tau_s })) => {
            vec![tau_s.ln()]
        }
        (ModelStructure::SecondOrderFilter, Some(ReferenceFilter::SecondOrder { wn_hz, zeta })) => {
            vec![wn_hz.ln(), zeta]
        }
        (ModelStructure::ExtraPole, _) => vec![m.extra_pole_hz.unwrap_or(100.0).ln()],
        _ => vec![],
    };
    Start {
        core: (m.core.a1, m.core.a2, m.core.a3),
        extra,
    }
}

/// Refines candidate `c` on `trace` from `starts` (or takes the swarm's model when the
/// refinement is off), with its fit on `trace`.
fn fit_one(
    trace: &Trace,
    sw: &Swarm,
    c: Candidate,
    starts: &[Start],
    opts: &IdentifyOptions,
    stage: Stage,
) -> Result<StructureFit, Error> {
    let refinement = if opts.refine.enabled {
        let mut setup = RefineSetup::full(c.structure, c.input, opts);
        let compare_opts;
        if stage == Stage::Compare {
            compare_opts = crate::options::RefineOptions {
                sign_iterations: opts.refine.sign_iterations.min(COMPARE_SIGN_ITERATIONS),
                max_iterations: opts.refine.max_iterations.min(COMPARE_ITERATIONS),
                tolerance: opts.refine.tolerance.max(COMPARE_TOLERANCE),
                ..opts.refine
            };
            setup.opts = &compare_opts;
            setup.uncertainty = UncertaintyLevel::Linear;
            setup.free_run_stage = false;
        }
        refine(trace, &sw.regs, starts, setup)?
    } else {
        // No refinement: the swarm's model as it is.
        let model = DriveModel {
            input: c.input,
            ..DriveModel::from(sw.paper_pso)
        };
        RefineResult {
            model,
            poles: sw.paper_pso_poles,
            start_cost: f64::NAN,
            cost: f64::NAN,
            rms: f64::NAN,
            cost_history: vec![],
            stages: vec![],
            chosen: 0,
            iterations: 0,
            evaluations: 0,
            on_bounds: vec![],
            uncertainty: None,
        }
    };
    let model = refinement.model;
    let estimation = if c.structure == ModelStructure::Paper {
        crate::metrics::score_paper(&model, trace, &sw.regs)?
    } else {
        score(&model, trace, None, opts)?
    };
    Ok(StructureFit {
        structure: c.structure,
        input: c.input,
        poles: refinement.poles,
        model,
        degenerate: degeneracy(&refinement),
        refinement,
        estimation,
        whole: stage == Stage::Whole,
        validation: None,
        verdict: None,
    })
}

/// A compared fit (docs/identification.md, "Choosing a structure"): at most this many friction
/// stages (stage B; the comparison needs the model near its fixed point, not at it), starts,
/// Levenberg–Marquardt iterations per stage, and a relative cost decrease that ends a stage.
const COMPARE_SIGN_ITERATIONS: usize = 1;
const COMPARE_STARTS: usize = 2;
/// Starts of a compared fit of an extended structure: the grid point with the lowest
/// equation-error cost.
const COMPARE_EXTENDED_STARTS: usize = 1;
const COMPARE_ITERATIONS: usize = 20;
const COMPARE_TOLERANCE: f64 = 1e-6;

/// Starts of the structure without integral action ([`ModelStructure::NoIntegral`]): the
/// paper's equation-error swarm with $p \equiv 0$ ($\alpha_3 = 0$, the integral regressor
/// dropped; $b_2$ stays free in the regression) over $(\omega_n, \zeta)$ within their bounds, on
/// the regressors `regs` already built; its distinct good particles, at most `k`.
fn no_integral_starts(
    regs: &Regressors,
    k: usize,
    opts: &IdentifyOptions,
) -> Result<Vec<Start>, Error> {
    let cost = regs.equation_error_cost()?;
    let (lo, hi) = (opts.bounds.lower(), opts.bounds.upper());
    let pso = Pso::new(lo[1..].to_vec(), hi[1..].to_vec())?.with_settings(opts.pso)?;
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let pair_cost = |s: &[f64]| match s {
        [wn, zeta] => cost.cost_hz(0.0, *wn, *zeta),
        _ => f64::INFINITY,
    };
    let result = pso.run(&pair_cost, &mut rng);
    let with_p: Vec<(Vec<f64>, f64)> = result
        .candidates
        .into_iter()
        .map(|(pos, c)| (std::iter::once(0.0).chain(pos).collect(), c))
        .collect();
    Ok(distinct_starts(&with_p, k, &[]))
}

/// Starts of an extended structure: its extra parameter on a grid over its bounds; at each
/// grid value the reference is shaped (dead time, filter) or the measured position freed of
/// the extra pole, and the paper's equation-error swarm (a shorter run) finds the poles; the
/// grid values with the lowest equation-error cost, distinct, are the starts.
fn extended_starts(
    trace: &Trace,
    s: ModelStructure,
    opts: &IdentifyOptions,
) -> Result<Vec<Start>, Error> {
    let eb = &opts.extended_bounds;
    let geo = |[lo, hi]: [f64; 2], k: usize, lo_floor: f64| -> Vec<f64> {
        let a = lo.max(lo_floor);
        (0..k)
            .map(|i| a * (hi / a).powf(i as f64 / (k - 1) as f64))
            .collect()
    };
    // Grid points as (extra parameters in search coordinates, the shaping model).
    let grid: Vec<Vec<f64>> = match s {
        ModelStructure::Paper | ModelStructure::NoIntegral => return Ok(vec![]),
        ModelStructure::Delay => {
            // Even steps of 5 ms (at most 41 points): a dead time shifts the whole response,
            // so the equation-error cost has narrow valleys in it.
            let [lo, hi] = eb.delay_s;
            let k = (((hi - lo) / 0.005).ceil() as usize).clamp(2, 41);
            (0..k)
                .map(|i| vec![lo + (hi - lo) * i as f64 / (k - 1) as f64])
                .collect()
        }
        ModelStructure::FirstOrderFilter => geo(eb.filter_tau_s, 12, 1e-5)
            .into_iter()
            .map(|v| vec![v.ln()])
            .collect(),
        ModelStructure::SecondOrderFilter => {
            let mut g = vec![];
            for w in geo(eb.filter_wn_hz, 10, 1e-3) {
                for z in [0.7f64, 1.0] {
                    g.push(vec![w.ln(), z.clamp(eb.filter_zeta[0], eb.filter_zeta[1])]);
                }
            }
            g
        }
        ModelStructure::ExtraPole => geo(eb.extra_pole_hz, 10, 1e-3)
            .into_iter()
            .map(|v| vec![v.ln()])
            .collect(),
    };
    let screen_opts = IdentifyOptions {
        pso: crate::options::PsoSettings {
            particles: 60,
            iterations: 40,
            ..opts.pso
        },
        start: opts.start,
        ..opts.clone()
    };
    let results: Vec<Option<(f64, Start)>> = grid
        .par_iter()
        .map(|g| {
            let tr = shaped_trace(trace, s, g).ok()?;
            let sw = swarm(&tr, &screen_opts).ok()?;
            let [p, wn, z] = match sw.result.best[..] {
                [a, b, c] => [a, b, c],
                _ => return None,
            };
            Some((
                sw.result.best_cost,
                Start {
                    core: Poles::from_hz(p, wn, z).denominator(),
                    extra: g.to_vec(),
                },
            ))
        })
        .collect();
    let mut ranked: Vec<(f64, Start)> = results.into_iter().flatten().collect();
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(ranked
        .into_iter()
        .take(opts.refine.starts)
        .map(|(_, s)| s)
        .collect())
}

/// The trace as the core sees it for a grid value `g` of structure `s`: the reference delayed
/// or filtered (the model's own exact scheme), or the position freed of the extra pole.
fn shaped_trace(trace: &Trace, s: ModelStructure, g: &[f64]) -> Result<Trace, Error> {
    let zero = ClosedLoopModel {
        a1: 0.0,
        a2: 0.0,
        a3: 0.0,
        b0: 1.0,
        b1: 0.0,
        b2: 0.0,
        dc: 0.0,
    };
    // Driven by the hold of the positions, whose acceleration impulses integrate back to the
    // positions exactly.
    let mut shaper = DriveModel {
        input: ReferenceInput::Hold,
        ..DriveModel::from(zero)
    };
    match s {
        ModelStructure::Delay => shaper.delay_s = g[0],
        ModelStructure::FirstOrderFilter => {
            shaper.reference_filter = Some(ReferenceFilter::FirstOrder { tau_s: g[0].exp() })
        }
        ModelStructure::SecondOrderFilter => {
            shaper.reference_filter = Some(ReferenceFilter::SecondOrder {
                wn_hz: g[0].exp(),
                zeta: g[1],
            })
        }
        ModelStructure::ExtraPole => {
            let p = std::f64::consts::TAU * g[0].exp();
            let n = trace.len();
            let mut xc = trace.x.clone();
            for (k, v) in xc.iter_mut().enumerate().take(n - 1).skip(1) {
                *v = trace.x[k] + (trace.x[k + 1] - trace.x[k - 1]) / (2.0 * trace.ts * p);
            }
            return Trace::new(trace.ts, trace.xr.clone(), xc);
        }
        ModelStructure::Paper | ModelStructure::NoIntegral => return Ok(trace.clone()),
    }
    let (pos, _, _, prefixed) = trace.prefixed_reference();
    let mut xr = shaper.simulate_positions(&pos, trace.ts, &SimOptions::default())?;
    if prefixed {
        xr.remove(0);
    }
    Trace::new(trace.ts, xr, trace.x.clone())
}

fn assemble(
    trace: &Trace,
    main: Swarm,
    fits: Vec<StructureFit>,
    validation: ValidationSource,
    chosen: Option<Candidate>,
    _opts: &IdentifyOptions,
) -> Result<Identification, Error> {
    let chosen = chosen.unwrap_or(Candidate {
        structure: ModelStructure::Paper,
        input: fits.first().map_or(ReferenceInput::Smooth, |f| f.input),
    });
    let paper = whole_fit(&fits, ModelStructure::Paper, chosen.input)
        .cloned()
        .ok_or(Error::RefinementFailed {
            structure: ModelStructure::Paper,
        })?;
    let sel = whole_fit(&fits, chosen.structure, chosen.input)
        .cloned()
        .unwrap_or_else(|| paper.clone());
    let fit_estimation_paper = fit_metrics_with(&main.paper_pso, trace, &main.regs)?;
    let refined = !paper.refinement.stages.is_empty();
    Ok(Identification {
        identified: paper.model.core,
        identified_poles: paper.poles,
        identified_model: paper.model,
        model: sel.model,
        structure: sel.structure,
        input: sel.input,
        uncertainty: sel.refinement.uncertainty.clone(),
        on_bounds: sel.refinement.on_bounds.clone(),
        validation,
        paper_pso: main.paper_pso,
        paper_pso_poles: main.paper_pso_poles,
        unconstrained_ls: main.baseline,
        pso_history: main.result.history,
        pso_cost: main.result.best_cost,
        refinement: refined.then(|| paper.refinement.clone()),
        condition_number: main.condition_number,
        condition_phi2: main.condition_phi2,
        moving_start: main.regs.intercept,
        fit_estimation: paper.estimation.clone(),
        fit_estimation_paper,
        structures: fits,
    })
}

/// The model of the swarm's poles: $a_i$ exactly from the poles (not via $\alpha_i a_2$, which
/// would round), $b_i$ and $d_c$ de-normalised by $a_2$ (paper eq. 8).
fn from_poles_and_theta(poles: &Poles, theta: &Theta) -> ClosedLoopModel {
    let a2 = poles.denominator().1;
    ClosedLoopModel::from_poles(
        poles,
        theta.beta2 * a2,
        theta.beta1 * a2,
        theta.beta0 * a2,
        theta.delta * a2,
    )
}

#[cfg(test)]
mod tests {
    use super::{Entry, Verdict, choose_among};

    fn entry(parameters: usize, trusted: bool, rms: f64) -> Entry {
        Entry {
            parameters,
            trusted,
            rms,
        }
    }

    /// The rule of docs/identification.md, "Choosing a structure", with the default margins
    /// (5 % selection, 30 % for an untrusted candidate).
    fn choice(entries: &[Entry]) -> usize {
        choose_among(entries, 0.05, 0.3).0
    }

    #[test]
    fn the_lowest_trusted_error_wins_unless_a_simpler_one_is_within_the_margin() {
        assert_eq!(choice(&[entry(7, true, 1.0), entry(9, true, 0.9)]), 1);
        assert_eq!(choice(&[entry(7, true, 1.0), entry(9, true, 0.97)]), 0);
        assert_eq!(choice(&[entry(7, true, 1.03), entry(5, true, 1.0)]), 1);
        // A tie in parameters and error goes to the earlier candidate (the paper's first).
        assert_eq!(choice(&[entry(7, true, 1.0), entry(7, true, 1.0)]), 0);
    }

    #[test]
    fn an_untrusted_candidate_must_beat_the_best_trusted_error_by_the_margin() {
        assert_eq!(choice(&[entry(7, true, 1.0), entry(9, false, 0.69)]), 1);
        let (c, v) = choose_among(&[entry(7, true, 1.0), entry(9, false, 0.71)], 0.05, 0.3);
        assert_eq!(c, 0);
        assert_eq!(
            v[1],
            Verdict::Degenerate {
                rms: 0.71,
                trusted_rms: 1.0,
                margin: 0.3
            }
        );
    }

    /// Before this rule compared with the trusted choice's error: a simpler trusted candidate
    /// within the selection margin (1.04, kept for its 5 parameters) raised the bar to
    /// 0.7 × 1.04 = 0.728, and the untrusted 0.72 was chosen — only because a worse trusted
    /// candidate had been added.
    #[test]
    fn adding_a_trusted_candidate_never_turns_the_choice_to_an_untrusted_one() {
        let base = [entry(7, true, 1.0), entry(9, false, 0.72)];
        assert_eq!(choice(&base), 0);
        let more = [
            entry(7, true, 1.0),
            entry(9, false, 0.72),
            entry(5, true, 1.04),
        ];
        assert_eq!(choice(&more), 2);
    }

    #[test]
    fn with_none_trusted_the_margin_rule_runs_over_all() {
        let (c, v) = choose_among(&[entry(9, false, 1.0), entry(7, false, 1.02)], 0.05, 0.3);
        assert_eq!(c, 1);
        assert!(matches!(v[0], Verdict::Simpler { .. }), "{:?}", v[0]);
    }
}
