//! Path elements ready for profiling: a curve and the caps on the path speed $\dot s$,
//! acceleration $\ddot s$ and jerk $\dddot s$ that keep every axis within its limits
//! (docs/gcode.md, "Limits along the path").

use super::geom::{Blend, Bounds, Geom, norm3};
use super::{InterpolateOptions, Limits, PlannerRules, Profile};
use crate::interp::{Feed, Move, MoveKind};
use crate::{AxisName, Error};

/// The options and limits the planner works with, resolved once.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Cfg {
    pub(crate) limits: Limits,
    pub(crate) ts: f64,
    pub(crate) max_samples: usize,
    /// Centripetal share of the acceleration on arcs (vcnc's rules).
    pub(crate) beta: f64,
    /// Jerk-limited profile.
    pub(crate) jerk: bool,
    /// LinuxCNC 2.9's planner rules.
    pub(crate) lc: bool,
    /// Moving-average time of jerk-limited chains, s (0 for the trapezoidal profile):
    /// $T_f = 2\max_i a_i/j_i$ over the limits with a jerk limit.
    pub(crate) tf: f64,
    /// Bounds of the path speed for X Y Z paths, tool-tip paths and rotary paths (units/s).
    pub(crate) vbound: [f64; 3],
    /// Tolerance of a plain `G64`, mm (`None`: LinuxCNC's rule).
    pub(crate) plain_tolerance: Option<f64>,
    /// Largest share of an axis' acceleration a velocity kink may take (LinuxCNC's
    /// `ARC_BLEND_KINK_RATIO`, default 0.1).
    pub(crate) kink_ratio: f64,
}

impl Cfg {
    pub(crate) fn new(limits: &Limits, opts: &InterpolateOptions) -> Cfg {
        let jerk = opts.profile == Profile::JerkLimited;
        let mut ratio: f64 = 0.0;
        if jerk {
            for l in &limits.axes {
                if l.max_jerk.is_finite() && l.max_jerk > 0.0 && l.max_acc > 0.0 {
                    ratio = ratio.max(l.max_acc / l.max_jerk);
                }
            }
            if limits.tcp_max_jerk.is_finite() && limits.tcp_max_jerk > 0.0 {
                ratio = ratio.max(limits.tcp_max_acc / limits.tcp_max_jerk);
            }
        }
        let v = |r: std::ops::Range<usize>| {
            r.map(|i| limits.axes[i].max_vel.powi(2))
                .sum::<f64>()
                .sqrt()
        };
        Cfg {
            limits: *limits,
            ts: opts.ts,
            max_samples: opts.max_samples,
            beta: opts.arc_centripetal_fraction,
            jerk,
            lc: opts.planner == PlannerRules::LinuxCnc29,
            tf: 2.0 * ratio,
            vbound: [v(0..3), limits.tcp_max_vel, v(3..6)],
            plain_tolerance: opts.blend_tolerance,
            kink_ratio: 0.1,
        }
    }

    /// The bound of the path speed of an element (for the filter's zones).
    pub(crate) fn speed_bound(&self, tcp: bool, xyz_basis: bool) -> f64 {
        if !xyz_basis {
            self.vbound[2]
        } else if tcp {
            self.vbound[1]
        } else {
            self.vbound[0]
        }
    }
}

/// One path element ready for profiling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Seg {
    pub(crate) geom: Geom,
    pub(crate) len: f64,
    /// Speed cap along s (feed and limits).
    pub(crate) vcap: f64,
    /// Speed cap from the limits alone.
    pub(crate) vlim: f64,
    /// Programmed speed along s (∞ for rapids).
    pub(crate) vfeed: f64,
    /// Acceleration cap along s.
    pub(crate) acap: f64,
    /// Jerk cap along s (∞ under the trapezoidal profile).
    pub(crate) jcap: f64,
    pub(crate) move_index: usize,
    /// `true`: s is the XYZ length; `false`: the rotary length.
    pub(crate) xyz_basis: bool,
}

/// A bad limit: not finite or negative.
pub(crate) fn check_limits(limits: &Limits, opts: &InterpolateOptions) -> Result<(), Error> {
    for (i, l) in limits.axes.iter().enumerate() {
        for (name, value) in [
            ("max_vel", l.max_vel),
            ("max_acc", l.max_acc),
            ("max_jerk", l.max_jerk),
        ] {
            let ok = if name == "max_jerk" {
                value > 0.0
            } else {
                value.is_finite() && value >= 0.0
            };
            if !ok {
                return Err(Error::InvalidLimit {
                    axis: AxisName::from_index(i),
                    name,
                    value,
                });
            }
        }
    }
    for (name, value) in [
        ("tcp_max_vel", limits.tcp_max_vel),
        ("tcp_max_acc", limits.tcp_max_acc),
        ("tcp_max_jerk", limits.tcp_max_jerk),
    ] {
        let ok = if name == "tcp_max_jerk" {
            value > 0.0
        } else {
            value.is_finite() && value >= 0.0
        };
        if !ok {
            return Err(Error::InvalidLimit {
                axis: None,
                name,
                value,
            });
        }
    }
    let bad = |name: &'static str, value: f64, expected: &'static str| Error::InvalidOption {
        name,
        value,
        expected,
    };
    if !(opts.ts.is_finite() && opts.ts > 0.0) {
        return Err(bad("ts", opts.ts, "a positive number of seconds"));
    }
    if let Some(t) = opts.blend_tolerance
        && !(t.is_finite() && t > 0.0)
    {
        return Err(bad("blend_tolerance", t, "a positive length"));
    }
    let beta = opts.arc_centripetal_fraction;
    if !(beta > 0.0 && beta < 1.0) {
        return Err(bad(
            "arc_centripetal_fraction",
            beta,
            "a fraction in (0, 1)",
        ));
    }
    if opts.profile == Profile::JerkLimited && Cfg::new(limits, opts).tf <= 0.0 {
        return Err(Error::NoJerkLimit);
    }
    Ok(())
}

/// The speed along s of a feed move: `G94` F/60, `G93` the length over 1/F (LinuxCNC's
/// inverse-time rule: the block lasts 1/F at that speed, plus its ramps).
pub(crate) fn feed_speed(feed: Option<Feed>, len: f64) -> f64 {
    match feed {
        Some(Feed::UnitsPerMin(f)) => f / 60.0,
        Some(Feed::InverseTime(f)) => len * f / 60.0,
        None => f64::INFINITY,
    }
}

/// Caps from derivative bounds (module doc): for every limited quantity $i$ (an axis, or the
/// tool tip in TCP mode) with bounds $G_1, G_2, G_3$ of $|g'|, |g''|, |g'''|$,
/// $$ G_1 \dot s \le v_i, \quad G_2 V^2 \le \beta a_i, \quad
///    G_1 |\ddot s| \le a_i - G_2 V^2 $$
/// with $V$ the speed the element can reach (the tangential acceleration gets what the
/// centripetal one leaves at that speed, at least $1 - \beta$), and under the jerk-limited profile
/// $G_3\dot s^3 + 3G_2\dot s|\ddot s| + G_1|\dddot s| \le j_i$: the first term at most half of
/// $j_i$, and with the acceleration cap tied to the jerk cap by the moving average
/// ($A = J T_f/2$, [`super::chain`]), $J = (j_i - G_3 V^3)/(G_1 + \tfrac32 G_2 V T_f)$ at the
/// element's speed cap $V$. Returns (speed cap, acceleration cap, jerk cap).
pub(crate) fn caps(
    cfg: &Cfg,
    terms: &[(f64, f64, f64, f64, f64, f64)],
    vfeed: f64,
) -> (f64, f64, f64) {
    let beta = cfg.beta;
    let mut v = f64::INFINITY;
    for &(g1, g2, g3, vl, al, jl) in terms {
        if g1 > 0.0 {
            v = v.min(vl / g1);
        }
        if g2 > 0.0 {
            v = v.min((beta * al / g2).sqrt());
        }
        if cfg.jerk && jl.is_finite() && g3 > 0.0 {
            // The speed term of the jerk takes at most half of it.
            v = v.min((jl / (2.0 * g3)).cbrt());
        }
    }
    // At the speed the element can reach, the tangential acceleration gets what the
    // centripetal one leaves (at least 1 − β), the path's jerk what the other two terms leave.
    let vv = v.min(vfeed);
    let mut a = f64::INFINITY;
    let mut j = f64::INFINITY;
    for &(g1, g2, g3, _, al, jl) in terms {
        if g1 > 0.0 {
            a = a.min((al - g2 * vv * vv) / g1);
        }
        if cfg.jerk && jl.is_finite() && g1 > 0.0 {
            let room = jl - g3 * vv * vv * vv;
            j = j.min(room / (g1 + 1.5 * g2 * vv * cfg.tf));
        }
    }
    if cfg.jerk {
        // The moving average gives |s'''| <= 2A/T_f: keep that within the jerk cap.
        a = a.min(j * cfg.tf / 2.0);
    }
    (v, a, j)
}

/// The quantities an element must keep within limits, with their derivative bounds: per axis
/// (and the tool tip instead of X Y Z in TCP mode) `(G1, G2, G3, v, a, j)`.
pub(crate) fn terms(
    cfg: &Cfg,
    b: &Bounds,
    tip: Option<(f64, f64, f64)>,
    tcp: bool,
) -> Vec<(f64, f64, f64, f64, f64, f64)> {
    let l = &cfg.limits;
    let mut out = Vec::with_capacity(6);
    for i in 0..6 {
        if tcp && i < 3 {
            continue;
        }
        let ax = l.axes[i];
        if b.g1[i] > 0.0 || b.g2[i] > 0.0 {
            out.push((
                b.g1[i],
                b.g2[i],
                b.g3[i],
                ax.max_vel,
                ax.max_acc,
                ax.max_jerk,
            ));
        }
    }
    if tcp && let Some((t1, t2, t3)) = tip {
        out.push((t1, t2, t3, l.tcp_max_vel, l.tcp_max_acc, l.tcp_max_jerk));
    }
    out
}

/// Build the element of a motion move; `None` for a zero-length move.
pub(crate) fn segment(mv: &Move, index: usize, cfg: &Cfg) -> Result<Option<Seg>, Error> {
    let limits = &cfg.limits;
    let d: [f64; 6] = std::array::from_fn(|i| mv.end[i] - mv.start[i]);
    let cannot = |axis: usize, what: &'static str| Error::AxisCannotMove {
        axis: AxisName::from_index(axis),
        what,
        line: mv.line,
    };
    let tcp_cannot = |what: &'static str| Error::AxisCannotMove {
        axis: None,
        what,
        line: mv.line,
    };
    let mut vlim = f64::INFINITY;
    let mut acap = f64::INFINITY;
    let mut jcap = f64::INFINITY;
    // Per-axis limit on a component that moves with rate `rate` per unit of s.
    let per_axis = |i: usize,
                    rate: f64,
                    vlim: &mut f64,
                    acap: &mut f64,
                    jcap: &mut f64|
     -> Result<(), Error> {
        if rate == 0.0 {
            return Ok(());
        }
        let l = limits.axes[i];
        if l.max_vel <= 0.0 {
            return Err(cannot(i, "velocity"));
        }
        if l.max_acc <= 0.0 {
            return Err(cannot(i, "acceleration"));
        }
        *vlim = vlim.min(l.max_vel / rate.abs());
        *acap = acap.min(l.max_acc / rate.abs());
        *jcap = jcap.min(l.max_jerk / rate.abs());
        Ok(())
    };
    let beta = cfg.beta;
    let (geom, len, xyz_basis) = match mv.kind {
        MoveKind::Dwell { .. } => return Ok(None),
        MoveKind::Rapid | MoveKind::Linear => {
            let xyz = norm3(&d[0..3]);
            let rot = norm3(&d[3..6]);
            let (len, xyz_basis) = if xyz > 0.0 {
                (xyz, true)
            } else if rot > 0.0 {
                (rot, false)
            } else {
                return Ok(None);
            };
            for (i, &di) in d.iter().enumerate() {
                if mv.tcp && i < 3 {
                    continue;
                }
                per_axis(i, di / len, &mut vlim, &mut acap, &mut jcap)?;
            }
            if mv.tcp && xyz > 0.0 {
                let rate = xyz / len;
                if limits.tcp_max_vel <= 0.0 {
                    return Err(tcp_cannot("velocity"));
                }
                if limits.tcp_max_acc <= 0.0 {
                    return Err(tcp_cannot("acceleration"));
                }
                vlim = vlim.min(limits.tcp_max_vel / rate);
                acap = acap.min(limits.tcp_max_acc / rate);
                jcap = jcap.min(limits.tcp_max_jerk / rate);
            }
            (
                Geom::Line {
                    p0: mv.start,
                    end: mv.end,
                    d,
                },
                len,
                xyz_basis,
            )
        }
        MoveKind::Arc(arc) => {
            let (u, v, w) = arc.plane.axes();
            let phi = arc.sweep_rad.abs();
            let r0 = arc.radius_start_mm;
            let r1 = arc.radius_end_mm;
            let k = (r1 - r0) / phi;
            let rmax = r0.max(r1);
            let planar = 0.5 * (r0 + r1) * phi;
            let len = planar.hypot(d[w]);
            if !(len > 0.0 && len.is_finite()) {
                return Ok(None);
            }
            let sigma = phi / len;
            let rv = k.hypot(rmax);
            let rc = (2.0 * k).hypot(rmax);
            for i in [w, 3, 4, 5] {
                if mv.tcp && i < 3 {
                    continue;
                }
                per_axis(i, d[i] / len, &mut vlim, &mut acap, &mut jcap)?;
            }
            let (vp, ap, rt) = if mv.tcp {
                if limits.tcp_max_vel <= 0.0 {
                    return Err(tcp_cannot("velocity"));
                }
                if limits.tcp_max_acc <= 0.0 {
                    return Err(tcp_cannot("acceleration"));
                }
                (limits.tcp_max_vel, limits.tcp_max_acc, rv.hypot(d[w] / phi))
            } else {
                for i in [u, v] {
                    if limits.axes[i].max_vel <= 0.0 {
                        return Err(cannot(i, "velocity"));
                    }
                    if limits.axes[i].max_acc <= 0.0 {
                        return Err(cannot(i, "acceleration"));
                    }
                }
                (
                    limits.axes[u].max_vel.min(limits.axes[v].max_vel),
                    limits.axes[u].max_acc.min(limits.axes[v].max_acc),
                    rv,
                )
            };
            if cfg.lc {
                // LinuxCNC 2.9 (emccanon ARC_FEED, tc.c pmCircleActualMaxVel): the normal
                // acceleration may take √3/2 of the in-plane limit; the tangential ratio is
                // ½ where the machine's speed reaches that, else √(1 − (v²/r / a)²).
                let r_eff = k.hypot(r0.min(r1));
                let a_n = ap * 3f64.sqrt() / 2.0;
                let v_rad = (a_n * r_eff).sqrt();
                let v_max = vp.min(vlim);
                vlim = v_max.min(v_rad);
                let ratio = if v_max * v_max / r_eff >= a_n {
                    0.5
                } else {
                    (1.0 - (v_max * v_max / r_eff / ap).powi(2)).sqrt()
                };
                acap = acap.min(ap * ratio);
            } else {
                vlim = vlim
                    .min(vp / (sigma * rt))
                    .min((beta * ap / (sigma * sigma * rc)).sqrt());
                acap = acap.min((1.0 - beta) * ap / (sigma * rt));
            }
            let (sa, ca) = (mv.start[v] - arc.centre[1], mv.start[u] - arc.centre[0]);
            let geom = Geom::Arc {
                p0: mv.start,
                end: mv.end,
                u,
                v,
                c: arc.centre,
                theta0: sa.atan2(ca),
                sgn: arc.sweep_rad.signum(),
                phi,
                r0,
                k,
            };
            if cfg.jerk {
                // The jerk of the arc's terms (caps of the module doc) on the in-plane axes (or
                // the tool tip).
                let b = geom.bounds(len);
                let tip = (
                    sigma * rt,
                    sigma * sigma * rc.hypot(0.0),
                    sigma * sigma * sigma * (3.0 * k).hypot(rmax),
                );
                let t = terms(cfg, &b, Some(tip), mv.tcp);
                let vfeed = feed_speed(mv.feed, len);
                let (vj, aj, jj) = caps(cfg, &t, vfeed);
                vlim = vlim.min(vj);
                acap = acap.min(aj);
                jcap = jcap.min(jj);
            }
            (geom, len, true)
        }
    };
    let vfeed = feed_speed(mv.feed, len);
    if cfg.jerk {
        acap = acap.min(jcap * cfg.tf / 2.0);
    } else {
        jcap = f64::INFINITY;
    }
    let vcap = vfeed.min(vlim);
    if !(vcap > 0.0 && acap > 0.0 && vlim.is_finite() && acap.is_finite() && len.is_finite()) {
        return Err(Error::NonFinite {
            line: mv.line,
            what: "path speed or acceleration cap",
        });
    }
    Ok(Some(Seg {
        geom,
        len,
        vcap,
        vlim,
        vfeed,
        acap,
        jcap,
        move_index: index,
        xyz_basis,
    }))
}

/// The caps of a corner blend run at most at `vfeed` (vcnc's rules: [`caps`] over its
/// derivative bounds).
pub(crate) fn blend_caps(cfg: &Cfg, b: &Blend, len: f64, tcp: bool, vfeed: f64) -> (f64, f64, f64) {
    let g = Geom::Blend(*b);
    let bd = g.bounds(len);
    let tip = (1.0, 1.0 / b.r, 1.0 / (b.r * b.r));
    let t = terms(cfg, &bd, Some(tip), tcp);
    caps(cfg, &t, vfeed)
}
