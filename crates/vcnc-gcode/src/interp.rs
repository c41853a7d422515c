//! G-code *meaning*: the interpreter that runs a parsed [`Program`] and produces a
//! [`Toolpath`], as LinuxCNC's RS274/NGC interpreter does. The supported language — codes,
//! parameters, expressions, O-word control flow, offsets, canned cycles — and every deliberate
//! difference from LinuxCNC are listed in docs/gcode.md.
//!
//! Stages, in the order LinuxCNC's interpreter uses for each block (`Interp::read` →
//! `check_items` → `execute_block`):
//!
//! 1. **collect** (module `block`): evaluate every word's value and every parameter assignment with
//!    the parameter values from *before* the line, and sort the words into G-codes, M-codes
//!    and letter values;
//! 2. **check**: modal-group conflicts, repeated words, words no code uses, missing words;
//! 3. **apply**: store the line's parameter assignments (they take effect at the end of the
//!    line, before its codes run), then execute in LinuxCNC's order: feed mode, `F`, `S`, `T`,
//!    M-codes, `G4`, plane, units, cutter compensation, tool length offset, coordinate system,
//!    path mode, distance modes, retract mode, `G10`/`G28`/`G30`/`G52`/`G92`, motion, stops.
//!
//! O-word statements (subroutines, conditions, loops) are matched once before the run
//! (module `flow`), so the run is linear in the program length apart from the loops themselves.
//! A streamed program ([`ChunkInterp`], module `seek`) runs through the same loop
//! (`Interp::run_piece`) a piece of the file at a time, its statements matched as they are
//! first read. A
//! program that does not end is stopped by [`InterpOptions::max_loop_iterations`].
//!
//! **Coordinates.** The interpreter keeps the machine position (machine coordinates, mm and
//! deg) and converts each programmed point as LinuxCNC's canonical layer does:
//! $$ \mathbf{m} = R_z(\theta)\,(\mathbf{p} + \mathbf{o}_{92}) + \mathbf{o}_{5x} + \mathbf{t} $$
//! with $\mathbf{p}$ the programmed point in mm and deg, $\mathbf{o}_{92}$ the G92/G52 offset,
//! $R_z(\theta)$ the rotation of the active coordinate system (`G10 L2 R`) about Z,
//! $\mathbf{o}_{5x}$ its offset (G54–G59.3) and $\mathbf{t}$ the tool offset (G43). Every
//! length in the [`Toolpath`] is in mm and every angle in degrees.
//!
//! **Start.** The machine rests at [`InterpOptions::start`] (default: every axis at 0, as after
//! homing) and the first block moves from there, as on a control. ([`StartPosition::FirstMove`]
//! keeps the behaviour of vcnc before this rule, for callers that have no start position yet.)
//!
//! **Feed rule** (docs/gcode.md, NIST RS274NGC v3 section 2.1.2.5): under `G94` the feed `F`
//! applies to the XYZ path length (in TCP mode that *is* the tool-tip path) whenever it is
//! non-zero, and the rotary axes move in proportion; a move of rotary axes alone takes `F` in
//! deg/min along $\sqrt{\Delta A^2+\Delta B^2+\Delta C^2}$. Under `G93` each feed block must carry
//! `F` and lasts $1/F$ minutes. As in LinuxCNC, `F` is read in the length units in force when
//! the block starts (`G20 G1 X1 F10` is 10 mm/min after `G21`): the feed comes before the
//! units change in the order above.
//!
//! Unknown words and codes are errors with line:column. [`InterpOptions::lenient`] downgrades
//! to warnings only what cannot change the path (`E` words, user M-codes `M100`–`M199`);
//! anything that changes what moves where is an error even then.

mod block;
mod comp;
mod cycles;
mod eval;
mod flow;
mod motion;
mod seek;

pub use seek::{ChunkInterp, ProgramRead, YIELD_MOVES};

use std::collections::HashMap;

use crate::AxisName;
use crate::diag::{Diagnostic, DiagnosticKind, Message, Severity, Sink, Span};
use crate::syntax::{NameId, OLabel, OStatement, OWord, Program};
use crate::tables::{LengthUnit, ParameterTable, ToolTable};
use eval::Params;
use flow::{Flow, Jump, LoopKind};

const MM_PER_INCH: f64 = 25.4;

/// Interpreter settings. Plain data; [`Default`] gives the documented defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct InterpOptions {
    /// Downgrade to warnings the problems that cannot change the path: unknown `E` words and
    /// user M-codes `M100`–`M199` (and the parser's dialect problems, in [`crate::load`]).
    /// Default `false`.
    pub lenient: bool,
    /// Where the machine rests before the first block. Default
    /// [`StartPosition::Machine`] with every axis at 0, as after homing.
    pub start: StartPosition,
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
    /// Numbered parameters at start (work offsets, G28/G30 positions, …), e.g. from a LinuxCNC
    /// parameter file ([`crate::parse_parameter_file`]). Default: all 0, G54 active.
    pub parameters: ParameterTable,
    /// Tools for `G43 H`, e.g. from a LinuxCNC tool table ([`crate::parse_tool_table`]).
    /// Default empty.
    pub tools: ToolTable,
    /// Length unit of [`InterpOptions::parameters`] and [`InterpOptions::tools`] (LinuxCNC
    /// `[TRAJ] LINEAR_UNITS`). Default mm.
    pub machine_units: LengthUnit,
    /// Most loop iterations (all `while`, `do` and `repeat` loops together); one more is an
    /// error naming the loop's line, so a program that never ends stops. Default 10 000 000.
    pub max_loop_iterations: u64,
    /// Deepest nesting of subroutine calls. Default 10 (LinuxCNC `INTERP_SUB_ROUTINE_LEVELS`).
    pub max_call_depth: usize,
    /// Most moves in the toolpath. Default 10 000 000 (about 1.5 GB of moves).
    pub max_moves: usize,
    /// The path mode before the program sets one (a control's start-up code). Default
    /// [`PathMode::ExactStop`] (`G61.1`); LinuxCNC 2.9 starts in a plain `G64` unless its INI
    /// file's start-up code names a mode (docs/gcode.md, "Path modes").
    pub path_mode: PathMode,
}

impl Default for InterpOptions {
    fn default() -> Self {
        InterpOptions {
            lenient: false,
            start: StartPosition::default(),
            block_delete: false,
            tcp_on_mcodes: Vec::new(),
            tcp_off_mcodes: Vec::new(),
            arc_abs_tol_mm: 0.002,
            arc_rel_tol: 0.001,
            arc_r_tol_mm: 0.00127,
            max_diagnostics: 1000,
            parameters: ParameterTable::default(),
            tools: ToolTable::default(),
            machine_units: LengthUnit::Mm,
            max_loop_iterations: 10_000_000,
            max_call_depth: 10,
            max_moves: 10_000_000,
            path_mode: PathMode::ExactStop,
        }
    }
}

/// Where the machine rests before the first block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StartPosition {
    /// At X Y Z A B C (mm, mm, mm, deg, deg, deg, machine coordinates); the first block moves
    /// from there, as on a control. In tool-centre-point mode the interpreter reads X Y Z as the
    /// tool tip (it has no kinematics).
    Machine([f64; 6]),
    /// vcnc's behaviour before issue 13, for callers without a start position: the machine
    /// rests at the target of the first straight motion (axes it does not name at 0), so that
    /// motion costs nothing; a first arc starts from all-zero axes, with a warning. A control
    /// does not do this: it hides the program's first move.
    FirstMove,
}

impl Default for StartPosition {
    fn default() -> Self {
        StartPosition::Machine([0.0; 6])
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
    /// Centre in the plane: coordinates along the plane's first and second axes, mm (machine
    /// coordinates).
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
    /// `G0` (and the positioning moves of cycles, `G28`, `G30`): straight line at the axis
    /// limits.
    Rapid,
    /// `G1` (and the feed moves of cycles): straight line at the feed.
    Linear,
    /// `G2`/`G3`: arc at the feed; the axes off the plane move in proportion to the angle.
    Arc(ArcMove),
    /// `G4` (and cycle dwells): hold still.
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

/// One move of the toolpath, in mm and degrees (machine coordinates).
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
    /// The path mode in force (modal group 13: `G61.1`, `G61`, `G64 P Q`).
    pub path: PathMode,
    /// The machine must come to rest after this move whatever the path mode (`M0`, `M1`, `M6`
    /// or the end of the program follow it).
    pub stop_after: bool,
    /// Tool-centre-point mode: X Y Z are the tool tip in the workpiece frame.
    pub tcp: bool,
}

/// How a block ends and how the next one joins it: the path mode in force when the block runs
/// (modal group 13), as LinuxCNC 2.9 reads it (docs/gcode.md, "Path modes").
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PathMode {
    /// `G61.1`, exact stop: the machine comes to rest at the end of the block.
    ExactStop,
    /// `G61`, exact path: the path runs through the programmed end point; the machine stops
    /// there only where the path turns (a corner), and runs on where the next block continues
    /// in the same direction.
    ExactPath,
    /// `G64 [P] [Q]`, continuous path: corners are blended.
    Blend {
        /// `P`: the blend may leave the programmed corner by at most this much, mm; `None` for
        /// a plain `G64` (no `P`, or `P0`): the planner's own rule.
        tolerance_mm: Option<f64>,
        /// `Q`: consecutive straight feed moves that stay within this distance of one straight
        /// line are merged into one move, mm; `None`: no merging. A `G64 P` without `Q` merges
        /// within `P`, as in LinuxCNC.
        merge_mm: Option<f64>,
    },
}

impl PathMode {
    /// `G61.1`: rest at the end of every block.
    pub fn is_exact_stop(&self) -> bool {
        matches!(self, PathMode::ExactStop)
    }

    /// A path mode written as its G-code: `G61.1`, `G61`, `G64`, `G64 P<mm>`, `G64 P<mm> Q<mm>`
    /// (mm; `P0` is a plain `G64`, `Q` defaults to `P`, as in LinuxCNC); `None` for anything
    /// else. Case and blanks between words do not matter.
    pub fn parse(text: &str) -> Option<PathMode> {
        let words: Vec<String> = text.split_whitespace().map(str::to_uppercase).collect();
        let first = words.first()?;
        match (first.as_str(), words.len()) {
            ("G61.1", 1) => return Some(PathMode::ExactStop),
            ("G61", 1) => return Some(PathMode::ExactPath),
            ("G64", _) => {}
            _ => return None,
        }
        let (mut p, mut q) = (None, None);
        for w in &words[1..] {
            let v: f64 = w.get(1..)?.parse().ok()?;
            if !(v.is_finite() && v >= 0.0) {
                return None;
            }
            match w.as_bytes()[0] {
                b'P' if p.is_none() => p = Some(v),
                b'Q' if q.is_none() => q = Some(v),
                _ => return None,
            }
        }
        let positive = |x: Option<f64>| x.filter(|v| *v > 0.0);
        Some(PathMode::Blend {
            tolerance_mm: positive(p),
            merge_mm: if q.is_some() {
                positive(q)
            } else {
                positive(p)
            },
        })
    }
}

/// The interpreted program: moves in mm and degrees.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Toolpath {
    /// X Y Z A B C where the machine rests before the first move (mm, mm, mm, deg, deg, deg):
    /// [`InterpOptions::start`].
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

/// Canned cycles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Cycle {
    G73,
    G81,
    G82,
    G83,
    G85,
    G89,
}

/// Modal motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Motion {
    Rapid,
    Linear,
    Cw,
    Ccw,
    Cycle(Cycle),
}

impl Motion {
    /// The G-code × 10 (`G73` → 730).
    pub(crate) fn code10(self) -> u32 {
        match self {
            Motion::Rapid => 0,
            Motion::Linear => 10,
            Motion::Cw => 20,
            Motion::Ccw => 30,
            Motion::Cycle(c) => match c {
                Cycle::G73 => 730,
                Cycle::G81 => 810,
                Cycle::G82 => 820,
                Cycle::G83 => 830,
                Cycle::G85 => 850,
                Cycle::G89 => 890,
            },
        }
    }
}

/// Sticky values of canned cycles (LinuxCNC `cycle_*` settings), program units.
#[derive(Debug, Clone, Copy, Default)]
struct CycleMemory {
    /// Initial level: the clear-plane height (normal axis) when the cycles started.
    il: Option<f64>,
    r: f64,
    z: f64,
    p: f64,
    q: f64,
}

/// Modal state.
#[derive(Debug, Clone)]
struct State {
    /// Machine position, mm and deg.
    pos: [f64; 6],
    /// `None` after `G80` (and at start).
    motion: Option<Motion>,
    plane: Plane,
    inch: bool,
    absolute: bool,
    /// `G90.1`: arc centres I J K absolute.
    arc_absolute: bool,
    inverse_time: bool,
    path: PathMode,
    tcp: bool,
    /// Current `G94` feed: mm/min (linear) and the raw value (deg/min for rotary moves).
    feed: Option<(f64, f64)>,
    spindle_rpm: f64,
    current_tool: u32,
    selected_tool: u32,
    /// Tool offset X Y Z A B C, mm and deg.
    tool_offset: [f64; 6],
    /// Active coordinate system, 1 (G54) … 9 (G59.3).
    coord_index: usize,
    /// Its offset, mm and deg.
    g5x: [f64; 6],
    /// Its XY rotation, deg.
    rotation_deg: f64,
    /// G92/G52 offset, mm and deg.
    g92: [f64; 6],
    /// `G99` (true, LinuxCNC's start-up mode) or `G98`.
    retract_r_plane: bool,
    cycle: CycleMemory,
    /// Line being executed.
    line: u32,
    /// `false` until the first motion under [`StartPosition::FirstMove`].
    started: bool,
    /// Cutter radius compensation (module `comp`).
    comp: comp::CompState,
}

/// One subroutine call (the main program is the first frame).
#[derive(Debug, Default)]
struct Frame {
    /// Block to continue at after the return.
    return_to: usize,
    /// The caller's `#1`–`#30`.
    saved: Option<Box<[f64; 30]>>,
    /// Named local parameters.
    locals: HashMap<NameId, f64>,
    /// Active `repeat` loops: (`repeat` block, iterations left).
    repeats: Vec<(usize, u64)>,
}

/// Interpret a parsed program.
///
/// Returns the toolpath and the warnings, or every error found (with the warnings).
pub fn interpret(
    program: &Program,
    opts: &InterpOptions,
) -> Result<(Toolpath, Vec<Diagnostic>), Vec<Diagnostic>> {
    let mut it = Interp::new(program, opts);
    it.run();
    it.release_held();
    conclude(it.sink, it.tp)
}

/// The end of a run: the last move is a stop; the toolpath and the warnings, or every
/// diagnostic when one is an error.
fn conclude(sink: Sink, mut tp: Toolpath) -> Result<(Toolpath, Vec<Diagnostic>), Vec<Diagnostic>> {
    if let Some(last) = tp.moves.last_mut() {
        last.stop_after = true;
    }
    let has_errors = sink.has_errors();
    let diags = sink.finish();
    if has_errors {
        Err(diags)
    } else {
        Ok((tp, diags))
    }
}

/// The warning for a program that never ends (`M2`, `M30`, closing `%`), at its last block.
fn no_end_warning(span: Span) -> Diagnostic {
    Diagnostic::warning(
        span,
        "the program ends without M2, M30 or a closing %: LinuxCNC refuses such a file (\"File ended with no percent sign or program end\")",
    )
}

/// The warning for blocks after the program's end on `end_line`, at the first of them.
fn after_end_warning(span: Span, end_line: u32) -> Diagnostic {
    Diagnostic::warning(
        span,
        format!("blocks after the program end on line {end_line} are not executed"),
    )
}

/// `true` when a block holds code (words or assignments), not only comments or a label.
fn has_code(b: &crate::syntax::Block) -> bool {
    !b.words.is_empty() || !b.assignments.is_empty()
}

/// Code after the program's end at block `at` (on line `end_line`) never runs: the warning at
/// the first block after it holding code, subroutine definitions skipped. `get(i)` gives block
/// `i`'s [`has_code`] and span (`None` past the last block).
fn after_end<E>(
    flow: &Flow,
    at: usize,
    end_line: u32,
    get: &mut dyn FnMut(usize) -> Result<Option<(bool, Span)>, E>,
) -> Result<Option<Diagnostic>, E> {
    let mut i = at + 1;
    loop {
        if let Some(Jump::Sub { end }) = flow.jumps.get(&i) {
            i = end + 1;
            continue;
        }
        match get(i)? {
            None => return Ok(None),
            Some((true, span)) => return Ok(Some(after_end_warning(span, end_line))),
            Some((false, _)) => i += 1,
        }
    }
}

/// The interpreter's state between two pieces of a program ([`ChunkInterp`]).
#[derive(Debug)]
struct Carry {
    sink: Sink,
    st: State,
    params: Params,
    tools: ToolTable,
    tp: Toolpath,
    frames: Vec<Frame>,
    loop_iterations: u64,
}

struct Interp<'a> {
    opts: &'a InterpOptions,
    /// The program, or the piece of it being run.
    prog: &'a Program,
    /// Index in the whole file of `prog.blocks[0]` (0 for a whole program).
    first: usize,
    /// The names [`NameId`]s refer to (the program's, or a streamed program's parser's).
    names: &'a [String],
    sink: Sink,
    st: State,
    params: Params,
    tools: ToolTable,
    tp: Toolpath,
    frames: Vec<Frame>,
    loop_iterations: u64,
}

/// How the run goes on after a statement (block indices count the blocks of the whole file).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Next {
    /// Continue at this block.
    Goto(usize),
    /// Test the `elseif` (or reach the `else` or `endif`) at this block: the branches before
    /// it did not run.
    Test(usize),
    /// The program ends (`M2`, `M30`, `%`, or an error that leaves nowhere to go).
    End,
}

/// Why [`Interp::run_piece`] returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Exit {
    /// The run goes on at a block outside the piece (or past the file's last block).
    Leave(Next),
    /// The run goes on inside the piece, but the moves made so far should be handed on first.
    Yield(Next),
    /// The O-word statement the run goes on at has partners not analysed yet.
    Unresolved(Next),
    /// The program ended at block `at`: by its end (`M2`, `M30`, `%`) on line `line`, or by an
    /// error (`None`).
    End { at: usize, line: Option<u32> },
    /// Too many moves (an error): nothing more runs and nothing more is said.
    Stop,
}

impl<'a> Interp<'a> {
    fn new(prog: &'a Program, opts: &'a InterpOptions) -> Self {
        let params = Params::new(&opts.parameters);
        let (start, started) = match opts.start {
            StartPosition::Machine(p) => (p, true),
            StartPosition::FirstMove => ([0.0; 6], false),
        };
        let mut it = Interp {
            opts,
            prog,
            first: 0,
            names: &prog.names,
            sink: Sink::new(opts.max_diagnostics),
            st: State {
                pos: start,
                motion: None,
                plane: Plane::XY,
                inch: false,
                absolute: true,
                arc_absolute: false,
                inverse_time: false,
                path: opts.path_mode,
                tcp: false,
                feed: None,
                spindle_rpm: 0.0,
                current_tool: 0,
                selected_tool: 0,
                tool_offset: [0.0; 6],
                coord_index: 1,
                g5x: [0.0; 6],
                rotation_deg: 0.0,
                g92: [0.0; 6],
                retract_r_plane: true,
                cycle: CycleMemory::default(),
                line: 0,
                started,
                comp: comp::CompState::default(),
            },
            params,
            tools: opts.tools.clone(),
            tp: Toolpath {
                start,
                ..Toolpath::default()
            },
            frames: vec![Frame::default()],
            loop_iterations: 0,
        };
        if start.iter().any(|v| !v.is_finite()) {
            it.sink.push(Diagnostic::new(
                Span {
                    line: 1,
                    col: 1,
                    start: 0,
                    end: 0,
                },
                Severity::Error,
                DiagnosticKind::Other,
                format!("start position {start:?} is not finite"),
            ));
        }
        it.load_start_offsets();
        it
    }

    /// The state to carry to the next piece of a program.
    fn into_carry(self) -> Carry {
        Carry {
            sink: self.sink,
            st: self.st,
            params: self.params,
            tools: self.tools,
            tp: self.tp,
            frames: self.frames,
            loop_iterations: self.loop_iterations,
        }
    }

    /// Go on with the next piece `prog` of a program from the carried state.
    /// `prog` holds the blocks of the file from index `first` on; `names` are the file's.
    fn resume(
        prog: &'a Program,
        first: usize,
        names: &'a [String],
        opts: &'a InterpOptions,
        c: Carry,
    ) -> Self {
        Interp {
            opts,
            prog,
            first,
            names,
            sink: c.sink,
            st: c.st,
            params: c.params,
            tools: c.tools,
            tp: c.tp,
            frames: c.frames,
            loop_iterations: c.loop_iterations,
        }
    }

    /// The name `id`.
    fn name(&self, id: NameId) -> &'a str {
        self.names.get(id.index()).map_or("", String::as_str)
    }

    fn frame(&self) -> &Frame {
        // The main frame is never popped.
        self.frames
            .last()
            .unwrap_or_else(|| unreachable!("the main frame is never popped"))
    }

    fn frame_mut(&mut self) -> &mut Frame {
        if self.frames.is_empty() {
            self.frames.push(Frame::default());
        }
        let n = self.frames.len() - 1;
        &mut self.frames[n]
    }

    fn err(&mut self, span: Span, kind: DiagnosticKind, msg: impl Message) {
        self.sink.report_msg(span, Severity::Error, kind, msg);
    }

    /// An unsupported word or code that cannot change the path: a warning under `lenient`.
    fn harmless(&mut self, span: Span, msg: impl Message) {
        if self.opts.lenient {
            self.sink
                .report_msg(span, Severity::Warning, DiagnosticKind::Unsupported, || {
                    format!("{} (ignored)", msg.build())
                });
        } else {
            self.sink
                .report_msg(span, Severity::Error, DiagnosticKind::Unsupported, msg);
        }
    }

    /// Run from the first block to the end of the program.
    fn run(&mut self) {
        let prog = self.prog;
        let delete = self.opts.block_delete;
        let skip = move |i: usize| prog.blocks[i].block_delete && delete;
        let flow = flow::analyse(prog, &skip, &mut self.sink);
        if self.sink.has_errors() {
            return;
        }
        match self.run_piece(Next::Goto(0), &flow, usize::MAX) {
            Exit::End {
                at,
                line: Some(end_line),
            } => {
                let mut get =
                    |i: usize| Ok::<_, ()>(prog.blocks.get(i).map(|b| (has_code(b), b.span)));
                if let Ok(Some(w)) = after_end(&flow, at, end_line, &mut get) {
                    self.sink.push(w);
                }
            }
            Exit::Stop => {}
            _ => {
                if let Some(last) = prog.blocks.last() {
                    self.sink.push(no_end_warning(last.span));
                }
            }
        }
    }

    /// Run the blocks of the piece `self.prog` from `next` until the run leaves the piece, needs
    /// an O-word statement's partners not analysed yet, has `yield_at` moves waiting or ends.
    fn run_piece(&mut self, mut next: Next, flow: &Flow, yield_at: usize) -> Exit {
        let prog = self.prog;
        let delete = self.opts.block_delete;
        loop {
            let (pc, test) = match next {
                Next::Goto(n) => (n, false),
                Next::Test(n) => (n, true),
                Next::End => return Exit::End { at: 0, line: None },
            };
            let Some(block) = pc.checked_sub(self.first).and_then(|i| prog.blocks.get(i)) else {
                return Exit::Leave(next);
            };
            if block.percent {
                if pc > 0 {
                    return Exit::End {
                        at: pc,
                        line: Some(block.line),
                    };
                }
                next = Next::Goto(pc + 1);
                continue;
            }
            if block.block_delete && delete {
                next = Next::Goto(pc + 1);
                continue;
            }
            let mut ended = None;
            let after = match block.o_word.as_deref() {
                Some(o) if !flow.resolved(pc, o) => return Exit::Unresolved(next),
                // The branches before this one did not run (the `if`'s line stays current).
                Some(o) if test => self.branch_test(pc, o, flow),
                Some(o) => {
                    self.st.line = block.line;
                    self.control(pc, o, block.span, flow)
                }
                None => {
                    self.st.line = block.line;
                    if self.block(block) {
                        ended = Some(block.line);
                        Next::End
                    } else {
                        Next::Goto(pc + 1)
                    }
                }
            };
            if self.tp.moves.len() > self.opts.max_moves {
                self.err(
                    block.span,
                    DiagnosticKind::Limit,
                    format!(
                        "the program makes more than {} moves (InterpOptions::max_moves)",
                        self.opts.max_moves
                    ),
                );
                return Exit::Stop;
            }
            if after == Next::End {
                return Exit::End {
                    at: pc,
                    line: ended,
                };
            }
            next = after;
            if self.tp.moves.len() >= yield_at {
                return Exit::Yield(next);
            }
        }
    }

    /// Execute an O-word statement at block `pc`.
    fn control(&mut self, pc: usize, o: &OWord, block_span: Span, flow: &Flow) -> Next {
        let span = o.keyword_span;
        let cond = |it: &mut Self, e| match it.eval(e) {
            Ok(v) => Some(v),
            Err(e) => {
                it.sink
                    .report_msg(e.span, Severity::Error, e.kind, e.message);
                None
            }
        };
        let jump = flow.jumps.get(&pc).copied();
        match (&o.statement, jump) {
            (OStatement::ProgramNumber, _) => Next::Goto(pc + 1),
            // Flowing into a definition skips it.
            (OStatement::Sub, Some(Jump::Sub { end })) => Next::Goto(end + 1),
            (OStatement::EndSub(v) | OStatement::Return(v), _) => {
                let value = match v {
                    Some(e) => match cond(self, *e) {
                        Some(x) => Some(x),
                        None => return Next::End,
                    },
                    None => None,
                };
                self.ret(value, block_span)
            }
            (OStatement::Call(args), _) => self.call(pc, o, args, flow),
            (OStatement::If(c), Some(Jump::Branch { next, .. })) => match cond(self, *c) {
                None => Next::End,
                Some(v) if v != 0.0 => Next::Goto(pc + 1),
                Some(_) => Next::Test(next),
            },
            // Reached from a branch that ran: leave the if.
            (OStatement::ElseIf(_), Some(Jump::Branch { endif, .. }))
            | (OStatement::Else, Some(Jump::Else { endif })) => Next::Goto(endif + 1),
            (OStatement::EndIf, _) => Next::Goto(pc + 1),
            (OStatement::While(c), Some(Jump::LoopStart { end })) => match cond(self, *c) {
                None => Next::End,
                Some(v) if v != 0.0 => Next::Goto(pc + 1),
                Some(_) => Next::Goto(end + 1),
            },
            (OStatement::Do, Some(Jump::LoopStart { .. })) => Next::Goto(pc + 1),
            (OStatement::Repeat(c), Some(Jump::LoopStart { end })) => match cond(self, *c) {
                None => Next::End,
                Some(n) if n >= 1.0 => {
                    // LinuxCNC runs the body `(int) n` times.
                    let n = n.min(u64::MAX as f64) as u64;
                    self.frame_mut().repeats.push((pc, n));
                    Next::Goto(pc + 1)
                }
                Some(_) => Next::Goto(end + 1),
            },
            (
                OStatement::EndWhile | OStatement::While(_) | OStatement::EndRepeat,
                Some(Jump::LoopEnd { start, head, kind }),
            ) => self.loop_end(pc, start, head, kind, o),
            (
                OStatement::Break,
                Some(Jump::LoopExit {
                    start, end, kind, ..
                }),
            ) => {
                if kind == LoopKind::Repeat {
                    self.pop_repeat(start);
                }
                Next::Goto(end + 1)
            }
            (
                OStatement::Continue,
                Some(Jump::LoopExit {
                    start,
                    head,
                    end,
                    kind,
                }),
            ) => match kind {
                LoopKind::While => {
                    if !self.count_iteration(head) {
                        return Next::End;
                    }
                    Next::Goto(start)
                }
                // The closing statement evaluates the condition or counts the repeat.
                LoopKind::Do | LoopKind::Repeat => Next::Goto(end),
            },
            _ => {
                // The pre-pass reported every statement without its partner.
                self.err(
                    span,
                    DiagnosticKind::ControlFlow,
                    "O-word statement out of place",
                );
                Next::End
            }
        }
    }

    /// A branch statement reached from a failed `if`/`elseif`: an `elseif` tests its
    /// condition; an `else` runs; an `endif` means no branch ran.
    fn branch_test(&mut self, at: usize, o: &OWord, flow: &Flow) -> Next {
        match (&o.statement, flow.jumps.get(&at).copied()) {
            (OStatement::ElseIf(c), Some(Jump::Branch { next, .. })) => match self.eval(*c) {
                Err(e) => {
                    self.sink
                        .report_msg(e.span, Severity::Error, e.kind, e.message);
                    Next::End
                }
                Ok(v) if v != 0.0 => Next::Goto(at + 1),
                Ok(_) => Next::Test(next),
            },
            _ => Next::Goto(at + 1),
        }
    }

    /// Count one loop iteration against the budget; `false` (and an error naming the loop)
    /// when it is exhausted.
    fn count_iteration(&mut self, head: Span) -> bool {
        self.loop_iterations += 1;
        if self.loop_iterations > self.opts.max_loop_iterations {
            let line = head.line;
            self.err(head, DiagnosticKind::LoopBudget, || {
                format!(
                    "the loop at line {line} has run more than {} iterations in all (InterpOptions::max_loop_iterations): the program does not end",
                    self.opts.max_loop_iterations
                )
            });
            return false;
        }
        true
    }

    /// The closing statement of a loop at `pc`, opened at `start` by the keyword `head`.
    fn loop_end(&mut self, pc: usize, start: usize, head: Span, kind: LoopKind, o: &OWord) -> Next {
        match kind {
            LoopKind::While => {
                if !self.count_iteration(head) {
                    return Next::End;
                }
                Next::Goto(start)
            }
            LoopKind::Do => {
                let OStatement::While(c) = o.statement else {
                    return Next::Goto(pc + 1);
                };
                match self.eval(c) {
                    Err(e) => {
                        self.sink
                            .report_msg(e.span, Severity::Error, e.kind, e.message);
                        Next::End
                    }
                    Ok(v) if v != 0.0 => {
                        if !self.count_iteration(head) {
                            return Next::End;
                        }
                        Next::Goto(start + 1)
                    }
                    Ok(_) => Next::Goto(pc + 1),
                }
            }
            LoopKind::Repeat => {
                let again = match self.frame_mut().repeats.last_mut() {
                    Some((s, left)) if *s == start => {
                        *left -= 1;
                        *left > 0
                    }
                    _ => false,
                };
                if again {
                    if !self.count_iteration(head) {
                        return Next::End;
                    }
                    Next::Goto(start + 1)
                } else {
                    self.pop_repeat(start);
                    Next::Goto(pc + 1)
                }
            }
        }
    }

    fn pop_repeat(&mut self, start: usize) {
        let f = self.frame_mut();
        if let Some(i) = f.repeats.iter().rposition(|(s, _)| *s == start) {
            f.repeats.truncate(i);
        }
    }

    /// `o<label> call [args]`.
    fn call(&mut self, pc: usize, o: &OWord, args: &[crate::syntax::ExprId], flow: &Flow) -> Next {
        let span = o.keyword_span;
        let Some(&sub) = flow.subs.get(&o.label) else {
            let name = match o.label {
                OLabel::Number(n) => format!("o{n}"),
                OLabel::Name(n) => format!("o<{}>", self.name(n)),
            };
            self.err(o.label_span, DiagnosticKind::UndefinedSubroutine, || {
                format!("subroutine {name} is not defined in this file (no '{name} sub')")
            });
            return Next::End;
        };
        if args.len() > 30 {
            self.err(
                span,
                DiagnosticKind::Block,
                format!(
                    "{} arguments: a call takes at most 30 (#1 … #30)",
                    args.len()
                ),
            );
            return Next::End;
        }
        let mut values = [0.0; 30];
        for (slot, &a) in values.iter_mut().zip(args) {
            match self.eval(a) {
                Ok(v) => *slot = v,
                Err(e) => {
                    self.sink
                        .report_msg(e.span, Severity::Error, e.kind, e.message);
                    return Next::End;
                }
            }
        }
        if self.frames.len() > self.opts.max_call_depth {
            self.err(span, DiagnosticKind::CallDepth, || {
                format!(
                    "subroutine calls nested more than {} deep (InterpOptions::max_call_depth)",
                    self.opts.max_call_depth
                )
            });
            return Next::End;
        }
        let saved: [f64; 30] = std::array::from_fn(|i| self.params.get(i as u32 + 1));
        for (i, v) in values.iter().enumerate() {
            self.params.set(i as u32 + 1, *v);
        }
        self.params.value_returned = false;
        self.frames.push(Frame {
            return_to: pc + 1,
            saved: Some(Box::new(saved)),
            locals: HashMap::new(),
            repeats: Vec::new(),
        });
        Next::Goto(sub + 1)
    }

    /// `endsub`/`return`: back to the caller, restoring its `#1`–`#30`.
    fn ret(&mut self, value: Option<f64>, block_span: Span) -> Next {
        if self.frames.len() <= 1 {
            // Flowing into an `endsub` in the main program (a `sub` skipped by a jump) is
            // prevented by the pre-pass; reaching one means the program ends here.
            self.err(
                block_span,
                DiagnosticKind::ControlFlow,
                "endsub or return reached outside a subroutine call",
            );
            return Next::End;
        }
        let Some(frame) = self.frames.pop() else {
            return Next::End;
        };
        if let Some(saved) = frame.saved {
            for (i, v) in saved.iter().enumerate() {
                self.params.set(i as u32 + 1, *v);
            }
        }
        self.params.value = value.unwrap_or(0.0);
        self.params.value_returned = value.is_some();
        Next::Goto(frame.return_to)
    }
}

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

#[cfg(test)]
mod tests;
