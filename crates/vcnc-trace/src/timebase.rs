//! Time columns checked into a uniform time base: first time, period, gaps (see
//! [`STEP_TOLERANCE`]).

/// Largest distance of a step from a whole number of periods, in periods: how time columns are
/// checked into a uniform time base (first time, period, gaps).
///
/// Scope samples are taken on the control's clock; a time column only repeats that clock, rounded
/// to the digits printed. A column is accepted when every step $\Delta t_k$ is within
/// [`STEP_TOLERANCE`] of a whole number $m_k \ge 1$ of periods $T$:
/// $$ \left| \frac{\Delta t_k}{T} - m_k \right| \le 0.2 . $$
/// $m_k = 1$ is a normal step, $m_k \ge 2$ a gap of $m_k - 1$ lost samples; anything else is an
/// irregular step and an error, as is time that stands still or goes back. $T$ is the period the
/// file declares, else the lower median step (robust to gaps); without a declaration it is then refined
/// to the mean over the whole record,
/// $$ T = \frac{t_{N-1} - t_0}{N - 1 + L}, $$
/// with $L$ the lost samples, which removes the rounding of individual steps. A declared period
/// must agree with that mean within 1 %.
pub const STEP_TOLERANCE: f64 = 0.2;

/// Largest relative difference between a declared period and the mean step.
pub const DECLARED_TOLERANCE: f64 = 0.01;

/// A checked time column.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Uniform {
    /// Time of the first sample, s.
    pub t0_s: f64,
    /// Sample period, s (`None` for fewer than two samples and no declaration).
    pub period_s: Option<f64>,
    /// Gaps: (index of the first sample after the gap, samples lost).
    pub gaps: Vec<(usize, usize)>,
}

/// Why a time column is not uniform; `row` indexes the column.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum TimeFault {
    /// `t[row] <= t[row - 1]`.
    NotIncreasing { row: usize, t_prev: f64, t: f64 },
    /// `t[row] - t[row - 1]` is not a whole number of periods.
    Irregular { row: usize, dt: f64, period: f64 },
    /// The mean step disagrees with the declared period.
    Mismatch { mean: f64, declared: f64 },
}

/// Checks `times` (s); `declared` is a period the file states (s).
pub(crate) fn uniform(times: &[f64], declared: Option<f64>) -> Result<Uniform, TimeFault> {
    let n = times.len();
    let t0_s = times.first().copied().unwrap_or(0.0);
    if n < 2 {
        return Ok(Uniform {
            t0_s,
            period_s: declared,
            gaps: Vec::new(),
        });
    }
    for k in 1..n {
        if times[k] <= times[k - 1] {
            return Err(TimeFault::NotIncreasing {
                row: k,
                t_prev: times[k - 1],
                t: times[k],
            });
        }
    }
    let period = match declared {
        Some(p) => p,
        None => median_step(times),
    };
    let mut gaps = Vec::new();
    let mut lost_total = 0usize;
    for k in 1..n {
        let dt = times[k] - times[k - 1];
        let r = dt / period;
        let m = r.round();
        if m < 1.0 || (r - m).abs() > STEP_TOLERANCE {
            return Err(TimeFault::Irregular { row: k, dt, period });
        }
        if m >= 2.0 {
            // Saturating: an absurd step (a time column of another unit) must not overflow.
            let lost = (m as usize).saturating_sub(1);
            lost_total = lost_total.saturating_add(lost);
            gaps.push((k, lost));
        }
    }
    let mean = (times[n - 1] - t0_s) / (n - 1).saturating_add(lost_total) as f64;
    let period_s = match declared {
        Some(d) => {
            if (mean / d - 1.0).abs() > DECLARED_TOLERANCE {
                return Err(TimeFault::Mismatch { mean, declared: d });
            }
            d
        }
        None => mean,
    };
    Ok(Uniform {
        t0_s,
        period_s: Some(period_s),
        gaps,
    })
}

/// Lower median of the steps, from at most 100 001 of them spread over the record.
fn median_step(times: &[f64]) -> f64 {
    let steps = times.len() - 1;
    let stride = steps.div_ceil(100_000).max(1);
    let mut s: Vec<f64> = (1..times.len())
        .step_by(stride)
        .map(|k| times[k] - times[k - 1])
        .collect();
    // The lower median: of two steps, a normal one and a gap, it takes the normal one.
    let mid = (s.len() - 1) / 2;
    *s.select_nth_unstable_by(mid, f64::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounded_times_give_the_exact_mean_period() {
        // 1 ms printed to 0.1 ms resolution around 1/3-ms offsets: steps jitter, the mean is exact.
        let t: Vec<f64> = (0..1000)
            .map(|k| ((k as f64 * 1e-3 + 1.0 / 3.0) * 1e4).round() / 1e4)
            .collect();
        let u = uniform(&t, None).unwrap();
        assert!((u.period_s.unwrap() - 1e-3).abs() < 1e-9);
        assert!(u.gaps.is_empty());
    }

    #[test]
    fn gaps_and_faults() {
        let mut t: Vec<f64> = (0..10).map(|k| k as f64 * 0.5).collect();
        t.drain(4..7); // samples 4, 5, 6 lost
        let u = uniform(&t, None).unwrap();
        assert_eq!(u.gaps, vec![(4, 3)]);
        assert_eq!(u.period_s, Some(0.5));
        assert_eq!(
            uniform(&[0.0, 1.0, 1.0], None),
            Err(TimeFault::NotIncreasing {
                row: 2,
                t_prev: 1.0,
                t: 1.0
            })
        );
        assert!(matches!(
            uniform(&[0.0, 1.0, 2.0, 3.5, 4.5], None),
            Err(TimeFault::Irregular { row: 3, .. })
        ));
        assert!(matches!(
            uniform(&[0.0, 1.0, 2.0], Some(1.05)),
            Err(TimeFault::Mismatch { .. })
        ));
        assert_eq!(uniform(&[2.0], None).unwrap().period_s, None);
    }
}
