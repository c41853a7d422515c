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
            Some(Candidate {
                d2: (x - q).norm_squared(),
                u: 0.0,
                seg: 0,
                t: 0.0,
                q,
            })
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
            orientation: nlerp(oa, ob, c.t),
        }
    }
}

/// Brute-force oracle over the raw reference samples (no merging of rests): every segment
/// $k \to k+1$ with $u = k + t$, the same projection, interpolation and tie rule.
pub(crate) fn brute_force_foot(
    reference: &[(Vector3<f64>, Vector3<f64>)],
    x: &Vector3<f64>,
) -> Option<Foot> {
    let (p0, o0) = reference.first()?;
    if reference.len() == 1 {
        return Some(Foot {
            u: 0.0,
            point: *p0,
            orientation: *o0,
        });
    }
    let mut best: Option<(Candidate, usize)> = None;
    for (k, w) in reference.windows(2).enumerate() {
        let [(pa, _), (pb, _)] = w else { continue };
        let (t, q, d2) = project(x, pa, pb);
        let c = Candidate {
            d2,
            u: k as f64 + t,
            seg: k,
            t,
            q,
        };
        if best.as_ref().is_none_or(|(b, _)| c.better_than(b)) {
            best = Some((c, k));
        }
    }
    let (c, k) = best?;
    let (oa, ob) = (&reference.get(k)?.1, &reference.get(k + 1)?.1);
    Some(Foot {
        u: c.u,
        point: c.q,
        orientation: nlerp(oa, ob, c.t),
    })
}
