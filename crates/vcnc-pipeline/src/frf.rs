//! Frequency responses of closed-loop models: Bode data of the tracking and disturbance
//! transfer functions (docs/drive-model.md), and the tracking bandwidth; and the true drive's
//! tracking response measured by simulating it on a multisine (every drive effect included:
//! docs/machine-file.md#frequency-response-of-the-true-drive), which shows what no 7-parameter
//! model can have — the resonance of a compliant transmission.

use std::collections::BTreeMap;
use std::f64::consts::TAU;

use rayon::prelude::*;
use serde::Serialize;
use vcnc_drive::{ClosedLoopModel, DriveModel, Frf, FrfKind, FrfOptions};
use vcnc_kinematics::nalgebra::Complex;
use vcnc_machine::Machine;

use crate::Error;
use crate::summary::ModelSummary;

/// `n` log-spaced frequencies from `f0` to `f1` Hz (both included).
pub fn log_freqs(f0: f64, f1: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| f0 * (f1 / f0).powf(i as f64 / (n.max(2) - 1) as f64))
        .collect()
}

/// Magnitude (dB) and phase (deg, unwrapped from sample to sample) of a frequency response
/// `h(ω)`, ω in rad/s, at `freqs` Hz.
pub fn bode(freqs: &[f64], h: impl Fn(f64) -> Complex<f64>) -> (Vec<f64>, Vec<f64>) {
    let mut mag = Vec::with_capacity(freqs.len());
    let mut phase = Vec::with_capacity(freqs.len());
    let mut prev: Option<f64> = None;
    for f in freqs {
        let z = h(TAU * f);
        mag.push(20.0 * z.norm().log10());
        let mut p = z.arg().to_degrees();
        if let Some(q) = prev {
            while p - q > 180.0 {
                p -= 360.0;
            }
            while p - q < -180.0 {
                p += 360.0;
            }
        }
        prev = Some(p);
        phase.push(p);
    }
    (mag, phase)
}

/// Bode data of one model: tracking $x/x_r$ and disturbance $x/d$ (d an acceleration).
#[derive(Debug, Clone, PartialEq)]
pub struct BodeData {
    /// Tracking magnitude, dB.
    pub track_mag: Vec<f64>,
    /// Tracking phase, deg.
    pub track_phase: Vec<f64>,
    /// Disturbance magnitude, dB.
    pub dist_mag: Vec<f64>,
    /// Disturbance phase, deg.
    pub dist_phase: Vec<f64>,
}

impl BodeData {
    /// Bode data of `m` at `freqs` Hz (a model without dead time, filter or extra pole as
    /// its 7-parameter core).
    pub fn of(m: &DriveModel, freqs: &[f64]) -> BodeData {
        let core = m.is_core_only();
        let (track_mag, track_phase) = bode(freqs, |w| {
            if core {
                m.core.tracking_frf(w)
            } else {
                m.tracking_frf(w)
            }
        });
        let (dist_mag, dist_phase) = bode(freqs, |w| {
            if core {
                m.core.disturbance_frf(w)
            } else {
                m.disturbance_frf(w)
            }
        });
        BodeData {
            track_mag,
            track_phase,
            dist_mag,
            dist_phase,
        }
    }
}

/// The frequencies of every FRF file and plot: 400 log-spaced points from 0.1 to 500 Hz.
pub fn standard_freqs() -> Vec<f64> {
    log_freqs(0.1, 500.0, 400)
}

/// First frequency where |G_track| falls 3 dB below its DC value (1), Hz, by bisection on a
/// log grid from 0.01 to 5000 Hz; `None` when it never does there.
pub fn bandwidth_hz(m: &ClosedLoopModel) -> Option<f64> {
    let target = 10f64.powf(-3.0 / 20.0);
    let freqs = log_freqs(0.01, 5000.0, 2000);
    let idx = freqs
        .iter()
        .position(|f| m.tracking_frf(TAU * f).norm() < target)?;
    if idx == 0 {
        return Some(freqs[0]);
    }
    let (mut lo, mut hi) = (freqs[idx - 1], freqs[idx]);
    for _ in 0..60 {
        let mid = (lo * hi).sqrt();
        if m.tracking_frf(TAU * mid).norm() < target {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// The options of the measured tracking response: the drive's default multisine (1 to 500 Hz,
/// about 120 log-spaced lines, 5 axis units/s peak on a 25 axis units/s bias, 2 periods
/// settled and 4 averaged at 1 Hz resolution).
pub fn measured_tracking_options() -> FrfOptions {
    FrfOptions {
        kind: FrfKind::Tracking,
        ..FrfOptions::default()
    }
}

/// Measures every axis' true tracking response (nominal → measured position) by simulating
/// its drive ([`vcnc_drive::Drive::measure_frf`]); axes in parallel, results in machine order.
/// `None` for an axis known only by its identified model: there is no drive to measure.
pub fn measure_tracking(machine: &Machine) -> Result<Vec<Option<Frf>>, Error> {
    let o = measured_tracking_options();
    machine
        .axes
        .par_iter()
        .map(|a| {
            a.drive()
                .map(|d| {
                    d.measure_frf(&o).map_err(|source| Error::Drive {
                        axis: a.name,
                        source,
                    })
                })
                .transpose()
        })
        .collect()
}

/// A measured response in a summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeasuredFrfSummary {
    /// Lines measured.
    pub lines: usize,
    /// Lowest line, Hz.
    pub f_min_hz: f64,
    /// Highest line, Hz.
    pub f_max_hz: f64,
    /// Line of the largest magnitude, Hz.
    pub peak_hz: f64,
    /// Largest magnitude, dB.
    pub peak_db: f64,
    /// Smallest load velocity while measuring, axis units/s (≤ 0: the axis stopped, friction
    /// and backlash were not linearised).
    pub min_load_velocity: f64,
}

impl MeasuredFrfSummary {
    /// The summary of a measured response (`None` when it has no line).
    pub fn of(f: &Frf) -> Option<MeasuredFrfSummary> {
        let (i, peak) = f
            .magnitude
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))?;
        Some(MeasuredFrfSummary {
            lines: f.freq_hz.len(),
            f_min_hz: *f.freq_hz.first()?,
            f_max_hz: *f.freq_hz.last()?,
            peak_hz: f.freq_hz[i],
            peak_db: 20.0 * peak.log10(),
            min_load_velocity: f.velocity_range.0,
        })
    }
}

/// The two-mass transmission's modes by formula (docs/machine-file.md#compliance).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TwoMassSummary {
    /// Resonance $\omega_r/2\pi = \sqrt{k(J_m + J_L)/(J_m J_L)}/2\pi$, Hz.
    pub resonance_hz: f64,
    /// Anti-resonance $\omega_a/2\pi = \sqrt{k/J_L}/2\pi$, Hz.
    pub antiresonance_hz: f64,
    /// Damping ratio of the resonance.
    pub zeta: f64,
}

/// One axis of `vcnc frf`'s summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisFrfSummary {
    /// The true drive's analytic model.
    #[serde(rename = "true")]
    pub truth: ModelSummary,
    /// The -3 dB tracking bandwidth of the true drive, Hz.
    pub bandwidth_3db_hz: Option<f64>,
    /// The model given with `--model`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model: Option<ModelSummary>,
    /// The true drive's tracking response measured by simulation.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub measured_tracking: Option<MeasuredFrfSummary>,
    /// The transmission's modes, for a two-mass drive.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub two_mass: Option<TwoMassSummary>,
}

/// `summary.json` of `vcnc frf`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrfSummary {
    /// Machine name.
    pub machine: String,
    /// Per axis.
    pub axes: BTreeMap<String, AxisFrfSummary>,
}

/// The FRF summary of a machine (and of models and measured tracking responses, one per
/// machine axis).
pub fn frf_summary(
    machine: &Machine,
    models: Option<&[DriveModel]>,
    measured: Option<&[Option<Frf>]>,
) -> FrfSummary {
    FrfSummary {
        machine: machine.name.clone(),
        axes: machine
            .axes
            .iter()
            .enumerate()
            .map(|(i, a)| {
                let truth = a.true_model();
                (
                    a.name.to_string(),
                    AxisFrfSummary {
                        truth: ModelSummary::of(&truth),
                        bandwidth_3db_hz: bandwidth_hz(&truth),
                        model: models.map(|m| ModelSummary::of_drive(&m[i])),
                        measured_tracking: measured
                            .and_then(|f| f[i].as_ref())
                            .and_then(MeasuredFrfSummary::of),
                        two_mass: a.drive().and_then(|d| d.effects().compliance).map(|c| {
                            TwoMassSummary {
                                resonance_hz: c.resonance_hz(),
                                antiresonance_hz: c.antiresonance_hz(),
                                zeta: c.zeta(),
                            }
                        }),
                    },
                )
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bandwidth_of_a_first_order_lag_is_its_corner() {
        // Truth: a3 / (s + p)(s² + 2ζωn s + ωn²) with a pair 100× faster is a first-order lag
        // of corner p to 1e-5 in magnitude; p = 10 Hz: |H| = 10^(−3/20) at
        // f = 10 sqrt(10^0.3 − 1) = 9.9763 Hz (−3 dB is not exactly 1/√2).
        let (p, wn, z) = (TAU * 10.0, TAU * 1000.0, 0.7);
        let a1 = p + 2.0 * z * wn;
        let a2 = wn * wn + 2.0 * z * wn * p;
        let a3 = p * wn * wn;
        let m = ClosedLoopModel::characteristic(a1, a2, a3);
        let bw = bandwidth_hz(&m).unwrap();
        let want = 10.0 * (10f64.powf(0.3) - 1.0).sqrt();
        assert!((bw - want).abs() < 1e-3, "{bw} vs {want}");
        let (mag, phase) = bode(&[1e-5], |w| m.tracking_frf(w));
        assert!(mag[0].abs() < 1e-6 && phase[0].abs() < 1e-3);
    }
}
