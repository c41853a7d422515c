//! What happens where two path elements meet inside a chain (docs/gcode.md, "Corners"): the
//! path runs straight through (tangent, or a small *kink* the axes can take within a sample),
//! a blend arc replaces the corner (`G64`), or the machine stops there (`G61` corners, and
//! corners that cannot be blended).
//!
//! **Kink.** At a junction where the path's direction changes from $\mathbf g'_-$ to
//! $\mathbf g'_+$ (per unit of $s$), running through at speed $v$ changes axis $i$'s velocity by
//! $v|g'_{+,i} - g'_{-,i}|$ within one sample: the second difference of its sampled positions
//! is at most that over $T_s$ plus the acceleration along the path. The junction is run through
//! when that share $f = \max_i v|\Delta g'_i|/(a_i T_s)$ is at most the kink ratio $r$ (0.1,
//! LinuxCNC's `ARC_BLEND_KINK_RATIO`), and the two elements' acceleration caps are lowered by
//! the factor $1 - f$, so that no sample's second difference exceeds the limit.
//!
//! **Blend** (vcnc's rule, LinuxCNC's geometry). Two lines meeting at $P$ with unit directions
//! $\mathbf u_1, \mathbf u_2$ and half-angle $\theta = \tfrac12\arccos(-\mathbf u_1\cdot\mathbf
//! u_2)$ are joined by the circular arc tangent to both at distance $d$ from $P$: radius
//! $R = d\tan\theta$, deviation from the corner $R(1-\sin\theta)/\sin\theta$. With the tolerance
//! $T$ (the smaller `G64 P` of the two blocks; for a plain `G64` a quarter of the block's length,
//! LinuxCNC 2.9's rule), $d$ is the largest distance that keeps the deviation within $T$ and
//! takes at most half of each line:
//! $$ d = \min\Big(\frac{T\cos\theta}{1-\sin\theta},\ \frac{L_1}{2},\ \frac{L_2}{2}\Big). $$
//! Along the arc A B C follow the cubic that leaves and joins the lines with their rates. Under
//! LinuxCNC's rules (`blendmath.c`) the radius is only as large as the speed the corner allows
//! needs ([`lc_blend`]).

use super::geom::{Blend, Geom, norm3};
use super::segment::{Cfg, Seg, blend_caps};
use crate::interp::{MoveKind, PathMode};

/// The element before the junction, as the chain holds it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Side {
    pub(crate) seg: Seg,
    /// Length before any blend trimmed it.
    pub(crate) nominal: f64,
    pub(crate) mode: PathMode,
    pub(crate) kind: MoveKind,
    pub(crate) tcp: bool,
}

/// What the chain does at a junction.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Joint {
    /// Run through with this speed cap; multiply the acceleration caps of the elements before
    /// and after by these factors.
    Through { cap: f64, keep_a: f64, keep_b: f64 },
    /// Replace the corner: trim the element before by `trim_a` and the one after by `trim_b`,
    /// and put this element between them. `consume`: the rest of the element before takes the
    /// blend's caps (LinuxCNC's rules).
    Blend {
        blend: Box<Seg>,
        trim_a: f64,
        trim_b: f64,
        consume: bool,
    },
    /// Stop at the junction; multiply both acceleration caps by `keep`.
    Stop { keep: f64 },
}

/// The tolerance of one side of a corner: its `G64 P`, else (plain `G64`, `G61`) the machine's
/// plain-`G64` tolerance or a quarter of its length.
fn tolerance(cfg: &Cfg, mode: &PathMode, nominal: f64) -> f64 {
    match mode {
        PathMode::Blend {
            tolerance_mm: Some(t),
            ..
        } => *t,
        _ if !cfg.lc => cfg.plain_tolerance.unwrap_or(0.25 * nominal),
        _ => 0.25 * nominal,
    }
}

/// Unit vector, or zeros.
fn unit(x: [f64; 3]) -> [f64; 3] {
    let n = norm3(&x);
    if n > 0.0 {
        [x[0] / n, x[1] / n, x[2] / n]
    } else {
        [0.0; 3]
    }
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The speed at which a junction with the change of direction `dg` (per unit of s) takes the
/// share `f` of the axes' acceleration within a sample (module doc): returns $f/v$.
fn kink_share_per_speed(cfg: &Cfg, dg: &[f64; 6], tcp: bool) -> f64 {
    let l = &cfg.limits;
    let mut f: f64 = 0.0;
    for (i, d) in dg.iter().enumerate() {
        if tcp && i < 3 {
            continue;
        }
        if *d != 0.0 {
            f = f.max(d.abs() / (l.axes[i].max_acc * cfg.ts));
            if cfg.jerk {
                f = f.max(d.abs() / (l.axes[i].max_jerk * cfg.ts * cfg.ts));
            }
        }
    }
    if tcp {
        let n = norm3(&dg[0..3]);
        if n > 0.0 {
            f = f.max(n / (l.tcp_max_acc * cfg.ts));
            if cfg.jerk {
                f = f.max(n / (l.tcp_max_jerk * cfg.ts * cfg.ts));
            }
        }
    }
    f
}

/// Jerk-limited: what a junction does to the samples' jerk. Where the path's direction jumps by
/// $\Delta g'$ and its second derivative by $\Delta g''$ (per unit of s), running through at
/// speed $v$ steps the velocity of quantity $i$ by $v|\Delta g'_i|$ and its acceleration by
/// $v^2|\Delta g''_i|$ at one instant; the third difference of its samples then reaches at most
/// $$ \frac{v|\Delta g'_i|}{T_s^2} + \frac{3}{4}\frac{v^2|\Delta g''_i|}{T_s} $$
/// (a velocity step moves the third difference by at most the step over $T_s^2$, an acceleration
/// step by at most ¾ of it over $T_s$). [`JerkJump::share`] is that over the jerk limit.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct JerkJump {
    /// Per quantity: the two coefficients over its jerk limit.
    terms: Vec<(f64, f64)>,
}

impl JerkJump {
    pub(crate) fn new(cfg: &Cfg, dg: &[f64; 6], dg2: &[f64; 6], tcp: bool) -> JerkJump {
        let l = &cfg.limits;
        let ts = cfg.ts;
        let mut terms = Vec::new();
        let mut add = |d1: f64, d2: f64, j: f64| {
            if (d1 != 0.0 || d2 != 0.0) && j.is_finite() {
                terms.push((d1 / (ts * ts * j), 0.75 * d2 / (ts * j)));
            }
        };
        for i in 0..6 {
            if tcp && i < 3 {
                continue;
            }
            add(dg[i].abs(), dg2[i].abs(), l.axes[i].max_jerk);
        }
        if tcp {
            add(norm3(&dg[0..3]), norm3(&dg2[0..3]), l.tcp_max_jerk);
        }
        JerkJump { terms }
    }

    /// The largest share of a jerk limit the junction takes at speed `v`.
    pub(crate) fn share(&self, v: f64) -> f64 {
        self.terms
            .iter()
            .map(|(c1, c2)| c1 * v + c2 * v * v)
            .fold(0.0, f64::max)
    }

    /// The speed at which the junction takes the share `r` of the jerk limits.
    pub(crate) fn cap(&self, r: f64) -> f64 {
        self.terms
            .iter()
            .map(|&(c1, c2)| {
                if c2 > 0.0 {
                    // c2 v² + c1 v − r = 0, the positive root.
                    2.0 * r / (c1 + (c1 * c1 + 4.0 * c2 * r).sqrt())
                } else if c1 > 0.0 {
                    r / c1
                } else {
                    f64::INFINITY
                }
            })
            .fold(f64::INFINITY, f64::min)
    }
}

/// The junction between `a` (its end) and `b` (its start, with its move's path mode `b_mode`
/// and length `b_nominal`).
pub(crate) fn joint(cfg: &Cfg, a: &Side, b: &Side) -> Joint {
    let (ga1, _) = a.seg.geom.ends(a.seg.len, true);
    let (gb1, _) = b.seg.geom.ends(b.seg.len, false);
    let dg: [f64; 6] = std::array::from_fn(|i| gb1[i] - ga1[i]);
    let vmax = a.seg.vcap.min(b.seg.vcap);
    let blend_mode = matches!(a.mode, PathMode::Blend { .. });
    let lines = matches!(a.kind, MoveKind::Linear | MoveKind::Rapid)
        && matches!(b.kind, MoveKind::Linear | MoveKind::Rapid)
        && a.seg.xyz_basis
        && b.seg.xyz_basis;
    let rotary = ga1[3..].iter().chain(&gb1[3..]).any(|x| *x != 0.0);
    if cfg.lc && !rotary {
        // LinuxCNC 2.9 (tp.c tpSetupTangent): the acceleration a kink takes, from the machine's
        // acceleration bounds of X Y Z, with the next element's acceleration added.
        let u1 = unit([ga1[0], ga1[1], ga1[2]]);
        let u2 = unit([gb1[0], gb1[1], gb1[2]]);
        // A reversal within 2° is a stop (SHARP_CORNER_DEG).
        if norm3(&[u1[0] + u2[0], u1[1] + u2[1], u1[2] + u2[2]]).powi(2)
            < (std::f64::consts::PI * 2.0 / 180.0).powi(2)
        {
            return Joint::Stop { keep: 1.0 };
        }
        let a_inst = vmax / cfg.ts + b.seg.acap;
        let mut scale: f64 = 0.0;
        if a.tcp {
            // In TCP mode the tip is what LinuxCNC's planner moves, and its bound is the tip's
            // (`tcp_max_acc`, a bound on the norm): the kink's velocity change as a vector.
            let bound = cfg.limits.tcp_max_acc;
            let du = [u2[0] - u1[0], u2[1] - u1[1], u2[2] - u1[2]];
            if bound > 0.0 {
                scale = a_inst * norm3(&du) / bound;
            }
        } else {
            for i in 0..3 {
                let bound = cfg.limits.axes[i].max_acc;
                if bound > 0.0 {
                    scale = scale.max((a_inst * (u2[i] - u1[i])).abs() / bound);
                }
            }
        }
        if matches!(a.kind, MoveKind::Arc(_)) || matches!(b.kind, MoveKind::Arc(_)) {
            scale /= 0.5;
        }
        let r = cfg.kink_ratio;
        if scale < r {
            return Joint::Through {
                cap: vmax,
                keep_a: 1.0 - scale,
                keep_b: 1.0 - scale,
            };
        }
        let kink_vel = vmax * r / scale;
        if !blend_mode {
            // Exact path: a stop, and the kink's acceleration reduction stays (LinuxCNC keeps
            // the kink properties it set while testing the corner).
            return Joint::Stop { keep: 1.0 - r };
        }
        if lines && let Some(bl) = lc_blend(cfg, a, b) {
            let Joint::Blend { blend, .. } = &bl else {
                return bl;
            };
            if blend.vcap >= kink_vel {
                return bl;
            }
        }
        return Joint::Through {
            cap: kink_vel,
            keep_a: 1.0 - r,
            keep_b: 1.0 - r,
        };
    }
    let f = vmax * kink_share_per_speed(cfg, &dg, a.tcp);
    if f <= cfg.kink_ratio {
        return Joint::Through {
            cap: vmax,
            keep_a: 1.0 - f,
            keep_b: 1.0 - f,
        };
    }
    if blend_mode
        && lines
        && let Some(bl) = blend(cfg, a, b)
    {
        return bl;
    }
    Joint::Stop { keep: 1.0 }
}

/// The geometry shared by both rule sets: the corner, the directions, the half-angle θ, the
/// tolerance and the lengths available.
struct Corner {
    p: [f64; 6],
    u1: [f64; 3],
    u2: [f64; 3],
    theta: f64,
    tol: f64,
    l1: f64,
    l2: f64,
}

fn corner(cfg: &Cfg, a: &Side, b: &Side) -> Option<Corner> {
    let p = a.seg.geom.end();
    let (ga1, _) = a.seg.geom.ends(a.seg.len, true);
    let (gb1, _) = b.seg.geom.ends(b.seg.len, false);
    let u1 = unit([ga1[0], ga1[1], ga1[2]]);
    let u2 = unit([gb1[0], gb1[1], gb1[2]]);
    let theta = (-dot(&u1, &u2)).clamp(-1.0, 1.0).acos() / 2.0;
    // Too sharp (a reversal) or too straight to fit an arc.
    if theta < 1e-3 || std::f64::consts::FRAC_PI_2 - theta < 1e-6 {
        return None;
    }
    let tol = tolerance(cfg, &a.mode, a.nominal)
        .min(tolerance(cfg, &b.mode, b.nominal))
        .min(0.25 * a.nominal)
        .min(0.25 * b.nominal);
    Some(Corner {
        p,
        u1,
        u2,
        theta,
        tol,
        l1: a.seg.len.min(0.5 * a.nominal),
        l2: 0.5 * b.nominal,
    })
}

/// The blend arc of radius `r` at distance `d` from the corner, with A B C on the cubic.
fn arc(c: &Corner, a: &Side, b: &Side, d: f64, r: f64) -> (Blend, f64) {
    let theta = c.theta;
    let normal = unit([c.u2[0] - c.u1[0], c.u2[1] - c.u1[1], c.u2[2] - c.u1[2]]);
    let h = r / theta.sin();
    let centre: [f64; 3] = std::array::from_fn(|i| c.p[i] + h * normal[i]);
    let (pa, ga1, _) = a.seg.geom.eval(a.seg.len - d, a.seg.len);
    let (pb, gb1, _) = b.seg.geom.eval(d, b.seg.len);
    let mut p0 = pa;
    let mut end = pb;
    for i in 0..3 {
        p0[i] = c.p[i] - d * c.u1[i];
        end[i] = c.p[i] + d * c.u2[i];
    }
    let e1 = unit(std::array::from_fn(|i| p0[i] - centre[i]));
    let phi = std::f64::consts::PI - 2.0 * theta;
    let bl = Blend {
        p0,
        end,
        c: centre,
        e1,
        e2: c.u1,
        r,
        phi,
        m0: [ga1[3], ga1[4], ga1[5]],
        m1: [gb1[3], gb1[4], gb1[5]],
    };
    (bl, r * phi)
}

/// vcnc's blend (module doc): the largest arc within the tolerance and half of each line.
fn blend(cfg: &Cfg, a: &Side, b: &Side) -> Option<Joint> {
    let c = corner(cfg, a, b)?;
    let d_tol = c.theta.cos() * c.tol / (1.0 - c.theta.sin());
    let d = d_tol.min(c.l1).min(c.l2);
    let r = c.theta.tan() * d;
    if !(r > 1e-9 && d > 0.0) {
        return None;
    }
    let (bl, len) = arc(&c, a, b, d, r);
    let vfeed = a.seg.vfeed.min(b.seg.vfeed);
    let (v, acc, j) = blend_caps(cfg, &bl, len, a.tcp, vfeed);
    Some(Joint::Blend {
        blend: Box::new(Seg {
            geom: Geom::Blend(bl),
            len,
            vcap: v.min(vfeed),
            vlim: v,
            vfeed,
            acap: acc,
            jcap: j,
            move_index: a.seg.move_index,
            xyz_basis: true,
        }),
        trim_a: d,
        trim_b: d,
        consume: false,
    })
}

/// The diameter of the circle inscribed in the cross-section, by the plane of unit normal `n`,
/// of the box of half-sides `bounds` (LinuxCNC's calculateInscribedDiameter): the largest
/// vector magnitude in that plane every component of which stays within its bound.
fn inscribed(n: &[f64; 3], bounds: [f64; 3]) -> f64 {
    let mut d = f64::INFINITY;
    for i in 0..3 {
        if bounds[i] > 0.0 {
            let scale = (1.0 - n[i] * n[i]).max(0.0).sqrt().max(1e-12);
            d = d.min(bounds[i] / scale);
        }
    }
    d
}

/// LinuxCNC 2.9's blend arc (blendmath.c `blendComputeParameters`, tp.c
/// `tpCreateLineLineBlend`): the arc may use $\sqrt3/2$ of the plane's acceleration sideways;
/// its speed is the smaller of that at the largest radius and the blocks' speeds; its radius is
/// only as large as that speed or a parabolic blend of the same length needs; the arc runs with
/// half the plane's acceleration along the path; a line left shorter than four samples at the
/// arc's speed runs with the arc's caps.
fn lc_blend(cfg: &Cfg, a: &Side, b: &Side) -> Option<Joint> {
    let c = corner(cfg, a, b)?;
    let (theta, phi) = (c.theta, std::f64::consts::PI - 2.0 * c.theta);
    let binormal = unit([
        c.u1[1] * c.u2[2] - c.u1[2] * c.u2[1],
        c.u1[2] * c.u2[0] - c.u1[0] * c.u2[2],
        c.u1[0] * c.u2[1] - c.u1[1] * c.u2[0],
    ]);
    let l = &cfg.limits;
    let a_max = inscribed(&binormal, std::array::from_fn(|i| l.axes[i].max_acc));
    let a_n = a_max * 3f64.sqrt() / 2.0;
    let v_req = a.seg.vcap.max(b.seg.vcap);
    let v_planar = inscribed(&binormal, std::array::from_fn(|i| l.axes[i].max_vel));
    let phi_eff = phi.min(std::f64::consts::PI * 0.49);
    let v1 = a.seg.vlim.min(b.seg.vlim / phi_eff.cos());
    let v2 = b.seg.vlim.min(a.seg.vlim / phi_eff.cos());
    let area = v1 * v2 / 2.0 * phi.sin();
    let base = norm3(&std::array::from_fn::<f64, 3, _>(|i| {
        c.u2[i] * v2 - c.u1[i] * v1
    }));
    let v_alt = 2.0 * area / base;
    let v_goal = v_req.min(v_alt.max(v_planar));
    let d_tol = theta.cos() * c.tol / (1.0 - theta.sin());
    let d_geom = d_tol.min(c.l1).min(c.l2);
    let r_geom = theta.tan() * d_geom;
    let v_plan = (a_n * r_geom).sqrt().min(v_goal);
    let a_par = 0.5 * a_max;
    let v_tri = (2.0 * a_par * d_geom).sqrt();
    let t_blend = v_tri.min(v_plan) / a_par;
    let r_blend = (t_blend * v_plan / phi).min(r_geom);
    let r = (v_plan * v_plan / a_n).max(r_blend);
    let d = r / theta.tan();
    if !(r > 1e-12 && r * phi > 1e-6) {
        return None;
    }
    let (bl, len) = arc(&c, a, b, d, r);
    let consume = (a.seg.len - d) / v_plan < 4.0 * cfg.ts;
    let acap = 0.5 * a_max;
    Some(Joint::Blend {
        blend: Box::new(Seg {
            geom: Geom::Blend(bl),
            len,
            vcap: v_plan.min(len / cfg.ts),
            vlim: v_plan,
            vfeed: v_req,
            acap,
            jcap: f64::INFINITY,
            move_index: a.seg.move_index,
            xyz_basis: true,
        }),
        trim_a: d,
        trim_b: d,
        consume,
    })
}
