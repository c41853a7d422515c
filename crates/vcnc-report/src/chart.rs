//! Panels: an axis frame with ticks, grid and labels, and the curves inside it, laid out by the
//! rules of [`crate::style`].

use crate::decimate::{min_max_per_column, simplify};
use crate::error::Error;
use crate::style::{self, Quantity, Role, text_width_px};
use crate::svg::{Anchor, Stroke, Svg, push_polyline_data};
use crate::ticks::{self, Ticks};

/// Linear or logarithmic axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scale {
    /// Linear.
    #[default]
    Linear,
    /// Base-10 logarithmic (only positive values are drawn).
    Log,
}

/// One axis of a panel: what it shows, its scale and, optionally, a fixed range.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// Quantity and unit printed along the axis.
    pub quantity: Quantity,
    /// Linear or log.
    pub scale: Scale,
    /// Fixed range in the quantity's unit; `None`: the data's range (padded 4 % when linear).
    pub range: Option<(f64, f64)>,
}

impl Axis {
    /// A linear axis over the data's range.
    pub fn linear(name: impl Into<String>, unit: impl Into<String>) -> Axis {
        Axis {
            quantity: Quantity::new(name, unit),
            scale: Scale::Linear,
            range: None,
        }
    }

    /// A log axis over the data's range.
    pub fn log(name: impl Into<String>, unit: impl Into<String>) -> Axis {
        Axis {
            quantity: Quantity::new(name, unit),
            scale: Scale::Log,
            range: None,
        }
    }
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mark {
    /// A line through the samples (non-finite samples break it).
    #[default]
    Line,
    /// A dot per sample.
    Dots,
    /// A line and a dot per sample.
    LineDots,
}

/// One curve: samples, legend label and role (which fixes colour, width, dash and order).
#[derive(Debug, Clone, PartialEq)]
pub struct Series<'a> {
    /// Legend text.
    pub label: String,
    /// What the curve is.
    pub role: Role,
    /// Abscissae, in the figure's x unit.
    pub x: &'a [f64],
    /// Ordinates, in the panel's y unit (same length as `x`; NaN leaves a gap).
    pub y: &'a [f64],
    /// Line, dots or both.
    pub mark: Mark,
}

impl<'a> Series<'a> {
    /// A line series.
    pub fn line(label: impl Into<String>, role: Role, x: &'a [f64], y: &'a [f64]) -> Series<'a> {
        Series {
            label: label.into(),
            role,
            x,
            y,
            mark: Mark::Line,
        }
    }

    pub(crate) fn check(&self, what: &str) -> Result<(), Error> {
        if self.x.len() != self.y.len() {
            return Err(Error::LengthMismatch {
                what: format!("{what}: series '{}' y", self.label),
                expected: self.x.len(),
                found: self.y.len(),
            });
        }
        Ok(())
    }
}

/// A rectangle in px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Rect {
    pub x: f64,
    pub y: f64,
    pub w: f64,
    pub h: f64,
}

/// Data → px along one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct AxisMap {
    pub lo: f64,
    pub hi: f64,
    pub scale: Scale,
    /// px of `lo`.
    pub p0: f64,
    /// px of `hi`.
    pub p1: f64,
}

impl AxisMap {
    fn t(&self, v: f64) -> f64 {
        match self.scale {
            Scale::Linear => v,
            Scale::Log => {
                if v > 0.0 {
                    v.log10()
                } else {
                    f64::NAN
                }
            }
        }
    }

    pub fn px(&self, v: f64) -> f64 {
        let (a, b) = (self.t(self.lo), self.t(self.hi));
        self.p0 + (self.t(v) - a) / (b - a) * (self.p1 - self.p0)
    }

    pub fn ticks(&self, target: usize) -> Ticks {
        match self.scale {
            Scale::Linear => ticks::linear(self.lo, self.hi, target),
            Scale::Log => ticks::log(self.lo, self.hi),
        }
    }
}

/// The range an axis shows for the given values.
pub(crate) fn data_range(axis: &Axis, values: impl Iterator<Item = f64>) -> (f64, f64) {
    if let Some((a, b)) = axis.range
        && a.is_finite()
        && b.is_finite()
        && b > a
        && (axis.scale == Scale::Linear || a > 0.0)
    {
        return (a, b);
    }
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for v in values {
        if v.is_finite() && (axis.scale == Scale::Linear || v > 0.0) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    match axis.scale {
        Scale::Linear => {
            if lo > hi {
                return (0.0, 1.0);
            }
            if hi - lo <= 1e-12 * hi.abs().max(lo.abs()).max(1e-300) {
                let pad = if hi == 0.0 { 1.0 } else { 0.05 * hi.abs() };
                return (lo - pad, hi + pad);
            }
            let pad = 0.04 * (hi - lo);
            (lo - pad, hi + pad)
        }
        Scale::Log => {
            if lo > hi {
                return (1.0, 10.0);
            }
            if hi <= lo * (1.0 + 1e-12) {
                return (lo / 2.0, hi * 2.0);
            }
            // A little room above and below, a twentieth of the span in log terms.
            let pad = 10f64.powf(0.03 * (hi / lo).log10());
            (lo / pad, hi * pad)
        }
    }
}

/// A legend entry.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LegendEntry {
    pub label: String,
    pub role: Role,
    pub mark: Mark,
}

/// Legend entries of several series, in first-seen order, without repeats.
pub(crate) fn legend_entries<'a>(series: impl Iterator<Item = &'a Series<'a>>) -> Vec<LegendEntry> {
    let mut out: Vec<LegendEntry> = Vec::new();
    for s in series {
        if s.label.is_empty() {
            continue;
        }
        if !out.iter().any(|e| e.label == s.label && e.role == s.role) {
            out.push(LegendEntry {
                label: s.label.clone(),
                role: s.role,
                mark: s.mark,
            });
        }
    }
    out
}

const LEGEND_SAMPLE_PX: f64 = 30.0;
const LEGEND_GAP_PX: f64 = 22.0;
pub(crate) const LEGEND_ROW_PX: f64 = 20.0;

/// Rows of legend entries that fit in `width` px.
pub(crate) fn legend_rows(entries: &[LegendEntry], width: f64) -> Vec<Vec<(LegendEntry, f64)>> {
    let mut rows: Vec<Vec<(LegendEntry, f64)>> = Vec::new();
    let mut used = 0.0;
    for e in entries {
        let w = LEGEND_SAMPLE_PX + 6.0 + text_width_px(&e.label, style::LABEL_FONT_PX);
        if rows.is_empty() || (used > 0.0 && used + w > width) {
            rows.push(Vec::new());
            used = 0.0;
        }
        if let Some(r) = rows.last_mut() {
            r.push((e.clone(), w));
        }
        used += w + LEGEND_GAP_PX;
    }
    rows
}

/// Draws a legend above the data (outside every panel) starting at (`x`, `y`); returns the
/// height used.
pub(crate) fn draw_legend(
    svg: &mut Svg,
    entries: &[LegendEntry],
    x: f64,
    y: f64,
    width: f64,
) -> f64 {
    let rows = legend_rows(entries, width);
    for (r, row) in rows.iter().enumerate() {
        let cy = y + r as f64 * LEGEND_ROW_PX + LEGEND_ROW_PX / 2.0;
        let mut cx = x;
        for (e, w) in row {
            let st = e.role.stroke();
            if e.mark != Mark::Dots {
                svg.line(cx, cy, cx + LEGEND_SAMPLE_PX, cy, &st);
            }
            if e.mark != Mark::Line {
                svg.circle(cx + LEGEND_SAMPLE_PX / 2.0, cy, 3.2, e.role.colour(), None);
            }
            svg.text(
                cx + LEGEND_SAMPLE_PX + 6.0,
                cy + 4.3,
                &e.label,
                style::LABEL_FONT_PX,
                Anchor::Start,
                0.0,
                "#000000",
            );
            cx += w + LEGEND_GAP_PX;
        }
    }
    rows.len() as f64 * LEGEND_ROW_PX
}

/// Width the y tick labels of a panel need, px.
pub(crate) fn y_label_width(t: &Ticks) -> f64 {
    t.major
        .iter()
        .map(|m| text_width_px(&m.text, style::TICK_FONT_PX))
        .fold(0.0, f64::max)
}

/// What to print along an axis: its label, and the common factor of the tick labels if any.
pub(crate) fn axis_title(q: &Quantity, t: &Ticks) -> String {
    match &t.factor_text {
        Some(f) if q.unit.is_empty() => format!("{} ({f})", q.name),
        Some(f) => format!("{} ({f} {})", q.name, q.unit),
        None => q.label(),
    }
}

/// Splits an axis title into two lines at the space nearest its middle when it is longer than
/// `len_px` (a y title must not run past its panel into the next one).
pub(crate) fn wrap_to(text: &str, len_px: f64) -> Vec<String> {
    if text_width_px(text, style::LABEL_FONT_PX) <= len_px {
        return vec![text.to_string()];
    }
    let mid = text.chars().count() / 2;
    let best = text
        .char_indices()
        .filter(|(_, c)| *c == ' ')
        .map(|(i, _)| i)
        .min_by_key(|&i| (text[..i].chars().count() as i64 - mid as i64).abs());
    match best {
        Some(i) => vec![text[..i].to_string(), text[i + 1..].to_string()],
        None => vec![text.to_string()],
    }
}

/// Extra left margin a y title needs when it wraps to two lines, px.
pub(crate) fn y_title_extra(q: &Quantity, t: &Ticks, len_px: f64) -> f64 {
    if wrap_to(&axis_title(q, t), len_px + 8.0).len() > 1 {
        style::LABEL_FONT_PX + 2.0
    } else {
        0.0
    }
}

/// Number of labelled ticks that fit along `len_px` with `per_px` px per label.
pub(crate) fn tick_target(len_px: f64, per_px: f64) -> usize {
    ((len_px / per_px).round() as usize).clamp(2, 12)
}

/// Options of [`draw_frame`].
pub(crate) struct FrameOptions<'a> {
    pub x_quantity: &'a Quantity,
    pub y_quantity: &'a Quantity,
    /// Print x tick labels and the x axis title (bottom panel of a stack).
    pub x_labels: bool,
    /// Where the y axis title goes (x px of its centre line).
    pub y_title_x: f64,
    /// Optional title above the panel, left-aligned.
    pub title: Option<&'a str>,
}

/// Draws grid, frame, ticks and labels of a panel; returns the clip id of its data area.
pub(crate) fn draw_frame(
    svg: &mut Svg,
    r: Rect,
    xm: &AxisMap,
    ym: &AxisMap,
    xt: &Ticks,
    yt: &Ticks,
    o: &FrameOptions,
) -> String {
    let grid = Stroke::solid(style::GRID_COLOUR, 0.8);
    let minor_grid = Stroke::solid(style::MINOR_GRID_COLOUR, 0.8);
    let axis = Stroke::solid(style::AXIS_COLOUR, 1.0);
    let (bottom, right) = (r.y + r.h, r.x + r.w);
    // Minor grid on log axes only (a linear axis with a minor grid looks busy).
    let mut minor = Vec::new();
    if xm.scale == Scale::Log {
        minor.extend(xt.minor.iter().map(|&v| {
            let p = xm.px(v);
            ((p, r.y), (p, bottom))
        }));
    }
    if ym.scale == Scale::Log {
        minor.extend(yt.minor.iter().map(|&v| {
            let p = ym.px(v);
            ((r.x, p), (right, p))
        }));
    }
    svg.segments(&minor, &minor_grid);
    let mut major: Vec<_> = xt
        .major
        .iter()
        .map(|m| {
            let p = xm.px(m.value);
            ((p, r.y), (p, bottom))
        })
        .collect();
    major.extend(yt.major.iter().map(|m| {
        let p = ym.px(m.value);
        ((r.x, p), (right, p))
    }));
    svg.segments(&major, &grid);
    // Ticks, outward; minor ticks shorter.
    let mut ticks = Vec::new();
    for m in &xt.major {
        let p = xm.px(m.value);
        ticks.push(((p, bottom), (p, bottom + style::TICK_PX)));
    }
    for m in &yt.major {
        let p = ym.px(m.value);
        ticks.push(((r.x - style::TICK_PX, p), (r.x, p)));
    }
    for &v in &xt.minor {
        let p = xm.px(v);
        ticks.push(((p, bottom), (p, bottom + style::MINOR_TICK_PX)));
    }
    for &v in &yt.minor {
        let p = ym.px(v);
        ticks.push(((r.x - style::MINOR_TICK_PX, p), (r.x, p)));
    }
    svg.segments(&ticks, &axis);
    svg.rect(r.x, r.y, r.w, r.h, "none", Some(&axis));
    // Tick labels.
    for m in &yt.major {
        let p = ym.px(m.value);
        svg.text_markup(
            r.x - style::TICK_PX - 3.0,
            p + 3.8,
            &m.markup,
            style::TICK_FONT_PX,
            Anchor::End,
            0.0,
            "#000000",
            false,
        );
    }
    if o.x_labels {
        for m in &xt.major {
            let p = xm.px(m.value);
            svg.text_markup(
                p,
                bottom + style::TICK_PX + 13.0,
                &m.markup,
                style::TICK_FONT_PX,
                Anchor::Middle,
                0.0,
                "#000000",
                false,
            );
        }
        svg.text(
            r.x + r.w / 2.0,
            bottom + style::TICK_PX + 32.0,
            &axis_title(o.x_quantity, xt),
            style::LABEL_FONT_PX,
            Anchor::Middle,
            0.0,
            "#000000",
        );
    }
    let title = axis_title(o.y_quantity, yt);
    let lines = wrap_to(&title, r.h + 8.0);
    let n = lines.len() as f64;
    for (i, l) in lines.iter().enumerate() {
        // Lines of a rotated title stack to the right (towards the axis).
        let x = o.y_title_x - (n - 1.0 - i as f64) * (style::LABEL_FONT_PX + 2.0);
        svg.text(
            x,
            r.y + r.h / 2.0,
            l,
            style::LABEL_FONT_PX,
            Anchor::Middle,
            -90.0,
            "#000000",
        );
    }
    if let Some(t) = o.title {
        svg.text(
            r.x,
            r.y - 6.0,
            t,
            style::PANEL_TITLE_FONT_PX,
            Anchor::Start,
            0.0,
            "#000000",
        );
    }
    svg.clip_rect(r.x, r.y, r.w, r.h)
}

/// Height below a panel for x tick labels and the x title, px.
pub(crate) const X_LABELS_PX: f64 = 44.0;

/// Draws the series of a panel inside its clip, thick truth first and thin models on top.
pub(crate) fn draw_series(
    svg: &mut Svg,
    clip: &str,
    r: Rect,
    xm: &AxisMap,
    ym: &AxisMap,
    series: &[Series],
) {
    let mut order: Vec<&Series> = series.iter().collect();
    order.sort_by_key(|s| s.role.z_order());
    svg.open_group_clipped(clip);
    for s in order {
        let st = s.role.stroke();
        if s.mark != Mark::Dots {
            let d = line_path(s.x, s.y, r, xm, ym);
            svg.path_d(&d, &st);
        }
        if s.mark != Mark::Line {
            for (x, y) in s.x.iter().zip(s.y) {
                let (px, py) = (xm.px(*x), ym.px(*y));
                if px.is_finite() && py.is_finite() {
                    svg.circle(px, py, 3.2, s.role.colour(), None);
                }
            }
        }
    }
    svg.close_group();
}

/// The `d` data of one series: finite runs, min/max per pixel column, then simplified.
fn line_path(x: &[f64], y: &[f64], r: Rect, xm: &AxisMap, ym: &AxisMap) -> String {
    let n = x.len().min(y.len());
    let monotone = x
        .windows(2)
        .all(|w| w[1] >= w[0] || w[0].is_nan() || w[1].is_nan());
    let mut d = String::new();
    let mut k = 0;
    while k < n {
        // A run of samples that map to finite pixels.
        let ok = |j: usize| xm.px(x[j]).is_finite() && ym.px(y[j]).is_finite();
        while k < n && !ok(k) {
            k += 1;
        }
        let start = k;
        while k < n && ok(k) {
            k += 1;
        }
        if start == k {
            continue;
        }
        let px: Vec<f64> = (start..k).map(|j| xm.px(x[j])).collect();
        let py: Vec<f64> = (start..k).map(|j| ym.px(y[j])).collect();
        let keep: Vec<usize> = if monotone {
            let cols = r.w.ceil().max(1.0) as usize;
            min_max_per_column(&px, &py, (r.x, r.x + r.w), cols)
        } else {
            (0..px.len()).collect()
        };
        let pts: Vec<(f64, f64)> = keep.iter().map(|&j| (px[j], py[j])).collect();
        let pts = simplify(&pts, 0.15);
        push_polyline_data(&mut d, &pts);
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_map_places_decades_evenly() {
        let m = AxisMap {
            lo: 1.0,
            hi: 1000.0,
            scale: Scale::Log,
            p0: 0.0,
            p1: 300.0,
        };
        approx::assert_abs_diff_eq!(m.px(10.0), 100.0, epsilon = 1e-9);
        approx::assert_abs_diff_eq!(m.px(100.0), 200.0, epsilon = 1e-9);
        assert!(m.px(-1.0).is_nan());
    }

    #[test]
    fn ranges_pad_linear_axes_and_respect_fixed_ones() {
        let a = Axis::linear("e", "µm");
        assert_eq!(data_range(&a, [0.0, 100.0].into_iter()), (-4.0, 104.0));
        assert_eq!(data_range(&a, [f64::NAN].into_iter()), (0.0, 1.0));
        let mut b = a.clone();
        b.range = Some((-1.0, 1.0));
        assert_eq!(data_range(&b, [0.0, 100.0].into_iter()), (-1.0, 1.0));
    }
}
