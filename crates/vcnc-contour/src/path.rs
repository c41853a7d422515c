//! The reference tip path as a polyline, segment projection, and the two foot-point searches.

use vcnc_kinematics::Pose;
use vcnc_kinematics::nalgebra::Vector3;

use crate::error::{Error, Result, Sequence};
use crate::{Foot, SearchWindow};

/// Checks a pose and returns its tip and unit tool axis. Shared by both searches so that they
/// see bit-identical data.
pub(crate) fn checked(
    pose: &Pose,
    which: Sequence,
    sample: usize,
) -> Result<(Vector3<f64>, Vector3<f64>)> {
    if !pose.p.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFinite {
            which,
            sample,
            what: "tip position (mm)",
            v: [pose.p.x, pose.p.y, pose.p.z],
        });
    }
    if !pose.o.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFinite {
            which,
            sample,
            what: "tool axis",
            v: [pose.o.x, pose.o.y, pose.o.z],
        });
    }
    let m = pose.o.amax();
    if m == 0.0 {
        return Err(Error::ZeroOrientation {
            which,
            sample,
            o: [pose.o.x, pose.o.y, pose.o.z],
        });
    }
    let o = pose.o / m;
    Ok((pose.p, o / o.norm()))
}

/// Projection of `p` on the segment `a → b`: the fraction $t \in [0, 1]$, the foot point and the
/// squared distance. A zero-length segment projects to `a` with $t = 0$; $t$ is clamped and the
/// clamped ends return `a` or `b` exactly, so a vertex shared by two segments gives the same
/// point (and distance) from both.
#[inline]
pub(crate) fn project(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
) -> (f64, Vector3<f64>, f64) {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let (t, q) = if len2 == 0.0 {
        (0.0, *a)
    } else {
        let t = (p - a).dot(&ab) / len2;
        if t <= 0.0 || t.is_nan() {
            (0.0, *a)
        } else if t >= 1.0 {
            (1.0, *b)
        } else {
            (t, a + ab * t)
        }
    };
    (t, q, (p - q).norm_squared())
}

/// Normalised linear interpolation of two unit tool axes at fraction `t` (nlerp). If they are
/// antiparallel at the midpoint (zero-length interpolant), the nearer end is used.
#[inline]
pub(crate) fn nlerp(oa: &Vector3<f64>, ob: &Vector3<f64>, t: f64) -> Vector3<f64> {
    if t == 0.0 {
        return *oa;
    }
    if t == 1.0 {
        return *ob;
    }
    let v = oa * (1.0 - t) + ob * t;
    let n = v.norm();
    if n > 1e-12 {
        v / n
    } else if t < 0.5 {
        *oa
    } else {
        *ob
    }
}

/// Most Newton steps of [`ReferencePath::refine`] (it converges in three or four).
const MAX_NEWTON_STEPS: usize = 16;
/// Pieces shorter than this (mm, a picometre) are points to [`ReferencePath::refine`].
const MIN_PIECE_MM: f64 = 1e-9;
/// Most crossings into a neighbouring piece in [`ReferencePath::refine`].
const MAX_PIECE_MOVES: usize = 4;
/// Step in the piece parameter below which [`ReferencePath::refine`] has converged: 10⁻⁹ of a
/// piece (below 10⁻⁹ mm on any feed path sampled at 1 ms). Rounding in the residual alone
/// moves the root by about 10⁻¹¹, so a tighter tolerance would never be met.
const NEWTON_TOLERANCE: f64 = 1e-9;

/// A candidate foot point: squared distance (mm²), path parameter, and where it lies.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Candidate {
    pub d2: f64,
    pub u: f64,
    pub seg: usize,
    pub t: f64,
    pub q: Vector3<f64>,
}

impl Candidate {
    /// The total order of both searches: smaller distance, then smaller u.
    #[inline]
    pub fn better_than(&self, other: &Candidate) -> bool {
        self.d2 < other.d2 || (self.d2 == other.d2 && self.u < other.u)
    }
}

/// The reference polyline with runs of identical consecutive poses (a machine at rest) merged
/// into one knot, so that rests cost nothing in the windowed search.
#[derive(Debug, Clone)]
pub(crate) struct ReferencePath {
    /// Knot tip positions, mm.
    p: Vec<Vector3<f64>>,
    /// Knot unit tool axes.
    o: Vec<Vector3<f64>>,
    /// Index of the first reference sample of each knot's run.
    first: Vec<usize>,
    /// Index of the last reference sample of each knot's run.
    last: Vec<usize>,
}

impl ReferencePath {
    pub fn new(reference: impl IntoIterator<Item = Pose>) -> Result<Self> {
        let reference = reference.into_iter();
        let n = reference.size_hint().0;
        let mut path = ReferencePath {
            p: Vec::with_capacity(n),
            o: Vec::with_capacity(n),
            first: Vec::with_capacity(n),
            last: Vec::with_capacity(n),
        };
        for (k, pose) in reference.enumerate() {
            let (p, o) = checked(&pose, Sequence::Reference, k)?;
            match (path.p.last(), path.o.last(), path.last.last_mut()) {
                (Some(lp), Some(lo), Some(last)) if *lp == p && *lo == o => *last = k,
                _ => {
                    path.p.push(p);
                    path.o.push(o);
                    path.first.push(k);
                    path.last.push(k);
                }
            }
        }
        if path.p.is_empty() {
            return Err(Error::Empty(Sequence::Reference));
        }
        Ok(path)
    }

    /// The segment that starts at the knot holding reference sample `k` (the last segment for a
    /// `k` past the end), with `cursor` a knot index no greater than the answer, advanced in
    /// place: calls with increasing `k` cost O(1) each on average.
    pub fn segment_of_sample(&self, k: usize, cursor: &mut usize) -> usize {
        let n = self.last.len();
        while *cursor + 1 < n && self.last[*cursor] < k {
            *cursor += 1;
        }
        (*cursor).min(self.segments().saturating_sub(1))
    }

    /// Number of segments (knots − 1).
    fn segments(&self) -> usize {
        self.p.len().saturating_sub(1)
    }

    /// Projection on segment `s` (knot `s` → knot `s + 1`), in reference-sample parameter:
    /// $u = \text{last}_s + t$, or the first sample of the knot's run when $t = 0$.
    #[inline]
    pub fn eval(&self, s: usize, x: &Vector3<f64>) -> Candidate {
        let a = &self.p[s];
        let b = &self.p[s + 1];
        let (t, q, d2) = project(x, a, b);
        self.candidate(s, t, q, d2)
    }

    /// The candidate at fraction `t` of piece `s` (point `q`, squared distance `d2`), with its
    /// path parameter: $u = \text{last}_s + t$, or the first sample of the knot's run when
    /// $t = 0$.
    #[inline]
    fn candidate(&self, s: usize, t: f64, q: Vector3<f64>, d2: f64) -> Candidate {
        let u = if t == 0.0 {
            self.first[s] as f64
        } else {
            self.last[s] as f64 + t
        };
        Candidate {
            d2,
            u,
            seg: s,
            t,
            q,
        }
    }

    /// The single-knot path: the foot is the knot.
    fn only_knot(&self, x: &Vector3<f64>) -> Option<Candidate> {
        if self.segments() == 0 {
            let q = *self.p.first()?;
            Some(self.candidate(0, 0.0, q, (x - q).norm_squared()))
        } else {
            None
        }
    }

    /// Global nearest point (O(segments)); used once to start the windowed search.
    pub fn nearest_global(&self, x: &Vector3<f64>, evals: &mut u64) -> Candidate {
        if let Some(c) = self.only_knot(x) {
            *evals += 1;
            return c;
        }
        let mut best = self.eval(0, x);
        for s in 1..self.segments() {
            let c = self.eval(s, x);
            if c.better_than(&best) {
                best = c;
            }
        }
        *evals += self.segments() as u64;
        best
    }

    /// Windowed nearest point around the previous foot segment `prev` (docs/contour.md).
    ///
    /// The window starts at `prev ± min_margin` segments and grows one segment at a time at an
    /// edge while (a) the best candidate is fewer than `min_margin` segments from that edge (the
    /// distance keeps decreasing towards it), or (b) the edge knot lies within the reach
    /// $\rho = k_\rho d^* + \rho_0$ of the actual tip, $d^*$ being the best distance so far
    /// (the path near the foot has not yet left the ball in which a closer point could lie).
    pub fn nearest_windowed(
        &self,
        x: &Vector3<f64>,
        prev: usize,
        win: &SearchWindow,
        evals: &mut u64,
    ) -> Candidate {
        if let Some(c) = self.only_knot(x) {
            *evals += 1;
            return c;
        }
        let nseg = self.segments();
        let prev = prev.min(nseg - 1);
        let mut lo = prev.saturating_sub(win.min_margin);
        let mut hi = (prev + win.min_margin).min(nseg - 1);
        let mut best = self.eval(lo, x);
        for s in lo + 1..=hi {
            let c = self.eval(s, x);
            if c.better_than(&best) {
                best = c;
            }
        }
        *evals += (hi - lo + 1) as u64;
        loop {
            let reach = win.reach_factor * best.d2.sqrt() + win.reach_mm;
            let reach2 = reach * reach;
            let mut grew = false;
            if lo > 0
                && (best.seg - lo < win.min_margin || (x - self.p[lo]).norm_squared() <= reach2)
            {
                lo -= 1;
                let c = self.eval(lo, x);
                *evals += 1;
                if c.better_than(&best) {
                    best = c;
                }
                grew = true;
            }
            if hi + 1 < nseg
                && (hi - best.seg < win.min_margin || (x - self.p[hi + 1]).norm_squared() <= reach2)
            {
                hi += 1;
                let c = self.eval(hi, x);
                *evals += 1;
                if c.better_than(&best) {
                    best = c;
                }
                grew = true;
            }
            if !grew {
                return best;
            }
        }
    }

    /// Tangent at knot `i` of the C¹ curve through the knot values `v` (per knot step): the
    /// central difference $(v_{i+1} - v_{i-1})/2$ inside, the second-order one-sided difference
    /// $\pm(3v_i - 4v_{i\mp1} + v_{i\mp2})/2$ at the two ends (the chord on a two-knot path).
    fn tangent_of(v: &[Vector3<f64>], i: usize) -> Vector3<f64> {
        let n = v.len();
        if n < 2 {
            Vector3::zeros()
        } else if n == 2 {
            v[1] - v[0]
        } else if i == 0 {
            (v[1] * 4.0 - v[0] * 3.0 - v[2]) * 0.5
        } else if i + 1 >= n {
            (v[n - 1] * 3.0 - v[n - 2] * 4.0 + v[n - 3]) * 0.5
        } else {
            (v[i + 1] - v[i - 1]) * 0.5
        }
    }

    /// Piece `s` of the C¹ curve through the knot values `v`: its end values and their
    /// [`tangent_of`](Self::tangent_of)s, $(v_s, m_s, v_{s+1}, m_{s+1})$.
    fn piece_of(v: &[Vector3<f64>], s: usize) -> [Vector3<f64>; 4] {
        [
            v[s],
            Self::tangent_of(v, s),
            v[s + 1],
            Self::tangent_of(v, s + 1),
        ]
    }

    /// The cubic Hermite interpolant of a piece `[v0, m0, v1, m1]` ([`piece_of`](Self::piece_of))
    /// at $\tau \in [0, 1]$, with its first and second derivatives in $\tau$: on the knots'
    /// tips, the reference tip curve (Catmull–Rom); on their tool axes, the reference tool axis
    /// before normalisation.
    fn hermite(piece: &[Vector3<f64>; 4], tau: f64) -> [Vector3<f64>; 3] {
        let [p0, m0, p1, m1] = piece;
        let (t, t2) = (tau, tau * tau);
        let t3 = t2 * t;
        let c = p0 * (2.0 * t3 - 3.0 * t2 + 1.0)
            + m0 * (t3 - 2.0 * t2 + t)
            + p1 * (3.0 * t2 - 2.0 * t3)
            + m1 * (t3 - t2);
        let d1 = p0 * (6.0 * t2 - 6.0 * t)
            + m0 * (3.0 * t2 - 4.0 * t + 1.0)
            + p1 * (6.0 * t - 6.0 * t2)
            + m1 * (3.0 * t2 - 2.0 * t);
        let d2 = p0 * (12.0 * t - 6.0)
            + m0 * (6.0 * t - 4.0)
            + p1 * (6.0 - 12.0 * t)
            + m1 * (6.0 * t - 2.0);
        [c, d1, d2]
    }

    /// Whether piece `s` is longer than [`MIN_PIECE_MM`]: a shorter one (a tool rotating about
    /// a fixed tip, or an axis at rest whose forward kinematics differ in the last bits) has no
    /// curve worth projecting on, and Newton's method there would follow rounding noise.
    fn has_length(&self, s: usize) -> bool {
        s + 1 < self.p.len() && (self.p[s + 1] - self.p[s]).norm_squared() > MIN_PIECE_MM.powi(2)
    }

    /// The polyline foot `c` moved onto the reference tip curve (docs/contour.md#the-foot-on-the-curve):
    /// the nearest point of the C¹ Catmull–Rom curve through the knots, found by Newton's
    /// method on $(q(\tau) - x)\cdot q'(\tau) = 0$ started at `c`, crossing into a neighbouring
    /// piece when the step leaves $[0, 1]$ (at most [`MAX_PIECE_MOVES`] times), clamped at a
    /// zero-length piece and at the path's ends.
    ///
    /// Why: between two reference samples the polyline turns by a finite angle $\theta$ at each
    /// knot, and from inside a bend the nearest polyline point jumps by about
    /// $2 d \tan(\theta/2)$ along the path as the tool passes a knot ($d$ the contour error). The
    /// reference orientation, taken at the foot, jumps with it: on the spiral, where the tool
    /// axis turns up to 1 mrad per sample and the true tip lags up to 0.45 mm, by up to
    /// 0.05 mrad from one sample to the next. The curve through the samples has no corner at
    /// each sample, and its foot moves continuously.
    ///
    /// A deterministic function of `c` and `x`, so the windowed search and the brute force,
    /// which find the same polyline foot, refine it to the same bits. Where Newton's method does
    /// not converge (the tool farther from the path than its radius of curvature, where the
    /// nearest point is not a smooth minimum) or lands implausibly far from the polyline foot,
    /// the polyline foot is kept.
    pub fn refine(&self, c: &Candidate, x: &Vector3<f64>) -> Candidate {
        let nseg = self.segments();
        if nseg == 0 {
            return *c;
        }
        // One start per point of the path: a knot is piece s at 0 (or the last piece at 1).
        let (mut s, mut tau) = if c.t == 1.0 {
            (c.seg + 1, 0.0)
        } else {
            (c.seg, c.t)
        };
        if s >= nseg {
            (s, tau) = (nseg - 1, 1.0);
        }
        if !self.has_length(s) {
            return *c;
        }
        let mut piece = Self::piece_of(&self.p, s);
        let mut moves = 0;
        let mut converged = false;
        for _ in 0..MAX_NEWTON_STEPS {
            let [q, d1, d2] = Self::hermite(&piece, tau);
            let r = q - x;
            let f = r.dot(&d1);
            let fp = d1.norm_squared() + r.dot(&d2);
            if !(fp > 0.0 && f.is_finite()) {
                return *c;
            }
            let mut next = tau - f / fp;
            let mut moved = false;
            if next < 0.0 {
                if s > 0 && moves < MAX_PIECE_MOVES && self.has_length(s - 1) {
                    s -= 1;
                    next = (next + 1.0).clamp(0.0, 1.0);
                    (moves, moved) = (moves + 1, true);
                } else {
                    next = 0.0;
                }
            } else if next > 1.0 {
                if s + 1 < nseg && moves < MAX_PIECE_MOVES && self.has_length(s + 1) {
                    s += 1;
                    next = (next - 1.0).clamp(0.0, 1.0);
                    (moves, moved) = (moves + 1, true);
                } else {
                    next = 1.0;
                }
            }
            let step = (next - tau).abs();
            tau = next;
            if moved {
                piece = Self::piece_of(&self.p, s);
            } else if step <= NEWTON_TOLERANCE {
                converged = true;
                break;
            }
        }
        if !converged {
            return *c;
        }
        let [q, _, _] = Self::hermite(&piece, tau);
        let d2 = (x - q).norm_squared();
        // The curve stays within a fraction of a piece of its chord; a foot farther than one
        // piece from the polyline's is not the nearest point being refined.
        let length = (self.p[s + 1] - self.p[s]).norm();
        if d2.is_nan() || d2.sqrt() > c.d2.sqrt() + length {
            return *c;
        }
        self.candidate(s, tau, q, d2)
    }

    /// The polyline candidate of a foot the brute force found on the raw reference samples
    /// (segment `k` → `k + 1` at fraction `t`), as the windowed search computes it on the
    /// knots: the knot holding sample `k`, or the projection on the piece from it. (The path
    /// parameter alone would not do: near a knot $k + t$ rounds to $k$.)
    pub fn candidate_on_raw(&self, k: usize, t: f64, x: &Vector3<f64>) -> Candidate {
        let s = self.first.partition_point(|f| *f <= k).saturating_sub(1);
        if t > 0.0 && k == self.last[s] && s + 1 < self.p.len() {
            self.eval(s, x)
        } else {
            let q = self.p[s];
            self.candidate(s, 0.0, q, (x - q).norm_squared())
        }
    }

    /// The foot with its reference orientation.
    pub fn foot(&self, c: &Candidate) -> Foot {
        let (oa, ob) = match (self.o.get(c.seg), self.o.get(c.seg + 1)) {
            (Some(a), Some(b)) => (a, b),
            (Some(a), None) => (a, a),
            _ => {
                // Unreachable for a checked path (at least one knot); keep a defined value.
                return Foot {
                    u: c.u,
                    point: c.q,
                    orientation: Vector3::z(),
                };
            }
        };
        Foot {
            u: c.u,
            point: c.q,
            orientation: self
                .orientation_at(c.seg, c.t)
                .unwrap_or_else(|| nlerp(oa, ob, c.t)),
        }
    }

    /// The reference tool axis inside piece `s` at $\tau \in (0, 1)$: the cubic Hermite
    /// interpolant of the knots' tool axes with the same tangents as the tip curve
    /// ([`tangent_of`](Self::tangent_of)), normalised — so a tool axis turning steadily between
    /// samples is followed, not cut short along the great circle. `None` at a knot (the knot's
    /// axis, exactly, is used), for a piece without a successor, or where the interpolant
    /// nearly vanishes (axes nearly opposite).
    fn orientation_at(&self, s: usize, tau: f64) -> Option<Vector3<f64>> {
        if tau <= 0.0 || tau >= 1.0 || s + 1 >= self.o.len() {
            return None;
        }
        let [v, _, _] = Self::hermite(&Self::piece_of(&self.o, s), tau);
        let n = v.norm();
        (n > 1e-6).then(|| v / n)
    }
}

/// Brute-force oracle over the raw reference tips (no merging of rests): the nearest point of
/// every segment $k \to k+1$ with $u = k + t$, the same projection and tie rule as the
/// windowed search; returned as the segment and fraction `(k, t)` (`(0, 0.0)` for a single
/// sample, `None` for none), for [`ReferencePath::candidate_on_raw`].
pub(crate) fn brute_force_segment(tips: &[Vector3<f64>], x: &Vector3<f64>) -> Option<(usize, f64)> {
    if tips.len() == 1 {
        return Some((0, 0.0));
    }
    let mut best: Option<Candidate> = None;
    for (k, w) in tips.windows(2).enumerate() {
        let (t, q, d2) = project(x, &w[0], &w[1]);
        let c = Candidate {
            d2,
            u: k as f64 + t,
            seg: k,
            t,
            q,
        };
        if best.as_ref().is_none_or(|b| c.better_than(b)) {
            best = Some(c);
        }
    }
    best.map(|c| (c.seg, c.t))
}
