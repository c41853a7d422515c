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
//! ```

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};
use vcnc_drive::ClosedLoopModel;

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
}

impl AxisModel {
    /// The closed-loop model.
    pub fn model(&self) -> ClosedLoopModel {
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

    /// From a model and its unit.
    pub fn new(unit: Unit, m: &ClosedLoopModel) -> AxisModel {
        AxisModel {
            unit,
            a1: m.a1,
            a2: m.a2,
            a3: m.a3,
            b0: m.b0,
            b1: m.b1,
            b2: m.b2,
            dc: m.dc,
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
            let model = m.model();
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

    /// The model of each machine axis, in the machine's order; errors if one is missing or has
    /// the wrong unit.
    pub fn for_machine(
        &self,
        machine: &Machine,
        file: &str,
    ) -> Result<Vec<ClosedLoopModel>, Error> {
        machine
            .axes
            .iter()
            .map(|a| {
                let m = self
                    .axes
                    .get(a.name.as_str())
                    .ok_or_else(|| Error::ModelMismatch {
                        file: file.to_string(),
                        message: format!(
                            "no model for axis {} of machine \"{}\"",
                            a.name, machine.name
                        ),
                    })?;
                if m.unit != a.unit {
                    return Err(Error::ModelMismatch {
                        file: file.to_string(),
                        message: format!(
                            "axis {}: the model is in {} but the machine axis is in {}",
                            a.name, m.unit, a.unit
                        ),
                    });
                }
                Ok(m.model())
            })
            .collect()
    }

    /// TOML text of this model set.
    pub fn to_toml_string(&self) -> Result<String, Error> {
        toml::to_string_pretty(self).map_err(|e| Error::Write {
            what: "the model file".into(),
            message: e.to_string(),
        })
    }
}
