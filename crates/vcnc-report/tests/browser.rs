//! `report.html` in a real browser: Debian's headless Chromium opens the report built by the
//! gallery (every figure type), and the test checks that
//! 1. the page needs nothing from outside (no script, no external reference),
//! 2. every figure of the manifest is in the laid-out page with a real size (the DOM as
//!    Chromium laid it out, read back with `--dump-dom` from a copy of the page that carries a
//!    measuring script; the report itself has none), and
//! 3. the screenshot is not blank, and inside every figure's box there are drawn pixels, some
//!    of them coloured (curves, colour maps): the figures rendered, not just took up space.
//!
//! Chromium is installed by `tests/ensure-chromium.sh` when missing (apt-get; needs root and
//! the Debian archive). If it cannot be installed the test FAILS with the script's message: it
//! never skips silently.

#[path = "../examples/gallery.rs"]
mod gallery;

use std::path::{Path, PathBuf};
use std::process::Command;

fn ensure_chromium() -> PathBuf {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ensure-chromium.sh");
    let t0 = std::time::Instant::now();
    let out = Command::new("bash")
        .arg(&script)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", script.display()));
    assert!(
        out.status.success(),
        "the browser test needs Debian's chromium and could not install it ({}):\n{}{}",
        script.display(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let log = String::from_utf8_lossy(&out.stderr);
    if !log.trim().is_empty() {
        eprintln!("{} ({:.0} s)", log.trim(), t0.elapsed().as_secs_f64());
    }
    PathBuf::from("chromium")
}

/// Runs headless Chromium on `page` with a fresh profile; returns stdout.
fn chromium(exe: &Path, profile: &Path, extra: &[String], page: &Path) -> Vec<u8> {
    let mut cmd = Command::new(exe);
    cmd.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-extensions",
        "--hide-scrollbars",
        "--force-device-scale-factor=1",
        "--force-color-profile=srgb",
    ])
    .arg(format!("--user-data-dir={}", profile.display()))
    .args(extra)
    .arg(format!("file://{}", page.display()));
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("cannot start chromium: {e}"));
    assert!(
        out.status.success(),
        "chromium failed on {}: {}",
        page.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// Measures, in the laid-out page, every inline figure: position, size, number of elements.
const MEASURE: &str = r#"<script>
(function () {
  var out = {height: Math.ceil(document.documentElement.scrollHeight), figures: []};
  var figs = document.querySelectorAll('figure > svg');
  for (var i = 0; i < figs.length; i++) {
    var r = figs[i].getBoundingClientRect();
    out.figures.push({x: r.left + window.scrollX, y: r.top + window.scrollY,
                      w: r.width, h: r.height, elements: figs[i].querySelectorAll('*').length});
  }
  var pre = document.createElement('pre');
  pre.id = 'vcnc-check';
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
})();
</script>"#;

#[derive(Debug, serde::Deserialize)]
struct Measured {
    height: f64,
    figures: Vec<Box_>,
}

#[derive(Debug, serde::Deserialize)]
struct Box_ {
    x: f64,
    y: f64,
    w: f64,
    h: f64,
    elements: usize,
}

#[test]
fn report_renders_in_headless_chromium_with_every_figure() {
    let exe = ensure_chromium();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    let g = gallery::build_gallery(&dir).expect("gallery builds");
    let report = dir.join(vcnc_report::REPORT_FILE);
    let html = std::fs::read_to_string(&report).unwrap();

    // 1. Self-contained: no script, no stylesheet link, no external reference of any kind.
    assert!(
        !html.contains("<script"),
        "the report must not need JavaScript"
    );
    assert!(
        !html.contains("<link"),
        "the report must not load stylesheets"
    );
    let external = html
        .match_indices("http")
        .filter(|(i, _)| !html[*i..].starts_with("http://www.w3.org/2000/svg"))
        .count();
    assert_eq!(external, 0, "the report must not reference the network");
    assert!(!html.contains("src="), "no external images or frames");

    // 2. Every figure laid out with a real size.
    let check = dir.join("report-check.html");
    std::fs::write(
        &check,
        html.replace("</body>", &format!("{MEASURE}</body>")),
    )
    .unwrap();
    let dom = chromium(
        &exe,
        &tmp.path().join("profile-dom"),
        &["--dump-dom".into(), "--window-size=1200,900".into()],
        &check,
    );
    let dom = String::from_utf8_lossy(&dom);
    let start = dom
        .find("<pre id=\"vcnc-check\">")
        .expect("the measuring script ran and wrote its result")
        + "<pre id=\"vcnc-check\">".len();
    let end = start + dom[start..].find("</pre>").unwrap();
    let m: Measured = serde_json::from_str(&dom[start..end].replace("&quot;", "\"")).unwrap();
    assert_eq!(
        m.figures.len(),
        g.figures.len(),
        "every manifest figure is in the page"
    );
    for (f, (name, _)) in m.figures.iter().zip(&g.figures) {
        assert!(
            f.w > 400.0 && f.h > 150.0,
            "{name} laid out at {} × {} px",
            f.w,
            f.h
        );
        assert!(
            f.elements > 20,
            "{name} has only {} SVG elements",
            f.elements
        );
    }

    // 3. The screenshot of the whole page (no script) is not blank, nor is any figure.
    let height = (m.height.ceil() as u32).clamp(600, 16_000);
    let shot = tmp.path().join("report.png");
    chromium(
        &exe,
        &tmp.path().join("profile-shot"),
        &[
            format!("--window-size=1200,{height}"),
            format!("--screenshot={}", shot.display()),
        ],
        &report,
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let (w, h) = (info.width as usize, info.height as usize);
    let ch = info.color_type.samples();
    assert!(ch >= 3, "screenshot is RGB(A)");
    let px = |x: usize, y: usize| {
        let i = (y * w + x) * ch;
        (buf[i], buf[i + 1], buf[i + 2])
    };
    let non_white = |(r, g, b): (u8, u8, u8)| r < 235 || g < 235 || b < 235;
    let coloured = |(r, g, b): (u8, u8, u8)| {
        let (hi, lo) = (r.max(g).max(b), r.min(g).min(b));
        hi - lo > 60
    };
    let total = (0..h)
        .step_by(2)
        .flat_map(|y| (0..w).step_by(2).map(move |x| (x, y)))
        .filter(|&(x, y)| non_white(px(x, y)))
        .count();
    let frac = total as f64 / ((w / 2) * (h / 2)) as f64;
    assert!(
        frac > 0.02,
        "the screenshot is (nearly) blank: {:.2} % drawn",
        100.0 * frac
    );
    for (f, (name, _)) in m.figures.iter().zip(&g.figures) {
        let (x0, y0) = (f.x.max(0.0) as usize, f.y.max(0.0) as usize);
        let (x1, y1) = (((f.x + f.w) as usize).min(w), ((f.y + f.h) as usize).min(h));
        assert!(x1 > x0 && y1 > y0, "{name} lies outside the screenshot");
        let (mut drawn, mut colour, mut n) = (0usize, 0usize, 0usize);
        for y in (y0..y1).step_by(2) {
            for x in (x0..x1).step_by(2) {
                let p = px(x, y);
                n += 1;
                drawn += usize::from(non_white(p));
                colour += usize::from(coloured(p));
            }
        }
        let (df, cf) = (drawn as f64 / n as f64, colour as f64 / n as f64);
        assert!(
            df > 0.03,
            "{name}: only {:.2} % of its box is drawn",
            100.0 * df
        );
        assert!(
            cf > 0.001,
            "{name}: no coloured pixel (curves or colour map missing)"
        );
    }
}
