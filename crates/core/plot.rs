//! SVG plots (plotters, SVG backend only: no system font libraries needed). Every plot is rendered
//! to a string and written atomically.

use std::path::Path;

use anyhow::{Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::output::write_atomic;

/// One named curve.
pub struct Series<'a> {
    /// Legend text.
    pub name: String,
    /// Abscissae.
    pub x: &'a [f64],
    /// Ordinates (same length as `x`).
    pub y: &'a [f64],
}

/// Axis scaling of a line plot.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    Linear,
    Log10,
}

/// Line plot description.
pub struct LinePlot<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub x_scale: Scale,
    pub series: Vec<Series<'a>>,
}

/// A scatter plot: each series drawn as dots (sweep results against one swept key).
pub fn write_scatter(path: &Path, plot: &LinePlot) -> Result<()> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let all = || {
            plot.series
                .iter()
                .flat_map(|s| s.x.iter().copied().zip(s.y.iter().copied()))
        };
        let (x0, x1) = finite_range(all().map(|p| p.0)).unwrap_or((0.0, 1.0));
        let (y0, y1) = finite_range(all().map(|p| p.1)).unwrap_or((0.0, 1.0));
        let mut chart = ChartBuilder::on(&root)
            .caption(plot.title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc(plot.x_label)
            .y_desc(plot.y_label)
            .light_line_style(WHITE)
            .draw()
            .map_err(plot_err)?;
        for (i, s) in plot.series.iter().enumerate() {
            let c = colour(i);
            let pts: Vec<(f64, f64)> =
                s.x.iter()
                    .copied()
                    .zip(s.y.iter().copied())
                    .filter(|(x, y)| x.is_finite() && y.is_finite())
                    .collect();
            chart
                .draw_series(pts.into_iter().map(|p| Circle::new(p, 3, c.filled())))
                .map_err(plot_err)?
                .label(s.name.clone())
                .legend(move |(x, y)| Circle::new((x + 8, y), 3, c.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    write_atomic(path, svg.as_bytes())
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(23, 190, 207),
];

fn colour(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

fn plot_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("plotting failed: {e:?}")
}

/// Keeps at most about `max_points` points of a curve while preserving its envelope: each bucket
/// contributes its first, minimum and maximum point (a plot of 30 000 samples stays a light SVG
/// and still shows every peak).
pub fn decimate(x: &[f64], y: &[f64], max_points: usize) -> Vec<(f64, f64)> {
    let n = x.len().min(y.len());
    if n <= max_points || max_points < 3 {
        return (0..n).map(|k| (x[k], y[k])).collect();
    }
    let buckets = max_points / 3;
    let per = n.div_ceil(buckets);
    let mut out = Vec::with_capacity(3 * buckets + 1);
    let mut start = 0;
    while start < n {
        let end = (start + per).min(n);
        let (mut kmin, mut kmax) = (start, start);
        for k in start..end {
            if y[k] < y[kmin] {
                kmin = k;
            }
            if y[k] > y[kmax] {
                kmax = k;
            }
        }
        let mut idx = [start, kmin, kmax];
        idx.sort_unstable();
        for (j, &k) in idx.iter().enumerate() {
            if j == 0 || k != idx[j - 1] {
                out.push((x[k], y[k]));
            }
        }
        start = end;
    }
    if out.last().is_some_and(|&(lx, _)| lx != x[n - 1]) {
        out.push((x[n - 1], y[n - 1]));
    }
    out
}

fn finite_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if lo > hi {
        return None;
    }
    if hi - lo < 1e-12 * (1.0 + hi.abs()) {
        let pad = 0.5 * (1.0 + hi.abs()) * 1e-3;
        return Some((lo - pad, hi + pad));
    }
    let pad = 0.04 * (hi - lo);
    Some((lo - pad, hi + pad))
}

fn draw_lines(area: &DrawingArea<SVGBackend, Shift>, plot: &LinePlot) -> Result<()> {
    let curves: Vec<Vec<(f64, f64)>> = plot
        .series
        .iter()
        .map(|s| {
            let pts = decimate(s.x, s.y, 3000);
            match plot.x_scale {
                Scale::Linear => pts,
                Scale::Log10 => pts.into_iter().filter(|(x, _)| *x > 0.0).collect(),
            }
        })
        .collect();
    let (x0, x1) = finite_range(curves.iter().flatten().map(|p| p.0)).unwrap_or((0.0, 1.0));
    let (y0, y1) = finite_range(curves.iter().flatten().map(|p| p.1)).unwrap_or((0.0, 1.0));
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(plot.title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70);
    match plot.x_scale {
        Scale::Linear => {
            let mut chart = builder
                .build_cartesian_2d(x0..x1, y0..y1)
                .map_err(plot_err)?;
            chart
                .configure_mesh()
                .x_desc(plot.x_label)
                .y_desc(plot.y_label)
                .light_line_style(WHITE)
                .draw()
                .map_err(plot_err)?;
            for (i, (s, pts)) in plot.series.iter().zip(&curves).enumerate() {
                let c = colour(i);
                chart
                    .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(1)))
                    .map_err(plot_err)?
                    .label(s.name.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                    });
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(plot_err)?;
        }
        Scale::Log10 => {
            // No linear padding on a log axis: the data's own positive extent.
            let xs = || {
                curves
                    .iter()
                    .flatten()
                    .map(|p| p.0)
                    .filter(|x| *x > 0.0 && x.is_finite())
            };
            let lo = xs().fold(f64::INFINITY, f64::min);
            let hi = xs().fold(0.0f64, f64::max);
            let (lo, hi) = if lo < hi {
                (lo, hi)
            } else {
                (x0.max(1e-9), x1.max(1e-9) * 10.0)
            };
            let mut chart = builder
                .build_cartesian_2d((lo..hi).log_scale(), y0..y1)
                .map_err(plot_err)?;
            chart
                .configure_mesh()
                .x_desc(plot.x_label)
                .y_desc(plot.y_label)
                .light_line_style(WHITE)
                .draw()
                .map_err(plot_err)?;
            for (i, (s, pts)) in plot.series.iter().zip(&curves).enumerate() {
                let c = colour(i);
                chart
                    .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(1)))
                    .map_err(plot_err)?
                    .label(s.name.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                    });
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(plot_err)?;
        }
    }
    Ok(())
}

/// Renders panels stacked vertically into one SVG file.
pub fn write_panels(path: &Path, panels: &[LinePlot], width: u32, panel_height: u32) -> Result<()> {
    let mut svg = String::new();
    {
        let height = panel_height * panels.len().max(1) as u32;
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let areas = root.split_evenly((panels.len().max(1), 1));
        for (area, plot) in areas.iter().zip(panels) {
            draw_lines(area, plot)?;
        }
        root.present().map_err(plot_err)?;
    }
    write_atomic(path, svg.as_bytes())
}

/// A single line plot.
pub fn write_line_plot(path: &Path, plot: &LinePlot) -> Result<()> {
    write_panels(path, std::slice::from_ref(plot), 900, 420)
}

/// A path in the plane, each point coloured by a value (e.g. the tool path coloured by contour
/// error), with a colour bar legend given as text.
pub fn write_coloured_path(
    path: &Path,
    title: &str,
    labels: (&str, &str),
    xy: &[(f64, f64)],
    value: &[f64],
    value_label: &str,
) -> Result<()> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (800, 700)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (main, bar) = root.split_horizontally(650);
        let (x0, x1) = finite_range(xy.iter().map(|p| p.0)).unwrap_or((0.0, 1.0));
        let (y0, y1) = finite_range(xy.iter().map(|p| p.1)).unwrap_or((0.0, 1.0));
        // Equal scales on both axes.
        let span = (x1 - x0).max(y1 - y0);
        let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        let mut chart = ChartBuilder::on(&main)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(
                cx - span / 2.0..cx + span / 2.0,
                cy - span / 2.0..cy + span / 2.0,
            )
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc(labels.0)
            .y_desc(labels.1)
            .light_line_style(WHITE)
            .draw()
            .map_err(plot_err)?;
        let vmax = value
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max);
        let scale = if vmax > 0.0 { 1.0 / vmax } else { 0.0 };
        let stride = (xy.len() / 4000).max(1);
        let n = xy.len().min(value.len());
        let segs = (stride..n).step_by(stride).map(|k| {
            let c = heat(value[k] * scale);
            PathElement::new(vec![xy[k - stride], xy[k]], c.stroke_width(2))
        });
        chart.draw_series(segs).map_err(plot_err)?;
        // Colour bar.
        let steps = 50;
        let bar = bar.margin(80, 60, 10, 30);
        let (_, h) = bar.dim_in_pixel();
        for i in 0..steps {
            let f = i as f64 / (steps - 1) as f64;
            let y0p = (h as f64 * (1.0 - f)) as i32;
            bar.draw(&Rectangle::new(
                [(0, y0p - (h as i32 / steps) - 1), (24, y0p)],
                heat(f).filled(),
            ))
            .map_err(plot_err)?;
        }
        let style = ("sans-serif", 12).into_font();
        bar.draw(&Text::new(format!("{vmax:.1}"), (0, -18), style.clone()))
            .map_err(plot_err)?;
        bar.draw(&Text::new("0", (0, h as i32 + 4), style.clone()))
            .map_err(plot_err)?;
        bar.draw(&Text::new(value_label.to_string(), (-20, -48), style))
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    write_atomic(path, svg.as_bytes())
}

/// Blue → green → yellow → red ramp for `f` in [0, 1].
fn heat(f: f64) -> RGBColor {
    let f = if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let stops = [
        (0.0, (49, 54, 149)),
        (0.35, (69, 170, 110)),
        (0.65, (240, 200, 40)),
        (1.0, (215, 25, 28)),
    ];
    for w in stops.windows(2) {
        let (f0, c0) = w[0];
        let (f1, c1) = w[1];
        if f <= f1 {
            let t = (f - f0) / (f1 - f0);
            let mix = |a: u8, b: u8| (a as f64 + t * (b as f64 - a as f64)).round() as u8;
            return RGBColor(mix(c0.0, c1.0), mix(c0.1, c1.1), mix(c0.2, c1.2));
        }
    }
    RGBColor(215, 25, 28)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_extremes_and_ends() {
        let x: Vec<f64> = (0..10_000).map(|k| k as f64).collect();
        let mut y = vec![0.0; 10_000];
        y[4321] = 5.0;
        y[777] = -3.0;
        let d = decimate(&x, &y, 300);
        assert!(d.len() <= 302);
        assert!(d.contains(&(4321.0, 5.0)));
        assert!(d.contains(&(777.0, -3.0)));
        assert_eq!(d.first(), Some(&(0.0, 0.0)));
        assert_eq!(d.last(), Some(&(9999.0, 0.0)));
    }
}
