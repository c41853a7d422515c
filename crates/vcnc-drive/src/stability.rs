//! The sampled closed loops as linear maps, and their stability: data and analysis, made from
//! the control law's constants ([`crate::law`]) and the plant's exact step ([`crate::plant`]),
//! not by running the engine. The checked drive ([`crate::Drive`]) rejects gains and effects
//! whose loop these matrices show unstable; the engine steps with the same constants (the test
//! `engine::real::tests::engine_ticks_are_the_stability_matrices` holds them to each other).
//!
//! Both maps are the servo tick at the servo period $h$ with the reference zero, friction,
//! quantisation, noise and limits off (friction's viscous part kept), written as
//! $s_{k+1} = M s_k$:
//!
//! - the ideal drive, $s = [x, \dot x, I, \hat x_{k-1}, \hat x_{k-2}]$: the law reads
//!   $\hat x_k = x_k$, $u = \text{direct} + K_I I_{k+1}$,
//!   $I_{k+1} = I_k + \Delta I$, and the rigid plant steps
//!   $x^+ = x + \varphi_1 \dot x + \varphi_2 c\,u$, $\dot x^+ = e^{-\beta h}\dot x + \varphi_1 c\,u$;
//! - a drive with effects, $s = [z, I, e_1, x_{f1}, x_{f2}, p_1 \ldots p_d]$ ($z$ the plant's
//!   state, $p$ the $d$ readings pending in the dead-time line, oldest first): the position
//!   reading $\hat x_p$ (the sensor's position, or $p_1$ behind a dead time), the velocity path
//!   $x_f = a\,x_{f1} + (1 - a)\hat x_v$, $u = \text{direct}(\hat x_p, x_f) + K_I I_{k+1}$,
//!   $z^+ = \Phi z + \Gamma_u u$ (backlash closed), $e_1^+ = -\hat x_p$.
//!
//! The law's terms are linear in the controller's past ($e_1$, $x_{f1}$, $x_{f2}$) when the
//! reference is zero; their coefficients are the law evaluated on unit vectors.

use nalgebra::{Complex, DMatrix, DVector, SMatrix};

use crate::Error;
use crate::effects::{Effects, FeedbackSource, FrictionLocation};
use crate::law::{Law, LawJob, RefSample, with_law};
use crate::model::{ClosedLoopModel, Poles};
use crate::params::{Controller, Plant};
use crate::plant::{Layout, Lin, RigidStep};

/// The rigid plant without Coulomb friction and limit: the linear part the matrices describe.
fn linear(plant: &Plant) -> Plant {
    Plant {
        coulomb_torque: 0.0,
        u_max: None,
        ..plant.clone()
    }
}

/// A law's terms `(direct, ΔI)` with zero reference, as rows over `(e1, xf1, xf2)`.
fn law_rows<L: Law>(law: &L) -> ([f64; 3], [f64; 3]) {
    let zero = RefSample::<f64>::zero();
    let mut d = [0.0; 3];
    let mut i = [0.0; 3];
    for k in 0..3 {
        let mut unit = [0.0; 3];
        unit[k] = 1.0;
        (d[k], i[k]) = law.terms0(&zero, 0.0, unit[0], unit[1], unit[2]);
    }
    (d, i)
}

/// Transition matrix of the ideal drive's sampled linear loop (module docs), state
/// $[x, \dot x, I, \hat x_{k-1}, \hat x_{k-2}]$.
pub(crate) fn ideal_matrix(
    plant: &Plant,
    controller: &Controller,
    servo_rate_hz: f64,
) -> Result<SMatrix<f64, 5, 5>, Error> {
    let h = 1.0 / servo_rate_hz;
    let plant = linear(plant);
    let step = RigidStep::new(&plant, h)?;
    struct M<'a> {
        step: &'a RigidStep,
    }
    impl LawJob for M<'_> {
        type Out = SMatrix<f64, 5, 5>;
        fn run<L: Law>(self, law: L) -> Self::Out {
            let p = self.step;
            let (d, i) = law_rows(&law);
            let (gd, gi) = law.one_reading_slopes();
            let k = law.k_int();
            // e1 = -x_{k-1} (zero reference): the law's rows over (x, v, I, xm1, xm2).
            let direct = [gd, 0.0, 0.0, d[1] - d[0], d[2]];
            let d_int = [gi, 0.0, 0.0, i[1] - i[0], i[2]];
            let mut integ = d_int;
            integ[2] += 1.0;
            let u: [f64; 5] = std::array::from_fn(|j| direct[j] + k * integ[j]);
            let mut m = SMatrix::<f64, 5, 5>::zeros();
            for j in 0..5 {
                m[(0, j)] = p.phi2 * p.c * u[j];
                m[(1, j)] = p.phi1 * p.c * u[j];
                m[(2, j)] = integ[j];
            }
            m[(0, 0)] += 1.0;
            m[(0, 1)] += p.phi1;
            m[(1, 1)] += p.decay;
            m[(3, 0)] = 1.0;
            m[(4, 3)] = 1.0;
            m
        }
    }
    Ok(with_law(controller, &plant, h, M { step: &step }))
}

/// Transition matrix of the loop of a drive with `effects`, linearised at rest (module docs),
/// state $[z, I, e_1, x_{f1}, x_{f2}, p_1 \ldots p_d]$.
pub(crate) fn effects_matrix(
    plant: &Plant,
    controller: &Controller,
    effects: &Effects,
    servo_rate_hz: f64,
) -> Result<DMatrix<f64>, Error> {
    let h = 1.0 / servo_rate_hz;
    let lay = Layout::of(effects);
    let n = lay.n();
    let on_load = effects
        .friction
        .is_none_or(|f| f.location == FrictionLocation::Load);
    let (phi, g_u) = match n {
        2 => dense::<2>(plant, effects, h, on_load)?,
        3 => dense::<3>(plant, effects, h, on_load)?,
        4 => dense::<4>(plant, effects, h, on_load)?,
        5 => dense::<5>(plant, effects, h, on_load)?,
        _ => dense::<6>(plant, effects, h, on_load)?,
    };
    let fb = effects.feedback;
    let d = fb.map_or(0, |f| f.dead_time_cycles as usize);
    let a = fb
        .and_then(|f| f.velocity_filter_hz)
        .map_or(0.0, |fc| (-std::f64::consts::TAU * fc * h).exp());
    let load_source = fb.is_none_or(|f| f.source == FeedbackSource::Load);
    let second_encoder = lay.two_mass && load_source;
    struct Rows {
        d: [f64; 3],
        i: [f64; 3],
        s: crate::law::Slopes,
        k: f64,
    }
    struct R;
    impl LawJob for R {
        type Out = Rows;
        fn run<L: Law>(self, law: L) -> Rows {
            let (d, i) = law_rows(&law);
            Rows {
                d,
                i,
                s: law.slopes(),
                k: law.k_int(),
            }
        }
    }
    let law = with_law(controller, plant, h, R);
    // State indices.
    let dim = n + 4 + d;
    let (i_int, i_e1, i_xf1, i_xf2, i_p) = (n, n + 1, n + 2, n + 3, n + 4);
    let unit = |j: usize| DVector::<f64>::from_fn(dim, |r, _| if r == j { 1.0 } else { 0.0 });
    // Readings as rows over the state.
    let reading = unit(if load_source { lay.xl() } else { lay.xm() });
    let xp = if d == 0 { reading.clone() } else { unit(i_p) };
    let xv = if second_encoder {
        unit(lay.xm())
    } else {
        reading.clone()
    };
    let xf = unit(i_xf1) * a + xv * (1.0 - a);
    let past = |c: &[f64; 3]| unit(i_e1) * c[0] + unit(i_xf1) * c[1] + unit(i_xf2) * c[2];
    let direct = past(&law.d) + &xp * law.s.dp + &xf * law.s.df;
    let integ = unit(i_int) + past(&law.i) + &xp * law.s.ip + &xf * law.s.i_f;
    let u = direct + &integ * law.k;
    let mut m = DMatrix::<f64>::zeros(dim, dim);
    for r in 0..n {
        let mut row = &u * g_u[r];
        for c in 0..n {
            row[c] += phi[(r, c)];
        }
        m.set_row(r, &row.transpose());
    }
    m.set_row(i_int, &integ.transpose());
    m.set_row(i_e1, &(-xp).transpose());
    m.set_row(i_xf1, &xf.transpose());
    m.set_row(i_xf2, &unit(i_xf1).transpose());
    for k in 0..d {
        let next = if k + 1 < d {
            unit(i_p + k + 1)
        } else {
            reading.clone()
        };
        m.set_row(i_p + k, &next.transpose());
    }
    Ok(m)
}

/// $\Phi$ and $\Gamma_u$ of the linear part in contact, as dynamic matrices.
fn dense<const N: usize>(
    plant: &Plant,
    effects: &Effects,
    h: f64,
    on_load: bool,
) -> Result<(DMatrix<f64>, Vec<f64>), Error> {
    let lin = Lin::<f64, N>::new(plant, effects, h, on_load, true)?;
    let (phi, g_u) = lin.matrices();
    Ok((
        DMatrix::from_fn(N, N, |i, j| phi[(i, j)]),
        g_u.iter().copied().collect(),
    ))
}

/// The eigenvalues of `m`, largest modulus first.
fn eigenvalues(m: &DMatrix<f64>) -> Result<Vec<Complex<f64>>, Error> {
    if !m.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFiniteModel);
    }
    let mut z: Vec<Complex<f64>> = m
        .clone()
        .try_schur(1e-15, 10_000)
        .ok_or(Error::NonFiniteModel)?
        .complex_eigenvalues()
        .iter()
        .copied()
        .collect();
    z.sort_by(|a, b| b.norm().total_cmp(&a.norm()));
    Ok(z)
}

/// Rejects gains that are stable in continuous time but not as sampled at the servo rate: the
/// spectral radius of [`ideal_matrix`] must not exceed 1 (a drive without integral action keeps
/// its pole at $z = 1$).
pub(crate) fn check_sampled(
    plant: &Plant,
    controller: &Controller,
    servo_rate_hz: f64,
) -> Result<(), Error> {
    let m = ideal_matrix(plant, controller, servo_rate_hz)?;
    let z = eigenvalues(&DMatrix::from_fn(5, 5, |i, j| m[(i, j)]))?;
    let radius = z.first().map_or(0.0, |z| z.norm());
    if radius > 1.0 + 1e-9 {
        return Err(Error::SampledUnstable {
            servo_rate_hz,
            radius,
        });
    }
    Ok(())
}

/// Rejects effects that destabilise the loop linearised at rest ([`effects_matrix`]).
pub(crate) fn check_effects(
    plant: &Plant,
    controller: &Controller,
    effects: &Effects,
    servo_rate_hz: f64,
) -> Result<(), Error> {
    let m = effects_matrix(plant, controller, effects, servo_rate_hz)?;
    let Some(&worst) = eigenvalues(&m)?.first() else {
        return Ok(());
    };
    let radius = worst.norm();
    if radius > 1.0 + 1e-9 {
        let s = worst.ln() / (1.0 / servo_rate_hz);
        return Err(Error::EffectsUnstable {
            servo_rate_hz,
            radius,
            mode_hz: s.im.abs() / std::f64::consts::TAU,
            growth_per_s: s.re,
        });
    }
    Ok(())
}

/// The three slowest eigenvalues $z$ of [`ideal_matrix`] (the other two are fast parasitic modes
/// of the velocity estimator and the hold) mapped by $s = \ln(z)/h$, rad/s, and their
/// $(p, \omega_n, \zeta)$ form.
pub(crate) fn effective_poles(
    plant: &Plant,
    controller: &Controller,
    servo_rate_hz: f64,
) -> Result<([Complex<f64>; 3], Poles), Error> {
    let m = ideal_matrix(plant, controller, servo_rate_hz)?;
    let z = eigenvalues(&DMatrix::from_fn(5, 5, |i, j| m[(i, j)]))?;
    let mut s = [Complex::new(0.0, 0.0); 3];
    for (si, zi) in s.iter_mut().zip(&z) {
        *si = zi.ln() / (1.0 / servo_rate_hz);
    }
    // Real cubic through the three roots (conjugate pairs make the imaginary parts vanish).
    let a1 = -(s[0] + s[1] + s[2]).re;
    let a2 = (s[0] * s[1] + s[0] * s[2] + s[1] * s[2]).re;
    let a3 = -(s[0] * s[1] * s[2]).re;
    let cubic = ClosedLoopModel::characteristic(a1, a2, a3);
    let poles = cubic.poles().ok_or(Error::NonFiniteModel)?;
    Ok((s, poles))
}
