//! Zero-phase low-pass prefilter (docs/identification.md, "numerics that decide accuracy").
//!
//! Filtering both sides of a linear ODE with one LTI filter $L$ keeps its parameters: if
//! $Y = \Phi\Theta + r$ then $LY = (L\Phi)\Theta + Lr$. A forward-backward pass of a second-order
//! Butterworth section gives $|H(j\omega)|^2$ with zero phase, so no column is delayed relative
//! to another.

use crate::Error;

/// Second-order Butterworth low-pass section (bilinear transform with pre-warping), run forward
/// and backward for zero phase.
///
/// With $K = \tan(\pi f_c T_s)$ and $n = 1/(1 + \sqrt2 K + K^2)$:
/// $$ b_0 = K^2 n,\ b_1 = 2 b_0,\ b_2 = b_0,\quad a_1 = 2(K^2 - 1) n,\ a_2 = (1 - \sqrt2 K + K^2) n. $$
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Butterworth2 {
    b0: f64,
    b1: f64,
    b2: f64,
    a1: f64,
    a2: f64,
    /// Odd-reflection padding at each end, samples: about 14 time constants of the filter poles,
    /// so the edge transient decays below 1e-6.
    pub pad: usize,
}

impl Butterworth2 {
    /// Filter with cutoff `cutoff_hz` (Hz, below Nyquist) at sample period `ts` (s).
    pub fn new(cutoff_hz: f64, ts: f64) -> Result<Butterworth2, Error> {
        if !(ts > 0.0 && ts.is_finite()) {
            return Err(Error::BadSamplePeriod { ts });
        }
        let nyquist = 0.5 / ts;
        if !(cutoff_hz > 0.0 && cutoff_hz < 0.95 * nyquist) {
            return Err(Error::InvalidOption {
                name: "prefilter.cutoff_hz",
                value: cutoff_hz,
                expected: "a cutoff above 0 and below 0.95 times the Nyquist frequency 0.5/ts",
            });
        }
        let k = (std::f64::consts::PI * cutoff_hz * ts).tan();
        let sq2 = std::f64::consts::SQRT_2;
        let n = 1.0 / (1.0 + sq2 * k + k * k);
        let b0 = k * k * n;
        // Pole time constant sqrt(2)/(2 pi fc); 14 of them, in samples.
        let pad = (14.0 * sq2 / (std::f64::consts::TAU * cutoff_hz * ts)).ceil() as usize;
        Ok(Butterworth2 {
            b0,
            b1: 2.0 * b0,
            b2: b0,
            a1: 2.0 * (k * k - 1.0) * n,
            a2: (1.0 - sq2 * k + k * k) * n,
            pad: pad.max(3),
        })
    }

    /// Zero-phase filtering of `x` into `out` (same length), with odd-reflection padding
    /// ($2x_0 - x_i$ before the start, $2x_{N-1} - x_{N-1-i}$ after the end) and steady-state
    /// initial conditions: a linear operator, so applying it to every column keeps the
    /// regression equation exact up to the residual. Allocates only the end padding.
    pub fn filtfilt(&self, x: &[f64], out: &mut [f64]) {
        self.filtfilt_many([x], [out]);
    }

    /// [`Butterworth2::filtfilt`] of `M` signals of one length at once: the recursions are
    /// interleaved so that their latency chains overlap (about `M` times the throughput of
    /// one at a time). Signals are truncated to the shortest input/output length.
    pub fn filtfilt_many<const M: usize>(&self, x: [&[f64]; M], out: [&mut [f64]; M]) {
        let n = x
            .iter()
            .map(|s| s.len())
            .chain(out.iter().map(|s| s.len()))
            .min()
            .unwrap_or(0);
        for m in 0..M {
            out[m][..n].copy_from_slice(&x[m][..n]);
        }
        self.filtfilt_many_in_place(out.map(|o| &mut o[..n]));
    }

    /// [`Butterworth2::filtfilt_many`] overwriting its inputs (no output buffers to allocate,
    /// which for long traces saves the page faults of fresh memory). Signals are truncated to
    /// the shortest length.
    #[allow(clippy::needless_range_loop)] // sample k of every signal m, interleaved
    pub fn filtfilt_many_in_place<const M: usize>(&self, sig: [&mut [f64]; M]) {
        let n = sig.iter().map(|s| s.len()).min().unwrap_or(0);
        if n < 2 {
            return;
        }
        let pad = self.pad.min(n - 1);
        // The right padding reflects the last `pad + 1` inputs, which the forward pass
        // overwrites: keep them (reversed, so that `right[m][i]` is the input `n - 1 - i`).
        let right: [Vec<f64>; M] =
            std::array::from_fn(|m| sig[m][n - 1 - pad..n].iter().rev().copied().collect());
        // Forward pass over [left pad, signal, right pad].
        let mut st: [[f64; 4]; M] =
            std::array::from_fn(|m| self.steady(2.0 * sig[m][0] - sig[m][pad]));
        for i in (1..=pad).rev() {
            for m in 0..M {
                self.step(&mut st[m], 2.0 * sig[m][0] - sig[m][i]);
            }
        }
        for k in 0..n {
            for m in 0..M {
                sig[m][k] = self.step(&mut st[m], sig[m][k]);
            }
        }
        let mut tail = vec![[0.0; M]; pad];
        for (i, t) in tail.iter_mut().enumerate() {
            for m in 0..M {
                t[m] = self.step(&mut st[m], 2.0 * right[m][0] - right[m][i + 1]);
            }
        }
        // Backward pass from the end of the right pad.
        let mut st: [[f64; 4]; M] =
            std::array::from_fn(|m| self.steady(tail.last().map_or(sig[m][n - 1], |t| t[m])));
        for t in tail.iter().rev() {
            for m in 0..M {
                self.step(&mut st[m], t[m]);
            }
        }
        for k in (0..n).rev() {
            for m in 0..M {
                sig[m][k] = self.step(&mut st[m], sig[m][k]);
            }
        }
    }

    /// Direct form I step (state: the last two inputs, then the last two outputs); returns
    /// the output. Everything but $-a_1 y_{k-1}$ is known a step early, so the recursion's
    /// critical path is one multiply and one subtraction (two thirds of direct form II
    /// transposed, whose chain also runs through the state update).
    #[inline(always)]
    fn step(&self, st: &mut [f64; 4], u: f64) -> f64 {
        let [u1, u2, y1, y2] = *st;
        let early = self.b0 * u + self.b1 * u1 + self.b2 * u2 - self.a2 * y2;
        let y = early - self.a1 * y1;
        *st = [u, u1, y, y1];
        y
    }

    /// State for a constant input `c` held forever (unit DC gain: the output is `c` too).
    fn steady(&self, c: f64) -> [f64; 4] {
        [c; 4]
    }

    /// Power gain $|H(e^{j\omega T_s})|^2$ of the zero-phase (forward-backward) filter at `f_hz`.
    pub fn zero_phase_gain(&self, f_hz: f64, ts: f64) -> f64 {
        let w = std::f64::consts::TAU * f_hz * ts;
        let (c1, s1, c2, s2) = (w.cos(), -w.sin(), (2.0 * w).cos(), -(2.0 * w).sin());
        let num = (
            self.b0 + self.b1 * c1 + self.b2 * c2,
            self.b1 * s1 + self.b2 * s2,
        );
        let den = (
            1.0 + self.a1 * c1 + self.a2 * c2,
            self.a1 * s1 + self.a2 * s2,
        );
        (num.0 * num.0 + num.1 * num.1) / (den.0 * den.0 + den.1 * den.1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    #[test]
    fn cutoff_is_minus_six_db_after_two_passes() {
        // Truth: a Butterworth section is -3 dB at its cutoff, so forward-backward is -6 dB.
        let f = Butterworth2::new(100.0, 1e-3).unwrap();
        assert!((f.zero_phase_gain(100.0, 1e-3) - 0.5).abs() < 1e-12);
        assert!((f.zero_phase_gain(0.0, 1e-3) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn sine_passes_with_zero_phase_and_predicted_gain() {
        // Truth: steady-state response of a zero-phase filter to a sine is the sine scaled by
        // |H|^2, with no delay.
        let ts = 1e-3;
        let filt = Butterworth2::new(50.0, ts).unwrap();
        let fsig = 20.0;
        let x: Vec<f64> = (0..4000)
            .map(|k| (TAU * fsig * k as f64 * ts).sin())
            .collect();
        let mut y = vec![0.0; x.len()];
        filt.filtfilt(&x, &mut y);
        let g = filt.zero_phase_gain(fsig, ts);
        let err = (500..3500)
            .map(|k| (y[k] - g * x[k]).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "max deviation {err}");
    }

    #[test]
    fn keeps_ramps_up_to_the_ends() {
        // Odd reflection continues a straight line, so a ramp passes unchanged but for the
        // decayed start-up transient of the padding (14 time constants: below 1e-8 relative).
        let filt = Butterworth2::new(30.0, 1e-3).unwrap();
        let x: Vec<f64> = (0..500).map(|k| 3.0 + 0.25 * k as f64).collect();
        let mut y = vec![0.0; x.len()];
        filt.filtfilt(&x, &mut y);
        let err = x
            .iter()
            .zip(&y)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-8 * 125.0, "max deviation {err}");
    }

    #[test]
    fn rejects_cutoff_above_nyquist() {
        assert!(Butterworth2::new(600.0, 1e-3).is_err());
        assert!(Butterworth2::new(0.0, 1e-3).is_err());
        assert!(Butterworth2::new(f64::NAN, 1e-3).is_err());
    }
}
