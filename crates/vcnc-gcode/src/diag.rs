//! Source spans and diagnostics shared by the parser and the interpreter.

use std::fmt;

/// Where a piece of syntax sits in the source text.
///
/// `line` and `col` are 1-based and meant for people (`col` counts Unicode characters, so a
/// multi-byte character is one column); `start..end` is the byte range in the whole source,
/// meant for tools.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Span {
    /// Line number, 1-based.
    pub line: u32,
    /// Column of the first character, 1-based, in characters.
    pub col: u32,
    /// Byte offset of the first byte in the source.
    pub start: usize,
    /// Byte offset one past the last byte in the source.
    pub end: usize,
}

/// How bad a diagnostic is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Severity {
    /// Reported and carried on: the program still runs (for example an unknown code under
    /// `lenient`).
    Warning,
    /// The program cannot be run as written.
    Error,
}

impl fmt::Display for Severity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Severity::Warning => f.write_str("warning"),
            Severity::Error => f.write_str("error"),
        }
    }
}

/// What kind of problem a [`Diagnostic`] reports, for programs that act on it (the message is
/// for people). The bad-input cases of docs/gcode.md ("Bad input") each have their own kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DiagnosticKind {
    /// Malformed text: numbers, comments, words without values, stray characters.
    Syntax,
    /// A `[` without its `]`, or a `]` without its `[`.
    UnbalancedBracket,
    /// A parameter number that is not a whole number in 1..=5601.
    ParameterNumber,
    /// A named parameter read before it was set.
    UndefinedParameter,
    /// Division by zero, or a function outside its domain (`SQRT` of a negative, …).
    Arithmetic,
    /// O-word statements that do not match (`endsub` without `sub`, `endif` without `if`, …).
    ControlFlow,
    /// An O-word with an unknown keyword (`o100 frobnicate`).
    UnknownOWord,
    /// A call of a subroutine that the file does not define.
    UndefinedSubroutine,
    /// The loop-iteration budget is exhausted: the program does not end.
    LoopBudget,
    /// Subroutine calls nested deeper than the limit.
    CallDepth,
    /// An unknown or unsupported G-code, M-code or word.
    Unsupported,
    /// Cutter radius compensation (`G40`–`G42.1`): what LinuxCNC refuses (the tool cannot
    /// reach a concave corner, an entry move too short, codes not allowed while it is on) and
    /// what vcnc does not do (in `G18`: an entry arc with a lathe tool orientation, a rotated
    /// coordinate system).
    CutterCompensation,
    /// Words that conflict, are missing or have no code that uses them.
    Block,
    /// A move that cannot be made (arc geometry, missing feed, bad offsets, …).
    Motion,
    /// The program stopped itself with `(ABORT, …)`.
    Abort,
    /// A size limit was reached (line length, blocks, moves, diagnostics).
    Limit,
    /// Anything else, including every warning.
    Other,
}

/// One problem found in a program, with its position.
///
/// `Display` prints `line:col: message`; the binary prefixes the file name
/// (`path:line:col: message`, STYLE "Errors").
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Diagnostic {
    /// Line number, 1-based.
    pub line: u32,
    /// Column, 1-based, in characters.
    pub col: u32,
    /// Error or warning.
    pub severity: Severity,
    /// What kind of problem it is.
    pub kind: DiagnosticKind,
    /// What is wrong, in words that name the offending text and values.
    pub message: String,
}

impl Diagnostic {
    /// An error of kind [`DiagnosticKind::Other`] at `span`.
    pub fn error(span: Span, message: impl Into<String>) -> Self {
        Diagnostic::new(span, Severity::Error, DiagnosticKind::Other, message)
    }

    /// A warning at `span`.
    pub fn warning(span: Span, message: impl Into<String>) -> Self {
        Diagnostic::new(span, Severity::Warning, DiagnosticKind::Other, message)
    }

    /// A diagnostic of any severity and kind at `span`.
    pub fn new(
        span: Span,
        severity: Severity,
        kind: DiagnosticKind,
        message: impl Into<String>,
    ) -> Self {
        Diagnostic {
            line: span.line,
            col: span.col,
            severity,
            kind,
            message: message.into(),
        }
    }

    /// `true` for [`Severity::Error`].
    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: {}", self.line, self.col, self.message)
    }
}

/// A diagnostic message, built only when it is stored: a literal, a `String`, or a closure.
pub(crate) trait Message {
    fn build(self) -> String;
}

impl Message for &str {
    fn build(self) -> String {
        self.to_string()
    }
}

impl Message for String {
    fn build(self) -> String {
        self
    }
}

impl<F: FnOnce() -> String> Message for F {
    fn build(self) -> String {
        self()
    }
}

/// A bounded collector: keeps the first `max` diagnostics and counts the rest, so a junk input
/// cannot make the diagnostic list grow without bound.
#[derive(Debug, Clone)]
pub(crate) struct Sink {
    pub(crate) list: Vec<Diagnostic>,
    max: usize,
    suppressed: usize,
    suppressed_error: bool,
    last_span: Span,
}

impl Sink {
    pub(crate) fn new(max: usize) -> Self {
        Sink {
            list: Vec::new(),
            max: max.max(1),
            suppressed: 0,
            suppressed_error: false,
            last_span: Span::default(),
        }
    }

    /// Report a diagnostic whose message is built only if it will be stored (junk input can
    /// produce millions of diagnostics; formatting them all would dominate the run time).
    pub(crate) fn report(
        &mut self,
        span: Span,
        severity: Severity,
        kind: DiagnosticKind,
        msg: &dyn Fn() -> String,
    ) {
        if self.list.len() < self.max {
            self.push(Diagnostic::new(span, severity, kind, msg()));
        } else {
            self.suppressed += 1;
            if severity == Severity::Error {
                self.suppressed_error = true;
            }
        }
    }

    /// [`Sink::report`] for any [`Message`].
    pub(crate) fn report_msg(
        &mut self,
        span: Span,
        severity: Severity,
        kind: DiagnosticKind,
        msg: impl Message,
    ) {
        if self.list.len() < self.max {
            self.push(Diagnostic::new(span, severity, kind, msg.build()));
        } else {
            self.suppressed += 1;
            if severity == Severity::Error {
                self.suppressed_error = true;
            }
        }
    }

    pub(crate) fn push(&mut self, d: Diagnostic) {
        if self.list.len() < self.max {
            self.last_span = Span {
                line: d.line,
                col: d.col,
                start: 0,
                end: 0,
            };
            self.list.push(d);
        } else {
            self.suppressed += 1;
            // Suppressed errors must still make the result an error.
            if d.is_error() {
                self.suppressed_error = true;
            }
        }
    }

    pub(crate) fn has_errors(&self) -> bool {
        self.suppressed_error || self.list.iter().any(Diagnostic::is_error)
    }

    /// Close the list: append one note saying how many diagnostics were suppressed.
    pub(crate) fn finish(mut self) -> Vec<Diagnostic> {
        if self.suppressed > 0 {
            let severity = if self.suppressed_error {
                Severity::Error
            } else {
                Severity::Warning
            };
            self.list.push(Diagnostic {
                line: self.last_span.line,
                col: self.last_span.col,
                severity,
                kind: DiagnosticKind::Limit,
                message: format!(
                    "{} further diagnostic(s) suppressed (the limit is {})",
                    self.suppressed, self.max
                ),
            });
        }
        self.list
    }
}
