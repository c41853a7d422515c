//! Right-handed rotations about the machine's principal axes, applied to vectors, and a rotated
//! vector's first two time derivatives (the chain rule of docs/kinematics.md).
//!
//! $R_x, R_y, R_z$ turn a vector right-handedly about +X, +Y, +Z; $R'$ and $R''$ are their
//! derivatives with respect to the angle.

use nalgebra::{Matrix3, Vector3};

use crate::types::PointMotion;

/// A principal axis of the machine frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Principal {
    X,
    Y,
    Z,
}

/// $R(\theta)\,v$ about `axis`, written out (exact zeros where the matrix has them).
pub(crate) fn rotate(axis: Principal, theta: f64, v: &Vector3<f64>) -> Vector3<f64> {
    let (s, c) = theta.sin_cos();
    match axis {
        Principal::X => Vector3::new(v.x, c * v.y - s * v.z, s * v.y + c * v.z),
        Principal::Y => Vector3::new(c * v.x + s * v.z, v.y, -s * v.x + c * v.z),
        Principal::Z => Vector3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z),
    }
}

/// $R(\theta)$, $R'(\theta)$ and $R''(\theta)$ about one principal axis.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RotFamily {
    r: Matrix3<f64>,
    r1: Matrix3<f64>,
    r2: Matrix3<f64>,
}

impl RotFamily {
    #[rustfmt::skip]
    pub(crate) fn new(axis: Principal, theta: f64) -> Self {
        let (s, c) = theta.sin_cos();
        let (r, r1, r2) = match axis {
            Principal::X => (
                Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c),
                Matrix3::new(0.0, 0.0, 0.0, 0.0, -s, -c, 0.0, c, -s),
                Matrix3::new(0.0, 0.0, 0.0, 0.0, -c, s, 0.0, -s, -c),
            ),
            Principal::Y => (
                Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c),
                Matrix3::new(-s, 0.0, c, 0.0, 0.0, 0.0, -c, 0.0, -s),
                Matrix3::new(-c, 0.0, -s, 0.0, 0.0, 0.0, s, 0.0, -c),
            ),
            Principal::Z => (
                Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
                Matrix3::new(-s, -c, 0.0, c, -s, 0.0, 0.0, 0.0, 0.0),
                Matrix3::new(-c, s, 0.0, -s, -c, 0.0, 0.0, 0.0, 0.0),
            ),
        };
        Self { r, r1, r2 }
    }

    /// $u = R(\theta)\,v$ and its time derivatives for an angle moving at `w` (rad/s) and
    /// `w_dot` (rad/s²) and a vector moving as `v`:
    /// $$ \dot u = R'\dot\theta\,v + R\dot v, \qquad
    ///    \ddot u = (R''\dot\theta^2 + R'\ddot\theta)\,v + 2R'\dot\theta\,\dot v + R\ddot v. $$
    pub(crate) fn motion(&self, w: f64, w_dot: f64, v: &PointMotion) -> PointMotion {
        PointMotion {
            p: self.r * v.p,
            p_dot: self.r1 * v.p * w + self.r * v.p_dot,
            p_ddot: (self.r2 * (w * w) + self.r1 * w_dot) * v.p
                + self.r1 * v.p_dot * (2.0 * w)
                + self.r * v.p_ddot,
        }
    }
}

/// A vector that does not move.
pub(crate) fn still(p: Vector3<f64>) -> PointMotion {
    PointMotion {
        p,
        p_dot: Vector3::zeros(),
        p_ddot: Vector3::zeros(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_out_rotations_equal_the_matrices() {
        let v = Vector3::new(0.3, -1.7, 2.9);
        for axis in [Principal::X, Principal::Y, Principal::Z] {
            for theta in [-2.0, -0.4, 0.0, 0.9, 3.0] {
                let m = RotFamily::new(axis, theta);
                assert!((m.r * v - rotate(axis, theta, &v)).norm() < 1e-15);
                // R' and R'' against central differences of R.
                let h = 1e-5;
                let fd1 = (RotFamily::new(axis, theta + h).r - RotFamily::new(axis, theta - h).r)
                    / (2.0 * h);
                let fd2 = (RotFamily::new(axis, theta + h).r - m.r * 2.0
                    + RotFamily::new(axis, theta - h).r)
                    / (h * h);
                assert!((fd1 - m.r1).norm() < 1e-9);
                assert!((fd2 - m.r2).norm() < 1e-5);
                // Right-handed: +X to +Y about Z, +Y to +Z about X, +Z to +X about Y.
                let q = std::f64::consts::FRAC_PI_2;
                let (from, to) = match axis {
                    Principal::X => (Vector3::y(), Vector3::z()),
                    Principal::Y => (Vector3::z(), Vector3::x()),
                    Principal::Z => (Vector3::x(), Vector3::y()),
                };
                assert!((rotate(axis, q, &from) - to).norm() < 1e-15);
            }
        }
    }
}
