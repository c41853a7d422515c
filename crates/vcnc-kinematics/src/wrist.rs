//! The tool axis of the closed-form five-axis families as a function of their tilt (A or B) and
//! C, and its inverse with branches, the singularity and C unwinding (docs/kinematics.md,
//! "Rotary axes and the tool axis").
//!
//! Every closed-form family orients the tool as
//! $$ o_w = R_z(\sigma_c c)\,R_t(\sigma_t t)\,\hat z, $$
//! where $t$ is the tilt (A about X, or B about Y), $R_t$ the rotation about its axis, and
//! $\sigma = +1$ for an axis that turns the spindle head, $-1$ for an axis that turns the table
//! (turning the table one way turns the tool the other way relative to the workpiece).
//! Written out, with $s_t = \sin t$:
//! $$ \text{A: } o_w = (\sigma_c\sigma_t\, s_t \sin c,\ -\sigma_t\, s_t\cos c,\ \cos t), \qquad
//!    \text{B: } o_w = (\sigma_t\, s_t\cos c,\ \sigma_c\sigma_t\, s_t\sin c,\ \cos t). $$

use std::f64::consts::TAU;

use nalgebra::Vector3;

use crate::error::{Error, Result};
use crate::types::{Branch, Tilt, Travel};

/// Below this $|\sin t|$ (t the tilt, A or B) the C angle is undefined (the tool axis is
/// parallel to the C axis): the inverse kinematics keeps the previous C. The C rate a path
/// demands grows as $1/|\sin t|$ near it (docs/kinematics.md).
pub const SINGULAR_SIN_A: f64 = 1e-9;

/// Rotary angles derived from a tool axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotaryAngles {
    /// The tilt (A or B), rad.
    pub a: f64,
    /// C, rad, unwound to the solution nearest to the previous C within the C travel.
    pub c: f64,
    /// True if $|\sin t| <$ [`SINGULAR_SIN_A`] and C was held at the previous value.
    pub singular: bool,
    /// True if the C nearest to the previous one is outside the C travel and a value a whole
    /// number of turns away was taken instead (the table must unwind).
    pub unwound: bool,
}

/// `o` normalised, or the error of a zero or non-finite tool axis. Scaled by its largest
/// component first, so that huge or tiny vectors normalise exactly.
pub(crate) fn unit_orientation(o: &Vector3<f64>, sample: Option<usize>) -> Result<Vector3<f64>> {
    let bad = |reason| Error::BadOrientation {
        o: [o.x, o.y, o.z],
        sample,
        reason,
    };
    if !o.iter().all(|v| v.is_finite()) {
        return Err(bad("not finite"));
    }
    let m = o.amax();
    if m == 0.0 {
        return Err(bad("zero length: no tool direction"));
    }
    let u = o / m;
    Ok(u / u.norm())
}

/// `c_raw` shifted by a whole number of turns to lie nearest to `c_prev` (rad).
pub fn unwrap_near(c_raw: f64, c_prev: f64) -> f64 {
    c_raw + TAU * ((c_prev - c_raw) / TAU).round()
}

/// `c_raw` shifted by whole turns to the value nearest to `c_prev` within `travel`, and whether
/// that is not the value nearest to `c_prev` overall (an unwinding move). `None` if no turn of
/// `c_raw` lies within the travel.
pub fn unwrap_within(c_raw: f64, c_prev: f64, travel: Travel) -> Option<(f64, bool)> {
    let c = unwrap_near(c_raw, c_prev);
    if travel.contains(c) {
        return Some((c, false));
    }
    let shifted = if c > travel.upper {
        c - TAU * ((c - travel.upper) / TAU).ceil()
    } else {
        c + TAU * ((travel.lower - c) / TAU).ceil()
    };
    travel.contains(shifted).then_some((shifted, true))
}

/// The tool-axis map of one closed-form family: which axis tilts, and whether the tilt and C
/// turn the head (`+1`) or the table (`-1`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Wrist {
    pub(crate) tilt: Tilt,
    /// $\sigma_t$: +1 if the tilt turns the head, −1 if it turns the table.
    pub(crate) sigma_t: f64,
    /// $\sigma_c$: +1 if C turns the head, −1 if it turns the table.
    pub(crate) sigma_c: f64,
}

impl Wrist {
    /// The tool axis in the workpiece frame for tilt `t` and `c` (rad).
    pub(crate) fn orientation(&self, t: f64, c: f64) -> Vector3<f64> {
        let (st, ct) = t.sin_cos();
        let (sc, cc) = c.sin_cos();
        let k = self.sigma_c * self.sigma_t;
        match self.tilt {
            Tilt::A => Vector3::new(k * (st * sc), -self.sigma_t * (st * cc), ct),
            Tilt::B => Vector3::new(self.sigma_t * (st * cc), k * (st * sc), ct),
        }
    }

    /// Tilt and C from a tool axis `o` (any positive length; normalised here) on `branch`:
    /// $t = \pm\arccos o_z$, and C from the signed components of the orientation formula,
    /// unwound to the value nearest `c_prev` within `c_travel`, held at `c_prev` at the
    /// singularity. $o_z$ is clamped into $[-1, 1]$ after normalising, so the result is never
    /// NaN; zero or non-finite `o` is an error, and so is a C whose every turn is outside the
    /// travel. `sample` tags errors.
    pub(crate) fn angles(
        &self,
        o: &Vector3<f64>,
        branch: Branch,
        c_prev: f64,
        c_travel: Travel,
        sample: Option<usize>,
    ) -> Result<RotaryAngles> {
        let u = unit_orientation(o, sample)?;
        if !c_prev.is_finite() {
            return Err(Error::BadParameter {
                name: "previous C".into(),
                value: format!("{c_prev} rad"),
                reason: "must be finite",
            });
        }
        let s = branch.sign();
        let t = s * u.z.clamp(-1.0, 1.0).acos();
        let sin_t = u.x.hypot(u.y);
        if sin_t < SINGULAR_SIN_A {
            return Ok(RotaryAngles {
                a: t,
                c: c_prev,
                singular: true,
                unwound: false,
            });
        }
        // sin c and cos c up to the positive factor |sin t|, from the written-out formula.
        let k = self.sigma_c * self.sigma_t;
        let c_raw = match self.tilt {
            Tilt::A => (k * s * u.x).atan2(-self.sigma_t * s * u.y),
            Tilt::B => (k * s * u.y).atan2(self.sigma_t * s * u.x),
        };
        let (c, unwound) =
            unwrap_within(c_raw, c_prev, c_travel).ok_or_else(|| Error::OutOfTravel {
                axis: vcnc_axis::AxisName::C,
                value: unwrap_near(c_raw, c_prev),
                lower: c_travel.lower,
                upper: c_travel.upper,
                sample,
            })?;
        Ok(RotaryAngles {
            a: t,
            c,
            singular: false,
            unwound,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unwinding_stays_within_travel() {
        let deg = |d: f64| d.to_radians();
        let travel = Travel::new(deg(-400.0), deg(400.0)).unwrap_or_default();
        // Nearest is within travel: no unwinding.
        let (c, unwound) = unwrap_within(deg(10.0), deg(370.0), travel).unwrap_or_default();
        assert!((c - deg(370.0)).abs() < 1e-12 && !unwound);
        // From 399° the nearest turn of 30° is 390°, within travel.
        let (c, unwound) = unwrap_within(deg(30.0), deg(399.0), travel).unwrap_or_default();
        assert!((c - deg(390.0)).abs() < 1e-12 && !unwound);
        // Nearest to 399° is 410°, beyond 400°: one turn back, 50°, an unwinding move.
        let (c, unwound) = unwrap_within(deg(50.0), deg(399.0), travel).unwrap_or_default();
        assert!(
            (c - deg(50.0)).abs() < 1e-12 && unwound,
            "{}",
            c.to_degrees()
        );
        // And the other way.
        let (c, unwound) = unwrap_within(deg(-50.0), deg(-399.0), travel).unwrap_or_default();
        assert!((c - deg(-50.0)).abs() < 1e-12 && unwound);
        // A travel narrower than a turn may hold no turn of the angle.
        let narrow = Travel::new(deg(-90.0), deg(90.0)).unwrap_or_default();
        assert!(unwrap_within(deg(180.0), 0.0, narrow).is_none());
        assert_eq!(
            unwrap_within(1.0, 0.5, Travel::UNBOUNDED),
            Some((1.0, false))
        );
    }

    #[test]
    fn angles_invert_the_orientation_for_every_wrist() {
        for tilt in [Tilt::A, Tilt::B] {
            for (sigma_t, sigma_c) in [(-1.0, -1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, 1.0)] {
                let w = Wrist {
                    tilt,
                    sigma_t,
                    sigma_c,
                };
                for (t, c) in [(0.4, 1.0), (-1.2, -2.5), (2.9, 0.1), (-0.01, 3.0)] {
                    let o = w.orientation(t, c);
                    assert!((o.norm() - 1.0).abs() < 1e-15);
                    let b = if t > 0.0 { Branch::Plus } else { Branch::Minus };
                    let r = w.angles(&o, b, c + 0.5, Travel::UNBOUNDED, None);
                    let r = r.unwrap_or_else(|e| panic!("{e}"));
                    assert!(
                        (r.a - t).abs() < 1e-12 && (r.c - c).abs() < 1e-9,
                        "{tilt:?} {r:?}"
                    );
                    // The other branch gives the same axis with the tilt negated.
                    let r2 = w.angles(&o, b.other(), c, Travel::UNBOUNDED, None);
                    let r2 = r2.unwrap_or_else(|e| panic!("{e}"));
                    assert!((r2.a + t).abs() < 1e-12);
                    assert!((w.orientation(r2.a, r2.c) - o).norm() < 1e-12);
                }
            }
        }
    }
}
