//! Byte-level helpers shared by the readers: line iteration with line numbers, field splitting,
//! number parsing with either decimal mark, and text decoding of header lines.
//!
//! Data rows are never turned into `String`s: a row is a byte slice, its fields are sub-slices,
//! and numbers are parsed straight from them, so reading a million rows allocates nothing per row.

use std::borrow::Cow;

/// Lines of a byte buffer with their 1-based line numbers, `\n` or `\r\n` terminated, the
/// terminator removed. The last line may lack a terminator ([`Line::terminated`] says so).
pub(crate) struct Lines<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
}

/// One line of [`Lines`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Line<'a> {
    /// 1-based line number in the file.
    pub no: usize,
    /// The line without its terminator.
    pub text: &'a [u8],
    /// Whether a `\n` ended the line (false only for a last line cut short).
    pub terminated: bool,
    /// Byte offset of the line's start in the buffer.
    pub offset: usize,
    /// Byte offset just past the line's terminator (the next line's start).
    pub next: usize,
}

impl<'a> Lines<'a> {
    /// All lines of `bytes`.
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Lines::starting_at(bytes, 0, 1)
    }

    /// Lines from byte `offset`, which starts line number `line`.
    pub(crate) fn starting_at(bytes: &'a [u8], offset: usize, line: usize) -> Self {
        Lines {
            bytes,
            pos: offset,
            line,
        }
    }
}

impl<'a> Iterator for Lines<'a> {
    type Item = Line<'a>;

    fn next(&mut self) -> Option<Line<'a>> {
        if self.pos >= self.bytes.len() {
            return None;
        }
        let rest = &self.bytes[self.pos..];
        let (mut text, terminated, advance) = match memchr::memchr(b'\n', rest) {
            Some(i) => (&rest[..i], true, i + 1),
            None => (rest, false, rest.len()),
        };
        if let [head @ .., b'\r'] = text {
            text = head;
        }
        let line = Line {
            no: self.line,
            text,
            terminated,
            offset: self.pos,
            next: self.pos + advance,
        };
        self.pos += advance;
        self.line += 1;
        Some(line)
    }
}

/// The bytes without leading and trailing ASCII white space.
pub(crate) fn trim(mut s: &[u8]) -> &[u8] {
    while let [first, rest @ ..] = s {
        if first.is_ascii_whitespace() {
            s = rest;
        } else {
            break;
        }
    }
    while let [rest @ .., last] = s {
        if last.is_ascii_whitespace() {
            s = rest;
        } else {
            break;
        }
    }
    s
}

/// Whether the line holds only white space.
pub(crate) fn is_blank(s: &[u8]) -> bool {
    s.iter().all(u8::is_ascii_whitespace)
}

/// Text of a header line: UTF-8 when it is, else Latin-1 (Windows exports write `µ` and `°` as
/// single bytes 0xB5 and 0xB0, which Latin-1 maps to the same characters).
pub(crate) fn decode(s: &[u8]) -> Cow<'_, str> {
    match std::str::from_utf8(s) {
        Ok(t) => Cow::Borrowed(t),
        Err(_) => Cow::Owned(s.iter().map(|&b| b as char).collect()),
    }
}

/// A field as printable text for error messages (shortened when long).
pub(crate) fn show(s: &[u8]) -> String {
    let t = decode(trim(s));
    if t.chars().count() > 40 {
        let mut u: String = t.chars().take(40).collect();
        u.push('…');
        u
    } else {
        t.into_owned()
    }
}

/// Why a field is not a finite number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum NumError {
    /// Not a number at all (or empty).
    Syntax,
    /// `NaN` or an infinity.
    NotFinite,
}

/// Parses a decimal number from a field, white space around it ignored. With `decimal_comma` the
/// mark is `,` (`1,5` is 1.5) — a field holding both `.` and `,` is refused rather than guessed.
///
/// The standard library's parser is used on purpose: since Rust 1.55 it implements the
/// Eisel–Lemire fast path with a correct fallback, so a third-party float parser would buy little
/// here; the speed comes from never allocating a `String` per field.
pub(crate) fn parse_f64(field: &[u8], decimal_comma: bool) -> Result<f64, NumError> {
    let f = trim(field);
    if f.is_empty() || f.len() > 64 {
        return Err(NumError::Syntax);
    }
    let v = if decimal_comma && f.contains(&b',') {
        if f.contains(&b'.') {
            return Err(NumError::Syntax);
        }
        let mut buf = [0u8; 64];
        let buf = &mut buf[..f.len()];
        for (d, &s) in buf.iter_mut().zip(f) {
            *d = if s == b',' { b'.' } else { s };
        }
        parse_ascii(buf)?
    } else {
        parse_ascii(f)?
    };
    if v.is_finite() {
        Ok(v)
    } else {
        Err(NumError::NotFinite)
    }
}

fn parse_ascii(f: &[u8]) -> Result<f64, NumError> {
    let s = std::str::from_utf8(f).map_err(|_| NumError::Syntax)?;
    // Rust accepts "inf", "infinity" and "nan" in any case: those are numbers, but not finite.
    s.parse::<f64>().map_err(|_| NumError::Syntax)
}

/// Whether the field parses as a number (finite or not) with either decimal mark.
pub(crate) fn looks_numeric(field: &[u8]) -> bool {
    !matches!(parse_f64(field, true), Err(NumError::Syntax))
}

/// Splits `line` at every `delim` byte (no quoting: scope exports do not quote numbers).
pub(crate) fn split_delim(line: &[u8], delim: u8) -> impl Iterator<Item = &[u8]> {
    line.split(move |&b| b == delim)
}

/// Splits `line` at runs of ASCII white space, dropping empty fields.
pub(crate) fn split_ws(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace())
        .filter(|f| !f.is_empty())
}

/// Line number of byte `offset` in `bytes` (1-based).
pub(crate) fn line_of_offset(bytes: &[u8], offset: usize) -> usize {
    1 + memchr::memchr_iter(b'\n', &bytes[..offset.min(bytes.len())]).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_number_from_one_and_strip_crlf() {
        let v: Vec<_> = Lines::new(b"a\r\nb\n\nc").collect();
        assert_eq!(v.len(), 4);
        assert_eq!((v[0].no, v[0].text), (1, &b"a"[..]));
        assert_eq!((v[1].no, v[1].text), (2, &b"b"[..]));
        assert!(v[2].text.is_empty() && v[2].terminated);
        assert_eq!((v[3].no, v[3].text, v[3].terminated), (4, &b"c"[..], false));
        assert_eq!(v[3].offset, 6);
    }

    #[test]
    fn numbers_with_either_decimal_mark() {
        assert_eq!(parse_f64(b" 1.5 ", false), Ok(1.5));
        assert_eq!(parse_f64(b"-0,25", true), Ok(-0.25));
        assert_eq!(parse_f64(b"1e-3", true), Ok(1e-3));
        assert_eq!(parse_f64(b"1,5", false), Err(NumError::Syntax));
        assert_eq!(parse_f64(b"1.000,5", true), Err(NumError::Syntax));
        assert_eq!(parse_f64(b"NaN", false), Err(NumError::NotFinite));
        assert_eq!(parse_f64(b"-inf", true), Err(NumError::NotFinite));
        assert_eq!(parse_f64(b"", false), Err(NumError::Syntax));
        assert_eq!(parse_f64(b"abc", false), Err(NumError::Syntax));
        assert!(looks_numeric(b"3,25") && !looks_numeric(b"x"));
    }

    #[test]
    fn latin1_header_text_decodes() {
        assert_eq!(decode(b"\xb5m"), "µm");
        assert_eq!(decode("µm".as_bytes()), "µm");
        assert_eq!(line_of_offset(b"a\nb\nc", 4), 3);
    }
}
