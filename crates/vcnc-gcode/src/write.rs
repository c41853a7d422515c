//! G-code writers: programs vcnc writes for a control to run — a program's own text with new
//! feeds (feed planning) and sampled positions as fine blocks (compensation).

use std::collections::BTreeMap;

use crate::{AxisName, Block, Program};

/// Per block of the program, in order: the length unit in force at the block's end (25.4 after
/// `G20`, 1 after `G21`), tracked in text order.
fn unit_scales(program: &Program) -> BTreeMap<u32, f64> {
    let mut scale = 1.0;
    program
        .blocks
        .iter()
        .map(|b| {
            for w in &b.words {
                if w.letter == 'G' && w.expr.is_none() {
                    if w.value == 20.0 {
                        scale = 25.4;
                    } else if w.value == 21.0 {
                        scale = 1.0;
                    }
                }
            }
            (b.line, scale)
        })
        .collect()
}

/// A feed value for an F word: rounded down to 10⁻⁴, at least 10⁻⁴, without trailing zeros.
fn f_word(v: f64) -> (f64, String) {
    let r = ((v * 1e4).floor() / 1e4).max(1e-4);
    let s = format!("{r:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.').to_string();
    (r, s)
}

/// The source text with an explicit F word on every feed line: the programmed feed (in the
/// line's units per minute) times the line's factor. `lines` holds each feed line's feed as the
/// interpreter reads it (mm/min or deg/min) and whether it is a pure rotary move; a line
/// without a factor keeps its feed. Only the F words change: every other character of the
/// source stays (the parser's spans say where each word is). Returns the text and the F values
/// written.
pub fn with_feed_factors(
    src: &str,
    program: &Program,
    lines: &BTreeMap<u32, (f64, bool)>,
    factors: &BTreeMap<u32, f64>,
) -> (String, BTreeMap<u32, f64>) {
    let scales = unit_scales(program);
    let mut edits: Vec<(usize, usize, String)> = Vec::new();
    let mut written = BTreeMap::new();
    for b in &program.blocks {
        let Some(&line) = lines.get(&b.line) else {
            continue;
        };
        let own = b.words.iter().find(|w| w.letter == 'F');
        let programmed = programmed_value(b, line, &scales);
        let factor = factors.get(&b.line).copied().unwrap_or(1.0);
        let (value, text) = f_word(programmed * factor);
        written.insert(b.line, value);
        match own {
            Some(w) => edits.push((w.span.start, w.span.end, format!("F{text}"))),
            None => {
                let end = b
                    .words
                    .iter()
                    .map(|w| w.span.end)
                    .max()
                    .unwrap_or(b.span.end);
                edits.push((end, end, format!(" F{text}")));
            }
        }
    }
    edits.sort_by_key(|e| e.0);
    let mut out = String::with_capacity(src.len() + edits.len() * 12);
    let mut at = 0;
    for (start, end, text) in edits {
        if start < at || end > src.len() {
            continue;
        }
        out.push_str(&src[at..start]);
        out.push_str(&text);
        at = end;
    }
    out.push_str(&src[at..]);
    (out, written)
}

/// The programmed feeds of the feed lines, as an F word would write them (line's units per
/// minute).
pub fn programmed_feeds(
    program: &Program,
    lines: &BTreeMap<u32, (f64, bool)>,
) -> BTreeMap<u32, f64> {
    let scales = unit_scales(program);
    program
        .blocks
        .iter()
        .filter_map(|b| {
            let &line = lines.get(&b.line)?;
            Some((b.line, programmed_value(b, line, &scales)))
        })
        .collect()
}

/// The feed in force on block `b` as its F word would write it: its own plain F word, else the
/// move's feed (mm/min or deg/min) in the length unit in force at the line.
fn programmed_value(
    b: &Block,
    (feed, pure_rotary): (f64, bool),
    scales: &BTreeMap<u32, f64>,
) -> f64 {
    match b.words.iter().find(|w| w.letter == 'F') {
        Some(w) if w.expr.is_none() && w.value.is_finite() => w.value,
        _ => {
            let scale = scales.get(&b.line).copied().unwrap_or(1.0);
            if pure_rotary { feed } else { feed / scale }
        }
    }
}

/// Axis positions sampled at `ts` (s) as a G-code program a control runs as they are
/// (docs/compensation.md#the-fine-block-program): `G21 G90 G49 G64`, a `G0` to the first
/// sample, then under `G93` one `G1` per sample period with $F = 60/T_s$ (the block lasts
/// exactly one period; only the axes that move are written, every value in full precision), a
/// `G4` dwell for each run of samples where no axis moves, `M2`. `axes` gives each axis and its
/// samples (all of one length); `header` lines become comments (parentheses are replaced).
pub fn fine_blocks(axes: &[(AxisName, &[f64])], ts: f64, header: &[String]) -> String {
    let n = axes.first().map_or(0, |a| a.1.len());
    let mut out = String::with_capacity(n * 64 + 256);
    out.push_str("%\n");
    for h in header {
        out.push('(');
        out.push_str(&h.replace(['(', ')'], "'"));
        out.push_str(")\n");
    }
    out.push_str("G21 G90 G17 G49 G64\n");
    if n == 0 {
        out.push_str("M2\n%\n");
        return out;
    }
    let at = |k: usize| -> Vec<f64> { axes.iter().map(|a| a.1[k]).collect() };
    let word = |a: &(AxisName, &[f64]), v: f64| format!(" {}{}", a.0, fmt_exact(v));
    out.push_str("G0");
    for (a, v) in axes.iter().zip(at(0)) {
        out.push_str(&word(a, v));
    }
    out.push_str("\nG93\n");
    let f = fmt_exact(60.0 / ts);
    let mut prev = at(0);
    let mut rest = 0usize;
    for k in 1..n {
        let cur = at(k);
        if cur == prev {
            rest += 1;
            continue;
        }
        if rest > 0 {
            out.push_str(&format!("G4 P{}\n", fmt_exact(rest as f64 * ts)));
            rest = 0;
        }
        out.push_str("G1");
        for ((a, v), p) in axes.iter().zip(&cur).zip(&prev) {
            if v != p {
                out.push_str(&word(a, *v));
            }
        }
        out.push_str(" F");
        out.push_str(&f);
        out.push('\n');
        prev = cur;
    }
    if rest > 0 {
        out.push_str(&format!("G4 P{}\n", fmt_exact(rest as f64 * ts)));
    }
    out.push_str("G94 G61\nM2\n%\n");
    out
}

/// A G-code number that reads back as the same `f64` (shortest round-trip decimal, never an
/// exponent: Rust's `Display` for floats writes plain decimals), `-0` written as `0`.
fn fmt_exact(v: f64) -> String {
    if v == 0.0 {
        "0".to_string()
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f_words_round_down() {
        assert_eq!(f_word(4500.0).1, "4500");
        assert_eq!(f_word(123.456789).1, "123.4567");
        assert_eq!(f_word(1e-9).1, "0.0001");
        assert!(f_word(0.3).0 <= 0.3);
    }

    #[test]
    fn every_feed_line_gets_an_explicit_f_word() {
        // Truth: RS274 modal feeds — a line without F inherits the previous line's; after the
        // rewrite each feed line carries its own value (programmed × factor) in its own units.
        let src = "G21 G90 G94 G64\nG0 X0\nG1 X1 F600\nX2\nG20 X0.1 F10 (inch)\nG0 X0\n";
        let (program, _) = crate::parse(src);
        let mut lines = BTreeMap::new();
        lines.insert(3, (600.0, false));
        lines.insert(4, (600.0, false));
        lines.insert(5, (254.0, false));
        let factors: BTreeMap<u32, f64> = [(3, 0.5), (4, 0.25), (5, 0.5)].into_iter().collect();
        let (text, written) = with_feed_factors(src, &program, &lines, &factors);
        assert_eq!(
            text,
            "G21 G90 G94 G64\nG0 X0\nG1 X1 F300\nX2 F150\nG20 X0.1 F5 (inch)\nG0 X0\n"
        );
        assert_eq!(written[&4], 150.0);
    }
}
