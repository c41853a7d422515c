//! `vcnc.Machine`: a machine file, and the runs of `vcnc interpolate`, `simulate` and
//! `predict` on it with every sample kept as numpy columns (named as the command line's tables
//! name them) and the run's `summary.json` as a dict; `Machine.kinematics` on arrays.

use std::path::PathBuf;
use std::sync::Arc;

use numpy::{AllowTypeChange, PyArray1, PyArray2, PyArrayLike2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyString, PyTuple};
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{Branch, Pose};
use vcnc_output::table;
use vcnc_pipeline::predict::{self, PredictOptions, PredictSummary};
use vcnc_pipeline::simulate::{self, simulate_summary_of};
use vcnc_pipeline::source::{self, Program};
use vcnc_pipeline::{
    Machine as MachineFile, MachineModels, Measured, PredictPiece, ReferenceChunk, SimulatePiece,
    Sink, Source, identify,
};

use crate::convert::{columns, to_py};
use crate::error;

/// Per-sample columns filled piece by piece, in a fixed order.
struct Columns {
    names: Vec<String>,
    values: Vec<Vec<f64>>,
}

impl Columns {
    fn new(names: Vec<String>) -> Columns {
        let values = vec![Vec::new(); names.len()];
        Columns { names, values }
    }

    /// Appends one piece, given as columns in the names' order.
    fn append(&mut self, piece: Vec<&[f64]>) {
        debug_assert_eq!(piece.len(), self.values.len(), "one column per name");
        for (v, c) in self.values.iter_mut().zip(piece) {
            v.extend_from_slice(c);
        }
    }

    /// `(columns, summary)` as a command's Python result: a dict of numpy arrays in the names'
    /// order and the summary as a dict.
    fn with_summary<'py, S: serde::Serialize>(
        self,
        py: Python<'py>,
        summary: &S,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let cols: Vec<(String, Vec<f64>)> = self.names.into_iter().zip(self.values).collect();
        PyTuple::new(py, [columns(py, cols)?.into_any(), to_py(py, summary)?])
    }
}

/// The columns of `vcnc interpolate`'s `reference.csv`: `t`, the tool tip `px py pz` (TCP
/// programs), per axis position, velocity and acceleration.
struct ReferenceColumns<'m> {
    machine: &'m MachineFile,
    ts: f64,
    tcp: bool,
    cols: Columns,
}

impl Sink<ReferenceChunk> for ReferenceColumns<'_> {
    type Error = vcnc_pipeline::Error;
    fn piece(&mut self, c: &ReferenceChunk) -> Result<(), Self::Error> {
        let t = piece_times(c.first, c.len(), self.ts);
        let tip = if self.tcp {
            Some(vcnc_pipeline::interpolate::tool_tips(self.machine, c)?)
        } else {
            None
        };
        self.cols.append(table::reference_columns(
            c,
            &t,
            tip.as_ref().map(|t| t.as_slice()),
        ));
        Ok(())
    }
}

/// The columns of `vcnc simulate`'s `trace.csv`: `t`, per axis `<A>_ref`, `<A>_act` and,
/// with models, `<A>_model`.
struct TraceColumns {
    ts: f64,
    cols: Columns,
}

impl Sink<SimulatePiece> for TraceColumns {
    type Error = vcnc_pipeline::Error;
    fn piece(&mut self, p: &SimulatePiece) -> Result<(), Self::Error> {
        let t = piece_times(p.first, p.len(), self.ts);
        self.cols.append(table::trace_columns(p, &t));
        Ok(())
    }
}

/// The times of the `len` samples from sample `first` at period `ts`, s.
fn piece_times(first: usize, len: usize, ts: f64) -> Vec<f64> {
    (first..first + len).map(|k| k as f64 * ts).collect()
}

/// The columns of `vcnc predict`'s `contour.csv`: `t`, `line`, per axis reference, true and
/// predicted positions, the reference, true and predicted poses, and the four contour errors
/// (µm, mrad).
struct ContourColumns {
    ts: f64,
    cols: Columns,
}

impl Sink<PredictPiece> for ContourColumns {
    type Error = vcnc_pipeline::Error;
    fn piece(&mut self, p: &PredictPiece) -> Result<(), Self::Error> {
        let Some(model) = p.models.first() else {
            return Ok(());
        };
        table::append_contour_columns(p, model, self.ts, 0..p.len(), &mut self.cols.values);
        Ok(())
    }
}

/// A program given as a path, or as G-code text (a `str` holding a line break).
fn program(program: &Bound<'_, PyAny>) -> PyResult<Program> {
    if let Ok(s) = program.cast::<PyString>() {
        let s: String = s.extract()?;
        if s.contains('\n') {
            return Ok(Program::Text {
                text: s,
                name: "<text>".to_string(),
            });
        }
    }
    Ok(Program::File(program.extract::<PathBuf>()?))
}

/// A machine file, checked.
#[pyclass(module = "vcnc", frozen)]
pub struct Machine {
    machine: Arc<MachineFile>,
}

/// The kinematics of a machine: forward and inverse over arrays.
#[pyclass(module = "vcnc", frozen)]
pub struct Kinematics {
    machine: Arc<MachineFile>,
}

#[pymethods]
impl Machine {
    /// Loads and checks the machine file at `path`.
    #[new]
    fn new(py: Python<'_>, path: PathBuf) -> PyResult<Machine> {
        let machine = py
            .detach(|| MachineFile::load(&path))
            .map_err(error::pipeline)?;
        Ok(Machine {
            machine: Arc::new(machine),
        })
    }

    /// The machine's name.
    #[getter]
    fn name(&self) -> String {
        self.machine.name.clone()
    }

    /// The machine's axes, in its order (`"X"`, …).
    #[getter]
    fn axes(&self) -> Vec<String> {
        self.machine
            .axes
            .iter()
            .map(|a| a.name.to_string())
            .collect()
    }

    /// Forward and inverse kinematics (a `ValueError` when the file has none).
    #[getter]
    fn kinematics(&self) -> PyResult<Kinematics> {
        self.machine.require_kinematics().map_err(error::pipeline)?;
        Ok(Kinematics {
            machine: Arc::clone(&self.machine),
        })
    }

    /// `vcnc interpolate`: the reference of `program` (a path, or G-code text). Returns
    /// `(columns, summary)`: the columns of `reference.csv` as numpy arrays and `summary.json`
    /// as a dict.
    #[pyo3(signature = (program, *, lenient=false))]
    fn interpolate<'py>(
        &self,
        py: Python<'py>,
        program: &Bound<'py, PyAny>,
        lenient: bool,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let program = self::program(program)?;
        let m = &*self.machine;
        let (cols, summary) = py
            .detach(|| {
                let plan = source::plan(m, program, lenient)?;
                let source = Source::Streamed(&plan);
                let names: Vec<_> = m.axes.iter().map(|a| a.name).collect();
                let mut sink = ReferenceColumns {
                    machine: m,
                    ts: source.ts(),
                    tcp: source.has_tcp(),
                    cols: Columns::new(table::reference_header(source.has_tcp(), &names)),
                };
                let outcome = vcnc_pipeline::interpolate::interpolate(m, source, &mut sink)?;
                Ok::<_, vcnc_pipeline::Error>((sink.cols, outcome.summary))
            })
            .map_err(error::pipeline)?;
        cols.with_summary(py, &summary)
    }

    /// `vcnc simulate`: the true drives (and the models of the file `models`, when given)
    /// run through `program`. Returns `(columns, summary)`: the columns of `trace.csv` and
    /// `summary.json`.
    #[pyo3(signature = (program, models=None, *, lenient=false))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        program: &Bound<'py, PyAny>,
        models: Option<PathBuf>,
        lenient: bool,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let program = self::program(program)?;
        let m = &*self.machine;
        let (cols, summary) = py
            .detach(|| {
                let plan = source::plan(m, program, lenient)?;
                let models = models.map(|p| MachineModels::load(&p, m)).transpose()?;
                let source = Source::Streamed(&plan);
                let names: Vec<_> = m.axes.iter().map(|a| a.name).collect();
                let mut sink = TraceColumns {
                    ts: source.ts(),
                    cols: Columns::new(table::trace_header(&names, models.is_some())),
                };
                let outcome = simulate::simulate(m, source, models.as_ref(), &mut sink)?;
                let summary = simulate_summary_of(
                    m,
                    (source.file(), source.len(), source.duration_s()),
                    &outcome.tracking,
                    models.as_ref(),
                );
                Ok::<_, vcnc_pipeline::Error>((sink.cols, summary))
            })
            .map_err(error::pipeline)?;
        cols.with_summary(py, &summary)
    }

    /// `vcnc predict`: contour and orientation errors of `program` on the true machine and
    /// with the models of the file `models` (identified on the fly from the machine's own
    /// excitation runs when `None`, as the command line does). Returns `(columns, summary)`:
    /// the columns of `contour.csv` and `summary.json`.
    #[pyo3(signature = (program, models=None, *, include_rapids=false, lenient=false))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        program: &Bound<'py, PyAny>,
        models: Option<PathBuf>,
        include_rapids: bool,
        lenient: bool,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let program = self::program(program)?;
        let m = &*self.machine;
        let (cols, summary) = py
            .detach(|| {
                let plan = source::plan(m, program, lenient)?;
                let models = identify::models_for(m, models.as_deref())?;
                let source = Source::Streamed(&plan);
                let mut sink = ContourColumns {
                    ts: source.ts(),
                    cols: Columns::new(table::contour_header(
                        &m.axes.iter().map(|a| a.name).collect::<Vec<_>>(),
                    )),
                };
                let opts = PredictOptions {
                    measured: if include_rapids {
                        Measured::All
                    } else {
                        Measured::Feed
                    },
                    tracking: false,
                };
                let outcome = predict::predict(m, source, &[&models], &opts, &mut sink)?;
                let summary = PredictSummary::new(
                    m,
                    &source,
                    outcome.summaries[0].clone(),
                    &models,
                    outcome.warnings.clone(),
                );
                Ok::<_, vcnc_pipeline::Error>((sink.cols, summary))
            })
            .map_err(error::pipeline)?;
        cols.with_summary(py, &summary)
    }

    fn __repr__(&self) -> String {
        format!(
            "Machine(name={:?}, axes={:?})",
            self.machine.name,
            self.axes().concat()
        )
    }
}

/// The rows of a 2-D array of `width` columns.
fn rows(a: &PyArrayLike2<'_, f64, AllowTypeChange>, width: usize) -> PyResult<Vec<Vec<f64>>> {
    let v = a.as_array();
    if v.ncols() != width {
        return Err(error::bad_input(format!(
            "expected an array of shape (N, {width}), got ({}, {})",
            v.nrows(),
            v.ncols()
        )));
    }
    Ok(v.rows().into_iter().map(|r| r.to_vec()).collect())
}

/// Rows of `width` values into an (N, width) numpy array.
fn matrix<'py, R: AsRef<[f64]>>(
    py: Python<'py>,
    rows: Vec<R>,
    width: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = rows.len();
    let flat: Vec<f64> = rows
        .iter()
        .flat_map(|r| r.as_ref().iter().copied())
        .collect();
    PyArray1::from_vec(py, flat).reshape([n, width])
}

#[pymethods]
impl Kinematics {
    /// The axes the kinematics reads, in the order of [`Kinematics::forward`]'s columns:
    /// X Y Z then the rotary axes, e.g. `["X", "Y", "Z", "A", "C"]`.
    #[getter]
    fn axis_names(&self) -> PyResult<Vec<&'static str>> {
        let kin = self.machine.require_kinematics().map_err(error::pipeline)?;
        Ok(kin.axis_names().into_iter().map(|a| a.as_str()).collect())
    }

    /// Forward kinematics (`vcnc kinematics forward`): rows of the axes in
    /// [`Kinematics::axis_names`]' order (mm, deg; e.g. `X Y Z A C`), shape (N, axes), to rows
    /// `px py pz ox oy oz` (tool tip, mm, and tool axis in the workpiece frame), shape (N, 6).
    fn forward<'py>(
        &self,
        py: Python<'py>,
        axes: PyArrayLike2<'py, f64, AllowTypeChange>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let kin = self.machine.require_kinematics().map_err(error::pipeline)?;
        let input = rows(&axes, kin.axis_names().len())?;
        let out: Vec<[f64; 6]> = py.detach(|| {
            input
                .iter()
                .map(|q| {
                    let p = kin.pose_of(q);
                    [p.p.x, p.p.y, p.p.z, p.o.x, p.o.y, p.o.z]
                })
                .collect()
        });
        matrix(py, out, 6)
    }

    /// Inverse kinematics (`vcnc kinematics inverse`): rows `px py pz ox oy oz`, shape (N, 6),
    /// to rows of the axes in [`Kinematics::axis_names`]' order (mm, deg), shape (N, axes), the
    /// rotary axes unwound continuously from row to row,
    /// on `branch` (1 or -1; the machine file's when `None`).
    #[pyo3(signature = (poses, branch=None))]
    fn inverse<'py>(
        &self,
        py: Python<'py>,
        poses: PyArrayLike2<'py, f64, AllowTypeChange>,
        branch: Option<i32>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let branch = branch
            .map(|b| {
                Branch::try_from(b)
                    .map_err(|_| error::bad_input(format!("branch {b}: expected 1 or -1")))
            })
            .transpose()?;
        let poses: Vec<Pose> = rows(&poses, 6)?
            .into_iter()
            .map(|r| {
                Pose::new(
                    Vector3::new(r[0], r[1], r[2]),
                    Vector3::new(r[3], r[4], r[5]),
                )
            })
            .collect();
        let kin = self.machine.require_kinematics().map_err(error::pipeline)?;
        let out = py
            .detach(|| kin.inverse_poses(&poses, branch))
            .map_err(error::kinematics)?;
        matrix(py, out, kin.axis_names().len())
    }
}

/// Registers the machine types.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Machine>()?;
    m.add_class::<Kinematics>()?;
    Ok(())
}
