//! `report.html` in a real browser: the report the gallery builds (every figure type) is
//! opened in Debian's headless Chromium and checked by `support/chromium.rs` (self-contained,
//! every figure laid out with a real size, screenshots not blank, every figure drawn and
//! coloured). Chromium is installed by `tests/ensure-chromium.sh` when missing; the test fails,
//! never skips, when it cannot be.

#[path = "../examples/gallery.rs"]
mod gallery;

#[path = "support/chromium.rs"]
mod chromium;

use std::path::Path;

#[test]
fn report_renders_in_headless_chromium_with_every_figure() {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ensure-chromium.sh");
    let exe = chromium::ensure_chromium(&script);
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    let g = gallery::build_gallery(&dir).expect("gallery builds");
    let names: Vec<String> = g.figures.iter().map(|(f, _)| f.clone()).collect();
    chromium::check_report(
        &exe,
        &dir.join(vcnc_report::REPORT_FILE),
        tmp.path(),
        &names,
        chromium::MAX_SHOT_PX,
    );
}
