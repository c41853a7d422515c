//! G-code *syntax*: lines, words, expressions, parameter assignments, O-word statements,
//! comments and their source spans (no machine meaning; the dialect is described in this
//! repository's docs/gcode.md, "Syntax").
//!
//! - one block per line (`\n` or `\r\n`); blank lines are dropped;
//! - `%` alone on a line delimits the program;
//! - `/` as the first character of a line marks a block-delete line;
//! - `N` followed by a whole number, first in the block (after `/`), is the line number;
//! - `( … )` and `; …` comments (LinuxCNC does not nest parentheses: a `(` inside a comment is
//!   reported);
//! - words are a letter (case-insensitive, plus `@` and `^` for polar coordinates) and a value:
//!   a number (optional sign, digits with at most one decimal point, no exponent; as in
//!   LinuxCNC blanks may appear inside: `X - 1 2.5` is `X-12.5`), or an expression: `[ … ]`,
//!   a parameter `#…`, a function `SIN[…]`, or a signed one of those (`X-#1`). Plain numbers are
//!   stored in [`Word::value`]; anything else becomes an expression tree in
//!   [`Program::exprs`] ([`Expr`]);
//! - `#n = value`, `#<name> = value` assign parameters (several per line; their effect comes at
//!   the end of the line, which the interpreter handles);
//! - `O<label> keyword …` is an O-word statement (subroutines, conditions, loops); it must be
//!   the only statement on its line, as in LinuxCNC.
//!
//! The parser never stops at the first problem: every diagnostic is collected with its
//! line:column, and parsing resumes at the next token (after a malformed value, at the next
//! line). Problems that only mean "another dialect" (a word without a value such as
//! `G28 X Y Z`, nested comments, RepRap checksums `*57` and quoted strings, stray characters)
//! are errors, downgraded to warnings under [`ParseOptions::lenient`]; the offending text is
//! skipped either way. Expressions, parameters and O-words are never downgraded: dropping them
//! would change what the program does.
//!
//! Robustness: any `&str` is accepted without panicking, in time linear in its length
//! (expression nesting is capped at 64 levels). A line longer than
//! [`ParseOptions::max_line_bytes`] is reported and skipped, the number of blocks is capped by
//! [`ParseOptions::max_blocks`] and the number of stored diagnostics by
//! [`ParseOptions::max_diagnostics`] (the rest are counted and the count is reported), so memory
//! stays bounded by the input size. [`parse_bytes`] accepts arbitrary bytes (invalid UTF-8
//! becomes U+FFFD and is reported as an unexpected character).

mod expr;
mod lexer;

use std::collections::HashMap;

pub(crate) use expr::parameter_number;
pub use expr::{BinOp, Expr, ExprId, ExprKind, Func, MAX_PARAMETER, NameId, ParamRef};

use crate::diag::{Diagnostic, DiagnosticKind, Severity, Sink, Span};
use expr::{Abandon, Value};
use lexer::{Flaw, Lexer, Tok};

/// Longest parameter or O-word name, in bytes.
const MAX_NAME_LEN: usize = 255;

/// Parser settings. Plain data; [`Default`] gives the documented defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct ParseOptions {
    /// Downgrade dialect problems (see the module doc) from errors to warnings. Default `false`.
    pub lenient: bool,
    /// Longest accepted line, in bytes (without the line break). Default 4096 (LinuxCNC itself
    /// accepts 255 characters).
    pub max_line_bytes: usize,
    /// Most blocks kept; the rest of the program is reported and dropped. Default 5 000 000.
    pub max_blocks: usize,
    /// Most diagnostics stored; further ones are counted in one closing note. Default 1000.
    pub max_diagnostics: usize,
}

impl Default for ParseOptions {
    fn default() -> Self {
        ParseOptions {
            lenient: false,
            max_line_bytes: 4096,
            max_blocks: 5_000_000,
            max_diagnostics: 1000,
        }
    }
}

/// A parsed program: its lines that hold syntax, in order, and the expressions and names they
/// refer to.
///
/// Memory is about 150 bytes per block plus 40 per word (a word whose value is an expression
/// costs the same 40 bytes, plus 40 per expression node); [`ParseOptions::max_blocks`] and
/// [`ParseOptions::max_line_bytes`] bound it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Program {
    /// One block per line that holds syntax (blank and junk-only lines are dropped).
    pub blocks: Vec<Block>,
    /// Expression nodes, referred to by [`ExprId`] from words, assignments and O-words.
    pub exprs: Vec<Expr>,
    /// Parameter and O-word names (lower-case, blanks removed), referred to by [`NameId`].
    pub names: Vec<String>,
}

impl Program {
    /// The expression node `id`.
    pub fn expr(&self, id: ExprId) -> &Expr {
        &self.exprs[id.index()]
    }

    /// The name `id`.
    pub fn name(&self, id: NameId) -> &str {
        self.names.get(id.index()).map_or("", String::as_str)
    }
}

/// One line of G-code.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Block {
    /// Line number in the file, 1-based (not the `N` word: see [`Block::line_number`]).
    pub line: u32,
    /// The whole line, without its line break.
    pub span: Span,
    /// `true` when the line starts with `/` (block delete).
    pub block_delete: bool,
    /// `true` when the line is a `%` program delimiter.
    pub percent: bool,
    /// The `N` word, if the block has one.
    pub line_number: Option<LineNumber>,
    /// The words in source order (letters upper-cased).
    pub words: Vec<Word>,
    /// The comments in source order.
    pub comments: Vec<Comment>,
    /// Parameter assignments in source order (they take effect at the end of the line).
    pub assignments: Vec<Assignment>,
    /// The O-word statement, when the line is one.
    pub o_word: Option<Box<OWord>>,
}

/// An `N` line number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineNumber {
    /// The number after `N` (dimensionless label).
    pub value: u32,
    /// From the `N` to the last digit.
    pub span: Span,
}

/// A word: a letter and its value, e.g. `X-0.5`, `G43.4` or `X[#1 + 2]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Word {
    /// Upper-case ASCII letter, or `@` / `^` (polar radius and angle).
    pub letter: char,
    /// The number exactly as written (finite; units depend on the letter and the modal state,
    /// which this module does not know); NaN when the value is an expression.
    pub value: f64,
    /// The value's expression when it is not a plain number.
    pub expr: Option<ExprId>,
    /// From the letter to the last character of the value.
    pub span: Span,
}

/// `#target = value`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Assignment {
    /// The parameter assigned.
    pub target: ParamRef,
    /// The value (an expression node; a plain number is a [`ExprKind::Number`] node).
    pub value: ExprId,
    /// From the `#` to the end of the value.
    pub span: Span,
}

/// An O-word label: `o100` or `o<name>`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum OLabel {
    /// `o` followed by a whole number.
    Number(u32),
    /// `o<name>`.
    Name(NameId),
}

/// An O-word statement (LinuxCNC O-codes).
#[derive(Debug, Clone, PartialEq)]
pub struct OWord {
    /// The label that ties the statements of one construct together.
    pub label: OLabel,
    /// The label's text (`o100`, `o<name>`).
    pub label_span: Span,
    /// The keyword and its arguments.
    pub statement: OStatement,
    /// The keyword's text.
    pub keyword_span: Span,
}

/// O-word keywords with their arguments.
#[derive(Debug, Clone, PartialEq)]
pub enum OStatement {
    /// `sub`: starts a subroutine definition.
    Sub,
    /// `endsub [value]`: ends it (and returns, setting `#<_value>` when a value is given).
    EndSub(Option<ExprId>),
    /// `call [a] [b] …`: calls the subroutine with `#1`, `#2`, … set to the arguments.
    Call(Vec<ExprId>),
    /// `return [value]`: returns early.
    Return(Option<ExprId>),
    /// `if [cond]`.
    If(ExprId),
    /// `elseif [cond]`.
    ElseIf(ExprId),
    /// `else`.
    Else,
    /// `endif`.
    EndIf,
    /// `while [cond]`: starts a while loop, or ends a `do` loop with the same label.
    While(ExprId),
    /// `endwhile`.
    EndWhile,
    /// `do`.
    Do,
    /// `repeat [count]`.
    Repeat(ExprId),
    /// `endrepeat`.
    EndRepeat,
    /// `break`: leaves the loop with the same label.
    Break,
    /// `continue`: starts the next iteration of the loop with the same label.
    Continue,
    /// `O1234` with no keyword: a program number (Fanuc style), ignored as by LinuxCNC.
    ProgramNumber,
}

/// Comment style.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommentKind {
    /// `( … )`.
    Paren,
    /// `; …` to the end of the line.
    Semicolon,
}

/// A comment.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Comment {
    /// Text between the delimiters, untrimmed.
    pub text: String,
    /// Which delimiters.
    pub kind: CommentKind,
    /// From the opening delimiter to the closing one (or the end of the line).
    pub span: Span,
}

/// Parse with the default (strict) options.
pub fn parse(src: &str) -> (Program, Vec<Diagnostic>) {
    parse_with(src, &ParseOptions::default())
}

/// Parse arbitrary bytes: invalid UTF-8 sequences become U+FFFD (and are then reported as
/// unexpected characters). Spans refer to the converted text.
pub fn parse_bytes(src: &[u8], opts: &ParseOptions) -> (Program, Vec<Diagnostic>) {
    let text = String::from_utf8_lossy(src);
    parse_with(&text, opts)
}

/// Expression arena and name table under construction.
#[derive(Default)]
struct Builder {
    exprs: Vec<Expr>,
    names: Vec<String>,
    index: HashMap<String, NameId>,
}

impl Builder {
    fn push_expr(&mut self, e: Expr) -> Option<ExprId> {
        let id = ExprId::from_index(self.exprs.len())?;
        self.exprs.push(e);
        Some(id)
    }

    fn intern(&mut self, name: &str) -> NameId {
        if let Some(&id) = self.index.get(name) {
            return id;
        }
        // Names are at most MAX_NAME_LEN bytes and at most one per few bytes of input, so the
        // count fits u32 for any input below 4 GB; saturate rather than wrap beyond it.
        let id = NameId(u32::try_from(self.names.len()).unwrap_or(u32::MAX));
        self.names.push(name.to_string());
        self.index.insert(name.to_string(), id);
        id
    }
}

/// Parse `src`, collecting every diagnostic (see the module doc for the limits).
pub fn parse_with(src: &str, opts: &ParseOptions) -> (Program, Vec<Diagnostic>) {
    let mut parser = ChunkParser::new(opts);
    let program = parser.parse_chunk(src);
    (program, parser.finish())
}

/// A parser fed a program a piece at a time, for programs too long to hold (`vcnc interpolate`
/// streams them, docs/performance.md).
///
/// Each call to [`ChunkParser::parse_chunk`] takes the next whole lines of the program and
/// returns their blocks as a [`Program`] of their own: line numbers and byte offsets continue
/// from the previous piece, the name table ([`Program::names`]) is shared, so that a
/// [`NameId`] means the same name in every piece, and each piece has its own expressions.
/// Parsing a program in pieces gives the same blocks and diagnostics as parsing it whole,
/// provided every piece ends with a line break (the last may not).
/// [`ParseOptions::max_blocks`] counts the blocks of all pieces together.
#[derive(Debug)]
pub struct ChunkParser {
    opts: ParseOptions,
    sink: Sink,
    names: Vec<String>,
    index: HashMap<String, NameId>,
    blocks_so_far: usize,
    line_no: u32,
    base: usize,
    stopped: bool,
}

impl ChunkParser {
    /// A parser at the start of a program.
    pub fn new(opts: &ParseOptions) -> Self {
        ChunkParser {
            opts: opts.clone(),
            sink: Sink::new(opts.max_diagnostics),
            names: Vec::new(),
            index: HashMap::new(),
            blocks_so_far: 0,
            line_no: 0,
            base: 0,
            stopped: false,
        }
    }

    /// `true` once an error has been reported (in any piece so far).
    pub fn has_errors(&self) -> bool {
        self.sink.has_errors()
    }

    /// Parse the next piece: whole lines, the line break of its last line included (except at
    /// the end of the program).
    pub fn parse_chunk(&mut self, src: &str) -> Program {
        let mut program = self.parse_piece(src);
        program.names = self.names.clone();
        program
    }

    /// The names of every piece so far ([`Program::names`]).
    pub(crate) fn names(&self) -> &[String] {
        &self.names
    }

    /// [`ChunkParser::parse_chunk`] without a copy of the names in the piece (they are
    /// [`ChunkParser::names`]).
    pub(crate) fn parse_piece(&mut self, src: &str) -> Program {
        let mut builder = Builder {
            exprs: Vec::new(),
            names: std::mem::take(&mut self.names),
            index: std::mem::take(&mut self.index),
        };
        let opts = &self.opts;
        let sink = &mut self.sink;
        let mut blocks = Vec::new();
        let mut base = self.base;
        let mut line_no = self.line_no;
        // A final piece without a trailing line break has one line more than its breaks.
        let mut pieces = src.split('\n').peekable();
        while let Some(raw) = pieces.next() {
            if pieces.peek().is_none() && raw.is_empty() && !src.is_empty() {
                // The empty remainder after the piece's last line break is not a line.
                break;
            }
            line_no = line_no.saturating_add(1);
            let start = base;
            base += raw.len() + 1;
            if self.stopped {
                continue;
            }
            let text = raw.strip_suffix('\r').unwrap_or(raw);
            if text.trim().is_empty() {
                continue;
            }
            let line_span = Span {
                line: line_no,
                col: 1,
                start,
                end: start + text.len(),
            };
            if text.len() > opts.max_line_bytes {
                sink.report(line_span, Severity::Error, DiagnosticKind::Limit, &|| {
                    format!(
                        "line is {} bytes long, longer than the limit of {} bytes; it is skipped",
                        text.len(),
                        opts.max_line_bytes
                    )
                });
                continue;
            }
            if self.blocks_so_far + blocks.len() >= opts.max_blocks {
                sink.push(Diagnostic::new(
                    line_span,
                    Severity::Error,
                    DiagnosticKind::Limit,
                    format!(
                        "program has more than {} blocks; the rest of the program is not parsed",
                        opts.max_blocks
                    ),
                ));
                self.stopped = true;
                continue;
            }
            let block = LineParser::new(text, line_span, opts.lenient, sink, &mut builder).run();
            // A line of pure junk leaves only diagnostics: do not keep an empty block for it.
            let empty = block.words.is_empty()
                && block.comments.is_empty()
                && block.assignments.is_empty()
                && block.o_word.is_none()
                && block.line_number.is_none()
                && !block.percent
                && !block.block_delete;
            if !empty {
                blocks.push(block);
            }
        }
        self.base = base;
        self.line_no = line_no;
        self.blocks_so_far += blocks.len();
        self.index = builder.index;
        self.names = builder.names;
        Program {
            blocks,
            exprs: builder.exprs,
            names: Vec::new(),
        }
    }

    /// Where the next piece starts: the number of lines read so far and the byte offset (in
    /// the text as parsed) of the next line.
    pub(crate) fn position(&self) -> (u32, usize) {
        (self.line_no, self.base)
    }

    /// Parse again whole lines read before, starting after line `line` at byte offset `base`
    /// (a streamed program's jump back, `interp/seek.rs`): the blocks are those the first
    /// reading gave, the diagnostics are not reported again, and the parser's position is
    /// kept. Returns the blocks (without the names: [`ChunkParser::names`]) and the position
    /// after them.
    pub(crate) fn parse_again(
        &mut self,
        src: &str,
        line: u32,
        base: usize,
    ) -> (Program, u32, usize) {
        let kept = (
            self.line_no,
            self.base,
            self.blocks_so_far,
            self.stopped,
            std::mem::replace(&mut self.sink, Sink::new(1)),
        );
        self.line_no = line;
        self.base = base;
        self.stopped = false;
        let program = self.parse_piece(src);
        let end = (self.line_no, self.base);
        (
            self.line_no,
            self.base,
            self.blocks_so_far,
            self.stopped,
            self.sink,
        ) = kept;
        (program, end.0, end.1)
    }

    /// Every diagnostic of every piece, in order.
    pub fn finish(self) -> Vec<Diagnostic> {
        self.sink.finish()
    }
}

/// Parser of one line.
struct LineParser<'a, 's> {
    lx: Lexer<'a>,
    block: Block,
    sink: &'s mut Sink,
    builder: &'s mut Builder,
    lenient: bool,
    /// Anything but comments seen yet (for `/`, `%`, `N` and `O` placement)?
    content: bool,
}

impl<'a, 's> LineParser<'a, 's> {
    fn new(
        text: &'a str,
        line_span: Span,
        lenient: bool,
        sink: &'s mut Sink,
        builder: &'s mut Builder,
    ) -> Self {
        LineParser {
            lx: Lexer::new(text, line_span),
            block: Block {
                line: line_span.line,
                span: line_span,
                ..Block::default()
            },
            sink,
            builder,
            lenient,
            content: false,
        }
    }

    /// An error that is never downgraded.
    fn error(&mut self, span: Span, kind: DiagnosticKind, msg: String) {
        self.sink
            .push(Diagnostic::new(span, Severity::Error, kind, msg));
    }

    /// A dialect problem: an error, or a warning under `lenient`.
    fn dialect(&mut self, span: Span, msg: &dyn Fn() -> String) {
        let sev = if self.lenient {
            Severity::Warning
        } else {
            Severity::Error
        };
        self.sink.report(span, sev, DiagnosticKind::Syntax, msg);
    }

    fn run(mut self) -> Block {
        while let Some((tok, span)) = self.lx.next() {
            if self.token(tok, span).is_err() {
                // A malformed value: the rest of the line cannot be read reliably.
                break;
            }
        }
        self.block
    }

    fn token(&mut self, tok: Tok<'a>, span: Span) -> Result<(), Abandon> {
        if self.block.o_word.is_some() && !matches!(tok, Tok::Comment(..)) {
            self.error(
                span,
                DiagnosticKind::Syntax,
                "unexpected text after an O-word statement (an O-word must be alone on its line)"
                    .into(),
            );
            return Err(Abandon);
        }
        match tok {
            Tok::Comment(body, kind, flaw) => {
                match flaw {
                    Flaw::None => {}
                    Flaw::Unclosed => self.dialect(span, &|| {
                        "comment opened with '(' is never closed on this line".to_string()
                    }),
                    Flaw::Nested => self.dialect(span, &|| {
                        "nested '(' inside a comment (comments do not nest in RS274/NGC)"
                            .to_string()
                    }),
                }
                self.block.comments.push(Comment {
                    text: body,
                    kind,
                    span,
                });
            }
            Tok::Slash => {
                if self.content || self.block.block_delete || !self.block.comments.is_empty() {
                    self.dialect(span, &|| {
                        "'/' (block delete) is only allowed at the start of a line".into()
                    });
                } else {
                    self.block.block_delete = true;
                }
            }
            Tok::Percent => {
                if self.content || self.block.block_delete || self.block.percent {
                    self.dialect(span, &|| {
                        "'%' (program delimiter) must be alone on its line".into()
                    });
                } else {
                    self.block.percent = true;
                }
                self.content = true;
            }
            Tok::Letter('O') => {
                let only_n = self.block.words.is_empty()
                    && self.block.assignments.is_empty()
                    && !self.block.percent;
                self.content = true;
                if !only_n {
                    self.error(
                        span,
                        DiagnosticKind::Syntax,
                        "an O-word must start its line (only '/' and an N word may precede it)"
                            .into(),
                    );
                    return Err(Abandon);
                }
                self.o_word(span)?;
            }
            Tok::Letter(letter) => {
                let was_content = self.content;
                self.content = true;
                if self.block.percent {
                    self.dialect(span, &|| {
                        "'%' (program delimiter) must be alone on its line".into()
                    });
                }
                self.word(letter, span, was_content)?;
            }
            Tok::Hash => {
                self.content = true;
                self.assignment(span)?;
            }
            Tok::LBracket => {
                self.content = true;
                self.error(
                    span,
                    DiagnosticKind::Syntax,
                    "'[' expression without a word letter or '#n =' before it".into(),
                );
                return Err(Abandon);
            }
            Tok::RBracket => {
                self.content = true;
                self.error(
                    span,
                    DiagnosticKind::UnbalancedBracket,
                    "unbalanced ']': no '[' opened it".into(),
                );
                return Err(Abandon);
            }
            Tok::Equals => {
                self.content = true;
                self.error(
                    span,
                    DiagnosticKind::Syntax,
                    "'=' without a parameter before it (assignments are written #n = value)".into(),
                );
                return Err(Abandon);
            }
            Tok::Number(_, raw) => {
                self.content = true;
                self.dialect(span, &|| format!("number '{raw}' has no letter before it"));
            }
            Tok::Str => {
                self.content = true;
                self.dialect(span, &|| {
                    "quoted string: RS274/NGC has no string values".into()
                });
            }
            Tok::Checksum => {
                let raw = self.lx.text_from_start(span).to_string();
                self.dialect(span, &|| {
                    format!("checksum '{raw}' is not RS274/NGC (RepRap dialect)")
                });
            }
            Tok::Junk(c) => {
                self.content = true;
                self.dialect(span, &|| match c {
                    '\u{FFFD}' => "invalid UTF-8 or replacement character".to_string(),
                    c if c.is_control() => {
                        format!("unexpected control character U+{:04X}", c as u32)
                    }
                    c => format!("unexpected character '{c}'"),
                });
            }
        }
        Ok(())
    }

    /// The value of the word whose letter is at `span`.
    fn word(&mut self, letter: char, span: Span, was_content: bool) -> Result<(), Abandon> {
        // Fast path: a plain number (by far the most common value).
        if let Some((tok, nspan)) = self.plain_number() {
            if let Tok::Number(Some(v), _) = tok {
                let wspan = Span {
                    end: nspan.end,
                    ..span
                };
                if letter == 'N' {
                    self.line_number(v, wspan, was_content);
                } else {
                    self.block.words.push(Word {
                        letter,
                        value: v,
                        expr: None,
                        span: wspan,
                    });
                }
                return Ok(());
            }
            // A malformed number: the general path reports it.
            self.lx.reset(self.lx.mark_at(nspan));
        }
        let save = self.lx.mark();
        let next = self.lx.peek_non_ws();
        let starts_value = match next {
            Some(b'0'..=b'9' | b'.' | b'+' | b'-' | b'[' | b'#') => true,
            Some(b) if b.is_ascii_alphabetic() => {
                // A function call (`XSIN[30]`) is a value; other letters start the next word.
                let (_, name) = self.lx.alpha_run();
                let is_call = self.lx.peek_non_ws() == Some(b'[');
                self.lx.reset(save);
                is_call && !name.is_empty()
            }
            _ => false,
        };
        if !starts_value {
            if next == Some(b'"') {
                self.lx.skip_ws();
                let _ = self.lx.next();
                self.dialect(span, &|| {
                    format!(
                        "word '{letter}' has a quoted string value, which RS274/NGC does not have"
                    )
                });
                return Ok(());
            }
            // Skip a glued run of letters (`Hello`) so it yields one diagnostic.
            self.lx.skip_alpha_run();
            let word = self.lx.text_from_start(span).to_string();
            self.dialect(span, &|| {
                if word.len() > 1 {
                    format!("'{word}' is not a word: letter '{letter}' has no value")
                } else {
                    format!("word '{letter}' has no value")
                }
            });
            return Ok(());
        }
        let (value, vspan) = self.real_value(0, expr::Ctx::Word(letter))?;
        let wspan = Span {
            end: vspan.end,
            ..span
        };
        match value {
            Value::Number(v) if letter == 'N' => self.line_number(v, wspan, was_content),
            Value::Number(v) => self.block.words.push(Word {
                letter,
                value: v,
                expr: None,
                span: wspan,
            }),
            Value::Expr(id) => {
                if letter == 'N' {
                    self.error(
                        wspan,
                        DiagnosticKind::Syntax,
                        "a line number N must be a plain whole number".into(),
                    );
                    return Ok(());
                }
                self.block.words.push(Word {
                    letter,
                    value: f64::NAN,
                    expr: Some(id),
                    span: wspan,
                });
            }
        }
        Ok(())
    }

    /// The number that starts here (after blanks), if the value is a plain number: digits or a
    /// point, or a sign directly followed by them.
    fn plain_number(&mut self) -> Option<(Tok<'a>, Span)> {
        let start = self.lx.mark();
        self.lx.skip_ws();
        match self.lx.peek() {
            Some(b'0'..=b'9' | b'.') => Some(self.lx.number()),
            Some(b'+' | b'-') => {
                let m = self.lx.mark();
                self.lx.bump();
                let digit = matches!(self.lx.peek_non_ws(), Some(b'0'..=b'9' | b'.'));
                self.lx.reset(m);
                if digit {
                    Some(self.lx.number())
                } else {
                    self.lx.reset(start);
                    None
                }
            }
            _ => {
                self.lx.reset(start);
                None
            }
        }
    }

    fn line_number(&mut self, value: f64, span: Span, was_content: bool) {
        let whole = value >= 0.0 && value.fract() == 0.0 && value <= f64::from(u32::MAX);
        if !whole {
            self.error(
                span,
                DiagnosticKind::Syntax,
                format!("line number N{value} is not a whole number in 0..=4294967295"),
            );
        } else if was_content || self.block.line_number.is_some() {
            self.dialect(span, &|| {
                format!("line number N{value} must start the block")
            });
        } else {
            self.block.line_number = Some(LineNumber {
                // Checked above to be a whole number in range.
                value: value as u32,
                span,
            });
        }
    }

    /// `#target = value`; the `#` is at `hash`.
    fn assignment(&mut self, hash: Span) -> Result<(), Abandon> {
        let start = lexer_mark_at(&self.lx, hash);
        let target = self.param_ref(start, 1)?;
        self.lx.skip_ws();
        if self.lx.peek() != Some(b'=') {
            let span = self.lx.span_from(start);
            let text = self.lx.text_from(start).trim().to_string();
            self.error(
                span,
                DiagnosticKind::Syntax,
                format!("parameter {text} is not assigned: expected '=' after it (#n = value)"),
            );
            return Err(Abandon);
        }
        self.lx.bump();
        let (value, vspan) = self.real_value(0, expr::Ctx::Assignment)?;
        let value = match value {
            Value::Expr(id) => id,
            Value::Number(x) => self
                .builder
                .push_expr(Expr {
                    kind: ExprKind::Number(x),
                    span: vspan,
                })
                .ok_or(Abandon)?,
        };
        let span = self.lx.span_from(start);
        self.block.assignments.push(Assignment {
            target,
            value,
            span,
        });
        // `#1 = 2 + 3` is not an expression: LinuxCNC needs `[2 + 3]`.
        if let Some(op @ (b'+' | b'-' | b'*' | b'/')) = self.lx.peek_non_ws() {
            self.lx.skip_ws();
            let m = self.lx.mark();
            self.lx.bump();
            let s = self.lx.span_from(m);
            self.error(
                s,
                DiagnosticKind::Syntax,
                format!(
                    "operator '{}' outside [ ]: an expression must be in brackets (#n = [a {} b])",
                    char::from(op),
                    char::from(op)
                ),
            );
            return Err(Abandon);
        }
        Ok(())
    }

    /// `O<label> keyword [args]`; the `O` is at `o_span`.
    fn o_word(&mut self, o_span: Span) -> Result<(), Abandon> {
        let start = lexer_mark_at(&self.lx, o_span);
        self.lx.skip_ws();
        let label = match self.lx.peek() {
            Some(b'<') => {
                let id = self.o_name()?;
                OLabel::Name(id)
            }
            Some(b'0'..=b'9') => {
                let (tok, nspan) = self.lx.number();
                match tok {
                    Tok::Number(Some(v), _)
                        if v >= 0.0 && v.fract() == 0.0 && v <= f64::from(u32::MAX) =>
                    {
                        OLabel::Number(v as u32)
                    }
                    _ => {
                        self.error(
                            nspan,
                            DiagnosticKind::Syntax,
                            "an O-word label must be a whole number or <name>".into(),
                        );
                        return Err(Abandon);
                    }
                }
            }
            _ => {
                let span = self.lx.span_from(start);
                self.error(
                    span,
                    DiagnosticKind::Syntax,
                    "an O-word needs a label: a whole number or <name> (o100, o<name>)".into(),
                );
                return Err(Abandon);
            }
        };
        let label_span = self.lx.span_from(start);
        let (kw_mark, keyword) = self.lx.alpha_run();
        let keyword_span = self.lx.span_from(kw_mark);
        let keyword = keyword.to_ascii_lowercase();
        let statement = match keyword.as_str() {
            "" => {
                // A bare `O1234` (Fanuc program number): only comments may follow.
                match self.lx.peek_non_ws() {
                    None | Some(b'(' | b';') => OStatement::ProgramNumber,
                    Some(_) => {
                        self.lx.skip_ws();
                        let m = self.lx.mark();
                        let _ = self.lx.bump_char();
                        let span = self.lx.span_from(m);
                        self.error(
                            span,
                            DiagnosticKind::UnknownOWord,
                            "an O-word needs a keyword (sub, endsub, call, return, if, elseif, else, endif, do, while, endwhile, repeat, endrepeat, break, continue)".into(),
                        );
                        return Err(Abandon);
                    }
                }
            }
            "sub" => OStatement::Sub,
            "endsub" => OStatement::EndSub(self.optional_bracket()?),
            "return" => OStatement::Return(self.optional_bracket()?),
            "call" => {
                let mut args = Vec::new();
                while self.lx.peek_non_ws() == Some(b'[') {
                    args.push(self.bracket_arg()?);
                }
                OStatement::Call(args)
            }
            "if" => OStatement::If(self.required_bracket(&keyword, keyword_span)?),
            "elseif" => OStatement::ElseIf(self.required_bracket(&keyword, keyword_span)?),
            "else" => OStatement::Else,
            "endif" => OStatement::EndIf,
            "while" => OStatement::While(self.required_bracket(&keyword, keyword_span)?),
            "endwhile" => OStatement::EndWhile,
            "do" => OStatement::Do,
            "repeat" => OStatement::Repeat(self.required_bracket(&keyword, keyword_span)?),
            "endrepeat" => OStatement::EndRepeat,
            "break" => OStatement::Break,
            "continue" => OStatement::Continue,
            other => {
                self.error(
                    keyword_span,
                    DiagnosticKind::UnknownOWord,
                    format!("unknown O-word keyword '{other}' (known: sub, endsub, call, return, if, elseif, else, endif, do, while, endwhile, repeat, endrepeat, break, continue)"),
                );
                return Err(Abandon);
            }
        };
        self.block.o_word = Some(Box::new(OWord {
            label,
            label_span,
            statement,
            keyword_span,
        }));
        Ok(())
    }

    /// `<name>` of an O-word (same rules as parameter names).
    fn o_name(&mut self) -> Result<NameId, Abandon> {
        self.lx.skip_ws();
        let m = self.lx.mark();
        self.name(m)
    }

    fn optional_bracket(&mut self) -> Result<Option<ExprId>, Abandon> {
        if self.lx.peek_non_ws() == Some(b'[') {
            Ok(Some(self.bracket_arg()?))
        } else {
            Ok(None)
        }
    }

    fn required_bracket(&mut self, keyword: &str, kw_span: Span) -> Result<ExprId, Abandon> {
        if self.lx.peek_non_ws() == Some(b'[') {
            self.bracket_arg()
        } else {
            self.error(
                kw_span,
                DiagnosticKind::Syntax,
                format!("'{keyword}' needs a condition in brackets: {keyword} [expression]"),
            );
            Err(Abandon)
        }
    }

    /// A `[ … ]` argument as an expression node.
    fn bracket_arg(&mut self) -> Result<ExprId, Abandon> {
        let (v, span) = self.real_value(0, expr::Ctx::OArgument)?;
        match v {
            Value::Expr(id) => Ok(id),
            Value::Number(x) => self
                .builder
                .push_expr(Expr {
                    kind: ExprKind::Number(x),
                    span,
                })
                .ok_or(Abandon),
        }
    }
}

/// A lexer mark at the start of `span` (which the lexer has just passed).
fn lexer_mark_at(lx: &Lexer<'_>, span: Span) -> lexer::Mark {
    lx.mark_at(span)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(src: &str) -> Vec<(char, f64)> {
        let (p, d) = parse(src);
        assert!(d.is_empty(), "{d:?}");
        p.blocks
            .iter()
            .flat_map(|b| b.words.iter().map(|w| (w.letter, w.value)))
            .collect()
    }

    #[test]
    fn number_forms() {
        // Truth: RS274/NGC number syntax (NIST RS274NGC v3 section 3.3.2.1).
        assert_eq!(
            words("x.5 X-0.5 X5. x+3 X-.25"),
            vec![
                ('X', 0.5),
                ('X', -0.5),
                ('X', 5.0),
                ('X', 3.0),
                ('X', -0.25)
            ]
        );
        assert_eq!(
            words("G0X1.1Y-2"),
            vec![('G', 0.0), ('X', 1.1), ('Y', -2.0)]
        );
        assert_eq!(words("G43.4"), vec![('G', 43.4)]);
    }

    #[test]
    fn blanks_inside_numbers() {
        // LinuxCNC ignores spaces and tabs outside comments.
        assert_eq!(words("X - 1 2 . 5\tY 3"), vec![('X', -12.5), ('Y', 3.0)]);
    }

    #[test]
    fn spans_are_char_columns() {
        let (p, d) = parse("(é) G1 X2\nY3");
        assert!(d.is_empty());
        let w = p.blocks[0].words[1];
        assert_eq!((w.span.line, w.span.col), (1, 8));
        assert_eq!(&"(é) G1 X2\nY3"[w.span.start..w.span.end], "X2");
        assert_eq!(p.blocks[1].words[0].span.col, 1);
        assert_eq!(p.blocks[1].line, 2);
    }

    #[test]
    fn line_numbers_comments_delete_percent() {
        let src = "%\n/N10 G1 (move) X1 ; tail\n%\n";
        let (p, d) = parse(src);
        assert!(d.is_empty(), "{d:?}");
        assert_eq!(p.blocks.len(), 3);
        assert!(p.blocks[0].percent && p.blocks[2].percent);
        let b = &p.blocks[1];
        assert!(b.block_delete);
        assert_eq!(b.line_number.map(|n| n.value), Some(10));
        assert_eq!(b.comments.len(), 2);
        assert_eq!(b.comments[0].text, "move");
        assert_eq!(b.comments[1].text, " tail");
        assert_eq!(b.comments[1].kind, CommentKind::Semicolon);
    }

    #[test]
    fn collects_every_diagnostic_with_position() {
        let src = "G1 X\nG0 ((a)) Y1 *12\nN5.5 G1\nG1 N7 Q\"s\"\n12";
        let (_, d) = parse(src);
        let pos: Vec<(u32, u32)> = d.iter().map(|d| (d.line, d.col)).collect();
        assert_eq!(
            pos,
            vec![(1, 4), (2, 4), (2, 13), (3, 1), (4, 4), (4, 7), (5, 1)]
        );
        assert!(d.iter().all(Diagnostic::is_error));
        let (_, d) = parse_with(
            src,
            &ParseOptions {
                lenient: true,
                ..ParseOptions::default()
            },
        );
        // The malformed line number stays an error; dialect issues become warnings.
        assert_eq!(d.iter().filter(|d| d.is_error()).count(), 1);
    }

    #[test]
    fn unclosed_comment_and_parameter_without_assignment() {
        let (p, d) = parse("G1 (open\nG1 X1 # 2");
        assert_eq!(p.blocks[0].comments[0].text, "open");
        assert_eq!((d[0].line, d[0].col), (1, 4));
        assert!(d[0].message.contains("never closed"));
        assert!(
            d.iter()
                .any(|d| d.line == 2 && d.col == 7 && d.message.contains('#'))
        );
    }

    #[test]
    fn out_of_range_value_is_an_error() {
        let big = format!("X{}", "9".repeat(400));
        let (p, d) = parse(&big);
        assert!(p.blocks.is_empty());
        assert_eq!(d.len(), 1);
        assert!(d[0].message.contains("out of range"));
    }

    #[test]
    fn limits_are_reported() {
        let opts = ParseOptions {
            max_line_bytes: 8,
            max_diagnostics: 2,
            ..ParseOptions::default()
        };
        let (_, d) = parse_with("G1 X1 Y2 Z3\n@\n@\n@\n@", &opts);
        assert_eq!(d.len(), 3);
        assert!(d[0].message.contains("longer than"));
        assert!(d[2].message.contains("3 further"));
        let opts = ParseOptions {
            max_blocks: 1,
            ..ParseOptions::default()
        };
        let (p, d) = parse_with("G1\nG1\nG1", &opts);
        assert_eq!(p.blocks.len(), 1);
        assert_eq!(d.len(), 1);
    }

    #[test]
    fn bytes_are_accepted() {
        let (p, d) = parse_bytes(b"G1 X1\xff\xfe Y2", &ParseOptions::default());
        assert_eq!(p.blocks[0].words.len(), 3);
        assert!(!d.is_empty());
    }

    /// Render an expression back as text with full brackets (shows the tree's shape).
    fn show(p: &Program, id: ExprId) -> String {
        match p.expr(id).kind {
            ExprKind::Number(x) => format!("{x}"),
            ExprKind::Param(ParamRef::Numbered(n)) => format!("#{n}"),
            ExprKind::Param(ParamRef::Named(n)) => format!("#<{}>", p.name(n)),
            ExprKind::Param(ParamRef::Indirect(e)) => format!("#({})", show(p, e)),
            ExprKind::Neg(e) => format!("-({})", show(p, e)),
            ExprKind::Func { func, arg } => format!("{}({})", func.name(), show(p, arg)),
            ExprKind::Atan { y, x } => format!("ATAN({},{})", show(p, y), show(p, x)),
            ExprKind::Binary { op, lhs, rhs } => {
                format!("({} {} {})", show(p, lhs), op.symbol(), show(p, rhs))
            }
            ExprKind::Exists(n) => format!("EXISTS(#<{}>)", p.name(n)),
        }
    }

    fn tree(src: &str) -> String {
        let (p, d) = parse(src);
        assert!(d.is_empty(), "{src}: {d:?}");
        let w = p.blocks[0].words[0];
        show(&p, w.expr.expect("an expression word"))
    }

    #[test]
    fn precedence_and_associativity_follow_linuxcnc() {
        // Truth: LinuxCNC Interp::precedence (** > * / MOD > + - > comparisons > AND OR XOR),
        // left to right within a level; checked against rs274 in tests/linuxcnc.rs.
        assert_eq!(tree("X[1 + 2 * 3 - 4 / 2]"), "((1 + (2 * 3)) - (4 / 2))");
        assert_eq!(tree("X[2 ** 3 ** 2]"), "((2 ** 3) ** 2)");
        assert_eq!(tree("X[1 LT 2 AND 3 GT 4]"), "((1 LT 2) AND (3 GT 4))");
        assert_eq!(tree("X[-2 ** 2]"), "(-2 ** 2)");
        assert_eq!(tree("X[-#1 * 2]"), "(-(#1) * 2)");
        assert_eq!(tree("X[7 mod 3]"), "(7 MOD 3)");
        assert_eq!(tree("XATAN[1]/[-1]"), "ATAN(1,-1)");
        assert_eq!(tree("X-SIN[30]"), "-(SIN(30))");
        assert_eq!(tree("X#<My Var>"), "#<myvar>");
        assert_eq!(tree("X##2"), "#(#2)");
        assert_eq!(tree("X#[1+1]"), "#((1 + 1))");
        assert_eq!(tree("X[EXISTS[#<_a>]]"), "EXISTS(#<_a>)");
    }

    #[test]
    fn assignments_and_o_words() {
        let (p, d) = parse(
            "#1 = 5 #<a>=[#1*2] G0 X#1\no<lp> while [#1 LT 3]\nO100 call [1] [2]\nO1234 (prog)",
        );
        assert!(d.is_empty(), "{d:?}");
        assert_eq!(p.blocks[0].assignments.len(), 2);
        assert_eq!(p.blocks[0].assignments[0].target, ParamRef::Numbered(1));
        assert_eq!(p.blocks[0].words.len(), 2);
        let o = p.blocks[1].o_word.as_ref().unwrap();
        assert!(matches!(o.label, OLabel::Name(n) if p.name(n) == "lp"));
        assert!(matches!(o.statement, OStatement::While(_)));
        let o = p.blocks[2].o_word.as_ref().unwrap();
        assert_eq!(o.label, OLabel::Number(100));
        assert!(matches!(&o.statement, OStatement::Call(a) if a.len() == 2));
        assert_eq!(
            p.blocks[3].o_word.as_ref().unwrap().statement,
            OStatement::ProgramNumber
        );
    }

    fn first_error(src: &str) -> (u32, u32, DiagnosticKind, String) {
        let (_, d) = parse(src);
        let e = d.iter().find(|d| d.is_error()).expect("an error");
        (e.line, e.col, e.kind, e.message.clone())
    }

    #[test]
    fn bad_expressions_are_errors_with_positions() {
        let (l, c, k, m) = first_error("G0 X[1 + 2");
        assert_eq!((l, c, k), (1, 5, DiagnosticKind::UnbalancedBracket), "{m}");
        let (l, c, k, _) = first_error("G0 X1]");
        assert_eq!((l, c, k), (1, 6, DiagnosticKind::UnbalancedBracket));
        let (_, c, k, m) = first_error("G0 X[1 FOO 2]");
        assert_eq!((c, k), (8, DiagnosticKind::Syntax));
        assert!(m.contains("FOO"));
        let (_, c, k, _) = first_error("G0 X#6000");
        assert_eq!((c, k), (5, DiagnosticKind::ParameterNumber));
        let (_, c, k, m) = first_error("#1 = 2 + 3");
        assert_eq!((c, k), (8, DiagnosticKind::Syntax));
        assert!(m.contains("brackets"));
        let (_, c, k, _) = first_error("o100 frobnicate");
        assert_eq!((c, k), (6, DiagnosticKind::UnknownOWord));
        let (_, c, _, m) = first_error("o100 if [1] G0 X1");
        assert_eq!(c, 13);
        assert!(m.contains("alone"));
        let (_, c, _, _) = first_error("G0 X1 o100 sub");
        assert_eq!(c, 7);
        // Deep nesting is bounded, not a stack overflow.
        let deep = format!("X{}1{}", "[".repeat(100), "]".repeat(100));
        let (_, _, k, m) = first_error(&deep);
        assert_eq!(k, DiagnosticKind::Syntax);
        assert!(m.contains("nested"));
    }

    #[test]
    fn lenient_never_downgrades_expressions() {
        let opts = ParseOptions {
            lenient: true,
            ..ParseOptions::default()
        };
        for src in ["G0 X[1", "#1 2", "o1 bogus", "G0 X]"] {
            let (_, d) = parse_with(src, &opts);
            assert!(d.iter().any(Diagnostic::is_error), "{src}: {d:?}");
        }
    }
}
