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
/// in order (module documentation).
pub fn predict<S: Sink<PredictPiece>>(
    machine: &Machine,
    source: Source<'_>,
    models: &[&MachineModels],
    opts: &PredictOptions,
    sink: &mut S,
) -> Result<PredictOutcome, S::Error> {
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
    let mut stats = Statistics::new(models.len());
    let mut piece = PredictPiece::default();

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
        for i in 0..axes {
            pending.reference[i].extend(&c.pos[i]);
            pending.actual[0].positions[i].extend(&drives.traces[i].true_position);
            for (set, out) in pending.actual[1..].iter_mut().zip(&model_runs.out) {
                set.positions[i].extend(&out[i]);
            }
        }
        // The reference poses, to every search.
        let pos = c.positions();
        let poses: Vec<Pose> = (0..n).map(|k| kin.pose_at(&pos, k)).collect();
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
    let saturated_ticks = drives.finish(machine)?;
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
    let (truth, summaries, figures) = stats.finish(which);
    let mut warnings = source.warnings().to_vec();
    warnings.extend(reference.warnings.iter().cloned());
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
/// contour figures, and the worst lines of the true machine.
struct Statistics {
    /// True tip, true orientation.
    truth: [MaxRms; 2],
    /// Per model set: true tip, true orientation, predicted tip, predicted orientation,
    /// |Δ tip|, |Δ orientation|.
    sets: Vec<[MaxRms; 6]>,
    samples: usize,
    worst: WorstLines,
}

impl Statistics {
    fn new(sets: usize) -> Statistics {
        Statistics {
            truth: [MaxRms::default(); 2],
            sets: vec![[MaxRms::default(); 6]; sets],
            samples: 0,
            worst: WorstLines::default(),
        }
    }

    fn add(&mut self, p: &PredictPiece, which: Measured) {
        self.samples += p.len();
        for k in 0..p.len() {
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
                self.worst.add(p.lines[k], tt, to);
            }
        }
    }

    #[allow(clippy::type_complexity)]
    fn finish(
        self,
        which: Measured,
    ) -> ((Figure, Figure), Vec<ContourSummary>, Vec<ContourFigures>) {
        let worst = ranked_blocks(self.worst.finish(), WORST_BLOCKS);
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

/// A block of the program and its largest contour errors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WorstBlock {
    /// Source line of the block.
    pub line: u32,
    /// Its largest tool-tip contour error, µm.
    pub contour_max_um: f64,
    /// Its largest orientation contour error, mrad.
    pub orientation_max_mrad: f64,
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
    /// Where the models come from (a file, or "identified on the fly").
    pub models: String,
    /// The actual-value latency stated per axis (axis letter → s) by which the models'
    /// positions were advanced (docs/drive-model.md#actual-value-latency); 0 for an axis
    /// without one.
    pub actual_latency_s: BTreeMap<String, f64>,
    /// Warnings of the run.
    pub warnings: Vec<String>,
}

impl PredictSummary {
    /// The summary of a prediction of `program` on `machine` with `models`.
    pub fn new(
        machine: &Machine,
        program: &str,
        contour: ContourSummary,
        models: &MachineModels,
        warnings: Vec<String>,
    ) -> PredictSummary {
        PredictSummary {
            contour,
            machine: machine.name.clone(),
            program: program.to_string(),
            models: models.source().to_string(),
            actual_latency_s: machine
                .axes
                .iter()
                .zip(models.latencies())
                .map(|(a, l)| (a.name.to_string(), l))
                .collect(),
            warnings,
        }
    }
}

/// The [`WORST_BLOCKS`] source lines with the largest true tool-tip contour error, in memory
/// that does not grow with the program (a 1 GB program has millions of lines): each run of
/// consecutive measured samples of one line is offered as a whole to a list of the best
/// [`WORST_BLOCKS`] lines so far, ranked as [`worst_blocks`] ranks them (larger error first,
/// then the smaller line). The list and every line's largest tool-tip error in it are exactly
/// the whole run's: a line outside the list at some time had a smaller error than all of it,
/// and the list's last error only grows. So is each listed line's orientation error, unless the
/// line ran more than once (O-word loops and calls) and left the list between its runs: its
/// orientation maximum then covers the runs since it came back (docs/performance.md).
#[derive(Debug, Default)]
pub struct WorstLines {
    /// The run being read: line, largest tool-tip and orientation errors.
    run: Option<(u32, f64, f64)>,
    /// The best lines so far: line → (tool tip, orientation).
    best: BTreeMap<u32, (f64, f64)>,
}

impl WorstLines {
    /// The next measured sample: its line (not 0) and its errors (mm, rad).
    pub fn add(&mut self, line: u32, tip: f64, orientation: f64) {
        match &mut self.run {
            Some((l, t, o)) if *l == line => {
                *t = t.max(tip);
                *o = o.max(orientation);
            }
            run => {
                if let Some(r) = run.replace((line, tip, orientation)) {
                    self.offer(r);
                }
            }
        }
    }

    fn offer(&mut self, (line, tip, orientation): (u32, f64, f64)) {
        if let Some(e) = self.best.get_mut(&line) {
            e.0 = e.0.max(tip);
            e.1 = e.1.max(orientation);
            return;
        }
        if self.best.len() < WORST_BLOCKS {
            self.best.insert(line, (tip, orientation));
            return;
        }
        // The last of the list: the smallest error, of equal ones the largest line.
        let Some((&last, &(t_last, _))) = self
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
            self.best.insert(line, (tip, orientation));
        }
    }

    /// The best lines: line → (largest tool-tip error mm, orientation error rad).
    pub fn finish(mut self) -> BTreeMap<u32, (f64, f64)> {
        if let Some(r) = self.run.take() {
            self.offer(r);
        }
        self.best
    }
}

/// Every sample of a prediction, for full-resolution figures: the sink that keeps everything
/// (poses excepted: they are the forward kinematics of the positions, recomputed where drawn).
#[derive(Debug, Clone, Default)]
pub struct PredictionRecord {
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
    fn extend(&mut self, p: &ActualPiece) {
        self.positions.resize_with(p.positions.len(), Vec::new);
        for (d, s) in self.positions.iter_mut().zip(&p.positions) {
            d.extend_from_slice(s);
        }
        self.tip_mm.extend_from_slice(&p.tip_mm);
        self.orientation_rad.extend_from_slice(&p.orientation_rad);
    }

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

impl Sink<PredictPiece> for PredictionRecord {
    type Error = Error;
    fn piece(&mut self, p: &PredictPiece) -> Result<(), Error> {
        self.lines.extend_from_slice(&p.lines);
        self.classes.extend_from_slice(&p.classes);
        self.reference.resize_with(p.reference.len(), Vec::new);
        for (d, s) in self.reference.iter_mut().zip(&p.reference) {
            d.extend_from_slice(s);
        }
        self.truth.extend(&p.truth);
        self.models
            .resize_with(p.models.len(), ActualRecord::default);
        for (d, s) in self.models.iter_mut().zip(&p.models) {
            d.extend(s);
        }
        Ok(())
    }
}
