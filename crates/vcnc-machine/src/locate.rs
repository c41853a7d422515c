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

#[cfg(test)]
mod tests {
    use super::*;

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
