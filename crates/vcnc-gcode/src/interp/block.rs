//! One block in the three stages of LinuxCNC's interpreter: **collect** the words into a typed
//! block (values evaluated), **check** it (modal groups, missing and extra words), **apply** it
//! (execute in LinuxCNC's order, `Interp::execute_block`). See the parent module's doc.

use super::eval::Target;
use super::{Cycle, Interp, MM_PER_INCH, Motion, PathMode, Plane, code10, gname};
use crate::diag::{DiagnosticKind, Severity, Span};
use crate::syntax::Block;

/// Index of the polar radius `@` in [`Collected::letters`].
pub(super) const AT: usize = 26;
/// Index of the polar angle `^`.
pub(super) const CARET: usize = 27;

/// A value with the span of its word.
pub(super) type Val = Option<(f64, Span)>;

fn letter_index(c: char) -> Option<usize> {
    match c {
        'A'..='Z' => Some(c as usize - 'A' as usize),
        '@' => Some(AT),
        '^' => Some(CARET),
        _ => None,
    }
}

/// A block after **collect**: every value evaluated.
pub(super) struct Collected {
    /// G-codes × 10 (`G43.4` → 434) with their spans, in source order.
    g: Vec<(u32, Span)>,
    /// M-codes with their spans.
    m: Vec<(u32, Span)>,
    /// Letter values: `A`…`Z`, then `@` and `^`.
    pub(super) letters: [Val; 28],
    /// Parameter assignments, evaluated, in source order.
    assigns: Vec<(Target, f64)>,
    /// `(ABORT, message)`.
    abort: Option<(String, Span)>,
}

impl Collected {
    pub(super) fn get(&self, c: char) -> Val {
        letter_index(c).and_then(|i| self.letters[i])
    }

    /// Any of X Y Z A B C `@` `^`.
    pub(super) fn has_axis_words(&self) -> bool {
        [0, 1, 2].iter().any(|&i| self.letters[23 + i].is_some())
            || [0, 1, 2].iter().any(|&i| self.letters[i].is_some())
            || self.letters[AT].is_some()
            || self.letters[CARET].is_some()
    }

    /// The first axis word's span.
    pub(super) fn first_axis_span(&self) -> Option<Span> {
        ['X', 'Y', 'Z', 'A', 'B', 'C', '@', '^']
            .iter()
            .filter_map(|&c| self.get(c).map(|(_, s)| s))
            .min_by_key(|s| s.col)
    }
}

/// G-code modal groups (LinuxCNC numbering in comments).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Group {
    /// 0: G4 G10 G28 G28.1 G30 G30.1 G52 G53 G92 G92.1 G92.2 G92.3.
    NonModal,
    /// 1: G0 G1 G2 G3 G73 G80 G81 G82 G83 G85 G89.
    Motion,
    /// 2: G17 G18 G19.
    Plane,
    /// 3: G90 G91.
    Distance,
    /// 4: G90.1 G91.1.
    ArcDistance,
    /// 5: G93 G94.
    FeedMode,
    /// 6: G20 G21.
    Units,
    /// 7: G40 G41 G41.1 G42 G42.1.
    Cutter,
    /// 8: G43 G43.1 G43.2 G49 (and vcnc's G43.4).
    ToolLength,
    /// 10: G98 G99.
    Retract,
    /// 12: G54 … G59.3.
    Coord,
    /// 13: G61 G61.1 G64.
    Path,
    /// 14: G96 G97.
    SpindleMode,
}

impl Group {
    fn name(self) -> &'static str {
        match self {
            Group::NonModal => "non-modal",
            Group::Motion => "motion",
            Group::Plane => "plane",
            Group::Distance => "distance",
            Group::ArcDistance => "arc distance",
            Group::FeedMode => "feed-rate mode",
            Group::Units => "units",
            Group::Cutter => "cutter compensation",
            Group::ToolLength => "tool length offset",
            Group::Retract => "canned-cycle return",
            Group::Coord => "coordinate system",
            Group::Path => "path control",
            Group::SpindleMode => "spindle speed mode",
        }
    }
}

/// The group of a supported G-code, or why it is not supported.
fn g_group(c: u32) -> Result<Group, (DiagnosticKind, &'static str)> {
    use DiagnosticKind::Unsupported;
    Ok(match c {
        40 | 100 | 280 | 281 | 300 | 301 | 520 | 530 | 920 | 921 | 922 | 923 => Group::NonModal,
        0 | 10 | 20 | 30 | 730 | 800 | 810 | 820 | 830 | 850 | 890 => Group::Motion,
        170 | 180 | 190 => Group::Plane,
        900 | 910 => Group::Distance,
        901 | 911 => Group::ArcDistance,
        930 | 940 => Group::FeedMode,
        200 | 210 => Group::Units,
        400 | 410 | 411 | 420 | 421 => Group::Cutter,
        430 | 431 | 432 | 434 | 490 => Group::ToolLength,
        980 | 990 => Group::Retract,
        540 | 550 | 560 | 570 | 580 | 590 | 591 | 592 | 593 => Group::Coord,
        610 | 611 | 640 => Group::Path,
        960 | 970 => Group::SpindleMode,
        50..=53 => {
            return Err((Unsupported, "splines (G5 G5.1 G5.2 G5.3) are not supported"));
        }
        70 | 80 => {
            return Err((
                Unsupported,
                "lathe diameter/radius mode (G7 G8) is not supported",
            ));
        }
        330 | 331 | 760 => {
            return Err((
                Unsupported,
                "spindle-synchronised motion (G33 G33.1 G76) is not supported",
            ));
        }
        382..=385 => return Err((Unsupported, "probing (G38.x) is not supported")),
        740 | 840 | 860 | 870 | 880 => {
            return Err((
                Unsupported,
                "this canned cycle is not supported (supported: G73 G81 G82 G83 G85 G89)",
            ));
        }
        700 | 710 | 720 => {
            return Err((Unsupported, "lathe cycles (G70 G71 G72) are not supported"));
        }
        171 | 181 | 191 => {
            return Err((
                Unsupported,
                "U V W planes (G17.1 G18.1 G19.1) are not supported",
            ));
        }
        950 => return Err((Unsupported, "feed per revolution (G95) is not supported")),
        _ => return Err((Unsupported, "unknown or unsupported G-code")),
    })
}

/// A block after **check**: codes sorted by group, the motion to run decided.
pub(super) struct Checked<'c> {
    pub(super) w: &'c Collected,
    pub(super) nonmodal: Option<(u32, Span)>,
    motion_code: Option<(u32, Span)>,
    plane: Option<(u32, Span)>,
    distance: Option<(u32, Span)>,
    arc_distance: Option<(u32, Span)>,
    feed_mode: Option<(u32, Span)>,
    units: Option<(u32, Span)>,
    cutter: Option<(u32, Span)>,
    tool_length: Option<(u32, Span)>,
    retract: Option<(u32, Span)>,
    coord: Option<(u32, Span)>,
    path: Option<(u32, Span)>,
    m_stop: Option<(u32, Span)>,
    m_tool: Option<(u32, Span)>,
    m_tcp: Option<(bool, Span)>,
    /// The motion this block runs (explicit, or the modal one triggered by axis words) and the
    /// span of what triggered it. `None`: no motion (or `G80`).
    pub(super) motion_to_be: Option<(Motion, Span)>,
}

fn motion_of(code: u32) -> Option<Motion> {
    Some(match code {
        0 => Motion::Rapid,
        10 => Motion::Linear,
        20 => Motion::Cw,
        30 => Motion::Ccw,
        730 => Motion::Cycle(Cycle::G73),
        810 => Motion::Cycle(Cycle::G81),
        820 => Motion::Cycle(Cycle::G82),
        830 => Motion::Cycle(Cycle::G83),
        850 => Motion::Cycle(Cycle::G85),
        890 => Motion::Cycle(Cycle::G89),
        _ => return None,
    })
}

impl Interp<'_> {
    /// Run one block; `true` at a program end (`M2`, `M30`, `(ABORT)`).
    pub(super) fn block(&mut self, block: &Block) -> bool {
        if block.words.is_empty() && block.assignments.is_empty() && block.comments.is_empty() {
            return false;
        }
        let Some(collected) = self.collect(block) else {
            return false;
        };
        let Some(checked) = self.check(&collected) else {
            return false;
        };
        self.apply(&checked)
    }

    /// **Collect**: evaluate the words and assignments (with the parameters as they were before
    /// the line) and sort them. `None` when a value could not be evaluated (reported).
    fn collect(&mut self, block: &Block) -> Option<Collected> {
        let mut c = Collected {
            g: Vec::new(),
            m: Vec::new(),
            letters: [None; 28],
            assigns: Vec::with_capacity(block.assignments.len()),
            abort: None,
        };
        let mut ok = true;
        for com in &block.comments {
            let t = com.text.trim_start();
            if let (Some(head), Some(rest)) = (t.get(..6), t.get(6..))
                && head.eq_ignore_ascii_case("abort,")
            {
                c.abort = Some((rest.trim().to_string(), com.span));
            }
        }
        for w in &block.words {
            let value = match w.expr {
                None => w.value,
                Some(e) => match self.eval(e) {
                    Ok(v) => v,
                    Err(e) => {
                        self.sink
                            .report_msg(e.span, Severity::Error, e.kind, e.message);
                        ok = false;
                        continue;
                    }
                },
            };
            match w.letter {
                'G' => match code10(value) {
                    Some(code) => c.g.push((code, w.span)),
                    None => {
                        self.err(w.span, DiagnosticKind::Unsupported, || {
                            format!("G{value} is not a G-code (at most one decimal)")
                        });
                        ok = false;
                    }
                },
                'M' => {
                    if value.fract() == 0.0 && (0.0..1e7).contains(&value) {
                        c.m.push((value as u32, w.span));
                    } else {
                        self.err(w.span, DiagnosticKind::Unsupported, || {
                            format!("M{value} is not an M-code (a whole number)")
                        });
                        ok = false;
                    }
                }
                'U' | 'V' | 'W' => {
                    self.err(w.span, DiagnosticKind::Unsupported, || {
                        format!("axis {} is not supported (vcnc has X Y Z A B C)", w.letter)
                    });
                    ok = false;
                }
                'E' | 'O' | 'N' => {
                    self.harmless(w.span, || format!("unsupported word '{}'", w.letter))
                }
                letter => {
                    let Some(i) = letter_index(letter) else {
                        self.harmless(w.span, || format!("unsupported word '{letter}'"));
                        continue;
                    };
                    if let Some((_, first)) = c.letters[i] {
                        self.err(w.span, DiagnosticKind::Block, || {
                            format!(
                                "word '{letter}' appears twice in one block (first at column {})",
                                first.col
                            )
                        });
                        ok = false;
                    } else {
                        c.letters[i] = Some((value, w.span));
                    }
                }
            }
        }
        for a in &block.assignments {
            let r = self
                .target(a.target, a.span)
                .and_then(|t| self.eval(a.value).map(|v| (t, v)));
            match r {
                Ok(tv) => c.assigns.push(tv),
                Err(e) => {
                    self.sink
                        .report_msg(e.span, Severity::Error, e.kind, e.message);
                    ok = false;
                }
            }
        }
        ok.then_some(c)
    }

    /// **Check**: sort the codes into their modal groups (one per group), refuse unsupported
    /// ones, decide the motion, and check that every word has a code that uses it.
    fn check<'c>(&mut self, w: &'c Collected) -> Option<Checked<'c>> {
        let mut k = Checked {
            nonmodal: None,
            motion_code: None,
            plane: None,
            distance: None,
            arc_distance: None,
            feed_mode: None,
            units: None,
            cutter: None,
            tool_length: None,
            retract: None,
            coord: None,
            path: None,
            m_stop: None,
            m_tool: None,
            m_tcp: None,
            motion_to_be: None,
            w,
        };
        let mut ok = self.check_g_groups(&mut k);
        ok &= self.check_m_groups(&mut k);
        if let (Some(_), Some((_, s))) = (k.m_tcp, k.tool_length) {
            self.err(
                s,
                DiagnosticKind::Block,
                "G43.4/G49 and a tool-centre-point M-code in one block",
            );
            ok = false;
        }
        ok &= self.check_motion(&mut k);
        ok &= self.check_words(&k);
        ok.then_some(k)
    }

    /// One G-code per modal group; unsupported codes refused.
    fn check_g_groups(&mut self, k: &mut Checked<'_>) -> bool {
        let mut ok = true;
        for &(code, span) in &k.w.g {
            let group = match g_group(code) {
                Ok(g) => g,
                Err((kind, why)) => {
                    self.err(span, kind, || format!("{}: {why}", gname(code)));
                    ok = false;
                    continue;
                }
            };
            let slot = match group {
                Group::NonModal => &mut k.nonmodal,
                Group::Motion => &mut k.motion_code,
                Group::Plane => &mut k.plane,
                Group::Distance => &mut k.distance,
                Group::ArcDistance => &mut k.arc_distance,
                Group::FeedMode => &mut k.feed_mode,
                Group::Units => &mut k.units,
                Group::Cutter => &mut k.cutter,
                Group::ToolLength => &mut k.tool_length,
                Group::Retract => &mut k.retract,
                Group::Coord => &mut k.coord,
                Group::Path => &mut k.path,
                // G96/G97 do not change the path.
                Group::SpindleMode => continue,
            };
            if let Some((prev, _)) = *slot {
                self.sink.report_msg(
                    span,
                    Severity::Error,
                    DiagnosticKind::Block,
                    format!(
                        "{} and {} in one block: both belong to the {} modal group",
                        gname(prev),
                        gname(code),
                        group.name()
                    ),
                );
                ok = false;
            } else {
                *slot = Some((code, span));
            }
        }
        ok
    }

    /// One M-code per modal group (M7 with M8 allowed); unsupported codes refused.
    fn check_m_groups(&mut self, k: &mut Checked<'_>) -> bool {
        let mut ok = true;
        let mut m_spindle: Option<(u32, Span)> = None;
        let mut m_coolant: Vec<(u32, Span)> = Vec::new();
        for &(c, span) in &k.w.m {
            let on = self.opts.tcp_on_mcodes.contains(&c);
            if on || self.opts.tcp_off_mcodes.contains(&c) {
                if let Some((_, s)) = k.m_tcp {
                    self.err(span, DiagnosticKind::Block, || {
                        format!(
                            "M{c} and the tool-centre-point M-code at column {} in one block",
                            s.col
                        )
                    });
                    ok = false;
                } else {
                    k.m_tcp = Some((on, span));
                }
                continue;
            }
            let (slot, group) = match c {
                0 | 1 | 2 | 30 | 60 => (&mut k.m_stop, "stopping"),
                3..=5 => (&mut m_spindle, "spindle"),
                6 | 61 => (&mut k.m_tool, "tool-change"),
                7..=9 => {
                    // M7 and M8 may share a block (LinuxCNC); M9 goes alone.
                    let clash = m_coolant.iter().find(|(p, _)| *p == c || *p == 9 || c == 9);
                    if let Some(&(p, _)) = clash {
                        self.err(span, DiagnosticKind::Block, || {
                            format!(
                                "M{p} and M{c} in one block: both belong to the coolant modal group"
                            )
                        });
                        ok = false;
                    } else {
                        m_coolant.push((c, span));
                    }
                    continue;
                }
                // Overrides, spindle orientation, digital and analog I/O: no effect on the path.
                19 | 48..=53 | 62..=68 => continue,
                70..=73 => {
                    self.err(span, DiagnosticKind::Unsupported, || {
                        format!(
                            "M{c}: saving and restoring the modal state (M70–M73) is not supported"
                        )
                    });
                    ok = false;
                    continue;
                }
                100..=199 => {
                    self.harmless(span, || {
                        format!("M{c}: user-defined M-codes (external programs) are not supported")
                    });
                    continue;
                }
                _ => {
                    self.err(span, DiagnosticKind::Unsupported, || {
                        format!("unsupported M-code M{c}")
                    });
                    ok = false;
                    continue;
                }
            };
            if let Some((prev, _)) = *slot {
                self.err(span, DiagnosticKind::Block, || {
                    format!("M{prev} and M{c} in one block: both belong to the {group} modal group")
                });
                ok = false;
            } else {
                *slot = Some((c, span));
            }
        }
        ok
    }

    /// Decide the motion of the block (LinuxCNC `enhance_block`).
    fn check_motion(&mut self, k: &mut Checked) -> bool {
        let axes = k.w.has_axis_words();
        // G10, G28, G30, G52, G92 and G43.1 take the axis words themselves.
        let nonmodal_uses_axes = matches!(k.nonmodal, Some((100 | 280 | 300 | 520 | 920, _)))
            || matches!(k.tool_length, Some((431, _)));
        let ijk = ['I', 'J', 'K'].iter().any(|&c| k.w.get(c).is_some());
        match k.motion_code {
            Some((800, s)) => {
                if axes && !nonmodal_uses_axes {
                    let span = k.w.first_axis_span().unwrap_or(s);
                    self.err(
                        span,
                        DiagnosticKind::Block,
                        "axis words with G80 (G80 cancels the motion mode)",
                    );
                    return false;
                }
                k.motion_to_be = None;
            }
            Some((code, s)) => {
                if nonmodal_uses_axes && let Some((g0, s0)) = k.nonmodal.or(k.tool_length) {
                    self.err(s0, DiagnosticKind::Block, || {
                        format!(
                            "{} and {} in one block: both use the axis words",
                            gname(code),
                            gname(g0)
                        )
                    });
                    let _ = s;
                    return false;
                }
                k.motion_to_be = motion_of(code).map(|m| (m, s));
            }
            None if nonmodal_uses_axes => {}
            None => {
                let arc_mode = matches!(self.st.motion, Some(Motion::Cw | Motion::Ccw));
                if axes || (ijk && arc_mode) {
                    let span =
                        k.w.first_axis_span()
                            .or_else(|| {
                                ['I', 'J', 'K']
                                    .iter()
                                    .find_map(|&c| k.w.get(c).map(|v| v.1))
                            })
                            .unwrap_or_default();
                    match self.st.motion {
                        Some(m) => k.motion_to_be = Some((m, span)),
                        None => {
                            self.err(
                                span,
                                DiagnosticKind::Block,
                                "axis words with no motion mode active (G0, G1, G2, G3 or a canned cycle; G80 cancels it)",
                            );
                            return false;
                        }
                    }
                }
            }
        }
        if let Some((530, s)) = k.nonmodal
            && !matches!(k.motion_to_be, Some((Motion::Rapid | Motion::Linear, _)))
        {
            self.err(
                s,
                DiagnosticKind::Block,
                "G53 needs G0 or G1 (machine coordinates for one straight move)",
            );
            return false;
        }
        true
    }

    /// Every word must have a code that uses it (LinuxCNC `check_other_codes`).
    fn check_words(&mut self, k: &Checked) -> bool {
        let mut ok = true;
        let motion = k.motion_to_be.map(|m| m.0);
        let arc = matches!(motion, Some(Motion::Cw | Motion::Ccw));
        let cycle = matches!(motion, Some(Motion::Cycle(_)));
        let nonmodal = k.nonmodal.map(|n| n.0);
        let g10 = nonmodal == Some(100);
        let dwell = nonmodal == Some(40);
        let g64 = matches!(k.path, Some((640, _)));
        let tlo = k.tool_length.map(|t| t.0);
        let mut no_user = |it: &mut Self, c: char, users: &str| {
            if let Some((_, s)) = k.w.get(c) {
                it.err(s, DiagnosticKind::Block, || {
                    format!("'{c}' word with no {users} to use it")
                });
                ok = false;
            }
        };
        if !(arc || g10) {
            for c in ['I', 'J', 'K'] {
                no_user(self, c, "G2/G3 arc");
            }
        }
        if !(arc || cycle || g10) {
            no_user(self, 'R', "G2/G3 arc, canned cycle or G10");
        }
        let p_cycle = matches!(motion, Some(Motion::Cycle(Cycle::G82 | Cycle::G89)));
        let p_m = k.w.m.iter().any(|(m, _)| matches!(m, 62..=68));
        if !(dwell || g10 || arc || g64 || p_cycle || p_m) {
            no_user(self, 'P', "G4, G10, G64, G82, G89 or G2/G3 arc");
        }
        let q_cycle = matches!(motion, Some(Motion::Cycle(Cycle::G73 | Cycle::G83)));
        let m61 = matches!(k.m_tool, Some((61, _)));
        if !(g64 || q_cycle || m61 || p_m || g10) {
            no_user(self, 'Q', "G64, G73, G83 or M61");
        }
        let comp_on = matches!(k.cutter, Some((410 | 411 | 420 | 421, _)));
        let comp_dynamic = matches!(k.cutter, Some((411 | 421, _)));
        if !(g10 || cycle || comp_dynamic) {
            no_user(self, 'L', "G10, G41.1, G42.1 or canned cycle");
        }
        if !matches!(tlo, Some(430 | 432 | 434)) {
            no_user(self, 'H', "G43, G43.2 or G43.4");
        }
        if !comp_on {
            no_user(
                self,
                'D',
                "G41/G42/G41.1/G42.1 (cutter radius compensation)",
            );
        }
        if let Some((p, s)) = k.w.get('P')
            && arc
            && dwell
        {
            self.err(
                s,
                DiagnosticKind::Block,
                "'P' word is ambiguous: G4 dwell and G2/G3 turns in one block",
            );
            let _ = p;
            ok = false;
        }
        if let Some((v, s)) = k.w.get('H')
            && (v < 0.0 || v.fract() != 0.0)
        {
            self.err(s, DiagnosticKind::Block, || {
                format!("H{v} is not a tool number (a whole number ≥ 0)")
            });
            ok = false;
        }
        if let Some((v, s)) = k.w.get('T')
            && (v < 0.0 || v.fract() != 0.0 || v > f64::from(u32::MAX))
        {
            self.err(s, DiagnosticKind::Block, || {
                format!("T{v} is not a tool number (a whole number ≥ 0)")
            });
            ok = false;
        }
        if let Some((v, s)) = k.w.get('S')
            && v < 0.0
        {
            self.err(s, DiagnosticKind::Block, || {
                format!("spindle speed S{v} is negative")
            });
            ok = false;
        }
        if let Some((v, s)) = k.w.get('F')
            && v < 0.0
        {
            self.err(s, DiagnosticKind::Block, || {
                format!("feed rate F{v} is negative")
            });
            ok = false;
        }
        let polar = k.w.get('@').or(k.w.get('^'));
        if let Some((_, s)) = polar {
            if matches!(k.nonmodal, Some((530, _))) {
                self.err(
                    s,
                    DiagnosticKind::Block,
                    "polar coordinates (@ ^) cannot be used with G53",
                );
                ok = false;
            } else if k.w.get('X').is_some() || k.w.get('Y').is_some() {
                self.err(
                    s,
                    DiagnosticKind::Block,
                    "polar coordinates (@ ^) and X or Y words in one block",
                );
                ok = false;
            } else if motion.is_none() {
                self.err(
                    s,
                    DiagnosticKind::Block,
                    "polar coordinates (@ ^) need a motion (G0, G1, G2, G3 or a cycle)",
                );
                ok = false;
            }
        }
        if cycle && let Some((_, s)) = ['A', 'B', 'C'].iter().find_map(|&c| k.w.get(c)) {
            self.err(
                s,
                DiagnosticKind::Block,
                "rotary axes cannot move in a canned cycle",
            );
            ok = false;
        }
        ok
    }

    /// **Apply**: store the assignments, then execute in LinuxCNC's order (parent module doc).
    /// `true` at a program end.
    fn apply(&mut self, k: &Checked<'_>) -> bool {
        for &(t, v) in &k.w.assigns {
            self.assign(t, v);
        }
        if let Some((msg, s)) = &k.w.abort {
            self.err(*s, DiagnosticKind::Abort, || {
                format!("program aborted: {msg}")
            });
            return true;
        }
        if !(self.apply_settings(k) && self.apply_modes(k)) {
            return false;
        }
        if let Some((c, s)) = k.nonmodal
            && c != 40
            && c != 530
            && !self.nonmodal(c, k, s)
        {
            return false;
        }
        self.apply_motion(k);
        // Stops.
        match k.m_stop {
            Some((0 | 1 | 60, _)) => {
                self.stop_after_last();
                false
            }
            Some(_) => true,
            None => false,
        }
    }

    /// Feed mode, `F`, `S`, `T`, tool change and tool-centre-point M-codes. `F` is read in the
    /// units in force before this block's `G20`/`G21`, which come later.
    fn apply_settings(&mut self, k: &Checked<'_>) -> bool {
        if let Some((c, _)) = k.feed_mode {
            let inverse = c == 930;
            if inverse != self.st.inverse_time {
                // Changing the feed mode leaves no valid feed (LinuxCNC resets it).
                self.st.feed = None;
            }
            self.st.inverse_time = inverse;
        }
        if let Some((f, _)) = k.w.get('F')
            && !self.st.inverse_time
        {
            self.st.feed = Some((f * self.lscale(), f));
        }
        if let Some((s, _)) = k.w.get('S') {
            self.st.spindle_rpm = s;
        }
        if let Some((t, _)) = k.w.get('T') {
            // Checked to be a whole number in range.
            self.st.selected_tool = t as u32;
        }
        match k.m_tool {
            Some((6, _)) => {
                // The machine must be at rest for a tool change.
                self.st.current_tool = self.st.selected_tool;
                self.stop_after_last();
            }
            Some((_, s)) => match k.w.get('Q') {
                Some((q, _)) if q >= 0.0 && q.fract() == 0.0 => self.st.current_tool = q as u32,
                _ => {
                    self.err(s, DiagnosticKind::Block, "M61 needs Q<tool number>");
                    return false;
                }
            },
            None => {}
        }
        if let Some((on, _)) = k.m_tcp {
            self.st.tcp = on;
            if on {
                self.st.tool_offset = [0.0; 6];
            }
        }
        true
    }

    /// `G4`, then the modal groups in LinuxCNC's order: plane, units, tool length offset,
    /// coordinate system, path control, distance modes, canned-cycle return.
    fn apply_modes(&mut self, k: &Checked<'_>) -> bool {
        if let Some((40, s)) = k.nonmodal {
            self.dwell(k, s);
        }
        if let Some((c, s)) = k.plane {
            let plane = match c {
                170 => Plane::XY,
                180 => Plane::ZX,
                _ => Plane::YZ,
            };
            if self.comp_on() && plane != self.st.plane {
                self.comp_refuse(s, "cannot change planes");
                return false;
            }
            self.st.plane = match c {
                170 => Plane::XY,
                180 => Plane::ZX,
                _ => Plane::YZ,
            };
        }
        if let Some((c, _)) = k.units {
            self.st.inch = c == 200;
        }
        if let Some((c, s)) = k.cutter
            && !self.cutter_mode(c, k, s)
        {
            return false;
        }
        if self.comp_on() {
            // What LinuxCNC refuses while compensation is on.
            let refused = [
                (k.tool_length, "cannot change the tool length offset"),
                (k.coord, "cannot change coordinate systems"),
                (k.retract, "cannot change the canned-cycle return mode"),
                (k.m_tool.filter(|m| m.0 == 6), "cannot change tools (M6)"),
                (
                    k.nonmodal.filter(|n| matches!(n.0, 280 | 300)),
                    "cannot use G28 or G30",
                ),
                (
                    k.nonmodal.filter(|n| matches!(n.0, 281 | 301)),
                    "cannot set a reference point (G28.1, G30.1)",
                ),
                (
                    k.nonmodal
                        .filter(|n| matches!(n.0, 520 | 920 | 921 | 922 | 923)),
                    "cannot change axis offsets (G52, G92)",
                ),
                (
                    k.motion_to_be
                        .filter(|m| matches!(m.0, Motion::Cycle(_)))
                        .map(|m| (0, m.1)),
                    "cannot use canned cycles",
                ),
            ];
            if let Some((what, s)) = refused
                .iter()
                .find_map(|(code, what)| code.map(|(_, s)| (*what, s)))
            {
                self.comp_refuse(s, what);
                return false;
            }
        }
        if let Some((c, s)) = k.tool_length
            && !self.tool_length(c, k, s)
        {
            return false;
        }
        if let Some((c, _)) = k.coord {
            let index = match c {
                540..=590 => ((c - 530) / 10) as usize,
                591 => 7,
                592 => 8,
                _ => 9,
            };
            self.select_coordinate_system(index);
        }
        if let Some((c, _)) = k.path {
            self.st.path = match c {
                610 => PathMode::ExactPath,
                611 => PathMode::ExactStop,
                _ => {
                    // G64 P Q as LinuxCNC's convert_control_mode: P0 or no P is a plain G64;
                    // Q defaults to P.
                    let tol = |letter: char, this: &mut Self| -> Option<f64> {
                        let (v, s) = k.w.get(letter)?;
                        if v < 0.0 {
                            this.err(s, DiagnosticKind::Block, || {
                                format!("G64 tolerance {letter}{v} is negative")
                            });
                            return None;
                        }
                        (v > 0.0).then(|| v * this.lscale())
                    };
                    let tolerance_mm = tol('P', self);
                    let merge_mm = if k.w.get('Q').is_some() {
                        tol('Q', self)
                    } else {
                        tolerance_mm
                    };
                    PathMode::Blend {
                        tolerance_mm,
                        merge_mm,
                    }
                }
            };
        }
        if let Some((c, _)) = k.distance {
            self.st.absolute = c == 900;
        }
        if let Some((c, _)) = k.arc_distance {
            self.st.arc_absolute = c == 901;
        }
        if let Some((c, _)) = k.retract {
            self.st.retract_r_plane = c == 990;
        }
        true
    }

    /// The motion mode and the block's motion. Any motion but a cycle ends a series of cycles
    /// (LinuxCNC's `cycle_il_flag`).
    fn apply_motion(&mut self, k: &Checked<'_>) {
        let prev = self.st.motion;
        let runs = match (k.motion_code, k.motion_to_be) {
            (Some((c, _)), _) => Some(motion_of(c)),
            (None, Some((m, _))) => Some(Some(m)),
            (None, None) => None,
        };
        if let Some(m) = runs
            && !matches!(m, Some(Motion::Cycle(_)))
        {
            self.st.cycle.il = None;
        }
        if let Some((c, _)) = k.motion_code {
            self.st.motion = motion_of(c);
        }
        if let Some((m, s)) = k.motion_to_be {
            let f_block = k.w.get('F');
            match m {
                Motion::Rapid | Motion::Linear => self.straight(m, k, s, f_block),
                Motion::Cw | Motion::Ccw => self.arc_block(m == Motion::Ccw, k, s, f_block),
                Motion::Cycle(c) => self.cycle(c, k, s, prev),
            }
        }
    }

    /// Length scale of program units: 25.4 mm per inch under `G20`, else 1.
    pub(super) fn lscale(&self) -> f64 {
        if self.st.inch { MM_PER_INCH } else { 1.0 }
    }

    pub(super) fn stop_after_last(&mut self) {
        if self.mark_held_stop() {
            return;
        }
        if let Some(last) = self.tp.moves.last_mut() {
            last.stop_after = true;
        }
    }
}
