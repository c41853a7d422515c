//! Output files: every file is written to a temporary file in its destination folder and renamed
//! into place, so a reader (or a run that is killed midway) sees either the old file or the
//! complete new one, never a half-written one.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// Writes `bytes` to `path` atomically (temporary file in the same folder, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = parent_dir(path);
    std::fs::create_dir_all(&dir)
        .map_err(|e| Error::io(format!("cannot create folder {}", dir.display()), e))?;
    let mut tmp = temp_file(&dir)?;
    tmp.write_all(bytes)
        .and_then(|_| tmp.as_file().sync_all())
        .map_err(|e| Error::io(format!("cannot write {}", path.display()), e))?;
    persist(tmp, path)
}

/// A temporary file in `dir`, readable by all (0644) as results are, to be renamed into place
/// by [`persist`].
pub(crate) fn temp_file(dir: &Path) -> Result<tempfile::NamedTempFile> {
    let mut builder = tempfile::Builder::new();
    builder.prefix(".vcnc-").suffix(".tmp");
    // Temporary files are private (0600) by default; results are ordinary files.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    builder.tempfile_in(dir).map_err(|e| {
        Error::io(
            format!("cannot create a temporary file in {}", dir.display()),
            e,
        )
    })
}

/// Renames a finished temporary file to `path` (after the test hook [`fail_point`]).
pub(crate) fn persist(tmp: tempfile::NamedTempFile, path: &Path) -> Result<()> {
    fail_point(path)?;
    tmp.persist(path).map_err(|e| {
        Error::io(
            format!("cannot move the new {} into place", path.display()),
            e.error,
        )
    })?;
    Ok(())
}

/// Pretty JSON of a summary, keys sorted at every level (the contract's layout), written
/// atomically.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let text = sorted_json(value).map_err(|e| Error::Encode {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    write_atomic(path, text.as_bytes())
}

/// Pretty JSON, keys sorted at every level, ending in a newline (through `serde_json::Value`,
/// whose maps keep their keys sorted).
fn sorted_json(value: &impl serde::Serialize) -> serde_json::Result<String> {
    let value = serde_json::to_value(value)?;
    let mut text = serde_json::to_string_pretty(&value)?;
    text.push('\n');
    Ok(text)
}

/// Pretty JSON of a value as the command line prints it (`trace info --json`): as it
/// serialises, ending in a newline.
pub fn json_text(value: &impl serde::Serialize) -> Result<String> {
    let mut text = serde_json::to_string_pretty(value).map_err(|e| Error::Encode {
        path: PathBuf::from("<standard output>"),
        message: e.to_string(),
    })?;
    text.push('\n');
    Ok(text)
}

/// A CSV table of numeric columns, built in memory and written atomically.
pub fn write_csv(path: &Path, header: &[String], columns: &[&[f64]]) -> Result<()> {
    let encode = |message: String| Error::Encode {
        path: path.to_path_buf(),
        message,
    };
    let rows = columns.iter().map(|c| c.len()).max().unwrap_or(0);
    let mut w =
        csv::WriterBuilder::new().from_writer(Vec::with_capacity(rows * columns.len() * 12));
    w.write_record(header).map_err(|e| encode(e.to_string()))?;
    let mut record: Vec<String> = Vec::with_capacity(columns.len());
    for k in 0..rows {
        record.clear();
        for c in columns {
            record.push(c.get(k).map(|v| format_num(*v)).unwrap_or_default());
        }
        w.write_record(&record).map_err(|e| encode(e.to_string()))?;
    }
    let bytes = w.into_inner().map_err(|e| encode(e.to_string()))?;
    write_atomic(path, &bytes)
}

pub use vcnc_pipeline::format_num;

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Test hook: when `VCNC_FAIL_WRITE` names this file's name, fail after the temporary file is
/// written and before the rename, as a crash or full disk would. Lets the end-to-end tests check
/// that an interrupted run leaves the previous file intact.
pub fn fail_point(path: &Path) -> Result<()> {
    if let Ok(name) = std::env::var("VCNC_FAIL_WRITE")
        && path
            .file_name()
            .is_some_and(|f| f.to_string_lossy() == name)
    {
        return Err(Error::InjectedFailure {
            path: path.to_path_buf(),
        });
    }
    Ok(())
}

/// Creates the output folder.
pub fn ensure_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::io(format!("cannot create output folder {}", dir.display()), e))
}
