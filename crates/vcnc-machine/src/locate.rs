//! Source positions in TOML documents: byte offsets to line:column, and the position of a dotted
//! key, so that errors found after deserialisation (a negative inertia, unstable gains) still
//! name the line of the offending key.

use toml::de::{DeTable, DeValue};

/// A position in a text file, 1-based.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineCol {
    /// Line, from 1.
    pub line: usize,
    /// Column in characters, from 1.
    pub col: usize,
}

impl std::fmt::Display for LineCol {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}", self.line, self.col)
    }
}

/// Line and column of byte `offset` in `src` (clamped to the end).
pub fn line_col(src: &str, offset: usize) -> LineCol {
    let mut offset = offset.min(src.len());
    while !src.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &src[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let col = src[line_start..offset].chars().count() + 1;
    LineCol { line, col }
}

/// Where the key at `path` (e.g. `["axes", "X", "plant", "j"]`) is written in `src`: the
/// position of its value, or of the deepest parent that exists. `None` if the document does not
/// parse or no part of the path exists.
pub fn locate_key(src: &str, path: &[&str]) -> Option<LineCol> {
    let doc = DeTable::parse(src).ok()?;
    let mut table = doc.get_ref();
    let mut found = None;
    for (i, key) in path.iter().enumerate() {
        let Some((k, v)) = table.iter().find(|(k, _)| k.get_ref().as_ref() == *key) else {
            return found;
        };
        let span = if v.span().start < v.span().end {
            v.span()
        } else {
            k.span()
        };
        found = Some(line_col(
            src,
            if i + 1 == path.len() {
                span.start
            } else {
                k.span().start
            },
        ));
        match v.get_ref() {
            DeValue::Table(t) => table = t,
            _ => break,
        }
    }
    found
}

/// Where a TOML deserialisation error points: its span's start, except for an unknown field
/// reported on a whole table (serde's internally tagged enums, such as `controller = { kind =
/// ... }`, buffer their content and lose the key's own span), where it is the first `name =`
/// of that field inside the span.
pub fn error_offset(src: &str, span: Option<std::ops::Range<usize>>, message: &str) -> usize {
    let Some(span) = span else { return 0 };
    let start = span.start.min(src.len());
    let name = message
        .strip_prefix("unknown field `")
        .and_then(|rest| rest.split('`').next())
        .filter(|n| !n.is_empty());
    let (Some(name), Some(text)) = (name, src.get(start..span.end.min(src.len()))) else {
        return start;
    };
    let is_word = |c: char| c.is_alphanumeric() || c == '_' || c == '-';
    let mut from = 0;
    while let Some(i) = text[from..].find(name) {
        let at = from + i;
        let before_ok = !text[..at].chars().next_back().is_some_and(is_word);
        let after = &text[at + name.len()..];
        if before_ok && after.trim_start_matches([' ', '\t']).starts_with('=') {
            return start + at;
        }
        from = at + name.len();
    }
    start
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_fields_in_inline_tables_point_at_the_key() {
        let src = "[axes.X]\ncontroller = { kind = \"p-pi\", kvv = 70.0, kv = 1.0 }\n";
        let span = src.find('{').unwrap()..src.len() - 1;
        let msg = "unknown field `kvv`, expected one of `kv`, `kp`";
        let at = line_col(src, error_offset(src, Some(span.clone()), msg));
        assert_eq!(at, LineCol { line: 2, col: 31 });
        // `kv` is a prefix of `kvv` and appears later: only a whole key followed by `=` counts.
        let msg = "unknown field `kv`, expected `kp`";
        let at = line_col(src, error_offset(src, Some(span.clone()), msg));
        assert_eq!(at, LineCol { line: 2, col: 43 });
        // Other errors keep the span's start.
        assert_eq!(
            error_offset(src, Some(span.clone()), "invalid type"),
            span.start
        );
        assert_eq!(error_offset(src, None, "unknown field `x`"), 0);
    }

    #[test]
    fn byte_offsets_become_line_and_column() {
        let src = "a = 1\nbé = 2\n";
        assert_eq!(line_col(src, 0), LineCol { line: 1, col: 1 });
        assert_eq!(line_col(src, 6), LineCol { line: 2, col: 1 });
        // 'é' is two bytes but one column: the '=' at byte 10 is column 4.
        assert_eq!(line_col(src, 10), LineCol { line: 2, col: 4 });
        assert_eq!(line_col(src, 1000).line, 3);
    }

    #[test]
    fn nested_keys_are_found_in_tables_and_inline_tables() {
        let src = "name = \"m\"\n\n[axes.X]\nunit = \"mm\"\nplant = { j = -1.0, b = 0.0 }\n";
        let at = locate_key(src, &["axes", "X", "plant", "j"]).unwrap();
        assert_eq!(at.line, 5);
        assert_eq!(&src.lines().nth(4).unwrap()[at.col - 1..at.col + 3], "-1.0");
        // A missing key falls back to its deepest existing parent.
        assert_eq!(locate_key(src, &["axes", "Y"]).map(|p| p.line), Some(3));
        assert_eq!(locate_key(src, &["nothing"]), None);
        assert_eq!(
            locate_key(src, &["axes", "X", "unit"]).map(|p| p.line),
            Some(4)
        );
    }
}
