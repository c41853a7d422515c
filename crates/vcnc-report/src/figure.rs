//! A finished figure (an SVG document) and atomic file writing.

use std::io::Write;
use std::path::Path;

use crate::error::Error;

/// A finished figure: a standalone SVG document.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Title (also the SVG's `<title>`).
    pub title: String,
    /// The SVG document.
    pub svg: String,
    /// Width, px.
    pub width_px: f64,
    /// Height, px.
    pub height_px: f64,
}

impl Figure {
    /// Writes the SVG to `path` atomically.
    pub fn save(&self, path: &Path) -> Result<(), Error> {
        write_atomic(path, self.svg.as_bytes())
    }
}

/// Writes `bytes` to `path` through a temporary file in the same folder renamed into place, so
/// a reader never sees a half-written file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    write_atomic_with(path, |w| w.write_all(bytes).map_err(|e| Error::io(path, e)))
}

/// [`write_atomic`] with the content written by `fill` into a buffered writer (a large file
/// need not exist in memory first).
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> Result<(), Error>,
) -> Result<(), Error> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let mut builder = tempfile::Builder::new();
    builder.prefix(".vcnc-").suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    let tmp = builder.tempfile_in(&dir).map_err(|e| Error::io(&dir, e))?;
    let mut w = std::io::BufWriter::with_capacity(1 << 20, tmp);
    fill(&mut w)?;
    let tmp = w
        .into_inner()
        .map_err(|e| Error::io(path, e.into_error()))?;
    tmp.as_file().sync_all().map_err(|e| Error::io(path, e))?;
    tmp.persist(path).map_err(|e| Error::io(path, e.error))?;
    Ok(())
}
