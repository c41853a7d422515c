//! Curves $\mathbf g(s)$ of the path elements, with their derivatives with respect to the path
//! parameter $s$ and bounds on them (docs/gcode.md, "Interpolation").
//!
//! Three kinds: a straight line, a programmed arc (circle, helix or the spiral LinuxCNC accepts
//! for a small radius change), and a corner blend: a circular arc in X Y Z tangent to both
//! blended lines, along which A B C follow the cubic (Hermite) curve that leaves and joins the
//! lines with their rates, so that every axis' velocity is continuous through the corner.

/// Curve of one path element, $\mathbf{g}(s)$, $s \in [0, L]$.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Geom {
    Line {
        p0: [f64; 6],
        end: [f64; 6],
        d: [f64; 6],
    },
    Arc {
        p0: [f64; 6],
        end: [f64; 6],
        u: usize,
        v: usize,
        c: [f64; 2],
        theta0: f64,
        /// Direction: +1 counter-clockwise, −1 clockwise.
        sgn: f64,
        /// |sweep|, rad.
        phi: f64,
        r0: f64,
        /// Radius change per radian, mm/rad.
        k: f64,
    },
    Blend(Blend),
}

/// A corner blend ([module doc](self)): X Y Z on the circle of centre `c` and radius `r`
/// through `p0` (in the direction of `e2` from there), A B C on a cubic in $s/L$.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Blend {
    pub(crate) p0: [f64; 6],
    pub(crate) end: [f64; 6],
    pub(crate) c: [f64; 3],
    /// Unit vector from the centre to the start.
    pub(crate) e1: [f64; 3],
    /// Unit tangent at the start (⊥ `e1`).
    pub(crate) e2: [f64; 3],
    pub(crate) r: f64,
    /// Angle swept, rad.
    pub(crate) phi: f64,
    /// A B C rates (per unit of s) at the start and at the end.
    pub(crate) m0: [f64; 3],
    pub(crate) m1: [f64; 3],
}

/// Largest |first|, |second|, |third| derivative of each of X Y Z A B C over an element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Bounds {
    pub(crate) g1: [f64; 6],
    pub(crate) g2: [f64; 6],
    pub(crate) g3: [f64; 6],
}

impl Geom {
    /// Position, first and second derivative with respect to s.
    pub(crate) fn eval(&self, s: f64, len: f64) -> ([f64; 6], [f64; 6], [f64; 6]) {
        match *self {
            Geom::Line { p0, end, d } => {
                let mut p = [0.0; 6];
                let mut g1 = [0.0; 6];
                let f = s / len;
                for i in 0..6 {
                    p[i] = if s >= len { end[i] } else { p0[i] + d[i] * f };
                    g1[i] = d[i] / len;
                }
                (p, g1, [0.0; 6])
            }
            Geom::Arc {
                p0,
                end,
                u,
                v,
                c,
                theta0,
                sgn,
                phi,
                r0,
                k,
            } => {
                let sigma = phi / len;
                let f = (s / len).clamp(0.0, 1.0);
                let ph = f * phi;
                let r = r0 + k * ph;
                let a = theta0 + sgn * ph;
                let (sa, ca) = a.sin_cos();
                let mut p = [0.0; 6];
                let mut g1 = [0.0; 6];
                let mut g2 = [0.0; 6];
                for i in 0..6 {
                    p[i] = if s >= len {
                        end[i]
                    } else {
                        p0[i] + (end[i] - p0[i]) * f
                    };
                    g1[i] = (end[i] - p0[i]) / len;
                }
                if s < len {
                    p[u] = c[0] + r * ca;
                    p[v] = c[1] + r * sa;
                }
                g1[u] = (k * ca - sgn * r * sa) * sigma;
                g1[v] = (k * sa + sgn * r * ca) * sigma;
                g2[u] = (-2.0 * sgn * k * sa - r * ca) * sigma * sigma;
                g2[v] = (2.0 * sgn * k * ca - r * sa) * sigma * sigma;
                (p, g1, g2)
            }
            Geom::Blend(b) => b.eval(s, len),
        }
    }

    /// Bounds of the derivatives over the element ([`Bounds`]).
    pub(crate) fn bounds(&self, len: f64) -> Bounds {
        match *self {
            Geom::Line { d, .. } => Bounds {
                g1: std::array::from_fn(|i| (d[i] / len).abs()),
                g2: [0.0; 6],
                g3: [0.0; 6],
            },
            Geom::Arc {
                p0,
                end,
                u,
                v,
                phi,
                r0,
                k,
                ..
            } => {
                let sigma = phi / len;
                let rmax = r0.max(r0 + k * phi);
                let mut g1: [f64; 6] = std::array::from_fn(|i| ((end[i] - p0[i]) / len).abs());
                let mut g2 = [0.0; 6];
                let mut g3 = [0.0; 6];
                for i in [u, v] {
                    g1[i] = k.hypot(rmax) * sigma;
                    g2[i] = (2.0 * k).hypot(rmax) * sigma * sigma;
                    g3[i] = (3.0 * k).hypot(rmax) * sigma * sigma * sigma;
                }
                Bounds { g1, g2, g3 }
            }
            Geom::Blend(b) => b.bounds(len),
        }
    }

    /// Unit tangent of X Y Z (or of A B C for a move of rotary axes alone, `xyz` false) at the
    /// start (`at_end` false) or at the end, and the derivatives $\mathbf g'$, $\mathbf g''$
    /// there.
    pub(crate) fn ends(&self, len: f64, at_end: bool) -> ([f64; 6], [f64; 6]) {
        let (_, g1, g2) = self.eval(if at_end { len } else { 0.0 }, len);
        (g1, g2)
    }

    /// The end point.
    pub(crate) fn end(&self) -> [f64; 6] {
        match *self {
            Geom::Line { end, .. } | Geom::Arc { end, .. } => end,
            Geom::Blend(b) => b.end,
        }
    }

    /// The start point.
    pub(crate) fn start(&self) -> [f64; 6] {
        match *self {
            Geom::Line { p0, .. } | Geom::Arc { p0, .. } => p0,
            Geom::Blend(b) => b.p0,
        }
    }
}

/// Cubic Hermite basis and its derivatives at σ ∈ [0, 1]: (h00, h10, h01, h11) for order 0 … 3.
fn hermite(sig: f64, order: usize) -> [f64; 4] {
    let (s2, s3) = (sig * sig, sig * sig * sig);
    match order {
        0 => [
            2.0 * s3 - 3.0 * s2 + 1.0,
            s3 - 2.0 * s2 + sig,
            -2.0 * s3 + 3.0 * s2,
            s3 - s2,
        ],
        1 => [
            6.0 * s2 - 6.0 * sig,
            3.0 * s2 - 4.0 * sig + 1.0,
            -6.0 * s2 + 6.0 * sig,
            3.0 * s2 - 2.0 * sig,
        ],
        2 => [
            12.0 * sig - 6.0,
            6.0 * sig - 4.0,
            -12.0 * sig + 6.0,
            6.0 * sig - 2.0,
        ],
        _ => [12.0, 6.0, -12.0, 6.0],
    }
}

impl Blend {
    fn eval(&self, s: f64, len: f64) -> ([f64; 6], [f64; 6], [f64; 6]) {
        let s = s.clamp(0.0, len);
        let ang = s / self.r;
        let (sa, ca) = ang.sin_cos();
        let mut p = [0.0; 6];
        let mut g1 = [0.0; 6];
        let mut g2 = [0.0; 6];
        for i in 0..3 {
            p[i] = self.c[i] + self.r * (ca * self.e1[i] + sa * self.e2[i]);
            g1[i] = -sa * self.e1[i] + ca * self.e2[i];
            g2[i] = -(ca * self.e1[i] + sa * self.e2[i]) / self.r;
        }
        let sig = s / len;
        let (h0, h1, h2) = (hermite(sig, 0), hermite(sig, 1), hermite(sig, 2));
        for k in 0..3 {
            let (q0, q1) = (self.p0[3 + k], self.end[3 + k]);
            let (m0, m1) = (self.m0[k] * len, self.m1[k] * len);
            p[3 + k] = h0[0] * q0 + h0[1] * m0 + h0[2] * q1 + h0[3] * m1;
            g1[3 + k] = (h1[0] * q0 + h1[1] * m0 + h1[2] * q1 + h1[3] * m1) / len;
            g2[3 + k] = (h2[0] * q0 + h2[1] * m0 + h2[2] * q1 + h2[3] * m1) / (len * len);
        }
        if s >= len {
            p = self.end;
        }
        (p, g1, g2)
    }

    fn bounds(&self, len: f64) -> Bounds {
        let mut b = Bounds {
            g1: [0.0; 6],
            g2: [0.0; 6],
            g3: [0.0; 6],
        };
        for i in 0..3 {
            let n = self.e1[i].hypot(self.e2[i]);
            b.g1[i] = n;
            b.g2[i] = n / self.r;
            b.g3[i] = n / (self.r * self.r);
        }
        for k in 0..3 {
            let (q0, q1) = (self.p0[3 + k], self.end[3 + k]);
            let (m0, m1) = (self.m0[k] * len, self.m1[k] * len);
            let at = |sig: f64, order: usize| {
                let h = hermite(sig, order);
                h[0] * q0 + h[1] * m0 + h[2] * q1 + h[3] * m1
            };
            // The first derivative is quadratic in σ: its largest magnitude is at an end or at
            // the vertex; the second is linear, the third constant.
            let (c2, c1) = (
                3.0 * (2.0 * q0 + m0 - 2.0 * q1 + m1),
                -2.0 * (3.0 * q0 + 2.0 * m0 - 3.0 * q1 + m1),
            );
            let mut g1 = at(0.0, 1).abs().max(at(1.0, 1).abs());
            if c2 != 0.0 {
                let sv = -c1 / (2.0 * c2);
                if (0.0..=1.0).contains(&sv) {
                    g1 = g1.max(at(sv, 1).abs());
                }
            }
            b.g1[3 + k] = g1 / len;
            b.g2[3 + k] = at(0.0, 2).abs().max(at(1.0, 2).abs()) / (len * len);
            b.g3[3 + k] = at(0.0, 3).abs() / (len * len * len);
        }
        b
    }
}

pub(crate) fn norm3(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blend_derivatives_match_finite_differences() {
        // Truth: central differences of the positions.
        let s2 = std::f64::consts::FRAC_1_SQRT_2;
        let b = Blend {
            p0: [1.0, 0.0, 0.0, 10.0, 0.0, 5.0],
            end: [s2, s2, 0.0, 12.0, 0.0, 4.0],
            c: [0.0, 0.0, 0.0],
            e1: [1.0, 0.0, 0.0],
            e2: [0.0, 1.0, 0.0],
            r: 1.0,
            phi: std::f64::consts::FRAC_PI_4,
            m0: [2.0, 0.0, -1.0],
            m1: [3.0, 0.0, -1.5],
        };
        let len = b.r * b.phi;
        let g = Geom::Blend(b);
        let h = 1e-5;
        for &s in &[0.1, 0.4, 0.7] {
            let (p, g1, g2) = g.eval(s, len);
            let (pm, g1m, _) = g.eval(s - h, len);
            let (pp, g1p, _) = g.eval(s + h, len);
            for i in 0..6 {
                assert!(((pp[i] - pm[i]) / (2.0 * h) - g1[i]).abs() < 1e-6, "g1 {i}");
                assert!(
                    ((g1p[i] - g1m[i]) / (2.0 * h) - g2[i]).abs() < 1e-5,
                    "g2 {i}"
                );
            }
            assert!((p[0].hypot(p[1]) - 1.0).abs() < 1e-12);
        }
        // Rates at the ends are those given; the bounds hold at a fine grid.
        let (g1, _) = g.ends(len, false);
        assert!((g1[3] - 2.0).abs() < 1e-12 && (g1[5] + 1.0).abs() < 1e-12);
        let (g1, _) = g.ends(len, true);
        assert!((g1[3] - 3.0).abs() < 1e-12);
        let bd = g.bounds(len);
        for k in 0..=1000 {
            let (_, g1, g2) = g.eval(len * k as f64 / 1000.0, len);
            for i in 0..6 {
                assert!(g1[i].abs() <= bd.g1[i] * (1.0 + 1e-9) + 1e-12);
                assert!(g2[i].abs() <= bd.g2[i] * (1.0 + 1e-9) + 1e-12);
            }
        }
    }
}
