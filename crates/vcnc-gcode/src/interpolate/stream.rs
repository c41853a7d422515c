//! Streaming: parse, interpret and interpolate a program a piece at a time, in memory that does
//! not grow with the program's length (docs/performance.md, "Streaming").
//!
//! The samples are bit for bit those of [`crate::load`] (tested on every fixture and on random
//! programs), which shapes the design:
//!
//! - **Two passes over the source.** A `G64` chain is rounded up to a whole number of samples
//!   by one time scale $\lambda$ for the whole chain (module doc of
//!   [`interpolate`](mod@crate::interpolate)), and a chain of fine blocks runs time-exactly or
//!   not depending on its slowest block, so neither can be sampled before its end is known. The
//!   first pass ([`plan`]) parses, interprets and plans without sampling, and keeps per chain only
//!   its sample count and $\lambda$ (16 bytes; per fine-block chain whether it runs
//!   time-exactly), the total length, the axes used and the warnings. The second
//!   ([`StreamPlan::sample`]) does it all again and samples.
//! - **An exact, bounded look-ahead.** The backward pass of a chain (module doc of
//!   [`interpolate`](mod@crate::interpolate)) is run over the segments not yet final, from an
//!   assumed stop after the last one seen. Going backwards, the first junction whose speed is
//!   its own cap (the cap is below the speed from which the machine could still stop) is final:
//!   the whole program's backward pass gives it the same value, bit for bit, whatever follows,
//!   because later segments can only raise the reachable speed there. Every segment before it is
//!   then final too, and is profiled (forward pass) and sampled. The look-ahead therefore holds
//!   the segments within one braking distance of the last one read — how far a control must look
//!   ahead — however long the program.
//! - **Pieces of source.** The source is read about [`StreamOptions::chunk_bytes`] at a time, cut
//!   at line breaks, parsed ([`crate::ChunkParser`]) and interpreted ([`ChunkInterp`]) a piece at a
//!   time. O-word statements (subroutines, conditions, loops) are indexed as they are first read,
//!   and a jump back reads the file again from the statement's offset ([`ChunkInterp`]).

use std::collections::VecDeque;

use super::{
    Limits, Move, MoveClass, MoveKind, Piece, Seg, Slowdown, Slowed, Trap, central_rates,
    chain_span, check_limits, continuous, eval_scaled, exact_stop_piece, fine_block, junction,
    output_axes, samples_for, segment, single,
};
use crate::diag::{Diagnostic, Span};
use crate::interp::{ChunkInterp, ProgramRead};
use crate::{AxisName, Error, InterpOptions, InterpolateOptions};

/// Where a streamed program comes from; it is read twice ([module doc](self)), and read again
/// from earlier offsets where O-word statements jump back.
pub trait ProgramSource {
    /// A reader at the start of the program.
    fn open(&self) -> std::io::Result<Box<dyn ProgramRead + '_>>;
}

impl ProgramSource for str {
    fn open(&self) -> std::io::Result<Box<dyn ProgramRead + '_>> {
        Ok(Box::new(std::io::Cursor::new(self.as_bytes())))
    }
}

impl ProgramSource for std::path::Path {
    fn open(&self) -> std::io::Result<Box<dyn ProgramRead + '_>> {
        Ok(Box::new(std::io::BufReader::with_capacity(
            1 << 16,
            std::fs::File::open(self)?,
        )))
    }
}

/// Streaming settings. Plain data; [`Default`] gives the documented defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamOptions {
    /// Source read per piece, bytes (cut at the next line break). Default 1 MiB.
    pub chunk_bytes: usize,
    /// Samples handed over per [`SampleChunk`]. Default 65 536.
    pub chunk_samples: usize,
}

impl Default for StreamOptions {
    fn default() -> Self {
        StreamOptions {
            chunk_bytes: 1 << 20,
            chunk_samples: 1 << 16,
        }
    }
}

/// Consecutive samples of a streamed trajectory: the columns of [`crate::Trajectory`] for samples
/// `first..first + len()`, with each sample's span resolved.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SampleChunk {
    /// Index of the first sample.
    pub first: usize,
    /// Per output axis ([`StreamPlan::axes`]): position (mm or deg).
    pub pos: Vec<Vec<f64>>,
    /// Per output axis: velocity (units/s).
    pub vel: Vec<Vec<f64>>,
    /// Per output axis: acceleration (units/s²).
    pub acc: Vec<Vec<f64>>,
    /// Per sample: X Y Z are tool-tip coordinates (TCP mode).
    pub tcp: Vec<bool>,
    /// Per sample: source line of its span ([`crate::BlockSpan`]; 0 without one).
    pub line: Vec<u32>,
    /// Per sample: class of its span (`None` without one).
    pub class: Vec<Option<MoveClass>>,
    /// Per sample: end point X Y Z A B C of its span's move (mm, deg; the start for none).
    pub target: Vec<[f64; 6]>,
}

impl SampleChunk {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.tcp.len()
    }

    /// `true` without samples.
    pub fn is_empty(&self) -> bool {
        self.tcp.is_empty()
    }

    fn clear(&mut self) {
        for v in self
            .pos
            .iter_mut()
            .chain(&mut self.vel)
            .chain(&mut self.acc)
        {
            v.clear();
        }
        self.tcp.clear();
        self.line.clear();
        self.class.clear();
        self.target.clear();
    }
}

/// What the first pass learned ([module doc](self)): enough to size the outputs and to sample
/// in the second.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamPlan {
    /// Sample period, s.
    pub ts: f64,
    /// Number of samples (the last one at rest on the last point).
    pub samples: usize,
    /// Output axes, in X Y Z A B C order (as [`crate::Trajectory::axes`]).
    pub axes: Vec<AxisName>,
    /// Which of X Y Z A B C the program names or moves ([`crate::Toolpath::axes_used`]).
    pub axes_used: [bool; 6],
    /// Where the machine rests before the first move ([`crate::Toolpath::start`]).
    pub start: [f64; 6],
    /// Some move runs in tool-centre-point mode.
    pub any_tcp: bool,
    /// Number of moves.
    pub moves: usize,
    /// Feeds slowed to the machine's limits, if any.
    pub slowdown: Option<Slowdown>,
    /// Every warning (parser, interpreter, interpolator), in the order of [`crate::load`].
    pub warnings: Vec<Diagnostic>,
    /// Most segments the look-ahead held at once.
    pub lookahead_peak: usize,
    interp: InterpOptions,
    limits: Limits,
    opts: InterpolateOptions,
    stream: StreamOptions,
    decisions: Decisions,
}

/// Per chain, in program order, what the second pass cannot know before the chain's end.
#[derive(Debug, Clone, Default, PartialEq)]
struct Decisions {
    /// Time-scaled chains of ≥ 2 segments: sample count and λ.
    chains: VecDeque<(u64, f64)>,
    /// Fine-block chains: `true` when run time-exactly.
    fine: VecDeque<bool>,
}

/// First pass: parse, interpret and plan `src` without sampling ([module doc](self)).
///
/// Errors are those of [`crate::load`] (a program with errors gives all its diagnostics, as
/// there) and [`Error::Read`].
pub fn plan(
    src: &(impl ProgramSource + ?Sized),
    interp: &InterpOptions,
    limits: &Limits,
    opts: &InterpolateOptions,
    stream: &StreamOptions,
) -> Result<StreamPlan, Error> {
    check_limits(limits, opts)?;
    let mut decisions = Decisions::default();
    let mut planner: Planner<'_, '_, Error> =
        Planner::new(limits, opts, Mode::Plan(&mut decisions));
    let run = run_source(src, interp, stream, &mut planner)?;
    let mut warnings = run.warnings;
    warnings.extend(planner.warnings_early.iter().cloned());
    let slowdown = std::mem::take(&mut planner.slowed).finish(&mut warnings);
    let axes = output_axes(opts, run.axes_used);
    let total = planner.total;
    let samples = usize::try_from(total + 1).map_err(|_| Error::TooManySamples {
        samples: (total + 1) as f64,
        max: opts.max_samples,
        duration_s: total as f64 * opts.ts,
    })?;
    let lookahead_peak = planner.lookahead_peak;
    let any_tcp = planner.any_tcp;
    drop(planner);
    Ok(StreamPlan {
        ts: opts.ts,
        samples,
        axes,
        axes_used: run.axes_used,
        start: run.start,
        any_tcp,
        moves: run.moves,
        slowdown,
        warnings,
        lookahead_peak,
        interp: interp.clone(),
        limits: *limits,
        opts: opts.clone(),
        stream: stream.clone(),
        decisions,
    })
}

impl StreamPlan {
    /// Duration, s.
    pub fn duration_s(&self) -> f64 {
        self.samples.saturating_sub(1) as f64 * self.ts
    }

    /// Second pass: read `src` again (the same program [`plan`] read) and hand its samples to
    /// `sink` in order, [`StreamOptions::chunk_samples`] at a time.
    pub fn sample<E: From<Error>>(
        &self,
        src: &(impl ProgramSource + ?Sized),
        sink: &mut dyn FnMut(&SampleChunk) -> Result<(), E>,
    ) -> Result<(), E> {
        let mut decisions = self.decisions.clone();
        let mut failure: Option<E> = None;
        let n_axes = self.axes.len();
        let emitter = Emitter {
            idx: self.axes.iter().map(|a| a.index()).collect(),
            chunk: SampleChunk {
                pos: vec![Vec::new(); n_axes],
                vel: vec![Vec::new(); n_axes],
                acc: vec![Vec::new(); n_axes],
                ..SampleChunk::default()
            },
            chunk_samples: self.stream.chunk_samples.max(1),
            next_sample: 0,
            spans: VecDeque::new(),
            first_span: true,
            sink,
            failure: &mut failure,
        };
        let mut planner = Planner::new(
            &self.limits,
            &self.opts,
            Mode::Sample {
                decisions: &mut decisions,
                out: emitter,
            },
        );
        let run = run_source(src, &self.interp, &self.stream, &mut planner);
        let run = match run {
            Ok(r) => r,
            Err(e) => return Err(planner.take_failure().unwrap_or_else(|| e.into())),
        };
        if let Some(e) = planner.take_failure() {
            return Err(e);
        }
        // Final sample: at rest on the last programmed point.
        let (end, tcp) = planner
            .last_move
            .as_ref()
            .map_or((run.start, false), |m| (m.end, m.tcp));
        if let Mode::Sample { out, .. } = &mut planner.mode {
            out.sample(&end, &[0.0; 6], &[0.0; 6], tcp);
            out.flush();
        }
        if let Some(e) = planner.take_failure() {
            return Err(e);
        }
        if planner.total + 1 != self.samples as u64 {
            return Err(Error::Read {
                message: format!(
                    "the program changed between the two passes ({} samples, then {})",
                    self.samples,
                    planner.total + 1
                ),
            }
            .into());
        }
        Ok(())
    }
}

/// What a pass over the source returns besides the planner's state.
struct SourceRun {
    warnings: Vec<Diagnostic>,
    axes_used: [bool; 6],
    start: [f64; 6],
    moves: usize,
}

/// Read, parse and interpret `src` a piece at a time, feeding the moves to `planner`.
///
/// As [`crate::load`], a program with errors gives every diagnostic: the moves stop going to the
/// planner at the first error, and the interpreter runs on to the end. A planner error is
/// returned only for a program without errors (the whole-program path interprets before it
/// interpolates).
fn run_source<E>(
    src: &(impl ProgramSource + ?Sized),
    interp_opts: &InterpOptions,
    stream: &StreamOptions,
    planner: &mut Planner<'_, '_, E>,
) -> Result<SourceRun, Error> {
    let reader = src.open().map_err(|e| Error::Read {
        message: e.to_string(),
    })?;
    let mut interp = ChunkInterp::new(reader, interp_opts, stream.chunk_bytes);
    let mut moves = 0usize;
    let mut planned: Result<(), Error> = Ok(());
    let mut out = Vec::new();
    loop {
        out.clear();
        let more = interp.next_moves(&mut out)?;
        // Until the first error of the program or of the planner.
        if planned.is_ok() && !interp.has_errors() {
            moves += out.len();
            for m in out.drain(..) {
                if let Err(e) = planner.push(m) {
                    planned = Err(e);
                    break;
                }
            }
        }
        if !more {
            break;
        }
    }
    let (tp, diags) = interp.finish()?;
    planned?;
    moves += tp.moves.len();
    for m in tp.moves {
        planner.push(m)?;
    }
    planner.finish()?;
    Ok(SourceRun {
        warnings: diags,
        axes_used: tp.axes_used,
        start: tp.start,
        moves,
    })
}

/// The sampling side of the second pass.
struct Emitter<'s, E> {
    /// Indices in X Y Z A B C of the output axes.
    idx: Vec<usize>,
    chunk: SampleChunk,
    chunk_samples: usize,
    /// Index of the next sample.
    next_sample: usize,
    /// Spans not yet passed: (first sample, end sample, line, class, target).
    spans: VecDeque<(usize, usize, u32, MoveClass, [f64; 6])>,
    first_span: bool,
    sink: &'s mut dyn FnMut(&SampleChunk) -> Result<(), E>,
    failure: &'s mut Option<E>,
}

impl<E> Emitter<'_, E> {
    fn span(&mut self, first: usize, end: usize, mv: &Move) {
        let first = if std::mem::take(&mut self.first_span) {
            0
        } else {
            first
        };
        self.spans
            .push_back((first, end, mv.line, MoveClass::of(&mv.kind), mv.end));
    }

    fn sample(&mut self, p: &[f64; 6], v: &[f64; 6], a: &[f64; 6], tcp: bool) {
        let k = self.next_sample;
        self.next_sample += 1;
        while self.spans.front().is_some_and(|s| s.1 <= k) {
            self.spans.pop_front();
        }
        let c = &mut self.chunk;
        if c.tcp.is_empty() {
            c.first = k;
        }
        for (j, &i) in self.idx.iter().enumerate() {
            c.pos[j].push(p[i]);
            c.vel[j].push(v[i]);
            c.acc[j].push(a[i]);
        }
        c.tcp.push(tcp);
        match self.spans.front().filter(|s| s.0 <= k) {
            Some(s) => {
                c.line.push(s.2);
                c.class.push(Some(s.3));
                c.target.push(s.4);
            }
            None => {
                c.line.push(0);
                c.class.push(None);
                c.target.push(*p);
            }
        }
        if c.tcp.len() >= self.chunk_samples {
            self.flush();
        }
    }

    fn flush(&mut self) {
        if self.chunk.is_empty() || self.failure.is_some() {
            self.chunk.clear();
            return;
        }
        if let Err(e) = (self.sink)(&self.chunk) {
            *self.failure = Some(e);
        }
        self.chunk.clear();
    }
}

/// Plan only, or plan and sample. (One planner exists per pass: the size difference between the
/// variants costs nothing.)
#[allow(clippy::large_enum_variant)]
enum Mode<'d, 's, E> {
    Plan(&'d mut Decisions),
    Sample {
        decisions: &'d mut Decisions,
        out: Emitter<'s, E>,
    },
}

/// Samples a profiled chain (or a single block) as its segments become final: the chain part
/// of [`crate::interpolate`]'s sampling, one segment at a time.
struct ChainSampler {
    /// Samples of the piece and its time scale.
    n: u64,
    lam: f64,
    /// First sample of the piece in the trajectory.
    base: u64,
    tcp: bool,
    /// Final segments not yet passed, with profile, unscaled start time and move.
    win: VecDeque<(Seg, Trap, f64, Move)>,
    /// Index in the chain of `win[0]`.
    offset: usize,
    /// Spans emitted for `win[..spans_done]`.
    spans_done: usize,
    /// Next sample of the piece and the index in `win` of its segment.
    j: u64,
    cur: usize,
}

impl ChainSampler {
    fn new(n: u64, lam: f64, base: u64, tcp: bool) -> Self {
        ChainSampler {
            n,
            lam,
            base,
            tcp,
            win: VecDeque::new(),
            offset: 0,
            spans_done: 0,
            j: 0,
            cur: 0,
        }
    }

    /// Emit every span and sample the final segments decide; `ended`: no segment follows.
    fn pump<E>(&mut self, ended: bool, out: &mut Emitter<'_, E>, ts: f64) {
        let n = self.n as usize;
        let base = self.base as usize;
        let lam = self.lam;
        while self.spans_done < self.win.len() && (self.spans_done + 1 < self.win.len() || ended) {
            let (_, trap, tau0, mv) = &self.win[self.spans_done];
            let first = self.offset + self.spans_done == 0;
            let last = ended && self.spans_done + 1 == self.win.len();
            let (k_first, k_end) = chain_span(*tau0, trap.duration(), lam, n, ts, first, last);
            out.span(base + k_first + 1, base + k_end + 1, mv);
            self.spans_done += 1;
        }
        let (inv, inv2) = (1.0 / lam, 1.0 / (lam * lam));
        while self.j < self.n {
            let tau = self.j as f64 * ts * inv;
            while self.cur + 1 < self.win.len() && tau >= self.win[self.cur + 1].2 {
                self.cur += 1;
            }
            if self.cur + 1 >= self.win.len() && !ended {
                break;
            }
            let (seg, trap, tau0, _) = &self.win[self.cur];
            let (p, v, a) = eval_scaled(seg, trap, tau - tau0, inv, inv2);
            out.sample(&p, &v, &a, self.tcp);
            self.j += 1;
        }
        while self.cur > 0 && self.spans_done > 0 {
            self.win.pop_front();
            self.cur -= 1;
            self.spans_done -= 1;
            self.offset += 1;
        }
    }
}

/// A `G64` chain being planned ([module doc](self)).
struct ChainState {
    tcp: bool,
    basis: Option<bool>,
    /// Segments not yet final with their moves and the junction cap at the start of each (the
    /// first entry's cap is unused: its junction is final).
    pend: VecDeque<(Seg, f64, Move)>,
    /// Forward-pass speed at the start of `pend[0]`.
    vf: f64,
    /// Segments in the chain so far.
    count: usize,
    /// Unscaled time of the final segments so far.
    t: f64,
    /// Scan the look-ahead when it holds this many segments.
    scan_at: usize,
    /// Second pass: the sampler, once the chain has two segments.
    sampler: Option<ChainSampler>,
}

/// A chain of fine blocks being gathered ([module doc](self)).
struct FineState {
    tcp: bool,
    first_line: u32,
    /// Moves in the chain so far.
    blocks: usize,
    /// Second pass: run time-exactly (else every block as an exact stop).
    exact: bool,
    /// First pass: the worst block too fast for the limits (speed, cap, line, col, rotary).
    refusal: Option<(f64, f64, u32, u32, bool)>,
    /// First pass: what running the blocks as exact stops adds (samples, slowdowns).
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

/// The planner of both passes: the logic of [`crate::interpolate`] fed one move at a time.
struct Planner<'d, 's, E> {
    limits: &'d Limits,
    opts: &'d InterpolateOptions,
    mode: Mode<'d, 's, E>,
    /// Moves received and not yet planned (the newest may still become a stop).
    queue: VecDeque<(usize, Move)>,
    received: usize,
    state: State,
    slowed: Slowed,
    warnings_early: Vec<Diagnostic>,
    total: u64,
    last_move: Option<Move>,
    lookahead_peak: usize,
    any_tcp: bool,
}

impl<'d, 's, E> Planner<'d, 's, E> {
    fn new(limits: &'d Limits, opts: &'d InterpolateOptions, mode: Mode<'d, 's, E>) -> Self {
        Planner {
            limits,
            opts,
            mode,
            queue: VecDeque::new(),
            received: 0,
            state: State::Idle,
            slowed: Slowed::default(),
            warnings_early: Vec::new(),
            total: 0,
            last_move: None,
            lookahead_peak: 0,
            any_tcp: false,
        }
    }

    fn take_failure(&mut self) -> Option<E> {
        match &mut self.mode {
            Mode::Sample { out, .. } => out.failure.take(),
            Mode::Plan(_) => None,
        }
    }

    fn sampling(&self) -> bool {
        matches!(self.mode, Mode::Sample { .. })
    }

    /// Count a piece's samples against the budget (as [`crate::interpolate`] does).
    fn account(&mut self, n: u64) -> Result<u64, Error> {
        let base = self.total;
        self.total += n;
        let max = self.opts.max_samples;
        if self.total + 1 > max as u64 {
            return Err(Error::TooManySamples {
                samples: (self.total + 1) as f64,
                max,
                duration_s: self.total as f64 * self.opts.ts,
            });
        }
        Ok(base)
    }

    /// The next move of the program.
    fn push(&mut self, mv: Move) -> Result<(), Error> {
        if let Mode::Sample { out, .. } = &self.mode
            && out.failure.is_some()
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
    fn finish(&mut self) -> Result<(), Error> {
        while !self.queue.is_empty() {
            self.step()?;
        }
        self.end_state()
    }

    /// Plan the oldest queued move.
    fn step(&mut self) -> Result<(), Error> {
        let Some((i, mv)) = self.queue.pop_front() else {
            return Ok(());
        };
        let taken = match std::mem::replace(&mut self.state, State::Idle) {
            State::Idle => false,
            State::Chain(c) => {
                self.state = State::Chain(c);
                self.chain_move(i, &mv)?
            }
            State::Fine(f) => {
                self.state = State::Fine(f);
                self.fine_move(i, &mv)?
            }
        };
        if !taken {
            self.idle_move(i, &mv)?;
        }
        self.last_move = Some(mv);
        Ok(())
    }

    /// A move with no chain open (the outer loop of [`crate::interpolate`]).
    fn idle_move(&mut self, i: usize, mv: &Move) -> Result<(), Error> {
        let ts = self.opts.ts;
        let max = self.opts.max_samples;
        if let MoveKind::Dwell { seconds } = mv.kind {
            let n = samples_for(seconds, ts, max)?;
            let base = self.account(n)?;
            if let Mode::Sample { out, .. } = &mut self.mode {
                let b = base as usize;
                out.span(b + 1, b + n as usize + 1, mv);
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
            let taken = self.fine_move(i, mv)?;
            debug_assert!(taken);
            return Ok(());
        }
        if continuous(mv) {
            self.state = State::Chain(Box::new(ChainState {
                tcp: mv.tcp,
                basis: None,
                pend: VecDeque::new(),
                vf: 0.0,
                count: 0,
                t: 0.0,
                scan_at: 64,
                sampler: None,
            }));
            let taken = self.chain_move(i, mv)?;
            debug_assert!(taken);
            return Ok(());
        }
        self.exact_stop(i, mv, false)
    }

    /// A block run on its own, rest to rest; `alt`: the first pass's alternative of a fine
    /// chain (counted apart, in the chain's state, until the chain's end decides).
    fn exact_stop(&mut self, i: usize, mv: &Move, alt: bool) -> Result<(), Error> {
        let (ts, max) = (self.opts.ts, self.opts.max_samples);
        let Some(seg) = segment(mv, i, self.limits, self.opts)? else {
            return Ok(());
        };
        if alt {
            if let State::Fine(f) = &mut self.state {
                let piece = exact_stop_piece(seg, mv, &mut f.alt_slowed, ts, max)?;
                f.alt_samples += piece.n;
            }
            return Ok(());
        }
        let piece = exact_stop_piece(seg, mv, &mut self.slowed, ts, max)?;
        self.sample_piece(piece, mv)
    }

    /// Count a whole piece of one block and, in the second pass, sample it.
    fn sample_piece(&mut self, piece: Piece, mv: &Move) -> Result<(), Error> {
        let base = self.account(piece.n)?;
        if let Mode::Sample { out, .. } = &mut self.mode {
            let mut s = ChainSampler::new(piece.n, piece.lambda, base, piece.tcp);
            for (seg, trap, tau0) in piece.segs {
                s.win.push_back((seg, trap, tau0, mv.clone()));
            }
            s.pump(true, out, self.opts.ts);
        }
        Ok(())
    }

    /// A move offered to the open fine chain; `false` when it ends the chain before it.
    fn fine_move(&mut self, i: usize, mv: &Move) -> Result<bool, Error> {
        let ts = self.opts.ts;
        let State::Fine(f) = &self.state else {
            return Ok(false);
        };
        if !fine_block(mv, ts) || mv.tcp != f.tcp {
            self.end_state()?;
            return Ok(false);
        }
        let sampling = self.sampling();
        let exact = f.exact;
        if !sampling {
            // Both ways, decided at the chain's end.
            self.exact_stop(i, mv, true)?;
        } else if !exact {
            self.exact_stop(i, mv, false)?;
        }
        let seg = segment(mv, i, self.limits, self.opts)?;
        let State::Fine(f) = &mut self.state else {
            return Ok(true);
        };
        f.blocks += 1;
        if let Some(seg) = seg {
            if !sampling {
                let speed = seg.len / ts;
                if speed > seg.vlim * (1.0 + 1e-9)
                    && f.refusal.is_none_or(|r| speed / seg.vlim > r.0 / r.1)
                {
                    f.refusal = Some((speed, seg.vlim, mv.line, mv.col, !seg.xyz_basis));
                }
                f.points += 1;
            } else if exact {
                // Point q arrives: sample q − 1 needs points q − 2, q − 1 and q (module doc of
                // the interpolator: central differences, at rest before the first point).
                let q = f.points;
                f.points += 1;
                let (a, b, c) = (if q >= 2 { f.prev } else { f.cur }, f.cur, mv.end);
                f.prev = f.cur;
                f.cur = mv.end;
                let k = (f.base + q - 1) as usize;
                let tcp = f.tcp;
                if let Mode::Sample { out, .. } = &mut self.mode {
                    out.span(k + 1, k + 2, mv);
                    let (v, acc) = central_rates(&a, &b, &c, ts);
                    out.sample(&b, &v, &acc, tcp);
                }
            }
        }
        if mv.stop_after {
            self.end_state()?;
        }
        Ok(true)
    }

    /// A move offered to the open chain; `false` when it ends the chain before it.
    fn chain_move(&mut self, i: usize, mv: &Move) -> Result<bool, Error> {
        let State::Chain(c) = &self.state else {
            return Ok(false);
        };
        if !continuous(mv) || mv.tcp != c.tcp {
            self.end_state()?;
            return Ok(false);
        }
        if let Some(seg) = segment(mv, i, self.limits, self.opts)? {
            let State::Chain(c) = &mut self.state else {
                return Ok(false);
            };
            if c.basis.is_some_and(|b| b != seg.xyz_basis) {
                self.end_state()?;
                return Ok(false);
            }
            c.basis = Some(seg.xyz_basis);
            self.slowed.feed(&seg, mv);
            let delta = mv
                .blend_tolerance_mm
                .unwrap_or(self.opts.junction_deviation);
            self.add_segment(seg, delta, mv)?;
        }
        if mv.stop_after {
            self.end_state()?;
        }
        Ok(true)
    }

    fn add_segment(&mut self, seg: Seg, delta: f64, mv: &Move) -> Result<(), Error> {
        let ts = self.opts.ts;
        let State::Chain(c) = &mut self.state else {
            return Ok(());
        };
        let cap = match c.pend.back() {
            Some((prev, _, _)) => junction(prev, &seg, delta, self.limits, ts),
            None => 0.0,
        };
        c.pend.push_back((seg, cap, mv.clone()));
        c.count += 1;
        self.lookahead_peak = self.lookahead_peak.max(c.pend.len());
        if c.count == 2
            && let Mode::Sample { decisions, .. } = &mut self.mode
        {
            let (n, lam) = decisions.chains.pop_front().unwrap_or((0, 1.0));
            let tcp = c.tcp;
            let base = self.total;
            self.account(n)?;
            if let State::Chain(c) = &mut self.state {
                c.sampler = Some(ChainSampler::new(n, lam, base, tcp));
            }
        }
        let State::Chain(c) = &mut self.state else {
            return Ok(());
        };
        if c.pend.len() >= c.scan_at {
            // The last junction whose speed is its own cap, looking back from a stop after
            // the newest segment (module doc).
            let mut w = 0.0f64;
            let mut found = None;
            for k in (1..c.pend.len()).rev() {
                let (s, cap, _) = &c.pend[k];
                let reach = (w * w + 2.0 * s.acap * s.len).sqrt();
                if *cap <= reach {
                    found = Some(k);
                    break;
                }
                w = reach;
            }
            if let Some(k) = found {
                let cap_k = c.pend[k].1;
                self.finalise(k, cap_k);
            }
            if let State::Chain(c) = &mut self.state {
                c.scan_at = c.pend.len() + c.pend.len().max(64);
            }
        }
        self.pump(false);
        Ok(())
    }

    /// Profile `pend[..k]`: the backward pass from junction `k`, whose speed is `end_speed`,
    /// then the forward pass, as [`crate::interpolate`] runs them.
    fn finalise(&mut self, k: usize, end_speed: f64) {
        let State::Chain(c) = &mut self.state else {
            return;
        };
        let mut wb = vec![0.0f64; k + 1];
        wb[k] = end_speed;
        for kk in (1..k).rev() {
            let (s, cap, _) = &c.pend[kk];
            let reach = (wb[kk + 1] * wb[kk + 1] + 2.0 * s.acap * s.len).sqrt();
            wb[kk] = cap.min(reach);
        }
        for exit_b in wb.iter().skip(1) {
            let Some((seg, _, mv)) = c.pend.pop_front() else {
                break;
            };
            let reach = (c.vf * c.vf + 2.0 * seg.acap * seg.len).sqrt();
            let exit = exit_b.min(reach);
            let trap = Trap::new(seg.len, c.vf, exit, seg.vcap, seg.acap);
            let tau0 = c.t;
            c.t += trap.duration();
            c.vf = exit;
            if let Some(s) = &mut c.sampler {
                s.win.push_back((seg, trap, tau0, mv));
            }
        }
    }

    /// Sample what the open chain's final segments allow.
    fn pump(&mut self, ended: bool) {
        let ts = self.opts.ts;
        if let (State::Chain(c), Mode::Sample { out, .. }) = (&mut self.state, &mut self.mode)
            && let Some(s) = &mut c.sampler
        {
            s.pump(ended, out, ts);
        }
    }

    /// Close the open chain, if any.
    fn end_state(&mut self) -> Result<(), Error> {
        let (ts, max) = (self.opts.ts, self.opts.max_samples);
        match std::mem::replace(&mut self.state, State::Idle) {
            State::Idle => Ok(()),
            State::Chain(mut c) => match c.count {
                0 => Ok(()),
                1 => {
                    // One segment: a block of its own, as the whole-program path runs it.
                    let Some((seg, _, mv)) = c.pend.pop_front() else {
                        return Ok(());
                    };
                    let piece = single(seg, c.tcp, None, ts, max)?;
                    self.sample_piece(piece, &mv)
                }
                _ => {
                    let k = c.pend.len();
                    let sampling = c.sampler.is_some();
                    self.state = State::Chain(c);
                    self.finalise(k, 0.0);
                    self.pump(true);
                    let State::Chain(c) = std::mem::replace(&mut self.state, State::Idle) else {
                        return Ok(());
                    };
                    if !sampling {
                        let t = c.t;
                        let n = samples_for(t, ts, max)?;
                        let lambda = (n as f64 * ts / t).max(1.0);
                        self.account(n)?;
                        if let Mode::Plan(d) = &mut self.mode {
                            d.chains.push_back((n, lambda));
                        }
                    }
                    Ok(())
                }
            },
            State::Fine(f) => {
                if self.sampling() {
                    if f.exact {
                        // The samples were emitted as the blocks came; count them.
                        let n = f.points - 1;
                        self.account(n)?;
                    }
                    return Ok(());
                }
                match f.refusal {
                    Some((speed, cap, line, col, deg)) => {
                        let unit = if deg { "deg" } else { "mm" };
                        let message = format!(
                            "the {} fine blocks from line {} (G93 G64, 1/F = one sample period) are not run as set-points: line {line} needs {speed:.3} {unit}/s along its path, the limits allow {cap:.3} {unit}/s; each block runs as an exact stop",
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
                        self.account(f.alt_samples)?;
                        if let Mode::Plan(d) = &mut self.mode {
                            d.fine.push_back(false);
                        }
                    }
                    None => {
                        self.account(f.points - 1)?;
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
