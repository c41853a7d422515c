//! Interpolation of a [`Toolpath`] at the sample period $T_s$ (docs/gcode.md, "Interpolation").
//!
//! Every move is a curve $\mathbf{g}(s)$ of its path parameter $s \in [0, L]$ and a scalar
//! speed profile $s(t)$; the samples are analytic:
//! $$ \mathbf{x} = \mathbf{g}(s), \qquad \dot{\mathbf{x}} = \mathbf{g}'(s)\,\dot s, \qquad
//!    \ddot{\mathbf{x}} = \mathbf{g}''(s)\,\dot s^2 + \mathbf{g}'(s)\,\ddot s $$
//! (never differenced). Samples sit at $t_k = k T_s$, $k = 0 \dots N$; the last sample is at rest
//! on the last programmed point.
//!
//! **Path parameter and feed rule.** $L$ is the XYZ length of the move (the tool-tip path in
//! TCP mode); for a move of rotary axes alone it is $\sqrt{\Delta A^2+\Delta B^2+\Delta C^2}$ in
//! degrees (NIST RS274NGC v3, 2.1.2.5). `G94` feeds apply along $s$ (mm/min, or deg/min for a
//! pure rotary move); a `G93` block runs at $L F / 60$ along $s$, so that it lasts $1/F$ plus its
//! ramps (LinuxCNC's inverse-time rule). Rapids run at the limits.
//!
//! **Limits along the path** (`segment`): for a straight move
//! $\mathbf{g}' = \mathbf{u} = \Delta\mathbf{x}/L$ is constant, so axis $i$ stays within its
//! limits when
//! $$ \dot s \le V = \min\Big(\tfrac{F}{60}, \min_i \tfrac{v_{\max,i}}{|u_i|}\Big), \qquad
//!    |\ddot s| \le A = \min_i \tfrac{a_{\max,i}}{|u_i|}, \qquad
//!    |\dddot s| \le J = \min_i \tfrac{j_{\max,i}}{|u_i|}. $$
//! In TCP mode the tool-tip limits replace those of X Y Z. On arcs and corner blends the
//! centripetal acceleration takes the fraction $\beta$
//! ([`InterpolateOptions::arc_centripetal_fraction`]) of the acceleration limit.
//!
//! **How moves join** (`planner`, `corner`,
//! `chain`): a `G61.1` block stops at its end; `G61` (exact path) runs through
//! where the next block continues in the same direction and stops at corners; `G64` blends
//! corners with arcs within its tolerance `P` and merges straight feeds within `Q`. Moves joined
//! without a stop form a chain, planned with an exact, bounded look-ahead: a backward pass from
//! an assumed stop and a forward pass from the chain's start, the chain's duration rounded up to
//! whole samples by one time scale ($t = \lambda\tau$, $\lambda \ge 1$).
//!
//! **Profiles** ([`Profile`]): trapezoidal (acceleration-limited, unbounded jerk), or
//! jerk-limited: a block on its own runs the time-optimal seven-phase profile (checked against
//! Ruckig), a chain its trapezoid smoothed by a moving average of the path position
//! (`chain`).
//!
//! **Time-exact chains of fine blocks** (`G93` + `G64`, `G1` only, every block's $1/F$ a whole
//! number $m$ of sample periods $T_s$, $1 \le m \le 32$,
//! [`FINE_BLOCK_MAX_SAMPLES`](crate::FINE_BLOCK_MAX_SAMPLES)): such a program is a stream of
//! set-points, a block per interpolation cycle or per few, as a pre-compensated program is
//! (docs/compensation.md). A maximal run of such blocks is not re-planned: a block of $m$
//! periods runs straight from its start to its end in $m$ equal steps, the position at its
//! $j$-th sample being $\mathbf x_0 + (\mathbf x_1 - \mathbf x_0)\,j/m$ (its end point at
//! $j = m$), and the velocity and acceleration are the central differences of those positions,
//! the chain at rest before its first and after its last block ([`time_exact_rates`]):
//! $$ \dot{\mathbf x}_k = \frac{\mathbf x_{k+1} - \mathbf x_{k-1}}{2T_s}, \qquad
//!    \ddot{\mathbf x}_k = \frac{\mathbf x_{k+1} - 2\mathbf x_k + \mathbf x_{k-1}}{T_s^2}. $$
//! A longer `G93` block, or one whose $1/F$ is not a whole number of periods, is an ordinary
//! move.
//! A chain with a block too fast for the limits runs block by block, each an exact stop, with a
//! warning naming the block.
//!
//! **Feeds the machine cannot follow** are run at its limits, as a control does, never refused:
//! a block whose programmed speed along $s$ exceeds its speed cap runs at the cap. One warning
//! sums them up: how many blocks were slowed and the worst one (line and factor);
//! [`Trajectory::slowdown`] holds the same figures.
//!
//! **Dwell**: holds the position for $P$ seconds rounded up to $T_s$.

use crate::diag::Diagnostic;
use crate::interp::{Move, MoveKind, Toolpath};
use crate::{AxisName, Error};

pub(crate) mod chain;
pub(crate) mod corner;
pub(crate) mod geom;
pub(crate) mod planner;
pub(crate) mod profile;
pub(crate) mod segment;
pub mod stream;

use chain::{Out, TcpSwitch};
use planner::{Decisions, Mode, Planner};
use segment::{Cfg, check_limits};

/// Velocity, acceleration and jerk limit of one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisLimits {
    /// Largest speed, mm/s for X Y Z, deg/s for A B C. 0 means the axis cannot move.
    pub max_vel: f64,
    /// Largest acceleration, mm/s² for X Y Z, deg/s² for A B C. 0 means the axis cannot move.
    pub max_acc: f64,
    /// Largest jerk, mm/s³ or deg/s³; `f64::INFINITY`: none (the trapezoidal profile never
    /// needs one). Used by [`Profile::JerkLimited`].
    pub max_jerk: f64,
}

/// Machine limits used by the interpolator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Limits of X Y Z A B C, in that order.
    pub axes: [AxisLimits; 6],
    /// Tool-tip path speed limit in TCP mode, mm/s (LinuxCNC `TRAJ MAX_LINEAR_VELOCITY`).
    pub tcp_max_vel: f64,
    /// Tool-tip path acceleration limit in TCP mode, mm/s² (LinuxCNC
    /// `TRAJ MAX_LINEAR_ACCELERATION`).
    pub tcp_max_acc: f64,
    /// Tool-tip path jerk limit in TCP mode, mm/s³ (`f64::INFINITY`: none).
    pub tcp_max_jerk: f64,
}

impl Limits {
    /// The same limits on every axis and on the tool-tip path (units per s and per s²), no jerk
    /// limit.
    pub fn uniform(max_vel: f64, max_acc: f64) -> Self {
        Limits::uniform_with_jerk(max_vel, max_acc, f64::INFINITY)
    }

    /// The same limits on every axis and on the tool-tip path, with a jerk limit (units/s³).
    pub fn uniform_with_jerk(max_vel: f64, max_acc: f64, max_jerk: f64) -> Self {
        Limits {
            axes: [AxisLimits {
                max_vel,
                max_acc,
                max_jerk,
            }; 6],
            tcp_max_vel: max_vel,
            tcp_max_acc: max_acc,
            tcp_max_jerk: max_jerk,
        }
    }
}

/// The speed profile of the interpolator (docs/gcode.md, "Speed profiles").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Profile {
    /// Acceleration-limited trapezoids, unbounded jerk (the paper's identification runs).
    #[default]
    Trapezoidal,
    /// Jerk-limited: time-optimal seven-phase profiles for blocks on their own, moving-average
    /// smoothed trapezoids for chains. Needs [`AxisLimits::max_jerk`].
    JerkLimited,
}

/// Whose rules the planner follows where controls differ (docs/gcode.md, "LinuxCNC 2.9's
/// planner").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlannerRules {
    /// vcnc's: the full acceleration on every stop, corner blends as large as the tolerance
    /// allows, half the acceleration centripetal on arcs ([`InterpolateOptions::arc_centripetal_fraction`]).
    #[default]
    Vcnc,
    /// LinuxCNC 2.9's trajectory planner (`tp.c`, `tc.c`, `blendmath.c`): 90 % of the
    /// acceleration next to exact-path corners, √3/2 of it centripetal on arcs, its blend-arc
    /// sizing, half the acceleration on a `G64` block that ends in a stop.
    LinuxCnc29,
}

/// Interpolator settings. Plain data; [`Default`] gives the documented defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct InterpolateOptions {
    /// Sample period $T_s$, s. Default 0.001.
    pub ts: f64,
    /// Largest number of samples a trajectory may have; longer ones are an error. Default
    /// 10 000 000 (2.8 h at 1 ms).
    pub max_samples: usize,
    /// Blend tolerance of a plain `G64` (no `P`), mm (deg for pure rotary chains); `None`
    /// (default): LinuxCNC 2.9's rule, a quarter of the shorter block's length.
    pub blend_tolerance: Option<f64>,
    /// Axes to output; `None` (default): the axes the program uses.
    pub axes: Option<Vec<AxisName>>,
    /// Fraction $\beta$ of the acceleration limit given to the centripetal acceleration on arcs
    /// (the rest is for the tangential one), in (0, 1). Default 0.5.
    pub arc_centripetal_fraction: f64,
    /// Speed profile. Default trapezoidal.
    pub profile: Profile,
    /// Planner rules. Default vcnc's.
    pub planner: PlannerRules,
}

impl Default for InterpolateOptions {
    fn default() -> Self {
        InterpolateOptions {
            ts: 0.001,
            max_samples: 10_000_000,
            blend_tolerance: None,
            axes: None,
            arc_centripetal_fraction: 0.5,
            profile: Profile::Trapezoidal,
            planner: PlannerRules::Vcnc,
        }
    }
}

/// Samples of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisTrack {
    /// The axis.
    pub name: AxisName,
    /// Position at $t_k = k T_s$: mm (X Y Z; the tool tip in TCP spans) or deg (A B C).
    pub pos: Vec<f64>,
    /// Velocity, mm/s or deg/s.
    pub vel: Vec<f64>,
    /// Acceleration, mm/s² or deg/s².
    pub acc: Vec<f64>,
}

/// What a span of the trajectory does: position (rapid), cut (feed) or wait (dwell).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MoveClass {
    /// `G0`, and the positioning moves of canned cycles, `G28` and `G30`.
    Rapid,
    /// `G1`, `G2`, `G3`, and the feed moves of canned cycles: the moves that cut.
    Feed,
    /// `G4`, and the dwells of canned cycles.
    Dwell,
}

impl MoveClass {
    /// The class of a move kind.
    pub fn of(kind: &MoveKind) -> MoveClass {
        match kind {
            MoveKind::Rapid => MoveClass::Rapid,
            MoveKind::Linear | MoveKind::Arc(_) => MoveClass::Feed,
            MoveKind::Dwell { .. } => MoveClass::Dwell,
        }
    }
}

/// Time span of one move in the trajectory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockSpan {
    /// Index of the move in [`Toolpath::moves`].
    pub move_index: usize,
    /// Source line of the move.
    pub line: u32,
    /// Rapid, feed or dwell.
    pub class: MoveClass,
    /// Start time, s.
    pub t_start_s: f64,
    /// End time, s (exact-stop blocks end on a sample; blocks inside a chain need not).
    pub t_end_s: f64,
    /// First sample of the span: samples `first_sample..end_sample` belong to it. A sample on
    /// the boundary of two spans belongs to the one that ends there (the first span also has
    /// sample 0), so every sample of a trajectory with moves belongs to exactly one span.
    pub first_sample: usize,
    /// One past the last sample of the span (equal to `first_sample` for a span shorter than a
    /// sample period that holds no sample).
    pub end_sample: usize,
    /// Tool-centre-point mode.
    pub tcp: bool,
}

/// How much the machine's limits slowed the programmed feeds (module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slowdown {
    /// Number of feed blocks that ran slower than programmed.
    pub blocks: usize,
    /// Source line of the most slowed block.
    pub worst_line: u32,
    /// Its slowdown: programmed speed over the speed it ran at (> 1, dimensionless).
    pub worst_factor: f64,
}

/// The cycle time of a program and how it splits between the kinds of move (a chain of moves
/// joined without a stop counts as the kind of its moves: feeds or rapids).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct CycleTime {
    /// The whole program, s (the trajectory's duration).
    pub total_s: f64,
    /// Feed moves (`G1` `G2` `G3`, the feed moves of cycles), s.
    pub feed_s: f64,
    /// Rapids (`G0`, the positioning moves of cycles, `G28`, `G30`), s.
    pub rapid_s: f64,
    /// Dwells, s.
    pub dwell_s: f64,
}

impl CycleTime {
    pub(crate) fn add(&mut self, class: MoveClass, dt: f64) {
        self.total_s += dt;
        match class {
            MoveClass::Feed => self.feed_s += dt,
            MoveClass::Rapid => self.rapid_s += dt,
            MoveClass::Dwell => self.dwell_s += dt,
        }
    }
}

/// The sampled reference trajectory.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Sample period, s.
    pub ts: f64,
    /// One track per output axis, in X Y Z A B C order.
    pub axes: Vec<AxisTrack>,
    /// Per sample: `true` when X Y Z are tool-tip coordinates (TCP mode). The rest sample where
    /// TCP mode switches on or off is a TCP sample (the TCP move's start or end point).
    pub tcp: Vec<bool>,
    /// The moves' time spans, in order (zero-length moves have none, nor have moves merged by
    /// `G64 Q`: the merged move's span names the last of them, as LinuxCNC does).
    pub blocks: Vec<BlockSpan>,
    /// Feeds slowed to the machine's limits, if any.
    pub slowdown: Option<Slowdown>,
    /// The cycle time and its split by kind of move.
    pub cycle: CycleTime,
    /// Warnings raised while interpolating (the slowdown summary).
    pub warnings: Vec<Diagnostic>,
}

impl Trajectory {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.tcp.len()
    }

    /// `true` when there are no samples (never the case for a result of [`interpolate`]).
    pub fn is_empty(&self) -> bool {
        self.tcp.is_empty()
    }

    /// Time of the last sample, s.
    pub fn duration_s(&self) -> f64 {
        self.len().saturating_sub(1) as f64 * self.ts
    }

    /// The track of axis `name`, if output.
    pub fn axis(&self, name: AxisName) -> Option<&AxisTrack> {
        self.axes.iter().find(|a| a.name == name)
    }

    /// The span sample `k` belongs to ([`BlockSpan::first_sample`]); O(log spans).
    pub fn span_at(&self, k: usize) -> Option<&BlockSpan> {
        let i = self.blocks.partition_point(|b| b.end_sample <= k);
        self.blocks.get(i).filter(|b| b.first_sample <= k)
    }

    /// The span of the move running at sample `k` (the earlier one at a boundary): the same as
    /// [`Trajectory::span_at`].
    pub fn block_at(&self, k: usize) -> Option<&BlockSpan> {
        self.span_at(k)
    }

    /// For every sample in order, the index in [`Trajectory::blocks`] of its span (`None` only
    /// for a trajectory without moves): O(samples + spans) in all.
    pub fn sample_spans(&self) -> impl Iterator<Item = Option<usize>> + '_ {
        let mut next = 0usize;
        (0..self.len()).map(move |k| {
            while next < self.blocks.len() && self.blocks[next].end_sample <= k {
                next += 1;
            }
            self.blocks
                .get(next)
                .filter(|b| b.first_sample <= k)
                .map(|_| next)
        })
    }
}

/// Velocity and acceleration of a time-exact chain at its samples (module doc): central
/// differences of the sampled positions, the chain at rest before its first and after its last
/// sample ($x_{-1} = x_0$, $x_n = x_{n-1}$):
/// $$ \dot x_k = \frac{x_{k+1} - x_{k-1}}{2T_s}, \qquad
///    \ddot x_k = \frac{x_{k+1} - 2x_k + x_{k-1}}{T_s^2}. $$
/// Returns `(vel, acc)` (units/s, units/s²). Reference pre-compensation uses the same function,
/// so that a compensated program reproduces the references it was computed with.
pub fn time_exact_rates(pos: &[f64], ts: f64) -> (Vec<f64>, Vec<f64>) {
    let n = pos.len();
    let at = |k: isize| pos[k.clamp(0, n as isize - 1) as usize];
    let (mut vel, mut acc) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for k in 0..n as isize {
        let (a, b, c) = (at(k - 1), at(k), at(k + 1));
        vel.push((c - a) / (2.0 * ts));
        acc.push((c - 2.0 * b + a) / (ts * ts));
    }
    (vel, acc)
}

/// The output axes: those asked for (sorted, without repeats), else those the program uses
/// (X Y Z when it uses none).
pub(crate) fn output_axes(opts: &InterpolateOptions, used: [bool; 6]) -> Vec<AxisName> {
    match &opts.axes {
        Some(list) => {
            let mut out = list.clone();
            out.sort();
            out.dedup();
            out
        }
        None => {
            let used: Vec<AxisName> = AxisName::ALL
                .iter()
                .zip(used)
                .filter_map(|(&n, u)| u.then_some(n))
                .collect();
            if used.is_empty() {
                vec![AxisName::X, AxisName::Y, AxisName::Z]
            } else {
                used
            }
        }
    }
}

/// The whole trajectory as [`Out`]: the sample columns and the spans.
struct Collector<'t> {
    tp: &'t Toolpath,
    idx: Vec<usize>,
    traj: Trajectory,
    last_index: Option<usize>,
}

impl Out for Collector<'_> {
    fn span(&mut self, first: usize, end: usize, t0: f64, t1: f64, index: usize, mv: &Move) {
        if self.last_index == Some(index)
            && let Some(b) = self.traj.blocks.last_mut()
        {
            b.end_sample = end;
            b.t_end_s = t1;
            return;
        }
        self.last_index = Some(index);
        let first = if self.traj.blocks.is_empty() {
            0
        } else {
            first
        };
        self.traj.blocks.push(BlockSpan {
            move_index: index,
            line: self.tp.moves.get(index).map_or(mv.line, |m| m.line),
            class: MoveClass::of(&mv.kind),
            t_start_s: t0,
            t_end_s: t1,
            first_sample: first,
            end_sample: end,
            tcp: mv.tcp,
        });
    }

    fn sample(&mut self, p: &[f64; 6], v: &[f64; 6], a: &[f64; 6], tcp: bool) {
        for (track, &i) in self.traj.axes.iter_mut().zip(&self.idx) {
            track.pos.push(p[i]);
            track.vel.push(v[i]);
            track.acc.push(a[i]);
        }
        self.traj.tcp.push(tcp);
    }

    fn failed(&self) -> bool {
        false
    }
}

/// Interpolate a toolpath into samples (module doc): the planner's two passes
/// (`planner`) over the moves in memory.
pub fn interpolate(
    tp: &Toolpath,
    limits: &Limits,
    opts: &InterpolateOptions,
) -> Result<Trajectory, Error> {
    check_limits(limits, opts)?;
    let cfg = Cfg::new(limits, opts);
    let ts = opts.ts;
    let mut decisions = Decisions::default();
    let mut first = Planner::new(&cfg, Mode::Plan(&mut decisions));
    for m in &tp.moves {
        first.push(m.clone())?;
    }
    first.finish()?;
    let mut warnings = std::mem::take(&mut first.warnings_early);
    let slowdown = std::mem::take(&mut first.slowed).finish(&mut warnings);
    let (total, cycle) = (first.total, first.cycle);
    drop(first);
    let len = usize::try_from(total + 1).map_err(|_| Error::TooManySamples {
        samples: (total + 1) as f64,
        max: opts.max_samples,
        duration_s: total as f64 * ts,
    })?;
    let names = output_axes(opts, tp.axes_used);
    let mut out = Collector {
        tp,
        idx: names.iter().map(|a| a.index()).collect(),
        traj: Trajectory {
            ts,
            axes: names
                .iter()
                .map(|&name| AxisTrack {
                    name,
                    pos: Vec::with_capacity(len),
                    vel: Vec::with_capacity(len),
                    acc: Vec::with_capacity(len),
                })
                .collect(),
            tcp: Vec::with_capacity(len),
            blocks: Vec::with_capacity(tp.moves.len()),
            slowdown,
            cycle,
            warnings,
        },
        last_index: None,
    };
    let mut switch = TcpSwitch::new(&mut out);
    let mut second = Planner::new(
        &cfg,
        Mode::Sample {
            decisions: &mut decisions,
            out: &mut switch,
        },
    );
    for m in &tp.moves {
        second.push(m.clone())?;
    }
    second.finish()?;
    second.final_sample(tp.start);
    drop(second);
    Ok(out.traj)
}

#[cfg(test)]
mod tests {
    use super::profile::Trap;
    use super::*;
    use crate::{InterpOptions, load};

    fn traj(src: &str, limits: &Limits, opts: &InterpolateOptions) -> Result<Trajectory, Error> {
        load(src, &InterpOptions::default(), limits, opts).map(|r| r.trajectory)
    }

    fn max_abs(x: &[f64]) -> f64 {
        x.iter().fold(0.0f64, |m, v| m.max(v.abs()))
    }

    /// Tool-tip (XYZ) speed at sample k.
    fn speed(t: &Trajectory, k: usize) -> f64 {
        [AxisName::X, AxisName::Y, AxisName::Z]
            .iter()
            .filter_map(|&a| t.axis(a))
            .map(|a| a.vel[k] * a.vel[k])
            .sum::<f64>()
            .sqrt()
    }

    #[test]
    fn trapezoid_formulas() {
        // Truth: T = L/V + V/A for L ≥ V²/A, else 2√(L/A).
        let t = Trap::new(10.0, 0.0, 0.0, 10.0, 100.0);
        assert!((t.duration() - 1.1).abs() < 1e-12);
        assert_eq!(t.eval(t.duration()).0, 10.0);
        let t = Trap::new(0.5, 0.0, 0.0, 10.0, 100.0);
        assert!((t.duration() - 2.0 * (0.5f64 / 100.0).sqrt()).abs() < 1e-12);
        // Stretched to 2 s with A kept: ends on time and on the point.
        let t = Trap::rest_to_rest_lasting(10.0, 100.0, 2.0);
        assert!((t.duration() - 2.0).abs() < 1e-12);
        assert!((t.eval(2.0 - 1e-12).0 - 10.0).abs() < 1e-9);
        assert!(t.vp < 10.0 / 1.0);
        // Decelerating from the start: the first sample already decelerates.
        let t = Trap::new(1.0, 10.0, 0.0, 10.0, 50.0);
        assert_eq!(t.eval(0.0), (0.0, 10.0, -50.0));
        assert!((t.duration() - 0.2).abs() < 1e-12);
        // Entry and exit speeds.
        let t = Trap::new(10.0, 5.0, 2.0, 10.0, 100.0);
        assert_eq!(t.eval(0.0).1, 5.0);
        assert!((t.eval(t.duration()).1 - 2.0).abs() < 1e-12);
    }

    #[test]
    fn exact_stop_block_takes_the_rounded_time_optimal_duration() {
        let ts = 0.001;
        for &(l, v, a) in &[
            (10.0, 10.0, 100.0),
            (0.5, 10.0, 100.0),
            (3.3333, 123.4, 2500.0),
            (77.7, 250.0, 2500.0),
        ] {
            let limits = Limits::uniform(1000.0, a);
            let src = format!("G0 X0\nG1 X{l} F{}", v * 60.0);
            let t = traj(&src, &limits, &InterpolateOptions::default()).unwrap();
            let t_star: f64 = if l >= v * v / a {
                l / v + v / a
            } else {
                2.0 * (l / a).sqrt()
            };
            let expected = (t_star / ts - 1e-9).ceil() * ts;
            let x = t.axis(AxisName::X).unwrap();
            assert!((t.duration_s() - expected).abs() < 1e-12, "{l} {v} {a}");
            assert_eq!(*x.pos.last().unwrap(), l);
            assert!(max_abs(&x.vel) <= v * (1.0 + 1e-12));
            assert!(max_abs(&x.acc) <= a * (1.0 + 1e-12));
            assert_eq!(t.blocks.len(), 1);
            assert!((t.blocks[0].t_end_s - expected).abs() < 1e-12);
        }
    }

    #[test]
    fn limits_are_projected_on_the_move_direction() {
        // u = (0.6, 0.8): V = min(100/0.6, 100/0.8) = 125 mm/s, A = min(1000/0.6, 1000/0.8)
        // = 1250 mm/s², T = 50/125 + 125/1250 = 0.5 s; Y saturates both of its limits.
        let limits = Limits::uniform(100.0, 1000.0);
        let t = traj(
            "G0 X0 Y0\nG1 X30 Y40 F60000",
            &limits,
            &InterpolateOptions::default(),
        )
        .unwrap();
        assert!((t.duration_s() - 0.5).abs() < 1e-12);
        let y = t.axis(AxisName::Y).unwrap();
        assert!((max_abs(&y.vel) - 100.0).abs() < 1e-9);
        assert!((max_abs(&y.acc) - 1000.0).abs() < 1e-9);
        assert!((max_abs(&t.axis(AxisName::X).unwrap().vel) - 75.0).abs() < 1e-9);
    }

    #[test]
    fn rapids_run_at_the_limits_and_pure_rotary_feeds_are_deg_per_min() {
        let limits = Limits::uniform(200.0, 1000.0);
        let t = traj("G0 X0\nG0 X100", &limits, &InterpolateOptions::default()).unwrap();
        assert!((t.duration_s() - 0.7).abs() < 1e-12);
        // 90° at F5400 deg/min = 90 deg/s: T = 1 + 0.09 s.
        let t = traj(
            "G0 A0\nG1 A90 F5400",
            &limits,
            &InterpolateOptions::default(),
        )
        .unwrap();
        assert!((t.duration_s() - 1.09).abs() < 1e-12);
        assert_eq!(t.axes.len(), 1);
        assert_eq!(t.axes[0].name, AxisName::A);
    }

    #[test]
    fn helical_arc_stays_on_the_circle_within_limits() {
        let limits = Limits::uniform(100.0, 1000.0);
        let src = "G0 X10 Y0 Z0\nG3 X-10 Y0 Z5 I-10 J0 F6000\nG2 X10 Y0 R10";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        let (x, y, z) = (
            t.axis(AxisName::X).unwrap(),
            t.axis(AxisName::Y).unwrap(),
            t.axis(AxisName::Z).unwrap(),
        );
        // From the end of the positioning rapid on, on the circle.
        for k in t.blocks[1].first_sample..t.len() {
            let r = x.pos[k].hypot(y.pos[k]);
            assert!((r - 10.0).abs() < 1e-9, "k {k}: r = {r}");
        }
        for a in [x, y, z] {
            assert!(max_abs(&a.vel) <= 100.0 * (1.0 + 1e-12));
            assert!(max_abs(&a.acc) <= 1000.0 * (1.0 + 1e-12));
        }
        // Helix: Z proportional to the angle; ends exactly.
        assert_eq!(x.pos.last(), Some(&10.0));
        assert_eq!(z.pos.last(), Some(&5.0));
        // Centripetal cap on the in-plane speed, √(½ A r) = 70.7 mm/s < feed 100: the
        // cruise is on it.
        let vmax = (t.blocks[1].first_sample..t.len())
            .map(|k| x.vel[k].hypot(y.vel[k]))
            .fold(0.0, f64::max);
        let cap = (0.5 * 1000.0 * 10.0f64).sqrt();
        assert!(vmax <= cap * 1.0001 && vmax > 0.99 * cap, "{vmax} vs {cap}");
    }

    #[test]
    fn collinear_g64_segments_run_as_one_trapezoid() {
        // 100 segments of 1 mm at 100 mm/s, 1000 mm/s²: one trapezoid of 100 mm,
        // T = 100/100 + 100/1000 = 1.1 s, x(t) as for a single block.
        let mut src = String::from("G64 G0 X0\nG1 F6000\n");
        for i in 1..=100 {
            src.push_str(&format!("X{i}\n"));
        }
        let limits = Limits::uniform(500.0, 1000.0);
        let t = traj(&src, &limits, &InterpolateOptions::default()).unwrap();
        assert!((t.duration_s() - 1.1).abs() < 1e-12);
        let one = Trap::new(100.0, 0.0, 0.0, 100.0, 1000.0);
        let x = t.axis(AxisName::X).unwrap();
        for k in 0..t.len() {
            let (s, sd, sdd) = one.eval(k as f64 * 0.001);
            assert!((x.pos[k] - s).abs() < 1e-9, "k {k}");
            assert!((x.vel[k] - sd).abs() < 1e-9, "k {k}");
            if (k as f64 * 0.001 - 0.1).abs() > 1e-9 && (k as f64 * 0.001 - 1.0).abs() > 1e-9 {
                assert!((x.acc[k] - sdd).abs() < 1e-9, "k {k}");
            }
        }
        assert_eq!(t.blocks.len(), 100);
    }

    #[test]
    fn g64_corners_are_blended_within_the_tolerance_and_the_limits() {
        // A 90° corner under G64 P0.01: the blend arc is tangent to both lines at
        // d = T cos θ / (1 − sin θ) from the corner (θ = 45°), its radius R = d tan θ, and it
        // leaves the corner by exactly T; on it the speed is capped by the centripetal share
        // β a of the acceleration, v = √(β a R) (module doc of corner.rs).
        let (a, tol) = (1000.0, 0.01);
        let theta = std::f64::consts::FRAC_PI_4;
        let d = theta.cos() * tol / (1.0 - theta.sin());
        let r = d * theta.tan();
        let v_arc = (0.5 * a * r).sqrt();
        let limits = Limits::uniform(500.0, a);
        let t = traj(
            "G64 P0.01 G0 X0 Y0\nG1 X10 F6000\nY10",
            &limits,
            &InterpolateOptions::default(),
        )
        .unwrap();
        let (x, y) = (t.axis(AxisName::X).unwrap(), t.axis(AxisName::Y).unwrap());
        let closest = (0..t.len())
            .map(|k| (x.pos[k] - 10.0).hypot(y.pos[k]))
            .fold(f64::INFINITY, f64::min);
        // Samples 1 ms apart at ≈ 3.5 mm/s straddle the arc's middle within 2 µm.
        assert!((closest - tol).abs() < 0.002, "{closest}");
        let slowest = (1..t.len() - 1)
            .filter(|&k| x.pos[k] > 9.9 && y.pos[k] < 0.1)
            .map(|k| speed(&t, k))
            .fold(f64::INFINITY, f64::min);
        // The chain's rounding to whole samples slows it by λ ≥ 1 (a fraction of a sample over
        // its 0.2 s).
        assert!(
            slowest <= v_arc * (1.0 + 1e-9) && slowest > v_arc / 1.01,
            "{slowest} vs {v_arc}"
        );
        // No sample turns the corner at speed: the second differences stay within the limit.
        for track in [x, y] {
            for k in 1..t.len() - 1 {
                let d2 = (track.pos[k + 1] - 2.0 * track.pos[k] + track.pos[k - 1]) / 1e-6;
                assert!(d2.abs() <= a * (1.0 + 1e-9), "{} k {k}: {d2}", track.name);
            }
        }
    }

    #[test]
    fn inverse_time_blocks_last_one_over_f_plus_their_ramps() {
        // LinuxCNC's rule: a G93 block runs at L·F/60 along its path, so that it lasts 1/F
        // plus its ramps: T = L/v + v/A (v reached), here under G61.1 (each block alone).
        let limits = Limits::uniform(100.0, 1000.0);
        let src = "G61.1 G0 X0\nG93 G1 X10 F60\nG1 X12 F120\nG1 X13 F600\nG3 X15 Y2 R2 F30";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        let d: Vec<f64> = t.blocks.iter().map(|b| b.t_end_s - b.t_start_s).collect();
        let rounded = |x: f64| (x / 1e-3 - 1e-9).ceil() * 1e-3;
        let arc = std::f64::consts::PI; // a quarter of a circle of radius 2
        let want = [
            rounded(1.0 + 10.0 / 1000.0),
            rounded(0.5 + 4.0 / 1000.0),
            rounded(0.1 + 10.0 / 1000.0),
            // On the arc half the acceleration is tangential.
            rounded(2.0 + (arc * 30.0 / 60.0) / 500.0),
        ];
        for (got, want) in d.iter().zip(want) {
            assert!((got - want).abs() < 1e-12, "{d:?} vs {want}");
        }
        assert_eq!(t.axis(AxisName::X).unwrap().pos.last(), Some(&15.0));
        // 100 mm in 0.1 s asks for 1000 mm/s: it runs at the 100 mm/s limit, 10 times slower,
        // with one summary warning naming the line.
        let src = "G61.1 G0 X0\nG93 G1 X100 F600\nG1 X0 F300\nG94 G1 X10 F60000";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        assert_eq!(t.warnings.len(), 1);
        assert_eq!(t.warnings[0].line, 2);
        assert!(
            t.warnings[0].message.starts_with("3 feed block(s)")
                && t.warnings[0]
                    .message
                    .contains("inverse time F600 asks for 1000.000 mm/s"),
            "{}",
            t.warnings[0].message
        );
        let s = t.slowdown.unwrap();
        assert_eq!((s.blocks, s.worst_line), (3, 2));
        assert!((s.worst_factor - 10.0).abs() < 1e-9);
        // Within the limits: no warning.
        let t = traj(
            "G0 X0\nG1 X10 F600",
            &limits,
            &InterpolateOptions::default(),
        )
        .unwrap();
        assert!(t.warnings.is_empty() && t.slowdown.is_none());
    }

    #[test]
    fn every_sample_belongs_to_one_span_with_its_class() {
        // Rapid, feed chain (G64), dwell, feed: spans tile the samples; boundary samples go to
        // the span that ends there.
        let limits = Limits::uniform(100.0, 1000.0);
        let src = "G0 X5\nG64 G1 X6 F600\nX7\nG4 P0.1\nG61 G1 X8";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        let classes: Vec<MoveClass> = t.blocks.iter().map(|b| b.class).collect();
        assert_eq!(
            classes,
            vec![
                MoveClass::Rapid,
                MoveClass::Feed,
                MoveClass::Feed,
                MoveClass::Dwell,
                MoveClass::Feed
            ]
        );
        assert_eq!(t.blocks[0].first_sample, 0);
        assert_eq!(t.blocks.last().unwrap().end_sample, t.len());
        for w in t.blocks.windows(2) {
            assert_eq!(w[0].end_sample, w[1].first_sample);
        }
        let spans: Vec<Option<usize>> = t.sample_spans().collect();
        for (k, s) in spans.iter().enumerate() {
            let b = &t.blocks[s.unwrap()];
            assert!(b.first_sample <= k && k < b.end_sample);
            assert_eq!(t.span_at(k), Some(b));
            let tk = k as f64 * t.ts;
            assert!(
                tk <= b.t_end_s + 1e-9 && (k == 0 || tk > b.t_start_s - 1e-9),
                "k {k}"
            );
        }
        // The rapid ends exactly on a sample, which belongs to it.
        let k = (t.blocks[0].t_end_s / t.ts).round() as usize;
        assert_eq!(t.span_at(k).unwrap().class, MoveClass::Rapid);
        assert_eq!(t.span_at(k + 1).unwrap().class, MoveClass::Feed);
    }

    #[test]
    fn the_cycle_time_splits_into_feeds_rapids_and_dwells() {
        // Truth: the spans' durations summed by class (a rapid, a G64 chain of feeds, a dwell,
        // a G61.1 feed, then a rapid chain under G64).
        let limits = Limits::uniform(100.0, 1000.0);
        let src = "G0 X5\nG64 G1 X6 F600\nY3\nG4 P0.1\nG61.1 G1 X8\nG64 G0 X20\nY30 Z5";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        let mut by = [0.0f64; 3];
        for b in &t.blocks {
            let i = match b.class {
                MoveClass::Feed => 0,
                MoveClass::Rapid => 1,
                MoveClass::Dwell => 2,
            };
            by[i] += b.t_end_s - b.t_start_s;
        }
        let c = t.cycle;
        assert!((c.total_s - t.duration_s()).abs() < 1e-12);
        assert!((c.feed_s + c.rapid_s + c.dwell_s - c.total_s).abs() < 1e-12);
        for (got, want) in [c.feed_s, c.rapid_s, c.dwell_s].iter().zip(by) {
            assert!((got - want).abs() < 1e-9, "{c:?} vs {by:?}");
        }
        assert!((c.dwell_s - 0.1).abs() < 1e-12 && c.rapid_s > 0.0 && c.feed_s > 0.0);
    }

    #[test]
    fn dwell_holds_for_p_rounded_up() {
        let limits = Limits::uniform(100.0, 1000.0);
        let t = traj("G4 P0.2505", &limits, &InterpolateOptions::default()).unwrap();
        assert_eq!(t.len(), 252);
        assert!(t.axis(AxisName::X).unwrap().pos.iter().all(|&x| x == 0.0));
    }

    #[test]
    fn sample_budget_and_bad_limits_are_errors() {
        let limits = Limits::uniform(100.0, 1000.0);
        let opts = InterpolateOptions {
            max_samples: 100,
            ..InterpolateOptions::default()
        };
        assert!(matches!(
            traj("G0 X0\nG1 X100 F600", &limits, &opts),
            Err(Error::TooManySamples { max: 100, .. })
        ));
        let mut l = limits;
        l.axes[4].max_vel = 0.0;
        assert!(matches!(
            traj("G0 B0\nG1 B1 F600", &l, &InterpolateOptions::default()),
            Err(Error::AxisCannotMove {
                axis: Some(AxisName::B),
                line: 2,
                ..
            })
        ));
        l.axes[0].max_acc = f64::NAN;
        assert!(matches!(
            traj("G0 X0", &l, &InterpolateOptions::default()),
            Err(Error::InvalidLimit {
                axis: Some(AxisName::X),
                ..
            })
        ));
        let opts = InterpolateOptions {
            ts: 0.0,
            ..InterpolateOptions::default()
        };
        assert!(traj("G0 X0", &limits, &opts).is_err());
    }

    #[test]
    fn tcp_mode_limits_the_tool_tip_path() {
        // Tip 50 mm at 50 mm/s and 500 mm/s²: T = 1 + 0.1 s. A moves 10° (10 deg/s, far from
        // its limit); X/Y axis limits do not apply to the tip.
        let mut limits = Limits::uniform(20.0, 100.0);
        limits.tcp_max_vel = 50.0;
        limits.tcp_max_acc = 500.0;
        limits.axes[3] = AxisLimits {
            max_vel: 1000.0,
            max_acc: 1.0e5,
            max_jerk: f64::INFINITY,
        };
        limits.axes[5] = limits.axes[3];
        let src = "G0 X0 Y0 Z0 A0 C0\nG43.4\nG1 X30 Y40 A10 C20 F60000";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        assert!((t.duration_s() - 1.1).abs() < 1e-12);
        assert!(t.tcp.iter().all(|&b| b));
        let vmax = (0..t.len()).map(|k| speed(&t, k)).fold(0.0, f64::max);
        assert!((vmax - 50.0).abs() < 1e-9);
        assert!(t.tcp[0]);
    }

    /// Fine-block program text: `G0` to the first point, then one `G93 G64 G1 … F60000` block
    /// (1 ms) per further point.
    fn fine_program(points: &[[f64; 2]]) -> String {
        let mut src = format!("G0 X{} Y{}\nG93 G64\n", points[0][0], points[0][1]);
        for p in &points[1..] {
            src.push_str(&format!("G1 X{} Y{} F60000\n", p[0], p[1]));
        }
        src
    }

    #[test]
    fn fine_blocks_run_as_set_points() {
        // Truth: the definition of a time-exact chain (docs/gcode.md) — sample k sits exactly on
        // the end point of block k, velocity and acceleration are the central differences
        // (time_exact_rates) with rest at both ends, and block k spans sample k alone.
        let limits = Limits::uniform(500.0, 5000.0);
        let points: Vec<[f64; 2]> = (0..60)
            .map(|k| {
                let t = k as f64 * 1e-3;
                [20.0 * t * t + 1e-7 * (k % 7) as f64, (40.0 * t).sin()]
            })
            .collect();
        let t = traj(
            &fine_program(&points),
            &limits,
            &InterpolateOptions::default(),
        )
        .unwrap();
        assert_eq!(t.len(), points.len());
        assert!((t.duration_s() - 0.059).abs() < 1e-12);
        for (i, name) in [AxisName::X, AxisName::Y].into_iter().enumerate() {
            let a = t.axis(name).unwrap();
            let pos: Vec<f64> = points.iter().map(|p| p[i]).collect();
            assert_eq!(
                a.pos, pos,
                "{name}: positions are the end points, bit for bit"
            );
            let (vel, acc) = time_exact_rates(&pos, t.ts);
            // The last sample is the trajectory's final rest.
            assert_eq!(a.vel[..pos.len() - 1], vel[..pos.len() - 1]);
            assert_eq!(a.acc[..pos.len() - 1], acc[..pos.len() - 1]);
        }
        for (k, b) in t.blocks.iter().enumerate() {
            assert_eq!(
                (b.first_sample, b.end_sample),
                (if k == 0 { 0 } else { k + 1 }, k + 2)
            );
            assert!((b.t_end_s - b.t_start_s - 1e-3).abs() < 1e-12);
            assert_eq!(b.line as usize, k + 3);
        }
        assert!(t.warnings.is_empty());
    }

    #[test]
    fn fine_blocks_too_fast_for_the_limits_run_as_exact_stops_with_a_warning() {
        // 1 mm in 1 ms is 1000 mm/s, twice the 500 mm/s limit: the chain is refused, every block
        // runs as an exact stop (the same trajectory as under G61.1), and one warning names the
        // block.
        let limits = Limits::uniform(500.0, 5000.0);
        let src = "G0 X0\nG93 G64\nG1 X0.1 F60000\nG1 X1.1 F60000\nG1 X1.2 F60000\n";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        let g61 = traj(
            &src.replace("G64", "G61.1"),
            &limits,
            &InterpolateOptions::default(),
        )
        .unwrap();
        assert_eq!(t.axes, g61.axes);
        let w: Vec<&Diagnostic> = t
            .warnings
            .iter()
            .filter(|d| d.message.contains("fine blocks"))
            .collect();
        assert_eq!(w.len(), 1, "{:?}", t.warnings);
        assert_eq!(w[0].line, 4);
        assert!(w[0].message.contains("1000.000 mm/s"), "{}", w[0].message);
    }

    #[test]
    fn blocks_of_several_periods_run_straight_in_equal_steps() {
        // Truth: the definition of a time-exact chain (module doc) — a block of m periods
        // (1/F = m·Ts) puts its j-th sample at start + (end − start)·j/m and its last on its end
        // point; velocity and acceleration are the central differences of those positions.
        let limits = Limits::uniform(500.0, 5000.0);
        let src = "G0 X0 Y0\nG93 G64\nG1 X0.003 Y0.0009 F20000\nG1 X0.005 F30000\nG1 Y0 F60000\n";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        let lerp = |a: f64, b: f64, j: f64, m: f64| a + (b - a) * (j / m);
        let x = [
            0.0,
            lerp(0.0, 0.003, 1.0, 3.0),
            lerp(0.0, 0.003, 2.0, 3.0),
            0.003,
            lerp(0.003, 0.005, 1.0, 2.0),
            0.005,
            0.005,
        ];
        let y = [
            0.0,
            lerp(0.0, 0.0009, 1.0, 3.0),
            lerp(0.0, 0.0009, 2.0, 3.0),
            0.0009,
            0.0009,
            0.0009,
            0.0,
        ];
        assert_eq!(t.axis(AxisName::X).unwrap().pos, x);
        assert_eq!(t.axis(AxisName::Y).unwrap().pos, y);
        let (vel, acc) = time_exact_rates(&x, t.ts);
        let a = t.axis(AxisName::X).unwrap();
        assert_eq!(a.vel[..6], vel[..6]);
        assert_eq!(a.acc[..6], acc[..6]);
        let lines: Vec<(u32, usize, usize)> = t
            .blocks
            .iter()
            .map(|b| (b.line, b.first_sample, b.end_sample))
            .collect();
        assert_eq!(lines, vec![(3, 0, 4), (4, 4, 6), (5, 6, 7)]);
        assert!(t.warnings.is_empty());
    }

    #[test]
    fn other_inverse_time_blocks_under_g64_are_not_set_points() {
        // 1/F = 1.5 ms is not a whole number of sample periods, and 1/F = 33 ms is longer than a
        // fine block may be: the blocks run as ordinary moves at L·F/60, a chain through their
        // collinear junction, as under G61 (exact path).
        let limits = Limits::uniform(500.0, 5000.0);
        for f in ["40000", "1818.1818"] {
            let src = format!("G0 X0\nG93 G64\nG1 X0.001 F{f}\nG1 X0.002 F{f}\n");
            let t = traj(&src, &limits, &InterpolateOptions::default()).unwrap();
            let g61 = traj(
                &src.replace("G64", "G61"),
                &limits,
                &InterpolateOptions::default(),
            )
            .unwrap();
            assert_eq!(t, g61, "F{f}");
        }
    }

    #[test]
    fn output_axes_can_be_chosen() {
        let limits = Limits::uniform(100.0, 1000.0);
        let opts = InterpolateOptions {
            axes: Some(vec![AxisName::C, AxisName::X]),
            ..InterpolateOptions::default()
        };
        let t = traj("G0 X0\nG1 X1 F600", &limits, &opts).unwrap();
        let names: Vec<AxisName> = t.axes.iter().map(|a| a.name).collect();
        assert_eq!(names, vec![AxisName::X, AxisName::C]);
        assert!(t.axis(AxisName::C).unwrap().pos.iter().all(|&c| c == 0.0));
    }
}
