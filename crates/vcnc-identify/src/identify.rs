//! The identification pipeline: regressors → PSO (paper) → output-error refinement, with the
//! unconstrained least-squares baseline beside it (docs/identification.md).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use vcnc_drive::{ClosedLoopModel, Poles};

use crate::Error;
use crate::metrics::{FitMetrics, fit_metrics_with};
use crate::options::IdentifyOptions;
use crate::pso::{HistoryEntry, Pso};
use crate::refine::{RefineResult, refine};
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

/// Everything [`identify`] found: the final model, the paper's PSO result and the baseline side
/// by side, the swarm history and the fit on the estimation run.
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// Final model: the output-error refinement of the PSO result (or the PSO result when the
    /// refinement is off). Always inside the pole bounds, hence stable.
    pub identified: ClosedLoopModel,
    /// Poles of `identified`.
    pub identified_poles: Poles,
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
    /// The refinement's details (costs, iterations), when it ran.
    pub refinement: Option<RefineResult>,
    /// Condition number of the column-scaled regressors.
    pub condition_number: f64,
    /// Condition number of the column-scaled $\Phi_2$.
    pub condition_phi2: f64,
    /// Whether the trace was treated as starting in motion.
    pub moving_start: bool,
    /// Fit of `identified` on the estimation run.
    pub fit_estimation: FitMetrics,
    /// Fit of `paper_pso` on the estimation run.
    pub fit_estimation_paper: FitMetrics,
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

/// Identifies the closed-loop model of one axis from `trace` (docs/identification.md).
///
/// Steps: validate the options; build the prefiltered regressors and their Gram matrix (one
/// O(N) pass); reject data that cannot identify the model (condition number above
/// `opts.max_condition`); unconstrained LS baseline; paper PSO over the poles with the
/// least-squares subproblem, seeded with `opts.seed`; output-error refinement from the swarm's
/// best (when `opts.refine.enabled`); fit metrics on the trace.
pub fn identify(trace: &Trace, opts: &IdentifyOptions) -> Result<Identification, Error> {
    opts.validate()?;
    let regs = Regressors::build(trace, opts)?;
    let condition_number = regs.check_identifiable(opts.max_condition)?;
    let condition_phi2 = regs.condition_phi2();
    let baseline = unconstrained_ls(&regs)?;
    let cost = regs.equation_error_cost()?;
    let pso = Pso::new(opts.bounds.lower().to_vec(), opts.bounds.upper().to_vec())?
        .with_settings(opts.pso)?;
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let swarm = pso.run(&cost, &mut rng);
    let [p_hz, wn_hz, zeta] = match swarm.best[..] {
        [a, b, c] => [a, b, c],
        _ => opts.bounds.lower(),
    };
    let paper_pso_poles = Poles::from_hz(p_hz, wn_hz, zeta);
    let (theta, _) = cost.theta_hz(p_hz, wn_hz, zeta);
    let paper_pso = from_poles_and_theta(&paper_pso_poles, &theta);
    let refinement = if opts.refine.enabled {
        Some(refine(
            trace,
            &regs,
            &paper_pso,
            &paper_pso_poles,
            &opts.bounds,
            &opts.refine,
        )?)
    } else {
        None
    };
    let (identified, identified_poles) = match &refinement {
        Some(r) => (r.model, r.poles),
        None => (paper_pso, paper_pso_poles),
    };
    let fit_estimation = fit_metrics_with(&identified, trace, &regs)?;
    let fit_estimation_paper = fit_metrics_with(&paper_pso, trace, &regs)?;
    Ok(Identification {
        identified,
        identified_poles,
        paper_pso,
        paper_pso_poles,
        unconstrained_ls: baseline,
        pso_history: swarm.history,
        pso_cost: swarm.best_cost,
        refinement,
        condition_number,
        condition_phi2,
        moving_start: regs.intercept,
        fit_estimation,
        fit_estimation_paper,
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
