//! `report.html`: one self-contained page per output folder (inline SVG and CSS, no network,
//! no script), built from the folder's files alone so that it can be rebuilt at any time
//! (`vcnc report DIR`).
//!
//! A command writes its figures (SVG), its `summary.json` and a [`Manifest`]
//! (`manifest.json`) that says what the run was (inputs, options, version), which tables to
//! show, which figures in which order with which caption, and every warning. [`build_report`]
//! reads them back and writes `report.html`.

use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::error::Error;
use crate::figure::write_atomic;
use crate::svg::{ID_PREFIX, escape};

/// File name of the manifest in an output folder.
pub const MANIFEST_FILE: &str = "manifest.json";
/// File name of the report in an output folder.
pub const REPORT_FILE: &str = "report.html";
/// Version of the manifest format written by this crate.
pub const MANIFEST_VERSION: u32 = 1;

/// What a run was and what its folder holds; written by every command as `manifest.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Format version ([`MANIFEST_VERSION`]).
    pub manifest_version: u32,
    /// Report title, e.g. "vcnc predict: spiral.ngc on NMV5000".
    pub title: String,
    /// The command line that produced the folder.
    pub command: String,
    /// vcnc version (e.g. "0.1.0 (git abc1234)").
    pub version: String,
    /// The run's inputs: machine, program, models, options … in the order to show.
    #[serde(default)]
    pub inputs: Vec<Input>,
    /// Tables to show before the summary file's own tables.
    #[serde(default)]
    pub tables: Vec<Table>,
    /// Figures, in the order to show.
    #[serde(default)]
    pub figures: Vec<FigureEntry>,
    /// Every warning of the run, as printed.
    #[serde(default)]
    pub warnings: Vec<String>,
    /// Other files of the folder worth naming (CSV, `.vtp`, model files).
    #[serde(default)]
    pub files: Vec<FileEntry>,
    /// The summary JSON file shown as tables (relative to the folder); `None`: none.
    #[serde(default)]
    pub summary: Option<String>,
}

impl Manifest {
    /// An empty manifest of the current version.
    pub fn new(
        title: impl Into<String>,
        command: impl Into<String>,
        version: impl Into<String>,
    ) -> Manifest {
        Manifest {
            manifest_version: MANIFEST_VERSION,
            title: title.into(),
            command: command.into(),
            version: version.into(),
            inputs: Vec::new(),
            tables: Vec::new(),
            figures: Vec::new(),
            warnings: Vec::new(),
            files: Vec::new(),
            summary: None,
        }
    }

    /// Saves `fig` as `DIR/file` and lists it (in call order) under `section` with `caption`.
    pub fn add_figure(
        &mut self,
        dir: &Path,
        file: &str,
        fig: &crate::Figure,
        caption: &str,
        section: &str,
    ) -> Result<(), Error> {
        let path = inside(dir, &dir.join(MANIFEST_FILE), file)?;
        fig.save(&path)?;
        self.figures.push(FigureEntry {
            file: file.to_string(),
            caption: caption.to_string(),
            section: section.to_string(),
        });
        Ok(())
    }

    /// Writes `DIR/manifest.json` atomically.
    pub fn write(&self, dir: &Path) -> Result<(), Error> {
        let path = dir.join(MANIFEST_FILE);
        let mut text = serde_json::to_string_pretty(self).map_err(|e| Error::Json {
            path: path.clone(),
            line: 0,
            column: 0,
            message: e.to_string(),
        })?;
        text.push('\n');
        write_atomic(&path, text.as_bytes())
    }

    /// Reads `DIR/manifest.json`.
    pub fn read(dir: &Path) -> Result<Manifest, Error> {
        let path = dir.join(MANIFEST_FILE);
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let m: Manifest = serde_json::from_str(&text).map_err(|e| json_error(&path, &e))?;
        if m.manifest_version != MANIFEST_VERSION {
            return Err(Error::Json {
                path,
                line: 0,
                column: 0,
                message: format!(
                    "manifest_version {} is not supported (this vcnc reads {MANIFEST_VERSION})",
                    m.manifest_version
                ),
            });
        }
        Ok(m)
    }
}

fn json_error(path: &Path, e: &serde_json::Error) -> Error {
    Error::Json {
        path: path.to_path_buf(),
        line: e.line(),
        column: e.column(),
        message: e.to_string(),
    }
}

/// One input of the run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Input {
    /// What it is: "machine", "program", "models", "seed", "option --lenient" …
    pub name: String,
    /// Its value as shown.
    pub value: String,
}

/// A table of text cells.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    /// Caption.
    pub title: String,
    /// Column headers (units in them: "tip max (µm)").
    pub header: Vec<String>,
    /// Rows, each as long as the header.
    pub rows: Vec<Vec<String>>,
    /// A note under the table, may be empty.
    #[serde(default)]
    pub note: String,
}

/// A figure of the folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FigureEntry {
    /// SVG file, relative to the folder (`identify/frf_X.svg`).
    pub file: String,
    /// Caption: what the figure shows and how to read it.
    pub caption: String,
    /// Section heading it goes under ("Identification", "Contour errors" …).
    #[serde(default)]
    pub section: String,
}

/// Another output file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileEntry {
    /// File, relative to the folder.
    pub file: String,
    /// What it holds.
    pub description: String,
}

const CSS: &str = "
body{font-family:'DejaVu Sans',Helvetica,Arial,sans-serif;color:#111;background:#fff;margin:0;line-height:1.45}
main{max-width:1120px;margin:0 auto;padding:24px 28px 48px}
h1{font-size:1.55em;margin:0 0 4px}h2{font-size:1.25em;margin:34px 0 10px;border-bottom:1px solid #ccc;padding-bottom:3px}
h3{font-size:1.05em;margin:22px 0 8px}
.meta{color:#444;font-size:.92em;margin:0}.meta code{font-size:.95em}
nav{margin:14px 0 0;font-size:.92em}nav a{margin-right:14px;color:#0b5394}
table{border-collapse:collapse;margin:6px 0 4px;font-size:.9em}
th,td{border:1px solid #d4d4d4;padding:3px 9px;text-align:left;vertical-align:top}
th{background:#f3f3f3;font-weight:600}td.n{text-align:right;font-variant-numeric:tabular-nums}
caption{caption-side:top;text-align:left;font-weight:600;padding:4px 0}
.note{color:#444;font-size:.88em;margin:2px 0 12px}
.warnings{background:#fff6e0;border:1px solid #e0b440;border-left:5px solid #e69f00;padding:8px 14px;margin:14px 0}
.warnings ul{margin:4px 0;padding-left:20px}.ok{color:#2d6a2d}
figure{margin:18px 0 30px}figure svg{display:block;max-width:100%;height:auto;border:1px solid #e4e4e4}
figcaption{font-size:.9em;color:#333;margin-top:6px;max-width:960px}
figcaption .file{color:#777;font-family:monospace;font-size:.95em}
code{font-family:'DejaVu Sans Mono',monospace}.scroll{overflow-x:auto}
@media print{nav{display:none}figure{break-inside:avoid}}
";

/// Reads the folder's manifest, summary and figures and writes `DIR/report.html`; returns its
/// path.
pub fn build_report(dir: &Path) -> Result<PathBuf, Error> {
    let manifest = Manifest::read(dir)?;
    let html = report_html(dir, &manifest)?;
    let path = dir.join(REPORT_FILE);
    write_atomic(&path, html.as_bytes())?;
    Ok(path)
}

/// A figure or file name of the manifest must stay inside the folder.
fn inside(dir: &Path, manifest: &Path, file: &str) -> Result<PathBuf, Error> {
    let p = Path::new(file);
    let ok = !file.is_empty()
        && p.components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir));
    if !ok {
        return Err(Error::BadFigure {
            manifest: manifest.to_path_buf(),
            file: file.to_string(),
            problem: "must be a relative path inside the folder".into(),
        });
    }
    Ok(dir.join(p))
}

/// The SVG element of a figure file, ready to inline: prolog dropped, ids made unique.
fn inline_svg(dir: &Path, manifest: &Path, file: &str, k: usize) -> Result<String, Error> {
    let path = inside(dir, manifest, file)?;
    let text = std::fs::read_to_string(&path).map_err(|e| Error::BadFigure {
        manifest: manifest.to_path_buf(),
        file: file.to_string(),
        problem: format!("cannot read {}: {e}", path.display()),
    })?;
    let start = text.find("<svg").ok_or_else(|| Error::BadFigure {
        manifest: manifest.to_path_buf(),
        file: file.to_string(),
        problem: "not an SVG document (no <svg element)".into(),
    })?;
    let end = text.rfind("</svg>").ok_or_else(|| Error::BadFigure {
        manifest: manifest.to_path_buf(),
        file: file.to_string(),
        problem: "not a complete SVG document (no </svg>)".into(),
    })?;
    let svg = &text[start..end + "</svg>".len()];
    if svg.contains("<script") || svg.contains("<foreignObject") {
        return Err(Error::BadFigure {
            manifest: manifest.to_path_buf(),
            file: file.to_string(),
            problem: "holds a script or foreign object; figures must be plain SVG".into(),
        });
    }
    Ok(svg.replace(ID_PREFIX, &format!("fig{k}-")))
}

/// Formats a JSON number for a table: integers as they are, others with four significant
/// digits (and a real minus sign).
fn fmt_number(v: &serde_json::Number) -> String {
    if let Some(i) = v.as_i64() {
        return i.to_string().replace('-', "−");
    }
    let f = v.as_f64().unwrap_or(f64::NAN);
    let a = f.abs();
    let s = if a == 0.0 {
        "0".to_string()
    } else if !(1e-3..1e6).contains(&a) {
        format!("{f:.3e}")
    } else {
        let dec = (3 - a.log10().floor() as i32).max(0) as usize;
        let t = format!("{f:.dec$}");
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        }
    };
    s.replace('-', "−")
}

fn fmt_json(v: &Value) -> (String, bool) {
    match v {
        Value::Null => ("–".into(), false),
        Value::Bool(b) => (if *b { "yes" } else { "no" }.into(), false),
        Value::Number(n) => (fmt_number(n), true),
        Value::String(s) => (s.clone(), false),
        Value::Array(a) if a.len() <= 8 && a.iter().all(|x| !x.is_object() && !x.is_array()) => (
            a.iter()
                .map(|x| fmt_json(x).0)
                .collect::<Vec<_>>()
                .join(", "),
            false,
        ),
        Value::Array(a) => (format!("[{} values]", a.len()), false),
        Value::Object(_) => ("{…}".into(), false),
    }
}

/// Leaves of a JSON value as ("a / b / c", value) pairs, in key order.
fn flatten(prefix: &str, v: &Value, out: &mut Vec<(String, Value)>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                let p = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix} / {k}")
                };
                flatten(&p, x, out);
            }
        }
        _ => out.push((prefix.to_string(), v.clone())),
    }
}

/// Tables of a summary JSON object: scalars of the top level in one table; each object either
/// as a matrix (when its members are objects with the same leaves, e.g. one row per axis) or
/// as a two-column table of its leaves.
fn summary_tables(v: &Value) -> Vec<Table> {
    let mut out = Vec::new();
    let Value::Object(top) = v else {
        return out;
    };
    let scalars: Vec<Vec<String>> = top
        .iter()
        .filter(|(_, x)| !x.is_object())
        .map(|(k, x)| vec![k.clone(), fmt_json(x).0])
        .collect();
    if !scalars.is_empty() {
        out.push(Table {
            title: "run".into(),
            header: vec!["key".into(), "value".into()],
            rows: scalars,
            note: String::new(),
        });
    }
    for (k, x) in top {
        let Value::Object(m) = x else { continue };
        let mut children: Vec<(String, Vec<(String, Value)>)> = m
            .iter()
            .filter(|(_, c)| c.is_object())
            .map(|(ck, c)| {
                let mut leaves = Vec::new();
                flatten("", c, &mut leaves);
                (ck.clone(), leaves)
            })
            .collect();
        // Members named by machine axes go in the canonical order X Y Z A B C.
        let axis = |k: &str| k.parse::<vcnc_axis::AxisName>().ok().map(|a| a.index());
        if children.iter().all(|(k, _)| axis(k).is_some()) {
            children.sort_by_key(|(k, _)| axis(k));
        }
        let same_shape = children.len() == m.len()
            && children.len() > 1
            && children.windows(2).all(|w| {
                w[0].1.len() == w[1].1.len() && w[0].1.iter().zip(&w[1].1).all(|(a, b)| a.0 == b.0)
            });
        if same_shape && children[0].1.len() > children.len() {
            // Many leaves, few members (one column per axis): leaves as rows.
            let mut header = vec![String::new()];
            header.extend(children.iter().map(|(ck, _)| ck.clone()));
            let rows = (0..children[0].1.len())
                .map(|i| {
                    let mut r = vec![children[0].1[i].0.clone()];
                    r.extend(children.iter().map(|(_, leaves)| fmt_json(&leaves[i].1).0));
                    r
                })
                .collect();
            out.push(Table {
                title: k.clone(),
                header,
                rows,
                note: String::new(),
            });
        } else if same_shape {
            let mut header = vec![String::new()];
            header.extend(children[0].1.iter().map(|(p, _)| p.clone()));
            let rows = children
                .iter()
                .map(|(ck, leaves)| {
                    let mut r = vec![ck.clone()];
                    r.extend(leaves.iter().map(|(_, v)| fmt_json(v).0));
                    r
                })
                .collect();
            out.push(Table {
                title: k.clone(),
                header,
                rows,
                note: String::new(),
            });
        } else {
            let mut leaves = Vec::new();
            flatten("", x, &mut leaves);
            out.push(Table {
                title: k.clone(),
                header: vec!["key".into(), "value".into()],
                rows: leaves
                    .iter()
                    .map(|(p, v)| vec![p.clone(), fmt_json(v).0])
                    .collect(),
                note: String::new(),
            });
        }
    }
    out
}

fn looks_numeric(s: &str) -> bool {
    let t = s.trim().trim_start_matches(['−', '-', '+']);
    !t.is_empty()
        && t.chars().next().is_some_and(|c| c.is_ascii_digit())
        && t.parse::<f64>().is_ok()
}

fn html_table(out: &mut String, t: &Table) {
    out.push_str("<div class=\"scroll\"><table>");
    if !t.title.is_empty() {
        let _ = write!(out, "<caption>{}</caption>", escape(&t.title));
    }
    out.push_str("<thead><tr>");
    for h in &t.header {
        let _ = write!(out, "<th>{}</th>", escape(h));
    }
    out.push_str("</tr></thead><tbody>");
    for r in &t.rows {
        out.push_str("<tr>");
        for c in r {
            if looks_numeric(c) {
                let _ = write!(out, "<td class=\"n\">{}</td>", escape(c));
            } else {
                let _ = write!(out, "<td>{}</td>", escape(c));
            }
        }
        out.push_str("</tr>");
    }
    out.push_str("</tbody></table></div>");
    if !t.note.is_empty() {
        let _ = write!(out, "<p class=\"note\">{}</p>", escape(&t.note));
    }
}

/// The report page of a folder and its manifest.
pub fn report_html(dir: &Path, m: &Manifest) -> Result<String, Error> {
    let mpath = dir.join(MANIFEST_FILE);
    let summary = match &m.summary {
        Some(f) => {
            let p = inside(dir, &mpath, f)?;
            let text = std::fs::read_to_string(&p).map_err(|e| Error::io(&p, e))?;
            Some(serde_json::from_str::<Value>(&text).map_err(|e| json_error(&p, &e))?)
        }
        None => None,
    };
    let mut o = String::with_capacity(1 << 20);
    o.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
    o.push_str("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n");
    let _ = writeln!(o, "<title>{}</title>", escape(&m.title));
    let _ = writeln!(o, "<style>{CSS}</style>\n</head>\n<body>\n<main>");
    let _ = writeln!(o, "<h1>{}</h1>", escape(&m.title));
    let _ = writeln!(
        o,
        "<p class=\"meta\">vcnc {} · <code>{}</code></p>",
        escape(&m.version),
        escape(&m.command)
    );
    o.push_str("<nav><a href=\"#inputs\">Inputs</a><a href=\"#warnings\">Warnings</a><a href=\"#summary\">Summary</a><a href=\"#figures\">Figures</a>");
    if !m.files.is_empty() {
        o.push_str("<a href=\"#files\">Files</a>");
    }
    o.push_str("</nav>\n");

    o.push_str("<section id=\"inputs\"><h2>Inputs</h2>");
    let mut inputs = Table {
        title: String::new(),
        header: vec!["input".into(), "value".into()],
        rows: m
            .inputs
            .iter()
            .map(|i| vec![i.name.clone(), i.value.clone()])
            .collect(),
        note: String::new(),
    };
    inputs
        .rows
        .push(vec!["vcnc version".into(), m.version.clone()]);
    html_table(&mut o, &inputs);
    o.push_str("</section>\n");

    o.push_str("<section id=\"warnings\"><h2>Warnings</h2>");
    if m.warnings.is_empty() {
        o.push_str("<p class=\"ok\">The run printed no warning.</p>");
    } else {
        let _ = write!(
            o,
            "<div class=\"warnings\"><strong>{} warning{}</strong><ul>",
            m.warnings.len(),
            if m.warnings.len() == 1 { "" } else { "s" }
        );
        for w in &m.warnings {
            let _ = write!(o, "<li>{}</li>", escape(w));
        }
        o.push_str("</ul></div>");
    }
    o.push_str("</section>\n");

    o.push_str("<section id=\"summary\"><h2>Summary</h2>");
    for t in &m.tables {
        html_table(&mut o, t);
    }
    if let (Some(v), Some(f)) = (&summary, &m.summary) {
        let _ = write!(o, "<h3>{}</h3>", escape(f));
        for t in summary_tables(v) {
            html_table(&mut o, &t);
        }
    }
    o.push_str("</section>\n");

    o.push_str("<section id=\"figures\"><h2>Figures</h2>");
    let mut section = "";
    for (k, f) in m.figures.iter().enumerate() {
        if f.section != section && !f.section.is_empty() {
            let _ = write!(o, "<h3>{}</h3>", escape(&f.section));
        }
        section = &f.section;
        let svg = inline_svg(dir, &mpath, &f.file, k)?;
        let _ = writeln!(
            o,
            "<figure id=\"figure-{k}\">{svg}<figcaption><strong>Figure {}.</strong> {} <span class=\"file\">({})</span></figcaption></figure>",
            k + 1,
            escape(&f.caption),
            escape(&f.file)
        );
    }
    if m.figures.is_empty() {
        o.push_str("<p>This run made no figure.</p>");
    }
    o.push_str("</section>\n");

    if !m.files.is_empty() {
        o.push_str("<section id=\"files\"><h2>Files</h2>");
        let t = Table {
            title: String::new(),
            header: vec!["file".into(), "size".into(), "holds".into()],
            rows: m
                .files
                .iter()
                .map(|f| {
                    let size = inside(dir, &mpath, &f.file)
                        .ok()
                        .and_then(|p| std::fs::metadata(p).ok())
                        .map_or("missing".to_string(), |md| human_size(md.len()));
                    vec![f.file.clone(), size, f.description.clone()]
                })
                .collect(),
            note: String::new(),
        };
        html_table(&mut o, &t);
        o.push_str("</section>\n");
    }
    o.push_str("</main>\n</body>\n</html>\n");
    Ok(o)
}

fn human_size(b: u64) -> String {
    if b < 1024 {
        format!("{b} B")
    } else if b < 1024 * 1024 {
        format!("{:.1} KiB", b as f64 / 1024.0)
    } else {
        format!("{:.1} MiB", b as f64 / (1024.0 * 1024.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_axis_objects_become_one_matrix() {
        let v: Value = serde_json::json!({
            "machine": "M",
            "identification": {
                "X": {"wn": 1.0, "zeta": {"a": 2}},
                "Y": {"wn": 3.5, "zeta": {"a": 4}}
            },
            "contour_um": {"true_max": 450.5698, "true_rms": 202.15}
        });
        let t = summary_tables(&v);
        assert_eq!(t[0].rows, vec![vec!["machine".to_string(), "M".into()]]);
        let id = t.iter().find(|t| t.title == "identification").unwrap();
        assert_eq!(id.header, ["", "wn", "zeta / a"]);
        assert_eq!(id.rows[1], ["Y", "3.5", "4"]);
        let c = t.iter().find(|t| t.title == "contour_um").unwrap();
        assert_eq!(c.rows[0], ["true_max", "450.6"]);
    }

    #[test]
    fn wide_per_axis_objects_are_transposed_and_axes_keep_machine_order() {
        let v: Value = serde_json::json!({
            "id": {
                "Z": {"a": 1, "b": 2, "c": 3, "d": 0},
                "A": {"a": 4, "b": 5, "c": 6, "d": 0},
                "X": {"a": 7, "b": 8, "c": 9, "d": 0}
            }
        });
        let t = summary_tables(&v);
        assert_eq!(t[0].header, ["", "X", "Z", "A"]);
        assert_eq!(t[0].rows[0], ["a", "7", "1", "4"]);
    }

    #[test]
    fn a_missing_or_foreign_figure_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let mut m = Manifest::new("t", "c", "v");
        m.figures.push(FigureEntry {
            file: "gone.svg".into(),
            caption: String::new(),
            section: String::new(),
        });
        m.write(dir.path()).unwrap();
        let e = build_report(dir.path()).unwrap_err();
        assert!(
            matches!(&e, Error::BadFigure { file, .. } if file == "gone.svg"),
            "{e}"
        );
        std::fs::write(
            dir.path().join("gone.svg"),
            "<svg><script>alert(1)</script></svg>",
        )
        .unwrap();
        let e = build_report(dir.path()).unwrap_err();
        assert!(e.to_string().contains("script"), "{e}");
    }

    #[test]
    fn inlined_figures_get_ids_of_their_own() {
        let dir = tempfile::tempdir().unwrap();
        let fig = crate::svg::Svg::new(10.0, 10.0);
        let mut svg = fig;
        let id = svg.clip_rect(0.0, 0.0, 5.0, 5.0);
        svg.open_group_clipped(&id);
        svg.close_group();
        let text = svg.finish("f", "sans-serif");
        std::fs::write(dir.path().join("a.svg"), &text).unwrap();
        std::fs::write(dir.path().join("b.svg"), &text).unwrap();
        let mut m = Manifest::new("t", "c", "v");
        for f in ["a.svg", "b.svg"] {
            m.figures.push(FigureEntry {
                file: f.into(),
                caption: String::new(),
                section: String::new(),
            });
        }
        let html = report_html(dir.path(), &m).unwrap();
        assert!(html.contains("id=\"fig0-0\"") && html.contains("url(#fig0-0)"));
        assert!(html.contains("id=\"fig1-0\"") && html.contains("url(#fig1-0)"));
        assert!(!html.contains(ID_PREFIX));
    }

    #[test]
    fn manifest_paths_cannot_leave_the_folder() {
        let d = Path::new("/tmp/x");
        let m = Path::new("/tmp/x/manifest.json");
        assert!(inside(d, m, "../etc/passwd").is_err());
        assert!(inside(d, m, "/etc/passwd").is_err());
        assert!(inside(d, m, "identify/frf_X.svg").is_ok());
    }

    #[test]
    fn unknown_manifest_keys_are_errors_with_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join(MANIFEST_FILE),
            "{\n  \"manifest_version\": 1, \"title\": \"t\", \"command\": \"c\", \"version\": \"v\",\n  \"colour\": 1\n}",
        )
        .unwrap();
        let e = Manifest::read(dir.path()).unwrap_err();
        assert!(matches!(e, Error::Json { line: 3, .. }), "{e}");
        assert!(e.to_string().contains("colour"), "{e}");
    }
}
