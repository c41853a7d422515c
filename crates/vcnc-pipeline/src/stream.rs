//! The reference trajectory of a program of any length, streamed (docs/performance.md,
//! "Streaming"): the program is read twice a piece at a time ([`vcnc_gcode::plan`]), and each
//! piece of samples goes through the inverse kinematics, the travel check and the statistics
//! before it is handed over and dropped. Memory does not grow with the program's length.
//!
//! The samples are those of [`crate::run::prepare`] bit for bit (tested), O-word control flow
//! included (the reader seeks back to the statements a jump leads to, docs/performance.md).

use std::path::Path;

use rayon::prelude::*;

use vcnc_gcode::{MoveClass, SampleChunk, StreamOptions, StreamPlan};
use vcnc_machine::Machine;

use crate::error::Error;
use crate::run::{AxisRates, InterpolateSummary, missing_axis, peak_warnings};

/// Most samples of a streamed reference: 2^40 (35 years at 1 ms).
pub const STREAM_MAX_SAMPLES: usize = 1 << 40;

/// A program planned for streaming on a machine.
#[derive(Debug, Clone)]
pub struct ReferenceStream {
    /// The program's path, as given.
    pub file: String,
    /// What the first pass learned.
    pub plan: StreamPlan,
    /// The warnings so far (parser, interpreter, interpolator), formatted with the file.
    pub warnings: Vec<String>,
}

/// One piece of the reference: per machine axis position, velocity and acceleration, and the
/// tool tip in the workpiece frame for TCP programs.
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
    /// Tool tip px py pz (mm, workpiece frame) per sample, for programs with TCP moves.
    pub tip: Option<[Vec<f64>; 3]>,
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
}

/// Feeds chunk `c` to each machine axis's true-drive stream, every axis in parallel (each
/// stream in order, so the thread count does not matter), into `traces` (one per axis, its
/// channels cleared first): the streamed `predict` and `simulate` step.
pub(crate) fn feed_drives(
    machine: &Machine,
    drives: &mut [vcnc_drive::DriveStream],
    traces: &mut [vcnc_drive::DriveTrace],
    c: &ReferenceChunk,
) -> Result<(), Error> {
    drives
        .par_iter_mut()
        .zip(traces.par_iter_mut())
        .enumerate()
        .try_for_each(|(i, (d, t))| {
            t.clear_channels(0);
            d.feed(c.axis(i), t).map_err(drive_error(machine, i))
        })
}

/// The pipeline's error for machine axis `i`'s drive error.
pub(crate) fn drive_error(machine: &Machine, i: usize) -> impl Fn(vcnc_drive::Error) -> Error + '_ {
    move |source| Error::Drive {
        axis: machine.axes[i].name,
        source,
    }
}

/// What streaming the reference measured.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamStats {
    /// Per machine axis: largest |velocity| and |acceleration|.
    pub max_vel: Vec<f64>,
    /// Per machine axis: largest |acceleration|.
    pub max_acc: Vec<f64>,
    /// Per machine axis: the position ever differs from the first sample's.
    pub moved: Vec<bool>,
    /// Samples in feed moves.
    pub feed_samples: usize,
    /// Warnings found while streaming (TCP references beyond an axis' limits).
    pub warnings: Vec<String>,
}

/// First pass over the program at `path` on `machine`.
pub fn plan_file(
    machine: &Machine,
    path: &Path,
    lenient: bool,
    opts: &StreamOptions,
) -> Result<ReferenceStream, Error> {
    let file = path.display().to_string();
    let interpolate = vcnc_gcode::InterpolateOptions {
        // The whole-program path's sample budget bounds the memory it holds; streamed, the
        // memory does not grow with the length, and this only refuses a program lasting more
        // than 2^40 samples (35 years at 1 ms), which is junk.
        max_samples: STREAM_MAX_SAMPLES,
        ..machine.interpolate_options()
    };
    let plan = match vcnc_gcode::plan(
        path,
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
    let warnings = plan
        .warnings
        .iter()
        .map(|d| format!("{file}:{}:{}: warning: {}", d.line, d.col, d.message))
        .collect();
    Ok(ReferenceStream {
        file,
        plan,
        warnings,
    })
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
    /// kinematics (TCP samples) and the travel check (the first sample beyond an axis' travel
    /// stops the run with [`Error::Travel`], as [`crate::run::prepare`] refuses it).
    pub fn run(
        &self,
        machine: &Machine,
        path: &Path,
        sink: &mut dyn FnMut(&ReferenceChunk) -> Result<(), Error>,
    ) -> Result<StreamStats, Error> {
        let n_axes = machine.axes.len();
        let mut stats = StreamStats {
            max_vel: vec![0.0; n_axes],
            max_acc: vec![0.0; n_axes],
            moved: vec![false; n_axes],
            feed_samples: 0,
            warnings: Vec::new(),
        };
        let mut first_pos: Vec<Option<f64>> = vec![None; n_axes];
        // Axes the program output that the machine lacks must stay still.
        let mut foreign_first: Vec<Option<f64>> = vec![None; self.plan.axes.len()];
        let kin = if self.plan.any_tcp {
            Some(machine.require_kinematics()?)
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
        let mut on_samples = |c: &SampleChunk| -> Result<(), Error> {
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
                        return Err(missing_axis(machine, &self.file, *name, c.line[k], 1));
                    }
                }
            }
            if let Some(kin) = kin
                && c.tcp.iter().any(|t| *t)
            {
                let r = kin.axes;
                let track = |i: usize| vcnc_kinematics::Track {
                    pos: &chunk.pos[i],
                    vel: &chunk.vel[i],
                    acc: &chunk.acc[i],
                };
                let [x, y, z] = kin.model.inverse_tcp_track(
                    [track(r.x), track(r.y), track(r.z)],
                    track(r.a),
                    track(r.c),
                    &c.tcp,
                );
                for (i, t) in [(r.x, x), (r.y, y), (r.z, z)] {
                    chunk.pos[i] = t.pos;
                    chunk.vel[i] = t.vel;
                    chunk.acc[i] = t.acc;
                }
            }
            for (i, a) in machine.axes.iter().enumerate() {
                let [lo, hi] = a.travel;
                if let Some(k) = chunk.pos[i].iter().position(|v| !(*v >= lo && *v <= hi)) {
                    return Err(Error::Travel {
                        file: self.file.clone(),
                        line: c.line[k],
                        axis: a.name,
                        value: chunk.pos[i][k],
                        lower: lo,
                        upper: hi,
                        unit: a.unit.as_str(),
                        t_s: (c.first + k) as f64 * ts,
                        target: (!c.tcp[k]).then(|| c.target[k][a.name.index()]),
                    });
                }
                let f = *first_pos[i].get_or_insert(chunk.pos[i].first().copied().unwrap_or(0.0));
                stats.moved[i] |= chunk.pos[i].iter().any(|p| *p != f);
                stats.max_vel[i] = chunk.vel[i]
                    .iter()
                    .fold(stats.max_vel[i], |m, v| m.max(v.abs()));
                stats.max_acc[i] = chunk.acc[i]
                    .iter()
                    .fold(stats.max_acc[i], |m, v| m.max(v.abs()));
            }
            chunk.tip = match kin {
                Some(kin) => {
                    let pos: Vec<&[f64]> = chunk.pos.iter().map(Vec::as_slice).collect();
                    let mut tip: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(n));
                    for k in 0..n {
                        let q = kin.model.forward(&kin.axes.at(&pos, k));
                        for (i, t) in tip.iter_mut().enumerate() {
                            t.push(q.p[i]);
                        }
                    }
                    Some(tip)
                }
                None => None,
            };
            chunk.class.clear();
            chunk.class.extend_from_slice(&c.class);
            chunk.line.clear();
            chunk.line.extend_from_slice(&c.line);
            stats.feed_samples += c
                .class
                .iter()
                .filter(|x| **x == Some(MoveClass::Feed))
                .count();
            sink(&chunk)
        };
        let mut adapted = |c: &SampleChunk| on_samples(c).map_err(Failure::Pipeline);
        match self.plan.sample(path, &mut adapted) {
            Ok(()) => {}
            Err(Failure::Pipeline(e)) => return Err(e),
            Err(Failure::Gcode(vcnc_gcode::Error::Read { message })) => {
                return Err(Error::Io {
                    file: self.file.clone(),
                    message,
                });
            }
            Err(Failure::Gcode(e)) => return Err(Error::gcode(&self.file, e)),
        }
        if self.plan.any_tcp {
            for (i, a) in machine.axes.iter().enumerate() {
                stats.warnings.extend(peak_warnings(
                    a,
                    stats.max_vel[i],
                    stats.max_acc[i],
                    &self.file,
                ));
            }
        }
        Ok(stats)
    }

    /// `summary.json` of `vcnc interpolate` from the streamed run.
    pub fn summary(&self, machine: &Machine, stats: &StreamStats) -> InterpolateSummary {
        let mut warnings = self.warnings.clone();
        warnings.extend(stats.warnings.iter().cloned());
        InterpolateSummary {
            machine: machine.name.clone(),
            program: self.file.clone(),
            duration_s: self.duration_s(),
            feed_duration_s: stats.feed_samples as f64 * self.plan.ts,
            samples: self.len(),
            ts_s: self.plan.ts,
            tcp: self.plan.any_tcp,
            axes: machine
                .axes
                .iter()
                .enumerate()
                .map(|(i, a)| {
                    (
                        a.name.to_string(),
                        AxisRates {
                            unit: a.unit,
                            max_vel: stats.max_vel[i],
                            max_acc: stats.max_acc[i],
                        },
                    )
                })
                .collect(),
            warnings,
        }
    }
}

/// Min/max envelope of a signal over fixed time buckets: what a plot of a long signal needs, a
/// spike never lost (each bucket keeps its extremes).
#[derive(Debug, Clone)]
pub struct Envelope {
    bucket: usize,
    min: Vec<f64>,
    max: Vec<f64>,
}

impl Envelope {
    /// An envelope of `samples` samples in about `columns` buckets.
    pub fn new(samples: usize, columns: usize) -> Self {
        let bucket = samples.div_ceil(columns.max(1)).max(1);
        let n = samples.div_ceil(bucket);
        Envelope {
            bucket,
            min: vec![f64::INFINITY; n],
            max: vec![f64::NEG_INFINITY; n],
        }
    }

    /// Add samples `first..first + values.len()`.
    pub fn add(&mut self, first: usize, values: &[f64]) {
        for (k, v) in values.iter().enumerate() {
            let b = (first + k) / self.bucket;
            if b < self.min.len() {
                self.min[b] = self.min[b].min(*v);
                self.max[b] = self.max[b].max(*v);
            }
        }
    }

    /// The envelope as a polyline: per bucket its minimum then its maximum, at the bucket's
    /// first sample time (`ts` per sample).
    pub fn polyline(&self, ts: f64) -> (Vec<f64>, Vec<f64>) {
        let mut t = Vec::with_capacity(2 * self.min.len());
        let mut v = Vec::with_capacity(2 * self.min.len());
        for (b, (lo, hi)) in self.min.iter().zip(&self.max).enumerate() {
            if lo.is_finite() {
                let tb = (b * self.bucket) as f64 * ts;
                t.extend([tb, tb]);
                v.extend([*lo, *hi]);
            }
        }
        (t, v)
    }
}

/// An error of the second pass: the G-code side's or the consumer's.
enum Failure {
    Gcode(vcnc_gcode::Error),
    Pipeline(Error),
}

impl From<vcnc_gcode::Error> for Failure {
    fn from(e: vcnc_gcode::Error) -> Self {
        Failure::Gcode(e)
    }
}
