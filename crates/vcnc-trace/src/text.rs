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

/// The first line of `bytes` that is neither blank, a `#` comment nor a line `skip` accepts
/// (given trimmed), and the number of the last line read. Each comment before it goes to
/// `comment` with its text (after the `#`, trimmed) and its line number.
pub(crate) fn first_content_line<'a>(
    bytes: &'a [u8],
    skip: impl Fn(&[u8]) -> bool,
    mut comment: impl FnMut(String, usize),
) -> (Option<Line<'a>>, usize) {
    let mut last_line = 1;
    for l in Lines::new(bytes) {
        last_line = l.no;
        let t = trim(l.text);
        if t.is_empty() {
            continue;
        }
        if t[0] == b'#' {
            comment(decode(&t[1..]).trim().to_string(), l.no);
            continue;
        }
        if skip(t) {
            continue;
        }
        return (Some(l), last_line);
    }
    (None, last_line)
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
/// Plain decimals (`-12.345678`: at most 19 significant digits, a mantissa up to $2^{53}$ and at
/// most 22 decimals — what scopes print) take Clinger's exact fast path, [`fast_decimal`];
/// anything else (exponents, long mantissas, `inf`, `NaN`) goes to the standard library's
/// parser, which is correctly rounded too. Both give the same, correctly rounded result, so the
/// split only buys speed; together with never allocating a `String` per field it is why no
/// third-party float parser is used.
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

/// Powers of ten exactly representable in `f64`.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Clinger's fast path (W. D. Clinger, "How to read floating point numbers accurately", PLDI
/// 1990): for `[+-]digits[.digits]` with a mantissa $m \le 2^{53}$ and $d \le 22$ decimals, $m$
/// and $10^d$ are exact doubles and the single IEEE division $m / 10^d$ is correctly rounded, so
/// the result is the double nearest the decimal. `None` for anything else.
pub(crate) fn fast_decimal(f: &[u8]) -> Option<f64> {
    let (neg, d) = match f.first()? {
        b'-' => (true, &f[1..]),
        b'+' => (false, &f[1..]),
        _ => (false, f),
    };
    // Wrapping arithmetic: with more than 19 digits the mantissa may wrap, and is then discarded.
    let mut mantissa: u64 = 0;
    let mut i = 0;
    while i < d.len() && d[i].is_ascii_digit() {
        mantissa = mantissa
            .wrapping_mul(10)
            .wrapping_add(u64::from(d[i] - b'0'));
        i += 1;
    }
    let int_digits = i;
    let mut decimals = 0;
    if i < d.len() && d[i] == b'.' {
        i += 1;
        let start = i;
        while i < d.len() && d[i].is_ascii_digit() {
            mantissa = mantissa
                .wrapping_mul(10)
                .wrapping_add(u64::from(d[i] - b'0'));
            i += 1;
        }
        decimals = i - start;
    }
    let digits = int_digits + decimals;
    if i != d.len() || digits == 0 || digits > 19 || mantissa > 1 << 53 || decimals >= POW10.len() {
        return None;
    }
    let v = mantissa as f64 / POW10[decimals];
    Some(if neg { -v } else { v })
}

fn parse_ascii(f: &[u8]) -> Result<f64, NumError> {
    if let Some(v) = fast_decimal(f) {
        return Ok(v);
    }
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

/// Appends the white-space separated fields of `line` to `out` (a reused buffer).
pub(crate) fn split_ws_into<'a>(line: &'a [u8], out: &mut Vec<&'a [u8]>) {
    let mut i = 0;
    let n = line.len();
    loop {
        while i < n && line[i].is_ascii_whitespace() {
            i += 1;
        }
        if i == n {
            return;
        }
        let start = i;
        while i < n && !line[i].is_ascii_whitespace() {
            i += 1;
        }
        out.push(&line[start..i]);
    }
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

    proptest::proptest! {
        /// The fast path agrees bit for bit with the standard parser (truth: Rust's correctly
        /// rounded `str::parse::<f64>`), on plain decimals of every length and sign.
        #[test]
        fn fast_path_equals_the_standard_parser(
            neg in proptest::bool::ANY,
            int in "[0-9]{1,12}",
            frac in proptest::option::of("[0-9]{0,15}"),
        ) {
            let s = format!("{}{int}{}", if neg { "-" } else { "" }, frac.map(|f| format!(".{f}")).unwrap_or_default());
            let std: f64 = s.parse().unwrap();
            let fast = fast_decimal(s.as_bytes());
            if let Some(v) = fast {
                proptest::prop_assert_eq!(v.to_bits(), std.to_bits(), "{}", s);
            }
            proptest::prop_assert_eq!(parse_f64(s.as_bytes(), false).unwrap().to_bits(), std.to_bits());
        }
    }

    #[test]
    fn fast_path_edges() {
        assert_eq!(fast_decimal(b"9007199254740992"), Some(9007199254740992.0));
        assert_eq!(fast_decimal(b"9007199254740993"), None); // > 2^53: the slow path
        assert_eq!(fast_decimal(b"0.000000000000000001"), Some(1e-18));
        assert_eq!(fast_decimal(b"0.00000000000000000000001"), None);
        assert_eq!(fast_decimal(b"00000000000000000001.5"), None); // 21 digits: the slow path
        assert_eq!(parse_f64(b"00000000000000000001.5", false), Ok(1.5));
        assert_eq!(fast_decimal(b"99999999999999999999"), None); // would wrap
        assert_eq!(parse_f64(b"99999999999999999999", false), Ok(1e20));
        assert_eq!(
            fast_decimal(b"-0").map(f64::to_bits),
            Some((-0.0f64).to_bits())
        );
        assert_eq!(fast_decimal(b"1e5"), None);
        assert_eq!(fast_decimal(b"."), None);
        assert_eq!(fast_decimal(b"1.2.3"), None);
        assert_eq!(parse_f64(b"1e5", false), Ok(1e5));
        assert_eq!(
            parse_f64(b"12345678901234567890.5", false),
            Ok(12345678901234567890.5)
        );
    }

    #[test]
    fn latin1_header_text_decodes() {
        assert_eq!(decode(b"\xb5m"), "µm");
        assert_eq!(decode("µm".as_bytes()), "µm");
        assert_eq!(line_of_offset(b"a\nb\nc", 4), 3);
    }
}
