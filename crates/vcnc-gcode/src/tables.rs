//! The machine's set-up tables, in LinuxCNC's file formats: the parameter file (`.var`: work
//! offsets, G28/G30 positions, G92 offsets) and the tool table (`.tbl`). Both hold lengths in
//! the machine's units ([`LengthUnit`], LinuxCNC `[TRAJ] LINEAR_UNITS`); the interpreter
//! converts them to mm. See docs/gcode.md ("Coordinates and offsets") for how they are used.

use std::collections::BTreeMap;

use crate::Error;
use crate::syntax::MAX_PARAMETER;

/// Length unit of the machine's tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LengthUnit {
    /// Millimetres (default).
    #[default]
    Mm,
    /// Inches (25.4 mm). LinuxCNC's stand-alone `rs274` reads its tables in inches.
    Inch,
}

impl LengthUnit {
    /// mm per unit: 1 or 25.4.
    pub fn mm(self) -> f64 {
        match self {
            LengthUnit::Mm => 1.0,
            LengthUnit::Inch => 25.4,
        }
    }
}

/// Numbered parameters, as in a LinuxCNC parameter file: parameter number → value (lengths in
/// the machine's [`LengthUnit`], angles in degrees). Parameters not listed are 0.
///
/// The ones the interpreter uses (LinuxCNC numbering): 5161–5166 the G28 position and 5181–5186
/// the G30 position (X Y Z A B C, machine coordinates); 5210 G92 enabled (1) or not (0);
/// 5211–5216 the G92 offsets; 5220 the coordinate system in use at start (1 = G54 … 9 = G59.3);
/// 5221–5230 the G54 offsets X Y Z A B C U V W and its XY rotation R (deg), 5241–5250 G55, …,
/// 5381–5390 G59.3.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ParameterTable {
    /// Parameter number (1..=5601) → value.
    pub values: BTreeMap<u32, f64>,
}

impl ParameterTable {
    /// The value of parameter `n` (0 when not listed).
    pub fn get(&self, n: u32) -> f64 {
        self.values.get(&n).copied().unwrap_or(0.0)
    }

    /// Set parameter `n`.
    pub fn set(&mut self, n: u32, value: f64) {
        self.values.insert(n, value);
    }
}

/// One tool of a [`ToolTable`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Tool {
    /// Pocket number (`P`).
    pub pocket: u32,
    /// Offsets X Y Z A B C (`X Y Z` in the machine's length unit, `A B C` in degrees); `G43`
    /// applies them. `Z` is the tool length.
    pub offset: [f64; 6],
    /// Diameter (`D`), machine length unit.
    pub diameter: f64,
    /// Lathe front angle (`I`), deg.
    pub front_angle_deg: f64,
    /// Lathe back angle (`J`), deg.
    pub back_angle_deg: f64,
    /// Lathe orientation (`Q`).
    pub orientation: i32,
    /// The text after `;`.
    pub comment: String,
}

/// A tool table: tool number → tool, as in a LinuxCNC `.tbl` file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ToolTable {
    /// Tool number (`T`) → its data.
    pub tools: BTreeMap<u32, Tool>,
}

/// Parse a LinuxCNC parameter file (`.var`).
///
/// Format (LinuxCNC `Interp::restore_parameters`): one parameter per line, `number value`
/// separated by blanks, numbers in increasing order, each in 1..=5601. Blank lines are skipped.
/// Unlike LinuxCNC, which skips lines it cannot read, any other line is an error naming
/// `file:line`, so a damaged file is not silently half-read. `file` is used in messages only.
pub fn parse_parameter_file(text: &str, file: &str) -> Result<ParameterTable, Error> {
    let mut table = ParameterTable::default();
    let mut last: Option<(u32, u32)> = None;
    for (i, raw) in text.lines().enumerate() {
        let line = u32::try_from(i + 1).unwrap_or(u32::MAX);
        let t = raw.trim();
        if t.is_empty() {
            continue;
        }
        let bad = |reason: String| Error::ParameterFile {
            file: file.to_string(),
            line,
            text: t.to_string(),
            reason,
        };
        let mut fields = t.split_whitespace();
        let (Some(n), Some(v), None) = (fields.next(), fields.next(), fields.next()) else {
            return Err(bad("expected '<parameter number> <value>'".into()));
        };
        let n: u32 = n
            .parse()
            .ok()
            .filter(|n| (1..=MAX_PARAMETER).contains(n))
            .ok_or_else(|| {
                bad(format!(
                    "parameter number '{n}' is not a whole number in 1..={MAX_PARAMETER}"
                ))
            })?;
        let v: f64 = v
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| {
                bad(format!(
                    "value '{v}' of parameter {n} is not a finite number"
                ))
            })?;
        if let Some((prev, prev_line)) = last
            && n <= prev
        {
            return Err(bad(format!(
                "parameter {n} comes after parameter {prev} (line {prev_line}): numbers must increase"
            )));
        }
        last = Some((n, line));
        table.set(n, v);
    }
    Ok(table)
}

/// Parse a LinuxCNC tool table (`.tbl`).
///
/// Format (LinuxCNC `loadToolTable`, the format of LinuxCNC 2.4 and later): one tool per line,
/// blank-separated words `T<tool> P<pocket> X.. Y.. Z.. A.. B.. C.. U.. V.. W.. D<diameter>
/// I<front angle> J<back angle> Q<orientation>`, letters in either case, then an optional
/// `; comment`. `T` is required; the others default to 0. `U V W` are accepted and ignored (vcnc
/// has no such axes). Blank lines are skipped. Any other text, a repeated tool number or an
/// old-style (numbers only) line is an error naming `file:line`.
pub fn parse_tool_table(text: &str, file: &str) -> Result<ToolTable, Error> {
    let mut table = ToolTable::default();
    let mut seen: BTreeMap<u32, u32> = BTreeMap::new();
    for (i, raw) in text.lines().enumerate() {
        let line = u32::try_from(i + 1).unwrap_or(u32::MAX);
        let (body, comment) = match raw.split_once(';') {
            Some((b, c)) => (b, c.trim()),
            None => (raw, ""),
        };
        if body.trim().is_empty() {
            continue;
        }
        let bad = |word: &str, reason: String| Error::ToolTable {
            file: file.to_string(),
            line,
            text: word.to_string(),
            reason,
        };
        let mut tool = Tool {
            comment: comment.to_string(),
            ..Tool::default()
        };
        let mut number: Option<u32> = None;
        for word in body.split_whitespace() {
            let mut chars = word.chars();
            let letter = chars.next().map(|c| c.to_ascii_uppercase());
            let value = chars.as_str();
            let real = || -> Result<f64, Error> {
                value
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        bad(word, "expected a letter followed by a finite number".into())
                    })
            };
            let whole = || -> Result<u32, Error> {
                value.parse::<u32>().map_err(|_| {
                    bad(
                        word,
                        "expected a letter followed by a whole number ≥ 0".into(),
                    )
                })
            };
            match letter {
                Some('T') => number = Some(whole()?),
                Some('P') => tool.pocket = whole()?,
                Some('X') => tool.offset[0] = real()?,
                Some('Y') => tool.offset[1] = real()?,
                Some('Z') => tool.offset[2] = real()?,
                Some('A') => tool.offset[3] = real()?,
                Some('B') => tool.offset[4] = real()?,
                Some('C') => tool.offset[5] = real()?,
                Some('U' | 'V' | 'W') => {
                    real()?;
                }
                Some('D') => tool.diameter = real()?,
                Some('I') => tool.front_angle_deg = real()?,
                Some('J') => tool.back_angle_deg = real()?,
                Some('Q') => {
                    tool.orientation = value
                        .parse()
                        .map_err(|_| bad(word, "expected Q followed by a whole number".into()))?;
                }
                Some(c) if c.is_ascii_digit() || c == '-' => {
                    return Err(bad(
                        word,
                        "old-style tool table line (numbers only) is not supported: write T<tool> P<pocket> Z<length> …".into(),
                    ));
                }
                _ => {
                    return Err(bad(
                        word,
                        "unknown word (expected T P X Y Z A B C U V W D I J Q)".into(),
                    ));
                }
            }
        }
        let Some(t) = number else {
            return Err(bad(
                body.trim(),
                "tool line without a T<tool number> word".into(),
            ));
        };
        if let Some(first) = seen.insert(t, line) {
            return Err(bad(
                body.trim(),
                format!("tool {t} is listed twice (first on line {first})"),
            ));
        }
        table.tools.insert(t, tool);
    }
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameter_file_reads_linuxcnc_format() {
        // Format as LinuxCNC writes it (`%d\t%f`).
        let t = parse_parameter_file("5161\t0.000000\n5220\t2.000000\n\n5241\t10.5\n", "a.var")
            .unwrap();
        assert_eq!(t.get(5220), 2.0);
        assert_eq!(t.get(5241), 10.5);
        assert_eq!(t.get(5242), 0.0);
    }

    #[test]
    fn parameter_file_errors_name_file_and_line() {
        let cases = [
            ("5221 1\n5220 1\n", 2, "increase"),
            ("5221 x\n", 1, "finite"),
            ("9999 1\n", 1, "1..=5601"),
            ("5221\n", 1, "expected"),
        ];
        for (text, line, needle) in cases {
            match parse_parameter_file(text, "p.var") {
                Err(Error::ParameterFile {
                    file,
                    line: l,
                    reason,
                    ..
                }) => {
                    assert_eq!(file, "p.var");
                    assert_eq!(l, line, "{text}");
                    assert!(reason.contains(needle), "{reason}");
                }
                other => panic!("{text}: {other:?}"),
            }
        }
    }

    #[test]
    fn tool_table_reads_linuxcnc_format() {
        let t = parse_tool_table(
            "T1 P1 Z12.5 D6 ;first tool\nt2 p2 x1 z-3.25 q3\n\n",
            "tool.tbl",
        )
        .unwrap();
        assert_eq!(t.tools[&1].offset[2], 12.5);
        assert_eq!(t.tools[&1].diameter, 6.0);
        assert_eq!(t.tools[&1].comment, "first tool");
        assert_eq!(t.tools[&2].offset[0], 1.0);
        assert_eq!(t.tools[&2].orientation, 3);
    }

    #[test]
    fn tool_table_errors_name_file_and_line() {
        let cases = [
            ("T1 P1 Z1\nT1 P2 Z2\n", 2, "twice"),
            ("T1 Zabc\n", 1, "finite"),
            ("P1 Z1\n", 1, "T<tool"),
            ("T1 E5\n", 1, "unknown"),
            ("1 1 0.5 0.25\n", 1, "old-style"),
        ];
        for (text, line, needle) in cases {
            match parse_tool_table(text, "t.tbl") {
                Err(Error::ToolTable {
                    file,
                    line: l,
                    reason,
                    ..
                }) => {
                    assert_eq!(file, "t.tbl");
                    assert_eq!(l, line, "{text}");
                    assert!(reason.contains(needle), "{reason}");
                }
                other => panic!("{text}: {other:?}"),
            }
        }
    }
}
