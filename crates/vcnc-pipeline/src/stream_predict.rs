//! `vcnc predict` streamed (docs/performance.md, "Streamed prediction"): the reference of a
//! program of any length goes a piece at a time through the true drives and the models, the
//! models' actual-value latency, the forward kinematics and the contour searches, and each
//! piece of finished samples is handed to the caller (who writes it) and dropped, with the
//! statistics of `summary.json` accumulated on the way. Memory does not grow with the
//! program's length.
//!
//! Every value is the whole-run prediction's ([`crate::predict::predict_releasing_rates`]) bit
//! for bit: the drives and models are the same simulations made resumable
//! ([`vcnc_drive::DriveStream`], [`vcnc_drive::ModelStream`]), the latency shift is
//! [`latency::Shifter`], the contour searches are [`vcnc_contour::ContourStream`], and the
//! statistics are the same sums in the same order (tested on the spiral and on a long
//! generated program, `tests/stream_predict.rs`).
//!
//! What is held at any time: the samples between the newest reference sample and the oldest
//! sample not yet finished — the models' latency look-ahead (a few samples) and the contour
//! searches' look-ahead (the window of the path the search may still move along, about a
//! piece) — and the ten worst lines so far.

use std::collections::{BTreeMap, VecDeque};
use std::path::Path;

use rayon::prelude::*;
use vcnc_contour::{ContourStream, SearchWindow, StreamLimits};
use vcnc_drive::{Channels, DriveModel, DriveTrace, SimOptions};
use vcnc_gcode::MoveClass;
use vcnc_kinematics::Pose;
use vcnc_machine::Machine;

use crate::predict::{ContourFigures, ContourSummary, Figure, WORST_BLOCKS};
use crate::run::Measured;
use crate::stats::MaxRms;
use crate::stream::{ReferenceChunk, ReferenceStream, StreamStats, drive_error, feed_drives};
use crate::{Error, latency};

/// Finished samples of a streamed prediction, `first..first + len()`: everything a row of
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
    /// Per machine axis: the true drive's (physical) position.
    pub truth: Vec<Vec<f64>>,
    /// Per machine axis: the model's position, advanced by the stated latency.
    pub predicted: Vec<Vec<f64>>,
    /// Reference tool poses (workpiece frame, mm, unit tool axis).
    pub reference_poses: Vec<Pose>,
    /// The true machine's tool poses.
    pub true_poses: Vec<Pose>,
    /// The models' tool poses.
    pub predicted_poses: Vec<Pose>,
    /// The true machine's tool-tip contour error, mm.
    pub true_tip_mm: Vec<f64>,
    /// The models' tool-tip contour error, mm.
    pub predicted_tip_mm: Vec<f64>,
    /// The true machine's orientation contour error, rad.
    pub true_orientation_rad: Vec<f64>,
    /// The models' orientation contour error, rad.
    pub predicted_orientation_rad: Vec<f64>,
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
        for v in self
            .reference
            .iter_mut()
            .chain(&mut self.truth)
            .chain(&mut self.predicted)
        {
            v.clear();
        }
        self.reference_poses.clear();
        self.true_poses.clear();
        self.predicted_poses.clear();
        self.true_tip_mm.clear();
        self.predicted_tip_mm.clear();
        self.true_orientation_rad.clear();
        self.predicted_orientation_rad.clear();
    }
}

/// What a streamed prediction measured.
#[derive(Debug, Clone)]
pub struct StreamedPrediction {
    /// The contour statistics of `summary.json` (bit for bit the whole run's).
    pub summary: ContourSummary,
    /// The same statistics as the tables print them.
    pub figures: ContourFigures,
    /// What streaming the reference measured (rates, warnings).
    pub stats: StreamStats,
    /// Per machine axis: servo ticks at which the true drive's command saturated.
    pub saturated_ticks: Vec<u64>,
}

/// The statistics of [`crate::predict::Prediction::figures`] and
/// [`crate::predict::worst_blocks`], accumulated sample by sample.
#[derive(Debug, Default)]
struct Figures {
    /// true tip, true orientation, predicted tip, predicted orientation, |Δ tip|, |Δ orientation|.
    acc: [MaxRms; 6],
    samples: usize,
    worst: WorstLines,
}

impl Figures {
    fn add(&mut self, p: &PredictPiece, which: Measured) {
        self.samples += p.len();
        for k in 0..p.len() {
            let m = match which {
                Measured::All => true,
                Measured::Feed => p.classes[k] == Some(MoveClass::Feed),
            };
            if !m {
                continue;
            }
            let (tt, to) = (p.true_tip_mm[k], p.true_orientation_rad[k]);
            let (pt, po) = (p.predicted_tip_mm[k], p.predicted_orientation_rad[k]);
            for (a, x) in
                self.acc
                    .iter_mut()
                    .zip([tt, to, pt, po, (tt - pt).abs(), (to - po).abs()])
            {
                a.add(x);
            }
            if p.lines[k] != 0 {
                self.worst.add(p.lines[k], tt, to);
            }
        }
    }

    fn finish(self, which: Measured) -> (ContourSummary, ContourFigures) {
        let n = self.acc[0].count();
        let pair = |tip: usize, or: usize, rms: bool| {
            let (t, o) = (self.acc[tip].max_rms(), self.acc[or].max_rms());
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
        let worst = crate::predict::ranked_blocks(self.worst.finish(), WORST_BLOCKS);
        let rows = figures.rows();
        let summary = ContourSummary {
            contour_um: rows.iter().map(|(_, k, f)| (*k, f.tip_um)).collect(),
            orientation_mrad: rows
                .iter()
                .map(|(_, k, f)| (*k, f.orientation_mrad))
                .collect(),
            samples: self.samples,
            measured: match which {
                Measured::Feed => "feed",
                Measured::All => "all",
            },
            measured_samples: n,
            worst_blocks: worst,
        };
        (summary, figures)
    }
}

/// The [`WORST_BLOCKS`] source lines with the largest true tool-tip contour error, in memory
/// that does not grow with the program (a 1 GB program has millions of lines): each run of
/// consecutive measured samples of one line is offered as a whole to a list of the best
/// [`WORST_BLOCKS`] lines so far, ranked as [`crate::predict::worst_blocks`] ranks them (larger
/// error first, then the smaller line). The list and every line's largest tool-tip error in it
/// are exactly the whole run's: a line outside the list at some time had a smaller error than
/// all of it, and the list's last error only grows. So is each listed line's orientation error,
/// unless the line ran more than once (O-word loops and calls) and left the list between its
/// runs: its orientation maximum then covers the runs since it came back (docs/performance.md).
#[derive(Debug, Default)]
struct WorstLines {
    /// The run being read: line, largest tool-tip and orientation errors.
    run: Option<(u32, f64, f64)>,
    /// The best lines so far: line → (tool tip, orientation).
    best: BTreeMap<u32, (f64, f64)>,
}

impl WorstLines {
    fn add(&mut self, line: u32, tip: f64, orientation: f64) {
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

    fn finish(mut self) -> BTreeMap<u32, (f64, f64)> {
        if let Some(r) = self.run.take() {
            self.offer(r);
        }
        self.best
    }
}

/// Samples waiting to be finished, from sample `base` on.
#[derive(Debug, Default)]
struct Pending {
    base: usize,
    lines: VecDeque<u32>,
    classes: VecDeque<Option<MoveClass>>,
    reference: Vec<VecDeque<f64>>,
    truth: Vec<VecDeque<f64>>,
    predicted: Vec<VecDeque<f64>>,
    reference_poses: VecDeque<Pose>,
    true_poses: VecDeque<Pose>,
    predicted_poses: VecDeque<Pose>,
    /// (tip mm, orientation rad) of the true machine and of the models.
    true_errors: VecDeque<(f64, f64)>,
    predicted_errors: VecDeque<(f64, f64)>,
}

impl Pending {
    fn new(axes: usize) -> Pending {
        Pending {
            reference: vec![VecDeque::new(); axes],
            truth: vec![VecDeque::new(); axes],
            predicted: vec![VecDeque::new(); axes],
            ..Pending::default()
        }
    }

    /// Samples known from both the true drives and the models (the models' may trail by the
    /// latency look-ahead).
    fn actual_known(&self) -> usize {
        let len = |v: &[VecDeque<f64>]| v.iter().map(VecDeque::len).min().unwrap_or(0);
        self.base + len(&self.truth).min(len(&self.predicted))
    }

    /// Samples finished: both contour errors known.
    fn finished(&self) -> usize {
        self.base + self.true_errors.len().min(self.predicted_errors.len())
    }

    /// Moves the samples up to `end` into `piece`.
    fn take(&mut self, end: usize, piece: &mut PredictPiece) {
        let n = end - self.base;
        piece.clear();
        piece.first = self.base;
        piece.lines.extend(self.lines.drain(..n));
        piece.classes.extend(self.classes.drain(..n));
        let axes = self.reference.len();
        piece.reference.resize_with(axes, Vec::new);
        piece.truth.resize_with(axes, Vec::new);
        piece.predicted.resize_with(axes, Vec::new);
        for (dst, src) in [
            (&mut piece.reference, &mut self.reference),
            (&mut piece.truth, &mut self.truth),
            (&mut piece.predicted, &mut self.predicted),
        ] {
            for (d, s) in dst.iter_mut().zip(src.iter_mut()) {
                d.extend(s.drain(..n));
            }
        }
        piece
            .reference_poses
            .extend(self.reference_poses.drain(..n));
        piece.true_poses.extend(self.true_poses.drain(..n));
        piece
            .predicted_poses
            .extend(self.predicted_poses.drain(..n));
        for (t, o) in self.true_errors.drain(..n) {
            piece.true_tip_mm.push(t);
            piece.true_orientation_rad.push(o);
        }
        for (t, o) in self.predicted_errors.drain(..n) {
            piece.predicted_tip_mm.push(t);
            piece.predicted_orientation_rad.push(o);
        }
        self.base = end;
    }
}

/// The contour search of one actual pose sequence (the true machine's or the models'), with
/// the poses it has been given.
struct Search {
    stream: ContourStream,
    /// Actual samples pushed.
    pushed: usize,
}

impl Search {
    fn new() -> Result<Search, Error> {
        Ok(Search {
            stream: ContourStream::new(&SearchWindow::default(), StreamLimits::default())?,
            pushed: 0,
        })
    }

    /// Pushes the actual samples `self.pushed..end` (axis positions `pos` per machine axis,
    /// from sample `base`), keeping their poses, and collects the finished errors.
    fn advance(
        &mut self,
        machine: &Machine,
        pos: &mut [VecDeque<f64>],
        base: usize,
        end: usize,
        poses: &mut VecDeque<Pose>,
        errors: &mut VecDeque<(f64, f64)>,
    ) -> Result<(), Error> {
        let kin = machine.require_kinematics()?;
        let cols: Vec<&[f64]> = pos.iter_mut().map(|p| &*p.make_contiguous()).collect();
        for k in self.pushed..end {
            let q = kin.model.forward(&kin.axes.at(&cols, k - base));
            self.stream.push_actual(&q)?;
            poses.push_back(q);
        }
        self.pushed = end;
        self.stream
            .drain(|_, tip, or, _| errors.push_back((tip, or)))?;
        Ok(())
    }
}

/// Runs `stream` (the program at `path`, planned on `machine`) through the true drives and
/// `models` (one per machine axis, each advanced by its axis' `actual_latency_s`, s; empty:
/// none) and the contour searches, handing each piece of finished samples to `sink` in order.
/// The statistics cover the samples `which` selects.
pub fn predict_streamed(
    machine: &Machine,
    stream: &ReferenceStream,
    path: &Path,
    models: &[DriveModel],
    actual_latency_s: &[f64],
    which: Measured,
    sink: &mut dyn FnMut(&PredictPiece) -> Result<(), Error>,
) -> Result<StreamedPrediction, Error> {
    let axes = machine.axes.len();
    if models.len() != axes {
        return Err(Error::Usage(format!(
            "{} models for {axes} axes",
            models.len()
        )));
    }
    latency::check(actual_latency_s, axes)?;
    let kin = machine.require_kinematics()?;
    let ts = stream.plan.ts;
    let drive_err = |i: usize| drive_error(machine, i);
    let opts = SimOptions::default();
    let mut drives = machine
        .axes
        .iter()
        .enumerate()
        .map(|(i, a)| {
            a.drive
                .stream(ts, Channels::TruePosition)
                .map_err(drive_err(i))
        })
        .collect::<Result<Vec<_>, Error>>()?;
    let mut model_streams = models
        .iter()
        .enumerate()
        .map(|(i, m)| m.stream(ts, &opts).map_err(drive_err(i)))
        .collect::<Result<Vec<_>, Error>>()?;
    let mut shifters: Vec<latency::Shifter> = (0..axes)
        .map(|i| latency::Shifter::new(actual_latency_s.get(i).copied().unwrap_or(0.0), ts))
        .collect();
    let (mut true_search, mut pred_search) = (Search::new()?, Search::new()?);
    let mut pending = Pending::new(axes);
    let mut figures = Figures::default();
    let mut piece = PredictPiece::default();
    // Per axis: the true drive's trace of the current piece and the model's positions before
    // and after the latency shift (buffers kept from piece to piece).
    let mut traces: Vec<DriveTrace> = (0..axes).map(|_| DriveTrace::default()).collect();
    let mut logged: Vec<Vec<f64>> = vec![Vec::new(); axes];
    let mut shifted: Vec<Vec<f64>> = vec![Vec::new(); axes];

    // Pushes the known actual samples to both searches and hands the finished ones to `sink`.
    let advance = |pending: &mut Pending,
                   true_search: &mut Search,
                   pred_search: &mut Search,
                   figures: &mut Figures,
                   piece: &mut PredictPiece,
                   sink: &mut dyn FnMut(&PredictPiece) -> Result<(), Error>|
     -> Result<(), Error> {
        let end = pending.actual_known();
        let base = pending.base;
        let Pending {
            truth,
            predicted,
            true_poses,
            predicted_poses,
            true_errors,
            predicted_errors,
            ..
        } = pending;
        let (a, b) = rayon::join(
            || true_search.advance(machine, truth, base, end, true_poses, true_errors),
            || {
                pred_search.advance(
                    machine,
                    predicted,
                    base,
                    end,
                    predicted_poses,
                    predicted_errors,
                )
            },
        );
        a?;
        b?;
        let done = pending.finished();
        if done > pending.base {
            pending.take(done, piece);
            figures.add(piece, which);
            sink(piece)?;
        }
        Ok(())
    };

    let mut on_chunk = |c: &ReferenceChunk| -> Result<(), Error> {
        let n = c.len();
        // The true drives and the models, every axis in parallel (each stream in order).
        let (a, b) = rayon::join(
            || feed_drives(machine, &mut drives, &mut traces, c),
            || {
                model_streams
                    .par_iter_mut()
                    .zip(shifters.par_iter_mut())
                    .zip(logged.par_iter_mut().zip(shifted.par_iter_mut()))
                    .enumerate()
                    .try_for_each(|(i, ((m, sh), (x, y)))| {
                        x.clear();
                        y.clear();
                        m.feed(c.axis(i), x).map_err(drive_err(i))?;
                        sh.feed(x, y);
                        Ok::<(), Error>(())
                    })
            },
        );
        a?;
        b?;
        pending.lines.extend(&c.line);
        pending.classes.extend(&c.class);
        for i in 0..axes {
            pending.reference[i].extend(&c.pos[i]);
            pending.truth[i].extend(&traces[i].true_position);
            pending.predicted[i].extend(&shifted[i]);
        }
        // The reference poses, to both searches.
        let pos: Vec<&[f64]> = c.pos.iter().map(Vec::as_slice).collect();
        let poses: Vec<Pose> = (0..n)
            .map(|k| kin.model.forward(&kin.axes.at(&pos, k)))
            .collect();
        true_search.stream.push_reference(poses.iter().copied())?;
        pred_search.stream.push_reference(poses.iter().copied())?;
        pending.reference_poses.extend(poses);
        advance(
            &mut pending,
            &mut true_search,
            &mut pred_search,
            &mut figures,
            &mut piece,
            sink,
        )
    };
    let stats = stream.run(machine, path, &mut on_chunk)?;

    // The end: the drives' saturation counts, the models' last shifted samples, the searches'
    // last feet.
    let saturated_ticks = drives
        .into_iter()
        .enumerate()
        .map(|(i, d)| d.finish().map_err(drive_err(i)))
        .collect::<Result<Vec<u64>, Error>>()?;
    for (i, ((m, sh), y)) in model_streams
        .into_iter()
        .zip(shifters)
        .zip(&mut shifted)
        .enumerate()
    {
        m.finish().map_err(drive_err(i))?;
        y.clear();
        sh.finish(y);
        pending.predicted[i].extend(y.iter());
    }
    true_search.stream.end_reference();
    pred_search.stream.end_reference();
    advance(
        &mut pending,
        &mut true_search,
        &mut pred_search,
        &mut figures,
        &mut piece,
        sink,
    )?;
    for (search, errors) in [
        (true_search, &mut pending.true_errors),
        (pred_search, &mut pending.predicted_errors),
    ] {
        search
            .stream
            .finish(|_, tip, or, _| errors.push_back((tip, or)))?;
    }
    let done = pending.finished();
    if done > pending.base {
        pending.take(done, &mut piece);
        figures.add(&piece, which);
        sink(&piece)?;
    }
    if pending.base != stream.len() {
        return Err(Error::Usage(format!(
            "the streamed prediction finished {} of {} samples",
            pending.base,
            stream.len()
        )));
    }
    let (summary, figures) = figures.finish(which);
    Ok(StreamedPrediction {
        summary,
        figures,
        stats,
        saturated_ticks,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Truth: [`crate::predict::worst_blocks`] over the whole series.
    #[test]
    fn the_worst_lines_are_the_whole_runs() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for case in 0..200 {
            let n = 1 + (next() % 3000) as usize;
            let recur = case % 2 == 1;
            let (mut lines, mut tip, mut or) = (Vec::new(), Vec::new(), Vec::new());
            let mut line = 1u32;
            for _ in 0..n {
                if next() % 7 == 0 {
                    // A new block: the next line, or (recurring) an earlier one.
                    line = if recur && next() % 3 == 0 {
                        1 + (next() % u64::from(line)) as u32
                    } else {
                        line + 1 + (next() % 3) as u32
                    };
                }
                lines.push(if next() % 50 == 0 { 0 } else { line });
                // Coarse values, so that ties occur.
                tip.push((next() % 40) as f64 * 1e-4);
                or.push((next() % 40) as f64 * 1e-5);
            }
            let mask: Vec<bool> = (0..n).map(|_| next() % 5 != 0).collect();
            let want = crate::predict::worst_blocks(&lines, &tip, &or, &mask, WORST_BLOCKS);
            let mut w = WorstLines::default();
            for k in 0..n {
                if mask[k] && lines[k] != 0 {
                    w.add(lines[k], tip[k], or[k]);
                }
            }
            let got = w.finish();
            let mut got: Vec<(u32, f64, f64)> = got
                .into_iter()
                .map(|(l, (t, o))| (l, t * 1e3, o * 1e3))
                .collect();
            got.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            assert_eq!(got.len(), want.len(), "case {case}");
            for (g, w) in got.iter().zip(&want) {
                assert_eq!((g.0, g.1), (w.line, w.contour_max_um), "case {case}");
                if !recur {
                    assert_eq!(g.2, w.orientation_max_mrad, "case {case}");
                } else {
                    assert!(g.2 <= w.orientation_max_mrad, "case {case}");
                }
            }
        }
    }
}
