//! numpy in and out, and summaries as Python objects.

use numpy::{AllowTypeChange, PyArray1, PyArrayLike1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A 1-D float64 array (or anything numpy converts to one) as samples. A contiguous float64
/// array is read in place (no conversion); the pipeline takes owned samples, so they are
/// copied once into it.
pub(crate) type Samples<'py> = PyArrayLike1<'py, f64, AllowTypeChange>;

/// The samples of `a`.
pub(crate) fn to_vec(a: &Samples<'_>) -> Vec<f64> {
    match a.as_slice() {
        Ok(s) => s.to_vec(),
        Err(_) => a.as_array().to_vec(),
    }
}

/// `v` handed to numpy without a copy.
pub(crate) fn array(py: Python<'_>, v: Vec<f64>) -> Py<PyArray1<f64>> {
    PyArray1::from_vec(py, v).unbind()
}

/// A serialisable summary as the Python object `json.loads` makes of its JSON (the same
/// object `summary.json` holds).
pub(crate) fn to_py<'py>(
    py: Python<'py>,
    value: &impl serde::Serialize,
) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(crate::error::internal)?;
    py.import("json")?.call_method1("loads", (text,))
}

/// Per-sample columns in order, as a dict of numpy arrays.
pub(crate) fn columns<'py>(
    py: Python<'py>,
    cols: Vec<(String, Vec<f64>)>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (name, v) in cols {
        d.set_item(name, array(py, v))?;
    }
    Ok(d)
}
