//! The objects of every `summary.json` (docs/cli.md): plain structs with documented units,
//! serialised with the keys scripts depend on. The binary writes them with their keys sorted.
//!
//! Error figures are in µm for linear axes and millidegrees for rotary ones; the key says which
//! (`freerun_rms_um`, `freerun_rms_mdeg`).

use serde::Serialize;
use serde::ser::SerializeMap;
use vcnc_axis::Unit;
use vcnc_drive::{ClosedLoopModel, DriveModel, Poles, ReferenceFilter};
use vcnc_identify::FitMetrics;

use crate::stats::rel_pct;

/// A root of the characteristic polynomial, rad/s.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Root {
    /// Real part, rad/s.
    pub re: f64,
    /// Imaginary part, rad/s.
    pub im: f64,
}

/// A 7-parameter model: `a1 a2 a3 b0 b1 b2 dc p_hz wn_hz zeta stable` (and the roots when the
/// model is not stable).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelSummary {
    /// The coefficients `a1 a2 a3 b0 b1 b2 dc`, as the model file holds them.
    #[serde(flatten)]
    pub coefficients: ClosedLoopModel,
    /// Real pole p, Hz (null when the poles are not one real and a pair).
    pub p_hz: Option<f64>,
    /// Natural frequency ωn of the pair, Hz.
    pub wn_hz: Option<f64>,
    /// Damping ratio ζ of the pair.
    pub zeta: Option<f64>,
    /// Every pole strictly in the left half plane.
    pub stable: bool,
    /// The roots, rad/s, when the model is not stable.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roots_rad_s: Option<Vec<Root>>,
    /// Whether an unstable model is at least marginally stable (a pole at the origin).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub marginally_stable: Option<bool>,
    /// Dead time of the reference, s (models with one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delay_s: Option<f64>,
    /// The control's nominal-position filter (models with one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_filter: Option<ReferenceFilter>,
    /// An extra real pole of the loop, Hz (models with one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub extra_pole_hz: Option<f64>,
}

impl ModelSummary {
    /// The summary of a model.
    pub fn of(m: &ClosedLoopModel) -> ModelSummary {
        let poles = m.poles();
        let stable = m.is_stable();
        ModelSummary {
            coefficients: *m,
            p_hz: poles.map(|p| p.p_hz()),
            wn_hz: poles.map(|p| p.wn_hz()),
            zeta: poles.map(|p| p.zeta),
            stable,
            roots_rad_s: (!stable).then(|| {
                m.roots()
                    .iter()
                    .map(|r| Root { re: r.re, im: r.im })
                    .collect()
            }),
            marginally_stable: (!stable).then(|| m.is_marginally_stable()),
            delay_s: None,
            reference_filter: None,
            extra_pole_hz: None,
        }
    }

    /// The summary of a model with its structure (dead time, filter, extra pole).
    pub fn of_drive(m: &DriveModel) -> ModelSummary {
        ModelSummary {
            delay_s: (m.delay_s != 0.0).then_some(m.delay_s),
            reference_filter: m.reference_filter,
            extra_pole_hz: m.extra_pole_hz,
            ..ModelSummary::of(&m.core)
        }
    }
}

/// Fit metrics of a model on a run (docs/identification.md): free-run and one-step errors, fit
/// %, tracking error; errors in µm or mdeg by the axis unit (the keys say which).
#[derive(Debug, Clone, PartialEq)]
pub struct FitSummary {
    /// The axis unit (chooses `_um` or `_mdeg`).
    pub unit: Unit,
    /// The metrics, in axis units.
    pub fit: FitMetrics,
}

impl Serialize for FitSummary {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let (u, k) = (self.unit.micro_label(), self.unit.micro_factor());
        let f = &self.fit;
        let mut m = s.serialize_map(Some(7))?;
        m.serialize_entry(&format!("freerun_rms_{u}"), &(f.freerun_rms * k))?;
        m.serialize_entry(&format!("freerun_max_{u}"), &(f.freerun_max * k))?;
        m.serialize_entry(&format!("onestep_rms_{u}"), &(f.onestep_rms * k))?;
        m.serialize_entry("fit_percent", &f.fit_percent)?;
        m.serialize_entry(&format!("tracking_rms_{u}"), &(f.tracking_rms * k))?;
        m.serialize_entry(&format!("tracking_peak_{u}"), &(f.tracking_peak * k))?;
        m.serialize_entry("samples", &f.samples)?;
        m.end()
    }
}

/// Relative errors of identified poles (and dc) against the truth, percent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PoleErrors {
    /// Real pole p, %.
    pub p: f64,
    /// Natural frequency ωn, %.
    pub wn: f64,
    /// Damping ratio ζ, %.
    pub zeta: f64,
    /// Coulomb acceleration dc, % (absent when the truth has none; null then).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dc: Option<Option<f64>>,
}

impl PoleErrors {
    /// Errors of `est` against `truth` (p, ωn, ζ), percent.
    pub fn of(truth: &Poles, est: &Poles) -> PoleErrors {
        PoleErrors {
            p: rel_pct(est.p, truth.p),
            wn: rel_pct(est.wn, truth.wn),
            zeta: rel_pct(est.zeta, truth.zeta),
            dc: None,
        }
    }

    /// Errors of the models' poles and dc; `None` when either cannot be written as poles.
    pub fn of_models(truth: &ClosedLoopModel, est: &ClosedLoopModel) -> Option<PoleErrors> {
        let (t, p) = (truth.poles()?, est.poles()?);
        let dc = (truth.dc != 0.0).then(|| rel_pct(est.dc, truth.dc));
        Some(PoleErrors {
            dc: Some(dc),
            ..PoleErrors::of(&t, &p)
        })
    }
}
