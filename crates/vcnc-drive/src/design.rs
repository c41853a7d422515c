//! Controller gains from desired closed-loop poles (docs/drive-model.md).
//!
//! The desired poles $(s + p)(s^2 + 2\zeta\omega_n s + \omega_n^2)$ give
//! $a_1 = p + 2\zeta\omega_n$, $a_2 = \omega_n^2 + 2\zeta\omega_n p$, $a_3 = p\,\omega_n^2$
//! ([`Poles::denominator`]); each design solves the controller's coefficient formulas
//! ([`crate::Controller::closed_loop_model`]) for its gains. Every design either returns finite
//! gains that reproduce the poles or an error saying why they cannot be reached; never NaN.

use crate::Error;
use crate::model::Poles;
use crate::params::{PPiGains, PidGains, Plant, SmcGains};

fn check_poles(poles: &Poles) -> Result<(f64, f64, f64), Error> {
    let ok = [poles.p, poles.wn, poles.zeta]
        .iter()
        .all(|v| v.is_finite() && *v > 0.0);
    if !ok {
        return Err(Error::BadDesign {
            p_hz: poles.p_hz(),
            wn_hz: poles.wn_hz(),
            zeta: poles.zeta,
        });
    }
    Ok(poles.denominator())
}

/// P-PI cascade gains for `poles` on `plant` (docs/drive-model.md), with the given feed-forward.
///
/// With $P = K_aK_tK_p/J = a_1 - B/J$ the remaining two coefficients require
/// $P\,K^2 - a_2 K + a_3 = 0$ for $K = K_v r_g$, and then $K_aK_tK_i/J = a_3/K$. Of the two roots
/// the larger one is taken, as the paper's Table 1 does:
///
/// $$ K = \frac{a_2 + \sqrt{a_2^2 - 4 P a_3}}{2P}. $$
///
/// Errors: [`Error::NegativeGain`] when $a_1 \le B/J$ (the velocity loop would need
/// $K_p \le 0$), [`Error::Unreachable`] when the discriminant is negative (these poles cannot be
/// placed by a P-PI on a plant with this $B/J$).
pub fn design_ppi(
    plant: &Plant,
    poles: &Poles,
    vff: f64,
    bff: f64,
    jff: f64,
) -> Result<PPiGains, Error> {
    plant.validate()?;
    let (a1, a2, a3) = check_poles(poles)?;
    let b_over_j = plant.b_over_j();
    let k_over_j = plant.ka_kt() / plant.j;
    // P = Ka Kt Kp / J.
    let p = a1 - b_over_j;
    if p <= 0.0 {
        return Err(Error::NegativeGain {
            gain: "kp",
            value: p / k_over_j,
            a1,
            b_over_j,
        });
    }
    let discriminant = a2 * a2 - 4.0 * p * a3;
    if discriminant < 0.0 {
        return Err(Error::Unreachable {
            p_hz: poles.p_hz(),
            wn_hz: poles.wn_hz(),
            zeta: poles.zeta,
            b_over_j,
            discriminant,
        });
    }
    // Larger root; both terms positive, no cancellation.
    let k = (a2 + discriminant.sqrt()) / (2.0 * p);
    let gains = PPiGains {
        kv: k / plant.rg,
        kp: p / k_over_j,
        ki: a3 / (k * k_over_j),
        vff,
        bff,
        jff,
    };
    finite_or_overflow(&[gains.kv, gains.kp, gains.ki], poles)?;
    Ok(gains)
}

/// PID gains for `poles` on `plant`: with $k = K_aK_t r_g/J$ the PID coefficients are linear in
/// the gains, $K_d = (a_1 - B/J)/k$, $K_p = a_2/k$, $K_i = a_3/k$ (docs/drive-model.md).
///
/// Error: [`Error::NegativeGain`] when $a_1 \le B/J$ ($K_d \le 0$).
pub fn design_pid(plant: &Plant, poles: &Poles, jff: f64, bff: f64) -> Result<PidGains, Error> {
    plant.validate()?;
    let (a1, a2, a3) = check_poles(poles)?;
    let b_over_j = plant.b_over_j();
    let k = plant.ka_kt() * plant.rg / plant.j;
    let kd = (a1 - b_over_j) / k;
    if kd <= 0.0 {
        return Err(Error::NegativeGain {
            gain: "kd",
            value: kd,
            a1,
            b_over_j,
        });
    }
    let gains = PidGains {
        kp: a2 / k,
        ki: a3 / k,
        kd,
        jff,
        bff,
    };
    finite_or_overflow(&[gains.kp, gains.ki, gains.kd], poles)?;
    Ok(gains)
}

/// Sliding-mode gains for `poles` on `plant` with exact estimates $\hat J_e = J_e$,
/// $\hat B_e = B_e$ (docs/drive-model.md): $\lambda = p$, $K_s = 2\zeta\omega_n J_e$,
/// $\rho = \omega_n^2 J_e$. Then $a_1 = \lambda + K_s/J_e$, $a_2 = K_s\lambda/J_e + \rho/J_e$,
/// $a_3 = \lambda\rho/J_e$ are the desired coefficients, and every pole is cancelled by a zero
/// ($G_{track} = 1$).
pub fn design_smc(plant: &Plant, poles: &Poles) -> Result<SmcGains, Error> {
    plant.validate()?;
    check_poles(poles)?;
    let je = plant.je();
    let gains = SmcGains {
        lambda: poles.p,
        ks: 2.0 * poles.zeta * poles.wn * je,
        rho: poles.wn * poles.wn * je,
        je_hat: je,
        be_hat: plant.be(),
    };
    finite_or_overflow(&[gains.lambda, gains.ks, gains.rho, gains.je_hat], poles)?;
    Ok(gains)
}

/// Extreme but finite inputs could still overflow; report them as a bad design.
fn finite_or_overflow(gains: &[f64], poles: &Poles) -> Result<(), Error> {
    if gains.iter().all(|g| g.is_finite()) {
        Ok(())
    } else {
        Err(Error::BadDesign {
            p_hz: poles.p_hz(),
            wn_hz: poles.wn_hz(),
            zeta: poles.zeta,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::Controller;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    /// Table 1 plant (docs/reference-numbers.md), friction as docs/reference-numbers.md recommends.
    fn plant() -> Plant {
        crate::presets::TABLE1_PLANT
    }

    #[test]
    fn ppi_design_recovers_table1_gains() {
        // Truth: docs/reference-numbers.md, Table 1 gains Kv = 70, Kp = 2.342478, Ki = 223.252126 give the
        // printed exact poles; designing from those poles (larger root) must give them back to
        // the precision of the printed poles (5 significant digits).
        let poles = Poles::from_hz(10.7296, 30.569, 0.44519);
        let g = design_ppi(&plant(), &poles, 0.5, 0.1, 0.0).unwrap();
        assert_relative_eq!(g.kv, 70.0, max_relative = 2e-4);
        assert_relative_eq!(g.kp, 2.342478, max_relative = 2e-4);
        assert_relative_eq!(g.ki, 223.252126, max_relative = 2e-4);
    }

    #[test]
    fn ppi_design_reports_unreachable_poles_instead_of_nan() {
        // Truth: the discriminant a2^2 - 4 (a1 - B/J) a3 worked by hand. A fast real pole with a
        // slow, lightly damped pair: p = 100 Hz, wn = 10 Hz, zeta = 0.1 gives a1 = 640.9,
        // a2 = 5.9e3, a3 = 2.48e6, so a2^2 = 3.5e7 < 4 P a3 = 6.3e9.
        let poles = Poles::from_hz(100.0, 10.0, 0.1);
        match design_ppi(&plant(), &poles, 0.0, 0.0, 0.0) {
            Err(Error::Unreachable {
                discriminant,
                b_over_j,
                ..
            }) => {
                assert!(discriminant < 0.0);
                assert_relative_eq!(b_over_j, 4.18572, max_relative = 1e-12);
            }
            other => panic!("expected Unreachable, got {other:?}"),
        }
        let msg = design_ppi(&plant(), &poles, 0.0, 0.0, 0.0)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("B/J = 4.18572"), "{msg}");
    }

    #[test]
    fn designs_slower_than_the_plant_need_negative_gains() {
        // a1 = p + 2 zeta wn below B/J = 4.19 1/s.
        let poles = Poles {
            p: 1.0,
            wn: 2.0,
            zeta: 0.5,
        };
        assert!(matches!(
            design_ppi(&plant(), &poles, 0.0, 0.0, 0.0),
            Err(Error::NegativeGain { gain: "kp", .. })
        ));
        assert!(matches!(
            design_pid(&plant(), &poles, 0.0, 0.0),
            Err(Error::NegativeGain { gain: "kd", .. })
        ));
        let bad = Poles {
            p: f64::NAN,
            wn: 2.0,
            zeta: 0.5,
        };
        assert!(matches!(
            design_smc(&plant(), &bad),
            Err(Error::BadDesign { .. })
        ));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Invariant: every design either fails with an error or returns finite gains whose
        /// closed-loop model has exactly the desired poles (truth: the desired poles themselves).
        #[test]
        fn designs_place_the_poles_or_fail(
            p_hz in 0.5f64..200.0,
            wn_hz in 1.0f64..300.0,
            zeta in 0.05f64..2.0,
            b_over_j in 0.0f64..50.0,
            j in 1e-4f64..10.0,
            rg in 0.1f64..100.0,
        ) {
            let plant = Plant { j, b: b_over_j * j, ka: 1.3, kt: 0.7, rg, coulomb_torque: 0.0, u_max: None };
            let poles = Poles::from_hz(p_hz, wn_hz, zeta);
            let results = [
                design_ppi(&plant, &poles, 0.5, 0.1, 0.0).map(Controller::PPi),
                design_pid(&plant, &poles, 0.0, 0.1).map(Controller::Pid),
                design_smc(&plant, &poles).map(Controller::Smc),
            ];
            for c in results.into_iter().flatten() {
                let m = c.closed_loop_model(&plant);
                let (a1, a2, a3) = poles.denominator();
                prop_assert!((m.a1 - a1).abs() <= 1e-9 * a1, "{c:?}: a1 {} vs {a1}", m.a1);
                prop_assert!((m.a2 - a2).abs() <= 1e-9 * a2, "{c:?}: a2 {} vs {a2}", m.a2);
                prop_assert!((m.a3 - a3).abs() <= 1e-9 * a3, "{c:?}: a3 {} vs {a3}", m.a3);
                prop_assert!(m.is_stable());
            }
            // The P-PI fails exactly when the discriminant is negative or a1 <= B/J.
            let (a1, a2, a3) = poles.denominator();
            let pp = a1 - b_over_j;
            let reachable = pp > 0.0 && a2 * a2 - 4.0 * pp * a3 >= 0.0;
            prop_assert_eq!(design_ppi(&plant, &poles, 0.0, 0.0, 0.0).is_ok(), reachable);
        }
    }
}
