//! The identification pipeline: regressors → PSO (paper) → output-error refinement from the
//! swarm's distinct good particles, for the paper's structure and any extended one, the
//! structure chosen by validation error; the unconstrained least-squares baseline beside it
//! (docs/identification.md).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use vcnc_drive::{ClosedLoopModel, DriveModel, Poles, ReferenceFilter, SimOptions};

use crate::Error;
use crate::metrics::{FitMetrics, fit_metrics_with, score};
use crate::options::{IdentifyOptions, ModelStructure};
use crate::pso::{HistoryEntry, Pso, PsoResult};
use crate::refine::{BoundHit, RefineResult, RefineSetup, Start, Uncertainty, refine};
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

/// Where the validation figures of the structures come from.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum ValidationSource {
    /// One structure only: nothing to choose, no validation.
    None,
    /// A separate validation trace ([`identify_with_validation`]).
    Trace,
    /// The end of the single trace, held out of the fit: samples `first..` (0-based).
    HeldOut {
        /// First held-out sample.
        first: usize,
        /// Number of held-out samples.
        samples: usize,
    },
}

/// One model structure as identified.
#[derive(Debug, Clone, PartialEq)]
pub struct StructureFit {
    /// The structure.
    pub structure: ModelStructure,
    /// Its refined model (fitted on the whole estimation trace).
    pub model: DriveModel,
    /// Poles of the model's core.
    pub poles: Poles,
    /// The refinement's details: costs, stages, parameters on bounds, uncertainty.
    pub refinement: RefineResult,
    /// Fit on the estimation trace.
    pub estimation: FitMetrics,
    /// Validation error that chose the structure: on the held-out samples (from the fit on the
    /// rest of the trace) or on the separate validation trace. `None` when nothing was chosen.
    pub validation: Option<FitMetrics>,
}

/// Everything [`identify`] found: the chosen model, the paper's PSO result and the baseline side
/// by side, the swarm history and the fit on the estimation run.
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// The paper's 7-parameter model, refined by output error (or the PSO result when the
    /// refinement is off). Always inside the pole bounds, hence stable.
    pub identified: ClosedLoopModel,
    /// Poles of `identified`.
    pub identified_poles: Poles,
    /// The model of the structure chosen by validation error (the paper's when only it was
    /// asked for): what a model file should hold.
    pub model: DriveModel,
    /// The chosen structure.
    pub structure: ModelStructure,
    /// Every structure identified, the paper's first.
    pub structures: Vec<StructureFit>,
    /// Where the validation figures come from.
    pub validation: ValidationSource,
    /// Standard deviations of the chosen model's parameters.
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
        let same = |o: &Start| {
            let (a, b) = (o.core, st.core);
            [(a.0, b.0), (a.1, b.1), (a.2, b.2)]
                .iter()
                .all(|(x, y)| (x - y).abs() <= 0.05 * x.abs().max(y.abs()))
        };
        if !out.iter().any(same) {
            out.push(st);
        }
    }
    out
}

/// Identifies the closed-loop model of one axis from `trace` (docs/identification.md).
///
/// Steps: validate the options; build the prefiltered regressors and their Gram matrix (one
/// O(N) pass); reject data that cannot identify the model (condition number above
/// `opts.max_condition`); unconstrained LS baseline; paper PSO over the poles with the
/// least-squares subproblem, seeded with `opts.seed`; output-error refinement from the swarm's
/// distinct good particles (when `opts.refine.enabled`); fit metrics on the trace.
///
/// With `opts.structures` beyond the paper's, each structure is identified the same way and
/// the one with the lowest validation error is chosen: the last `opts.holdout_fraction` of the
/// trace is held out (the structures are fitted on the rest; each model runs free through the
/// whole trace and is scored on the held-out samples only); then the chosen structure and the
/// paper's are refitted on the whole trace. Held out at the end, and contiguous: a free run
/// needs the initial state, which is known only at the trace's start, and the residuals of
/// neighbouring samples are strongly correlated, so scattered held-out samples would be
/// predicted from their fitted neighbours' errors rather than from the model. When the end of
/// the trace hardly moves (less than a tenth of the reference's path), the start is held out
/// instead (fit on the rest, scored on the start).
pub fn identify(trace: &Trace, opts: &IdentifyOptions) -> Result<Identification, Error> {
    opts.validate()?;
    let structures = structure_list(opts);
    let main = swarm(trace, opts)?;
    if structures.len() == 1 || !opts.refine.enabled {
        let fits = fit_structures(trace, &main, &structures[..1], opts, None)?;
        return assemble(trace, main, fits, ValidationSource::None, None);
    }
    let n = trace.len();
    let split = n - ((n as f64 * opts.holdout_fraction) as usize).max(1);
    let path = |a: usize, b: usize| -> f64 {
        trace.xr[a..b].windows(2).map(|w| (w[1] - w[0]).abs()).sum()
    };
    let hold_end = path(split, n) >= 0.1 * path(0, n);
    let (fit_range, hold) = if hold_end {
        (0..split, split..n)
    } else {
        let k = n - split;
        (k..n, 0..k)
    };
    let part = Trace::new(
        trace.ts,
        trace.xr[fit_range.clone()].to_vec(),
        trace.x[fit_range.clone()].to_vec(),
    )?;
    let part = match &trace.reference_derivatives {
        Some((v, a)) => part.with_reference_derivatives(
            v[fit_range.clone()].to_vec(),
            a[fit_range.clone()].to_vec(),
        )?,
        None => part,
    };
    let part_swarm = swarm(&part, opts)?;
    let part_fits = fit_structures(&part, &part_swarm, &structures, opts, None)?;
    // Validation: each model (fitted on the part) runs free through the whole trace; the
    // held-out samples score it. Fitted on the end, it must run through the start too: its
    // free run from rest at the start is all it knows.
    let validations: Vec<FitMetrics> = part_fits
        .iter()
        .map(|f| score(&f.model, trace, Some(hold.clone()), opts))
        .collect::<Result<_, _>>()?;
    let chosen = choose(&part_fits, &validations, opts.selection_margin);
    // Refit the paper's structure and the chosen one on the whole trace, from their part fits.
    let mut refit: Vec<ModelStructure> = vec![ModelStructure::Paper];
    if structures[chosen] != ModelStructure::Paper {
        refit.push(structures[chosen]);
    }
    let mut fits = fit_structures(trace, &main, &refit, opts, Some(&part_fits))?;
    // Report every structure: the refitted ones whole, the others as fitted on the part.
    for (i, f) in part_fits.into_iter().enumerate() {
        let v = validations[i].clone();
        match fits.iter_mut().find(|g| g.structure == f.structure) {
            Some(g) => g.validation = Some(v),
            None => fits.push(StructureFit {
                validation: Some(v),
                ..f
            }),
        }
    }
    let source = ValidationSource::HeldOut {
        first: hold.start,
        samples: hold.len(),
    };
    assemble(trace, main, fits, source, Some(structures[chosen]))
}

/// [`identify`] with a separate validation trace of the same axis (a simulated machine's
/// validation program, or a second recording): every structure is fitted on `trace` and
/// scored by its free run on `validation`; the lowest validation error chooses.
pub fn identify_with_validation(
    trace: &Trace,
    validation: &Trace,
    opts: &IdentifyOptions,
) -> Result<Identification, Error> {
    opts.validate()?;
    let structures = structure_list(opts);
    let main = swarm(trace, opts)?;
    let mut fits = fit_structures(trace, &main, &structures, opts, None)?;
    let validations: Vec<FitMetrics> = fits
        .iter()
        .map(|f| score(&f.model, validation, None, opts))
        .collect::<Result<_, _>>()?;
    let chosen = choose(&fits, &validations, opts.selection_margin);
    for (f, v) in fits.iter_mut().zip(validations) {
        f.validation = Some(v);
    }
    let s = structures[chosen];
    assemble(trace, main, fits, ValidationSource::Trace, Some(s))
}

/// The paper's structure first, then the others asked for, each once.
fn structure_list(opts: &IdentifyOptions) -> Vec<ModelStructure> {
    let mut out = vec![ModelStructure::Paper];
    for s in &opts.structures {
        if !out.contains(s) {
            out.push(*s);
        }
    }
    out
}

/// Index of the structure chosen by validation free-run RMS: the lowest, unless a structure
/// with fewer extra parameters comes within `margin` (relative) of it.
fn choose(fits: &[StructureFit], val: &[FitMetrics], margin: f64) -> usize {
    let best = val
        .iter()
        .map(|v| v.freerun_rms)
        .fold(f64::INFINITY, f64::min);
    let mut chosen = 0;
    let mut chosen_key = (usize::MAX, f64::INFINITY);
    for (i, (f, v)) in fits.iter().zip(val).enumerate() {
        if v.freerun_rms <= best * (1.0 + margin) {
            let key = (f.structure.extra_parameters(), v.freerun_rms);
            if key.0 < chosen_key.0 || (key.0 == chosen_key.0 && key.1 < chosen_key.1) {
                chosen = i;
                chosen_key = key;
            }
        }
    }
    chosen
}

/// Refines each structure on `trace`. Starts: the swarm's distinct particles (paper), a grid
/// of the extra parameter screened by the equation-error swarm (extended), plus the fits
/// `previous` of the same structure (a refit).
fn fit_structures(
    trace: &Trace,
    sw: &Swarm,
    structures: &[ModelStructure],
    opts: &IdentifyOptions,
    previous: Option<&[StructureFit]>,
) -> Result<Vec<StructureFit>, Error> {
    structures
        .iter()
        .map(|&s| {
            let mut starts = match previous.and_then(|p| p.iter().find(|f| f.structure == s)) {
                Some(f) => vec![start_of(&f.model, s)],
                None => vec![],
            };
            if s == ModelStructure::Paper {
                starts.extend(distinct_starts(
                    &sw.result.candidates,
                    opts.refine.starts,
                    &[],
                ));
            } else if previous.is_none() {
                starts.extend(extended_starts(trace, s, opts)?);
            }
            fit_one(trace, sw, s, &starts, opts)
        })
        .collect()
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

fn fit_one(
    trace: &Trace,
    sw: &Swarm,
    s: ModelStructure,
    starts: &[Start],
    opts: &IdentifyOptions,
) -> Result<StructureFit, Error> {
    let refinement = if opts.refine.enabled {
        refine(
            trace,
            &sw.regs,
            starts,
            RefineSetup {
                structure: s,
                bounds: &opts.bounds,
                extended: &opts.extended_bounds,
                opts: &opts.refine,
            },
        )?
    } else {
        // No refinement: the swarm's model as it is.
        let model = DriveModel::from(sw.paper_pso);
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
    let estimation = if model.is_core_only() {
        fit_metrics_with(&model.core, trace, &sw.regs)?
    } else {
        score(&model, trace, None, opts)?
    };
    Ok(StructureFit {
        structure: s,
        poles: refinement.poles,
        model,
        refinement,
        estimation,
        validation: None,
    })
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
        ModelStructure::Paper => return Ok(vec![]),
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
    let mut shaper = DriveModel::from(zero);
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
        ModelStructure::Paper => return Ok(trace.clone()),
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
    chosen: Option<ModelStructure>,
) -> Result<Identification, Error> {
    let paper = fits
        .iter()
        .find(|f| f.structure == ModelStructure::Paper)
        .cloned()
        .ok_or(Error::RefinementFailed {
            structure: ModelStructure::Paper,
        })?;
    let chosen = chosen.unwrap_or(ModelStructure::Paper);
    let sel = fits
        .iter()
        .find(|f| f.structure == chosen)
        .cloned()
        .unwrap_or_else(|| paper.clone());
    let fit_estimation_paper = fit_metrics_with(&main.paper_pso, trace, &main.regs)?;
    let refined = !paper.refinement.stages.is_empty();
    Ok(Identification {
        identified: paper.model.core,
        identified_poles: paper.poles,
        model: sel.model,
        structure: sel.structure,
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
