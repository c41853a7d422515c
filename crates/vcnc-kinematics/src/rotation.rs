//! Right-handed rotations about the machine's principal axes, applied to vectors, and a rotated
//! vector's first two time derivatives (the chain rule of docs/kinematics.md).
//!
//! $R_x, R_y, R_z$ turn a vector right-handedly about +X, +Y, +Z; $R'$ and $R''$ are their
//! derivatives with respect to the angle.

use nalgebra::Vector3;

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

/// $R(\theta)$, $R'(\theta)$ and $R''(\theta)$ about one principal axis, kept as the axis and
/// $\sin\theta$, $\cos\theta$.
///
/// [`RotFamily::motion`] multiplies by the three matrices written out per axis, so that after
/// inlining the compiler sees their constant entries (the ones vanish, no matrix is stored),
/// a third of the `scale` bench's inverse-kinematics time. The products keep the order of a
/// full 3×3 product, zero terms included (`0·x` is kept: it decides the sign of a zero result),
/// so the results are bit for bit those of the matrix form (the test below checks it).
#[derive(Debug, Clone, Copy)]
pub(crate) struct RotFamily {
    axis: Principal,
    s: f64,
    c: f64,
}

/// A 3×3 matrix as rows.
type Rows = [[f64; 3]; 3];

/// $Mv$, each row summed left to right as a full matrix-vector product does.
#[inline(always)]
fn mul(m: &Rows, v: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
        m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
        m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
    )
}

/// $R$, $R'$, $R''$ about `axis` as rows.
#[inline(always)]
#[rustfmt::skip]
fn rows(axis: Principal, s: f64, c: f64) -> (Rows, Rows, Rows) {
    match axis {
        Principal::X => (
            [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
            [[0.0, 0.0, 0.0], [0.0, -s, -c], [0.0, c, -s]],
            [[0.0, 0.0, 0.0], [0.0, -c, s], [0.0, -s, -c]],
        ),
        Principal::Y => (
            [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
            [[-s, 0.0, c], [0.0, 0.0, 0.0], [-c, 0.0, -s]],
            [[-c, 0.0, -s], [0.0, 0.0, 0.0], [s, 0.0, -c]],
        ),
        Principal::Z => (
            [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
            [[-s, -c, 0.0], [c, -s, 0.0], [0.0, 0.0, 0.0]],
            [[-c, s, 0.0], [-s, -c, 0.0], [0.0, 0.0, 0.0]],
        ),
    }
}

/// [`RotFamily::motion`] for the matrices `r`, `r1`, `r2`.
#[inline(always)]
fn motion_with(
    (r, r1, r2): (Rows, Rows, Rows),
    w: f64,
    w_dot: f64,
    v: &PointMotion,
) -> PointMotion {
    let w2 = w * w;
    let m: Rows =
        std::array::from_fn(|i| std::array::from_fn(|j| r2[i][j] * w2 + r1[i][j] * w_dot));
    PointMotion {
        p: mul(&r, &v.p),
        p_dot: mul(&r1, &v.p) * w + mul(&r, &v.p_dot),
        p_ddot: mul(&m, &v.p) + mul(&r1, &v.p_dot) * (2.0 * w) + mul(&r, &v.p_ddot),
    }
}

impl RotFamily {
    #[inline(always)]
    pub(crate) fn new(axis: Principal, theta: f64) -> Self {
        let (s, c) = theta.sin_cos();
        Self { axis, s, c }
    }

    /// $u = R(\theta)\,v$ and its time derivatives for an angle moving at `w` (rad/s) and
    /// `w_dot` (rad/s²) and a vector moving as `v`:
    /// $$ \dot u = R'\dot\theta\,v + R\dot v, \qquad
    ///    \ddot u = (R''\dot\theta^2 + R'\ddot\theta)\,v + 2R'\dot\theta\,\dot v + R\ddot v. $$
    #[inline(always)]
    pub(crate) fn motion(&self, w: f64, w_dot: f64, v: &PointMotion) -> PointMotion {
        // One arm per axis, so that each is compiled with its own constant entries.
        let (s, c) = (self.s, self.c);
        match self.axis {
            Principal::X => motion_with(rows(Principal::X, s, c), w, w_dot, v),
            Principal::Y => motion_with(rows(Principal::Y, s, c), w, w_dot, v),
            Principal::Z => motion_with(rows(Principal::Z, s, c), w, w_dot, v),
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
    use nalgebra::Matrix3;

    /// $R$, $R'$, $R''$ as nalgebra matrices: the oracle of the written-out products.
    struct Mats {
        r: Matrix3<f64>,
        r1: Matrix3<f64>,
        r2: Matrix3<f64>,
    }

    #[rustfmt::skip]
    fn matrices(axis: Principal, theta: f64) -> Mats {
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
        Mats { r, r1, r2 }
    }

    #[test]
    fn the_written_out_motion_is_the_matrix_products_bit_for_bit() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(28);
        // Values with exact zeros of both signs, so that the sign of a zero result is checked.
        let draw = |rng: &mut rand_chacha::ChaCha8Rng| match rng.random_range(0..6) {
            0 => 0.0,
            1 => -0.0,
            2 => 1.0,
            _ => rng.random_range(-500.0..500.0),
        };
        for _ in 0..20_000 {
            let axis = [Principal::X, Principal::Y, Principal::Z][rng.random_range(0..3)];
            let theta = draw(&mut rng) * 0.01;
            let (w, w_dot) = (draw(&mut rng), draw(&mut rng));
            let v3 =
                |rng: &mut rand_chacha::ChaCha8Rng| Vector3::new(draw(rng), draw(rng), draw(rng));
            let v = PointMotion {
                p: v3(&mut rng),
                p_dot: v3(&mut rng),
                p_ddot: v3(&mut rng),
            };
            let m = matrices(axis, theta);
            let want = PointMotion {
                p: m.r * v.p,
                p_dot: m.r1 * v.p * w + m.r * v.p_dot,
                p_ddot: (m.r2 * (w * w) + m.r1 * w_dot) * v.p
                    + m.r1 * v.p_dot * (2.0 * w)
                    + m.r * v.p_ddot,
            };
            let got = RotFamily::new(axis, theta).motion(w, w_dot, &v);
            for (a, b) in [
                (got.p, want.p),
                (got.p_dot, want.p_dot),
                (got.p_ddot, want.p_ddot),
            ] {
                for i in 0..3 {
                    assert_eq!(
                        a[i].to_bits(),
                        b[i].to_bits(),
                        "{axis:?} {theta} {w} {w_dot} {v:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn written_out_rotations_equal_the_matrices() {
        let v = Vector3::new(0.3, -1.7, 2.9);
        for axis in [Principal::X, Principal::Y, Principal::Z] {
            for theta in [-2.0, -0.4, 0.0, 0.9, 3.0] {
                let m = matrices(axis, theta);
                assert!((m.r * v - rotate(axis, theta, &v)).norm() < 1e-15);
                // R' and R'' against central differences of R.
                let h = 1e-5;
                let fd1 = (matrices(axis, theta + h).r - matrices(axis, theta - h).r) / (2.0 * h);
                let fd2 = (matrices(axis, theta + h).r - m.r * 2.0 + matrices(axis, theta - h).r)
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
