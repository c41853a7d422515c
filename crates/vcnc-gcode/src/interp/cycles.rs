//! Canned cycles `G73 G81 G82 G83 G85 G89` expanded into moves as LinuxCNC's interpreter does
//! (`interp_cycles.cc`, `convert_cycle_xy` and its `CYCLE_MACRO`, LinuxCNC 2.9).
//!
//! In the plane's coordinates (`aa`, `bb` in the plane, `cc` along its normal; `G17`: X Y Z,
//! `G18`: Z X Y, `G19`: Y Z X), with the numbers in program units as LinuxCNC computes them:
//!
//! - the *initial level* `il` is the normal coordinate when the first cycle of a series started
//!   (any other motion ends the series);
//! - `G90`: R and Z are absolute; `G91`: `r = il + R`, `z = r + Z`, and X Y are increments
//!   applied before every repeat;
//! - if `il` is below R, one rapid along the normal up to R first;
//! - `clear` is R under `G99` (LinuxCNC's start-up mode) or `il` under `G98`;
//! - each of the `L` repeats: rapid in the plane (at the current height on the first repeat if
//!   it is above R, else at `clear`), rapid down to R, then the cycle:
//!   `G81` feed to z, rapid to clear; `G82` the same with a dwell P at the bottom; `G85` feed to
//!   z, feed back to R, rapid to clear; `G89` feed to z, dwell P, feed to clear; `G83` pecks of
//!   Q: feed one peck deeper, rapid out to R, rapid back to 0.254 mm (0.010 in) above the last
//!   depth, … then feed to z and rapid to clear; `G73` the same but retracting only by 0.254 mm
//!   between pecks.
//!
//! Every move of a cycle carries the cycle block's line; rapids are [`MoveKind::Rapid`], feeds
//! [`MoveKind::Linear`], dwells [`MoveKind::Dwell`]. Moves inside a cycle stop exactly.

use super::block::{AT, CARET, Checked};
use super::{Cycle, Feed, Interp, Motion, MoveKind};
use crate::diag::{DiagnosticKind, Span};

/// LinuxCNC `G83_RAPID_DELTA`: how far above the last depth a peck restarts, inches.
const RAPID_DELTA_INCH: f64 = 0.010;

/// Parameters of one cycle block, program units.
struct Plan {
    r: f64,
    z: f64,
    clear: f64,
    p: f64,
    q: f64,
}

impl Interp<'_> {
    /// Run cycle `c`; `prev` is the motion mode before this block.
    pub(super) fn cycle(&mut self, c: Cycle, k: &Checked, span: Span, prev: Option<Motion>) {
        let err =
            |it: &mut Self, s: Span, msg: &str| it.err(s, DiagnosticKind::Block, msg.to_string());
        if self.st.inverse_time {
            err(
                self,
                span,
                "canned cycles cannot run under G93 inverse-time feed",
            );
            return;
        }
        let feed = match self.st.feed {
            Some((mm, _)) if mm > 0.0 => mm,
            _ => {
                err(self, span, "canned cycle with no feed rate set (F)");
                return;
            }
        };
        let same = prev == Some(Motion::Cycle(c));
        let (u, v, w) = self.st.plane.axes();
        let names = ['X', 'Y', 'Z'];
        let r_word = match k.w.get('R') {
            Some((r, _)) => r,
            None if same => self.st.cycle.r,
            None => {
                err(
                    self,
                    span,
                    "R clearance plane unspecified in the canned cycle",
                );
                return;
            }
        };
        let z_word = match k.w.get(names[w]) {
            Some((z, _)) => z,
            None if same => self.st.cycle.z,
            None => {
                let msg = format!(
                    "{} (the cycle's depth) is unspecified in the canned cycle",
                    names[w]
                );
                self.err(span, DiagnosticKind::Block, msg);
                return;
            }
        };
        let repeats = match k.w.get('L') {
            None => 1,
            Some((l, s)) if l >= 1.0 && l.fract() == 0.0 && l <= 1e6 => {
                let _ = s;
                l as u64
            }
            Some((l, s)) => {
                self.err(s, DiagnosticKind::Block, || {
                    format!("L{l}: a canned cycle repeats a whole number ≥ 1 of times")
                });
                return;
            }
        };
        let p = match (c, k.w.get('P')) {
            (Cycle::G82 | Cycle::G89, Some((p, s))) if p < 0.0 => {
                self.err(s, DiagnosticKind::Block, || {
                    format!("dwell time P{p} is negative")
                });
                return;
            }
            (Cycle::G82 | Cycle::G89, Some((p, _))) => p,
            (Cycle::G82 | Cycle::G89, None) if same => self.st.cycle.p,
            (Cycle::G82 | Cycle::G89, None) => {
                err(
                    self,
                    span,
                    "the dwell time P is missing in the G82/G89 cycle",
                );
                return;
            }
            _ => self.st.cycle.p,
        };
        let q = match (c, k.w.get('Q')) {
            (Cycle::G73 | Cycle::G83, Some((q, s))) if q <= 0.0 => {
                self.err(s, DiagnosticKind::Block, || {
                    format!("peck depth Q{q} must be positive")
                });
                return;
            }
            (Cycle::G73 | Cycle::G83, Some((q, _))) => q,
            (Cycle::G73 | Cycle::G83, None) if same => self.st.cycle.q,
            (Cycle::G73 | Cycle::G83, None) => {
                err(
                    self,
                    span,
                    "the peck depth Q is missing in the G73/G83 cycle",
                );
                return;
            }
            _ => self.st.cycle.q,
        };
        // Program coordinates in program units.
        let cur = self.program_position_in_units();
        let mut current_cc = cur[w];
        let mut old_cc = match self.st.cycle.il {
            Some(il) => il,
            None => {
                self.st.cycle.il = Some(current_cc);
                current_cc
            }
        };
        let word = |i: usize| k.w.get(names[i]).map(|x| x.0);
        let (mut aa, mut bb, aa_inc, bb_inc, r, z);
        let (mut rad_inc, mut ang_inc) = (0.0, 0.0);
        if self.st.absolute {
            r = r_word;
            z = z_word;
            let polar = k.w.letters[AT].or(k.w.letters[CARET]);
            if polar.is_some() {
                let radius = k.w.letters[AT].map_or(cur[1].hypot(cur[0]), |x| x.0);
                let theta = k.w.letters[CARET].map_or(cur[1].atan2(cur[0]), |x| x.0.to_radians());
                aa = radius * theta.cos();
                bb = radius * theta.sin();
            } else {
                aa = word(u).unwrap_or(cur[u]);
                bb = word(v).unwrap_or(cur[v]);
            }
            (aa_inc, bb_inc) = (0.0, 0.0);
        } else {
            aa_inc = word(u).unwrap_or(0.0);
            bb_inc = word(v).unwrap_or(0.0);
            rad_inc = k.w.letters[AT].map_or(0.0, |x| x.0);
            ang_inc = k.w.letters[CARET].map_or(0.0, |x| x.0.to_radians());
            r = r_word + old_cc;
            z = r + z_word;
            aa = cur[u];
            bb = cur[v];
        }
        if r < z {
            self.err(span, DiagnosticKind::Block, || {
                format!(
                    "the R plane ({r}) is below the cycle's depth {} ({z})",
                    names[w]
                )
            });
            return;
        }
        let feed = Feed::UnitsPerMin(feed);
        let at = |it: &mut Self, a: f64, b: f64, c: f64, rapid: bool| {
            it.cycle_move(a, b, c, rapid, feed, span);
        };
        if old_cc < r {
            at(self, cur[u], cur[v], r, true);
            old_cc = r;
            current_cc = old_cc;
        }
        let plan = Plan {
            r,
            z,
            clear: if self.st.retract_r_plane { r } else { old_cc },
            p,
            q,
        };
        for rep in (1..=repeats).rev() {
            aa += aa_inc;
            bb += bb_inc;
            if rad_inc != 0.0 || ang_inc != 0.0 {
                if aa == 0.0 && bb == 0.0 {
                    self.err(
                        span,
                        DiagnosticKind::Motion,
                        "incremental polar cycle at the origin: the direction is undefined",
                    );
                    return;
                }
                let radius = bb.hypot(aa) + rad_inc;
                let theta = bb.atan2(aa) + ang_inc;
                aa = radius * theta.cos();
                bb = radius * theta.sin();
            }
            if rep == repeats && current_cc > plan.r {
                at(self, aa, bb, current_cc, true);
                at(self, aa, bb, plan.r, true);
            } else {
                at(self, aa, bb, plan.clear, true);
                if plan.clear > plan.r {
                    at(self, aa, bb, plan.r, true);
                }
            }
            self.cycle_body(c, aa, bb, &plan, feed, span);
        }
        self.st.cycle.r = r_word;
        self.st.cycle.z = z_word;
        self.st.cycle.p = p;
        self.st.cycle.q = q;
    }

    fn cycle_body(&mut self, c: Cycle, aa: f64, bb: f64, plan: &Plan, feed: Feed, span: Span) {
        let at = |it: &mut Self, depth: f64, rapid: bool| {
            it.cycle_move(aa, bb, depth, rapid, feed, span)
        };
        // 0.010 in, in program units.
        let delta = if self.st.inch {
            RAPID_DELTA_INCH
        } else {
            RAPID_DELTA_INCH * 25.4
        };
        match c {
            Cycle::G81 => {
                at(self, plan.z, false);
                at(self, plan.clear, true);
            }
            Cycle::G82 => {
                at(self, plan.z, false);
                self.cycle_dwell(plan.p, span);
                at(self, plan.clear, true);
            }
            Cycle::G85 => {
                at(self, plan.z, false);
                at(self, plan.r, false);
                at(self, plan.clear, true);
            }
            Cycle::G89 => {
                at(self, plan.z, false);
                self.cycle_dwell(plan.p, span);
                at(self, plan.clear, false);
            }
            Cycle::G73 | Cycle::G83 => {
                let mut depth = plan.r - plan.q;
                while depth > plan.z {
                    at(self, depth, false);
                    if c == Cycle::G83 {
                        at(self, plan.r, true);
                    }
                    at(self, depth + delta, true);
                    depth -= plan.q;
                }
                at(self, plan.z, false);
                at(self, plan.clear, true);
            }
        }
    }

    fn cycle_dwell(&mut self, seconds: f64, span: Span) {
        let pos = self.st.pos;
        self.emit(MoveKind::Dwell { seconds }, pos, span, None);
    }

    /// A move to (`aa`, `bb`, `cc`) of the plane, program units; other axes stay.
    fn cycle_move(&mut self, aa: f64, bb: f64, cc: f64, rapid: bool, feed: Feed, span: Span) {
        let (u, v, w) = self.st.plane.axes();
        let s = self.lscale();
        let cur = self.to_program(self.st.pos);
        let cur_units = self.program_position_in_units();
        let mut p = cur;
        for (i, x) in [(u, aa), (v, bb), (w, cc)] {
            // An unchanged coordinate stays exactly where it is (no unit round trip).
            if x != cur_units[i] {
                p[i] = x * s;
            }
        }
        let m = self.to_machine_from(p, cur);
        let exact = self.st.exact_stop;
        self.st.exact_stop = true;
        if rapid {
            self.emit(MoveKind::Rapid, m, span, None);
        } else {
            self.emit(MoveKind::Linear, m, span, Some(feed));
        }
        self.st.exact_stop = exact;
    }
}
