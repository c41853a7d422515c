//! The control's reference shaping (docs/machine-file.md#reference): the interpolation delay and
//! the nominal-position filter, applied to position, velocity and acceleration alike, per lane.
//!
//! The delay and the moving average read past inputs at fixed lags, so both work on one linear
//! buffer: from `start` on, the last `keep` nominal references (the delay plus the window),
//! oldest first, followed by the block being shaped; after a block, `start` moves on by the
//! block's length, and the `keep` references go back to the front when the buffer's end is
//! reached (once per 16 blocks or more). No ring index per tick and value. The first- and
//! second-order filters are exact for a reference that is linear between ticks (first-order
//! hold, [`foh_filter`]). A band-stop is the second-order filter of its denominator with the
//! input passed through: its output is a fixed combination of the input and the two states
//! ([`band_stop_output`]), so it is exact for the same reference. The result does not depend on
//! how the ticks are split into blocks.

use std::f64::consts::TAU;

use nalgebra::SMatrix;

use crate::Error;
use crate::effects::{Shaping, ShapingFilter};
use crate::lane::Lane;
use crate::law::RefSample;
use crate::model::check_exp_norm;

/// The shaping of one drive, or of lanes of drives whose shaping has the same structure (the
/// same delay in ticks, and the same filter kind with the same moving-average window).
pub(crate) struct Shaper<T: Lane> {
    ext: Vec<RefSample<T>>,
    start: usize,
    keep: usize,
    filter: Filter<T>,
}

enum Filter<T: Lane> {
    None,
    /// $s^+ = \Phi s + \Gamma_0 u_k + \Gamma_1 u_{k+1}$ per channel (2 states), output $s_0$;
    /// with `through` (a band-stop), output $c_u u_{k+1} + c_0 s^+_0 + c_1 s^+_1$.
    Lin {
        phi: [[T; 2]; 2],
        g0: [T; 2],
        g1: [T; 2],
        s: [[T; 2]; 3],
        u_prev: [T; 3],
        through: Option<[T; 3]>,
    },
    /// Trapezoidal moving average over `m` ticks: running sum of the last m + 1 inputs.
    Avg {
        m: usize,
        sum: [T; 3],
        inv_m: T,
    },
}

/// The structure lanes must share to be shaped together: delay plus window, and the filter
/// kind with its window (a band-stop, whose input passes through, apart from the low-passes).
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    None,
    Lin { through: bool },
    Avg(usize),
}

fn window(shaping: &Option<Shaping>, h: f64) -> (Kind, usize) {
    let (filter, delay) = match shaping {
        None => (None, 0),
        Some(s) => (s.filter, s.delay_ticks),
    };
    match filter {
        None => (Kind::None, delay),
        Some(ShapingFilter::MovingAverage { window_s }) => {
            let m = (window_s / h).round().max(1.0) as usize;
            (Kind::Avg(m), delay + m + 1)
        }
        Some(ShapingFilter::BandStop { .. }) => (Kind::Lin { through: true }, delay),
        Some(_) => (Kind::Lin { through: false }, delay),
    }
}

impl<T: Lane> Shaper<T> {
    /// Holding `r0` before the first reference (every delayed or filtered channel starts
    /// there: a run starts at rest, [`RefSample::rest`]; a frequency response in its steady
    /// motion), lane `l` shaped by `shapings[l]` (the last one in the lanes beyond) at servo
    /// period `h`; `None` when the lanes' shapings differ in structure.
    pub(crate) fn new(
        shapings: &[Option<Shaping>],
        h: f64,
        r0: RefSample<T>,
    ) -> Result<Option<Shaper<T>>, Error> {
        let (kind, keep) = window(&shapings[0], h);
        if shapings[1..].iter().any(|s| window(s, h) != (kind, keep)) {
            return Ok(None);
        }
        let pick = |l: usize| shapings[l.min(shapings.len() - 1)];
        let u0 = [r0.xr, r0.vr, r0.ar];
        let filter = match kind {
            Kind::None => Filter::None,
            Kind::Avg(m) => {
                let n = T::splat((m + 1) as f64);
                Filter::Avg {
                    m,
                    sum: [u0[0] * n, u0[1] * n, u0[2] * n],
                    inv_m: T::splat(1.0 / m as f64),
                }
            }
            Kind::Lin { through } => {
                let mut lanes = Vec::with_capacity(T::WIDTH);
                for l in 0..T::WIDTH {
                    let Some(Shaping {
                        filter: Some(f), ..
                    }) = pick(l)
                    else {
                        unreachable!(
                            "the lanes share a first- or second-order filter or a band-stop"
                        )
                    };
                    lanes.push((foh_filter(f, h)?, band_stop_output(f)));
                }
                let c = |f: &dyn Fn(&FohFilter) -> f64| T::from_fn(|l| f(&lanes[l].0));
                // At rest on u0: s = [u0, 0] (the filters have unit DC gain).
                let zero = T::splat(0.0);
                Filter::Lin {
                    phi: std::array::from_fn(|i| std::array::from_fn(|j| c(&|f| f.phi[i][j]))),
                    g0: std::array::from_fn(|i| c(&|f| f.g0[i])),
                    g1: std::array::from_fn(|i| c(&|f| f.g1[i])),
                    s: [[u0[0], zero], [u0[1], zero], [u0[2], zero]],
                    u_prev: u0,
                    through: through.then(|| {
                        std::array::from_fn(|i| {
                            T::from_fn(|l| lanes[l].1.expect("the lanes share a band-stop")[i])
                        })
                    }),
                }
            }
        };
        Ok(Some(Shaper {
            ext: vec![r0; keep],
            start: 0,
            keep,
            filter,
        }))
    }

    /// Shapes the next `out.len()` ticks: `fill` writes their nominal references into the
    /// slice it is given, and `out` receives the loop's references.
    #[inline(always)]
    pub(crate) fn shape(
        &mut self,
        out: &mut [RefSample<T>],
        fill: impl FnOnce(&mut [RefSample<T>]),
    ) {
        let b = out.len();
        if self.keep == 0 {
            fill(out);
        } else {
            fill(self.inputs(b));
            self.delayed_into(out);
        }
        self.filter_in_place(out);
    }

    /// [`Shaper::shape`] of nominal references already in `buf`, in place.
    pub(crate) fn shape_block(&mut self, buf: &mut [RefSample<T>]) {
        if self.keep == 0 {
            self.filter_in_place(buf);
        } else {
            let b = buf.len();
            self.inputs(b).copy_from_slice(buf);
            self.delayed_into(buf);
            self.filter_in_place(buf);
        }
    }

    /// Room for the next `b` nominal references in the buffer, after the `keep` kept ones.
    #[inline(always)]
    fn inputs(&mut self, b: usize) -> &mut [RefSample<T>] {
        let keep = self.keep;
        if self.start + keep + b > self.ext.len() {
            self.ext.copy_within(self.start..self.start + keep, 0);
            self.start = 0;
            let len = keep + 16 * b;
            if self.ext.len() < len {
                // Beyond the kept inputs every slot is written before it is read.
                self.ext.resize(len, RefSample::zero());
            }
        }
        let s0 = self.start;
        &mut self.ext[s0 + keep..s0 + keep + b]
    }

    /// The delayed (and averaged) references of the `out.len()` inputs just written.
    #[inline(always)]
    fn delayed_into(&mut self, out: &mut [RefSample<T>]) {
        let (b, keep) = (out.len(), self.keep);
        let s0 = self.start;
        let ext = &self.ext[s0..s0 + keep + b];
        match &mut self.filter {
            Filter::Avg { m, sum, inv_m } => {
                // With the delay d = keep - m - 1, the averaged input of tick k is u_{k-d}, at
                // index m + 1 + j for tick k0 + j; the input leaving the running sum,
                // u_{k-d-m-1}, at index j; the window's oldest, u_{k-d-m}, at j + 1.
                let (m, inv_m) = (*m, *inv_m);
                let half = T::splat(0.5);
                let [mut a0, mut a1, mut a2] = *sum;
                let rows = out
                    .iter_mut()
                    .zip(&ext[m + 1..m + 1 + b])
                    .zip(ext[..b].iter().zip(&ext[1..b + 1]));
                for ((out, new), (leaving, oldest)) in rows {
                    a0 = a0 + (new.xr - leaving.xr);
                    a1 = a1 + (new.vr - leaving.vr);
                    a2 = a2 + (new.ar - leaving.ar);
                    *out = RefSample {
                        xr: (a0 - half * (new.xr + oldest.xr)) * inv_m,
                        vr: (a1 - half * (new.vr + oldest.vr)) * inv_m,
                        ar: (a2 - half * (new.ar + oldest.ar)) * inv_m,
                    };
                }
                *sum = [a0, a1, a2];
            }
            // The delayed input of tick k0 + j, u_{k0+j-keep}, is at index j.
            Filter::None | Filter::Lin { .. } => out.copy_from_slice(&ext[..b]),
        }
        self.start += b;
    }

    /// The first- or second-order filter or the band-stop over `buf`, in place.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // three channels side by side
    fn filter_in_place(&mut self, buf: &mut [RefSample<T>]) {
        let Filter::Lin {
            phi,
            g0,
            g1,
            s,
            u_prev,
            through,
        } = &mut self.filter
        else {
            return;
        };
        for r in buf.iter_mut() {
            let u = [r.xr, r.vr, r.ar];
            let mut y = [T::splat(0.0); 3];
            for c in 0..3 {
                let (s0, s1) = (s[c][0], s[c][1]);
                let n0 = phi[0][0] * s0 + phi[0][1] * s1 + g0[0] * u_prev[c] + g1[0] * u[c];
                let n1 = phi[1][0] * s0 + phi[1][1] * s1 + g0[1] * u_prev[c] + g1[1] * u[c];
                s[c] = [n0, n1];
                y[c] = match through {
                    None => n0,
                    Some([cu, c0, c1]) => *cu * u[c] + *c0 * n0 + *c1 * n1,
                };
            }
            *u_prev = u;
            *r = RefSample {
                xr: y[0],
                vr: y[1],
                ar: y[2],
            };
        }
    }
}

/// $\dot s = A s + B u$ of the second-order filter $\omega^2/(s^2 + 2\zeta\omega s + \omega^2)$:
/// $s = (y, \dot y)$.
fn second_order(w: f64, zeta: f64) -> ([[f64; 2]; 2], [f64; 2]) {
    ([[0.0, 1.0], [-w * w, -2.0 * zeta * w]], [0.0, w * w])
}

/// A band-stop's output $[c_u, c_0, c_1]$ from its input and the states $s = (y, \dot y)$ of
/// the second-order filter of its denominator (`None`: not a band-stop). With
/// $k = \omega_d^2/\omega_z^2$ and $G = \omega_d^2/(s^2 + 2\zeta_d\omega_d s + \omega_d^2)$,
/// $H = k + (1 - k)G + c_1 sG$ with $c_1 = 2(\zeta_z\omega_z - \zeta_d\omega_d)/\omega_z^2$
/// (both sides' numerators agree term by term); with equal frequencies, the identity plus
/// $2(\zeta_z - \zeta_d)/\omega$ times the filter's derivative.
fn band_stop_output(filter: ShapingFilter) -> Option<[f64; 3]> {
    let ShapingFilter::BandStop {
        frequency_hz,
        zeta_numerator,
        zeta_denominator,
        denominator_frequency_hz,
    } = filter
    else {
        return None;
    };
    let wz = TAU * frequency_hz;
    let wd = TAU * denominator_frequency_hz.unwrap_or(frequency_hz);
    let k = (wd / wz) * (wd / wz);
    let c1 = 2.0 * (zeta_numerator * wz - zeta_denominator * wd) / (wz * wz);
    Some([k, 1.0 - k, c1])
}

/// The discretised first- or second-order filter of one drive.
struct FohFilter {
    phi: [[f64; 2]; 2],
    g0: [f64; 2],
    g1: [f64; 2],
}

#[allow(clippy::needless_range_loop)] // 2×2 blocks: indices read best
/// FOH discretisation of $\dot s = A s + B u$ (docs/machine-file.md#reference): with $u$ linear
/// between ticks, $s^+ = \Phi s + \Gamma_a u_k + \Gamma_l (u_{k+1} - u_k)$ where the exponential
/// of $\begin{bmatrix}A & B & 0\\0 & 0 & 1\\0 & 0 & 0\end{bmatrix}h$ holds $\Phi$,
/// $\Gamma_a = \int_0^h e^{A\sigma}d\sigma B$ and $h\Gamma_l = \int_0^h e^{A\sigma}(h - \sigma)d\sigma B$.
fn foh_filter(filter: ShapingFilter, h: f64) -> Result<FohFilter, Error> {
    let (a, b) = match filter {
        ShapingFilter::FirstOrder { time_constant_s } => (
            [[-1.0 / time_constant_s, 0.0], [0.0, -1.0]],
            [1.0 / time_constant_s, 0.0],
        ),
        ShapingFilter::SecondOrder {
            time_constant_s,
            zeta,
        } => second_order(1.0 / time_constant_s, zeta),
        // A band-stop's states are those of its denominator's second-order filter.
        ShapingFilter::BandStop {
            frequency_hz,
            zeta_denominator,
            denominator_frequency_hz,
            ..
        } => second_order(
            TAU * denominator_frequency_hz.unwrap_or(frequency_hz),
            zeta_denominator,
        ),
        ShapingFilter::MovingAverage { .. } => {
            unreachable!("a moving average is not a first- or second-order filter")
        }
    };
    let mut m = SMatrix::<f64, 4, 4>::zeros();
    for i in 0..2 {
        for j in 0..2 {
            m[(i, j)] = a[i][j] * h;
        }
        m[(i, 2)] = b[i] * h;
    }
    m[(2, 3)] = 1.0;
    check_exp_norm(&m)?;
    let e = m.exp();
    let mut f = FohFilter {
        phi: [[0.0; 2]; 2],
        g0: [0.0; 2],
        g1: [0.0; 2],
    };
    for i in 0..2 {
        for j in 0..2 {
            f.phi[i][j] = e[(i, j)];
        }
        let ga = e[(i, 2)];
        let gl = e[(i, 3)];
        f.g1[i] = gl;
        f.g0[i] = ga - gl;
    }
    if !e.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFiniteModel);
    }
    Ok(f)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shaper's position output for a nominal position that ramps from 0 to 1 over one
    /// tick (a step, as the fine interpolation sees it) starting at tick 5.
    fn shaped_step(filter: ShapingFilter, h: f64, n: usize) -> Vec<f64> {
        let r = |x: f64| RefSample {
            xr: x,
            vr: 0.0,
            ar: 0.0,
        };
        let shaping = Some(Shaping {
            filter: Some(filter),
            delay_ticks: 0,
        });
        let mut s = Shaper::<f64>::new(&[shaping], h, r(0.0))
            .unwrap()
            .expect("one lane");
        (0..n)
            .map(|k| {
                let mut one = [r(if k >= 6 { 1.0 } else { 0.0 })];
                s.shape_block(&mut one);
                one[0].xr
            })
            .collect()
    }

    #[test]
    fn reference_filters_follow_their_analytic_step_responses() {
        // Truth: the continuous filters' responses to the input the servo loop sees, a ramp
        // from 0 to 1 over one tick h starting at t0 = 5h (the fine interpolation is linear
        // between ticks), in closed form: with S the filter's ramp response (integral of its
        // step response), y(t) = (S(t - t0) - S(t - t0 - h)) / h.
        let h = 5e-5;
        let t0 = 5.0 * h;
        let check = |filter, s_ramp: &dyn Fn(f64) -> f64, what: &str| {
            let y = shaped_step(filter, h, 2000);
            for (k, yk) in y.iter().enumerate() {
                let t = k as f64 * h - t0;
                let s = |t: f64| if t <= 0.0 { 0.0 } else { s_ramp(t) };
                let exact = (s(t) - s(t - h)) / h;
                // 1e-10 of the step: the closed forms themselves lose ~1e-12 to cancellation.
                assert!(
                    (yk - exact).abs() < 1e-10,
                    "{what}, tick {k}: {yk} vs {exact}"
                );
            }
        };
        let tf = 2e-3;
        check(
            ShapingFilter::FirstOrder {
                time_constant_s: tf,
            },
            &|t| t - tf * (1.0 - (-t / tf).exp()),
            "first order",
        );
        // Critically damped second order: step 1 - e^{-t/T}(1 + t/T), ramp
        // t - 2T + e^{-t/T}(2T + t).
        check(
            ShapingFilter::SecondOrder {
                time_constant_s: tf,
                zeta: 1.0,
            },
            &|t| t - 2.0 * tf + (-t / tf).exp() * (2.0 * tf + t),
            "second order, zeta 1",
        );
        // Underdamped: ramp response t - 2 zeta/wn + e^{-zeta wn t}(2 zeta/wn cos wd t
        // + (2 zeta² - 1)/wd sin wd t).
        let (zeta, wn) = (0.4, 1.0 / tf);
        let wd = wn * (1.0f64 - zeta * zeta).sqrt();
        check(
            ShapingFilter::SecondOrder {
                time_constant_s: tf,
                zeta,
            },
            &|t| {
                t - 2.0 * zeta / wn
                    + (-zeta * wn * t).exp()
                        * (2.0 * zeta / wn * (wd * t).cos()
                            + (2.0 * zeta * zeta - 1.0) / wd * (wd * t).sin())
            },
            "second order, zeta 0.4",
        );
        // Moving average over Tw: y(t) = (U(t) - U(t - Tw)) / Tw with U the input's integral;
        // for the unit ramp-step, S(t) = (Sr(t) - Sr(t - Tw)) / Tw with Sr(t) = t²/2.
        let tw = 80.0 * h;
        let sr = |t: f64| if t <= 0.0 { 0.0 } else { 0.5 * t * t };
        check(
            ShapingFilter::MovingAverage { window_s: tw },
            &|t| (sr(t) - sr(t - tw)) / tw,
            "moving average",
        );
    }
}
