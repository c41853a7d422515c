//! `report.html` in a real browser: Debian's headless Chromium opens a report and the checks
//! are that
//! 1. the page needs nothing from outside (no script, no external reference),
//! 2. every figure is in the laid-out page with a real size (the DOM as Chromium laid it out,
//!    read back with `--dump-dom` from a copy of the page that carries a measuring script; the
//!    report itself has none), and
//! 3. the screenshot is not blank, and inside every figure's box there are drawn pixels, some
//!    of them coloured (curves, colour maps): the figures rendered, not just took up space.
//!
//! A page taller than one screenshot (at most 16 000 px) is checked in passes: the first pass is the
//! report itself; each further pass is a copy whose figures already checked are hidden (one
//! injected CSS rule), so the next ones move up into the screenshot.
//!
//! Shared by vcnc-report's own browser test (the gallery of every figure type) and the binary's
//! end-to-end test (the demo's report), which include this file with `#[path]`. Chromium is
//! installed by `ensure-chromium.sh` when missing (apt-get; needs root and the Debian archive);
//! if it cannot be installed the test FAILS with the script's message: it never skips silently.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs `ensure-chromium.sh` (the script at `script`) and returns the browser's command name.
/// Prints how long an installation took, when there was one.
pub fn ensure_chromium(script: &Path) -> PathBuf {
    let t0 = std::time::Instant::now();
    let out = Command::new("bash")
        .arg(script)
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

#[derive(Debug, Clone, serde::Deserialize)]
struct Box_ {
    x: f64,
    y: f64,
    w: f64,
    h: f64,
    elements: usize,
}

/// Tallest screenshot Chromium is asked for, px.
pub const MAX_SHOT_PX: u32 = 16_000;

/// The laid-out page `html` (written beside the report as `name` so that relative references
/// would resolve as in the report): page height and every figure's box.
fn measure(exe: &Path, work: &Path, dir: &Path, html: &str, name: &str) -> Measured {
    let check = dir.join(name);
    std::fs::write(
        &check,
        html.replace("</body>", &format!("{MEASURE}</body>")),
    )
    .unwrap();
    let dom = chromium(
        exe,
        &work.join(format!("profile-dom-{name}")),
        &["--dump-dom".into(), "--window-size=1200,900".into()],
        &check,
    );
    std::fs::remove_file(&check).ok();
    let dom = String::from_utf8_lossy(&dom);
    let start = dom
        .find("<pre id=\"vcnc-check\">")
        .expect("the measuring script ran and wrote its result")
        + "<pre id=\"vcnc-check\">".len();
    let end = start + dom[start..].find("</pre>").unwrap();
    serde_json::from_str(&dom[start..end].replace("&quot;", "\"")).unwrap()
}

/// A screenshot: width, height, samples per pixel, pixels.
struct Shot {
    w: usize,
    h: usize,
    ch: usize,
    buf: Vec<u8>,
}

impl Shot {
    fn px(&self, x: usize, y: usize) -> (u8, u8, u8) {
        let i = (y * self.w + x) * self.ch;
        (self.buf[i], self.buf[i + 1], self.buf[i + 2])
    }
}

fn screenshot(exe: &Path, work: &Path, page: &Path, height: u32, tag: &str) -> Shot {
    let shot = work.join(format!("shot-{tag}.png"));
    chromium(
        exe,
        &work.join(format!("profile-shot-{tag}")),
        &[
            format!("--window-size=1200,{height}"),
            format!("--screenshot={}", shot.display()),
        ],
        page,
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let ch = info.color_type.samples();
    assert!(ch >= 3, "screenshot is RGB(A)");
    Shot {
        w: info.width as usize,
        h: info.height as usize,
        ch,
        buf,
    }
}

fn non_white((r, g, b): (u8, u8, u8)) -> bool {
    r < 235 || g < 235 || b < 235
}

fn coloured((r, g, b): (u8, u8, u8)) -> bool {
    let (hi, lo) = (r.max(g).max(b), r.min(g).min(b));
    hi - lo > 60
}

/// Checks `report` (a `report.html` whose figures are named, in order, by `names`) in headless
/// Chromium, with screenshots at most `shot_px` tall (≤ [`MAX_SHOT_PX`]); `work` is a scratch
/// folder. Returns the number of screenshot passes.
pub fn check_report(
    exe: &Path,
    report: &Path,
    work: &Path,
    names: &[String],
    shot_px: u32,
) -> usize {
    let shot_px = shot_px.clamp(600, MAX_SHOT_PX);
    let html = std::fs::read_to_string(report).unwrap();
    let dir = report.parent().unwrap();

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
    let m = measure(exe, work, dir, &html, "report-check.html");
    assert_eq!(
        m.figures.len(),
        names.len(),
        "every manifest figure is in the page"
    );
    for (f, name) in m.figures.iter().zip(names) {
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

    // 3. Screenshots: the page is not blank, nor is any figure. Pass 0 is the report itself.
    let mut first = 0;
    let mut pass = 0;
    while first < names.len() {
        let (page, boxes, height) = if first == 0 {
            (report.to_path_buf(), m.figures.clone(), m.height)
        } else {
            let hide: Vec<String> = (0..first).map(|k| format!("#figure-{k}")).collect();
            let copy = html.replace(
                "</head>",
                &format!("<style>{}{{display:none}}</style></head>", hide.join(",")),
            );
            let name = format!("report-pass-{pass}.html");
            let mm = measure(exe, work, dir, &copy, &format!("check-{name}"));
            let page = dir.join(&name);
            std::fs::write(&page, &copy).unwrap();
            (page, mm.figures, mm.height)
        };
        let height = (height.ceil() as u32).clamp(600, shot_px);
        let shot = screenshot(exe, work, &page, height, &pass.to_string());
        if first == 0 {
            let total = (0..shot.h)
                .step_by(2)
                .flat_map(|y| (0..shot.w).step_by(2).map(move |x| (x, y)))
                .filter(|&(x, y)| non_white(shot.px(x, y)))
                .count();
            let frac = total as f64 / ((shot.w / 2) * (shot.h / 2)) as f64;
            assert!(
                frac > 0.02,
                "the screenshot is (nearly) blank: {:.2} % drawn",
                100.0 * frac
            );
        } else {
            std::fs::remove_file(&page).ok();
        }
        let before = first;
        for (k, f) in boxes.iter().enumerate().skip(first) {
            let name = &names[k];
            if f.y + f.h > shot.h as f64 {
                break;
            }
            let (x0, y0) = (f.x.max(0.0) as usize, f.y.max(0.0) as usize);
            let (x1, y1) = (
                ((f.x + f.w) as usize).min(shot.w),
                ((f.y + f.h) as usize).min(shot.h),
            );
            assert!(x1 > x0 && y1 > y0, "{name} lies outside the screenshot");
            let (mut drawn, mut colour, mut n) = (0usize, 0usize, 0usize);
            for y in (y0..y1).step_by(2) {
                for x in (x0..x1).step_by(2) {
                    let p = shot.px(x, y);
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
            first = k + 1;
        }
        assert!(
            first > before,
            "{} does not fit in a {shot_px} px screenshot",
            names[before]
        );
        pass += 1;
    }
    pass
}
