//! A validated identification trace: reference and measured axis position at a uniform period.

use crate::Error;

/// Fewest samples accepted: seven parameters, the prefilter's edge margins and the
/// central-difference ends must leave a meaningful regression.
pub const MIN_SAMPLES: usize = 100;

/// Smallest peak-to-peak reference range accepted, axis units (1 µm or 1 mdeg): below it the run
/// excites nothing.
pub const MIN_MOTION: f64 = 1e-3;

/// Relative tolerance on the time step of a trace given by its time column. Real loggers jitter:
/// the EMPS benchmark's clock gives steps between 0.99998 ms and 1.00003 ms.
pub const TIME_JITTER: f64 = 1e-3;

/// Speed (axis units/s) below which a trace counts as starting at rest for the free-run
/// convention of [`Trace::prefixed_reference`] (the default sign deadband).
pub const REST_SPEED: f64 = 1.5;

/// How the sample instants of a logged trace are known ([`Trace::from_log`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Timing<'a> {
    /// A time column, s: always checked (strictly increasing, uniform within [`TIME_JITTER`],
    /// hence no gaps); the period is its median step.
    Column(&'a [f64]),
    /// A time column and a period the user states, s: the column is checked as for
    /// [`Timing::Column`] and its period must agree with the stated one within
    /// [`TIME_JITTER`]. A stated period never replaces the checks of an existing column.
    ColumnWithPeriod(&'a [f64], f64),
    /// No time column: the period, s.
    Period(f64),
}

/// Reference $x_r$ and measured position $x$ of one axis, sampled at the period `ts`.
///
/// Built by [`Trace::new`] or [`Trace::from_columns`], which validate the data; the fields are
/// public for reading, and code that edits them should rebuild the trace through a constructor.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// Sample period $T_s$, s.
    pub ts: f64,
    /// Reference position $x_{r,k}$, axis units (mm or deg).
    pub xr: Vec<f64>,
    /// Measured position $x_k$, axis units (mm or deg).
    pub x: Vec<f64>,
    /// Reference velocity $\dot x_{r,k}$ and acceleration $\ddot x_{r,k}$ (axis units/s, /s²)
    /// when known exactly (a simulated machine's interpolator); `None` for measured data, where
    /// central differences of $x_r$ stand in. Set by [`Trace::with_reference_derivatives`].
    /// The free-run simulation uses them: a model with $b_0 \ne 0$ (sliding mode) feeds the
    /// acceleration straight through, and central differences blur the steps of a trapezoidal
    /// profile's acceleration.
    pub reference_derivatives: Option<(Vec<f64>, Vec<f64>)>,
}

impl Trace {
    /// A trace sampled at the period `ts` (s). Checks: `ts` positive and finite, equal lengths,
    /// finite values, at least [`MIN_SAMPLES`] samples, reference range at least [`MIN_MOTION`].
    pub fn new(ts: f64, xr: Vec<f64>, x: Vec<f64>) -> Result<Trace, Error> {
        if !(ts > 0.0 && ts.is_finite()) {
            return Err(Error::BadSamplePeriod { ts });
        }
        if xr.len() != x.len() {
            return Err(Error::LengthMismatch {
                t: 0,
                xr: xr.len(),
                x: x.len(),
            });
        }
        check_finite("xr", &xr)?;
        check_finite("x", &x)?;
        if xr.len() < MIN_SAMPLES {
            return Err(Error::TooFewSamples {
                got: xr.len(),
                needed: MIN_SAMPLES,
            });
        }
        let (lo, hi) = xr
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(*v), hi.max(*v))
            });
        let range = hi - lo;
        if range.is_nan() || range < MIN_MOTION {
            return Err(Error::NoMotion {
                range,
                threshold: MIN_MOTION,
            });
        }
        Ok(Trace {
            ts,
            xr,
            x,
            reference_derivatives: None,
        })
    }

    /// Attaches the exact reference velocity `vr` (axis units/s) and acceleration `ar`
    /// (axis units/s²), checked for length and finiteness.
    pub fn with_reference_derivatives(
        mut self,
        vr: Vec<f64>,
        ar: Vec<f64>,
    ) -> Result<Trace, Error> {
        if vr.len() != self.xr.len() || ar.len() != self.xr.len() {
            return Err(Error::LengthMismatch {
                t: vr.len().max(ar.len()),
                xr: self.xr.len(),
                x: self.x.len(),
            });
        }
        check_finite("vr", &vr)?;
        check_finite("ar", &ar)?;
        self.reference_derivatives = Some((vr, ar));
        Ok(self)
    }

    /// The reference as the model simulation sees it, and whether a rest sample was prefixed.
    ///
    /// A trace that starts at rest ([`Trace::starts_at_rest`] with [`REST_SPEED`]) is returned
    /// as it is: the model starts at rest at $x_{r,0}$ at the first sample, exactly as the drive
    /// did (a prefixed rest sample would turn an acceleration step at $t_0$ into a one-sample
    /// ramp before it and make the model lead by half a sample). A trace that starts moving
    /// (EMPS) gets one rest sample at the measured $x_0$ prefixed (docs/drive-model.md and docs/reference-numbers.md):
    /// positions $[x_0, x_{r,0}, x_{r,1}, ...]$, so it enters as a one-sample ramp from $x_0$ to
    /// $x_{r,0}$. Velocity and acceleration are the exact ones when attached (with a zero
    /// prefixed), else central differences.
    pub fn prefixed_reference(&self) -> (Vec<f64>, Vec<f64>, Vec<f64>, bool) {
        let prefixed = !self.starts_at_rest(REST_SPEED);
        let x0 = self.x.first().copied().unwrap_or(0.0);
        let mut pos = Vec::with_capacity(self.xr.len() + 1);
        if prefixed {
            pos.push(x0);
        }
        pos.extend_from_slice(&self.xr);
        match &self.reference_derivatives {
            Some((vr, ar)) => {
                let mut vel = Vec::with_capacity(pos.len());
                let mut acc = Vec::with_capacity(pos.len());
                if prefixed {
                    vel.push(0.0);
                    acc.push(0.0);
                }
                vel.extend_from_slice(vr);
                acc.extend_from_slice(ar);
                (pos, vel, acc, prefixed)
            }
            None => {
                let (vel, acc) = vcnc_drive::model::central_differences(&pos, self.ts);
                (pos, vel, acc, prefixed)
            }
        }
    }

    /// The reference velocity and acceleration of the smooth model input
    /// ([`vcnc_drive::drive_model::ReferenceInput::Smooth`]): the exact ones when attached,
    /// else the central differences of $x_r$ ([`vcnc_drive::model::central_differences`]).
    pub fn smooth_rates(&self) -> (Vec<f64>, Vec<f64>) {
        match &self.reference_derivatives {
            Some((v, a)) => (v.clone(), a.clone()),
            None => vcnc_drive::model::central_differences(&self.xr, self.ts),
        }
    }

    /// A trace from raw logged columns: time `t` (s), reference `xr` and measured position `x`
    /// (axis units). The period is the median step; every step must lie within
    /// [`TIME_JITTER`] (relative) of it, and time must increase strictly.
    pub fn from_columns(t: &[f64], xr: &[f64], x: &[f64]) -> Result<Trace, Error> {
        if t.len() != xr.len() || t.len() != x.len() {
            return Err(Error::LengthMismatch {
                t: t.len(),
                xr: xr.len(),
                x: x.len(),
            });
        }
        check_finite("t", t)?;
        check_finite("xr", xr)?;
        check_finite("x", x)?;
        if t.len() < MIN_SAMPLES {
            return Err(Error::TooFewSamples {
                got: t.len(),
                needed: MIN_SAMPLES,
            });
        }
        for (k, w) in t.windows(2).enumerate() {
            if w[1] <= w[0] {
                return Err(Error::TimeNotIncreasing {
                    row: k + 1,
                    t_prev: w[0],
                    t: w[1],
                });
            }
        }
        // Nominal period: the median step (robust to one bad step, which is then the one
        // reported).
        let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
        let mid = steps.len() / 2;
        let ts = *steps.select_nth_unstable_by(mid, f64::total_cmp).1;
        for (k, w) in t.windows(2).enumerate() {
            let dt = w[1] - w[0];
            if (dt - ts).abs() > TIME_JITTER * ts {
                return Err(Error::NonUniformTime {
                    row: k + 1,
                    dt,
                    ts,
                    tolerance: TIME_JITTER,
                });
            }
        }
        Trace::new(ts, xr.to_vec(), x.to_vec())
    }

    /// A trace from a log: the columns `xr`, `x` (axis units) with their timing. The only way
    /// a user's file should become a trace: a time column, when the file has one, is always
    /// checked, whatever period the user states ([`Timing`]).
    pub fn from_log(timing: Timing<'_>, xr: Vec<f64>, x: Vec<f64>) -> Result<Trace, Error> {
        match timing {
            Timing::Column(t) => Trace::from_columns(t, &xr, &x),
            Timing::ColumnWithPeriod(t, ts) => {
                if !(ts > 0.0 && ts.is_finite()) {
                    return Err(Error::BadSamplePeriod { ts });
                }
                let tr = Trace::from_columns(t, &xr, &x)?;
                if (tr.ts - ts).abs() > TIME_JITTER * ts {
                    return Err(Error::PeriodMismatch {
                        given: ts,
                        measured: tr.ts,
                        tolerance: TIME_JITTER,
                    });
                }
                Ok(tr)
            }
            Timing::Period(ts) => Trace::new(ts, xr, x),
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether the trace has no samples (never true for a validated trace).
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Duration $(N-1) T_s$, s.
    pub fn duration_s(&self) -> f64 {
        self.len().saturating_sub(1) as f64 * self.ts
    }

    /// Whether the axis is at rest at the first sample: the reference speed there (the attached
    /// exact one, else the one-sided second-order difference $(-3x_0 + 4x_1 - x_2)/(2T_s)$,
    /// exact for a parabola) and the measured forward-difference speed are within `deadband`
    /// (axis units/s). The second-order difference sees a reference that starts accelerating
    /// from rest at $t_0$ as 0 whatever the acceleration (a forward difference sees
    /// $a T_s / 2$: 2.5 mm/s at 5000 mm/s² and 1 ms, above [`REST_SPEED`]), and a drive that
    /// is already moving (EMPS: 14 mm/s) as its speed. The measured position lags the
    /// reference, so its forward difference is near 0 at a rest start; a second-order
    /// difference would amplify its quantisation four times.
    pub fn starts_at_rest(&self, deadband: f64) -> bool {
        let forward = |s: &[f64]| match s {
            [a, b, ..] => ((b - a) / self.ts).abs(),
            _ => 0.0,
        };
        let vr0 = match (&self.reference_derivatives, self.xr.as_slice()) {
            (Some((vr, _)), _) => vr.first().copied().unwrap_or(0.0).abs(),
            (None, [a, b, c, ..]) => ((4.0 * b - 3.0 * a - c) / (2.0 * self.ts)).abs(),
            (None, xr) => forward(xr),
        };
        vr0 <= deadband && forward(&self.x) <= deadband
    }

    /// RMS of the tracking error $e = x_r - x$, axis units.
    pub fn tracking_rms(&self) -> f64 {
        let n = self.len().max(1) as f64;
        (self
            .xr
            .iter()
            .zip(&self.x)
            .map(|(r, x)| (r - x) * (r - x))
            .sum::<f64>()
            / n)
            .sqrt()
    }

    /// Peak $|x_r - x|$, axis units.
    pub fn tracking_peak(&self) -> f64 {
        self.xr
            .iter()
            .zip(&self.x)
            .map(|(r, x)| (r - x).abs())
            .fold(0.0, f64::max)
    }
}

fn check_finite(column: &'static str, v: &[f64]) -> Result<(), Error> {
    match v.iter().position(|v| !v.is_finite()) {
        Some(row) => Err(Error::NonFinite {
            column,
            row,
            value: v[row],
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(n: usize) -> Vec<f64> {
        (0..n).map(|k| k as f64 * 0.01).collect()
    }

    #[test]
    fn a_reference_accelerating_from_rest_is_a_rest_start_at_any_acceleration() {
        // Truth: x_r = a t^2 / 2 from t = 0 has zero speed at the first sample; x_r = x_0 + v t
        // has speed v. Accelerations from 500 to 50 000 mm/s² at 1 ms (a forward difference
        // would report a Ts / 2 = 0.25 .. 25 mm/s, most above the 1.5 mm/s rest speed).
        let n = 100;
        let ts = 1e-3;
        for a in [500.0, 2500.0, 5000.0, 20_000.0, 50_000.0] {
            let xr: Vec<f64> = (0..n).map(|k| 0.5 * a * (k as f64 * ts).powi(2)).collect();
            let tr = Trace::new(ts, xr, vec![0.0; n]).unwrap();
            assert!(tr.starts_at_rest(REST_SPEED), "a = {a} mm/s²");
        }
        for v in [2.0, 14.0, 250.0] {
            let xr: Vec<f64> = (0..n).map(|k| v * k as f64 * ts).collect();
            let x: Vec<f64> = xr.iter().map(|r| r - 0.01).collect();
            let tr = Trace::new(ts, xr, x).unwrap();
            assert!(!tr.starts_at_rest(REST_SPEED), "v = {v} mm/s");
        }
        // The reference starting from rest but the measured axis moving at 5 mm/s (a drive
        // still settling): not a rest start.
        let xr: Vec<f64> = (0..n)
            .map(|k| 0.5 * 2500.0 * (k as f64 * ts).powi(2))
            .collect();
        let x: Vec<f64> = (0..n).map(|k| 0.005 * k as f64).collect();
        assert!(!Trace::new(ts, xr, x).unwrap().starts_at_rest(REST_SPEED));
    }

    #[test]
    fn accepts_jittered_time_like_emps() {
        // EMPS logs t = 0, 0.00100002406, 0.00200000802, ...: within 3e-5 of 1 ms.
        let n = 200;
        let t: Vec<f64> = (0..n)
            .map(|k| k as f64 * 1e-3 + if k % 3 == 1 { 2.4e-8 } else { 0.0 })
            .collect();
        let tr = Trace::from_columns(&t, &ramp(n), &ramp(n)).unwrap();
        assert!((tr.ts - 1e-3).abs() < 1e-9);
    }

    #[test]
    fn a_stated_period_never_skips_the_time_column_checks() {
        // Regression (issue 18): a file whose time jumps back was accepted when a period was
        // given on the command line.
        let n = 200;
        let mut t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        t[120] = t[110];
        let back = Trace::from_log(Timing::ColumnWithPeriod(&t, 1e-3), ramp(n), ramp(n));
        assert!(
            matches!(back, Err(Error::TimeNotIncreasing { row: 120, .. })),
            "{back:?}"
        );
        // A gap of one missing sample.
        let gap: Vec<f64> = (0..n)
            .map(|k| if k < 100 { k } else { k + 1 } as f64 * 1e-3)
            .collect();
        assert!(matches!(
            Trace::from_log(Timing::ColumnWithPeriod(&gap, 1e-3), ramp(n), ramp(n)),
            Err(Error::NonUniformTime { row: 100, .. })
        ));
        // A column at 1 ms stated as 2 ms.
        let good: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        assert!(matches!(
            Trace::from_log(Timing::ColumnWithPeriod(&good, 2e-3), ramp(n), ramp(n)),
            Err(Error::PeriodMismatch { .. })
        ));
        // Agreeing: accepted; no column: the period alone.
        let ok = Trace::from_log(Timing::ColumnWithPeriod(&good, 1e-3), ramp(n), ramp(n));
        assert!((ok.unwrap().ts - 1e-3).abs() < 1e-12);
        assert!(Trace::from_log(Timing::Period(1e-3), ramp(n), ramp(n)).is_ok());
    }

    #[test]
    fn reports_each_bad_input_with_its_values() {
        let n = 200;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let mut x = ramp(n);
        x[17] = f64::NAN;
        match Trace::from_columns(&t, &ramp(n), &x) {
            Err(Error::NonFinite {
                column: "x",
                row: 17,
                ..
            }) => {}
            other => panic!("{other:?}"),
        }
        let mut t2 = t.clone();
        t2[50] = t2[49];
        assert!(matches!(
            Trace::from_columns(&t2, &ramp(n), &ramp(n)),
            Err(Error::TimeNotIncreasing { row: 50, .. })
        ));
        let mut t3 = t.clone();
        for v in t3.iter_mut().skip(100) {
            *v += 0.5e-3;
        }
        assert!(matches!(
            Trace::from_columns(&t3, &ramp(n), &ramp(n)),
            Err(Error::NonUniformTime { row: 100, .. })
        ));
        assert!(matches!(
            Trace::from_columns(&t[..10], &ramp(10), &ramp(10)),
            Err(Error::TooFewSamples {
                got: 10,
                needed: MIN_SAMPLES
            })
        ));
        assert!(matches!(
            Trace::new(1e-3, vec![5.0; n], vec![5.0; n]),
            Err(Error::NoMotion { .. })
        ));
        assert!(matches!(
            Trace::new(1e-3, ramp(n), ramp(n - 1)),
            Err(Error::LengthMismatch { .. })
        ));
        assert!(matches!(
            Trace::new(0.0, ramp(n), ramp(n)),
            Err(Error::BadSamplePeriod { .. })
        ));
    }
}
