//! What a run was, for its `report.html`. Every computing command fills a [`RunReport`] — the
//! command line, the vcnc version, the inputs, tables, figures with captions, warnings and the
//! other files of the folder — and finishes it, which writes `manifest.json` and builds
//! `report.html` with vcnc-report. `vcnc report DIR` rebuilds the page from the folder alone.

use std::path::{Path, PathBuf};

use vcnc_report::report::report_html;
use vcnc_report::{FigureEntry, FileEntry, Input, MANIFEST_FILE, Manifest, Table};

pub use vcnc_report::REPORT_FILE;

use crate::files::write_atomic;
use crate::{Error, Result};

/// The summary every computing command writes; the report shows it as tables.
const SUMMARY_FILE: &str = "summary.json";

/// The manifest of one output folder, filled while the command runs.
pub struct RunReport {
    dir: PathBuf,
    /// What `manifest.json` will hold.
    pub manifest: Manifest,
}

impl RunReport {
    /// A report of the folder `dir` with this title; the command line and the version are this
    /// process's.
    pub fn new(dir: &Path, title: impl Into<String>) -> RunReport {
        RunReport {
            dir: dir.to_path_buf(),
            manifest: Manifest::new(title, command_line(), version()),
        }
    }

    /// The output folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// One input of the run (machine, program, models, an option), in the order to show.
    pub fn input(&mut self, name: &str, value: impl Into<String>) {
        self.manifest.inputs.push(Input {
            name: name.to_string(),
            value: value.into(),
        });
    }

    /// A table shown before the summary file's own tables (units in the header).
    pub fn table(&mut self, title: &str, header: &[&str], rows: Vec<Vec<String>>, note: &str) {
        self.manifest.tables.push(Table {
            title: title.to_string(),
            header: header.iter().map(|h| h.to_string()).collect(),
            rows,
            note: note.to_string(),
        });
    }

    /// Saves a figure as `DIR/file` and lists it under `section` with its caption. A figure
    /// with nothing to draw (a program that moves no axis, a sweep without a result) is not an
    /// error of the run: the report says why it is missing instead. Any other error of the
    /// figure builder is.
    pub fn figure(
        &mut self,
        file: &str,
        fig: Result<vcnc_report::Figure, vcnc_report::Error>,
        caption: &str,
        section: &str,
    ) -> Result<()> {
        match fig {
            Ok(fig) => {
                write_atomic(&self.dir.join(file), fig.svg.as_bytes())?;
                self.manifest.figures.push(FigureEntry {
                    file: file.to_string(),
                    caption: caption.to_string(),
                    section: section.to_string(),
                });
                Ok(())
            }
            Err(e @ vcnc_report::Error::Empty { .. }) => {
                self.manifest
                    .warnings
                    .push(format!("{file} not drawn: {e}"));
                Ok(())
            }
            Err(source) => Err(Error::Draw {
                file: file.to_string(),
                source,
            }),
        }
    }

    /// Another file of the folder worth naming.
    pub fn file(&mut self, file: &str, description: &str) {
        self.manifest.files.push(FileEntry {
            file: file.to_string(),
            description: description.to_string(),
        });
    }

    /// Warnings of the run, as printed.
    pub fn warnings(&mut self, warnings: &[String]) {
        self.manifest.warnings.extend(warnings.iter().cloned());
    }

    /// The figures, warnings and report of a sub-folder's run (the demo's `identify/`), listed
    /// here with the sub-folder's relative path in front of their files.
    pub fn include(&mut self, sub: &RunReport, prefix: &str) {
        for f in &sub.manifest.figures {
            self.manifest.figures.push(FigureEntry {
                file: format!("{prefix}/{}", f.file),
                ..f.clone()
            });
        }
        self.manifest.warnings.extend(
            sub.manifest
                .warnings
                .iter()
                .map(|w| format!("{prefix}: {w}")),
        );
    }

    /// Writes `manifest.json` (pointing at `summary.json` when the folder has one) and builds
    /// `report.html`.
    pub fn finish(&mut self) -> Result<()> {
        if self.dir.join(SUMMARY_FILE).is_file() {
            self.manifest.summary = Some(SUMMARY_FILE.to_string());
        }
        let path = self.dir.join(MANIFEST_FILE);
        let mut text = serde_json::to_string_pretty(&self.manifest).map_err(|e| Error::Encode {
            path: path.clone(),
            message: e.to_string(),
        })?;
        text.push('\n');
        write_atomic(&path, text.as_bytes())?;
        write_report(&self.dir, &self.manifest)?;
        Ok(())
    }
}

/// Builds `DIR/report.html` from the folder's manifest, summary and figures; returns its path.
/// Errors reading them come back as vcnc-report's errors (they name the file); writing the page
/// is an atomic write.
fn write_report(dir: &Path, manifest: &Manifest) -> Result<PathBuf> {
    let html = report_html(dir, manifest)?;
    let path = dir.join(REPORT_FILE);
    write_atomic(&path, html.as_bytes())?;
    Ok(path)
}

/// `vcnc report DIR`: rebuilds `report.html` from the folder's own files (manifest, summary,
/// figures), e.g. after editing a caption in `manifest.json` or copying the folder elsewhere.
/// A folder without a readable, valid manifest, or whose manifest names a summary or figure
/// it does not hold, is bad input ([`Error::Folder`]); failing to write the page is a runtime
/// failure. Returns the manifest and the page's path.
pub fn rebuild(dir: &Path) -> Result<(Manifest, PathBuf)> {
    let manifest = Manifest::read(dir).map_err(Error::Folder)?;
    // Read everything the page needs first, so that a missing figure is reported as the bad
    // input it is and not as a failed write.
    let html = report_html(dir, &manifest).map_err(Error::Folder)?;
    let path = dir.join(REPORT_FILE);
    write_atomic(&path, html.as_bytes())?;
    Ok((manifest, path))
}

/// The vcnc version shown in reports.
pub fn version() -> String {
    env!("CARGO_PKG_VERSION").to_string()
}

/// This process's command line as a shell would take it back: `vcnc` and the arguments, each
/// quoted when it holds anything but letters, digits and `-_.,/:=+@%^`.
pub fn command_line() -> String {
    let mut words = vec!["vcnc".to_string()];
    words.extend(
        std::env::args_os()
            .skip(1)
            .map(|a| shell_word(&a.to_string_lossy())),
    );
    words.join(" ")
}

fn shell_word(s: &str) -> String {
    let plain = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.,/:=+@%^".contains(c));
    if plain {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shell_words_are_quoted_only_when_needed() {
        assert_eq!(
            shell_word("axes.X.controller.vff=0.3:0.7:5"),
            "axes.X.controller.vff=0.3:0.7:5"
        );
        assert_eq!(shell_word("my dir"), "'my dir'");
        assert_eq!(shell_word("it's"), r"'it'\''s'");
        assert_eq!(shell_word(""), "''");
    }
}
