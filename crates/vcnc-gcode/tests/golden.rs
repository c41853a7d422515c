//! Golden tests over real programs written for other parsers (`tests/data/corpus`, see its
//! PROVENANCE.md). Each program, strict and lenient, is parsed and interpreted, and a text
//! snapshot of its blocks, diagnostics and moves is compared exactly with the committed one in
//! `tests/data/golden`. Regenerate after an intended change with
//! `VCNC_BLESS=1 cargo test -p vcnc-gcode --test integration golden`, then review the diff.

use std::fmt::Write;
use std::path::{Path, PathBuf};
use vcnc_gcode::{
    Block, CommentKind, Diagnostic, Feed, InterpOptions, MoveKind, ParseOptions, PathMode,
    interpret, parse_with,
};

fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/corpus")
}

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/golden")
}

/// The programs: everything in the corpus but the provenance and expectation files.
fn programs() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(corpus_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let name = p.file_name().unwrap().to_string_lossy();
            !name.ends_with(".md") && !name.ends_with(".expected.txt")
        })
        .collect();
    v.sort();
    v
}

fn block_text(b: &Block) -> String {
    let mut s = format!("{}:{}", b.line, b.span.col);
    if b.percent {
        s.push_str(" %");
    }
    if b.block_delete {
        s.push_str(" /");
    }
    if let Some(n) = b.line_number {
        let _ = write!(s, " N{}", n.value);
    }
    for w in &b.words {
        let _ = write!(s, " {}{}@{}", w.letter, w.value, w.span.col);
    }
    for c in &b.comments {
        match c.kind {
            CommentKind::Paren => {
                let _ = write!(s, " ({})@{}", c.text, c.span.col);
            }
            CommentKind::Semicolon => {
                let _ = write!(s, " ;{}@{}", c.text, c.span.col);
            }
        }
    }
    s
}

fn diag_text(d: &Diagnostic) -> String {
    format!("{} {d}", d.severity)
}

fn snapshot(name: &str, src: &str, lenient: bool) -> (String, bool) {
    let mode = if lenient { "lenient" } else { "strict" };
    let mut out = format!(
        "# {name} ({mode}): blocks (line:col, words as letter value @col, comments), \
         diagnostics, moves. Regenerate with VCNC_BLESS=1.\n"
    );
    let (program, diags) = parse_with(
        src,
        &ParseOptions {
            lenient,
            ..ParseOptions::default()
        },
    );
    out.push_str("== blocks\n");
    for b in &program.blocks {
        let _ = writeln!(out, "{}", block_text(b));
    }
    out.push_str("== syntax diagnostics\n");
    for d in &diags {
        let _ = writeln!(out, "{}", diag_text(d));
    }
    let mut accepted = !diags.iter().any(Diagnostic::is_error);
    let opts = InterpOptions {
        lenient,
        ..InterpOptions::default()
    };
    match interpret(&program, &opts) {
        Ok((tp, warnings)) => {
            out.push_str("== interpreter diagnostics\n");
            for d in &warnings {
                let _ = writeln!(out, "{}", diag_text(d));
            }
            let _ = writeln!(out, "== toolpath: start {:?}", tp.start);
            for m in &tp.moves {
                let kind = match m.kind {
                    MoveKind::Rapid => "rapid".to_string(),
                    MoveKind::Linear => "linear".to_string(),
                    MoveKind::Arc(a) => format!(
                        "arc {:?} centre {:?} sweep {:.9} rad r {:.9}",
                        a.plane, a.centre, a.sweep_rad, a.radius_start_mm
                    ),
                    MoveKind::Dwell { seconds } => format!("dwell {seconds} s"),
                };
                let feed = match m.feed {
                    Some(Feed::UnitsPerMin(f)) => format!("F {f}/min"),
                    Some(Feed::InverseTime(f)) => format!("F 1/{f} min"),
                    None => "-".to_string(),
                };
                let _ = writeln!(
                    out,
                    "{}:{} {kind} -> {:?} {feed}{}{}",
                    m.line,
                    m.col,
                    m.end,
                    match m.path {
                        PathMode::ExactStop => " G61.1".to_string(),
                        PathMode::ExactPath => " G61".to_string(),
                        PathMode::Blend {
                            tolerance_mm,
                            merge_mm,
                        } => format!(
                            " G64{}{}",
                            tolerance_mm.map_or(String::new(), |p| format!(" P{p}")),
                            merge_mm.map_or(String::new(), |q| format!(" Q{q}"))
                        ),
                    },
                    if m.tcp { " TCP" } else { "" }
                );
            }
        }
        Err(d) => {
            accepted = false;
            out.push_str("== interpreter diagnostics (rejected)\n");
            for d in &d {
                let _ = writeln!(out, "{}", diag_text(d));
            }
        }
    }
    (out, accepted)
}

fn compare_or_bless(file: &str, got: &str) {
    let path = golden_dir().join(file);
    if std::env::var("VCNC_BLESS").is_ok_and(|v| v == "1") {
        std::fs::create_dir_all(golden_dir()).unwrap();
        std::fs::write(&path, got).unwrap();
        return;
    }
    let want = std::fs::read_to_string(&path).unwrap_or_else(|_| {
        panic!(
            "missing golden file {}; run with VCNC_BLESS=1",
            path.display()
        )
    });
    if want != got {
        let line = want
            .lines()
            .zip(got.lines())
            .position(|(a, b)| a != b)
            .map_or(want.lines().count().min(got.lines().count()), |i| i);
        panic!(
            "{} differs from the output at line {}:\n  golden: {:?}\n  output: {:?}\n(run with VCNC_BLESS=1 if the change is intended)",
            path.display(),
            line + 1,
            want.lines().nth(line),
            got.lines().nth(line)
        );
    }
}

#[test]
fn corpus_matches_golden_snapshots() {
    let progs = programs();
    assert_eq!(progs.len(), 5, "{progs:?}");
    for p in progs {
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        let src = std::fs::read_to_string(&p).unwrap();
        for lenient in [false, true] {
            let (snap, _) = snapshot(&name, &src, lenient);
            let mode = if lenient { "lenient" } else { "strict" };
            compare_or_bless(&format!("{name}.{mode}.txt"), &snap);
        }
    }
}

#[test]
fn rejections_point_into_the_file_and_lenient_drops_only_harmless_words() {
    let mut rejected = Vec::new();
    let mut rejected_lenient = Vec::new();
    for p in programs() {
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        let src = std::fs::read_to_string(&p).unwrap();
        let lines = src.lines().count() as u32;
        for lenient in [false, true] {
            let (program, diags) = parse_with(
                &src,
                &ParseOptions {
                    lenient,
                    ..ParseOptions::default()
                },
            );
            let opts = InterpOptions {
                lenient,
                ..InterpOptions::default()
            };
            let mut errors: Vec<Diagnostic> =
                diags.into_iter().filter(Diagnostic::is_error).collect();
            if let Err(d) = interpret(&program, &opts) {
                errors.extend(d.into_iter().filter(Diagnostic::is_error));
            }
            for e in &errors {
                // Every rejection points into the file.
                assert!(e.line >= 1 && e.line <= lines && e.col >= 1, "{name}: {e}");
                let text = src.lines().nth(e.line as usize - 1).unwrap();
                assert!(e.col as usize <= text.chars().count(), "{name}: {e}");
            }
            if !errors.is_empty() {
                if lenient {
                    rejected_lenient.push(name.clone());
                } else {
                    rejected.push(name.clone());
                }
            }
        }
    }
    // Strict: the dialect files are rejected, the plain ones accepted.
    assert_eq!(rejected, vec!["edge_cases.gcode", "special-fields.gcode"]);
    // Lenient still rejects what would change the path: edge_cases' unknown M587 (it may
    // change modes) and special-fields' `G92 E0` (a G92 without axis words once `E` is dropped).
    assert_eq!(
        rejected_lenient,
        vec!["edge_cases.gcode", "special-fields.gcode"]
    );
}

#[test]
fn circle_matches_the_cncjs_expected_words() {
    // Truth: cncjs/gcode-parser's expected parse (circle.expected.txt).
    let expected = std::fs::read_to_string(corpus_dir().join("circle.expected.txt")).unwrap();
    let src = std::fs::read_to_string(corpus_dir().join("circle.nc")).unwrap();
    let (program, diags) = parse_with(&src, &ParseOptions::default());
    assert!(diags.is_empty());
    let rows: Vec<Vec<(char, f64)>> = expected
        .lines()
        .filter(|l| !l.starts_with('#') && l.contains("->"))
        .map(|l| {
            let rhs = l.split("->").nth(1).unwrap();
            rhs.split(']')
                .filter(|t| t.contains('['))
                .map(|t| {
                    let t = t.trim().trim_start_matches('[');
                    let (letter, value) = t.split_once(',').unwrap();
                    (letter.chars().next().unwrap(), value.parse().unwrap())
                })
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), program.blocks.len());
    for (row, block) in rows.iter().zip(&program.blocks) {
        let got: Vec<(char, f64)> = block.words.iter().map(|w| (w.letter, w.value)).collect();
        assert_eq!(&got, row);
        assert!(block.line_number.is_none());
    }
    // And it means a 5 mm circle about the origin in four clockwise quarters.
    let (tp, _) = interpret(&program, &InterpOptions::default()).unwrap();
    let arcs: Vec<_> = tp
        .moves
        .iter()
        .filter_map(|m| match m.kind {
            MoveKind::Arc(a) => Some(a),
            _ => None,
        })
        .collect();
    assert_eq!(arcs.len(), 4);
    for a in arcs {
        assert_eq!(a.centre, [0.0, 0.0]);
        assert_eq!(a.radius_start_mm, 5.0);
        assert!((a.sweep_rad + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }
}

#[test]
fn spaces_variants_parse_alike() {
    // spaces.nc writes one block three ways (no spaces, spaces, spaces inside words).
    let src = std::fs::read_to_string(corpus_dir().join("spaces.nc")).unwrap();
    let (program, diags) = parse_with(&src, &ParseOptions::default());
    assert!(diags.is_empty());
    let words: Vec<Vec<(char, f64)>> = program
        .blocks
        .iter()
        .map(|b| b.words.iter().map(|w| (w.letter, w.value)).collect())
        .collect();
    assert_eq!(words.len(), 3);
    assert!(words.iter().all(|w| *w == words[0]));
}
