//! A sweep over two keys as a heat map: one cell per configuration, coloured by the result.

use crate::chart::Rect;
use crate::error::Error;
use crate::figure::Figure;
use crate::lines::draw_title;
use crate::path::{ColourScale, draw_colour_bar, fmt_value};
use crate::style::{self, Quantity, colour_map, text_width_px};
use crate::svg::{Anchor, Stroke, Svg};

/// Results on a grid of two swept keys.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatMap<'a> {
    /// The key along the columns.
    pub x_key: Quantity,
    /// Its values, one per column (in the order to draw).
    pub x_values: &'a [f64],
    /// The key along the rows.
    pub y_key: Quantity,
    /// Its values, one per row (drawn bottom to top).
    pub y_values: &'a [f64],
    /// The result.
    pub result: Quantity,
    /// Row-major results: `values[j * x_values.len() + i]` belongs to `(x_values[i],
    /// y_values[j])`; NaN marks a configuration without a result (drawn hatched grey).
    pub values: &'a [f64],
}

/// A sweep table put on a grid (see [`grid_from_rows`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SweepGrid {
    /// Distinct values of the first key, ascending (columns).
    pub x_values: Vec<f64>,
    /// Distinct values of the second key, ascending (rows).
    pub y_values: Vec<f64>,
    /// Row-major results, `values[j * x_values.len() + i]`; NaN where no row gave one.
    pub values: Vec<f64>,
}

/// Sorted distinct key values and the row-major grid of a scattered sweep table (one row per
/// configuration: key 1, key 2, result). Configurations missing from the table are NaN; when a
/// pair occurs twice the later row wins.
pub fn grid_from_rows(x: &[f64], y: &[f64], z: &[f64]) -> Result<SweepGrid, Error> {
    for (what, v) in [("second key", y), ("result", z)] {
        if v.len() != x.len() {
            return Err(Error::LengthMismatch {
                what: format!("sweep table {what}"),
                expected: x.len(),
                found: v.len(),
            });
        }
    }
    let distinct = |v: &[f64], what: &str| -> Result<Vec<f64>, Error> {
        if let Some((i, bad)) = v.iter().enumerate().find(|(_, a)| !a.is_finite()) {
            return Err(Error::NonFinite {
                what: format!("sweep table {what}"),
                index: i,
                value: *bad,
            });
        }
        let mut d = v.to_vec();
        d.sort_by(f64::total_cmp);
        d.dedup();
        Ok(d)
    };
    let xs = distinct(x, "first key")?;
    let ys = distinct(y, "second key")?;
    let mut grid = vec![f64::NAN; xs.len() * ys.len()];
    for ((a, b), c) in x.iter().zip(y).zip(z) {
        let i = xs.partition_point(|v| v < a);
        let j = ys.partition_point(|v| v < b);
        grid[j * xs.len() + i] = *c;
    }
    Ok(SweepGrid {
        x_values: xs,
        y_values: ys,
        values: grid,
    })
}

/// A swept key value as printed: its shortest exact form when short (`0.002`, `350`), else
/// three significant digits.
fn fmt_key(v: f64) -> String {
    let s = format!("{v}");
    if s.len() <= 8 {
        s.replace('-', "−")
    } else {
        fmt_value(v)
    }
}

/// Renders a [`HeatMap`]: cells coloured on the sequential map from the smallest to the
/// largest result, the value printed in each cell when it fits, the smallest result outlined.
pub fn sweep_heatmap(title: &str, m: &HeatMap) -> Result<Figure, Error> {
    let (nx, ny) = (m.x_values.len(), m.y_values.len());
    if nx == 0 || ny == 0 {
        return Err(Error::Empty {
            what: title.to_string(),
        });
    }
    if m.values.len() != nx * ny {
        return Err(Error::LengthMismatch {
            what: format!("{title}: results (columns × rows = {nx} × {ny})"),
            expected: nx * ny,
            found: m.values.len(),
        });
    }
    let finite = || m.values.iter().copied().filter(|v| v.is_finite());
    let lo = finite().fold(f64::INFINITY, f64::min);
    let hi = finite().fold(f64::NEG_INFINITY, f64::max);
    if lo > hi {
        return Err(Error::Empty {
            what: format!("{title}: no finite result"),
        });
    }
    let hi_s = if hi > lo { hi } else { lo + 1.0 };
    let cs = ColourScale {
        lo,
        hi: hi_s,
        max: hi,
    };
    let best = m
        .values
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .min_by(|a, b| a.1.total_cmp(b.1).then(a.0.cmp(&b.0)))
        .map(|(k, _)| k);

    let ylabels: Vec<String> = m.y_values.iter().map(|v| fmt_key(*v)).collect();
    let label_w = ylabels
        .iter()
        .map(|s| text_width_px(s, style::TICK_FONT_PX))
        .fold(0.0, f64::max);
    let w = style::FIGURE_WIDTH_PX;
    let left = label_w + 8.0 + style::LABEL_FONT_PX + 14.0;
    let bar_col = 170.0;
    let plot_w = w - left - bar_col;
    let cell_w = plot_w / nx as f64;
    // Rows tall enough for the rotated y label to fit beside them (up to 140 px a row).
    let y_label_h = text_width_px(&m.y_key.label(), style::LABEL_FONT_PX) + 10.0;
    let cell_h = (plot_w * 0.6 / ny as f64)
        .clamp(22.0, 60.0)
        .max((y_label_h / ny as f64).min(140.0));
    let plot_h = cell_h * ny as f64;
    let note = match best {
        Some(k) => format!(
            "smallest {}: {} {} at {} = {}, {} = {} (outlined)",
            m.result.name,
            fmt_value(m.values[k]),
            m.result.unit,
            m.x_key.name,
            fmt_key(m.x_values[k % nx]),
            m.y_key.name,
            fmt_key(m.y_values[k / nx])
        ),
        None => String::new(),
    };
    let h = 24.0 + 10.0 + 18.0 + 6.0 + plot_h.max(120.0) + 50.0;
    let mut svg = Svg::new(w, h);
    let top = draw_title(&mut svg, title, &note, 12.0) + 6.0;
    let r = Rect {
        x: left,
        y: top,
        w: plot_w,
        h: plot_h,
    };
    let grid = Stroke::solid("#ffffff", 1.0);
    for j in 0..ny {
        for i in 0..nx {
            let v = m.values[j * nx + i];
            let x = r.x + i as f64 * cell_w;
            let y = r.y + r.h - (j + 1) as f64 * cell_h;
            match cs.level(v) {
                Some(_) => {
                    let f = (v - cs.lo) / (cs.hi - cs.lo);
                    let c = colour_map(f);
                    svg.rect(x, y, cell_w, cell_h, &style::hex(c), Some(&grid));
                    let t = fmt_value(v);
                    if text_width_px(&t, style::TICK_FONT_PX) + 6.0 < cell_w && cell_h >= 16.0 {
                        svg.text(
                            x + cell_w / 2.0,
                            y + cell_h / 2.0 + 4.0,
                            &t,
                            style::TICK_FONT_PX,
                            Anchor::Middle,
                            0.0,
                            style::text_on(c),
                        );
                    }
                }
                None => {
                    svg.rect(x, y, cell_w, cell_h, "#e6e6e6", Some(&grid));
                    svg.text(
                        x + cell_w / 2.0,
                        y + cell_h / 2.0 + 4.0,
                        "–",
                        style::TICK_FONT_PX,
                        Anchor::Middle,
                        0.0,
                        "#777777",
                    );
                }
            }
        }
    }
    if let Some(k) = best {
        let (i, j) = (k % nx, k / nx);
        svg.rect(
            r.x + i as f64 * cell_w + 1.0,
            r.y + r.h - (j + 1) as f64 * cell_h + 1.0,
            cell_w - 2.0,
            cell_h - 2.0,
            "none",
            Some(&Stroke::solid("#000000", 2.2)),
        );
    }
    // Column and row labels (categorical: the swept values themselves).
    let xstep = {
        let widest = m
            .x_values
            .iter()
            .map(|v| text_width_px(&fmt_key(*v), style::TICK_FONT_PX))
            .fold(0.0, f64::max);
        ((widest + 8.0) / cell_w).ceil().max(1.0) as usize
    };
    for (i, v) in m.x_values.iter().enumerate().step_by(xstep) {
        svg.text(
            r.x + (i as f64 + 0.5) * cell_w,
            r.y + r.h + 16.0,
            &fmt_key(*v),
            style::TICK_FONT_PX,
            Anchor::Middle,
            0.0,
            "#000000",
        );
    }
    let ystep = ((14.0 / cell_h).ceil().max(1.0)) as usize;
    for (j, l) in ylabels.iter().enumerate().step_by(ystep) {
        svg.text(
            r.x - 6.0,
            r.y + r.h - (j as f64 + 0.5) * cell_h + 4.0,
            l,
            style::TICK_FONT_PX,
            Anchor::End,
            0.0,
            "#000000",
        );
    }
    svg.text(
        r.x + r.w / 2.0,
        r.y + r.h + 38.0,
        &m.x_key.label(),
        style::LABEL_FONT_PX,
        Anchor::Middle,
        0.0,
        "#000000",
    );
    svg.text(
        left - label_w - 14.0 - style::LABEL_FONT_PX / 2.0,
        r.y + r.h / 2.0,
        &m.y_key.label(),
        style::LABEL_FONT_PX,
        Anchor::Middle,
        -90.0,
        "#000000",
    );
    let bar = Rect {
        x: r.x + r.w + 30.0,
        y: r.y,
        w: 16.0,
        h: r.h.max(120.0),
    };
    draw_colour_bar(&mut svg, bar, &cs, &m.result, &[]);
    Ok(Figure {
        title: title.to_string(),
        svg: svg.finish(title, style::FONT_FAMILY),
        width_px: w,
        height_px: h,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scattered_rows_land_in_their_cells() {
        let x = [2.0, 1.0, 2.0, 1.0];
        let y = [10.0, 10.0, 20.0, 20.0];
        let z = [4.0, 3.0, 6.0, 5.0];
        let g = grid_from_rows(&x, &y, &z).unwrap();
        assert_eq!(g.x_values, [1.0, 2.0]);
        assert_eq!(g.y_values, [10.0, 20.0]);
        assert_eq!(g.values, [3.0, 4.0, 5.0, 6.0]);
        let g = grid_from_rows(&x[..3], &y[..3], &z[..3]).unwrap();
        assert!(g.values[2].is_nan());
        assert!(grid_from_rows(&[f64::NAN], &[1.0], &[1.0]).is_err());
    }

    #[test]
    fn the_best_cell_is_named_in_the_note() {
        let SweepGrid {
            x_values: xs,
            y_values: ys,
            values: g,
        } = grid_from_rows(
            &[1.0, 2.0, 1.0, 2.0],
            &[5.0, 5.0, 6.0, 6.0],
            &[9.0, 2.5, 7.0, 8.0],
        )
        .unwrap();
        let f = sweep_heatmap(
            "sweep",
            &HeatMap {
                x_key: Quantity::new("kp", ""),
                x_values: &xs,
                y_key: Quantity::new("feed", "mm/min"),
                y_values: &ys,
                result: Quantity::new("max contour error", "µm"),
                values: &g,
            },
        )
        .unwrap();
        assert!(
            f.svg
                .contains("smallest max contour error: 2.50 µm at kp = 2, feed = 5"),
            "{}",
            f.svg
        );
    }
}
