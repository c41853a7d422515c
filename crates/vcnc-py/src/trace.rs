//! `vcnc.read_trace`: a scope file of any format vcnc reads, its channels as numpy arrays, and
//! its axes paired (`Trace.pair`), with the command line's trace options
//! ([`vcnc_trace::TraceArgs`], the same checks and messages).

use std::path::PathBuf;

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vcnc_pipeline::AxisName;
use vcnc_pipeline::traces::{self, MeasuredTrace, PairOptions, ReadOptions};
use vcnc_trace::{GapPolicy, TraceArgs};

use crate::convert::array;
use crate::error;

/// The keyword names of the trace options, in the command line's order.
pub(crate) const TRACE_OPTIONS: [&str; 10] = [
    "ts",
    "units",
    "trace_format",
    "joints",
    "axis_map",
    "t_col",
    "axes",
    "xr_col",
    "x_col",
    "gaps",
];

/// The trace options of the command line (`vcnc trace info`, `identify --trace`, `validate`),
/// given as keyword arguments (`**options`; [`TRACE_OPTIONS`]): checked into the reader's and
/// the pairing's options. An unknown keyword or a value of the wrong type is a `ValueError`
/// that names it.
pub(crate) fn trace_options(
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<(ReadOptions, PairOptions)> {
    let mut args = TraceArgs::default();
    let mut gaps = None;
    let mut axes = Vec::new();
    for (key, value) in options.into_iter().flat_map(|d| d.iter()) {
        let key: String = key.extract()?;
        if value.is_none() {
            continue;
        }
        let bad = |e: PyErr| error::bad_input(format!("trace option {key}={value}: {e}"));
        match key.as_str() {
            "ts" => args.ts = Some(value.extract().map_err(bad)?),
            "units" => args.units = Some(value.extract().map_err(bad)?),
            "trace_format" => args.trace_format = Some(value.extract().map_err(bad)?),
            "joints" => args.joints = Some(value.extract().map_err(bad)?),
            "axis_map" => args.axis_map = Some(value.extract().map_err(bad)?),
            "t_col" => args.t_col = Some(value.extract().map_err(bad)?),
            "axes" => axes = value.extract().map_err(bad)?,
            "xr_col" => args.xr_col = Some(value.extract().map_err(bad)?),
            "x_col" => args.x_col = Some(value.extract().map_err(bad)?),
            "gaps" => gaps = Some(value.extract::<String>().map_err(bad)?),
            _ => {
                return Err(error::bad_input(format!(
                    "unknown trace option '{key}'; the options are {}",
                    TRACE_OPTIONS.join(", ")
                )));
            }
        }
    }
    args.axes = axis_names(axes)?;
    args.gaps = gaps
        .map(|g| GapPolicy::parse(&g))
        .transpose()
        .map_err(error::pipeline)?;
    let read = args.read_options().map_err(error::pipeline)?;
    let pair = args.pair_options().map_err(error::pipeline)?;
    Ok((read, pair))
}

/// Axis letters to axes; an unknown letter is refused with the letters allowed.
pub(crate) fn axis_names(names: Vec<String>) -> PyResult<Vec<AxisName>> {
    names.iter().map(|n| axis_name(n)).collect()
}

/// One axis letter.
pub(crate) fn axis_name(name: &str) -> PyResult<AxisName> {
    name.parse::<AxisName>()
        .map_err(|_| error::bad_input(format!("axis '{name}': expected one of X Y Z A B C")))
}

/// One channel of a trace file, as read: its samples (in the file's unit) and what vcnc
/// inferred about it.
#[pyclass(module = "vcnc", frozen, get_all)]
pub struct Channel {
    /// The channel's name in the file.
    pub name: String,
    /// The file's description of it (empty without one).
    pub description: String,
    /// The axis it belongs to (`"X"` … `"C"`), `None` when unknown.
    pub axis: Option<String>,
    /// What it measures (`"nominal position"`, `"actual position"`, …, `"other"`).
    pub quantity: String,
    /// Its unit as the file states it (`None` when the file states none).
    pub unit: Option<String>,
    /// Sample period, s (`None` when the file gives no time base).
    pub period_s: Option<f64>,
    /// Time of the first sample, s.
    pub t0_s: f64,
    /// Line of the file its header (or first sample) is on.
    pub line: usize,
    /// 0-based column.
    pub column: usize,
    /// The samples (NaN where the file has none).
    pub samples: Py<PyArray1<f64>>,
}

#[pymethods]
impl Channel {
    fn __repr__(&self) -> String {
        format!(
            "Channel(name={:?}, axis={:?}, quantity={:?}, unit={:?}, period_s={:?})",
            self.name, self.axis, self.quantity, self.unit, self.period_s
        )
    }
}

/// One axis of a trace paired: nominal and actual positions on one grid, in mm or deg.
#[pyclass(module = "vcnc", frozen, get_all)]
pub struct PairedAxis {
    /// The axis (`"X"` … `"C"`).
    pub axis: String,
    /// `"mm"` or `"deg"`.
    pub unit: String,
    /// Sample period, s.
    pub ts_s: f64,
    /// Time of the first sample, s.
    pub t0_s: f64,
    /// Time of every sample, s: `t0_s + k ts_s`.
    pub t: Py<PyArray1<f64>>,
    /// Nominal (reference) position $x_r$, mm or deg.
    pub nominal: Py<PyArray1<f64>>,
    /// Actual (measured) position $x$, mm or deg.
    pub actual: Py<PyArray1<f64>>,
    /// The channel the nominal position comes from.
    pub nominal_channel: String,
    /// The channel the actual position comes from.
    pub actual_channel: String,
}

#[pymethods]
impl PairedAxis {
    fn __repr__(&self) -> String {
        format!(
            "PairedAxis(axis={:?}, unit={:?}, ts_s={}, nominal_channel={:?}, actual_channel={:?})",
            self.axis, self.unit, self.ts_s, self.nominal_channel, self.actual_channel
        )
    }
}

/// A trace file read: every channel, and the pairing options it was read with.
#[pyclass(module = "vcnc", frozen)]
pub struct Trace {
    trace: vcnc_trace::Trace,
    pair: PairOptions,
}

/// `vcnc.read_trace(path, **options)`: reads a scope file (format detected from the content
/// unless `trace_format` is given). The options are the command line's trace options
/// ([`TRACE_OPTIONS`]).
#[pyfunction]
#[pyo3(signature = (path, **options))]
pub fn read_trace(
    py: Python<'_>,
    path: PathBuf,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<Trace> {
    let (read, pair) = trace_options(options)?;
    let trace = py
        .detach(|| vcnc_trace::read_path(&path, &read))
        .map_err(error::pipeline)?;
    Ok(Trace { trace, pair })
}

#[pymethods]
impl Trace {
    /// The file as given.
    #[getter]
    fn file(&self) -> &str {
        &self.trace.file
    }

    /// The format read (`vcnc trace info`'s name of it).
    #[getter]
    fn format(&self) -> String {
        self.trace.format.to_string()
    }

    /// Name–value pairs the file states about itself (control, date, separator, …).
    #[getter]
    fn metadata(&self) -> Vec<(String, String)> {
        self.trace.metadata.clone()
    }

    /// Every channel, in the file's order.
    #[getter]
    fn channels(&self, py: Python<'_>) -> Vec<Channel> {
        self.trace
            .channels
            .iter()
            .map(|c| Channel {
                name: c.name.clone(),
                description: c.description.clone(),
                axis: c.axis.map(|a| a.to_string()),
                quantity: c.quantity.describe().to_string(),
                unit: c.unit.as_ref().map(ToString::to_string),
                period_s: c.period_s,
                t0_s: c.t0_s,
                line: c.line,
                column: c.column,
                samples: array(py, c.samples.clone()),
            })
            .collect()
    }

    /// Per axis, nominal and actual positions on one grid, in mm or deg (the pairing of
    /// `vcnc identify --trace`, with the options the trace was read with).
    fn pair(&self, py: Python<'_>) -> PyResult<Vec<PairedAxis>> {
        let paired = py
            .detach(|| vcnc_trace::pair(&self.trace, &self.pair))
            .map_err(error::pipeline)?;
        Ok(paired
            .axes
            .into_iter()
            .map(|a| {
                let t: Vec<f64> = (0..a.nominal.len())
                    .map(|k| a.t0_s + k as f64 * a.ts_s)
                    .collect();
                PairedAxis {
                    axis: a.axis.to_string(),
                    unit: a.unit.to_string(),
                    ts_s: a.ts_s,
                    t0_s: a.t0_s,
                    t: array(py, t),
                    nominal: array(py, a.nominal),
                    actual: array(py, a.actual),
                    nominal_channel: a.provenance.nominal.name.clone(),
                    actual_channel: a.provenance.actual.name.clone(),
                }
            })
            .collect())
    }

    fn __repr__(&self) -> String {
        format!(
            "Trace(file={:?}, format={:?}, channels={})",
            self.trace.file,
            self.trace.format.to_string(),
            self.trace.channels.len()
        )
    }
}

/// Reads and pairs `path` as `vcnc identify --trace` does.
pub(crate) fn measured(
    path: &std::path::Path,
    read: &ReadOptions,
    pair: &PairOptions,
) -> PyResult<MeasuredTrace> {
    traces::read_trace(path, read, pair).map_err(error::pipeline)
}
