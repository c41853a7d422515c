//! The true drive's frequency response, measured as a drive commissioning tool measures it: by
//! simulating the drive (every effect included) under a multisine excitation and dividing the
//! spectra of output and input at the excited lines (docs/machine-file.md#frequency-response-of-the-true-drive).
//!
//! # Method
//!
//! 1. **Excitation.** A multisine of period $T = 1/f_0$ with $M$ lines at harmonics $k_i f_0$
//!    between `f_min_hz` and `f_max_hz` (every harmonic, or about `lines` of them spaced
//!    logarithmically), Schroeder phases $\varphi_i = -\pi i (i - 1)/M$ (a low crest factor), and
//!    scaled to the requested peak: for [`FrfKind::Tracking`] and [`FrfKind::LoadTracking`] a
//!    nominal-position multisine with equal velocity amplitude on every line,
//!    $m(t) = \sum_i \frac{a}{\omega_i}\sin(\omega_i t + \varphi_i)$ (with its exact velocity and
//!    acceleration as feed-forward), whose peak velocity is `amplitude`; for
//!    [`FrfKind::Mechanical`] a torque multisine $\sum_i a\cos(\omega_i t + \varphi_i)$ of peak
//!    `amplitude` N·m added to the current command (the position and velocity loops stay
//!    closed).
//! 2. **Friction.** Both ride on a constant bias velocity `bias_velocity`: while the axis never
//!    stops or reverses, Coulomb friction is a constant torque and backlash stays closed on one
//!    flank, so they only shift the mean (the DC line, which is not measured) and the response
//!    is that of the drive linearised about steady motion. [`Frf::velocity_range`] reports the
//!    load velocity's range over the measured periods: if it includes 0, raise the bias or lower
//!    the amplitude.
//! 3. **Periodic steady state.** The drive starts at rest, runs `settle_periods` periods for
//!    the start-up transient to die out, then `periods` more. The ramp $v_b t$ is subtracted from
//!    nominal and measured positions alike (leaving periodic signals plus a constant following
//!    error), the periods are averaged sample by sample (which also averages encoder noise
//!    down), and the DFT of one period is taken at the excited lines only (exact twiddles from a
//!    table of one period: no leakage, no window).
//! 4. **FRF** $G(j\omega_i) = Y(k_i)/U(k_i)$, with $U$ the DFT of the logged input itself (the
//!    nominal multisine, or the motor torque actually applied).

use std::f64::consts::{PI, TAU};

use nalgebra::Complex;

use crate::Error;
use crate::drive::Drive;
use crate::engine::real::{Build, Real, RealJob, with_real};
use crate::engine::{ReferenceShaper, Servo, real_noise};
use crate::law::{Law, RefSample};

/// Which frequency response to measure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrfKind {
    /// Nominal position (the logged, unshaped reference) → measured position (the reading the
    /// position loop uses, what a control's scope logs): the response the identified
    /// 7-parameter model describes (dimensionless).
    Tracking,
    /// Nominal position → true load position (the tool side, what the part sees).
    LoadTracking,
    /// Motor torque → motor speed, (rad/s)/(N·m): the mechanical admittance with its
    /// resonance and anti-resonance, measured in closed loop as drive tools do.
    Mechanical,
}

/// How to measure (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct FrfOptions {
    /// Input and output.
    pub kind: FrfKind,
    /// Lowest line, Hz (default 1). Positive.
    pub f_min_hz: f64,
    /// Highest line, Hz (default 500). Below half the servo rate.
    pub f_max_hz: f64,
    /// Frequency resolution $f_0 = 1/T$, Hz: the lines are its harmonics. Default: `f_min_hz`.
    /// The servo rate must be a whole multiple of it.
    pub resolution_hz: Option<f64>,
    /// About this many lines, spaced logarithmically (default 120); 0: every harmonic of $f_0$
    /// between `f_min_hz` and `f_max_hz` (linear spacing).
    pub lines: usize,
    /// Peak of the excitation: velocity of the position multisine, axis units/s (default 5), or
    /// torque of the torque multisine, N·m (default: 1 % of the torque that accelerates
    /// `plant.j` at 100 rad/s², at least 0.01 N·m).
    pub amplitude: Option<f64>,
    /// Bias velocity the excitation rides on, axis units/s (default 25). Positive.
    pub bias_velocity: f64,
    /// Periods discarded while the start-up transient dies out (default 2).
    pub settle_periods: usize,
    /// Periods averaged (default 4, at least 1).
    pub periods: usize,
}

impl Default for FrfOptions {
    fn default() -> Self {
        FrfOptions {
            kind: FrfKind::Tracking,
            f_min_hz: 1.0,
            f_max_hz: 500.0,
            resolution_hz: None,
            lines: 120,
            amplitude: None,
            bias_velocity: 25.0,
            settle_periods: 2,
            periods: 4,
        }
    }
}

/// A measured frequency response.
#[derive(Debug, Clone, PartialEq)]
pub struct Frf {
    /// What was measured.
    pub kind: FrfKind,
    /// Line frequencies, Hz, increasing.
    pub freq_hz: Vec<f64>,
    /// $G(j\omega)$ at each line (dimensionless, or (rad/s)/(N·m) for
    /// [`FrfKind::Mechanical`]).
    pub response: Vec<Complex<f64>>,
    /// $|G|$.
    pub magnitude: Vec<f64>,
    /// $\arg G$, degrees, unwrapped along frequency (starting within (−180°, 180°]).
    pub phase_deg: Vec<f64>,
    /// Smallest and largest load velocity over the measured periods, axis units/s.
    pub velocity_range: (f64, f64),
}

/// The excitation of one period, its lines and the DFT table.
struct Plan {
    n_per: usize,
    harmonics: Vec<usize>,
    /// One period of the excitation: position, velocity, acceleration (position kinds) or
    /// torque in `pos` (torque kind).
    pos: Vec<f64>,
    vel: Vec<f64>,
    acc: Vec<f64>,
    /// $\cos(2\pi n/N)$, $\sin(2\pi n/N)$.
    cos: Vec<f64>,
    sin: Vec<f64>,
}

fn bad(name: &'static str, value: f64, expected: &'static str) -> Error {
    Error::BadParameter {
        name,
        value,
        expected,
    }
}

impl Plan {
    fn new(o: &FrfOptions, servo_rate_hz: f64, amplitude: f64) -> Result<Plan, Error> {
        if !(o.f_min_hz.is_finite() && o.f_min_hz > 0.0) {
            return Err(bad("frf.f_min_hz", o.f_min_hz, "positive and finite"));
        }
        if !(o.f_max_hz.is_finite() && o.f_max_hz >= o.f_min_hz && o.f_max_hz < 0.5 * servo_rate_hz)
        {
            return Err(bad(
                "frf.f_max_hz",
                o.f_max_hz,
                "at least f_min_hz and below half the servo rate",
            ));
        }
        let f0 = o.resolution_hz.unwrap_or(o.f_min_hz);
        let ratio = servo_rate_hz / f0;
        if !(f0.is_finite() && f0 > 0.0 && f0 <= o.f_min_hz)
            || (ratio - ratio.round()).abs() > 1e-6 * ratio
            || ratio > 2.0e7
        {
            return Err(bad(
                "frf.resolution_hz",
                f0,
                "positive, at most f_min_hz, dividing the servo rate a whole number of times \
                 (at most 2e7 servo ticks per period)",
            ));
        }
        if !(o.bias_velocity.is_finite() && o.bias_velocity > 0.0) {
            return Err(bad(
                "frf.bias_velocity",
                o.bias_velocity,
                "positive and finite",
            ));
        }
        if !(amplitude.is_finite() && amplitude > 0.0) {
            return Err(bad("frf.amplitude", amplitude, "positive and finite"));
        }
        if o.periods == 0 {
            return Err(bad("frf.periods", 0.0, "at least 1"));
        }
        let n_per = ratio.round() as usize;
        let k_lo = (o.f_min_hz / f0 - 1e-9).ceil().max(1.0) as usize;
        let k_hi = ((o.f_max_hz / f0 + 1e-9).floor() as usize).min(n_per / 2 - 1);
        if k_hi < k_lo {
            return Err(bad("frf.f_max_hz", o.f_max_hz, "leaving at least one line"));
        }
        let mut harmonics: Vec<usize> = if o.lines == 0 || o.lines > k_hi - k_lo {
            (k_lo..=k_hi).collect()
        } else {
            let m = o.lines.max(2);
            let r = k_hi as f64 / k_lo as f64;
            (0..m)
                .map(|i| (k_lo as f64 * r.powf(i as f64 / (m - 1) as f64)).round() as usize)
                .collect()
        };
        harmonics.dedup();
        let (cos, sin): (Vec<f64>, Vec<f64>) = (0..n_per)
            .map(|n| (TAU * n as f64 / n_per as f64).sin_cos())
            .map(|(s, c)| (c, s))
            .unzip();
        let m = harmonics.len() as f64;
        let (mut pos, mut vel, mut acc) = (vec![0.0; n_per], vec![0.0; n_per], vec![0.0; n_per]);
        for (i, &k) in harmonics.iter().enumerate() {
            let phi = -PI * (i as f64) * (i as f64 + 1.0) / m;
            let (sp, cp) = phi.sin_cos();
            let w = TAU * k as f64 * f0;
            for n in 0..n_per {
                let idx = (k * n) % n_per;
                // sin(wt + phi) and cos(wt + phi) from the table.
                let s = sin[idx] * cp + cos[idx] * sp;
                let c = cos[idx] * cp - sin[idx] * sp;
                match o.kind {
                    FrfKind::Mechanical => pos[n] += c,
                    _ => {
                        pos[n] += s / w;
                        vel[n] += c;
                        acc[n] -= w * s;
                    }
                }
            }
        }
        let peak_of = |v: &[f64]| v.iter().fold(0.0f64, |p, x| p.max(x.abs()));
        let scale = amplitude
            / match o.kind {
                FrfKind::Mechanical => peak_of(&pos),
                _ => peak_of(&vel),
            };
        for v in [&mut pos, &mut vel, &mut acc] {
            for x in v.iter_mut() {
                *x *= scale;
            }
        }
        Ok(Plan {
            n_per,
            harmonics,
            pos,
            vel,
            acc,
            cos,
            sin,
        })
    }

    /// DFT of one period at harmonic `k`.
    fn dft(&self, x: &[f64], k: usize) -> Complex<f64> {
        let (mut re, mut im) = (0.0, 0.0);
        let mut idx = 0;
        for v in x {
            re += v * self.cos[idx];
            im -= v * self.sin[idx];
            idx += k;
            if idx >= self.n_per {
                idx -= self.n_per;
            }
        }
        Complex::new(re, im)
    }
}

/// Period-averaged input and output, and the load velocity range.
struct Measured {
    input: Vec<f64>,
    output: Vec<f64>,
    v_range: (f64, f64),
}

struct FrfJob<'a> {
    o: &'a FrfOptions,
    plan: &'a Plan,
    drive: &'a Drive,
    h: f64,
}

impl RealJob for FrfJob<'_> {
    type Out = Result<Measured, Error>;

    fn run<L: Law, const N: usize, const TM: bool>(self, e: Real<f64, L, N, TM>) -> Self::Out {
        let (o, plan, h) = (self.o, self.plan, self.h);
        // The readings' noise, as the drive's simulation draws it.
        let (mut pr, mut mr) = real_noise(self.drive);
        let motor_noise = e.second_encoder();
        let n_per = plan.n_per;
        let vb = o.bias_velocity;
        let torque_kind = o.kind == FrfKind::Mechanical;
        let nominal = |i: usize| {
            let n = i % n_per;
            let t = i as f64 * h;
            if torque_kind {
                RefSample {
                    xr: vb * t,
                    vr: vb,
                    ar: 0.0,
                }
            } else {
                RefSample {
                    xr: vb * t + plan.pos[n],
                    vr: vb + plan.vel[n],
                    ar: plan.acc[n],
                }
            }
        };
        let r0 = nominal(0);
        let xm0 = e.quant().read(r0.xr, -0.0);
        let mut st = e.rest(r0.xr, xm0);
        let mut shaper =
            ReferenceShaper::new(&[self.drive.effects().shaping], h, r0)?.expect("one lane");
        let kakt = self.drive.plant().ka_kt();
        let rg = self.drive.plant().rg;
        let total = (o.settle_periods + o.periods) * n_per;
        let first = o.settle_periods * n_per;
        let (mut input, mut output) = (vec![0.0; n_per], vec![0.0; n_per]);
        let mut v_range = (f64::INFINITY, f64::NEG_INFINITY);
        // The loop's references, shaped a block of ticks ahead (they do not depend on the loop).
        const BLOCK: usize = 64;
        let mut refs = [r0; BLOCK];
        for i in 0..total {
            let nom = nominal(i);
            if i % BLOCK == 0 {
                let block = &mut refs[..BLOCK.min(total - i)];
                for (j, r) in block.iter_mut().enumerate() {
                    *r = nominal(i + j);
                }
                shaper.shape_block(block);
            }
            let r = refs[i % BLOCK];
            let inject = if torque_kind {
                plan.pos[i % n_per] / kakt
            } else {
                0.0
            };
            let (xl, vl, vm) = (
                e.load_position(&st),
                e.load_velocity(&st),
                e.motor_velocity(&st),
            );
            let z_before = e.state(&st);
            let noise = (pr.draw(), if motor_noise { mr.draw() } else { 0.0 });
            let out = e.tick_with(&mut st, &r, inject, noise);
            if i < first {
                continue;
            }
            let ramp = vb * i as f64 * h;
            let n = i % n_per;
            let (u, y) = match o.kind {
                FrfKind::Tracking => (nom.xr - ramp, out.xp - ramp),
                FrfKind::LoadTracking => (nom.xr - ramp, xl - ramp),
                FrfKind::Mechanical => (e.torque(&z_before, out.u_in), vm / rg),
            };
            input[n] += u;
            output[n] += y;
            v_range = (v_range.0.min(vl), v_range.1.max(vl));
        }
        let inv = 1.0 / o.periods as f64;
        for v in input.iter_mut().chain(output.iter_mut()) {
            *v *= inv;
        }
        Ok(Measured {
            input,
            output,
            v_range,
        })
    }
}

impl Drive {
    /// Measures the drive's frequency response by simulation (module documentation: multisine
    /// on a bias velocity, periodic steady state, DFT at the excited lines). Deterministic: the
    /// encoder noise comes from the drive's seed. Cost: (settle + periods) × $1/f_0$ simulated
    /// seconds plus one DFT per line over one period (defaults: 6 s and 120 lines).
    ///
    /// Errors: [`Error::BadParameter`] naming `frf.<option>` for unusable options.
    pub fn measure_frf(&self, options: &FrfOptions) -> Result<Frf, Error> {
        let amplitude = options.amplitude.unwrap_or(match options.kind {
            FrfKind::Mechanical => (0.01 * self.plant().j * 100.0).max(0.01),
            _ => 5.0,
        });
        let plan = Plan::new(options, self.servo_rate_hz(), amplitude)?;
        let h = 1.0 / self.servo_rate_hz();
        let m = with_real(
            self,
            h,
            Build::Full,
            FrfJob {
                o: options,
                plan: &plan,
                drive: self,
                h,
            },
        )??;
        let f0 = self.servo_rate_hz() / plan.n_per as f64;
        let mut frf = Frf {
            kind: options.kind,
            freq_hz: Vec::with_capacity(plan.harmonics.len()),
            response: Vec::with_capacity(plan.harmonics.len()),
            magnitude: Vec::with_capacity(plan.harmonics.len()),
            phase_deg: Vec::with_capacity(plan.harmonics.len()),
            velocity_range: m.v_range,
        };
        let mut last_phase: Option<f64> = None;
        for &k in &plan.harmonics {
            let g = plan.dft(&m.output, k) / plan.dft(&m.input, k);
            let mut ph = g.arg().to_degrees();
            if let Some(prev) = last_phase {
                ph += 360.0 * ((prev - ph) / 360.0).round();
            }
            last_phase = Some(ph);
            frf.freq_hz.push(k as f64 * f0);
            frf.response.push(g);
            frf.magnitude.push(g.norm());
            frf.phase_deg.push(ph);
        }
        Ok(frf)
    }
}
