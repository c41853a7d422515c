//! Cutter radius compensation (`G40`, `G41`, `G41.1`, `G42`, `G42.1`) with LinuxCNC 2.9's
//! semantics (LinuxCNC documentation, "G-Codes", sections G40 and G41/G42/G41.1/G42.1, and its
//! interpreter `interp_convert.cc`/`interp_queue.cc`), in the XY (`G17`) and XZ (`G18`) planes.
//!
//! **Geometry.** With compensation on, the tool centre runs at distance $r$ (the tool radius)
//! from the programmed path, on the left (`G41`) or right (`G42`) of the direction of travel.
//! All geometry is done in program coordinates (mm) of the plane, on its first and second
//! axes in [`Plane::axes`] order: X, Y in `G17`; Z, X in `G18`. Left, right, and the turning
//! of arcs (`G3` counter-clockwise) are those of that order in both planes, which is what
//! LinuxCNC's `rs274` does in `G18` (travelling +X under `G41`, the tool is on the −Z side).
//! The axis normal to the plane (Z in `G17`, Y in `G18`) and the rotary axes take their
//! programmed values.
//!
//! - **Entry move** (the first move after comp on, a straight line): from the tool's current
//!   point $\mathbf c$ to the programmed end $\mathbf p$ moved by $r$ perpendicular to the
//!   line $\mathbf c \to \mathbf p$, on the compensation side. The move must be longer than $r$.
//! - **Later straight moves** end at $\mathbf p$ moved by $r$ perpendicular to the programmed
//!   line. Where the programmed path turns away from the tool (a *convex* corner, the tool
//!   outside it), the tool goes around the programmed corner on an arc of radius $r$ centred
//!   on it (a straight traverse for `G0`, which has no arc form). Where it turns towards the tool
//!   (a *concave* corner), the previous compensated line is shortened to where the two offset
//!   lines meet; if that would reverse the previous move, the tool cannot reach the corner
//!   without gouging: an error. Corners within 0.05 rad of straight join without an arc.
//! - **Arcs** keep their programmed centre; their radius grows or shrinks by $r$ (tool outside or
//!   inside the arc); the tool radius must be smaller than an arc it runs inside. A convex
//!   corner before an arc gets the same corner arc as for lines.
//! - **Exit** (`G40`): the tool stays where the last compensated move left it; the next move (a
//!   straight line: an arc is an error) runs from there to its programmed end, uncompensated.
//!
//! Because a concave corner shortens the move *before* it, each compensated move is held back
//! until the next one is known (LinuxCNC's canon queue): moves made while one is held (a dwell,
//! a move of the normal axis alone) are held with it and follow its end point.
//!
//! - **Concave corners with arcs** (arc → line, line → arc, arc → arc): the previous move ends
//!   where the two tool paths (offset line, or the tool circle of radius arc radius ± r about
//!   the arc's centre) meet, the meeting point nearest the tool; when they do not meet, or the
//!   held move would reverse or its arc grow, the tool cannot fit: an error.
//!
//! - **Entry arc**: the programmed end moves by r towards or away from the
//!   centre; the arc runs from the tool to there about the point of the line from that end to
//!   the programmed centre that is equally far from both ends.
//!
//! **Lathe tools** (`G18` only): a tool orientation 1–8 (the tool table's `Q`, or `L` on
//! `G41.1`/`G42.1`) makes the controlled point the tool's imaginary tip. As `rs274` shows it,
//! the geometry above is done for the nose centre and the whole compensated path (ends, arc
//! and corner centres) moves by the nose radius along X and/or Z towards the tip
//! ([`tip_direction`]). The entry move starts from the controlled point as if it were the nose
//! centre (LinuxCNC's choice), so the tool's position in the plane is the controlled point
//! before the entry and the nose centre after it ([`Interp::tool_in_plane`]).
//!
//! Not done (refused with an error naming the line): `G19` (LinuxCNC refuses it too); in
//! `G18`, an entry arc with a lathe orientation (LinuxCNC 2.9 cuts a stray full circle there),
//! orientations outside 0–9, and a rotated coordinate system (its arcs would leave the
//! machine's XZ plane).

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use super::block::Checked;
use super::{ArcMove, Feed, Interp, Move, MoveKind, Plane, Toolpath};
use crate::diag::{DiagnosticKind, Span};

/// Angle tolerance for corners, rad (LinuxCNC `TOLERANCE_CONCAVE_CORNER`).
const CORNER_TOL: f64 = 0.05;

/// Side of the programmed path the tool runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Side {
    Left,
    Right,
}

impl Side {
    /// +1 on the left, −1 on the right: the tool is at `sign · r` along the left normal.
    fn sign(self) -> f64 {
        match self {
            Side::Left => 1.0,
            Side::Right => -1.0,
        }
    }
}

/// What a held move's end may do when the next move moves it.
#[derive(Debug, Clone, Copy)]
pub(super) enum Check {
    /// A straight move whose direction in the plane must not reverse.
    Direction {
        /// The direction, machine frame.
        along: [f64; 2],
        /// The move's start in the plane (machine frame) where the tool is the nose centre:
        /// for the entry move, the controlled point it starts from (LinuxCNC takes it for the
        /// nose centre, see [`Interp::tool_in_plane`]).
        from: [f64; 2],
    },
    /// An arc whose sweep (rad) must not grow.
    Sweep(f64),
    /// Nothing to check (corner arcs, dwells, moves without motion in the plane).
    Free,
}

/// A compensated move held until the next move is known.
#[derive(Debug, Clone)]
pub(super) struct Held {
    mv: Move,
    check: Check,
}

/// Compensation in force.
#[derive(Debug, Clone)]
pub(super) struct Comp {
    side: Side,
    /// Tool radius, mm (≥ 0; 0 runs the programmed path).
    radius: f64,
    /// A lathe tool's controlled point (its imaginary tip) from its nose centre, in the plane
    /// (program coordinates, mm, the plane's axis order); zero for a mill or orientation 0/9.
    tip: [f64; 2],
    /// The lathe tool orientation (0–9) `tip` comes from.
    orientation: i32,
    /// Programmed point in the plane (program coordinates, mm) at the end of the last
    /// compensated move; `None` until the entry move.
    nominal: Option<[f64; 2]>,
    /// When the last compensated move was an arc: the tool centre's circle (centre in program
    /// coordinates, radius), mm.
    circle: Option<([f64; 2], f64)>,
}

/// Compensation state carried by the interpreter.
#[derive(Debug, Clone, Default)]
pub(super) struct CompState {
    pub(super) on: Option<Comp>,
    /// Moves held back (see module doc).
    pub(super) held: Vec<Held>,
    /// How the next emitted move is held (set just before [`Interp::emit`]).
    pub(super) hold_next: Option<Check>,
    /// After `G40`: the programmed point the next move starts from (the tool is elsewhere),
    /// as the in-plane axes and their coordinates (the plane may change before that move).
    pub(super) nominal_after_off: Option<([usize; 2], [f64; 2])>,
    /// After `G40`: the next move must be straight.
    pub(super) arc_not_allowed: bool,
}

fn dir(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[1] - a[1]).atan2(b[0] - a[0])
}

fn polar(p: [f64; 2], r: f64, angle: f64) -> [f64; 2] {
    [p[0] + r * angle.cos(), p[1] + r * angle.sin()]
}

/// The intersections of the line through `p` with direction angle `a` and the circle
/// (`c`, `r`), or `None` when they do not meet.
fn line_circle(p: [f64; 2], a: f64, c: [f64; 2], r: f64) -> Option<[[f64; 2]; 2]> {
    let d = [a.cos(), a.sin()];
    let w = [p[0] - c[0], p[1] - c[1]];
    // |w + t d|² = r²: t² + 2 (w·d) t + |w|² − r² = 0.
    let b = w[0] * d[0] + w[1] * d[1];
    let disc = b * b - (w[0] * w[0] + w[1] * w[1] - r * r);
    if disc < 0.0 {
        return None;
    }
    let q = disc.sqrt();
    Some([polar(p, -b - q, a), polar(p, -b + q, a)])
}

/// The intersections of the circles (`c1`, `r1`) and (`c2`, `r2`), or `None`.
fn circle_circle(c1: [f64; 2], r1: f64, c2: [f64; 2], r2: f64) -> Option<[[f64; 2]; 2]> {
    let dist = (c2[0] - c1[0]).hypot(c2[1] - c1[1]);
    if dist == 0.0 || r1 == 0.0 {
        return None;
    }
    // Law of cosines: the angle at c1 between c1 → c2 and c1 → intersection.
    let cos = (r1 * r1 + dist * dist - r2 * r2) / (2.0 * r1 * dist);
    if !(-1.0..=1.0).contains(&cos) {
        return None;
    }
    let base = dir(c1, c2);
    let spread = cos.acos();
    Some([polar(c1, r1, base - spread), polar(c1, r1, base + spread)])
}

/// The feed of a compensated move whose programmed path is `len` mm long: as LinuxCNC, an
/// inverse-time `F` becomes the rate that runs the *programmed* move in 1/F minutes (the
/// compensated move, and a corner arc before it, run at that rate).
fn programmed_rate(feed: Option<Feed>, len: f64) -> Option<Feed> {
    match feed {
        Some(Feed::InverseTime(f)) => Some(Feed::UnitsPerMin(f * len)),
        other => other,
    }
}

/// How far the path turns away from the tool at a corner, in (−π/2, 3π/2] (> 0: convex, the
/// tool goes around the outside): `s` the side's sign, `before` the previous move's direction
/// at its end, `alpha` the next move's direction at its start.
fn corner_turn(s: f64, before: f64, alpha: f64) -> f64 {
    let mut turn = s * (before - alpha);
    while turn <= -FRAC_PI_2 {
        turn += TAU;
    }
    while turn > 1.5 * PI {
        turn -= TAU;
    }
    turn
}

/// Where a lathe tool's controlled point lies from its nose centre, in nose radii along X and
/// Z, for LinuxCNC's tool orientations 1–8 (0 and 9: the nose centre itself). As `rs274`
/// shows it: the whole compensated path moves by this, whichever side (`G41`/`G42`).
fn tip_direction(orientation: i32) -> [f64; 2] {
    match orientation {
        1 => [-1.0, 1.0],
        2 => [-1.0, -1.0],
        3 => [1.0, -1.0],
        4 => [1.0, 1.0],
        5 => [0.0, 1.0],
        6 => [-1.0, 0.0],
        7 => [0.0, -1.0],
        8 => [1.0, 0.0],
        _ => [0.0, 0.0],
    }
}

/// The one of `pts` nearest to `to`.
fn nearest(pts: [[f64; 2]; 2], to: [f64; 2]) -> [f64; 2] {
    let d = |p: [f64; 2]| (p[0] - to[0]).hypot(p[1] - to[1]);
    if d(pts[0]) <= d(pts[1]) {
        pts[0]
    } else {
        pts[1]
    }
}

/// Signed sweep of an arc from `s` to `e` about `c` turning `ccw` with `turns` turns (as
/// `motion::arc_sweep`, full circle when the points coincide).
fn sweep(ccw: bool, s: [f64; 2], e: [f64; 2], c: [f64; 2], turns: u32) -> f64 {
    super::motion::arc_sweep(ccw, s, e, c, turns)
}

/// Hand the held moves of `comp` on to `tp` (at the end of the program, or when the next
/// move no longer changes them); zero-length straight moves are dropped, as everywhere.
pub(super) fn release_into(comp: &mut CompState, tp: &mut Toolpath) {
    for h in std::mem::take(&mut comp.held) {
        let zero =
            h.mv.start == h.mv.end && matches!(h.mv.kind, MoveKind::Rapid | MoveKind::Linear);
        if !zero {
            tp.moves.push(h.mv);
        }
    }
}

impl Interp<'_> {
    /// Compensation is on with a non-zero radius: moves are compensated.
    pub(super) fn comp_active(&self) -> bool {
        self.st.comp.on.as_ref().is_some_and(|c| c.radius > 0.0)
    }

    /// Compensation is on (radius possibly 0): the codes LinuxCNC refuses then are refused.
    pub(super) fn comp_on(&self) -> bool {
        self.st.comp.on.is_some()
    }

    /// The error for `what` while compensation is on.
    pub(super) fn comp_refuse(&mut self, span: Span, what: &str) {
        self.err(span, DiagnosticKind::CutterCompensation, || {
            format!("{what} with cutter radius compensation on (G40 turns it off first)")
        });
    }

    /// Where the next move starts in the compensation plane, when that is not the tool's
    /// position: the programmed point while compensation is on or just after `G40`. The
    /// in-plane axes (indices of a position) and the point's coordinates on them.
    pub(super) fn nominal_in_plane(&self) -> Option<([usize; 2], [f64; 2])> {
        let on = self.st.comp.on.as_ref().filter(|c| c.radius > 0.0);
        match on.and_then(|c| c.nominal) {
            Some(p) => Some((self.plane_axes(), p)),
            None => self.st.comp.nominal_after_off,
        }
    }

    /// `p` (program coordinates) with its in-plane coordinates replaced by the programmed
    /// point the next move starts from, if that is not the tool's position.
    pub(super) fn with_nominal(&self, mut p: [f64; 6]) -> [f64; 6] {
        if let Some(([u, v], at)) = self.nominal_in_plane() {
            p[u] = at[0];
            p[v] = at[1];
        }
        p
    }

    /// Compensation in `G18` under a rotated coordinate system is refused (with the error,
    /// `true`): the rotation turns X and Y, so its arcs would leave the machine's XZ plane.
    fn refuse_rotated_g18(&mut self, span: Span) -> bool {
        let deg = self.st.rotation_deg;
        if self.st.plane == Plane::XY || deg == 0.0 {
            return false;
        }
        self.err(span, DiagnosticKind::CutterCompensation, || {
            format!(
                "cutter radius compensation in the XZ plane (G18) with a rotated coordinate system (G10 L2 R{deg}) is not supported: clear the rotation or compensate in G17"
            )
        });
        true
    }

    /// The compensation plane's first and second axes (indices of a position): X, Y in
    /// `G17`; Z, X in `G18`, where left/right of travel and `G2`/`G3` follow from that order
    /// as in `G17` (the plane seen from +Y).
    fn plane_axes(&self) -> [usize; 2] {
        let (u, v, _) = self.st.plane.axes();
        [u, v]
    }

    /// The axis normal to the compensation plane (Z in `G17`, Y in `G18`).
    fn normal_axis(&self) -> usize {
        self.st.plane.axes().2
    }

    /// The in-plane coordinates of position `p`.
    fn in_plane(&self, p: [f64; 6]) -> [f64; 2] {
        let [u, v] = self.plane_axes();
        [p[u], p[v]]
    }

    /// `G40`, `G41`, `G41.1`, `G42`, `G42.1` (code × 10). `false` after an error.
    pub(super) fn cutter_mode(&mut self, code: u32, k: &Checked, span: Span) -> bool {
        if code == 400 {
            if self.comp_active() && self.nominal_in_plane().is_some() {
                // The held move ends where it is, but must not run backwards (a concave corner
                // before it deeper than it is long).
                let c = self.tool_in_plane();
                if !self.move_held_end(c, span) {
                    return false;
                }
                self.st.comp.nominal_after_off = self.nominal_in_plane();
                self.st.comp.arc_not_allowed = true;
            }
            self.st.comp.on = None;
            return true;
        }
        let g = super::gname(code);
        if self.refuse_rotated_g18(span) {
            return false;
        }
        match self.st.plane {
            Plane::XY | Plane::ZX => {}
            Plane::YZ => {
                self.err(span, DiagnosticKind::CutterCompensation, || {
                    format!("{g}: cutter radius compensation is allowed only in the XY (G17) and XZ (G18) planes, not G19")
                });
                return false;
            }
        }
        if self.comp_on() {
            self.err(span, DiagnosticKind::CutterCompensation, || {
                format!("{g}: cannot turn cutter radius compensation on when it is on (G40 first)")
            });
            return false;
        }
        let dynamic = code == 411 || code == 421;
        let orientation;
        let radius = if dynamic {
            let Some((d, _)) = k.w.get('D') else {
                self.err(span, DiagnosticKind::CutterCompensation, || {
                    format!("{g} with no D word (the tool diameter)")
                });
                return false;
            };
            orientation = match k.w.get('L') {
                None => 0,
                Some((l, ls)) => {
                    if self.st.plane != Plane::ZX {
                        self.err(ls, DiagnosticKind::CutterCompensation, || {
                            format!(
                                "{g} with L{l} (lathe tool orientation), but the plane is not G18"
                            )
                        });
                        return false;
                    }
                    if !(0.0..=9.0).contains(&l) || l.fract() != 0.0 {
                        self.err(ls, DiagnosticKind::CutterCompensation, || {
                            format!("{g} L{l}: the lathe tool orientation must be a whole number from 0 to 9")
                        });
                        return false;
                    }
                    l as i32
                }
            };
            d * self.lscale() / 2.0
        } else {
            let tool = match k.w.get('D') {
                None => self.st.current_tool,
                Some((d, ds)) => {
                    if d < 0.0 || (d - d.round()).abs() > 1e-4 {
                        self.err(ds, DiagnosticKind::CutterCompensation, || {
                            format!("{g} D{d}: D must be a tool number (a whole number ≥ 0)")
                        });
                        return false;
                    }
                    // D0 is the tool in the spindle.
                    if d.round() == 0.0 {
                        self.st.current_tool
                    } else {
                        d.round() as u32
                    }
                }
            };
            let Some(t) = self.tools.tools.get(&tool).cloned() else {
                if tool == 0 {
                    // No tool loaded: radius 0, the path runs as programmed.
                    self.st.comp.on = Some(Comp {
                        side: if code == 410 { Side::Left } else { Side::Right },
                        radius: 0.0,
                        tip: [0.0; 2],
                        orientation: 0,
                        nominal: None,
                        circle: None,
                    });
                    return true;
                }
                let at = k.w.get('D').map_or(span, |v| v.1);
                self.err(at, DiagnosticKind::CutterCompensation, || {
                    format!("{g} D{tool}: tool {tool} is not in the tool table")
                });
                return false;
            };
            let lathe = t.orientation != 0 && t.orientation != 9;
            if lathe && self.st.plane != Plane::ZX {
                self.err(span, DiagnosticKind::CutterCompensation, || {
                    format!(
                        "{g} with lathe tool {tool} (orientation {}), but the plane is not G18",
                        t.orientation
                    )
                });
                return false;
            }
            if !(0..=9).contains(&t.orientation) {
                self.err(span, DiagnosticKind::CutterCompensation, || {
                    format!(
                        "{g} with tool {tool} of orientation {}: a lathe tool orientation is a whole number from 0 to 9 (the tool table's Q)",
                        t.orientation
                    )
                });
                return false;
            }
            orientation = t.orientation;
            t.diameter * self.opts.machine_units.mm() / 2.0
        };
        let mut side = if code == 410 || code == 411 {
            Side::Left
        } else {
            Side::Right
        };
        // A negative diameter (a tool smaller than the nominal one the path was made for)
        // compensates on the other side.
        if radius < 0.0 {
            side = if side == Side::Left {
                Side::Right
            } else {
                Side::Left
            };
        }
        if !radius.is_finite() {
            self.err(span, DiagnosticKind::CutterCompensation, || {
                format!("{g}: tool radius {radius} mm is out of range")
            });
            return false;
        }
        let [dx, dz] = tip_direction(orientation);
        let r = radius.abs();
        self.st.comp.on = Some(Comp {
            side,
            radius: r,
            // The plane's order is Z, X.
            tip: [dz * r, dx * r],
            orientation,
            nominal: None,
            circle: None,
        });
        true
    }

    /// Machine coordinates, in the plane, of in-plane program point `p`.
    fn machine_in_plane(&self, p: [f64; 2]) -> [f64; 2] {
        let [u, v] = self.plane_axes();
        let mut q = [0.0; 6];
        q[u] = p[0];
        q[v] = p[1];
        self.in_plane(self.to_machine(q))
    }

    /// Machine coordinates, in the plane, of where the controlled point goes when the tool
    /// (the nose centre for a lathe tool) is at in-plane program point `p`.
    fn machine_tool(&self, p: [f64; 2]) -> [f64; 2] {
        let tip = self.st.comp.on.as_ref().map_or([0.0; 2], |c| c.tip);
        self.machine_in_plane([p[0] + tip[0], p[1] + tip[1]])
    }

    /// The tool's position in the plane (program coordinates): after the entry move, a lathe
    /// tool's nose centre; before it, the controlled point (LinuxCNC computes the entry from
    /// there as if it were the nose centre).
    fn tool_in_plane(&self) -> [f64; 2] {
        let p = self.in_plane(self.to_program(self.st.pos));
        match self.st.comp.on.as_ref().filter(|c| c.nominal.is_some()) {
            Some(c) => [p[0] - c.tip[0], p[1] - c.tip[1]],
            None => p,
        }
    }

    /// Machine target of a compensated move: program point `p` with the tool at in-plane point
    /// `at`.
    fn comp_target(&self, p: [f64; 6], at: [f64; 2]) -> [f64; 6] {
        let cur = self.to_program(self.st.pos);
        let mut m = self.to_machine_from(p, cur);
        let [u, v] = self.plane_axes();
        [m[u], m[v]] = self.machine_tool(at);
        m
    }

    /// Emit a move that is held back with `check`.
    fn emit_held(
        &mut self,
        kind: MoveKind,
        end: [f64; 6],
        span: Span,
        feed: Option<Feed>,
        check: Check,
    ) {
        self.st.comp.hold_next = Some(check);
        self.emit(kind, end, span, feed);
        self.st.comp.hold_next = None;
    }

    /// Called by [`Interp::emit`] with a new move: hold it if compensation holds moves.
    pub(super) fn hold(&mut self, mv: Move) -> Option<Move> {
        let check = self.st.comp.hold_next.take();
        match check {
            Some(check) => {
                self.st.comp.held.push(Held { mv, check });
                None
            }
            None if !self.st.comp.held.is_empty() => {
                self.st.comp.held.push(Held {
                    mv,
                    check: Check::Free,
                });
                None
            }
            None => Some(mv),
        }
    }

    /// Hand the held moves on (zero-length straight moves dropped, as everywhere).
    pub(super) fn release_held(&mut self) {
        release_into(&mut self.st.comp, &mut self.tp);
    }

    /// Mark the last held move as a stop; `false` when none is held.
    pub(super) fn mark_held_stop(&mut self) -> bool {
        match self.st.comp.held.last_mut() {
            Some(h) => {
                h.mv.stop_after = true;
                true
            }
            None => false,
        }
    }

    /// Move the in-plane end of the held moves to the tool at program point `p` and release them; an error (and
    /// `false`) when that reverses a held straight move or lengthens a held arc (the tool
    /// cannot reach the corner without gouging).
    fn move_held_end(&mut self, p: [f64; 2], span: Span) -> bool {
        let m = self.machine_tool(p);
        let nose = self.machine_in_plane(p);
        let [u, v] = self.plane_axes();
        // LinuxCNC's allowance for an arc's sweep growing: 0.0254 in mm programs, 0.001 in
        // inch programs (compared with radians, as LinuxCNC does).
        let grow = if self.st.inch { 0.001 } else { 0.0254 };
        let mut first = true;
        let mut problem = None;
        for h in &mut self.st.comp.held {
            if !first {
                [h.mv.start[u], h.mv.start[v]] = m;
            }
            first = false;
            let s = [h.mv.start[u], h.mv.start[v]];
            match (&mut h.mv.kind, h.check) {
                (MoveKind::Arc(a), check) => {
                    let new = sweep(a.sweep_rad > 0.0, s, m, a.centre, a.turns);
                    if let Check::Sweep(old) = check
                        && new.abs() > old.abs() + grow
                    {
                        problem = Some(
                            "arc move in a concave corner cannot be reached by the tool without gouging",
                        );
                    }
                    a.sweep_rad = new;
                    a.radius_end_mm = (m[0] - a.centre[0]).hypot(m[1] - a.centre[1]);
                }
                (_, Check::Direction { along: d, from: f })
                    if d[0] * (nose[0] - f[0]) + d[1] * (nose[1] - f[1]) < 0.0 =>
                {
                    problem = Some(if h.mv.kind == MoveKind::Rapid {
                        "straight traverse in a concave corner cannot be reached by the tool without gouging"
                    } else {
                        "straight feed in a concave corner cannot be reached by the tool without gouging"
                    });
                }
                _ => {}
            }
            [h.mv.end[u], h.mv.end[v]] = m;
            if matches!(h.mv.kind, MoveKind::Dwell { .. }) {
                h.mv.start = h.mv.end;
            }
        }
        if let Some(msg) = problem {
            let r = self.st.comp.on.as_ref().map_or(0.0, |c| c.radius);
            self.err(span, DiagnosticKind::CutterCompensation, || {
                format!("{msg} (tool radius {r:.4} mm)")
            });
            return false;
        }
        [self.st.pos[u], self.st.pos[v]] = m;
        self.release_held();
        true
    }

    /// A program-frame in-plane direction in the machine frame (turned by the coordinate
    /// system's rotation).
    fn rotate_dir(&self, d: [f64; 2]) -> [f64; 2] {
        let o = self.machine_in_plane([0.0, 0.0]);
        let m = self.machine_in_plane(d);
        [m[0] - o[0], m[1] - o[1]]
    }

    /// A compensated `G0`/`G1` to program point `p` (LinuxCNC `convert_straight_comp1/2`).
    pub(super) fn comp_straight(
        &mut self,
        rapid: bool,
        p: [f64; 6],
        span: Span,
        feed: Option<Feed>,
    ) {
        let Some(comp) = self.st.comp.on.clone() else {
            return;
        };
        let kind = if rapid {
            MoveKind::Rapid
        } else {
            MoveKind::Linear
        };
        let r = comp.radius;
        let s = comp.side.sign();
        if self.refuse_rotated_g18(span) {
            return;
        }
        let c = self.tool_in_plane();
        let pp = self.in_plane(p);
        let from = comp.nominal.unwrap_or(c);
        let w = self.normal_axis();
        let w0 = self.to_program(self.st.pos)[w];
        let programmed = (pp[0] - from[0]).hypot(pp[1] - from[1]).hypot(p[w] - w0);
        let feed = programmed_rate(feed, programmed);
        let Some(op) = comp.nominal else {
            // Entry move: to p moved by r perpendicular to c → p.
            let len = (pp[0] - c[0]).hypot(pp[1] - c[1]);
            if len <= r {
                self.err(span, DiagnosticKind::CutterCompensation, || {
                    format!(
                        "the cutter compensation entry move ({len:.4} mm in the plane) is not longer than the tool radius ({r:.4} mm)"
                    )
                });
                return;
            }
            let normal = dir(c, pp) + s * FRAC_PI_2;
            let end = polar(pp, r, normal);
            let d = self.rotate_dir([normal.cos(), normal.sin()]);
            let target = self.comp_target(p, end);
            let from = self.machine_in_plane(c);
            self.emit_held(
                kind,
                target,
                span,
                feed,
                Check::Direction { along: d, from },
            );
            self.set_nominal(pp, None);
            return;
        };
        if pp == op {
            // No motion in the plane: the axis normal to it (and rotary axes) move, the tool
            // stays beside the path.
            let target = self.comp_target(p, c);
            self.emit_held(kind, target, span, feed, Check::Free);
            return;
        }
        // Direction of the programmed move, and of the previous one at its end (the tool sits
        // at s·90° from it, so it is the direction op → tool turned back by s·90°).
        let alpha = dir(op, pp);
        let before = dir(op, c) - s * FRAC_PI_2;
        let turn = corner_turn(s, before, alpha);
        let offset = alpha + s * FRAC_PI_2;
        let end = polar(pp, r, offset);
        let mid = polar(op, r, offset);
        let prev_arc_outside = self.st.comp.held.first().is_some_and(|h| match h.mv.kind {
            MoveKind::Arc(a) => s * a.sweep_rad < 0.0,
            _ => false,
        });
        let prev_is_arc = self
            .st
            .comp
            .held
            .first()
            .is_some_and(|h| matches!(h.mv.kind, MoveKind::Arc(_)));
        let concave = !(-CORNER_TOL..=PI + CORNER_TOL).contains(&turn)
            || (turn > PI - CORNER_TOL && prev_arc_outside);
        if concave && let Some((pc, pr)) = comp.circle.filter(|_| prev_is_arc) {
            // Arc → line: the previous arc ends where its tool circle meets the new offset
            // line (the meeting point nearest the tool).
            let Some(pts) = line_circle(mid, alpha, pc, pr) else {
                self.err(span, DiagnosticKind::CutterCompensation, || {
                    format!("arc to straight motion makes a corner the compensated tool (radius {r:.4} mm) can't fit in without gouging")
                });
                return;
            };
            if !self.move_held_end(nearest(pts, c), span) {
                return;
            }
        } else if concave {
            // Shorten the previous line to where the two offset lines meet: back along it by
            // r / tan(half the inside angle).
            let half = (turn + PI) / 2.0;
            if half == 0.0 {
                self.err(
                    span,
                    DiagnosticKind::CutterCompensation,
                    "a zero-degree inside corner is invalid for cutter compensation",
                );
                return;
            }
            let back = r / half.tan();
            let meet = polar(c, back, before + PI);
            if !self.move_held_end(meet, span) {
                return;
            }
        } else if turn > CORNER_TOL {
            // Convex corner: around the programmed corner op, radius r.
            if !self.move_held_end(c, span) {
                return;
            }
            let cur = self.to_program(self.st.pos);
            let mut corner = cur;
            corner[3..6].copy_from_slice(&p[3..6]);
            let corner_m = self.comp_target(corner, mid);
            if rapid {
                self.emit(MoveKind::Rapid, corner_m, span, None);
            } else {
                let om = self.machine_tool(op);
                let sw = sweep(comp.side == Side::Right, c, mid, op, 1);
                let arc = ArcMove {
                    plane: self.st.plane,
                    centre: om,
                    sweep_rad: sw,
                    radius_start_mm: r,
                    radius_end_mm: r,
                    turns: 1,
                };
                self.emit(MoveKind::Arc(arc), corner_m, span, feed);
            }
        } else if !self.move_held_end(c, span) {
            return;
        }
        let d = self.rotate_dir([pp[0] - op[0], pp[1] - op[1]]);
        let target = self.comp_target(p, end);
        let from = self.machine_in_plane(self.tool_in_plane());
        self.emit_held(
            kind,
            target,
            span,
            feed,
            Check::Direction { along: d, from },
        );
        self.set_nominal(pp, None);
    }

    /// Record the programmed end of the move just held and, for an arc, its tool circle.
    fn set_nominal(&mut self, p: [f64; 2], circle: Option<([f64; 2], f64)>) {
        if let Some(c) = &mut self.st.comp.on {
            c.nominal = Some(p);
            c.circle = circle;
        }
    }

    /// An arc as the entry move (LinuxCNC `convert_arc_comp1`; its centre, of either format,
    /// is found from the tool's position as for an uncompensated arc): the
    /// programmed end moves by r towards the centre (tool inside) or away from it (outside), and
    /// the arc runs from the tool to there about a centre on the line from that end to the
    /// programmed centre, equally far from both ends.
    fn comp_entry_arc(
        &mut self,
        comp: &Comp,
        geom: ArcMove,
        end: [f64; 6],
        span: Span,
        feed: Option<Feed>,
    ) {
        let r = comp.radius;
        if comp.tip != [0.0; 2] {
            // rs274 moves straight to the arc's end, then runs a full circle there.
            let o = comp.orientation;
            self.err(span, DiagnosticKind::CutterCompensation, || {
                format!(
                    "an arc as the cutter compensation entry move with lathe tool orientation {o} is not supported (LinuxCNC 2.9 cuts a full circle there): enter with a straight move"
                )
            });
            return;
        }
        let c = self.tool_in_plane();
        let e = self.in_plane(end);
        let dist = (e[0] - c[0]).hypot(e[1] - c[1]);
        if dist <= r {
            self.err(span, DiagnosticKind::CutterCompensation, || {
                format!(
                    "the cutter compensation entry arc ({dist:.4} mm from start to end) is not longer than the tool radius ({r:.4} mm)"
                )
            });
            return;
        }
        let centre = geom.centre;
        let ccw = geom.sweep_rad > 0.0;
        let Some(inside) = self.arc_side(comp, &geom, e, span) else {
            return;
        };
        let out = if inside { PI } else { 0.0 };
        let new_end = polar(e, r, dir(centre, e) + out);
        // Centre n = new_end + t·u (u towards the programmed centre) with |n − c| = t:
        // t = |c − new_end|² / (2 u·(c − new_end)).
        let to_c = [c[0] - new_end[0], c[1] - new_end[1]];
        let ua = dir(new_end, centre);
        let u = [ua.cos(), ua.sin()];
        let along = u[0] * to_c[0] + u[1] * to_c[1];
        let chord = to_c[0].hypot(to_c[1]);
        if along.abs() < 1e-6 * chord {
            self.err(span, DiagnosticKind::CutterCompensation, || {
                format!(
                    "the cutter compensation entry arc has no centre for the tool radius ({r:.4} mm)"
                )
            });
            return;
        }
        let t = chord * chord / (2.0 * along);
        let n = polar(new_end, t, ua);
        let rr = (n[0] - new_end[0]).hypot(n[1] - new_end[1]);
        let arc = ArcMove {
            plane: self.st.plane,
            centre: self.machine_tool(n),
            sweep_rad: sweep(ccw, c, new_end, n, geom.turns),
            radius_start_mm: (c[0] - n[0]).hypot(c[1] - n[1]),
            radius_end_mm: rr,
            turns: geom.turns,
        };
        let feed = self.arc_rate(&geom, end, feed);
        let target = self.comp_target(end, new_end);
        self.emit_held(MoveKind::Arc(arc), target, span, feed, Check::Free);
        self.set_nominal(e, Some((n, rr)));
    }

    /// Whether the tool runs inside the arc `geom` ending at `e` (the arc turns towards the
    /// tool's side); `None`, with the error, when the tool does not fit inside it.
    fn arc_side(&mut self, comp: &Comp, geom: &ArcMove, e: [f64; 2], span: Span) -> Option<bool> {
        let r = comp.radius;
        let ccw = geom.sweep_rad > 0.0;
        let arc_r = (geom.centre[0] - e[0]).hypot(geom.centre[1] - e[1]);
        let inside = (ccw && comp.side == Side::Left) || (!ccw && comp.side == Side::Right);
        if inside && arc_r <= r {
            self.err(span, DiagnosticKind::CutterCompensation, || {
                format!(
                    "the tool radius ({r:.4} mm) is not less than the radius of the arc it runs inside ({arc_r:.4} mm)"
                )
            });
            return None;
        }
        Some(inside)
    }

    /// The feed of a compensated arc to `end`: under `G93` the rate of its programmed length
    /// (LinuxCNC's F × length).
    fn arc_rate(&self, geom: &ArcMove, end: [f64; 6], feed: Option<Feed>) -> Option<Feed> {
        let w = self.normal_axis();
        let w0 = self.to_program(self.st.pos)[w];
        let programmed = (geom.sweep_rad.abs() * geom.radius_start_mm).hypot(end[w] - w0);
        programmed_rate(feed, programmed)
    }

    /// A compensated `G2`/`G3` (LinuxCNC `convert_arc_comp2`): `start`/`end` programmed (program
    /// coordinates), `geom` the programmed arc (program coordinates).
    pub(super) fn comp_arc(
        &mut self,
        geom: ArcMove,
        end: [f64; 6],
        span: Span,
        feed: Option<Feed>,
    ) {
        let Some(comp) = self.st.comp.on.clone() else {
            return;
        };
        let Some(op) = comp.nominal else {
            self.comp_entry_arc(&comp, geom, end, span, feed);
            return;
        };
        let r = comp.radius;
        let s = comp.side.sign();
        let c = self.tool_in_plane();
        let e = self.in_plane(end);
        let feed = self.arc_rate(&geom, end, feed);
        let centre = geom.centre;
        let ccw = geom.sweep_rad > 0.0;
        let Some(inside) = self.arc_side(&comp, &geom, e, span) else {
            return;
        };
        let arc_r = (centre[0] - e[0]).hypot(centre[1] - e[1]);
        // Direction of travel at the arc's start, and of the previous move at its end.
        let radial = dir(centre, op);
        let alpha = radial + if ccw { FRAC_PI_2 } else { -FRAC_PI_2 };
        let before = dir(op, c) - s * FRAC_PI_2;
        let turn = corner_turn(s, before, alpha);
        // The tool's offset direction from the path: away from the centre outside, towards it
        // inside.
        let out = if inside { PI } else { 0.0 };
        let new_end = polar(e, r, dir(centre, e) + out);
        let concave = !(-CORNER_TOL..=PI + CORNER_TOL).contains(&turn)
            || ((turn - PI).abs() < CORNER_TOL && !inside);
        let tool_r = if inside { arc_r - r } else { arc_r + r };
        let mut start = c;
        if concave {
            // The previous move ends where the tool's paths meet (the meeting point nearest
            // the tool): a line's offset line, or an arc's tool circle, with this arc's.
            let meet = match comp.circle.filter(|_| {
                self.st
                    .comp
                    .held
                    .first()
                    .is_some_and(|h| matches!(h.mv.kind, MoveKind::Arc(_)))
            }) {
                Some((pc, pr)) => circle_circle(pc, pr, centre, tool_r),
                None => line_circle(c, before, centre, tool_r),
            };
            let Some(pts) = meet else {
                self.err(span, DiagnosticKind::CutterCompensation, || {
                    format!("arc move in a concave corner cannot be reached by the tool (radius {r:.4} mm) without gouging")
                });
                return;
            };
            start = nearest(pts, c);
            if !self.move_held_end(start, span) {
                return;
            }
        } else if !self.move_held_end(c, span) {
            return;
        }
        if !concave && turn > CORNER_TOL {
            let mid = polar(op, r, radial + out);
            let mut corner = self.to_program(self.st.pos);
            corner[3..6].copy_from_slice(&end[3..6]);
            let corner_m = self.comp_target(corner, mid);
            let sw = sweep(comp.side == Side::Right, c, mid, op, 1);
            let arc = ArcMove {
                plane: self.st.plane,
                centre: self.machine_tool(op),
                sweep_rad: sw,
                radius_start_mm: r,
                radius_end_mm: r,
                turns: 1,
            };
            self.emit(MoveKind::Arc(arc), corner_m, span, feed);
            start = mid;
        }
        let sw = sweep(ccw, start, new_end, centre, geom.turns);
        let arc = ArcMove {
            plane: self.st.plane,
            centre: self.machine_tool(centre),
            sweep_rad: sw,
            radius_start_mm: (start[0] - centre[0]).hypot(start[1] - centre[1]),
            radius_end_mm: (new_end[0] - centre[0]).hypot(new_end[1] - centre[1]),
            turns: geom.turns,
        };
        let target = self.comp_target(end, new_end);
        self.emit_held(
            MoveKind::Arc(arc),
            target,
            span,
            feed,
            Check::Sweep(geom.sweep_rad),
        );
        self.set_nominal(e, Some((centre, tool_r)));
    }
}
