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

use super::chain::{Out, TcpSwitch};
use super::planner::{Decisions, Mode, Planner};
use super::segment::{Cfg, check_limits};
use super::{CycleTime, Limits, Move, MoveClass, Slowdown, output_axes};
use crate::diag::Diagnostic;
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
    /// The cycle time and its split by kind of move ([`crate::Trajectory::cycle`]).
    pub cycle: CycleTime,
    /// Every warning (parser, interpreter, interpolator), in the order of [`crate::load`].
    pub warnings: Vec<Diagnostic>,
    /// Most pieces the look-ahead held at once.
    pub lookahead_peak: usize,
    interp: InterpOptions,
    cfg: Cfg,
    stream: StreamOptions,
    decisions: Decisions,
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
    let cfg = Cfg::new(limits, opts);
    let mut decisions = Decisions::default();
    let mut planner = Planner::new(&cfg, Mode::Plan(&mut decisions));
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
    let (lookahead_peak, any_tcp, cycle) = (planner.lookahead_peak, planner.any_tcp, planner.cycle);
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
        cycle,
        warnings,
        lookahead_peak,
        interp: interp.clone(),
        cfg,
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
        let mut emitter = Emitter {
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
        let mut switch = TcpSwitch::new(&mut emitter);
        let mut planner = Planner::new(
            &self.cfg,
            Mode::Sample {
                decisions: &mut decisions,
                out: &mut switch,
            },
        );
        let run = run_source(src, &self.interp, &self.stream, &mut planner);
        let total = planner.total;
        let run = match run {
            Ok(r) => r,
            Err(e) => {
                drop(planner);
                return Err(failure.unwrap_or_else(|| e.into()));
            }
        };
        planner.final_sample(run.start);
        drop(planner);
        emitter.flush();
        if let Some(e) = failure {
            return Err(e);
        }
        if total + 1 != self.samples as u64 {
            return Err(Error::Read {
                message: format!(
                    "the program changed between the two passes ({} samples, then {})",
                    self.samples,
                    total + 1
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
fn run_source(
    src: &(impl ProgramSource + ?Sized),
    interp_opts: &InterpOptions,
    stream: &StreamOptions,
    planner: &mut Planner<'_, '_, '_>,
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

/// The sampling side of the second pass: samples into chunks, each with its span resolved.
struct Emitter<'s, E> {
    /// Indices in X Y Z A B C of the output axes.
    idx: Vec<usize>,
    chunk: SampleChunk,
    chunk_samples: usize,
    /// Index of the next sample.
    next_sample: usize,
    /// Spans not yet passed: (first sample, end sample, line, class, target, move index).
    spans: VecDeque<(usize, usize, u32, MoveClass, [f64; 6], usize)>,
    first_span: bool,
    sink: &'s mut dyn FnMut(&SampleChunk) -> Result<(), E>,
    failure: &'s mut Option<E>,
}

impl<E> Out for Emitter<'_, E> {
    fn span(&mut self, first: usize, end: usize, _t0: f64, _t1: f64, index: usize, mv: &Move) {
        if let Some(last) = self.spans.back_mut()
            && last.5 == index
        {
            last.1 = end;
            return;
        }
        let first = if std::mem::take(&mut self.first_span) {
            0
        } else {
            first
        };
        self.spans
            .push_back((first, end, mv.line, MoveClass::of(&mv.kind), mv.end, index));
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

    fn failed(&self) -> bool {
        self.failure.is_some()
    }
}

impl<E> Emitter<'_, E> {
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
