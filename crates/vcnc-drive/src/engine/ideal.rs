//! The servo tick of the ideal drive: the rigid plant with Coulomb friction ([`RigidStep`]),
//! one encoder reading for both loops, no effects (module docs of [`crate::engine`]).
//!
//! The control law is affine in the reading $\hat x$: $u = u_0 + g_u \hat x$ with $u_0$ the
//! direct part and $K_I\times$integrator at $\hat x = 0$. Everything that does not depend on
//! $\hat x$ is computed first; on the unsaturated path $\hat x$ enters the new position and
//! velocity through one multiply-add each, so the loop-carried chain is short (an algebraic
//! rearrangement of $u = $ direct $+ K_I I$ and of the plant step, not an approximation). With a
//! limit, the integrator holds while $u$ is saturated and its increment would drive $u$ further
//! into the limit (conditional-integration anti-windup).

use super::{Logged, Servo};
use crate::Error;
use crate::engine::noise::Quant;
use crate::law::{Law, RefSample};
use crate::params::Plant;
use crate::plant::RigidStep;

/// Constants of the ideal drive's loop.
#[derive(Clone)]
pub(crate) struct Ideal<L> {
    law: L,
    plant: RigidStep,
    u_max: f64,
    /// $K_aK_t$, N·m/V (for logging the torque).
    ka_kt: f64,
    /// Slopes of the law in the reading: direct part, integrator increment, and of $u$.
    gd: f64,
    gi: f64,
    k_int: f64,
    gu: f64,
    /// Plant coefficients folded with the law: $\varphi_1 c$, $\varphi_2 c$, and their
    /// products with `gu`.
    phi1_c: f64,
    phi2_c: f64,
    phi1_c_gu: f64,
    phi2_c_gu: f64,
    /// The encoder's quantisation.
    quant: Quant<f64>,
}

/// The ideal loop's state: plant, integrator, the previous two readings and the previous
/// tick's reference position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct IdealState {
    pub(crate) x: f64,
    pub(crate) v: f64,
    pub(crate) integ: f64,
    pub(crate) xm1: f64,
    pub(crate) xm2: f64,
    pub(crate) xr1: f64,
}

impl<L: Law> Ideal<L> {
    /// The loop of `law` on `plant` at servo period `h`, its encoder quantising to
    /// `resolution`.
    pub(crate) fn new(law: L, plant: &Plant, resolution: f64, h: f64) -> Result<Ideal<L>, Error> {
        let step = RigidStep::new(plant, h)?;
        let (gd, gi) = law.one_reading_slopes();
        let k_int = law.k_int();
        let gu = gd + k_int * gi;
        let (phi1_c, phi2_c) = (step.phi1 * step.c, step.phi2 * step.c);
        Ok(Ideal {
            law,
            plant: step,
            u_max: plant.u_max.unwrap_or(f64::INFINITY),
            ka_kt: plant.ka_kt(),
            gd,
            gi,
            k_int,
            gu,
            phi1_c,
            phi2_c,
            phi1_c_gu: phi1_c * gu,
            phi2_c_gu: phi2_c * gu,
            quant: Quant::new(resolution),
        })
    }

    /// One tick from the encoder reading `xm`: control $u_k$ (saturated) and plant step over
    /// the period. Returns `(u, saturated)`.
    #[inline(always)]
    fn step(&self, st: &mut IdealState, xm: f64, r: &RefSample<f64>) -> (f64, bool) {
        let e1 = st.xr1 - st.xm1;
        let (direct0, d_int0) = self.law.terms0(r, st.xr1, e1, st.xm1, st.xm2);
        let integ0 = st.integ + d_int0;
        let u0 = direct0 + self.k_int * integ0;
        let u = u0 + self.gu * xm;
        let p = &self.plant;
        let (x, v) = (st.x, st.v);
        let saturated = u.abs() > self.u_max;
        let u_applied = if !saturated {
            st.integ = integ0 + self.gi * xm;
            let v_star = (p.decay * v + self.phi1_c * u0) + self.phi1_c_gu * xm;
            let x_star = (x + p.phi1 * v + self.phi2_c * u0) + self.phi2_c_gu * xm;
            p.finish(&mut st.x, &mut st.v, v_star, x_star);
            u
        } else {
            // Conditional integration: hold the integrator if its increment pushes u further
            // into the limit.
            let d_int = d_int0 + self.gi * xm;
            let mut u = u;
            if self.k_int * d_int * u > 0.0 {
                u = direct0 + self.gd * xm + self.k_int * st.integ;
            } else {
                st.integ += d_int;
            }
            let u = u.clamp(-self.u_max, self.u_max);
            let a_u = p.c * u;
            let v_star = p.decay * v + p.phi1 * a_u;
            let x_star = x + p.phi1 * v + p.phi2 * a_u;
            p.finish(&mut st.x, &mut st.v, v_star, x_star);
            u
        };
        st.xm2 = st.xm1;
        st.xm1 = xm;
        st.xr1 = r.xr;
        (u_applied, saturated)
    }
}

impl<L: Law> Servo<f64> for Ideal<L> {
    type State = IdealState;

    /// A quiet encoder's noise is −0 (`Noise::box_muller`).
    const MINUS_ZERO_QUIET: bool = true;

    fn quant(&self) -> &Quant<f64> {
        &self.quant
    }

    fn rest(&self, x0: f64, xm0: f64) -> IdealState {
        IdealState {
            x: x0,
            v: 0.0,
            integ: 0.0,
            xm1: xm0,
            xm2: xm0,
            xr1: x0,
        }
    }

    fn second_encoder(&self) -> bool {
        false
    }

    #[inline(always)]
    fn tick(&self, st: &mut IdealState, r: &RefSample<f64>, noise: (f64, f64)) -> bool {
        let xm = self.quant.read(st.x, noise.0);
        self.step(st, xm, r).1
    }

    #[inline(always)]
    fn logged_tick(
        &self,
        st: &mut IdealState,
        r: &RefSample<f64>,
        noise: (f64, f64),
    ) -> (Logged<f64>, bool) {
        let xm = self.quant.read(st.x, noise.0);
        let (x, v) = (st.x, st.v);
        let (u, saturated) = self.step(st, xm, r);
        let logged = Logged {
            position: xm,
            true_position: x,
            velocity: v,
            control: u,
            motor_position: x,
            motor_torque: self.ka_kt * u,
        };
        (logged, saturated)
    }
}
