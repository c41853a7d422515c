//! Property tests of the machine-file loader (issue 7, the CI twin of the `machine_file_mutate`
//! fuzz target in `fuzz/`).
//!
//! Starting from the shipped machine files, random edits — numbers replaced by NaN, ±inf,
//! negative, huge, tiny or random values; values of the wrong type; strings swapped; keys
//! renamed or deleted; lines deleted or duplicated; junk lines inserted — must give either a
//! machine or a typed [`vcnc_machine::Error`] whose message names the file (every loader error
//! is bad input by construction: the loader builds no runtime variant). A panic fails the test.
//! Accepted machines must keep the loader's promise that every drive's closed loop is finite and
//! stable (Routh–Hurwitz on the analytic model, docs/drive-model.md).
//!
//! `ballscrew-*.toml` have no kinematics; the 5-axis and 3-axis sample machines (`nmv5000.toml`
//! with its URDF, the others with a `family`) are loaded with the real `machines/` folder as
//! base directory so that its URDF chain, offsets and travels are checked too.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use proptest::sample::Index;
use vcnc_machine::{Error, Machine};

#[path = "support/words.rs"]
mod words;
use words::{KEYS, LINES, STRINGS};

/// The name the loader is given; every error message must contain it.
const SOURCE: &str = "fuzz.toml";

/// The shipped files, and whether they need `machines/` as base directory.
const FILES: [(&str, &str, bool); 8] = [
    (
        "ballscrew-ppi.toml",
        include_str!("../../../machines/ballscrew-ppi.toml"),
        false,
    ),
    (
        "ballscrew-pid.toml",
        include_str!("../../../machines/ballscrew-pid.toml"),
        false,
    ),
    (
        "ballscrew-smc.toml",
        include_str!("../../../machines/ballscrew-smc.toml"),
        false,
    ),
    (
        "nmv5000.toml",
        include_str!("../../../machines/nmv5000.toml"),
        true,
    ),
    (
        "vmc-3axis.toml",
        include_str!("../../../machines/vmc-3axis.toml"),
        true,
    ),
    (
        "dmu-bc-trunnion.toml",
        include_str!("../../../machines/dmu-bc-trunnion.toml"),
        true,
    ),
    (
        "gantry-head-head.toml",
        include_str!("../../../machines/gantry-head-head.toml"),
        true,
    ),
    (
        "head-table.toml",
        include_str!("../../../machines/head-table.toml"),
        true,
    ),
];

fn machines_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machines")
}

/// Loads `src` as [`SOURCE`]; for the URDF file from the real folder, else from one that does
/// not exist (so a `[kinematics]` section inserted into a ball-screw file is an error, not a read).
fn load(src: &str, needs_dir: bool) -> Result<Machine, Error> {
    let dir = if needs_dir {
        machines_dir()
    } else {
        PathBuf::from("/nonexistent")
    };
    Machine::from_toml_str(src, SOURCE, &dir)
}

/// The property: a typed bad-input error naming the file, or a machine with stable drives.
fn check(src: &str, needs_dir: bool) -> Result<(), TestCaseError> {
    match load(src, needs_dir) {
        Err(e) => {
            let msg = e.to_string();
            prop_assert!(
                msg.contains(SOURCE),
                "the message does not name the file: {msg:?}\n--- file ---\n{src}"
            );
        }
        Ok(m) => {
            prop_assert!(!m.axes.is_empty());
            for a in &m.axes {
                let model = a.true_model();
                prop_assert!(
                    model.is_finite() && model.is_marginally_stable(),
                    "axis {} accepted with model {model:?}\n--- file ---\n{src}",
                    a.name
                );
            }
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Where things are in a TOML text (outside comments and strings).

/// Byte ranges of the code part of each line: up to a `#` that is not inside a string.
fn code_ranges(src: &str) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for line in src.split_inclusive('\n') {
        let mut in_string = false;
        let mut end = start + line.trim_end_matches(['\n', '\r']).len();
        for (i, c) in line.char_indices() {
            match c {
                '"' => in_string = !in_string,
                '#' if !in_string => {
                    end = start + i;
                    break;
                }
                _ => {}
            }
        }
        out.push((start, end));
        start += line.len();
    }
    out
}

/// Tokens of the code parts, as byte ranges: runs of `[A-Za-z0-9_.+-]` outside strings, and
/// string insides (marked `true`).
fn tokens(src: &str) -> Vec<(usize, usize, bool)> {
    let word = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '+' | '-');
    let mut out = Vec::new();
    for (s, e) in code_ranges(src) {
        let line = &src[s..e];
        let mut run: Option<usize> = None;
        let mut string: Option<usize> = None;
        for (i, c) in line.char_indices() {
            if let Some(open) = string {
                if c == '"' {
                    out.push((s + open, s + i, true));
                    string = None;
                }
                continue;
            }
            if let Some(r) = run
                && !word(c)
            {
                out.push((s + r, s + i, false));
                run = None;
            }
            if c == '"' {
                string = Some(i + 1);
            } else if run.is_none() && word(c) {
                run = Some(i);
            }
        }
        if let Some(r) = run {
            out.push((s + r, e, false));
        }
    }
    out
}

/// Numeric literals: tokens that parse as a number once `_` are removed (and `inf`/`nan`).
fn numbers(src: &str) -> Vec<(usize, usize)> {
    tokens(src)
        .into_iter()
        .filter(|&(s, e, quoted)| {
            let t = src[s..e].replace('_', "");
            !quoted
                && (t.parse::<f64>().is_ok()
                    || matches!(t.trim_start_matches(['+', '-']), "inf" | "nan"))
                && t.bytes()
                    .any(|b| b.is_ascii_digit() || b == b'i' || b == b'n')
        })
        .map(|(s, e, _)| (s, e))
        .collect()
}

/// Keys: unquoted tokens followed by `=` (dotted keys as one token are split by the loader
/// anyway), and table-header names `[a.b]`.
fn keys(src: &str) -> Vec<(usize, usize)> {
    tokens(src)
        .into_iter()
        .filter(|&(s, e, quoted)| {
            let after = src[e..].trim_start_matches([' ', '\t']);
            let before = src[..s].trim_end_matches([' ', '\t']);
            !quoted
                && src[s..e].starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
                && ((after.starts_with('=') && !after.starts_with("=="))
                    || (before.ends_with('[') && after.starts_with(']')))
        })
        .map(|(s, e, _)| (s, e))
        .collect()
}

/// String insides.
fn strings(src: &str) -> Vec<(usize, usize)> {
    tokens(src)
        .into_iter()
        .filter(|t| t.2)
        .map(|(s, e, _)| (s, e))
        .collect()
}

/// The byte range of `key = value` that starts at the key `(s, e)`, with a following comma: the
/// value ends at a `,`, `}` or line end outside brackets and strings.
fn entry_range(src: &str, (s, e): (usize, usize)) -> (usize, usize) {
    let mut depth = 0i32;
    let mut in_string = false;
    let mut end = src.len();
    for (i, c) in src[e..].char_indices() {
        match c {
            '"' => in_string = !in_string,
            _ if in_string => {}
            '[' | '{' => depth += 1,
            ']' | '}' if depth > 0 => depth -= 1,
            ',' | '}' | '\n' if depth == 0 => {
                end = e + i + usize::from(c == ',');
                break;
            }
            _ => {}
        }
    }
    (s, end)
}

/// Line ranges including the line break.
fn lines(src: &str) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for line in src.split_inclusive('\n') {
        out.push((start, start + line.len()));
        start += line.len();
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Mutations.

/// One edit of the text. Indices pick among the candidates present when it is applied.
#[derive(Debug, Clone)]
enum Mutation {
    /// Replace a numeric literal.
    Number(Index, String),
    /// Replace a numeric literal by a value of another type or shape.
    WrongType(Index, &'static str),
    /// Replace the inside of a string.
    Str(Index, &'static str),
    /// Rename a key.
    RenameKey(Index, &'static str),
    /// Delete a `key = value` (line or inline-table entry).
    DeleteKey(Index),
    /// Delete a line.
    DeleteLine(Index),
    /// Duplicate a line.
    DuplicateLine(Index),
    /// Insert a line before a line.
    Insert(Index, String),
}

/// A float as a TOML literal (`nan`, `inf`, `-inf` or Rust's shortest round-trip form).
fn toml_float(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { "inf".into() } else { "-inf".into() }
    } else {
        format!("{v:?}")
    }
}

fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        3 => prop::sample::select(&[
            "nan", "-nan", "inf", "-inf", "0", "0.0", "-0.0", "-1", "-1.0", "1", "2", "1e308",
            "-1e308", "1e-308", "5e-324", "1e9", "-1e9", "1e-9", "9223372036854775807",
            "-9223372036854775808", "18446744073709551616", "1e400",
        ][..]).prop_map(str::to_string),
        2 => any::<f64>().prop_map(toml_float),
        2 => (-1e6..1e6f64).prop_map(toml_float),
        1 => (-1e3..1e3f64).prop_map(|v| toml_float(v * 1e-6)),
        1 => any::<i64>().prop_map(|v| v.to_string()),
    ]
}

const WRONG: &[&str] = &[
    "\"\"",
    "\"1.0\"",
    "true",
    "[]",
    "[1.0]",
    "[1.0, 2.0, 3.0]",
    "{}",
    "{ j = 1.0 }",
    "1979-05-27",
    "[[]]",
    "'single'",
];

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        6 => (any::<Index>(), number()).prop_map(|(i, v)| Mutation::Number(i, v)),
        1 => (any::<Index>(), prop::sample::select(WRONG)).prop_map(|(i, v)| Mutation::WrongType(i, v)),
        1 => (any::<Index>(), prop::sample::select(STRINGS)).prop_map(|(i, v)| Mutation::Str(i, v)),
        2 => (any::<Index>(), prop::sample::select(KEYS)).prop_map(|(i, k)| Mutation::RenameKey(i, k)),
        2 => any::<Index>().prop_map(Mutation::DeleteKey),
        1 => any::<Index>().prop_map(Mutation::DeleteLine),
        1 => any::<Index>().prop_map(Mutation::DuplicateLine),
        1 => (any::<Index>(), prop_oneof![
            3 => prop::sample::select(LINES).prop_map(str::to_string),
            1 => "\\PC{0,30}",
        ]).prop_map(|(i, l)| Mutation::Insert(i, l)),
    ]
}

/// Applies `m` to `src` (no-op when there is no candidate).
fn apply(src: &mut String, m: &Mutation) {
    let pick = |v: Vec<(usize, usize)>, i: &Index| (!v.is_empty()).then(|| v[i.index(v.len())]);
    match m {
        Mutation::Number(i, v) => {
            if let Some((s, e)) = pick(numbers(src), i) {
                src.replace_range(s..e, v);
            }
        }
        Mutation::WrongType(i, v) => {
            if let Some((s, e)) = pick(numbers(src), i) {
                src.replace_range(s..e, v);
            }
        }
        Mutation::Str(i, v) => {
            if let Some((s, e)) = pick(strings(src), i) {
                src.replace_range(s..e, v);
            }
        }
        Mutation::RenameKey(i, k) => {
            if let Some((s, e)) = pick(keys(src), i) {
                src.replace_range(s..e, k);
            }
        }
        Mutation::DeleteKey(i) => {
            let entries: Vec<(usize, usize)> = keys(src)
                .into_iter()
                .filter(|&(_, e)| src[e..].trim_start_matches([' ', '\t']).starts_with('='))
                .collect();
            if let Some(k) = pick(entries, i) {
                let (s, e) = entry_range(src, k);
                src.replace_range(s..e, "");
            }
        }
        Mutation::DeleteLine(i) => {
            if let Some((s, e)) = pick(lines(src), i) {
                src.replace_range(s..e, "");
            }
        }
        Mutation::DuplicateLine(i) => {
            if let Some((s, e)) = pick(lines(src), i) {
                let line = src[s..e].to_string();
                let line = if line.ends_with('\n') {
                    line
                } else {
                    format!("{line}\n")
                };
                src.insert_str(s, &line);
            }
        }
        Mutation::Insert(i, l) => {
            let at = pick(lines(src), i).map_or(0, |(s, _)| s);
            src.insert_str(at, &format!("{l}\n"));
        }
    }
}

// ---------------------------------------------------------------------------------------------

/// The baseline: every shipped file loads as it is (else the properties below would only test
/// the error path).
#[test]
fn shipped_files_load() {
    for (name, src, needs_dir) in FILES {
        let m = load(src, needs_dir).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(m.source, SOURCE);
        assert_eq!(m.kinematics.is_some(), needs_dir, "{name}");
    }
}

/// The mutation helpers find what they should (hand-checked on a small document), so the
/// properties really edit numbers, keys and strings.
#[test]
fn scanners_find_numbers_keys_strings_and_entries() {
    let src = "# j = 1\n[axes.X]\nunit = \"mm\" # 2\ntravel = [-100.0, 1e3]\nplant = { j = 0.01, b = -inf }\n";
    let text = |v: Vec<(usize, usize)>| {
        v.iter()
            .map(|&(s, e)| src[s..e].to_string())
            .collect::<Vec<_>>()
    };
    assert_eq!(text(numbers(src)), ["-100.0", "1e3", "0.01", "-inf"]);
    assert_eq!(
        text(keys(src)),
        ["axes.X", "unit", "travel", "plant", "j", "b"]
    );
    assert_eq!(text(strings(src)), ["mm"]);
    let j = keys(src)[4];
    assert_eq!(text(vec![entry_range(src, j)]), ["j = 0.01,"]);
    let b = keys(src)[5];
    assert_eq!(text(vec![entry_range(src, b)]), ["b = -inf "]);
    let plant = keys(src)[3];
    assert_eq!(
        text(vec![entry_range(src, plant)]),
        ["plant = { j = 0.01, b = -inf }"]
    );
}

/// Known bad edits give the expected typed errors with the line of the offending key.
#[test]
fn targeted_edits_name_the_key_and_line() {
    let (_, ppi, _) = FILES[0];
    let negative_j = ppi.replace("j = 0.01", "j = -0.01");
    let e = load(&negative_j, false).unwrap_err();
    assert!(matches!(e, Error::Invalid { .. }), "{e:?}");
    let msg = e.to_string();
    let plant_line = ppi.lines().position(|l| l.starts_with("plant")).unwrap() + 1;
    assert!(msg.starts_with(&format!("{SOURCE}:{plant_line}:")), "{msg}");
    assert!(msg.contains("axes.X.plant.j"), "{msg}");

    let nan_ts = ppi.replace("sample_period_s = 0.001", "sample_period_s = nan");
    let msg = load(&nan_ts, false).unwrap_err().to_string();
    assert!(
        msg.contains("sample_period_s") && msg.contains("NaN"),
        "{msg}"
    );

    let typo = ppi.replace("max_velocity", "max_velocty");
    let e = load(&typo, false).unwrap_err();
    assert!(matches!(e, Error::Toml { .. }), "{e:?}");
    assert!(e.to_string().contains("max_velocty"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// Random edits of a shipped file: never a panic; errors are bad input and name the file;
    /// accepted machines have stable drives.
    #[test]
    fn mutated_machine_files_fail_well(
        file in 0..FILES.len(),
        edits in prop::collection::vec(mutation(), 1..6),
    ) {
        let (_, base, needs_dir) = FILES[file];
        let mut src = base.to_string();
        for m in &edits {
            apply(&mut src, m);
        }
        check(&src, needs_dir)?;
    }

    /// Arbitrary text (printable junk with TOML punctuation) as a machine file.
    #[test]
    fn junk_text_fails_well(src in "[ -~\n\tαé]{0,300}") {
        check(&src, false)?;
    }
}
