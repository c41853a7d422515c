//! Figures a paper would print, a report a person can open, and a 3-D view of the error on
//! the part — built from plain data (slices, labels, units, roles), so any command can use it.
//!
//! ```text
//!   plain data (slices, Quantity, Role)
//!        │
//!        ├─ style ─── one look: colour per Role, fonts, "quantity (unit)", viridis
//!        │
//!        ├─ line_figure / comparison_figure / tracking_errors      time series, differences
//!        ├─ bode / convergence / sweep_line                         log axes with decades
//!        ├─ contour_path_views / error_along_path                   the path coloured by error
//!        ├─ sweep_heatmap (grid_from_rows)                          two swept keys
//!        │        └─► Figure (SVG text) ─► Figure::save
//!        │
//!        ├─ Manifest (manifest.json) + summary.json + SVGs ─► build_report ─► report.html
//!        └─ VtpPath ─► write_vtp ─► path.vtp (ParaView)
//! ```
//!
//! Rules every figure follows (see [`style`]):
//! 1. every axis names its quantity and unit ("contour error (µm)"), with a real µ and minus;
//! 2. a curve's look comes from its [`Role`] (reference, true machine, measurement, vcnc model,
//!    paper's method), the same in every command, from a colour-blind-safe palette;
//! 3. legends sit outside the data, above the panels;
//! 4. log axes print decades (0.1, 1, 10 … or 10ⁿ) with minor ticks at 2 … 9;
//! 5. coordinates are kept to 0.1 px (no stair-steps), long series are reduced to the
//!    first/min/max/last sample of each pixel column (a spike is never lost);
//! 6. curves that lie on top of each other are drawn thick-under-thin, and compared in a
//!    difference panel of their own;
//! 7. only the axes a program uses get panels.
//!
//! ```
//! use vcnc_report::{Axis, LineFigure, Panel, Role, Series, line_figure};
//!
//! let t: Vec<f64> = (0..1000).map(|k| k as f64 * 1e-3).collect();
//! let truth: Vec<f64> = t.iter().map(|t| 50.0 * (20.0 * t).sin()).collect();
//! let model: Vec<f64> = truth.iter().map(|e| e * 1.01).collect();
//! let fig = line_figure(&LineFigure::new(
//!     "axis X: tracking error",
//!     Axis::linear("time t", "s"),
//!     vec![Panel::new(
//!         Axis::linear("tracking error x_r − x", "µm"),
//!         vec![
//!             Series::line("true machine", Role::TrueMachine, &t, &truth),
//!             Series::line("vcnc model", Role::Model, &t, &model),
//!         ],
//!     )],
//! ))
//! .unwrap();
//! assert!(fig.svg.contains("tracking error x_r − x (µm)"));
//! ```

mod chart;
mod decimate;
mod error;
mod figure;
mod lines;
mod map;
mod path;
pub mod report;
pub mod style;
mod svg;
mod ticks;
pub mod vtp;

pub use chart::{Axis, Mark, Scale, Series};
pub use decimate::min_max_per_column;
pub use error::Error;
pub use figure::{Figure, write_atomic};
pub use lines::{
    AxisErrors, BodeCurve, BodeGroup, Comparison, LineFigure, Panel, XMarker, axis_is_used, bode,
    comparison_figure, convergence, line_figure, sweep_line, tracking_errors,
};
pub use map::{HeatMap, SweepGrid, grid_from_rows, sweep_heatmap};
pub use path::{
    ColouredPath, PathErrors, PathViewOptions, WorstBlock, arc_length_mm, arc_length_mm_of,
    contour_path_views, error_along_path, percentile, worst_blocks,
};
pub use report::{
    FigureEntry, FileEntry, Input, MANIFEST_FILE, Manifest, REPORT_FILE, Table, build_report,
};
pub use style::{Quantity, Role};
pub use vtp::{PointScalars, PointVectors, Vectors, VtpEncoding, VtpPath, write_vtp};
