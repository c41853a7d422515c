//! The look-ahead of a chain of path elements joined without a stop (docs/gcode.md,
//! "Continuous path"), planned with a bounded look-ahead and sampled as its speeds become final.
//!
//! **Pieces.** The speed is planned over *pieces*: stretches of the chain's path parameter $s$
//! with a speed cap $V$ and an acceleration cap $A$, and a speed cap at their start. Under the
//! trapezoidal profile the pieces are the elements and the cap at a piece's start is the junction
//! speed. Under the jerk-limited profile the planned trapezoid $s(\tau)$ is smoothed by a moving
//! average of length $T_f$ ([`super::segment::Cfg::tf`]):
//! $$ s_f(t) = \frac1{T_f}\int_{t-T_f}^{t} s(\tau)\,d\tau, \qquad
//!    \dot s_f = \frac{\dot s(t) - \dot s(t - T_f)}{T_f}, \quad \dots $$
//! so that $|\dddot s_f| \le 2A/T_f$ and $|\ddot s_f| \le A$. While $s_f$ is in an element, the
//! window has seen the trapezoid only within $V T_f$ of it (at most $V$ for $T_f$ either side),
//! so each element's caps are applied to the trapezoid over its *zone*, the element widened by
//! $V_e T_f$ at both ends, and each junction cap $w$ over $[s_k - wT_f, s_k + wT_f]$: the pieces
//! are where the caps of the zones covering them are constant.
//!
//! **Passes.** A backward pass from an assumed stop after the last piece known, and a forward
//! pass from the chain's start, give each piece its entry and exit speeds; each piece is then a
//! trapezoid between them under its caps. Going backwards, the first piece start whose speed is
//! its own cap (below the speed from which the machine could still stop) is final whatever
//! follows, because later pieces can only raise the reachable speed there; the pieces before it
//! are profiled and handed to the sampler (the bounded look-ahead of docs/performance.md,
//! "Streaming").

use std::collections::VecDeque;

use super::profile::{SCurve, Trap};
use super::segment::Seg;
use crate::interp::Move;

/// A stretch of the speed plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Piece {
    pub(crate) len: f64,
    pub(crate) vcap: f64,
    pub(crate) acap: f64,
    /// Speed cap at the start.
    pub(crate) cap0: f64,
    /// Chain position of the start.
    pub(crate) s0: f64,
}

/// A piece with its final profile and its unscaled start time.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Planned {
    pub(crate) piece: Piece,
    pub(crate) prof: Prof,
    pub(crate) tau0: f64,
}

/// The speed profile of a piece: a trapezoid, or (a block on its own under the jerk-limited
/// profile) the seven-phase profile.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Prof {
    Trap(Trap),
    S(Box<SCurve>),
}

impl Prof {
    pub(crate) fn duration(&self) -> f64 {
        match self {
            Prof::Trap(t) => t.duration(),
            Prof::S(p) => p.duration(),
        }
    }

    /// $(s, \dot s, \ddot s)$ at local time `tau`.
    pub(crate) fn eval(&self, tau: f64) -> (f64, f64, f64) {
        match self {
            Prof::Trap(t) => t.eval(tau),
            Prof::S(p) => {
                let (s, sd, sdd, _) = p.eval(tau);
                (s, sd, sdd)
            }
        }
    }

    /// $\int_0^\tau s$ (trapezoids only; the seven-phase profile is never filtered).
    fn integral(&self, tau: f64) -> f64 {
        match self {
            Prof::Trap(t) => t.integral(tau),
            Prof::S(_) => 0.0,
        }
    }

    /// The local time at which the piece reaches `s` (trapezoids; 0 otherwise).
    fn time_at(&self, s: f64) -> f64 {
        match self {
            Prof::Trap(t) => t.time_at(s),
            Prof::S(_) => 0.0,
        }
    }
}

/// An element of the chain: its curve and caps, where it starts on the chain, and its move.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Elem {
    pub(crate) seg: Seg,
    pub(crate) s0: f64,
    pub(crate) mv: Move,
}

/// A cap over a stretch of the chain (jerk-limited: an element's zone or a junction's).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Zone {
    lo: f64,
    hi: f64,
    v: f64,
    a: f64,
}

/// The speed plan of a chain being built ([module doc](self)).
#[derive(Debug, Clone)]
pub(crate) struct Plan {
    /// Moving-average time $T_f$, s (0: trapezoidal).
    tf: f64,
    /// Bound of the path speed (zones reach this far times $T_f$ past what is known).
    vbound: f64,
    /// Chain length so far.
    pub(crate) total: f64,
    /// Jerk-limited: zones not yet swept past.
    zones: Vec<Zone>,
    /// Jerk-limited: pieces exist up to here.
    swept: f64,
    /// Pieces not yet final.
    pend: VecDeque<Piece>,
    /// Forward-pass speed at the start of `pend[0]`.
    vf: f64,
    /// Unscaled time of the final pieces so far.
    pub(crate) t: f64,
    /// Scan the look-ahead when it holds this many pieces.
    scan_at: usize,
    /// Pieces made final and not yet taken.
    pub(crate) done: VecDeque<Planned>,
    /// Elements so far.
    pub(crate) elems: usize,
    /// Jerk-limited: speed cap of the last piece made, acceleration cap of the last element.
    last_vcap: f64,
    last_acap: f64,
}

impl Plan {
    pub(crate) fn new(tf: f64, vbound: f64) -> Plan {
        Plan {
            tf,
            vbound,
            total: 0.0,
            zones: Vec::new(),
            swept: 0.0,
            pend: VecDeque::new(),
            vf: 0.0,
            t: 0.0,
            scan_at: 64,
            done: VecDeque::new(),
            elems: 0,
            last_vcap: 0.0,
            last_acap: f64::INFINITY,
        }
    }

    /// Pieces not yet final.
    pub(crate) fn pending(&self) -> usize {
        self.pend.len()
    }

    /// Add an element with the junction speed cap `w` at its start (ignored for the first);
    /// under the jerk-limited profile the junction's zone keeps the share `keep` of the
    /// acceleration caps around it.
    pub(crate) fn push(&mut self, seg: &Seg, w: f64, keep: f64) {
        let s0 = self.total;
        self.total += seg.len;
        let first = self.elems == 0;
        self.elems += 1;
        if self.tf == 0.0 {
            self.pend.push_back(Piece {
                len: seg.len,
                vcap: seg.vcap,
                acap: seg.acap,
                cap0: if first { 0.0 } else { w },
                s0,
            });
        } else {
            let ext = seg.vcap * self.tf;
            self.zones.push(Zone {
                lo: s0 - ext,
                hi: self.total + ext,
                v: seg.vcap,
                a: seg.acap,
            });
            if !first {
                let ext = w * self.tf;
                self.zones.push(Zone {
                    lo: s0 - ext,
                    hi: s0 + ext,
                    v: w,
                    a: keep * self.last_acap.min(seg.acap),
                });
            }
            self.last_acap = seg.acap;
            // Later elements start at or after the chain's end, so no later zone reaches back
            // before this.
            let upto = self.total - self.vbound * self.tf;
            self.sweep(upto);
        }
        if self.pend.len() >= self.scan_at {
            self.scan();
            self.scan_at = self.pend.len() + self.pend.len().max(64);
        }
    }

    /// Jerk-limited: make the pieces of `[swept, upto]`.
    fn sweep(&mut self, upto: f64) {
        let upto = upto.min(self.total);
        if upto <= self.swept {
            return;
        }
        let mut cuts: Vec<f64> = vec![self.swept, upto];
        for z in &self.zones {
            for x in [z.lo, z.hi] {
                if x > self.swept && x < upto {
                    cuts.push(x);
                }
            }
        }
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        for w in cuts.windows(2) {
            let (a, b) = (w[0], w[1]);
            if b - a <= 1e-12 * self.total.max(1.0) {
                continue;
            }
            let mid = 0.5 * (a + b);
            let (mut v, mut acc) = (f64::INFINITY, f64::INFINITY);
            for z in &self.zones {
                if z.lo <= mid && mid <= z.hi {
                    v = v.min(z.v);
                    acc = acc.min(z.a);
                }
            }
            let cap0 = match self.pend.back() {
                _ if a == 0.0 => 0.0,
                Some(p) => p.vcap.min(v),
                None => v.min(self.last_vcap),
            };
            self.pend.push_back(Piece {
                len: b - a,
                vcap: v,
                acap: acc,
                cap0,
                s0: a,
            });
            self.last_vcap = v;
        }
        self.swept = upto;
        let swept = self.swept;
        self.zones.retain(|z| z.hi > swept);
    }

    /// The last junction whose speed is its own cap, looking back from a stop after the newest
    /// piece, and everything before it made final ([module doc](self)).
    fn scan(&mut self) {
        let mut w = 0.0f64;
        let mut found = None;
        for k in (1..self.pend.len()).rev() {
            let p = &self.pend[k];
            let reach = (w * w + 2.0 * p.acap * p.len).sqrt();
            if p.cap0 <= reach {
                found = Some(k);
                break;
            }
            w = reach;
        }
        if let Some(k) = found {
            let cap = self.pend[k].cap0;
            self.finalise(k, cap);
        }
    }

    /// Profile `pend[..k]`: the backward pass from the start of `pend[k]`, whose speed is
    /// `end_speed`, then the forward pass.
    fn finalise(&mut self, k: usize, end_speed: f64) {
        let mut wb = vec![0.0f64; k + 1];
        wb[k] = end_speed;
        for kk in (1..k).rev() {
            let p = &self.pend[kk];
            let reach = (wb[kk + 1] * wb[kk + 1] + 2.0 * p.acap * p.len).sqrt();
            wb[kk] = p.cap0.min(reach);
        }
        for exit_b in wb.iter().skip(1) {
            let Some(p) = self.pend.pop_front() else {
                break;
            };
            let reach = (self.vf * self.vf + 2.0 * p.acap * p.len).sqrt();
            let exit = exit_b.min(reach);
            let trap = Trap::new(p.len, self.vf, exit, p.vcap, p.acap);
            let tau0 = self.t;
            self.t += trap.duration();
            self.vf = exit;
            self.done.push_back(Planned {
                piece: p,
                prof: Prof::Trap(trap),
                tau0,
            });
        }
    }

    /// The chain has ended: everything is final, at rest after the last piece.
    pub(crate) fn finish(&mut self) {
        if self.tf != 0.0 {
            let total = self.total;
            self.sweep(total);
        }
        let k = self.pend.len();
        self.finalise(k, 0.0);
    }
}

/// Where samples and spans go (the stream's chunks, or the whole trajectory).
pub(crate) trait Out {
    /// The span of move `index`: samples `first..end`, times `t0..t1` (s). A span of the same
    /// move as the previous one extends it.
    fn span(&mut self, first: usize, end: usize, t0: f64, t1: f64, index: usize, mv: &Move);
    /// The next sample.
    fn sample(&mut self, p: &[f64; 6], v: &[f64; 6], a: &[f64; 6], tcp: bool);
    /// The output has failed (the planner stops).
    fn failed(&self) -> bool;
}

/// Writes the sample where TCP mode switches off as the TCP move's last sample. The machine
/// rests there (docs/gcode.md, "Path modes": it stops where TCP mode changes), on the end point
/// of the TCP move, whose X Y Z are tool-tip coordinates reached under the tool-tip limits. The
/// next move would write that sample as its first one, with its own flag (off) and its starting
/// acceleration (under the axis limits); instead it is written as the last sample of a program
/// ending in TCP mode is (`Planner::final_sample`): on the point, TCP, velocity and acceleration
/// 0. The switch on needs nothing: its rest sample opens the TCP move, which writes it.
pub(crate) struct TcpSwitch<'o> {
    out: &'o mut dyn Out,
    /// The flag the previous sample was given by its move.
    prev_tcp: bool,
}

impl<'o> TcpSwitch<'o> {
    pub(crate) fn new(out: &'o mut dyn Out) -> TcpSwitch<'o> {
        TcpSwitch {
            out,
            prev_tcp: false,
        }
    }
}

impl Out for TcpSwitch<'_> {
    fn span(&mut self, first: usize, end: usize, t0: f64, t1: f64, index: usize, mv: &Move) {
        self.out.span(first, end, t0, t1, index, mv);
    }

    fn sample(&mut self, p: &[f64; 6], v: &[f64; 6], a: &[f64; 6], tcp: bool) {
        let switch_off = self.prev_tcp && !tcp;
        self.prev_tcp = tcp;
        if switch_off {
            self.out.sample(p, &[0.0; 6], &[0.0; 6], true);
        } else {
            self.out.sample(p, v, a, tcp);
        }
    }

    fn failed(&self) -> bool {
        self.out.failed()
    }
}

/// Samples a planned chain (or a block on its own) as its pieces become final.
#[derive(Debug, Clone)]
pub(crate) struct Sampler {
    /// Samples of the chain and its time scale λ (t = λτ).
    n: u64,
    lam: f64,
    /// Moving-average time, s (0: none).
    tf: f64,
    /// First sample of the chain in the trajectory, and its time (s).
    base: u64,
    t_base: f64,
    tcp: bool,
    /// Final pieces not yet passed, and the chain index of `win[0]`.
    win: VecDeque<Planned>,
    win_offset: usize,
    /// Elements not yet passed, and the chain index of `elems[0]`.
    elems: VecDeque<Elem>,
    elem_offset: usize,
    /// Elements whose span is out, the end of the last span (in the chain's samples) and its
    /// end time (in the chain's time).
    spans_done: usize,
    span_end: u64,
    prev_t_end: f64,
    /// Elements in the chain, once known.
    elems_total: Option<usize>,
    /// Every piece is final.
    complete: bool,
    /// Unscaled end time and chain position of the final pieces so far.
    planned_t: f64,
    planned_s: f64,
    /// Next sample.
    j: u64,
    /// Index in `win` of the piece, and in `elems` of the element, of the last sample.
    cur: usize,
    cur_elem: usize,
}

impl Sampler {
    pub(crate) fn new(n: u64, lam: f64, tf: f64, base: u64, ts: f64, tcp: bool) -> Sampler {
        Sampler {
            n,
            lam,
            tf,
            base,
            t_base: base as f64 * ts,
            tcp,
            win: VecDeque::new(),
            win_offset: 0,
            elems: VecDeque::new(),
            elem_offset: 0,
            spans_done: 0,
            span_end: 0,
            prev_t_end: 0.0,
            elems_total: None,
            complete: false,
            planned_t: 0.0,
            planned_s: 0.0,
            j: 0,
            cur: 0,
            cur_elem: 0,
        }
    }

    pub(crate) fn add_elem(&mut self, e: Elem) {
        self.elems.push_back(e);
    }

    pub(crate) fn add_planned(&mut self, p: Planned) {
        self.planned_t = p.tau0 + p.prof.duration();
        self.planned_s = p.piece.s0 + p.piece.len;
        self.win.push_back(p);
    }

    /// Take a plan's newly final pieces.
    pub(crate) fn take(&mut self, plan: &mut Plan) {
        while let Some(p) = plan.done.pop_front() {
            self.add_planned(p);
        }
    }

    /// No piece or element follows.
    pub(crate) fn end(&mut self) {
        self.complete = true;
        self.elems_total = Some(self.elem_offset + self.elems.len());
    }

    /// The end time of element `c` (chain index) in the chain's scaled time, if known.
    fn elem_end_time(&self, c: usize, ts: f64) -> Option<f64> {
        if self.elems_total == Some(c + 1) {
            return Some(self.n as f64 * ts);
        }
        let e = self.elems.get(c.checked_sub(self.elem_offset)?)?;
        if self.tf == 0.0 {
            // One piece per element.
            let p = self.win.get(c.checked_sub(self.win_offset)?)?;
            return Some(self.lam * (p.tau0 + p.prof.duration()));
        }
        let s = e.s0 + e.seg.len;
        if !(self.complete || s < self.planned_s) {
            return None;
        }
        let i = self.win.iter().rposition(|p| p.piece.s0 <= s).unwrap_or(0);
        let p = self.win.get(i)?;
        let tau = p.tau0 + p.prof.time_at(s - p.piece.s0);
        // The moving average delays the position by half its length.
        Some(self.lam * tau + 0.5 * self.tf)
    }

    /// Emit the spans that are known: samples $k$ with $t_\text{start} < t_k \le t_\text{end}$
    /// belong to an element (`BlockSpan::first_sample`), the first element from the chain's
    /// start, the last to its end.
    fn spans(&mut self, out: &mut dyn Out, ts: f64) {
        let n = self.n as usize;
        let last_in = |t_rel: f64| ((t_rel / ts + 1e-9).floor().max(0.0) as usize).min(n);
        loop {
            let c = self.spans_done;
            let Some(e) = c
                .checked_sub(self.elem_offset)
                .and_then(|i| self.elems.get(i))
            else {
                return;
            };
            let last = self.elems_total == Some(c + 1);
            // Until the chain's end is known, the newest element may still be the last.
            if self.elems_total.is_none() && c + 1 >= self.elem_offset + self.elems.len() {
                return;
            }
            let Some(t_end) = self.elem_end_time(c, ts) else {
                return;
            };
            let t_start = if c == 0 { 0.0 } else { self.prev_t_end };
            let k_first = if c == 0 { 0 } else { last_in(t_start) };
            let k_end = if last { n } else { last_in(t_end) }.max(k_first);
            let base = self.base as usize;
            out.span(
                base + k_first + 1,
                base + k_end + 1,
                self.t_base + t_start,
                self.t_base + t_end,
                e.seg.move_index,
                &e.mv,
            );
            self.span_end = k_end as u64 + 1;
            self.prev_t_end = t_end;
            self.spans_done += 1;
        }
    }

    /// Position, velocity and acceleration at sample `j`, or `None` until the pieces it needs
    /// are final.
    fn state(&mut self, j: u64, ts: f64) -> Option<([f64; 6], [f64; 6], [f64; 6])> {
        let lam = self.lam;
        let (inv, inv2) = (1.0 / lam, 1.0 / (lam * lam));
        if self.tf == 0.0 {
            let tau = j as f64 * ts * inv;
            while self.cur + 1 < self.win.len() && tau >= self.win[self.cur + 1].tau0 {
                self.cur += 1;
            }
            if self.cur + 1 >= self.win.len() && !self.complete {
                return None;
            }
            let p = &self.win[self.cur];
            let e = &self.elems[self.win_offset + self.cur - self.elem_offset];
            let (s, sd, sdd) = p.prof.eval(tau - p.tau0);
            return Some(eval_scaled(&e.seg, s, sd, sdd, inv, inv2));
        }
        let t = j as f64 * ts;
        let (lead, lag) = (t * inv, (t - self.tf) * inv);
        if !self.complete && lead >= self.planned_t {
            return None;
        }
        let (s1, v1, _) = self.unfiltered(lead);
        let (s0, v0, _) = self.unfiltered(lag);
        let sf = lam * self.integral(lag.max(0.0), lead) / self.tf;
        let sd = (s1 - s0) / self.tf;
        let sdd = (v1 - v0) * inv / self.tf;
        while self.cur_elem + 1 < self.elems.len() && sf > self.elems[self.cur_elem + 1].s0 {
            self.cur_elem += 1;
        }
        let e = &self.elems[self.cur_elem];
        let (p, g1, g2) = e.seg.geom.eval(sf - e.s0, e.seg.len);
        let v = std::array::from_fn(|i| g1[i] * sd);
        let a = std::array::from_fn(|i| g2[i] * sd * sd + g1[i] * sdd);
        Some((p, v, a))
    }

    /// $(s, \dot s, \ddot s)$ of the unscaled trapezoid at `tau` (at rest before the start and
    /// after the end).
    fn unfiltered(&self, tau: f64) -> (f64, f64, f64) {
        if tau <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let Some(last) = self.win.back() else {
            return (0.0, 0.0, 0.0);
        };
        if tau >= self.planned_t {
            return (last.piece.s0 + last.piece.len, 0.0, 0.0);
        }
        let i = self.win.iter().rposition(|p| p.tau0 <= tau).unwrap_or(0);
        let p = &self.win[i];
        let (s, sd, sdd) = p.prof.eval(tau - p.tau0);
        (p.piece.s0 + s, sd, sdd)
    }

    /// $\int_a^b s\,d\tau$ over the final pieces (s held at the chain's end after the last).
    fn integral(&self, a: f64, b: f64) -> f64 {
        let mut acc = 0.0;
        for p in &self.win {
            let (t0, t1) = (p.tau0, p.tau0 + p.prof.duration());
            let (lo, hi) = (a.max(t0), b.min(t1));
            if hi > lo {
                acc += p.piece.s0 * (hi - lo) + p.prof.integral(hi - t0) - p.prof.integral(lo - t0);
            }
        }
        if let Some(last) = self.win.back()
            && b > self.planned_t
        {
            acc += (last.piece.s0 + last.piece.len) * (b - a.max(self.planned_t));
        }
        acc
    }

    /// Emit every span and sample the final pieces decide.
    pub(crate) fn pump(&mut self, out: &mut dyn Out, ts: f64) {
        self.spans(out, ts);
        while self.j < self.n && self.j < self.span_end {
            let Some((p, v, a)) = self.state(self.j, ts) else {
                break;
            };
            out.sample(&p, &v, &a, self.tcp);
            self.j += 1;
        }
        // Drop what no later sample or span needs.
        if self.tf == 0.0 {
            let keep = (self.win_offset + self.cur).min(self.spans_done);
            while self.win_offset < keep {
                self.win.pop_front();
                self.cur -= 1;
                self.win_offset += 1;
            }
        } else {
            let lag = (self.j as f64 * ts - self.tf) / self.lam;
            while self.win.len() > 1 && self.win[0].tau0 + self.win[0].prof.duration() < lag {
                self.win.pop_front();
                self.win_offset += 1;
            }
            let keep = (self.elem_offset + self.cur_elem).min(self.spans_done);
            while self.elem_offset < keep {
                self.elems.pop_front();
                self.cur_elem -= 1;
                self.elem_offset += 1;
            }
            return;
        }
        while self.elem_offset < self.win_offset.min(self.spans_done) {
            self.elems.pop_front();
            self.elem_offset += 1;
        }
    }
}

/// Position, velocity and acceleration at path position `s` of an element with path speed and
/// acceleration `sd`, `sdd` (unscaled), the time scale applied ($\dot s / \lambda$,
/// $\ddot s / \lambda^2$ with `inv` = 1/λ, `inv2` = 1/λ²).
pub(crate) fn eval_scaled(
    seg: &Seg,
    s: f64,
    sd: f64,
    sdd: f64,
    inv: f64,
    inv2: f64,
) -> ([f64; 6], [f64; 6], [f64; 6]) {
    let (sd, sdd) = (sd * inv, sdd * inv2);
    let (p, g1, g2) = seg.geom.eval(s, seg.len);
    let mut v = [0.0; 6];
    let mut a = [0.0; 6];
    for i in 0..6 {
        v[i] = g1[i] * sd;
        a[i] = g2[i] * sd * sd + g1[i] * sdd;
    }
    (p, v, a)
}
