//! The actual-value latency: from the logged actual position a model predicts to the physical
//! axis position (docs/drive-model.md#actual-value-latency).
//!
//! A control logs (and its position loop uses) the position reading of some servo cycles ago:
//! fieldbus transfer, sampling of the encoder interface. The logged actual position therefore
//! trails the physical axis by a latency $\tau$:
//! $$ x_\text{log}(t) = x(t - \tau), \qquad x(t) = x_\text{log}(t + \tau). $$
//! A model identified from nominal and logged positions predicts $x_\text{log}$, and no
//! identification can tell $\tau$ (a delay in the measurement and the same delay in the
//! actuation give the same record), so $\tau$ is **stated** — read from the control's
//! configuration — and the physical position is the model's prediction advanced by it.
//!
//! # The shift
//!
//! The predicted positions are samples $x_k = x(kT_s)$. With $\tau/T_s = m + u$, $m$ whole and
//! $0 \le u < 1$, the advanced sample $y_k = x((k + m + u)T_s)$ is the cubic (four-point)
//! Lagrange interpolant through $x_{k+m-1}, x_{k+m}, x_{k+m+1}, x_{k+m+2}$ at $u$:
//! $$ y_k = -\tfrac{u(u-1)(u-2)}{6}x_{k+m-1} + \tfrac{(u+1)(u-1)(u-2)}{2}x_{k+m}
//!          - \tfrac{(u+1)u(u-2)}{2}x_{k+m+1} + \tfrac{(u+1)u(u-1)}{6}x_{k+m+2}. $$
//! A whole number of samples ($u = 0$) is an exact copy. Before the first sample the signal is
//! the first (the axis at rest where the program starts). Within the last two samples, and up
//! to one sample past the last, the cubic through the last four samples is evaluated
//! (extrapolated past the end): the run ends where the reference does, while the axes are still
//! settling, and holding the last value there would leave the prediction a latency behind the
//! physical axis — at the spiral's end 0.8 mdeg on C, 1.7 µm at the tip. Farther past the end
//! (latencies over one sample) it is held at that extrapolation.
//!
//! **Error.** For a signal with a bounded fourth derivative $M_4$ the interpolation error is
//! $$ |y_k - x(t_k + \tau)| \le \frac{|(u+1)u(u-1)(u-2)|}{24}\,T_s^4 M_4
//!    \le \frac{9}{384}\,T_s^4 M_4 \approx 0.0234\,T_s^4 M_4 $$
//! (the Lagrange remainder; the largest factor is at $u = 1/2$). A model's position is
//! continuously differentiable, but its acceleration jumps where friction reverses or the
//! reference acceleration steps (through $b_0$); the cubic reproduces parabolas exactly, and
//! across a jump $\Delta a$ of the acceleration its error is at most $0.0357\,\Delta a\,T_s^2$
//! (any $u$; $0.0147\,\Delta a\,T_s^2$ for $u \le 0.1$; computed by brute force over the jump's
//! place). At $T_s = 1$ ms a jump of 50 mm/s² (a feed drive's Coulomb friction) costs at most
//! 1.8 nm.

/// `x` (samples at period `ts`, s) advanced by `shift_s` (s; negative: delayed), by the cubic
/// Lagrange interpolation of the module documentation (the start held, the end extrapolated by
/// at most one sample):
/// $y_k = x(kT_s + \text{shift})$. [`Shifter`] gives the same values, bit for bit, from a signal
/// that arrives a piece at a time.
pub fn shifted(x: &[f64], shift_s: f64, ts: f64) -> Vec<f64> {
    let n = x.len();
    if n == 0 || shift_s == 0.0 {
        return x.to_vec();
    }
    let shift = Shift::new(shift_s, ts);
    let last = n as i64 - 1;
    let at = |i: i64| x[i.clamp(0, last) as usize];
    (0..n as i64).map(|k| shift.value(k, last, at)).collect()
}

/// The shift by $m + u$ samples of the module documentation: what one output sample needs.
#[derive(Debug, Clone, Copy)]
struct Shift {
    /// Whole samples.
    m: i64,
    /// Fraction of a sample, `0 <= u < 1`.
    u: f64,
    /// The last node the interior formula reads, after $x_{k+m}$: 0 for a whole number of
    /// samples (an exact copy), 2 otherwise.
    reach: i64,
    /// The interior formula's Lagrange weights at `u`.
    w: [f64; 4],
}

impl Shift {
    fn new(shift_s: f64, ts: f64) -> Shift {
        let s = shift_s / ts;
        let m = s.floor();
        let u = s - m;
        Shift {
            m: m as i64,
            u,
            reach: if u == 0.0 { 0 } else { 2 },
            w: [
                -u * (u - 1.0) * (u - 2.0) / 6.0,
                (u + 1.0) * (u - 1.0) * (u - 2.0) / 2.0,
                -(u + 1.0) * u * (u - 2.0) / 2.0,
                (u + 1.0) * u * (u - 1.0) / 6.0,
            ],
        }
    }

    /// Whether output sample `k` is computed by the interior formula whatever the signal's
    /// length, given that samples up to `known` are known: everything it reads is known.
    fn interior(&self, k: i64, known: i64) -> bool {
        k + self.m + self.reach <= known
    }

    /// Output sample `k` of a signal whose last sample is `last` (`at(i)`: sample `i`, clamped
    /// to `0..=last`).
    #[inline]
    fn value(&self, k: i64, last: i64, at: impl Fn(i64) -> f64) -> f64 {
        let (u, w) = (self.u, &self.w);
        let j = k + self.m;
        if last >= 3 && j + self.reach > last {
            // The cubic through the last four samples at $e$ samples after the fourth-last,
            // $e \le 4$ (one sample past the end).
            let e = ((j - (last - 3)) as f64 + u).min(4.0);
            let l = [
                -(e - 1.0) * (e - 2.0) * (e - 3.0) / 6.0,
                e * (e - 2.0) * (e - 3.0) / 2.0,
                -e * (e - 1.0) * (e - 3.0) / 2.0,
                e * (e - 1.0) * (e - 2.0) / 6.0,
            ];
            l[0] * at(last - 3) + l[1] * at(last - 2) + l[2] * at(last - 1) + l[3] * at(last)
        } else if u == 0.0 {
            at(j)
        } else {
            w[0] * at(j - 1) + w[1] * at(j) + w[2] * at(j + 1) + w[3] * at(j + 2)
        }
    }
}

/// [`shifted`] of a signal that arrives a piece at a time (a streamed prediction,
/// docs/performance.md): the same values bit for bit, each given out as soon as the samples it
/// reads have arrived — $m + 2$ samples after its own for a shift of $m + u$ samples, the last
/// ones at [`Shifter::finish`]. It holds a few samples, never the signal.
#[derive(Debug, Clone)]
pub struct Shifter {
    /// `None`: no shift (samples pass through).
    shift: Option<Shift>,
    /// Samples `base..base + buf.len()` of the input.
    buf: std::collections::VecDeque<f64>,
    base: i64,
    /// Samples received.
    received: i64,
    /// The next output sample.
    next: i64,
}

impl Shifter {
    /// A shifter by `shift_s` (s) of samples at period `ts` (s).
    pub fn new(shift_s: f64, ts: f64) -> Shifter {
        Shifter {
            shift: (shift_s != 0.0).then(|| Shift::new(shift_s, ts)),
            buf: std::collections::VecDeque::new(),
            base: 0,
            received: 0,
            next: 0,
        }
    }

    /// Takes the next samples of the signal and appends to `out` every output sample that is
    /// now known.
    pub fn feed(&mut self, x: &[f64], out: &mut Vec<f64>) {
        let Some(shift) = self.shift else {
            out.extend_from_slice(x);
            self.received += x.len() as i64;
            return;
        };
        self.buf.extend(x);
        self.received += x.len() as i64;
        let known = self.received - 1;
        while self.next < self.received && shift.interior(self.next, known) {
            let (buf, base) = (&self.buf, self.base);
            out.push(shift.value(self.next, known, |i| {
                buf[(i.clamp(0, known) - base) as usize]
            }));
            self.next += 1;
        }
        // Keep what later samples read: from the next one's first node, and the last four
        // (the end's cubic).
        let keep_from = (self.next + shift.m - 1).min(self.received - 4).max(0);
        while self.base < keep_from {
            self.buf.pop_front();
            self.base += 1;
        }
    }

    /// The signal has ended: appends the remaining output samples to `out`.
    pub fn finish(mut self, out: &mut Vec<f64>) {
        let Some(shift) = self.shift else {
            return;
        };
        let last = self.received - 1;
        let (buf, base) = (&self.buf, self.base);
        while self.next < self.received {
            out.push(shift.value(self.next, last, |i| buf[(i.clamp(0, last) - base) as usize]));
            self.next += 1;
        }
    }
}

/// The bound of the shift's interpolation error for a signal whose fourth derivative is at most
/// `m4` (axis units/s⁴): $|(u+1)u(u-1)(u-2)|\,T_s^4 M_4 / 24$, axis units (module
/// documentation; 0 for a whole number of samples).
pub fn interpolation_error_bound(shift_s: f64, ts: f64, m4: f64) -> f64 {
    let s = shift_s / ts;
    let u = s - s.floor();
    ((u + 1.0) * u * (u - 1.0) * (u - 2.0)).abs() / 24.0 * ts.powi(4) * m4
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    #[test]
    fn a_sine_advanced_by_the_latency_is_within_the_lagrange_bound() {
        // Truth: x(t) = A sin(ωt) sampled, against the analytic A sin(ω(t + τ)); the bound is
        // the Lagrange remainder with M4 = A ω⁴. The start is excluded (held by design); the
        // end, extrapolated up to one sample, has the remainder of the last four samples'
        // cubic, at most Ts⁴ M4 (|e(e−1)(e−2)(e−3)|/24 ≤ 1 for e ≤ 4).
        let (a, f, ts) = (10.0, 20.0, 1e-3);
        let w = TAU * f;
        let n = 2000;
        let x: Vec<f64> = (0..n).map(|k| a * (w * k as f64 * ts).sin()).collect();
        for tau in [1e-4, 2.5e-4, 5e-4, 1.3e-3, 3.7e-3] {
            let y = shifted(&x, tau, ts);
            let bound = interpolation_error_bound(tau, ts, a * w.powi(4));
            let m = (tau / ts).ceil() as usize + 3;
            let err = (1..n - m)
                .map(|k| (y[k] - a * (w * (k as f64 * ts + tau)).sin()).abs())
                .fold(0.0f64, f64::max);
            assert!(err <= bound, "tau {tau}: error {err} > bound {bound}");
            // The bound is tight, not vacuous: the error reaches a good share of it.
            assert!(err > 0.5 * bound, "tau {tau}: error {err} ≪ bound {bound}");
            let end_bound = ts.powi(4) * a * w.powi(4);
            for (k, yk) in y.iter().enumerate().skip(n - m) {
                let q = k as f64 + tau / ts;
                if q <= (n - 1) as f64 + 1.0 {
                    let e = (yk - a * (w * (k as f64 * ts + tau)).sin()).abs();
                    assert!(e <= end_bound, "tau {tau}, sample {k}: {e} > {end_bound}");
                }
            }
        }
        // 20 Hz, ±10 mm (a peak acceleration of 158 m/s², far beyond a feed drive's) at 1 ms
        // advanced by 0.1 ms: below 20 nm.
        assert!(interpolation_error_bound(1e-4, ts, a * w.powi(4)) < 2e-5);
    }

    #[test]
    fn whole_samples_are_exact_the_start_held_and_the_end_extrapolated() {
        let x = [1.0, 2.0, 4.0, 8.0, 16.0];
        // Past the end: the cubic through 2, 4, 8, 16 one sample on (−2 + 16 − 48 + 64 = 30),
        // then held.
        assert_eq!(shifted(&x, 2e-3, 1e-3), vec![4.0, 8.0, 16.0, 30.0, 30.0]);
        assert_eq!(shifted(&x, -1e-3, 1e-3), vec![1.0, 1.0, 2.0, 4.0, 8.0]);
        assert_eq!(shifted(&x, 0.0, 1e-3), x.to_vec());
        // A cubic is reproduced exactly up to one sample past the end; a constant everywhere.
        let c: Vec<f64> = (0..20)
            .map(|k| {
                let t = k as f64;
                0.5 * t * t * t - 2.0 * t * t + t - 3.0
            })
            .collect();
        let y = shifted(&c, 0.37, 1.0);
        for (k, v) in y.iter().enumerate().skip(1) {
            let t = k as f64 + 0.37;
            let want = 0.5 * t * t * t - 2.0 * t * t + t - 3.0;
            assert!((v - want).abs() < 1e-9, "{k}: {v} vs {want}");
        }
        let flat = shifted(&[3.0; 7], 0.6e-3, 1e-3);
        assert!(flat.iter().all(|v| (v - 3.0).abs() < 1e-15), "{flat:?}");
    }

    #[test]
    fn the_shifter_gives_the_whole_signal_shift_bit_for_bit_for_any_pieces() {
        // Truth: `shifted` over the whole signal. Lengths from 1 sample (start and end rules
        // at once) to several hundred; shifts whole, fractional, over several samples, and
        // negative; pieces of 1, 2, 7 samples, the whole, and irregular ones.
        let signal = |n: usize| -> Vec<f64> {
            (0..n)
                .map(|k| (0.37 * k as f64).sin() * 5.0 + 1e-3 * (k * k) as f64)
                .collect()
        };
        let splits: [&[usize]; 5] = [&[1], &[2], &[7], &[usize::MAX], &[3, 1, 11, 2, 29, 5]];
        for n in [1, 2, 3, 4, 5, 9, 300] {
            let x = signal(n);
            for tau in [0.0, 1e-4, 1e-3, 2.5e-3, 7.3e-3, -1.6e-3] {
                let want = shifted(&x, tau, 1e-3);
                for split in splits {
                    let mut sh = Shifter::new(tau, 1e-3);
                    let mut got = Vec::new();
                    let (mut at, mut i) = (0, 0);
                    while at < n {
                        let len = split[i % split.len()].min(n - at);
                        sh.feed(&x[at..at + len], &mut got);
                        at += len;
                        i += 1;
                    }
                    sh.finish(&mut got);
                    let bits = |v: &[f64]| v.iter().map(|y| y.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&got), bits(&want), "n {n}, tau {tau}, split {split:?}");
                }
            }
        }
    }
}
