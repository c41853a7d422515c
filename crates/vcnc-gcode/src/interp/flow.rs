//! The structure of a program's O-word statements, found once before it runs: which
//! statements belong together (`if … elseif … else … endif`, `while … endwhile`,
//! `do … while`, `repeat … endrepeat`, `sub … endsub`) and where each jumps. Errors (an `endsub`
//! without `sub`, an unclosed `if`, a `break` outside its loop, …) are reported with the
//! statement's line and column. One pass with a stack: linear in the program length.
//!
//! The pass is fed one O-word statement at a time ([`Analyser::statement`]), in file order: from
//! the whole parsed program ([`analyse`]), or as a streamed program's pieces are first read
//! (`seek.rs`), which then runs with the part of the table known so far ([`Flow::resolved`]).
//! Block indices count the parsed blocks of the whole file in both cases.

use std::collections::HashMap;

use crate::diag::{Diagnostic, DiagnosticKind, Severity, Sink, Span};
use crate::syntax::{Block, OLabel, OStatement, OWord, Program};

/// Kind of a loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum LoopKind {
    While,
    Do,
    Repeat,
}

/// Where an O-word statement leads (block indices).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Jump {
    /// `sub`: its `endsub` (the body is skipped when the program flows into it).
    Sub { end: usize },
    /// `if`/`elseif`: the next branch statement (`elseif`, `else` or `endif`) and the `endif`.
    Branch { next: usize, endif: usize },
    /// `else`: the `endif`.
    Else { endif: usize },
    /// `while` (of a while loop), `do`, `repeat`: the closing statement.
    LoopStart { end: usize },
    /// `endwhile`, the `while` closing a `do`, `endrepeat`: the opening statement (and its
    /// keyword, which the loop budget's error names).
    LoopEnd {
        start: usize,
        head: Span,
        kind: LoopKind,
    },
    /// `break`/`continue`: the loop's opening and closing statements.
    LoopExit {
        start: usize,
        head: Span,
        end: usize,
        kind: LoopKind,
    },
}

/// The jump table and the subroutines.
#[derive(Debug, Default)]
pub(super) struct Flow {
    pub(super) jumps: HashMap<usize, Jump>,
    /// Subroutine label → index of its `sub` statement.
    pub(super) subs: HashMap<OLabel, usize>,
    /// Line of each `sub` statement (for the error naming a second definition).
    pub(super) sub_lines: HashMap<usize, u32>,
    /// Every statement of the file has been analysed.
    pub(super) complete: bool,
}

impl Flow {
    /// Whether the statement `o` at block `pc` can run: its partners have been analysed (always,
    /// once the whole file has been).
    pub(super) fn resolved(&self, pc: usize, o: &OWord) -> bool {
        self.complete
            || match o.statement {
                OStatement::Call(_) => self.subs.contains_key(&o.label),
                OStatement::ProgramNumber
                | OStatement::EndSub(_)
                | OStatement::Return(_)
                | OStatement::EndIf => true,
                _ => self.jumps.contains_key(&pc),
            }
    }
}

#[derive(Debug)]
enum Open {
    Sub,
    If {
        /// The `if`, `elseif` and `else` statements, each with `true` for the `else`.
        branches: Vec<(usize, bool)>,
        has_else: bool,
    },
    Loop {
        kind: LoopKind,
        exits: Vec<usize>,
    },
}

#[derive(Debug)]
struct Frame {
    label: OLabel,
    /// The label as written in messages (`o100`, `o<name>`).
    text: String,
    index: usize,
    line: u32,
    /// The opening keyword.
    head: Span,
    open: Open,
}

/// Analyse `program` whole. Blocks in `skip` (deleted lines) are ignored.
pub(super) fn analyse(program: &Program, skip: &dyn Fn(usize) -> bool, sink: &mut Sink) -> Flow {
    let mut a = Analyser::default();
    let mut flow = Flow::default();
    for (i, b) in program.blocks.iter().enumerate() {
        if !skip(i) {
            a.statement(i, b, &program.names, &mut flow, sink);
        }
    }
    a.finish(&mut flow, sink);
    flow
}

/// The pass's state: the open constructs, innermost last.
#[derive(Debug, Default)]
pub(super) struct Analyser {
    stack: Vec<Frame>,
}

impl Analyser {
    /// The next block of the file, `i` (`names`: the file's): its O-word statement, if any,
    /// goes into `flow`.
    pub(super) fn statement(
        &mut self,
        i: usize,
        b: &Block,
        names: &[String],
        flow: &mut Flow,
        sink: &mut Sink,
    ) {
        let Some(o) = b.o_word.as_deref() else {
            return;
        };
        let mut a = Pass {
            state: self,
            flow,
            names,
            sink,
        };
        let (label, span) = (o.label, o.keyword_span);
        match &o.statement {
            OStatement::ProgramNumber | OStatement::Call(_) => {}
            OStatement::Sub => a.sub(i, label, span),
            OStatement::EndSub(_) => a.endsub(i, label, span),
            OStatement::Return(_) => a.ret(label, span),
            OStatement::If(_) => a.open(
                i,
                label,
                span,
                Open::If {
                    branches: vec![(i, false)],
                    has_else: false,
                },
            ),
            OStatement::ElseIf(_) => a.branch(i, label, span, false),
            OStatement::Else => a.branch(i, label, span, true),
            OStatement::EndIf => a.endif(i, label, span),
            OStatement::While(_) => a.while_(i, label, span),
            OStatement::Do => a.open_loop(i, label, span, LoopKind::Do),
            OStatement::Repeat(_) => a.open_loop(i, label, span, LoopKind::Repeat),
            OStatement::EndWhile => a.end_loop(i, label, span, LoopKind::While),
            OStatement::EndRepeat => a.end_loop(i, label, span, LoopKind::Repeat),
            OStatement::Break => a.exit(i, label, span, "break"),
            OStatement::Continue => a.exit(i, label, span, "continue"),
        }
    }

    /// The end of the file: every construct still open is an error; the table is complete.
    pub(super) fn finish(mut self, flow: &mut Flow, sink: &mut Sink) {
        for f in std::mem::take(&mut self.stack) {
            let what = match f.open {
                Open::Sub => "sub … endsub",
                Open::If { .. } => "if … endif",
                Open::Loop {
                    kind: LoopKind::While,
                    ..
                } => "while … endwhile",
                Open::Loop {
                    kind: LoopKind::Do, ..
                } => "do … while",
                Open::Loop {
                    kind: LoopKind::Repeat,
                    ..
                } => "repeat … endrepeat",
            };
            let msg = format!(
                "{} is never closed: {what} needs its closing statement with the same label",
                f.text
            );
            sink.push(Diagnostic::new(
                f.head,
                Severity::Error,
                DiagnosticKind::ControlFlow,
                msg,
            ));
        }
        flow.complete = true;
    }
}

/// One statement's analysis: the state, the table, the file's names and where errors go.
struct Pass<'a> {
    state: &'a mut Analyser,
    flow: &'a mut Flow,
    names: &'a [String],
    sink: &'a mut Sink,
}

impl Pass<'_> {
    fn label(&self, l: OLabel) -> String {
        match l {
            OLabel::Number(n) => format!("o{n}"),
            OLabel::Name(n) => format!(
                "o<{}>",
                self.names.get(n.index()).map_or("", String::as_str)
            ),
        }
    }

    fn err(&mut self, span: Span, msg: String) {
        self.sink.push(Diagnostic::new(
            span,
            Severity::Error,
            DiagnosticKind::ControlFlow,
            msg,
        ));
    }

    /// The innermost open construct, when it has this label.
    fn top(&self, label: OLabel) -> Option<&Frame> {
        self.state.stack.last().filter(|f| f.label == label)
    }

    fn open(&mut self, index: usize, label: OLabel, head: Span, open: Open) {
        let text = self.label(label);
        self.state.stack.push(Frame {
            label,
            text,
            index,
            line: head.line,
            head,
            open,
        });
    }

    fn open_loop(&mut self, index: usize, label: OLabel, head: Span, kind: LoopKind) {
        self.open(
            index,
            label,
            head,
            Open::Loop {
                kind,
                exits: Vec::new(),
            },
        );
    }

    fn sub(&mut self, i: usize, label: OLabel, span: Span) {
        if let Some(f) = self.state.stack.last() {
            let msg = format!(
                "{} sub inside {} opened at line {}: subroutines cannot be defined inside other statements",
                self.label(label),
                f.text,
                f.line
            );
            self.err(span, msg);
            return;
        }
        if let Some(&first) = self.flow.subs.get(&label) {
            let line = self.flow.sub_lines.get(&first).copied().unwrap_or(0);
            let msg = format!(
                "subroutine {} is defined twice (first at line {line})",
                self.label(label),
            );
            self.err(span, msg);
        }
        self.flow.subs.entry(label).or_insert(i);
        self.flow.sub_lines.entry(i).or_insert(span.line);
        self.open(i, label, span, Open::Sub);
    }

    fn endsub(&mut self, i: usize, label: OLabel, span: Span) {
        match self.top(label) {
            Some(Frame {
                open: Open::Sub,
                index,
                ..
            }) => {
                let start = *index;
                self.flow.jumps.insert(start, Jump::Sub { end: i });
                self.state.stack.pop();
            }
            _ => self.unmatched(label, span, "endsub", "sub"),
        }
    }

    /// As in LinuxCNC, a return leaves the subroutine it is in, whatever its label.
    fn ret(&mut self, label: OLabel, span: Span) {
        if !self.state.stack.iter().any(|f| matches!(f.open, Open::Sub)) {
            let msg = format!(
                "{} return outside a subroutine definition (sub … endsub)",
                self.label(label)
            );
            self.err(span, msg);
        }
    }

    /// `elseif` or `else`.
    fn branch(&mut self, i: usize, label: OLabel, span: Span, is_else: bool) {
        let kw = if is_else { "else" } else { "elseif" };
        let after_else = match self.state.stack.last_mut() {
            Some(Frame {
                open: Open::If { branches, has_else },
                label: l,
                ..
            }) if *l == label => {
                let after = *has_else;
                branches.push((i, is_else));
                *has_else |= is_else;
                after
            }
            _ => return self.unmatched(label, span, kw, "if"),
        };
        if after_else {
            let msg = format!("{} {kw} after the else of this if", self.label(label));
            self.err(span, msg);
        }
    }

    fn endif(&mut self, i: usize, label: OLabel, span: Span) {
        let branches = match self.top(label) {
            Some(Frame {
                open: Open::If { branches, .. },
                ..
            }) => branches.clone(),
            _ => return self.unmatched(label, span, "endif", "if"),
        };
        for (k, &(b, is_else)) in branches.iter().enumerate() {
            let next = branches.get(k + 1).map_or(i, |n| n.0);
            let jump = if is_else {
                Jump::Else { endif: i }
            } else {
                Jump::Branch { next, endif: i }
            };
            self.flow.jumps.insert(b, jump);
        }
        self.state.stack.pop();
    }

    /// A `while` with the label of an open `do` closes it; otherwise it opens a loop.
    fn while_(&mut self, i: usize, label: OLabel, span: Span) {
        let closes_do = matches!(
            self.top(label),
            Some(Frame {
                open: Open::Loop {
                    kind: LoopKind::Do,
                    ..
                },
                ..
            })
        );
        if closes_do {
            self.close_loop(i, LoopKind::Do);
        } else {
            self.open_loop(i, label, span, LoopKind::While);
        }
    }

    fn end_loop(&mut self, i: usize, label: OLabel, span: Span, kind: LoopKind) {
        let matches_top = matches!(
            self.top(label),
            Some(Frame { open: Open::Loop { kind: k, .. }, .. }) if *k == kind
        );
        if matches_top {
            self.close_loop(i, kind);
        } else if kind == LoopKind::While {
            self.unmatched(label, span, "endwhile", "while");
        } else {
            self.unmatched(label, span, "endrepeat", "repeat");
        }
    }

    fn close_loop(&mut self, end: usize, kind: LoopKind) {
        if let Some(Frame {
            index,
            head,
            open: Open::Loop { exits, .. },
            ..
        }) = self.state.stack.pop()
        {
            let jumps = &mut self.flow.jumps;
            jumps.insert(index, Jump::LoopStart { end });
            jumps.insert(
                end,
                Jump::LoopEnd {
                    start: index,
                    head,
                    kind,
                },
            );
            for e in exits {
                jumps.insert(
                    e,
                    Jump::LoopExit {
                        start: index,
                        head,
                        end,
                        kind,
                    },
                );
            }
        }
    }

    /// `break` or `continue`: the enclosing `while` or `do` loop with this label.
    fn exit(&mut self, i: usize, label: OLabel, span: Span, kw: &str) {
        let target = self
            .state
            .stack
            .iter_mut()
            .rev()
            .take_while(|f| !matches!(f.open, Open::Sub))
            .find(|f| f.label == label && matches!(f.open, Open::Loop { .. }));
        let kind = match target {
            Some(Frame {
                open: Open::Loop { kind, exits },
                ..
            }) => {
                let allowed = *kind == LoopKind::While || (*kind == LoopKind::Do && kw == "break");
                if allowed {
                    exits.push(i);
                    return;
                }
                Some(*kind)
            }
            _ => None,
        };
        let l = self.label(label);
        let msg = match kind {
            Some(LoopKind::Repeat) => format!(
                "{l} {kw} in a repeat loop: as in LinuxCNC, break and continue apply to while and do loops only"
            ),
            Some(_) => format!(
                "{l} continue in a do … while loop is refused: LinuxCNC 2.9 does not continue such a loop (it leaves it), so the program would not run as written; use while … endwhile"
            ),
            None => format!("{l} {kw} outside a loop labelled {l} (do, while or repeat)"),
        };
        self.err(span, msg);
    }

    /// A closing statement that does not close the innermost open construct.
    fn unmatched(&mut self, label: OLabel, span: Span, keyword: &str, opener: &str) {
        let l = self.label(label);
        let msg = match self.state.stack.last() {
            Some(f) => format!(
                "{l} {keyword} does not match the innermost open statement, {} opened at line {} (expected {l} {opener} before it)",
                f.text, f.line,
            ),
            None => format!("{l} {keyword} without a {l} {opener} before it"),
        };
        self.err(span, msg);
    }
}
