//! Tool-tip and orientation contour errors between a reference and an actual pose sequence
//! (docs/contour.md), for vcnc.
//!
//! The **tool-tip contour error** of actual sample $k$ is the distance from the actual tip
//! $p_a$ to the nearest point of the reference tip path, the C¹ Catmull–Rom curve $c(u)$
//! through the reference samples (docs/contour.md#the-foot-on-the-curve):
//! $$ \varepsilon_k = \min_u \big\lVert p_a - c(u)\big\rVert, $$
//! reached at the foot parameter $u^* = j + \tau$ (piece index plus fraction). The
//! **orientation contour error** is the angle between the actual tool axis and the reference
//! tool axis at the same $u^*$ (interpolated by the same cubic, normalised):
//! $$ \phi_k = \operatorname{atan2}\big(\lVert o_a \times o_r(u^*)\rVert,\ o_a \cdot o_r(u^*)\big). $$
//! It is never the error at the same time index (that mixes in the tracking lag and is about
//! twice the contour error). The curve, unlike the polyline through the samples, has no corner
//! at each sample, so the foot — and the reference orientation taken there — does not jump as
//! a tool inside a bend passes a sample.
//!
//! The nearest point of the polyline is searched in a window around the previous one
//! ([`SearchWindow`]), which costs O(N + M) for N actual and M reference samples instead of the
//! O(N·M) of the brute force ([`contour_errors_brute_force`], the test oracle), and then moved
//! onto the curve by Newton's method. Ties (equal distances, e.g. at a vertex) go to the
//! smallest $u^*$ in both searches, so they agree bit for bit whenever the window contains the
//! global foot. Runs of identical reference poses (the machine at rest) are merged into one
//! knot; zero-length segments project onto their start.
//!
//! [`ContourStream`] is the same search over a reference that arrives in pieces, interleaved
//! with the actual poses, in memory bounded by [`StreamLimits`] whatever the run's length
//! (docs/contour.md#streamed-search): a sample is searched once the knots its search reads have
//! arrived, so its answer is the whole-path search's, bit for bit, given the first-sample and
//! history conditions stated there. [`ContourSearch`] is that search with the whole path held.
//!
//! **Units:** positions in mm, angles in rad (the caller converts to µm and mrad for output).
//!
//! ```
//! use vcnc_contour::contour_errors;
//! use vcnc_kinematics::{Pose, nalgebra::Vector3};
//!
//! // Reference: a straight line along X; actual: 3 µm beside it and 2 samples behind.
//! let line = |x: f64, dy: f64| Pose::new(Vector3::new(x, dy, 0.0), Vector3::z());
//! let reference: Vec<Pose> = (0..100).map(|k| line(0.1 * k as f64, 0.0)).collect();
//! let actual: Vec<Pose> = (0..100).map(|k| line(0.1 * (k as f64 - 2.0).max(0.0), 0.003)).collect();
//! let report = contour_errors(&reference, &actual)?;
//! assert!((report.tip_max_mm - 0.003).abs() < 1e-12);
//! assert_eq!(report.orientation_max_rad, 0.0);
//! # Ok::<(), vcnc_contour::Error>(())
//! ```

mod error;
mod path;
mod stream;

use vcnc_kinematics::Pose;
use vcnc_kinematics::nalgebra::Vector3;

pub use error::{Error, Result, Sequence};

use path::{Reach, ReferencePath, SearchState, brute_force_segment, checked};
pub use stream::{ContourStream, StreamHeld, StreamLimits};

/// The foot point of one actual sample on the reference path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Foot {
    /// Path parameter $u^*$ = reference segment index + fraction, in reference samples
    /// (`0.0 ..= len - 1`).
    pub u: f64,
    /// The nearest point of the reference tip path, mm.
    pub point: Vector3<f64>,
    /// The reference tool axis at $u^*$ (the cubic through the samples' axes, normalised), unit
    /// length.
    pub orientation: Vector3<f64>,
}

impl Foot {
    /// A placeholder for a search to write its foot into (not a foot: zero axis).
    pub(crate) fn unset() -> Self {
        Foot {
            u: 0.0,
            point: Vector3::zeros(),
            orientation: Vector3::zeros(),
        }
    }
}

/// Contour errors of an actual pose sequence against a reference one (docs/contour.md).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ContourReport {
    /// Tool-tip contour error per actual sample, mm.
    pub tip_mm: Vec<f64>,
    /// Orientation contour error per actual sample, rad.
    pub orientation_rad: Vec<f64>,
    /// Foot point per actual sample (empty from a [`ContourSearch`] told not to keep them).
    pub foot: Vec<Foot>,
    /// Largest tool-tip contour error, mm.
    pub tip_max_mm: f64,
    /// Root mean square of the tool-tip contour error, mm.
    pub tip_rms_mm: f64,
    /// Largest orientation contour error, rad.
    pub orientation_max_rad: f64,
    /// Root mean square of the orientation contour error, rad.
    pub orientation_rms_rad: f64,
    /// Number of segment projections performed (a deterministic measure of the search cost:
    /// N·(M − 1) for the brute force, a small multiple of N + M for the windowed search).
    pub segment_evaluations: u64,
}

/// Settings of the windowed foot-point search.
///
/// The window starts `min_margin` segments either side of the previous foot and grows at an
/// edge while the best candidate is fewer than `min_margin` segments from that edge (the
/// distance keeps decreasing towards it) or while the edge vertex lies within the reach
/// $\rho = k_\rho\, d^* + \rho_0$ of the actual tip ($d^*$ the best distance so far). It then
/// finds the global foot unless the reference path leaves that ball and comes back closer
/// further on (e.g. the neighbouring turn of a spiral, which is not the point being tracked;
/// with $k_\rho = 2$ corners sharper than 60° can also be cut).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchWindow {
    /// Segments kept beyond the best candidate on each side; at least 1. Default 3.
    pub min_margin: usize,
    /// $k_\rho$: reach as a multiple of the best distance so far (unitless, ≥ 0). Default 2.
    pub reach_factor: f64,
    /// $\rho_0$: reach added to it, mm (≥ 0). Default 0.
    pub reach_mm: f64,
}

impl Default for SearchWindow {
    fn default() -> Self {
        Self {
            min_margin: 3,
            reach_factor: 2.0,
            reach_mm: 0.0,
        }
    }
}

impl SearchWindow {
    /// Checks the settings.
    pub fn validate(&self) -> Result<()> {
        if self.min_margin == 0 {
            return Err(Error::BadWindow {
                name: "min_margin",
                value: 0.0,
                reason: "must be at least 1 (else the window cannot follow the foot)",
            });
        }
        if !(self.reach_factor.is_finite() && self.reach_factor >= 0.0) {
            return Err(Error::BadWindow {
                name: "reach_factor",
                value: self.reach_factor,
                reason: "must be finite and >= 0",
            });
        }
        if !(self.reach_mm.is_finite() && self.reach_mm >= 0.0) {
            return Err(Error::BadWindow {
                name: "reach_mm",
                value: self.reach_mm,
                reason: "must be finite and >= 0",
            });
        }
        Ok(())
    }
}

/// Angle between two tool axes, rad, accurate at small and large angles:
/// $\operatorname{atan2}(\lVert o_a \times o_r\rVert, o_a \cdot o_r)$.
pub fn orientation_error(o_a: &Vector3<f64>, o_r: &Vector3<f64>) -> f64 {
    o_a.cross(o_r).norm().atan2(o_a.dot(o_r))
}

/// Contour errors with the windowed foot-point search and default [`SearchWindow`].
pub fn contour_errors(reference: &[Pose], actual: &[Pose]) -> Result<ContourReport> {
    contour_errors_with(reference, actual, &SearchWindow::default())
}

/// Contour errors with the windowed foot-point search (O(N + M)): the first actual sample is
/// located by a global search, every later one in a window around the previous foot.
pub fn contour_errors_with(
    reference: &[Pose],
    actual: &[Pose],
    window: &SearchWindow,
) -> Result<ContourReport> {
    window.validate()?;
    let path = ContourPath::new(reference)?;
    if actual.is_empty() {
        return Err(Error::Empty(Sequence::Actual));
    }
    let mut search = ContourSearch::new(&path, window, true, actual.len())?;
    for pose in actual {
        search.push(pose)?;
    }
    search.finish()
}

/// The reference path of the windowed search, built once and shared by any number of
/// [`ContourSearch`]es (for example the true machine's and a model's, run side by side).
#[derive(Debug, Clone)]
pub struct ContourPath {
    path: ReferencePath,
}

impl ContourPath {
    /// The reference poses as a path (runs of identical poses merged into one knot).
    pub fn new(reference: &[Pose]) -> Result<Self> {
        Self::from_poses(reference.iter().copied())
    }

    /// [`ContourPath::new`] of poses given one at a time (a long run need not hold them:
    /// they can be computed as the path takes them).
    pub fn from_poses(reference: impl IntoIterator<Item = Pose>) -> Result<Self> {
        Ok(Self {
            path: ReferencePath::new(reference)?,
        })
    }
}

/// The windowed contour search fed one actual pose at a time, so that a long run never holds
/// its actual poses; [`contour_errors_with`] is this search over a slice, and the two give the
/// same report bit for bit. [`ContourStream`] is the same search over a reference that arrives
/// in pieces.
#[derive(Debug)]
pub struct ContourSearch<'a> {
    path: &'a ReferencePath,
    window: SearchWindow,
    acc: Accumulator,
    state: SearchState,
}

impl<'a> ContourSearch<'a> {
    /// A search along `path`. `keep_feet`: whether the report keeps each sample's [`Foot`] (56
    /// bytes a sample); `capacity`: the expected number of actual samples (a hint).
    pub fn new(
        path: &'a ContourPath,
        window: &SearchWindow,
        keep_feet: bool,
        capacity: usize,
    ) -> Result<Self> {
        window.validate()?;
        Ok(Self {
            path: &path.path,
            window: *window,
            acc: Accumulator::new(capacity, true, keep_feet),
            state: SearchState::new(),
        })
    }

    /// The contour errors of the next actual sample: the first is located by a global search,
    /// every later one in a window around the previous foot. When that foot has moved
    /// backwards along the path, or the segment at the reference sample of the same index is
    /// closer than it, a second window is searched, started at that segment, and the closer of
    /// the two candidates is kept.
    ///
    /// The global search of the first sample is skipped when its tip lies exactly on the first
    /// reference tip (a run starting from rest where its reference starts): the foot is then
    /// $u^* = 0$ exactly as the global search finds it (nothing is closer than 0, and ties go
    /// to the smaller $u$), counted as one projection.
    ///
    /// The second window is the time hint: actual sample $k$ is where the machine was when
    /// reference sample $k$ was commanded, so its foot lies a tracking lag behind that sample.
    /// It catches the foot when the path turns back on itself close to where it came from (a
    /// raster's reversal to the next pass a few mm over). There the previous foot's window can
    /// stay on the pass just left, whose points are close but not the closest, and never reach
    /// the new pass, whose start leaves the window's ball at the corner. The sign of that is a
    /// foot running backwards while the machine runs forwards, or a commanded point closer than
    /// the foot found. Taking the closer of two candidates never moves the result away from the
    /// global foot; the test costs one projection a sample, the second window is searched only
    /// when it fires, so the cost stays O(N + M).
    pub fn push(&mut self, pose: &Pose) -> Result<()> {
        let (x, o) = checked(pose, Sequence::Actual, self.state.k)?;
        let mut foot = Foot::unset();
        whole(self.path.step(
            &mut self.state,
            &x,
            &self.window,
            usize::MAX,
            &mut self.acc.evals,
            &mut foot,
        ))?;
        self.acc.push(&x, &o, foot);
        Ok(())
    }

    /// The report of the samples pushed (an error when there were none).
    pub fn finish(self) -> Result<ContourReport> {
        if self.state.k == 0 {
            return Err(Error::Empty(Sequence::Actual));
        }
        Ok(self.acc.finish())
    }
}

/// A search over a whole (ended) path never needs more reference nor a dropped knot; if it
/// did, that would be a bug, reported rather than panicking.
fn whole<T>(r: Reach<T>) -> Result<T> {
    r.map_err(|_| Error::Internal("the foot search read past the end of a whole reference path"))
}

/// Contour errors with a brute-force foot search over every reference segment (O(N·M)); the
/// oracle of the windowed search.
pub fn contour_errors_brute_force(reference: &[Pose], actual: &[Pose]) -> Result<ContourReport> {
    if reference.is_empty() {
        return Err(Error::Empty(Sequence::Reference));
    }
    if actual.is_empty() {
        return Err(Error::Empty(Sequence::Actual));
    }
    // The knots (every pose checked), to move each polyline foot onto the reference curve as
    // the windowed search does: the brute force checks the search's choice of the polyline
    // foot; the refinement is the same function of it.
    let path = ReferencePath::new(reference.iter().copied())?;
    let tips: Vec<Vector3<f64>> = reference.iter().map(|pose| pose.p).collect();
    let mut acc = Accumulator::new(actual.len(), true, true);
    let per_sample = reference.len().saturating_sub(1).max(1) as u64;
    for (k, pose) in actual.iter().enumerate() {
        let (x, o) = checked(pose, Sequence::Actual, k)?;
        let Some((seg, t)) = brute_force_segment(&tips, &x) else {
            return Err(Error::Empty(Sequence::Reference));
        };
        acc.evals += per_sample;
        let on_curve = whole(path.refine(&path.candidate_on_raw(seg, t, &x), &x))?;
        acc.push(&x, &o, whole(path.foot(&on_curve))?);
    }
    Ok(acc.finish())
}

/// Collects the per-sample series (or only their statistics) and the statistics.
#[derive(Debug)]
struct Accumulator {
    report: ContourReport,
    keep_series: bool,
    keep_feet: bool,
    evals: u64,
    count: usize,
    sum_tip2: f64,
    sum_ori2: f64,
}

impl Accumulator {
    fn new(n: usize, keep_series: bool, keep_feet: bool) -> Self {
        let n = if keep_series { n } else { 0 };
        Self {
            report: ContourReport {
                tip_mm: Vec::with_capacity(n),
                orientation_rad: Vec::with_capacity(n),
                foot: Vec::with_capacity(if keep_feet { n } else { 0 }),
                ..ContourReport::default()
            },
            keep_series,
            keep_feet: keep_series && keep_feet,
            evals: 0,
            count: 0,
            sum_tip2: 0.0,
            sum_ori2: 0.0,
        }
    }

    /// Adds a sample; returns its tip (mm) and orientation (rad) contour errors.
    fn push(&mut self, x: &Vector3<f64>, o: &Vector3<f64>, foot: Foot) -> (f64, f64) {
        let tip = (x - foot.point).norm();
        let ori = orientation_error(o, &foot.orientation);
        let r = &mut self.report;
        r.tip_max_mm = r.tip_max_mm.max(tip);
        r.orientation_max_rad = r.orientation_max_rad.max(ori);
        self.sum_tip2 += tip * tip;
        self.sum_ori2 += ori * ori;
        self.count += 1;
        if self.keep_series {
            r.tip_mm.push(tip);
            r.orientation_rad.push(ori);
        }
        if self.keep_feet {
            r.foot.push(foot);
        }
        (tip, ori)
    }

    fn finish(mut self) -> ContourReport {
        let n = self.count.max(1) as f64;
        self.report.tip_rms_mm = (self.sum_tip2 / n).sqrt();
        self.report.orientation_rms_rad = (self.sum_ori2 / n).sqrt();
        self.report.segment_evaluations = self.evals;
        self.report
    }
}
