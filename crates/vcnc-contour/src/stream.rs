//! The windowed contour search over a reference that arrives in pieces, in bounded memory
//! (docs/contour.md#streamed-search).

use std::collections::VecDeque;

use vcnc_kinematics::Pose;
use vcnc_kinematics::nalgebra::Vector3;

use crate::error::{Error, Result, Sequence};
use crate::path::{MAX_PIECE_MOVES, Need, ReferencePath, SearchState, checked};
use crate::{Accumulator, ContourReport, Foot, SearchWindow};

/// Bounds of a [`ContourStream`]'s memory (docs/contour.md#streamed-search). A knot is one
/// reference pose (runs of identical poses merged), 64 bytes; a waiting actual sample 48 bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamLimits {
    /// Knots kept behind the previous foot and the time hint's knot, for later searches whose
    /// foot moves back or whose window grows back (knots). A search that reads farther back
    /// is an error ([`Error::HistoryExceeded`]); on feed paths the window reaches back a few
    /// knots, so this happens only on pathological paths. At least
    /// [`SearchWindow::min_margin`] + 6. Default 65 536.
    pub history: usize,
    /// Reference samples over which the first actual sample is searched globally when its
    /// tip is not exactly on the first reference tip (samples). The stream then equals the
    /// whole-path search when the global foot lies among them. At least 1. Default 65 536.
    pub first_window: usize,
    /// Most actual samples waiting for reference (samples): a sample waits until the knots its
    /// search reads have arrived — a rest at the last knot held included. At least 1. Default
    /// 1 048 576.
    pub queue: usize,
    /// Most reference knots held (knots): the history, the knots from the oldest waiting
    /// sample's previous foot to the last one pushed (how far the caller pushes reference
    /// ahead), and the first window until the first sample's foot is found. At least
    /// `first_window` + 8 and `history` + 8. Default 1 048 576.
    pub knots: usize,
}

impl Default for StreamLimits {
    fn default() -> Self {
        Self {
            history: 1 << 16,
            first_window: 1 << 16,
            queue: 1 << 20,
            knots: 1 << 20,
        }
    }
}

impl StreamLimits {
    /// Checks the limits against the search window's settings.
    pub fn validate(&self, window: &SearchWindow) -> Result<()> {
        let bad = |name, value, reason| {
            Err(Error::BadLimits {
                name,
                value,
                reason,
            })
        };
        if self.history < window.min_margin.saturating_add(MAX_PIECE_MOVES + 2) {
            return bad(
                "history",
                self.history,
                "must be at least min_margin + 6 (the window's first edge, the refinement's \
                 crossings and its tangents)",
            );
        }
        if self.first_window == 0 {
            return bad("first_window", 0, "must be at least 1");
        }
        if self.queue == 0 {
            return bad("queue", 0, "must be at least 1");
        }
        if self.knots < self.first_window.saturating_add(8)
            || self.knots < self.history.saturating_add(8)
        {
            return bad(
                "knots",
                self.knots,
                "must be at least first_window + 8 and history + 8",
            );
        }
        Ok(())
    }
}

/// What a [`ContourStream`] holds (a diagnostic of its memory).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamHeld {
    /// Reference knots held (knots).
    pub knots: usize,
    /// Index of the oldest knot held among the path's knots (knots dropped before it).
    pub first_knot: usize,
    /// Actual samples waiting for reference (samples).
    pub queued: usize,
}

/// The windowed contour search of [`ContourSearch`](crate::ContourSearch) over a reference
/// that arrives a piece at a time, interleaved with the actual poses, in memory bounded by
/// [`StreamLimits`] whatever the run's length (docs/contour.md#streamed-search).
///
/// An actual sample's search runs when the knots it reads are held: the same search code as
/// [`ContourSearch`](crate::ContourSearch), over the knots held; where it would read a knot
/// not pushed yet (the window growing forward, the time hint's knot, the refinement's
/// neighbours) or ask whether the path ends at the last knot held, the sample waits and is
/// searched again, from the same state, once more reference has arrived or the reference has
/// ended. Every answer is then the whole-path search's, bit for bit (tip and orientation
/// errors, foot, statistics and [`segment_evaluations`](ContourReport::segment_evaluations)),
/// provided that the first sample's tip lies on the first reference tip or its global foot lies
/// within [`StreamLimits::first_window`], and that no search reaches back more than
/// [`StreamLimits::history`] knots (else an error). Knots farther back are dropped.
///
/// Errors: a bad pose is refused with the poses before it taken; a full queue refuses the
/// pose; a search reaching back beyond the history leaves its sample waiting (it would fail
/// again). After any error, the results of the run are incomplete.
///
/// ```
/// use vcnc_contour::{ContourStream, SearchWindow, StreamLimits};
/// use vcnc_kinematics::{Pose, nalgebra::Vector3};
///
/// // Reference: a line along X in pieces of 100 samples; actual: 3 µm beside it, 2 samples behind.
/// let line = |x: f64, dy: f64| Pose::new(Vector3::new(x, dy, 0.0), Vector3::z());
/// let mut stream = ContourStream::new(&SearchWindow::default(), StreamLimits::default())?;
/// let mut worst = 0.0f64;
/// for piece in 0..10 {
///     let samples = piece * 100..(piece + 1) * 100;
///     stream.push_reference(samples.clone().map(|k| line(0.1 * k as f64, 0.0)))?;
///     for k in samples {
///         stream.push_actual(&line(0.1 * (k as f64 - 2.0).max(0.0), 0.003))?;
///     }
///     stream.drain(|_k, tip_mm, _rad, _foot| worst = worst.max(tip_mm))?;
/// }
/// stream.end_reference();
/// let report = stream.finish(|_k, tip_mm, _rad, _foot| worst = worst.max(tip_mm))?;
/// assert!((report.tip_max_mm - 0.003).abs() < 1e-12 && report.tip_max_mm == worst);
/// # Ok::<(), vcnc_contour::Error>(())
/// ```
#[derive(Debug)]
pub struct ContourStream {
    path: ReferencePath,
    window: SearchWindow,
    limits: StreamLimits,
    /// Search state after the last sample answered.
    state: SearchState,
    /// Checked actual samples (tip, unit tool axis) waiting; the front is sample `state.k`.
    queue: VecDeque<(Vector3<f64>, Vector3<f64>)>,
    /// Actual samples pushed.
    pushed: usize,
    acc: Accumulator,
    /// One past the last knot held when the front sample last needed more reference: it is not
    /// searched again until a knot has arrived or the reference has ended.
    stalled: Option<usize>,
}

impl ContourStream {
    /// An empty stream. Unlike [`ContourSearch`](crate::ContourSearch) it keeps no per-sample
    /// series: each sample's errors and [`Foot`] are handed to the caller by
    /// [`drain`](Self::drain) and [`finish`](Self::finish).
    pub fn new(window: &SearchWindow, limits: StreamLimits) -> Result<Self> {
        window.validate()?;
        limits.validate(window)?;
        Ok(Self {
            path: ReferencePath::open(0),
            window: *window,
            limits,
            state: SearchState::new(),
            queue: VecDeque::new(),
            pushed: 0,
            acc: Accumulator::new(0, false, false),
            stalled: None,
        })
    }

    /// Appends reference poses (the path's next samples), each checked as
    /// [`ContourPath`](crate::ContourPath) checks it (an error names its index in the whole
    /// run). An error when the stream would hold more than [`StreamLimits::knots`] knots, or
    /// after [`end_reference`](Self::end_reference).
    pub fn push_reference(&mut self, poses: impl IntoIterator<Item = Pose>) -> Result<()> {
        if self.path.ended() {
            return Err(Error::StreamOrder("reference pushed after end_reference"));
        }
        for pose in poses {
            if self.path.push(&pose)? && self.path.held() > self.limits.knots {
                self.compact(true);
                if self.path.held() > self.limits.knots {
                    return Err(Error::TooManyKnots {
                        sample: self.path.samples() - 1,
                        limit: self.limits.knots,
                    });
                }
            }
        }
        Ok(())
    }

    /// No more reference: the path ends at the last pose pushed.
    pub fn end_reference(&mut self) {
        self.path.end();
    }

    /// Queues the next actual pose, checked as [`ContourSearch::push`](crate::ContourSearch::push)
    /// checks it (an error names its index). An error when [`StreamLimits::queue`] samples
    /// already wait: push reference (and [`drain`](Self::drain)) first.
    pub fn push_actual(&mut self, pose: &Pose) -> Result<()> {
        let (x, o) = checked(pose, Sequence::Actual, self.pushed)?;
        if self.queue.len() >= self.limits.queue {
            return Err(Error::QueueFull {
                sample: self.pushed,
                limit: self.limits.queue,
            });
        }
        self.queue.push_back((x, o));
        self.pushed += 1;
        Ok(())
    }

    /// Calls `f(k, tip_mm, orientation_rad, foot)` for each actual sample whose result is
    /// final, in order (`k` its index, the tool-tip contour error in mm, the orientation
    /// contour error in rad, its foot), and forgets it; then drops the knots no later search
    /// may read. Samples whose search needs reference not pushed yet stay queued.
    pub fn drain(&mut self, mut f: impl FnMut(usize, f64, f64, &Foot)) -> Result<()> {
        if self.path.ended() && self.path.samples() == 0 && !self.queue.is_empty() {
            return Err(Error::Empty(Sequence::Reference));
        }
        while let Some(&(x, o)) = self.queue.front() {
            let held_to = self.path.base() + self.path.held();
            if !self.path.ended() && self.stalled == Some(held_to) {
                break;
            }
            let k = self.state.k;
            let mut foot = Foot::unset();
            match self.path.step(
                &mut self.state,
                &x,
                &self.window,
                self.limits.first_window,
                &mut self.acc.evals,
                &mut foot,
            ) {
                Ok(()) => {
                    let (tip, ori) = self.acc.push(&x, &o, foot);
                    self.queue.pop_front();
                    self.stalled = None;
                    f(k, tip, ori, &foot);
                }
                Err(Need::More) if self.path.ended() => {
                    return Err(Error::Internal(
                        "the foot search read past the end of an ended reference path",
                    ));
                }
                Err(Need::More) => {
                    self.stalled = Some(held_to);
                    break;
                }
                Err(Need::History { knot }) => {
                    return Err(Error::HistoryExceeded {
                        sample: k,
                        knot,
                        oldest: self.path.base(),
                        history: self.limits.history,
                    });
                }
            }
        }
        self.compact(false);
        Ok(())
    }

    /// After [`end_reference`](Self::end_reference) and the last
    /// [`push_actual`](Self::push_actual): [`drain`](Self::drain)s the rest and returns the
    /// statistics (maxima, RMS, [`segment_evaluations`](ContourReport::segment_evaluations));
    /// its per-sample vectors are empty. Errors: the reference not ended, or no reference or
    /// no actual pose at all.
    pub fn finish(mut self, f: impl FnMut(usize, f64, f64, &Foot)) -> Result<ContourReport> {
        if !self.path.ended() {
            return Err(Error::StreamOrder("finish called before end_reference"));
        }
        if self.path.samples() == 0 {
            return Err(Error::Empty(Sequence::Reference));
        }
        self.drain(f)?;
        if !self.queue.is_empty() {
            return Err(Error::Internal(
                "actual samples left waiting after the reference ended",
            ));
        }
        if self.pushed == 0 {
            return Err(Error::Empty(Sequence::Actual));
        }
        Ok(self.acc.finish())
    }

    /// What the stream holds now.
    pub fn held(&self) -> StreamHeld {
        StreamHeld {
            knots: self.path.held(),
            first_knot: self.path.base(),
            queued: self.queue.len(),
        }
    }

    /// Drops the knots more than [`StreamLimits::history`] behind the next search's anchor
    /// (its previous foot and hint knot): when at least a quarter of those held can go (so
    /// that moving the rest costs O(1) a knot), or always with `force`. Nothing before the
    /// first sample's foot is found.
    fn compact(&mut self, force: bool) {
        let Some(anchor) = self.state.anchor() else {
            return;
        };
        let to = anchor.saturating_sub(self.limits.history);
        let d = to.saturating_sub(self.path.base());
        if d > 0 && (force || 4 * d >= self.path.held()) {
            self.path.drop_before(to);
        }
    }
}
