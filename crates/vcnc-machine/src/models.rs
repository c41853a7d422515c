//! Identified model files (`model.toml`): the 7-parameter closed-loop model of each axis, as
//! written by `vcnc identify` and read by `--model`.
//!
//! ```toml
//! machine = "NMV5000 (virtual)"
//!
//! [axes.X]
//! unit = "mm"
//! a1 = 393.46
//! a2 = 154786.6
//! a3 = 1.47676e7
//! b0 = 0.0
//! b1 = 207.4
//! b2 = 116085.0
//! dc = 47.7
//! input = "smooth"
//! ```

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};
use vcnc_axis::AxisName;
use vcnc_drive::drive_model::ReferenceInput;
use vcnc_drive::{ClosedLoopModel, DriveModel, MAX_ACTUAL_LATENCY_S, ReferenceFilter};

use crate::file::Unit;
use crate::locate::{error_offset, line_col, locate_key};
use crate::{Error, Machine};

/// One axis of a model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisModel {
    /// mm or deg; must match the machine's axis.
    pub unit: Unit,
    /// Denominator coefficient of s², 1/s.
    pub a1: f64,
    /// Denominator coefficient of s, 1/s².
    pub a2: f64,
    /// Denominator constant, 1/s³.
    pub a3: f64,
    /// Numerator coefficient of s³.
    pub b0: f64,
    /// Numerator coefficient of s², 1/s.
    pub b1: f64,
    /// Numerator coefficient of s, 1/s².
    pub b2: f64,
    /// Coulomb friction acceleration, units/s².
    pub dc: f64,
    /// Dead time of the reference, s (0 or absent: none; docs/identification.md).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub delay_s: f64,
    /// The control's nominal-position filter, if the model has one:
    /// `{ kind = "first-order", tau_s }` or `{ kind = "second-order", wn_hz, zeta }`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_filter: Option<ReferenceFilter>,
    /// An extra real pole of the loop, Hz, if the model has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extra_pole_hz: Option<f64>,
    /// How the model's reference input is rebuilt from the nominal positions: `"smooth"` (the
    /// interpolator's velocity and acceleration; absent: this) or `"hold"` (the first-order
    /// hold of the positions), chosen by the identification (docs/identification.md, "The
    /// model input") and honoured by every simulation of the model.
    #[serde(default)]
    pub input: ReferenceInput,
    /// The control's actual-value latency, s (0 or absent: none): the time by which the logged
    /// actual position — what the model predicts — trails the physical axis. Stated from the
    /// control's configuration, never identified (docs/drive-model.md#actual-value-latency);
    /// predictions of the physical axis advance the model's positions by it.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub actual_latency_s: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl AxisModel {
    /// The 7-parameter core of the model.
    pub fn core(&self) -> ClosedLoopModel {
        ClosedLoopModel {
            a1: self.a1,
            a2: self.a2,
            a3: self.a3,
            b0: self.b0,
            b1: self.b1,
            b2: self.b2,
            dc: self.dc,
        }
    }

    /// The model: the core with its dead time, reference filter, extra pole and stated
    /// actual-value latency.
    pub fn model(&self) -> DriveModel {
        DriveModel {
            core: self.core(),
            delay_s: self.delay_s,
            reference_filter: self.reference_filter,
            extra_pole_hz: self.extra_pole_hz,
            actual_latency_s: self.actual_latency_s,
            input: self.input,
        }
    }

    /// From a model and its unit.
    pub fn new(unit: Unit, m: &DriveModel) -> AxisModel {
        let c = &m.core;
        AxisModel {
            unit,
            a1: c.a1,
            a2: c.a2,
            a3: c.a3,
            b0: c.b0,
            b1: c.b1,
            b2: c.b2,
            dc: c.dc,
            delay_s: m.delay_s,
            reference_filter: m.reference_filter,
            extra_pole_hz: m.extra_pole_hz,
            input: m.input,
            actual_latency_s: m.actual_latency_s,
        }
    }
}

/// A model file: one identified model per axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSet {
    /// The machine the models were identified on (informative).
    #[serde(default)]
    pub machine: String,
    /// Free text: how the models were obtained.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Models by axis letter.
    pub axes: BTreeMap<String, AxisModel>,
}

impl ModelSet {
    /// Reads a model file; every model must be finite and stable (a pole at the origin is allowed
    /// for drives without integral action).
    pub fn load(path: &Path) -> Result<ModelSet, Error> {
        let (file, src) = crate::read_text(path)?;
        ModelSet::from_toml_str(&src, &file)
    }

    /// Parses and checks a model file given as text.
    pub fn from_toml_str(src: &str, file: &str) -> Result<ModelSet, Error> {
        let set: ModelSet = toml::from_str(src).map_err(|e| Error::Toml {
            file: file.to_string(),
            at: line_col(src, error_offset(src, e.span(), e.message())),
            message: e.message().trim().to_string(),
        })?;
        for (name, m) in &set.axes {
            if !(0.0..=MAX_ACTUAL_LATENCY_S).contains(&m.actual_latency_s) {
                return Err(Error::Invalid {
                    file: file.to_string(),
                    at: locate_key(src, &["axes", name, "actual_latency_s"]),
                    key: format!("axes.{name}.actual_latency_s"),
                    message: format!(
                        "actual-value latency {} s: must be finite, ≥ 0 and ≤ {MAX_ACTUAL_LATENCY_S} s",
                        m.actual_latency_s
                    ),
                });
            }
            if let Err(e) = m.model().validate() {
                return Err(Error::Invalid {
                    file: file.to_string(),
                    at: locate_key(src, &["axes", name]),
                    key: format!("axes.{name}"),
                    message: format!("the model of axis {name}: {e}"),
                });
            }
            let model = m.core();
            if !model.is_finite() || !model.is_marginally_stable() {
                let poles = model
                    .roots()
                    .iter()
                    .map(|r| format!("{:.4}{:+.4}i", r.re, r.im))
                    .collect::<Vec<_>>()
                    .join(", ");
                return Err(Error::Invalid {
                    file: file.to_string(),
                    at: locate_key(src, &["axes", name]),
                    key: format!("axes.{name}"),
                    message: format!("the model of axis {name} is not stable: poles {poles} rad/s"),
                });
            }
        }
        Ok(set)
    }

    /// The model of axis `name` in `unit` (the file `file` names in messages), or the error
    /// `missing` says when the file has none, or a unit mismatch.
    pub(crate) fn model_of(
        &self,
        name: AxisName,
        unit: Unit,
        file: &str,
        missing: impl FnOnce() -> String,
    ) -> Result<DriveModel, Error> {
        let m = self
            .axes
            .get(name.as_str())
            .ok_or_else(|| Error::ModelMismatch {
                file: file.to_string(),
                message: missing(),
            })?;
        if m.unit != unit {
            return Err(Error::ModelMismatch {
                file: file.to_string(),
                message: format!(
                    "axis {name}: the model is in {} but the machine axis is in {unit}",
                    m.unit
                ),
            });
        }
        Ok(m.model())
    }

    /// TOML text of this model set.
    pub fn to_toml_string(&self) -> Result<String, Error> {
        toml::to_string_pretty(self).map_err(|e| Error::Write {
            what: "the model file".into(),
            message: e.to_string(),
        })
    }
}

/// A machine's models, checked against the machine once when built: one [`DriveModel`] per
/// machine axis, in the machine's order (each with its stated actual-value latency), and where
/// they come from. Everything downstream indexes it by the machine's axes and never checks it
/// again.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineModels {
    models: Vec<DriveModel>,
    source: String,
}

impl MachineModels {
    /// The models of the model file at `path` for `machine`: every machine axis must have one,
    /// in the machine axis' unit.
    pub fn load(path: &Path, machine: &Machine) -> Result<MachineModels, Error> {
        let file = path.display().to_string();
        MachineModels::of_set(&ModelSet::load(path)?, machine, &file)
    }

    /// The models of a model file (`file` names it in messages) for `machine`.
    pub fn of_set(set: &ModelSet, machine: &Machine, file: &str) -> Result<MachineModels, Error> {
        let models = machine
            .axes
            .iter()
            .map(|a| {
                set.model_of(a.name, a.unit, file, || {
                    format!(
                        "no model for axis {} of machine \"{}\"",
                        a.name, machine.name
                    )
                })
            })
            .collect::<Result<Vec<_>, Error>>()?;
        Ok(MachineModels {
            models,
            source: file.to_string(),
        })
    }

    /// Models made by vcnc itself (identified on the fly, the paper's method, a sweep's
    /// designs), one per machine axis in the machine's order; `source` says where they come
    /// from. A count that is not the machine's is vcnc's own failure, not the user's input.
    pub fn new(
        machine: &Machine,
        models: Vec<DriveModel>,
        source: impl Into<String>,
    ) -> Result<MachineModels, Error> {
        if models.len() != machine.axes.len() {
            return Err(Error::ModelCount {
                machine: machine.name.clone(),
                axes: machine.axes.len(),
                models: models.len(),
            });
        }
        for m in &models {
            m.validate().map_err(|e| Error::ModelMismatch {
                file: machine.source.clone(),
                message: e.to_string(),
            })?;
        }
        Ok(MachineModels {
            models,
            source: source.into(),
        })
    }

    /// The same models with each axis' actual-value latency replaced by `latency_s` (s, per
    /// machine axis, in order).
    pub fn with_latencies(&self, latency_s: impl IntoIterator<Item = f64>) -> MachineModels {
        let mut m = self.clone();
        for (model, l) in m.models.iter_mut().zip(latency_s) {
            model.actual_latency_s = l;
        }
        m
    }

    /// The models, one per machine axis in the machine's order.
    pub fn models(&self) -> &[DriveModel] {
        &self.models
    }

    /// The model of machine axis `i` (index into [`Machine::axes`]).
    pub fn get(&self, i: usize) -> &DriveModel {
        &self.models[i]
    }

    /// Where the models come from: a model file's path, or how vcnc made them.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The stated actual-value latency of each machine axis, s, in the machine's order.
    pub fn latencies(&self) -> impl Iterator<Item = f64> + '_ {
        self.models.iter().map(|m| m.actual_latency_s)
    }

    /// The model file of these models (`machine` and `description` informative).
    pub fn to_set(&self, machine: &Machine, description: Option<String>) -> ModelSet {
        ModelSet {
            machine: machine.name.clone(),
            description,
            axes: machine
                .axes
                .iter()
                .zip(&self.models)
                .map(|(a, m)| (a.name.to_string(), AxisModel::new(a.unit, m)))
                .collect(),
        }
    }
}
