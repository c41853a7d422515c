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

/// The feed of a feed line as the interpreter read it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LineFeed {
    /// `G94`: mm/min (deg/min for a move of rotary axes alone, `pure_rotary`).
    PerMinute {
        /// The feed, mm/min or deg/min.
        feed: f64,
        /// A move of rotary axes alone.
        pure_rotary: bool,
    },
    /// `G93`: the inverse time, 1/min (the block lasts 1/F minutes; F times a factor slows it
    /// by that factor, as for a feed per minute).
    InverseTime(f64),
}

/// The source text with an explicit F word on every feed line: the programmed feed (in the
/// line's units per minute, or its inverse time) times the line's factor. `lines` holds each
/// feed line's feed as the interpreter reads it; a line without a factor keeps its feed. Only the F words change: every other character of the
/// source stays (the parser's spans say where each word is). Returns the text and the F values
/// written.
pub fn with_feed_factors(
    src: &str,
    program: &Program,
    lines: &BTreeMap<u32, LineFeed>,
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
pub fn programmed_feeds(program: &Program, lines: &BTreeMap<u32, LineFeed>) -> BTreeMap<u32, f64> {
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
/// move's feed (mm/min or deg/min in the length unit in force at the line; an inverse time as
/// it is).
fn programmed_value(b: &Block, line: LineFeed, scales: &BTreeMap<u32, f64>) -> f64 {
    match b.words.iter().find(|w| w.letter == 'F') {
        Some(w) if w.expr.is_none() && w.value.is_finite() => w.value,
        _ => match line {
            LineFeed::PerMinute {
                feed,
                pure_rotary: true,
            }
            | LineFeed::InverseTime(feed) => feed,
            LineFeed::PerMinute { feed, .. } => feed / scales.get(&b.line).copied().unwrap_or(1.0),
        },
    }
}

/// How [`fine_blocks`] writes a program a control can run
/// (docs/compensation.md#the-fine-block-program): the word resolution, the shortest block and
/// how far a block's straight line may stray from the samples it replaces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockRules {
    /// Fewest sample periods in a block: the control's block cycle over $T_s$, rounded up
    /// (1 … [`FINE_BLOCK_MAX_SAMPLES`](crate::FINE_BLOCK_MAX_SAMPLES)).
    pub min_samples: u64,
    /// Resolution of linear-axis words, mm (0: every value in full precision).
    pub resolution: f64,
    /// Resolution of rotary-axis words, deg (0: full precision).
    pub rotary_resolution: f64,
    /// Largest distance of a block's straight line from a sample it replaces, linear axes, mm
    /// (0: no sample is merged unless it lies on the line).
    pub tolerance: f64,
    /// The same for rotary axes, deg.
    pub rotary_tolerance: f64,
}

impl BlockRules {
    /// One block per sample period, every value in full precision: the set-points themselves.
    pub const EXACT: BlockRules = BlockRules {
        min_samples: 1,
        resolution: 0.0,
        rotary_resolution: 0.0,
        tolerance: 0.0,
        rotary_tolerance: 0.0,
    };

    fn resolution(&self, axis: AxisName) -> f64 {
        if axis.is_rotary() {
            self.rotary_resolution
        } else {
            self.resolution
        }
    }

    fn tolerance(&self, axis: AxisName) -> f64 {
        if axis.is_rotary() {
            self.rotary_tolerance
        } else {
            self.tolerance
        }
    }
}

/// A program written by [`fine_blocks`], with what it is made of.
#[derive(Debug, Clone, PartialEq)]
pub struct FineProgram {
    /// The program text.
    pub text: String,
    /// Motion blocks (`G1`) written.
    pub blocks: usize,
    /// Dwell blocks (`G4`) written.
    pub dwells: usize,
    /// The shortest motion block, sample periods (0 when there is none). It is at least
    /// `rules.min_samples` unless all the samples together last fewer periods.
    pub shortest_block: u64,
    /// Per axis (in the order given): the largest distance between a sample and the position
    /// the program runs through at that sample, axis units — the chord error of the merged
    /// blocks and the rounding of the words together.
    pub deviation: Vec<f64>,
}

/// Axis positions sampled at `ts` (s) as a G-code program a control runs as it is
/// (docs/compensation.md#the-fine-block-program): `G21 G90 G49 G64`, a `G0` to the first
/// sample, then under `G93` straight `G1` blocks through the samples, each lasting a whole
/// number $m$ of sample periods with $F = 60/(mT_s)$ (`rules.min_samples` ≤ $m$ ≤
/// [`FINE_BLOCK_MAX_SAMPLES`](crate::FINE_BLOCK_MAX_SAMPLES); the longest whose line stays
/// within the tolerance of every sample it replaces; only the axes that move are written, at
/// the stated resolution), a `G4` dwell for each run of at least `min_samples` samples where no
/// axis moves, `M2`. `axes` gives each axis and its samples (all of one length); `header` lines
/// become comments (parentheses are replaced).
pub fn fine_blocks(
    axes: &[(AxisName, &[f64])],
    ts: f64,
    header: &[String],
    rules: &BlockRules,
) -> FineProgram {
    let n = axes.first().map_or(0, |a| a.1.len());
    let mut out = String::with_capacity(n * 64 + 256);
    out.push_str("%\n");
    for h in header {
        out.push('(');
        out.push_str(&h.replace(['(', ')'], "'"));
        out.push_str(")\n");
    }
    out.push_str("G21 G90 G17 G49 G64\n");
    let mut program = FineProgram {
        text: String::new(),
        blocks: 0,
        dwells: 0,
        shortest_block: 0,
        deviation: vec![0.0; axes.len()],
    };
    if n == 0 {
        out.push_str("M2\n%\n");
        program.text = out;
        return program;
    }
    // Every sample as written: each value at its axis' resolution, read back.
    let q: Vec<Vec<f64>> = axes
        .iter()
        .map(|(a, v)| {
            let res = rules.resolution(*a);
            v.iter().map(|x| word_value(*x, res).1).collect()
        })
        .collect();
    let same = |k: usize, p: &[f64]| q.iter().zip(p).all(|(c, x)| c[k] == *x);
    let tol: Vec<f64> = axes.iter().map(|(a, _)| rules.tolerance(*a)).collect();
    out.push_str("G0");
    for (a, v) in axes {
        out.push_str(&format!(" {a}{}", word_value(v[0], rules.resolution(*a)).0));
    }
    out.push_str("\nG93\n");
    let mut at: Vec<f64> = q.iter().map(|c| c[0]).collect();
    for (i, (_, v)) in axes.iter().enumerate() {
        program.deviation[i] = (v[0] - at[i]).abs();
    }
    // How far the straight line from `at` to sample `s + m` (as written) strays from the
    // samples it replaces, per axis.
    let stray = |at: &[f64], s: usize, m: usize| -> Vec<f64> {
        axes.iter()
            .enumerate()
            .map(|(i, (_, v))| {
                (1..=m).fold(0.0f64, |w, j| {
                    let p = if j == m {
                        q[i][s + m]
                    } else {
                        at[i] + (q[i][s + m] - at[i]) * (j as f64 / m as f64)
                    };
                    w.max((v[s + j] - p).abs())
                })
            })
            .collect()
    };
    let min = rules.min_samples.max(1) as usize;
    let max = (crate::FINE_BLOCK_MAX_SAMPLES as usize).max(min);
    let mut s = 0usize;
    while s + 1 < n {
        // A rest: the samples that read back as the current position.
        let rest = (s + 1..n).take_while(|&k| same(k, &at)).count();
        if rest >= min || s + 1 + rest == n {
            // When fewer than `min` samples follow the rest, the dwell leaves the block after
            // it the samples it lacks (the rest is at least `min` long, so the dwell keeps one).
            let tail = n - 1 - s - rest;
            let rest = if tail > 0 && tail < min {
                rest - (min - tail)
            } else {
                rest
            };
            for (i, (_, v)) in axes.iter().enumerate() {
                for x in &v[s + 1..=s + rest] {
                    program.deviation[i] = program.deviation[i].max((x - at[i]).abs());
                }
            }
            out.push_str(&format!("G4 P{}\n", fmt_exact(rest as f64 * ts)));
            program.dwells += 1;
            s += rest;
            continue;
        }
        // A straight block of m periods: the longest within the tolerance; failing that, the
        // one that strays least. It must not leave fewer than `min` samples after it, unless
        // those are a rest at its end; when no block can (a block cycle of more than half the
        // longest block), the longest is taken. A block that ends where it starts is a dwell.
        let left = n - 1 - s;
        let mut best: Option<(usize, f64, Vec<f64>)> = None;
        for m in min.min(left)..=max.min(left) {
            let e = s + m;
            let end: Vec<f64> = q.iter().map(|c| c[e]).collect();
            let after = left - m;
            if after > 0 && after < min && !(e + 1..n).all(|k| same(k, &end)) {
                continue;
            }
            let dev = stray(&at, s, m);
            let excess = dev
                .iter()
                .zip(&tol)
                .map(|(d, t)| (d - t).max(0.0))
                .fold(0.0f64, f64::max);
            if best.as_ref().is_none_or(|b| excess <= b.1) {
                best = Some((m, excess, dev));
            }
        }
        let (m, _, dev) = best.unwrap_or_else(|| {
            let m = left.min(max);
            (m, 0.0, stray(&at, s, m))
        });
        let e = s + m;
        if q.iter().zip(&at).all(|(c, x)| c[e] == *x) {
            // The samples left return to where they start, as written: a line from a point
            // to itself is no move (the interpreter drops it), so they are a dwell there.
            for (d, v) in program.deviation.iter_mut().zip(&dev) {
                *d = d.max(*v);
            }
            out.push_str(&format!("G4 P{}\n", fmt_exact(m as f64 * ts)));
            program.dwells += 1;
            s = e;
            continue;
        }
        out.push_str("G1");
        for (i, (a, v)) in axes.iter().enumerate() {
            if q[i][e] != at[i] {
                out.push_str(&format!(" {a}{}", word_value(v[e], rules.resolution(*a)).0));
            }
            program.deviation[i] = program.deviation[i].max(dev[i]);
            at[i] = q[i][e];
        }
        out.push_str(" F");
        out.push_str(&word_value(60.0 / (m as f64 * ts), 1e-4).0);
        out.push('\n');
        program.shortest_block = if program.blocks == 0 {
            m as u64
        } else {
            program.shortest_block.min(m as u64)
        };
        program.blocks += 1;
        s = e;
    }
    out.push_str("G94 G61\nM2\n%\n");
    program.text = out;
    program
}

/// A value as a G-code word writes it at resolution `res` (rounded to the nearest multiple,
/// with as many decimals as the resolution needs and trailing zeros dropped; `res` = 0: the
/// shortest decimal that reads back as the same `f64`), and the value the word reads back as.
pub fn word_value(v: f64, res: f64) -> (String, f64) {
    if res <= 0.0 {
        let text = fmt_exact(v);
        return (text, if v == 0.0 { 0.0 } else { v });
    }
    let decimals = (-res.log10() - 1e-9).ceil().max(0.0) as usize;
    let r = (v / res).round() * res;
    let mut text = format!("{r:.decimals$}");
    if text.contains('.') {
        text = text.trim_end_matches('0').trim_end_matches('.').to_string();
    }
    if text == "-0" {
        text = "0".to_string();
    }
    let back = text.parse::<f64>().unwrap_or(r);
    (text, back)
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
        let per_min = |feed| LineFeed::PerMinute {
            feed,
            pure_rotary: false,
        };
        let mut lines = BTreeMap::new();
        lines.insert(3, per_min(600.0));
        lines.insert(4, per_min(600.0));
        lines.insert(5, per_min(254.0));
        let factors: BTreeMap<u32, f64> = [(3, 0.5), (4, 0.25), (5, 0.5)].into_iter().collect();
        let (text, written) = with_feed_factors(src, &program, &lines, &factors);
        assert_eq!(
            text,
            "G21 G90 G94 G64\nG0 X0\nG1 X1 F300\nX2 F150\nG20 X0.1 F5 (inch)\nG0 X0\n"
        );
        assert_eq!(written[&4], 150.0);
    }

    #[test]
    fn inverse_time_feeds_are_scaled_as_they_are() {
        // Truth: under G93 the F word is 1/minutes (RS274/NGC; LinuxCNC's G93), whatever the
        // length unit: F × factor makes the block last 1/factor times as long.
        let src = "G20 G93 G1 X1 A10 F2\nX2 A20 F0.5\n[#1] G1 X3 F[1+1]\n";
        let (program, _) = crate::parse(src);
        let lines: BTreeMap<u32, LineFeed> = [
            (1, LineFeed::InverseTime(2.0)),
            (2, LineFeed::InverseTime(0.5)),
        ]
        .into_iter()
        .collect();
        let factors: BTreeMap<u32, f64> = [(1, 0.5), (2, 0.25)].into_iter().collect();
        let (text, written) = with_feed_factors(src, &program, &lines, &factors);
        assert!(
            text.starts_with("G20 G93 G1 X1 A10 F1\nX2 A20 F0.125\n"),
            "{text}"
        );
        assert_eq!(written[&2], 0.125);
    }
}
