//! vcnc from Python (docs/python.md): the `vcnc` extension module, numpy arrays in and out.
//!
//! Every function calls the library entry points the command line calls, in the same order,
//! so that a result from Python equals the command line's bit for bit:
//!
//! | Python | command line | library |
//! |---|---|---|
//! | `read_trace`, `Trace.pair` | `vcnc trace info` | `vcnc_trace::read_path`, `vcnc_trace::pair` |
//! | `identify`, `identify_trace`, `models_toml` | `vcnc identify --trace` | `vcnc_pipeline::traces::identify_measured`, `identify::model_set` |
//! | `Model.validate` | `vcnc validate` | `vcnc_pipeline::validate::validate_measured` |
//! | `Machine.interpolate` / `simulate` / `predict` | `vcnc interpolate` / `simulate` / `predict` | `vcnc_pipeline::{interpolate, simulate, predict}` |
//! | `Machine.kinematics.forward` / `inverse` | `vcnc kinematics` | `vcnc_machine::Kinematics::{pose_of, inverse_poses}` |
//!
//! Long calls release the GIL. Errors keep the command line's kind and message: bad input
//! (exit code 2 there) is a `ValueError`, any other failure a `RuntimeError`.
//!
//! `pyo3/extension-module` is set only by maturin (the `extension-module` feature), so the
//! crate builds and links in `cargo build --workspace` too.

mod convert;
mod error;
mod identify;
mod machine;
mod model;
mod trace;

use pyo3::prelude::*;

/// The extension module `vcnc._vcnc` (re-exported by the `vcnc` package).
#[pymodule]
fn _vcnc(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(trace::read_trace, m)?)?;
    m.add_function(wrap_pyfunction!(identify::identify, m)?)?;
    m.add_function(wrap_pyfunction!(identify::identify_trace, m)?)?;
    m.add_function(wrap_pyfunction!(identify::models_toml, m)?)?;
    m.add_function(wrap_pyfunction!(model::load_models, m)?)?;
    m.add_class::<trace::Trace>()?;
    m.add_class::<trace::Channel>()?;
    m.add_class::<trace::PairedAxis>()?;
    m.add_class::<identify::Identification>()?;
    m.add_class::<model::Model>()?;
    machine::register(m)?;
    Ok(())
}
