//! `vcnc.identify` (arrays) and `vcnc.identify_trace` (files): the identification of
//! `vcnc identify --trace`, its result as an [`Identification`].
//!
//! Arrays take the command line's route too: [`vcnc_trace::from_columns`] makes them the trace
//! a delimited file `t,xr,x` would be, through the delimited reader's own law (the time column
//! checked into a sample period: first time, mean period, lost samples; then the pairing and
//! units as for a file), so that the identification equals the file's bit for bit. Errors in
//! the arrays name them `<arrays>` (or the `name` given) with the line the sample would be on:
//! sample `k` (from 0) is line `k + 2`.

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::PyDict;
use vcnc_pipeline::identify::{self as pipeline_identify, AxisIdentifySummary};
use vcnc_pipeline::traces::{self, MeasuredTrace};
use vcnc_pipeline::{AxisIdentification, MAX_ACTUAL_LATENCY_S, OptionsFile};
use vcnc_trace::TraceArgs;

use crate::convert::{Samples, array, to_py, to_vec};
use crate::error;
use crate::model::Model;
use crate::trace::{axis_name, trace_options};

/// How `model.toml` describes models identified from a measured trace (`vcnc identify
/// --trace` writes the same).
const TRACE_MODELS: &str = "identified by vcnc from a measured trace";

/// The identification of one axis, as `vcnc identify --trace` makes it.
#[pyclass(module = "vcnc", frozen)]
pub struct Identification {
    id: AxisIdentification,
    /// The trace's name (its path as given, or the `name` of arrays).
    file: String,
}

/// The identifier options: the file (or TOML text) `options`, with `structures` when given.
fn options_file(options: Option<String>, structures: Option<Vec<String>>) -> PyResult<OptionsFile> {
    let (mut text, file) = match options {
        None => (String::new(), "<options>".to_string()),
        // TOML text has a key; a path has none.
        Some(o) if o.contains('=') || o.contains('\n') => (o, "<options>".to_string()),
        Some(p) => {
            let path = PathBuf::from(&p);
            let text = std::fs::read_to_string(&path).map_err(|e| {
                error::pipeline(vcnc_pipeline::Error::Io {
                    file: p.clone(),
                    message: e.to_string(),
                })
            })?;
            (text, p)
        }
    };
    if let Some(s) = structures {
        // A top-level key goes before any table of the options.
        let names: Vec<String> = s.iter().map(|n| format!("{n:?}")).collect();
        text = format!("structures = [{}]\n{text}", names.join(", "));
    }
    if text.is_empty() {
        return Ok(OptionsFile::default());
    }
    OptionsFile::from_toml_str(&text, &file).map_err(error::pipeline)
}

/// The stated actual-value latency (`--actual-latency-s`), checked as the command line does.
fn check_latency(t: Option<f64>) -> PyResult<()> {
    match t {
        Some(t) if !(0.0..=MAX_ACTUAL_LATENCY_S).contains(&t) => Err(error::bad_input(format!(
            "actual_latency_s {t}: must be finite, ≥ 0 and ≤ {MAX_ACTUAL_LATENCY_S} s"
        ))),
        _ => Ok(()),
    }
}

/// Identifies every paired axis of `m` (the GIL released) and states the latency.
fn identify_measured(
    py: Python<'_>,
    m: &MeasuredTrace,
    options: &OptionsFile,
    seed: Option<u64>,
    actual_latency_s: Option<f64>,
) -> PyResult<Vec<Identification>> {
    let mut ids = py
        .detach(|| traces::identify_measured(m, options, seed))
        .map_err(error::pipeline)?;
    if let Some(t) = actual_latency_s {
        for r in &mut ids {
            r.result.model.actual_latency_s = t;
        }
    }
    Ok(ids
        .into_iter()
        .map(|id| Identification {
            id,
            file: m.paired.file.clone(),
        })
        .collect())
}

/// The arrays `t` (or a sample period), `xr`, `x` as the trace file `name` holding them
/// (module documentation).
pub(crate) fn arrays_trace(
    py: Python<'_>,
    name: &str,
    t: &Bound<'_, PyAny>,
    xr: &Samples<'_>,
    x: &Samples<'_>,
    axis: &str,
    units: &str,
) -> PyResult<MeasuredTrace> {
    let axis = axis_name(axis)?;
    let (times, ts) = match t.extract::<f64>() {
        Ok(ts) => (None, Some(ts)),
        Err(_) => (Some(t.extract::<Samples<'_>>()?), None),
    };
    let args = TraceArgs {
        ts,
        units: Some(units.to_string()),
        axes: vec![axis],
        xr_col: Some("xr".into()),
        x_col: Some("x".into()),
        ..TraceArgs::default()
    };
    let read = args.read_options().map_err(error::pipeline)?;
    let pair = args.pair_options().map_err(error::pipeline)?;
    // The times are read in place when contiguous; the positions are copied once, into the
    // trace's channels.
    let times = times.as_ref().map(|t| match t.as_slice() {
        Ok(s) => std::borrow::Cow::Borrowed(s),
        Err(_) => std::borrow::Cow::Owned(t.as_array().to_vec()),
    });
    let columns = vec![("xr".to_string(), to_vec(xr)), ("x".to_string(), to_vec(x))];
    py.detach(|| {
        let trace = vcnc_trace::from_columns(name, times.as_deref(), columns, &read)
            .map_err(error::pipeline)?;
        let paired = vcnc_trace::pair(&trace, &pair).map_err(error::pipeline)?;
        Ok(MeasuredTrace { trace, paired })
    })
}

/// `vcnc.identify(t, xr, x, *, units="mm", ...)`: identifies one axis from its nominal `xr`
/// and actual `x` positions sampled at the times `t` (s; or `t` the sample period, s).
#[pyfunction]
#[pyo3(signature = (t, xr, x, *, units="mm", structures=None, options=None, seed=None,
                    axis="X", actual_latency_s=None, name="<arrays>"))]
#[allow(clippy::too_many_arguments)]
pub fn identify(
    py: Python<'_>,
    t: &Bound<'_, PyAny>,
    xr: Samples<'_>,
    x: Samples<'_>,
    units: &str,
    structures: Option<Vec<String>>,
    options: Option<String>,
    seed: Option<u64>,
    axis: &str,
    actual_latency_s: Option<f64>,
    name: &str,
) -> PyResult<Identification> {
    check_latency(actual_latency_s)?;
    let options = options_file(options, structures)?;
    let m = arrays_trace(py, name, t, &xr, &x, axis, units)?;
    let mut ids = identify_measured(py, &m, &options, seed, actual_latency_s)?;
    ids.pop()
        .ok_or_else(|| error::internal("the paired arrays hold no axis"))
}

/// `vcnc.identify_trace(path, **options)`: identifies every axis of a trace file, as
/// `vcnc identify --trace` does (same options, same models); `**trace` are the trace options
/// of `read_trace`.
#[pyfunction]
#[pyo3(signature = (path, *, structures=None, options=None, seed=None, actual_latency_s=None,
                    **trace))]
pub fn identify_trace(
    py: Python<'_>,
    path: PathBuf,
    structures: Option<Vec<String>>,
    options: Option<String>,
    seed: Option<u64>,
    actual_latency_s: Option<f64>,
    trace: Option<&Bound<'_, PyDict>>,
) -> PyResult<Vec<Identification>> {
    check_latency(actual_latency_s)?;
    // The options first: a mistake in them is reported before the trace is read.
    let options = options_file(options, structures)?;
    let (read, pair) = trace_options(trace)?;
    let m = py.detach(|| crate::trace::measured(&path, &read, &pair))?;
    identify_measured(py, &m, &options, seed, actual_latency_s)
}

/// `model.toml` of identifications, as `vcnc identify --trace` writes it (`machine` defaults to
/// `trace <file>` of the first).
#[pyfunction]
#[pyo3(signature = (identifications, *, machine=None, description=None))]
pub fn models_toml(
    identifications: Vec<PyRef<'_, Identification>>,
    machine: Option<String>,
    description: Option<String>,
) -> PyResult<String> {
    let machine = match (machine, identifications.first()) {
        (Some(m), _) => m,
        (None, Some(i)) => format!("trace {}", i.file),
        (None, None) => return Err(error::bad_input("no identification given")),
    };
    let ids: Vec<AxisIdentification> = identifications.iter().map(|i| i.id.clone()).collect();
    pipeline_identify::model_set(
        &machine,
        description.as_deref().unwrap_or(TRACE_MODELS),
        &ids,
    )
    .to_toml_string()
    .map_err(error::pipeline)
}

#[pymethods]
impl Identification {
    /// The axis (`"X"` … `"C"`).
    #[getter]
    fn axis(&self) -> String {
        self.id.axis.to_string()
    }

    /// `"mm"` or `"deg"`.
    #[getter]
    fn unit(&self) -> String {
        self.id.unit.to_string()
    }

    /// The chosen model structure (`"paper"`, `"no-integral"`, `"delay"`,
    /// `"first-order-filter"`, `"second-order-filter"`, `"extra-pole"`).
    #[getter]
    fn structure(&self) -> &'static str {
        self.id.result.structure.name()
    }

    /// The chosen model.
    #[getter]
    fn model(&self) -> Model {
        Model::of(self.id.axis, self.id.unit, &self.id.result.model)
    }

    /// The axis' entry of `summary.json` (chosen model, every structure tried with its fit,
    /// uncertainty, PSO, warnings …) as a dict.
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &AxisIdentifySummary::of(&self.id))
    }

    /// Every structure tried, with its model and fits (the summary's `structures`).
    #[getter]
    fn structures<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.summary(py)?.get_item("structures")
    }

    /// The chosen model's parameters ± one standard deviation (the summary's `uncertainty`;
    /// `None` where the refinement gives none).
    #[getter]
    fn uncertainty<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.summary(py)?.get_item("uncertainty")
    }

    /// The chosen model's fit on the whole trace (the summary's `fit`).
    #[getter]
    fn fit<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.summary(py)?.get_item("fit")
    }

    /// The warnings the command line prints for this axis.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        pipeline_identify::axis_warnings(&self.id)
    }

    /// The samples the fit is on and the model's free run, for plotting: a dict of numpy
    /// arrays `t` (s from the first sample), `xr`, `x`, `x_model` (mm or deg).
    #[getter]
    fn validation<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let tr = &self.id.validation_trace;
        let d = PyDict::new(py);
        let t: Vec<f64> = (0..tr.xr.len()).map(|k| k as f64 * tr.ts).collect();
        d.set_item("t", array(py, t))?;
        d.set_item("xr", array(py, tr.xr.clone()))?;
        d.set_item("x", array(py, tr.x.clone()))?;
        d.set_item("x_model", array(py, self.id.validation.predicted_x.clone()))?;
        Ok(d)
    }

    /// `model.toml` of this axis, as `vcnc identify --trace` writes it.
    fn to_toml(&self) -> PyResult<String> {
        pipeline_identify::model_set(
            &format!("trace {}", self.file),
            TRACE_MODELS,
            std::slice::from_ref(&self.id),
        )
        .to_toml_string()
        .map_err(error::pipeline)
    }

    fn __repr__(&self) -> String {
        format!(
            "Identification(axis={:?}, structure={:?}, file={:?})",
            self.id.axis.to_string(),
            self.id.result.structure.name(),
            self.file
        )
    }
}
