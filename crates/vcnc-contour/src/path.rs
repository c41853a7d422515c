//! The reference tip path as a polyline (whole, or a window of it that arrives in pieces),
//! segment projection, and the foot-point searches.

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
pub(crate) const MAX_PIECE_MOVES: usize = 4;
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

/// Why a search over the knots held cannot answer (docs/contour.md#streamed-search).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Need {
    /// It reads a knot not pushed yet, or asks whether the path ends at the last knot held
    /// while the reference has not ended: run it again when more reference has arrived.
    More,
    /// It reads knot `knot` (global index), already dropped.
    History {
        /// Global knot index read.
        knot: usize,
    },
}

/// The result of a search over the knots held.
pub(crate) type Reach<T> = std::result::Result<T, Need>;

/// The state a foot search carries from one actual sample to the next; the search of sample
/// `k` is a pure function of it, the pose and the path.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SearchState {
    /// Segment (global knot index) of the previous polyline foot; `None` before the first.
    pub prev: Option<usize>,
    /// Knot cursor of the time hint ([`ReferencePath::segment_of_sample`]).
    pub hint: usize,
    /// Path parameter of the previous foot, reference samples.
    pub prev_u: f64,
    /// Index of the next actual sample.
    pub k: usize,
}

impl SearchState {
    pub fn new() -> Self {
        Self {
            prev: None,
            hint: 0,
            prev_u: f64::NEG_INFINITY,
            k: 0,
        }
    }

    /// The lowest knot a later search starts from (the previous foot's segment, the hint's
    /// cursor); `None` before the first foot, when nothing may be dropped.
    pub fn anchor(&self) -> Option<usize> {
        self.prev.map(|s| s.min(self.hint))
    }
}

/// The reference polyline with runs of identical consecutive poses (a machine at rest) merged
/// into one knot, so that rests cost nothing in the windowed search.
///
/// Held as a window of knots: global knot indices `base .. base + p.len()`, the path possibly
/// continuing after them (`ended` false: a streamed reference) — docs/contour.md#streamed-search.
/// A whole path is the window with everything held (`base` 0, `ended`). Every read of the
/// searches goes through [`local`](Self::local) or [`exists`](Self::exists), which answer
/// [`Need`] where the window cannot: a search that answers reads exactly what it would read on
/// the whole path, and gives the same bits.
#[derive(Debug, Clone)]
pub(crate) struct ReferencePath {
    /// Knot tip positions, mm.
    p: Vec<Vector3<f64>>,
    /// Knot unit tool axes.
    o: Vec<Vector3<f64>>,
    /// Index of the first reference sample of each knot's run.
    first: Vec<usize>,
    /// Index of the last reference sample of each knot's run (of the last knot held, final
    /// only once the path has ended or another knot has arrived).
    last: Vec<usize>,
    /// Global index of the first knot held (knots dropped before it).
    base: usize,
    /// Whether the path ends at the last knot held.
    ended: bool,
    /// Reference samples pushed.
    samples: usize,
}

impl ReferencePath {
    /// The whole path of the poses given (ended).
    pub fn new(reference: impl IntoIterator<Item = Pose>) -> Result<Self> {
        let reference = reference.into_iter();
        let mut path = Self::open(reference.size_hint().0);
        for pose in reference {
            path.push(&pose)?;
        }
        path.ended = true;
        if path.p.is_empty() {
            return Err(Error::Empty(Sequence::Reference));
        }
        Ok(path)
    }

    /// An empty path that continues (a streamed reference).
    pub fn open(capacity: usize) -> Self {
        ReferencePath {
            p: Vec::with_capacity(capacity),
            o: Vec::with_capacity(capacity),
            first: Vec::with_capacity(capacity),
            last: Vec::with_capacity(capacity),
            base: 0,
            ended: false,
            samples: 0,
        }
    }

    /// Appends the next reference sample (checked, naming its whole-run index); returns
    /// whether it made a new knot (else it extended the last knot's run).
    #[inline]
    pub fn push(&mut self, pose: &Pose) -> Result<bool> {
        let k = self.samples;
        let (p, o) = checked(pose, Sequence::Reference, k)?;
        self.samples += 1;
        match (self.p.last(), self.o.last(), self.last.last_mut()) {
            (Some(lp), Some(lo), Some(last)) if *lp == p && *lo == o => {
                *last = k;
                Ok(false)
            }
            _ => {
                self.p.push(p);
                self.o.push(o);
                self.first.push(k);
                self.last.push(k);
                Ok(true)
            }
        }
    }

    /// No more reference: the path ends at the last knot held.
    pub fn end(&mut self) {
        self.ended = true;
    }

    /// Whether the path has ended.
    pub fn ended(&self) -> bool {
        self.ended
    }

    /// Reference samples pushed.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Knots held.
    pub fn held(&self) -> usize {
        self.p.len()
    }

    /// Global index of the first knot held.
    pub fn base(&self) -> usize {
        self.base
    }

    /// One past the global index of the last knot held.
    #[inline]
    fn end_held(&self) -> usize {
        self.base + self.p.len()
    }

    /// Drops the knots before global index `to` (at most up to the last knot held).
    pub fn drop_before(&mut self, to: usize) {
        let d = to
            .saturating_sub(self.base)
            .min(self.p.len().saturating_sub(1));
        if d > 0 {
            self.p.drain(..d);
            self.o.drain(..d);
            self.first.drain(..d);
            self.last.drain(..d);
            self.base += d;
        }
    }

    /// Whether knot `g` (global index) exists: `More` when it is the first knot after the
    /// ones held and the path has not ended.
    #[inline]
    fn exists(&self, g: usize) -> Reach<bool> {
        if g < self.end_held() {
            Ok(true)
        } else if self.ended {
            Ok(false)
        } else {
            Err(Need::More)
        }
    }

    /// The storage index of knot `g` (global), which must be held: `History` before the
    /// first held, `More` after the last (on an ended path, a read past its end: a bug, which
    /// the callers report as an internal error).
    #[inline]
    fn local(&self, g: usize) -> Reach<usize> {
        if g < self.base {
            Err(Need::History { knot: g })
        } else if g < self.end_held() {
            Ok(g - self.base)
        } else {
            Err(Need::More)
        }
    }

    /// The last reference sample of knot `g`'s run, once it is final (another knot held after
    /// it, or the path ended).
    #[inline]
    fn last_of(&self, g: usize) -> Reach<usize> {
        let i = self.local(g)?;
        if i + 1 < self.p.len() || self.ended {
            Ok(self.last[i])
        } else {
            Err(Need::More)
        }
    }

    /// The segment that starts at the knot holding reference sample `k` (the last segment for a
    /// `k` past the end), with `cursor` a knot index no greater than the answer, advanced in
    /// place: calls with increasing `k` cost O(1) each on average.
    pub fn segment_of_sample(&self, k: usize, cursor: &mut usize) -> Reach<usize> {
        while self.exists(*cursor + 1)? && self.last_of(*cursor)? < k {
            *cursor += 1;
        }
        // The last segment for a cursor on the last knot (0 on a single-knot path).
        Ok(if self.exists(*cursor + 1)? {
            *cursor
        } else {
            cursor.saturating_sub(1)
        })
    }

    /// Projection on segment `s` (knot `s` → knot `s + 1`, both held), in reference-sample
    /// parameter: $u = \text{last}_s + t$, or the first sample of the knot's run when $t = 0$.
    #[inline]
    fn eval(&self, s: usize, x: &Vector3<f64>) -> Candidate {
        let i = s - self.base;
        let (t, q, d2) = project(x, &self.p[i], &self.p[i + 1]);
        self.candidate_at(i, t, q, d2)
    }

    /// The candidate at fraction `t` of piece `s` (point `q`, squared distance `d2`), with its
    /// path parameter: $u = \text{last}_s + t$, or the first sample of the knot's run when
    /// $t = 0$. Knot `s + 1` must be held (so that `last_s` is final).
    #[inline]
    fn candidate(&self, s: usize, t: f64, q: Vector3<f64>, d2: f64) -> Candidate {
        self.candidate_at(s - self.base, t, q, d2)
    }

    /// [`candidate`](Self::candidate) by storage index `i`.
    #[inline]
    fn candidate_at(&self, i: usize, t: f64, q: Vector3<f64>, d2: f64) -> Candidate {
        let u = if t == 0.0 {
            self.first[i] as f64
        } else {
            self.last[i] as f64 + t
        };
        Candidate {
            d2,
            u,
            seg: i + self.base,
            t,
            q,
        }
    }

    /// The single-knot path: the foot is the knot (`None` when there is a segment).
    fn only_knot(&self, x: &Vector3<f64>) -> Reach<Option<Candidate>> {
        if self.exists(1)? {
            return Ok(None);
        }
        let q = self.p[self.local(0)?];
        Ok(Some(self.candidate(0, 0.0, q, (x - q).norm_squared())))
    }

    /// The first actual sample's foot: the global nearest point over the polyline through the
    /// reference samples `0 .. first_window` (the knots whose run starts there; the whole path
    /// when it ends sooner), O(segments). A tip exactly on the first knot is answered at once:
    /// $u^* = 0$ (nothing is closer than 0, and ties go to the smaller $u$), the candidate the
    /// global search would return, counted as one projection.
    pub fn nearest_first(
        &self,
        x: &Vector3<f64>,
        first_window: usize,
        evals: &mut u64,
    ) -> Reach<Candidate> {
        let i0 = self.local(0)?;
        if *x == self.p[i0] {
            // The projection on segment 0 (or the knot alone) of a point on its start: t = 0,
            // the point p_0, distance 0, u = first_0 = 0.
            let q = self.p[i0];
            *evals += 1;
            return Ok(self.candidate(0, 0.0, q, (x - q).norm_squared()));
        }
        if let Some(c) = self.only_knot(x)? {
            *evals += 1;
            return Ok(c);
        }
        // Knots 0 .. n of the prefix: those whose run starts before `first_window`, known once
        // a knot starting at or after it is held, or the path has ended.
        let n = if self.ended && self.samples <= first_window {
            self.end_held()
        } else {
            match self.first.iter().position(|&f| f >= first_window) {
                Some(i) => (i + self.base).max(1),
                None if self.ended => self.end_held(),
                None => return Err(Need::More),
            }
        };
        if n == 1 {
            let q = self.p[i0];
            *evals += 1;
            return Ok(self.candidate(0, 0.0, q, (x - q).norm_squared()));
        }
        let mut best = self.eval(0, x);
        for s in 1..n - 1 {
            let c = self.eval(s, x);
            if c.better_than(&best) {
                best = c;
            }
        }
        *evals += (n - 1) as u64;
        Ok(best)
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
    ) -> Reach<Candidate> {
        if let Some(c) = self.only_knot(x)? {
            *evals += 1;
            return Ok(c);
        }
        // Segments with both knots held: global 0 .. nseg (the path's segments if it ended).
        let nseg = self.end_held() - 1;
        let prev = prev.min(nseg - 1);
        let lo0 = prev.saturating_sub(win.min_margin);
        let mut lo = lo0;
        if lo < self.base {
            return Err(Need::History { knot: lo });
        }
        let mut hi = prev + win.min_margin;
        if hi > nseg - 1 {
            if !self.ended {
                return Err(Need::More);
            }
            hi = nseg - 1;
        }
        let mut best = self.eval(lo, x);
        for s in lo + 1..=hi {
            let c = self.eval(s, x);
            if c.better_than(&best) {
                best = c;
            }
        }
        *evals += (hi - lo + 1) as u64;
        let base = self.base;
        loop {
            let reach = win.reach_factor * best.d2.sqrt() + win.reach_mm;
            let reach2 = reach * reach;
            let mut grew = false;
            if lo > 0
                && (best.seg - lo < win.min_margin
                    || (x - self.p[lo - base]).norm_squared() <= reach2)
            {
                if lo == base {
                    return Err(Need::History { knot: lo - 1 });
                }
                lo -= 1;
                let c = self.eval(lo, x);
                *evals += 1;
                if c.better_than(&best) {
                    best = c;
                }
                grew = true;
            }
            // Knot hi + 1 is held; segment hi + 1 exists if knot hi + 2 does.
            let wants = |best: &Candidate| {
                hi - best.seg < win.min_margin
                    || (x - self.p[hi + 1 - base]).norm_squared() <= reach2
            };
            let grow_hi = if hi + 1 < nseg {
                wants(&best)
            } else if self.ended || !wants(&best) {
                false
            } else {
                return Err(Need::More);
            };
            if grow_hi {
                hi += 1;
                let c = self.eval(hi, x);
                *evals += 1;
                if c.better_than(&best) {
                    best = c;
                }
                grew = true;
            }
            if !grew {
                return Ok(best);
            }
        }
    }

    /// The foot of the next actual sample (tip `x`), written to `foot`, and the state moved
    /// on: the first sample by [`nearest_first`](Self::nearest_first), every later one in a
    /// window around the previous foot plus the time hint (see `ContourSearch::push`), then
    /// refined onto the curve. `state`, `evals` and `foot` change only when it answers, so a
    /// search that needs more reference is run again from the same state. (The foot is
    /// written in place rather than returned in the `Result`: measured faster.)
    pub fn step(
        &self,
        state: &mut SearchState,
        x: &Vector3<f64>,
        win: &SearchWindow,
        first_window: usize,
        evals: &mut u64,
        foot: &mut Foot,
    ) -> Reach<()> {
        let mut st = *state;
        let mut ev = 0u64;
        let c = match st.prev {
            None => self.nearest_first(x, first_window, &mut ev)?,
            Some(s) => {
                let a = self.nearest_windowed(x, s, win, &mut ev)?;
                let h = self.segment_of_sample(st.k, &mut st.hint)?;
                let far = h.abs_diff(a.seg) > 2 * win.min_margin;
                if far
                    && (a.u < st.prev_u || {
                        ev += 1;
                        self.eval(h, x).better_than(&a)
                    })
                {
                    let b = self.nearest_windowed(x, h, win, &mut ev)?;
                    if b.better_than(&a) { b } else { a }
                } else {
                    a
                }
            }
        };
        st.prev_u = c.u;
        st.prev = Some(c.seg);
        // The search moves on along the polyline; what is reported is the foot on the curve.
        let on_curve = self.refine(&c, x)?;
        *foot = self.foot(&on_curve)?;
        st.k += 1;
        *state = st;
        *evals += ev;
        Ok(())
    }

    /// Tangent at knot `i` of the C¹ curve through the knot values `v` (per knot step): the
    /// central difference $(v_{i+1} - v_{i-1})/2$ inside, the second-order one-sided difference
    /// $\pm(3v_i - 4v_{i\mp1} + v_{i\mp2})/2$ at the two ends (the chord on a two-knot path,
    /// zero on a single knot).
    #[inline]
    fn tangent_of(&self, v: &[Vector3<f64>], i: usize) -> Reach<Vector3<f64>> {
        // Inside the knots held (the usual case): the central difference, read directly.
        if i > self.base && i + 1 < self.end_held() {
            let j = i - self.base;
            return Ok((v[j + 1] - v[j - 1]) * 0.5);
        }
        let at = |g: usize| self.local(g).map(|j| v[j]);
        Ok(if self.exists(i + 1)? {
            if i > 0 {
                (at(i + 1)? - at(i - 1)?) * 0.5
            } else if self.exists(2)? {
                (at(1)? * 4.0 - at(0)? * 3.0 - at(2)?) * 0.5
            } else {
                at(1)? - at(0)?
            }
        } else if i == 0 {
            Vector3::zeros()
        } else if i == 1 {
            at(1)? - at(0)?
        } else {
            (at(i)? * 3.0 - at(i - 1)? * 4.0 + at(i - 2)?) * 0.5
        })
    }

    /// Piece `s` of the C¹ curve through the knot values `v`: its end values and their
    /// [`tangent_of`](Self::tangent_of)s, $(v_s, m_s, v_{s+1}, m_{s+1})$.
    #[inline]
    fn piece_of(&self, v: &[Vector3<f64>], s: usize) -> Reach<[Vector3<f64>; 4]> {
        let mut out = [Vector3::zeros(); 4];
        self.piece_into(v, s, &mut out)?;
        Ok(out)
    }

    /// [`piece_of`](Self::piece_of) written into `out`.
    #[inline(always)]
    fn piece_into(&self, v: &[Vector3<f64>], s: usize, out: &mut [Vector3<f64>; 4]) -> Reach<()> {
        // Both tangents central differences inside the knots held (the usual case).
        if s > self.base && s + 2 < self.end_held() {
            let j = s - self.base;
            *out = [
                v[j],
                (v[j + 1] - v[j - 1]) * 0.5,
                v[j + 1],
                (v[j + 2] - v[j]) * 0.5,
            ];
            return Ok(());
        }
        *out = [
            v[self.local(s)?],
            self.tangent_of(v, s)?,
            v[self.local(s + 1)?],
            self.tangent_of(v, s + 1)?,
        ];
        Ok(())
    }

    /// The cubic Hermite interpolant of a piece `[v0, m0, v1, m1]` ([`piece_of`](Self::piece_of))
    /// at $\tau \in [0, 1]$, with its first and second derivatives in $\tau$: on the knots'
    /// tips, the reference tip curve (Catmull–Rom); on their tool axes, the reference tool axis
    /// before normalisation.
    // Inlined with the piece (measured: the foot_search bench ran 20 % slower when the piece
    // went through memory to a separate function).
    #[inline(always)]
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
    #[inline]
    fn has_length(&self, s: usize) -> Reach<bool> {
        Ok(self.exists(s + 1)?
            && (self.p[self.local(s + 1)?] - self.p[self.local(s)?]).norm_squared()
                > MIN_PIECE_MM.powi(2))
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
    pub fn refine(&self, c: &Candidate, x: &Vector3<f64>) -> Reach<Candidate> {
        if !self.exists(1)? {
            return Ok(*c);
        }
        // One start per point of the path: a knot is piece s at 0 (or the last piece at 1).
        let (mut s, mut tau) = if c.t == 1.0 {
            (c.seg + 1, 0.0)
        } else {
            (c.seg, c.t)
        };
        if !self.exists(s + 1)? {
            // s is the last knot: the end of the last piece.
            (s, tau) = (s - 1, 1.0);
        }
        if !self.has_length(s)? {
            return Ok(*c);
        }
        let mut piece = [Vector3::zeros(); 4];
        self.piece_into(&self.p, s, &mut piece)?;
        let mut moves = 0;
        let mut converged = false;
        for _ in 0..MAX_NEWTON_STEPS {
            let [q, d1, d2] = Self::hermite(&piece, tau);
            let r = q - x;
            let f = r.dot(&d1);
            let fp = d1.norm_squared() + r.dot(&d2);
            if !(fp > 0.0 && f.is_finite()) {
                return Ok(*c);
            }
            let mut next = tau - f / fp;
            let mut moved = false;
            if next < 0.0 {
                if s > 0 && moves < MAX_PIECE_MOVES && self.has_length(s - 1)? {
                    s -= 1;
                    next = (next + 1.0).clamp(0.0, 1.0);
                    (moves, moved) = (moves + 1, true);
                } else {
                    next = 0.0;
                }
            } else if next > 1.0 {
                // Piece s + 1 exists if knot s + 2 does.
                if self.exists(s + 2)? && moves < MAX_PIECE_MOVES && self.has_length(s + 1)? {
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
                self.piece_into(&self.p, s, &mut piece)?;
            } else if step <= NEWTON_TOLERANCE {
                converged = true;
                break;
            }
        }
        if !converged {
            return Ok(*c);
        }
        let [q, _, _] = Self::hermite(&piece, tau);
        let d2 = (x - q).norm_squared();
        // The curve stays within a fraction of a piece of its chord; a foot farther than one
        // piece from the polyline's is not the nearest point being refined.
        let i = self.local(s)?;
        let length = (self.p[i + 1] - self.p[i]).norm();
        if d2.is_nan() || d2.sqrt() > c.d2.sqrt() + length {
            return Ok(*c);
        }
        Ok(self.candidate_at(i, tau, q, d2))
    }

    /// The polyline candidate of a foot the brute force found on the raw reference samples
    /// (segment `k` → `k + 1` at fraction `t`), as the windowed search computes it on the
    /// knots: the knot holding sample `k`, or the projection on the piece from it. (The path
    /// parameter alone would not do: near a knot $k + t$ rounds to $k$.) A whole path only.
    pub fn candidate_on_raw(&self, k: usize, t: f64, x: &Vector3<f64>) -> Candidate {
        let s = self.first.partition_point(|f| *f <= k).saturating_sub(1);
        if t > 0.0 && k == self.last[s] && s + 1 < self.p.len() {
            self.eval(s + self.base, x)
        } else {
            let q = self.p[s];
            self.candidate_at(s, 0.0, q, (x - q).norm_squared())
        }
    }

    /// The foot with its reference orientation.
    #[inline]
    pub fn foot(&self, c: &Candidate) -> Reach<Foot> {
        let oa = self.o[self.local(c.seg)?];
        let ob = if self.exists(c.seg + 1)? {
            self.o[self.local(c.seg + 1)?]
        } else {
            oa
        };
        Ok(Foot {
            u: c.u,
            point: c.q,
            orientation: self
                .orientation_at(c.seg, c.t)?
                .unwrap_or_else(|| nlerp(&oa, &ob, c.t)),
        })
    }

    /// The reference tool axis inside piece `s` at $\tau \in (0, 1)$: the cubic Hermite
    /// interpolant of the knots' tool axes with the same tangents as the tip curve
    /// ([`tangent_of`](Self::tangent_of)), normalised — so a tool axis turning steadily between
    /// samples is followed, not cut short along the great circle. `None` at a knot (the knot's
    /// axis, exactly, is used), for a piece without a successor, or where the interpolant
    /// nearly vanishes (axes nearly opposite).
    #[inline]
    fn orientation_at(&self, s: usize, tau: f64) -> Reach<Option<Vector3<f64>>> {
        if tau <= 0.0 || tau >= 1.0 || !self.exists(s + 1)? {
            return Ok(None);
        }
        let [v, _, _] = Self::hermite(&self.piece_of(&self.o, s)?, tau);
        let n = v.norm();
        Ok((n > 1e-6).then(|| v / n))
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
