//! Contour-error views of a tool-tip path: the path in 3-D (an isometric view and the two
//! projections that show it best) coloured by the error on a percentile-clipped scale with the
//! worst blocks marked by their source line, and the error along the path's arc length.

use crate::chart::{self, Axis, AxisMap, FrameOptions, Rect, Scale, Series};
use crate::error::Error;
use crate::figure::Figure;
use crate::lines::{Comparison, XMarker, comparison_figure, draw_title};
use crate::style::{self, COLOUR_LEVELS, Quantity, colour_map, hex, text_width_px};
use crate::svg::{Anchor, Stroke, Svg, push_polyline_data};
use crate::ticks;

/// A tool-tip path and the value to colour it by.
#[derive(Debug, Clone, PartialEq)]
pub struct ColouredPath<'a> {
    /// Tool-tip positions in the workpiece frame, mm (x, y, z).
    pub points_mm: &'a [[f64; 3]],
    /// Value per point (the contour error), in `value.unit`; NaN leaves a gap.
    pub values: &'a [f64],
    /// What the value is (e.g. "contour error", µm).
    pub value: Quantity,
    /// Source line of the block each point belongs to (1-based), to mark the worst blocks.
    pub block_line: Option<&'a [u32]>,
}

/// Options of [`contour_path_views`].
#[derive(Debug, Clone, PartialEq)]
pub struct PathViewOptions {
    /// The colour scale ends at this percentile of the values, % (default 99.5): one spike at a
    /// rapid turn does not darken the whole part; larger values take the top colour.
    pub clip_percentile: f64,
    /// How many of the worst blocks to mark (default 5).
    pub worst_blocks: usize,
    /// Figure width, px (default 1040).
    pub width_px: f64,
}

impl Default for PathViewOptions {
    fn default() -> Self {
        PathViewOptions {
            clip_percentile: 99.5,
            worst_blocks: 5,
            width_px: 1040.0,
        }
    }
}

/// A block with one of the largest errors.
#[derive(Debug, Clone, PartialEq)]
pub struct WorstBlock {
    /// Source line (1-based).
    pub line: u32,
    /// Index of the sample with the block's largest value.
    pub index: usize,
    /// That value.
    pub value: f64,
}

/// The `n` blocks with the largest value, largest first (ties: lower line first). Each block
/// (source line) appears once, at its worst sample; non-finite values and samples of line 0 (no
/// source line, or not measured) are ignored.
pub fn worst_blocks(values: &[f64], block_line: &[u32], n: usize) -> Vec<WorstBlock> {
    let mut best: std::collections::BTreeMap<u32, (usize, f64)> = Default::default();
    for (i, (&v, &l)) in values.iter().zip(block_line).enumerate() {
        if !v.is_finite() || l == 0 {
            continue;
        }
        let e = best.entry(l).or_insert((i, v));
        if v > e.1 {
            *e = (i, v);
        }
    }
    let mut all: Vec<WorstBlock> = best
        .into_iter()
        .map(|(line, (index, value))| WorstBlock { line, index, value })
        .collect();
    all.sort_by(|a, b| b.value.total_cmp(&a.value).then(a.line.cmp(&b.line)));
    all.truncate(n);
    all
}

/// A marked place on a figure: the worst sample of one or more bad blocks lying close together.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct HotSpot {
    /// Sample index of the worst value.
    pub index: usize,
    /// "L142", or "L26–29" for neighbouring blocks merged into one mark.
    pub label: String,
}

/// Up to `n` marks for the worst blocks: blocks are taken worst first, and a block whose worst
/// sample lies within `radius` (by `dist` between sample indices) of a mark already made joins
/// that mark (and, if among the 4n worst, its label) instead of getting a ring of its own, so
/// labels never pile up and the marks show n separate bad places.
pub(crate) fn hot_spots(
    values: &[f64],
    block_line: &[u32],
    n: usize,
    dist: impl Fn(usize, usize) -> f64,
    radius: f64,
) -> Vec<HotSpot> {
    // Every block, worst first: a block near a mark joins its label while it is among the 4n
    // worst (beyond that it is just the flank of a mark's peak); a block far from every mark
    // starts a new one, so the n marks are n separate places.
    let cand = worst_blocks(values, block_line, usize::MAX);
    let mut spots: Vec<(usize, Vec<u32>)> = Vec::new();
    for (rank, b) in cand.into_iter().enumerate() {
        if let Some(s) = spots.iter_mut().find(|s| dist(s.0, b.index) < radius) {
            if rank < 4 * n {
                s.1.push(b.line);
            }
        } else if spots.len() < n {
            spots.push((b.index, vec![b.line]));
        } else if rank >= 4 * n {
            break;
        }
    }
    spots
        .into_iter()
        .map(|(index, lines)| {
            let worst = lines[0];
            let mut l = lines;
            l.sort_unstable();
            let consecutive = l.windows(2).all(|w| w[1] == w[0] + 1);
            let label = match l.len() {
                1 => format!("L{worst}"),
                _ if consecutive => format!("L{}–{}", l[0], l[l.len() - 1]),
                k => format!("L{worst} +{}", k - 1),
            };
            HotSpot { index, label }
        })
        .collect()
}

/// The marks of the worst blocks on a 3-D path: neighbouring bad blocks (their worst samples
/// within 8 % of the part's diagonal of each other) share one mark. The path views and the
/// error along the path (when given the points) use this same rule, so both mark the same
/// places with the same labels.
pub(crate) fn path_hot_spots(
    points_mm: &[[f64; 3]],
    values: &[f64],
    block_line: &[u32],
    n: usize,
) -> Vec<HotSpot> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points_mm.iter().filter(|p| p.iter().all(|c| c.is_finite())) {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let diag = (0..3)
        .map(|k| (hi[k] - lo[k]).max(0.0).powi(2))
        .sum::<f64>()
        .sqrt();
    hot_spots(
        values,
        block_line,
        n,
        |a, b| {
            let (p, q) = (points_mm[a], points_mm[b]);
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        },
        0.08 * diag,
    )
}

/// The `p`-th percentile (0 … 100) of the finite values, interpolating linearly between order
/// statistics (Hyndman & Fan, *Sample quantiles in statistical packages*, 1996, definition 7,
/// the default of R and NumPy); `None` if no value is finite. With the sorted values
/// $x_{(1)} \le \dots \le x_{(n)}$ and $h = (n-1)\,p/100$:
///
/// $$ Q(p) = x_{(\lfloor h \rfloor + 1)} + (h - \lfloor h \rfloor)\,\big(x_{(\lfloor h \rfloor + 2)} - x_{(\lfloor h \rfloor + 1)}\big) $$
pub fn percentile(values: &[f64], p: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    let h = (v.len() - 1) as f64 * (p / 100.0).clamp(0.0, 1.0);
    let lo = h.floor() as usize;
    let (_, a, rest) = v.select_nth_unstable_by(lo, f64::total_cmp);
    let a = *a;
    if rest.is_empty() {
        return Some(a);
    }
    let b = rest.iter().copied().fold(f64::INFINITY, f64::min);
    Some(a + (h - lo as f64) * (b - a))
}

/// Cumulative arc length of a polyline, mm (0 at the first point).
pub fn arc_length_mm(points_mm: &[[f64; 3]]) -> Vec<f64> {
    arc_length_mm_of(points_mm.iter().copied())
}

/// [`arc_length_mm`] of points given one at a time (a long path need not be held whole).
pub fn arc_length_mm_of(points_mm: impl IntoIterator<Item = [f64; 3]>) -> Vec<f64> {
    let points = points_mm.into_iter();
    let mut s = 0.0;
    let mut out = Vec::with_capacity(points.size_hint().0);
    let mut prev: Option<[f64; 3]> = None;
    for p in points {
        if let Some(q) = prev {
            let d = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
            if d.is_finite() {
                s += d;
            }
        }
        prev = Some(p);
        out.push(s);
    }
    out
}

/// A 2-D view of the path: how to map a 3-D point to the plane, and what its axes are.
#[derive(Debug, Clone, Copy, PartialEq)]
enum View {
    /// Isometric, seen from the direction (+1, −1, +1): $u = (x + y)\cos 30°$,
    /// $v = z + (y - x)\sin 30°$ (u right, v up; +x points right-down, +y right-up, +z up).
    Iso,
    /// Orthographic onto the plane of two coordinates (indices into x y z).
    Plane(usize, usize),
}

const AXIS_NAMES: [&str; 3] = ["x", "y", "z"];

impl View {
    fn project(self, p: &[f64; 3]) -> (f64, f64) {
        match self {
            View::Iso => {
                let (c, s) = (30f64.to_radians().cos(), 0.5);
                ((p[0] + p[1]) * c, p[2] + (p[1] - p[0]) * s)
            }
            View::Plane(a, b) => (p[a], p[b]),
        }
    }

    fn title(self) -> String {
        match self {
            View::Iso => "isometric view".to_string(),
            View::Plane(a, b) => format!(
                "{}{} projection",
                AXIS_NAMES[a].to_uppercase(),
                AXIS_NAMES[b].to_uppercase()
            ),
        }
    }
}

/// The two coordinate planes that show the path best: the plane across the smallest extent
/// first (the path's own plane for a flat part), then the plane across the second smallest.
fn best_planes(points: &[[f64; 3]]) -> [View; 2] {
    let mut ext = [0.0f64; 3];
    for (k, e) in ext.iter_mut().enumerate() {
        let (lo, hi) = points
            .iter()
            .map(|p| p[k])
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        *e = if hi >= lo { hi - lo } else { 0.0 };
    }
    let mut order = [0usize, 1, 2];
    // Smallest extent first; ties keep x y z order (z dropped before y before x when equal is
    // impossible to tell apart, so a flat XY part shows XY first).
    order.sort_by(|&a, &b| ext[a].total_cmp(&ext[b]).then(b.cmp(&a)));
    let plane = |drop: usize| {
        let mut k = (0..3).filter(|&i| i != drop);
        let a = k.next().unwrap_or(0);
        let b = k.next().unwrap_or(1);
        View::Plane(a, b)
    };
    [plane(order[0]), plane(order[1])]
}

/// The colour scale of a path: `[lo, hi]` and whether values above `hi` exist.
pub(crate) struct ColourScale {
    pub lo: f64,
    pub hi: f64,
    pub max: f64,
}

impl ColourScale {
    pub(crate) fn level(&self, v: f64) -> Option<usize> {
        if !v.is_finite() {
            return None;
        }
        let f = ((v - self.lo) / (self.hi - self.lo)).clamp(0.0, 1.0);
        Some(((f * COLOUR_LEVELS as f64) as usize).min(COLOUR_LEVELS - 1))
    }

    pub(crate) fn level_colour(level: usize) -> String {
        hex(colour_map((level as f64 + 0.5) / COLOUR_LEVELS as f64))
    }
}

/// Pixel tolerance below which consecutive points of one colour are merged.
const MERGE_PX: f64 = 0.6;

/// Draws the path projected by `to_px`, one `<path>` per colour level (low levels first, so the
/// largest errors lie on top), over a dark outline that keeps light colours visible.
fn draw_coloured_path(
    svg: &mut Svg,
    clip: &str,
    pts: &[(f64, f64)],
    values: &[f64],
    cs: &ColourScale,
) {
    let mut outline = String::new();
    let mut levels: Vec<String> = vec![String::new(); COLOUR_LEVELS];
    // Runs of one colour; each segment takes the level of the larger of its two end values, so
    // a one-sample spike colours both its segments.
    let mut run: Vec<(f64, f64)> = Vec::new();
    let mut run_level: Option<usize> = None;
    let mut pending: Option<(f64, f64)> = None;
    let mut outline_run: Vec<(f64, f64)> = Vec::new();
    let flush = |run: &mut Vec<(f64, f64)>,
                 pending: &mut Option<(f64, f64)>,
                 level: Option<usize>,
                 levels: &mut Vec<String>| {
        if let Some(p) = pending.take() {
            run.push(p);
        }
        if let Some(l) = level
            && run.len() > 1
        {
            push_polyline_data(&mut levels[l], run);
        }
        run.clear();
    };
    let far = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs().max((a.1 - b.1).abs()) >= MERGE_PX;
    for i in 1..pts.len().min(values.len()) {
        let (p, q) = (pts[i - 1], pts[i]);
        let finite = p.0.is_finite() && p.1.is_finite() && q.0.is_finite() && q.1.is_finite();
        let level = if finite {
            cs.level(values[i - 1].max(values[i]))
                .or(cs.level(values[i]))
                .or(cs.level(values[i - 1]))
        } else {
            None
        };
        if !finite {
            flush(&mut run, &mut pending, run_level, &mut levels);
            run_level = None;
            let o = crate::decimate::simplify(&outline_run, 0.3);
            push_polyline_data(&mut outline, &o);
            outline_run.clear();
            continue;
        }
        if level != run_level || run.is_empty() {
            flush(&mut run, &mut pending, run_level, &mut levels);
            run_level = level;
            run.push(p);
        }
        match run.last() {
            Some(&last) if !far(last, q) => pending = Some(q),
            _ => {
                run.push(q);
                pending = None;
            }
        }
        if outline_run.last().is_none_or(|&l| far(l, q)) {
            if outline_run.is_empty() {
                outline_run.push(p);
            }
            outline_run.push(q);
        }
    }
    flush(&mut run, &mut pending, run_level, &mut levels);
    if let Some(&last) = pts.last()
        && last.0.is_finite()
        && outline_run.last() != Some(&last)
        && !outline_run.is_empty()
    {
        outline_run.push(last);
    }
    let o = crate::decimate::simplify(&outline_run, 0.3);
    push_polyline_data(&mut outline, &o);
    svg.open_group_clipped(clip);
    svg.path_d(&outline, &Stroke::solid("#2b2b2b", 3.8));
    for (l, d) in levels.iter().enumerate() {
        svg.path_d(d, &Stroke::solid(&ColourScale::level_colour(l), 2.4));
    }
    svg.close_group();
}

/// Bounds of finite 2-D points, padded 5 % (at least 1 mm).
/// (Points given one at a time: a long path's projections are never held, only their pixels.)
fn bounds(pts: impl IntoIterator<Item = (f64, f64)>) -> ((f64, f64), (f64, f64)) {
    let mut b = (
        (f64::INFINITY, f64::NEG_INFINITY),
        (f64::INFINITY, f64::NEG_INFINITY),
    );
    for (u, v) in pts {
        if u.is_finite() && v.is_finite() {
            b.0 = (b.0.0.min(u), b.0.1.max(u));
            b.1 = (b.1.0.min(v), b.1.1.max(v));
        }
    }
    let pad = |(lo, hi): (f64, f64)| {
        if lo > hi {
            return (0.0, 1.0);
        }
        let p = (0.05 * (hi - lo)).max(0.5);
        (lo - p, hi + p)
    };
    (pad(b.0), pad(b.1))
}

/// One view in its cell: frame (projections) or triad and scale bar (isometric), the coloured
/// path and the worst-block markers.
#[allow(clippy::too_many_arguments)]
fn draw_view(
    svg: &mut Svg,
    cell: Rect,
    view: View,
    path: &ColouredPath,
    cs: &ColourScale,
    worst: &[HotSpot],
    min_h: f64,
) {
    let pts = || path.points_mm.iter().map(|p| view.project(p));
    let ((u0, u1), (v0, v1)) = bounds(pts());
    let framed = matches!(view, View::Plane(..));
    let (ml, mb, mt) = if framed {
        (70.0, 44.0, 22.0)
    } else {
        (8.0, 8.0, 22.0)
    };
    let inner = Rect {
        x: cell.x + ml,
        y: cell.y + mt,
        w: cell.w - ml - 10.0,
        h: cell.h - mt - mb,
    };
    let (du, dv) = (u1 - u0, v1 - v0);
    let scale = (inner.w / du).min(inner.h / dv);
    // A very flat view gets a stretched vertical scale, said in its title.
    let ex = if dv * scale < min_h {
        (min_h / (dv * scale)).min(inner.h / (dv * scale))
    } else {
        1.0
    };
    let (w, h) = (du * scale, dv * scale * ex);
    let r = Rect {
        x: inner.x + (inner.w - w) / 2.0,
        y: inner.y + (inner.h - h) / 2.0,
        w,
        h,
    };
    let xm = AxisMap {
        lo: u0,
        hi: u1,
        scale: Scale::Linear,
        p0: r.x,
        p1: r.x + r.w,
    };
    let ym = AxisMap {
        lo: v0,
        hi: v1,
        scale: Scale::Linear,
        p0: r.y + r.h,
        p1: r.y,
    };
    let mut title = view.title();
    if ex > 1.0 + 1e-9 {
        let e = if ex < 10.0 {
            format!("{ex:.1}")
        } else {
            format!("{ex:.0}")
        };
        title.push_str(&format!(" (vertical scale ×{e})"));
    }
    let clip = if let View::Plane(a, b) = view {
        let xt = xm.ticks(chart::tick_target(r.w, 80.0));
        let yt = ym.ticks(chart::tick_target(r.h, 40.0));
        let qx = Quantity::new(AXIS_NAMES[a], style::units::MM);
        let qy = Quantity::new(AXIS_NAMES[b], style::units::MM);
        let lw = chart::y_label_width(&yt);
        chart::draw_frame(
            svg,
            r,
            &xm,
            &ym,
            &xt,
            &yt,
            &FrameOptions {
                x_quantity: &qx,
                y_quantity: &qy,
                x_labels: true,
                y_title_x: r.x - lw - style::TICK_PX - 12.0 - style::LABEL_FONT_PX / 2.0,
                title: None,
            },
        )
    } else {
        draw_triad_and_scale_bar(svg, cell, r, du * scale / du);
        svg.clip_rect(cell.x, cell.y + mt, cell.w, cell.h - mt)
    };
    svg.text(
        cell.x + if framed { ml } else { 8.0 },
        cell.y + 15.0,
        &title,
        style::PANEL_TITLE_FONT_PX,
        Anchor::Start,
        0.0,
        "#000000",
    );
    let px: Vec<(f64, f64)> = pts().map(|(u, v)| (xm.px(u), ym.px(v))).collect();
    draw_coloured_path(svg, &clip, &px, path.values, cs);
    // Worst blocks: a ring at the worst sample and the line number beside it.
    let ring = Stroke::solid("#000000", 1.4);
    let marks: Vec<(f64, f64, &str)> = worst
        .iter()
        .filter_map(|wb| {
            let &(x, y) = px.get(wb.index)?;
            (x.is_finite() && y.is_finite()).then_some((x, y, wb.label.as_str()))
        })
        .collect();
    for &(x, y, _) in &marks {
        svg.circle(x, y, 6.0, "none", Some(&ring));
    }
    // Labels: the first of four places around the ring that overlaps no label placed before.
    let mut placed: Vec<Rect> = Vec::new();
    for &(x, y, label) in &marks {
        let wl = text_width_px(label, style::TICK_FONT_PX);
        let hl = style::TICK_FONT_PX;
        let options = [
            (x + 8.0, y - 7.0, Anchor::Start),
            (x - 8.0, y - 7.0, Anchor::End),
            (x + 8.0, y + 7.0 + hl, Anchor::Start),
            (x - 8.0, y + 7.0 + hl, Anchor::End),
        ];
        let boxed = |&(lx, ly, a): &(f64, f64, Anchor)| Rect {
            x: if a == Anchor::Start { lx } else { lx - wl },
            y: ly - hl,
            w: wl,
            h: hl + 2.0,
        };
        let free = |r: &Rect| {
            placed
                .iter()
                .all(|q| r.x + r.w < q.x || q.x + q.w < r.x || r.y + r.h < q.y || q.y + q.h < r.y)
        };
        let choice = options
            .iter()
            .find(|o| free(&boxed(o)))
            .unwrap_or(&options[0]);
        placed.push(boxed(choice));
        svg.text_halo(choice.0, choice.1, label, style::TICK_FONT_PX, choice.2);
    }
}

/// Axis directions of the isometric view and a scale bar of a round length.
fn draw_triad_and_scale_bar(svg: &mut Svg, cell: Rect, r: Rect, px_per_mm: f64) {
    let o = (cell.x + 26.0, cell.y + cell.h - 26.0);
    let len = 26.0;
    let st = Stroke::solid("#333333", 1.3);
    let c = 30f64.to_radians().cos();
    for (name, (du, dv)) in [("x", (c, -0.5)), ("y", (c, 0.5)), ("z", (0.0, 1.0))] {
        let e = (o.0 + du * len, o.1 - dv * len);
        svg.line(o.0, o.1, e.0, e.1, &st);
        svg.text(
            e.0 + du * 9.0,
            e.1 - dv * 9.0 + 4.0,
            name,
            style::TICK_FONT_PX,
            Anchor::Middle,
            0.0,
            "#333333",
        );
    }
    // Scale bar: the round length nearest a fifth of the view width.
    let target_mm = r.w / px_per_mm / 5.0;
    if target_mm.is_finite() && target_mm > 0.0 {
        let e = 10f64.powf(target_mm.log10().floor());
        let m = target_mm / e;
        let nice = if m < 2.0 {
            1.0
        } else if m < 5.0 {
            2.0
        } else {
            5.0
        } * e;
        let wpx = nice * px_per_mm;
        let (x1, y) = (cell.x + cell.w - 16.0, cell.y + cell.h - 14.0);
        let x0 = x1 - wpx;
        svg.segments(
            &[
                ((x0, y), (x1, y)),
                ((x0, y - 4.0), (x0, y + 4.0)),
                ((x1, y - 4.0), (x1, y + 4.0)),
            ],
            &Stroke::solid("#333333", 1.3),
        );
        let label = format!(
            "{} mm",
            ticks::linear(0.0, nice, 2)
                .major
                .last()
                .map_or_else(|| nice.to_string(), |t| t.text.clone())
        );
        svg.text(
            (x0 + x1) / 2.0,
            y - 7.0,
            &label,
            style::TICK_FONT_PX,
            Anchor::Middle,
            0.0,
            "#333333",
        );
    }
}

/// Vertical colour bar with ticks, the clip stated under it and its label to the right of the
/// tick numbers (never over them).
pub(crate) fn draw_colour_bar(
    svg: &mut Svg,
    r: Rect,
    cs: &ColourScale,
    q: &Quantity,
    footer: &[String],
) {
    let n = COLOUR_LEVELS;
    let step = r.h / n as f64;
    for l in 0..n {
        let y = r.y + r.h - (l + 1) as f64 * step;
        // Overlap by half a pixel so no white seams show between the bands.
        svg.rect(
            r.x,
            y - 0.5,
            r.w,
            step + 1.0,
            &ColourScale::level_colour(l),
            None,
        );
    }
    let axis = Stroke::solid(style::AXIS_COLOUR, 1.0);
    svg.rect(r.x, r.y, r.w, r.h, "none", Some(&axis));
    let clipped = cs.max > cs.hi;
    if clipped {
        // An arrow head on top in the top colour: values beyond the scale exist.
        svg.polygon(
            &[
                (r.x, r.y - 1.0),
                (r.x + r.w / 2.0, r.y - 13.0),
                (r.x + r.w, r.y - 1.0),
            ],
            &ColourScale::level_colour(n - 1),
        );
    }
    let m = AxisMap {
        lo: cs.lo,
        hi: cs.hi,
        scale: Scale::Linear,
        p0: r.y + r.h,
        p1: r.y,
    };
    let t = m.ticks(chart::tick_target(r.h, 40.0));
    let segs: Vec<_> = t
        .major
        .iter()
        .map(|k| {
            let y = m.px(k.value);
            ((r.x + r.w, y), (r.x + r.w + style::TICK_PX, y))
        })
        .collect();
    svg.segments(&segs, &axis);
    let mut label_w: f64 = 0.0;
    for k in &t.major {
        let y = m.px(k.value);
        svg.text_markup(
            r.x + r.w + style::TICK_PX + 3.0,
            y + 3.8,
            &k.markup,
            style::TICK_FONT_PX,
            Anchor::Start,
            0.0,
            "#000000",
            false,
        );
        label_w = label_w.max(text_width_px(&k.text, style::TICK_FONT_PX));
    }
    let lx = r.x + r.w + style::TICK_PX + 3.0 + label_w + 10.0 + style::LABEL_FONT_PX / 2.0;
    svg.text(
        lx,
        r.y + r.h / 2.0,
        &chart::axis_title(q, &t),
        style::LABEL_FONT_PX,
        Anchor::Middle,
        -90.0,
        "#000000",
    );
    for (i, l) in footer.iter().enumerate() {
        svg.text(
            r.x - 10.0,
            r.y + r.h + 22.0 + 14.0 * i as f64,
            l,
            style::TICK_FONT_PX - 0.5,
            Anchor::Start,
            0.0,
            "#333333",
        );
    }
}

/// "99.5th", "99th", "1st", "92nd" (percentile names).
fn ordinal_pct(p: f64) -> String {
    let s = fmt_pct(p);
    let suffix = if s.contains('.') {
        "th"
    } else {
        match (p as u64 % 100, p as u64 % 10) {
            (11..=13, _) => "th",
            (_, 1) => "st",
            (_, 2) => "nd",
            (_, 3) => "rd",
            _ => "th",
        }
    };
    format!("{s}{suffix}")
}

fn fmt_pct(p: f64) -> String {
    let s = format!("{p:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// A value with three significant digits.
pub(crate) fn fmt_value(v: f64) -> String {
    if !v.is_finite() {
        return v.to_string();
    }
    let a = v.abs();
    let dec = if a >= 100.0 {
        0
    } else if a >= 10.0 {
        1
    } else if a >= 1.0 {
        2
    } else if a == 0.0 {
        0
    } else {
        (2 - a.log10().floor() as i32).max(0) as usize
    };
    let s = format!("{v:.dec$}");
    s.replace('-', "−")
}

/// The tool-tip path in three views (isometric, and the two coordinate projections that show
/// it best), coloured by `path.values` on a scale from 0 (or the lowest value, if negative) to
/// the `clip_percentile`-th percentile, with the worst blocks ringed and labelled `L<line>`.
pub fn contour_path_views(
    title: &str,
    path: &ColouredPath,
    opts: &PathViewOptions,
) -> Result<Figure, Error> {
    let n = path.points_mm.len();
    if n < 2 {
        return Err(Error::Empty {
            what: format!("{title}: fewer than two path points"),
        });
    }
    if path.values.len() != n {
        return Err(Error::LengthMismatch {
            what: format!("{title}: {}", path.value.name),
            expected: n,
            found: path.values.len(),
        });
    }
    if let Some(l) = path.block_line
        && l.len() != n
    {
        return Err(Error::LengthMismatch {
            what: format!("{title}: block line numbers"),
            expected: n,
            found: l.len(),
        });
    }
    if !(opts.clip_percentile > 0.0 && opts.clip_percentile <= 100.0) {
        return Err(Error::InvalidOption {
            what: "clip_percentile".into(),
            value: opts.clip_percentile.to_string(),
            expected: "a percentile in (0, 100]".into(),
        });
    }
    let max = path
        .values
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(f64::NEG_INFINITY, f64::max);
    let min = path
        .values
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(f64::INFINITY, f64::min);
    if !max.is_finite() {
        return Err(Error::Empty {
            what: format!("{title}: no finite {}", path.value.name),
        });
    }
    let hi = percentile(path.values, opts.clip_percentile).unwrap_or(max);
    let lo = if min >= 0.0 {
        0.0
    } else {
        percentile(path.values, 100.0 - opts.clip_percentile).unwrap_or(min)
    };
    let hi = if hi > lo { hi } else { lo + 1.0 };
    let cs = ColourScale { lo, hi, max };
    let worst = path
        .block_line
        .map(|l| worst_blocks(path.values, l, opts.worst_blocks))
        .unwrap_or_default();
    let spots = path
        .block_line
        .map(|l| path_hot_spots(path.points_mm, path.values, l, opts.worst_blocks))
        .unwrap_or_default();

    let w = opts.width_px;
    let bar_col = 150.0;
    let left_w = w - bar_col - 10.0;
    let cell = (left_w / 2.0).floor();
    let planes = best_planes(path.points_mm);
    // Height of the second projection's cell from its aspect ratio.
    let ((bu0, bu1), (bv0, bv1)) = bounds(path.points_mm.iter().map(|p| planes[1].project(p)));
    let inner_w = left_w - 80.0;
    let row2_h = ((bv1 - bv0) / (bu1 - bu0) * inner_w).clamp(90.0, cell - 66.0) + 66.0;

    let mut note = format!(
        "colour: {} ({}), scale 0 … {} {} ({} percentile)",
        path.value.name,
        path.value.unit,
        fmt_value(hi),
        path.value.unit,
        ordinal_pct(opts.clip_percentile)
    );
    if lo != 0.0 {
        note = note.replacen(" 0 …", &format!(" {} …", fmt_value(lo)), 1);
    }
    if !worst.is_empty() {
        let list: Vec<String> = worst
            .iter()
            .map(|b| format!("L{} {}", b.line, fmt_value(b.value)))
            .collect();
        note.push_str(&format!(
            "; worst blocks ({}): {}",
            path.value.unit,
            list.join(", ")
        ));
    }
    let top0 = 24.0 + 10.0 + 18.0;
    let h = top0 + cell + row2_h + 10.0;
    let mut svg = Svg::new(w, h);
    let top = draw_title(&mut svg, title, &note, 12.0);
    let c1 = Rect {
        x: 0.0,
        y: top,
        w: cell,
        h: cell,
    };
    let c2 = Rect {
        x: cell,
        y: top,
        w: cell,
        h: cell,
    };
    let c3 = Rect {
        x: 0.0,
        y: top + cell,
        w: left_w,
        h: row2_h,
    };
    draw_view(&mut svg, c1, View::Iso, path, &cs, &spots, 60.0);
    draw_view(&mut svg, c2, planes[0], path, &cs, &spots, 60.0);
    draw_view(&mut svg, c3, planes[1], path, &cs, &spots, 60.0);
    let bar = Rect {
        x: left_w + 24.0,
        y: top + 40.0,
        w: 16.0,
        h: cell - 120.0,
    };
    let unit = if path.value.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", path.value.unit)
    };
    let pct = opts.clip_percentile;
    let footer = if cs.max > cs.hi {
        vec![
            "scale clipped at the".to_string(),
            format!("{} percentile:", ordinal_pct(pct)),
            format!(
                "{}{unit} (max {}{unit})",
                fmt_value(cs.hi),
                fmt_value(cs.max)
            ),
        ]
    } else {
        vec![
            "scale up to the".to_string(),
            format!("{} percentile", ordinal_pct(pct)),
            format!("= max, {}{unit}", fmt_value(cs.max)),
        ]
    };
    draw_colour_bar(&mut svg, bar, &cs, &path.value, &footer);
    Ok(Figure {
        title: title.to_string(),
        svg: svg.finish(title, style::FONT_FAMILY),
        width_px: w,
        height_px: h,
    })
}

/// Errors along the path: the contour error against arc length on top, the orientation error
/// below, each with a difference panel when models are compared with a truth; the worst blocks
/// (by the truth's contour error) marked by dashed lines labelled `L<line>`.
#[derive(Debug, Clone, PartialEq)]
pub struct PathErrors<'a> {
    /// Arc length of the reference tool-tip path at each sample, mm.
    pub arc_length_mm: &'a [f64],
    /// Contour error of the truth (true machine or measurement), µm.
    pub contour_truth: Series<'a>,
    /// Contour errors of the models, µm.
    pub contour_models: Vec<Series<'a>>,
    /// Orientation error of the truth, mrad.
    pub orientation_truth: Series<'a>,
    /// Orientation errors of the models, mrad.
    pub orientation_models: Vec<Series<'a>>,
    /// Source line of each sample's block, to mark the worst blocks.
    pub block_line: Option<&'a [u32]>,
    /// How many worst blocks to mark.
    pub worst_blocks: usize,
    /// The tool-tip points the contour error belongs to (mm), when known: the worst blocks are
    /// then merged into marks by distance on the part, exactly as [`contour_path_views`] of the
    /// same points and values does, so both figures mark the same places. `None`: blocks within
    /// 2 % of the path's length of each other share a mark.
    pub points_mm: Option<&'a [[f64; 3]]>,
}

/// Renders [`PathErrors`] (x: arc length s in mm).
pub fn error_along_path(title: &str, e: &PathErrors) -> Result<Figure, Error> {
    let n = e.arc_length_mm.len();
    for s in std::iter::once(&e.contour_truth)
        .chain(&e.contour_models)
        .chain(std::iter::once(&e.orientation_truth))
        .chain(&e.orientation_models)
    {
        if s.x.len() != n {
            return Err(Error::LengthMismatch {
                what: format!("{title}: series '{}' x (arc length)", s.label),
                expected: n,
                found: s.x.len(),
            });
        }
    }
    let markers = match e.block_line {
        Some(l) => {
            if l.len() != n {
                return Err(Error::LengthMismatch {
                    what: format!("{title}: block line numbers"),
                    expected: n,
                    found: l.len(),
                });
            }
            let s = e.arc_length_mm;
            let total = s
                .iter()
                .copied()
                .filter(|v| v.is_finite())
                .fold(0.0, f64::max);
            let spots = match e.points_mm {
                Some(p) if p.len() == n => path_hot_spots(p, e.contour_truth.y, l, e.worst_blocks),
                Some(p) => {
                    return Err(Error::LengthMismatch {
                        what: format!("{title}: tool-tip points"),
                        expected: n,
                        found: p.len(),
                    });
                }
                None => hot_spots(
                    e.contour_truth.y,
                    l,
                    e.worst_blocks,
                    |a, b| (s[a] - s[b]).abs(),
                    0.02 * total,
                ),
            };
            spots
                .into_iter()
                .map(|h| XMarker {
                    x: s[h.index],
                    label: h.label,
                })
                .collect()
        }
        None => Vec::new(),
    };
    let cmp = [
        Comparison {
            title: None,
            y: Axis::linear("contour error", style::units::UM),
            truth: e.contour_truth.clone(),
            others: e.contour_models.clone(),
            difference: Some(Quantity::new("model − truth", style::units::UM)),
        },
        Comparison {
            title: None,
            y: Axis::linear("orientation error", style::units::MRAD),
            truth: e.orientation_truth.clone(),
            others: e.orientation_models.clone(),
            difference: Some(Quantity::new("model − truth", style::units::MRAD)),
        },
    ];
    comparison_figure(
        title,
        "",
        Axis::linear("arc length s", style::units::MM),
        &cmp,
        markers,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentile_matches_the_textbook_definition() {
        // Hyndman & Fan type 7 on 1..=5: p = 50 → 3, p = 90 → 4.6 (h = 3.6).
        let v = [5.0, 1.0, 4.0, 2.0, 3.0];
        approx::assert_abs_diff_eq!(percentile(&v, 50.0).unwrap(), 3.0);
        approx::assert_abs_diff_eq!(percentile(&v, 90.0).unwrap(), 4.6, epsilon = 1e-12);
        approx::assert_abs_diff_eq!(percentile(&v, 100.0).unwrap(), 5.0);
        assert_eq!(percentile(&[f64::NAN], 50.0), None);
    }

    #[test]
    fn worst_blocks_name_each_line_once_at_its_worst_sample() {
        let v = [1.0, 9.0, 2.0, 8.0, 7.0, f64::NAN, 3.0];
        let l = [10, 10, 11, 12, 12, 13, 13];
        let w = worst_blocks(&v, &l, 3);
        assert_eq!(
            w,
            vec![
                WorstBlock {
                    line: 10,
                    index: 1,
                    value: 9.0
                },
                WorstBlock {
                    line: 12,
                    index: 3,
                    value: 8.0
                },
                WorstBlock {
                    line: 13,
                    index: 6,
                    value: 3.0
                },
            ]
        );
    }

    #[test]
    fn a_flat_part_is_shown_from_above_first() {
        let pts: Vec<[f64; 3]> = (0..100)
            .map(|k| {
                let a = k as f64 * 0.1;
                [50.0 * a.cos(), 30.0 * a.sin(), 0.01 * a]
            })
            .collect();
        assert_eq!(best_planes(&pts), [View::Plane(0, 1), View::Plane(0, 2)]);
    }

    #[test]
    fn a_spike_keeps_its_colour_and_the_scale_is_clipped() {
        let n = 20_000;
        let pts: Vec<[f64; 3]> = (0..n)
            .map(|k| {
                let a = k as f64 * 1e-3;
                [40.0 * a.cos(), 40.0 * a.sin(), a]
            })
            .collect();
        let mut v: Vec<f64> = (0..n).map(|k| 10.0 + (k % 100) as f64 * 0.01).collect();
        v[12_345] = 500.0;
        let lines: Vec<u32> = (0..n).map(|k| 1 + k as u32 / 100).collect();
        let p = ColouredPath {
            points_mm: &pts,
            values: &v,
            value: Quantity::new("contour error", "µm"),
            block_line: Some(&lines),
        };
        let f = contour_path_views("t", &p, &PathViewOptions::default()).unwrap();
        let top = ColourScale::level_colour(COLOUR_LEVELS - 1);
        assert!(
            f.svg.contains(&format!("stroke=\"{top}\"")),
            "spike drawn in the top colour"
        );
        assert!(f.svg.contains("L124"), "the spike's block is labelled");
        assert!(f.svg.contains("99.5th percentile"));
        assert!(f.svg.len() < 200_000, "{} bytes", f.svg.len());
        // Same input, same bytes.
        let g = contour_path_views("t", &p, &PathViewOptions::default()).unwrap();
        assert_eq!(f.svg, g.svg);
    }
}

#[cfg(test)]
mod long_path {
    use super::*;

    #[test]
    fn a_million_point_path_stays_a_light_svg() {
        // Size is bounded by pixels, not samples: runs of one colour merge below 0.6 px.
        let n = 1_000_000;
        let pts: Vec<[f64; 3]> = (0..n)
            .map(|k| {
                let s = k as f64 / n as f64;
                let a = s * 6.0 * std::f64::consts::PI;
                [
                    30.0 + (20.0 + 50.0 * s) * a.cos(),
                    15.0 + (20.0 + 50.0 * s) * a.sin(),
                    -6.0 * s,
                ]
            })
            .collect();
        let v: Vec<f64> = (0..n)
            .map(|k| 400.0 * (k as f64 / n as f64 * 37.0).sin().abs())
            .collect();
        let p = ColouredPath {
            points_mm: &pts,
            values: &v,
            value: Quantity::new("contour error", "µm"),
            block_line: None,
        };
        let f = contour_path_views("t", &p, &PathViewOptions::default()).unwrap();
        assert!(f.svg.len() < 300_000, "{} bytes", f.svg.len());
    }
}
