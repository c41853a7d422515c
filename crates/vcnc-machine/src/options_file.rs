//! Identifier options as a file of their own, for measured traces (`vcnc identify --trace
//! TRACE.csv --options OPTIONS.toml`). The document is the `[identification.options]` table of
//! a machine file written at the top level: the same keys, the same defaults, unknown keys
//! rejected.
//!
//! ```toml
//! deadband = 2.0               # mm/s
//! seed = 7
//! [bounds]
//! wn_hz = [5.0, 200.0]
//! [prefilter]
//! cutoff_hz = 40.0
//! ```

use std::path::Path;

use vcnc_identify::IdentifyOptions;

use crate::Error;
use crate::locate::{error_offset, line_col, locate_key};

/// Identifier options read from a file, with whether the file sets the keys whose defaults
/// depend on the data: the pole bound `bounds.p_hz` (relaxed for drives without integral action
/// when not set) and `structures` (every structure is tried when not set).
/// (docs/machine-file.md, "One bound rule for machines and traces".)
#[derive(Debug, Clone, PartialEq, Default)]
pub struct OptionsFile {
    /// The options, checked.
    pub options: IdentifyOptions,
    /// True when the file writes `bounds.p_hz`.
    pub sets_p_bounds: bool,
    /// True when the file writes `structures`.
    pub sets_structures: bool,
}

impl OptionsFile {
    /// Reads and checks an options file.
    pub fn load(path: &Path) -> Result<OptionsFile, Error> {
        let (file, src) = crate::read_text(path)?;
        OptionsFile::from_toml_str(&src, &file)
    }

    /// Parses and checks options given as text; `file` names the source in errors.
    pub fn from_toml_str(src: &str, file: &str) -> Result<OptionsFile, Error> {
        let options: IdentifyOptions = toml::from_str(src).map_err(|e| Error::Toml {
            file: file.to_string(),
            at: line_col(src, error_offset(src, e.span(), e.message())),
            message: e.message().trim().to_string(),
        })?;
        if let Err(e) = options.validate() {
            let key = match &e {
                vcnc_identify::Error::InvalidOption { name, .. }
                | vcnc_identify::Error::InvalidBounds { name, .. } => name.to_string(),
                _ => String::new(),
            };
            let path: Vec<&str> = key.split('.').filter(|s| !s.is_empty()).collect();
            return Err(Error::Invalid {
                file: file.to_string(),
                at: locate_key(src, &path),
                key,
                message: e.to_string(),
            });
        }
        let table = src.parse::<toml::Table>().ok();
        let sets_p_bounds = table
            .as_ref()
            .and_then(|t| t.get("bounds")?.get("p_hz").map(|_| ()))
            .is_some();
        let sets_structures = table.as_ref().is_some_and(|t| t.contains_key("structures"));
        Ok(OptionsFile {
            options,
            sets_p_bounds,
            sets_structures,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_file_gives_the_defaults() {
        let o = OptionsFile::from_toml_str("", "o.toml").unwrap();
        assert_eq!(o.options, IdentifyOptions::default());
        assert!(!o.sets_p_bounds);
    }

    #[test]
    fn keys_set_what_they_name() {
        let src =
            "deadband = 2.5\nseed = 9\n[bounds]\np_hz = [0.001, 300.0]\n[pso]\nparticles = 50\n";
        let o = OptionsFile::from_toml_str(src, "o.toml").unwrap();
        assert_eq!(o.options.deadband, 2.5);
        assert_eq!(o.options.seed, 9);
        assert_eq!(o.options.bounds.p_hz, [0.001, 300.0]);
        assert_eq!(o.options.pso.particles, 50);
        assert!(o.sets_p_bounds);
    }

    #[test]
    fn unknown_keys_and_bad_values_name_file_line_and_key() {
        let e = OptionsFile::from_toml_str("deadband = 1.0\ndeadbnd = 2.0\n", "o.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("o.toml:2:1"), "{e}");
        assert!(e.contains("deadbnd"), "{e}");
        let e = OptionsFile::from_toml_str("seed = 1\n[bounds]\nwn_hz = [50.0, 5.0]\n", "o.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("o.toml:3:"), "{e}");
        assert!(e.contains("bounds.wn_hz"), "{e}");
        let e = OptionsFile::from_toml_str("deadband = \"fast\"\n", "o.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("o.toml:1:"), "{e}");
    }
}
