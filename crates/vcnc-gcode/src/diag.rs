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
    /// What is wrong, in words that name the offending text and values.
    pub message: String,
}

impl Diagnostic {
    /// An error at `span`.
    pub fn error(span: Span, message: impl Into<String>) -> Self {
        Diagnostic {
            line: span.line,
            col: span.col,
            severity: Severity::Error,
            message: message.into(),
        }
    }

    /// A warning at `span`.
    pub fn warning(span: Span, message: impl Into<String>) -> Self {
        Diagnostic {
            line: span.line,
            col: span.col,
            severity: Severity::Warning,
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
    pub(crate) fn report(&mut self, span: Span, severity: Severity, msg: &dyn Fn() -> String) {
        if self.list.len() < self.max {
            self.push(Diagnostic {
                line: span.line,
                col: span.col,
                severity,
                message: msg(),
            });
        } else {
            self.suppressed += 1;
            if severity == Severity::Error {
                self.suppressed_error = true;
            }
        }
    }

    /// [`Sink::report`] for any [`Message`].
    pub(crate) fn report_msg(&mut self, span: Span, severity: Severity, msg: impl Message) {
        if self.list.len() < self.max {
            self.push(Diagnostic {
                line: span.line,
                col: span.col,
                severity,
                message: msg.build(),
            });
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
                message: format!(
                    "{} further diagnostic(s) suppressed (the limit is {})",
                    self.suppressed, self.max
                ),
            });
        }
        self.list
    }
}
