//! Feed planning with identified models (docs/compensation.md#feed-planning): per-block feeds,
//! never above the programmed ones, that keep the predicted tool-tip contour error within a
//! tolerance with as short a cycle time as the scheme finds; and, for comparison, the single
//! uniform feed scale that meets the same tolerance.
//!
//! ```text
//!   program text ──prepare──▶ original Run (its tool path: the reference of every contour error)
//!        │
//!        │  factors s_b ∈ [s_min, 1] per feed line, F_b = s_b F_b,programmed (explicit F words)
//!        ▼
//!   rewritten text ──prepare──▶ Run ──models──▶ contour errors e_k vs the ORIGINAL path
//!        │                                          │  charged to the lines that ran in the
//!        │                                          ▼  preceding lag window: E_b = max e_k
//!        └──────────── s_b ← clamp(s_b · θ ε / E_b) ◀┘  (error ∝ feed, to first order)
//! ```
//!
//! **Why multiplicative.** At a feed well inside the limits a drive's contour error is, to
//! first order, proportional to the speed: the tip follows the path with each axis lagging by
//! its own time constant, and the normal component of the lag mismatch scales with the
//! velocity (docs/compensation.md#feed-planning; on the NMV5000 spiral the measured error is
//! linear in the feed to 0.1 %). With $E_b$ the largest predicted error charged to line $b$,
//! the update
//! $$ s_b \leftarrow \operatorname{clamp}\Big(s_b\,\frac{\theta\,\varepsilon}{E_b},\ \tfrac12 s_b,\ 2 s_b\Big) \wedge 1 $$
//! ($\varepsilon$ the tolerance, $\theta < 1$ a margin) slows the lines that exceed the
//! tolerance and speeds up those with room, each towards the feed at which its own error would
//! just meet $\theta\varepsilon$. A sample's error is charged to every line that ran within the
//! *lag window* before it (three time constants of the slowest model pole), since the error
//! builds up over the drives' settling. The plan with the shortest cycle time whose predicted
//! maximum is within $\varepsilon$ is kept; if none is found, the last plan is scaled down
//! uniformly (bisection) until it is.
//!
//! **Uniform baseline.** The largest single factor $u$ (every `G94` feed times $u$) whose
//! predicted maximum is within $\varepsilon$, by bisection on $\log u$.
//!
//! Every evaluation goes through the program text (the F words as written, rounded down to
//! 10⁻⁴), the interpolator and the models, so what is predicted is what the file will run.

use std::collections::BTreeMap;

use serde::Serialize;
use vcnc_drive::DriveModel;
use vcnc_gcode::write::LineFeed;
use vcnc_gcode::{Feed, MoveKind};
use vcnc_machine::{Machine, MachineModels};

use crate::Error;
use crate::compensate::{ContourStats, Judged, feed_samples, with_models};
use crate::run::{Run, prepare};

/// Settings of [`plan_feeds`]. Plain data; [`FeedPlanOptions::new`] gives the documented
/// defaults for a tolerance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FeedPlanOptions {
    /// Tool-tip contour-error tolerance, mm.
    pub tolerance_mm: f64,
    /// The plan aims at this fraction $\theta$ of the tolerance. Default 0.97.
    pub target_fraction: f64,
    /// Most planning iterations. Default 40.
    pub max_iterations: usize,
    /// Bisection steps of the uniform factor (and of a final scale-down). Default 24.
    pub bisection_steps: usize,
    /// Smallest feed factor. Default 10⁻³.
    pub min_factor: f64,
    /// Lag window, s; `None` (default): three time constants of the slowest model pole.
    pub lag_s: Option<f64>,
    /// Orientation contour-error tolerance, rad; `None` (default): the orientation is not
    /// constrained.
    pub orientation_tolerance_rad: Option<f64>,
    /// Largest ratio of the factors of two consecutive feed lines, $1 + g$ (≥ 1). Default 1.2:
    /// without it a line whose own error is small would run much faster than its neighbours,
    /// a spike of acceleration and of orientation error.
    pub max_step_ratio: f64,
}

impl FeedPlanOptions {
    /// Largest predicted error over its tolerance (tip, and orientation when constrained).
    fn excess(&self, p: &PlannedProgram) -> f64 {
        self.excess_series(p).into_iter().fold(0.0f64, f64::max)
    }

    /// Per sample: the larger of the tip and (when constrained) orientation errors over their
    /// tolerances.
    fn excess_series(&self, p: &PlannedProgram) -> Vec<f64> {
        let tip = p
            .predicted
            .tip_mm
            .iter()
            .map(|e| e.abs() / self.tolerance_mm);
        let e: Vec<f64> = match self.orientation_tolerance_rad {
            Some(o) => tip
                .zip(&p.predicted.orientation_rad)
                .map(|(t, r)| t.max(r.abs() / o))
                .collect(),
            None => tip.collect(),
        };
        e.into_iter()
            .zip(&p.feed)
            .map(|(e, f)| if *f { e } else { 0.0 })
            .collect()
    }

    /// The defaults for a tolerance in mm.
    pub fn new(tolerance_mm: f64) -> FeedPlanOptions {
        FeedPlanOptions {
            tolerance_mm,
            target_fraction: 0.97,
            max_iterations: 40,
            bisection_steps: 24,
            min_factor: 1e-3,
            lag_s: None,
            orientation_tolerance_rad: None,
            max_step_ratio: 1.2,
        }
    }

    fn check(&self) -> Result<(), Error> {
        let bad = |what: &'static str, value: f64| {
            Err(Error::FeedPlanOption {
                what,
                value,
                expected: "positive and finite",
            })
        };
        if !(self.tolerance_mm.is_finite() && self.tolerance_mm > 0.0) {
            return bad("the tolerance", self.tolerance_mm);
        }
        if !(self.target_fraction > 0.0 && self.target_fraction <= 1.0) {
            return Err(Error::FeedPlanOption {
                what: "the target fraction",
                value: self.target_fraction,
                expected: "in (0, 1]",
            });
        }
        if !(self.min_factor > 0.0 && self.min_factor < 1.0) {
            return Err(Error::FeedPlanOption {
                what: "the smallest feed factor",
                value: self.min_factor,
                expected: "in (0, 1)",
            });
        }
        if !(self.max_step_ratio >= 1.0 && self.max_step_ratio.is_finite()) {
            return Err(Error::FeedPlanOption {
                what: "the largest factor ratio of neighbouring lines",
                value: self.max_step_ratio,
                expected: "at least 1 and finite",
            });
        }
        if let Some(o) = self.orientation_tolerance_rad
            && !(o.is_finite() && o > 0.0)
        {
            return bad("the orientation tolerance", o);
        }
        if let Some(l) = self.lag_s
            && !(l.is_finite() && l >= 0.0)
        {
            return bad("the lag window", l);
        }
        Ok(())
    }
}

/// A feed line of the program: a line whose moves are `G94` feed moves.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlannedLine {
    /// Source line (1-based).
    pub line: u32,
    /// The line's F is an inverse time (`G93`, 1/min).
    pub inverse_time: bool,
    /// Programmed feed of the line's (first) move, in the program's units per minute or its
    /// inverse time (as an F word would write it).
    pub programmed_f: f64,
    /// Planned feed, same unit (rounded down to 10⁻⁴).
    pub planned_f: f64,
    /// `planned_f / programmed_f` (dimensionless, ≤ 1).
    pub factor: f64,
    /// Largest predicted contour error charged to the line in the final plan, µm.
    pub predicted_max_um: f64,
}

/// One evaluation of a plan.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlanStep {
    /// Predicted largest contour error, µm.
    pub predicted_max_um: f64,
    /// Cycle time, s.
    pub cycle_time_s: f64,
}

/// A program with planned feeds and the prediction it was planned with.
#[derive(Debug, Clone)]
pub struct PlannedProgram {
    /// The program text with the planned F words.
    pub text: String,
    /// The program prepared on the machine.
    pub run: Run,
    /// The models' contour errors against the original path.
    pub predicted: vcnc_contour::ContourReport,
    /// Per sample of `predicted`: whether its foot lies on a feed move of the original (only
    /// those are held to the tolerance; rapids are not cut).
    pub feed: Vec<bool>,
}

impl PlannedProgram {
    /// Cycle time, s.
    pub fn cycle_time_s(&self) -> f64 {
        self.run.duration_s()
    }
}

/// The result of [`plan_feeds`].
#[derive(Debug, Clone)]
pub struct FeedPlan {
    /// The original program prepared on the machine (its path is the reference).
    pub original: Run,
    /// The models' contour errors on the original program.
    pub original_predicted: vcnc_contour::ContourReport,
    /// Per-line feeds.
    pub plan: PlannedProgram,
    /// Every feed line with its planned feed, in line order.
    pub lines: Vec<PlannedLine>,
    /// Every evaluation of the per-line plan, in order.
    pub history: Vec<PlanStep>,
    /// The uniform factor that meets the tolerance.
    pub uniform_factor: f64,
    /// The program with every feed times the uniform factor.
    pub uniform: PlannedProgram,
    /// Lag window used, s.
    pub lag_s: f64,
}

/// The feed lines of a prepared program: line → its (first) move's feed, per minute or in
/// inverse time.
fn feed_lines(run: &Run) -> BTreeMap<u32, LineFeed> {
    let mut out = BTreeMap::new();
    for m in &run.loaded.toolpath.moves {
        if !matches!(m.kind, MoveKind::Linear | MoveKind::Arc(_)) {
            continue;
        }
        let feed = match m.feed {
            Some(Feed::UnitsPerMin(feed)) => LineFeed::PerMinute {
                feed,
                pure_rotary: matches!(m.kind, MoveKind::Linear) && m.start[..3] == m.end[..3],
            },
            Some(Feed::InverseTime(f)) => LineFeed::InverseTime(f),
            None => continue,
        };
        out.entry(m.line).or_insert(feed);
    }
    out
}

/// The evaluation context: machine, models, original run and program.
struct Planner<'a> {
    machine: &'a Machine,
    models: &'a MachineModels,
    src: &'a str,
    file: &'a str,
    lenient: bool,
    original: &'a Run,
    lines: BTreeMap<u32, LineFeed>,
}

impl Planner<'_> {
    /// The program with these factors, prepared and predicted.
    fn evaluate(&self, factors: &BTreeMap<u32, f64>) -> Result<PlannedProgram, Error> {
        let (text, _) = vcnc_gcode::write::with_feed_factors(
            self.src,
            &self.original.loaded.program,
            &self.lines,
            factors,
        );
        let run = prepare(self.machine, &text, self.file, self.lenient)?;
        let predicted = with_models(self.machine, self.original, &run, self.models)?;
        let feed = feed_samples(self.original, &predicted);
        Ok(PlannedProgram {
            text,
            run,
            predicted,
            feed,
        })
    }

    fn uniform(&self, u: f64) -> BTreeMap<u32, f64> {
        self.lines.keys().map(|l| (*l, u)).collect()
    }
}

/// Largest error over its tolerance charged to each feed line: the samples of its spans and
/// the lag window after them (module documentation).
fn charged(p: &PlannedProgram, lag: usize, opts: &FeedPlanOptions) -> BTreeMap<u32, f64> {
    let e = &opts.excess_series(p);
    let n = e.len();
    // m[k] = max e[k ..= k + lag]
    let m: Vec<f64> = (0..n)
        .map(|k| {
            e[k..(k + lag + 1).min(n)]
                .iter()
                .fold(0.0f64, |a, b| a.max(*b))
        })
        .collect();
    let mut out: BTreeMap<u32, f64> = BTreeMap::new();
    let traj = &p.run.loaded.trajectory;
    for b in &traj.blocks {
        let (lo, hi) = (b.first_sample.min(n), b.end_sample.min(n));
        let worst = if lo < hi {
            m[lo..hi].iter().fold(0.0f64, |a, b| a.max(*b))
        } else {
            m.get(lo.min(n.saturating_sub(1))).copied().unwrap_or(0.0)
        };
        let v = out.entry(b.line).or_insert(0.0);
        *v = v.max(worst);
    }
    out
}

/// Plans per-line feeds for `src` (the program at `file`) on `machine` with `models` (one per
/// machine axis), and the uniform baseline (module documentation). The contour errors are the
/// physical axes': each model's positions advanced by its stated actual-value latency
/// ([`crate::latency`]).
pub fn plan_feeds(
    machine: &Machine,
    src: &str,
    file: &str,
    models: &MachineModels,
    opts: &FeedPlanOptions,
    lenient: bool,
) -> Result<FeedPlan, Error> {
    opts.check()?;
    let original = prepare(machine, src, file, lenient)?;
    let lines = feed_lines(&original);
    if lines.is_empty() {
        return Err(Error::NothingToPlan {
            file: file.to_string(),
        });
    }
    let original_predicted = with_models(machine, &original, &original, models)?;
    let lag_s = opts.lag_s.unwrap_or_else(|| lag_window(models.models()));
    let lag = (lag_s / original.ts).round() as usize;
    let planner = Planner {
        machine,
        models,
        src,
        file,
        lenient,
        original: &original,
        lines,
    };
    let feasible = |p: &PlannedProgram| opts.excess(p) <= 1.0;

    // Uniform baseline: bisection on log u.
    let (uniform_factor, uniform) = bisect(&planner, opts, |u| planner.uniform(u))?;

    // Per-line plan: multiplicative updates from the programmed feeds.
    let mut factors = planner.uniform(1.0);
    let mut history = Vec::new();
    let mut best: Option<(BTreeMap<u32, f64>, PlannedProgram)> = None;
    for _ in 0..opts.max_iterations {
        let p = planner.evaluate(&factors)?;
        history.push(PlanStep {
            predicted_max_um: p.predicted.tip_max_mm * 1e3,
            cycle_time_s: p.cycle_time_s(),
        });
        if feasible(&p)
            && best
                .as_ref()
                .is_none_or(|b| p.cycle_time_s() < b.1.cycle_time_s())
        {
            best = Some((factors.clone(), p.clone()));
        }
        let e = charged(&p, lag, opts);
        let before = factors.clone();
        for (line, s) in factors.iter_mut() {
            let err = e.get(line).copied().unwrap_or(0.0);
            let ratio = if err > 0.0 {
                opts.target_fraction / err
            } else {
                2.0
            };
            *s = (*s * ratio.clamp(0.5, 2.0)).clamp(opts.min_factor, 1.0);
        }
        limit_steps(&mut factors, opts.max_step_ratio);
        let changed = factors
            .iter()
            .zip(before.values())
            .any(|((_, a), b)| (a / b - 1.0).abs() > 0.005);
        if !changed && feasible(&p) {
            break;
        }
    }
    let (factors, plan) = match best {
        Some(b) => b,
        None => {
            // Scale the last plan down until it meets the tolerance.
            let base = factors.clone();
            let (u, p) = bisect(&planner, opts, |u| {
                base.iter()
                    .map(|(l, s)| (*l, (s * u).max(opts.min_factor)))
                    .collect()
            })?;
            let scaled = base
                .iter()
                .map(|(l, s)| (*l, (s * u).max(opts.min_factor)))
                .collect();
            (scaled, p)
        }
    };
    let programmed = vcnc_gcode::write::programmed_feeds(&original.loaded.program, &planner.lines);
    let (_, written) = vcnc_gcode::write::with_feed_factors(
        src,
        &original.loaded.program,
        &planner.lines,
        &factors,
    );
    let charged_final = charged(&plan, lag, opts);
    let lines = programmed
        .iter()
        .map(|(line, f)| {
            let planned = written.get(line).copied().unwrap_or(*f);
            PlannedLine {
                line: *line,
                inverse_time: matches!(planner.lines.get(line), Some(LineFeed::InverseTime(_))),
                programmed_f: *f,
                planned_f: planned,
                factor: planned / f,
                predicted_max_um: charged_final.get(line).copied().unwrap_or(0.0)
                    * opts.tolerance_mm
                    * 1e3,
            }
        })
        .collect();
    Ok(FeedPlan {
        original_predicted,
        original,
        plan,
        lines,
        history,
        uniform_factor,
        uniform,
        lag_s,
    })
}

/// Lowers factors so that no two consecutive lines differ by more than `ratio` (a forward and
/// a backward pass: the result is the largest such profile below the input).
fn limit_steps(factors: &mut BTreeMap<u32, f64>, ratio: f64) {
    let mut v: Vec<f64> = factors.values().copied().collect();
    for i in 1..v.len() {
        v[i] = v[i].min(v[i - 1] * ratio);
    }
    for i in (0..v.len().saturating_sub(1)).rev() {
        v[i] = v[i].min(v[i + 1] * ratio);
    }
    for (s, n) in factors.values_mut().zip(v) {
        *s = n;
    }
}

/// The largest factor `u` in `[min_factor, 1]` whose program `factors(u)` meets the tolerance:
/// a first guess from the error's proportionality to the feed, stepped down until it meets the
/// tolerance, then bisection on `log u` between it and the last factor that did not; an error
/// when even `min_factor` does not.
fn bisect(
    planner: &Planner,
    opts: &FeedPlanOptions,
    factors: impl Fn(f64) -> BTreeMap<u32, f64>,
) -> Result<(f64, PlannedProgram), Error> {
    let mut hi = 1.0f64;
    let mut p = planner.evaluate(&factors(hi))?;
    if opts.excess(&p) <= 1.0 {
        return Ok((1.0, p));
    }
    let mut u = hi;
    loop {
        let step = (0.95 / opts.excess(&p)).clamp(0.05, 0.5);
        let next = (u * step).max(opts.min_factor);
        if next == u {
            return Err(Error::ToleranceUnreachable {
                min_factor: opts.min_factor,
                tip_um: p.predicted.tip_max_mm * 1e3,
                orientation_mrad: p.predicted.orientation_max_rad * 1e3,
                excess: opts.excess(&p),
            });
        }
        hi = u;
        u = next;
        p = planner.evaluate(&factors(u))?;
        if opts.excess(&p) <= 1.0 {
            break;
        }
    }
    let (mut lo, mut up) = (u.ln(), hi.ln());
    let mut good = (u, p);
    for _ in 0..opts.bisection_steps {
        let mid = 0.5 * (lo + up);
        let p = planner.evaluate(&factors(mid.exp()))?;
        if opts.excess(&p) <= 1.0 {
            lo = mid;
            good = (mid.exp(), p);
        } else {
            up = mid;
        }
    }
    Ok(good)
}

/// Three time constants of the slowest pole of any model plus its dead time, s (at least
/// 10 ms).
pub fn lag_window(models: &[DriveModel]) -> f64 {
    let delay = models.iter().map(|m| m.delay_s).fold(0.0f64, f64::max);
    let slowest = models
        .iter()
        .filter_map(|m| m.slowest_decay_rate(1e-9))
        .min_by(f64::total_cmp);
    match slowest {
        Some(r) => (3.0 / r + delay).clamp(0.01, 1.0),
        None => 0.05 + delay,
    }
}

/// One program's figures in `summary.json` of `vcnc feed-plan`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlanFigures {
    /// Cycle time, s.
    pub cycle_time_s: f64,
    /// The models' contour statistics against the original path.
    pub predicted: ContourStats,
    /// The true machine's contour statistics against the original path.
    pub true_machine: ContourStats,
}

/// `summary.json` of `vcnc feed-plan`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FeedPlanSummary {
    /// Machine name.
    pub machine: String,
    /// The original program.
    pub program: String,
    /// The model file.
    pub models: String,
    /// The planned program written.
    pub planned_program: String,
    /// Options of the plan.
    pub options: FeedPlanOptions,
    /// Lag window used, s.
    pub lag_s: f64,
    /// Tolerance, µm.
    pub tolerance_um: f64,
    /// The original program.
    pub original: PlanFigures,
    /// Per-line feeds.
    pub planned: PlanFigures,
    /// Every feed times [`FeedPlanSummary::uniform_factor`].
    pub uniform: PlanFigures,
    /// The uniform factor.
    pub uniform_factor: f64,
    /// `1 − planned / uniform` cycle time (the saving of per-line feeds), dimensionless.
    pub saving_vs_uniform: f64,
    /// Feed lines, and how many were slowed.
    pub lines: usize,
    /// Lines with a factor below 1.
    pub lines_slowed: usize,
    /// Smallest factor of any line.
    pub min_factor: f64,
    /// Evaluations of the per-line plan.
    pub history: Vec<PlanStep>,
}

/// A feed plan judged on the true machine (`vcnc feed-plan`): the original program, the
/// per-line plan and the uniform scale, each run through the true drives and measured against
/// the ORIGINAL program's path.
#[derive(Debug, Clone)]
pub struct JudgedPlan {
    /// The plan.
    pub plan: FeedPlan,
    /// The original program on the true machine.
    pub original: Judged,
    /// The per-line feeds on the true machine.
    pub planned: Judged,
    /// The uniform feed scale on the true machine.
    pub uniform: Judged,
    /// `summary.json` (`planned_program`: where the plan is written).
    pub summary: FeedPlanSummary,
}

/// [`plan_feeds`] for the program at `program`, then each program judged on the true machine
/// ([`JudgedPlan`]); `planned_program` names where the plan will be written.
pub fn plan_and_judge(
    machine: &Machine,
    program: &std::path::Path,
    models: &MachineModels,
    opts: &FeedPlanOptions,
    planned_program: &str,
    lenient: bool,
) -> Result<JudgedPlan, Error> {
    let src = crate::run::read_program(program)?;
    let file = program.display().to_string();
    let plan = plan_feeds(machine, &src, &file, models, opts, lenient)?;
    let judge = |run: &Run| crate::compensate::on_true_machine(machine, &plan.original, run);
    let (original, planned, uniform) = (
        judge(&plan.original)?,
        judge(&plan.plan.run)?,
        judge(&plan.uniform.run)?,
    );
    let figures = |p: &vcnc_contour::ContourReport, j: &Judged| -> Result<PlanFigures, Error> {
        Ok(PlanFigures {
            cycle_time_s: j.cycle_time_s,
            predicted: ContourStats::over_feed(&plan.original, p),
            true_machine: ContourStats::over_feed(&plan.original, j.contour(machine)?),
        })
    };
    let summary = FeedPlanSummary {
        machine: machine.name.clone(),
        program: file,
        models: models.source().to_string(),
        planned_program: planned_program.to_string(),
        options: *opts,
        lag_s: plan.lag_s,
        tolerance_um: opts.tolerance_mm * 1e3,
        original: figures(&plan.original_predicted, &original)?,
        planned: figures(&plan.plan.predicted, &planned)?,
        uniform: figures(&plan.uniform.predicted, &uniform)?,
        uniform_factor: plan.uniform_factor,
        saving_vs_uniform: 1.0 - planned.cycle_time_s / uniform.cycle_time_s,
        lines: plan.lines.len(),
        lines_slowed: plan.lines.iter().filter(|l| l.factor < 1.0).count(),
        min_factor: plan.lines.iter().map(|l| l.factor).fold(1.0, f64::min),
        history: plan.history.clone(),
    };
    Ok(JudgedPlan {
        plan,
        original,
        planned,
        uniform,
        summary,
    })
}
