//! The control's nominal-position filter chain (docs/machine-file.md#control): what a CNC does
//! to its interpolated setpoints before handing them to the drives — a delay of whole
//! interpolation periods and a chain of low-pass filters (first order, second order, moving
//! average; a triangle filter is two moving averages; an FIR filter of given taps), applied to
//! position, velocity and acceleration alike so that the feed-forward stays consistent.
//!
//! It is the same law as a drive's own reference shaping (`[axes.<A>.reference]`,
//! [`crate::ReferenceShaping`]), stepped by the same code at the interpolation period instead
//! of the servo period: the first- and second-order filters exactly for a reference that is
//! linear between samples, the moving average as the trapezoidal sum over its window. An FIR
//! filter is a law of the samples themselves, $y_k = \sum_j h_j u_{k-j}$, and acts after the
//! others (linear filters commute; several FIR filters are one, their taps convolved). Each
//! stage starts at rest on the first reference sample, so the filter is causal and hands on
//! exactly as many samples as it receives; fed in pieces it gives the whole run's values bit
//! for bit.

use crate::Error;
use crate::effects::{ReferenceShaping, Shaping, ShapingFilter, check_shaping};
use crate::engine::ReferenceShaper;
use crate::law::RefSample;
use crate::model::Reference;

/// A checked nominal-position filter chain at an interpolation period.
#[derive(Debug, Clone, PartialEq)]
pub struct NominalFilter {
    ts: f64,
    delay_s: f64,
    filters: Vec<ShapingFilter>,
    /// Per stage: the delay (first stage only) and its filter, in whole periods.
    stages: Vec<Shaping>,
    /// The FIR filter's taps, newest sample first (`None`: none).
    fir: Option<Vec<f64>>,
}

/// Most taps an FIR filter may have.
pub const MAX_FIR_TAPS: usize = 4096;

impl NominalFilter {
    /// The chain: a delay of `delay_s` (a whole number of periods `ts`, at most 1 s), then
    /// `filters` in order (each checked as [`ReferenceShaping::filter`] is, at the period `ts`:
    /// time constants in (0, 1] s, ζ in (0, 2], moving-average windows whole periods).
    pub fn new(delay_s: f64, filters: &[ShapingFilter], ts: f64) -> Result<NominalFilter, Error> {
        if !(ts > 0.0 && ts.is_finite()) {
            return Err(Error::BadSamplePeriod { ts });
        }
        let rate = 1.0 / ts;
        let mut stages = Vec::new();
        let first = check_shaping(
            &ReferenceShaping {
                filter: filters.first().copied(),
                interpolation_delay_s: delay_s,
            },
            rate,
        )?;
        stages.extend(first);
        for f in filters.iter().skip(1) {
            let s = check_shaping(
                &ReferenceShaping {
                    filter: Some(*f),
                    interpolation_delay_s: 0.0,
                },
                rate,
            )?;
            stages.extend(s);
        }
        Ok(NominalFilter {
            ts,
            delay_s,
            filters: filters.to_vec(),
            stages,
            fir: None,
        })
    }

    /// The chain followed by an FIR filter of `taps` ($h_0$ for the newest sample first; at
    /// most [`MAX_FIR_TAPS`], finite, summing to 1 within $10^{-9}$: unit static gain); a
    /// second call convolves the taps with the first's.
    pub fn with_fir(mut self, taps: &[f64]) -> Result<NominalFilter, Error> {
        let sum: f64 = taps.iter().sum();
        if taps.is_empty() || taps.len() > MAX_FIR_TAPS || taps.iter().any(|h| !h.is_finite()) {
            return Err(Error::BadParameter {
                name: "fir.taps",
                value: taps.len() as f64,
                expected: "1 to 4096 finite taps",
            });
        }
        if (sum - 1.0).abs() > 1e-9 {
            return Err(Error::BadParameter {
                name: "fir.taps (their sum)",
                value: sum,
                expected: "1 within 1e-9 (unit static gain: divide the taps by their sum)",
            });
        }
        let taps = match self.fir.take() {
            None => taps.to_vec(),
            Some(h) => {
                let mut c = vec![0.0; h.len() + taps.len() - 1];
                for (i, a) in h.iter().enumerate() {
                    for (j, b) in taps.iter().enumerate() {
                        c[i + j] += a * b;
                    }
                }
                c
            }
        };
        if taps.len() > MAX_FIR_TAPS {
            return Err(Error::BadParameter {
                name: "fir.taps",
                value: taps.len() as f64,
                expected: "at most 4096 taps in all",
            });
        }
        self.fir = Some(taps);
        Ok(self)
    }

    /// The FIR filter's taps, if any.
    pub fn fir(&self) -> Option<&[f64]> {
        self.fir.as_deref()
    }

    /// The delay, s.
    pub fn delay_s(&self) -> f64 {
        self.delay_s
    }

    /// The filters, in order.
    pub fn filters(&self) -> &[ShapingFilter] {
        &self.filters
    }

    /// The interpolation period, s.
    pub fn ts(&self) -> f64 {
        self.ts
    }

    /// Neither delay nor filter: the chain hands on its input.
    pub fn is_identity(&self) -> bool {
        self.stages.is_empty() && self.fir.is_none()
    }

    /// A stream of this chain, at rest until its first sample.
    pub fn stream(&self) -> NominalStream {
        NominalStream {
            filter: self.clone(),
            shapers: Vec::new(),
            buf: Vec::new(),
            past: Vec::new(),
            seen: 0,
        }
    }
}

/// [`NominalFilter`] fed a piece of the reference at a time.
pub struct NominalStream {
    filter: NominalFilter,
    /// One per stage, made at the first sample (at rest on it).
    shapers: Vec<ReferenceShaper<f64>>,
    buf: Vec<RefSample<f64>>,
    /// The FIR filter's input: its last `taps − 1` samples (at rest on the first before the
    /// start), then the piece.
    past: Vec<RefSample<f64>>,
    /// Samples fed so far.
    seen: usize,
}

impl NominalStream {
    /// Filters the next piece `r` into `pos`, `vel`, `acc` (cleared first; as long as the
    /// piece).
    pub fn feed(
        &mut self,
        r: Reference<'_>,
        pos: &mut Vec<f64>,
        vel: &mut Vec<f64>,
        acc: &mut Vec<f64>,
    ) -> Result<(), Error> {
        let n = r.check_piece(self.seen)?;
        self.seen += n;
        pos.clear();
        vel.clear();
        acc.clear();
        if n == 0 {
            return Ok(());
        }
        if self.shapers.is_empty() && !self.filter.stages.is_empty() {
            let r0 = RefSample {
                xr: r.pos[0],
                vr: r.vel[0],
                ar: r.acc[0],
            };
            for s in &self.filter.stages {
                let shaper = ReferenceShaper::new(&[Some(*s)], self.filter.ts, r0)?
                    .expect("one lane always has one structure");
                self.shapers.push(shaper);
            }
        }
        self.buf.clear();
        self.buf.extend((0..n).map(|k| RefSample {
            xr: r.pos[k],
            vr: r.vel[k],
            ar: r.acc[k],
        }));
        for s in &mut self.shapers {
            s.shape_block(&mut self.buf);
        }
        if let Some(h) = &self.filter.fir {
            let l = h.len();
            if self.past.is_empty() {
                self.past = vec![self.buf[0]; l - 1];
            }
            self.past.extend_from_slice(&self.buf);
            for (k, out) in self.buf.iter_mut().enumerate() {
                // Output k: the newest input at past[k + l − 1], h_j weighting past[k + l − 1 − j].
                let w = &self.past[k..k + l];
                let (mut x, mut v, mut a) = (0.0, 0.0, 0.0);
                for (hj, u) in h.iter().zip(w.iter().rev()) {
                    x += hj * u.xr;
                    v += hj * u.vr;
                    a += hj * u.ar;
                }
                *out = RefSample {
                    xr: x,
                    vr: v,
                    ar: a,
                };
            }
            self.past.drain(..n);
        }
        pos.extend(self.buf.iter().map(|s| s.xr));
        vel.extend(self.buf.iter().map(|s| s.vr));
        acc.extend(self.buf.iter().map(|s| s.ar));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(f: &NominalFilter, x: &[f64], pieces: &[usize]) -> Vec<f64> {
        let (v, a) = crate::model::central_differences(x, f.ts());
        let mut s = f.stream();
        let (mut p, mut vv, mut aa) = (Vec::new(), Vec::new(), Vec::new());
        let mut out = Vec::new();
        let mut at = 0usize;
        for &len in pieces.iter().chain(std::iter::once(&usize::MAX)) {
            let end = at.saturating_add(len).min(x.len());
            s.feed(
                Reference {
                    pos: &x[at..end],
                    vel: &v[at..end],
                    acc: &a[at..end],
                },
                &mut p,
                &mut vv,
                &mut aa,
            )
            .unwrap();
            out.extend_from_slice(&p);
            at = end;
            if at == x.len() {
                break;
            }
        }
        out
    }

    #[test]
    fn a_triangle_is_two_moving_averages_and_a_delay_shifts_by_whole_periods() {
        // Truths: a moving average of m samples over a reference linear between samples is
        // the trapezoidal mean over its window (exact: a ramp is delayed by m/2 periods), two
        // in a row over a ramp delay it by their two half-windows, and a delay of d periods
        // hands on sample k - d (the first sample before the start).
        let ts = 1e-3;
        let x: Vec<f64> = (0..200)
            .map(|k| if k < 20 { 0.0 } else { (k - 20) as f64 * 0.01 })
            .collect();
        let ma = |w| ShapingFilter::MovingAverage { window_s: w };
        let tri = NominalFilter::new(0.0, &[ma(0.004), ma(0.004)], ts).unwrap();
        let y = run(&tri, &x, &[7, 1, 50]);
        for (k, yk) in y.iter().enumerate().skip(40) {
            // A ramp of slope 0.01 per sample, delayed by 2 + 2 samples.
            assert!((yk - (k as f64 - 24.0) * 0.01).abs() < 1e-12, "{k}: {yk}");
        }
        let delay = NominalFilter::new(0.003, &[], ts).unwrap();
        let y = run(&delay, &x, &[5, 5]);
        for (k, yk) in y.iter().enumerate() {
            assert_eq!(*yk, x[k.saturating_sub(3)]);
        }
        assert!(NominalFilter::new(0.0, &[], ts).unwrap().is_identity());
    }

    #[test]
    fn pieces_give_the_whole_run_bit_for_bit() {
        let ts = 5e-4;
        let x: Vec<f64> = (0..3000)
            .map(|k| (k as f64 * ts * 7.0).sin() * 3.0 + (k as f64 * ts * 29.0).cos())
            .collect();
        let f = NominalFilter::new(
            0.002,
            &[
                ShapingFilter::SecondOrder {
                    time_constant_s: 0.003,
                    zeta: 0.7,
                },
                ShapingFilter::MovingAverage { window_s: 0.004 },
                ShapingFilter::FirstOrder {
                    time_constant_s: 0.01,
                },
            ],
            ts,
        )
        .unwrap();
        assert_eq!(run(&f, &x, &[3000]), run(&f, &x, &[1, 2, 333, 1000, 17]));
    }

    #[test]
    fn an_fir_filter_is_its_convolution_sum_from_rest() {
        // Truth: y_k = Σ_j h_j u_{k−j} with u_{k} = u_0 before the start, summed here
        // directly; two FIR filters in a row are one with the taps convolved.
        let ts = 1e-3;
        let x: Vec<f64> = (0..300)
            .map(|k| ((k * k) % 17) as f64 * 0.1 + k as f64 * 0.01)
            .collect();
        let h = [0.1, 0.2, 0.4, 0.2, 0.1];
        let f = NominalFilter::new(0.0, &[], ts)
            .unwrap()
            .with_fir(&h)
            .unwrap();
        let y = run(&f, &x, &[4, 1, 100]);
        for (k, yk) in y.iter().enumerate() {
            let want: f64 = h
                .iter()
                .enumerate()
                .map(|(j, hj)| hj * x[k.saturating_sub(j)])
                .sum();
            assert!((yk - want).abs() < 1e-12, "{k}: {yk} against {want}");
        }
        let g = [0.5, 0.5];
        let twice = NominalFilter::new(0.0, &[], ts)
            .unwrap()
            .with_fir(&h)
            .unwrap()
            .with_fir(&g)
            .unwrap();
        let once = f.clone();
        let y2 = run(&twice, &x, &[300]);
        let y1 = run(&once, &x, &[300]);
        for k in 1..300 {
            let want = 0.5 * y1[k] + 0.5 * y1[k - 1];
            assert!((y2[k] - want).abs() < 1e-12, "{k}");
        }
        assert!(
            NominalFilter::new(0.0, &[], ts)
                .unwrap()
                .with_fir(&[0.5, 0.4])
                .is_err()
        );
        assert!(
            NominalFilter::new(0.0, &[], ts)
                .unwrap()
                .with_fir(&[])
                .is_err()
        );
    }

    #[test]
    fn bad_stages_are_refused_naming_the_value() {
        let ts = 1e-3;
        for (delay, f) in [
            (0.0015, None),
            (0.0, Some(ShapingFilter::MovingAverage { window_s: 0.0025 })),
            (
                0.0,
                Some(ShapingFilter::FirstOrder {
                    time_constant_s: -1.0,
                }),
            ),
            (
                0.0,
                Some(ShapingFilter::SecondOrder {
                    time_constant_s: 0.01,
                    zeta: 3.0,
                }),
            ),
        ] {
            let filters: Vec<ShapingFilter> = f.into_iter().collect();
            let e = NominalFilter::new(delay, &filters, ts).unwrap_err();
            assert!(matches!(e, Error::BadParameter { .. }), "{e}");
        }
    }
}
