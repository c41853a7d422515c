//! The structure of a program's O-word statements, found once before it runs: which
//! statements belong together (`if … elseif … else … endif`, `while … endwhile`,
//! `do … while`, `repeat … endrepeat`, `sub … endsub`) and where each jumps. Errors (an `endsub`
//! without `sub`, an unclosed `if`, a `break` outside its loop, …) are reported with the
//! statement's line and column. One pass with a stack: linear in the program length.

use std::collections::HashMap;

use crate::diag::{Diagnostic, DiagnosticKind, Severity, Sink, Span};
use crate::syntax::{OLabel, OStatement, Program};

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
    /// `endwhile`, the `while` closing a `do`, `endrepeat`: the opening statement.
    LoopEnd { start: usize, kind: LoopKind },
    /// `break`/`continue`: the loop's opening and closing statements.
    LoopExit {
        start: usize,
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
}

#[derive(Debug)]
enum Open {
    Sub,
    If {
        branches: Vec<usize>,
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
    index: usize,
    open: Open,
}

/// Analyse `program`. Blocks in `skip` (deleted lines) are ignored.
pub(super) fn analyse(program: &Program, skip: &dyn Fn(usize) -> bool, sink: &mut Sink) -> Flow {
    let mut a = Analyser {
        program,
        sink,
        flow: Flow::default(),
        stack: Vec::new(),
    };
    for (i, b) in program.blocks.iter().enumerate() {
        let Some(o) = b.o_word.as_deref() else {
            continue;
        };
        if skip(i) {
            continue;
        }
        let (label, span) = (o.label, o.keyword_span);
        match &o.statement {
            OStatement::ProgramNumber | OStatement::Call(_) => {}
            OStatement::Sub => a.sub(i, label, span),
            OStatement::EndSub(_) => a.endsub(i, label, span),
            OStatement::Return(_) => a.ret(label, span),
            OStatement::If(_) => a.open(
                i,
                label,
                Open::If {
                    branches: vec![i],
                    has_else: false,
                },
            ),
            OStatement::ElseIf(_) => a.branch(i, label, span, false),
            OStatement::Else => a.branch(i, label, span, true),
            OStatement::EndIf => a.endif(i, label, span),
            OStatement::While(_) => a.while_(i, label),
            OStatement::Do => a.open_loop(i, label, LoopKind::Do),
            OStatement::Repeat(_) => a.open_loop(i, label, LoopKind::Repeat),
            OStatement::EndWhile => a.end_loop(i, label, span, LoopKind::While),
            OStatement::EndRepeat => a.end_loop(i, label, span, LoopKind::Repeat),
            OStatement::Break => a.exit(i, label, span, "break"),
            OStatement::Continue => a.exit(i, label, span, "continue"),
        }
    }
    a.unclosed();
    a.flow
}

/// The pass's state: the open constructs, innermost last.
struct Analyser<'p, 's> {
    program: &'p Program,
    sink: &'s mut Sink,
    flow: Flow,
    stack: Vec<Frame>,
}

impl Analyser<'_, '_> {
    fn label(&self, l: OLabel) -> String {
        match l {
            OLabel::Number(n) => format!("o{n}"),
            OLabel::Name(n) => format!("o<{}>", self.program.name(n)),
        }
    }

    fn line(&self, block: usize) -> u32 {
        self.program.blocks[block].line
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
        self.stack.last().filter(|f| f.label == label)
    }

    fn open(&mut self, index: usize, label: OLabel, open: Open) {
        self.stack.push(Frame { label, index, open });
    }

    fn open_loop(&mut self, index: usize, label: OLabel, kind: LoopKind) {
        self.open(
            index,
            label,
            Open::Loop {
                kind,
                exits: Vec::new(),
            },
        );
    }

    fn sub(&mut self, i: usize, label: OLabel, span: Span) {
        if let Some(f) = self.stack.last() {
            let msg = format!(
                "{} sub inside {} opened at line {}: subroutines cannot be defined inside other statements",
                self.label(label),
                self.label(f.label),
                self.line(f.index)
            );
            self.err(span, msg);
            return;
        }
        if let Some(&first) = self.flow.subs.get(&label) {
            let msg = format!(
                "subroutine {} is defined twice (first at line {})",
                self.label(label),
                self.line(first)
            );
            self.err(span, msg);
        }
        self.flow.subs.entry(label).or_insert(i);
        self.open(i, label, Open::Sub);
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
                self.stack.pop();
            }
            _ => self.unmatched(label, span, "endsub", "sub"),
        }
    }

    /// As in LinuxCNC, a return leaves the subroutine it is in, whatever its label.
    fn ret(&mut self, label: OLabel, span: Span) {
        if !self.stack.iter().any(|f| matches!(f.open, Open::Sub)) {
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
        let after_else = match self.stack.last_mut() {
            Some(Frame {
                open: Open::If { branches, has_else },
                label: l,
                ..
            }) if *l == label => {
                let after = *has_else;
                branches.push(i);
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
        for (k, &b) in branches.iter().enumerate() {
            let next = branches.get(k + 1).copied().unwrap_or(i);
            let is_else = matches!(
                self.program.blocks[b]
                    .o_word
                    .as_deref()
                    .map(|o| &o.statement),
                Some(OStatement::Else)
            );
            let jump = if is_else {
                Jump::Else { endif: i }
            } else {
                Jump::Branch { next, endif: i }
            };
            self.flow.jumps.insert(b, jump);
        }
        self.stack.pop();
    }

    /// A `while` with the label of an open `do` closes it; otherwise it opens a loop.
    fn while_(&mut self, i: usize, label: OLabel) {
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
            self.open_loop(i, label, LoopKind::While);
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
            open: Open::Loop { exits, .. },
            ..
        }) = self.stack.pop()
        {
            self.flow.jumps.insert(index, Jump::LoopStart { end });
            self.flow
                .jumps
                .insert(end, Jump::LoopEnd { start: index, kind });
            for e in exits {
                self.flow.jumps.insert(
                    e,
                    Jump::LoopExit {
                        start: index,
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
        let msg = match self.stack.last() {
            Some(f) => format!(
                "{l} {keyword} does not match the innermost open statement, {} opened at line {} (expected {l} {opener} before it)",
                self.label(f.label),
                self.line(f.index),
            ),
            None => format!("{l} {keyword} without a {l} {opener} before it"),
        };
        self.err(span, msg);
    }

    /// Every construct still open at the end of the file.
    fn unclosed(&mut self) {
        for f in std::mem::take(&mut self.stack) {
            let b = &self.program.blocks[f.index];
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
            let span = b.o_word.as_deref().map_or(b.span, |o| o.keyword_span);
            let msg = format!(
                "{} is never closed: {what} needs its closing statement with the same label",
                self.label(f.label)
            );
            self.err(span, msg);
        }
    }
}
