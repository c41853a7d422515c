//! Small statistics of sample series.

/// `(a - b) * k` sample by sample: tracking errors `x_r - x` and prediction errors in µm/mdeg.
pub fn scaled_diff(a: &[f64], b: &[f64], k: f64) -> Vec<f64> {
    a.iter().zip(b).map(|(a, b)| (a - b) * k).collect()
}

/// `(max_abs, rms)` of [`scaled_diff`]`(a, b, k)` without building it (the same sums in the
/// same order, so the same bits).
pub fn scaled_diff_max_rms(a: &[f64], b: &[f64], k: f64) -> (f64, f64) {
    let mut acc = MaxRms::default();
    for (a, b) in a.iter().zip(b) {
        acc.add((a - b) * k);
    }
    acc.max_rms()
}

/// [`max_abs`] and [`rms`] of a series given a sample at a time (a streamed run's): the same
/// sums in the same order, so the same bits as over the whole series.
#[derive(Debug, Clone, Copy, Default)]
pub struct MaxRms {
    max: f64,
    sq: f64,
    n: usize,
}

impl MaxRms {
    /// Adds the next sample.
    #[inline]
    pub fn add(&mut self, x: f64) {
        self.max = self.max.max(x.abs());
        self.sq += x * x;
        self.n += 1;
    }

    /// Samples added.
    pub fn count(&self) -> usize {
        self.n
    }

    /// `(max |x|, RMS)` of the samples added; `(0, 0)` without any.
    pub fn max_rms(&self) -> (f64, f64) {
        if self.n == 0 {
            (0.0, 0.0)
        } else {
            (self.max, (self.sq / self.n as f64).sqrt())
        }
    }
}

/// Root mean square of a slice (0 for an empty one).
pub fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// Largest |x| of a slice (0 for an empty one).
pub fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

/// Relative error in percent, `100 (est − truth) / truth`.
pub fn rel_pct(est: f64, truth: f64) -> f64 {
    100.0 * (est - truth) / truth
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_of_a_known_series() {
        let v = [3.0, -4.0];
        assert_eq!(max_abs(&v), 4.0);
        assert!((rms(&v) - (12.5f64).sqrt()).abs() < 1e-15);
        assert_eq!(rms(&[]), 0.0);
        assert_eq!(
            scaled_diff(&[1.0, 2.0], &[0.5, 2.0], 1000.0),
            vec![500.0, 0.0]
        );
        assert!((rel_pct(110.0, 100.0) - 10.0).abs() < 1e-12);
    }
}
