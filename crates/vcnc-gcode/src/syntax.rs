//! G-code *syntax*: lines, words, comments and their source spans (no machine meaning).
//!
//! The dialect is the ISO 6983 / LinuxCNC (RS274/NGC) / Fanuc common subset of docs/gcode.md:
//!
//! - one block per line (`\n` or `\r\n`); blank lines are dropped;
//! - `%` alone on a line delimits the program;
//! - `/` as the first character of a line marks a block-delete line;
//! - `N` followed by a whole number, first in the block (after `/`), is the line number;
//! - `( … )` and `; …` comments (LinuxCNC does not nest parentheses: a `(` inside a comment is
//!   reported);
//! - words are a letter (case-insensitive) and a number: optional sign, digits with at most one
//!   decimal point (`X.5`, `X-0.5`, `X5.`); no exponent. As in LinuxCNC, spaces and tabs may
//!   appear between the letter and the number and inside the number (`X - 1 2.5` is `X-12.5`).
//!
//! The parser never stops at the first problem: every diagnostic is collected with its
//! line:column, and parsing resumes at the next token. Problems that only mean "another
//! dialect" (a word without a value such as `G28 X Y Z`, nested comments, RepRap checksums `*57`
//! and quoted strings, stray characters) are errors, downgraded to warnings under
//! [`ParseOptions::lenient`]; the offending text is skipped either way.
//!
//! Robustness: any `&str` is accepted without panicking, in time linear in its length. A line
//! longer than [`ParseOptions::max_line_bytes`] is reported and skipped, the number of blocks is
//! capped by [`ParseOptions::max_blocks`] and the number of stored diagnostics by
//! [`ParseOptions::max_diagnostics`] (the rest are counted and the count is reported), so memory
//! stays bounded by the input size. [`parse_bytes`] accepts arbitrary bytes (invalid UTF-8 becomes
//! U+FFFD and is reported as an unexpected character).

use crate::diag::{Diagnostic, Severity, Sink, Span};

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

/// A parsed program: its lines that hold syntax (words, comments, `N`, `%` or `/`), in order.
///
/// Memory is about 150 bytes per block plus 40 per word; [`ParseOptions::max_blocks`] and
/// [`ParseOptions::max_line_bytes`] bound it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Program {
    /// One block per line that holds syntax (blank and junk-only lines are dropped).
    pub blocks: Vec<Block>,
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
}

/// An `N` line number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineNumber {
    /// The number after `N` (dimensionless label).
    pub value: u32,
    /// From the `N` to the last digit.
    pub span: Span,
}

/// A word: letter and value, e.g. `X-0.5` or `G43.4`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Word {
    /// Upper-case ASCII letter.
    pub letter: char,
    /// The value exactly as written (finite; units depend on the letter and the modal state,
    /// which this module does not know).
    pub value: f64,
    /// From the letter to the last character of the number.
    pub span: Span,
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

/// Parse `src`, collecting every diagnostic (see the module doc for the limits).
pub fn parse_with(src: &str, opts: &ParseOptions) -> (Program, Vec<Diagnostic>) {
    let mut sink = Sink::new(opts.max_diagnostics);
    let mut program = Program::default();
    let mut base = 0usize;
    let mut line_no: u32 = 0;
    for raw in src.split('\n') {
        line_no = line_no.saturating_add(1);
        let start = base;
        base += raw.len() + 1;
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
            sink.report(line_span, Severity::Error, &|| {
                format!(
                    "line is {} bytes long, longer than the limit of {} bytes; it is skipped",
                    text.len(),
                    opts.max_line_bytes
                )
            });
            continue;
        }
        if program.blocks.len() >= opts.max_blocks {
            sink.push(Diagnostic::error(
                line_span,
                format!(
                    "program has more than {} blocks; the rest of the program is not parsed",
                    opts.max_blocks
                ),
            ));
            break;
        }
        let block = parse_line(text, line_span, opts.lenient, &mut sink);
        // A line of pure junk leaves only diagnostics: do not keep an empty block for it.
        let empty = block.words.is_empty()
            && block.comments.is_empty()
            && block.line_number.is_none()
            && !block.percent
            && !block.block_delete;
        if !empty {
            program.blocks.push(block);
        }
    }
    (program, sink.finish())
}

/// What is wrong with a parenthesised comment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Flaw {
    None,
    Nested,
    Unclosed,
}

#[derive(Debug, Clone, PartialEq)]
enum Tok<'a> {
    Letter(char),
    /// A number; `None` when the text has no digit (a lone sign or point) or is not finite.
    Number(Option<f64>, &'a str),
    Comment(String, CommentKind, Flaw),
    Slash,
    Percent,
    Str,
    Checksum,
    Junk(char),
}

/// Tokeniser over one line. Column counting is incremental (characters, not bytes).
struct Lexer<'a> {
    text: &'a str,
    bytes: &'a [u8],
    pos: usize,
    col: u32,
    line: u32,
    base: usize,
    scratch: String,
}

impl<'a> Lexer<'a> {
    fn new(text: &'a str, line_span: Span) -> Self {
        Lexer {
            text,
            bytes: text.as_bytes(),
            pos: 0,
            col: 1,
            line: line_span.line,
            base: line_span.start,
            scratch: String::new(),
        }
    }

    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    /// Advance one byte, counting a column for each byte that starts a character.
    fn bump(&mut self) {
        if let Some(&b) = self.bytes.get(self.pos) {
            self.pos += 1;
            if b & 0xC0 != 0x80 {
                self.col += 1;
            }
        }
    }

    /// Advance one whole character.
    fn bump_char(&mut self) -> Option<char> {
        let c = self.text.get(self.pos..)?.chars().next()?;
        self.pos += c.len_utf8();
        self.col += 1;
        Some(c)
    }

    fn skip_ws(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\r' | 0x0B | 0x0C)) {
            self.bump();
        }
    }

    fn mark(&self) -> (usize, u32) {
        (self.pos, self.col)
    }

    fn span_from(&self, mark: (usize, u32), end: usize) -> Span {
        Span {
            line: self.line,
            col: mark.1,
            start: self.base + mark.0,
            end: self.base + end,
        }
    }

    /// Skip a run of ASCII letters glued together (recovery after a word without a value).
    fn skip_alpha_run(&mut self) {
        while matches!(self.peek(), Some(b) if b.is_ascii_alphabetic()) {
            self.bump();
        }
    }

    fn next(&mut self) -> Option<(Tok<'a>, Span)> {
        self.skip_ws();
        let m = self.mark();
        let b = self.peek()?;
        let tok = match b {
            b'a'..=b'z' | b'A'..=b'Z' => {
                self.bump();
                Tok::Letter(char::from(b.to_ascii_uppercase()))
            }
            b'0'..=b'9' | b'.' | b'+' | b'-' => return Some(self.number()),
            b'(' => return Some(self.paren_comment()),
            b';' => {
                let text = self.text.get(self.pos + 1..).unwrap_or("").to_string();
                while self.peek().is_some() {
                    self.bump();
                }
                Tok::Comment(text, CommentKind::Semicolon, Flaw::None)
            }
            b'/' => {
                self.bump();
                Tok::Slash
            }
            b'%' => {
                self.bump();
                Tok::Percent
            }
            b'"' => {
                // RepRap-style quoted string; `""` is an escaped quote inside it.
                self.bump();
                loop {
                    match self.peek() {
                        None => break,
                        Some(b'"') => {
                            self.bump();
                            if self.peek() == Some(b'"') {
                                self.bump();
                            } else {
                                break;
                            }
                        }
                        Some(_) => self.bump(),
                    }
                }
                Tok::Str
            }
            b'*' => {
                self.bump();
                while matches!(self.peek(), Some(b'0'..=b'9')) {
                    self.bump();
                }
                Tok::Checksum
            }
            _ => {
                let c = self.bump_char().unwrap_or('\u{FFFD}');
                Tok::Junk(c)
            }
        };
        let end = self.pos;
        Some((tok, self.span_from(m, end)))
    }

    /// `[+-]? (digit | '.' | blank)*` with at least one digit and at most one point.
    fn number(&mut self) -> (Tok<'a>, Span) {
        let m = self.mark();
        let mut end = self.pos;
        let mut digits = 0usize;
        let mut points = 0usize;
        let mut blanks = false;
        if matches!(self.peek(), Some(b'+' | b'-')) {
            self.bump();
            end = self.pos;
        }
        loop {
            match self.peek() {
                Some(b'0'..=b'9') => {
                    digits += 1;
                    self.bump();
                    end = self.pos;
                }
                Some(b'.') if points == 0 => {
                    points += 1;
                    self.bump();
                    end = self.pos;
                }
                Some(b' ' | b'\t') => {
                    // Blanks inside a number are allowed (LinuxCNC); they only count when a
                    // digit or point follows.
                    let save = (self.pos, self.col);
                    self.skip_ws();
                    if matches!(self.peek(), Some(b'0'..=b'9'))
                        || (points == 0 && self.peek() == Some(b'.'))
                    {
                        blanks = true;
                    } else {
                        self.pos = save.0;
                        self.col = save.1;
                        break;
                    }
                }
                _ => break,
            }
        }
        // Leave the lexer just after the number's last character.
        let raw = self.text.get(m.0..end).unwrap_or("");
        let span = self.span_from(m, end);
        if digits == 0 {
            return (Tok::Number(None, raw), span);
        }
        let value = if blanks {
            self.scratch.clear();
            self.scratch
                .extend(raw.chars().filter(|c| !c.is_ascii_whitespace()));
            self.scratch.parse::<f64>().ok()
        } else {
            raw.parse::<f64>().ok()
        };
        (Tok::Number(value.filter(|v| v.is_finite()), raw), span)
    }

    /// `( … )`; nesting is tracked for recovery and flagged.
    fn paren_comment(&mut self) -> (Tok<'a>, Span) {
        let m = self.mark();
        self.bump();
        let text_start = self.pos;
        let mut depth = 1usize;
        let mut nested = false;
        let mut text_end = None;
        while let Some(b) = self.peek() {
            match b {
                b'(' => {
                    depth += 1;
                    nested = true;
                }
                b')' => {
                    depth -= 1;
                    if depth == 0 {
                        text_end = Some(self.pos);
                        self.bump();
                        break;
                    }
                }
                _ => {}
            }
            self.bump();
        }
        let closed = text_end.is_some();
        let te = text_end.unwrap_or(self.pos);
        let text = self.text.get(text_start..te).unwrap_or("").to_string();
        let end = self.pos;
        let span = self.span_from(m, end);
        let flaw = if !closed {
            Flaw::Unclosed
        } else if nested {
            Flaw::Nested
        } else {
            Flaw::None
        };
        (Tok::Comment(text, CommentKind::Paren, flaw), span)
    }
}

fn parse_line(text: &str, line_span: Span, lenient: bool, sink: &mut Sink) -> Block {
    let mut block = Block {
        line: line_span.line,
        span: line_span,
        ..Block::default()
    };
    let sev = if lenient {
        Severity::Warning
    } else {
        Severity::Error
    };
    let dialect = |sink: &mut Sink, span: Span, msg: &dyn Fn() -> String| {
        sink.report(span, sev, msg);
    };
    let mut lx = Lexer::new(text, line_span);
    // Anything but comments seen yet (for `/`, `%` and `N` placement)?
    let mut content = false;
    while let Some((tok, span)) = lx.next() {
        match tok {
            Tok::Comment(body, kind, flaw) => {
                match flaw {
                    Flaw::None => {}
                    Flaw::Unclosed => dialect(sink, span, &|| {
                        "comment opened with '(' is never closed on this line".to_string()
                    }),
                    Flaw::Nested => dialect(sink, span, &|| {
                        "nested '(' inside a comment (comments do not nest in RS274/NGC)"
                            .to_string()
                    }),
                }
                block.comments.push(Comment {
                    text: body,
                    kind,
                    span,
                });
            }
            Tok::Slash => {
                if content || block.block_delete || !block.comments.is_empty() {
                    dialect(sink, span, &|| {
                        "'/' (block delete) is only allowed at the start of a line".into()
                    });
                } else {
                    block.block_delete = true;
                }
            }
            Tok::Percent => {
                if content || block.block_delete || block.percent {
                    dialect(sink, span, &|| {
                        "'%' (program delimiter) must be alone on its line".into()
                    });
                } else {
                    block.percent = true;
                }
                content = true;
            }
            Tok::Letter(letter) => {
                let was_content = content;
                content = true;
                if block.percent {
                    dialect(sink, span, &|| {
                        "'%' (program delimiter) must be alone on its line".into()
                    });
                }
                let save = (lx.pos, lx.col);
                let next = lx.next();
                match next {
                    Some((Tok::Number(Some(value), _), nspan)) => {
                        let wspan = Span {
                            line: span.line,
                            col: span.col,
                            start: span.start,
                            end: nspan.end,
                        };
                        if letter == 'N' {
                            line_number(&mut block, value, wspan, was_content, lenient, sink);
                        } else {
                            block.words.push(Word {
                                letter,
                                value,
                                span: wspan,
                            });
                        }
                    }
                    Some((Tok::Number(None, raw), nspan)) => {
                        let wspan = Span {
                            end: nspan.end,
                            ..span
                        };
                        sink.report(wspan, Severity::Error, &|| {
                            if raw.bytes().any(|b| b.is_ascii_digit()) {
                                format!("value '{raw}' of word '{letter}' is out of range")
                            } else {
                                format!("word '{letter}' has a malformed number '{raw}'")
                            }
                        });
                    }
                    Some((Tok::Str, _)) => {
                        dialect(sink, span, &|| {
                            format!(
                                "word '{letter}' has a quoted string value, which RS274/NGC does not have"
                            )
                        });
                    }
                    _ => {
                        // Put the look-ahead token back and skip a glued run of letters
                        // (`Hello`) so it yields one diagnostic.
                        lx.pos = save.0;
                        lx.col = save.1;
                        lx.skip_alpha_run();
                        let end = lx.pos;
                        let word = text.get(span.start - line_span.start..end).unwrap_or("");
                        dialect(sink, span, &|| {
                            if word.len() > 1 {
                                format!("'{word}' is not a word: letter '{letter}' has no value")
                            } else {
                                format!("word '{letter}' has no value")
                            }
                        });
                    }
                }
            }
            Tok::Number(_, raw) => {
                content = true;
                dialect(sink, span, &|| {
                    format!("number '{raw}' has no letter before it")
                });
            }
            Tok::Str => {
                content = true;
                dialect(sink, span, &|| {
                    "quoted string: RS274/NGC has no string values".into()
                });
            }
            Tok::Checksum => {
                let raw = text
                    .get(span.start - line_span.start..span.end - line_span.start)
                    .unwrap_or("*");
                dialect(sink, span, &|| {
                    format!("checksum '{raw}' is not RS274/NGC (RepRap dialect)")
                });
            }
            Tok::Junk(c) => {
                content = true;
                dialect(sink, span, &|| match c {
                    '#' => "'#' parameters are not supported".to_string(),
                    '[' | ']' => format!("'{c}' expressions are not supported"),
                    '\u{FFFD}' => "invalid UTF-8 or replacement character".to_string(),
                    c if c.is_control() => {
                        format!("unexpected control character U+{:04X}", c as u32)
                    }
                    c => format!("unexpected character '{c}'"),
                });
            }
        }
    }
    block
}

fn line_number(
    block: &mut Block,
    value: f64,
    span: Span,
    was_content: bool,
    lenient: bool,
    sink: &mut Sink,
) {
    let severity = if lenient {
        Severity::Warning
    } else {
        Severity::Error
    };
    let whole = value >= 0.0 && value.fract() == 0.0 && value <= f64::from(u32::MAX);
    if !whole {
        sink.report(span, Severity::Error, &|| {
            format!("line number N{value} is not a whole number in 0..=4294967295")
        });
    } else if was_content || block.line_number.is_some() {
        sink.report(span, severity, &|| {
            format!("line number N{value} must start the block")
        });
    } else {
        block.line_number = Some(LineNumber {
            // Checked above to be a whole number in range.
            value: value as u32,
            span,
        });
    }
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
    fn unclosed_comment_and_junk() {
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
}
