//! Tool-tip and orientation contour errors of a program with the true drives and with sets of
//! identified models (docs/contour.md, docs/performance.md "Streamed prediction").
//!
//! [`predict`] takes the reference a piece at a time from its [`Source`] through the true
//! drives and each model set (each model's positions advanced by its stated actual-value
//! latency, [`crate::latency`]), the forward kinematics and the contour searches
//! ([`vcnc_contour::ContourStream`], docs/contour.md#streamed-search), and hands each piece of
//! finished samples ([`PredictPiece`]) to a [`Sink`], accumulating the statistics of
//! `summary.json` on the way. Memory does not grow with the program: what is held is the
//! samples between the newest reference sample and the oldest one not finished (the latency
//! look-ahead and the searches' look-ahead, about a piece) and the ten worst lines so far.
//! [`PredictionRecord`] is the sink that keeps every sample, for full-resolution figures.
//!
//! The statistics are sums in sample order (the same bits whatever the pieces), and the worst
//! blocks a bounded list that is exactly the whole run's ranking ([`WorstLines`]).

use std::collections::{BTreeMap, VecDeque};

use rayon::prelude::*;
use serde::Serialize;
use vcnc_axis::{AxisName, Unit};
use vcnc_contour::{ContourStream, SearchWindow, StreamLimits};
use vcnc_drive::Channels;
use vcnc_gcode::MoveClass;
use vcnc_kinematics::Pose;
use vcnc_machine::{Kinematics, Machine, MachineModels};

use crate::Error;
use crate::drives::{ModelRuns, TrueDrives};
use crate::run::Measured;
use crate::sink::Sink;
use crate::source::{ReferenceChunk, ReferenceStats, Source};
use crate::stats::MaxRms;

/// One actual pose sequence of a piece (the true machine's, or a model set's).
#[derive(Debug, Clone, Default)]
pub struct ActualPiece {
    /// Per machine axis: the axis position (the physical axis: a model's advanced by its
    /// stated latency), mm or deg.
    pub positions: Vec<Vec<f64>>,
    /// Tool poses (workpiece frame, mm, unit tool axis).
    pub poses: Vec<Pose>,
    /// Tool-tip contour error, mm.
    pub tip_mm: Vec<f64>,
    /// Orientation contour error, rad.
    pub orientation_rad: Vec<f64>,
}

impl ActualPiece {
    fn clear(&mut self) {
        self.positions.iter_mut().for_each(Vec::clear);
        self.poses.clear();
        self.tip_mm.clear();
        self.orientation_rad.clear();
    }
}

/// Finished samples of a prediction, `first..first + len()`: everything a row of
/// `contour.csv` holds.
#[derive(Debug, Clone, Default)]
pub struct PredictPiece {
    /// Index of the first sample.
    pub first: usize,
    /// Per sample: the source line of the block running (0 where none is).
    pub lines: Vec<u32>,
    /// Per sample: the kind of move running.
    pub classes: Vec<Option<MoveClass>>,
    /// Per sample: what the reference does there ([`BlockFlags`]).
    pub flags: Vec<BlockFlags>,
    /// Per machine axis: the reference position, mm or deg.
    pub reference: Vec<Vec<f64>>,
    /// Reference tool poses.
    pub reference_poses: Vec<Pose>,
    /// The true machine.
    pub truth: ActualPiece,
    /// Each model set, in the order given.
    pub models: Vec<ActualPiece>,
}

impl PredictPiece {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.lines.len()
    }

    /// `true` without samples.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    fn clear(&mut self) {
        self.lines.clear();
        self.classes.clear();
        self.flags.clear();
        self.reference.iter_mut().for_each(Vec::clear);
        self.reference_poses.clear();
        self.truth.clear();
        self.models.iter_mut().for_each(ActualPiece::clear);
    }
}

/// What a prediction measures besides the contour errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PredictOptions {
    /// Which samples the contour statistics cover.
    pub measured: Measured,
    /// Also the true drives' tracking figures ([`PredictOutcome::tracking`]).
    pub tracking: bool,
}

/// What a prediction measured.
#[derive(Debug, Clone)]
pub struct PredictOutcome {
    /// The true machine's contour statistics (max, RMS) over the measured samples, tool tip in
    /// µm and orientation in mrad (those of [`PredictOutcome::figures`], also without models).
    pub truth: (Figure, Figure),
    /// With [`PredictOptions::tracking`], per machine axis: max |x_r − x| and RMS of x_r − x of
    /// the true drive's encoder reading over every sample, µm or mdeg; else empty.
    pub tracking: Vec<(f64, f64)>,
    /// Per model set: the contour part of `summary.json`.
    pub summaries: Vec<ContourSummary>,
    /// Per model set: the same statistics as the tables print them.
    pub figures: Vec<ContourFigures>,
    /// What handing on the reference measured (rates, which axes moved).
    pub reference: ReferenceStats,
    /// Per machine axis: servo ticks at which the true drive's command saturated.
    pub saturated_ticks: Vec<u64>,
    /// Every warning of the run, in order (the program's, then the references' limits).
    pub warnings: Vec<String>,
}

/// Runs the reference of `source` through the true drives and through each model set of
/// `models`, evaluates every contour error, and hands each piece of finished samples to `sink`
/// in order (module documentation). A program that moves no axis is refused
/// ([`Error::NoMotion`]): there is no contour to measure.
pub fn predict<S: Sink<PredictPiece>>(
    machine: &Machine,
    source: Source<'_>,
    models: &[&MachineModels],
    opts: &PredictOptions,
    sink: &mut S,
) -> Result<PredictOutcome, S::Error> {
    if !source.has_motion() {
        return Err(Error::NoMotion {
            file: source.file().to_string(),
            samples: source.len(),
        }
        .into());
    }
    let axes = machine.axes.len();
    let which = opts.measured;
    let kin = machine.require_kinematics().map_err(Error::from)?;
    let ts = source.ts();
    let channels = if opts.tracking {
        Channels::All
    } else {
        Channels::TruePosition
    };
    let mut drives = TrueDrives::new(machine, ts, channels)?;
    let mut tracking = vec![MaxRms::default(); if opts.tracking { axes } else { 0 }];
    let mut model_runs = ModelRuns::new(machine, models, ts, true)?;
    let mut pending = Pending::new(axes, 1 + models.len())?;
    let mut stats = Statistics::new(models.len(), ts, machine);
    let mut piece = PredictPiece::default();
    let mut flagger = Flagger::new(machine);

    let mut on_chunk = |c: &ReferenceChunk| -> Result<(), S::Error> {
        let n = c.len();
        // The true drives and the models, every axis in parallel (each stream in order).
        let (a, b) = rayon::join(|| drives.feed(machine, c), || model_runs.feed(machine, c));
        a?;
        b?;
        for (i, t) in tracking.iter_mut().enumerate() {
            let k = machine.axes[i].unit.micro_factor();
            for (r, x) in c.pos[i].iter().zip(&drives.traces[i].position) {
                t.add((r - x) * k);
            }
        }
        pending.lines.extend(&c.line);
        pending.classes.extend(&c.class);
        // The reference poses, to every search.
        let pos = c.positions();
        let poses: Vec<Pose> = (0..n).map(|k| kin.pose_at(&pos, k)).collect();
        flagger.flag(machine, c, &poses, &mut pending.flags);
        for i in 0..axes {
            pending.reference[i].extend(&c.pos[i]);
            pending.actual[0].positions[i].extend(drives.physical(i));
            for (set, out) in pending.actual[1..].iter_mut().zip(&model_runs.out) {
                set.positions[i].extend(&out[i]);
            }
        }
        for a in &mut pending.actual {
            a.search
                .push_reference(poses.iter().copied())
                .map_err(Error::from)?;
        }
        pending.reference_poses.extend(poses);
        pending.advance(kin)?;
        pending.hand_on(&mut piece, &mut stats, which, sink)
    };
    let reference = source.for_each(machine, &mut on_chunk)?;

    // The end: the drives' saturation counts, the models' last shifted samples, the searches'
    // last feet.
    let (saturated_ticks, true_rest) = drives.finish(machine)?;
    for (p, y) in pending.actual[0].positions.iter_mut().zip(&true_rest) {
        p.extend(y);
    }
    let last = model_runs.finish(machine)?;
    for (set, out) in pending.actual[1..].iter_mut().zip(&last) {
        for (p, y) in set.positions.iter_mut().zip(out) {
            p.extend(y);
        }
    }
    for a in &mut pending.actual {
        a.search.end_reference();
    }
    pending.advance(kin)?;
    pending.hand_on(&mut piece, &mut stats, which, sink)?;
    for a in &mut pending.actual {
        let search = std::mem::replace(&mut a.search, new_search()?);
        let errors = &mut a.errors;
        search
            .finish(|_, tip, or, _| errors.push_back((tip, or)))
            .map_err(Error::from)?;
    }
    pending.hand_on(&mut piece, &mut stats, which, sink)?;
    if pending.base != source.len() {
        return Err(Error::Unfinished {
            run: "prediction",
            finished: pending.base,
            samples: source.len(),
        }
        .into());
    }
    let texts = block_texts(&source, &stats.worst.lines());
    let (truth, summaries, figures) = stats.finish(which, machine, kin, &texts);
    let mut warnings = source.warnings().to_vec();
    warnings.extend(reference.warnings.iter().cloned());
    warnings.extend(model_warnings(machine, models));
    Ok(PredictOutcome {
        truth,
        tracking: tracking.iter().map(MaxRms::max_rms).collect(),
        summaries,
        figures,
        reference,
        saturated_ticks,
        warnings,
    })
}

/// The warnings about the models of a prediction: [`lag_mismatch`] of the machine's own
/// models (where axes are known by them) and of each set in `models`, each said once.
pub fn model_warnings(machine: &Machine, models: &[&MachineModels]) -> Vec<String> {
    let own = machine.own_models();
    let mut warnings: Vec<String> = Vec::new();
    for w in own
        .iter()
        .chain(models.iter().copied())
        .filter_map(|set| lag_mismatch(machine, set))
    {
        if !warnings.contains(&w) {
            warnings.push(w);
        }
    }
    warnings
}

/// A warning when the axes' models of `set` lag the reference by different times (a dead time
/// or a nominal-position filter on some axes and not on others): the axes then fall behind the
/// path by different amounts, and the predicted contour error is dominated by that mismatch
/// rather than by the loops. Lags within two sample periods of each other pass.
pub fn lag_mismatch(machine: &Machine, set: &MachineModels) -> Option<String> {
    let lags: Vec<(AxisName, f64)> = machine
        .axes
        .iter()
        .zip(set.models())
        .map(|(a, m)| (a.name, m.reference_lag_s()))
        .collect();
    let (lo, hi) = lags
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), (_, l)| {
            (lo.min(*l), hi.max(*l))
        });
    if hi - lo <= 2.0 * machine.ts {
        return None;
    }
    let list = lags
        .iter()
        .map(|(n, l)| format!("{n} {:.1} ms", l * 1e3))
        .collect::<Vec<_>>()
        .join(", ");
    Some(format!(
        "the models of {} lag the reference by different times ({list}: dead time plus nominal-position filter): the contour error predicted is then dominated by that mismatch; identify every axis with the same structure (`structures` in the machine file's `[identification.options]`, or in the `--options` file of `identify --trace`) unless the control really filters its axes differently",
        set.source()
    ))
}

fn new_search() -> Result<ContourStream, Error> {
    Ok(ContourStream::new(
        &SearchWindow::default(),
        StreamLimits::default(),
    )?)
}

/// One actual pose sequence waiting to be finished, with its contour search.
struct PendingActual {
    positions: Vec<VecDeque<f64>>,
    poses: VecDeque<Pose>,
    /// (tip mm, orientation rad) per finished sample.
    errors: VecDeque<(f64, f64)>,
    search: ContourStream,
    /// Actual samples pushed to the search.
    pushed: usize,
}

impl PendingActual {
    /// Pushes the actual samples `self.pushed..end` (from sample `base` on) to the search,
    /// keeping their poses, and collects the finished errors.
    fn advance(&mut self, kin: &Kinematics, base: usize, end: usize) -> Result<(), Error> {
        let cols: Vec<&[f64]> = self
            .positions
            .iter_mut()
            .map(|p| &*p.make_contiguous())
            .collect();
        for k in self.pushed..end {
            let q = kin.pose_at(&cols, k - base);
            self.search.push_actual(&q)?;
            self.poses.push_back(q);
        }
        self.pushed = end;
        let errors = &mut self.errors;
        self.search
            .drain(|_, tip, or, _| errors.push_back((tip, or)))?;
        Ok(())
    }

    /// Moves its first `n` samples into `piece`.
    fn take(&mut self, n: usize, piece: &mut ActualPiece) {
        piece.positions.resize_with(self.positions.len(), Vec::new);
        for (d, s) in piece.positions.iter_mut().zip(&mut self.positions) {
            d.extend(s.drain(..n));
        }
        piece.poses.extend(self.poses.drain(..n));
        for (t, o) in self.errors.drain(..n) {
            piece.tip_mm.push(t);
            piece.orientation_rad.push(o);
        }
    }
}

/// Samples waiting to be finished, from sample `base` on.
struct Pending {
    base: usize,
    lines: VecDeque<u32>,
    classes: VecDeque<Option<MoveClass>>,
    flags: VecDeque<BlockFlags>,
    reference: Vec<VecDeque<f64>>,
    reference_poses: VecDeque<Pose>,
    /// The true machine first, then each model set.
    actual: Vec<PendingActual>,
}

impl Pending {
    fn new(axes: usize, actual: usize) -> Result<Pending, Error> {
        Ok(Pending {
            base: 0,
            lines: VecDeque::new(),
            classes: VecDeque::new(),
            flags: VecDeque::new(),
            reference: vec![VecDeque::new(); axes],
            reference_poses: VecDeque::new(),
            actual: (0..actual)
                .map(|_| {
                    Ok(PendingActual {
                        positions: vec![VecDeque::new(); axes],
                        poses: VecDeque::new(),
                        errors: VecDeque::new(),
                        search: new_search()?,
                        pushed: 0,
                    })
                })
                .collect::<Result<Vec<_>, Error>>()?,
        })
    }

    /// Pushes the samples known of every actual sequence (the models' may trail by the latency
    /// look-ahead) to its search, every search in parallel.
    fn advance(&mut self, kin: &Kinematics) -> Result<(), Error> {
        let known = self
            .actual
            .iter()
            .flat_map(|a| a.positions.iter().map(VecDeque::len))
            .min()
            .unwrap_or(0);
        let (base, end) = (self.base, self.base + known);
        self.actual
            .par_iter_mut()
            .try_for_each(|a| a.advance(kin, base, end))
    }

    /// Hands the samples finished in every sequence (both contour errors known) to the
    /// statistics and to `sink`.
    fn hand_on<S: Sink<PredictPiece>>(
        &mut self,
        piece: &mut PredictPiece,
        stats: &mut Statistics,
        which: Measured,
        sink: &mut S,
    ) -> Result<(), S::Error> {
        let n = self
            .actual
            .iter()
            .map(|a| a.errors.len())
            .min()
            .unwrap_or(0);
        if n == 0 {
            return Ok(());
        }
        piece.clear();
        piece.first = self.base;
        piece.lines.extend(self.lines.drain(..n));
        piece.classes.extend(self.classes.drain(..n));
        piece.flags.extend(self.flags.drain(..n));
        piece.reference.resize_with(self.reference.len(), Vec::new);
        for (d, s) in piece.reference.iter_mut().zip(&mut self.reference) {
            d.extend(s.drain(..n));
        }
        piece
            .reference_poses
            .extend(self.reference_poses.drain(..n));
        let (truth, models) = self.actual.split_first_mut().expect("the true machine");
        truth.take(n, &mut piece.truth);
        piece.models.resize_with(models.len(), ActualPiece::default);
        for (a, p) in models.iter_mut().zip(&mut piece.models) {
            a.take(n, p);
        }
        self.base += n;
        stats.add(piece, which);
        sink.piece(piece)
    }
}

/// The statistics of `summary.json`, accumulated sample by sample: per model set the six
/// contour figures, and the worst lines of the true machine with what happens in them.
struct Statistics {
    /// True tip, true orientation.
    truth: [MaxRms; 2],
    /// Per model set: true tip, true orientation, predicted tip, predicted orientation,
    /// |Δ tip|, |Δ orientation|.
    sets: Vec<[MaxRms; 6]>,
    samples: usize,
    worst: WorstLines,
    /// Sample period, s.
    ts: f64,
    /// Per machine axis: rotary (deg).
    rotary: Vec<bool>,
    /// The previous sample's reference and true tool tips, mm.
    last_tips: Option<([f64; 3], [f64; 3])>,
}

impl Statistics {
    fn new(sets: usize, ts: f64, machine: &Machine) -> Statistics {
        Statistics {
            truth: [MaxRms::default(); 2],
            sets: vec![[MaxRms::default(); 6]; sets],
            samples: 0,
            worst: WorstLines::default(),
            ts,
            rotary: machine.axes.iter().map(|a| a.unit == Unit::Deg).collect(),
            last_tips: None,
        }
    }

    fn add(&mut self, p: &PredictPiece, which: Measured) {
        self.samples += p.len();
        for k in 0..p.len() {
            let tips = (tip(&p.reference_poses[k]), tip(&p.truth.poses[k]));
            let (last_ref, last_true) = self.last_tips.replace(tips).unwrap_or(tips);
            if which == Measured::Feed && p.classes[k] != Some(MoveClass::Feed) {
                continue;
            }
            let (tt, to) = (p.truth.tip_mm[k], p.truth.orientation_rad[k]);
            self.truth[0].add(tt);
            self.truth[1].add(to);
            for (acc, m) in self.sets.iter_mut().zip(&p.models) {
                let (pt, po) = (m.tip_mm[k], m.orientation_rad[k]);
                for (a, x) in acc
                    .iter_mut()
                    .zip([tt, to, pt, po, (tt - pt).abs(), (to - po).abs()])
                {
                    a.add(x);
                }
            }
            if p.lines[k] != 0 {
                let mut s = LineSample {
                    class: p.classes[k],
                    flags: p.flags.get(k).copied().unwrap_or_default(),
                    tangent: sub(tips.0, last_ref),
                    planned_mm_s: norm(sub(tips.0, last_ref)) / self.ts,
                    achieved_mm_s: norm(sub(tips.1, last_true)) / self.ts,
                    ..LineSample::default()
                };
                for (i, rotary) in self.rotary.iter().enumerate().take(MAX_AXES) {
                    s.reference[i] = p.reference[i][k];
                    s.actual[i] = p.truth.positions[i][k];
                    s.rotary_range[i] = if *rotary {
                        [p.reference[i][k]; 2]
                    } else {
                        [0.0; 2]
                    };
                }
                self.worst.add(p.lines[k], tt, to, &s);
            }
        }
    }

    #[allow(clippy::type_complexity)]
    fn finish(
        self,
        which: Measured,
        machine: &Machine,
        kin: &Kinematics,
        texts: &BTreeMap<u32, String>,
    ) -> ((Figure, Figure), Vec<ContourSummary>, Vec<ContourFigures>) {
        let details = self.worst.finish_detailed();
        let per_line = details
            .iter()
            .map(|(l, (t, o, _))| (*l, (*t, *o)))
            .collect();
        let mut worst = ranked_blocks(per_line, WORST_BLOCKS);
        for b in &mut worst {
            if let Some((_, _, d)) = details.get(&b.line) {
                b.cause = Some(d.cause(machine, kin, texts.get(&b.line)));
            }
        }
        let samples = self.samples;
        let [(tmax, trms), (omax, orms)] = self.truth.map(|a| a.max_rms());
        let truth = (
            Figure {
                tip_um: tmax * 1e3,
                orientation_mrad: omax * 1e3,
            },
            Figure {
                tip_um: trms * 1e3,
                orientation_mrad: orms * 1e3,
            },
        );
        let (summaries, figures) = self
            .sets
            .iter()
            .map(|acc| {
                let pair = |tip: usize, or: usize, rms: bool| {
                    let (t, o) = (acc[tip].max_rms(), acc[or].max_rms());
                    let pick = |x: (f64, f64)| if rms { x.1 } else { x.0 };
                    Figure {
                        tip_um: pick(t) * 1e3,
                        orientation_mrad: pick(o) * 1e3,
                    }
                };
                let figures = ContourFigures {
                    true_max: pair(0, 1, false),
                    true_rms: pair(0, 1, true),
                    predicted_max: pair(2, 3, false),
                    predicted_rms: pair(2, 3, true),
                    discrepancy_max: pair(4, 5, false),
                    discrepancy_rms: pair(4, 5, true),
                };
                let rows = figures.rows();
                let summary = ContourSummary {
                    contour_um: rows.iter().map(|(_, k, f)| (*k, f.tip_um)).collect(),
                    orientation_mrad: rows
                        .iter()
                        .map(|(_, k, f)| (*k, f.orientation_mrad))
                        .collect(),
                    samples,
                    measured: which.label(),
                    measured_samples: acc[0].count(),
                    worst_blocks: worst.clone(),
                };
                (summary, figures)
            })
            .unzip();
        (truth, summaries, figures)
    }
}

fn tip(q: &Pose) -> [f64; 3] {
    [q.p.x, q.p.y, q.p.z]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Most machine axes (X Y Z A B C).
const MAX_AXES: usize = 6;

/// A reference velocity or acceleration at least this share of the axis' limit counts as
/// running at the limit.
pub const LIMIT_SHARE: f64 = 0.99;

/// The tool-tip path's direction is taken over chords of this length, mm, for
/// [`BlockFlags::sharp_corner`] (short enough for a corner's blend, long enough that the
/// sample period and the feed do not matter).
pub const CORNER_CHORD_MM: f64 = 0.05;

/// A turn of the path direction of more than this between consecutive chords is a sharp
/// corner, deg.
pub const CORNER_DEG: f64 = 30.0;

/// A block that turns a rotary axis by more than this is unwinding it, deg: the same
/// orientation lay less than half a turn away.
pub const UNWIND_DEG: f64 = 180.0;

/// What the reference does in a block, the usual causes of a large contour error
/// (docs/contour.md#why-a-block-is-bad).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct BlockFlags {
    /// Some axis' reference velocity or acceleration reaches [`LIMIT_SHARE`] of its limit:
    /// the planner ran the block at the machine's limits.
    pub axis_limit: bool,
    /// Some axis' reference velocity changes sign (after standing still or not): friction
    /// and backlash act there.
    pub axis_reversal: bool,
    /// The tool-tip path turns by more than [`CORNER_DEG`] between two chords of
    /// [`CORNER_CHORD_MM`].
    pub sharp_corner: bool,
    /// A rotary axis turns by more than [`UNWIND_DEG`] within the block.
    pub rotary_unwinding: bool,
}

impl BlockFlags {
    fn or(self, o: BlockFlags) -> BlockFlags {
        BlockFlags {
            axis_limit: self.axis_limit || o.axis_limit,
            axis_reversal: self.axis_reversal || o.axis_reversal,
            sharp_corner: self.sharp_corner || o.sharp_corner,
            rotary_unwinding: self.rotary_unwinding || o.rotary_unwinding,
        }
    }

    /// The flags set, as words: `axis limit`, `reversal`, `sharp corner`, `unwinding`.
    pub fn words(&self) -> Vec<&'static str> {
        [
            (self.axis_limit, "axis limit"),
            (self.axis_reversal, "reversal"),
            (self.sharp_corner, "sharp corner"),
            (self.rotary_unwinding, "unwinding"),
        ]
        .into_iter()
        .filter_map(|(on, w)| on.then_some(w))
        .collect()
    }
}

/// Per-sample [`BlockFlags`] of the reference, piece by piece: keeps each axis' last moving
/// direction and the path's last chord between pieces, so any split gives the same flags.
struct Flagger {
    /// Per machine axis: the sign of its last velocity that was not still (0: none yet).
    sign: Vec<f64>,
    /// The start of the current chord and the previous chord's unit direction.
    anchor: Option<[f64; 3]>,
    direction: Option<[f64; 3]>,
}

impl Flagger {
    fn new(machine: &Machine) -> Flagger {
        Flagger {
            sign: vec![0.0; machine.axes.len()],
            anchor: None,
            direction: None,
        }
    }

    fn flag(
        &mut self,
        machine: &Machine,
        c: &ReferenceChunk,
        poses: &[Pose],
        out: &mut VecDeque<BlockFlags>,
    ) {
        let cos_corner = CORNER_DEG.to_radians().cos();
        for (k, pose) in poses.iter().enumerate().take(c.len()) {
            let mut f = BlockFlags::default();
            for (i, a) in machine.axes.iter().enumerate() {
                let (v, acc) = (c.vel[i][k], c.acc[i][k]);
                f.axis_limit |= v.abs() >= LIMIT_SHARE * a.max_velocity
                    || acc.abs() >= LIMIT_SHARE * a.max_acceleration;
                // Still: below a millionth of the velocity limit (the rounding of the inverse
                // kinematics stays far below it).
                if v.abs() > 1e-6 * a.max_velocity {
                    let s = v.signum();
                    f.axis_reversal |= self.sign[i] != 0.0 && s != self.sign[i];
                    self.sign[i] = s;
                }
            }
            let p = tip(pose);
            let anchor = *self.anchor.get_or_insert(p);
            let chord = sub(p, anchor);
            let len = norm(chord);
            if len >= CORNER_CHORD_MM {
                let d = chord.map(|x| x / len);
                if let Some(prev) = self.direction {
                    f.sharp_corner = dot(prev, d) < cos_corner;
                }
                self.direction = Some(d);
                self.anchor = Some(p);
            }
            out.push_back(f);
        }
    }
}

/// What the worst-ranked sample of a line and the line's run show.
#[derive(Debug, Clone, Copy, Default)]
struct LineSample {
    class: Option<MoveClass>,
    /// Flags, or-ed over the line.
    flags: BlockFlags,
    /// At the worst sample: per machine axis, reference and true position.
    reference: [f64; MAX_AXES],
    actual: [f64; MAX_AXES],
    /// At the worst sample: the reference tool tip's step, mm (its direction).
    tangent: [f64; 3],
    /// Largest reference / true tool-tip speed over the line, mm/s.
    planned_mm_s: f64,
    achieved_mm_s: f64,
    /// Per rotary machine axis: the reference's range over the line, deg.
    rotary_range: [[f64; 2]; MAX_AXES],
}

impl LineSample {
    /// Takes `o` (a later sample or run of the same line) in; `o_worse`: its error is the
    /// larger, so its worst sample becomes the line's.
    fn merge(&mut self, o: &LineSample, o_worse: bool) {
        if o_worse {
            self.class = o.class;
            self.reference = o.reference;
            self.actual = o.actual;
            self.tangent = o.tangent;
        }
        self.flags = self.flags.or(o.flags);
        self.planned_mm_s = self.planned_mm_s.max(o.planned_mm_s);
        self.achieved_mm_s = self.achieved_mm_s.max(o.achieved_mm_s);
        for (r, x) in self.rotary_range.iter_mut().zip(&o.rotary_range) {
            *r = [r[0].min(x[0]), r[1].max(x[1])];
        }
    }

    /// Why the line is bad: its flags, speeds and the axis whose following error moves the
    /// tool tip most across the path at the worst sample.
    fn cause(&self, machine: &Machine, kin: &Kinematics, text: Option<&String>) -> BlockCause {
        let axes = machine.axes.len().min(MAX_AXES);
        let column =
            |q: &[f64; MAX_AXES]| -> Vec<[f64; 1]> { q[..axes].iter().map(|x| [*x]).collect() };
        let pose_of = |cols: &[[f64; 1]]| {
            let s: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
            tip(&kin.pose_at(&s, 0))
        };
        let base = column(&self.reference);
        let p0 = pose_of(&base);
        let t = norm(self.tangent);
        let across = |d: [f64; 3]| {
            if t > 0.0 {
                let u = self.tangent.map(|x| x / t);
                let along = dot(d, u);
                norm([
                    d[0] - along * u[0],
                    d[1] - along * u[1],
                    d[2] - along * u[2],
                ])
            } else {
                norm(d)
            }
        };
        let mut best: Option<(usize, f64)> = None;
        for i in 0..axes {
            let mut q = base.clone();
            q[i] = [self.actual[i]];
            let share = across(sub(pose_of(&q), p0));
            if best.is_none_or(|(_, b)| share > b) {
                best = Some((i, share));
            }
        }
        let mut flags = self.flags;
        flags.rotary_unwinding = self
            .rotary_range
            .iter()
            .any(|[lo, hi]| hi - lo > UNWIND_DEG);
        BlockCause {
            text: text.cloned().unwrap_or_default(),
            kind: match self.class {
                Some(MoveClass::Feed) => "cutting",
                Some(MoveClass::Rapid) => "link",
                Some(MoveClass::Dwell) => "dwell",
                None => "",
            },
            planned_feed_mm_min: self.planned_mm_s * 60.0,
            achieved_feed_mm_min: self.achieved_mm_s * 60.0,
            axis: best.map_or(String::new(), |(i, _)| machine.axes[i].name.to_string()),
            axis_share_um: best.map_or(0.0, |(_, s)| s * 1e3),
            flags,
        }
    }
}

/// The G-code text of `lines` (trimmed, at most [`TEXT_CHARS`] characters), read from the
/// program of `source` again (a prepared run's file where it is on disk).
fn block_texts(source: &Source<'_>, lines: &[u32]) -> BTreeMap<u32, String> {
    let wanted: std::collections::BTreeSet<u32> = lines.iter().copied().collect();
    let mut out = BTreeMap::new();
    let Some(&last) = wanted.last() else {
        return out;
    };
    let mut take = |n: usize, l: &str| {
        let n = u32::try_from(n + 1).unwrap_or(u32::MAX);
        if wanted.contains(&n) {
            out.insert(n, l.trim().chars().take(TEXT_CHARS).collect());
        }
        n < last
    };
    let path = match source {
        Source::Streamed(s) => match &s.program {
            crate::source::Program::Text { text, .. } => {
                for (n, l) in text.lines().enumerate() {
                    if !take(n, l) {
                        break;
                    }
                }
                return out;
            }
            crate::source::Program::File(p) => p.clone(),
        },
        Source::Prepared(r) => std::path::PathBuf::from(&r.file),
    };
    // The texts are a courtesy of the table: a file gone since the run leaves them empty.
    if let Ok(f) = std::fs::File::open(path) {
        use std::io::BufRead;
        for (n, l) in std::io::BufReader::new(f).split(b'\n').enumerate() {
            let Ok(l) = l else { break };
            if !take(n, &String::from_utf8_lossy(&l)) {
                break;
            }
        }
    }
    out
}

/// Characters of a block's G-code text kept in [`BlockCause::text`].
pub const TEXT_CHARS: usize = 120;

/// A block of the program and its largest contour errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorstBlock {
    /// Source line of the block.
    pub line: u32,
    /// Its largest tool-tip contour error, µm.
    pub contour_max_um: f64,
    /// Its largest orientation contour error, mrad.
    pub orientation_max_mrad: f64,
    /// Where and why (a prediction's worst blocks; `None` from [`worst_blocks`]).
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub cause: Option<BlockCause>,
}

/// Where a worst block is and what happens in it (docs/contour.md#why-a-block-is-bad).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BlockCause {
    /// The block's G-code text (trimmed; empty when the program cannot be read again).
    pub text: String,
    /// `cutting` (a feed move), `link` (a rapid), `dwell`, at the worst sample.
    pub kind: &'static str,
    /// The reference's largest tool-tip speed over the block (the feed the planner gave it
    /// within the machine's limits), mm/min.
    pub planned_feed_mm_min: f64,
    /// The true machine's largest tool-tip speed over the block, mm/min.
    pub achieved_feed_mm_min: f64,
    /// The machine axis whose following error alone moves the tool tip farthest across the
    /// path at the worst sample (its reference with that one axis at its true position).
    pub axis: String,
    /// That axis' share: the tool tip's move across the path, µm.
    pub axis_share_um: f64,
    /// What the reference does in the block.
    pub flags: BlockFlags,
}

/// The `n` source lines with the largest tool-tip error (mm) among the samples `mask` selects,
/// worst first (ties: the earlier line); their orientation error (rad) beside it.
pub fn worst_blocks(
    lines: &[u32],
    tip_mm: &[f64],
    orientation_rad: &[f64],
    mask: &[bool],
    n: usize,
) -> Vec<WorstBlock> {
    let mut per_line: BTreeMap<u32, (f64, f64)> = BTreeMap::new();
    for k in 0..lines.len().min(tip_mm.len()).min(mask.len()) {
        if !mask[k] || lines[k] == 0 {
            continue;
        }
        let e = per_line.entry(lines[k]).or_insert((0.0, 0.0));
        e.0 = e.0.max(tip_mm[k]);
        e.1 = e.1.max(orientation_rad.get(k).copied().unwrap_or(0.0));
    }
    ranked_blocks(per_line, n)
}

/// The `n` lines of `per_line` (line → largest tool-tip error mm, orientation error rad) with
/// the largest tool-tip error in µm, worst first (ties: the earlier line).
pub(crate) fn ranked_blocks(per_line: BTreeMap<u32, (f64, f64)>, n: usize) -> Vec<WorstBlock> {
    let mut v: Vec<WorstBlock> = per_line
        .into_iter()
        .map(|(line, (t, o))| WorstBlock {
            line,
            contour_max_um: t * 1e3,
            orientation_max_mrad: o * 1e3,
            cause: None,
        })
        .collect();
    v.sort_by(|a, b| {
        b.contour_max_um
            .total_cmp(&a.contour_max_um)
            .then(a.line.cmp(&b.line))
    });
    v.truncate(n);
    v
}

/// One statistic of the tool-tip (µm) and orientation (mrad) contour errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figure {
    /// Tool tip, µm.
    pub tip_um: f64,
    /// Orientation, mrad.
    pub orientation_mrad: f64,
}

/// The contour statistics of a prediction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContourFigures {
    /// Max with the true drives.
    pub true_max: Figure,
    /// RMS with the true drives.
    pub true_rms: Figure,
    /// Max with the models.
    pub predicted_max: Figure,
    /// RMS with the models.
    pub predicted_rms: Figure,
    /// Max of |predicted − true|.
    pub discrepancy_max: Figure,
    /// RMS of |predicted − true|.
    pub discrepancy_rms: Figure,
}

impl ContourFigures {
    /// `(table label, summary key, figure)`, in table order.
    pub fn rows(&self) -> [(&'static str, &'static str, Figure); 6] {
        [
            ("true max", "true_max", self.true_max),
            ("true RMS", "true_rms", self.true_rms),
            ("predicted max", "predicted_max", self.predicted_max),
            ("predicted RMS", "predicted_rms", self.predicted_rms),
            ("|pred - true| max", "discrepancy_max", self.discrepancy_max),
            ("|pred - true| RMS", "discrepancy_rms", self.discrepancy_rms),
        ]
    }
}

/// The contour part of a summary: `contour_um.{true_max …}`, `orientation_mrad.{…}`,
/// `samples`, `measured`, `measured_samples`, `worst_blocks`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContourSummary {
    /// Tool-tip contour error statistics, µm.
    pub contour_um: BTreeMap<&'static str, f64>,
    /// Orientation contour error statistics, mrad.
    pub orientation_mrad: BTreeMap<&'static str, f64>,
    /// Number of samples of the run.
    pub samples: usize,
    /// Which samples the statistics cover: `feed` (feed moves, the default) or `all`.
    pub measured: &'static str,
    /// How many samples they cover.
    pub measured_samples: usize,
    /// The blocks with the largest true contour errors, worst first.
    pub worst_blocks: Vec<WorstBlock>,
}

/// Blocks listed in a summary's `worst_blocks`.
pub const WORST_BLOCKS: usize = 10;

/// `summary.json` of `vcnc predict`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PredictSummary {
    /// The contour figures.
    #[serde(flatten)]
    pub contour: ContourSummary,
    /// Machine name.
    pub machine: String,
    /// Program path.
    pub program: String,
    /// The planner's cycle time of the program and its split between feeds, rapids and
    /// dwells, s.
    pub cycle_time: vcnc_gcode::CycleTime,
    /// What played the true machine ("virtual drives", or the machine's identified models:
    /// docs/machine-file.md#a-machine-made-of-identified-models).
    pub truth: String,
    /// Where the models come from (a file, or "identified on the fly").
    pub models: String,
    /// The actual-value latency stated per axis (axis letter → s) by which the models'
    /// positions were advanced (docs/drive-model.md#actual-value-latency); 0 for an axis
    /// without one.
    pub actual_latency_s: BTreeMap<String, f64>,
    /// Warnings of the run.
    pub warnings: Vec<String>,
    /// The per-sample outputs keep every `decimate`-th sample (1: all).
    pub decimate: usize,
    /// Bytes of each per-sample output written before the summary (table, figures, VTP).
    pub output_bytes: BTreeMap<String, u64>,
}

impl PredictSummary {
    /// The summary of a prediction of the program `source` on `machine` with `models`.
    pub fn new(
        machine: &Machine,
        source: &Source<'_>,
        contour: ContourSummary,
        models: &MachineModels,
        warnings: Vec<String>,
    ) -> PredictSummary {
        PredictSummary {
            contour,
            machine: machine.name.clone(),
            program: source.file().to_string(),
            cycle_time: source.cycle(),
            truth: machine.truth_description(),
            models: models.source().to_string(),
            actual_latency_s: machine
                .axes
                .iter()
                .zip(models.latencies())
                .map(|(a, l)| (a.name.to_string(), l))
                .collect(),
            warnings,
            decimate: 1,
            output_bytes: BTreeMap::new(),
        }
    }
}

/// The [`WORST_BLOCKS`] source lines with the largest true tool-tip contour error, in memory
/// that does not grow with the program (a 1 GB program has millions of lines): each run of
/// consecutive measured samples of one line is offered as a whole to a list of the best
/// [`WORST_BLOCKS`] lines so far, ranked as [`worst_blocks`] ranks them (larger error first,
/// then the smaller line). The list and every line's largest tool-tip error in it are exactly
/// the whole run's: a line outside the list at some time had a smaller error than all of it,
/// and the list's last error only grows. So is each listed line's orientation error (and what
/// [`BlockCause`] says of it), unless the line ran more than once (O-word loops and calls) and
/// left the list between its runs: it then covers the runs since it came back
/// (docs/performance.md).
#[derive(Debug, Default)]
pub struct WorstLines {
    /// The run being read: line, largest tool-tip and orientation errors, what it shows.
    run: Option<(u32, f64, f64, LineSample)>,
    /// The best lines so far: line → (tool tip, orientation, what it shows).
    best: BTreeMap<u32, (f64, f64, LineSample)>,
}

impl WorstLines {
    /// The next measured sample: its line (not 0) and its errors (mm, rad).
    pub fn add_errors(&mut self, line: u32, tip: f64, orientation: f64) {
        self.add(line, tip, orientation, &LineSample::default());
    }

    fn add(&mut self, line: u32, tip: f64, orientation: f64, s: &LineSample) {
        match &mut self.run {
            Some((l, t, o, d)) if *l == line => {
                d.merge(s, tip > *t);
                *t = t.max(tip);
                *o = o.max(orientation);
            }
            run => {
                if let Some(r) = run.replace((line, tip, orientation, *s)) {
                    self.offer(r);
                }
            }
        }
    }

    fn offer(&mut self, (line, tip, orientation, s): (u32, f64, f64, LineSample)) {
        if let Some(e) = self.best.get_mut(&line) {
            e.2.merge(&s, tip > e.0);
            e.0 = e.0.max(tip);
            e.1 = e.1.max(orientation);
            return;
        }
        if self.best.len() < WORST_BLOCKS {
            self.best.insert(line, (tip, orientation, s));
            return;
        }
        // The last of the list: the smallest error, of equal ones the largest line.
        let Some((&last, &(t_last, _, _))) = self
            .best
            .iter()
            .min_by(|a, b| (a.1.0 * 1e3).total_cmp(&(b.1.0 * 1e3)).then(b.0.cmp(a.0)))
        else {
            return;
        };
        // Ranked in µm, as the summary's figures (two errors in mm may round to one in µm).
        if (tip * 1e3)
            .total_cmp(&(t_last * 1e3))
            .then(last.cmp(&line))
            .is_gt()
        {
            self.best.remove(&last);
            self.best.insert(line, (tip, orientation, s));
        }
    }

    /// The lines in the list so far (the run being read included).
    fn lines(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self.best.keys().copied().collect();
        v.extend(self.run.map(|r| r.0));
        v
    }

    fn finish_detailed(mut self) -> BTreeMap<u32, (f64, f64, LineSample)> {
        if let Some(r) = self.run.take() {
            self.offer(r);
        }
        self.best
    }

    /// The best lines: line → (largest tool-tip error mm, orientation error rad).
    pub fn finish(self) -> BTreeMap<u32, (f64, f64)> {
        self.finish_detailed()
            .into_iter()
            .map(|(l, (t, o, _))| (l, (t, o)))
            .collect()
    }
}

/// Every sample of a prediction, for full-resolution figures: the sink that keeps everything
/// (poses excepted: they are the forward kinematics of the positions, recomputed where drawn).
#[derive(Debug, Clone, Default)]
pub struct PredictionRecord {
    /// Keep every `every`-th sample only (samples 0, N, 2N, …; 0 or 1 keeps every one): a
    /// long program's figures and `.vtp` in bounded memory.
    pub every: usize,
    /// The run's samples when known (0 if not): the record's vectors are then sized once for
    /// the samples it keeps instead of growing by doubling (which may hold twice that).
    pub samples: usize,
    /// Per sample: the source line of the block running.
    pub lines: Vec<u32>,
    /// Per sample: the kind of move running.
    pub classes: Vec<Option<MoveClass>>,
    /// Per machine axis: the reference positions.
    pub reference: Vec<Vec<f64>>,
    /// The true machine.
    pub truth: ActualRecord,
    /// Each model set.
    pub models: Vec<ActualRecord>,
}

/// Every sample of one actual sequence.
#[derive(Debug, Clone, Default)]
pub struct ActualRecord {
    /// Per machine axis: the positions.
    pub positions: Vec<Vec<f64>>,
    /// Tool-tip contour error, mm.
    pub tip_mm: Vec<f64>,
    /// Orientation contour error, rad.
    pub orientation_rad: Vec<f64>,
}

impl ActualRecord {
    /// The positions per machine axis.
    pub fn positions(&self) -> Vec<&[f64]> {
        self.positions.iter().map(Vec::as_slice).collect()
    }
}

impl PredictionRecord {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.lines.len()
    }

    /// `true` without samples.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// Per sample: whether the statistics count it.
    pub fn measured(&self, which: Measured) -> Vec<bool> {
        which.mask(&self.classes)
    }

    /// The reference positions per machine axis.
    pub fn reference_positions(&self) -> Vec<&[f64]> {
        self.reference.iter().map(Vec::as_slice).collect()
    }
}

impl PredictionRecord {
    /// A record of every `every`-th sample of a run of `samples` samples.
    pub fn of_run(samples: usize, every: usize) -> PredictionRecord {
        PredictionRecord {
            every,
            samples,
            ..PredictionRecord::default()
        }
    }
}

impl Sink<PredictPiece> for PredictionRecord {
    type Error = Error;
    fn piece(&mut self, p: &PredictPiece) -> Result<(), Error> {
        let every = self.every.max(1);
        // The piece's samples kept: those whose index is a multiple of `every`.
        let start = (every - p.first % every) % every;
        // Sized once for the samples kept (a no-op after the first piece).
        let kept = self.samples.div_ceil(every);
        let keep = |v: &[f64], out: &mut Vec<f64>| {
            out.reserve_exact(kept.saturating_sub(out.len()));
            out.extend(v.iter().skip(start).step_by(every));
        };
        self.lines
            .reserve_exact(kept.saturating_sub(self.lines.len()));
        self.lines.extend(p.lines.iter().skip(start).step_by(every));
        self.classes
            .reserve_exact(kept.saturating_sub(self.classes.len()));
        self.classes
            .extend(p.classes.iter().skip(start).step_by(every));
        self.reference.resize_with(p.reference.len(), Vec::new);
        for (d, s) in self.reference.iter_mut().zip(&p.reference) {
            keep(s, d);
        }
        self.models
            .resize_with(p.models.len(), ActualRecord::default);
        for (d, s) in std::iter::once(&mut self.truth)
            .chain(self.models.iter_mut())
            .zip(std::iter::once(&p.truth).chain(&p.models))
        {
            d.positions.resize_with(s.positions.len(), Vec::new);
            for (dp, sp) in d.positions.iter_mut().zip(&s.positions) {
                keep(sp, dp);
            }
            keep(&s.tip_mm, &mut d.tip_mm);
            keep(&s.orientation_rad, &mut d.orientation_rad);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reference of `n` samples per axis from `f(k) -> (position, velocity)` of X and Y (the
    /// other axes at rest).
    fn chunk(machine: &Machine, n: usize, f: impl Fn(usize) -> [(f64, f64); 2]) -> ReferenceChunk {
        let axes = machine.axes.len();
        let mut c = ReferenceChunk {
            pos: vec![vec![0.0; n]; axes],
            vel: vec![vec![0.0; n]; axes],
            acc: vec![vec![0.0; n]; axes],
            class: vec![Some(MoveClass::Feed); n],
            line: vec![1; n],
            ..ReferenceChunk::default()
        };
        for k in 0..n {
            for (i, (p, v)) in f(k).into_iter().enumerate() {
                c.pos[i][k] = p;
                c.vel[i][k] = v;
            }
        }
        c
    }

    fn flags_of(machine: &Machine, c: &ReferenceChunk, pieces: usize) -> Vec<BlockFlags> {
        let kin = machine.require_kinematics().unwrap();
        let pos = c.positions();
        let poses: Vec<Pose> = (0..c.len()).map(|k| kin.pose_at(&pos, k)).collect();
        let mut flagger = Flagger::new(machine);
        let mut out = VecDeque::new();
        // Cut into `pieces`: the flags do not depend on where.
        let step = c.len().div_ceil(pieces);
        for start in (0..c.len()).step_by(step) {
            let end = (start + step).min(c.len());
            let part = ReferenceChunk {
                first: start,
                pos: c.pos.iter().map(|v| v[start..end].to_vec()).collect(),
                vel: c.vel.iter().map(|v| v[start..end].to_vec()).collect(),
                acc: c.acc.iter().map(|v| v[start..end].to_vec()).collect(),
                class: c.class[start..end].to_vec(),
                line: c.line[start..end].to_vec(),
            };
            flagger.flag(machine, &part, &poses[start..end], &mut out);
        }
        out.into()
    }

    #[test]
    fn a_right_angle_turn_is_a_sharp_corner_and_a_reversal_is_flagged_once() {
        let m = Machine::embedded_nmv5000().unwrap();
        // X out 10 mm at 10 mm/s (10 µm per sample), then Y out, then X back.
        let v = 10.0;
        let d = v * m.ts;
        let n = 3000;
        let f = |k: usize| {
            let k = k as f64;
            if k < 1000.0 {
                [(k * d, v), (0.0, 0.0)]
            } else if k < 2000.0 {
                [(1000.0 * d, 0.0), ((k - 1000.0) * d, v)]
            } else {
                [((3000.0 - k) * d, -v), (1000.0 * d, 0.0)]
            }
        };
        let c = chunk(&m, n, f);
        for pieces in [1, 7] {
            let flags = flags_of(&m, &c, pieces);
            let corners: Vec<usize> = (0..n).filter(|k| flags[*k].sharp_corner).collect();
            // Corners at both turns only, within about two chords (0.05 mm: 5 samples) after
            // each (a chord across the turn may split it into two turns of 45°).
            let near = |k: &usize, at: usize| (at..at + 12).contains(k);
            assert!(
                corners.iter().all(|k| near(k, 1000) || near(k, 2000)),
                "{corners:?}"
            );
            assert!(corners.iter().any(|k| near(k, 1000)) && corners.iter().any(|k| near(k, 2000)));
            // X reverses at 2000 (after standing still); Y never does.
            let rev: Vec<usize> = (0..n).filter(|k| flags[*k].axis_reversal).collect();
            assert_eq!(rev, vec![2000]);
            assert!(flags.iter().all(|f| !f.axis_limit && !f.rotary_unwinding));
        }
    }

    #[test]
    fn a_reference_at_the_velocity_limit_is_flagged() {
        let m = Machine::embedded_nmv5000().unwrap();
        let vmax = m.axes[0].max_velocity;
        let c = chunk(&m, 10, |k| {
            let v = if k < 5 { 0.5 * vmax } else { vmax };
            [(k as f64 * 1e-3, v), (0.0, 0.0)]
        });
        let flags = flags_of(&m, &c, 1);
        let at: Vec<bool> = flags.iter().map(|f| f.axis_limit).collect();
        assert_eq!(at, [[false; 5], [true; 5]].concat());
    }

    #[test]
    fn a_decimated_record_keeps_every_nth_sample_whatever_the_pieces() {
        let piece = |first: usize, n: usize| PredictPiece {
            first,
            lines: (first..first + n).map(|k| k as u32).collect(),
            classes: vec![Some(MoveClass::Feed); n],
            flags: vec![BlockFlags::default(); n],
            reference: vec![(first..first + n).map(|k| k as f64).collect()],
            reference_poses: Vec::new(),
            truth: ActualPiece {
                positions: vec![(first..first + n).map(|k| -(k as f64)).collect()],
                poses: Vec::new(),
                tip_mm: (first..first + n).map(|k| k as f64 * 2.0).collect(),
                orientation_rad: vec![0.0; n],
            },
            models: Vec::new(),
        };
        // The run's length unknown, exact, or too short: the same record.
        for (samples, cuts) in [0, 100, 40]
            .into_iter()
            .flat_map(|s| [vec![100], vec![3, 40, 57], vec![1; 100]].map(|c| (s, c)))
        {
            let mut r = PredictionRecord::of_run(samples, 7);
            let mut first = 0;
            for n in cuts {
                r.piece(&piece(first, n)).unwrap();
                first += n;
            }
            let kept: Vec<u32> = (0..100).step_by(7).collect();
            assert_eq!(r.lines, kept);
            assert_eq!(
                r.reference[0],
                kept.iter().map(|k| *k as f64).collect::<Vec<_>>()
            );
            assert_eq!(r.truth.positions[0][1], -7.0);
            assert_eq!(r.truth.tip_mm[2], 28.0);
            if samples == 100 {
                assert_eq!(r.lines.capacity(), kept.len(), "sized once");
            }
        }
    }
}
