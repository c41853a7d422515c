//! The servo tick of a drive with effects (docs/machine-file.md#drive-effects): two-mass
//! mechanics with backlash, Stribeck and Maxwell-slip friction, current loop and torque limit,
//! feedback dead time, velocity filter, noisy motor and load encoders; on one drive or on lanes
//! of drives that share the loop's [`Structure`] ([`crate::lane`]).
//!
//! # One servo tick (period $h$)
//!
//! 1. Reference: the fine-interpolated nominal sample, shaped (`super::shaping`), and the
//!    noise of this tick's readings, both prepared a block of ticks ahead (`crate::engine`).
//! 2. Readings: the position sensor (load scale or motor encoder) is read with quantisation and
//!    seeded noise, and the position loop takes the reading of $n$ ticks ago (dead time). The
//!    velocity path reads the motor encoder (the same reading in a rigid or semi-closed drive),
//!    low-pass filtered $x_f \leftarrow a x_f + (1 - a)\hat x_m$, $a = e^{-2\pi f_c h}$; the
//!    velocity is the BDF2 difference of $x_f$, the PI's $\int\dot\theta$ its increments.
//! 3. Control: the law ([`crate::law`]) with separate position and velocity readings;
//!    limit $|u| \le \min(u_{max}, T_{max}/K_aK_t)$ with conditional integration.
//! 4. Plant: the linear part (masses, spring and damper, viscous friction, current loop) is
//!    stepped exactly, $z^* = \Phi z + \Gamma_u u + \Gamma_o o$ ($o = \pm b$ the backlash
//!    offset in contact; a second $\Phi, \Gamma$ without spring while in the gap;
//!    [`crate::plant::Lin`]). Friction is a torque $f$ held over the step: $z = z^* + \Gamma_f f$,
//!    chosen implicitly for the set-valued part (stick: $f$ such that the friction body's
//!    velocity ends at 0, if that needs at most the static level; otherwise the Stribeck level
//!    at the step's initial speed) or, for Maxwell-slip, as the Heun average of the elements'
//!    force before and after the step.

use super::{Logged, Servo};
use crate::Error;
use crate::drive::Drive;
use crate::effects::{
    FeedbackSource, FrictionKind, FrictionLaw, FrictionLocation, MAX_ELEMENTS, Stribeck,
    maxwell_slip_stiffness,
};
use crate::engine::noise::Quant;
use crate::lane::{LANES, Lane};
use crate::law::{Law, LawOn, RefSample};
use crate::plant::{Layout, Lin};

/// Friction of the engine, per lane: the table's law, or the plant's symmetric Coulomb friction.
/// One per engine, never in a collection: the Maxwell-slip variant's arrays stay inline.
#[derive(Clone, Copy)]
#[allow(clippy::large_enum_variant)]
enum Fric<T: Lane> {
    None,
    SetValued(Stribeck<T>),
    Maxwell {
        /// The slip levels (the Stribeck law, the Coulomb level beyond its flat speed).
        levels: Stribeck<T>,
        /// Elements of the lane with the most; every lane has that many (`exists` all true).
        n_max: usize,
        uniform: bool,
        /// Element `i` exists in the lane.
        exists: [T::Mask; MAX_ELEMENTS],
        /// Element stiffness $k_i$, N·m per axis unit.
        k: [T; MAX_ELEMENTS],
        /// $w_i = 1/(N k_i)$: element $i$ slips at deflection ±level · $w_i$; their extremes.
        w: [T; MAX_ELEMENTS],
        w_max: T,
        w_min: T,
    },
}

/// What the drives of one batch must share: the loop's structure. The numbers (gains, masses,
/// levels, limits, delays, noise) may differ.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Structure {
    law: &'static str,
    n: usize,
    two_mass: bool,
    n_cur: usize,
    /// 0 none, 1 set-valued, 2 Maxwell-slip.
    fric: u8,
    fric_motor: bool,
    one_reading: bool,
    load_source: bool,
    second_encoder: bool,
    delayed: bool,
}

/// Which engine to build.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) enum Build {
    /// The drive as it is.
    Full,
    /// Linearised at rest: no friction (viscous kept), backlash closed, no limit, ideal
    /// sensors.
    Linear,
}

/// Constants of the loop of a drive with effects, per lane of `T`.
///
/// `N` states; `TM`: two-mass layout `[x_m, v_m, x_L, v_L, current...]`, else rigid
/// `[x, v, current...]`. Both are compile-time so that the state lives in registers.
#[derive(Clone)]
pub(crate) struct Real<T: Lane, L: Law, const N: usize, const TM: bool> {
    law: L::On<T>,
    /// Current-loop states (0, 1, 2).
    n_cur: usize,
    /// In contact (or no backlash).
    lin: Lin<T, N>,
    /// In the backlash gap (no spring).
    gap: Lin<T, N>,
    half_backlash: T,
    /// Lanes with backlash, and whether any has.
    backlash: T::Mask,
    any_backlash: bool,
    fric: Fric<T>,
    /// Friction acts on the motor of a two-mass drive (else on the load).
    fric_motor: bool,
    u_lim: T,
    k_int: T,
    /// Law slopes ([`Law::slopes`]).
    s_dp: T,
    s_df: T,
    s_ip: T,
    s_if: T,
    /// Slope of $u$ (unsaturated) in the delayed position reading $\hat x_p$.
    gu_p: T,
    /// Slopes of $u$ in the two readings of the tick that enter it undelayed.
    ga: T,
    gb: T,
    /// Velocity filter: $x_f = a\,x_{f1} + b\,\hat x_v$ ($a = 0$, $b = 1$ without a filter).
    vf_a: T,
    vf_b: T,
    /// The position and velocity readings are the same undelayed number.
    one_reading: bool,
    load_source: bool,
    second_encoder: bool,
    dead_time: [usize; LANES],
    ka_kt: T,
    /// Tangent stiffness of the Maxwell-slip elements at rest (all sticking), N·m per axis unit.
    ms_rest_stiffness: T,
    /// Quantisation of the position sensor and of the motor encoder.
    pos_q: Quant<T>,
    motor_q: Quant<T>,
}

/// Loop state. The arrays that are indexed at run time live behind boxes (made once per
/// simulation), so that the scalars and $z$ can stay in registers.
#[derive(Clone)]
pub(crate) struct RealState<T: Lane, const N: usize> {
    z: [T; N],
    integ: T,
    e1: T,
    xr1: T,
    /// Filtered velocity-path position at the previous two ticks.
    xf1: T,
    xf2: T,
    delay: Box<Delay<T>>,
    /// Maxwell-slip element deflections, axis units.
    ms: Box<[T; MAX_ELEMENTS]>,
    /// Their force $\sum k_i d_i$, N·m, and tangent stiffness (elements between their slip
    /// bounds), N·m per axis unit.
    ms_force: T,
    ms_stiffness: T,
    /// All elements slipping at +level (+1), at −level (−1), or not (0); the level, N·m. While
    /// all slip, `ms` is stale: the deflections are ±level · $w_i$.
    ms_sat: T,
    ms_level: T,
}

/// Ring of the last readings for the position-loop dead time (at most 100 cycles), one slot of
/// lanes per tick, a delay per lane.
#[derive(Clone)]
struct Delay<T> {
    buf: [T; 128],
    pos: usize,
    d: [usize; LANES],
    /// The delay every lane has, if they share one (the usual case: one fieldbus): one slot
    /// read whole instead of a lane from each lane's slot.
    shared: Option<usize>,
}

impl<T: Lane> Delay<T> {
    /// Stores `x` and returns the value stored `d` pushes ago (`x` itself when `d` = 0).
    #[inline(always)]
    fn push(&mut self, x: T) -> T {
        self.buf[self.pos] = x;
        let out = match self.shared {
            Some(d) => self.buf[(self.pos + 128 - d) & 127],
            None => T::from_fn(|l| self.buf[(self.pos + 128 - self.d[l]) & 127].at(l)),
        };
        self.pos = (self.pos + 1) & 127;
        out
    }
}

/// What one tick produced, per lane.
#[derive(Clone, Copy)]
pub(crate) struct TickOut<T: Lane> {
    /// Control (after the limit), V.
    pub(crate) u: T,
    /// Limited this tick.
    pub(crate) saturated: T::Mask,
    /// Reading the position loop used (after the dead time), axis units.
    pub(crate) xp: T,
    /// Command applied to the plant (with the injection), V.
    pub(crate) u_in: T,
}

impl<L: Law, const N: usize, const TM: bool> Real<f64, L, N, TM> {
    /// The loop of `drive` at servo period `h` (its law `law`, its layout `N`, `TM`).
    pub(crate) fn new(drive: &Drive, h: f64, build: Build, law: L) -> Result<Self, Error> {
        let plant = drive.plant();
        let e = drive.effects();
        let lay = Layout::of(e);
        let linear = build == Build::Linear;
        // Friction: the table's law, else the plant's symmetric Coulomb friction.
        let law_f = e.friction.or_else(|| {
            (plant.coulomb_torque > 0.0).then_some(FrictionLaw {
                kind: FrictionKind::SetValued,
                coulomb: [plant.coulomb_torque; 2],
                static_: [plant.coulomb_torque; 2],
                stribeck_velocity: 1.0,
                exponent: 2.0,
                location: FrictionLocation::Load,
            })
        });
        let on_load = law_f.is_none_or(|f| f.location == FrictionLocation::Load);
        let fric = match (law_f, linear) {
            (_, true) | (None, _) => Fric::None,
            (Some(f), false) => match f.kind {
                FrictionKind::SetValued => Fric::SetValued(Stribeck::of(|_| &f, false)),
                FrictionKind::MaxwellSlip {
                    elements,
                    presliding_displacement,
                } => {
                    let k = maxwell_slip_stiffness(
                        f.coulomb[0].max(f.coulomb[1]),
                        elements,
                        presliding_displacement,
                    );
                    let mut w = [0.0; MAX_ELEMENTS];
                    for (wi, k) in w.iter_mut().zip(&k).take(elements) {
                        *wi = 1.0 / (elements as f64 * k);
                    }
                    Fric::Maxwell {
                        levels: Stribeck::of(|_| &f, true),
                        n_max: elements,
                        uniform: true,
                        exists: [true; MAX_ELEMENTS],
                        k,
                        w,
                        w_max: w[..elements].iter().fold(0.0, |m: f64, v| m.max(*v)),
                        w_min: w[..elements]
                            .iter()
                            .fold(f64::INFINITY, |m: f64, v| m.min(*v)),
                    }
                }
            },
        };
        let mut lin = Lin::<f64, N>::new(plant, e, h, on_load, true)?;
        let mut gap = Lin::<f64, N>::new(plant, e, h, on_load, false)?;
        let half_backlash = match (e.compliance, linear) {
            (Some(c), false) => 0.5 * c.backlash,
            _ => 0.0,
        };
        let u_lim = if linear {
            f64::INFINITY
        } else {
            let from_torque = e.torque_max.map_or(f64::INFINITY, |t| t / plant.ka_kt());
            plant.u_max.unwrap_or(f64::INFINITY).min(from_torque)
        };
        let fb = e.feedback;
        let vf_a = fb
            .and_then(|f| f.velocity_filter_hz)
            .map_or(0.0, |fc| (-std::f64::consts::TAU * fc * h).exp());
        let load_source = fb.is_none_or(|f| f.source == FeedbackSource::Load);
        let second_encoder = lay.two_mass && load_source;
        let dead_time = fb.map_or(0, |f| f.dead_time_cycles as usize);
        let s = law.slopes();
        let k_int = law.k_int();
        let vf_b = 1.0 - vf_a;
        let gu_p = s.dp + k_int * s.ip;
        let gu_v = (s.df + k_int * s.i_f) * vf_b;
        let one_reading = dead_time == 0 && !second_encoder;
        // Which readings enter u undelayed (see `Real::tick`).
        let (ga, gb) = if one_reading {
            (gu_p + gu_v, 0.0)
        } else if second_encoder && dead_time == 0 {
            (gu_p, gu_v)
        } else {
            (0.0, gu_v)
        };
        if let Fric::SetValued(f) = &fric {
            for l in [&mut lin, &mut gap] {
                l.stick_lim = [l.g * f.static_[0], l.g * f.static_[1]];
            }
        }
        // The sensors: ideal ones for the linearised loop.
        let enc = drive.encoder();
        let (pos_res, motor_res) = match (linear, e.feedback) {
            (true, _) => (0.0, 0.0),
            (false, Some(f)) => (enc.resolution, f.motor_resolution),
            (false, None) => (enc.resolution, enc.resolution),
        };
        Ok(Real {
            law: L::gather(&[&law]),
            n_cur: lay.n_cur,
            lin,
            gap,
            half_backlash,
            backlash: half_backlash > 0.0,
            any_backlash: half_backlash > 0.0,
            ms_rest_stiffness: match &fric {
                Fric::Maxwell { k, .. } => k.iter().sum(),
                _ => 0.0,
            },
            fric,
            fric_motor: lay.two_mass && !on_load,
            u_lim,
            k_int,
            s_dp: s.dp,
            s_df: s.df,
            s_ip: s.ip,
            s_if: s.i_f,
            gu_p,
            ga,
            gb,
            vf_a,
            vf_b,
            one_reading,
            load_source,
            second_encoder,
            dead_time: [dead_time; LANES],
            ka_kt: plant.ka_kt(),
            pos_q: Quant::new(pos_res),
            motor_q: Quant::new(motor_res),
        })
    }

    /// The loop's structure: what lanes must share.
    pub(crate) fn structure(&self) -> Structure {
        Structure {
            law: std::any::type_name::<L>(),
            n: N,
            two_mass: TM,
            n_cur: self.n_cur,
            fric: match self.fric {
                Fric::None => 0,
                Fric::SetValued(_) => 1,
                Fric::Maxwell { .. } => 2,
            },
            fric_motor: self.fric_motor,
            one_reading: self.one_reading,
            load_source: self.load_source,
            second_encoder: self.second_encoder,
            delayed: self.dead_time[0] > 0,
        }
    }
}

impl<T: Lane, L: Law, const N: usize, const TM: bool> Real<T, L, N, TM> {
    /// Index of the load position and velocity in $z$ (the motor's are 0 and 1).
    const XL: usize = if TM { 2 } else { 0 };
    const VL: usize = if TM { 3 } else { 1 };
    /// Index of the current loop's output.
    const ICUR: usize = if TM { 4 } else { 2 };

    /// Lane `l` runs `loops[l]` (the last one in the lanes beyond), all of one [`Structure`].
    pub(crate) fn gather(loops: &[&Real<f64, L, N, TM>]) -> Real<T, L, N, TM> {
        let e0 = loops[0];
        let pick = |l: usize| loops[l.min(loops.len() - 1)];
        let v = |f: &dyn Fn(&Real<f64, L, N, TM>) -> f64| T::from_fn(|l| f(pick(l)));
        let half_backlash = v(&|e| e.half_backlash);
        let backlash = half_backlash.gt(T::splat(0.0));
        let fric = match e0.fric {
            Fric::None => Fric::None,
            Fric::SetValued(_) => Fric::SetValued(Stribeck::gather(&|l| match &pick(l).fric {
                Fric::SetValued(s) => *s,
                _ => unreachable!("the lanes share a structure"),
            })),
            Fric::Maxwell { .. } => {
                let ms = |l: usize| match &pick(l).fric {
                    Fric::Maxwell {
                        levels,
                        n_max,
                        k,
                        w,
                        w_max,
                        w_min,
                        ..
                    } => (*levels, *n_max, *k, *w, *w_max, *w_min),
                    _ => unreachable!("the lanes share a structure"),
                };
                let each: [_; LANES] = std::array::from_fn(ms);
                let n_max = each.iter().map(|m| m.1).max().unwrap_or(0);
                Fric::Maxwell {
                    levels: Stribeck::gather(&|l| each[l].0),
                    n_max,
                    uniform: each.iter().all(|m| m.1 == n_max),
                    exists: std::array::from_fn(|i| T::mask_from_fn(|l| i < each[l].1)),
                    k: std::array::from_fn(|i| T::from_fn(|l| each[l].2[i])),
                    w: std::array::from_fn(|i| T::from_fn(|l| each[l].3[i])),
                    w_max: T::from_fn(|l| each[l].4),
                    w_min: T::from_fn(|l| each[l].5),
                }
            }
        };
        let laws: Vec<&L> = (0..T::WIDTH).map(|l| scalar_law(pick(l))).collect();
        Real {
            law: L::gather(&laws),
            n_cur: e0.n_cur,
            lin: Lin::gather(&(0..T::WIDTH).map(|l| &pick(l).lin).collect::<Vec<_>>()),
            gap: Lin::gather(&(0..T::WIDTH).map(|l| &pick(l).gap).collect::<Vec<_>>()),
            half_backlash,
            backlash,
            any_backlash: T::any(backlash),
            fric,
            fric_motor: e0.fric_motor,
            u_lim: v(&|e| e.u_lim),
            k_int: v(&|e| e.k_int),
            s_dp: v(&|e| e.s_dp),
            s_df: v(&|e| e.s_df),
            s_ip: v(&|e| e.s_ip),
            s_if: v(&|e| e.s_if),
            gu_p: v(&|e| e.gu_p),
            ga: v(&|e| e.ga),
            gb: v(&|e| e.gb),
            vf_a: v(&|e| e.vf_a),
            vf_b: v(&|e| e.vf_b),
            one_reading: e0.one_reading,
            load_source: e0.load_source,
            second_encoder: e0.second_encoder,
            dead_time: std::array::from_fn(|l| pick(l).dead_time[0]),
            ka_kt: v(&|e| e.ka_kt),
            ms_rest_stiffness: v(&|e| e.ms_rest_stiffness),
            pos_q: Quant::gather(&(0..T::WIDTH).map(|l| &pick(l).pos_q).collect::<Vec<_>>()),
            motor_q: Quant::gather(&(0..T::WIDTH).map(|l| &pick(l).motor_q).collect::<Vec<_>>()),
        }
    }

    /// The state at rest at position `x0` with readings `xm0`.
    pub(crate) fn rest_state(&self, x0: T, xm0: T) -> RealState<T, N> {
        let zero = T::splat(0.0);
        let mut z = [zero; N];
        z[0] = x0;
        z[Self::XL] = x0;
        let d0 = self.dead_time[0];
        RealState {
            z,
            integ: zero,
            e1: x0 - xm0,
            xr1: x0,
            xf1: xm0,
            xf2: xm0,
            delay: Box::new(Delay {
                buf: [xm0; 128],
                pos: 0,
                d: self.dead_time,
                shared: self.dead_time[..T::WIDTH]
                    .iter()
                    .all(|d| *d == d0)
                    .then_some(d0),
            }),
            ms: Box::new([zero; MAX_ELEMENTS]),
            ms_force: zero,
            ms_stiffness: self.ms_rest_stiffness,
            ms_sat: zero,
            ms_level: zero,
        }
    }

    /// One servo tick with loop reference `r` (already shaped), extra command `inject` (V,
    /// added after the limit: a torque excitation) and the noise of this tick's position and
    /// motor-encoder readings.
    #[inline(always)]
    pub(crate) fn tick_with(
        &self,
        st: &mut RealState<T, N>,
        r: &RefSample<T>,
        inject: T,
        noise: (T, T),
    ) -> TickOut<T> {
        // Everything that does not depend on this tick's readings first.
        let (d0, i0) = self.law.terms0(r, st.xr1, st.e1, st.xf1, st.xf2);
        let af = self.vf_a * st.xf1;
        let direct_a = d0 + self.s_df * af;
        let integ_a = st.integ + i0 + self.s_if * af;
        let u_a = direct_a + self.k_int * integ_a;
        // Readings.
        let x_sensor = if self.load_source {
            st.z[Self::XL]
        } else {
            st.z[0]
        };
        let reading = self.pos_q.read(x_sensor, noise.0);
        let zero = T::splat(0.0);
        // u = ub + ga xa + gb xb with xa, xb the readings of this tick (0 when unused) and ub
        // the rest: the plant folds ga, gb into its coefficients (see `plant_step`).
        let (xp, xv, ub, xa, xb) = if self.one_reading {
            (reading, reading, u_a, reading, zero)
        } else if self.second_encoder {
            let xv = self.motor_q.read(st.z[0], noise.1);
            if self.dead_time[0] == 0 {
                (reading, xv, u_a, reading, xv)
            } else {
                let xp = st.delay.push(reading);
                (xp, xv, u_a + self.gu_p * xp, zero, xv)
            }
        } else {
            let xp = st.delay.push(reading);
            (xp, reading, u_a + self.gu_p * xp, zero, reading)
        };
        // The part of u that this tick's readings make, computed once and fed to the plant.
        let w = self.ga * xa + self.gb * xb;
        let u = ub + w;
        let xf = af + self.vf_b * xv;
        let d_int = i0 + self.s_ip * xp + self.s_if * xf;
        let saturated = u.abs().gt(self.u_lim);
        let (u, ub, w) = if !T::any(saturated) {
            st.integ = st.integ + d_int;
            (u, ub, w)
        } else {
            // Conditional integration: hold the integrator if its increment pushes u further
            // into the limit.
            let direct = d0 + self.s_dp * xp + self.s_df * xf;
            let hold = saturated & (self.k_int * d_int * u).gt(zero);
            let u_hold = direct + self.k_int * st.integ;
            st.integ = T::select(hold, st.integ, st.integ + d_int);
            let us = T::select(hold, u_hold, u).clamp(-self.u_lim, self.u_lim);
            (
                T::select(saturated, us, u),
                T::select(saturated, us, ub),
                T::select(saturated, zero, w),
            )
        };
        st.e1 = r.xr - xp;
        st.xr1 = r.xr;
        st.xf2 = st.xf1;
        st.xf1 = xf;
        let u_in = u + inject;
        let ub = ub + inject;
        if TM && !self.fric_motor {
            self.plant_step::<2, 3>(st, ub, w);
        } else {
            self.plant_step::<0, 1>(st, ub, w);
        }
        TickOut {
            u,
            saturated,
            xp,
            u_in,
        }
    }

    /// Load position and velocity, motor velocity, axis units (/s).
    pub(crate) fn load_position(&self, st: &RealState<T, N>) -> T {
        st.z[Self::XL]
    }
    pub(crate) fn load_velocity(&self, st: &RealState<T, N>) -> T {
        st.z[Self::VL]
    }
    pub(crate) fn motor_velocity(&self, st: &RealState<T, N>) -> T {
        st.z[1]
    }

    /// The mechanical and current-loop state $z$.
    pub(crate) fn state(&self, st: &RealState<T, N>) -> [T; N] {
        st.z
    }

    /// Motor torque at the start of a tick whose command is `u_in`, N·m: $K_aK_t u$, or the
    /// current loop's output (read before the tick).
    #[inline(always)]
    pub(crate) fn torque(&self, z: &[T; N], u_in: T) -> T {
        if self.n_cur == 0 {
            self.ka_kt * u_in
        } else {
            self.ka_kt * z[Self::ICUR.min(N - 1)]
        }
    }

    /// The plant over one tick under the held command $u = u_b + w$, $w$ the part of $u$ that
    /// the tick's readings make (module docs, step 4). Written so that every new state is
    /// (terms known before the readings) + (coefficient) × $w$: the free response
    /// $P = \Phi z + \Gamma_o o + \Gamma_u u_b$ and the friction's own terms are computed while
    /// the encoder is read (an algebraic rearrangement, not an approximation).
    ///
    /// `IX`, `IV`: index of the friction body's position and velocity in $z$.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // small dense kernel on z, p and Γ: indices read best
    fn plant_step<const IX: usize, const IV: usize>(&self, st: &mut RealState<T, N>, ub: T, w: T) {
        let zero = T::splat(0.0);
        let merged;
        let (lin, o) = if self.any_backlash {
            let d = st.z[0] - st.z[2];
            let hb = self.half_backlash;
            let (c_pos, c_neg) = (d.ge(hb), d.le(-hb));
            let o = T::select(c_pos, hb, T::select(c_neg, -hb, zero));
            let in_gap = self.backlash & !c_pos & !c_neg;
            let lin = if !T::any(in_gap) {
                &self.lin
            } else if T::all(in_gap) {
                &self.gap
            } else {
                merged = Lin::select(in_gap, &self.gap, &self.lin);
                &merged
            };
            (lin, o)
        } else {
            (&self.lin, zero)
        };
        let z = st.z;
        // Φ z with the positions entering only through the transmission's deflection
        // d = x_m - x_L (two-mass) or not at all (rigid): A (e_0 + e_L) = 0, so
        // Φ (e_0 + e_L) = e_0 + e_L exactly and Φ z = Φ_0 d + (e_0 + e_L) x_L + Σ_{j ≠ 0, L} Φ_j z_j.
        // Fewer products, and the large absolute position only passes through one addition.
        let d = if TM { z[0] - z[Self::XL] } else { zero };
        let mut p = [zero; N];
        // The current loop's states do not depend on the mechanics: their rows skip them.
        for i in 0..N {
            let mut acc = lin.g_u[i] * ub;
            if self.any_backlash {
                acc = T::select(self.backlash, acc + lin.g_o[i] * o, acc);
            }
            let mech_row = i < Self::ICUR;
            if TM && mech_row {
                acc = acc + lin.phi[i][0] * d;
            }
            for j in 1..N {
                if !(TM && j == Self::XL) && (mech_row || j >= Self::ICUR) {
                    acc = acc + lin.phi[i][j] * z[j];
                }
            }
            if i == 0 || i == Self::XL {
                acc = acc + z[Self::XL];
            }
            p[i] = acc;
        }
        match &self.fric {
            Fric::None => {
                for i in 0..N {
                    st.z[i] = p[i] + lin.g_u[i] * w;
                }
            }
            Fric::SetValued(levels) => {
                // The sliding level either way, from the speed the step starts with (the
                // static level when the step reverses the motion): known before the readings.
                let v0 = z[IV];
                let (f_pos, f_neg) = if !levels.any_stribeck() {
                    (levels.coulomb[0], -levels.coulomb[1])
                } else {
                    let (up, down) = (v0.gt(zero), (-v0).gt(zero));
                    let all = T::mask_from_fn(|_| true);
                    (
                        levels.level(all, T::select(up, v0, zero)),
                        -levels.level(!all, T::select(down, -v0, zero)),
                    )
                };
                let v_star = p[IV] + lin.g_u[IV] * w;
                let stuck = v_star.le(lin.stick_lim[0]) & v_star.ge(-lin.stick_lim[1]);
                // Stuck at the end of the step (|v*| within g T_s): the friction is whatever
                // stops the body, f = v*/g, so z = z* + Γ_f v*/g.
                let z_stuck = |i: usize| {
                    if i == IV {
                        zero
                    } else {
                        (p[i] + lin.stick_k[i] * p[IV]) + lin.stick_gu[i] * w
                    }
                };
                if T::all(stuck) {
                    for i in 0..N {
                        st.z[i] = z_stuck(i);
                    }
                } else {
                    let f = T::select(v_star.gt(zero), f_pos, f_neg);
                    let all_slide = !T::any(stuck);
                    for i in 0..N {
                        let z_slide = (p[i] + lin.g_f[i] * f) + lin.g_u[i] * w;
                        st.z[i] = if all_slide {
                            z_slide
                        } else {
                            T::select(stuck, z_stuck(i), z_slide)
                        };
                    }
                }
            }
            Fric::Maxwell {
                levels,
                n_max,
                uniform,
                exists,
                k,
                w: wk,
                w_max,
                w_min,
            } => {
                let x0 = z[IX];
                // Trapezoidal rule on the elements' force: the end force is predicted with
                // their tangent stiffness K (elements between their slip bounds) from the
                // position x* the step reaches under the initial force f0:
                // f = f0 + K/2 (x* + Γ_f,x f0 - x0), linear in w through x*.
                let (f0, half_k) = (st.ms_force, T::splat(0.5) * st.ms_stiffness);
                let rigid = half_k.eq(zero);
                if T::all(rigid) {
                    for i in 0..N {
                        st.z[i] = (p[i] + lin.g_f[i] * f0) + lin.g_u[i] * w;
                    }
                } else {
                    let f_p = (T::splat(1.0) + half_k * lin.g_f[IX]) * f0 + half_k * (p[IX] - x0);
                    let f_w = half_k * lin.g_u[IX];
                    for i in 0..N {
                        let c = lin.g_f[i];
                        let zi = (p[i] + c * f_p) + (lin.g_u[i] + c * f_w) * w;
                        st.z[i] = if T::any(rigid) {
                            T::select(rigid, (p[i] + lin.g_f[i] * f0) + lin.g_u[i] * w, zi)
                        } else {
                            zi
                        };
                    }
                }
                // Slip levels: T(v) in the direction of motion, T_s against it (element i slips
                // at ±level · w_i, w_i = 1/(N k_i)).
                let v0 = z[IV];
                let pos = v0.ge(zero);
                let lev = levels.level(pos, T::select(pos, v0, -v0));
                let hi = T::select(pos, lev, levels.static_[0]);
                let lo = T::select(pos, levels.static_[1], lev);
                let dx = st.z[IX] - x0;
                // Fast path of steady sliding: every element slipping the same way stays so
                // (d_i + dx beyond the new bound for every i); their deflections are then
                // level · w_i, kept implicit.
                let (dl_hi, dl_lo) = (hi - st.ms_level, lo - st.ms_level);
                let stays_hi = dx.ge(dl_hi * T::select(dl_hi.ge(zero), *w_max, *w_min));
                let stays_lo = (-dx).ge(dl_lo * T::select(dl_lo.ge(zero), *w_max, *w_min));
                let take_hi = st.ms_sat.gt(zero) & stays_hi;
                let take_lo = !take_hi & st.ms_sat.lt(zero) & stays_lo;
                let slide = take_hi | take_lo;
                let general = !slide;
                let (mut sat, mut level, mut force, mut stiffness) = (st.ms_sat, zero, zero, zero);
                if T::any(general) {
                    let refresh = general & !st.ms_sat.eq(zero);
                    if T::any(refresh) {
                        let dd = st.ms_sat * st.ms_level;
                        for i in 0..*n_max {
                            let m = if *uniform {
                                refresh
                            } else {
                                refresh & exists[i]
                            };
                            st.ms[i] = T::select(m, dd * wk[i], st.ms[i]);
                        }
                    }
                    // "Every element at the limit" kept as a running AND of masks (the count of
                    // elements at either limit compared with N, per lane).
                    let all = T::mask_from_fn(|_| true);
                    let (mut all_hi, mut all_lo) = (all, all);
                    let one = T::splat(1.0);
                    let every = T::all(general);
                    // Sums of non-negative terms, a term masked to +0 where the element does
                    // not count: the same numbers (x + 0 = x for x >= 0).
                    for i in 0..*n_max {
                        let (lo_i, hi_i) = (-lo * wk[i], hi * wk[i]);
                        let d = (st.ms[i] + dx).clamp(lo_i, hi_i);
                        let (above, below) = (d.gt(lo_i), d.lt(hi_i));
                        if *uniform {
                            st.ms[i] = if every {
                                d
                            } else {
                                T::select(general, d, st.ms[i])
                            };
                            force = force + k[i] * d;
                            stiffness = stiffness + k[i].masked(above & below);
                            all_hi = all_hi & !below;
                            all_lo = all_lo & !above;
                        } else {
                            let ex = exists[i];
                            st.ms[i] = T::select(general & ex, d, st.ms[i]);
                            force = T::select(ex, force + k[i] * d, force);
                            stiffness = stiffness + k[i].masked(ex & above & below);
                            all_hi = all_hi & !(ex & below);
                            all_lo = all_lo & !(ex & above);
                        }
                    }
                    sat = T::select(all_hi, one, T::select(all_lo, -one, zero));
                    level = T::select(all_hi, hi, T::select(all_lo, lo, zero));
                }
                st.ms_sat = T::select(slide, st.ms_sat, sat);
                st.ms_level = T::select(take_hi, hi, T::select(take_lo, lo, level));
                st.ms_force = T::select(take_hi, hi, T::select(take_lo, -lo, force));
                st.ms_stiffness = T::select(slide, zero, stiffness);
            }
        }
    }
}

/// The scalar law of a scalar loop (its `L::On<f64>` is `L`).
fn scalar_law<L: Law, const N: usize, const TM: bool>(e: &Real<f64, L, N, TM>) -> &L {
    L::as_scalar(&e.law)
}

impl<T: Lane, L: Law, const N: usize, const TM: bool> Servo<T> for Real<T, L, N, TM> {
    type State = RealState<T, N>;

    fn quant(&self) -> &Quant<T> {
        &self.pos_q
    }

    fn rest(&self, x0: T, xm0: T) -> RealState<T, N> {
        self.rest_state(x0, xm0)
    }

    fn second_encoder(&self) -> bool {
        self.second_encoder
    }

    #[inline(always)]
    fn tick(&self, st: &mut RealState<T, N>, r: &RefSample<T>, noise: (T, T)) -> T::Mask {
        self.tick_with(st, r, T::splat(0.0), noise).saturated
    }

    #[inline(always)]
    fn logged_tick(
        &self,
        st: &mut RealState<T, N>,
        r: &RefSample<T>,
        noise: (T, T),
    ) -> (Logged<T>, T::Mask) {
        let (xl, vl, xm) = (st.z[Self::XL], st.z[Self::VL], st.z[0]);
        let z_before = st.z;
        let out = self.tick_with(st, r, T::splat(0.0), noise);
        let logged = Logged {
            position: out.xp,
            true_position: xl,
            velocity: vl,
            control: out.u,
            motor_position: xm,
            motor_torque: self.torque(&z_before, out.u_in),
        };
        (logged, out.saturated)
    }
}

/// Monomorphised on the law, the state size and the layout: something to do with the loop of a
/// drive with effects ([`with_real`]).
pub(crate) trait RealJob {
    type Out;
    fn run<L: Law, const N: usize, const TM: bool>(self, e: Real<f64, L, N, TM>) -> Self::Out;
}

/// Builds the loop of `drive` at servo period `h` and runs `job` on it.
pub(crate) fn with_real<J: RealJob>(
    drive: &Drive,
    h: f64,
    build: Build,
    job: J,
) -> Result<J::Out, Error> {
    struct ByLaw<'a, J> {
        drive: &'a Drive,
        h: f64,
        build: Build,
        job: J,
    }
    impl<J: RealJob> crate::law::LawJob for ByLaw<'_, J> {
        type Out = Result<J::Out, Error>;
        fn run<L: Law>(self, law: L) -> Self::Out {
            let (d, h, b, job) = (self.drive, self.h, self.build, self.job);
            let lay = Layout::of(d.effects());
            Ok(match (lay.two_mass, lay.n()) {
                (false, 2) => job.run(Real::<f64, L, 2, false>::new(d, h, b, law)?),
                (false, 3) => job.run(Real::<f64, L, 3, false>::new(d, h, b, law)?),
                (false, _) => job.run(Real::<f64, L, 4, false>::new(d, h, b, law)?),
                (true, 4) => job.run(Real::<f64, L, 4, true>::new(d, h, b, law)?),
                (true, 5) => job.run(Real::<f64, L, 5, true>::new(d, h, b, law)?),
                (true, _) => job.run(Real::<f64, L, 6, true>::new(d, h, b, law)?),
            })
        }
    }
    crate::law::with_law(
        drive.controller(),
        drive.plant(),
        h,
        ByLaw {
            drive,
            h,
            build,
            job,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::{Compliance, CurrentLoop, CurrentLoopOrder, Feedback, Friction};
    use crate::params::Plant;
    use crate::presets::table1_drive;
    use crate::{DriveParams, Encoder};
    use nalgebra::DMatrix;

    /// The loop's state as a vector: $z$, integrator, $e_1$, $x_{f1}$, $x_{f2}$, the pending
    /// dead-time readings (oldest first): the state of `stability::effects_matrix`.
    fn pack<const N: usize>(st: &RealState<f64, N>) -> Vec<f64> {
        let mut v: Vec<f64> = st.z.to_vec();
        v.extend([st.integ, st.e1, st.xf1, st.xf2]);
        let d = st.delay.d[0];
        v.extend((0..d).map(|i| st.delay.buf[(st.delay.pos + 128 - d + i) & 127]));
        v
    }

    fn unpack<const N: usize>(st: &mut RealState<f64, N>, v: &[f64]) {
        st.z.copy_from_slice(&v[..N]);
        (st.integ, st.e1, st.xf1, st.xf2) = (v[N], v[N + 1], v[N + 2], v[N + 3]);
        let d = st.delay.d[0];
        for (i, x) in v[N + 4..].iter().enumerate() {
            st.delay.buf[(st.delay.pos + 128 - d + i) & 127] = *x;
        }
    }

    /// The linearised engine's tick applied to each unit state: the columns of its matrix.
    fn tick_matrix(drive: &Drive) -> DMatrix<f64> {
        struct T;
        impl RealJob for T {
            type Out = DMatrix<f64>;
            fn run<L: Law, const N: usize, const TM: bool>(
                self,
                e: Real<f64, L, N, TM>,
            ) -> Self::Out {
                let dim = N + 4 + e.dead_time[0];
                let mut m = DMatrix::<f64>::zeros(dim, dim);
                for col in 0..dim {
                    let mut st = e.rest_state(0.0, 0.0);
                    let mut unit = vec![0.0; dim];
                    unit[col] = 1.0;
                    unpack(&mut st, &unit);
                    e.tick_with(&mut st, &RefSample::zero(), 0.0, (0.0, 0.0));
                    for (row, x) in pack(&st).iter().enumerate() {
                        m[(row, col)] = *x;
                    }
                }
                m
            }
        }
        let h = 1.0 / drive.servo_rate_hz();
        with_real(drive, h, Build::Linear, T).expect("builds")
    }

    #[test]
    fn engine_ticks_are_the_stability_matrices() {
        // Truth: the engine itself. The stability analysis derives the linearised loop from the
        // law's and the plant step's constants; the engine's tick (linearised: no friction, no
        // backlash, ideal sensors, no limit) applied to unit states must give the same matrix,
        // to rounding (the tick folds its terms in another order), for each law, rigid and
        // two-mass drives, current loops of both orders, each feedback path with and without
        // dead time and velocity filter.
        let two_mass = |p: &mut DriveParams| {
            p.compliance = Some(Compliance {
                j_motor: 0.004,
                stiffness: None,
                mode_hz: Some(150.0),
                damping: None,
                mode_zeta: Some(0.05),
                backlash: 0.002,
            })
        };
        let mut cases: Vec<DriveParams> = Vec::new();
        for law in 0..3 {
            for variant in 0..6 {
                let mut p = crate::presets::table1_drive();
                if law > 0 {
                    let poles = p.closed_loop_model().unwrap().poles().unwrap();
                    let design = Some(crate::PoleDesign {
                        p_hz: poles.p_hz(),
                        wn_hz: poles.wn_hz(),
                        zeta: poles.zeta,
                    });
                    p.controller = if law == 1 {
                        crate::ControllerSpec::Pid {
                            kp: None,
                            ki: None,
                            kd: None,
                            design,
                            jff: 0.1,
                            bff: 0.2,
                        }
                    } else {
                        crate::ControllerSpec::Smc {
                            lambda: None,
                            ks: None,
                            rho: None,
                            je_hat: None,
                            be_hat: None,
                            design,
                        }
                    };
                }
                p.encoder = Encoder::default();
                match variant {
                    0 => {}
                    1 => two_mass(&mut p),
                    2 => {
                        two_mass(&mut p);
                        p.feedback = Some(Feedback {
                            dead_time_cycles: 2,
                            velocity_filter_hz: Some(1500.0),
                            ..Feedback::default()
                        });
                    }
                    3 => {
                        two_mass(&mut p);
                        p.feedback = Some(Feedback {
                            source: FeedbackSource::Motor,
                            dead_time_cycles: 1,
                            ..Feedback::default()
                        });
                        p.current_loop = Some(CurrentLoop {
                            order: CurrentLoopOrder::SecondOrder,
                            bandwidth_hz: Some(1200.0),
                            zeta: Some(0.7),
                            torque_max: None,
                        });
                    }
                    4 => {
                        p.feedback = Some(Feedback {
                            dead_time_cycles: 3,
                            ..Feedback::default()
                        });
                        p.current_loop = Some(CurrentLoop {
                            order: CurrentLoopOrder::FirstOrder,
                            bandwidth_hz: Some(1500.0),
                            zeta: None,
                            torque_max: Some(5.0),
                        });
                    }
                    _ => {
                        two_mass(&mut p);
                        p.friction = Some(Friction::Coulomb {
                            coulomb_torque_negative: None,
                            location: FrictionLocation::Motor,
                        });
                    }
                }
                cases.push(p);
            }
        }
        for (k, p) in cases.iter().enumerate() {
            let d = p.validate().unwrap_or_else(|e| panic!("case {k}: {e}"));
            let want = tick_matrix(&d);
            let got = d.effects_transition_matrix().unwrap();
            assert_eq!(got.shape(), want.shape(), "case {k}");
            let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let diff = (&got - &want).iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(diff <= 1e-14 * scale, "case {k}: {diff:e} of {scale:e}");
        }
        // The ideal drive's matrix against its own tick (linear plant: no friction, no limit).
        let d = table1_drive().validate().unwrap();
        let m = d.sampled_transition_matrix().unwrap();
        let h = 1.0 / d.servo_rate_hz();
        let plant = Plant {
            coulomb_torque: 0.0,
            u_max: None,
            ..d.plant().clone()
        };
        let law = crate::law::PPi::of(d.controller(), &plant, h).unwrap();
        let ideal = crate::engine::ideal::Ideal::new(law, &plant, 0.0, h).unwrap();
        for col in 0..5 {
            let mut z = [0.0; 5];
            z[col] = 1.0;
            let mut st = crate::engine::ideal::IdealState {
                x: z[0],
                v: z[1],
                integ: z[2],
                xm1: z[3],
                xm2: z[4],
                xr1: 0.0,
            };
            crate::engine::Servo::tick(&ideal, &mut st, &RefSample::zero(), (-0.0, 0.0));
            for (row, v) in [st.x, st.v, st.integ, st.xm1, st.xm2].iter().enumerate() {
                assert_eq!(m[(row, col)].to_bits(), v.to_bits(), "({row}, {col})");
            }
        }
    }
}
