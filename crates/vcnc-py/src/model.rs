//! `vcnc.Model`: one axis' identified model (a `model.toml` entry): free run, frequency
//! response, validation on measured samples, and the model file.

use std::path::PathBuf;

use numpy::{Complex64, PyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vcnc_drive::SimOptions;
use vcnc_machine::{AxisModel, ModelSet};
use vcnc_pipeline::validate::{ValidateSummary, validate_measured};
use vcnc_pipeline::{AxisName, DriveModel, ModelSummary, Unit};

use crate::convert::{Samples, array, to_py, to_vec};
use crate::error;
use crate::identify::arrays_trace;

/// One axis' model, as a model file holds it.
#[pyclass(module = "vcnc", frozen)]
pub struct Model {
    axis: AxisName,
    model: AxisModel,
}

impl Model {
    /// The model `m` of `axis`.
    pub(crate) fn of(axis: AxisName, unit: Unit, m: &DriveModel) -> Model {
        Model {
            axis,
            model: AxisModel::new(unit, m),
        }
    }

    /// The model file holding this model alone.
    fn set(&self, machine: &str, description: Option<String>) -> ModelSet {
        ModelSet {
            machine: machine.to_string(),
            description,
            axes: [(self.axis.to_string(), self.model.clone())].into(),
        }
    }
}

/// Every axis' model of the model file at `path`, by axis letter.
#[pyfunction]
pub fn load_models(path: PathBuf) -> PyResult<Vec<Model>> {
    let set = ModelSet::load(&path).map_err(error::pipeline)?;
    set.axes
        .into_iter()
        .map(|(a, model)| {
            Ok(Model {
                axis: crate::trace::axis_name(&a)?,
                model,
            })
        })
        .collect()
}

#[pymethods]
impl Model {
    /// The model of `axis` in the model file at `path` (`vcnc identify` writes them); `axis`
    /// may be left out when the file holds one model.
    #[staticmethod]
    #[pyo3(signature = (path, axis=None))]
    fn from_toml(path: PathBuf, axis: Option<String>) -> PyResult<Model> {
        let file = path.display().to_string();
        let mut models = load_models(path)?;
        let has = || {
            models
                .iter()
                .map(|m| m.axis.to_string())
                .collect::<Vec<_>>()
                .join(" ")
        };
        match axis {
            Some(a) => {
                let a = crate::trace::axis_name(&a)?;
                let has = has();
                models.into_iter().find(|m| m.axis == a).ok_or_else(|| {
                    error::bad_input(format!("{file}: no model of axis {a} (it has {has})"))
                })
            }
            None if models.len() == 1 => Ok(models.remove(0)),
            None => Err(error::bad_input(format!(
                "{file}: holds models of axes {}; name one with axis=",
                has()
            ))),
        }
    }

    /// The axis (`"X"` … `"C"`).
    #[getter]
    fn axis(&self) -> String {
        self.axis.to_string()
    }

    /// `"mm"` or `"deg"`.
    #[getter]
    fn unit(&self) -> String {
        self.model.unit.to_string()
    }

    /// The model's structure: `"paper"`, `"no-integral"` (no integral mode, `a3 = 0`), or the
    /// one addition it has (`"delay"`, `"first-order-filter"`, `"second-order-filter"`,
    /// `"extra-pole"`).
    #[getter]
    fn structure(&self) -> &'static str {
        if self.model.a3 == 0.0 {
            return "no-integral";
        }
        match (&self.model.reference_filter, self.model.extra_pole_hz) {
            (Some(f), _) if f.order() == 1 => "first-order-filter",
            (Some(_), _) => "second-order-filter",
            (None, Some(_)) => "extra-pole",
            (None, None) if self.model.delay_s != 0.0 => "delay",
            (None, None) => "paper",
        }
    }

    /// The model file's entry: `a1 a2 a3 b0 b1 b2 dc`, `delay_s`, `reference_filter`,
    /// `extra_pole_hz`, `input`, `actual_latency_s` (units in docs/machine-file.md).
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.model)
    }

    /// The model as `summary.json` states it: the parameters with the poles `p_hz`, `wn_hz`,
    /// `zeta` (Hz), stability and roots.
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &ModelSummary::of_drive(&self.model.model()))
    }

    /// Coulomb friction acceleration, mm/s² or deg/s².
    #[getter]
    fn dc(&self) -> f64 {
        self.model.dc
    }

    /// Dead time of the reference, s.
    #[getter]
    fn delay_s(&self) -> f64 {
        self.model.delay_s
    }

    /// The stated actual-value latency, s.
    #[getter]
    fn actual_latency_s(&self) -> f64 {
        self.model.actual_latency_s
    }

    /// The poles of the 7-parameter core: `{"p_hz", "wn_hz", "zeta"}`, `None` when the core
    /// has no real pole and complex pair.
    #[getter]
    fn poles<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(p) = self.model.core().poles() else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("p_hz", p.p_hz())?;
        d.set_item("wn_hz", p.wn_hz())?;
        d.set_item("zeta", p.zeta)?;
        Ok(Some(d))
    }

    /// Free run from rest at `xr[0]`: the model's (logged) position at every sample of the
    /// nominal positions `xr` sampled every `ts` s, with the model's input (docs/drive-model.md).
    fn simulate(&self, py: Python<'_>, xr: Samples<'_>, ts: f64) -> PyResult<Py<PyArray1<f64>>> {
        let xr = to_vec(&xr);
        let m = self.model.model();
        let x = py
            .detach(|| m.simulate_positions(&xr, ts, &SimOptions::default()))
            .map_err(error::drive)?;
        Ok(array(py, x))
    }

    /// Tracking frequency response $x / x_r$ at the frequencies `f_hz` (Hz): complex values.
    fn frf<'py>(&self, py: Python<'py>, f_hz: Samples<'_>) -> Bound<'py, PyArray1<Complex64>> {
        let m = self.model.model();
        let h: Vec<Complex64> = to_vec(&f_hz)
            .into_iter()
            .map(|f| {
                let h = m.tracking_frf(2.0 * std::f64::consts::PI * f);
                Complex64::new(h.re, h.im)
            })
            .collect();
        PyArray1::from_vec(py, h)
    }

    /// Scores the model on measured samples as `vcnc validate` does: `t` (s, or the sample
    /// period), nominal `xr` and actual `x` in `units`. The axis' entry of `vcnc validate`'s
    /// `summary.json` as a dict, with the model's free run under `x_model`.
    #[pyo3(signature = (t, xr, x, *, units=None, name="<arrays>"))]
    fn validate<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
        xr: Samples<'py>,
        x: Samples<'py>,
        units: Option<&str>,
        name: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let units = units.unwrap_or(self.model.unit.as_str());
        let axis = self.axis.to_string();
        let m = arrays_trace(py, name, t, &xr, &x, &axis, units)?;
        let set = self.set("python", None);
        let v = py
            .detach(|| validate_measured(&m, &set, "<model>", &[self.axis]))
            .map_err(error::pipeline)?;
        let summary = to_py(py, &ValidateSummary::of(&m, "<model>", &v))?;
        let entry = summary.get_item("axes")?.get_item(&axis)?;
        let x_model = v
            .into_iter()
            .next()
            .map(|a| a.fit.predicted_x)
            .unwrap_or_default();
        entry.set_item("x_model", array(py, x_model))?;
        Ok(entry)
    }

    /// The model file holding this model (`machine` names what it was identified on).
    #[pyo3(signature = (machine="python", description=None))]
    fn to_toml(&self, machine: &str, description: Option<String>) -> PyResult<String> {
        self.set(machine, description)
            .to_toml_string()
            .map_err(error::pipeline)
    }

    fn __repr__(&self) -> String {
        format!(
            "Model(axis={:?}, structure={:?}, unit={:?})",
            self.axis.to_string(),
            self.structure(),
            self.model.unit.to_string()
        )
    }
}
