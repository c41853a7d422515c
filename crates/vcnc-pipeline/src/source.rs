//! Where a run's reference comes from, handed on a piece at a time (docs/performance.md,
//! "Streaming").
//!
//! Every run that drives axes — interpolate, simulate, predict — reads its reference from a
//! [`Source`] and sees it as consecutive [`ReferenceChunk`]s of machine-axis references:
//!
//! - [`Source::Streamed`]: a program of any length read twice a piece at a time
//!   ([`vcnc_gcode::plan`]); each piece of samples goes through the inverse kinematics (TCP
//!   samples) and the travel check before it is handed over and dropped, so memory does not grow
//!   with the program. The samples are [`crate::run::prepare`]'s bit for bit (tested), O-word
//!   control flow included.
//! - [`Source::Prepared`]: a program prepared whole ([`crate::run::prepare`], which has done the
//!   inverse kinematics and the travel check), its samples handed on in the same pieces — for the
//!   runs that need the whole reference anyway (compensation, feed planning, sweeps that run one
//!   program on many machines).
//!
//! Both give the same chunks, so what a run computes does not depend on where its reference
//! came from.

use std::path::{Path, PathBuf};

use vcnc_gcode::{MoveClass, SampleChunk, StreamOptions, StreamPlan};
use vcnc_machine::Machine;

use crate::error::Error;
use crate::run::{Run, missing_axis, moves, no_motion_warning, peak_warnings};

/// Most samples of a streamed reference: 2^40 (35 years at 1 ms).
pub const STREAM_MAX_SAMPLES: usize = 1 << 40;

/// Samples per piece of a run: a piece's buffers (the reference, the drives' and models'
/// positions, three poses and the errors of each sample, a table's columns) are about 1 kB a
/// sample, so 16 384 keep them near 16 MB; longer pieces save nothing measurable.
pub const PIECE_SAMPLES: usize = 1 << 14;

/// A program's text: a file read a piece at a time, or text in memory (the embedded spiral).
#[derive(Debug, Clone)]
pub enum Program {
    /// A file.
    File(PathBuf),
    /// Text in memory, with the name messages give it.
    Text {
        /// The program.
        text: String,
        /// Its name in messages (`<embedded>/gcode/spiral.ngc`).
        name: String,
    },
}

impl Program {
    /// The name messages and summaries give the program (the path as given).
    pub fn name(&self) -> String {
        match self {
            Program::File(p) => p.display().to_string(),
            Program::Text { name, .. } => name.clone(),
        }
    }

    /// First pass of the streamed interpolation over the program.
    fn plan(
        &self,
        interp: &vcnc_gcode::InterpOptions,
        limits: &vcnc_gcode::Limits,
        opts: &vcnc_gcode::InterpolateOptions,
        stream: &StreamOptions,
    ) -> Result<StreamPlan, vcnc_gcode::Error> {
        match self {
            Program::File(p) => vcnc_gcode::plan(p.as_path(), interp, limits, opts, stream),
            Program::Text { text, .. } => {
                vcnc_gcode::plan(text.as_str(), interp, limits, opts, stream)
            }
        }
    }

    /// Second pass: the samples of `plan`, a piece at a time.
    fn sample<E: From<vcnc_gcode::Error>>(
        &self,
        plan: &StreamPlan,
        sink: &mut dyn FnMut(&SampleChunk) -> Result<(), E>,
    ) -> Result<(), E> {
        match self {
            Program::File(p) => plan.sample(p.as_path(), sink),
            Program::Text { text, .. } => plan.sample(text.as_str(), sink),
        }
    }
}

/// A program planned for streaming on a machine (the first of its two passes).
#[derive(Debug, Clone)]
pub struct ReferenceStream {
    /// The program's name, as messages and summaries give it.
    pub file: String,
    /// The program.
    pub program: Program,
    /// What the first pass learned.
    pub plan: StreamPlan,
    /// The warnings of the first pass (parser, interpreter, interpolator), formatted with the
    /// program's name.
    pub warnings: Vec<String>,
}

/// One piece of the reference: per machine axis position, velocity and acceleration.
#[derive(Debug, Clone, Default)]
pub struct ReferenceChunk {
    /// Index of the first sample.
    pub first: usize,
    /// Per machine axis (in the machine's order): position, mm or deg.
    pub pos: Vec<Vec<f64>>,
    /// Per machine axis: velocity, units/s.
    pub vel: Vec<Vec<f64>>,
    /// Per machine axis: acceleration, units/s².
    pub acc: Vec<Vec<f64>>,
    /// Per sample: class of its block (`None` without one).
    pub class: Vec<Option<MoveClass>>,
    /// Per sample: the source line of the block running (0 where none is).
    pub line: Vec<u32>,
}

impl ReferenceChunk {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.class.len()
    }

    /// `true` without samples.
    pub fn is_empty(&self) -> bool {
        self.class.is_empty()
    }

    /// Machine axis `i`'s reference in this chunk.
    pub fn axis(&self, i: usize) -> vcnc_drive::Reference<'_> {
        vcnc_drive::Reference {
            pos: &self.pos[i],
            vel: &self.vel[i],
            acc: &self.acc[i],
        }
    }

    /// The axis positions per machine axis.
    pub fn positions(&self) -> Vec<&[f64]> {
        self.pos.iter().map(Vec::as_slice).collect()
    }
}

/// What handing on the reference measured.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceStats {
    /// Per machine axis: largest |velocity|, units/s.
    pub max_vel: Vec<f64>,
    /// Per machine axis: largest |acceleration|, units/s².
    pub max_acc: Vec<f64>,
    /// Per machine axis: the position ever differs from the first sample's.
    pub moved: Vec<bool>,
    /// Samples in feed moves.
    pub feed_samples: usize,
    /// Samples handed on.
    pub samples: usize,
    /// Warnings found while streaming (TCP references beyond an axis' limits); a prepared
    /// run's are among its own warnings already.
    pub warnings: Vec<String>,
}

impl ReferenceStats {
    fn new(axes: usize) -> ReferenceStats {
        ReferenceStats {
            max_vel: vec![0.0; axes],
            max_acc: vec![0.0; axes],
            moved: vec![false; axes],
            feed_samples: 0,
            samples: 0,
            warnings: Vec::new(),
        }
    }

    /// Takes a chunk's samples into the statistics; `first_pos` keeps each axis' first
    /// position.
    fn observe(&mut self, c: &ReferenceChunk, first_pos: &mut [Option<f64>]) {
        for (i, f) in first_pos.iter_mut().enumerate() {
            let f = *f.get_or_insert(c.pos[i].first().copied().unwrap_or(0.0));
            self.moved[i] |= c.pos[i].iter().any(|p| *p != f);
            self.max_vel[i] = c.vel[i].iter().fold(self.max_vel[i], |m, v| m.max(v.abs()));
            self.max_acc[i] = c.acc[i].iter().fold(self.max_acc[i], |m, v| m.max(v.abs()));
        }
        self.feed_samples += c
            .class
            .iter()
            .filter(|x| **x == Some(MoveClass::Feed))
            .count();
        self.samples += c.len();
    }
}

/// Where a run's reference comes from (module documentation).
#[derive(Debug, Clone, Copy)]
pub enum Source<'a> {
    /// A program prepared whole.
    Prepared(&'a Run),
    /// A program planned for streaming.
    Streamed(&'a ReferenceStream),
}

impl Source<'_> {
    /// The program's name, as messages and summaries give it.
    pub fn file(&self) -> &str {
        match self {
            Source::Prepared(r) => &r.file,
            Source::Streamed(s) => &s.file,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            Source::Prepared(r) => r.len(),
            Source::Streamed(s) => s.len(),
        }
    }

    /// `true` without samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sample period, s.
    pub fn ts(&self) -> f64 {
        match self {
            Source::Prepared(r) => r.ts,
            Source::Streamed(s) => s.plan.ts,
        }
    }

    /// Duration of the program, s.
    pub fn duration_s(&self) -> f64 {
        match self {
            Source::Prepared(r) => r.duration_s(),
            Source::Streamed(s) => s.duration_s(),
        }
    }

    /// The planner's cycle time, split between feeds, rapids and dwells (the duration before
    /// sampling: [`Source::duration_s`] is the last sample's time).
    pub fn cycle(&self) -> vcnc_gcode::CycleTime {
        match self {
            Source::Prepared(r) => r.loaded.trajectory.cycle,
            Source::Streamed(s) => s.plan.cycle,
        }
    }

    /// Whether some samples are in tool-centre-point mode.
    pub fn has_tcp(&self) -> bool {
        match self {
            Source::Prepared(r) => r.has_tcp(),
            Source::Streamed(s) => s.plan.any_tcp,
        }
    }

    /// Whether the program moves at all (a feed move or a rapid of some length).
    pub fn has_motion(&self) -> bool {
        match self {
            Source::Prepared(r) => r.has_motion(),
            Source::Streamed(s) => moves(&s.plan.cycle),
        }
    }

    /// The warnings known before the reference is handed on.
    pub fn warnings(&self) -> &[String] {
        match self {
            Source::Prepared(r) => &r.warnings,
            Source::Streamed(s) => &s.warnings,
        }
    }

    /// Hands the reference to `sink` in pieces of [`PIECE_SAMPLES`], in order, and returns
    /// what it measured. A streamed program is checked as it goes (the first sample beyond an
    /// axis' travel stops the run with [`Error::Travel`], as [`crate::run::prepare`] refuses
    /// it). A failure of `sink` stops the run and is returned as it is.
    pub fn for_each<E: From<Error>>(
        &self,
        machine: &Machine,
        sink: &mut dyn FnMut(&ReferenceChunk) -> Result<(), E>,
    ) -> Result<ReferenceStats, E> {
        match self {
            Source::Prepared(run) => Ok(prepared_chunks(machine, run, sink)?),
            Source::Streamed(s) => s.run(machine, sink),
        }
    }
}

/// A prepared run's reference in pieces of [`PIECE_SAMPLES`].
fn prepared_chunks<E: From<Error>>(
    machine: &Machine,
    run: &Run,
    sink: &mut dyn FnMut(&ReferenceChunk) -> Result<(), E>,
) -> Result<ReferenceStats, E> {
    let axes = machine.axes.len().min(run.axes.len());
    let mut stats = ReferenceStats::new(axes);
    let mut first_pos = vec![None; axes];
    let mut chunk = ReferenceChunk {
        pos: vec![Vec::new(); axes],
        vel: vec![Vec::new(); axes],
        acc: vec![Vec::new(); axes],
        ..ReferenceChunk::default()
    };
    let n = run.len();
    for start in (0..n).step_by(PIECE_SAMPLES) {
        let end = (start + PIECE_SAMPLES).min(n);
        chunk.first = start;
        for (i, a) in run.axes.iter().enumerate().take(axes) {
            for (dst, src) in [
                (&mut chunk.pos[i], &a.pos),
                (&mut chunk.vel[i], &a.vel),
                (&mut chunk.acc[i], &a.acc),
            ] {
                dst.clear();
                dst.extend_from_slice(&src[start..end]);
            }
        }
        chunk.class.clear();
        chunk.class.extend_from_slice(&run.classes[start..end]);
        chunk.line.clear();
        chunk.line.extend_from_slice(&run.lines[start..end]);
        stats.observe(&chunk, &mut first_pos);
        sink(&chunk)?;
    }
    Ok(stats)
}

/// First pass over `program` on `machine` (pieces of [`PIECE_SAMPLES`]).
pub fn plan(machine: &Machine, program: Program, lenient: bool) -> Result<ReferenceStream, Error> {
    let opts = StreamOptions {
        chunk_samples: PIECE_SAMPLES,
        ..StreamOptions::default()
    };
    plan_pieces(machine, program, lenient, &opts)
}

/// [`plan`] with pieces of source and of samples of the sizes `opts` gives (the results do not
/// depend on them; tests cut the program and its reference anywhere with them).
pub fn plan_pieces(
    machine: &Machine,
    program: Program,
    lenient: bool,
    opts: &StreamOptions,
) -> Result<ReferenceStream, Error> {
    let file = program.name();
    let interpolate = vcnc_gcode::InterpolateOptions {
        // The whole-program path's sample budget bounds the memory it holds; streamed, the
        // memory does not grow with the length, and this only refuses a program lasting more
        // than 2^40 samples (35 years at 1 ms), which is junk.
        max_samples: STREAM_MAX_SAMPLES,
        ..machine.interpolate_options()
    };
    let plan = match program.plan(
        &machine.interp_options(lenient),
        &machine.limits(),
        &interpolate,
        opts,
    ) {
        Ok(p) => p,
        // The machine lacks the axis (its limits are 0): said as the whole-program path says it.
        Err(vcnc_gcode::Error::AxisCannotMove {
            axis: Some(name),
            line,
            ..
        }) if machine.axis(name).is_none() => {
            return Err(missing_axis(machine, &file, name, line, 1));
        }
        Err(vcnc_gcode::Error::Read { message }) => {
            return Err(Error::Io { file, message });
        }
        Err(e) => return Err(Error::gcode(&file, e)),
    };
    if plan.any_tcp {
        machine.require_kinematics()?;
    }
    let mut warnings: Vec<String> = plan
        .warnings
        .iter()
        .map(|d| format!("{file}:{}:{}: warning: {}", d.line, d.col, d.message))
        .collect();
    if !moves(&plan.cycle) {
        warnings.push(no_motion_warning(&file));
    }
    Ok(ReferenceStream {
        file,
        program,
        plan,
        warnings,
    })
}

/// [`plan`] of the program file at `path`.
pub fn plan_file(machine: &Machine, path: &Path, lenient: bool) -> Result<ReferenceStream, Error> {
    plan(machine, Program::File(path.to_path_buf()), lenient)
}

impl ReferenceStream {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.plan.samples
    }

    /// `true` without samples (never: a trajectory ends with a sample at rest).
    pub fn is_empty(&self) -> bool {
        self.plan.samples == 0
    }

    /// Duration, s.
    pub fn duration_s(&self) -> f64 {
        self.plan.duration_s()
    }

    /// Second pass: hand the reference to `sink` a piece at a time, after the inverse
    /// kinematics (TCP samples) and the travel check.
    fn run<E: From<Error>>(
        &self,
        machine: &Machine,
        sink: &mut dyn FnMut(&ReferenceChunk) -> Result<(), E>,
    ) -> Result<ReferenceStats, E> {
        let file = self.file.clone();
        let n_axes = machine.axes.len();
        let mut stats = ReferenceStats::new(n_axes);
        let mut first_pos: Vec<Option<f64>> = vec![None; n_axes];
        // Axes the program output that the machine lacks must stay still.
        let mut foreign_first: Vec<Option<f64>> = vec![None; self.plan.axes.len()];
        let kin = if self.plan.any_tcp {
            Some(machine.require_kinematics().map_err(Error::from)?)
        } else {
            None
        };
        let ts = self.plan.ts;
        let mut chunk = ReferenceChunk::default();
        // Where each machine axis is among the streamed axes (`None`: the program never
        // names it, so it rests at 0).
        let source: Vec<Option<usize>> = machine
            .axes
            .iter()
            .map(|a| self.plan.axes.iter().position(|x| *x == a.name))
            .collect();
        let mut on_samples = |c: &SampleChunk| -> Result<(), Failure<E>> {
            let n = c.len();
            chunk.first = c.first;
            // The buffers are kept from piece to piece (the inverse kinematics replaces X Y Z
            // with new ones).
            chunk.pos.resize_with(n_axes, Vec::new);
            chunk.vel.resize_with(n_axes, Vec::new);
            chunk.acc.resize_with(n_axes, Vec::new);
            for (i, j) in source.iter().enumerate() {
                for (dst, src) in [
                    (&mut chunk.pos[i], &c.pos),
                    (&mut chunk.vel[i], &c.vel),
                    (&mut chunk.acc[i], &c.acc),
                ] {
                    dst.clear();
                    match j {
                        Some(j) => dst.extend_from_slice(&src[*j]),
                        None => dst.resize(n, 0.0),
                    }
                }
            }
            for (j, name) in self.plan.axes.iter().enumerate() {
                if machine.axis(*name).is_some() {
                    continue;
                }
                for (k, &p) in c.pos[j].iter().enumerate() {
                    let f = *foreign_first[j].get_or_insert(p);
                    if p != f {
                        return Err(Failure::Pipeline(missing_axis(
                            machine, &file, *name, c.line[k], 1,
                        )));
                    }
                }
            }
            if let Some(kin) = kin
                && c.tcp.iter().any(|t| *t)
            {
                kin.inverse_tcp(&mut chunk.pos, &mut chunk.vel, &mut chunk.acc, &c.tcp)
                    .map_err(|source| {
                        Failure::Pipeline(Error::Kinematics {
                            context: file.clone(),
                            source,
                        })
                    })?;
            }
            for (i, a) in machine.axes.iter().enumerate() {
                let [lo, hi] = a.travel;
                if let Some(k) = chunk.pos[i].iter().position(|v| !(*v >= lo && *v <= hi)) {
                    return Err(Failure::Pipeline(Error::Travel {
                        file: file.clone(),
                        line: c.line[k],
                        axis: a.name,
                        value: chunk.pos[i][k],
                        lower: lo,
                        upper: hi,
                        unit: a.unit.as_str(),
                        t_s: (c.first + k) as f64 * ts,
                        target: (!c.tcp[k]).then(|| c.target[k][a.name.index()]),
                    }));
                }
            }
            chunk.class.clear();
            chunk.class.extend_from_slice(&c.class);
            chunk.line.clear();
            chunk.line.extend_from_slice(&c.line);
            stats.observe(&chunk, &mut first_pos);
            sink(&chunk).map_err(Failure::Consumer)
        };
        match self.program.sample(&self.plan, &mut on_samples) {
            Ok(()) => {}
            Err(Failure::Consumer(e)) => return Err(e),
            Err(Failure::Pipeline(e)) => return Err(e.into()),
            Err(Failure::Gcode(vcnc_gcode::Error::Read { message })) => {
                return Err(Error::Io { file, message }.into());
            }
            Err(Failure::Gcode(e)) => return Err(Error::gcode(&file, e).into()),
        }
        if self.plan.any_tcp {
            for (i, a) in machine.axes.iter().enumerate() {
                stats
                    .warnings
                    .extend(peak_warnings(a, stats.max_vel[i], stats.max_acc[i], &file));
            }
        }
        Ok(stats)
    }
}

/// An error of the second pass: the G-code side's, the pipeline's or the consumer's.
enum Failure<E> {
    Gcode(vcnc_gcode::Error),
    Pipeline(Error),
    Consumer(E),
}

impl<E> From<vcnc_gcode::Error> for Failure<E> {
    fn from(e: vcnc_gcode::Error) -> Self {
        Failure::Gcode(e)
    }
}
