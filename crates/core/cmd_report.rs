//! `vcnc report DIR`: rebuilds `report.html` from the folder's own files (manifest, summary,
//! figures), e.g. after editing a caption in `manifest.json` or copying the folder elsewhere.

use std::path::Path;

use anyhow::Result;

use crate::Ctx;

/// `vcnc report DIR`. A folder without a readable, valid `manifest.json`, or whose manifest
/// names a summary or figure it does not hold, is bad input (exit 2; the message names the
/// file); failing to write the page is a runtime failure (exit 1).
pub fn report(dir: &Path, ctx: &Ctx) -> Result<()> {
    let (manifest, path) = vcnc_output::report::rebuild(dir)?;
    if !ctx.quiet {
        println!(
            "{}: {} figures -> {}",
            manifest.title,
            manifest.figures.len(),
            path.display()
        );
    }
    Ok(())
}
