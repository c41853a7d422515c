//! Coordinates and moves: program ↔ machine coordinates (parent module doc), straight moves,
//! arcs, dwells, tool length offsets, coordinate systems, `G10`, `G28`/`G30`, `G52`/`G92`.
//! LinuxCNC semantics throughout (`interp_convert.cc`, `interp_find.cc`, `interp_arc.cc`).

use std::f64::consts::TAU;

use super::block::{AT, CARET, Checked, Val};
use super::{ArcMove, Feed, Interp, Motion, Move, MoveKind, PathMode, Plane};
use crate::diag::{DiagnosticKind, Span};

const AXES: [char; 6] = ['X', 'Y', 'Z', 'A', 'B', 'C'];

/// First parameter of coordinate system `index` (1 = G54 → 5221; X Y Z A B C U V W R follow).
fn coord_base(index: usize) -> u32 {
    5201 + 20 * index as u32
}

/// Signed sweep, rad, of an arc from `s` to `e` about `c` (in-plane coordinates) with `turns`
/// turns: in (0, 2π] in the direction of travel for the first turn (equal points make a full
/// circle), plus 2π for each further turn; positive counter-clockwise.
pub(super) fn arc_sweep(ccw: bool, s: [f64; 2], e: [f64; 2], c: [f64; 2], turns: u32) -> f64 {
    let t0 = (s[1] - c[1]).atan2(s[0] - c[0]);
    let t1 = (e[1] - c[1]).atan2(e[0] - c[0]);
    let same = (e[0] - s[0]).hypot(e[1] - s[1]) <= 1e-9;
    let mut d = if ccw { t1 - t0 } else { t0 - t1 };
    if same {
        d = TAU;
    } else {
        if d <= 0.0 {
            d += TAU;
        }
        if d > TAU {
            d -= TAU;
        }
    }
    let magnitude = d + TAU * f64::from(turns - 1);
    if ccw { magnitude } else { -magnitude }
}

fn rotate(x: f64, y: f64, deg: f64) -> (f64, f64) {
    if deg == 0.0 {
        return (x, y);
    }
    let (s, c) = deg.to_radians().sin_cos();
    (x * c - y * s, x * s + y * c)
}

impl Interp<'_> {
    /// Machine coordinates of program point `p` (mm, deg): $R(\mathbf p + \mathbf o_{92}) +
    /// \mathbf o_{5x} + \mathbf t$.
    pub(super) fn to_machine(&self, p: [f64; 6]) -> [f64; 6] {
        let mut m: [f64; 6] = std::array::from_fn(|i| p[i] + self.st.g92[i]);
        (m[0], m[1]) = rotate(m[0], m[1], self.st.rotation_deg);
        for (i, v) in m.iter_mut().enumerate() {
            *v += self.st.g5x[i] + self.st.tool_offset[i];
        }
        m
    }

    /// Program coordinates of machine point `m` (the inverse of [`Interp::to_machine`]).
    pub(super) fn to_program(&self, m: [f64; 6]) -> [f64; 6] {
        let mut p: [f64; 6] =
            std::array::from_fn(|i| m[i] - self.st.g5x[i] - self.st.tool_offset[i]);
        (p[0], p[1]) = rotate(p[0], p[1], -self.st.rotation_deg);
        for (i, v) in p.iter_mut().enumerate() {
            *v -= self.st.g92[i];
        }
        p
    }

    /// Machine coordinates of program point `p`, where `cur` is the current position's program
    /// coordinates: an axis whose program coordinate does not change keeps its machine
    /// coordinate exactly (converting back and forth would move it by rounding).
    pub(super) fn to_machine_from(&self, p: [f64; 6], cur: [f64; 6]) -> [f64; 6] {
        let mut m = self.to_machine(p);
        let keep_xy = self.st.rotation_deg == 0.0 || (p[0] == cur[0] && p[1] == cur[1]);
        for (i, v) in m.iter_mut().enumerate() {
            if p[i] == cur[i] && (i >= 2 || keep_xy) {
                *v = self.st.pos[i];
            }
        }
        m
    }

    /// mm (or deg) per unit of the machine's tables, for axis `i`.
    fn table_unit(&self, i: usize) -> f64 {
        if i < 3 {
            self.opts.machine_units.mm()
        } else {
            1.0
        }
    }

    /// The block's value of axis `i` in mm or deg.
    fn axis_value(&self, k: &Checked, i: usize) -> Option<f64> {
        let s = self.lscale();
        k.w.get(AXES[i]).map(|(v, _)| if i < 3 { v * s } else { v })
    }

    /// Coordinate system selection (G54 … G59.3): offsets and rotation from the parameters.
    pub(super) fn select_coordinate_system(&mut self, index: usize) {
        let index = index.clamp(1, 9);
        self.st.coord_index = index;
        self.params.set(5220, index as f64);
        let base = coord_base(index);
        self.st.g5x =
            std::array::from_fn(|i| self.params.get(base + i as u32) * self.table_unit(i));
        self.st.rotation_deg = self.params.get(base + 9);
    }

    /// The offsets in force at start: coordinate system #5220, G92 offsets when #5210 is 1.
    pub(super) fn load_start_offsets(&mut self) {
        let n = self.params.get(5220);
        let index = if (1.0..=9.0).contains(&n) && n.fract() == 0.0 {
            n as usize
        } else {
            1
        };
        self.select_coordinate_system(index);
        if self.params.get(5210) == 1.0 {
            self.st.g92 =
                std::array::from_fn(|i| self.params.get(5211 + i as u32) * self.table_unit(i));
        }
    }

    fn store_g92(&mut self) {
        for i in 0..6 {
            let v = self.st.g92[i] / self.table_unit(i);
            self.params.set(5211 + i as u32, v);
        }
        self.params.set(5210, 1.0);
    }

    /// The programmed end point in program coordinates (LinuxCNC `find_ends`, without G53):
    /// absolute or incremental words, polar `@ ^` in the XY plane.
    fn program_target(&mut self, k: &Checked) -> Option<[f64; 6]> {
        // Under cutter compensation (and for the move after G40) the program continues from the
        // programmed point, not the tool's.
        let cur = self.with_nominal(self.to_program(self.st.pos));
        let mut p = cur;
        for (i, v) in p.iter_mut().enumerate() {
            if let Some(x) = self.axis_value(k, i) {
                *v = if self.st.absolute { x } else { *v + x };
            }
        }
        let radius: Val = k.w.letters[AT];
        let angle: Val = k.w.letters[CARET];
        if radius.is_none() && angle.is_none() {
            return Some(p);
        }
        let s = self.lscale();
        let span = radius.or(angle).map(|v| v.1).unwrap_or_default();
        let at_origin = p[0] == 0.0 && p[1] == 0.0;
        let (r0, t0) = (p[1].hypot(p[0]), p[1].atan2(p[0]));
        let (r, t) = if self.st.absolute {
            match (radius, angle) {
                (Some((r, _)), Some((a, _))) => (r * s, a.to_radians()),
                (Some((r, _)), None) => {
                    if at_origin {
                        self.err(span, DiagnosticKind::Motion, "polar radius @ without angle ^ at the origin: the direction is undefined");
                        return None;
                    }
                    (r * s, t0)
                }
                (None, Some((a, _))) => (r0, a.to_radians()),
                (None, None) => (r0, t0),
            }
        } else {
            if at_origin {
                self.err(
                    span,
                    DiagnosticKind::Motion,
                    "incremental polar move (G91 @ ^) at the origin: the direction is undefined",
                );
                return None;
            }
            let r = r0 + radius.map_or(0.0, |(v, _)| v * s);
            let t = t0 + angle.map_or(0.0, |(v, _)| v.to_radians());
            (r, t)
        };
        p[0] = r * t.cos();
        p[1] = r * t.sin();
        Some(p)
    }

    /// The machine target of a straight move (`G53` takes machine coordinates).
    fn straight_target(&mut self, k: &Checked) -> Option<[f64; 6]> {
        if matches!(k.nonmodal, Some((530, _))) {
            let mut m = self.st.pos;
            for (i, v) in m.iter_mut().enumerate() {
                if let Some(x) = self.axis_value(k, i) {
                    // LinuxCNC: rotary axes keep the tool offset under G53.
                    *v = if i < 3 { x } else { x + self.st.tool_offset[i] };
                }
            }
            return Some(m);
        }
        let p = self.program_target(k)?;
        Some(self.to_machine_from(p, self.to_program(self.st.pos)))
    }

    fn mark_axes(&mut self, k: &Checked) {
        for (i, used) in self.tp.axes_used.iter_mut().enumerate() {
            if k.w.get(AXES[i]).is_some()
                || (i < 2 && (k.w.letters[AT].is_some() || k.w.letters[CARET].is_some()))
            {
                *used = true;
            }
        }
    }

    /// Append a move from the current position to `end` (zero-length motions are dropped).
    pub(super) fn emit(&mut self, kind: MoveKind, end: [f64; 6], span: Span, feed: Option<Feed>) {
        let start = self.st.pos;
        if let Some(i) = (0..6).find(|&i| !end[i].is_finite()) {
            self.err(span, DiagnosticKind::Motion, || {
                format!(
                    "{} target is out of range after unit conversion and offsets",
                    AXES[i]
                )
            });
            return;
        }
        if !self.st.started && !matches!(kind, MoveKind::Dwell { .. }) {
            self.st.started = true;
            if let MoveKind::Arc(_) = kind {
                self.sink.push(crate::diag::Diagnostic::warning(
                    span,
                    "the first motion is an arc: it starts from all axes at 0",
                ));
            } else {
                // StartPosition::FirstMove: the opening motion defines the start.
                self.tp.start = end;
                for mv in &mut self.tp.moves {
                    mv.start = end;
                    mv.end = end;
                }
                self.st.pos = end;
                return;
            }
        }
        self.st.pos = end;
        for i in 0..6 {
            if end[i] != start[i] {
                self.tp.axes_used[i] = true;
            }
        }
        let zero = end == start && matches!(kind, MoveKind::Rapid | MoveKind::Linear);
        if zero {
            return;
        }
        if !matches!(kind, MoveKind::Dwell { .. }) && !self.comp_active() {
            // The first move after G40 (a straight move, G28/G30) has started from the
            // programmed point: from now on the tool's position is the program's.
            self.st.comp.nominal_after_off = None;
        }
        let mv = Move {
            line: span.line,
            col: span.col,
            kind,
            start,
            end,
            feed,
            path: if matches!(kind, MoveKind::Dwell { .. }) {
                PathMode::ExactStop
            } else {
                self.st.path
            },
            stop_after: matches!(kind, MoveKind::Dwell { .. }),
            tcp: self.st.tcp,
        };
        if let Some(mv) = self.hold(mv) {
            self.tp.moves.push(mv);
        }
    }

    /// The feed of a feed move, or `None` (reported) when there is none.
    pub(super) fn feed_for(&mut self, span: Span, f_block: Val, pure_rotary: bool) -> Option<Feed> {
        if self.st.inverse_time {
            match f_block {
                Some((f, _)) if f > 0.0 => Some(Feed::InverseTime(f)),
                Some((_, s)) => {
                    self.err(
                        s,
                        DiagnosticKind::Motion,
                        "G93 inverse-time feed F0: the move would take forever",
                    );
                    None
                }
                None => {
                    self.err(
                        span,
                        DiagnosticKind::Motion,
                        "G93 inverse-time mode needs an F word on every feed block",
                    );
                    None
                }
            }
        } else {
            match self.st.feed {
                Some((mm, raw)) if mm > 0.0 => {
                    Some(Feed::UnitsPerMin(if pure_rotary { raw } else { mm }))
                }
                Some(_) => {
                    self.err(span, DiagnosticKind::Motion, "feed move with feed rate F0");
                    None
                }
                None => {
                    self.err(
                        span,
                        DiagnosticKind::Motion,
                        "feed move with no feed rate set (F)",
                    );
                    None
                }
            }
        }
    }

    /// `G0`/`G1` (with `G53`, polar coordinates).
    pub(super) fn straight(&mut self, m: Motion, k: &Checked, span: Span, f_block: Val) {
        self.mark_axes(k);
        self.st.comp.arc_not_allowed = false;
        if self.comp_active() {
            if let Some((530, s)) = k.nonmodal {
                self.comp_refuse(s, "G53 (machine coordinates)");
                return;
            }
            let Some(p) = self.program_target(k) else {
                return;
            };
            let feed = if m == Motion::Rapid {
                None
            } else {
                let cur = self.to_program(self.st.pos);
                let xyz_zero = (0..3).all(|i| p[i] == cur[i]);
                match self.feed_for(span, f_block, xyz_zero) {
                    Some(f) => Some(f),
                    None => return,
                }
            };
            self.comp_straight(m == Motion::Rapid, p, span, feed);
            return;
        }
        let Some(target) = self.straight_target(k) else {
            return;
        };
        if m == Motion::Rapid {
            self.emit(MoveKind::Rapid, target, span, None);
            return;
        }
        let xyz_zero = (0..3).all(|i| target[i] == self.st.pos[i]);
        match self.feed_for(span, f_block, xyz_zero) {
            Some(feed) => self.emit(MoveKind::Linear, target, span, Some(feed)),
            None => self.st.pos = target,
        }
    }

    /// `G4 P`.
    pub(super) fn dwell(&mut self, k: &Checked, span: Span) {
        match k.w.get('P') {
            Some((p, s)) if p < 0.0 => {
                self.err(s, DiagnosticKind::Block, || {
                    format!("dwell time P{p} is negative")
                });
            }
            Some((p, _)) => {
                let pos = self.st.pos;
                self.emit(MoveKind::Dwell { seconds: p }, pos, span, None);
            }
            None => self.err(
                span,
                DiagnosticKind::Block,
                "G4 dwell without a P word (seconds)",
            ),
        }
    }

    /// `G2`/`G3`: a circular or helical arc (full circle when the end is the start).
    pub(super) fn arc_block(&mut self, ccw: bool, k: &Checked, span: Span, f_block: Val) {
        self.mark_axes(k);
        if self.st.rotation_deg != 0.0 && self.st.plane != Plane::XY {
            self.err(
                span,
                DiagnosticKind::Motion,
                "G18/G19 arcs in a rotated coordinate system (G10 L2 R) are not supported",
            );
            return;
        }
        if self.st.comp.arc_not_allowed {
            self.err(
                span,
                DiagnosticKind::CutterCompensation,
                "the move just after G40 (cutter compensation off) must be straight, not an arc",
            );
            return;
        }
        let start_p = self.with_nominal(self.to_program(self.st.pos));
        let Some(end_p) = self.program_target(k) else {
            return;
        };
        let Some(geom) = self.arc_geometry(ccw, start_p, end_p, span, k) else {
            return;
        };
        if self.comp_active() {
            if let Some(feed) = self.feed_for(span, f_block, false) {
                self.comp_arc(geom, end_p, span, Some(feed));
            }
            return;
        }
        let (u, v, _) = geom.plane.axes();
        let mut c6 = start_p;
        c6[u] = geom.centre[0];
        c6[v] = geom.centre[1];
        let cm = self.to_machine(c6);
        let arc = ArcMove {
            centre: [cm[u], cm[v]],
            ..geom
        };
        let end = self.to_machine_from(end_p, start_p);
        if let Some(feed) = self.feed_for(span, f_block, false) {
            self.emit(MoveKind::Arc(arc), end, span, Some(feed));
        } else {
            self.st.pos = end;
        }
    }

    /// Arc centre, sweep and radii in program coordinates (LinuxCNC `interp_arc.cc`).
    fn arc_geometry(
        &mut self,
        ccw: bool,
        start: [f64; 6],
        end: [f64; 6],
        span: Span,
        k: &Checked,
    ) -> Option<ArcMove> {
        let plane = self.st.plane;
        let (u, v, _) = plane.axes();
        let turns = match k.w.get('P') {
            None => 1,
            Some((p, s)) => {
                if p < 1.0 || p.fract() != 0.0 || p > 1e6 {
                    self.err(s, DiagnosticKind::Block, || {
                        format!("arc turns P{p} must be a whole number ≥ 1")
                    });
                    return None;
                }
                p as u32
            }
        };
        let s = [start[u], start[v]];
        let e = [end[u], end[v]];
        let r_word = k.w.get('R');
        let c = match r_word {
            Some(r) => self.arc_centre_r(ccw, s, e, r, k)?,
            None => self.arc_centre_offsets(s, span, k)?,
        };
        let r0 = (s[0] - c[0]).hypot(s[1] - c[1]);
        let r1 = (e[0] - c[0]).hypot(e[1] - c[1]);
        if r0.is_nan() || r0 <= 0.0 || !r0.is_finite() || !r1.is_finite() {
            self.err(
                span,
                DiagnosticKind::Motion,
                "arc centre coincides with the start point",
            );
            return None;
        }
        if r_word.is_none() && !self.radii_agree(r0, r1, span) {
            return None;
        }
        let sweep = arc_sweep(ccw, s, e, c, turns);
        if !(sweep.is_finite() && c[0].is_finite() && c[1].is_finite()) {
            self.err(span, DiagnosticKind::Motion, "arc geometry is out of range");
            return None;
        }
        Some(ArcMove {
            plane,
            centre: c,
            sweep_rad: sweep,
            radius_start_mm: r0,
            radius_end_mm: r1,
            turns,
        })
    }

    fn plane_name(&self) -> &'static str {
        match self.st.plane {
            Plane::XY => "G17",
            Plane::ZX => "G18",
            Plane::YZ => "G19",
        }
    }

    /// Centre of an `R`-format arc from `s` to `e` (in-plane coordinates): on the left of the
    /// chord for `G3` with R > 0 (and for `G2` with R < 0).
    fn arc_centre_r(
        &mut self,
        ccw: bool,
        s: [f64; 2],
        e: [f64; 2],
        (r, rs): (f64, Span),
        k: &Checked,
    ) -> Option<[f64; 2]> {
        if ['I', 'J', 'K'].iter().any(|&c| k.w.get(c).is_some()) {
            self.err(
                rs,
                DiagnosticKind::Block,
                "arc with both R and I/J/K: use one form",
            );
            return None;
        }
        let r = r * self.lscale();
        let (du, dv) = (e[0] - s[0], e[1] - s[1]);
        let chord = du.hypot(dv);
        if chord == 0.0 {
            self.err(
                rs,
                DiagnosticKind::Motion,
                "R-form arc with the end point equal to the start: a full circle needs I/J/K",
            );
            return None;
        }
        if r == 0.0 {
            self.err(rs, DiagnosticKind::Motion, "arc radius R0");
            return None;
        }
        let half = chord / 2.0;
        let h2 = r * r - half * half;
        let h = if h2 >= 0.0 {
            h2.sqrt()
        } else if half - r.abs() <= self.opts.arc_r_tol_mm {
            0.0
        } else {
            self.err(rs, DiagnosticKind::Motion, || {
                format!(
                    "arc radius |R| = {:.6} mm is smaller than half the chord ({half:.6} mm)",
                    r.abs()
                )
            });
            return None;
        };
        let (nu, nv) = (-dv / chord, du / chord);
        let side = if ccw == (r > 0.0) { 1.0 } else { -1.0 };
        Some([
            s[0] + du / 2.0 + side * h * nu,
            s[1] + dv / 2.0 + side * h * nv,
        ])
    }

    /// Centre of an `I J K` arc: offsets from the start (`G91.1`) or the centre itself
    /// (`G90.1`), in the plane's two axes; the normal axis's letter is an error.
    fn arc_centre_offsets(&mut self, s: [f64; 2], span: Span, k: &Checked) -> Option<[f64; 2]> {
        let (u, v, w) = self.st.plane.axes();
        let letters = ['I', 'J', 'K'];
        let pname = self.plane_name();
        if let Some((_, sp)) = k.w.get(letters[w]) {
            self.err(sp, DiagnosticKind::Block, || {
                format!(
                    "'{}' word in a {pname} arc: centre offsets must lie in the arc plane",
                    letters[w]
                )
            });
            return None;
        }
        let (ou, ov) = (k.w.get(letters[u]), k.w.get(letters[v]));
        if ou.is_none() && ov.is_none() {
            self.err(span, DiagnosticKind::Block, || {
                format!(
                    "{pname} arc needs R or at least one of {}, {}",
                    letters[u], letters[v]
                )
            });
            return None;
        }
        let l = self.lscale();
        Some(if self.st.arc_absolute {
            [ou.map_or(s[0], |o| o.0 * l), ov.map_or(s[1], |o| o.0 * l)]
        } else {
            [
                s[0] + ou.map_or(0.0, |o| o.0 * l),
                s[1] + ov.map_or(0.0, |o| o.0 * l),
            ]
        })
    }

    /// LinuxCNC's test of a centre-format arc (`interp_arc.cc`): the radius difference may not
    /// exceed 100 × the absolute tolerance, nor both the absolute and the relative tolerance.
    fn radii_agree(&mut self, r0: f64, r1: f64, span: Span) -> bool {
        let abs_err = (r1 - r0).abs();
        let rel_err = abs_err / r0.max(r1);
        if abs_err > 100.0 * self.opts.arc_abs_tol_mm
            || (abs_err > self.opts.arc_abs_tol_mm && rel_err > self.opts.arc_rel_tol)
        {
            self.err(span, DiagnosticKind::Motion, || {
                format!(
                    "radius to the end of the arc differs from the radius to the start: \
                     r_start = {r0:.6} mm, r_end = {r1:.6} mm, difference {abs_err:.6} mm \
                     ({:.4} %)",
                    100.0 * rel_err
                )
            });
            return false;
        }
        true
    }

    /// Tool length group: `G43 [H]`, `G43.1 <axes>`, `G43.2 H|<axes>`, `G49`, vcnc's `G43.4`.
    /// `false` when the block cannot go on (reported).
    pub(super) fn tool_length(&mut self, code: u32, k: &Checked, span: Span) -> bool {
        match code {
            430 | 432 => {
                if code == 432 && k.w.get('H').is_none() {
                    // LinuxCNC 2.9 adds a tool's offset only ("Requested tool -1 not found").
                    self.err(
                        span,
                        DiagnosticKind::Block,
                        "G43.2 needs H<tool number> (the offset of that tool is added)",
                    );
                    return false;
                }
                let add: [f64; 6] = {
                    let tool = match k.w.get('H') {
                        Some((h, _)) => h as u32,
                        None => self.st.current_tool,
                    };
                    if tool == 0 {
                        [0.0; 6]
                    } else {
                        match self.tools.tools.get(&tool) {
                            Some(t) => std::array::from_fn(|i| t.offset[i] * self.table_unit(i)),
                            None => {
                                let at = k.w.get('H').map_or(span, |h| h.1);
                                self.err(at, DiagnosticKind::Block, || {
                                    format!("tool {tool} is not in the tool table (G43 needs its length)")
                                });
                                return false;
                            }
                        }
                    }
                };
                if code == 430 {
                    self.st.tool_offset = add;
                } else {
                    for (o, a) in self.st.tool_offset.iter_mut().zip(add) {
                        *o += a;
                    }
                }
                self.st.tcp = false;
            }
            431 => {
                self.st.tool_offset = std::array::from_fn(|i| self.axis_value(k, i).unwrap_or(0.0));
                self.st.tcp = false;
            }
            434 => {
                self.st.tcp = true;
                self.st.tool_offset = [0.0; 6];
            }
            _ => {
                self.st.tcp = false;
                self.st.tool_offset = [0.0; 6];
            }
        }
        true
    }

    /// Group-0 codes other than `G4` and `G53`. `false` when the block cannot go on.
    pub(super) fn nonmodal(&mut self, code: u32, k: &Checked, span: Span) -> bool {
        match code {
            100 => self.g10(k, span),
            280 | 300 => {
                self.home(code == 280, k, span);
                true
            }
            281 | 301 => {
                let base = if code == 281 { 5161 } else { 5181 };
                for i in 0..6 {
                    let v = self.st.pos[i] / self.table_unit(i);
                    self.params.set(base + i as u32, v);
                }
                true
            }
            520 => {
                for i in 0..6 {
                    if let Some(v) = self.axis_value(k, i) {
                        self.st.g92[i] = v;
                    }
                }
                self.store_g92();
                true
            }
            920 => {
                if !(0..6).any(|i| k.w.get(AXES[i]).is_some()) {
                    self.err(
                        span,
                        DiagnosticKind::Block,
                        "G92 needs at least one axis word",
                    );
                    return false;
                }
                // New offsets so that the current point gets the given coordinates.
                let q = self.to_program(self.st.pos);
                for (i, qi) in q.iter().enumerate() {
                    if let Some(v) = self.axis_value(k, i) {
                        self.st.g92[i] += qi - v;
                    }
                }
                self.store_g92();
                true
            }
            921 => {
                self.st.g92 = [0.0; 6];
                for i in 0..6 {
                    self.params.set(5211 + i as u32, 0.0);
                }
                self.params.set(5210, 0.0);
                true
            }
            922 => {
                self.st.g92 = [0.0; 6];
                self.params.set(5210, 0.0);
                true
            }
            _ => {
                // G92.3: restore the offsets from the parameters.
                self.st.g92 =
                    std::array::from_fn(|i| self.params.get(5211 + i as u32) * self.table_unit(i));
                self.params.set(5210, 1.0);
                true
            }
        }
    }

    /// `G28`/`G30`: rapid through the programmed point to the stored position (all axes when
    /// no axis word is given, else the named ones).
    fn home(&mut self, g28: bool, k: &Checked, span: Span) {
        let Some(p) = self.program_target(k) else {
            return;
        };
        self.mark_axes(k);
        let mid = self.to_machine_from(p, self.to_program(self.st.pos));
        self.emit(MoveKind::Rapid, mid, span, None);
        let base = if g28 { 5161 } else { 5181 };
        let any = (0..6).any(|i| k.w.get(AXES[i]).is_some());
        let mut end = mid;
        for (i, v) in end.iter_mut().enumerate() {
            if !any || k.w.get(AXES[i]).is_some() {
                *v = self.params.get(base + i as u32) * self.table_unit(i);
            }
        }
        self.emit(MoveKind::Rapid, end, span, None);
    }

    /// `G10 L1/L2/L10/L20`.
    fn g10(&mut self, k: &Checked, span: Span) -> bool {
        let Some((l, ls)) = k.w.get('L') else {
            self.err(
                span,
                DiagnosticKind::Block,
                "G10 needs an L word (L1, L2, L10 or L20)",
            );
            return false;
        };
        let Some((p, ps)) = k.w.get('P') else {
            self.err(span, DiagnosticKind::Block, "G10 needs a P word");
            return false;
        };
        if p < 0.0 || p.fract() != 0.0 {
            self.err(ps, DiagnosticKind::Block, || {
                format!("G10 P{p} is not a whole number ≥ 0")
            });
            return false;
        }
        match l {
            2.0 | 20.0 => {
                if p > 9.0 {
                    self.err(ps, DiagnosticKind::Block, || {
                        format!("G10 L{l} P{p}: the coordinate system must be P0 (current) … P9")
                    });
                    return false;
                }
                let index = if p == 0.0 {
                    self.st.coord_index
                } else {
                    p as usize
                };
                self.set_coordinate_system(index, l == 20.0, k);
                true
            }
            1.0 | 10.0 => {
                self.set_tool(p as u32, l == 10.0, k);
                true
            }
            _ => {
                self.err(ls, DiagnosticKind::Unsupported, || {
                    format!("G10 L{l} is not supported (L1, L2, L10, L20)")
                });
                false
            }
        }
    }

    /// `G10 L2` (offsets given) or `L20` (offsets such that the current point has the given
    /// coordinates) for coordinate system `index`.
    fn set_coordinate_system(&mut self, index: usize, l20: bool, k: &Checked) {
        let base = coord_base(index);
        let mut o: [f64; 6] =
            std::array::from_fn(|i| self.params.get(base + i as u32) * self.table_unit(i));
        let mut rot = self.params.get(base + 9);
        if let Some((r, _)) = k.w.get('R') {
            rot = r;
        }
        if l20 {
            // o = m − t − R(p' + o92), p' the current point in that system with the given
            // coordinates.
            let m = self.st.pos;
            let t = self.st.tool_offset;
            let mut q: [f64; 6] = std::array::from_fn(|i| m[i] - t[i] - o[i]);
            (q[0], q[1]) = rotate(q[0], q[1], -rot);
            let mut p: [f64; 6] = std::array::from_fn(|i| q[i] - self.st.g92[i]);
            for (i, v) in p.iter_mut().enumerate() {
                if let Some(x) = self.axis_value(k, i) {
                    *v = x;
                }
            }
            let mut r: [f64; 6] = std::array::from_fn(|i| p[i] + self.st.g92[i]);
            (r[0], r[1]) = rotate(r[0], r[1], rot);
            for i in 0..6 {
                if k.w.get(AXES[i]).is_some() || (i < 2 && rot != 0.0) {
                    o[i] = m[i] - t[i] - r[i];
                }
            }
        } else {
            for (i, v) in o.iter_mut().enumerate() {
                if let Some(x) = self.axis_value(k, i) {
                    *v = x;
                }
            }
        }
        for (i, v) in o.iter().enumerate() {
            self.params.set(base + i as u32, v / self.table_unit(i));
        }
        self.params.set(base + 9, rot);
        if index == self.st.coord_index {
            self.select_coordinate_system(index);
        }
    }

    /// `G10 L1` (tool table entry given) or `L10` (offset such that the current point has the
    /// given coordinates with this tool's offset).
    fn set_tool(&mut self, tool: u32, l10: bool, k: &Checked) {
        let unit: [f64; 6] = std::array::from_fn(|i| self.table_unit(i));
        let entry = self.tools.tools.entry(tool).or_default();
        let mut off: [f64; 6] = std::array::from_fn(|i| entry.offset[i] * unit[i]);
        if l10 {
            let m = self.st.pos;
            let mut q: [f64; 6] =
                std::array::from_fn(|i| m[i] - self.st.g5x[i] - self.st.tool_offset[i]);
            (q[0], q[1]) = rotate(q[0], q[1], -self.st.rotation_deg);
            let mut p: [f64; 6] = std::array::from_fn(|i| q[i] - self.st.g92[i]);
            for (i, v) in p.iter_mut().enumerate() {
                if let Some(x) = self.axis_value(k, i) {
                    *v = x;
                }
            }
            let mut r: [f64; 6] = std::array::from_fn(|i| p[i] + self.st.g92[i]);
            (r[0], r[1]) = rotate(r[0], r[1], self.st.rotation_deg);
            for (i, o) in off.iter_mut().enumerate() {
                if k.w.get(AXES[i]).is_some() {
                    *o = m[i] - self.st.g5x[i] - r[i];
                }
            }
        } else {
            for (i, o) in off.iter_mut().enumerate() {
                if let Some(x) = self.axis_value(k, i) {
                    *o = x;
                }
            }
        }
        let s = self.lscale();
        let mu = self.opts.machine_units.mm();
        let entry = self.tools.tools.entry(tool).or_default();
        for i in 0..6 {
            entry.offset[i] = off[i] / unit[i];
        }
        if let Some((r, _)) = k.w.get('R') {
            entry.diameter = 2.0 * r * s / mu;
        }
        if let Some((i, _)) = k.w.get('I') {
            entry.front_angle_deg = i;
        }
        if let Some((j, _)) = k.w.get('J') {
            entry.back_angle_deg = j;
        }
        if let Some((q, _)) = k.w.get('Q') {
            entry.orientation = q as i32;
        }
    }
}
