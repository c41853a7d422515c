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
use super::{Cycle, Feed, Interp, Motion, MoveKind, PathMode};
use crate::diag::{DiagnosticKind, Span};

/// LinuxCNC `G83_RAPID_DELTA`: how far above the last depth a peck restarts, inches.
const RAPID_DELTA_INCH: f64 = 0.010;

/// The words of one cycle block, sticky values filled in (program units, as written).
struct Words {
    r: f64,
    z: f64,
    repeats: u64,
    p: f64,
    q: f64,
}

/// Where the repeats start (program units): the first point in the plane and the increments
/// before each repeat, R and the depth along the normal, the initial level and the height.
struct Start {
    aa: f64,
    bb: f64,
    aa_inc: f64,
    bb_inc: f64,
    radius_inc: f64,
    angle_inc: f64,
    r: f64,
    z: f64,
    old_cc: f64,
    current_cc: f64,
}

/// Parameters of one cycle, program units.
struct Plan {
    r: f64,
    z: f64,
    clear: f64,
    p: f64,
    q: f64,
}

impl Interp<'_> {
    fn cycle_err(&mut self, span: Span, msg: impl crate::diag::Message) {
        self.err(span, DiagnosticKind::Block, msg);
    }

    /// Run cycle `c`; `prev` is the motion mode before this block.
    pub(super) fn cycle(&mut self, c: Cycle, k: &Checked, span: Span, prev: Option<Motion>) {
        if self.st.inverse_time {
            self.cycle_err(span, "canned cycles cannot run under G93 inverse-time feed");
            return;
        }
        let feed = match self.st.feed {
            Some((mm, _)) if mm > 0.0 => Feed::UnitsPerMin(mm),
            _ => {
                self.cycle_err(span, "canned cycle with no feed rate set (F)");
                return;
            }
        };
        let same = prev == Some(Motion::Cycle(c));
        let Some(words) = self.cycle_words(c, k, span, same) else {
            return;
        };
        let Some(start) = self.cycle_start(k, &words, span) else {
            return;
        };
        self.cycle_repeats(c, start, &words, feed, span);
        self.st.cycle.r = words.r;
        self.st.cycle.z = words.z;
        self.st.cycle.p = words.p;
        self.st.cycle.q = words.q;
    }

    /// R, the depth, L, P and Q of the block, or their sticky values when the cycle continues.
    fn cycle_words(&mut self, c: Cycle, k: &Checked, span: Span, same: bool) -> Option<Words> {
        let (_, _, w) = self.st.plane.axes();
        let normal = ['X', 'Y', 'Z'][w];
        let r = match k.w.get('R') {
            Some((r, _)) => r,
            None if same => self.st.cycle.r,
            None => {
                self.cycle_err(span, "R clearance plane unspecified in the canned cycle");
                return None;
            }
        };
        let z = match k.w.get(normal) {
            Some((z, _)) => z,
            None if same => self.st.cycle.z,
            None => {
                self.cycle_err(span, || {
                    format!("{normal} (the cycle's depth) is unspecified in the canned cycle")
                });
                return None;
            }
        };
        let repeats = match k.w.get('L') {
            None => 1,
            Some((l, _)) if l >= 1.0 && l.fract() == 0.0 && l <= 1e6 => l as u64,
            Some((l, s)) => {
                self.cycle_err(s, || {
                    format!("L{l}: a canned cycle repeats a whole number ≥ 1 of times")
                });
                return None;
            }
        };
        let dwell = matches!(c, Cycle::G82 | Cycle::G89);
        let p = match k.w.get('P') {
            Some((p, s)) if dwell && p < 0.0 => {
                self.cycle_err(s, || format!("dwell time P{p} is negative"));
                return None;
            }
            Some((p, _)) if dwell => p,
            None if dwell && !same => {
                self.cycle_err(span, "the dwell time P is missing in the G82/G89 cycle");
                return None;
            }
            _ => self.st.cycle.p,
        };
        let peck = matches!(c, Cycle::G73 | Cycle::G83);
        let q = match k.w.get('Q') {
            Some((q, s)) if peck && q <= 0.0 => {
                self.cycle_err(s, || format!("peck depth Q{q} must be positive"));
                return None;
            }
            Some((q, _)) if peck => q,
            None if peck && !same => {
                self.cycle_err(span, "the peck depth Q is missing in the G73/G83 cycle");
                return None;
            }
            _ => self.st.cycle.q,
        };
        Some(Words {
            r,
            z,
            repeats,
            p,
            q,
        })
    }

    /// The first point, increments, R and depth (LinuxCNC `convert_cycle_xy`), and the rapid
    /// up to R when the initial level is below it.
    fn cycle_start(&mut self, k: &Checked, words: &Words, span: Span) -> Option<Start> {
        let (u, v, w) = self.st.plane.axes();
        let names = ['X', 'Y', 'Z'];
        let cur = self.program_position_in_units();
        let current_cc = cur[w];
        let old_cc = *self.st.cycle.il.get_or_insert(current_cc);
        let word = |i: usize| k.w.get(names[i]).map(|x| x.0);
        let mut st = Start {
            aa: cur[u],
            bb: cur[v],
            aa_inc: 0.0,
            bb_inc: 0.0,
            radius_inc: 0.0,
            angle_inc: 0.0,
            r: words.r,
            z: words.z,
            old_cc,
            current_cc,
        };
        if self.st.absolute {
            if k.w.letters[AT].is_some() || k.w.letters[CARET].is_some() {
                let radius = k.w.letters[AT].map_or(cur[1].hypot(cur[0]), |x| x.0);
                let theta = k.w.letters[CARET].map_or(cur[1].atan2(cur[0]), |x| x.0.to_radians());
                st.aa = radius * theta.cos();
                st.bb = radius * theta.sin();
            } else {
                st.aa = word(u).unwrap_or(cur[u]);
                st.bb = word(v).unwrap_or(cur[v]);
            }
        } else {
            st.aa_inc = word(u).unwrap_or(0.0);
            st.bb_inc = word(v).unwrap_or(0.0);
            st.radius_inc = k.w.letters[AT].map_or(0.0, |x| x.0);
            st.angle_inc = k.w.letters[CARET].map_or(0.0, |x| x.0.to_radians());
            st.r = words.r + old_cc;
            st.z = st.r + words.z;
        }
        if st.r < st.z {
            let (r, z) = (st.r, st.z);
            self.cycle_err(span, || {
                format!(
                    "the R plane ({r}) is below the cycle's depth {} ({z})",
                    names[w]
                )
            });
            return None;
        }
        if st.old_cc < st.r {
            let feed = Feed::UnitsPerMin(0.0);
            self.cycle_move(cur[u], cur[v], st.r, true, feed, span);
            st.old_cc = st.r;
            st.current_cc = st.r;
        }
        Some(st)
    }

    /// The `L` repeats (LinuxCNC `CYCLE_MACRO`): position in the plane, down to R, the cycle.
    fn cycle_repeats(&mut self, c: Cycle, mut st: Start, words: &Words, feed: Feed, span: Span) {
        let plan = Plan {
            r: st.r,
            z: st.z,
            clear: if self.st.retract_r_plane {
                st.r
            } else {
                st.old_cc
            },
            p: words.p,
            q: words.q,
        };
        let at = |it: &mut Self, a: f64, b: f64, c: f64| it.cycle_move(a, b, c, true, feed, span);
        for rep in (1..=words.repeats).rev() {
            st.aa += st.aa_inc;
            st.bb += st.bb_inc;
            if st.radius_inc != 0.0 || st.angle_inc != 0.0 {
                if st.aa == 0.0 && st.bb == 0.0 {
                    self.err(
                        span,
                        DiagnosticKind::Motion,
                        "incremental polar cycle at the origin: the direction is undefined",
                    );
                    return;
                }
                let radius = st.bb.hypot(st.aa) + st.radius_inc;
                let theta = st.bb.atan2(st.aa) + st.angle_inc;
                st.aa = radius * theta.cos();
                st.bb = radius * theta.sin();
            }
            let (aa, bb) = (st.aa, st.bb);
            if rep == words.repeats && st.current_cc > plan.r {
                at(self, aa, bb, st.current_cc);
                at(self, aa, bb, plan.r);
            } else {
                at(self, aa, bb, plan.clear);
                if plan.clear > plan.r {
                    at(self, aa, bb, plan.r);
                }
            }
            self.cycle_body(c, aa, bb, &plan, feed, span);
        }
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
        // LinuxCNC runs canned cycles in exact-path mode (G61), whatever the mode in force.
        let mode = self.st.path;
        self.st.path = PathMode::ExactPath;
        if rapid {
            self.emit(MoveKind::Rapid, m, span, None);
        } else {
            self.emit(MoveKind::Linear, m, span, Some(feed));
        }
        self.st.path = mode;
    }
}
