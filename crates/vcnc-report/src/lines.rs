//! Line figures: stacked panels over one shared x axis (time series, Bode, convergence,
//! errors along the path), and the comparison layout that gives every "model against truth"
//! panel a difference panel of its own.

use vcnc_axis::AxisName;

use crate::chart::{
    self, Axis, AxisMap, FrameOptions, LegendEntry, Mark, Rect, Scale, Series, X_LABELS_PX,
};
use crate::error::Error;
use crate::figure::Figure;
use crate::style::{self, Quantity, Role, text_width_px};
use crate::svg::{Anchor, Stroke, Svg};

/// One panel of a stacked figure.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel<'a> {
    /// Title printed above the panel, if any.
    pub title: Option<String>,
    /// The y axis.
    pub y: Axis,
    /// The curves.
    pub series: Vec<Series<'a>>,
    /// Height of the data area, px.
    pub height_px: f64,
}

impl<'a> Panel<'a> {
    /// A panel of the default height (190 px).
    pub fn new(y: Axis, series: Vec<Series<'a>>) -> Panel<'a> {
        Panel {
            title: None,
            y,
            series,
            height_px: 190.0,
        }
    }

    /// The same panel with a title.
    pub fn titled(mut self, title: impl Into<String>) -> Panel<'a> {
        self.title = Some(title.into());
        self
    }
}

/// A vertical marker line across every panel at one x (a block boundary, a worst block).
#[derive(Debug, Clone, PartialEq)]
pub struct XMarker {
    /// Position, in the figure's x unit.
    pub x: f64,
    /// Short label printed above the top panel ("L120").
    pub label: String,
}

/// Panels stacked over one shared x axis.
#[derive(Debug, Clone, PartialEq)]
pub struct LineFigure<'a> {
    /// Figure title.
    pub title: String,
    /// A line of smaller text under the title (notes such as axes left out), may be empty.
    pub note: String,
    /// The shared x axis.
    pub x: Axis,
    /// Panels, top to bottom.
    pub panels: Vec<Panel<'a>>,
    /// Vertical markers.
    pub markers: Vec<XMarker>,
    /// Figure width, px.
    pub width_px: f64,
}

impl<'a> LineFigure<'a> {
    /// A figure of the default width with no note and no markers.
    pub fn new(title: impl Into<String>, x: Axis, panels: Vec<Panel<'a>>) -> LineFigure<'a> {
        LineFigure {
            title: title.into(),
            note: String::new(),
            x,
            panels,
            markers: Vec::new(),
            width_px: style::FIGURE_WIDTH_PX,
        }
    }
}

const RIGHT_PX: f64 = 24.0;
const PANEL_GAP_PX: f64 = 14.0;
const PANEL_TITLE_PX: f64 = 20.0;

/// Draws a title (and note) at the top; returns the y below them.
pub(crate) fn draw_title(svg: &mut Svg, title: &str, note: &str, x: f64) -> f64 {
    let mut y = 24.0;
    svg.text_markup(
        x,
        y,
        &crate::svg::escape(title),
        style::TITLE_FONT_PX,
        Anchor::Start,
        0.0,
        "#000000",
        true,
    );
    if !note.is_empty() {
        y += 18.0;
        svg.text(
            x,
            y,
            note,
            style::TICK_FONT_PX,
            Anchor::Start,
            0.0,
            "#444444",
        );
    }
    y + 10.0
}

/// Renders a [`LineFigure`].
///
/// Every series is checked (x and y of equal length); non-finite samples leave gaps. Curves
/// are drawn thick truth first, thin model last (see [`Role::z_order`]); the legend is one
/// strip above the panels, outside the data.
pub fn line_figure(fig: &LineFigure) -> Result<Figure, Error> {
    if fig.panels.is_empty() {
        return Err(Error::Empty {
            what: fig.title.clone(),
        });
    }
    for p in &fig.panels {
        for s in &p.series {
            s.check(&fig.title)?;
        }
    }
    let w = fig.width_px;
    let xr = chart::data_range(
        &fig.x,
        fig.panels
            .iter()
            .flat_map(|p| p.series.iter().flat_map(|s| s.x.iter().copied())),
    );
    // y ranges and ticks first: the left margin must fit the widest tick label of any panel.
    let yms: Vec<(f64, f64)> = fig
        .panels
        .iter()
        .map(|p| {
            chart::data_range(
                &p.y,
                p.series.iter().flat_map(|s| {
                    s.x.iter()
                        .zip(s.y)
                        .filter(move |(x, _)| **x >= xr.0 && **x <= xr.1)
                        .map(|(_, y)| *y)
                }),
            )
        })
        .collect();
    let yts: Vec<_> = fig
        .panels
        .iter()
        .zip(&yms)
        .map(|(p, r)| {
            AxisMap {
                lo: r.0,
                hi: r.1,
                scale: p.y.scale,
                p0: 0.0,
                p1: 1.0,
            }
            .ticks(chart::tick_target(p.height_px, 42.0))
        })
        .collect();
    let label_w = yts.iter().map(chart::y_label_width).fold(0.0, f64::max);
    let extra = fig
        .panels
        .iter()
        .zip(&yts)
        .map(|(p, t)| chart::y_title_extra(&p.y.quantity, t, p.height_px))
        .fold(0.0, f64::max);
    let left = label_w + style::TICK_PX + 3.0 + 8.0 + style::LABEL_FONT_PX + 12.0 + extra;
    let y_title_x = left - label_w - style::TICK_PX - 3.0 - 8.0 - style::LABEL_FONT_PX / 2.0;
    let plot_w = w - left - RIGHT_PX;

    let entries: Vec<LegendEntry> =
        chart::legend_entries(fig.panels.iter().flat_map(|p| p.series.iter()));
    let legend_h = chart::legend_rows(&entries, plot_w).len() as f64 * chart::LEGEND_ROW_PX;
    let marker_h = if fig.markers.is_empty() {
        0.0
    } else {
        4.0 + 13.0 * MARKER_ROWS as f64
    };
    let mut h = 24.0 + 10.0 + if fig.note.is_empty() { 0.0 } else { 18.0 };
    h += legend_h + 6.0 + marker_h;
    for (i, p) in fig.panels.iter().enumerate() {
        if p.title.is_some() {
            h += PANEL_TITLE_PX;
        }
        h += p.height_px;
        h += if i + 1 == fig.panels.len() {
            X_LABELS_PX
        } else {
            PANEL_GAP_PX
        };
    }
    h += 6.0;

    let mut svg = Svg::new(w, h);
    let mut top = draw_title(&mut svg, &fig.title, &fig.note, 12.0);
    top += chart::draw_legend(&mut svg, &entries, left, top, plot_w) + 6.0;
    let markers_top = top;
    top += marker_h;
    let xt_target = chart::tick_target(plot_w, 95.0);
    let mut marker_spans = Vec::new();
    for (i, (p, (yr, yt))) in fig.panels.iter().zip(yms.iter().zip(&yts)).enumerate() {
        if p.title.is_some() {
            top += PANEL_TITLE_PX;
        }
        let r = Rect {
            x: left,
            y: top,
            w: plot_w,
            h: p.height_px,
        };
        let xm = AxisMap {
            lo: xr.0,
            hi: xr.1,
            scale: fig.x.scale,
            p0: r.x,
            p1: r.x + r.w,
        };
        let ym = AxisMap {
            lo: yr.0,
            hi: yr.1,
            scale: p.y.scale,
            p0: r.y + r.h,
            p1: r.y,
        };
        let xt = xm.ticks(xt_target);
        let last = i + 1 == fig.panels.len();
        let clip = chart::draw_frame(
            &mut svg,
            r,
            &xm,
            &ym,
            &xt,
            yt,
            &FrameOptions {
                x_quantity: &fig.x.quantity,
                y_quantity: &p.y.quantity,
                x_labels: last,
                y_title_x,
                title: p.title.as_deref(),
            },
        );
        // A zero line on linear y axes that cross zero, a shade darker than the grid.
        if p.y.scale == Scale::Linear && yr.0 < 0.0 && yr.1 > 0.0 {
            let z = ym.px(0.0);
            svg.line(r.x, z, r.x + r.w, z, &Stroke::solid("#aaaaaa", 0.8));
        }
        chart::draw_series(&mut svg, &clip, r, &xm, &ym, &p.series);
        let mst = Stroke {
            colour: "#444444".into(),
            width_px: 0.8,
            dash_px: vec![2.0, 3.0],
            opacity: 1.0,
        };
        for m in &fig.markers {
            let px = xm.px(m.x);
            if px.is_finite() && px >= r.x && px <= r.x + r.w {
                svg.line(px, r.y, px, r.y + r.h, &mst);
                if i == 0 {
                    marker_spans.push((px, m.label.clone()));
                }
            }
        }
        top += p.height_px + if last { X_LABELS_PX } else { PANEL_GAP_PX };
    }
    draw_marker_labels(&mut svg, &mut marker_spans, markers_top, marker_h);
    Ok(Figure {
        title: fig.title.clone(),
        svg: svg.finish(&fig.title, style::FONT_FAMILY),
        width_px: w,
        height_px: h,
    })
}

/// Rows of marker labels above the top panel.
const MARKER_ROWS: usize = 3;

/// Marker labels above the top panel, in staggered rows so neighbours do not collide (a label
/// that finds no room in any row is left out; its dashed line still shows the place).
fn draw_marker_labels(svg: &mut Svg, spans: &mut [(f64, String)], top: f64, h: f64) {
    spans.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut row_end = [f64::NEG_INFINITY; MARKER_ROWS];
    for (px, label) in spans.iter() {
        let wdt = text_width_px(label, style::TICK_FONT_PX);
        let Some(row) = row_end.iter().position(|end| px - wdt / 2.0 > end + 3.0) else {
            continue;
        };
        row_end[row] = px + wdt / 2.0;
        let y = top + h - 4.0 - row as f64 * 13.0;
        svg.text(
            *px,
            y,
            label,
            style::TICK_FONT_PX,
            Anchor::Middle,
            0.0,
            "#222222",
        );
    }
}

/// A signal compared against its truth: drawn in one panel, and the differences
/// (other − truth, sample by sample) in a panel of their own below, so that curves lying on top
/// of each other still show how far apart they are.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison<'a> {
    /// Title of the signal panel, if any.
    pub title: Option<String>,
    /// The signal's y axis.
    pub y: Axis,
    /// The truth (true machine or measurement).
    pub truth: Series<'a>,
    /// Models compared against it (same samples as the truth).
    pub others: Vec<Series<'a>>,
    /// Quantity of the difference panel; `None`: "`other label` − `truth label`" in the signal's
    /// unit.
    pub difference: Option<Quantity>,
}

/// A [`LineFigure`] whose panels come in pairs: each [`Comparison`] as a signal panel and a
/// difference panel (60 % of its height).
pub fn comparison_figure(
    title: &str,
    note: &str,
    x: Axis,
    comparisons: &[Comparison],
    markers: Vec<XMarker>,
) -> Result<Figure, Error> {
    let mut diffs: Vec<Vec<Vec<f64>>> = Vec::new();
    for c in comparisons {
        c.truth.check(title)?;
        let mut d = Vec::new();
        for o in &c.others {
            o.check(title)?;
            if o.y.len() != c.truth.y.len() {
                return Err(Error::LengthMismatch {
                    what: format!("{title}: '{}' against '{}'", o.label, c.truth.label),
                    expected: c.truth.y.len(),
                    found: o.y.len(),
                });
            }
            d.push(o.y.iter().zip(c.truth.y).map(|(a, b)| a - b).collect());
        }
        diffs.push(d);
    }
    let mut panels = Vec::new();
    for (c, d) in comparisons.iter().zip(&diffs) {
        let mut series = vec![c.truth.clone()];
        series.extend(c.others.iter().cloned());
        panels.push(Panel {
            title: c.title.clone(),
            y: c.y.clone(),
            series,
            height_px: 170.0,
        });
        if c.others.is_empty() {
            continue;
        }
        let q = c.difference.clone().unwrap_or_else(|| {
            let name = if c.others.len() == 1 {
                format!("{} − {}", c.others[0].label, c.truth.label)
            } else {
                format!("model − {}", c.truth.label)
            };
            Quantity::new(name, c.y.quantity.unit.clone())
        });
        let dseries = c
            .others
            .iter()
            .zip(d)
            .map(|(o, dy)| Series {
                label: o.label.clone(),
                role: o.role,
                x: o.x,
                y: dy,
                mark: o.mark,
            })
            .collect();
        panels.push(Panel {
            title: None,
            y: Axis {
                quantity: q,
                scale: Scale::Linear,
                range: None,
            },
            series: dseries,
            height_px: 105.0,
        });
    }
    let mut fig = LineFigure::new(title, x, panels);
    fig.note = note.to_string();
    fig.markers = markers;
    line_figure(&fig)
}

/// Tracking error of one machine axis: the reference position (to tell whether the program
/// moves the axis) and the errors to draw.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisErrors<'a> {
    /// The axis.
    pub axis: AxisName,
    /// Reference position x_r, in the axis unit (mm or deg).
    pub reference: &'a [f64],
    /// Tracking error of the truth (true machine or measurement), in µm (linear axes) or mdeg
    /// (rotary axes).
    pub truth: Series<'a>,
    /// Tracking errors of the models, same unit and samples.
    pub models: Vec<Series<'a>>,
}

/// Whether a program uses an axis: its reference moves, or some error on it is not zero.
pub fn axis_is_used(t: &AxisErrors) -> bool {
    let span = t
        .reference
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let moves = span.1 > span.0;
    let nonzero = std::iter::once(&t.truth)
        .chain(&t.models)
        .any(|s| s.y.iter().any(|v| v.is_finite() && *v != 0.0));
    moves || nonzero
}

/// Tracking errors x_r − x of the axes a program uses (one signal panel and one difference
/// panel each); axes it does not move are left out and named in the note.
pub fn tracking_errors(title: &str, axes: &[AxisErrors]) -> Result<Figure, Error> {
    let (used, unused): (Vec<&AxisErrors>, Vec<&AxisErrors>) =
        axes.iter().partition(|a| axis_is_used(a));
    if used.is_empty() {
        return Err(Error::Empty {
            what: format!("{title}: no axis moves"),
        });
    }
    let note = if unused.is_empty() {
        String::new()
    } else {
        let names: Vec<&str> = unused.iter().map(|a| a.axis.as_str()).collect();
        format!("not moved by the program, not shown: {}", names.join(", "))
    };
    let comparisons: Vec<Comparison> = used
        .iter()
        .map(|a| {
            let unit = style::error_unit(a.axis.unit());
            Comparison {
                title: Some(format!("axis {}", a.axis)),
                y: Axis::linear(format!("{} tracking error", a.axis), unit),
                truth: a.truth.clone(),
                others: a.models.clone(),
                difference: Some(Quantity::new("model − truth", unit)),
            }
        })
        .collect();
    comparison_figure(
        title,
        &note,
        Axis::linear("time t", style::units::S),
        &comparisons,
        Vec::new(),
    )
}

/// One frequency response: magnitude and phase at each frequency.
#[derive(Debug, Clone, PartialEq)]
pub struct BodeCurve<'a> {
    /// Legend label.
    pub label: String,
    /// Role.
    pub role: Role,
    /// Frequencies, Hz (positive, increasing).
    pub freq_hz: &'a [f64],
    /// Magnitude, dB.
    pub mag_db: &'a [f64],
    /// Phase, deg (unwrapped).
    pub phase_deg: &'a [f64],
}

/// A response of several curves, e.g. tracking x/x_r or disturbance x/d.
#[derive(Debug, Clone, PartialEq)]
pub struct BodeGroup<'a> {
    /// Name of the response, e.g. "tracking x/x_r".
    pub name: String,
    /// The curves.
    pub curves: Vec<BodeCurve<'a>>,
}

/// Bode diagrams: for each group a magnitude panel (dB) and a phase panel (deg) over a log
/// frequency axis with decade labels and minor ticks.
pub fn bode(title: &str, groups: &[BodeGroup]) -> Result<Figure, Error> {
    let mut panels = Vec::new();
    for g in groups {
        for c in &g.curves {
            for (what, v) in [("mag_db", c.mag_db), ("phase_deg", c.phase_deg)] {
                if v.len() != c.freq_hz.len() {
                    return Err(Error::LengthMismatch {
                        what: format!("{title}: {} '{}' {what}", g.name, c.label),
                        expected: c.freq_hz.len(),
                        found: v.len(),
                    });
                }
            }
            if let Some((i, f)) = c
                .freq_hz
                .iter()
                .enumerate()
                .find(|(_, f)| !(f.is_finite() && **f > 0.0))
            {
                return Err(Error::NonFinite {
                    what: format!("{title}: {} '{}' freq_hz (must be > 0)", g.name, c.label),
                    index: i,
                    value: *f,
                });
            }
        }
        let mag = g
            .curves
            .iter()
            .map(|c| Series::line(c.label.clone(), c.role, c.freq_hz, c.mag_db))
            .collect();
        let phase = g
            .curves
            .iter()
            .map(|c| Series::line(c.label.clone(), c.role, c.freq_hz, c.phase_deg))
            .collect();
        panels.push(Panel {
            title: Some(format!("{}: magnitude", g.name)),
            y: Axis::linear("magnitude", style::units::DB),
            series: mag,
            height_px: 170.0,
        });
        panels.push(Panel {
            title: Some(format!("{}: phase", g.name)),
            y: Axis::linear("phase", style::units::DEG),
            series: phase,
            height_px: 150.0,
        });
    }
    line_figure(&LineFigure::new(
        title,
        Axis::log("frequency f", style::units::HZ),
        panels,
    ))
}

/// PSO convergence: cost against iteration on a log axis, one curve per history (global best,
/// swarm mean, …), each with its role (use [`Role::Other`]).
pub fn convergence(title: &str, cost: &Quantity, curves: &[Series]) -> Result<Figure, Error> {
    line_figure(&LineFigure::new(
        title,
        Axis::linear("iteration", ""),
        vec![Panel {
            title: None,
            y: Axis {
                quantity: cost.clone(),
                scale: Scale::Log,
                range: None,
            },
            series: curves.to_vec(),
            height_px: 300.0,
        }],
    ))
}

/// A sweep over one key: the result against the key's value. A series marked
/// [`Mark::Line`] (the default) is drawn as dots joined by a thin line when its values are
/// sorted, as dots alone when they are not; a series marked [`Mark::Dots`] or
/// [`Mark::LineDots`] keeps its mark (e.g. every configuration of a many-key sweep as dots
/// beside the best per value as a line).
pub fn sweep_line(
    title: &str,
    key: &Quantity,
    result: &Quantity,
    series: &[Series],
) -> Result<Figure, Error> {
    let series: Vec<Series> = series
        .iter()
        .map(|s| {
            let sorted = s.x.windows(2).all(|w| w[0] <= w[1]);
            let mark = match s.mark {
                Mark::Line if sorted => Mark::LineDots,
                Mark::Line => Mark::Dots,
                m => m,
            };
            Series { mark, ..s.clone() }
        })
        .collect();
    line_figure(&LineFigure::new(
        title,
        Axis {
            quantity: key.clone(),
            scale: Scale::Linear,
            range: None,
        },
        vec![Panel {
            title: None,
            y: Axis {
                quantity: result.clone(),
                scale: Scale::Linear,
                range: None,
            },
            series,
            height_px: 300.0,
        }],
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_three_axis_program_gets_no_rotary_panels() {
        let t: Vec<f64> = (0..100).map(|k| k as f64 * 0.01).collect();
        let moving: Vec<f64> = t.iter().map(|v| v * 10.0).collect();
        let still = vec![0.0; 100];
        let err: Vec<f64> = t.iter().map(|v| v.sin()).collect();
        let zero = vec![0.0; 100];
        let ax = |axis, r, e| AxisErrors {
            axis,
            reference: r,
            truth: Series::line("true machine", Role::TrueMachine, &t, e),
            models: vec![Series::line("vcnc model", Role::Model, &t, e)],
        };
        let axes = [
            ax(AxisName::X, &moving[..], &err[..]),
            ax(AxisName::Y, &moving[..], &err[..]),
            ax(AxisName::Z, &moving[..], &err[..]),
            ax(AxisName::A, &still[..], &zero[..]),
            ax(AxisName::C, &still[..], &zero[..]),
        ];
        let f = tracking_errors("tracking", &axes).unwrap();
        assert!(f.svg.contains("axis X") && f.svg.contains("axis Z"));
        assert!(!f.svg.contains("axis A") && !f.svg.contains("axis C"));
        assert!(f.svg.contains("not shown: A, C"));
        assert!(f.svg.contains("tracking error (µm)"));
    }

    #[test]
    fn mismatched_lengths_are_an_error_naming_the_series() {
        let x = [1.0, 2.0, 3.0];
        let y = [1.0, 2.0];
        let p = Panel::new(
            Axis::linear("e", "µm"),
            vec![Series::line("bad", Role::Model, &x, &y)],
        );
        let e = line_figure(&LineFigure::new("t", Axis::linear("t", "s"), vec![p])).unwrap_err();
        assert!(e.to_string().contains("'bad'"), "{e}");
    }

    #[test]
    fn bode_refuses_non_positive_frequencies() {
        let f = [0.0, 1.0];
        let m = [0.0, 0.0];
        let g = BodeGroup {
            name: "tracking".into(),
            curves: vec![BodeCurve {
                label: "true".into(),
                role: Role::TrueMachine,
                freq_hz: &f,
                mag_db: &m,
                phase_deg: &m,
            }],
        };
        assert!(matches!(
            bode("b", &[g]),
            Err(Error::NonFinite { index: 0, .. })
        ));
    }
}

#[cfg(test)]
mod long_series {
    use super::*;

    /// Absolute coordinates of every `<path d=…>` drawn in `stroke` colour.
    fn paths_of(svg: &str, stroke: &str) -> Vec<Vec<(f64, f64)>> {
        let mut out = Vec::new();
        for el in svg.split("<path").skip(1) {
            if !el.contains(&format!("stroke=\"{stroke}\"")) {
                continue;
            }
            let d = el
                .split(" d=\"")
                .nth(1)
                .and_then(|r| r.split('"').next())
                .unwrap();
            let mut pts = Vec::new();
            let mut cur: (f64, f64);
            for sub in d.split('M').filter(|s| !s.is_empty()) {
                let (start, rest) = sub.split_once('l').unwrap_or((sub, ""));
                let v: Vec<f64> = start.split(' ').map(|x| x.parse().unwrap()).collect();
                cur = (v[0], v[1]);
                pts.push(cur);
                let r: Vec<f64> = rest
                    .split(' ')
                    .filter(|x| !x.is_empty())
                    .map(|x| x.parse().unwrap())
                    .collect();
                for c in r.chunks(2) {
                    cur = (cur.0 + c[0], cur.1 + c[1]);
                    pts.push(cur);
                }
            }
            out.push(pts);
        }
        out
    }

    #[test]
    fn a_million_samples_make_a_small_svg_that_still_reaches_the_spike() {
        let n = 1_000_000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-4).collect();
        let mut e: Vec<f64> = t.iter().map(|t| 20.0 * (t * 3.0).sin()).collect();
        e[777_777] = 95.0;
        let fig = line_figure(&LineFigure::new(
            "long run",
            Axis::linear("time t", "s"),
            vec![Panel::new(
                Axis {
                    quantity: Quantity::new("tracking error", "µm"),
                    scale: Scale::Linear,
                    range: Some((-25.0, 100.0)),
                },
                vec![Series::line("true machine", Role::TrueMachine, &t, &e)],
            )],
        ))
        .unwrap();
        assert!(fig.svg.len() < 20_000, "{} bytes", fig.svg.len());
        let paths = paths_of(&fig.svg, Role::TrueMachine.colour());
        // The legend sample is one path; the data path is the one with many points.
        let data = paths.iter().max_by_key(|p| p.len()).unwrap();
        let top = data.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        // The panel spans 190 px for 125 µm: 95 µm sits 5/125 of the way down from the top.
        let frame_top = fig
            .svg
            .split("<rect x=\"")
            .filter_map(|r| {
                let (x, rest) = r.split_once('"')?;
                let y = rest.split("y=\"").nth(1)?.split('"').next()?;
                let h = rest.split("height=\"").nth(1)?.split('"').next()?;
                (x.parse::<f64>().ok()? > 10.0 && h == "190").then(|| y.parse::<f64>().ok())?
            })
            .next()
            .unwrap();
        approx::assert_abs_diff_eq!(top, frame_top + 190.0 * 5.0 / 125.0, epsilon = 0.15);
    }
}
