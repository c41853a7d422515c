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
//!   rewritten text ──streamed, a piece at a time──▶ models ──▶ contour errors e_k vs the
//!        │                                          │        ORIGINAL path, reduced on the fly:
//!        │                                          ▼        E_b = max e_j over the lag window
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
//! just meet $\theta\varepsilon$. A sample's error is charged to the line running at every
//! sample of the *lag window* before it (three time constants of the slowest model pole), since
//! the error builds up over the drives' settling: $E_b = \max e_j$ over $j \in [k, k + L]$ for
//! every sample $k$ of line $b$. (A line whose block is shorter than a sample period holds no
//! sample and is charged nothing; its factor then follows its neighbours' through the step
//! ratio limit.) The plan with the shortest cycle time whose predicted maximum is within
//! $\varepsilon$ is kept; if none is found, the last plan is scaled down uniformly (the search
//! below) until it is.
//!
//! **Uniform baseline.** The largest single factor $u$ (every feed times $u$) whose predicted
//! maximum is within $\varepsilon$: bracketed by steps down from 1 guessed from the
//! proportionality, then narrowed on $\log u$ to the precision of
//! [`FeedPlanOptions::bisection_steps`] bisection steps by a safeguarded secant on
//! $\log(\text{error})$ (`largest_feasible`). Where the error is proportional to the feed
//! the secant lands on the answer in a step or two; the predicted maximum can also jump with
//! the factor (on the spiral at 10 µm from 0.974 to 1.006 of the tolerance within 2·10⁻⁷ of
//! $u$: the samples and blends of the interpolated path change), and a jump can only be
//! bracketed, not interpolated, so there the search falls back to bisection.
//!
//! **Evaluations stream.** Every evaluation goes through the program text (the F words as
//! written, rounded down to 10⁻⁴), the interpolator and the models, so what is predicted is
//! what the file will run; factors that write the same text are evaluated once. The run is not
//! kept: the rewritten text is interpolated a piece at a time ([`crate::source`]), each piece
//! runs through the models' streams (`drives`), the forward kinematics and the
//! contour search along the original path, and each finished sample is reduced on the spot
//! ([`Evaluation`]: per-line charges by a running window maximum, the largest errors, the feed
//! samples' statistics, the cycle time). Held are the original's path and about a piece of
//! samples, whatever the tolerance; the errors are the whole run's bit for bit (test
//! `a_streamed_evaluation_is_the_whole_runs_bit_for_bit`). The three programs judged on the
//! true machine at the end stream the same way ([`measure`]), and keep for `feed_plan.svg` at
//! most [`FIGURE_POINTS`] points a series.
//!
//! **Cost** (`vcnc feed-plan` on the NMV5000 spiral, 2-core VM shared with other work): 200 µm
//! 0.82 s, 27 MB; 50 µm 1.96 s, 30 MB; 10 µm 15.4 s, 30 MB (before streaming, measured back
//! to back: 1.21 s 45 MB, 2.95 s 105 MB, 29.2 s 623 MB). At 10 µm the uniform search evaluates
//! 19 programs of about 850 000 samples (0.5–1 s each) to bracket the jump above to its
//! precision; the per-line plan's ten evaluations are shorter (about 190 000 samples).

use std::collections::{BTreeMap, HashMap, VecDeque};

use serde::Serialize;
use vcnc_contour::{ContourStream, SearchWindow, StreamLimits};
use vcnc_drive::DriveModel;
use vcnc_gcode::write::LineFeed;
use vcnc_gcode::{Feed, MoveKind};
use vcnc_kinematics::Pose;
use vcnc_machine::{Machine, MachineModels};

use crate::Error;
use crate::compensate::ContourStats;
use crate::drives::{ModelRuns, TrueDrives};
use crate::run::{Run, prepare};
use crate::source::{Program, ReferenceChunk, Source};
use crate::stats::MaxRms;

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
    /// The precision of the uniform factor (and of a final scale-down): the search stops when
    /// the largest factor known to meet the tolerance and the smallest known not to are
    /// closer, in $\log u$, than their first bracket divided by $2^{\text{bisection\_steps}}$
    /// (what as many bisection steps would reach). Default 24.
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
    /// A sample's error over its tolerance: the larger of the tip and (when constrained)
    /// orientation errors over their tolerances; 0 off the feed moves (only those are held to
    /// the tolerance: rapids are not cut).
    fn excess(&self, s: &Sample) -> f64 {
        if !s.feed {
            return 0.0;
        }
        let tip = s.tip_mm.abs() / self.tolerance_mm;
        match self.orientation_tolerance_rad {
            Some(o) => tip.max(s.orientation_rad.abs() / o),
            None => tip,
        }
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

/// A program with planned feeds and what the models predict of it.
#[derive(Debug, Clone)]
pub struct PlannedProgram {
    /// The program text with the planned F words.
    pub text: String,
    /// Per feed line, its factor.
    pub factors: BTreeMap<u32, f64>,
    /// The models' run of it against the original path.
    pub evaluation: Evaluation,
}

impl PlannedProgram {
    /// Cycle time, s.
    pub fn cycle_time_s(&self) -> f64 {
        self.evaluation.cycle_time_s
    }
}

/// What one run of a program measured against the original path keeps: the figures of
/// `summary.json` and of the plan, never a per-sample series (docs/compensation.md, "Feed
/// planning": an evaluation streams).
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Cycle time (the last sample's time), s.
    pub cycle_time_s: f64,
    /// Samples.
    pub samples: usize,
    /// Largest error over its tolerance of a feed sample (≤ 1: the plan meets the tolerance).
    pub excess: f64,
    /// Largest tool-tip contour error of any sample, mm.
    pub tip_max_mm: f64,
    /// Largest orientation contour error of any sample, rad.
    pub orientation_max_rad: f64,
    /// The contour statistics of the feed samples.
    pub feed: ContourStats,
    /// Per source line: the largest error over its tolerance charged to it (module
    /// documentation).
    pub charged: BTreeMap<u32, f64>,
}

/// The result of [`plan_feeds`].
#[derive(Debug, Clone)]
pub struct FeedPlan {
    /// The original program prepared on the machine (its path is the reference).
    pub original: Run,
    /// The models' run of the original program.
    pub original_predicted: Evaluation,
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
    /// Evaluations of programs made in all (the per-line plan's, the uniform search's, the
    /// original's).
    pub evaluations: usize,
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

/// The original program as the reference of every contour error: its run, its tool poses,
/// per sample whether it is cut (a feed move; every sample of a program without one), and the
/// arc length of its tool-tip path, mm.
pub struct OriginalPath<'a> {
    run: &'a Run,
    poses: Vec<Pose>,
    feed: Vec<bool>,
    arc_mm: Vec<f64>,
}

impl<'a> OriginalPath<'a> {
    /// The path of `run` on `machine` (an error without kinematics).
    pub fn new(machine: &Machine, run: &'a Run) -> Result<OriginalPath<'a>, Error> {
        let poses = run.reference_poses(machine)?;
        let mut feed = run.measured(crate::run::Measured::Feed);
        if !feed.iter().any(|f| *f) {
            feed.iter_mut().for_each(|f| *f = true);
        }
        let mut arc_mm = Vec::with_capacity(poses.len());
        let mut acc = 0.0;
        for (i, p) in poses.iter().enumerate() {
            if i > 0 {
                acc += (p.p - poses[i - 1].p).norm();
            }
            arc_mm.push(acc);
        }
        Ok(OriginalPath {
            run,
            poses,
            feed,
            arc_mm,
        })
    }

    /// Whether a foot at path parameter `u` lies on a feed move (the nearest sample's).
    fn cut(&self, u: f64) -> bool {
        let k = u.round().max(0.0) as usize;
        self.feed
            .get(k.min(self.feed.len().saturating_sub(1)))
            .copied()
            .unwrap_or(false)
    }

    /// Where a foot at path parameter `u` lies along the tool-tip path, mm.
    fn position_mm(&self, u: f64) -> f64 {
        let s = &self.arc_mm;
        if s.is_empty() {
            return 0.0;
        }
        let j = (u.floor().max(0.0) as usize).min(s.len() - 1);
        let next = s.get(j + 1).copied().unwrap_or(s[j]);
        s[j] + (u - j as f64) * (next - s[j])
    }
}

/// What moves the axes of a run measured against the original path.
#[derive(Debug, Clone, Copy)]
pub enum Axes<'a> {
    /// The identified models (the prediction a plan is made with): the physical axes, each
    /// model's positions advanced by its stated actual-value latency ([`crate::latency`]).
    Models(&'a MachineModels),
    /// The true machine (its drives, or the models it is made of).
    TrueMachine,
}

/// The axes' stages, fed a piece of the reference at a time.
enum Stages {
    Models(ModelRuns),
    True(TrueDrives),
}

/// One finished sample of a run measured against the original path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Index.
    pub k: usize,
    /// The source line of the block running (0 where none is).
    pub line: u32,
    /// Tool-tip contour error, mm.
    pub tip_mm: f64,
    /// Orientation contour error, rad.
    pub orientation_rad: f64,
    /// Its foot's path parameter on the original path.
    pub foot_u: f64,
    /// Its foot lies on a feed move of the original.
    pub feed: bool,
}

/// Runs the reference of `source` (any program: the original or one with other feeds) through
/// `axes`, the forward kinematics and the contour search along the ORIGINAL path, a piece at a
/// time, handing each reference piece to `on_reference` and each finished sample to
/// `on_sample` in order; returns the samples. Memory does not grow with the run: held are
/// the original's path and the samples between the newest reference sample and the oldest
/// unfinished one (the latency look-ahead). The errors are those of
/// [`crate::compensate::with_models`] and [`crate::compensate::on_true_machine`] on the
/// prepared run, bit for bit: the same drive streams, and the same search (the original
/// pushed whole, the first sample's global search over all of it: `vcnc_contour`'s
/// streamed-search conditions hold).
pub fn measure(
    machine: &Machine,
    original: &OriginalPath,
    source: Source<'_>,
    axes: Axes<'_>,
    on_reference: &mut dyn FnMut(&ReferenceChunk) -> Result<(), Error>,
    on_sample: &mut dyn FnMut(&Sample),
) -> Result<usize, Error> {
    let kin = machine.require_kinematics()?;
    let ts = source.ts();
    let mut stages = match axes {
        Axes::Models(m) => Stages::Models(ModelRuns::new(machine, &[m], ts, true)?),
        Axes::TrueMachine => Stages::True(TrueDrives::new(
            machine,
            ts,
            vcnc_drive::Channels::TruePosition,
        )?),
    };
    let whole = original.poses.len().max(1);
    let limits = StreamLimits {
        first_window: whole,
        knots: StreamLimits::default().knots.max(whole + 8),
        ..StreamLimits::default()
    };
    let mut search = ContourStream::new(&SearchWindow::default(), limits)?;
    search.push_reference(original.poses.iter().copied())?;
    search.end_reference();
    let mut pending = Pending {
        positions: vec![Vec::new(); machine.axes.len()],
        lines: VecDeque::new(),
        search,
        finished: 0,
    };
    source.for_each(machine, &mut |c: &ReferenceChunk| {
        on_reference(c)?;
        pending.lines.extend(&c.line);
        match &mut stages {
            Stages::Models(m) => {
                m.feed(machine, c)?;
                for (p, y) in pending.positions.iter_mut().zip(&m.out[0]) {
                    p.extend(y);
                }
            }
            Stages::True(d) => {
                d.feed(machine, c)?;
                for (i, p) in pending.positions.iter_mut().enumerate() {
                    p.extend(d.physical(i));
                }
            }
        }
        pending.advance(kin, original, on_sample)
    })?;
    let rest = match stages {
        Stages::Models(m) => m.finish(machine)?.swap_remove(0),
        Stages::True(d) => d.finish(machine)?.1,
    };
    for (p, y) in pending.positions.iter_mut().zip(&rest) {
        p.extend(y);
    }
    pending.advance(kin, original, on_sample)?;
    let Pending {
        mut lines,
        search,
        mut finished,
        ..
    } = pending;
    search.finish(|k, tip, or, foot| {
        finished += 1;
        on_sample(&sample(original, k, lines.pop_front(), tip, or, foot));
    })?;
    if finished != source.len() {
        return Err(Error::Unfinished {
            run: "feed-plan evaluation",
            finished,
            samples: source.len(),
        });
    }
    Ok(finished)
}

fn sample(
    original: &OriginalPath,
    k: usize,
    line: Option<u32>,
    tip_mm: f64,
    orientation_rad: f64,
    foot: &vcnc_contour::Foot,
) -> Sample {
    Sample {
        k,
        line: line.unwrap_or(0),
        tip_mm,
        orientation_rad,
        foot_u: foot.u,
        feed: original.cut(foot.u),
    }
}

/// The samples of [`measure`] between the reference and the contour search.
struct Pending {
    /// Per machine axis: the physical positions not yet searched.
    positions: Vec<Vec<f64>>,
    /// The source lines of the samples not yet finished.
    lines: VecDeque<u32>,
    search: ContourStream,
    finished: usize,
}

impl Pending {
    /// Searches the samples whose positions every axis knows, and hands on the finished ones.
    fn advance(
        &mut self,
        kin: &vcnc_machine::Kinematics,
        original: &OriginalPath,
        on_sample: &mut dyn FnMut(&Sample),
    ) -> Result<(), Error> {
        let known = self.positions.iter().map(Vec::len).min().unwrap_or(0);
        for k in 0..known {
            self.search.push_actual(&kin.pose_at(&self.positions, k))?;
        }
        for p in &mut self.positions {
            p.drain(..known);
        }
        let (lines, finished) = (&mut self.lines, &mut self.finished);
        self.search.drain(|k, tip, or, foot| {
            *finished += 1;
            on_sample(&sample(original, k, lines.pop_front(), tip, or, foot));
        })?;
        Ok(())
    }
}

/// The contour statistics of a run's feed samples, accumulated in sample order by
/// [`MaxRms`] (the bits of [`ContourStats::over`] on the whole series).
#[derive(Debug, Clone, Copy, Default)]
struct FeedStats {
    tip: MaxRms,
    orientation: MaxRms,
}

impl FeedStats {
    fn add(&mut self, s: &Sample) {
        if s.feed {
            self.tip.add(s.tip_mm);
            self.orientation.add(s.orientation_rad);
        }
    }

    fn stats(&self) -> ContourStats {
        let ((tip_max, tip_rms), (or_max, or_rms)) =
            (self.tip.max_rms(), self.orientation.max_rms());
        ContourStats {
            contour_max_um: tip_max * 1e3,
            contour_rms_um: tip_rms * 1e3,
            orientation_max_mrad: or_max * 1e3,
            orientation_rms_mrad: or_rms * 1e3,
        }
    }
}

/// Each sample's error over its tolerance charged to the line that ran at every sample of the
/// lag window before it: line $b$ gets $\max e_j$ over $j \in [k, k + \text{lag}]$ for each
/// of its samples $k$. A running window maximum (a deque of decreasing errors): the same bits
/// as the maximum over the whole series, in memory of the window.
#[derive(Debug, Clone, Default)]
struct Charger {
    lag: usize,
    /// (sample, error) of the candidates for the window's maximum, errors decreasing.
    window: VecDeque<(usize, f64)>,
    /// The lines of the samples whose window is not complete yet.
    lines: VecDeque<u32>,
    /// Samples added.
    added: usize,
    /// The line of the last sample charged and its largest charge since its run began (a run
    /// of samples of one line is charged once).
    run: Option<(u32, f64)>,
    charged: BTreeMap<u32, f64>,
}

impl Charger {
    fn new(lag: usize) -> Charger {
        Charger {
            lag,
            ..Charger::default()
        }
    }

    fn add(&mut self, line: u32, e: f64) {
        let j = self.added;
        self.added += 1;
        while self.window.back().is_some_and(|b| b.1 <= e) {
            self.window.pop_back();
        }
        self.window.push_back((j, e));
        self.lines.push_back(line);
        if j >= self.lag {
            self.settle(j - self.lag);
        }
    }

    /// Charges sample `k`, whose window is complete (or ends with the run).
    fn settle(&mut self, k: usize) {
        while self.window.front().is_some_and(|f| f.0 < k) {
            self.window.pop_front();
        }
        let m = self.window.front().map_or(0.0, |f| 0.0f64.max(f.1));
        let Some(line) = self.lines.pop_front() else {
            return;
        };
        match &mut self.run {
            Some((l, v)) if *l == line => *v = v.max(m),
            run => {
                if let Some(r) = run.replace((line, m)) {
                    self.charge(r);
                }
            }
        }
    }

    fn charge(&mut self, (line, m): (u32, f64)) {
        if line != 0 {
            let v = self.charged.entry(line).or_insert(0.0);
            *v = v.max(m);
        }
    }

    fn finish(mut self) -> BTreeMap<u32, f64> {
        for k in self.added - self.lines.len()..self.added {
            self.settle(k);
        }
        if let Some(r) = self.run.take() {
            self.charge(r);
        }
        self.charged
    }
}

/// The models' run of `source` against the original path, reduced on the fly to an
/// [`Evaluation`] (`lag`: the lag window in samples).
pub fn evaluate(
    machine: &Machine,
    original: &OriginalPath,
    source: Source<'_>,
    models: &MachineModels,
    opts: &FeedPlanOptions,
    lag: usize,
) -> Result<Evaluation, Error> {
    let mut feed = FeedStats::default();
    let mut charger = Charger::new(lag);
    let (mut excess, mut tip_max, mut or_max) = (0.0f64, 0.0f64, 0.0f64);
    let samples = measure(
        machine,
        original,
        source,
        Axes::Models(models),
        &mut |_| Ok(()),
        &mut |s| {
            let e = opts.excess(s);
            excess = excess.max(e);
            tip_max = tip_max.max(s.tip_mm);
            or_max = or_max.max(s.orientation_rad);
            feed.add(s);
            charger.add(s.line, e);
        },
    )?;
    Ok(Evaluation {
        cycle_time_s: source.duration_s(),
        samples,
        excess,
        tip_max_mm: tip_max,
        orientation_max_rad: or_max,
        feed: feed.stats(),
        charged: charger.finish(),
    })
}

/// The evaluation context: machine, models, original run and program.
struct Planner<'a> {
    machine: &'a Machine,
    models: &'a MachineModels,
    src: &'a str,
    file: &'a str,
    lenient: bool,
    original: &'a OriginalPath<'a>,
    lines: BTreeMap<u32, LineFeed>,
    opts: &'a FeedPlanOptions,
    lag: usize,
    /// Every program evaluated and its evaluation: a program written again (factors closer than
    /// the F words' 10⁻⁴ write the same text) is not run again.
    done: std::cell::RefCell<HashMap<String, Evaluation>>,
}

impl Planner<'_> {
    /// The program text with these factors.
    fn text(&self, factors: &BTreeMap<u32, f64>) -> String {
        vcnc_gcode::write::with_feed_factors(
            self.src,
            &self.original.run.loaded.program,
            &self.lines,
            factors,
        )
        .0
    }

    /// The program with these factors, streamed through the models (once per program text).
    fn evaluate(&self, factors: &BTreeMap<u32, f64>) -> Result<Evaluation, Error> {
        let text = self.text(factors);
        if let Some(e) = self.done.borrow().get(&text) {
            return Ok(e.clone());
        }
        let stream = crate::source::plan(
            self.machine,
            Program::Text {
                text: text.clone(),
                name: self.file.to_string(),
            },
            self.lenient,
        )?;
        let e = evaluate(
            self.machine,
            self.original,
            Source::Streamed(&stream),
            self.models,
            self.opts,
            self.lag,
        )?;
        self.done.borrow_mut().insert(text, e.clone());
        Ok(e)
    }

    fn uniform(&self, u: f64) -> BTreeMap<u32, f64> {
        self.lines.keys().map(|l| (*l, u)).collect()
    }

    fn planned(&self, factors: BTreeMap<u32, f64>, evaluation: Evaluation) -> PlannedProgram {
        PlannedProgram {
            text: self.text(&factors),
            factors,
            evaluation,
        }
    }
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
    let lag_s = opts.lag_s.unwrap_or_else(|| lag_window(models.models()));
    let lag = (lag_s / original.ts).round() as usize;
    let path = OriginalPath::new(machine, &original)?;
    let original_predicted = evaluate(
        machine,
        &path,
        Source::Prepared(&original),
        models,
        opts,
        lag,
    )?;
    let planner = Planner {
        machine,
        models,
        src,
        file,
        lenient,
        original: &path,
        lines,
        opts,
        lag,
        done: std::cell::RefCell::new(HashMap::new()),
    };
    let feasible = |e: &Evaluation| e.excess <= 1.0;

    // Uniform baseline: a safeguarded secant search on log u.
    let (uniform_factor, uniform) = largest_feasible(&planner, |u| planner.uniform(u))?;
    let uniform = planner.planned(planner.uniform(uniform_factor), uniform);

    // Per-line plan: multiplicative updates from the programmed feeds.
    let mut factors = planner.uniform(1.0);
    let mut history = Vec::new();
    let mut best: Option<(BTreeMap<u32, f64>, Evaluation)> = None;
    for _ in 0..opts.max_iterations {
        let p = planner.evaluate(&factors)?;
        history.push(PlanStep {
            predicted_max_um: p.tip_max_mm * 1e3,
            cycle_time_s: p.cycle_time_s,
        });
        if feasible(&p)
            && best
                .as_ref()
                .is_none_or(|b| p.cycle_time_s < b.1.cycle_time_s)
        {
            best = Some((factors.clone(), p.clone()));
        }
        let before = factors.clone();
        for (line, s) in factors.iter_mut() {
            let err = p.charged.get(line).copied().unwrap_or(0.0);
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
    let (factors, evaluation) = match best {
        Some(b) => b,
        None => {
            // Scale the last plan down until it meets the tolerance.
            let base = factors.clone();
            let scaled = |u: f64| -> BTreeMap<u32, f64> {
                base.iter()
                    .map(|(l, s)| (*l, (s * u).max(opts.min_factor)))
                    .collect()
            };
            let (u, p) = largest_feasible(&planner, scaled)?;
            (scaled(u), p)
        }
    };
    let plan = planner.planned(factors, evaluation);
    let programmed = vcnc_gcode::write::programmed_feeds(&original.loaded.program, &planner.lines);
    let (_, written) = vcnc_gcode::write::with_feed_factors(
        src,
        &original.loaded.program,
        &planner.lines,
        &plan.factors,
    );
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
                predicted_max_um: plan.evaluation.charged.get(line).copied().unwrap_or(0.0)
                    * opts.tolerance_mm
                    * 1e3,
            }
        })
        .collect();
    // The original's, and each program run once.
    let evaluations = 1 + planner.done.borrow().len();
    drop(planner);
    Ok(FeedPlan {
        original_predicted,
        original,
        plan,
        lines,
        history,
        uniform_factor,
        uniform,
        lag_s,
        evaluations,
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

/// The largest factor `u` in `[min_factor, 1]` whose program `factors(u)` meets the tolerance,
/// and its evaluation; an error when even `min_factor` does not.
///
/// A first guess from the error's proportionality to the feed, stepped down until it meets the
/// tolerance, brackets it: $[\log u_{ok}, \log u_{over}]$. The bracket then shrinks until it
/// is narrower than its first width over $2^{\text{bisection\_steps}}$ (the precision of as
/// many bisection steps): each step tries the root of the secant of $\log(\text{excess})$
/// against $\log u$ through the bracket's ends (the error being about proportional to the
/// feed, that line is nearly exact: a step or two land next to the answer), kept at least a
/// 16th of the bracket inside it; a step that did not halve the bracket makes the next one a
/// bisection. So the search never takes more than twice the bisection's steps, and ends with
/// the largest factor evaluated that meets the tolerance.
fn largest_feasible(
    planner: &Planner,
    factors: impl Fn(f64) -> BTreeMap<u32, f64>,
) -> Result<(f64, Evaluation), Error> {
    let opts = planner.opts;
    let mut hi = 1.0f64;
    let mut p = planner.evaluate(&factors(hi))?;
    if p.excess <= 1.0 {
        return Ok((1.0, p));
    }
    let mut over;
    let mut u = hi;
    loop {
        let step = (0.95 / p.excess).clamp(0.05, 0.5);
        let next = (u * step).max(opts.min_factor);
        if next == u {
            return Err(Error::ToleranceUnreachable {
                min_factor: opts.min_factor,
                tip_um: p.feed.contour_max_um,
                orientation_mrad: p.feed.orientation_max_mrad,
                excess: p.excess,
            });
        }
        hi = u;
        over = p.excess;
        u = next;
        p = planner.evaluate(&factors(u))?;
        if p.excess <= 1.0 {
            break;
        }
    }
    // g(x) = log excess at u = e^x: g(lo) ≤ 0 < g(up).
    let (mut lo, mut up) = (u.ln(), hi.ln());
    let (mut g_lo, mut g_up) = (p.excess.ln(), over.ln());
    let precision = (up - lo) / 2f64.powi(opts.bisection_steps.min(1000) as i32);
    let mut good = (u, p);
    let mut secant = true;
    while up - lo > precision {
        let width = up - lo;
        let margin = width / 16.0;
        let x = if secant && g_up > g_lo && g_lo.is_finite() {
            (lo - g_lo * width / (g_up - g_lo)).clamp(lo + margin, up - margin)
        } else {
            0.5 * (lo + up)
        };
        if !(x > lo && x < up) {
            // No factor left between the two (a precision finer than a double's).
            break;
        }
        let p = planner.evaluate(&factors(x.exp()))?;
        if p.excess <= 1.0 {
            lo = x;
            g_lo = p.excess.ln();
            good = (x.exp(), p);
        } else {
            up = x;
            g_up = p.excess.ln();
        }
        secant = up - lo <= 0.5 * width;
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
    /// Evaluations of programs with the models in all (the original, the uniform search, the
    /// per-line plan, a final scale-down).
    pub evaluations: usize,
}

/// Most points of each series of `feed_plan.svg`: a longer run keeps, of each run of
/// consecutive samples, the one with the largest error (and the first's speed).
pub const FIGURE_POINTS: usize = 20_000;

/// A run's series for `feed_plan.svg`, at most [`FIGURE_POINTS`] points each: every sample of
/// a run that short, else of each `every` consecutive samples the one with the largest true
/// tool-tip error (its position and error) and the first one's speed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PathSeries {
    /// Samples per point.
    pub every: usize,
    /// Where the sample's foot lies along the original tool-tip path, mm.
    pub position_mm: Vec<f64>,
    /// The true machine's tool-tip contour error there, mm.
    pub tip_mm: Vec<f64>,
    /// The arc length of the run's own reference tool-tip path, mm.
    pub reference_mm: Vec<f64>,
    /// The reference tool-tip speed there (the step to the next sample over the period), mm/s.
    pub speed_mm_s: Vec<f64>,
}

/// One program on the true machine against the original path.
#[derive(Debug, Clone)]
pub struct JudgedRun {
    /// Cycle time, s.
    pub cycle_time_s: f64,
    /// Contour statistics of the feed samples.
    pub true_machine: ContourStats,
    /// The figure's series.
    pub series: PathSeries,
}

/// Streams `source` through the true machine against the original path ([`measure`]),
/// keeping the statistics and the figure's series.
fn judge(
    machine: &Machine,
    original: &OriginalPath,
    source: Source<'_>,
) -> Result<JudgedRun, Error> {
    let kin = machine.require_kinematics()?;
    let every = source.len().div_ceil(FIGURE_POINTS).max(1);
    let ts = source.ts();
    let mut series = PathSeries {
        every,
        ..PathSeries::default()
    };
    // The reference tips: the last one and the arc length to it.
    let mut last: Option<(usize, vcnc_kinematics::nalgebra::Vector3<f64>)> = None;
    let mut arc = 0.0;
    let mut on_reference = |c: &ReferenceChunk| {
        let pos = c.positions();
        for j in 0..c.len() {
            let (k, p) = (c.first + j, kin.pose_at(&pos, j).p);
            if let Some((prev, q)) = last {
                let step = (p - q).norm();
                if prev.is_multiple_of(every) {
                    series.reference_mm.push(arc);
                    series.speed_mm_s.push(step / ts);
                }
                arc += step;
            }
            last = Some((k, p));
        }
        Ok(())
    };
    let mut feed = FeedStats::default();
    let mut bucket: Option<(f64, f64)> = None;
    let (mut position_mm, mut tip_mm) = (Vec::new(), Vec::new());
    let mut on_sample = |s: &Sample| {
        feed.add(s);
        if bucket.is_none_or(|b| s.tip_mm > b.1) {
            bucket = Some((original.position_mm(s.foot_u), s.tip_mm));
        }
        if (s.k + 1).is_multiple_of(every)
            && let Some((x, e)) = bucket.take()
        {
            position_mm.push(x);
            tip_mm.push(e);
        }
    };
    measure(
        machine,
        original,
        source,
        Axes::TrueMachine,
        &mut on_reference,
        &mut on_sample,
    )?;
    if let Some((x, e)) = bucket {
        position_mm.push(x);
        tip_mm.push(e);
    }
    if let Some((k, _)) = last
        && k.is_multiple_of(every)
    {
        series.reference_mm.push(arc);
        series.speed_mm_s.push(0.0);
    }
    series.position_mm = position_mm;
    series.tip_mm = tip_mm;
    Ok(JudgedRun {
        cycle_time_s: source.duration_s(),
        true_machine: feed.stats(),
        series,
    })
}

/// A feed plan judged on the true machine (`vcnc feed-plan`): the original program, the
/// per-line plan and the uniform scale, each run through the true drives and measured against
/// the ORIGINAL program's path, a piece at a time.
#[derive(Debug, Clone)]
pub struct JudgedPlan {
    /// The plan.
    pub plan: FeedPlan,
    /// The original program on the true machine.
    pub original: JudgedRun,
    /// The per-line feeds on the true machine.
    pub planned: JudgedRun,
    /// The uniform feed scale on the true machine.
    pub uniform: JudgedRun,
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
    let path = OriginalPath::new(machine, &plan.original)?;
    let judge_text = |text: &str| -> Result<JudgedRun, Error> {
        let stream = crate::source::plan(
            machine,
            Program::Text {
                text: text.to_string(),
                name: file.clone(),
            },
            lenient,
        )?;
        judge(machine, &path, Source::Streamed(&stream))
    };
    let (original, planned, uniform) = (
        judge(machine, &path, Source::Prepared(&plan.original))?,
        judge_text(&plan.plan.text)?,
        judge_text(&plan.uniform.text)?,
    );
    let figures = |p: &Evaluation, j: &JudgedRun| PlanFigures {
        cycle_time_s: j.cycle_time_s,
        predicted: p.feed,
        true_machine: j.true_machine,
    };
    let summary = FeedPlanSummary {
        machine: machine.name.clone(),
        program: file,
        models: models.source().to_string(),
        planned_program: planned_program.to_string(),
        options: *opts,
        lag_s: plan.lag_s,
        tolerance_um: opts.tolerance_mm * 1e3,
        original: figures(&plan.original_predicted, &original),
        planned: figures(&plan.plan.evaluation, &planned),
        uniform: figures(&plan.uniform.evaluation, &uniform),
        uniform_factor: plan.uniform_factor,
        saving_vs_uniform: 1.0 - planned.cycle_time_s / uniform.cycle_time_s,
        lines: plan.lines.len(),
        lines_slowed: plan.lines.iter().filter(|l| l.factor < 1.0).count(),
        min_factor: plan.lines.iter().map(|l| l.factor).fold(1.0, f64::min),
        history: plan.history.clone(),
        evaluations: plan.evaluations,
    };
    Ok(JudgedPlan {
        plan,
        original,
        planned,
        uniform,
        summary,
    })
}
