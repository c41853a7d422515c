//! Speed profiles along a path parameter $s$: the trapezoid (acceleration-limited) and the
//! time-optimal seven-phase profile (jerk-limited) of a rest-to-rest move (docs/gcode.md,
//! "Speed profiles"). Both give $(s, \dot s, \ddot s, \dddot s)$ at a local time $\tau$.

/// Trapezoidal (or triangular) speed profile from $v_0$ to $v_1$ over length $L$, unscaled time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Trap {
    pub(crate) v0: f64,
    pub(crate) vp: f64,
    pub(crate) a: f64,
    pub(crate) ta: f64,
    pub(crate) tc: f64,
    pub(crate) td: f64,
    pub(crate) la: f64,
    pub(crate) lc: f64,
    pub(crate) len: f64,
}

impl Trap {
    /// Fastest profile with entry `v0`, exit `v1`, cruise cap `vcap`, acceleration `a`.
    pub(crate) fn new(len: f64, v0: f64, v1: f64, vcap: f64, a: f64) -> Trap {
        let reach = (a * len + 0.5 * (v0 * v0 + v1 * v1)).sqrt();
        let vp = vcap.min(reach).max(v0).max(v1);
        Trap::with_peak(len, v0, v1, vp, a)
    }

    /// Rest-to-rest profile lasting `t` (≥ the optimal time) with acceleration `a`:
    /// $v_p = 2aL/(aT + \sqrt{a^2T^2 - 4aL})$.
    pub(crate) fn rest_to_rest_lasting(len: f64, a: f64, t: f64) -> Trap {
        let disc = (a * a * t * t - 4.0 * a * len).max(0.0);
        let vp = 2.0 * a * len / (a * t + disc.sqrt());
        Trap::with_peak(len, 0.0, 0.0, vp, a)
    }

    fn with_peak(len: f64, v0: f64, v1: f64, vp: f64, a: f64) -> Trap {
        let ta = ((vp - v0) / a).max(0.0);
        let td = ((vp - v1) / a).max(0.0);
        let la = (vp * vp - v0 * v0) / (2.0 * a);
        let ld = (vp * vp - v1 * v1) / (2.0 * a);
        let lc = (len - la - ld).max(0.0);
        let tc = if vp > 0.0 { lc / vp } else { 0.0 };
        Trap {
            v0,
            vp,
            a,
            ta,
            tc,
            td,
            la: la.max(0.0),
            lc,
            len,
        }
    }

    pub(crate) fn duration(&self) -> f64 {
        self.ta + self.tc + self.td
    }

    /// $(s, \dot s, \ddot s)$ at local time `tau`.
    pub(crate) fn eval(&self, tau: f64) -> (f64, f64, f64) {
        let tau = tau.max(0.0);
        let (s, sd, sdd) = if tau < self.ta {
            (
                self.v0 * tau + 0.5 * self.a * tau * tau,
                self.v0 + self.a * tau,
                self.a,
            )
        } else if tau < self.ta + self.tc {
            (self.la + self.vp * (tau - self.ta), self.vp, 0.0)
        } else if tau < self.duration() {
            let u = tau - self.ta - self.tc;
            (
                self.la + self.lc + self.vp * u - 0.5 * self.a * u * u,
                self.vp - self.a * u,
                -self.a,
            )
        } else {
            (self.len, self.vp - self.a * self.td, 0.0)
        };
        (s.clamp(0.0, self.len), sd.max(0.0), sdd)
    }

    /// $\int_0^\tau s\,d\tau'$ (the antiderivative of [`Trap::eval`]'s position; the position is
    /// held at $L$ after the end).
    pub(crate) fn integral(&self, tau: f64) -> f64 {
        let tau = tau.max(0.0);
        let t1 = tau.min(self.ta);
        let mut acc = self.v0 * t1 * t1 / 2.0 + self.a * t1 * t1 * t1 / 6.0;
        if tau <= self.ta {
            return acc;
        }
        let t2 = (tau - self.ta).min(self.tc);
        acc += self.la * t2 + self.vp * t2 * t2 / 2.0;
        if tau <= self.ta + self.tc {
            return acc;
        }
        let t3 = (tau - self.ta - self.tc).min(self.td);
        acc += (self.la + self.lc) * t3 + self.vp * t3 * t3 / 2.0 - self.a * t3 * t3 * t3 / 6.0;
        let rest = tau - self.duration();
        if rest > 0.0 {
            acc += self.len * rest;
        }
        acc
    }

    /// The local time at which the profile reaches `s` (0 ≤ s ≤ L).
    pub(crate) fn time_at(&self, s: f64) -> f64 {
        if s <= 0.0 {
            return 0.0;
        }
        if s < self.la {
            // v0 τ + a τ²/2 = s
            return 2.0 * s / (self.v0 + (self.v0 * self.v0 + 2.0 * self.a * s).sqrt());
        }
        if s < self.la + self.lc && self.vp > 0.0 {
            return self.ta + (s - self.la) / self.vp;
        }
        let r = (s - self.la - self.lc).max(0.0);
        // vp u − a u²/2 = r, the smaller root.
        let disc = (self.vp * self.vp - 2.0 * self.a * r).max(0.0);
        let u = if self.vp + disc.sqrt() > 0.0 {
            2.0 * r / (self.vp + disc.sqrt())
        } else {
            0.0
        };
        (self.ta + self.tc + u.min(self.td)).min(self.duration())
    }
}

/// Duration and length of the fastest change of speed from `v0` to `v1` with the acceleration
/// zero at both ends, under acceleration `a` and jerk `j` (the first or last three phases of a
/// seven-phase profile): with $\Delta v = |v_1 - v_0|$,
/// $$ T = \frac{\Delta v}{a} + \frac{a}{j} \ (\Delta v \ge a^2/j), \qquad
///    T = 2\sqrt{\Delta v / j} \ \text{(the acceleration limit is not reached)}, $$
/// and the length is $(v_0 + v_1)T/2$ (the speed is symmetric about its mean).
pub(crate) fn speed_change(v0: f64, v1: f64, a: f64, j: f64) -> (f64, f64) {
    let dv = (v1 - v0).abs();
    let t = if dv * j >= a * a {
        dv / a + a / j
    } else {
        2.0 * (dv / j).sqrt()
    };
    (t, 0.5 * (v0 + v1) * t)
}

/// One phase of a seven-phase profile: its duration and constant jerk, and the state at its
/// start.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Phase {
    t: f64,
    j: f64,
    s: f64,
    v: f64,
    a: f64,
}

/// The time-optimal rest-to-rest profile of length $L$ under speed $V$, acceleration $A$ and
/// jerk $J$ (the seven phases jerk $+J$, acceleration $A$, jerk $-J$, cruise, jerk $-J$,
/// deceleration, jerk $+J$; phases of zero length drop out). The peak speed is $V$ when
/// $2L_{\text{acc}}(V) \le L$, else the root of $2L_{\text{acc}}(v_p) = L$:
/// $$ v_p = \tfrac12\big(-A^2/J + \sqrt{A^4/J^2 + 4AL}\big) \quad (L \ge 2A^3/J^2), \qquad
///    v_p = (L^2 J / 4)^{1/3} \ \text{otherwise} $$
/// ([`speed_change`] gives $L_{\text{acc}}$). Its duration is what Ruckig returns for the same
/// move (`tests/ruckig.rs`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SCurve {
    phases: [Phase; 7],
    len: f64,
    duration: f64,
}

impl SCurve {
    /// The time-optimal profile (module doc). `len`, `v`, `a`, `j` positive and finite.
    pub(crate) fn rest_to_rest(len: f64, v: f64, a: f64, j: f64) -> SCurve {
        let (_, l_acc) = speed_change(0.0, v, a, j);
        let vp = if 2.0 * l_acc <= len {
            v
        } else if len * j * j >= 2.0 * a * a * a {
            let q = a * a / j;
            0.5 * (-q + (q * q + 4.0 * a * len).sqrt())
        } else {
            (len * len * j / 4.0).cbrt()
        };
        // Jerk phase and constant-acceleration phase of the ramp 0 → vp.
        let (tj, ta) = if vp * j >= a * a {
            (a / j, vp / a - a / j)
        } else {
            ((vp / j).sqrt(), 0.0)
        };
        let (_, l_ramp) = speed_change(0.0, vp, a, j);
        let tc = ((len - 2.0 * l_ramp) / vp).max(0.0);
        let plan = [
            (tj, j),
            (ta, 0.0),
            (tj, -j),
            (tc, 0.0),
            (tj, -j),
            (ta, 0.0),
            (tj, j),
        ];
        let mut phases = [Phase {
            t: 0.0,
            j: 0.0,
            s: 0.0,
            v: 0.0,
            a: 0.0,
        }; 7];
        let (mut s, mut sv, mut sa) = (0.0, 0.0, 0.0);
        let mut duration = 0.0;
        for (p, &(t, jj)) in phases.iter_mut().zip(&plan) {
            *p = Phase {
                t,
                j: jj,
                s,
                v: sv,
                a: sa,
            };
            s += sv * t + sa * t * t / 2.0 + jj * t * t * t / 6.0;
            sv += sa * t + jj * t * t / 2.0;
            sa += jj * t;
            duration += t;
        }
        SCurve {
            phases,
            len,
            duration,
        }
    }

    pub(crate) fn duration(&self) -> f64 {
        self.duration
    }

    /// The phase durations, s (jerk +J, acceleration, jerk −J, cruise, jerk −J, deceleration,
    /// jerk +J).
    #[cfg(test)]
    pub(crate) fn phase_durations(&self) -> [f64; 7] {
        std::array::from_fn(|i| self.phases[i].t)
    }

    /// $(s, \dot s, \ddot s, \dddot s)$ at local time `tau`; at rest on $L$ after the end.
    pub(crate) fn eval(&self, tau: f64) -> (f64, f64, f64, f64) {
        let mut rest = tau.max(0.0);
        if rest >= self.duration {
            return (self.len, 0.0, 0.0, 0.0);
        }
        for p in &self.phases {
            if rest < p.t {
                let t = rest;
                let s = p.s + p.v * t + p.a * t * t / 2.0 + p.j * t * t * t / 6.0;
                let v = p.v + p.a * t + p.j * t * t / 2.0;
                let a = p.a + p.j * t;
                return (s.clamp(0.0, self.len), v.max(0.0), a, p.j);
            }
            rest -= p.t;
        }
        (self.len, 0.0, 0.0, 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_integral_is_the_antiderivative() {
        // Truth: the trapezoid rule on a fine grid.
        let t = Trap::new(10.0, 2.0, 1.0, 20.0, 100.0);
        let n = 200_000;
        let end = t.duration() + 0.05;
        let h = end / n as f64;
        let mut sum = 0.0;
        for k in 0..n {
            let (a, b) = (t.eval(k as f64 * h).0, t.eval((k + 1) as f64 * h).0);
            sum += 0.5 * (a + b) * h;
        }
        assert!(
            (t.integral(end) - sum).abs() < 1e-7,
            "{} {}",
            t.integral(end),
            sum
        );
        for s in [0.0, 0.3, 2.0, 7.7, 9.99, 10.0] {
            let tau = t.time_at(s);
            assert!((t.eval(tau).0 - s).abs() < 1e-9, "{s}");
        }
    }

    #[test]
    fn seven_phases_end_on_the_point_at_rest_within_the_limits() {
        for &(l, v, a, j) in &[
            (100.0, 50.0, 1000.0, 1.0e5),
            (1.0, 50.0, 1000.0, 1.0e5),
            (0.001, 50.0, 1000.0, 1.0e5),
            (10.0, 5.0, 1000.0, 1.0e4),
        ] {
            let p = SCurve::rest_to_rest(l, v, a, j);
            let (s, sd, sdd, _) = p.eval(p.duration() * (1.0 - 1e-15));
            assert!((s - l).abs() < 1e-9 * l.max(1.0), "{l}");
            assert!(sd.abs() < 1e-6 && sdd.abs() < 1e-3, "{sd} {sdd}");
            let n = 10_000;
            for k in 0..=n {
                let (_, sd, sdd, sddd) = p.eval(p.duration() * k as f64 / n as f64);
                assert!(sd <= v * (1.0 + 1e-12) && sdd.abs() <= a * (1.0 + 1e-12));
                assert!(sddd.abs() <= j);
            }
        }
    }
}

#[cfg(test)]
mod ruckig {
    use super::*;

    /// The goldens of `scripts/ruckig/goldens.py`: (L, V, A, J, duration, seven phase times).
    pub(crate) fn goldens() -> Vec<([f64; 5], [f64; 7])> {
        let text = include_str!("../../tests/data/ruckig/single_moves.csv");
        text.lines()
            .filter(|l| !l.starts_with('#') && !l.starts_with("length"))
            .map(|l| {
                let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
                (
                    [v[0], v[1], v[2], v[3], v[4]],
                    std::array::from_fn(|i| v[5 + i]),
                )
            })
            .collect()
    }

    #[test]
    fn seven_phase_durations_equal_ruckigs() {
        // Truth: Ruckig's time-optimal durations and phases (tests/data/ruckig, made by
        // scripts/ruckig/goldens.py). Figures: the largest relative difference of the duration
        // and of any phase (relative to the duration).
        let g = goldens();
        assert!(g.len() >= 50);
        // The jerk of the seven phases (+J, 0, −J, 0, −J, 0, +J) in both; Ruckig writes the two
        // middle −J phases as one when there is no cruise. Compare the phases with zero-length
        // ones dropped and equal neighbours joined.
        let canonical = |t: &[f64; 7], total: f64| -> Vec<(f64, i8)> {
            let signs = [1i8, 0, -1, 0, -1, 0, 1];
            let mut out: Vec<(f64, i8)> = Vec::new();
            for (d, s) in t.iter().zip(signs) {
                if *d <= 1e-12 * total {
                    continue;
                }
                match out.last_mut() {
                    Some(last) if last.1 == s => last.0 += d,
                    _ => out.push((*d, s)),
                }
            }
            out
        };
        let (mut worst_t, mut worst_phase) = (0.0f64, 0.0f64);
        for ([l, v, a, j, t], phases) in &g {
            let p = SCurve::rest_to_rest(*l, *v, *a, *j);
            worst_t = worst_t.max((p.duration() - t).abs() / t);
            let (mine, theirs) = (canonical(&p.phase_durations(), *t), canonical(phases, *t));
            assert_eq!(
                mine.iter().map(|x| x.1).collect::<Vec<_>>(),
                theirs.iter().map(|x| x.1).collect::<Vec<_>>(),
                "phases of {l} {v} {a} {j}"
            );
            for (m, r) in mine.iter().zip(&theirs) {
                worst_phase = worst_phase.max((m.0 - r.0).abs() / t);
            }
        }
        println!(
            "{} moves: duration within {worst_t:.1e}, phases within {worst_phase:.1e} of Ruckig's (relative)",
            g.len()
        );
        assert!(worst_t < 1e-9, "{worst_t}");
        assert!(worst_phase < 1e-8, "{worst_phase}");
    }
}
