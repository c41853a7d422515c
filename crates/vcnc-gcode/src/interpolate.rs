//! Trapezoidal interpolation of a [`Toolpath`] at the sample period $T_s$ (docs/gcode.md).
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
//! pure rotary move); rotary axes moving with linear ones move in proportion to $s$. Rapids
//! use the same parameter and no feed: they run at the limits.
//!
//! **Limits along the path.** For a straight move $\mathbf{g}' = \mathbf{u} = \Delta\mathbf{x}/L$
//! is constant, so axis $i$ stays within its limits when
//! $$ \dot s \le V = \min\Big(\tfrac{F}{60}, \min_i \tfrac{v_{\max,i}}{|u_i|}\Big), \qquad
//!    |\ddot s| \le A = \min_i \tfrac{a_{\max,i}}{|u_i|}. $$
//! In TCP mode X Y Z are the tool tip: instead of their axis limits the tip path limits apply,
//! $|\dot{\mathbf{p}}| \le$ `tcp_max_vel`, $|\ddot{\mathbf{p}}| \le$ `tcp_max_acc`; A B C keep
//! their own limits. On an arc of radius $r$ the in-plane velocity has magnitude
//! $\sigma R_v \dot s$ and the in-plane acceleration at most
//! $\sigma^2 R_c \dot s^2 + \sigma R_v |\ddot s|$, with $\sigma = |\Phi|/L$ (rad per unit of
//! $s$), $R_v = \sqrt{k^2 + r^2}$, $R_c = \sqrt{4k^2 + r^2}$ and $k$ the radius change per
//! radian (0 on a true circle). The centripetal term gets the fraction $\beta$
//! ([`InterpolateOptions::arc_centripetal_fraction`], default ½) of the smaller in-plane
//! acceleration limit, the tangential term the rest:
//! $$ \dot s \le \sqrt{\beta A_p / (\sigma^2 R_c)}, \qquad |\ddot s| \le (1-\beta) A_p / (\sigma R_v). $$
//! Both bounds hold for every component, so no axis exceeds its limits anywhere on the arc.
//!
//! **Exact stop** (`G61`, rapids, dwells, `G93`): each block is a rest-to-rest trapezoid. Its
//! time-optimal duration is
//! $$ T^* = \frac{L}{V} + \frac{V}{A} \quad (L \ge V^2/A), \qquad T^* = 2\sqrt{L/A} \ \text{(triangle)}, $$
//! rounded **up** to $T = \lceil T^*/T_s \rceil T_s$ by lowering the peak speed with $A$ kept:
//! $v_p = 2AL / (AT + \sqrt{A^2T^2 - 4AL})$ (the smaller root of $T = L/v_p + v_p/A$), so the
//! block ends exactly on a sample and on its programmed point.
//!
//! **Continuous path** (`G64`): consecutive `G64` feed moves (same TCP mode, same kind of path
//! parameter, no stop between them) form one chain. The junction speed between two segments is
//! limited by the junction-deviation rule (grbl, LinuxCNC's `G64 P` analogue): with $\theta$ the
//! angle between the exit and entry directions,
//! $\cos\theta = -\mathbf{t}_1\cdot\mathbf{t}_2$ and $\delta$ the deviation
//! ([`InterpolateOptions::junction_deviation`] or the move's `G64 P`),
//! $$ v_j^2 = A\,\delta\,\frac{\sin(\theta/2)}{1 - \sin(\theta/2)}, $$
//! and by a rotary-axis rule when X Y Z set the path: the jump of axis $i$'s velocity,
//! $v_j |u_{i}^{+} - u_{i}^{-}|$, may not exceed $a_{\max,i} T_s$. A backward pass (from rest at
//! the end, $v_{\text{entry}} \le \sqrt{v_{\text{exit}}^2 + 2AL}$) and a forward pass (from rest at
//! the start) then give every segment its entry and exit speeds, and each segment is a trapezoid
//! between them under its own $V$ and $A$. Collinear short segments therefore run as one
//! trapezoid over the whole chain. The chain's total duration is rounded up to a whole number of
//! samples by uniform time scaling ($t = \lambda\tau$, $\lambda \ge 1$: speeds divide by
//! $\lambda$, accelerations by $\lambda^2$). Velocity jumps at junctions are the
//! (bounded) price of a polyline; within a segment every sample honours the limits.
//!
//! **Inverse time** (`G93`): a feed block takes exactly $1/F$ minutes, rounded up to a whole
//! number of samples (exact when $60/F$ is a multiple of $T_s$): a rest-to-rest trapezoid with
//! the acceleration $A$ and the peak speed lowered as above to fit that duration.
//!
//! **Time-exact chains of fine blocks** (`G93` + `G64`, every block's $1/F$ exactly one sample
//! period $T_s$, `G1` only): such a program is a stream of set-points, one per interpolation
//! cycle, as a pre-compensated program is (docs/compensation.md). A maximal run of such blocks
//! is not re-planned: the position at sample $k$ of the chain is the end point of its block $k$,
//! and the velocity and acceleration are the central differences of those positions, the chain
//! at rest before its first and after its last block ([`time_exact_rates`]):
//! $$ \dot{\mathbf x}_k = \frac{\mathbf x_{k+1} - \mathbf x_{k-1}}{2T_s}, \qquad
//!    \ddot{\mathbf x}_k = \frac{\mathbf x_{k+1} - 2\mathbf x_k + \mathbf x_{k-1}}{T_s^2}. $$
//! Each block's speed along its path parameter must stay within the speed cap $V$ above
//! (axis, tool-tip and feed-independent limits); its acceleration is the program's affair (a
//! pre-compensated set-point has acceleration spikes the axis does not perform). A chain with
//! a block too fast for the limits runs as before — every `G93` block an exact stop — with a
//! warning naming the block. Blocks with a longer $1/F$, arcs and `G61` blocks are never part
//! of such a chain, so no other program changes.
//!
//! **Feeds the machine cannot follow** are run at its limits, as a control does, never refused:
//! a `G94` feed above a block's speed cap $V_{\lim}$ (the axis, tool-tip or centripetal limits
//! above) runs at $V_{\lim}$, slowed by the factor $F/(60 V_{\lim})$; a `G93` block whose $1/F$
//! is shorter than its time-optimal duration $T^*$ at the limits takes $T^*$, slowed by
//! $T^* F / 60$. One warning sums them up: how many blocks were slowed and the worst one (line
//! and factor); [`Trajectory::slowdown`] holds the same figures.
//!
//! **Dwell**: holds the position for $P$ seconds rounded up to $T_s$.

use crate::diag::{Diagnostic, Span};
use crate::interp::{Feed, Move, MoveKind, Toolpath};
use crate::{AxisName, Error};

pub mod stream;

/// Velocity and acceleration limit of one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisLimits {
    /// Largest speed, mm/s for X Y Z, deg/s for A B C. 0 means the axis cannot move.
    pub max_vel: f64,
    /// Largest acceleration, mm/s² for X Y Z, deg/s² for A B C. 0 means the axis cannot move.
    pub max_acc: f64,
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
}

impl Limits {
    /// The same limits on every axis and on the tool-tip path (units per s and per s²).
    pub fn uniform(max_vel: f64, max_acc: f64) -> Self {
        Limits {
            axes: [AxisLimits { max_vel, max_acc }; 6],
            tcp_max_vel: max_vel,
            tcp_max_acc: max_acc,
        }
    }
}

/// Interpolator settings. Plain data; [`Default`] gives the documented defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct InterpolateOptions {
    /// Sample period $T_s$, s. Default 0.001.
    pub ts: f64,
    /// Largest number of samples a trajectory may have; longer ones are an error. Default
    /// 10 000 000 (2.8 h at 1 ms).
    pub max_samples: usize,
    /// Junction deviation $\delta$ for `G64` corners, mm (deg for pure rotary chains), used when
    /// the move has no `G64 P`. Default 0.01.
    pub junction_deviation: f64,
    /// Axes to output; `None` (default): the axes the program uses.
    pub axes: Option<Vec<AxisName>>,
    /// Fraction $\beta$ of the acceleration limit given to the centripetal acceleration on arcs
    /// (the rest is for the tangential one), in (0, 1). Default 0.5.
    pub arc_centripetal_fraction: f64,
}

impl Default for InterpolateOptions {
    fn default() -> Self {
        InterpolateOptions {
            ts: 0.001,
            max_samples: 10_000_000,
            junction_deviation: 0.01,
            axes: None,
            arc_centripetal_fraction: 0.5,
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
    /// End time, s (exact-stop blocks end on a sample; inner `G64` segments need not).
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

/// The sampled reference trajectory.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Sample period, s.
    pub ts: f64,
    /// One track per output axis, in X Y Z A B C order.
    pub axes: Vec<AxisTrack>,
    /// Per sample: `true` when X Y Z are tool-tip coordinates (TCP mode).
    pub tcp: Vec<bool>,
    /// The moves' time spans, in order (zero-length moves have none).
    pub blocks: Vec<BlockSpan>,
    /// Feeds slowed to the machine's limits, if any.
    pub slowdown: Option<Slowdown>,
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

/// Trapezoidal (or triangular) speed profile from $v_0$ to $v_1$ over length $L$, unscaled time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Trap {
    v0: f64,
    vp: f64,
    a: f64,
    ta: f64,
    tc: f64,
    td: f64,
    la: f64,
    lc: f64,
    len: f64,
}

impl Trap {
    /// Fastest profile with entry `v0`, exit `v1`, cruise cap `vcap`, acceleration `a`.
    pub(crate) fn new(len: f64, v0: f64, v1: f64, vcap: f64, a: f64) -> Trap {
        let reach = (a * len + 0.5 * (v0 * v0 + v1 * v1)).sqrt();
        let vp = vcap.min(reach).max(v0).max(v1);
        Trap::with_peak(len, v0, v1, vp, a)
    }

    /// Rest-to-rest profile lasting `t` (≥ the optimal time) with acceleration `a`:
    /// $v_p = 2aL/(aT + \sqrt{a^2T^2 - 4aL})$.
    pub(crate) fn rest_to_rest_lasting(len: f64, a: f64, t: f64) -> Trap {
        let disc = (a * a * t * t - 4.0 * a * len).max(0.0);
        let vp = 2.0 * a * len / (a * t + disc.sqrt());
        Trap::with_peak(len, 0.0, 0.0, vp, a)
    }

    fn with_peak(len: f64, v0: f64, v1: f64, vp: f64, a: f64) -> Trap {
        let ta = ((vp - v0) / a).max(0.0);
        let td = ((vp - v1) / a).max(0.0);
        let la = (vp * vp - v0 * v0) / (2.0 * a);
        let ld = (vp * vp - v1 * v1) / (2.0 * a);
        let lc = (len - la - ld).max(0.0);
        let tc = if vp > 0.0 { lc / vp } else { 0.0 };
        Trap {
            v0,
            vp,
            a,
            ta,
            tc,
            td,
            la: la.max(0.0),
            lc,
            len,
        }
    }

    pub(crate) fn duration(&self) -> f64 {
        self.ta + self.tc + self.td
    }

    /// $(s, \dot s, \ddot s)$ at local time `tau`.
    pub(crate) fn eval(&self, tau: f64) -> (f64, f64, f64) {
        let tau = tau.max(0.0);
        let (s, sd, sdd) = if tau < self.ta {
            (
                self.v0 * tau + 0.5 * self.a * tau * tau,
                self.v0 + self.a * tau,
                self.a,
            )
        } else if tau < self.ta + self.tc {
            (self.la + self.vp * (tau - self.ta), self.vp, 0.0)
        } else if tau < self.duration() {
            let u = tau - self.ta - self.tc;
            (
                self.la + self.lc + self.vp * u - 0.5 * self.a * u * u,
                self.vp - self.a * u,
                -self.a,
            )
        } else {
            (self.len, self.vp - self.a * self.td, 0.0)
        };
        (s.clamp(0.0, self.len), sd.max(0.0), sdd)
    }
}

/// Curve of one move, $\mathbf{g}(s)$.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Geom {
    Line {
        p0: [f64; 6],
        end: [f64; 6],
        d: [f64; 6],
    },
    Arc {
        p0: [f64; 6],
        end: [f64; 6],
        u: usize,
        v: usize,
        c: [f64; 2],
        theta0: f64,
        /// Direction: +1 counter-clockwise, −1 clockwise.
        sgn: f64,
        /// |sweep|, rad.
        phi: f64,
        r0: f64,
        /// Radius change per radian, mm/rad.
        k: f64,
    },
}

/// One move ready for profiling.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Seg {
    geom: Geom,
    len: f64,
    /// Speed cap along s (feed and limits).
    vcap: f64,
    /// Speed cap from the limits alone.
    vlim: f64,
    /// Programmed `G94` speed along s (∞ for rapids and `G93` blocks).
    vfeed: f64,
    /// Acceleration cap along s.
    acap: f64,
    move_index: usize,
    /// `true`: s is the XYZ length; `false`: the rotary length.
    xyz_basis: bool,
}

impl Geom {
    /// Position, first and second derivative with respect to s.
    fn eval(&self, s: f64, len: f64) -> ([f64; 6], [f64; 6], [f64; 6]) {
        match *self {
            Geom::Line { p0, end, d } => {
                let mut p = [0.0; 6];
                let mut g1 = [0.0; 6];
                let f = s / len;
                for i in 0..6 {
                    p[i] = if s >= len { end[i] } else { p0[i] + d[i] * f };
                    g1[i] = d[i] / len;
                }
                (p, g1, [0.0; 6])
            }
            Geom::Arc {
                p0,
                end,
                u,
                v,
                c,
                theta0,
                sgn,
                phi,
                r0,
                k,
            } => {
                let sigma = phi / len;
                let f = (s / len).clamp(0.0, 1.0);
                let ph = f * phi;
                let r = r0 + k * ph;
                let a = theta0 + sgn * ph;
                let (sa, ca) = a.sin_cos();
                let mut p = [0.0; 6];
                let mut g1 = [0.0; 6];
                let mut g2 = [0.0; 6];
                for i in 0..6 {
                    p[i] = if s >= len {
                        end[i]
                    } else {
                        p0[i] + (end[i] - p0[i]) * f
                    };
                    g1[i] = (end[i] - p0[i]) / len;
                }
                if s < len {
                    p[u] = c[0] + r * ca;
                    p[v] = c[1] + r * sa;
                }
                g1[u] = (k * ca - sgn * r * sa) * sigma;
                g1[v] = (k * sa + sgn * r * ca) * sigma;
                g2[u] = (-2.0 * sgn * k * sa - r * ca) * sigma * sigma;
                g2[v] = (2.0 * sgn * k * ca - r * sa) * sigma * sigma;
                (p, g1, g2)
            }
        }
    }
}

fn norm3(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

pub(crate) fn check_limits(limits: &Limits, opts: &InterpolateOptions) -> Result<(), Error> {
    for (i, l) in limits.axes.iter().enumerate() {
        for (name, value) in [("max_vel", l.max_vel), ("max_acc", l.max_acc)] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(Error::InvalidLimit {
                    axis: AxisName::from_index(i),
                    name,
                    value,
                });
            }
        }
    }
    for (name, value) in [
        ("tcp_max_vel", limits.tcp_max_vel),
        ("tcp_max_acc", limits.tcp_max_acc),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(Error::InvalidLimit {
                axis: None,
                name,
                value,
            });
        }
    }
    let bad = |name: &'static str, value: f64, expected: &'static str| Error::InvalidOption {
        name,
        value,
        expected,
    };
    if !(opts.ts.is_finite() && opts.ts > 0.0) {
        return Err(bad("ts", opts.ts, "a positive number of seconds"));
    }
    if !(opts.junction_deviation.is_finite() && opts.junction_deviation >= 0.0) {
        return Err(bad(
            "junction_deviation",
            opts.junction_deviation,
            "a non-negative length",
        ));
    }
    let beta = opts.arc_centripetal_fraction;
    if !(beta > 0.0 && beta < 1.0) {
        return Err(bad(
            "arc_centripetal_fraction",
            beta,
            "a fraction in (0, 1)",
        ));
    }
    Ok(())
}

/// Build the segment of a motion move; `None` for a zero-length move.
pub(crate) fn segment(
    mv: &Move,
    index: usize,
    limits: &Limits,
    opts: &InterpolateOptions,
) -> Result<Option<Seg>, Error> {
    let d: [f64; 6] = std::array::from_fn(|i| mv.end[i] - mv.start[i]);
    let cannot = |axis: usize, what: &'static str| Error::AxisCannotMove {
        axis: AxisName::from_index(axis),
        what,
        line: mv.line,
    };
    let tcp_cannot = |what: &'static str| Error::AxisCannotMove {
        axis: None,
        what,
        line: mv.line,
    };
    let mut vlim = f64::INFINITY;
    let mut acap = f64::INFINITY;
    // Per-axis limit on a component that moves with rate `rate` per unit of s.
    let per_axis = |i: usize, rate: f64, vlim: &mut f64, acap: &mut f64| -> Result<(), Error> {
        if rate == 0.0 {
            return Ok(());
        }
        let l = limits.axes[i];
        if l.max_vel <= 0.0 {
            return Err(cannot(i, "velocity"));
        }
        if l.max_acc <= 0.0 {
            return Err(cannot(i, "acceleration"));
        }
        *vlim = vlim.min(l.max_vel / rate.abs());
        *acap = acap.min(l.max_acc / rate.abs());
        Ok(())
    };
    let beta = opts.arc_centripetal_fraction;
    let (geom, len, xyz_basis) = match mv.kind {
        MoveKind::Dwell { .. } => return Ok(None),
        MoveKind::Rapid | MoveKind::Linear => {
            let xyz = norm3(&d[0..3]);
            let rot = norm3(&d[3..6]);
            let (len, xyz_basis) = if xyz > 0.0 {
                (xyz, true)
            } else if rot > 0.0 {
                (rot, false)
            } else {
                return Ok(None);
            };
            for (i, &di) in d.iter().enumerate() {
                if mv.tcp && i < 3 {
                    continue;
                }
                per_axis(i, di / len, &mut vlim, &mut acap)?;
            }
            if mv.tcp && xyz > 0.0 {
                let rate = xyz / len;
                if limits.tcp_max_vel <= 0.0 {
                    return Err(tcp_cannot("velocity"));
                }
                if limits.tcp_max_acc <= 0.0 {
                    return Err(tcp_cannot("acceleration"));
                }
                vlim = vlim.min(limits.tcp_max_vel / rate);
                acap = acap.min(limits.tcp_max_acc / rate);
            }
            (
                Geom::Line {
                    p0: mv.start,
                    end: mv.end,
                    d,
                },
                len,
                xyz_basis,
            )
        }
        MoveKind::Arc(arc) => {
            let (u, v, w) = arc.plane.axes();
            let phi = arc.sweep_rad.abs();
            let r0 = arc.radius_start_mm;
            let r1 = arc.radius_end_mm;
            let k = (r1 - r0) / phi;
            let rmax = r0.max(r1);
            let planar = 0.5 * (r0 + r1) * phi;
            let len = planar.hypot(d[w]);
            if !(len > 0.0 && len.is_finite()) {
                return Ok(None);
            }
            let sigma = phi / len;
            let rv = k.hypot(rmax);
            let rc = (2.0 * k).hypot(rmax);
            for i in [w, 3, 4, 5] {
                if mv.tcp && i < 3 {
                    continue;
                }
                per_axis(i, d[i] / len, &mut vlim, &mut acap)?;
            }
            let (vp, ap, rt) = if mv.tcp {
                if limits.tcp_max_vel <= 0.0 {
                    return Err(tcp_cannot("velocity"));
                }
                if limits.tcp_max_acc <= 0.0 {
                    return Err(tcp_cannot("acceleration"));
                }
                (limits.tcp_max_vel, limits.tcp_max_acc, rv.hypot(d[w] / phi))
            } else {
                for i in [u, v] {
                    if limits.axes[i].max_vel <= 0.0 {
                        return Err(cannot(i, "velocity"));
                    }
                    if limits.axes[i].max_acc <= 0.0 {
                        return Err(cannot(i, "acceleration"));
                    }
                }
                (
                    limits.axes[u].max_vel.min(limits.axes[v].max_vel),
                    limits.axes[u].max_acc.min(limits.axes[v].max_acc),
                    rv,
                )
            };
            vlim = vlim
                .min(vp / (sigma * rt))
                .min((beta * ap / (sigma * sigma * rc)).sqrt());
            acap = acap.min((1.0 - beta) * ap / (sigma * rt));
            let (sa, ca) = (mv.start[v] - arc.centre[1], mv.start[u] - arc.centre[0]);
            (
                Geom::Arc {
                    p0: mv.start,
                    end: mv.end,
                    u,
                    v,
                    c: arc.centre,
                    theta0: sa.atan2(ca),
                    sgn: arc.sweep_rad.signum(),
                    phi,
                    r0,
                    k,
                },
                len,
                true,
            )
        }
    };
    let vfeed = match mv.feed {
        Some(Feed::UnitsPerMin(f)) => f / 60.0,
        _ => f64::INFINITY,
    };
    let vcap = vfeed.min(vlim);
    if !(vcap > 0.0 && acap > 0.0 && vlim.is_finite() && acap.is_finite() && len.is_finite()) {
        return Err(Error::NonFinite {
            line: mv.line,
            what: "path speed or acceleration cap",
        });
    }
    Ok(Some(Seg {
        geom,
        len,
        vcap,
        vlim,
        vfeed,
        acap,
        move_index: index,
        xyz_basis,
    }))
}

/// A stretch of the timeline: a hold or a chain of segments with their profiles.
#[derive(Debug, Clone)]
pub(crate) struct Piece {
    /// Samples in the piece (its duration is `n · ts`).
    n: u64,
    /// Time scale λ ≥ 1 (t = λ τ).
    lambda: f64,
    /// Segments with their profile and unscaled start time.
    segs: Vec<(Seg, Trap, f64)>,
    /// Hold position (dwell) when `segs` is empty.
    hold: [f64; 6],
    /// Move index of a dwell.
    dwell_move: Option<usize>,
    tcp: bool,
    /// A time-exact chain of fine blocks (module doc): its positions at the samples.
    exact: Option<Exact>,
}

/// The samples of a time-exact chain: `points[j]` is the position at the piece's sample `j`
/// (`points[0]` the start, `points[n]` the end); `moves[j]` the move that ends on `points[j + 1]`.
#[derive(Debug, Clone)]
pub(crate) struct Exact {
    points: Vec<[f64; 6]>,
    moves: Vec<usize>,
}

/// Number of whole samples covering `t` seconds (tolerating round-off just above a multiple).
pub(crate) fn samples_for(t: f64, ts: f64, max: usize) -> Result<u64, Error> {
    let n = (t / ts - 1e-9).ceil().max(0.0);
    if !n.is_finite() || n > max as f64 {
        return Err(Error::TooManySamples {
            samples: n,
            max,
            duration_s: t,
        });
    }
    Ok(n as u64)
}

/// Rest-to-rest piece for one segment lasting at least `t_min` rounded up (exact stop).
pub(crate) fn single(
    seg: Seg,
    tcp: bool,
    t_req: Option<f64>,
    ts: f64,
    max: usize,
) -> Result<Piece, Error> {
    let opt = Trap::new(seg.len, 0.0, 0.0, seg.vcap, seg.acap);
    let target = t_req.unwrap_or(opt.duration()).max(opt.duration());
    let n = samples_for(target, ts, max)?;
    let t = n as f64 * ts;
    let trap = if t > opt.duration() {
        Trap::rest_to_rest_lasting(seg.len, seg.acap, t)
    } else {
        opt
    };
    let lambda = (t / trap.duration()).max(1.0);
    Ok(Piece {
        n,
        lambda,
        segs: vec![(seg, trap, 0.0)],
        hold: [0.0; 6],
        dwell_move: None,
        tcp,
        exact: None,
    })
}

/// The rest-to-rest piece of a block run on its own (exact stop, `G93`, rapid): a `G93` block
/// lasts its $1/F$ (at least $T^*$, the feed cap not applying), any other block its rounded
/// time-optimal duration; a block slowed to the limits is noted in `slowed`.
pub(crate) fn exact_stop_piece(
    seg: Seg,
    mv: &Move,
    slowed: &mut Slowed,
    ts: f64,
    max: usize,
) -> Result<Piece, Error> {
    match mv.feed {
        Some(Feed::InverseTime(f)) => {
            let want = 60.0 / f;
            let t_min = Trap::new(seg.len, 0.0, 0.0, seg.vlim, seg.acap).duration();
            if want < t_min * (1.0 - 1e-12) {
                slowed.note(
                    t_min / want,
                    mv,
                    Cause::InverseTime {
                        want_s: want,
                        min_s: t_min,
                        f,
                    },
                );
            }
            // The feed cap does not apply: the duration does (at least T*).
            let seg = Seg {
                vcap: seg.vlim,
                ..seg
            };
            single(seg, mv.tcp, Some(want), ts, max)
        }
        _ => {
            slowed.feed(&seg, mv);
            single(seg, mv.tcp, None, ts, max)
        }
    }
}

/// Position, velocity and acceleration at unscaled time `tau_rel` into a segment's profile, the
/// chain's time scale applied ($\dot s / \lambda$, $\ddot s / \lambda^2$ with `inv` = 1/λ,
/// `inv2` = 1/λ²; module doc).
pub(crate) fn eval_scaled(
    seg: &Seg,
    trap: &Trap,
    tau_rel: f64,
    inv: f64,
    inv2: f64,
) -> ([f64; 6], [f64; 6], [f64; 6]) {
    let (s, sd, sdd) = trap.eval(tau_rel);
    let (sd, sdd) = (sd * inv, sdd * inv2);
    let (p, g1, g2) = seg.geom.eval(s, seg.len);
    let mut v = [0.0; 6];
    let mut a = [0.0; 6];
    for i in 0..6 {
        v[i] = g1[i] * sd;
        a[i] = g2[i] * sd * sd + g1[i] * sdd;
    }
    (p, v, a)
}

/// Velocity and acceleration at `b` of a time-exact chain from its neighbours `a` and `c`
/// (central differences, [`time_exact_rates`]).
pub(crate) fn central_rates(
    a: &[f64; 6],
    b: &[f64; 6],
    c: &[f64; 6],
    ts: f64,
) -> ([f64; 6], [f64; 6]) {
    let v = std::array::from_fn(|i| (c[i] - a[i]) / (2.0 * ts));
    let acc = std::array::from_fn(|i| (c[i] - 2.0 * b[i] + a[i]) / (ts * ts));
    (v, acc)
}

/// First and one-past-last sample (within a piece of `n` samples) of the span of a chain's
/// segment starting at unscaled time `tau0` and lasting `dur`: samples $k$ with
/// $t_\text{start} < t_k \le t_\text{end}$ ([`BlockSpan::first_sample`]); the first segment
/// starts at 0, the last ends on the piece's last sample.
pub(crate) fn chain_span(
    tau0: f64,
    dur: f64,
    lam: f64,
    n: usize,
    ts: f64,
    first: bool,
    last: bool,
) -> (usize, usize) {
    let last_in = |t_rel: f64| ((t_rel / ts + 1e-9).floor().max(0.0) as usize).min(n);
    let k_end = if last { n } else { last_in(lam * (tau0 + dur)) };
    let k_first = if first { 0 } else { last_in(lam * tau0) };
    (k_first, k_end.max(k_first))
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

/// Junction speed cap between `a` (exit) and `b` (entry).
pub(crate) fn junction(a: &Seg, b: &Seg, delta: f64, limits: &Limits, ts: f64) -> f64 {
    let (_, ta, _) = a.geom.eval(a.len, a.len);
    let (_, tb, _) = b.geom.eval(0.0, b.len);
    let range = if a.xyz_basis { 0..3 } else { 3..6 };
    let na = norm3(&ta[range.clone()]);
    let nb = norm3(&tb[range.clone()]);
    let mut vj = a.vcap.min(b.vcap);
    if !(na > 0.0 && nb > 0.0) {
        return 0.0;
    }
    let dot: f64 = range.clone().map(|i| ta[i] * tb[i]).sum::<f64>() / (na * nb);
    let cos_theta = -dot;
    if cos_theta > 0.999_999 {
        return 0.0;
    }
    if cos_theta > -0.999_999 {
        let sin_half = (0.5 * (1.0 - cos_theta)).sqrt();
        let acc = a.acap.min(b.acap);
        vj = vj.min((acc * delta * sin_half / (1.0 - sin_half)).sqrt());
    }
    if a.xyz_basis {
        for i in 3..6 {
            let jump = (tb[i] - ta[i]).abs();
            if jump > 0.0 {
                vj = vj.min(limits.axes[i].max_acc * ts / jump);
            }
        }
    }
    vj.max(0.0)
}

/// Look-ahead over a chain of ≥ 2 segments: junction caps, backward and forward passes.
fn chain(
    segs: Vec<Seg>,
    deltas: &[f64],
    tcp: bool,
    limits: &Limits,
    ts: f64,
    max: usize,
) -> Result<Piece, Error> {
    let m = segs.len();
    let mut vj = vec![0.0; m + 1];
    for i in 1..m {
        vj[i] = junction(&segs[i - 1], &segs[i], deltas[i], limits, ts);
    }
    // Backward pass: vj[i] is the speed at the start of segment i (end of i − 1).
    for i in (0..m).rev() {
        let reach = (vj[i + 1] * vj[i + 1] + 2.0 * segs[i].acap * segs[i].len).sqrt();
        vj[i] = vj[i].min(reach);
    }
    vj[0] = 0.0;
    vj[m] = 0.0;
    // Forward pass.
    for i in 0..m {
        let reach = (vj[i] * vj[i] + 2.0 * segs[i].acap * segs[i].len).sqrt();
        vj[i + 1] = vj[i + 1].min(reach);
    }
    let mut out = Vec::with_capacity(m);
    let mut t = 0.0;
    for (i, seg) in segs.into_iter().enumerate() {
        let trap = Trap::new(seg.len, vj[i], vj[i + 1], seg.vcap, seg.acap);
        let d = trap.duration();
        out.push((seg, trap, t));
        t += d;
    }
    let n = samples_for(t, ts, max)?;
    let lambda = (n as f64 * ts / t).max(1.0);
    Ok(Piece {
        n,
        lambda,
        segs: out,
        hold: [0.0; 6],
        dwell_move: None,
        tcp,
        exact: None,
    })
}

/// A fine block: `G1` under `G93` and `G64` whose $1/F$ is exactly one sample period (within
/// $10^{-9}$ relative), the element of a time-exact chain (module doc).
pub(crate) fn fine_block(mv: &Move, ts: f64) -> bool {
    !mv.exact_stop
        && matches!(mv.kind, MoveKind::Linear)
        && matches!(mv.feed, Some(Feed::InverseTime(f)) if (60.0 / (f * ts) - 1.0).abs() <= 1e-9)
}

/// What became of a chain of fine blocks; `next` is the index of the first move after it.
enum Chain {
    /// Run time-exactly as this piece.
    Exact { piece: Piece, next: usize },
    /// A block is faster than the limits allow: the blocks run as before, block by block, with
    /// this warning.
    Refused { next: usize, warning: Diagnostic },
}

/// The time-exact chain of fine blocks starting at move `i` (module doc).
fn time_exact_chain(
    tp: &Toolpath,
    i: usize,
    limits: &Limits,
    opts: &InterpolateOptions,
) -> Result<Chain, Error> {
    let ts = opts.ts;
    let first = &tp.moves[i];
    let mut points = vec![first.start];
    let mut moves = Vec::new();
    let mut refusal: Option<(f64, f64, &Move, bool)> = None;
    let mut j = i;
    while j < tp.moves.len() {
        let m = &tp.moves[j];
        if !fine_block(m, ts) || m.tcp != first.tcp {
            break;
        }
        if let Some(seg) = segment(m, j, limits, opts)? {
            // The block's speed along its path parameter against the limits' speed cap.
            let speed = seg.len / ts;
            if speed > seg.vlim * (1.0 + 1e-9)
                && refusal.is_none_or(|r| speed / seg.vlim > r.0 / r.1)
            {
                refusal = Some((speed, seg.vlim, m, !seg.xyz_basis));
            }
            points.push(m.end);
            moves.push(j);
        }
        j += 1;
        if m.stop_after {
            break;
        }
    }
    if let Some((speed, cap, m, deg)) = refusal {
        let unit = if deg { "deg" } else { "mm" };
        let message = format!(
            "the {} fine blocks from line {} (G93 G64, 1/F = one sample period) are not run as set-points: line {} needs {speed:.3} {unit}/s along its path, the limits allow {cap:.3} {unit}/s; each block runs as an exact stop",
            j - i,
            first.line,
            m.line
        );
        let span = Span {
            line: m.line,
            col: m.col,
            start: 0,
            end: 0,
        };
        return Ok(Chain::Refused {
            next: j,
            warning: Diagnostic::warning(span, message),
        });
    }
    let n = moves.len() as u64;
    Ok(Chain::Exact {
        piece: Piece {
            n,
            lambda: 1.0,
            segs: Vec::new(),
            hold: first.start,
            dwell_move: None,
            tcp: first.tcp,
            exact: Some(Exact { points, moves }),
        },
        next: j,
    })
}

pub(crate) fn continuous(mv: &Move) -> bool {
    !mv.exact_stop
        && matches!(mv.feed, Some(Feed::UnitsPerMin(_)))
        && matches!(mv.kind, MoveKind::Linear | MoveKind::Arc(_))
}

/// Why a block was slowed (numbers only: the message is built once, for the worst block).
#[derive(Clone, Copy)]
pub(crate) enum Cause {
    /// `G94`: programmed speed and the cap, along s (mm/s or deg/s).
    Feed { v_feed: f64, v_lim: f64, deg: bool },
    /// `G93`: requested and shortest durations, s, and F (1/min).
    InverseTime { want_s: f64, min_s: f64, f: f64 },
}

/// Blocks slowed to the limits: the count and the worst (factor, line, column, cause).
#[derive(Default)]
pub(crate) struct Slowed {
    count: usize,
    worst: Option<(f64, u32, u32, Cause)>,
}

impl Slowed {
    /// Note a `G94` segment whose feed is above its speed cap.
    pub(crate) fn feed(&mut self, seg: &Seg, mv: &Move) {
        if seg.vfeed.is_finite() && seg.vfeed > seg.vlim * (1.0 + 1e-9) {
            let cause = Cause::Feed {
                v_feed: seg.vfeed,
                v_lim: seg.vlim,
                deg: !seg.xyz_basis,
            };
            self.note(seg.vfeed / seg.vlim, mv, cause);
        }
    }

    /// The notes of `later` (taken in order after these), as if noted here one by one.
    pub(crate) fn merge(&mut self, later: Slowed) {
        self.count += later.count;
        if let Some(w) = later.worst
            && self.worst.is_none_or(|s| w.0 > s.0)
        {
            self.worst = Some(w);
        }
    }

    pub(crate) fn note(&mut self, factor: f64, mv: &Move, cause: Cause) {
        self.count += 1;
        if self.worst.is_none_or(|w| factor > w.0) {
            self.worst = Some((factor, mv.line, mv.col, cause));
        }
    }

    pub(crate) fn finish(self, warnings: &mut Vec<Diagnostic>) -> Option<Slowdown> {
        let (factor, line, col, cause) = self.worst?;
        let detail = match cause {
            Cause::Feed { v_feed, v_lim, deg } => {
                let unit = if deg { "deg" } else { "mm" };
                format!(
                    "F{} asks for {v_feed:.3} {unit}/s, the limits allow {v_lim:.3} {unit}/s",
                    fmt_num(v_feed * 60.0)
                )
            }
            Cause::InverseTime { want_s, min_s, f } => format!(
                "inverse time F{} asks for {want_s:.4} s, the limits need {min_s:.4} s",
                fmt_num(f)
            ),
        };
        warnings.push(Diagnostic::warning(
            Span {
                line,
                col,
                start: 0,
                end: 0,
            },
            format!(
                "{} feed block(s) run slower than programmed, at the machine's limits; the worst is line {line} ({detail}): {factor:.3} times slower",
                self.count
            ),
        ));
        Some(Slowdown {
            blocks: self.count,
            worst_line: line,
            worst_factor: factor,
        })
    }
}

/// A number without trailing zeros.
fn fmt_num(x: f64) -> String {
    let s = format!("{x:.4}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Interpolate a toolpath into samples (module doc).
pub fn interpolate(
    tp: &Toolpath,
    limits: &Limits,
    opts: &InterpolateOptions,
) -> Result<Trajectory, Error> {
    check_limits(limits, opts)?;
    let ts = opts.ts;
    let max = opts.max_samples;
    let mut slowed = Slowed::default();
    let mut pieces: Vec<Piece> = Vec::new();
    let mut total: u64 = 0;
    let push = |p: Piece, total: &mut u64, pieces: &mut Vec<Piece>| -> Result<(), Error> {
        *total += p.n;
        if *total + 1 > max as u64 {
            return Err(Error::TooManySamples {
                samples: (*total + 1) as f64,
                max,
                duration_s: *total as f64 * ts,
            });
        }
        pieces.push(p);
        Ok(())
    };
    let mut i = 0;
    // Fine blocks before this move index run as exact stops (their chain was refused).
    let mut not_exact_until = 0;
    let mut warnings_early: Vec<Diagnostic> = Vec::new();
    while i < tp.moves.len() {
        let mv = &tp.moves[i];
        if let MoveKind::Dwell { seconds } = mv.kind {
            let n = samples_for(seconds, ts, max)?;
            let p = Piece {
                n,
                lambda: 1.0,
                segs: Vec::new(),
                hold: mv.start,
                dwell_move: Some(i),
                tcp: mv.tcp,
                exact: None,
            };
            push(p, &mut total, &mut pieces)?;
            i += 1;
            continue;
        }
        if i >= not_exact_until && fine_block(mv, ts) {
            match time_exact_chain(tp, i, limits, opts)? {
                Chain::Exact { piece, next } => {
                    push(piece, &mut total, &mut pieces)?;
                    i = next;
                    continue;
                }
                Chain::Refused { next, warning } => {
                    // Run these blocks as before (each an exact stop), and say why.
                    warnings_early.push(warning);
                    not_exact_until = next;
                }
            }
        }
        if continuous(mv) {
            // Gather the chain.
            let mut segs = Vec::new();
            let mut deltas = Vec::new();
            let mut j = i;
            let mut basis = None;
            while j < tp.moves.len() {
                let m = &tp.moves[j];
                if !continuous(m) || m.tcp != mv.tcp {
                    break;
                }
                if let Some(seg) = segment(m, j, limits, opts)? {
                    if basis.is_some_and(|b| b != seg.xyz_basis) {
                        break;
                    }
                    basis = Some(seg.xyz_basis);
                    slowed.feed(&seg, m);
                    segs.push(seg);
                    deltas.push(m.blend_tolerance_mm.unwrap_or(opts.junction_deviation));
                }
                j += 1;
                if m.stop_after {
                    break;
                }
            }
            match segs.len() {
                0 => {}
                1 => {
                    let seg = segs[0];
                    push(single(seg, mv.tcp, None, ts, max)?, &mut total, &mut pieces)?;
                }
                _ => push(
                    chain(segs, &deltas, mv.tcp, limits, ts, max)?,
                    &mut total,
                    &mut pieces,
                )?,
            }
            i = j.max(i + 1);
            continue;
        }
        if let Some(seg) = segment(mv, i, limits, opts)? {
            let piece = exact_stop_piece(seg, mv, &mut slowed, ts, max)?;
            push(piece, &mut total, &mut pieces)?;
        }
        i += 1;
    }
    let mut warnings = warnings_early;
    let slowdown = slowed.finish(&mut warnings);
    let mut t = sample(tp, &pieces, total, opts, warnings)?;
    t.slowdown = slowdown;
    Ok(t)
}

/// Fill the sample arrays.
fn sample(
    tp: &Toolpath,
    pieces: &[Piece],
    total: u64,
    opts: &InterpolateOptions,
    warnings: Vec<Diagnostic>,
) -> Result<Trajectory, Error> {
    let ts = opts.ts;
    let names = output_axes(opts, tp.axes_used);
    let idx: Vec<usize> = names.iter().map(|a| a.index()).collect();
    let len = usize::try_from(total + 1).map_err(|_| Error::TooManySamples {
        samples: (total + 1) as f64,
        max: opts.max_samples,
        duration_s: total as f64 * ts,
    })?;
    let mut axes: Vec<AxisTrack> = names
        .iter()
        .map(|&name| AxisTrack {
            name,
            pos: Vec::with_capacity(len),
            vel: Vec::with_capacity(len),
            acc: Vec::with_capacity(len),
        })
        .collect();
    let mut tcp = Vec::with_capacity(len);
    let mut blocks = Vec::with_capacity(tp.moves.len());
    let emit = |p: &[f64; 6], v: &[f64; 6], a: &[f64; 6], axes: &mut [AxisTrack]| {
        for (track, &i) in axes.iter_mut().zip(&idx) {
            track.pos.push(p[i]);
            track.vel.push(v[i]);
            track.acc.push(a[i]);
        }
    };
    let zero = [0.0; 6];
    let class = |mi: usize| {
        tp.moves
            .get(mi)
            .map_or(MoveClass::Feed, |m| MoveClass::of(&m.kind))
    };
    let mut k0: u64 = 0;
    for piece in pieces {
        let t0 = k0 as f64 * ts;
        let lam = piece.lambda;
        // Samples k with t_start < t_k ≤ t_end belong to a span (BlockSpan::first_sample).
        let base = k0 as usize;
        let n = piece.n as usize;
        if let Some(ex) = &piece.exact {
            // Time-exact: the positions are the block end points; velocity and acceleration
            // are their central differences, at rest before and after (time_exact_rates).
            for (j, &mi) in ex.moves.iter().enumerate() {
                blocks.push(BlockSpan {
                    move_index: mi,
                    line: tp.moves.get(mi).map_or(0, |m| m.line),
                    class: class(mi),
                    t_start_s: t0 + j as f64 * ts,
                    t_end_s: t0 + (j + 1) as f64 * ts,
                    first_sample: base + j + 1,
                    end_sample: base + j + 2,
                    tcp: piece.tcp,
                });
            }
            let last = ex.points.len() - 1;
            for j in 0..n {
                let (a, b, c) = (
                    &ex.points[j.saturating_sub(1)],
                    &ex.points[j],
                    &ex.points[(j + 1).min(last)],
                );
                let (v, acc) = central_rates(a, b, c, ts);
                emit(b, &v, &acc, &mut axes);
                tcp.push(piece.tcp);
            }
        } else if piece.segs.is_empty() {
            if let Some(mi) = piece.dwell_move {
                blocks.push(BlockSpan {
                    move_index: mi,
                    line: tp.moves.get(mi).map_or(0, |m| m.line),
                    class: class(mi),
                    t_start_s: t0,
                    t_end_s: t0 + piece.n as f64 * ts,
                    first_sample: base + 1,
                    end_sample: base + n + 1,
                    tcp: piece.tcp,
                });
            }
            for _ in 0..piece.n {
                emit(&piece.hold, &zero, &zero, &mut axes);
                tcp.push(piece.tcp);
            }
        } else {
            let last = piece.segs.len() - 1;
            for (j, (seg, trap, tau0)) in piece.segs.iter().enumerate() {
                let t_end = if j == last {
                    t0 + piece.n as f64 * ts
                } else {
                    t0 + lam * (tau0 + trap.duration())
                };
                let (k_first, k_end) =
                    chain_span(*tau0, trap.duration(), lam, n, ts, j == 0, j == last);
                blocks.push(BlockSpan {
                    move_index: seg.move_index,
                    line: tp.moves.get(seg.move_index).map_or(0, |m| m.line),
                    class: class(seg.move_index),
                    t_start_s: t0 + lam * tau0,
                    t_end_s: t_end,
                    first_sample: base + k_first + 1,
                    end_sample: base + k_end + 1,
                    tcp: piece.tcp,
                });
            }
            let mut cur = 0usize;
            let (inv, inv2) = (1.0 / lam, 1.0 / (lam * lam));
            for j in 0..piece.n {
                let tau = j as f64 * ts * inv;
                while cur < last && tau >= piece.segs[cur + 1].2 {
                    cur += 1;
                }
                let (seg, trap, tau0) = &piece.segs[cur];
                let (p, v, a) = eval_scaled(seg, trap, tau - tau0, inv, inv2);
                emit(&p, &v, &a, &mut axes);
                tcp.push(piece.tcp);
            }
        }
        k0 += piece.n;
    }
    // Final sample: at rest on the last programmed point.
    let end = tp.moves.last().map_or(tp.start, |m| m.end);
    emit(&end, &zero, &zero, &mut axes);
    tcp.push(tp.moves.last().is_some_and(|m| m.tcp));
    if let Some(first) = blocks.first_mut() {
        first.first_sample = 0;
    }
    Ok(Trajectory {
        ts,
        axes,
        tcp,
        blocks,
        slowdown: None,
        warnings,
    })
}

#[cfg(test)]
mod tests {
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
    fn g64_corner_speed_follows_the_junction_deviation() {
        // 90° corner: cos θ = 0, sin(θ/2) = √½, v_j² = A δ sin/(1 − sin) (grbl's rule).
        let (a, delta) = (1000.0, 0.01);
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let vj = (a * delta * s / (1.0 - s)).sqrt();
        let limits = Limits::uniform(500.0, a);
        let t = traj(
            "G64 G0 X0 Y0\nG1 X10 F6000\nY10",
            &limits,
            &InterpolateOptions::default(),
        )
        .unwrap();
        let corner = t.blocks[0].t_end_s;
        let k = (corner / t.ts).floor() as usize;
        // The speed changes by at most A·Ts between samples around the corner.
        for kk in [k, k + 1] {
            assert!(
                (speed(&t, kk) - vj).abs() <= a * t.ts + 1e-9,
                "{} vs {vj}",
                speed(&t, kk)
            );
        }
        assert!(vj > 0.0);
    }

    #[test]
    fn inverse_time_blocks_last_one_over_f() {
        let limits = Limits::uniform(100.0, 1000.0);
        let src = "G0 X0\nG93 G1 X10 F60\nG1 X12 F120\nG1 X13 F600\nG3 X15 Y2 R2 F30";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        let d: Vec<f64> = t.blocks.iter().map(|b| b.t_end_s - b.t_start_s).collect();
        for (got, want) in d.iter().zip([1.0, 0.5, 0.1, 2.0]) {
            assert!((got - want).abs() < 1e-12, "{d:?}");
        }
        assert_eq!(t.axis(AxisName::X).unwrap().pos.last(), Some(&15.0));
        // 100 mm in 0.1 s cannot be done at 100 mm/s: it runs at the limits (T* = 1.1 s),
        // 11 times slower, with one summary warning naming the line.
        let src = "G0 X0\nG93 G1 X100 F600\nG1 X0 F300\nG94 G1 X10 F60000";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        let d: Vec<f64> = t.blocks.iter().map(|b| b.t_end_s - b.t_start_s).collect();
        assert!(
            (d[0] - 1.1).abs() < 1e-12 && (d[1] - 1.1).abs() < 1e-12,
            "{d:?}"
        );
        assert_eq!(t.warnings.len(), 1);
        assert_eq!(t.warnings[0].line, 2);
        assert!(
            t.warnings[0].message.starts_with("3 feed block(s)"),
            "{}",
            t.warnings[0].message
        );
        let s = t.slowdown.unwrap();
        assert_eq!((s.blocks, s.worst_line), (3, 2));
        assert!((s.worst_factor - 11.0).abs() < 1e-9);
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
        // runs as the G93 exact stop it was before (the same trajectory as under G61), and one
        // warning names the block.
        let limits = Limits::uniform(500.0, 5000.0);
        let src = "G0 X0\nG93 G64\nG1 X0.1 F60000\nG1 X1.1 F60000\nG1 X1.2 F60000\n";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        let g61 = traj(
            &src.replace("G64", "G61"),
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
    fn longer_inverse_time_blocks_under_g64_are_not_set_points() {
        // 1/F = 2 ms is not one sample period: the blocks keep their exact-stop trapezoids.
        let limits = Limits::uniform(500.0, 5000.0);
        let src = "G0 X0\nG93 G64\nG1 X0.001 F30000\nG1 X0.002 F30000\n";
        let t = traj(src, &limits, &InterpolateOptions::default()).unwrap();
        let g61 = traj(
            &src.replace("G64", "G61"),
            &limits,
            &InterpolateOptions::default(),
        )
        .unwrap();
        assert_eq!(t, g61);
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
