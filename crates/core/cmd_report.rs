//! `vcnc report DIR`: rebuilds `report.html` from the folder's own files (manifest, summary,
//! figures), e.g. after editing a caption in `manifest.json` or copying the folder elsewhere.

use std::path::Path;

use anyhow::Result;
use vcnc_report::Manifest;

use crate::{Ctx, bad_input};

/// `vcnc report DIR`. A folder without a readable, valid `manifest.json`, or whose manifest
/// names a summary or figure it does not hold, is bad input (exit 2; the message names the
/// file); failing to write the page is a runtime failure (exit 1).
pub fn report(dir: &Path, ctx: &Ctx) -> Result<()> {
    let manifest = Manifest::read(dir).map_err(|e| bad_input(e.to_string()))?;
    // Read everything the page needs first, so that a missing figure is reported as the bad
    // input it is and not as a failed write.
    let html =
        vcnc_report::report::report_html(dir, &manifest).map_err(|e| bad_input(e.to_string()))?;
    let path = dir.join(vcnc_report::REPORT_FILE);
    crate::output::write_atomic(&path, html.as_bytes())?;
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
