//! Numeric columns of a CSV file with a header row (`#` comment lines skipped): the input of
//! `vcnc kinematics` and the simple `t, xr, x` trace layout.

use std::path::Path;

use crate::Error;

/// Reads the columns `names` (matched exactly, else case-insensitively) of the CSV file at
/// `path`; every value must be a finite number. `hint` is appended to a missing-column error
/// (how to choose other columns).
pub fn read_columns(path: &Path, names: &[&str], hint: &str) -> Result<Vec<Vec<f64>>, Error> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| Error::Io {
        file: file.clone(),
        message: e.to_string(),
    })?;
    let table_error = |line: u64, message: String| Error::Table {
        file: file.clone(),
        line,
        message,
    };
    let mut rdr = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(false)
        .from_reader(bytes.as_slice());
    let header = rdr
        .headers()
        .map_err(|e| table_error(1, format!("cannot read the header row: {e}")))?
        .clone();
    let idx: Vec<usize> = names
        .iter()
        .map(|name| {
            header
                .iter()
                .position(|h| h == *name)
                .or_else(|| header.iter().position(|h| h.eq_ignore_ascii_case(name)))
                .ok_or_else(|| Error::MissingColumn {
                    file: file.to_string(),
                    column: name.to_string(),
                    header: header.iter().collect::<Vec<_>>().join(", "),
                    hint: hint.to_string(),
                })
        })
        .collect::<Result<_, _>>()?;
    let mut out: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    for (row, rec) in rdr.records().enumerate() {
        let rec =
            rec.map_err(|e| table_error(e.position().map_or(0, |p| p.line()), e.to_string()))?;
        let line = rec.position().map_or(row as u64 + 2, |p| p.line());
        for (i, &c) in idx.iter().enumerate() {
            let s = rec.get(c).unwrap_or("");
            let v: f64 = s.parse().map_err(|_| {
                table_error(
                    line,
                    format!("column '{}': '{s}' is not a number", names[i]),
                )
            })?;
            if !v.is_finite() {
                return Err(table_error(
                    line,
                    format!("column '{}' is {s}: not a finite number", names[i]),
                ));
            }
            out[i].push(v);
        }
    }
    Ok(out)
}
