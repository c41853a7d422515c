//! The planner: moves in, one at a time, samples out. The whole-program interpolation
//! ([`crate::interpolate`]) and the streamed one ([`crate::plan`], [`crate::StreamPlan::sample`])
//! both run it, twice: a first pass that plans without sampling and decides what cannot be known
//! before a chain's end (its sample count and time scale, whether a chain of fine blocks runs
//! time-exactly), and a second that plans again and samples. One planner, so the two give the
//! same samples bit for bit.
//!
//! A move becomes, in order of precedence:
//! - a **dwell**: the position held for $P$ rounded up to whole samples;
//! - part of a **chain of fine blocks** (`G93 G64`, $1/F$ one sample period): set-points;
//! - merged with its neighbours under `G64 Q` (straight feeds within $Q$ of one line);
//! - part of a **chain** ([`super::chain`]): moves joined without a stop (`G61`, `G64`);
//! - a block **on its own** (`G61.1`, or a chain of one), rest to rest: a trapezoid, or the
//!   seven-phase profile under the jerk-limited profile, its time-optimal duration rounded up to
//!   whole samples.

use std::collections::VecDeque;

use super::chain::{Elem, Out, Piece, Plan, Planned, Prof, Sampler};
use super::corner::{JerkJump, Joint, Side, joint};
use super::geom::Geom;
use super::profile::{SCurve, Trap};
use super::segment::{Cfg, Seg, segment};
use super::{CycleTime, MoveClass, Slowdown};
use crate::Error;
use crate::diag::{Diagnostic, Span};
use crate::interp::{Feed, Move, MoveKind, PathMode};

/// Per chain, in program order, what the second pass cannot know before the chain's end.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Decisions {
    /// Chains of ≥ 2 elements: sample count and time scale λ.
    pub(crate) chains: VecDeque<(u64, f64)>,
    /// Fine-block chains: `true` when run time-exactly.
    pub(crate) fine: VecDeque<bool>,
}

/// Plan only, or plan and sample.
pub(crate) enum Mode<'d, 'o> {
    Plan(&'d mut Decisions),
    Sample {
        decisions: &'d mut Decisions,
        out: &'o mut dyn Out,
    },
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

/// Velocity and acceleration at `b` of a time-exact chain from its neighbours `a` and `c`
/// (central differences, [`super::time_exact_rates`]).
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

/// The most sample periods a fine block may last: a `G93` block of up to 32 periods whose
/// $1/F$ is a whole number of them runs time-exactly; a longer one is an ordinary move.
pub const FINE_BLOCK_MAX_SAMPLES: u64 = 32;

/// The sample periods of a fine block: `G1` under `G93` and `G64` whose $1/F$ is a whole number
/// $m$ of sample periods, $1 \le m \le$ [`FINE_BLOCK_MAX_SAMPLES`] (within $10^{-7}$
/// relative: an F word written with four decimals), the element of a time-exact chain (module
/// doc of [`crate::interpolate`](mod@crate::interpolate)); `None` for any other move.
pub(crate) fn fine_samples(mv: &Move, ts: f64) -> Option<u64> {
    if !matches!(mv.path, PathMode::Blend { .. }) || !matches!(mv.kind, MoveKind::Linear) {
        return None;
    }
    let Some(Feed::InverseTime(f)) = mv.feed else {
        return None;
    };
    let periods = 60.0 / (f * ts);
    let m = periods.round();
    (m >= 1.0 && m <= FINE_BLOCK_MAX_SAMPLES as f64 && (periods - m).abs() <= 1e-7 * m)
        .then_some(m as u64)
}

/// Whether `mv` is a fine block ([`fine_samples`]).
pub(crate) fn fine_block(mv: &Move, ts: f64) -> bool {
    fine_samples(mv, ts).is_some()
}

/// Why a block was slowed (numbers only: the message is built once, for the worst block).
#[derive(Clone, Copy)]
pub(crate) enum Cause {
    /// Programmed speed and the cap, along s (mm/s or deg/s); the F word and whether it is
    /// inverse time.
    Feed {
        v_feed: f64,
        v_lim: f64,
        deg: bool,
        f: f64,
        inverse: bool,
    },
}

/// Blocks slowed to the limits: the count and the worst (factor, line, column, cause).
#[derive(Default)]
pub(crate) struct Slowed {
    count: usize,
    worst: Option<(f64, u32, u32, Cause)>,
}

impl Slowed {
    /// Note a segment whose feed is above its speed cap.
    pub(crate) fn feed(&mut self, seg: &Seg, mv: &Move) {
        if seg.vfeed.is_finite() && seg.vfeed > seg.vlim * (1.0 + 1e-9) {
            let (f, inverse) = match mv.feed {
                Some(Feed::InverseTime(f)) => (f, true),
                Some(Feed::UnitsPerMin(f)) => (f, false),
                None => (0.0, false),
            };
            let cause = Cause::Feed {
                v_feed: seg.vfeed,
                v_lim: seg.vlim,
                deg: !seg.xyz_basis,
                f,
                inverse,
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

    fn note(&mut self, factor: f64, mv: &Move, cause: Cause) {
        self.count += 1;
        if self.worst.is_none_or(|w| factor > w.0) {
            self.worst = Some((factor, mv.line, mv.col, cause));
        }
    }

    pub(crate) fn finish(self, warnings: &mut Vec<Diagnostic>) -> Option<Slowdown> {
        let (factor, line, col, cause) = self.worst?;
        let Cause::Feed {
            v_feed,
            v_lim,
            deg,
            f,
            inverse,
        } = cause;
        let unit = if deg { "deg" } else { "mm" };
        let word = if inverse { "inverse time F" } else { "F" };
        let detail = format!(
            "{word}{} asks for {v_feed:.3} {unit}/s, the limits allow {v_lim:.3} {unit}/s",
            fmt_num(f)
        );
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

/// The element at the open end of a chain (a blend may still trim its end).
#[derive(Debug, Clone)]
struct Tail {
    side: Side,
    mv: Move,
    /// Speed cap at its start.
    w_in: f64,
    /// LinuxCNC's rules: the rest of a line a blend consumed (part of the blend's element).
    consumed: bool,
    /// Share of the acceleration cap its junctions take (the larger of the two ends': kinks
    /// at its start and end never act at once; LinuxCNC's `kink_accel_reduce`).
    reduce: f64,
}

/// A chain being planned.
struct ChainState {
    tcp: bool,
    basis: bool,
    rapid: bool,
    tail: Tail,
    plan: Plan,
    /// Second pass: the sampler, once the chain has two elements.
    sampler: Option<Sampler>,
    /// Elements handed to the plan, and the last one.
    pushed: usize,
    last: Option<Seg>,
}

/// A chain of fine blocks being gathered.
struct FineState {
    tcp: bool,
    first_line: u32,
    /// Moves in the chain so far.
    blocks: usize,
    /// Second pass: run time-exactly (else every block as an exact stop).
    exact: bool,
    /// First pass: the worst block too fast for the limits (speed, cap, line, col, rotary).
    refusal: Option<(f64, f64, u32, u32, bool)>,
    /// First pass: what running the blocks as exact stops adds (samples, slowdowns, cycle).
    alt_samples: u64,
    alt_slowed: Slowed,
    /// Points of the chain (first pass: counted; second pass: the last two kept).
    points: u64,
    prev: [f64; 6],
    cur: [f64; 6],
    /// First sample of the chain in the trajectory.
    base: u64,
}

enum State {
    Idle,
    Chain(Box<ChainState>),
    Fine(Box<FineState>),
}

/// Straight feeds gathered under `G64 Q` (LinuxCNC's "naive CAM detector", emccanon.cc
/// `see_segment`): the moves so far, all within Q of the line from the first one's start to
/// the last one's end.
struct Merge {
    q: f64,
    moves: Vec<(usize, Move)>,
}

/// The planner of both passes ([module doc](self)).
pub(crate) struct Planner<'c, 'd, 'o> {
    cfg: &'c Cfg,
    mode: Mode<'d, 'o>,
    /// Moves received and not yet planned (the newest may still become a stop).
    queue: VecDeque<(usize, Move)>,
    received: usize,
    merge: Option<Merge>,
    state: State,
    pub(crate) slowed: Slowed,
    pub(crate) warnings_early: Vec<Diagnostic>,
    pub(crate) total: u64,
    pub(crate) last_move: Option<Move>,
    pub(crate) lookahead_peak: usize,
    pub(crate) any_tcp: bool,
    /// Samples per class of move (first pass).
    pub(crate) cycle: CycleTime,
}

impl<'c, 'd, 'o> Planner<'c, 'd, 'o> {
    pub(crate) fn new(cfg: &'c Cfg, mode: Mode<'d, 'o>) -> Self {
        Planner {
            cfg,
            mode,
            queue: VecDeque::new(),
            received: 0,
            merge: None,
            state: State::Idle,
            slowed: Slowed::default(),
            warnings_early: Vec::new(),
            total: 0,
            last_move: None,
            lookahead_peak: 0,
            any_tcp: false,
            cycle: CycleTime::default(),
        }
    }

    fn sampling(&self) -> bool {
        matches!(self.mode, Mode::Sample { .. })
    }

    /// Count a piece's samples against the budget; returns its first sample.
    fn account(&mut self, n: u64, class: MoveClass) -> Result<u64, Error> {
        let base = self.total;
        self.total += n;
        let max = self.cfg.max_samples;
        if self.total + 1 > max as u64 {
            return Err(Error::TooManySamples {
                samples: (self.total + 1) as f64,
                max,
                duration_s: self.total as f64 * self.cfg.ts,
            });
        }
        self.cycle.add(class, n as f64 * self.cfg.ts);
        Ok(base)
    }

    /// The next move of the program.
    pub(crate) fn push(&mut self, mv: Move) -> Result<(), Error> {
        if let Mode::Sample { out, .. } = &self.mode
            && out.failed()
        {
            return Err(Error::Read {
                message: "the output failed".into(),
            });
        }
        self.any_tcp |= mv.tcp;
        self.queue.push_back((self.received, mv));
        self.received += 1;
        // The newest move waits: the next piece may still mark it as a stop.
        while self.queue.len() > 1 {
            self.step()?;
        }
        Ok(())
    }

    /// The program has ended: plan what is left.
    pub(crate) fn finish(&mut self) -> Result<(), Error> {
        while !self.queue.is_empty() {
            self.step()?;
        }
        self.flush_merge()?;
        self.end_state(true)
    }

    /// The final sample: at rest on the last programmed point.
    pub(crate) fn final_sample(&mut self, start: [f64; 6]) {
        let (end, tcp) = self
            .last_move
            .as_ref()
            .map_or((start, false), |m| (m.end, m.tcp));
        if let Mode::Sample { out, .. } = &mut self.mode {
            out.sample(&end, &[0.0; 6], &[0.0; 6], tcp);
        }
    }

    /// Take the oldest queued move: merge it under `G64 Q`, or plan it.
    fn step(&mut self) -> Result<(), Error> {
        let Some((i, mv)) = self.queue.pop_front() else {
            return Ok(());
        };
        self.last_move = Some(mv.clone());
        let q = match mv.path {
            PathMode::Blend {
                merge_mm: Some(q), ..
            } if mergeable(&mv) => Some(q),
            _ => None,
        };
        if let Some(m) = &mut self.merge {
            let last = &m.moves[m.moves.len() - 1].1;
            if q == Some(m.q)
                && last.feed == mv.feed
                && last.path == mv.path
                && last.tcp == mv.tcp
                && m.moves.len() < 100
                && linkable(&m.moves, &mv, m.q)
            {
                m.moves.push((i, mv.clone()));
                if mv.stop_after {
                    self.flush_merge()?;
                }
                return Ok(());
            }
            self.flush_merge()?;
        }
        if let Some(q) = q
            && !mv.stop_after
        {
            self.merge = Some(Merge {
                q,
                moves: vec![(i, mv)],
            });
            return Ok(());
        }
        self.plan_move(i, &mv)
    }

    /// Plan the gathered straight feeds as one move from the first one's start to the last
    /// one's end, named after the last one (as LinuxCNC reports it).
    fn flush_merge(&mut self) -> Result<(), Error> {
        let Some(m) = self.merge.take() else {
            return Ok(());
        };
        let (i, last) = m.moves[m.moves.len() - 1].clone();
        let merged = Move {
            start: m.moves[0].1.start,
            ..last
        };
        self.plan_move(i, &merged)
    }

    /// Plan move `mv` (index `i` in the program).
    fn plan_move(&mut self, i: usize, mv: &Move) -> Result<(), Error> {
        let taken = match std::mem::replace(&mut self.state, State::Idle) {
            State::Idle => false,
            State::Chain(c) => {
                self.state = State::Chain(c);
                self.chain_move(i, mv)?
            }
            State::Fine(f) => {
                self.state = State::Fine(f);
                self.fine_move(i, mv)?
            }
        };
        if !taken {
            self.idle_move(i, mv)?;
        }
        Ok(())
    }

    /// A move with no chain open.
    fn idle_move(&mut self, i: usize, mv: &Move) -> Result<(), Error> {
        let ts = self.cfg.ts;
        let max = self.cfg.max_samples;
        if let MoveKind::Dwell { seconds } = mv.kind {
            let n = samples_for(seconds, ts, max)?;
            let base = self.account(n, MoveClass::Dwell)?;
            if let Mode::Sample { out, .. } = &mut self.mode {
                let b = base as usize;
                let t0 = base as f64 * ts;
                out.span(b + 1, b + n as usize + 1, t0, t0 + n as f64 * ts, i, mv);
                for _ in 0..n {
                    out.sample(&mv.start, &[0.0; 6], &[0.0; 6], mv.tcp);
                }
            }
            return Ok(());
        }
        if fine_block(mv, ts) {
            let exact = match &mut self.mode {
                Mode::Plan(_) => true,
                Mode::Sample { decisions, .. } => decisions.fine.pop_front().unwrap_or(true),
            };
            let fine = FineState {
                tcp: mv.tcp,
                first_line: mv.line,
                blocks: 0,
                exact,
                refusal: None,
                alt_samples: 0,
                alt_slowed: Slowed::default(),
                points: 1,
                prev: mv.start,
                cur: mv.start,
                base: self.total,
            };
            self.state = State::Fine(Box::new(fine));
            self.fine_move(i, mv)?;
            return Ok(());
        }
        let Some(seg) = segment(mv, i, self.cfg)? else {
            return Ok(());
        };
        self.slowed.feed(&seg, mv);
        if mv.path.is_exact_stop() || mv.stop_after {
            let mut seg = seg;
            if self.cfg.lc && matches!(mv.path, PathMode::Blend { .. }) {
                // A G64 block that ends in a stop: half acceleration (end_state).
                seg.acap *= 0.5;
            }
            return self.single(seg, mv, false);
        }
        self.open_chain(seg, mv, 1.0);
        Ok(())
    }

    /// Open a chain whose first element is `seg` (its acceleration cap kept to the share
    /// `keep`).
    fn open_chain(&mut self, seg: Seg, mv: &Move, keep: f64) {
        let cfg = self.cfg;
        self.state = State::Chain(Box::new(ChainState {
            tcp: mv.tcp,
            basis: seg.xyz_basis,
            rapid: matches!(mv.kind, MoveKind::Rapid),
            tail: Tail {
                side: Side {
                    seg,
                    nominal: seg.len,
                    mode: mv.path,
                    kind: mv.kind,
                    tcp: mv.tcp,
                },
                mv: mv.clone(),
                w_in: 0.0,
                consumed: false,
                reduce: 1.0 - keep,
            },
            plan: Plan::new(cfg.tf, cfg.speed_bound(mv.tcp, seg.xyz_basis)),
            sampler: None,
            pushed: 0,
            last: None,
        }));
    }

    /// A block run on its own, rest to rest (module doc); `alt`: the first pass's alternative
    /// of a fine chain (counted apart until the chain's end decides).
    fn single(&mut self, seg: Seg, mv: &Move, alt: bool) -> Result<(), Error> {
        let cfg = self.cfg;
        let (ts, max) = (cfg.ts, cfg.max_samples);
        let seg = if cfg.lc {
            Seg {
                vcap: seg.vcap.min(seg.len / ts),
                ..seg
            }
        } else {
            seg
        };
        let (prof, n, lam) = if cfg.jerk {
            let p = SCurve::rest_to_rest(seg.len, seg.vcap, seg.acap, seg.jcap);
            let n = samples_for(p.duration(), ts, max)?;
            let lam = (n as f64 * ts / p.duration()).max(1.0);
            (Prof::S(Box::new(p)), n, lam)
        } else {
            let opt = Trap::new(seg.len, 0.0, 0.0, seg.vcap, seg.acap);
            let n = samples_for(opt.duration(), ts, max)?;
            let t = n as f64 * ts;
            let trap = if t > opt.duration() {
                Trap::rest_to_rest_lasting(seg.len, seg.acap, t)
            } else {
                opt
            };
            let lam = (t / trap.duration()).max(1.0);
            (Prof::Trap(trap), n, lam)
        };
        if alt {
            if let State::Fine(f) = &mut self.state {
                f.alt_samples += n;
            }
            return Ok(());
        }
        let class = MoveClass::of(&mv.kind);
        let base = self.account(n, class)?;
        if let Mode::Sample { out, .. } = &mut self.mode {
            let mut s = Sampler::new(n, lam, 0.0, base, ts, mv.tcp);
            s.add_elem(Elem {
                seg,
                s0: 0.0,
                mv: mv.clone(),
            });
            s.add_planned(Planned {
                piece: Piece {
                    len: seg.len,
                    vcap: seg.vcap,
                    acap: seg.acap,
                    cap0: 0.0,
                    s0: 0.0,
                },
                prof,
                tau0: 0.0,
            });
            s.end();
            s.pump(&mut **out, ts);
        }
        Ok(())
    }

    /// A move offered to the open fine chain; `false` when it ends the chain before it.
    fn fine_move(&mut self, i: usize, mv: &Move) -> Result<bool, Error> {
        let ts = self.cfg.ts;
        let State::Fine(f) = &self.state else {
            return Ok(false);
        };
        let Some(m) = fine_samples(mv, ts).filter(|_| mv.tcp == f.tcp) else {
            self.end_state(false)?;
            return Ok(false);
        };
        let sampling = self.sampling();
        let exact = f.exact;
        let seg = segment(mv, i, self.cfg)?;
        if let Some(seg) = seg {
            if !sampling {
                // Both ways, decided at the chain's end.
                let mut sl = Slowed::default();
                sl.feed(&seg, mv);
                self.single(seg, mv, true)?;
                if let State::Fine(f) = &mut self.state {
                    f.alt_slowed.merge(sl);
                }
            } else if !exact {
                self.slowed.feed(&seg, mv);
                self.single(seg, mv, false)?;
            }
        }
        let State::Fine(f) = &mut self.state else {
            return Ok(true);
        };
        f.blocks += 1;
        if let Some(seg) = seg {
            if !sampling {
                let speed = seg.len / (m as f64 * ts);
                if speed > seg.vlim * (1.0 + 1e-9)
                    && f.refusal.is_none_or(|r| speed / seg.vlim > r.0 / r.1)
                {
                    f.refusal = Some((speed, seg.vlim, mv.line, mv.col, !seg.xyz_basis));
                }
                f.points += m;
            } else if exact {
                // The block's m points run straight from its start to its end, one per sample.
                // Point q arrives: sample q − 1 needs points q − 2, q − 1 and q (central
                // differences, at rest before the first point).
                for j in 1..=m {
                    let c: [f64; 6] = if j == m {
                        mv.end
                    } else {
                        let w = j as f64 / m as f64;
                        std::array::from_fn(|d| mv.start[d] + (mv.end[d] - mv.start[d]) * w)
                    };
                    let q = f.points;
                    f.points += 1;
                    let (a, b) = (if q >= 2 { f.prev } else { f.cur }, f.cur);
                    f.prev = f.cur;
                    f.cur = c;
                    let k = (f.base + q - 1) as usize;
                    let tcp = f.tcp;
                    if let Mode::Sample { out, .. } = &mut self.mode {
                        let t0 = k as f64 * ts;
                        out.span(k + 1, k + 2, t0, t0 + ts, i, mv);
                        let (v, acc) = central_rates(&a, &b, &c, ts);
                        out.sample(&b, &v, &acc, tcp);
                    }
                }
            }
        }
        if mv.stop_after {
            self.end_state(false)?;
        }
        Ok(true)
    }

    /// A move offered to the open chain; `false` when it does not join it (the chain is then
    /// closed, or a new one opened with it).
    fn chain_move(&mut self, i: usize, mv: &Move) -> Result<bool, Error> {
        let cfg = self.cfg;
        let State::Chain(c) = &self.state else {
            return Ok(false);
        };
        let joins = matches!(
            mv.kind,
            MoveKind::Rapid | MoveKind::Linear | MoveKind::Arc(_)
        ) && !fine_block(mv, cfg.ts)
            && mv.tcp == c.tcp
            && matches!(mv.kind, MoveKind::Rapid) == c.rapid;
        if !joins {
            // LinuxCNC stops between a feed and a rapid (tp.c handleModeChange) without halving
            // the acceleration; a dwell or a fine block follows a stop that does.
            let switch = matches!(
                mv.kind,
                MoveKind::Rapid | MoveKind::Linear | MoveKind::Arc(_)
            ) && !fine_block(mv, cfg.ts);
            self.end_state(!switch)?;
            return Ok(false);
        }
        let Some(seg) = segment(mv, i, cfg)? else {
            return Ok(true);
        };
        if seg.xyz_basis != c.basis {
            self.end_state(false)?;
            return Ok(false);
        }
        self.slowed.feed(&seg, mv);
        let b = Side {
            seg,
            nominal: seg.len,
            mode: mv.path,
            kind: mv.kind,
            tcp: mv.tcp,
        };
        let j = joint(cfg, &c.tail.side, &b);
        match j {
            Joint::Stop { keep } => {
                if let State::Chain(c) = &mut self.state {
                    c.tail.reduce = c.tail.reduce.max(1.0 - keep);
                }
                self.end_state(false)?;
                if mv.path.is_exact_stop() || mv.stop_after {
                    let mut seg = seg;
                    seg.acap *= keep;
                    self.single(seg, mv, false)?;
                } else {
                    self.open_chain(seg, mv, keep);
                }
                return Ok(true);
            }
            Joint::Through {
                cap,
                keep_a,
                keep_b,
            } => {
                let State::Chain(c) = &mut self.state else {
                    return Ok(true);
                };
                c.tail.reduce = c.tail.reduce.max(1.0 - keep_a);
                let w = cap.min(c.tail.side.seg.vcap).min(b.seg.vcap);
                self.push_tail()?;
                self.set_tail(b, mv, w);
                if let State::Chain(c) = &mut self.state {
                    c.tail.reduce = 1.0 - keep_b;
                }
            }
            Joint::Blend {
                blend,
                trim_a,
                trim_b,
                consume,
            } => {
                let blend = *blend;
                let State::Chain(c) = &mut self.state else {
                    return Ok(true);
                };
                let tail = &mut c.tail;
                let new_len = tail.side.seg.len - trim_a;
                let w_blend;
                if new_len > 1e-9 * tail.side.nominal.max(1.0) {
                    tail.side.seg = trim(&tail.side.seg, 0.0, new_len);
                    if consume {
                        tail.side.seg.vcap = tail.side.seg.vcap.min(blend.vcap);
                        tail.side.seg.acap = tail.side.seg.acap.min(blend.acap);
                        tail.consumed = true;
                    }
                    w_blend = tail.side.seg.vcap.min(blend.vcap);
                    self.push_tail()?;
                } else {
                    w_blend = tail.w_in.min(blend.vcap);
                }
                let State::Chain(c) = &mut self.state else {
                    return Ok(true);
                };
                c.tail = Tail {
                    side: Side {
                        seg: blend,
                        nominal: blend.len,
                        mode: c.tail.side.mode,
                        kind: MoveKind::Linear,
                        tcp: mv.tcp,
                    },
                    mv: c.tail.mv.clone(),
                    w_in: w_blend,
                    consumed: false,
                    reduce: 0.0,
                };
                self.push_tail()?;
                let mut b = b;
                b.seg = trim(&b.seg, trim_b, b.seg.len);
                let w = blend.vcap.min(b.seg.vcap);
                self.set_tail(b, mv, w);
            }
        }
        if mv.path.is_exact_stop() || mv.stop_after {
            self.end_state(mv.stop_after)?;
        }
        Ok(true)
    }

    fn set_tail(&mut self, side: Side, mv: &Move, w_in: f64) {
        if let State::Chain(c) = &mut self.state {
            c.tail = Tail {
                side,
                mv: mv.clone(),
                w_in,
                consumed: false,
                reduce: 0.0,
            };
        }
    }

    /// Hand the chain's tail element to its plan (and, in the second pass, to its sampler).
    fn push_tail(&mut self) -> Result<(), Error> {
        let cfg = self.cfg;
        let ts = cfg.ts;
        let State::Chain(c) = &mut self.state else {
            return Ok(());
        };
        let mut seg = c.tail.side.seg;
        seg.acap *= 1.0 - c.tail.reduce;
        if cfg.lc && !c.tail.consumed {
            // LinuxCNC 2.9 (tp.c tpComputeOptimalVelocity): at least 1.02 samples per element
            // (a consumed line is part of its blend's element).
            seg.vcap = seg.vcap.min(seg.len / (1.02 * ts));
        }
        let mut w = c.tail.w_in.min(seg.vcap);
        let mut keep = 1.0;
        // An element shorter than a thousandth of a sample at its speed (what rounding leaves of
        // a line between two blends) is passed over at once: its two junctions act as one,
        // between the elements around it.
        let tiny = seg.len < 1e-3 * seg.vcap * ts;
        if cfg.jerk
            && !tiny
            && let Some(prev) = &c.last
        {
            // The junction's own jerk takes at most half of the limits; the path's jerk around
            // it (the zone of its cap) keeps the rest ([`JerkJump`]).
            let (ga1, ga2) = prev.geom.ends(prev.len, true);
            let (gb1, gb2) = seg.geom.ends(seg.len, false);
            let dg: [f64; 6] = std::array::from_fn(|i| gb1[i] - ga1[i]);
            let dg2: [f64; 6] = std::array::from_fn(|i| gb2[i] - ga2[i]);
            let jump = JerkJump::new(cfg, &dg, &dg2, c.tcp);
            w = w.min(jump.cap(0.5));
            keep = 1.0 - jump.share(w);
        }
        if !tiny {
            c.last = Some(seg);
        }
        let s0 = c.plan.total;
        c.plan.push(&seg, w, keep);
        c.pushed += 1;
        self.lookahead_peak = self.lookahead_peak.max(c.plan.pending());
        if c.pushed == 1
            && let Mode::Sample { decisions, .. } = &mut self.mode
        {
            let (n, lam) = decisions.chains.pop_front().unwrap_or((0, 1.0));
            let (tcp, rapid) = (c.tcp, c.rapid);
            let class = if rapid {
                MoveClass::Rapid
            } else {
                MoveClass::Feed
            };
            let base = self.account(n, class)?;
            if let State::Chain(c) = &mut self.state {
                c.sampler = Some(Sampler::new(n, lam, cfg.tf, base, ts, tcp));
            }
        }
        let State::Chain(c) = &mut self.state else {
            return Ok(());
        };
        if let (Some(s), Mode::Sample { out, .. }) = (&mut c.sampler, &mut self.mode) {
            s.add_elem(Elem {
                seg,
                s0,
                mv: c.tail.mv.clone(),
            });
            s.take(&mut c.plan);
            s.pump(&mut **out, ts);
        } else {
            c.plan.done.clear();
        }
        Ok(())
    }

    /// Close the open chain, if any. `stopped`: it ends because the machine must stop after
    /// its last move (a stop, a dwell, the end), which LinuxCNC's rules take at half
    /// acceleration after a `G64` block.
    fn end_state(&mut self, stopped: bool) -> Result<(), Error> {
        let cfg = self.cfg;
        let (ts, max) = (cfg.ts, cfg.max_samples);
        match std::mem::replace(&mut self.state, State::Idle) {
            State::Idle => Ok(()),
            State::Chain(mut c) => {
                if cfg.lc && stopped && matches!(c.tail.side.mode, PathMode::Blend { .. }) {
                    // tc.c tcGetOverallMaxAccel: a segment left with the parabolic blend
                    // condition (nothing to blend with) runs at half acceleration.
                    c.tail.side.seg.acap *= 0.5;
                }
                if c.pushed == 0 {
                    let mut seg = c.tail.side.seg;
                    seg.acap *= 1.0 - c.tail.reduce;
                    let mv = c.tail.mv.clone();
                    return self.single(seg, &mv, false);
                }
                self.state = State::Chain(c);
                self.push_tail()?;
                let State::Chain(mut c) = std::mem::replace(&mut self.state, State::Idle) else {
                    return Ok(());
                };
                c.plan.finish();
                match (&mut c.sampler, &mut self.mode) {
                    (Some(s), Mode::Sample { out, .. }) => {
                        s.take(&mut c.plan);
                        s.end();
                        s.pump(&mut **out, ts);
                    }
                    (_, Mode::Plan(_)) => {
                        let t = c.plan.t;
                        let n = samples_for(t + cfg.tf, ts, max)?;
                        let lambda = if cfg.tf == 0.0 {
                            (n as f64 * ts / t).max(1.0)
                        } else {
                            ((n as f64 * ts - cfg.tf) / t).max(1.0)
                        };
                        let class = if c.rapid {
                            MoveClass::Rapid
                        } else {
                            MoveClass::Feed
                        };
                        self.account(n, class)?;
                        if let Mode::Plan(d) = &mut self.mode {
                            d.chains.push_back((n, lambda));
                        }
                    }
                    _ => {}
                }
                Ok(())
            }
            State::Fine(f) => {
                if self.sampling() {
                    if f.exact {
                        // The samples were emitted as the blocks came; count them.
                        self.account(f.points - 1, MoveClass::Feed)?;
                    }
                    return Ok(());
                }
                match f.refusal {
                    Some((speed, cap, line, col, deg)) => {
                        let unit = if deg { "deg" } else { "mm" };
                        let message = format!(
                            "the {} fine blocks from line {} (G93 G64, 1/F a whole number of sample periods) are not run as set-points: line {line} needs {speed:.3} {unit}/s along its path, the limits allow {cap:.3} {unit}/s; each block runs as an exact stop",
                            f.blocks, f.first_line
                        );
                        let span = Span {
                            line,
                            col,
                            start: 0,
                            end: 0,
                        };
                        self.warnings_early.push(Diagnostic::warning(span, message));
                        self.slowed.merge(f.alt_slowed);
                        self.account(f.alt_samples, MoveClass::Feed)?;
                        if let Mode::Plan(d) = &mut self.mode {
                            d.fine.push_back(false);
                        }
                    }
                    None => {
                        self.account(f.points - 1, MoveClass::Feed)?;
                        if let Mode::Plan(d) = &mut self.mode {
                            d.fine.push_back(true);
                        }
                    }
                }
                Ok(())
            }
        }
    }
}

/// The part `[s0, s1]` of a straight element (blends trim only lines).
fn trim(seg: &Seg, s0: f64, s1: f64) -> Seg {
    let (p0, _, _) = seg.geom.eval(s0, seg.len);
    let (end, _, _) = seg.geom.eval(s1, seg.len);
    let end = if s1 >= seg.len { seg.geom.end() } else { end };
    let p0 = if s0 <= 0.0 { seg.geom.start() } else { p0 };
    let d: [f64; 6] = std::array::from_fn(|i| end[i] - p0[i]);
    Seg {
        geom: Geom::Line { p0, end, d },
        len: s1 - s0,
        ..*seg
    }
}

/// A straight feed `G64 Q` may merge: `G1` under `G94`, no rotary axis moving.
fn mergeable(mv: &Move) -> bool {
    matches!(mv.kind, MoveKind::Linear)
        && matches!(mv.feed, Some(Feed::UnitsPerMin(_)))
        && mv.start[3..] == mv.end[3..]
        && mv.start[..3] != mv.end[..3]
}

/// Whether `mv` extends the gathered moves: every gathered end point within `q` of the segment
/// from the first start to `mv`'s end (emccanon.cc `linkable`).
fn linkable(moves: &[(usize, Move)], mv: &Move, q: f64) -> bool {
    let b = moves[0].1.start;
    let e = mv.end;
    let m: [f64; 3] = std::array::from_fn(|i| e[i] - b[i]);
    let mm = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
    if mm == 0.0 {
        return false;
    }
    moves.iter().all(|(_, p)| {
        let pb: [f64; 3] = std::array::from_fn(|i| p.end[i] - b[i]);
        let t = ((pb[0] * m[0] + pb[1] * m[1] + pb[2] * m[2]) / mm).clamp(0.0, 1.0);
        let d: [f64; 3] = std::array::from_fn(|i| pb[i] - t * m[i]);
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() <= q
    })
}
