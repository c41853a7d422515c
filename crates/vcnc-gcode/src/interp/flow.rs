//! The structure of a program's O-word statements, found once before it runs: which
//! statements belong together (`if … elseif … else … endif`, `while … endwhile`,
//! `do … while`, `repeat … endrepeat`, `sub … endsub`) and where each jumps. Errors (an `endsub`
//! without `sub`, an unclosed `if`, a `break` outside its loop, …) are reported with the
//! statement's line and column. One pass with a stack: linear in the program length.

use std::collections::HashMap;

use crate::diag::{Diagnostic, DiagnosticKind, Severity, Sink};
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
    let mut flow = Flow::default();
    let mut stack: Vec<Frame> = Vec::new();
    let label_text = |l: OLabel| match l {
        OLabel::Number(n) => format!("o{n}"),
        OLabel::Name(n) => format!("o<{}>", program.name(n)),
    };
    let err = |sink: &mut Sink, span, kind, msg: String| {
        sink.push(Diagnostic::new(span, Severity::Error, kind, msg));
    };
    for (i, b) in program.blocks.iter().enumerate() {
        let Some(o) = b.o_word.as_deref() else {
            continue;
        };
        if skip(i) {
            continue;
        }
        let label = o.label;
        let span = o.keyword_span;
        let line_of = |j: usize| program.blocks[j].line;
        // The innermost open construct, when it has this label.
        let top_matches = |stack: &[Frame]| stack.last().is_some_and(|f| f.label == label);
        match &o.statement {
            OStatement::ProgramNumber | OStatement::Call(_) => {}
            OStatement::Sub => {
                if let Some(f) = stack.last() {
                    err(
                        sink,
                        span,
                        DiagnosticKind::ControlFlow,
                        format!(
                            "{} sub inside {} opened at line {}: subroutines cannot be defined inside other statements",
                            label_text(label),
                            label_text(f.label),
                            line_of(f.index)
                        ),
                    );
                    continue;
                }
                if let Some(&first) = flow.subs.get(&label) {
                    err(
                        sink,
                        span,
                        DiagnosticKind::ControlFlow,
                        format!(
                            "subroutine {} is defined twice (first at line {})",
                            label_text(label),
                            line_of(first)
                        ),
                    );
                }
                flow.subs.entry(label).or_insert(i);
                stack.push(Frame {
                    label,
                    index: i,
                    open: Open::Sub,
                });
            }
            OStatement::EndSub(_) => match stack.last() {
                Some(Frame {
                    open: Open::Sub,
                    index,
                    ..
                }) if top_matches(&stack) => {
                    flow.jumps.insert(*index, Jump::Sub { end: i });
                    stack.pop();
                }
                _ => unmatched(
                    sink,
                    &stack,
                    &label_text,
                    line_of,
                    label,
                    span,
                    "endsub",
                    "sub",
                ),
            },
            OStatement::Return(_) => {
                // As in LinuxCNC, a return leaves the subroutine it is in, whatever its label.
                let inside = stack.iter().any(|f| matches!(f.open, Open::Sub));
                if !inside {
                    err(
                        sink,
                        span,
                        DiagnosticKind::ControlFlow,
                        format!(
                            "{} return outside a subroutine definition (sub … endsub)",
                            label_text(label)
                        ),
                    );
                }
            }
            OStatement::If(_) => stack.push(Frame {
                label,
                index: i,
                open: Open::If {
                    branches: vec![i],
                    has_else: false,
                },
            }),
            OStatement::ElseIf(_) | OStatement::Else => {
                let is_else = matches!(o.statement, OStatement::Else);
                let kw = if is_else { "else" } else { "elseif" };
                match stack.last_mut() {
                    Some(Frame {
                        open: Open::If { branches, has_else },
                        label: l,
                        ..
                    }) if *l == label => {
                        if *has_else {
                            err(
                                sink,
                                span,
                                DiagnosticKind::ControlFlow,
                                format!("{} {kw} after the else of this if", label_text(label)),
                            );
                        }
                        branches.push(i);
                        *has_else |= is_else;
                    }
                    _ => unmatched(sink, &stack, &label_text, line_of, label, span, kw, "if"),
                }
            }
            OStatement::EndIf => match stack.last() {
                Some(Frame {
                    open: Open::If { branches, .. },
                    ..
                }) if top_matches(&stack) => {
                    for (k, &b) in branches.iter().enumerate() {
                        let next = branches.get(k + 1).copied().unwrap_or(i);
                        let is_else = matches!(
                            program.blocks[b].o_word.as_deref().map(|o| &o.statement),
                            Some(OStatement::Else)
                        );
                        let jump = if is_else {
                            Jump::Else { endif: i }
                        } else {
                            Jump::Branch { next, endif: i }
                        };
                        flow.jumps.insert(b, jump);
                    }
                    stack.pop();
                }
                _ => unmatched(
                    sink,
                    &stack,
                    &label_text,
                    line_of,
                    label,
                    span,
                    "endif",
                    "if",
                ),
            },
            OStatement::While(_) => {
                // A `while` with the label of an open `do` closes it; otherwise it opens a loop.
                if let Some(Frame {
                    open:
                        Open::Loop {
                            kind: LoopKind::Do, ..
                        },
                    ..
                }) = stack.last()
                    && top_matches(&stack)
                {
                    close_loop(&mut flow, &mut stack, i, LoopKind::Do);
                } else {
                    stack.push(Frame {
                        label,
                        index: i,
                        open: Open::Loop {
                            kind: LoopKind::While,
                            exits: Vec::new(),
                        },
                    });
                }
            }
            OStatement::Do | OStatement::Repeat(_) => stack.push(Frame {
                label,
                index: i,
                open: Open::Loop {
                    kind: if matches!(o.statement, OStatement::Do) {
                        LoopKind::Do
                    } else {
                        LoopKind::Repeat
                    },
                    exits: Vec::new(),
                },
            }),
            OStatement::EndWhile | OStatement::EndRepeat => {
                let (kind, kw, opener) = if matches!(o.statement, OStatement::EndWhile) {
                    (LoopKind::While, "endwhile", "while")
                } else {
                    (LoopKind::Repeat, "endrepeat", "repeat")
                };
                match stack.last() {
                    Some(Frame {
                        open: Open::Loop { kind: k, .. },
                        ..
                    }) if *k == kind && top_matches(&stack) => {
                        close_loop(&mut flow, &mut stack, i, kind);
                    }
                    _ => unmatched(sink, &stack, &label_text, line_of, label, span, kw, opener),
                }
            }
            OStatement::Break | OStatement::Continue => {
                let kw = if matches!(o.statement, OStatement::Break) {
                    "break"
                } else {
                    "continue"
                };
                let target = stack
                    .iter_mut()
                    .rev()
                    .take_while(|f| !matches!(f.open, Open::Sub))
                    .find(|f| f.label == label && matches!(f.open, Open::Loop { .. }));
                match target {
                    Some(Frame {
                        open:
                            Open::Loop {
                                kind: LoopKind::Repeat,
                                ..
                            },
                        ..
                    }) => err(
                        sink,
                        span,
                        DiagnosticKind::ControlFlow,
                        format!(
                            "{} {kw} in a repeat loop: as in LinuxCNC, break and continue apply to while and do loops only",
                            label_text(label)
                        ),
                    ),
                    Some(Frame {
                        open:
                            Open::Loop {
                                kind: LoopKind::Do, ..
                            },
                        ..
                    }) if kw == "continue" => err(
                        sink,
                        span,
                        DiagnosticKind::ControlFlow,
                        format!(
                            "{} continue in a do … while loop is refused: LinuxCNC 2.9 does not continue such a loop (it leaves it), so the program would not run as written; use while … endwhile",
                            label_text(label)
                        ),
                    ),
                    Some(Frame {
                        open: Open::Loop { exits, .. },
                        ..
                    }) => exits.push(i),
                    _ => err(
                        sink,
                        span,
                        DiagnosticKind::ControlFlow,
                        format!(
                            "{} {kw} outside a loop labelled {} (do, while or repeat)",
                            label_text(label),
                            label_text(label)
                        ),
                    ),
                }
            }
        }
    }
    for f in stack {
        let b = &program.blocks[f.index];
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
        err(
            sink,
            span,
            DiagnosticKind::ControlFlow,
            format!(
                "{} is never closed: {what} needs its closing statement with the same label",
                label_text(f.label)
            ),
        );
    }
    flow
}

fn close_loop(flow: &mut Flow, stack: &mut Vec<Frame>, end: usize, kind: LoopKind) {
    if let Some(Frame {
        index,
        open: Open::Loop { exits, .. },
        ..
    }) = stack.pop()
    {
        flow.jumps.insert(index, Jump::LoopStart { end });
        flow.jumps.insert(end, Jump::LoopEnd { start: index, kind });
        for e in exits {
            flow.jumps.insert(
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

/// Report a closing statement that does not close the innermost open construct.
#[allow(clippy::too_many_arguments)]
fn unmatched(
    sink: &mut Sink,
    stack: &[Frame],
    label_text: &dyn Fn(OLabel) -> String,
    line_of: impl Fn(usize) -> u32,
    label: OLabel,
    span: crate::diag::Span,
    keyword: &str,
    opener: &str,
) {
    let msg = match stack.last() {
        Some(f) => format!(
            "{} {keyword} does not match the innermost open statement, {} opened at line {} (expected {} {opener} before it)",
            label_text(label),
            label_text(f.label),
            line_of(f.index),
            label_text(label)
        ),
        None => format!(
            "{} {keyword} without a {} {opener} before it",
            label_text(label),
            label_text(label)
        ),
    };
    sink.push(Diagnostic::new(
        span,
        Severity::Error,
        DiagnosticKind::ControlFlow,
        msg,
    ));
}
