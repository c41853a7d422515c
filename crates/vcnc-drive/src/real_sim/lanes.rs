//! Several drives with effects in one loop, one drive per SIMD lane (docs/machine-file.md#cost).
//!
//! The drives of a batch share the loop's structure (control law, state size and layout,
//! friction model and body, which readings enter the loop and whether they are delayed, servo
//! ticks per sample); every number may differ per lane (gains, masses, levels, backlash, limits,
//! quantisation, noise, dead time, number of Maxwell-slip elements, reference shaping). Each
//! lane performs, in the same order, the same IEEE operations as [`Engine::tick`] does for its
//! drive alone (no fused multiply-add: Rust never contracts), so each lane's trace is that of
//! [`crate::Drive::simulate`] bit for bit. What the scalar loop decides with a branch, a lane
//! decides with a select between the branches' values, computed as the scalar branch computes
//! them; a branch that no lane takes is skipped as a whole (the same numbers either way).
//!
//! Outside the ticks' dependency chain: the reference's fine interpolation and shaping, on
//! lanes for a sample at a time when the lanes' shaping shares its structure (the same delay
//! and moving-average window in ticks, or none; else per lane, as the scalar loop), and the
//! readings' noise, each lane from its own streams in the scalar loop's order, drawn one tick
//! at a time during the previous sample's ticks (the generator's scalar work then runs in the
//! gaps the tick's dependency chain leaves, instead of apart). The Stribeck level's exponential
//! is [`crate::effects::exp_neg`] on lanes; per lane remain only a Stribeck exponent other than
//! 1 and 2 (libm's power, the scalar loop's) and the rare rounding of a reading beyond
//! $2^{51}$ quanta.
//!
//! Lanes are four `f64` in a 256-bit AVX register, operated on with `std::arch` intrinsics
//! (add, subtract, multiply, divide, compare, blend, sign-bit masks: each the IEEE operation of
//! the scalar code, lane by lane). x86-64 with AVX2 only, checked at run time; elsewhere the
//! drives run one at a time ([`crate::batch`] falls back), with the same results. The loop is
//! compiled twice, for AVX2 and for AVX2 with AVX-512VL ([`run_avx512vl`], chosen where the
//! processor has it): the same 256-bit operations, the latter with 32 vector registers instead
//! of 16 for the loop's thirty-odd live lane values (fewer spills; docs/machine-file.md#cost).
//! No SIMD
//! crate: the portable `std::simd` is nightly-only, and the few operations needed are single
//! intrinsics.

use std::arch::x86_64::*;
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

use super::{Engine, Fric, Lin, RLaw, Reader, ShapeFilter, Shaper};
use crate::Error;
use crate::effects::{FrictionLaw, MAX_ELEMENTS, Shaping};
use crate::model::Reference;
use crate::sim::{DriveTrace, RefSample, quantise_to};

use super::LANES;

// ---------------------------------------------------------------------------------------------
// Lane arrays.
//
// Stored as plain arrays; every operation on whole lanes is one AVX instruction (std::arch),
// inlined into [`run_avx2`], the only place they run (after the processor's AVX2 was checked).
// Left to LLVM's SLP vectoriser, the same operations on arrays came out with their conditions
// packed, shuffled and partly scalar: a third of the loop's time.

/// One `f64` per lane.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub(crate) struct F(pub(crate) [f64; LANES]);

/// One condition per lane: all bits set (true) or none (false), the form of a vector
/// comparison's result.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub(crate) struct M(pub(crate) [i64; LANES]);

#[inline(always)]
fn ld(a: F) -> __m256d {
    // SAFETY: `F` is 32-byte aligned; AVX is present wherever lanes run (`run_batch`).
    unsafe { _mm256_load_pd(a.0.as_ptr()) }
}

#[inline(always)]
fn st(v: __m256d) -> F {
    let mut f = F([0.0; LANES]);
    // SAFETY: as `ld`.
    unsafe { _mm256_store_pd(f.0.as_mut_ptr(), v) };
    f
}

#[inline(always)]
fn ldm(m: M) -> __m256d {
    // SAFETY: as `ld` (`M` is 32-byte aligned, its bits read as doubles).
    unsafe { _mm256_load_pd(m.0.as_ptr().cast()) }
}

#[inline(always)]
fn stm(v: __m256d) -> M {
    let mut m = M([0; LANES]);
    // SAFETY: as `ld`.
    unsafe { _mm256_store_pd(m.0.as_mut_ptr().cast(), v) };
    m
}

impl F {
    #[inline(always)]
    pub(crate) fn splat(v: f64) -> F {
        F([v; LANES])
    }
    #[inline(always)]
    fn map(f: impl Fn(usize) -> f64) -> F {
        F(std::array::from_fn(f))
    }
    /// `self < o` (ordered: false with a NaN, as Rust's `<`), and so on.
    #[inline(always)]
    fn lt(self, o: F) -> M {
        // SAFETY: as `ld`.
        stm(unsafe { _mm256_cmp_pd::<_CMP_LT_OQ>(ld(self), ld(o)) })
    }
    #[inline(always)]
    fn le(self, o: F) -> M {
        // SAFETY: as `ld`.
        stm(unsafe { _mm256_cmp_pd::<_CMP_LE_OQ>(ld(self), ld(o)) })
    }
    #[inline(always)]
    fn gt(self, o: F) -> M {
        // SAFETY: as `ld`.
        stm(unsafe { _mm256_cmp_pd::<_CMP_GT_OQ>(ld(self), ld(o)) })
    }
    #[inline(always)]
    fn ge(self, o: F) -> M {
        // SAFETY: as `ld`.
        stm(unsafe { _mm256_cmp_pd::<_CMP_GE_OQ>(ld(self), ld(o)) })
    }
    #[inline(always)]
    fn eq(self, o: F) -> M {
        // SAFETY: as `ld`.
        stm(unsafe { _mm256_cmp_pd::<_CMP_EQ_OQ>(ld(self), ld(o)) })
    }
    /// `f64::abs`: the sign bit cleared.
    #[inline(always)]
    fn abs(self) -> F {
        // SAFETY: as `ld`.
        st(unsafe { _mm256_andnot_pd(_mm256_set1_pd(-0.0), ld(self)) })
    }
    /// `self` in the lanes of `m`, else +0 (a bitwise and: cheaper than a select).
    #[inline(always)]
    fn masked(self, m: M) -> F {
        // SAFETY: as `ld`.
        st(unsafe { _mm256_and_pd(ld(self), ldm(m)) })
    }
    /// `f64::clamp` per lane (the bounds ordered, as the scalar loop asserts).
    #[inline(always)]
    fn clamp(self, lo: F, hi: F) -> F {
        let x = sel(self.lt(lo), lo, self);
        sel(x.gt(hi), hi, x)
    }
}

/// `if m { a } else { b }` per lane.
#[inline(always)]
fn sel(m: M, a: F, b: F) -> F {
    // SAFETY: as `ld`.
    st(unsafe { _mm256_blendv_pd(ld(b), ld(a), ldm(m)) })
}

impl M {
    #[inline(always)]
    fn bits(self) -> i32 {
        // SAFETY: as `ld`.
        unsafe { _mm256_movemask_pd(ldm(self)) }
    }
    #[inline(always)]
    fn any(self) -> bool {
        self.bits() != 0
    }
    #[inline(always)]
    fn all(self) -> bool {
        self.bits() == (1 << LANES) - 1
    }
    /// Lane `l`'s condition.
    #[inline(always)]
    fn at(self, l: usize) -> bool {
        self.0[l] != 0
    }
    /// A condition per lane.
    fn of(f: impl Fn(usize) -> bool) -> M {
        M(std::array::from_fn(|l| -(f(l) as i64)))
    }
}

macro_rules! lane_op {
    ($tr:ident, $f:ident, $intr:ident) => {
        impl $tr for F {
            type Output = F;
            #[inline(always)]
            fn $f(self, o: F) -> F {
                // SAFETY: as `ld`.
                st(unsafe { $intr(ld(self), ld(o)) })
            }
        }
    };
}
lane_op!(Add, add, _mm256_add_pd);
lane_op!(Sub, sub, _mm256_sub_pd);
lane_op!(Mul, mul, _mm256_mul_pd);
lane_op!(Div, div, _mm256_div_pd);

impl Neg for F {
    type Output = F;
    /// The sign bit flipped, as Rust's `-x`.
    #[inline(always)]
    fn neg(self) -> F {
        // SAFETY: as `ld`.
        st(unsafe { _mm256_xor_pd(_mm256_set1_pd(-0.0), ld(self)) })
    }
}

macro_rules! mask_op {
    ($tr:ident, $f:ident, $intr:ident) => {
        impl $tr for M {
            type Output = M;
            #[inline(always)]
            fn $f(self, o: M) -> M {
                // SAFETY: as `ld`.
                stm(unsafe { $intr(ldm(self), ldm(o)) })
            }
        }
    };
}
mask_op!(BitAnd, bitand, _mm256_and_pd);
mask_op!(BitOr, bitor, _mm256_or_pd);

impl Not for M {
    type Output = M;
    #[inline(always)]
    fn not(self) -> M {
        // SAFETY: as `ld`.
        stm(unsafe { _mm256_xor_pd(ldm(self), _mm256_castsi256_pd(_mm256_set1_epi64x(-1))) })
    }
}

/// [`exp_neg`](crate::effects::exp_neg) per lane: the same operations in the same order.
#[inline(always)]
fn exp_neg(p: F) -> F {
    use crate::effects::exp_neg_consts::{C, INV_LN2, LN2_HI, LN2_LO, ROUND};
    let x = -p;
    let t = x * F::splat(INV_LN2) + F::splat(ROUND);
    let n = t - F::splat(ROUND);
    let r = (x - n * F::splat(LN2_HI)) - n * F::splat(LN2_LO);
    let c = |i: usize| F::splat(C[i]); // a constant, no intrinsic: no AVX needed to inline
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let q0 = c(0) + c(1) * r;
    let q1 = c(2) + c(3) * r;
    let q2 = c(4) + c(5) * r;
    let q3 = c(6) + c(7) * r;
    let q4 = c(8) + c(9) * r;
    let q5 = c(10) + c(11) * r;
    let q6 = c(12) + c(13) * r;
    let s0 = q0 + q1 * r2;
    let s1 = q2 + q3 * r2;
    let s2 = q4 + q5 * r2;
    let u0 = s0 + s1 * r4;
    let u1 = s2 + q6 * r4;
    let poly = u0 + u1 * r8;
    // SAFETY: as `ld` (64-bit integer lanes: AVX2).
    let scale = unsafe {
        let k = _mm256_sub_epi64(
            _mm256_castpd_si256(ld(t)),
            _mm256_set1_epi64x(ROUND.to_bits() as i64),
        );
        _mm256_castsi256_pd(_mm256_slli_epi64::<52>(_mm256_add_epi64(
            k,
            _mm256_set1_epi64x(1023),
        )))
    };
    poly * st(scale)
}

/// Lane `l` of each of `xs`.
fn lanes_of<T, const K: usize>(xs: &[T; K], f: impl Fn(&T) -> f64) -> F {
    F::map(|l| f(&xs[l.min(K - 1)]))
}

// ---------------------------------------------------------------------------------------------
// Control laws per lane (the same expressions as `RLaw::terms0`, operand for operand).

/// The loop's reference of one tick, per lane.
#[derive(Clone, Copy)]
pub(crate) struct RefF {
    xr: F,
    vr: F,
    ar: F,
}

/// [`RLaw::terms0`] on lanes.
pub(crate) trait LaneLaw: Copy {
    fn terms0(&self, r: &RefF, xr1: F, e1: F, xf1: F, xf2: F) -> (F, F);
}

macro_rules! lane_law {
    ($lanes:ident, $scalar:ident, [$($f:ident),*]) => {
        #[derive(Clone, Copy)]
        pub(crate) struct $lanes {
            $($f: F,)*
        }
        impl $lanes {
            pub(crate) fn of(laws: &[super::$scalar; LANES]) -> $lanes {
                $lanes { $($f: lanes_of(laws, |x| x.$f),)* }
            }
        }
    };
}
lane_law!(
    PPiL,
    PPiR,
    [kv, kp, vff_over_rg, inv_rg, half_h_kv, inv_2h, ff_a, ff_v]
);
lane_law!(PidL, PidR, [kp, kd, half_h, inv_2h, ff_a, ff_v]);
lane_law!(
    SmcL,
    SmcR,
    [lambda, ks, je_hat, be_hat, half_h_lambda, inv_2h]
);

impl LaneLaw for PPiL {
    #[inline(always)]
    fn terms0(&self, r: &RefF, xr1: F, e1: F, xf1: F, xf2: F) -> (F, F) {
        let v0 = (xf2 - F::splat(4.0) * xf1) * self.inv_2h;
        let w_err0 = self.kv * r.xr + self.vff_over_rg * r.vr - self.inv_rg * v0;
        let direct0 = self.kp * w_err0 + self.ff_a * r.ar + self.ff_v * r.vr;
        let d_int0 =
            self.half_h_kv * (r.xr + e1) + self.vff_over_rg * (r.xr - xr1) + self.inv_rg * xf1;
        (direct0, d_int0)
    }
}

impl LaneLaw for PidL {
    #[inline(always)]
    fn terms0(&self, r: &RefF, _xr1: F, e1: F, xf1: F, xf2: F) -> (F, F) {
        let v0 = (xf2 - F::splat(4.0) * xf1) * self.inv_2h;
        let direct0 = self.kp * r.xr + self.kd * (r.vr - v0) + self.ff_a * r.ar + self.ff_v * r.vr;
        (direct0, self.half_h * (r.xr + e1))
    }
}

impl LaneLaw for SmcL {
    #[inline(always)]
    fn terms0(&self, r: &RefF, _xr1: F, e1: F, xf1: F, xf2: F) -> (F, F) {
        let v0 = (xf2 - F::splat(4.0) * xf1) * self.inv_2h;
        let e_dot0 = r.vr - v0;
        let surface0 = self.lambda * r.xr + e_dot0;
        let direct0 =
            self.je_hat * (r.ar + self.lambda * e_dot0) + self.be_hat * v0 + self.ks * surface0;
        (direct0, self.half_h_lambda * (r.xr + e1) + (r.xr - e1))
    }
}

// ---------------------------------------------------------------------------------------------
// The engine on lanes.

/// [`Lin`] on lanes (the fields the tick reads).
#[derive(Clone, Copy)]
struct LinF<const N: usize> {
    phi: [[F; N]; N],
    g_u: [F; N],
    g_f: [F; N],
    g_o: [F; N],
    stick_k: [F; N],
    stick_gu: [F; N],
    stick_lim: [F; 2],
}

impl<const N: usize> LinF<N> {
    fn of(lins: [&Lin<N>; LANES]) -> LinF<N> {
        let v = |f: &dyn Fn(&Lin<N>) -> f64| F::map(|l| f(lins[l]));
        LinF {
            phi: std::array::from_fn(|i| std::array::from_fn(|j| v(&|x| x.phi[i][j]))),
            g_u: std::array::from_fn(|i| v(&|x| x.g_u[i])),
            g_f: std::array::from_fn(|i| v(&|x| x.g_f[i])),
            g_o: std::array::from_fn(|i| v(&|x| x.g_o[i])),
            stick_k: std::array::from_fn(|i| v(&|x| x.stick_k[i])),
            stick_gu: std::array::from_fn(|i| v(&|x| x.stick_gu[i])),
            stick_lim: std::array::from_fn(|i| v(&|x| x.stick_lim[i])),
        }
    }

    /// `b`'s coefficients in the lanes of `m`, else `a`'s.
    #[inline(always)]
    fn select(m: M, b: &LinF<N>, a: &LinF<N>) -> LinF<N> {
        let mut out = *a;
        for i in 0..N {
            for j in 0..N {
                out.phi[i][j] = sel(m, b.phi[i][j], a.phi[i][j]);
            }
            out.g_u[i] = sel(m, b.g_u[i], a.g_u[i]);
            out.g_f[i] = sel(m, b.g_f[i], a.g_f[i]);
            out.g_o[i] = sel(m, b.g_o[i], a.g_o[i]);
            out.stick_k[i] = sel(m, b.stick_k[i], a.stick_k[i]);
            out.stick_gu[i] = sel(m, b.stick_gu[i], a.stick_gu[i]);
        }
        for i in 0..2 {
            out.stick_lim[i] = sel(m, b.stick_lim[i], a.stick_lim[i]);
        }
        out
    }
}

/// Friction on lanes: every lane has the same kind. One per engine, never in a collection: the
/// Maxwell-slip variant's arrays stay inline.
#[allow(clippy::large_enum_variant)]
enum FricF {
    None,
    SetValued {
        laws: [FrictionLaw; LANES],
    },
    Maxwell {
        laws: [FrictionLaw; LANES],
        /// Elements of the lane with the most.
        n_max: usize,
        /// Every lane has `n_max` elements (`exists` is all true).
        uniform: bool,
        /// Element `i` exists in the lane.
        exists: [M; MAX_ELEMENTS],
        k: [F; MAX_ELEMENTS],
        w: [F; MAX_ELEMENTS],
        w_max: F,
        w_min: F,
        v_flat: F,
        coulomb: [F; 2],
        static_: [F; 2],
        /// Stribeck velocity; exponent 2, exponent neither 1 nor 2.
        vs: F,
        exp2: M,
        exp_other: M,
    },
}

/// [`super::RState`] on lanes.
pub(crate) struct StateF<const N: usize> {
    z: [F; N],
    integ: F,
    e1: F,
    xr1: F,
    xf1: F,
    xf2: F,
    delay: Box<DelayF>,
    ms: Box<[F; MAX_ELEMENTS]>,
    ms_force: F,
    ms_stiffness: F,
    /// +1, −1 or 0, as a float.
    ms_sat: F,
    ms_level: F,
}

/// Dead-time rings, one slot of lanes per tick, a delay per lane.
struct DelayF {
    buf: [F; 128],
    pos: usize,
    d: [usize; LANES],
    /// The delay every lane has, if they share one (the usual case: one fieldbus): one slot
    /// read whole instead of a lane from each lane's slot.
    shared: Option<usize>,
}

impl DelayF {
    #[inline(always)]
    fn push(&mut self, x: F) -> F {
        self.buf[self.pos] = x;
        let out = match self.shared {
            Some(d) => self.buf[(self.pos + 128 - d) & 127],
            None => F::map(|l| self.buf[(self.pos + 128 - self.d[l]) & 127].0[l]),
        };
        self.pos = (self.pos + 1) & 127;
        out
    }
}

/// Quantisation of one reader per lane.
#[derive(Clone, Copy)]
struct QuantF {
    q: F,
    inv_q: F,
    /// `q > 0`.
    on: M,
}

impl QuantF {
    fn of(readers: [&Reader; LANES]) -> QuantF {
        let q = F::map(|l| readers[l].q);
        QuantF {
            q,
            inv_q: F::map(|l| readers[l].inv_q),
            on: q.gt(F::splat(0.0)),
        }
    }

    /// [`quantise_to`] of `x + noise` per lane.
    #[inline(always)]
    fn read(&self, x: F, noise: F) -> F {
        const MAGIC: f64 = 6_755_399_441_055_744.0;
        let x = x + noise;
        let y = x * self.inv_q;
        if (y.abs().lt(F::splat(2_251_799_813_685_248.0)) | !self.on).all() {
            let n = (y + F::splat(MAGIC)) - F::splat(MAGIC);
            sel(self.on, n * self.q, x)
        } else {
            F::map(|l| quantise_to(x.0[l], self.q.0[l], self.inv_q.0[l]))
        }
    }
}

/// The loop constants of [`Engine`] on lanes.
pub(crate) struct EngineF<B, const N: usize, const TM: bool> {
    law: B,
    n_cur: usize,
    lin: LinF<N>,
    gap: LinF<N>,
    half_backlash: F,
    /// Lanes with backlash, and whether any has.
    backlash: M,
    any_backlash: bool,
    fric: FricF,
    fric_motor: bool,
    u_lim: F,
    k_int: F,
    s_dp: F,
    s_df: F,
    s_ip: F,
    s_if: F,
    gu_p: F,
    ga: F,
    gb: F,
    vf_a: F,
    vf_b: F,
    one_reading: bool,
    load_source: bool,
    second_encoder: bool,
    delayed: bool,
    dead_time: [usize; LANES],
    ka_kt: F,
    ms_rest_stiffness: F,
    pos_q: QuantF,
    motor_q: QuantF,
}

/// What one tick produced, per lane.
struct TickF {
    u: F,
    xp: F,
    u_in: F,
    saturated: M,
}

impl<B: LaneLaw, const N: usize, const TM: bool> EngineF<B, N, TM> {
    const XL: usize = if TM { 2 } else { 0 };
    const VL: usize = if TM { 3 } else { 1 };
    const ICUR: usize = if TM { 4 } else { 2 };

    /// The lanes of `engines` (of the same [`super::Structure`]) with their readers.
    pub(crate) fn of<L: RLaw>(
        engines: [&Engine<L, N, TM>; LANES],
        law: B,
        readers: [&(Reader, Reader); LANES],
    ) -> EngineF<B, N, TM> {
        let e0 = engines[0];
        let v = |f: &dyn Fn(&Engine<L, N, TM>) -> f64| F::map(|l| f(engines[l]));
        let half_backlash = v(&|e| e.half_backlash);
        let backlash = half_backlash.gt(F::splat(0.0));
        let fric = match e0.fric {
            Fric::None => FricF::None,
            Fric::SetValued(_) => FricF::SetValued {
                laws: std::array::from_fn(|l| match engines[l].fric {
                    Fric::SetValued(law) => law,
                    _ => unreachable!("the lanes share a structure"),
                }),
            },
            Fric::Maxwell { .. } => {
                let ms = |l: usize| match &engines[l].fric {
                    Fric::Maxwell {
                        law,
                        n,
                        k,
                        w,
                        w_max,
                        w_min,
                        v_flat,
                    } => (*law, *n, *k, *w, *w_max, *w_min, *v_flat),
                    _ => unreachable!("the lanes share a structure"),
                };
                let each: [_; LANES] = std::array::from_fn(ms);
                let laws = std::array::from_fn(|l| each[l].0);
                let n_max = each.iter().map(|m| m.1).max().unwrap_or(0);
                FricF::Maxwell {
                    laws,
                    n_max,
                    uniform: each.iter().all(|m| m.1 == n_max),
                    exists: std::array::from_fn(|i| M::of(|l| i < each[l].1)),
                    k: std::array::from_fn(|i| F::map(|l| each[l].2[i])),
                    w: std::array::from_fn(|i| F::map(|l| each[l].3[i])),
                    w_max: F::map(|l| each[l].4),
                    w_min: F::map(|l| each[l].5),
                    v_flat: F::map(|l| each[l].6),
                    coulomb: [
                        F::map(|l| each[l].0.coulomb[0]),
                        F::map(|l| each[l].0.coulomb[1]),
                    ],
                    static_: [
                        F::map(|l| each[l].0.static_[0]),
                        F::map(|l| each[l].0.static_[1]),
                    ],
                    vs: F::map(|l| each[l].0.stribeck_velocity),
                    exp2: M::of(|l| each[l].0.exponent == 2.0),
                    exp_other: M::of(|l| each[l].0.exponent != 2.0 && each[l].0.exponent != 1.0),
                }
            }
        };
        EngineF {
            law,
            n_cur: e0.n_cur,
            lin: LinF::of(std::array::from_fn(|l| &engines[l].lin)),
            gap: LinF::of(std::array::from_fn(|l| &engines[l].gap)),
            half_backlash,
            backlash,
            any_backlash: backlash.any(),
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
            delayed: e0.dead_time > 0,
            dead_time: std::array::from_fn(|l| engines[l].dead_time),
            ka_kt: v(&|e| e.ka_kt),
            ms_rest_stiffness: v(&|e| e.ms_rest_stiffness),
            pos_q: QuantF::of(std::array::from_fn(|l| &readers[l].0)),
            motor_q: QuantF::of(std::array::from_fn(|l| &readers[l].1)),
        }
    }

    /// [`Engine::rest`] per lane.
    fn rest(&self, x0: F, xm0: F) -> StateF<N> {
        let mut z = [F::splat(0.0); N];
        z[0] = x0;
        z[Self::XL] = x0;
        let zero = F::splat(0.0);
        StateF {
            z,
            integ: zero,
            e1: x0 - xm0,
            xr1: x0,
            xf1: xm0,
            xf2: xm0,
            delay: Box::new(DelayF {
                buf: [xm0; 128],
                pos: 0,
                d: self.dead_time,
                shared: self
                    .dead_time
                    .iter()
                    .all(|d| *d == self.dead_time[0])
                    .then_some(self.dead_time[0]),
            }),
            ms: Box::new([zero; MAX_ELEMENTS]),
            ms_force: zero,
            ms_stiffness: self.ms_rest_stiffness,
            ms_sat: zero,
            ms_level: zero,
        }
    }

    /// [`Engine::tick`] per lane.
    #[inline(always)]
    fn tick(&self, st: &mut StateF<N>, r: &RefF, inject: F, noise: (F, F)) -> TickF {
        let (d0, i0) = self.law.terms0(r, st.xr1, st.e1, st.xf1, st.xf2);
        let af = self.vf_a * st.xf1;
        let direct_a = d0 + self.s_df * af;
        let integ_a = st.integ + i0 + self.s_if * af;
        let u_a = direct_a + self.k_int * integ_a;
        let x_sensor = if self.load_source {
            st.z[Self::XL]
        } else {
            st.z[0]
        };
        let reading = self.pos_q.read(x_sensor, noise.0);
        let zero = F::splat(0.0);
        let (xp, xv, ub, xa, xb) = if self.one_reading {
            (reading, reading, u_a, reading, zero)
        } else if self.second_encoder {
            let xv = self.motor_q.read(st.z[0], noise.1);
            if !self.delayed {
                (reading, xv, u_a, reading, xv)
            } else {
                let xp = st.delay.push(reading);
                (xp, xv, u_a + self.gu_p * xp, zero, xv)
            }
        } else {
            let xp = st.delay.push(reading);
            (xp, reading, u_a + self.gu_p * xp, zero, reading)
        };
        let w = self.ga * xa + self.gb * xb;
        let u = ub + w;
        let xf = af + self.vf_b * xv;
        let d_int = i0 + self.s_ip * xp + self.s_if * xf;
        let saturated = u.abs().gt(self.u_lim);
        let (u, ub, w) = if !saturated.any() {
            st.integ = st.integ + d_int;
            (u, ub, w)
        } else {
            let direct = d0 + self.s_dp * xp + self.s_df * xf;
            let hold = saturated & (self.k_int * d_int * u).gt(zero);
            let u_hold = direct + self.k_int * st.integ;
            st.integ = sel(hold, st.integ, st.integ + d_int);
            let us = sel(hold, u_hold, u).clamp(-self.u_lim, self.u_lim);
            (
                sel(saturated, us, u),
                sel(saturated, us, ub),
                sel(saturated, zero, w),
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
        TickF {
            u,
            xp,
            u_in,
            saturated,
        }
    }

    /// [`Engine::torque`] per lane.
    #[inline(always)]
    fn torque(&self, z: &[F; N], u_in: F) -> F {
        if self.n_cur == 0 {
            self.ka_kt * u_in
        } else {
            self.ka_kt * z[Self::ICUR.min(N - 1)]
        }
    }

    /// [`Engine::plant_step`] per lane.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // small dense kernel on z, p and Γ: indices read best
    fn plant_step<const IX: usize, const IV: usize>(&self, st: &mut StateF<N>, ub: F, w: F) {
        let zero = F::splat(0.0);
        let merged;
        let (lin, o) = if self.any_backlash {
            let d = st.z[0] - st.z[2];
            let hb = self.half_backlash;
            let (c_pos, c_neg) = (d.ge(hb), d.le(-hb));
            let o = sel(c_pos, hb, sel(c_neg, -hb, zero));
            let in_gap = self.backlash & !c_pos & !c_neg;
            let lin = if !in_gap.any() {
                &self.lin
            } else if in_gap.all() {
                &self.gap
            } else {
                merged = LinF::select(in_gap, &self.gap, &self.lin);
                &merged
            };
            (lin, o)
        } else {
            (&self.lin, zero)
        };
        let z = st.z;
        let d = if TM { z[0] - z[Self::XL] } else { zero };
        let mut p = [zero; N];
        for i in 0..N {
            let mut acc = lin.g_u[i] * ub;
            if self.any_backlash {
                acc = sel(self.backlash, acc + lin.g_o[i] * o, acc);
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
            FricF::None => {
                for i in 0..N {
                    st.z[i] = p[i] + lin.g_u[i] * w;
                }
            }
            FricF::SetValued { laws } => {
                let v0 = z[IV];
                let mut f_pos = zero;
                let mut f_neg = zero;
                for l in 0..LANES {
                    let (law, v0) = (&laws[l], v0.0[l]);
                    (f_pos.0[l], f_neg.0[l]) = if law.static_ == law.coulomb {
                        (law.coulomb[0], -law.coulomb[1])
                    } else {
                        (law.level(0, v0.max(0.0)), -law.level(1, (-v0).max(0.0)))
                    };
                }
                let v_star = p[IV] + lin.g_u[IV] * w;
                let stuck = v_star.le(lin.stick_lim[0]) & v_star.ge(-lin.stick_lim[1]);
                let f = sel(v_star.gt(zero), f_pos, f_neg);
                for i in 0..N {
                    let z_stuck = if i == IV {
                        zero
                    } else {
                        (p[i] + lin.stick_k[i] * p[IV]) + lin.stick_gu[i] * w
                    };
                    let z_slide = (p[i] + lin.g_f[i] * f) + lin.g_u[i] * w;
                    st.z[i] = sel(stuck, z_stuck, z_slide);
                }
            }
            FricF::Maxwell {
                laws,
                n_max,
                uniform,
                exists,
                k,
                w: wk,
                w_max,
                w_min,
                v_flat,
                coulomb,
                static_,
                vs,
                exp2,
                exp_other,
            } => {
                let x0 = z[IX];
                let (f0, half_k) = (st.ms_force, F::splat(0.5) * st.ms_stiffness);
                let rigid = half_k.eq(zero);
                // No closures here: a closure is a function of its own, without AVX, that
                // would call the intrinsics instead of inlining them.
                if rigid.all() {
                    for i in 0..N {
                        st.z[i] = (p[i] + lin.g_f[i] * f0) + lin.g_u[i] * w;
                    }
                } else {
                    let f_p = (F::splat(1.0) + half_k * lin.g_f[IX]) * f0 + half_k * (p[IX] - x0);
                    let f_w = half_k * lin.g_u[IX];
                    for i in 0..N {
                        let c = lin.g_f[i];
                        let zi = (p[i] + c * f_p) + (lin.g_u[i] + c * f_w) * w;
                        st.z[i] = if rigid.any() {
                            sel(rigid, (p[i] + lin.g_f[i] * f0) + lin.g_u[i] * w, zi)
                        } else {
                            zi
                        };
                    }
                }
                // Slip levels (the scalar loop's `level` closure).
                let v0 = z[IV];
                let pos = v0.ge(zero);
                let speed = sel(pos, v0, -v0);
                let flat = speed.gt(*v_flat);
                // The law's own branches (FrictionLaw::level) as selects: the Coulomb level
                // beyond v_flat, at rest the static level, T_c beyond p = 40, the short series
                // below p = 1e-4, in between the exponential (`exp_neg` on lanes); a general
                // exponent's level per lane, with libm's power as in the scalar loop.
                let (tc, ts) = (
                    sel(pos, coulomb[0], coulomb[1]),
                    sel(pos, static_[0], static_[1]),
                );
                let lev = if flat.all() {
                    tc
                } else {
                    let one = F::splat(1.0);
                    let at_rest = speed.eq(zero);
                    let trivial = ts.eq(tc) | at_rest;
                    let r = speed / *vs;
                    let p = sel(*exp2, r * r, r);
                    let (big, small) = (p.gt(F::splat(40.0)), p.lt(F::splat(1e-4)));
                    let general = !flat & !trivial;
                    // Flat, and beyond p = 40: the Coulomb level; at rest the static level.
                    let mut lev = sel(trivial & !flat, sel(at_rest, ts, tc), tc);
                    let power = general & !*exp_other;
                    let short = power & small;
                    if short.any() {
                        let series = tc
                            + (ts - tc)
                                * (one - p * (one - p * (F::splat(0.5) - p / F::splat(6.0))));
                        lev = sel(short, series, lev);
                    }
                    let exp = power & !(big | small);
                    if exp.any() {
                        lev = sel(exp, tc + (ts - tc) * exp_neg(p), lev);
                    }
                    let libm = general & *exp_other;
                    if libm.any() {
                        for l in 0..LANES {
                            if libm.at(l) {
                                let dir = if pos.at(l) { 0 } else { 1 };
                                lev.0[l] = laws[l].level(dir, speed.0[l]);
                            }
                        }
                    }
                    lev
                };
                let hi = sel(pos, lev, static_[0]);
                let lo = sel(pos, static_[1], lev);
                let dx = st.z[IX] - x0;
                let (dl_hi, dl_lo) = (hi - st.ms_level, lo - st.ms_level);
                let stays_hi = dx.ge(dl_hi * sel(dl_hi.ge(zero), *w_max, *w_min));
                let stays_lo = (-dx).ge(dl_lo * sel(dl_lo.ge(zero), *w_max, *w_min));
                let take_hi = st.ms_sat.gt(zero) & stays_hi;
                let take_lo = !take_hi & st.ms_sat.lt(zero) & stays_lo;
                let slide = take_hi | take_lo;
                let general = !slide;
                let (mut sat, mut level, mut force, mut stiffness) = (st.ms_sat, zero, zero, zero);
                if general.any() {
                    let refresh = general & !st.ms_sat.eq(zero);
                    if refresh.any() {
                        let dd = st.ms_sat * st.ms_level;
                        for i in 0..*n_max {
                            let m = if *uniform {
                                refresh
                            } else {
                                refresh & exists[i]
                            };
                            st.ms[i] = sel(m, dd * wk[i], st.ms[i]);
                        }
                    }
                    // The scalar loop counts the elements at either limit and compares the
                    // counts with N; a lane's "every element at the limit" is the same truth,
                    // kept here as a running AND of masks (one instruction an element instead
                    // of a masked add, and no compare at the end).
                    let all = M::of(|_| true);
                    let (mut all_hi, mut all_lo) = (all, all);
                    let one = F::splat(1.0);
                    let every = general.all();
                    // Sums of non-negative terms, a term masked to +0 where the scalar loop
                    // skips it: the same numbers (x + 0 = x for x >= 0).
                    for i in 0..*n_max {
                        let (lo_i, hi_i) = (-lo * wk[i], hi * wk[i]);
                        let d = (st.ms[i] + dx).clamp(lo_i, hi_i);
                        let (above, below) = (d.gt(lo_i), d.lt(hi_i));
                        if *uniform {
                            st.ms[i] = if every { d } else { sel(general, d, st.ms[i]) };
                            force = force + k[i] * d;
                            stiffness = stiffness + k[i].masked(above & below);
                            all_hi = all_hi & !below;
                            all_lo = all_lo & !above;
                        } else {
                            let ex = exists[i];
                            st.ms[i] = sel(general & ex, d, st.ms[i]);
                            force = sel(ex, force + k[i] * d, force);
                            stiffness = stiffness + k[i].masked(ex & above & below);
                            all_hi = all_hi & !(ex & below);
                            all_lo = all_lo & !(ex & above);
                        }
                    }
                    sat = sel(all_hi, one, sel(all_lo, -one, zero));
                    level = sel(all_hi, hi, sel(all_lo, lo, zero));
                }
                st.ms_sat = sel(slide, st.ms_sat, sat);
                st.ms_level = sel(take_hi, hi, sel(take_lo, lo, level));
                st.ms_force = sel(take_hi, hi, sel(take_lo, -lo, force));
                st.ms_stiffness = sel(slide, zero, stiffness);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Reference shaping on lanes.

/// [`Shaper`] on lanes whose shaping has the same structure (the same delay in ticks, and the
/// same moving-average window or none): the same buffer and running sums, one lane per drive,
/// each lane the operations of [`Shaper::shape_block`] for its drive.
struct ShaperF {
    ext: Vec<RefF>,
    start: usize,
    keep: usize,
    /// The moving average's window `m`, running sums (position, velocity, acceleration) and
    /// $1/m$ per lane.
    avg: Option<(usize, [F; 3], F)>,
}

impl ShaperF {
    /// The lanes of `shapers` (one per lane, at rest), if they share their structure.
    fn of(shapers: &[Shaper]) -> Option<ShaperF> {
        let s0 = &shapers[0];
        let window = |s: &Shaper| match s.filter {
            ShapeFilter::None => Some(None),
            ShapeFilter::Avg { m, .. } => Some(Some(m)),
            ShapeFilter::Lin { .. } => None,
        };
        let w0 = window(s0)?;
        if shapers
            .iter()
            .any(|s| s.keep != s0.keep || window(s) != Some(w0) || s.start != 0)
        {
            return None;
        }
        let avg = w0.map(|m| {
            let lanes = |f: &dyn Fn(&[f64; 3], f64) -> f64| {
                F::map(|l| match &shapers[l].filter {
                    ShapeFilter::Avg { sum, inv_m, .. } => f(sum, *inv_m),
                    _ => unreachable!("the lanes share a structure"),
                })
            };
            (
                m,
                [
                    lanes(&|s, _| s[0]),
                    lanes(&|s, _| s[1]),
                    lanes(&|s, _| s[2]),
                ],
                lanes(&|_, inv_m| inv_m),
            )
        });
        let ext = (0..s0.keep)
            .map(|i| RefF {
                xr: F::map(|l| shapers[l].ext[i].xr),
                vr: F::map(|l| shapers[l].ext[i].vr),
                ar: F::map(|l| shapers[l].ext[i].ar),
            })
            .collect();
        Some(ShaperF {
            ext,
            start: 0,
            keep: s0.keep,
            avg,
        })
    }

    /// Whether the shaping does anything (a delay or a filter); else the loop's references
    /// are the nominal ones.
    fn active(&self) -> bool {
        self.keep > 0
    }

    /// Room for the next `b` nominal references, in place in the shaper's buffer (no copy):
    /// fill it, then [`ShaperF::shape_into`] with `b` references. Only for an active shaper.
    #[inline(always)]
    fn inputs(&mut self, b: usize) -> &mut [RefF] {
        let keep = self.keep;
        if self.start + keep + b > self.ext.len() {
            self.ext.copy_within(self.start..self.start + keep, 0);
            self.start = 0;
            let len = keep + 16 * b;
            if self.ext.len() < len {
                // Beyond the kept inputs every slot is written before it is read.
                let zero = F::splat(0.0);
                self.ext.resize(
                    len,
                    RefF {
                        xr: zero,
                        vr: zero,
                        ar: zero,
                    },
                );
            }
        }
        let s0 = self.start;
        &mut self.ext[s0 + keep..s0 + keep + b]
    }

    /// [`Shaper::shape_block`] per lane, of the references just written into
    /// [`ShaperF::inputs`], into `out`.
    #[inline(always)]
    fn shape_into(&mut self, out: &mut [RefF]) {
        let (b, keep) = (out.len(), self.keep);
        let s0 = self.start;
        let ext = &self.ext[s0..s0 + keep + b];
        match &mut self.avg {
            Some((m, sum, inv_m)) => {
                let (m, inv_m) = (*m, *inv_m);
                let half = F::splat(0.5);
                let [mut a0, mut a1, mut a2] = *sum;
                let rows = out
                    .iter_mut()
                    .zip(&ext[m + 1..m + 1 + b])
                    .zip(ext[..b].iter().zip(&ext[1..b + 1]));
                for ((out, new), (leaving, oldest)) in rows {
                    a0 = a0 + (new.xr - leaving.xr);
                    a1 = a1 + (new.vr - leaving.vr);
                    a2 = a2 + (new.ar - leaving.ar);
                    *out = RefF {
                        xr: (a0 - half * (new.xr + oldest.xr)) * inv_m,
                        vr: (a1 - half * (new.vr + oldest.vr)) * inv_m,
                        ar: (a2 - half * (new.ar + oldest.ar)) * inv_m,
                    };
                }
                *sum = [a0, a1, a2];
            }
            None => out.copy_from_slice(&ext[..b]),
        }
        self.start += b;
    }
}

/// The fine interpolation of one sample on lanes, into `out` (its ticks): tick 0 the sample
/// `s0` itself, as in the scalar engine (`p0 + 0·dp` would differ for a −0.0 sample), tick j
/// `s0 + (j/n_sub)·d`, the scalar loop's operations lane by lane.
#[inline(always)]
fn interpolate(out: &mut [RefF], s0: &RefF, d: &RefF, inv_sub: f64) {
    out[0] = *s0;
    for (j, r) in out[1..].iter_mut().enumerate() {
        let w = F::splat((j + 1) as f64 * inv_sub);
        *r = RefF {
            xr: s0.xr + w * d.xr,
            vr: s0.vr + w * d.vr,
            ar: s0.ar + w * d.ar,
        };
    }
}

/// Sample `k` of every lane's reference.
#[inline(always)]
fn sample_at(inputs: &[LaneInput<'_>; LANES], k: usize) -> RefF {
    RefF {
        xr: F::map(|l| inputs[l].reference.pos[k]),
        vr: F::map(|l| inputs[l].reference.vel[k]),
        ar: F::map(|l| inputs[l].reference.acc[k]),
    }
}

// ---------------------------------------------------------------------------------------------
// The run.

/// One lane's drive: its reference, reference shaping and readers (lanes beyond the batch's
/// drives repeat a drive; their traces are dropped).
pub(crate) struct LaneInput<'r> {
    pub(crate) reference: Reference<'r>,
    pub(crate) shaping: Option<Shaping>,
    pub(crate) readers: (Reader, Reader),
}

/// Runs the lanes through their references (the same length, `n_sub` ticks of `h` each) into
/// `traces` (one per lane; cleared and sized by the caller).
pub(crate) fn run_batch<B: LaneLaw, const N: usize, const TM: bool>(
    e: &EngineF<B, N, TM>,
    inputs: &mut [LaneInput<'_>; LANES],
    n_sub: usize,
    h: f64,
    traces: &mut [&mut DriveTrace; LANES],
) -> Result<(), Error> {
    if std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512vl")
    {
        // SAFETY: both features `run_avx512vl` enables beyond AVX2 are checked just above.
        unsafe { run_avx512vl(e, inputs, n_sub, h, traces) }
    } else {
        // SAFETY: the lanes run only on a processor with AVX2 (`available`, checked by the
        // caller).
        unsafe { run_avx2(e, inputs, n_sub, h, traces) }
    }
}

/// Whether this processor runs lanes (AVX2).
pub(crate) fn available() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

/// [`run_body`] compiled with the target features `$features` (a `target_feature` attribute
/// takes a literal, hence one function per feature set).
macro_rules! run_with {
    ($(#[$doc:meta])* $name:ident, $features:literal) => {
        $(#[$doc])*
        #[target_feature(enable = $features)]
        fn $name<B: LaneLaw, const N: usize, const TM: bool>(
            e: &EngineF<B, N, TM>,
            inputs: &mut [LaneInput<'_>; LANES],
            n_sub: usize,
            h: f64,
            traces: &mut [&mut DriveTrace; LANES],
        ) -> Result<(), Error> {
            run_body(e, inputs, n_sub, h, traces)
        }
    };
}
run_with!(
    /// [`run_body`] compiled for AVX2.
    run_avx2,
    "avx2"
);
run_with!(
    /// [`run_body`] compiled for AVX2 with AVX-512VL.
    run_avx512vl,
    "avx2,avx512f,avx512vl"
);

/// The noise of one tick's readings, each lane's from its readers' streams (the motor
/// encoder's where `motor` lanes read it noisily; else it stays 0, as the scalar loop's).
#[inline(always)]
fn draw(inputs: &mut [LaneInput<'_>; LANES], motor: bool, out: &mut (F, F)) {
    for (l, input) in inputs.iter_mut().enumerate() {
        out.0.0[l] = input.readers.0.noise();
        if motor {
            out.1.0[l] = input.readers.1.noise();
        }
    }
}

/// [`Engine::run`] per lane.
#[inline(always)]
fn run_body<B: LaneLaw, const N: usize, const TM: bool>(
    e: &EngineF<B, N, TM>,
    inputs: &mut [LaneInput<'_>; LANES],
    n_sub: usize,
    h: f64,
    traces: &mut [&mut DriveTrace; LANES],
) -> Result<(), Error> {
    let n = inputs[0].reference.pos.len();
    let x0 = F::map(|l| inputs[l].reference.pos[0]);
    let xm0 = F::map(|l| {
        let r = &inputs[l].readers.0;
        quantise_to(x0.0[l], r.q, r.inv_q)
    });
    let mut st = e.rest(x0, xm0);
    let r0 = |l: usize| {
        let r = &inputs[l].reference;
        RefSample {
            xr: r.pos[0],
            vr: r.vel[0],
            ar: r.acc[0],
        }
    };
    let mut shapers = Vec::with_capacity(LANES);
    for (l, input) in inputs.iter().enumerate() {
        shapers.push(Shaper::new(input.shaping, h, r0(l))?);
    }
    let shaped: [bool; LANES] = std::array::from_fn(|l| inputs[l].shaping.is_some());
    // All lanes shaped alike (the usual case: a machine's drives share their control's
    // reference shaping): one shaper on lanes; else one per lane, as the scalar loop.
    let mut shared = if shaped.iter().all(|s| *s) {
        ShaperF::of(&shapers)
    } else {
        None
    };
    let inv_sub = 1.0 / n_sub as f64;
    // Ticks at the limit per lane, counted in floats (exact below 2^53).
    let mut saturated_f = F::splat(0.0);
    let one = F::splat(1.0);
    // Per lane, as the scalar loop, where the lanes are not shaped alike: the sample's fine
    // references (shaped).
    let mut refs: Vec<Vec<RefSample>> = if shared.is_some() {
        Vec::new()
    } else {
        (0..LANES).map(|l| vec![r0(l); n_sub]).collect()
    };
    // The same, across lanes, tick by tick, and the readings' noise.
    let zero = F::splat(0.0);
    let mut refs_f = vec![
        RefF {
            xr: zero,
            vr: zero,
            ar: zero,
        };
        n_sub
    ];
    // The readings' noise of this sample's ticks, and of the next sample's, drawn during this
    // sample's ticks (one tick's draws per tick: the generator's work fills the gaps of the
    // ticks' dependency chain instead of running apart). Each reader's stream in tick order,
    // as the scalar loop draws it.
    let mut noise_f = vec![(zero, zero); n_sub];
    let mut noise_next = vec![(zero, zero); n_sub];
    let motor_noise = e.second_encoder && inputs.iter().any(|i| i.readers.1.std > 0.0);
    let ticks_of = |k: usize| if k + 1 == n { 1 } else { n_sub };
    if n > 0 {
        for nf in &mut noise_f[..ticks_of(0)] {
            draw(inputs, motor_noise, nf);
        }
    }
    for k in 0..n {
        let last = k + 1 == n;
        let ticks = ticks_of(k);
        let ticks_next = if last { 0 } else { ticks_of(k + 1) };
        if let Some(shaper) = shared.as_mut() {
            // The fine interpolation on lanes, written straight into the shaper's buffer.
            let s0 = sample_at(inputs, k);
            let d = if last {
                RefF {
                    xr: zero,
                    vr: zero,
                    ar: zero,
                }
            } else {
                let s1 = sample_at(inputs, k + 1);
                RefF {
                    xr: s1.xr - s0.xr,
                    vr: s1.vr - s0.vr,
                    ar: s1.ar - s0.ar,
                }
            };
            if shaper.active() {
                interpolate(shaper.inputs(ticks), &s0, &d, inv_sub);
                shaper.shape_into(&mut refs_f[..ticks]);
            } else {
                interpolate(&mut refs_f[..ticks], &s0, &d, inv_sub);
            }
        }
        for (l, input) in inputs.iter_mut().enumerate() {
            if shared.is_none() {
                let (pos, vel, acc) = (
                    input.reference.pos,
                    input.reference.vel,
                    input.reference.acc,
                );
                let (p0, v0, a0) = (pos[k], vel[k], acc[k]);
                let (dp, dv, da) = if last {
                    (0.0, 0.0, 0.0)
                } else {
                    (pos[k + 1] - p0, vel[k + 1] - v0, acc[k + 1] - a0)
                };
                let refs = &mut refs[l][..ticks];
                refs[0] = RefSample {
                    xr: p0,
                    vr: v0,
                    ar: a0,
                };
                for (j, r) in refs[1..].iter_mut().enumerate() {
                    let w = (j + 1) as f64 * inv_sub;
                    *r = RefSample {
                        xr: p0 + w * dp,
                        vr: v0 + w * dv,
                        ar: a0 + w * da,
                    };
                }
                if shaped[l] {
                    shapers[l].shape_block(refs);
                }
                for (rf, r) in refs_f.iter_mut().zip(refs.iter()) {
                    rf.xr.0[l] = r.xr;
                    rf.vr.0[l] = r.vr;
                    rf.ar.0[l] = r.ar;
                }
            }
        }
        let (xl, vl, xm) = (
            st.z[EngineF::<B, N, TM>::XL],
            st.z[EngineF::<B, N, TM>::VL],
            st.z[0],
        );
        let z_before = st.z;
        let out = e.tick(&mut st, &refs_f[0], zero, noise_f[0]);
        let torque = e.torque(&z_before, out.u_in);
        saturated_f = saturated_f + one.masked(out.saturated);
        for (l, trace) in traces.iter_mut().enumerate() {
            trace.position.push(out.xp.0[l]);
            trace.true_position.push(xl.0[l]);
            trace.velocity.push(vl.0[l]);
            trace.control.push(out.u.0[l]);
            trace.motor_position.push(xm.0[l]);
            trace.motor_torque.push(torque.0[l]);
        }
        if ticks_next > 0 {
            draw(inputs, motor_noise, &mut noise_next[0]);
        }
        for (j, (r, nf)) in refs_f[1..ticks].iter().zip(&noise_f[1..ticks]).enumerate() {
            let out = e.tick(&mut st, r, zero, *nf);
            saturated_f = saturated_f + one.masked(out.saturated);
            if j + 1 < ticks_next {
                draw(inputs, motor_noise, &mut noise_next[j + 1]);
            }
        }
        std::mem::swap(&mut noise_f, &mut noise_next);
    }
    for (trace, s) in traces.iter_mut().zip(saturated_f.0) {
        trace.saturated_ticks = s as u64;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[target_feature(enable = "avx2")]
    fn exp_neg_avx2(p: F) -> F {
        exp_neg(p)
    }

    #[test]
    fn exp_neg_on_lanes_is_the_scalar_one_bit_for_bit() {
        // Truth: `effects::exp_neg`, which the scalar loop's friction level uses; every p of
        // a log-spaced sweep over the friction law's range (1e-4 to 40) and beyond.
        if !available() {
            return;
        }
        let ps: Vec<f64> = (0..40_000)
            .map(|i| 1e-6 * (7e8f64).powf(i as f64 / 40_000.0))
            .filter(|p| *p <= 700.0)
            .collect();
        for c in ps.chunks_exact(LANES) {
            let p = F(std::array::from_fn(|l| c[l]));
            // SAFETY: AVX2 is present (checked above).
            let v = unsafe { exp_neg_avx2(p) };
            for (p, v) in c.iter().zip(v.0) {
                let s = crate::effects::exp_neg(*p);
                assert_eq!(v.to_bits(), s.to_bits(), "p = {p}");
            }
        }
    }
}
