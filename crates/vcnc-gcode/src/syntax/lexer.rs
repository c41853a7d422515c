//! Tokeniser over one line of G-code. Columns are counted incrementally, in characters.

use crate::diag::Span;

/// What is wrong with a parenthesised comment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Flaw {
    None,
    Nested,
    Unclosed,
}

/// A statement-level token (inside `[ ]` the expression parser reads characters itself).
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Tok<'a> {
    /// A word letter (upper-cased), including the polar-coordinate letters `@` and `^`.
    Letter(char),
    /// A number; `None` when the text has no digit (a lone sign or point) or is not finite.
    Number(Option<f64>, &'a str),
    Comment(String, super::CommentKind, Flaw),
    Slash,
    Percent,
    Str,
    Checksum,
    Hash,
    LBracket,
    RBracket,
    Equals,
    Junk(char),
}

/// Cursor over one line.
pub(super) struct Lexer<'a> {
    pub(super) text: &'a str,
    bytes: &'a [u8],
    pub(super) pos: usize,
    pub(super) col: u32,
    line: u32,
    base: usize,
    scratch: String,
}

/// A saved cursor position.
#[derive(Debug, Clone, Copy)]
pub(super) struct Mark {
    pos: usize,
    col: u32,
}

impl<'a> Lexer<'a> {
    pub(super) fn new(text: &'a str, line_span: Span) -> Self {
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

    #[inline]
    pub(super) fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    /// Advance one byte, counting a column for each byte that starts a character.
    #[inline]
    pub(super) fn bump(&mut self) {
        if let Some(&b) = self.bytes.get(self.pos) {
            self.pos += 1;
            if b & 0xC0 != 0x80 {
                self.col += 1;
            }
        }
    }

    /// Advance one whole character.
    pub(super) fn bump_char(&mut self) -> Option<char> {
        let c = self.text.get(self.pos..)?.chars().next()?;
        self.pos += c.len_utf8();
        self.col += 1;
        Some(c)
    }

    #[inline]
    pub(super) fn skip_ws(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\r' | 0x0B | 0x0C)) {
            self.bump();
        }
    }

    /// The next byte after blanks, without consuming anything.
    #[inline]
    pub(super) fn peek_non_ws(&self) -> Option<u8> {
        self.bytes[self.pos..]
            .iter()
            .copied()
            .find(|b| !matches!(b, b' ' | b'\t' | b'\r' | 0x0B | 0x0C))
    }

    #[inline]
    pub(super) fn mark(&self) -> Mark {
        Mark {
            pos: self.pos,
            col: self.col,
        }
    }

    #[inline]
    pub(super) fn reset(&mut self, m: Mark) {
        self.pos = m.pos;
        self.col = m.col;
    }

    /// The span from `m` to the current position.
    #[inline]
    pub(super) fn span_from(&self, m: Mark) -> Span {
        self.span_between(m, self.pos)
    }

    #[inline]
    pub(super) fn span_between(&self, m: Mark, end: usize) -> Span {
        Span {
            line: self.line,
            col: m.col,
            start: self.base + m.pos,
            end: self.base + end,
        }
    }

    /// A mark at the start of `span`, a span of this line that the cursor has passed.
    pub(super) fn mark_at(&self, span: Span) -> Mark {
        Mark {
            pos: span.start.saturating_sub(self.base).min(self.pos),
            col: span.col,
        }
    }

    /// The source text from the start of `span` to the cursor.
    pub(super) fn text_from_start(&self, span: Span) -> &'a str {
        let m = self.mark_at(span);
        self.text.get(m.pos..self.pos).unwrap_or("")
    }

    /// The source text between `m` and the current position.
    pub(super) fn text_from(&self, m: Mark) -> &'a str {
        self.text.get(m.pos..self.pos).unwrap_or("")
    }

    /// Skip a run of ASCII letters glued together (recovery after a word without a value).
    pub(super) fn skip_alpha_run(&mut self) {
        while matches!(self.peek(), Some(b) if b.is_ascii_alphabetic()) {
            self.bump();
        }
    }

    /// Read a run of ASCII letters (after blanks), upper-cased; empty if none. The cursor is
    /// left after the run.
    pub(super) fn alpha_run(&mut self) -> (Mark, String) {
        self.skip_ws();
        let m = self.mark();
        let mut s = String::new();
        while let Some(b) = self.peek() {
            if !b.is_ascii_alphabetic() {
                break;
            }
            s.push(char::from(b.to_ascii_uppercase()));
            self.bump();
        }
        (m, s)
    }

    pub(super) fn next(&mut self) -> Option<(Tok<'a>, Span)> {
        self.skip_ws();
        let m = self.mark();
        let b = self.peek()?;
        let tok = match b {
            b'a'..=b'z' | b'A'..=b'Z' | b'@' | b'^' => {
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
                Tok::Comment(text, super::CommentKind::Semicolon, Flaw::None)
            }
            b'/' => {
                self.bump();
                Tok::Slash
            }
            b'%' => {
                self.bump();
                Tok::Percent
            }
            b'#' => {
                self.bump();
                Tok::Hash
            }
            b'[' => {
                self.bump();
                Tok::LBracket
            }
            b']' => {
                self.bump();
                Tok::RBracket
            }
            b'=' => {
                self.bump();
                Tok::Equals
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
        Some((tok, self.span_from(m)))
    }

    /// `[+-]? (digit | '.' | blank)*` with at least one digit and at most one point.
    pub(super) fn number(&mut self) -> (Tok<'a>, Span) {
        let m = self.mark();
        let mut end = self.pos;
        let mut end_col = self.col;
        let mut digits = 0usize;
        let mut points = 0usize;
        let mut blanks = false;
        if matches!(self.peek(), Some(b'+' | b'-')) {
            self.bump();
            end = self.pos;
            end_col = self.col;
        }
        loop {
            match self.peek() {
                Some(b'0'..=b'9') => {
                    digits += 1;
                    self.bump();
                    end = self.pos;
                    end_col = self.col;
                }
                Some(b'.') if points == 0 => {
                    points += 1;
                    self.bump();
                    end = self.pos;
                    end_col = self.col;
                }
                Some(b' ' | b'\t') => {
                    // Blanks inside a number are allowed (LinuxCNC); they only count when a
                    // digit or point follows.
                    let save = self.mark();
                    self.skip_ws();
                    if matches!(self.peek(), Some(b'0'..=b'9'))
                        || (points == 0 && self.peek() == Some(b'.'))
                    {
                        blanks = true;
                    } else {
                        self.reset(save);
                        break;
                    }
                }
                _ => break,
            }
        }
        // Leave the lexer just after the number's last character.
        self.pos = end;
        self.col = end_col;
        let raw = self.text.get(m.pos..end).unwrap_or("");
        let span = self.span_between(m, end);
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
        let span = self.span_from(m);
        let flaw = if !closed {
            Flaw::Unclosed
        } else if nested {
            Flaw::Nested
        } else {
            Flaw::None
        };
        (Tok::Comment(text, super::CommentKind::Paren, flaw), span)
    }
}
