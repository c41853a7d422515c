//! G-code *meaning*: the modal interpreter that turns parsed blocks into a [`Toolpath`].
//!
//! Supported (docs/gcode.md; LinuxCNC / NIST RS274NGC v3 semantics where docs/gcode.md is silent):
//!
//! | group | codes |
//! |---|---|
//! | motion | `G0 G1 G2 G3` (arcs: `I J K` centre offsets, always incremental, or `R`; `P` turns) |
//! | non-modal | `G4 P` dwell, `P` in seconds |
//! | plane | `G17 G18 G19` (arc axes (X,Y), (Z,X), (Y,Z): the normal is +Z, +Y, +X) |
//! | units | `G20` inch, `G21` mm |
//! | distance | `G90` absolute, `G91` incremental |
//! | feed mode | `G93` inverse time, `G94` units per minute |
//! | path | `G61` exact stop (default), `G64` continuous (optional `P` tolerance in program units, `Q` accepted) |
//! | tool-centre point | `G43.4` on (optional `H`), `G49` off, plus M-codes mapped by [`InterpOptions`] |
//! | M | `M0 M1` pause, `M2 M30` end, `M3 M4 M5` spindle, `M6` tool change, `M7 M8 M9` coolant |
//! | words | `F S T`, axes `X Y Z A B C` |
//!
//! Order of execution inside a block (NIST RS274NGC v3, section 3.8): feed mode, F, S, T, M6,
//! spindle, coolant, dwell, plane, units, tool-centre point, path mode, distance mode, motion,
//! stop. One deliberate difference: an `F` word is read in the length units the block ends up
//! in (`G20 G1 X1 F10` is 10 inch/min), which is what a programmer writing that line means.
//! The physical feed is kept when the units change later.
//!
//! Units are converted once, here: every length in the [`Toolpath`] is in mm, every angle in
//! degrees (`G20` scales X Y Z I J K R and linear feeds by 25.4; A B C are always degrees).
//!
//! **Feed rule** (docs/gcode.md, NIST RS274NGC v3 section 2.1.2.5): under `G94` the feed `F`
//! applies to the XYZ path length (in TCP mode that *is* the tool-tip path) whenever it is
//! non-zero, and the rotary axes move in proportion; a move of rotary axes alone takes `F` in
//! deg/min along $\sqrt{\Delta A^2+\Delta B^2+\Delta C^2}$. Under `G93` each feed block must carry
//! `F` and lasts $1/F$ minutes.
//!
//! **Initial position**: with [`InterpOptions::initial_position`] `None`, the machine is taken to
//! rest at the target of the first `G0`/`G1` block (axes it does not name are 0), so a program's
//! opening positioning block defines [`Toolpath::start`] and costs no motion. Real programs
//! begin with such a block. If the first motion is an arc, it starts from all-zero axes and a
//! warning says so.
//!
//! Unknown words and codes are errors with line:column, or warnings under
//! [`InterpOptions::lenient`] (then ignored). Modal-group conflicts, repeated words, words without
//! a code that uses them, arcs that do not fit, feed moves without a feed, and `G93` feed blocks
//! without `F` are always errors.

use crate::AxisName;
use crate::diag::{Diagnostic, Message, Severity, Sink, Span};
use crate::syntax::Program;
use std::f64::consts::TAU;

const MM_PER_INCH: f64 = 25.4;

/// Interpreter settings. Plain data; [`Default`] gives the documented defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct InterpOptions {
    /// Downgrade unknown words and codes (and the parser's dialect problems, in
    /// [`crate::load`]) to warnings. Default `false`.
    pub lenient: bool,
    /// Start position of X Y Z A B C (mm, mm, mm, deg, deg, deg). `None` (default): rest at the
    /// first motion block's target (see the module doc).
    pub initial_position: Option<[f64; 6]>,
    /// Block-delete switch: when `true`, lines starting with `/` are skipped. Default `false`
    /// (switch off: they run), as on LinuxCNC and Fanuc controls at power-up.
    pub block_delete: bool,
    /// M-codes that switch tool-centre-point mode on, like `G43.4` (LinuxCNC configs often use
    /// `M428`). Default empty.
    pub tcp_on_mcodes: Vec<u32>,
    /// M-codes that switch tool-centre-point mode off, like `G49` (e.g. `M429`). Default empty.
    pub tcp_off_mcodes: Vec<u32>,
    /// Centre-format arcs: absolute tolerance on |end radius − start radius|, mm. Default
    /// 0.002 mm. See [`InterpOptions::arc_rel_tol`].
    pub arc_abs_tol_mm: f64,
    /// Centre-format arcs: relative tolerance on the radius difference (dimensionless). Default
    /// 0.001. As in LinuxCNC (`interp_arc.cc`), an arc is rejected when the radius difference
    /// exceeds 100 × `arc_abs_tol_mm`, or exceeds both `arc_abs_tol_mm` and `arc_rel_tol` × radius.
    /// Accepted arcs with a small difference run as a spiral whose radius changes linearly.
    pub arc_rel_tol: f64,
    /// Radius-format arcs: how much `|R|` may fall short of half the chord, mm (the arc is then
    /// a half circle). Default 0.00127 mm (LinuxCNC `RADIUS_TOLERANCE_MM`).
    pub arc_r_tol_mm: f64,
    /// Most diagnostics stored (the rest are counted). Default 1000.
    pub max_diagnostics: usize,
}

impl Default for InterpOptions {
    fn default() -> Self {
        InterpOptions {
            lenient: false,
            initial_position: None,
            block_delete: false,
            tcp_on_mcodes: Vec::new(),
            tcp_off_mcodes: Vec::new(),
            arc_abs_tol_mm: 0.002,
            arc_rel_tol: 0.001,
            arc_r_tol_mm: 0.00127,
            max_diagnostics: 1000,
        }
    }
}

/// Arc plane (`G17`, `G18`, `G19`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Plane {
    /// `G17`: first axis X, second Y, normal +Z.
    #[default]
    XY,
    /// `G18`: first axis Z, second X, normal +Y.
    ZX,
    /// `G19`: first axis Y, second Z, normal +X.
    YZ,
}

impl Plane {
    /// Axis indices (0 = X, 1 = Y, 2 = Z) of the first and second in-plane axes and the normal.
    /// Angles are measured from the first axis towards the second; counter-clockwise (`G3`) is
    /// positive when seen from the normal's positive side.
    pub fn axes(self) -> (usize, usize, usize) {
        match self {
            Plane::XY => (0, 1, 2),
            Plane::ZX => (2, 0, 1),
            Plane::YZ => (1, 2, 0),
        }
    }
}

/// Circular (or helical) geometry of a `G2`/`G3` move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcMove {
    /// The arc plane.
    pub plane: Plane,
    /// Centre in the plane: coordinates along the plane's first and second axes, mm.
    pub centre: [f64; 2],
    /// Signed swept angle, rad: positive counter-clockwise (`G3`), negative clockwise (`G2`);
    /// includes the extra full turns of a `P` word.
    pub sweep_rad: f64,
    /// Distance from the centre to the start point, mm.
    pub radius_start_mm: f64,
    /// Distance from the centre to the end point, mm (equal to the start radius within the
    /// arc tolerance; the path is a spiral with linearly varying radius when they differ).
    pub radius_end_mm: f64,
    /// Number of turns programmed with `P` (1 when absent).
    pub turns: u32,
}

/// What a move does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MoveKind {
    /// `G0`: straight line at the axis limits.
    Rapid,
    /// `G1`: straight line at the feed.
    Linear,
    /// `G2`/`G3`: arc at the feed; the axes off the plane move in proportion to the angle.
    Arc(ArcMove),
    /// `G4`: hold still.
    Dwell {
        /// Dwell time, s.
        seconds: f64,
    },
}

/// Programmed feed of a move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Feed {
    /// `G94`: mm/min along the XYZ (tool-tip) path, or deg/min along the rotary path for a move
    /// of rotary axes alone (module doc, feed rule).
    UnitsPerMin(f64),
    /// `G93`: the move lasts 1/F minutes; the value is F in 1/min.
    InverseTime(f64),
}

/// One move of the toolpath, in mm and degrees.
#[derive(Debug, Clone, PartialEq)]
pub struct Move {
    /// Source line (1-based).
    pub line: u32,
    /// Source column of the word that caused the move (1-based).
    pub col: u32,
    /// Rapid, linear, arc or dwell.
    pub kind: MoveKind,
    /// X Y Z A B C at the start (mm, mm, mm, deg, deg, deg).
    pub start: [f64; 6],
    /// X Y Z A B C at the end (mm, mm, mm, deg, deg, deg); equal to `start` for a dwell.
    pub end: [f64; 6],
    /// Feed of `G1`/`G2`/`G3` moves; `None` for rapids and dwells.
    pub feed: Option<Feed>,
    /// `true` under `G61` (rest at the end of the block), `false` under `G64`.
    pub exact_stop: bool,
    /// The machine must come to rest after this move whatever the path mode (`M0`, `M1`, `M6`
    /// or the end of the program follow it).
    pub stop_after: bool,
    /// Tool-centre-point mode: X Y Z are the tool tip in the workpiece frame.
    pub tcp: bool,
    /// `G64 P` blending tolerance, mm (`None`: the interpolator's default).
    pub blend_tolerance_mm: Option<f64>,
}

/// The interpreted program: moves in mm and degrees.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Toolpath {
    /// X Y Z A B C where the machine rests before the first move (mm, mm, mm, deg, deg, deg).
    pub start: [f64; 6],
    /// Moves in program order (zero-length motions are dropped).
    pub moves: Vec<Move>,
    /// Which of X Y Z A B C the program names or moves.
    pub axes_used: [bool; 6],
}

impl Toolpath {
    /// The programmed points: the start, then the end of every motion (dwells excluded).
    pub fn points(&self) -> Vec<[f64; 6]> {
        std::iter::once(self.start)
            .chain(
                self.moves
                    .iter()
                    .filter(|m| !matches!(m.kind, MoveKind::Dwell { .. }))
                    .map(|m| m.end),
            )
            .collect()
    }

    /// Names of the used axes, in X Y Z A B C order.
    pub fn axis_names(&self) -> Vec<AxisName> {
        AxisName::ALL
            .iter()
            .zip(self.axes_used)
            .filter_map(|(&n, u)| u.then_some(n))
            .collect()
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Motion {
    Rapid,
    Linear,
    Cw,
    Ccw,
}

/// Modal state.
#[derive(Debug, Clone)]
struct State {
    pos: [f64; 6],
    motion: Option<Motion>,
    plane: Plane,
    inch: bool,
    absolute: bool,
    inverse_time: bool,
    exact_stop: bool,
    tcp: bool,
    /// Current `G94` feed, mm/min (linear) and the raw value (deg/min for rotary moves).
    feed: Option<(f64, f64)>,
    blend_tol: Option<f64>,
    started: bool,
}

/// Interpret a parsed program.
///
/// Returns the toolpath and the warnings, or every error found (with the warnings).
pub fn interpret(
    program: &Program,
    opts: &InterpOptions,
) -> Result<(Toolpath, Vec<Diagnostic>), Vec<Diagnostic>> {
    let mut it = Interp {
        opts,
        sink: Sink::new(opts.max_diagnostics),
        st: State {
            pos: opts.initial_position.unwrap_or([0.0; 6]),
            motion: None,
            plane: Plane::XY,
            inch: false,
            absolute: true,
            inverse_time: false,
            exact_stop: true,
            tcp: false,
            feed: None,
            blend_tol: None,
            started: opts.initial_position.is_some(),
        },
        tp: Toolpath {
            start: opts.initial_position.unwrap_or([0.0; 6]),
            ..Toolpath::default()
        },
    };
    if let Some(p) = opts.initial_position
        && p.iter().any(|v| !v.is_finite())
    {
        it.sink.push(Diagnostic::error(
            Span {
                line: 1,
                col: 1,
                start: 0,
                end: 0,
            },
            format!("initial position {p:?} is not finite"),
        ));
    }
    let mut seen_percent = false;
    let mut ended_at: Option<u32> = None;
    for (bi, block) in program.blocks.iter().enumerate() {
        if let Some(end_line) = ended_at {
            if !block.words.is_empty() {
                it.sink.push(Diagnostic::warning(
                    block.span,
                    format!("blocks after the program end on line {end_line} are not executed"),
                ));
            }
            break;
        }
        if block.percent {
            if seen_percent || bi > 0 {
                ended_at = Some(block.line);
            }
            seen_percent = true;
            continue;
        }
        if block.block_delete && opts.block_delete {
            continue;
        }
        if block.words.is_empty() {
            continue;
        }
        if it.block(block) {
            ended_at = Some(block.line);
        }
    }
    if let Some(last) = it.tp.moves.last_mut() {
        last.stop_after = true;
    }
    let has_errors = it.sink.has_errors();
    let diags = it.sink.finish();
    if has_errors {
        Err(diags)
    } else {
        Ok((it.tp, diags))
    }
}

struct Interp<'a> {
    opts: &'a InterpOptions,
    sink: Sink,
    st: State,
    tp: Toolpath,
}

/// A G or M code with its span.
type Code = (u32, Span);

/// `value × 10` as an integer when the value has at most one decimal (G43.4 → 434).
fn code10(v: f64) -> Option<u32> {
    let t = v * 10.0;
    let r = t.round();
    ((t - r).abs() < 1e-6 && (0.0..1e7).contains(&r)).then_some(r as u32)
}

fn gname(c: u32) -> String {
    if c.is_multiple_of(10) {
        format!("G{}", c / 10)
    } else {
        format!("G{}.{}", c / 10, c % 10)
    }
}

#[derive(Default)]
struct Groups {
    motion: Option<Code>,
    nonmodal: Option<Code>,
    plane: Option<Code>,
    units: Option<Code>,
    distance: Option<Code>,
    feed_mode: Option<Code>,
    path: Option<Code>,
    tlo: Option<Code>,
    m_stop: Option<Code>,
    m_spindle: Option<Code>,
    m_tool: Option<Code>,
    m_coolant: Vec<Code>,
    m_tcp: Option<(bool, Span)>,
}

fn letter_index(c: char) -> Option<usize> {
    c.is_ascii_uppercase().then(|| (c as u8 - b'A') as usize)
}

impl Interp<'_> {
    fn err(&mut self, span: Span, msg: impl Message) {
        self.sink.report_msg(span, Severity::Error, msg);
    }

    fn unsupported(&mut self, span: Span, msg: impl Message) {
        if self.opts.lenient {
            self.sink.report_msg(span, Severity::Warning, || {
                format!("{} (ignored)", msg.build())
            });
        } else {
            self.sink.report_msg(span, Severity::Error, msg);
        }
    }

    fn set_group(
        &mut self,
        slot: &mut Option<Code>,
        code: Code,
        group: &str,
        name: fn(u32) -> String,
    ) {
        if let Some((prev, _)) = *slot {
            self.err(code.1, || {
                format!(
                    "{} and {} in one block: both belong to the {group} modal group",
                    name(prev),
                    name(code.0)
                )
            });
        } else {
            *slot = Some(code);
        }
    }

    /// Interpret one block; returns `true` at a program end (`M2`, `M30`).
    fn block(&mut self, block: &crate::syntax::Block) -> bool {
        let mut g = Groups::default();
        let mut letters: [Option<(f64, Span)>; 26] = [None; 26];
        let mname = |c: u32| format!("M{c}");
        for w in &block.words {
            match w.letter {
                'G' => match code10(w.value) {
                    Some(c) => {
                        let code = (c, w.span);
                        let slot = match c {
                            0 | 10 | 20 | 30 => Some((&mut g.motion, "motion")),
                            40 => Some((&mut g.nonmodal, "non-modal")),
                            170 | 180 | 190 => Some((&mut g.plane, "plane")),
                            200 | 210 => Some((&mut g.units, "units")),
                            900 | 910 => Some((&mut g.distance, "distance")),
                            930 | 940 => Some((&mut g.feed_mode, "feed-rate mode")),
                            610 | 640 => Some((&mut g.path, "path-control")),
                            434 | 490 => Some((&mut g.tlo, "tool-length")),
                            _ => None,
                        };
                        match slot {
                            Some((slot, group)) => {
                                let mut s = *slot;
                                self.set_group(&mut s, code, group, gname);
                                *slot = s;
                            }
                            None => self
                                .unsupported(w.span, || format!("unsupported G-code {}", gname(c))),
                        }
                    }
                    None => self.unsupported(w.span, || format!("unsupported G-code G{}", w.value)),
                },
                'M' => {
                    let c = (w.value.fract() == 0.0 && (0.0..1e7).contains(&w.value))
                        .then_some(w.value as u32);
                    let Some(c) = c else {
                        self.unsupported(w.span, || format!("unsupported M-code M{}", w.value));
                        continue;
                    };
                    let on = self.opts.tcp_on_mcodes.contains(&c);
                    let off = self.opts.tcp_off_mcodes.contains(&c);
                    if on || off {
                        if let Some((_, s)) = g.m_tcp {
                            self.err(
                                w.span,
                                format!("M{c} and the tool-centre-point M-code at column {} in one block", s.col),
                            );
                        } else {
                            g.m_tcp = Some((on, w.span));
                        }
                        continue;
                    }
                    let code = (c, w.span);
                    match c {
                        0 | 1 | 2 | 30 => {
                            let mut s = g.m_stop;
                            self.set_group(&mut s, code, "stopping", mname);
                            g.m_stop = s;
                        }
                        3..=5 => {
                            let mut s = g.m_spindle;
                            self.set_group(&mut s, code, "spindle", mname);
                            g.m_spindle = s;
                        }
                        6 => {
                            let mut s = g.m_tool;
                            self.set_group(&mut s, code, "tool-change", mname);
                            g.m_tool = s;
                        }
                        7..=9 => {
                            // M7 and M8 may share a block (LinuxCNC); M9 goes alone.
                            let clash = g
                                .m_coolant
                                .iter()
                                .find(|(p, _)| *p == c || *p == 9 || c == 9);
                            if let Some(&(p, _)) = clash {
                                self.err(
                                    w.span,
                                    format!("M{p} and M{c} in one block: both belong to the coolant modal group"),
                                );
                            } else {
                                g.m_coolant.push(code);
                            }
                        }
                        _ => self.unsupported(w.span, || format!("unsupported M-code M{c}")),
                    }
                }
                'A' | 'B' | 'C' | 'X' | 'Y' | 'Z' | 'F' | 'I' | 'J' | 'K' | 'P' | 'Q' | 'R'
                | 'S' | 'T' | 'H' => {
                    let Some(i) = letter_index(w.letter) else {
                        continue;
                    };
                    if let Some((_, first)) = letters[i] {
                        self.err(w.span, || {
                            format!(
                                "word '{}' appears twice in one block (first at column {})",
                                w.letter, first.col
                            )
                        });
                    } else if !w.value.is_finite() {
                        self.err(
                            w.span,
                            format!("value of word '{}' is not finite", w.letter),
                        );
                    } else {
                        letters[i] = Some((w.value, w.span));
                    }
                }
                other => self.unsupported(w.span, || format!("unsupported word '{other}'")),
            }
        }
        let get = |c: char| letter_index(c).and_then(|i| letters[i]);

        // Which commands use which words.
        let block_motion = g.motion.map(|(c, s)| {
            let m = match c {
                0 => Motion::Rapid,
                10 => Motion::Linear,
                20 => Motion::Cw,
                _ => Motion::Ccw,
            };
            (m, s)
        });
        let axis_words: Vec<(usize, f64, Span)> = AxisName::ALL
            .iter()
            .enumerate()
            .filter_map(|(i, n)| get(n.letter()).map(|(v, s)| (i, v, s)))
            .collect();
        let motion = block_motion.map(|(m, _)| m).or(self.st.motion);
        let moving = !axis_words.is_empty();
        let arc_move = moving && matches!(motion, Some(Motion::Cw | Motion::Ccw));
        let dwell = g.nonmodal.is_some();
        let path_g64 = matches!(g.path, Some((640, _)));
        let tcp_g434 = matches!(g.tlo, Some((434, _)));
        if moving && motion.is_none() {
            let s = axis_words[0].2;
            self.err(
                s,
                "axis words with no motion mode active (G0, G1, G2 or G3)",
            );
        }
        for c in ['I', 'J', 'K', 'R'] {
            if let Some((_, s)) = get(c)
                && !arc_move
            {
                self.err(s, format!("'{c}' word with no G2/G3 arc move to use it"));
            }
        }
        if let Some((_, s)) = get('P')
            && !(dwell || arc_move || path_g64)
        {
            self.err(s, "'P' word with no G4, G64 or G2/G3 arc move to use it");
        }
        if let Some((_, s)) = get('P')
            && dwell
            && arc_move
        {
            self.err(
                s,
                "'P' word is ambiguous: G4 dwell and G2/G3 turns in one block",
            );
        }
        if let Some((_, s)) = get('Q')
            && !path_g64
        {
            self.err(s, "'Q' word with no G64 to use it");
        }
        if let Some((v, s)) = get('H') {
            if !tcp_g434 {
                self.err(s, "'H' word with no G43.4 to use it");
            } else if v < 0.0 || v.fract() != 0.0 {
                self.err(s, format!("H{v} is not a tool number (a whole number ≥ 0)"));
            }
        }
        if let Some((v, s)) = get('T')
            && (v < 0.0 || v.fract() != 0.0)
        {
            self.err(s, format!("T{v} is not a tool number (a whole number ≥ 0)"));
        }
        if let Some((v, s)) = get('S')
            && v < 0.0
        {
            self.err(s, format!("spindle speed S{v} is negative"));
        }
        if let (Some(_), Some((_, s))) = (g.m_tcp, g.tlo) {
            self.err(s, "G43.4/G49 and a tool-centre-point M-code in one block");
        }

        // 1. feed mode; 2. F.
        if let Some((c, _)) = g.feed_mode {
            let inverse = c == 930;
            if inverse != self.st.inverse_time {
                // Changing the feed mode leaves no valid feed (LinuxCNC resets it).
                self.st.feed = None;
            }
            self.st.inverse_time = inverse;
        }
        let inch_after = match g.units {
            Some((200, _)) => true,
            Some(_) => false,
            None => self.st.inch,
        };
        let lscale = if inch_after { MM_PER_INCH } else { 1.0 };
        let mut f_block = None;
        if let Some((f, s)) = get('F') {
            if f < 0.0 {
                self.err(s, format!("feed rate F{f} is negative"));
            } else {
                f_block = Some((f, s));
                if !self.st.inverse_time {
                    self.st.feed = Some((f * lscale, f));
                }
            }
        }
        // 6. tool change: the machine must be at rest.
        if g.m_tool.is_some()
            && let Some(last) = self.tp.moves.last_mut()
        {
            last.stop_after = true;
        }
        // 10. dwell.
        if dwell {
            match get('P') {
                Some((p, s)) if p < 0.0 => self.err(s, format!("dwell time P{p} is negative")),
                Some((p, _)) => {
                    let span = g.nonmodal.map_or(block.span, |c| c.1);
                    self.tp.moves.push(Move {
                        line: span.line,
                        col: span.col,
                        kind: MoveKind::Dwell { seconds: p },
                        start: self.st.pos,
                        end: self.st.pos,
                        feed: None,
                        exact_stop: true,
                        stop_after: true,
                        tcp: self.st.tcp,
                        blend_tolerance_mm: None,
                    });
                }
                None => {
                    let s = g.nonmodal.map_or(block.span, |c| c.1);
                    self.err(s, "G4 dwell without a P word (seconds)");
                }
            }
        }
        // 11. plane; 12. units.
        if let Some((c, _)) = g.plane {
            self.st.plane = match c {
                170 => Plane::XY,
                180 => Plane::ZX,
                _ => Plane::YZ,
            };
        }
        self.st.inch = inch_after;
        // 14. tool-centre point.
        match (g.tlo, g.m_tcp) {
            (Some((434, _)), _) | (None, Some((true, _))) => self.st.tcp = true,
            (Some(_), _) | (None, Some((false, _))) => self.st.tcp = false,
            (None, None) => {}
        }
        // 16. path mode.
        if let Some((c, _)) = g.path {
            self.st.exact_stop = c == 610;
            self.st.blend_tol = None;
            if c == 640
                && let Some((p, s)) = get('P')
            {
                if p < 0.0 {
                    self.err(s, format!("G64 tolerance P{p} is negative"));
                } else if p > 0.0 {
                    self.st.blend_tol = Some(p * lscale);
                }
            }
        }
        // 17. distance mode.
        if let Some((c, _)) = g.distance {
            self.st.absolute = c == 900;
        }
        // 20. motion.
        if let Some((m, _)) = block_motion {
            self.st.motion = Some(m);
        }
        if moving && let Some(m) = motion {
            let span = block_motion.map_or(axis_words[0].2, |(_, s)| s);
            let mut target = self.st.pos;
            for &(i, v, _) in &axis_words {
                let v = if i < 3 { v * lscale } else { v };
                target[i] = if self.st.absolute {
                    v
                } else {
                    self.st.pos[i] + v
                };
                self.tp.axes_used[i] = true;
            }
            if let Some(&(i, _, s)) = axis_words.iter().find(|&&(i, _, _)| !target[i].is_finite()) {
                self.err(
                    s,
                    format!(
                        "{} target is out of range after unit conversion",
                        AxisName::ALL[i]
                    ),
                );
                return false;
            }
            self.motion(m, target, span, f_block, &get, lscale);
        }
        // 21. stop.
        match g.m_stop {
            Some((0 | 1, _)) => {
                if let Some(last) = self.tp.moves.last_mut() {
                    last.stop_after = true;
                }
                false
            }
            Some(_) => true,
            None => false,
        }
    }

    fn feed_for(
        &mut self,
        span: Span,
        f_block: Option<(f64, Span)>,
        pure_rotary: bool,
    ) -> Option<Feed> {
        if self.st.inverse_time {
            match f_block {
                Some((f, _)) if f > 0.0 => Some(Feed::InverseTime(f)),
                Some((_, s)) => {
                    self.err(s, "G93 inverse-time feed F0: the move would take forever");
                    None
                }
                None => {
                    self.err(
                        span,
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
                    self.err(span, "feed move with feed rate F0");
                    None
                }
                None => {
                    self.err(span, "feed move with no feed rate set (F)");
                    None
                }
            }
        }
    }

    fn motion(
        &mut self,
        m: Motion,
        target: [f64; 6],
        span: Span,
        f_block: Option<(f64, Span)>,
        get: &dyn Fn(char) -> Option<(f64, Span)>,
        lscale: f64,
    ) {
        let start = self.st.pos;
        let xyz_zero = (0..3).all(|i| target[i] == start[i]);
        let feed = match m {
            Motion::Rapid => None,
            _ => self.feed_for(span, f_block, xyz_zero && m == Motion::Linear),
        };
        let kind = match m {
            Motion::Rapid => MoveKind::Rapid,
            Motion::Linear => MoveKind::Linear,
            Motion::Cw | Motion::Ccw => {
                if !self.st.started {
                    self.sink.push(Diagnostic::warning(
                        span,
                        "the first motion is an arc: it starts from all axes at 0",
                    ));
                    self.st.started = true;
                }
                match self.arc(m == Motion::Ccw, start, target, span, get, lscale) {
                    Some(a) => MoveKind::Arc(a),
                    None => return,
                }
            }
        };
        if !self.st.started {
            // The opening positioning block defines the start (module doc).
            self.st.started = true;
            self.tp.start = target;
            for mv in &mut self.tp.moves {
                mv.start = target;
                mv.end = target;
            }
            self.st.pos = target;
            return;
        }
        self.st.pos = target;
        if m != Motion::Rapid && feed.is_none() {
            // The missing feed has been reported.
            return;
        }
        if target == start && !matches!(kind, MoveKind::Arc(_)) {
            return;
        }
        self.tp.moves.push(Move {
            line: span.line,
            col: span.col,
            kind,
            start,
            end: target,
            feed,
            exact_stop: self.st.exact_stop,
            stop_after: false,
            tcp: self.st.tcp,
            blend_tolerance_mm: self.st.blend_tol,
        });
    }

    fn arc(
        &mut self,
        ccw: bool,
        start: [f64; 6],
        end: [f64; 6],
        span: Span,
        get: &dyn Fn(char) -> Option<(f64, Span)>,
        lscale: f64,
    ) -> Option<ArcMove> {
        let plane = self.st.plane;
        let (u, v, w) = plane.axes();
        let offset_letters = ['I', 'J', 'K'];
        let (su, sv) = (start[u], start[v]);
        let (eu, ev) = (end[u], end[v]);
        let turns = match get('P') {
            None => 1,
            Some((p, s)) => {
                if p < 1.0 || p.fract() != 0.0 || p > 1e6 {
                    self.err(s, format!("arc turns P{p} must be a whole number ≥ 1"));
                    return None;
                }
                p as u32
            }
        };
        let pname = match plane {
            Plane::XY => "G17",
            Plane::ZX => "G18",
            Plane::YZ => "G19",
        };
        let r_word = get('R');
        let has_offsets = offset_letters.iter().any(|&c| get(c).is_some());
        let (cu, cv) = if let Some((r, rs)) = r_word {
            if has_offsets {
                self.err(rs, "arc with both R and I/J/K: use one form");
                return None;
            }
            let r = r * lscale;
            let (du, dv) = (eu - su, ev - sv);
            let chord = du.hypot(dv);
            if chord == 0.0 {
                self.err(
                    rs,
                    "R-form arc with the end point equal to the start: a full circle needs I/J/K",
                );
                return None;
            }
            if r == 0.0 {
                self.err(rs, "arc radius R0");
                return None;
            }
            let half = chord / 2.0;
            let h2 = r * r - half * half;
            let h = if h2 >= 0.0 {
                h2.sqrt()
            } else if half - r.abs() <= self.opts.arc_r_tol_mm {
                0.0
            } else {
                self.err(
                    rs,
                    format!(
                        "arc radius |R| = {:.6} mm is smaller than half the chord ({:.6} mm)",
                        r.abs(),
                        half
                    ),
                );
                return None;
            };
            // Left normal of the chord; G3 with R > 0 has its centre on the left.
            let (nu, nv) = (-dv / chord, du / chord);
            let side = if ccw == (r > 0.0) { 1.0 } else { -1.0 };
            (su + du / 2.0 + side * h * nu, sv + dv / 2.0 + side * h * nv)
        } else {
            let normal_letter = offset_letters[w];
            if let Some((_, s)) = get(normal_letter) {
                self.err(
                    s,
                    format!("'{normal_letter}' word in a {pname} arc: centre offsets must lie in the arc plane"),
                );
                return None;
            }
            let ou = get(offset_letters[u]);
            let ov = get(offset_letters[v]);
            if ou.is_none() && ov.is_none() {
                self.err(
                    span,
                    format!(
                        "{pname} arc needs R or at least one of {}, {}",
                        offset_letters[u], offset_letters[v]
                    ),
                );
                return None;
            }
            (
                su + ou.map_or(0.0, |o| o.0 * lscale),
                sv + ov.map_or(0.0, |o| o.0 * lscale),
            )
        };
        let r0 = (su - cu).hypot(sv - cv);
        let r1 = (eu - cu).hypot(ev - cv);
        if r0.is_nan() || r0 <= 0.0 || !r0.is_finite() || !r1.is_finite() {
            self.err(span, "arc centre coincides with the start point");
            return None;
        }
        if r_word.is_none() {
            let abs_err = (r1 - r0).abs();
            let rel_err = abs_err / r0.max(r1);
            if abs_err > 100.0 * self.opts.arc_abs_tol_mm
                || (abs_err > self.opts.arc_abs_tol_mm && rel_err > self.opts.arc_rel_tol)
            {
                self.err(
                    span,
                    format!(
                        "radius to the end of the arc differs from the radius to the start: \
                         r_start = {r0:.6} mm, r_end = {r1:.6} mm, difference {abs_err:.6} mm \
                         ({:.4} %)",
                        100.0 * rel_err
                    ),
                );
                return None;
            }
        }
        let t0 = (sv - cv).atan2(su - cu);
        let t1 = (ev - cv).atan2(eu - cu);
        let same = (eu - su).hypot(ev - sv) <= 1e-9;
        // Unsigned sweep in (0, 2π] in the direction of travel; equal points make a full circle.
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
        let sweep = if ccw { magnitude } else { -magnitude };
        if !(sweep.is_finite() && cu.is_finite() && cv.is_finite()) {
            self.err(span, "arc geometry is out of range");
            return None;
        }
        Some(ArcMove {
            plane,
            centre: [cu, cv],
            sweep_rad: sweep,
            radius_start_mm: r0,
            radius_end_mm: r1,
            turns,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::syntax::parse;
    use std::f64::consts::{FRAC_PI_2, PI};

    fn run(src: &str) -> Result<(Toolpath, Vec<Diagnostic>), Vec<Diagnostic>> {
        run_with(src, &InterpOptions::default())
    }

    fn run_with(
        src: &str,
        opts: &InterpOptions,
    ) -> Result<(Toolpath, Vec<Diagnostic>), Vec<Diagnostic>> {
        let (p, d) = parse(src);
        assert!(d.is_empty(), "{d:?}");
        interpret(&p, opts)
    }

    fn ok(src: &str) -> Toolpath {
        match run(src) {
            Ok((tp, _)) => tp,
            Err(e) => panic!("{src}: {e:?}"),
        }
    }

    /// (line, col) of every error.
    fn errors(src: &str) -> Vec<(u32, u32)> {
        match run(src) {
            Ok(_) => Vec::new(),
            Err(d) => d
                .iter()
                .filter(|d| d.is_error())
                .map(|d| (d.line, d.col))
                .collect(),
        }
    }

    fn arc(m: &Move) -> ArcMove {
        match m.kind {
            MoveKind::Arc(a) => a,
            k => panic!("not an arc: {k:?}"),
        }
    }

    #[test]
    fn opening_block_defines_the_start() {
        let tp = ok("G4 P1\nG0 X10 Y5\nG1 X20 F600");
        assert_eq!(tp.start, [10.0, 5.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(tp.moves.len(), 2);
        // The dwell before the first motion holds at the start.
        assert_eq!(tp.moves[0].start, tp.start);
        assert_eq!(tp.moves[1].end, [20.0, 5.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(tp.moves[1].feed, Some(Feed::UnitsPerMin(600.0)));
        let opts = InterpOptions {
            initial_position: Some([1.0; 6]),
            ..InterpOptions::default()
        };
        let (tp, _) = run_with("G0 X10 Y5", &opts).unwrap();
        assert_eq!(tp.start, [1.0; 6]);
        assert_eq!(tp.moves.len(), 1);
        assert_eq!(tp.points().len(), 2);
    }

    #[test]
    fn incremental_equals_absolute() {
        let a = ok("G0 X1 Y2\nG90 G1 X4 Y6 A30 F100\nX0");
        let b = ok("G0 X1 Y2\nG91 G1 X3 Y4 A30 F100\nX-4");
        assert_eq!(a, b);
    }

    #[test]
    fn inch_converts_lengths_and_linear_feeds_only() {
        // 1 in = 25.4 mm exactly; rotary words and pure rotary feeds are not scaled.
        let tp = ok("G20 G0 X1 A0\nG1 X2 F10\nG1 A90 F3600");
        assert_eq!(tp.start[0], 25.4);
        assert_eq!(tp.moves[0].end[0], 50.8);
        assert_eq!(tp.moves[0].feed, Some(Feed::UnitsPerMin(254.0)));
        assert_eq!(tp.moves[1].end[3], 90.0);
        assert_eq!(tp.moves[1].feed, Some(Feed::UnitsPerMin(3600.0)));
    }

    #[test]
    fn modal_conflicts_and_repeats_are_errors_with_columns() {
        assert_eq!(errors("G0 G1 X1 F1"), vec![(1, 4)]);
        assert_eq!(errors("G90 G91"), vec![(1, 5)]);
        assert_eq!(errors("G0 X1\nG1 X1 X2 F1"), vec![(2, 7)]);
        assert_eq!(errors("M3 M5"), vec![(1, 4)]);
        assert_eq!(errors("M8 M9"), vec![(1, 4)]);
        assert!(errors("M7 M8").is_empty());
        assert_eq!(errors("G17 G18"), vec![(1, 5)]);
    }

    #[test]
    fn words_without_a_user_are_errors() {
        assert_eq!(errors("G0 X0\nG1 X1 I2 F100"), vec![(2, 7)]);
        assert_eq!(errors("G1 P2 F100"), vec![(1, 4)]);
        assert_eq!(errors("H1"), vec![(1, 1)]);
        assert_eq!(errors("X1"), vec![(1, 1)]);
        assert_eq!(errors("G4"), vec![(1, 1)]);
        assert!(errors("G43.4 H1 G64 P0.01 Q0.01").is_empty());
    }

    #[test]
    fn feeds_must_be_set() {
        // No feed ever set.
        assert_eq!(errors("G0 X0\nG1 X1"), vec![(2, 1)]);
        // G93: F on every feed block.
        assert_eq!(errors("G0 X0\nG93 G1 X1 F2\nG1 X3"), vec![(3, 1)]);
        // Leaving G93 leaves no feed.
        assert_eq!(errors("G0 X0\nG93 G1 X1 F2\nG94 G1 X3"), vec![(3, 5)]);
        let tp = ok("G0 X0\nG93 G1 X1 F2\nG0 X0\nG1 X3 F4");
        assert_eq!(tp.moves[0].feed, Some(Feed::InverseTime(2.0)));
        assert_eq!(tp.moves[1].feed, None);
        assert_eq!(tp.moves[2].feed, Some(Feed::InverseTime(4.0)));
    }

    #[test]
    fn unknown_codes_are_errors_or_lenient_warnings() {
        let src = "G0 X0\nG54 G1 X1 F100 E5 M587";
        assert_eq!(errors(src), vec![(2, 1), (2, 16), (2, 19)]);
        let opts = InterpOptions {
            lenient: true,
            ..InterpOptions::default()
        };
        let (tp, warnings) = run_with(src, &opts).unwrap();
        assert_eq!(tp.moves.len(), 1);
        assert_eq!(warnings.len(), 3);
        assert!(warnings.iter().all(|w| w.severity == Severity::Warning));
        assert!(warnings[0].message.contains("G54"));
    }

    #[test]
    fn centre_format_arcs() {
        // Quarter circle clockwise about the origin: from angle 0 to −90°.
        let tp = ok("G0 X10 Y0\nG2 X0 Y-10 I-10 J0 F100");
        let a = arc(&tp.moves[0]);
        assert_eq!(a.centre, [0.0, 0.0]);
        assert!((a.sweep_rad + FRAC_PI_2).abs() < 1e-12);
        assert_eq!(a.radius_start_mm, 10.0);
        // Full circle, and two turns with P2.
        let tp = ok("G0 X10 Y0\nG3 X10 Y0 I-10 F100\nG3 X10 Y0 I-10 P2");
        assert!((arc(&tp.moves[0]).sweep_rad - 2.0 * PI).abs() < 1e-12);
        assert!((arc(&tp.moves[1]).sweep_rad - 4.0 * PI).abs() < 1e-12);
        // G18: first axis Z, second X; K and I offsets.
        let tp = ok("G18 G0 X0 Z10\nG3 X10 Z0 K-10 F100");
        let a = arc(&tp.moves[0]);
        assert_eq!(a.plane, Plane::ZX);
        assert_eq!(a.centre, [0.0, 0.0]);
        assert!((a.sweep_rad - FRAC_PI_2).abs() < 1e-12);
        // Offsets off the plane are errors.
        assert_eq!(errors("G0 X10 Y0\nG2 X0 Y-10 I-10 K1 F100"), vec![(2, 17)]);
    }

    #[test]
    fn radius_format_arcs() {
        // G3 from (1,0) to (0,1): R1 → centre (0,0), 90°; R−1 → centre (1,1), 270°.
        let tp = ok("G0 X1 Y0\nG3 X0 Y1 R1 F100\nG0 X1 Y0\nG3 X0 Y1 R-1");
        let a = arc(&tp.moves[0]);
        assert!(a.centre[0].abs() < 1e-12 && a.centre[1].abs() < 1e-12);
        assert!((a.sweep_rad - FRAC_PI_2).abs() < 1e-12);
        let b = arc(&tp.moves[2]);
        assert!((b.centre[0] - 1.0).abs() < 1e-12 && (b.centre[1] - 1.0).abs() < 1e-12);
        assert!((b.sweep_rad - 1.5 * PI).abs() < 1e-12);
        // G2 with R > 0 puts the centre on the right: (1,0) → (0,1) centre (1,1), −90°.
        let tp = ok("G0 X1 Y0\nG2 X0 Y1 R1 F100");
        let c = arc(&tp.moves[0]);
        assert!((c.centre[0] - 1.0).abs() < 1e-12 && (c.centre[1] - 1.0).abs() < 1e-12);
        assert!((c.sweep_rad + FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn arcs_that_do_not_fit_are_errors() {
        // End radius 10.5 vs start radius 10: 5 %, far over 0.002 mm and 0.1 %.
        assert_eq!(errors("G0 X10 Y0\nG2 X0 Y-10.5 I-10 J0 F100"), vec![(2, 1)]);
        // Within 0.002 mm: accepted (runs as a spiral).
        let tp = ok("G0 X10 Y0\nG2 X0 Y-10.001 I-10 J0 F100");
        assert!((arc(&tp.moves[0]).radius_end_mm - 10.001).abs() < 1e-12);
        // R shorter than half the chord (5 mm).
        assert_eq!(errors("G0 X0 Y0\nG2 X10 Y0 R4 F100"), vec![(2, 11)]);
        // A 1.27 µm shortfall is tolerated (LinuxCNC RADIUS_TOLERANCE_MM): a half circle.
        let tp = ok("G0 X0 Y0\nG2 X10 Y0 R4.999 F100");
        assert_eq!(errors("G0 X0 Y0\nG2 X10 Y0 R4.99 F100"), vec![(2, 11)]);
        assert!((arc(&tp.moves[0]).sweep_rad + PI).abs() < 1e-12);
        // R and I together; no offsets at all.
        assert_eq!(errors("G0 X0 Y0\nG2 X10 Y0 R5 I5 F100"), vec![(2, 11)]);
        assert_eq!(errors("G0 X0 Y0\nG2 X10 Y0 F100"), vec![(2, 1)]);
    }

    #[test]
    fn tcp_mode_by_g43_4_or_mapped_m_codes() {
        let tp = ok("G0 X0\nG43.4 H1\nG1 X1 F100\nG49\nG1 X2");
        assert!(tp.moves[0].tcp && !tp.moves[1].tcp);
        let opts = InterpOptions {
            tcp_on_mcodes: vec![428],
            tcp_off_mcodes: vec![429],
            ..InterpOptions::default()
        };
        let (tp, _) = run_with("G0 X0\nM428\nG1 X1 F100\nM429\nG1 X2", &opts).unwrap();
        assert!(tp.moves[0].tcp && !tp.moves[1].tcp);
        assert_eq!(errors("M428"), vec![(1, 1)]);
    }

    #[test]
    fn path_mode_stops_and_program_end() {
        let tp = ok("%\nG0 X0\nG64 P0.05 G1 X1 F100\nM6 T2\nG1 X2\nM0\nG61 G1 X3\nM30\nG1 X9\n%");
        assert_eq!(tp.moves.len(), 3);
        assert!(!tp.moves[0].exact_stop && tp.moves[0].stop_after);
        assert_eq!(tp.moves[0].blend_tolerance_mm, Some(0.05));
        assert!(tp.moves[1].stop_after);
        assert!(tp.moves[2].exact_stop);
        let (_, warnings) = run("G0 X0\nM2\nG1 X9").unwrap();
        assert_eq!(warnings.len(), 1);
        assert_eq!(warnings[0].line, 3);
    }

    #[test]
    fn block_delete_switch() {
        let src = "G0 X0\n/G0 X5\nG0 X1";
        assert_eq!(ok(src).moves.len(), 2);
        let opts = InterpOptions {
            block_delete: true,
            ..InterpOptions::default()
        };
        assert_eq!(run_with(src, &opts).unwrap().0.moves.len(), 1);
    }

    #[test]
    fn dwell_and_units_order() {
        let tp = ok("G0 X0\nG4 P0.5\nG20 G1 X1 F10");
        assert_eq!(tp.moves[0].kind, MoveKind::Dwell { seconds: 0.5 });
        // F read in the block's final units: 10 in/min.
        assert_eq!(tp.moves[1].feed, Some(Feed::UnitsPerMin(254.0)));
    }
}
